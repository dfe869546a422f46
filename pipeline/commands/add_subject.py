"""Command `add-subject`: register a new subject from its raw files.

Writes `data/subjects/<id>.yaml` and appends `<id>` to `subjects` in params.yaml, so the next
`dvc repro` runs that subject's foreach stages (plus store and report) and nothing else. It also
appends `<id>` to `transfer.subjects` (unless `policy=False` or it is a round trip), so that
`dvc repro` gives the new person a walking policy from the universal one (`transfer@<id>`: gated,
fine-tuned within `transfer`'s budget while the gate fails) without a hand edit.

Files are referenced through the data manifest (`data/sources.yaml`) like every other raw file:
a file whose sha256 is already listed reuses that entry (e.g. a file from the shared mirror).
Any other file is copied to `data/raw/<id>/` and tracked there with DVC (`dvc add`: one
`<file>.dvc` per file, plus that folder's `.gitignore`, to commit with the subject and `dvc push`),
and gets a new entry `local/<id>/<file name>` with `path: data/raw/<id>/<file name>`, its sha256
and as origin the `origin` URL given (`<origin>/<file name>`) or else `dvc:data/raw/<id>/<file name>`.
No committed file holds a path of this machine. The manifest reads the DVC-checked-out copy (after
`dvc pull` in another clone) and checks the hash on every use.

The DVC repository is the registry's `root` (the repository root by default; tests point it at a
clone). A registry whose manifest lies outside its root (a scratch copy, e.g. in tests) is not
committed anywhere: there a new file's origin stays the `file://` URL to where it lies now.

Everything is checked before anything is written: the id is new, every file exists, every file
is read by the ingest readers and goes through the canonical frame (units, up axis, body scale)
with the chosen marker set, and the static trial is quiet standing (`ingest.static.check_static`,
params `ingest.static`), the DVC repository is there and `data/raw/<id>/` is not, and a marker set
given as a YAML file lies inside the repository. params.yaml and the manifest are edited by appending
lines, keeping their comments. If anything fails while writing (`dvc add` included), the copies in
`data/raw/<id>/` are removed and no registry file is changed.

Up axis `auto` (the default): detected per marker file (`ingest.canonical.detect_up_axis`); when
all files agree the subject file declares that axis (so later runs check it), else `auto`.
Static `auto`: the quiet standing before a walk in the trials (`ingest.static.find_standing_window`),
written as that trial's file and `window_s`.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import logging
import os
import re
import shutil
import subprocess
import sys
import urllib.parse
from dataclasses import dataclass
from pathlib import Path

import yaml

from ingest.canonical import load_trial, resolve_up_axis
from ingest.errors import GaitloopError, IngestError, SubjectError
from ingest.manifest import DEFAULT_MANIFEST, DVC_SCHEME, Manifest, Source, sha256_of
from ingest.markersets import REPO_ROOT, markerset_path
from ingest.readers import read_markers, read_mot, read_robot_log
from ingest.robot_log import robot_table
from ingest.static import StaticCheckParams, check_static, find_standing_window
from ingest.subject import (
    MARKERSETS_DIR,
    STATIC_AUTO,
    STATIC_NONE,
    SUBJECTS_DIR,
    UP_AXIS_CHOICES,
    FileFormat,
    StaticSpec,
    Subject,
    TrialSpec,
    check_body_size,
    load_markerset,
)
from pipeline.commands.quicklook import fitting_markerset
from pipeline.params import load_params, parse_params
from pipeline.paths import PARAMS_FILE
from pipeline.stages.outputs import replacing
from sim.learn.transfer import TransferSection
from sim.motion.reference import ReferenceParams

ID_PATTERN = re.compile(r"^[a-z0-9][a-z0-9_-]{0,63}$")
MARKER_SUFFIXES = (".trc", ".c3d", ".csv")
MOT_SUFFIXES = (".mot", ".sto")
RAW_DIR = Path("data") / "raw"  # DVC-tracked copies of added subjects' files, relative to the root
ORIGIN_PATTERN = re.compile(r"^https?://[^\s]+$")
DVC_TIMEOUT_S = 600

log = logging.getLogger("gaitloop.pipeline")


@dataclass(frozen=True)
class NewTrial:
    """One trial to register: its condition, marker file and optional angles / GRF `.mot` files and
    robot log (`.csv`, `ingest.readers.robot_log`: a robot-assisted trial)."""

    condition: str
    markers: Path
    angles: Path | None = None
    grf: Path | None = None
    robot_log: Path | None = None

    @classmethod
    def parse(cls, text: str) -> NewTrial:
        """`COND=MARKERS[,ANGLES[,GRF[,ROBOT_LOG]]]` (empty fields skip a file), e.g.
        `free=walk1.trc,walk1_ik.mot,walk1_grf.mot` or `pid=walk2.trc,walk2_ik.mot,,walk2_robot.csv`."""
        cond, sep, files = text.partition("=")
        parts = [p.strip() for p in files.split(",")] if sep else []
        if not cond.strip() or not parts or not parts[0] or len(parts) > 4:
            raise SubjectError(text, "a trial is COND=MARKERS[,ANGLES.mot[,GRF.mot[,ROBOT_LOG.csv]]]")
        paths = [Path(p) if p else None for p in parts] + [None] * (4 - len(parts))
        return cls(cond.strip(), *paths)


@dataclass(frozen=True)
class Registry:
    """Where subjects are registered: the subject files, params.yaml, the manifest, the mirror, and
    the repository `root` (git + DVC) new raw files are tracked in, under `data/raw/<id>/`."""

    subjects_dir: Path = SUBJECTS_DIR
    params_path: Path = PARAMS_FILE
    manifest_path: Path = DEFAULT_MANIFEST
    markersets_dir: Path = MARKERSETS_DIR
    mirror: Path | None = None
    root: Path = REPO_ROOT

    @classmethod
    def of_repo(cls, root: Path, mirror: Path | None = None) -> Registry:
        """The registry of the repository checked out at `root` (e.g. another clone)."""
        root = Path(root)
        return cls(root / "data" / "subjects", root / "params.yaml", root / "data" / "sources.yaml",
                   root / "data" / "markersets", mirror, root)

    @property
    def tracks_with_dvc(self) -> bool:
        """New raw files go to DVC when the manifest is the root's (not a scratch copy elsewhere)."""
        return self.manifest_path.resolve().is_relative_to(self.root.resolve())


