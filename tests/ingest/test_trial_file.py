"""The processed trials' file (ingest/trial_file.py): real opencap4 walks, processed, written and read
back with their rows of the subject's tables (themselves through parquet, as the ingest stage writes
them), give the same trials: every marker and angle bit for bit and in the same order, the walk phases,
identity, rate, provenance, the files' time columns and treadmill recognition, and each trial's events and
strides."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ingest.canonical import load_trial
from ingest.errors import IngestError
from ingest.manifest import Manifest
from ingest.process import ProcessedTrial, SubjectTables, process_trial
from ingest.subject import load_subject
from ingest.treadmill import Treadmill, TreadmillCheck
from ingest.trial import Provenance
from ingest.trial_file import TABLES, read_trials, trial_arrays, write_trials

N_TRIALS = 3  # opencap4's first walks: 1.3-1.45 s each, 51 markers and the IK angles


@pytest.fixture(scope="module")
def processed(ingest_params) -> tuple[ProcessedTrial, ...]:
    subject = load_subject("opencap4")
    manifest = Manifest.load()
    return tuple(process_trial(load_trial(subject, spec, manifest), subject.markerset, ingest_params)
                 for spec in subject.trials[:N_TRIALS])


def _through_parquet(trials: tuple[ProcessedTrial, ...], folder) -> SubjectTables:
    """The subject's stacked tables written and read as the ingest stage does."""
    out = []
    for name in TABLES:
        path = folder / f"{name}.parquet"
        pd.concat([getattr(t, name) for t in trials], ignore_index=True).to_parquet(path, index=False)
        out.append(pd.read_parquet(path))
    return SubjectTables(*out)


def _written(trials, path) -> None:
    with open(path, "wb") as fh:
        write_trials(fh, trials)


def test_processed_trials_round_trip(processed, tmp_path):
    path = tmp_path / "trials.npz"
    _written(processed, path)
    mirror = str(Manifest.load().mirror)  # where this machine read the files from
    assert mirror in processed[0].trial.provenance[0].file
    assert mirror not in str(trial_arrays(processed)["meta"])
    back = read_trials(path, _through_parquet(processed, tmp_path))
    assert [b.trial.trial for b in back] == [p.trial.trial for p in processed]
    for p, b in zip(processed, back, strict=True):
        for f in ("subject", "source", "condition", "trial", "rate_hz"):
            assert getattr(b.trial, f) == getattr(p.trial, f), f
        # the files by their manifest keys: no path of this machine, the same bytes in every clone
        keyed = tuple(Provenance(q.key, q.sha256, q.reader, q.key) for q in p.trial.provenance)
        assert b.trial.provenance == keyed
        assert all(q.key and not Path(q.key).is_absolute() for q in p.trial.provenance)
        assert b.treadmill is None and p.treadmill is None
        assert np.array_equal(b.trial.time_s, p.trial.time_s)
        assert list(b.trial.file_time_s) == list(p.trial.file_time_s) == ["markers", "angles", "grf"]
        for kind, t in p.trial.file_time_s.items():
            assert np.array_equal(b.trial.file_time_s[kind], t), kind
        for kind in ("markers", "angles"):
            got, want = getattr(b.trial, kind), getattr(p.trial, kind)
            assert list(got) == list(want) and len(want) > 10, kind  # names and their order
            for name, x in want.items():
                assert got[name].dtype == np.float64 and np.array_equal(got[name], x, equal_nan=True), name
        assert p.phases is not None and len(p.phases) == p.trial.n_frames
        assert list(b.phases) == list(p.phases)
        for name in ("events", "strides"):
            want = getattr(p, name).reset_index(drop=True)
            assert len(want) > 0
            pd.testing.assert_frame_equal(getattr(b, name), want, check_dtype=False)
        assert len(b.cycles) == len(p.cycles) and b.robot.empty


def test_treadmill_recognition_round_trips(processed, tmp_path):
    """A treadmill trial's recognition (numpy scalars, as detection makes them) comes back equal."""
    check = TreadmillCheck(np.float64(0.05), np.float64(0.6), np.float64(1.2), np.float64(0.3))
    found = Treadmill(False, np.float64(1.19), False, np.float64(0.3), check)
    one = dataclasses.replace(processed[0], treadmill=found)
    path = tmp_path / "trials.npz"
    _written((one,), path)
    (back,) = read_trials(path, _through_parquet((one,), tmp_path))
    assert back.treadmill == found


def test_a_missing_older_or_broken_file_names_itself(processed, tmp_path):
    tables = _through_parquet(processed[:1], tmp_path)
    with pytest.raises(IngestError, match=r"trials\.npz: no processed trials here: ingest the subject first"):
        read_trials(tmp_path / "trials.npz", tables)
    arrays = trial_arrays(processed[:1])
    arrays["meta"] = np.array(str(arrays["meta"]).replace('"format": 1', '"format": 0'))
    np.savez_compressed(tmp_path / "old.npz", **arrays)
    with pytest.raises(IngestError, match=r"old\.npz: processed trials of format 0, expected 1"):
        read_trials(tmp_path / "old.npz", tables)
    (tmp_path / "broken.npz").write_bytes(b"not a zip")
    with pytest.raises(IngestError, match=r"broken\.npz: cannot read processed trials .*ingest the subject"):
        read_trials(tmp_path / "broken.npz", tables)
