"""A subject's processed trials as one file, written once by ingest and read by every stage that
needs a trial's signals, so no stage re-ingests a raw recording.

The file is a compressed `.npz` (no pickles). For the k-th trial, in the subject file's order:

- `<k>/time_s` (n,), `<k>/markers` (m, n, 3) in metres, `<k>/angles` (a, n) in degrees: the
  gap-filled, filtered canonical trial (`ProcessedTrial.trial`; a treadmill trial's overground
  equivalent), float64 as ingest made it;
- `<k>/phases` (n,): its walk phase labels (`ProcessedTrial.phases`);
- `<k>/file_time_s/<kind>`: the time column of each file it was read from (`Trial.file_time_s`);

and `meta`, one JSON text: the format version and per trial its identity (subject, source,
condition, trial), `rate_hz`, the marker and angle names in the order of the arrays, the kinds of
its file time columns, its provenance and its treadmill recognition (`ingest.treadmill.Treadmill`, or
null). A source file is named by its manifest key, not by its path on this machine, so that every
clone writes the same bytes (DVC compares their hashes); read back, its `Provenance.file` is the key.

A trial's events, strides, cycles and robot rows are not repeated here: they are the subject's
stacked tables (`SubjectTables`), which `trials_from_arrays` splits by trial. Force plates, a robot
log and robot markers are not kept either: ingest has turned them into the events and robot tables.
`trial_arrays` and `trials_from_arrays` are pure; `write_trials` and `read_trials` do the I/O.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import BinaryIO

import numpy as np
import pandas as pd

from ingest.errors import IngestError
from ingest.process import ProcessedTrial, SubjectTables
from ingest.treadmill import Treadmill, TreadmillCheck
from ingest.trial import Provenance, Trial

FORMAT = 1
TABLES = ("events", "strides", "cycles", "robot")


def trial_arrays(trials: Sequence[ProcessedTrial]) -> dict[str, np.ndarray]:
    """The arrays of the file (module docstring) for `trials`, in their order."""
    out: dict[str, np.ndarray] = {}
    meta = []
    for k, pt in enumerate(trials):
        t = pt.trial
        n = t.n_frames
        out[f"{k}/time_s"] = np.asarray(t.time_s, float)
        out[f"{k}/markers"] = (np.stack([t.markers[m] for m in t.markers]) if t.markers
                               else np.empty((0, n, 3)))
        out[f"{k}/angles"] = np.stack([t.angles[a] for a in t.angles]) if t.angles else np.empty((0, n))
        out[f"{k}/phases"] = np.asarray(pt.phases if pt.phases is not None else np.full(n, ""), str)
        out |= {f"{k}/file_time_s/{kind}": np.asarray(x, float) for kind, x in t.file_time_s.items()}
        meta.append({"subject": t.subject, "source": t.source, "condition": t.condition, "trial": t.trial,
                     "rate_hz": float(t.rate_hz), "markers": list(t.markers), "angles": list(t.angles),
                     "file_time_s": list(t.file_time_s),
                     "provenance": [[p.key or p.file, p.sha256, p.reader, p.key] for p in t.provenance],
                     "treadmill": None if pt.treadmill is None else asdict(pt.treadmill)})
    out["meta"] = np.array(json.dumps({"format": FORMAT, "trials": meta}, default=_plain))
    return out


def _plain(x: object) -> object:
    """JSON of the numpy scalars a `Treadmill` may hold."""
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


def _rows(table: pd.DataFrame, trial: str) -> pd.DataFrame:
    return table[table["trial"] == trial].reset_index(drop=True) if len(table) else table


def trials_from_arrays(arrays: Mapping[str, np.ndarray], tables: SubjectTables,
                       origin: str | Path = "processed trials") -> tuple[ProcessedTrial, ...]:
    """The processed trials of the file's `arrays`, each with its rows of the subject's `tables`
    (`origin`: the file, for errors)."""
    meta = json.loads(str(arrays["meta"]))
    if meta.get("format") != FORMAT:
        raise IngestError(origin, f"processed trials of format {meta.get('format')}, expected {FORMAT}: "
                                  "ingest the subject again")
    out = []
    for k, m in enumerate(meta["trials"]):
        markers, angles = arrays[f"{k}/markers"], arrays[f"{k}/angles"]
        trial = Trial(subject=m["subject"], condition=m["condition"], source=m["source"], trial=m["trial"],
                      rate_hz=m["rate_hz"], time_s=arrays[f"{k}/time_s"],
                      markers={name: markers[j] for j, name in enumerate(m["markers"])},
                      angles={name: angles[j] for j, name in enumerate(m["angles"])},
                      provenance=tuple(Provenance(*p) for p in m["provenance"]),
                      file_time_s={kind: arrays[f"{k}/file_time_s/{kind}"] for kind in m["file_time_s"]})
        tm = m["treadmill"]
        treadmill = None if tm is None else Treadmill(**(tm | {"check": TreadmillCheck(**tm["check"])}))
        rows = {name: _rows(getattr(tables, name), trial.trial) for name in TABLES}
        out.append(ProcessedTrial(trial, rows["events"], rows["strides"], rows["cycles"], rows["robot"],
                                  treadmill, arrays[f"{k}/phases"]))
    return tuple(out)


def write_trials(fh: BinaryIO, trials: Sequence[ProcessedTrial]) -> None:
    """`trials` as one compressed `.npz` into the open binary file `fh`."""
    np.savez_compressed(fh, **trial_arrays(trials))


def read_trials(path: Path, tables: SubjectTables) -> tuple[ProcessedTrial, ...]:
    """The processed trials of the file at `path`, with their rows of the subject's `tables`."""
    if not path.is_file():
        raise IngestError(path, "no processed trials here: ingest the subject first")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
        return trials_from_arrays(arrays, tables, path)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise IngestError(path, f"cannot read processed trials ({exc!r}): ingest the subject again") from None


__all__ = ["read_trials", "trial_arrays", "trials_from_arrays", "write_trials"]
