"""Command `simulate <subject>`: replay-human rollouts for every condition and seed, processed by the
same ingest code as the real recordings.

Each bout is preceded by a lead-in (`sim.motion.replay.with_lead_in`: the bout's first stride repeated,
ramping up from rest over `rollout.lead_in_ramp_s`, `rollout.lead_in_s` long) so that the robot and
every controller enter the bout from the same natural state (following a user who started walking),
not from an arbitrary mid-walk initial condition; only the bout itself is recorded.

Inputs: `<root>/<subject>/model/human.xml` and `reference.npz` (scale/reference stages) and the real
stride table `<root>/<subject>/real/strides.parquet`. The replay human walks the subject's
*straight bouts only*: runs of kept real strides (steady, straight walking; turns, starts and stops
excluded by ingest), widened by `rollout.bout_margin_s`. The Camargo circuit's turns are outside what
the follow-me comparison needs. Each (bout, condition, seed) rollout becomes a canonical sim `Trial`
through the human's virtual markers and goes through `ingest.process.process_trial`.

Outputs in `<root>/<subject>/sim/`: events, strides, cycles (the real columns plus `human_mode`,
`seed`), robot.parquet (sim.rollout.loop.ROBOT_COLUMNS), summary.json; and
`reports/<subject>/robot_tracking.png` (e_x, e_y over time, seed 0, pid vs adaptive).
"""

from __future__ import annotations

import os
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
from pipeline.params import Params, SimulateSection
from pipeline.paths import (
    PROCESSED_ROOT,
    REPORTS_ROOT,
    human_xml,
    real_dir,
    reference_npz,
    report_dir,
    sim_dir,
)
from pipeline.stages.outputs import replacing, write_outputs
from sim.body.markers import trial_from_qpos
from sim.errors import SimulationError
from sim.motion.reference import load_reference
from sim.motion.replay import Motion, ReplayHuman, with_lead_in
from sim.robot.controllers import make_controller
from sim.rollout.loop import ROBOT_COLUMNS, RolloutParams, rollout
from sim.rollout.world import robot_info


def straight_bouts(strides: pd.DataFrame, trial: str, margin_s: float, join_gap_s: float = 0.3
                   ) -> list[tuple[float, float]]:
    """(start, end) times of runs of kept strides of `trial` (overlapping or within `join_gap_s`),
    widened by `margin_s`."""
    kept = strides[(strides["trial"] == trial) & strides["kept"]].sort_values("t_start_s")
    bouts: list[list[float]] = []
    for t0, t1 in zip(kept["t_start_s"], kept["t_end_s"], strict=True):
        if bouts and t0 <= bouts[-1][1] + join_gap_s:
            bouts[-1][1] = max(bouts[-1][1], t1)
        else:
            bouts.append([t0, t1])
    return [(b0 - margin_s, b1 + margin_s) for b0, b1 in bouts]


@dataclass(frozen=True)
class Job:
    trial: str
    bout: int
    t0_s: float
    t1_s: float
    stride_s: float
    condition: str
    seed: int


_WORKER: dict = {}


def _init_worker(human_xml: str, reference_npz: str, subject_id: str, section: SimulateSection,
                 replay: dict, ingest: IngestParams) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    _WORKER.update(spec=mujoco.MjSpec.from_file(human_xml), model=mujoco.MjModel.from_xml_path(human_xml),
                   ref=load_reference(reference_npz), subject=load_subject(subject_id), section=section,
                   replay=replay, ingest=ingest)


def _run_job(job: Job) -> dict:
    w = _WORKER
    section: SimulateSection = w["section"]
    ref, subject = w["ref"], w["subject"]
    time_s, qpos = ref.motion(job.trial)
    rows = (time_s >= job.t0_s) & (time_s <= job.t1_s)
    t, q = time_s[rows], qpos[rows]
    rate = float(1.0 / np.median(np.diff(time_s)))
    with_robot = job.condition != "free"
    p = RolloutParams(robot=section.robot, sample_rate_hz=rate, max_physics_dt_s=section.max_physics_dt_s,
                      start_offset_m=section.start_offset_m, with_robot=with_robot, subject=subject.id,
                      condition=job.condition, trial=f"{job.trial}_bout{job.bout}_seed{job.seed}",
                      discard_s=section.lead_in_s)
    ctrl = None
    if with_robot:
        if job.condition not in section.controllers:
            raise SimulationError(f"rollout.conditions: {job.condition}", "not in robot.controllers")
        ctrl = make_controller(section.controllers[job.condition], robot_info(section.robot))
    motion = with_lead_in(Motion(t - t[0], q), job.stride_s, section.lead_in_s, section.lead_in_ramp_s)
    human = ReplayHuman(motion, w["replay"])
    result = rollout(w["spec"], human, ctrl, p, job.seed)
    out = {"job": job, "stable": result.stable, "warnings": result.warnings, "fall": result.fall_time_s,
           "robot": result.robot, "wall_s": result.wall_s, "n_steps": result.n_physics_steps,
           "sim_s": result.n_physics_steps * result.physics_dt_s}
    trial = trial_from_qpos(w["model"], result.human_qpos, rate, subject.id, job.condition, p.trial,
                            t0_s=float(t[0]))
    try:
        processed = process_trial(trial, subject.markerset, w["ingest"])
        extra = {"human_mode": human.mode, "seed": job.seed}
        out.update({k: getattr(processed, k).assign(**extra) for k in ("events", "strides", "cycles")})
    except IngestError as exc:
        out["skipped"] = str(exc)
    return out