def _check_file(path: Path, kind: str) -> Path:
    path = Path(path)
    if not path.is_file():
        raise IngestError(path, f"{kind} file not found")
    readers = {"markers": read_markers, "static": read_markers, "robot_log": read_robot_log}
    suffixes = {"markers": MARKER_SUFFIXES, "static": MARKER_SUFFIXES, "robot_log": (".csv",)}
    suffixes = suffixes.get(kind, MOT_SUFFIXES)
    if path.suffix.lower() not in suffixes:
        raise IngestError(path, f"{kind} file must be one of {', '.join(suffixes)}")
    try:
        readers.get(kind, read_mot)(path)
    except GaitloopError as exc:
        raise IngestError(path, f"unreadable {kind} file: {getattr(exc, 'problem', exc)}") from None
    except Exception as exc:  # a reader tripping over garbage is still an unreadable file
        raise IngestError(path, f"unreadable {kind} file ({type(exc).__name__}: {exc})") from None
    return path.resolve()


def _manifest_key(path: Path, manifest: Manifest, by_sha: dict[str, str], subject_id: str,
                  new: dict[str, Source], tracked: bool, origin: str | None) -> str:
    """The manifest key of `path`: the listed one for a known sha256, else a new entry in `new`
    (module docstring: tracked by DVC in data/raw/<id>/, or a `file://` origin)."""
    sha = sha256_of(path)
    if sha in by_sha:
        return by_sha[sha]
    key = f"local/{subject_id}/{path.name}"
    n = 1
    while key in manifest.sources or key in new:
        n += 1
        key = f"local/{subject_id}/{path.stem}_{n}{path.suffix}"
    local = (RAW_DIR / subject_id / key.rsplit("/", 1)[1]).as_posix() if tracked else None
    if origin:
        url = f"{origin.rstrip('/')}/{urllib.parse.quote(path.name)}"
    else:
        url = f"{DVC_SCHEME}{local}" if tracked else path.as_uri()
    new[key] = Source(key, url, sha, local)
    by_sha[sha] = key
    return key


