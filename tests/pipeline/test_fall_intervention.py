"""Scripted balance loss (issue 13): each event type happens when scheduled and the rollout stays
numerically stable; the robot's answer to it is measured per rollout and stored once per job."""

from __future__ import annotations

import mujoco
import numpy as np
import pandas as pd
import pytest

from metrics.fall_intervention import FallRuleParams, event_metrics
from pipeline.params import parse_params
from pipeline.runs.jobs import policy_setup
from pipeline.stages.sweep import run_sweep
from pipeline.store.read import query
from pipeline.store.records import SWEEP_COLUMNS
from pipeline.store.write import store_results
from sim.body.balance_loss import BalanceLoss, body_geoms
from sim.learn.policy_human import PolicyWalk
from sim.learn.walk_env import HUMAN_ACTUATORS
from sim.rollout.batch import RolloutJob, Worker

ONSET_S = 4.0
WALK_S = 7.0


class Probe:
    """Per sample: the feet's world positions, the pelvis's applied force, the human's largest motor
    force as a share of its normal limit, and the feet's friction coefficients."""

    def __init__(self, model: mujoco.MjModel) -> None:
        body = mujoco.mjtObj.mjOBJ_BODY
        self.feet = [mujoco.mj_name2id(model, body, f"foot_{s}") for s in ("l", "r")]
        self.pelvis = mujoco.mj_name2id(model, body, "pelvis")
        act = mujoco.mjtObj.mjOBJ_ACTUATOR
        self.motors = np.array([mujoco.mj_name2id(model, act, n) for n in HUMAN_ACTUATORS])
        self.limit = np.abs(model.actuator_forcerange[self.motors, 1]).copy()
        self.foot_geoms = [body_geoms(model, f) for f in self.feet]
        self.rows: list[tuple] = []

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, k: int) -> None:
        force = np.abs(data.actuator_force[self.motors]) / self.limit
        friction = [float(model.geom_friction[g, 0].min()) for g in self.foot_geoms]
        self.rows.append((data.time, data.xpos[self.feet].copy(), data.xfrc_applied[self.pelvis, :3].copy(),
                          float(force.max()), friction))

    def frame(self) -> dict[str, np.ndarray]:
        t, feet, push, force, friction = zip(*self.rows, strict=True)
        return {"t": np.array(t), "feet": np.array(feet), "push": np.array(push), "force": np.array(force),
                "friction": np.array(friction)}


@pytest.fixture(scope="module")
def worker(params, camargo_model, policies_root):
    from dataclasses import replace

    doc = params.document()
    doc["scenarios"]["commands"]["steady"] = [{"walk_s": WALK_S, "speed": 1.0}]
    setup = policy_setup("camargo", parse_params(doc), camargo_model.parents[1], policies_root)
    return Worker(replace(setup, process=False))


def _run(worker: Worker, event: BalanceLoss | None) -> tuple[object, dict]:
    probes: list[Probe] = []

    def make(model: mujoco.MjModel) -> Probe:
        probes.append(Probe(model))
        return probes[-1]

    o = worker.run(RolloutJob("free", 0, "event", PolicyWalk(scenario="steady", event=event)), probe=make)
    assert o.stable, o.warnings
    assert np.isfinite(o.pelvis_z).all() and np.isfinite(o.pelvis_xy).all()
    return o, probes[0].frame()


def _window(f: dict, event: BalanceLoss) -> np.ndarray:
    return (f["t"] > event.onset_s + 0.02) & (f["t"] < event.onset_s + event.duration_s - 0.02)


def test_trip_holds_the_swing_foot(worker):
    event = BalanceLoss("trip", 0.3, 0.005, ONSET_S)
    o, f = _run(worker, event)
    on = _window(f, event)
    k0 = int(np.flatnonzero(f["t"] >= event.onset_s)[0])
    swing = int(np.argmax(f["feet"][k0, :, 2]))
    moved = np.linalg.norm(f["feet"][on, swing] - f["feet"][k0, swing], axis=1)
    assert moved.max() < 0.01, moved.max()                          # held in place (1 cm)
    before = np.linalg.norm(np.diff(f["feet"][k0 - 30:k0, swing, :2], axis=0), axis=1).sum()
    assert before > 0.2                                              # it was swinging before the onset


