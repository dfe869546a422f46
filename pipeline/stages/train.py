"""Commands `train <subject>`, `simulate <subject> --human policy` and `evaluate-policy <subject>`.

`train`: PPO + AMP on the subject's scaled human and reference cycle (sim/learn/train.py); the policy goes
to `data/policies/<subject>/` (policy.zip, vecnormalize.pkl, amp.pt, progress.json with the exact
commands, steps and wall time of every run; metrics via dvclive or metrics.csv).

Policy rollouts: the trained policy drives the human through `sim.rollout.loop.rollout` (the same code
as the replay human) in the conditions free / pid / adaptive; each rollout becomes a canonical sim
`Trial` through the virtual markers and is processed by `ingest.process.process_trial`, like the
replay rollouts. `simulate --human policy` writes them to `<root>/<subject>/sim_policy/` with the
metrics tables (gait, compliance, harness) of the policy mode.

`evaluate-policy`: the checks of issue 6 (10 seeded 20-s free walks: falls, gait speed and stride
length vs the real kept strides, knee flexion peak in swing; pid and adaptive 15-s walks; a 200 N,
0.2 s lateral pelvis push; SPM of hip and knee flexion real vs sim with the figure
`reports/<subject>/policy_spm.png`: primary, the real free walking retargeted onto the policy's
body and processed like a simulation vs one mean curve per rollout; also against the dataset's IK).
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd
from tqdm import tqdm

from ingest.errors import IngestError
from ingest.process import IngestParams, process_trial
from ingest.subject import load_subject
from pipeline import paths
from pipeline.params import EvalParams, Params
from pipeline.stages.outputs import replacing, write_outputs
from sim.body.markers import trial_from_qpos
from sim.errors import SimulationError
from sim.learn.policy_human import PolicyHuman, Push
from sim.learn.train import BODY_FILE, CYCLE_FILE, POLICY_FILE, TrainParams, load_body, load_policy, train
from sim.learn.walk_env import make_walk_env
from sim.motion.reference import load_reference
from sim.robot.controllers import make_controller
from sim.robot.controllers.warm_start import WarmStarted
from sim.robot.mrba import RobotParams
from sim.rollout.loop import ROBOT_COLUMNS, RolloutParams, rollout
from sim.rollout.world import robot_info


def _inputs(subject: str, root: Path) -> tuple[Path, Path]:
    xml, npz = paths.human_xml(root, subject), paths.reference_npz(root, subject)
    for f in (xml, npz):
        if not f.exists():
            raise SimulationError(f, f"missing input of the policy stages for {subject} (run `python -m "
                                  f"pipeline scale {subject}` and `reference {subject}`)")
    return xml, npz


def run_train(subject: str, params: Params, *, n_envs: int | None, threads: int | None, steps: int | None,
              resume: bool, root: Path = paths.PROCESSED_ROOT, out_root: Path = paths.POLICIES_ROOT,
              max_wall_s: float | None = None, subprocess: bool | None = None,
              init_from: str | None = None) -> dict:
    """Train `subject`'s policy; `init_from`: another subject whose committed policy is the start."""
    p = params.train.build()
    start = None
    if init_from is not None and not resume:
        start = paths.policy_dir(out_root, init_from)
        if not (start / POLICY_FILE).exists():
            raise SimulationError(start, f"no trained policy of {init_from!r} to start {subject}'s from")
    xml, npz = _inputs(subject, root)
    cycle = load_reference(npz).cycle
    command = "python -m pipeline train " + " ".join(sys.argv[2:]) if sys.argv[1:2] == ["train"] else ""
    return train(xml, cycle, p, paths.policy_dir(out_root, subject), n_envs=n_envs, threads=threads,
                 total_steps=steps, resume=resume, max_wall_s=max_wall_s, subprocess=subprocess,
                 command=command, init_from=start)


# -- policy rollouts ----------------------------------------------------------------------------

@dataclass(frozen=True)
class PolicyJob:
    condition: str          # free or a controller name
    seed: int
    duration_s: float
    push_n: float = 0.0     # lateral push (signed, world y) at push_time_s; 0 = none
    push_time_s: float = 0.0
    push_duration_s: float = 0.0
    tag: str = ""


