"""Kinematic heel strikes scored against force-plate heel strikes on the real recordings.

The force-plate truth is computed here, independently of ingest.events: vertical GRF above 20 N
for at least 0.2 s after an unloaded sample, assigned to the foot whose heel marker is nearest the
centre of pressure, read straight from the files in their own (Y-up) lab frame. Only heel strikes
of forward walking are scored: the Camargo subject side-steps into place during the first 1.7 s
(pelvis below 0.7 m/s, moving sideways), which is not gait.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ingest.canonical import load_trial
from ingest.events import score_events
from ingest.manifest import Manifest
from ingest.process import IngestParams, process_trial
from ingest.readers import read_mot, read_trc
from ingest.subject import load_subject

ROOT = Path(__file__).resolve().parents[2]
WALKING_SPEED_MPS = 1.0  # forward walking: within 1 s of the pelvis moving faster than this


def _params(method: str) -> IngestParams:
    p = IngestParams.from_dict(yaml.safe_load((ROOT / "params.yaml").read_text())["ingest"])
    return dataclasses.replace(p, events=dataclasses.replace(p.events, method=method))


def force_plate_heel_strikes(grf_path: Path, trc_path: Path, heel: dict[str, str],
                             pelvis: list[str]) -> list[tuple[str, float]]:
    grf, trc = read_mot(grf_path), read_trc(trc_path)
    t_grf, table = grf.time_s, grf.table
    names = list(trc.names)
    pelvis_xz = trc.xyz_m[:, [names.index(n) for n in pelvis]][..., [0, 2]]
    pelvis_xz = np.nanmean(pelvis_xz, axis=1)
    speed = np.full(len(trc.time_s), np.nan)
    lag = int(0.25 * trc.rate_hz)
    speed[lag:-lag] = np.linalg.norm(pelvis_xz[2 * lag:] - pelvis_xz[:-2 * lag], axis=1) / 0.5
    fast = trc.time_s[np.nan_to_num(speed) > WALKING_SPEED_MPS]
    truth = []
    plates = sorted({c[: -len("_vy")] for c in table.columns if c.endswith("_vy")})
    for plate in plates:
        loaded = table[f"{plate}_vy"].to_numpy() > 20.0
        onsets = np.flatnonzero(~loaded[:-1] & loaded[1:]) + 1
        for i in onsets:
            if loaded[i:i + int(0.2 / np.median(np.diff(t_grf)))].all():
                t = t_grf[i]
                if not len(fast) or not fast[0] - 1.0 <= t <= fast[-1] + 1.0:
                    continue
                k = int(np.argmin(np.abs(trc.time_s - t)))
                cop = table[[f"{plate}_px", f"{plate}_pz"]].to_numpy()[i + 2]
                dist = {s: np.linalg.norm(trc.xyz_m[k, names.index(m)][[0, 2]] - cop)
                        for s, m in heel.items()}
                truth.append((min(dist, key=dist.get), float(t)))
    return truth


def _score(subject_id: str):
    subject, manifest = load_subject(subject_id), Manifest.load()
    heel = {s: subject.markerset[f"heel_{s}"] for s in ("left", "right")}
    pelvis = [subject.markerset[r] for r in ("asis_left", "asis_right", "psis_left", "psis_right")]
    errors, n_truth = [], 0
    for spec in subject.trials:
        truth = force_plate_heel_strikes(manifest.resolve(spec.grf), manifest.resolve(spec.markers),
                                         heel, pelvis)
        events = process_trial(load_trial(subject, spec, manifest), subject.markerset,
                               _params("kinematic")).events
        assert set(events["method"]) == {"kinematic"}
        for side, t in truth:  # noqa: B007 (used by query via @side)
            n_truth += 1
            det = events.query("side == @side and event == 'heel_strike'")["time_s"].to_numpy()
            if len(det) and np.min(np.abs(det - t)) <= 0.1:
                errors.append(det[np.argmin(np.abs(det - t))] - t)
    return np.array(errors), n_truth


@pytest.mark.parametrize("subject_id", ["camargo", "opencap4"])
def test_kinematic_heel_strikes_match_force_plates(subject_id):
    errors, n_truth = _score(subject_id)
    assert n_truth >= (6 if subject_id == "camargo" else 24)
    assert len(errors) / n_truth >= 0.8
    assert np.median(np.abs(errors)) <= 0.020


def test_score_events_agrees_with_own_truth_on_camargo():
    """The library's own force-plate events, scored with the library scorer, tell the same story."""
    subject, manifest = load_subject("camargo"), Manifest.load()
    trial = load_trial(subject, subject.trials[0], manifest)
    kin = process_trial(trial, subject.markerset, _params("kinematic")).events
    force = process_trial(trial, subject.markerset, _params("force")).events
    assert set(force["method"]) == {"force"}
    walking = force[(force["time_s"] > 3.5) & (force["time_s"] < 13.5)]
    score = score_events(kin, walking)
    assert score.n_truth == 6 and score.matched_fraction == 1.0
    assert score.median_abs_error_s <= 0.020
    toe_off = score_events(kin, walking, "toe_off")
    assert toe_off.matched_fraction >= 0.8 and toe_off.median_abs_error_s <= 0.020


def test_auto_uses_plates_where_they_see_the_foot():
    subject, manifest = load_subject("opencap4"), Manifest.load()
    trial = load_trial(subject, subject.trials[0], manifest)
    events = process_trial(trial, subject.markerset, _params("auto")).events
    assert {"force"} <= set(events["method"])
    assert events["time_s"].is_monotonic_increasing