def _dvc_command() -> list[str]:
    """How to run DVC: this interpreter's `dvc` module (the venv's), else `dvc` on the PATH."""
    if importlib.util.find_spec("dvc") is not None:
        return [sys.executable, "-m", "dvc"]
    found = shutil.which("dvc")
    if found is None:
        raise SubjectError("dvc", "DVC is not installed (pip install dvc): new raw files are tracked with it")
    return [found]


def _check_dvc_target(registry: Registry, subject_id: str, manifest: Manifest) -> Path:
    """The folder new files will be copied to, `<root>/data/raw/<id>/`, once checked: the root is a DVC
    repository, the folder does not exist and no manifest entry points into it."""
    root = registry.root
    if not (root / ".dvc").is_dir():
        raise SubjectError(root, "not a DVC repository (no .dvc/ folder): new raw files are tracked with DVC "
                           "(`dvc init`)")
    folder = root / RAW_DIR / subject_id
    prefix = f"{(RAW_DIR / subject_id).as_posix()}/"
    if folder.exists() or folder.is_symlink() or any((s.path or "").startswith(prefix)
                                                     for s in manifest.sources.values()):
        raise SubjectError(folder, f"raw folder of subject {subject_id!r} already exists or is listed in the "
                           "manifest: remove it or choose another id")
    return folder


def _track_with_dvc(registry: Registry, folder: Path, files: dict[str, Path], new: dict[str, Source],
                    dvc: list[str]) -> None:
    """Copy each new file to its `path` under the root and `dvc add` them (one .dvc file each).
    Raises `SubjectError` having removed `folder` again when a copy or DVC fails."""
    try:
        folder.mkdir(parents=True)
        for key, source in new.items():
            copy = registry.root / source.path
            shutil.copyfile(files[key], copy)
            if sha256_of(copy) != source.sha256:
                raise IngestError(files[key], "changed while it was being registered")
        env = {**os.environ, "DVC_NO_ANALYTICS": "1"}
        try:
            done = subprocess.run([*dvc, "add", "--quiet", *(s.path for s in new.values())],
                                  cwd=registry.root, env=env, capture_output=True, text=True,
                                  timeout=DVC_TIMEOUT_S)
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise SubjectError(folder, f"`dvc add` could not run ({exc})") from None
        if done.returncode != 0:
            detail = " ".join((done.stderr or done.stdout).split())[-600:]
            raise SubjectError(folder, f"`dvc add` failed (exit {done.returncode}): {detail}")
        missing = [s.path for s in new.values() if not (registry.root / f"{s.path}.dvc").is_file()]
        if missing:
            raise SubjectError(folder, f"`dvc add` wrote no .dvc file for {', '.join(missing)}")
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


def _append_subject_to_params(text: str, subject_id: str, path: Path) -> str:
    lines = text.splitlines(keepends=True)
    try:
        start = next(i for i, line in enumerate(lines) if re.match(r"^subjects:\s*(#.*)?$", line))
    except StopIteration:
        raise SubjectError(path, "no block list 'subjects:' at the top level to add the subject to") from None
    end = start + 1
    while end < len(lines) and re.match(r"^\s+(-.*)?(#.*)?$", lines[end]):
        end += 1
    while end > start + 1 and not lines[end - 1].strip().startswith("-"):
        end -= 1
    indent = re.match(r"^(\s*)-", lines[end - 1]).group(1) if end > start + 1 else "  "
    if lines[end - 1] and not lines[end - 1].endswith("\n"):
        lines[end - 1] += "\n"
    lines.insert(end, f"{indent}- {subject_id}\n")
    return "".join(lines)


