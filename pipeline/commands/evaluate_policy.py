"""Command `evaluate-policy <subject>`: does the trained walking policy walk like its subject?

Seeded walks of the policy human through the batch runner: free walking, walking with each
controller of `rollout.conditions`, and free walking with a lateral pelvis push. The checks and
their thresholds are `metrics.policy_checks` with `evaluate_policy.checks` of params.yaml; the SPM
figure goes to `reports/<subject>/policy_spm.png`.
"""

from __future__ import annotations

import time
from pathlib import Path

import mujoco
import pandas as pd

from ingest.subject import load_subject
from metrics.compliance import compliance_headline
from metrics.plots import policy_spm_figure
from metrics.policy_checks import curves, enough, gait_check, spm_check
from pipeline import paths
from pipeline.params import Params
from pipeline.stages.outputs import write_figure
from pipeline.stages.simulate import policy_job, policy_setup
from sim.learn.policy_human import PolicyWalk
from sim.learn.train import BODY_FILE
from sim.motion.reference import load_reference
from sim.rollout.batch import RolloutOutcome, batch_tables, reference_cycles, run_batch

SPM_JOINTS = ("hip_flexion", "knee_flexion")


def evaluate_policy(subject: str, params: Params, root: Path = paths.PROCESSED_ROOT,
                    policy_root: Path = paths.POLICIES_ROOT, reports: Path = paths.REPORTS_ROOT,
                    progress: bool = True) -> dict:
    ev, checks = params.evaluate_policy.build(), params.evaluate_policy.checks.build()
    start = time.perf_counter()
    seeds = range(ev.n_seeds)
    controllers = [c for c in params.rollout.conditions if c != "free"]
    push_s = min(ev.free_s, ev.push_time_s + ev.push_recovery_s)
    jobs = [policy_job("free", s, PolicyWalk(ev.free_s)) for s in seeds]
    jobs += [policy_job(c, s, PolicyWalk(ev.robot_s)) for c in controllers for s in seeds]
    jobs += [policy_job("free", s, PolicyWalk(push_s, ev.push_n * (1 if s % 2 == 0 else -1), ev.push_time_s,
                                              ev.push_duration_s), tag="push") for s in seeds]
    outcomes = run_batch(policy_setup(subject, params, root, policy_root), jobs, params.rollout.workers,
                         f"policy rollouts {subject}", progress)
    pushed = [o for o in outcomes if o.job.human.push_n]
    groups: dict[str, list[RolloutOutcome]] = {
        "free": [o for o in outcomes if o.job.condition == "free" and not o.job.human.push_n],
        **{c: [o for o in outcomes if o.job.condition == c] for c in controllers}}
    real = paths.real_dir(root, subject)
    real_strides = pd.read_parquet(real / "strides.parquet")
    real_cycles = pd.read_parquet(real / "cycles.parquet")
    # the policy imitates free walking: its gait is compared with the free-walking strides
    real_kept = real_strides[real_strides["kept"] & (real_strides["condition"] == "free")]
    real_free_cycles = real_cycles[real_cycles["condition"] == "free"]
    free = batch_tables(groups["free"])  # cycles exist for kept strides only (ingest.cycles)
    sim_kept = free["strides"][free["strides"]["kept"]] if not free["strides"].empty else free["strides"]
    sim_cycles = free["cycles"]
    n_free_ok = sum(not o.fell for o in groups["free"])
    doc: dict = {"subject": subject, "human_mode": "policy"}
    doc["free"] = {"rollouts": len(groups["free"]), "no_fall": n_free_ok,
                   "pass_no_fall": enough(n_free_ok, len(groups["free"]), checks.free_no_fall_fraction),
                   "distance_m": [round(o.distance_m, 2) for o in groups["free"]],
                   **gait_check(real_kept, sim_kept, real_free_cycles, sim_cycles, checks)}
    for c in controllers:
        ok = sum(not o.fell for o in groups[c])
        doc[c] = {"rollouts": len(groups[c]), "no_fall": ok,
                  "pass_no_fall": enough(ok, len(groups[c]), checks.robot_no_fall_fraction),
                  "human_falls": sum(o.human_fall_s is not None for o in groups[c]),
                  "robot_fall_detections": sum(o.robot_fall_s is not None for o in groups[c])}
    robot = batch_tables([o for c in controllers for o in groups[c]])["robot"]
    doc["compliance"] = compliance_headline(robot, params.metrics.exclude_locked)
    recovered = sum(not o.fell for o in pushed)
    doc["push"] = {"force_n": ev.push_n, "duration_s": ev.push_duration_s, "at_s": ev.push_time_s,
                   "walk_s": push_s, "rollouts": len(pushed), "recovered": recovered,
                   "pass": enough(recovered, len(pushed), checks.push_recovered_fraction)}
    xml, npz = paths.human_xml(root, subject), paths.reference_npz(root, subject)
    policy_body = paths.policy_dir(policy_root, subject) / BODY_FILE
    in_model = reference_cycles(mujoco.MjModel.from_xml_path(str(policy_body)), load_reference(npz), subject,
                                load_subject(subject).markerset, params.ingest.build())
    spm, shown = {}, {}
    for joint in SPM_JOINTS:
        dataset, model_real = curves(real_free_cycles, joint), curves(in_model, joint)
        means, every = curves(sim_cycles, joint, per=("trial",)), curves(sim_cycles, joint)
        spm[joint] = {"primary": spm_check(model_real, means, checks, min_a=ev.spm_min_real_cycles),
                      "vs_dataset_rollout_means": spm_check(dataset, means, checks),
                      "vs_dataset_all_cycles": spm_check(dataset, every, checks),
                      "model_vs_dataset": spm_check(dataset, model_real, checks)}
        spm[joint]["pass"] = spm[joint]["primary"]["pass"]
        shown[joint] = {"real (dataset IK)": dataset, "real (same model)": model_real,
                        "policy (rollout means)": means}
    spm["primary_test"] = (f"real free walking retargeted onto the policy's body and processed like the "
                           f"simulation (virtual markers, same ingest) vs one mean curve per "
                           f"{ev.free_s:.0f}-s policy rollout; anova1, alpha {checks.spm_alpha}; "
                           f"pass: no cluster longer than "
                           f"{checks.max_spm_cluster_pct:.0f} % of the cycle")
    doc["spm"] = spm
    png = paths.report_dir(reports, subject) / "policy_spm.png"
    write_figure(policy_spm_figure(shown, spm, subject), png, params.report.dpi)
    doc["policy_body_is_current_model"] = policy_body.read_bytes() == xml.read_bytes()
    doc["figure"] = paths.repo_relative(png)
    doc["unstable_rollouts"] = sum(not o.stable for o in outcomes)
    doc["skipped"] = [f"{o.job.trial}: {o.skipped}" for o in outcomes if o.skipped]
    free = doc["free"]
    doc["checks"] = {
        "free_no_fall": free["pass_no_fall"], "free_speed": free["pass_speed"],
        "free_stride_length": free["pass_stride_length"], "free_knee_peak": free["pass_knee_peak"],
        **{f"{c}_no_fall": doc[c]["pass_no_fall"] for c in controllers}, "push": doc["push"]["pass"],
        **{f"spm_{j}": spm[j]["pass"] for j in SPM_JOINTS}}
    doc["wall_s"] = round(time.perf_counter() - start, 1)
    return doc


__all__ = ["evaluate_policy"]