_W: dict = {}


def _init(human_xml: str, rate: float, policy_dir: str, subject_id: str, tp: TrainParams, ev: EvalParams,
          robot: RobotParams, controllers: dict, ingest: IngestParams, max_dt_s: float,
          offset_m: float) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    model, norm = load_policy(policy_dir)
    _, cycle = load_body(policy_dir)
    env = make_walk_env(human_xml, cycle, tp.env)

    def policy(obs: np.ndarray) -> np.ndarray:
        o = norm.normalize_obs(obs) if norm is not None else obs
        return model.predict(o, deterministic=True)[0]

    _W.update(spec=mujoco.MjSpec.from_file(human_xml), human=mujoco.MjModel.from_xml_path(human_xml),
              pd_model=env.model, cycle=cycle, policy=policy, subject=load_subject(subject_id), tp=tp,
              ev=ev,
              robot=robot, controllers=controllers, ingest=ingest, rate=rate, max_dt_s=max_dt_s,
              offset_m=offset_m)


def _run(job: PolicyJob) -> dict:
    w = _W
    rng = np.random.default_rng(job.seed)
    push = Push(job.push_time_s, (0.0, job.push_n), job.push_duration_s) if job.push_n else None
    human = PolicyHuman(w["policy"], w["pd_model"], w["cycle"], w["tp"].env, job.duration_s,
                        start_phase=float(rng.random()), push=push,
                        fall_height_fraction=w["ev"].fall_height_fraction)
    with_robot = job.condition != "free"
    trial = f"policy_{job.tag or job.condition}_seed{job.seed}"
    p = RolloutParams(robot=w["robot"], sample_rate_hz=w["rate"], max_physics_dt_s=w["max_dt_s"],
                      start_offset_m=w["offset_m"], with_robot=with_robot, subject=w["subject"].id,
                      condition=job.condition, trial=trial)
    ctrl = None
    if with_robot:
        if job.condition not in w["controllers"]:
            raise SimulationError(f"condition {job.condition}", "not in robot.controllers")
        ctrl = WarmStarted(make_controller(w["controllers"][job.condition], robot_info(w["robot"])),
                           w["cycle"].speed_mps)
    result = rollout(w["spec"], human, ctrl, p, job.seed)
    fall = human.fall_time_s
    out = {"job": job, "stable": result.stable, "warnings": result.warnings, "human_fall_s": fall,
           "robot_fall_s": result.fall_time_s, "robot": result.robot, "wall_s": result.wall_s,
           "sim_s": result.n_physics_steps * result.physics_dt_s,
           "distance_m": float(result.human_qpos[-1, 0] - result.human_qpos[0, 0])}
    qpos = result.human_qpos
    if fall is not None:  # gait analysis of the walking before the fall only
        qpos = qpos[result.time_s < fall]
    try:
        sim_trial = trial_from_qpos(w["human"], qpos, w["rate"], w["subject"].id, job.condition, trial)
        processed = process_trial(sim_trial, w["subject"].markerset, w["ingest"])
        extra = {"human_mode": "policy", "seed": job.seed}
        out.update({k: getattr(processed, k).assign(**extra) for k in ("events", "strides", "cycles")})
    except (IngestError, SimulationError) as exc:
        out["skipped"] = str(exc)
    return out


def policy_rollouts(subject: str, params: Params, jobs: list[PolicyJob], root: Path = paths.PROCESSED_ROOT,
                    policy_root: Path = paths.POLICIES_ROOT, workers: int | None = None, progress: bool = True
                    ) -> list[dict]:
    tp, ev = params.train.build(), params.evaluate_policy.build()
    _, npz = _inputs(subject, root)
    policy_dir = paths.policy_dir(policy_root, subject)
    for f in (POLICY_FILE, BODY_FILE, CYCLE_FILE):
        if not (policy_dir / f).exists():
            raise SimulationError(policy_dir / f, f"no trained policy: run `python -m pipeline train "
                                  f"{subject}`")
    ref = load_reference(npz)
    rate = float(1.0 / np.median(np.diff(ref.time_s[ref.trial == ref.trial[0]])))
    r = params.rollout
    init = (str(policy_dir / BODY_FILE), rate, str(policy_dir), subject, tp, ev, params.robot.build(),
            params.robot.controller_specs(), params.ingest.build(), r.max_physics_dt_s, r.start_offset_m)
    n = workers or r.workers
    with ProcessPoolExecutor(max_workers=max(1, n), initializer=_init, initargs=init) as pool:
        return list(tqdm(pool.map(_run, jobs), total=len(jobs), desc=f"policy rollouts {subject}",
                         disable=not progress))