def _append_transfer_subject(text: str, subject_id: str, path: Path) -> str:
    """`text` with `subject_id` added to the flow list `subjects: [...]` of the top-level
    `transfer:` block, comments kept."""
    lines = text.splitlines(keepends=True)
    start = next((i for i, line in enumerate(lines) if re.match(r"^transfer:\s*(#.*)?$", line)), None)
    for line_no in range(start + 1 if start is not None else len(lines), len(lines)):
        line = lines[line_no]
        if line.strip() and not line[0].isspace():
            break
        m = re.match(r"^(\s+subjects:\s*)\[([^\]]*)\](.*)$", line, re.S)
        if m:
            items = [x.strip() for x in m.group(2).split(",") if x.strip()]
            lines[line_no] = f"{m.group(1)}[{', '.join([*items, subject_id])}]{m.group(3)}"
            return "".join(lines)
    raise SubjectError(path, "no flow list 'subjects: [...]' in the top-level 'transfer:' block to add the "
                       "subject to (or register it with --no-policy)")


def _markerset_ref(markerset: str, registry: Registry) -> str:
    """How the subject file names the marker set: a shipped set by name, a YAML file by its path
    relative to the repository root, so it reads the same from any working directory and clone.
    A file outside the repository is refused (absolute path kept for a scratch registry)."""
    directory = registry.markersets_dir
    path = markerset_path(markerset, directory)
    if path.parent.resolve() == directory.resolve():
        return path.stem
    path, root = path.resolve(), registry.root.resolve()
    if path.is_relative_to(root):
        return path.relative_to(root).as_posix()
    if registry.tracks_with_dvc:
        raise SubjectError(path, f"marker set file is outside the repository {root}: copy it into "
                           "data/markersets/ (or elsewhere in the repository) so the subject reads in any "
                           "clone")
    return str(path)


