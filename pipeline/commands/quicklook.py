"""Command `events <file>`: gait events of one marker file read directly, without the manifest.

The files are wrapped in a one-trial subject and a manifest that maps each file to itself (its
sha256 taken on the spot), then read by `ingest.canonical.load_trial`: the same readers, axis
conversion, heading rotation and body-scale checks as the pipeline.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pandas as pd

from ingest.canonical import load_trial
from ingest.errors import IngestError, SubjectError
from ingest.manifest import Manifest, Source, sha256_of
from ingest.markersets import pick_markerset
from ingest.readers import read_markers
from ingest.subject import MARKERSETS_DIR, FileFormat, Subject, TrialSpec, load_markerset, load_subject
from ingest.trial import Trial

EVENT_OUTPUT_COLUMNS = ["side", "event", "time_s"]


def fitting_markerset(names: tuple[str, ...], path: Path, directory: Path = MARKERSETS_DIR) -> str:
    """Name of the shipped marker set in `directory` that fits a file holding markers `names`: every
    role covered (directly or derived), the fewest derived roles (`ingest.markersets.pick_markerset`);
    `IngestError` naming the file, with the closest sets' missing roles, when none fits."""
    try:
        return pick_markerset(names, path, directory)
    except SubjectError as exc:
        raise IngestError(path, f"{exc.problem}; or pass --subject") from None


def quicklook_subject(path: Path, subject_id: str | None, up_axis: str | None,
                      markerset: str | None) -> Subject:
    """The subject whose file format and marker set apply to `path`: the registered one when
    `subject_id` is given, else a stand-in (no body size) with up axis `up_axis` (default auto: detected
    as a subject file's `auto`, `ingest.canonical.detect_up_axis`) and the marker set `markerset` or
    the one that fits the file; `up_axis` and `markerset` override."""
    if subject_id:
        subject = load_subject(subject_id)
    else:
        subject = Subject(id="unknown", height_m=math.nan, mass_kg=math.nan, dataset="file",
                          markerset={}, format=FileFormat(up_axis="auto"), static=None)
        markerset = markerset or fitting_markerset(read_markers(path).names, path)
    if up_axis:
        subject = dataclasses.replace(subject, format=dataclasses.replace(subject.format, up_axis=up_axis))
    if markerset:
        subject = dataclasses.replace(subject, markerset=load_markerset(markerset))
    return subject


def file_trial(markers: Path, grf: Path | None, subject: Subject) -> Trial:
    """Canonical Trial of `markers` (.trc/.c3d/.csv) and an optional OpenSim GRF `.mot` file."""
    files = [p.resolve() for p in (markers, grf) if p is not None]
    for path in files:
        if not path.is_file():
            raise IngestError(path, "file not found")
    keys = [str(p.relative_to(p.anchor)) for p in files]
    manifest = Manifest({k: Source(k, p.as_uri(), sha256_of(p)) for k, p in zip(keys, files, strict=True)},
                        mirror=Path(files[0].anchor), cache=files[0].parent)
    spec = TrialSpec(id=markers.stem, condition="free", markers=keys[0],
                     grf=keys[1] if grf is not None else None)
    return load_trial(dataclasses.replace(subject, trials=(spec,)), spec, manifest)


def format_events(events: pd.DataFrame, fmt: str) -> str:
    """`side,event,time_s` rows as csv, an aligned table or a JSON list of records."""
    out = events[EVENT_OUTPUT_COLUMNS].assign(time_s=events["time_s"].round(4))
    if fmt == "csv":
        return out.to_csv(index=False, float_format="%.4f").rstrip("\n")
    if fmt == "table":
        return out.to_string(index=False, float_format="%.4f")
    if fmt == "json":
        return json.dumps(out.to_dict(orient="records"), indent=2)
    raise ValueError(f"unknown format {fmt!r} (csv | table | json)")
