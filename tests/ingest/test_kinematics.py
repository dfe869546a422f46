"""Sagittal angles computed from markers agree with the OpenSim IK angles of the same trials,
so trials that come without joint coordinates (and simulated ones) get comparable cycles."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from pydantic import TypeAdapter

from ingest.canonical import load_trial
from ingest.kinematics import marker_angles
from ingest.manifest import Manifest
from ingest.process import IngestParams, clean_markers, landmarks, process_trial, trial_path
from ingest.subject import load_subject

ROOT = Path(__file__).resolve().parents[2]
PARAMS = TypeAdapter(IngestParams).validate_python(
    yaml.safe_load((ROOT / "params.yaml").read_text())["ingest"])


@pytest.mark.parametrize("subject_id", ["camargo", "opencap4"])
def test_marker_angles_track_ik_angles(subject_id):
    subject = load_subject(subject_id)
    trial = clean_markers(load_trial(subject, subject.trials[0], Manifest.load()),
                          subject.markerset, PARAMS)
    lm = landmarks(trial, subject.markerset)
    path = trial_path(lm, trial.rate_hz, PARAMS)
    ours = marker_angles(lm, path.heading_rad)
    walking = path.walking
    for side in ("left", "right"):
        for joint, min_r in (("hip_flexion", 0.98), ("knee_flexion", 0.98),
                             ("ankle_dorsiflexion", 0.9)):
            x, y = ours[f"{joint}_{side}"][walking], trial.angles[f"{joint}_{side}"][walking]
            assert np.corrcoef(x, y)[0, 1] > min_r, (joint, side)
            assert np.std(x - y) < 4.0, (joint, side)
        assert abs(np.mean(ours[f"knee_flexion_{side}"][walking]
                           - trial.angles[f"knee_flexion_{side}"][walking])) < 5.0


def test_trial_without_ik_gets_cycles_from_markers():
    subject = load_subject("camargo")
    trial = load_trial(subject, subject.trials[0], Manifest.load()).with_(angles={})
    cycles = process_trial(trial, subject.markerset, PARAMS).cycles
    knee = cycles.query("joint == 'knee_flexion'").groupby(["side", "stride"])["angle_deg"].max()
    assert len(knee) >= 8
    assert knee.between(50, 80).all()