def add_subject(subject_id: str, height_m: float, mass_kg: float, static: Path | str,
                trials: list[NewTrial], *, markerset: str | None = None, up_axis: str = "auto",
                knee_flexion_sign: int = 1, dataset: str | None = None, round_trip_of: str | None = None,
                origin: str | None = None, policy: bool = True, registry: Registry = Registry()) -> Path:
    """Check and register a subject; returns the new subject file. `static` is a marker file or
    "auto", `up_axis` x, y, z or "auto", `origin` an http(s) URL the new files are published under,
    `policy` whether `dvc repro` transfers a walking policy to it (module docstring). Raises
    `SubjectError` or `IngestError` naming the id or file at fault, having written nothing."""
    subj_file = registry.subjects_dir / f"{subject_id}.yaml"
    if not ID_PATTERN.match(subject_id):
        raise SubjectError(subject_id, "subject id must be lower case letters, digits, '_' or '-'")
    params = load_params(registry.params_path)
    if subj_file.exists() or subject_id in params.subjects:
        raise SubjectError(subj_file, f"subject {subject_id!r} is already registered")
    if not trials:
        raise SubjectError(subject_id, "no trials given (--trial COND=FILE)")
    needed = list(params.section("retarget", ReferenceParams).conditions)
    if needed and not any(t.condition in needed for t in trials):
        raise SubjectError(subject_id, f"no trial with condition in {needed} (params retarget.conditions): "
                           "the reference motion of the simulated human is built from those")
    check_body_size(height_m, mass_kg, subject_id)
    if up_axis not in UP_AXIS_CHOICES or knee_flexion_sign not in (1, -1):
        raise SubjectError(subject_id, "up axis must be x, y, z or auto and knee flexion sign 1 or -1")
    if round_trip_of is not None and not ID_PATTERN.match(round_trip_of):
        raise SubjectError(round_trip_of, "round_trip_of must be a subject id")
    if origin is not None and not ORIGIN_PATTERN.match(origin):
        raise SubjectError(origin, "origin must be an http(s) URL the files are published under")
    for t in trials:
        if t.robot_log and t.condition == "free":
            raise SubjectError(t.robot_log, "a robot log belongs to a robot-assisted trial: name the "
                               "controller that ran as the trial's condition, not 'free'")
    static_none = str(static) == STATIC_NONE  # no standing: scaled from the walks (ingest.static)
    static_auto = str(static) == STATIC_AUTO or static_none
    static = None if static_auto else _check_file(Path(static), "static")
    checked = [NewTrial(t.condition, _check_file(t.markers, "markers"),
                        t.angles and _check_file(t.angles, "angles"), t.grf and _check_file(t.grf, "grf"),
                        t.robot_log and _check_file(t.robot_log, "robot_log"))
               for t in trials]
    fit_on = checked[0].markers if static_auto else static
    markerset = markerset or fitting_markerset(read_markers(fit_on).names, fit_on, registry.markersets_dir)
    roles = load_markerset(markerset, registry.markersets_dir)
    markerset = _markerset_ref(markerset, registry)
    marker_files = [t.markers for t in checked] if static_auto else [static, *(t.markers for t in checked)]
    detected = up_axis == "auto"
    up_axis = _resolved_up_axis(marker_files, roles, up_axis)
    detected = detected and up_axis != "auto"

    manifest = Manifest.load(registry.manifest_path, mirror=registry.mirror)
    by_sha = {s.sha256: k for k, s in manifest.sources.items()}
    new: dict[str, Source] = {}
    tracked = registry.tracks_with_dvc
    key = lambda p: p and _manifest_key(p, manifest, by_sha, subject_id, new, tracked, origin)  # noqa: E731
    static_key = None if static_auto else key(static)
    specs, ids = [], set()
    for t in checked:
        trial_id, n = t.markers.stem, 1
        while trial_id in ids:
            n += 1
            trial_id = f"{t.markers.stem}_{n}"
        ids.add(trial_id)
        specs.append(TrialSpec(trial_id, t.condition, key(t.markers), key(t.angles), key(t.grf),
                               key(t.robot_log)))

    # Read every trial exactly as the pipeline will (files mapped to where they lie now).
    fmt = FileFormat(up_axis=up_axis, knee_flexion_sign=knee_flexion_sign)
    static_spec = StaticSpec(static_key or (STATIC_NONE if static_none else STATIC_AUTO))
    subject = Subject(subject_id, float(height_m), float(mass_kg), dataset or f"added:{subject_id}", roles,
                      fmt, static_spec, tuple(specs))
    paths = [*([] if static_auto else [static]),
             *(p for t in checked for p in (t.markers, t.angles, t.grf, t.robot_log) if p)]
    files = {key(p): p for p in paths}
    here = _FilesAsTheyLie({k: Source(k, p.as_uri(), sha256_of(p)) for k, p in files.items()}, files)
    for spec in specs:
        try:
            trial = load_trial(subject, spec, here)
            if trial.robot_log is not None:  # the log must cover the mocap
                robot_table(trial.robot_log, trial.time_s, subject_id, spec.condition, spec.id)
        except GaitloopError as exc:
            raise IngestError(files.get(spec.markers, spec.markers), f"cannot be ingested as subject "
                              f"{subject_id!r}: {getattr(exc, 'problem', exc)}") from None
    standing_check = params.section("ingest.static", StaticCheckParams)
    if static_none:
        static_doc, note = STATIC_NONE, "static: none: scaled from the walking trials (--static none).\n"
    elif static_auto:  # the standing before a walk, in the trials (its IK too, for the joint zeros)
        found = find_standing_window([t.markers for t in checked], subject, standing_check)
        chosen = next(i for i, t in enumerate(checked) if str(t.markers) == found.source)
        window = [round(found.t0_s, 3), round(found.t1_s, 3)]
        static_doc = {"markers": specs[chosen].markers, "window_s": window,
                      **({"angles": specs[chosen].angles} if specs[chosen].angles else {})}
        note = (f"static: quiet standing {found.t0_s:.2f}-{found.t1_s:.2f} s of {Path(found.source).name}, "
                "found by --static auto.\n")
    else:
        check_static(static, subject, None, standing_check)  # refuses a walk or jump given as static
        static_doc, note = {"markers": static_key}, ""

    doc = {
        "id": subject_id, "height_m": float(height_m), "mass_kg": float(mass_kg),
        "dataset": subject.dataset, "markerset": markerset,
        "format": {"up_axis": up_axis, "knee_flexion_sign": knee_flexion_sign},
        "static": static_doc,
        "trials": [{k: v for k, v in dataclasses.asdict(s).items() if v is not None} for s in specs],
        **({"round_trip_of": round_trip_of} if round_trip_of else {}),
    }
    params_text = _append_subject_to_params(registry.params_path.read_text(), subject_id,
                                            registry.params_path)
    transfer = policy and round_trip_of is None
    if transfer:
        params_text = _append_transfer_subject(params_text, subject_id, registry.params_path)
    parsed = parse_params(yaml.safe_load(params_text), registry.params_path)
    if subject_id not in parsed.subjects:
        raise SubjectError(registry.params_path, "could not add the subject to the 'subjects' list")
    if transfer and subject_id not in parsed.section("transfer", TransferSection).subjects:
        raise SubjectError(registry.params_path, "could not add the subject to 'transfer.subjects'")
    manifest_text = _manifest_with(registry.manifest_path, new, files) if new else None
    folder = dvc = None
    if new and tracked:  # last checks before writing: the DVC repository and a fresh raw folder
        folder, dvc = _check_dvc_target(registry, subject_id, manifest), _dvc_command()

    targets = [subj_file, registry.params_path, *([registry.manifest_path] if new else [])]
    try:
        if folder is not None:
            _track_with_dvc(registry, folder, files, new, dvc)
        with replacing(*targets) as temps:
            temps[0].write_text(f"# Registered by `python -m pipeline add-subject {subject_id}`.\n"
                                + (f"# up axis {up_axis.upper()} detected in all marker files (--up-axis "
                                   "auto).\n" if detected else "")
                                + (f"# {note}" if note else "") + yaml.safe_dump(doc, sort_keys=False))
            temps[1].write_text(params_text)
            if new:
                temps[2].write_text(manifest_text)
    except BaseException:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
        raise
    if folder is not None:
        rel = folder.relative_to(registry.root).as_posix()
        log.warning("add-subject %s: %d new raw file(s) tracked with DVC in %s/: commit its .dvc files "
                    "(and .gitignore, if any) with the subject file, params.yaml and data/sources.yaml, "
                    "then `dvc push`", subject_id, len(new), rel)
    return subj_file


