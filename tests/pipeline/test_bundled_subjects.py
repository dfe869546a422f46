"""The bundled example subjects beyond camargo and opencap4 (issue 12: every person in the shared data
with walking trials): lenhart2015 (one overground walk with force plates) and the two people of the
moissenet C3D files, each ingested from its real files into a temporary root and checked against
what the recordings say: heel strikes against the force plates, strides and speeds for the person's
height, a standing pose to scale from (static: none, nothing refused), replay-only (no policy)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from ingest.canonical import load_trial
from ingest.events import side_times
from ingest.manifest import Manifest
from ingest.process import process_trial
from ingest.readers import read_markers, read_mot
from ingest.static import read_static_trial
from ingest.subject import load_subject
from pipeline.cli import main
from pipeline.stages.ingest import run_ingest
from sim.body.scaling import scale_subject

# subject -> the person's declared height (m): moissenet's norm_description.xlsx, lenhart2015's an
# estimate from its markers (data README).
BUNDLED = {"lenhart2015": 1.65, "moissenet_np1023": 1.55, "moissenet_np1014": 1.645}
MOISSENET = "moissenet_GaitEventsAlgorithms_norm/NormSubjects/"
LENHART_GRF = "lenhart2015_opensim-jam/models/lenhart2015/motion_data/overground_17_grf.mot"


@pytest.fixture(scope="module")
def manifest() -> Manifest:
    return Manifest.load()


@pytest.fixture(scope="module")
def ingested(tmp_path_factory, params) -> dict[str, dict[str, pd.DataFrame]]:
    """Each bundled subject's `ingest` outputs, made by the stage in a temporary root."""
    root = tmp_path_factory.mktemp("processed")
    out = {}
    for sid in BUNDLED:
        folder = run_ingest(sid, params, root, progress=False)
        out[sid] = {name: pd.read_parquet(folder / f"{name}.parquet") for name in ("events", "strides")}
        out[sid]["summary"] = json.loads((folder / "summary.json").read_text())
    return out


@pytest.mark.parametrize("sid", BUNDLED)
def test_registered_with_public_origins(sid, params, manifest):
    subject = load_subject(sid)
    assert sid in params.subjects and subject.height_m == BUNDLED[sid]
    keys = [k for t in subject.trials for k in (t.markers, t.angles, t.grf) if k]
    assert keys and all(manifest.sources[k].url.startswith("https://raw.githubusercontent.com/")
                        for k in keys)


@pytest.mark.parametrize("sid", BUNDLED)
def test_heel_strikes_both_sides_in_every_trial(sid, ingested):
    events = ingested[sid]["events"]
    for trial in load_subject(sid).trials:
        ev = events[events["trial"] == trial.id]
        assert all(len(side_times(ev, side, "heel_strike")) >= 2 for side in ("left", "right"))


@pytest.mark.parametrize("sid", BUNDLED)
def test_strides_are_steady_walking_for_the_persons_height(sid, ingested):
    """Kept strides on both sides; length 0.7-1.0 x height (measured 0.80-0.84), 0.9-1.2 s, 0.9-1.6 m/s."""
    kept = ingested[sid]["strides"].query("kept")
    assert set(kept["side"]) == {"left", "right"}
    assert kept["stride_length_m"].between(0.7 * BUNDLED[sid], 1.0 * BUNDLED[sid]).all()
    assert kept["stride_time_s"].between(0.9, 1.2).all() and kept["gait_speed_mps"].between(0.9, 1.6).all()
    assert ingested[sid]["summary"]["n_strides"] >= 3


def _kinematic_vs(trial, subject, ingest_params, reference: pd.DataFrame) -> np.ndarray:
    """Kinematic event time minus the nearest reference event of the same side and kind (s)."""
    kinematic = dataclasses.replace(ingest_params.events, method="kinematic")
    p = dataclasses.replace(ingest_params, events=kinematic)
    kin = process_trial(trial, subject.markerset, p).events
    out = []
    for _, ref in reference.iterrows():
        t = side_times(kin, ref["side"], ref["event"])
        out.append(t[np.argmin(np.abs(t - ref["time_s"]))] - ref["time_s"])
    return np.array(out)


