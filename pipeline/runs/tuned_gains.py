"""The tuned-gains file (data/tuning/controllers.yaml, `paths.TUNED_GAINS`, committed): the follow-me
controllers' searched gains, controller name -> {gain: value}, written by `tune-controllers` and read on
top of params.yaml `robot.controllers.<name>.gains` (a gain is set in one of them, never both). Reading
it here imports no simulation code, so that the metrics stage can hash the gains (`tuned_document`);
`pipeline.runs.setup.controller_specs` merges and checks them against each class's declared gains."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from pipeline.params import Params, ParamsError


def read_tuned(path: str | Path) -> dict[str, dict[str, Any]]:
    """The tuned-gains file: controller name -> {gain: value}; {} when there is none. `ParamsError`
    naming the file when it is not YAML or not that shape (the values are checked by the merge)."""
    path = Path(path)
    if not path.is_file():
        return {}
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ParamsError(path, f"not valid YAML ({exc})") from None
    doc = {} if doc is None else doc
    if not isinstance(doc, dict) or not all(isinstance(v, dict) for v in doc.values()):
        raise ParamsError(path, "expected controller name -> {gain: value}")
    return {str(name): dict(gains) for name, gains in doc.items()}


def write_tuned(path: str | Path, tuned: Mapping[str, Mapping[str, float]], header: str = "") -> None:
    """Write the tuned-gains file (one flow mapping per controller, a `# ` comment header)."""
    lines = [f"# {ln}" if ln else "#" for ln in header.splitlines()]
    for name, gains in tuned.items():
        lines.append(f"{name}: {{{', '.join(f'{k}: {float(v)!r}' for k, v in gains.items())}}}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def tuned_document(params: Params) -> dict[str, Any]:
    """The params.yaml document (a copy) with the tuned-gains file's gains (`params.tuned_file`) on top
    of `robot.controllers.<name>.gains`: what a run's controllers get, unchecked (`check-params` and
    `pipeline.runs.setup.controller_specs` check it); a tuned controller the document lacks is left out."""
    document = params.document()
    controllers = document.get("robot", {}).get("controllers", {})
    for name, gains in read_tuned(params.tuned_file).items():
        if isinstance(controllers.get(name), dict):
            controllers[name]["gains"] = {**controllers[name].get("gains", {}), **gains}
    return document


__all__ = ["read_tuned", "tuned_document", "write_tuned"]