def test_slip_drops_the_stance_foot_friction_for_its_duration(worker):
    event = BalanceLoss("slip", 0.5, 0.05, ONSET_S)
    o, f = _run(worker, event)
    on = _window(f, event)
    k0 = int(np.flatnonzero(f["t"] >= event.onset_s)[0])
    stance = int(np.argmin(f["feet"][k0, :, 2]))
    assert np.allclose(f["friction"][on, stance], 0.05)
    assert np.allclose(f["friction"][on, 1 - stance], f["friction"][0, 1 - stance])
    after = f["t"] > event.onset_s + event.duration_s + 0.05
    assert np.allclose(f["friction"][after], f["friction"][0])      # restored
    _, base = _run(worker, None)
    slide = np.abs(np.diff(f["feet"][on, stance, :2], axis=0)).sum()
    slide0 = np.abs(np.diff(base["feet"][on, stance, :2], axis=0)).sum()
    assert slide != pytest.approx(slide0, rel=1e-3)                  # the slip changed the motion


def test_collapse_caps_every_motor_at_its_fraction(worker):
    event = BalanceLoss("collapse", 0.5, 0.1, ONSET_S)
    o, f = _run(worker, event)
    on = _window(f, event)
    assert f["force"][on].max() <= 0.1 + 1e-6
    assert f["force"][f["t"] < event.onset_s].max() > 0.1         # walking needs more than that
    assert o.human_fall_s is not None and o.human_fall_s > event.onset_s
    # the rollout ends `rollout.stop_after_fall_s` after the fall (nothing after a fall is measured)
    end_s = (len(o.pelvis_z) - 1) / o.sample_rate_hz
    assert end_s == pytest.approx(o.human_fall_s + worker.setup.stop_after_fall_s, abs=0.02)
    assert end_s < WALK_S


def test_push_is_lateral_and_only_for_its_duration(worker):
    event = BalanceLoss("push", 0.3, 400.0, ONSET_S)
    o, f = _run(worker, event)
    on = _window(f, event)
    assert np.allclose(np.linalg.norm(f["push"][on, :2], axis=1), 400.0)
    assert np.abs(f["push"][on, 1]).min() > 390.0                  # straight walk along x: lateral is y
    off = (f["t"] < event.onset_s - 0.02) | (f["t"] > event.onset_s + event.duration_s + 0.02)
    assert np.abs(f["push"][off]).max() == 0.0


def test_event_metrics_detection_latency_and_false_alarms():
    t = np.arange(0, 10, 0.01)
    z = np.full_like(t, 0.95)
    z[t > 5.1] -= 0.3 * (t[t > 5.1] - 5.1)
    robot = pd.DataFrame({"time_s": t, "harness_fx_n": 0.0, "harness_fy_n": 0.0,
                          "harness_fz_n": np.where(t > 5.3, 900.0, 20.0)})
    p = FallRuleParams(detection_window_s=1.5, confirm_s=1.0, baseline_s=2.0, caught_drop_m=0.22)
    row = event_metrics("trip", 5.0, t, z, robot, robot_fall_s=5.3, human_fall_s=6.0, p=p)
    assert row["detected"] and row["caught"]
    assert row["latency_s"] == pytest.approx(0.3)
    assert row["pelvis_drop_at_lock_m"] == pytest.approx(0.06, abs=1e-3)
    assert row["max_harness_force_n"] == 900.0
    late = event_metrics("trip", 5.0, t, z, robot, robot_fall_s=7.0, human_fall_s=6.0, p=p)
    assert not late["detected"] and not late["caught"]
    early = event_metrics("trip", 5.0, t, z, robot, robot_fall_s=4.0, human_fall_s=None, p=p)
    assert early["before_onset"] and not early["detected"]
    alarm = event_metrics("none", None, t, z, robot, robot_fall_s=3.0, human_fall_s=None, p=p)
    assert alarm["false_alarm"] and alarm["walk_s"] == 3.0
    true = event_metrics("none", None, t, z, robot, robot_fall_s=3.0, human_fall_s=3.5, p=p)
    assert not true["false_alarm"]