def test_lenhart2015_kinematic_events_match_its_force_plates(manifest, ingest_params, ingested):
    """Its GRF file (rows ending in a tab) gives 3 plate contacts, L-R-L, 1.39 body weights at the
    declared 62 kg; the auto events take them, and the kinematic ones lie within 25 ms (16 ms at most
    measured)."""
    grf = read_mot(manifest.resolve(LENHART_GRF))
    assert len(grf.table.columns) == 28 and len(grf.table) == 5150
    assert 840 < grf.table[[f"ground_force_{k}_vy" for k in (1, 2, 3)]].to_numpy().max() < 850
    subject = load_subject("lenhart2015")
    trial = load_trial(subject, subject.trials[0], manifest)
    events = ingested["lenhart2015"]["events"]
    force = events[events["method"] == "force"]
    strikes = force[force["event"] == "heel_strike"]
    assert len(force) == 6 and list(strikes["side"]) == ["left", "right", "left"]
    delta = _kinematic_vs(trial, subject, ingest_params, force)
    assert np.abs(delta).max() < 0.025


@pytest.mark.parametrize("sid", ["moissenet_np1023", "moissenet_np1014"])
def test_moissenet_kinematic_events_match_the_plate_marked_ones(sid, manifest, ingest_params):
    """The C3D's EVENT group holds the right foot's plate-measured strike and off (mFS, mFO): the
    kinematic events lie within 30 ms of them (24 ms at most measured)."""
    import ezc3d

    subject = load_subject(sid)
    for spec in subject.trials:
        path = manifest.resolve(spec.markers)
        event = ezc3d.c3d(str(path))["parameters"]["EVENT"]
        marked = pd.DataFrame({"side": [c.lower() for c in event["CONTEXTS"]["value"]],
                               "label": event["LABELS"]["value"], "time_s": event["TIMES"]["value"][1]})
        marked = marked[marked["label"].isin(["mFS", "mFO"])].assign(
            event=lambda d: d["label"].map({"mFS": "heel_strike", "mFO": "toe_off"}))
        assert len(marked) == 2
        delta = _kinematic_vs(load_trial(subject, spec, manifest), subject, ingest_params, marked)
        assert np.abs(delta).max() < 0.030


@pytest.mark.parametrize("sid", ["moissenet_np1023", "moissenet_np1014"])
def test_moissenet_c3d_points_are_markers_only(sid, manifest):
    """Plug-in Gait's outputs (angles, forces, moments, powers in LABELS and LABELS2, the centre of
    mass, segment axes such as RFOO/RFOA/RFOL/RFOP) and unlabelled `*n` trajectories are left out."""
    for spec in load_subject(sid).trials:
        names = set(read_markers(manifest.resolve(spec.markers)).names)
        assert {"LASI", "RPSI", "LKNE", "RANK", "LHEE", "RTOE", "SACR", "C7"} <= names
        assert not any(n.startswith("*") or n.endswith(("Angles", "Force", "Moment", "Power")) for n in names)
        assert not names & {"CentreOfMass", "CentreOfMassFloor", "RFOL", "RTIL", "PELO", "LFEO"}


@pytest.mark.parametrize("sid", BUNDLED)
def test_standing_pose_from_the_walks_scales_a_plausible_body(sid, manifest, params):
    """static: none is not refused; thighs and shanks 0.22-0.26 x height, left/right within 3 %."""
    subject = load_subject(sid)
    static = read_static_trial(subject, manifest, check=params.ingest.static.build())
    body = scale_subject(subject, static, params.human.build())
    lengths = body.segment_lengths_m
    for seg in ("thigh", "shank"):
        left, right = lengths[f"{seg}_l"], lengths[f"{seg}_r"]
        assert 0.22 < left / subject.height_m < 0.26 and 0.22 < right / subject.height_m < 0.26
        assert abs(left - right) / (left + right) * 2 < 0.03


def test_a_subject_without_a_policy_simulates_empty_policy_tables(tmp_path):
    """simulate --human policy (the simulate_policy stage) exits 0 and writes empty tables."""
    assert main(["simulate", "moissenet_np1014", "--human", "policy", "--root", str(tmp_path)]) == 0
    folder = tmp_path / "moissenet_np1014" / "sim_policy"
    assert json.loads((folder / "summary.json").read_text())["rollouts"] == 0
    assert pd.read_parquet(folder / "strides.parquet").empty
