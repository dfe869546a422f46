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
from pydantic import TypeAdapter

from ingest.canonical import load_trial
from ingest.events import score_events, side_times
from ingest.manifest import Manifest
from ingest.process import IngestParams, process_trial
from ingest.readers import read_mot, read_trc
from ingest.subject import load_subject

ROOT = Path(__file__).resolve().parents[2]
WALKING_SPEED_MPS = 1.0  # forward walking: within 1 s of the pelvis moving faster than this


def _params(method: str) -> IngestParams:
    p = TypeAdapter(IngestParams).validate_python(
        yaml.safe_load((ROOT / "params.yaml").read_text())["ingest"])
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


# --- heel strikes at the start of a recording ----------------------------------------------------

START_S = 0.05  # "at the start": within the first 50 ms


def _cut(trial, t0: float, duration_s: float = 3.0):
    """The trial from `t0` for `duration_s`, markers and angles only (as if the recording began there)."""
    keep = (trial.time_s >= t0) & (trial.time_s < t0 + duration_s)
    return dataclasses.replace(trial, time_s=trial.time_s[keep], plates=None,
                               markers={k: v[keep] for k, v in trial.markers.items()},
                               angles={k: v[keep] for k, v in trial.angles.items()})


def _early_heel_strikes(trial, subject) -> list[tuple[str, float]]:
    events = process_trial(trial, subject.markerset, _params("kinematic")).events
    hs = events[(events["event"] == "heel_strike") & (events["time_s"] < trial.time_s[0] + START_S)]
    return [(s, t - trial.time_s[0]) for s, t in zip(hs["side"], hs["time_s"], strict=True)]


def test_recording_cut_mid_swing_gets_no_heel_strike_at_its_start():
    """Camargo cut at mid-swing of either foot (the other one then in mid-stance, loaded and flat):
    no foot lands in the first 50 ms, so no heel strike may be put there. The rule that put one on
    any foot starting behind its most anterior point gave the stance foot a strike at t ~ 0."""
    subject, manifest = load_subject("camargo"), Manifest.load()
    trial = load_trial(subject, subject.trials[0], manifest)
    truth = process_trial(trial, subject.markerset, _params("auto")).events
    cuts = []
    for side in ("left", "right"):
        toe_offs, strikes = (side_times(truth, side, e) for e in ("toe_off", "heel_strike"))
        for t in toe_offs[(toe_offs > 4.0) & (toe_offs < 11.5)]:
            later = strikes[strikes > t]
            if len(later) and later[0] - t < 0.6:  # a swing (not the turn's shuffle)
                cuts.append((side, (t + later[0]) / 2))
    assert len(cuts) >= 8
    for side, t0 in cuts:
        early = _early_heel_strikes(_cut(trial, t0), subject)
        assert not early, f"cut at {t0:.2f} s (mid-swing of the {side} foot): heel strikes {early}"


def test_recording_starting_at_a_heel_strike_keeps_it():
    """Camargo cut 5 ms before each force-plate heel strike: the landing is in the recording and is found."""
    subject, manifest = load_subject("camargo"), Manifest.load()
    trial = load_trial(subject, subject.trials[0], manifest)
    force = process_trial(trial, subject.markerset, _params("force")).events
    strikes = force[(force["event"] == "heel_strike") & (force["time_s"] > 3.5) & (force["time_s"] < 13.5)]
    assert len(strikes) >= 4
    for side, t in zip(strikes["side"], strikes["time_s"], strict=True):
        early = _early_heel_strikes(_cut(trial, t - 0.005), subject)
        assert [s for s, _ in early] == [side], f"cut at {t - 0.005:.3f} s: {early}"
        assert abs(early[0][1] - 0.005) <= 0.02


def _on_loaded_plate(trial, heel: str, t: float) -> bool:
    """A plate already loaded (> 20 N) at `t` with its centre of pressure within 0.15 m of the heel:
    the foot landed at (or just before) the recording's first sample, before a plate onset could show."""
    k = int(np.argmin(np.abs(trial.plates.time_s - t)))
    i = int(np.argmin(np.abs(trial.time_s - t)))
    dist = np.linalg.norm(trial.plates.cop_m[k, :, :2] - trial.markers[heel][i, :2], axis=1)
    return bool(((trial.plates.fz_n[k] > 20.0) & (dist < 0.15)).any())


def test_opencap_start_heel_strikes_are_plate_heel_strikes():
    """Each opencap4 walk is a force-plate window starting in double support: the leading foot has
    just landed (a true heel strike at t ~ 0) while the trailing heel is rising towards toe off (no
    heel strike). Every kinematic heel strike in a walk's first 50 ms must match a plate heel strike,
    or a plate already loaded under that heel at the first sample."""
    subject, manifest = load_subject("opencap4"), Manifest.load()
    heel = {s: subject.markerset[f"heel_{s}"] for s in ("left", "right")}
    pelvis = [subject.markerset[r] for r in ("asis_left", "asis_right", "psis_left", "psis_right")]
    n_early = 0
    for spec in subject.trials:
        trial = load_trial(subject, spec, manifest)
        truth = force_plate_heel_strikes(manifest.resolve(spec.grf), manifest.resolve(spec.markers), heel,
                                         pelvis)
        for side, dt in _early_heel_strikes(trial, subject):
            n_early += 1
            t = trial.time_s[0] + dt
            matched = any(s == side and abs(tt - t) <= 0.05 for s, tt in truth) or _on_loaded_plate(
                trial, subject.markerset[f"heel_{side}"], t)
            assert matched, f"{spec.id}: {side} heel strike at {dt:.3f} s without a plate heel strike"
    assert n_early >= 8  # the leading foot's landing is kept
