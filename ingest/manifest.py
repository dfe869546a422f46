"""Data manifest: raw files named by public origin URL and sha256, resolved locally.

A file is looked up in the mirror folder first (``GAITLOOP_MIRROR``, default ``../shared/data``
beside the checkout), then in the download cache (``data/raw``), then downloaded from its origin
into the cache. Its sha256 is verified every time; nothing unverified is ever returned.

An entry may also name a repository-relative ``path``: a copy tracked by DVC (``data/raw/<subject>/``,
written by ``add-subject``), looked up first, under the repository root. Its ``url`` is then the
file's public origin, or ``dvc:<path>`` when it has none (``dvc pull`` is the only way to get it).
"""

from __future__ import annotations

import hashlib
import os
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ingest.errors import ManifestError

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_MANIFEST = REPO_ROOT / "data" / "sources.yaml"
DEFAULT_CACHE = REPO_ROOT / "data" / "raw"


def default_mirror() -> Path:
    return Path(os.environ.get("GAITLOOP_MIRROR", REPO_ROOT.parent / "shared" / "data"))


DVC_SCHEME = "dvc:"


@dataclass(frozen=True)
class Source:
    """A manifest entry: `url` is the public origin (or `dvc:<path>`), `path` a DVC-tracked copy
    relative to the repository root, if any."""

    key: str
    url: str
    sha256: str
    path: str | None = None


def repo_relative(value: object) -> bool:
    """Whether `value` is a path that stays inside the repository: POSIX, relative, no `..`, no drive
    or scheme."""
    text = str(value)
    parts = text.split("/")
    return bool(text) and not text.startswith("/") and not any(c in text for c in "\\:") \
        and ".." not in parts and "" not in parts


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@dataclass(frozen=True)
class Manifest:
    """The set of known files and where to look for them.

    A file verified once is not hashed again by the same Manifest while its size and
    modification time stay the same.
    """

    sources: dict[str, Source]
    mirror: Path
    cache: Path
    root: Path = REPO_ROOT
    _verified: dict[Path, tuple[int, int]] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def load(
        cls, path: Path = DEFAULT_MANIFEST, mirror: Path | None = None, cache: Path = DEFAULT_CACHE,
        root: Path = REPO_ROOT,
    ) -> Manifest:
        """The manifest at `path`; `root` is the repository that entries' `path`s are relative to."""
        try:
            doc = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ManifestError(path, f"cannot read manifest ({exc})") from None
        files = (doc or {}).get("files") or {}
        sources = {}
        for key, entry in files.items():
            if not isinstance(entry, dict) or "sha256" not in entry or "url" not in entry:
                raise ManifestError(path, f"entry {key!r} needs 'url' and 'sha256'")
            url = str(entry["url"])
            local = entry.get("path") or (url[len(DVC_SCHEME):] if url.startswith(DVC_SCHEME) else None)
            if local is not None and not repo_relative(local):
                raise ManifestError(path, f"entry {key!r}: path {local!r} must be relative to the repository "
                                    "root, without '..'")
            sources[key] = Source(key, url, str(entry["sha256"]).lower(), local)
        return cls(sources, mirror or default_mirror(), cache, Path(root))

    def resolve(self, key: str, verify: bool = True) -> Path:
        """Local path of a verified copy of `key`; raises `ManifestError` naming the file. With
        `verify` False a local copy is returned unchecked: the caller verifies it (`verify`) before
        trusting what it read (a download is verified before it is kept, either way)."""
        try:
            source = self.sources[key]
        except KeyError:
            raise ManifestError(key, "not listed in the data manifest (data/sources.yaml)") from None
        local = [self.mirror / key, self.cache / key]
        if source.path:  # the repository's own DVC-tracked copy first
            local.insert(0, self.root / source.path)
        for path in local:
            if path.is_file():
                if verify:
                    self._verify(path, source)
                return path
        cached = local[-1]
        if source.url.startswith(DVC_SCHEME):
            raise ManifestError(key, f"tracked by DVC as {source.path} but not checked out under "
                                f"{self.root}: run `dvc pull {source.path}.dvc`")
        cached.parent.mkdir(parents=True, exist_ok=True)
        partial = cached.with_name(cached.name + ".part")
        try:
            with urllib.request.urlopen(source.url, timeout=30) as response:
                partial.write_bytes(response.read())
        except OSError as exc:
            partial.unlink(missing_ok=True)
            raise ManifestError(
                key, f"not in mirror {self.mirror} and download from {source.url} failed ({exc})"
            ) from None
        self._verify(partial, source)
        partial.replace(cached)
        return cached

    def verify(self, key: str, path: Path) -> None:
        """Check that `path` is `key`'s file (its sha256); raises `ManifestError` naming the file."""
        self._verify(path, self.sources[key])

    def _verify(self, path: Path, source: Source) -> None:
        stat = path.stat()
        if self._verified.get(path) == (stat.st_size, stat.st_mtime_ns):
            return
        actual = sha256_of(path)
        if actual != source.sha256:
            if path.name.endswith(".part"):
                path.unlink(missing_ok=True)
            raise ManifestError(
                path, f"sha256 mismatch for {source.key}: manifest says {source.sha256}, file is {actual}"
            )
        self._verified[path] = (stat.st_size, stat.st_mtime_ns)
