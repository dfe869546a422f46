"""Simulated trials out as OpenSim files, and back in as a recorded subject with robot logs.

camargo's walk_10m trials (free, pid, adaptive; one walk each) are exported with `export`, registered
with `add-subject --round-trip-of camargo` in a temporary registry and processed by ingest as real
trials: their tables must equal the simulation's (Table I within 2 %, Table II within 1 %, Table
III within 0.3 deg, events within one sample). The exported GRF, read back, must give force-plate
heel strikes at the simulated feet's contact onsets, and the .mot carries OpenSim's names and signs.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ingest.canonical import plates_from_grf, up_to_z
from ingest.events import force_plate_events
from ingest.manifest import Manifest
from ingest.process import process_subject
from ingest.readers import read_mot, read_robot_log, read_trc
from ingest.subject import FileFormat, load_subject
from metrics.compliance import compliance_table
from metrics.gait import gait_table
from metrics.stability import stability_table
from pipeline.commands.add_subject import NewTrial, Registry, add_subject
from pipeline.commands.export import run_export
from pipeline.params import check_params
from pipeline.paths import PARAMS_FILE, POLICIES_ROOT
from pipeline.runs.jobs import policy_setup, scenario_jobs
from sim.body.ground_reaction import GroundReactionProbe
from sim.rollout.batch import Worker

REPO = Path(__file__).resolve().parents[2]
CONDITIONS = ("free", "pid", "adaptive")
JOINTS = ("hip_flexion", "knee_flexion", "ankle_dorsiflexion")

pytestmark = pytest.mark.skipif(not (POLICIES_ROOT / "camargo" / "policy.zip").is_file(),
                                reason="camargo's committed policy is missing")


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("round_trip")
    params = check_params()
    out = run_export("camargo", params, tmp / "export", "walk_10m", CONDITIONS, 1, progress=False)
    (tmp / "subjects").mkdir()
    shutil.copy(PARAMS_FILE, tmp / "params.yaml")
    shutil.copy(REPO / "data" / "sources.yaml", tmp / "sources.yaml")
    registry = Registry(subjects_dir=tmp / "subjects", params_path=tmp / "params.yaml",
                        manifest_path=tmp / "sources.yaml")
    trials = [NewTrial(c, out / f"walk_10m_{c}_seed0.trc", out / f"walk_10m_{c}_seed0_ik.mot", None,
                       None if c == "free" else out / f"walk_10m_{c}_seed0_robot.csv") for c in CONDITIONS]
    add_subject("camargo_rt", 1.80, 74.8, out / "static.trc", trials, markerset="camargo", up_axis="y",
                round_trip_of="camargo", registry=registry)
    subject = load_subject("camargo_rt", tmp / "subjects")
    manifest = Manifest.load(tmp / "sources.yaml", cache=tmp / "raw")
    real = process_subject(subject, manifest, params.ingest)
    worker = Worker(policy_setup("camargo", params))
    jobs = scenario_jobs(params, CONDITIONS, 1, ("walk_10m",))
    outcomes = [worker.run(j, probe=GroundReactionProbe) for j in jobs]
    sim = {k: pd.concat([o.tables[k] for o in outcomes], ignore_index=True)
           for k in ("events", "strides", "cycles")}
    sim["robot"] = pd.concat([o.robot for o in outcomes if not o.robot.empty], ignore_index=True)
    return {"out": out, "subject": subject, "real": real, "sim": sim, "outcomes": outcomes, "params": params}


def test_round_trip_subject_is_labelled_and_has_robot_trials(round_trip):
    subject = round_trip["subject"]
    assert subject.round_trip_of == "camargo"
    assert {t.condition for t in subject.trials if t.robot_log} == {"pid", "adaptive"}
    robot = round_trip["real"].robot
    assert set(robot["condition"]) == {"pid", "adaptive"} and set(robot["source"]) == {"real"}


def test_table1_real_equals_sim_within_2_percent(round_trip):
    cols = ["mean_abs_ex_cm", "mean_abs_ey_cm"]
    real = compliance_table(round_trip["real"].robot).set_index("condition")[cols]
    sim = compliance_table(round_trip["sim"]["robot"]).set_index("condition")[cols]
    assert sorted(real.index) == ["adaptive", "pid"]
    np.testing.assert_allclose(real.loc[sim.index].to_numpy(), sim.to_numpy(), rtol=0.02)


def test_table2_real_equals_sim_within_1_percent(round_trip):
    cols = ["stride_length_m_mean", "gait_speed_mps_mean"]
    real = gait_table(round_trip["real"].strides).set_index("condition")
    sim = gait_table(round_trip["sim"]["strides"]).set_index("condition")
    assert sorted(real.index) == sorted(CONDITIONS) and (real["n_strides"] >= 4).all()
    np.testing.assert_allclose(real.loc[sim.index, cols].to_numpy(), sim[cols].to_numpy(), rtol=0.01)


def test_table3_real_equals_sim_within_03_deg(round_trip):
    def sd(cycles: pd.DataFrame) -> pd.Series:
        return stability_table(cycles, True, JOINTS).set_index(["condition", "joint"])["intercycle_sd_deg"]

    real, sim = sd(round_trip["real"].cycles), sd(round_trip["sim"]["cycles"])
    assert len(real) == len(sim) == len(CONDITIONS) * len(JOINTS)
    assert np.abs(real.loc[sim.index] - sim).max() <= 0.3


def test_events_within_one_sample(round_trip):
    real, sim = round_trip["real"].events, round_trip["sim"]["events"]
    for o in round_trip["outcomes"]:  # the simulation analyses the walking before a fall only
        end = (np.inf if o.first_fall_s is None else o.first_fall_s) - 0.1
        dt = 1.0 / o.sample_rate_hz
        for (side, event), s in sim[sim["condition"] == o.job.condition].groupby(["side", "event"]):
            r = real[(real["condition"] == o.job.condition) & (real["side"] == side)
                     & (real["event"] == event)]
            a, b = np.sort(r["time_s"][r["time_s"] < end]), np.sort(s["time_s"][s["time_s"] < end])
            assert len(a) == len(b) > 2, (o.job.condition, side, event)
            assert np.abs(a - b).max() <= dt + 1e-9


def test_exported_grf_gives_heel_strikes_at_contact_onsets(round_trip):
    out, params = round_trip["out"], round_trip["params"]
    o = next(o for o in round_trip["outcomes"] if o.job.condition == "pid")
    table = read_trc(out / "walk_10m_pid_seed0.trc")
    xyz = up_to_z(table.xyz_m, "y")
    markers = {n: xyz[:, j] for j, n in enumerate(table.names)}
    roles = round_trip["subject"].markerset
    feet = {s: (markers[roles[f"heel_{s}"]][:, :2] + markers[roles[f"toe_{s}"]][:, :2]) / 2
            for s in ("left", "right")}
    plates = plates_from_grf(read_mot(out / "walk_10m_pid_seed0_grf.mot"), FileFormat(up_axis="y"), 0.0)
    events = force_plate_events(plates, feet, table.time_s, params.ingest.events)
    n = len(o.robot)
    ground = o.probe.arrays(len(o.probe.force) - n)
    t = table.time_s
    threshold = params.ingest.events.force_threshold_n  # the plates' own contact threshold:
    for side in ("left", "right"):  # a foot that shuffles without unloading fully still crosses it
        loaded = ground[side][0][:, 2] > threshold
        onsets = t[np.flatnonzero(loaded[1:] & ~loaded[:-1]) + 1]
        strikes = events[(events["side"] == side) & (events["event"] == "heel_strike")]["time_s"].to_numpy()
        assert len(strikes) >= 6
        assert max(np.abs(onsets - s).min() for s in strikes) <= 0.010


def test_mot_has_opensim_names_and_signs(round_trip):
    out = round_trip["out"]
    mot = read_mot(out / "walk_10m_free_seed0_ik.mot")
    cols = set(mot.table.columns)
    for name in ("hip_flexion_r", "hip_flexion_l", "knee_angle_r", "knee_angle_l", "ankle_angle_r",
                 "ankle_angle_l", "pelvis_tilt", "pelvis_tx", "pelvis_ty", "pelvis_tz"):
        assert name in cols
    assert mot.in_degrees
    walking = mot.table[(mot.table["time"] > 4) & (mot.table["time"] < 8)]
    assert walking["knee_angle_r"].max() > 40      # knee flexion positive (swing)
    assert walking["hip_flexion_r"].max() > 15     # hip flexion positive (leg forward)
    assert walking["hip_flexion_r"].min() < -5     # and extension negative (push-off)
    assert 0.7 < walking["pelvis_ty"].median() < 1.3   # Y up, metres
    assert walking["pelvis_tx"].iloc[-1] > walking["pelvis_tx"].iloc[0] + 3   # walking along +X
    log = read_robot_log(out / "walk_10m_pid_seed0_robot.csv")
    assert log.wrench is not None and log.fall is not None and len(log.time_s) == len(mot.time_s)
    assert (out / "model.xml").is_file() and "robot log" in (out / "README.md").read_text()


def test_markers_on_the_robot_give_the_same_table1(round_trip, tmp_path):
    """Without the robot logs: the subject file's `robot_markers` (the block the export README gives)
    turn the markers on the robot into the same robot table, filtered like every marker."""
    import yaml

    readme = (round_trip["out"] / "README.md").read_text()
    block = yaml.safe_load(readme.split("```yaml", 1)[1].split("```", 1)[0])
    doc = yaml.safe_load(round_trip["subject"].path.read_text())
    doc["trials"] = [{k: v for k, v in t.items() if k != "robot_log"} for t in doc["trials"]]
    doc.update(block)
    (tmp_path / "camargo_rt.yaml").write_text(yaml.safe_dump(doc))
    subject = load_subject("camargo_rt", tmp_path)
    assert subject.robot_markers is not None and not any(t.robot_log for t in subject.trials)
    manifest = Manifest.load(round_trip["subject"].path.parent.parent / "sources.yaml",
                             cache=round_trip["subject"].path.parent.parent / "raw")
    robot = process_subject(subject, manifest, round_trip["params"].ingest).robot
    assert not robot["locked"].any()  # markers do not know the robot's fall state: compare before it
    end = {o.job.condition: min(t for t in (o.robot_fall_s, np.inf) if t is not None)
           for o in round_trip["outcomes"]}
    sim = round_trip["sim"]["robot"]

    def before_fall(table: pd.DataFrame) -> pd.DataFrame:
        return table[table["time_s"] < table["condition"].map(end)]

    cols = ["mean_abs_ex_cm", "mean_abs_ey_cm"]
    real = compliance_table(before_fall(robot)).set_index("condition")[cols]
    sim = compliance_table(before_fall(sim)).set_index("condition")[cols]
    assert sorted(real.index) == ["adaptive", "pid"]
    np.testing.assert_allclose(real.loc[sim.index].to_numpy(), sim.to_numpy(), rtol=0.02)
