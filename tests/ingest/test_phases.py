"""Walk phases read from the pelvis motion, on Camargo's level-ground circuit: it stands until
about 3.8 s, starts, turns 180 deg and stops (Camargo et al. 2021; times read off its recording)."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from pydantic import TypeAdapter

from ingest.canonical import load_trial
from ingest.manifest import Manifest
from ingest.phases import PhaseParams, motion_phases
from ingest.process import IngestParams, walk_phases
from ingest.subject import load_subject

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def camargo_phases():
    p = TypeAdapter(IngestParams).validate_python(
        yaml.safe_load((ROOT / "params.yaml").read_text())["ingest"])
    subject = load_subject("camargo")
    trial = load_trial(subject, subject.trials[0], Manifest.load())
    return trial.time_s, walk_phases(trial, subject.markerset, p)


def spans(time_s, phase):
    change = np.flatnonzero(phase[1:] != phase[:-1]) + 1
    starts, ends = np.r_[0, change], np.r_[change, len(phase)] - 1
    return [(str(phase[a]), float(time_s[a]), float(time_s[b])) for a, b in zip(starts, ends, strict=True)]


def test_camargo_circuit_phases(camargo_phases):
    time_s, phase = camargo_phases
    s = spans(time_s, phase)
    standing = [x for x in s if x[0] == "standing" and x[2] - x[1] > 1.0]
    assert len(standing) == 2  # quiet standing before the walk and after it
    assert 3.4 < standing[0][2] < 4.2  # gait initiation at ~3.8 s
    start = next(x for x in s if x[0] == "start" and x[1] > standing[0][1])
    assert abs(start[1] - standing[0][2]) < 0.05 and 0.8 < start[2] - start[1] < 2.5
    turns = [x for x in s if x[0] == "turn" and standing[0][2] < x[1] < standing[1][1]]
    assert sum(e - b for _, b, e in turns) > 1.5  # the 180 deg turn of the circuit
    stop = [x for x in s if x[0] == "stop" and x[2] <= standing[1][1] + 0.05][-1]
    assert 0.5 < stop[2] - stop[1] < 2.0  # stops within ~1.4 s
    steady = sum(e - b for ph, b, e in s if ph == "steady" and standing[0][2] < b < standing[1][1])
    assert steady > 2.0


def test_synthetic_path_phases():
    """A path that stands 2 s, ramps to 1.5 m/s over 1.5 s, walks, turns 90 deg at 60 deg/s, walks
    and stops: each phase is found where it was made."""
    from ingest.bouts import PelvisPath

    rate = 100.0
    t = np.arange(0, 14, 1 / rate)
    speed = np.interp(t, [0, 2, 3.5, 12, 13.2, 14], [0, 0, 1.5, 1.5, 0, 0])
    heading = np.interp(t, [0, 6, 7.5, 14], [0, 0, np.pi / 2, np.pi / 2])
    path = PelvisPath(np.zeros((len(t), 2)), speed, heading, np.degrees(np.gradient(heading, 1 / rate)),
                      speed > 0.3, np.zeros(len(t), bool))
    phase = motion_phases(path, rate, PhaseParams())
    at = {ph: phase[int(time * rate)] for ph, time in (("standing", 1.0), ("start", 2.5), ("steady", 4.5),
                                                       ("turn", 6.7), ("stop", 12.9))}
    assert all(at[ph] == ph for ph in at), at
