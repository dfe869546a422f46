"""Treadmill walking (ingest/treadmill.py): a real overground walk made into a treadmill walk gives the
same heel strikes and stride lengths, declared or detected; real overground trials are not taken for
treadmill walking; the real treadmill trial of kgc6 DM processes into kept strides.

The treadmill copy of a Camargo straight walk subtracts its mean forward pelvis velocity (along the
pelvis facing) from every marker: the pelvis then hardly travels while the feet step back and forth,
as on a belt at that speed. The issue's numbers: heel strikes within 10 ms, stride lengths within 2 %.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ingest.canonical import load_trial
from ingest.errors import SubjectError
from ingest.events import side_times
from ingest.manifest import Manifest, Source, sha256_of
from ingest.process import PELVIS_ROLES, process_trial
from ingest.subject import FileFormat, Subject, TrialSpec, load_markerset, load_subject
from ingest.trial import Trial

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data"
KGC6_TREADMILL = ("kgc6_DM_jam-resources/models/knee_tka/grand_challenge/DM/experimental_data/"
                  "motion_analysis/DM_ngait_tm_ss1_new.trc")
# Camargo's two straight walks (s): out (with its start) and back (with its stop), turn excluded.
WINDOWS = [(3.6, 8.0), (9.0, 13.0)]


@pytest.fixture(scope="module")
def camargo():
    subject = load_subject("camargo")
    trial = load_trial(subject, subject.trials[0], Manifest.load()).with_(plates=None)  # kinematic events
    return subject, trial


def _crop(trial: Trial, t0: float, t1: float) -> Trial:
    keep = (trial.time_s >= t0) & (trial.time_s <= t1)
    return trial.with_(time_s=trial.time_s[keep], markers={n: x[keep] for n, x in trial.markers.items()},
                       angles={n: x[keep] for n, x in trial.angles.items()})


def _on_treadmill(trial: Trial, markerset: dict[str, str]) -> tuple[Trial, float]:
    """The trial with its mean forward pelvis velocity (along the pelvis facing) taken from every
    marker, and that speed: a belt at that speed."""
    m = {r: trial.markers[markerset[r]] for r in PELVIS_ROLES}
    facing = np.nanmean((m["asis_left"] + m["asis_right"] - m["psis_left"] - m["psis_right"])[:, :2], axis=0)
    facing /= np.linalg.norm(facing)
    pelvis = np.mean([m[r] for r in PELVIS_ROLES], axis=0)
    speed = float(np.nanmean(np.gradient(pelvis[:, :2], trial.time_s, axis=0) @ facing))
    belt = np.zeros((trial.n_frames, 3))
    belt[:, :2] = speed * (trial.time_s - trial.time_s[0])[:, None] * facing
    return trial.with_(markers={n: x - belt for n, x in trial.markers.items()}), speed


@pytest.mark.parametrize("declared", [True, False], ids=["declared", "detected"])
@pytest.mark.parametrize("window", WINDOWS, ids=["out", "back"])
def test_treadmill_copy_matches_overground(camargo, ingest_params, window, declared):
    subject, trial = camargo
    overground = _crop(trial, *window)
    treadmill, speed = _on_treadmill(overground, subject.markerset)
    og = process_trial(overground, subject.markerset, ingest_params)
    tm = process_trial(treadmill, subject.markerset, ingest_params, treadmill=True if declared else None,
                       belt_speed_mps=speed if declared else None)
    assert og.treadmill is None
    assert tm.treadmill is not None and tm.treadmill.declared is declared
    assert tm.treadmill.belt_speed_mps == pytest.approx(speed, rel=0.02)
    assert "treadmill" in tm.trial.provenance[-1].reader
    for side in ("left", "right"):
        hs = [side_times(r.events, side, "heel_strike") for r in (og, tm)]
        assert len(hs[0]) == len(hs[1]) >= 3
        assert np.abs(hs[0] - hs[1]).max() <= 0.010
    kept = og.strides[og.strides["kept"]]
    assert len(kept) >= 4
    both = kept.merge(tm.strides, on=["side", "stride"], suffixes=("_og", "_tm"))
    assert both["kept_tm"].all()
    error = (both["stride_length_m_tm"] / both["stride_length_m_og"] - 1).abs()
    assert error.max() < 0.02


def test_overground_trials_are_not_treadmill(ingest_params):
    manifest = Manifest.load()
    for subject_id in ("camargo", "opencap4"):
        subject = load_subject(subject_id)
        for spec in subject.trials[:3]:
            result = process_trial(load_trial(subject, spec, manifest), subject.markerset, ingest_params)
            assert result.treadmill is None, spec.id


def test_real_treadmill_trial_gives_kept_strides(ingest_params):
    path = DATA / KGC6_TREADMILL
    if not path.is_file():
        pytest.skip(f"{path} is not in the shared data")
    subject = Subject(id="kgc6_dm", height_m=1.72, mass_kg=70.0, dataset="kgc6_DM_jam-resources",
                      markerset=load_markerset("kgc6"), format=FileFormat(up_axis="y"), static=None)
    spec = TrialSpec(id="tm_ss1", condition="free", markers=KGC6_TREADMILL)
    manifest = Manifest({KGC6_TREADMILL: Source(KGC6_TREADMILL, path.as_uri(), sha256_of(path))}, DATA,
                        ROOT / "data" / "raw")
    trial = load_trial(dataclasses.replace(subject, trials=(spec,)), spec, manifest)
    result = process_trial(trial, subject.markerset, ingest_params)
    assert result.treadmill is not None and not result.treadmill.declared
    assert 1.1 < result.treadmill.belt_speed_mps < 1.3  # the belt at ~1.2 m/s (stance foot plateau)
    kept = result.strides[result.strides["kept"]]
    assert len(kept) >= 20  # 17.5 s, ~15-17 steps per belt
    assert kept["stride_time_s"].between(1.0, 1.5).all()
    assert kept["gait_speed_mps"].between(1.0, 1.4).all()


def test_subject_file_declares_treadmill(tmp_path):
    doc = {"id": "tm", "height_m": 1.72, "mass_kg": 70.0, "dataset": "x", "markerset": "kgc6",
           "format": {"up_axis": "y"}, "treadmill": True,
           "trials": [{"id": "a", "condition": "free", "markers": "a.trc", "belt_speed_mps": 1.2},
                      {"id": "b", "condition": "free", "markers": "b.trc", "treadmill": False}]}
    (tmp_path / "tm.yaml").write_text(yaml.safe_dump(doc))
    a, b = load_subject("tm", tmp_path).trials
    assert (a.treadmill, a.belt_speed_mps, b.treadmill, b.belt_speed_mps) == (True, 1.2, False, None)
    doc["trials"][1]["belt_speed_mps"] = 1.0
    (tmp_path / "tm.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(SubjectError, match="treadmill: false"):
        load_subject("tm", tmp_path)
    doc["trials"][1] = {"id": "b", "condition": "free", "markers": "b.trc", "belt_speed_mps": -1}
    (tmp_path / "tm.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(SubjectError, match="belt_speed_mps"):
        load_subject("tm", tmp_path)