def _tables(results: list[dict]) -> dict[str, pd.DataFrame]:
    tables = {}
    for name in ("events", "strides", "cycles"):
        parts = [r[name] for r in results if name in r]
        tables[name] = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
    robot = [r["robot"] for r in results if not r["robot"].empty]
    tables["robot"] = pd.concat(robot, ignore_index=True)[ROBOT_COLUMNS] if robot else \
        pd.DataFrame(columns=ROBOT_COLUMNS)
    return tables


def _fell(r: dict) -> bool:
    return r["human_fall_s"] is not None or r["robot_fall_s"] is not None or not r["stable"]


def compliance_summary(robot: pd.DataFrame) -> dict:
    """Per controller: mean |e_x|, |e_y| (cm) and harness force RMS (N), before any arm lock."""
    out = {}
    for cond, df in robot.groupby("condition"):
        df = df[~df["locked"]]
        f = np.sqrt((df[["harness_fx_n", "harness_fy_n", "harness_fz_n"]] ** 2).sum(axis=1))
        out[str(cond)] = {"mean_abs_e_x_cm": round(float(df.e_x_m.abs().mean() * 100), 3),
                          "mean_abs_e_y_cm": round(float(df.e_y_m.abs().mean() * 100), 3),
                          "harness_force_rms_n": round(float(np.sqrt((f**2).mean())), 2)}
    return out


def run_simulate_policy(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                        policy_root: Path = paths.POLICIES_ROOT, progress: bool = True) -> dict:
    """Policy rollouts of every `rollout.conditions` x `rollout.n_seeds` (duration `evaluate_policy.
    free_s` / `robot_s`) written to `<root>/<subject>/sim_policy/` like the replay datasets."""
    ev, r = params.evaluate_policy.build(), params.rollout
    jobs = [PolicyJob(c, s, ev.free_s if c == "free" else ev.robot_s)
            for c in r.conditions for s in range(r.n_seeds)]
    results = policy_rollouts(subject, params, jobs, root, policy_root, progress=progress)
    tables = _tables(results)
    # the metrics issue's tables for the policy mode (metrics/ library, same functions as the stage)
    from metrics.compliance import compliance_table
    from metrics.gait import gait_table
    from metrics.harness import harness_table

    tables["metrics_gait"] = gait_table(tables["strides"])
    tables["metrics_compliance"] = compliance_table(tables["robot"])
    tables["metrics_harness"] = harness_table(tables["robot"])
    summary = {"human_mode": "policy", "rollouts": len(results),
               "falls": {c: sum(_fell(x) for x in results if x["job"].condition == c) for c in
                         sorted({x["job"].condition for x in results})},
               "unstable": sum(not x["stable"] for x in results),
               "conditions": compliance_summary(tables["robot"])}
    write_outputs(paths.sim_policy_dir(root, subject), tables, {"summary": summary})
    return summary


# -- evaluation ---------------------------------------------------------------------------------

def swing_knee_peaks(cycles: pd.DataFrame) -> np.ndarray:
    """Knee flexion maximum (deg) in swing (60-100 % of the cycle) of each cycle."""
    k = cycles[(cycles["joint"] == "knee_flexion") & (cycles["pct"] >= 60)]
    return k.groupby(["trial", "side", "stride"])["angle_deg"].max().to_numpy()