def test_fall_intervention_study_is_stored_and_summarised(tmp_path, params, policies_root):
    doc = params.document()
    doc["fall_intervention"].update(subjects=["camargo"], variants=["healthy"], conditions=["free", "pid"],
                                    scenarios=["steady"], seeds=1, events=["none", "collapse"])
    doc["scenarios"]["commands"]["steady"] = [{"walk_s": 6.0, "speed": 1.0}]
    p = parse_params(doc)
    summary = run_sweep(p, tmp_path / "sweeps", policies_root, progress=False, study="fall_intervention")
    assert summary["ran"] == 4 and not summary["failed"]
    rows = pd.read_parquet(tmp_path / "sweeps" / "fall_intervention" / "results.parquet")
    collapse = rows[rows["event"] == "collapse"].set_index("condition")
    assert collapse.loc["free", "human_fall_s"] > collapse.loc["free", "onset_s"]   # unsupported: falls
    assert bool(collapse.loc["pid", "detected"])
    db = tmp_path / "results.duckdb"
    store_results(db, [], sweeps=[rows])
    store_results(db, [], sweeps=[rows])                                # stored once per job
    assert query(db, "SELECT count(*) AS n FROM sweep_results")["n"].iloc[0] == 4
    fi = query(db, "SELECT * FROM fall_intervention WHERE condition = 'pid'")
    assert fi["events_falling_free"].iloc[0] == 1 and fi["detection_rate_falling"].iloc[0] == 1.0
    fa = query(db, "SELECT * FROM false_alarms")
    assert fa["rollouts"].iloc[0] == 1
    # a later run of the study (other params: other keys) is kept, but the views show only its jobs
    store_results(db, [], sweeps=[rows.assign(job_key=rows["job_key"] + "-v2")])
    assert query(db, "SELECT count(*) AS n FROM sweep_results")["n"].iloc[0] == 8
    assert query(db, "SELECT count(*) AS n FROM sweep_rollouts")["n"].iloc[0] == 4
    assert query(db, "SELECT events FROM fall_intervention WHERE condition = 'pid'")["events"].iloc[0] == 1


def _rollout(condition: str, seed: int, robot_fall_s: float | None, human_fall_s: float | None,
             fell: bool | None = None) -> dict:
    """One trip rollout of the store (`SWEEP_COLUMNS`, event columns from `event_metrics`): onset at
    5 s, after which the pelvis drops 0.3 m/s; `fell` defaults to a fall or a lock."""
    t = np.arange(0, 10, 0.01)
    z = 0.95 - 0.3 * np.clip(t - 5.0, 0.0, None)
    row = dict.fromkeys(SWEEP_COLUMNS, np.nan)
    row.update(study="fi", job_key=f"{condition}-{seed}", subject="s1", variant="weak", condition=condition,
               gains_hash="g", scenario="steady", seed=seed, params_hash="p", n_strides=0, n_samples=0,
               fell=fell if fell is not None else robot_fall_s is not None or human_fall_s is not None,
               wall_s=1.0)
    row.update(event_metrics("trip", 5.0, t, z, pd.DataFrame(), robot_fall_s, human_fall_s,
                             FallRuleParams(caught_drop_m=0.22)))
    return row


def test_falls_not_caught_lists_each_uncaught_fall_with_its_reason(tmp_path):
    """`falls_not_caught`: the pid rollouts whose seed fell walking free after the onset and that pid
    did not catch, each with the first reason that applies; a caught one, one whose free walk did not
    fall and one whose free walk fell before the onset (no confirmation) are not listed."""
    free = [_rollout("free", seed, None, 6.5) for seed in range(7)]
    free += [_rollout("free", 7, None, None), _rollout("free", 8, None, 4.0)]
    pid = [_rollout("pid", 0, 6.0, 6.5),               # locked in the window, pelvis 0.30 m down
           _rollout("pid", 1, 7.0, 7.5),               # locked 2 s after the onset: window 1.5 s
           _rollout("pid", 2, None, None),             # never locked, did not fall
           _rollout("pid", 3, 4.2, 4.0),               # fell before the onset
           _rollout("pid", 4, 4.5, None),              # arm locked before the onset
           _rollout("pid", 5, None, None, fell=True),  # unstable: fell without a fall or lock time
           _rollout("pid", 6, 5.3, 6.0),               # caught: 0.09 m down at the lock
           _rollout("pid", 7, None, None),             # free walk did not fall
           _rollout("pid", 8, None, None)]             # free walk fell before the onset
    db = tmp_path / "results.duckdb"
    store_results(db, [], sweeps=[pd.DataFrame(free + pid, columns=SWEEP_COLUMNS)])
    missed = query(db, "SELECT * FROM falls_not_caught ORDER BY seed")
    assert dict(zip(missed["seed"], missed["reason"], strict=True)) == {
        0: "dropped", 1: "not_detected", 2: "not_detected", 3: "fell_before_onset",
        4: "locked_before_onset", 5: "unstable"}
    assert set(missed["condition"]) == {"pid"} and set(missed["event"]) == {"trip"}
    assert missed.loc[0, "pelvis_drop_at_lock_m"] == pytest.approx(0.3, abs=1e-3)
    assert missed.loc[1, "latency_s"] == pytest.approx(2.0)
    fi = query(db, "SELECT * FROM fall_intervention WHERE condition = 'pid'").iloc[0]
    # the same confirmation as the counts: 5 events fell free (seeds 0-2, 5, 6), one of them caught
    assert fi["events_falling_free"] == 5 and fi["caught_rate_falling"] == pytest.approx(1 / 5)
