"""Command `export <subject>`: simulated trials as OpenSim files (`ingest.opensim_export`).

Each trial is the rollout `simulate` runs for that job (same setup, scenario, condition and seed:
a rollout is a pure function of them), run again with the feet's ground reactions recorded
(`sim.body.ground_reaction`). The whole trial is written, a fall included. The folder holds, per
trial, the virtual markers (.trc, mm, Y up; with the robot also markers on it,
`sim.robot.mrba.robot_markers`), the joint coordinates (.mot, degrees), the ground
reactions (.mot + ExternalLoads .xml) and, with the robot, its log (.csv, `ingest.readers.robot_log`);
plus `static.trc` (the model standing in its static pose, for scaling), the scaled model's MJCF
(`model.xml`) and a README saying what each file is and how to read the trials back.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from ingest.opensim_export import UP_AXIS, GroundReaction, export_trial
from ingest.robot_log import log_from_table
from ingest.trial import Trial
from pipeline import paths
from pipeline.params import Params
from pipeline.runs.jobs import policy_setup, replay_jobs, replay_setup, scenario_jobs
from sim.body.ground_reaction import GroundReactionProbe
from sim.body.markers import trial_from_qpos
from sim.errors import SimulationError
from sim.robot.mrba import ROBOT_MARKERS, robot_markers
from sim.rollout.batch import RolloutOutcome, Worker
from sim.rollout.scenarios import ScenariosSection
from sim.rollout.section import RolloutSection

STATIC_S = 1.0


def export_folder(subject: str, scenario: str | None) -> Path:
    return paths.EXPORTS_ROOT / subject / (scenario or "replay")


def run_export(subject: str, params: Params, out: Path | None = None, scenario: str | None = "walk_10m",
               conditions: tuple[str, ...] | None = None, walks: int | None = None,
               root: Path = paths.PROCESSED_ROOT, policy_root: Path = paths.POLICIES_ROOT,
               progress: bool = True) -> Path:
    """Export `subject`'s simulated trials of `scenario` (policy human; None: the replay human's
    straight bouts) in `conditions` (default `rollout.conditions`), `walks` per condition (default
    as in `simulate`); returns the folder."""
    r = params.section("rollout", RolloutSection)
    conditions = r.conditions if conditions is None else conditions
    if scenario is None:
        setup = replay_setup(subject, params, root)
        jobs = replay_jobs(subject, params, root, conditions=conditions,
                           seeds=range(walks if walks is not None else r.n_seeds))
    else:
        commands = params.section("scenarios", ScenariosSection).commands
        if scenario not in commands:
            raise SimulationError(f"scenario {scenario!r}",
                                  f"not in params scenarios ({', '.join(commands)})")
        setup = policy_setup(subject, params, root, policy_root)
        jobs = scenario_jobs(params, conditions, walks, (scenario,))
    folder = Path(out) if out is not None else export_folder(subject, scenario)
    folder.mkdir(parents=True, exist_ok=True)
    if not jobs:
        raise SimulationError(subject, "nothing to export (no condition or walk)")
    worker = Worker(setup)
    model = worker.human_model
    rows, neutral = [], None
    for job in tqdm(jobs, desc=f"export {subject}", unit="trial", disable=not progress):
        o = worker.run(job, keep_result=True, probe=GroundReactionProbe)
        trial, log = sim_trial(model, subject, o), None
        if not o.robot.empty:  # the robot's log, and markers on it (either gives the robot's signals)
            log = log_from_table(o.robot, folder / f"{job.trial}_robot.csv")
            on_robot, neutral = robot_markers(o.world, o.result.world_qpos)
            trial = trial.with_(markers={**trial.markers, **on_robot})
        files = export_trial(folder, trial, o.result.human_qpos[:, :3], ground_of(o), log)
        fell = o.human_fall_s if o.human_fall_s is not None else o.robot_fall_s
        rows.append((job, files, fell))
    export_trial(folder, static_trial(model, subject, o.sample_rate_hz))
    shutil.copyfile(setup.human_xml, folder / "model.xml")
    (folder / "README.md").write_text(readme(subject, scenario, rows, neutral))
    return folder


def sim_trial(model: mujoco.MjModel, subject: str, o: RolloutOutcome) -> Trial:
    """The outcome's motion as the canonical sim Trial `simulate` processes (virtual markers, angles;
    `sim.rollout.batch.process_motion`)."""
    return trial_from_qpos(model, o.result.human_qpos, o.human.sample_rate_hz, subject, o.job.condition,
                           o.job.trial, t0_s=o.human.t0_s)


def ground_of(o: RolloutOutcome) -> dict[str, GroundReaction]:
    """The recorded ground reactions from the first kept sample on (the lead-in is not exported)."""
    n = len(o.result.time_s)
    first = len(o.probe.force) - n
    return {side: GroundReaction(*arrays) for side, arrays in o.probe.arrays(first).items()}


def static_trial(model: mujoco.MjModel, subject: str, rate_hz: float) -> Trial:
    """`STATIC_S` of the model standing still in its `static` keyframe (its scaling pose)."""
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "static")
    q = model.key_qpos[key] if key >= 0 else model.qpos0
    n = int(round(STATIC_S * rate_hz)) + 1
    return trial_from_qpos(model, np.tile(q, (n, 1)), rate_hz, subject, "static", "static")


def readme(subject: str, scenario: str | None, rows: list, neutral_in_base_m: np.ndarray | None) -> str:
    """What the export folder holds."""
    lines = [f"# gaitloop export: {subject}, {'scenario ' + scenario if scenario else 'replay human'}", "",
             "Simulated trials written by `python -m pipeline export` (gaitloop). Frames: OpenSim's, "
             f"{UP_AXIS.upper()} up, X forward (the simulation's walking direction), Z to the right.", "",
             "| file | what |", "|---|---|",
             "| `<trial>.trc` | virtual markers (mm), named as the subject's real markers; with the robot "
             f"also {', '.join(ROBOT_MARKERS)} (two on the base along its heading, the arm's end) |",
             "| `<trial>_ik.mot` | joint coordinates (degrees; OpenSim names and signs; knee flexion +; "
             "pelvis_tx/ty/tz in m) |",
             "| `<trial>_grf.mot` | ground reaction per foot from the simulated foot contacts: `r_`/`l_` "
             "ground_force_v* (N), _p* centre of pressure (m, 0 while unloaded), ground_torque_* (N m) |",
             "| `<trial>_grf.xml` | OpenSim ExternalLoads applying them to calcn_r / calcn_l |",
             "| `<trial>_robot.csv` | the robot's log (gaitloop robot log v1, see the project README) |",
             "| `static.trc` | the model standing in its static pose, 1 s (a static trial for scaling) |",
             "| `model.xml` | the scaled MuJoCo human (MJCF) that walked |", "",
             "## Trials", "", "| trial | condition | seed | fell at (s) |", "|---|---|---|---|"]
    for job, _, fell in rows:
        at = "" if fell is None else f"{fell:.2f}"
        lines.append(f"| {job.trial} | {job.condition} | {job.seed} | {at} |")
    lines += ["", "## Read them back", "",
              "`python -m pipeline add-subject <new id> --height-m H --mass-kg M --static static.trc "
              "--up-axis y --markerset <set> --round-trip-of " + subject + " --trial "
              "<condition>=<trial>.trc,<trial>_ik.mot,,<trial>_robot.csv ...` registers them as a "
              "recorded subject (a round trip: the store and report label it so).", ""]
    if neutral_in_base_m is not None:
        x, y, z = (float(v) for v in neutral_in_base_m)
        lines += ["Without the robot logs, the markers on the robot give the same signals: add to the "
                  "subject file", "", "```yaml", "robot_markers:", f"  base_front: {ROBOT_MARKERS[0]}",
                  f"  base_rear: {ROBOT_MARKERS[1]}", f"  arm_end: {ROBOT_MARKERS[2]}",
                  f"  neutral_in_base_m: [{x:.6f}, {y:.6f}, {z:.6f}]", "```", ""]
    return "\n".join(lines)


__all__ = ["export_folder", "run_export"]