def curves(cycles: pd.DataFrame, joint: str,
           per: tuple[str, ...] = ("trial", "side", "stride")) -> np.ndarray:
    """(n, n_points) of one joint, sides pooled: one curve per cycle, or with `per=("trial",)` one
    mean curve per trial (a simulated rollout)."""
    c = cycles[cycles["joint"] == joint]
    if c.empty:
        return np.zeros((0, 0))
    return c.pivot_table(index=list(per), columns="pct", values="angle_deg").to_numpy()


def real_in_model_cycles(model: mujoco.MjModel, reference, subject_id: str, ingest: IngestParams,
                         condition: str = "free") -> pd.DataFrame:
    """Cycles of the subject's recorded `condition` trials as retargeted onto `model` (the motion in
    reference.npz), through the model's virtual markers and the same ingest code as every simulated
    trial: the real gait in the model's joint definitions and event detection."""
    subject = load_subject(subject_id)
    parts = []
    for trial in sorted(set(reference.trial[reference.condition == condition].tolist())):
        t, q = reference.motion(trial)
        rate = float(1.0 / np.median(np.diff(t)))
        sim_trial = trial_from_qpos(model, q, rate, subject_id, condition, trial, t0_s=float(t[0]))
        parts.append(process_trial(sim_trial, subject.markerset, ingest).cycles)
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def spm_check(a: np.ndarray, b: np.ndarray, max_cluster_pct: float = 20.0, min_a: int = 2) -> dict:
    """SPM anova1 (alpha 0.05) of curves `a` vs `b`: clusters (% of cycle), the longest, pass. With
    fewer than `min_a` curves in `a` the test is still run and reported but not judged (pass None):
    the mean of so few real cycles is not a reference to hold a simulation to."""
    from metrics.spm import spm_test

    if not (a.size and b.size) or a.shape[1] != b.shape[1]:
        return {"n_a": int(len(a)), "n_b": int(len(b)), "skipped": "no curves", "pass": False}
    res = spm_test(a, b, "anova1", 0.05, 2)
    spans = [(round(c.start_pct, 1), round(c.end_pct, 1)) for c in res.clusters]
    longest = round(float(max((e - s for s, e in spans), default=0.0)), 1)
    diff = np.abs(a.mean(0) - b.mean(0))
    out = {"n_a": int(len(a)), "n_b": int(len(b)), "clusters_pct": spans, "longest_cluster_pct": longest,
           "skipped": res.skipped, "pass": not res.skipped and longest <= max_cluster_pct,
           "mean_abs_difference_deg": round(float(diff.mean()), 2),
           "max_abs_difference_deg": round(float(diff.max()), 2)}
    if len(a) < min_a:
        out.update({"pass": None, "not_judged": f"{len(a)} real cycles < {min_a}"})
    return out


