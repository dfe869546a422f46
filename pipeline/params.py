"""params.yaml: every tunable number of gaitloop, read once per command here and passed down."""

from __future__ import annotations

from pathlib import Path

import yaml

from ingest.errors import GaitloopError
from ingest.process import IngestParams

REPO_ROOT = Path(__file__).resolve().parent.parent
PARAMS_FILE = REPO_ROOT / "params.yaml"


class ParamsError(GaitloopError):
    """A params file that is missing, not YAML, or lacks a section a stage needs."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        super().__init__(f"{self.path}: {problem}")


def load_params(path: str | Path = PARAMS_FILE) -> dict:
    """The whole params file as a dict; raises `ParamsError` naming the file when unusable."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ParamsError(path, f"cannot read params file ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise ParamsError(path, f"not valid YAML ({exc})") from None
    if not isinstance(doc, dict):
        raise ParamsError(path, "expected a mapping of sections (subjects, ingest, ...)")
    return doc


def ingest_params(params: dict, path: str | Path = PARAMS_FILE) -> IngestParams:
    """`IngestParams` from the `ingest` section of `params` (read from `path`, named in errors)."""
    section = params.get("ingest")
    if not isinstance(section, dict):
        raise ParamsError(path, "no 'ingest' section")
    try:
        return IngestParams.from_dict(section)
    except KeyError as exc:
        raise ParamsError(path, f"ingest section lacks key {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise ParamsError(path, f"invalid ingest section ({exc})") from None