def _manifest_with(path: Path, new: dict[str, Source], files: dict[str, Path]) -> str:
    """The manifest's text with `new` appended (comments kept), checked to read back as given."""
    entries = "".join(f"  {k}:\n    url: {s.url}\n" + (f"    path: {s.path}\n" if s.path else "")
                      + f"    sha256: {s.sha256}\n    bytes: {files[k].stat().st_size}\n"
                      for k, s in new.items())
    text = path.read_text()
    text += ("" if text.endswith("\n") else "\n") + entries
    try:
        listed = (yaml.safe_load(text) or {}).get("files") or {}
    except yaml.YAMLError as exc:
        raise SubjectError(path, f"the new manifest entries do not read back ({exc})") from None
    if any(not isinstance(listed.get(k), dict) or listed[k].get("url") != s.url
           or listed[k].get("path") != s.path for k, s in new.items()):
        raise SubjectError(path, "the new manifest entries do not read back as written (is 'files:' the "
                           "manifest's last block?)")
    return text


def _resolved_up_axis(paths: list[Path], roles: dict[str, str], up_axis: str) -> str:
    """`up_axis` as given, or for `auto` the axis detected in every marker file when they agree
    (errors name the file whose axis cannot be told); `auto` again when they do not."""
    if up_axis != "auto":
        return up_axis
    fmt = FileFormat(up_axis="auto")
    found = set()
    for path in paths:
        table = read_markers(path)
        found.add(resolve_up_axis(table.xyz_m, table.names, roles, fmt, str(path))[0])
    return found.pop() if len(found) == 1 else "auto"


@dataclass(frozen=True)
class _FilesAsTheyLie:
    """A manifest stand-in resolving keys to the files where they lie now (pre-registration check)."""

    sources: dict[str, Source]
    files: dict[str, Path]

    def resolve(self, key: str, verify: bool = True) -> Path:
        return self.files[key]

    def verify(self, key: str, path: Path) -> None:
        """Nothing to check: the sha256 of each file was just taken from the file itself."""
