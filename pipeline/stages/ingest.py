"""Stage `ingest <subject>`: a subject's raw trials -> events, strides and cycles tables, and the
processed trials themselves.

Outputs in `<out_root>/<subject>/real/`: `events.parquet`, `strides.parquet`, `cycles.parquet`
(columns in docs/data.md), `robot.parquet` (the robot logs of robot-assisted trials as robot tables,
`ingest.robot`; empty without), `trials.npz` (every processed trial: gap-filled, filtered markers and
angles, walk phases, provenance; `ingest.trial_file`) and `summary.json`, a small DVC metrics file,
written all-or-nothing. The stages that need a trial's signals read them back with `read_ingested`
instead of ingesting the raw recordings again.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ingest.errors import IngestError
from ingest.manifest import Manifest
from ingest.process import IngestParams, SubjectTables, process_subject
from ingest.subject import load_subject
from ingest.trial import SIDES
from ingest.trial_file import read_trials, write_trials
from pipeline.params import Params
from pipeline.paths import PROCESSED_ROOT, REAL_TRIALS, real_dir, real_trials
from pipeline.stages.outputs import write_outputs

TABLES = ("events", "strides", "cycles", "robot")


def summary(strides: pd.DataFrame, n_trials: int) -> dict:
    """Counts (strides rejected for mixing force-plate and kinematic heel strikes among them), and
    mean stride length and gait speed of the kept strides."""
    kept = strides[strides["kept"]]
    mixed = strides["reason"].astype(str).str.startswith("mixed event sources")
    return {
        "n_trials": n_trials,
        "n_strides": len(strides),
        "n_kept": {side: int((kept["side"] == side).sum()) for side in SIDES},
        "n_mixed_event_sources": int(mixed.sum()),
        "mean_stride_length_m": round(float(kept["stride_length_m"].mean()), 4),
        "mean_gait_speed_mps": round(float(kept["gait_speed_mps"].mean()), 4),
    }


def run_ingest(subject_id: str, params: Params, out_root: Path = PROCESSED_ROOT,
               progress: bool = True) -> Path:
    """Process every trial of `subject_id` and write the stage outputs; returns their folder."""
    subject = load_subject(subject_id)
    tables: SubjectTables = process_subject(subject, Manifest.load(), params.section("ingest", IngestParams),
                                            progress=progress)
    folder = real_dir(out_root, subject_id)
    write_outputs(folder, {name: getattr(tables, name) for name in TABLES},
                  {"summary": summary(tables.strides, len(subject.trials))},
                  others={REAL_TRIALS: lambda fh: write_trials(fh, tables.trials)})
    return folder


def read_ingested(subject_id: str, root: Path = PROCESSED_ROOT) -> SubjectTables:
    """The ingest stage's outputs of `subject_id` read back: its tables and its processed trials in
    the subject file's order. A missing output raises `IngestError` naming the file and the command
    that makes it."""
    folder = real_dir(root, subject_id)
    files = [folder / f"{name}.parquet" for name in TABLES] + [real_trials(root, subject_id)]
    for f in files:
        if not f.is_file():
            where = "" if Path(root) == PROCESSED_ROOT else f" --out-root {root}"
            raise IngestError(f, f"missing: run `python -m pipeline ingest {subject_id}{where}` first")
    tables = SubjectTables(*(pd.read_parquet(f) for f in files[:-1]))
    return SubjectTables(*(getattr(tables, name) for name in TABLES), read_trials(files[-1], tables))