def plot_tracking(path: Path, robot: pd.DataFrame, subject: str) -> None:
    """e_x and e_y over time, seed 0, one line per controller and bout."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(9, 5.5), sharex=False)
    colours = {"pid": "tab:red", "adaptive": "tab:blue"}
    first = robot[robot["seed"] == robot["seed"].min()]
    for (cond, trial), df in first.groupby(["condition", "trial"], sort=True):
        for ax, col in zip(axes, ("e_x_m", "e_y_m"), strict=True):
            label = cond if trial.endswith("bout0_seed0") or trial == first["trial"].iloc[0] else None
            ax.plot(df["time_s"], df[col] * 100, color=colours.get(cond), lw=1, label=label)
    for ax, name in zip(axes, ("e_x (cm, forward)", "e_y (cm, lateral)"), strict=True):
        ax.set_ylabel(name)
        ax.axhline(0, color="k", lw=0.5)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[1].set_xlabel("time in bout (s)")
    fig.suptitle(f"{subject}: pelvis offset from the arm's neutral point, replay human, seed 0")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summarise(robot: pd.DataFrame, results: list[dict]) -> dict:
    per = {}
    for cond, df in robot.groupby("condition"):
        f = np.sqrt((df[["harness_fx_n", "harness_fy_n", "harness_fz_n"]] ** 2).sum(axis=1))
        per[cond] = {"mean_abs_e_x_cm": round(float(df.e_x_m.abs().mean() * 100), 3),
                     "mean_abs_e_y_cm": round(float(df.e_y_m.abs().mean() * 100), 3),
                     "harness_force_rms_n": round(float(np.sqrt((f**2).mean())), 3),
                     "falls": int(df.groupby(["trial"]).fall.any().sum())}
    wall = sum(r["wall_s"] for r in results)
    sim_s = sum(r["sim_s"] for r in results)
    return {"rollouts": len(results), "unstable": sum(not r["stable"] for r in results),
            "warnings": sorted({k for r in results for k in r["warnings"]}),
            "skipped": [f"{r['job'].trial} bout {r['job'].bout} {r['job'].condition} seed {r['job'].seed}: "
                        f"{r['skipped']}" for r in results if "skipped" in r],
            "realtime_factor": round(sim_s / wall, 2) if wall else None,  # lead-ins included
            "human_mode": "replay", "bouts": "straight bouts only (kept real strides)", "conditions": per}


def run_simulate(subject_id: str, params: Params, root: Path = PROCESSED_ROOT,
                 reports: Path = REPORTS_ROOT, progress: bool = True) -> dict:
    section = params.simulate_section()
    replay, ip = params.rollout.replay.build(), params.ingest.build()
    xml, ref_npz = human_xml(root, subject_id), reference_npz(root, subject_id)
    strides_file = real_dir(root, subject_id) / "strides.parquet"
    for f in (xml, ref_npz, strides_file):
        if not f.exists():
            raise SimulationError(f, f"missing input of `simulate {subject_id}` (run the stage that "
                                  "makes it)")
    strides = pd.read_parquet(strides_file)
    ref = load_reference(ref_npz)
    jobs = []
    for trial in sorted(set(ref.trial.tolist())):
        stride_s = float(strides.loc[(strides["trial"] == trial) & strides["kept"], "stride_time_s"].median())
        for b, (t0, t1) in enumerate(straight_bouts(strides, trial, section.bout_margin_s)):
            jobs += [Job(trial, b, t0, t1, stride_s, c, s) for c in section.conditions
                     for s in range(section.n_seeds)]
    if not jobs:
        raise SimulationError(strides_file, f"no straight bout (kept strides) in the retargeted trials of "
                              f"{subject_id}")
    init = (str(xml), str(ref_npz), subject_id, section, replay, ip)
    with ProcessPoolExecutor(max_workers=max(1, section.workers), initializer=_init_worker,
                             initargs=init) as pool:
        results = list(tqdm(pool.map(_run_job, jobs), total=len(jobs), desc=f"simulate {subject_id}",
                            disable=not progress))
    robot = pd.concat([r["robot"] for r in results if not r["robot"].empty], ignore_index=True)
    robot = robot[ROBOT_COLUMNS] if not robot.empty else pd.DataFrame(columns=ROBOT_COLUMNS)
    tables = {}
    for name in ("events", "strides", "cycles"):
        parts = [r[name] for r in results if name in r]
        tables[name] = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()
    tables["robot"] = robot
    summary = summarise(robot, results)
    write_outputs(sim_dir(root, subject_id), tables, {"summary": summary})
    png = report_dir(reports, subject_id) / "robot_tracking.png"
    with replacing(png) as (tmp,):
        plot_tracking(tmp.with_suffix(".png"), robot, subject_id)
        tmp.with_suffix(".png").replace(tmp)
    return summary