def spm_figure(path: Path, curves_by_joint: dict, results: dict, subject: str) -> None:
    """Mean +- SD of the real curves (dataset and in the model) and of the policy's rollout means,
    with the supra-threshold clusters of the primary test shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"real (dataset IK)": ("0.5", "--"), "real (same model)": ("k", "-"),
              "policy (rollout means)": ("tab:blue", "-")}
    fig, axes = plt.subplots(1, len(curves_by_joint), figsize=(5.5 * len(curves_by_joint), 4.0))
    for ax, (joint, groups) in zip(np.atleast_1d(axes), curves_by_joint.items(), strict=True):
        for name, data in groups.items():
            if data.size == 0:
                continue
            colour, ls = styles[name]
            x = np.linspace(0, 100, data.shape[1])
            m, sd = data.mean(0), data.std(0)
            ax.plot(x, m, color=colour, ls=ls, label=f"{name} (n={len(data)})")
            ax.fill_between(x, m - sd, m + sd, color=colour, alpha=0.12)
        primary = results[joint]["primary"]
        for c0, c1 in primary.get("clusters_pct", []):
            ax.axvspan(c0, c1, color="tab:red", alpha=0.15)
        ax.set_title(f"{joint}: clusters (red) vs real in the model,\nlongest "
                     f"{primary.get('longest_cluster_pct', float('nan')):.0f} % of the cycle", fontsize=10)
        ax.set_xlabel("gait cycle (%)")
        ax.set_ylabel("angle (deg)")
        ax.legend(fontsize=8)
    fig.suptitle(f"{subject}: free walking, real vs policy human (SPM anova1, alpha 0.05)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def evaluate_policy(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                    policy_root: Path = paths.POLICIES_ROOT,
                    reports: Path = paths.REPORTS_ROOT, progress: bool = True) -> dict:
    ev = params.evaluate_policy.build()
    start = time.perf_counter()
    seeds = range(ev.n_seeds)
    jobs = [PolicyJob("free", s, ev.free_s) for s in seeds]
    jobs += [PolicyJob(c, s, ev.robot_s) for c in ("pid", "adaptive") for s in seeds]
    push_s = min(ev.free_s, ev.push_time_s + 5.0)
    jobs += [PolicyJob("free", s, push_s, ev.push_n * (1 if s % 2 == 0 else -1), ev.push_time_s,
                       ev.push_duration_s, tag="push") for s in seeds]
    results = policy_rollouts(subject, params, jobs, root, policy_root, progress=progress)
    groups = {"free": [r for r in results if r["job"].condition == "free" and not r["job"].push_n],
              "pid": [r for r in results if r["job"].condition == "pid"],
              "adaptive": [r for r in results if r["job"].condition == "adaptive"],
              "push": [r for r in results if r["job"].push_n]}
    real_strides = pd.read_parquet(paths.real_dir(root, subject) / "strides.parquet")
    real_cycles = pd.read_parquet(paths.real_dir(root, subject) / "cycles.parquet")
    # the policy imitates free walking: its gait is compared with the free-walking strides
    real_kept = real_strides[real_strides["kept"] & (real_strides["condition"] == "free")]
    free = _tables(groups["free"])
    sim_kept = free["strides"][free["strides"]["kept"]] if not free["strides"].empty else free["strides"]
    doc: dict = {"subject": subject, "human_mode": "policy"}
    n_free_ok = sum(not _fell(r) for r in groups["free"])
    real_v, real_l = float(real_kept["gait_speed_mps"].mean()), float(real_kept["stride_length_m"].mean())
    sim_v = float(sim_kept["gait_speed_mps"].mean()) if len(sim_kept) else float("nan")
    sim_l = float(sim_kept["stride_length_m"].mean()) if len(sim_kept) else float("nan")
    kept_ids = set(zip(sim_kept["trial"], sim_kept["side"], sim_kept["stride"], strict=True))
    sim_cycles = free["cycles"]
    if len(sim_cycles):
        ids = list(zip(sim_cycles["trial"], sim_cycles["side"], sim_cycles["stride"], strict=True))
        sim_cycles = sim_cycles[[i in kept_ids for i in ids]]
    real_free_cycles = real_cycles[real_cycles["condition"] == "free"]
    real_knee, sim_knee = swing_knee_peaks(real_free_cycles), swing_knee_peaks(sim_cycles) \
        if len(sim_cycles) else np.array([])
    knee_diff = float(np.mean(sim_knee) - np.mean(real_knee)) if len(sim_knee) else float("nan")
    doc["free"] = {
        "rollouts": len(groups["free"]), "no_fall": n_free_ok, "pass_no_fall": n_free_ok >= 9,
        "distance_m": [round(r["distance_m"], 2) for r in groups["free"]],
        "kept_strides_sim": int(len(sim_kept)), "kept_strides_real": int(len(real_kept)),
        "gait_speed_mps": {"real": round(real_v, 3), "sim": round(sim_v, 3),
                           "error_pct": round(100 * (sim_v / real_v - 1), 2)},
        "stride_length_m": {"real": round(real_l, 3), "sim": round(sim_l, 3),
                            "error_pct": round(100 * (sim_l / real_l - 1), 2)},
        "knee_swing_peak_deg": {"real": round(float(np.mean(real_knee)), 2),
                                "sim": round(float(np.mean(sim_knee)), 2) if len(sim_knee) else None,
                                "difference": round(knee_diff, 2)},
    }
    f = doc["free"]
    f["pass_speed"] = bool(abs(f["gait_speed_mps"]["error_pct"]) <= 15)
    f["pass_stride_length"] = bool(abs(f["stride_length_m"]["error_pct"]) <= 15)
    f["pass_knee_peak"] = bool(abs(knee_diff) <= 10)
    for c in ("pid", "adaptive"):
        ok = sum(not _fell(r) for r in groups[c])
        doc[c] = {"rollouts": len(groups[c]), "no_fall": ok, "pass_no_fall": ok >= 8,
                  "human_falls": sum(r["human_fall_s"] is not None for r in groups[c]),
                  "robot_fall_detections": sum(r["robot_fall_s"] is not None for r in groups[c])}
    doc["compliance"] = compliance_summary(_tables(groups["pid"] + groups["adaptive"])["robot"])
    rec = sum(not _fell(r) for r in groups["push"])
    doc["push"] = {"force_n": ev.push_n, "duration_s": ev.push_duration_s, "at_s": ev.push_time_s,
                   "walk_s": push_s, "rollouts": len(groups["push"]), "recovered": rec, "pass": rec >= 7}
    xml, npz = _inputs(subject, root)
    policy_body = paths.policy_dir(policy_root, subject) / BODY_FILE
    policy_model = mujoco.MjModel.from_xml_path(str(policy_body))
    in_model = real_in_model_cycles(policy_model, load_reference(npz), subject, params.ingest.build())
    spm, shown = {}, {}
    for joint in ("hip_flexion", "knee_flexion"):
        dataset, model_real = curves(real_free_cycles, joint), curves(in_model, joint)
        means = curves(sim_cycles, joint, per=("trial",)) if len(sim_cycles) else np.zeros((0, 0))
        every = curves(sim_cycles, joint) if len(sim_cycles) else np.zeros((0, 0))
        spm[joint] = {"primary": spm_check(model_real, means, min_a=ev.spm_min_real_cycles),
                      "vs_dataset_rollout_means": spm_check(dataset, means),
                      "vs_dataset_all_cycles": spm_check(dataset, every),
                      "model_vs_dataset": spm_check(dataset, model_real)}
        spm[joint]["pass"] = spm[joint]["primary"]["pass"]
        shown[joint] = {"real (dataset IK)": dataset, "real (same model)": model_real,
                        "policy (rollout means)": means}
    spm["primary_test"] = ("real free walking retargeted onto the policy's body and processed like the "
                           "simulation (virtual markers, same ingest) vs one mean curve per 20-s policy "
                           "rollout; anova1, alpha 0.05; pass: no cluster longer than 20 % of the cycle")
    doc["spm"] = spm
    png = paths.report_dir(reports, subject) / "policy_spm.png"
    png.parent.mkdir(parents=True, exist_ok=True)
    with replacing(png) as (tmp,):
        spm_figure(tmp.with_suffix(".png"), shown, spm, subject)
        tmp.with_suffix(".png").replace(tmp)
    doc["policy_body_is_current_model"] = policy_body.read_bytes() == xml.read_bytes()
    doc["figure"] = paths.repo_relative(png)
    doc["unstable_rollouts"] = sum(not r["stable"] for r in results)
    doc["skipped"] = [f"{r['job'].tag or r['job'].condition} seed {r['job'].seed}: {r['skipped']}"
                      for r in results if "skipped" in r]
    doc["checks"] = {
        "free_no_fall": f["pass_no_fall"], "free_speed": f["pass_speed"],
        "free_stride_length": f["pass_stride_length"], "free_knee_peak": f["pass_knee_peak"],
        "pid_no_fall": doc["pid"]["pass_no_fall"], "adaptive_no_fall": doc["adaptive"]["pass_no_fall"],
        "push": doc["push"]["pass"],
        **{f"spm_{j}": spm[j]["pass"] for j in ("hip_flexion", "knee_flexion")}}
    doc["wall_s"] = round(time.perf_counter() - start, 1)
    return doc


__all__ = ["EvalParams", "PolicyJob", "evaluate_policy", "policy_rollouts", "run_simulate_policy",
           "run_train"]
