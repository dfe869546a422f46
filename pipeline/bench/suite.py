"""Command `bench`: ingest throughput on the bundled real recordings.

Each measured run is `load_trial` (sha256 check, read, canonical frame) + `process_trial` (gap
fill, filter, events, strides, cycles) with a fresh manifest, so the file hash is paid as in a
real run. One untimed warm-up, then the best of `repeat` runs (`time.perf_counter`); the Camargo
trial and its bare floor take turns, 10 x `repeat` rounds, and their ratio is the target.

Retargeting (`time_retarget`): marker IK (`sim.motion.retarget.retarget`) of the whole Camargo trial and
of opencap4's free walks on their scaled humans (built in memory from params), best of `repeat`
runs for opencap4 and of two for the 15-s Camargo trial; ingest is not timed there.

Human model (`time_human`): build + compile time of each subject's scaled human and the raw
`mj_step` rate of that human standing (see the function).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from ingest.canonical import load_trial
from ingest.manifest import Manifest
from ingest.process import IngestParams, process_trial
from ingest.subject import Subject, TrialSpec, load_subject
from pipeline.bench import SECTIONS
from pipeline.params import Params
from sim.body.human_params import HumanParams
from sim.motion.reference import ReferenceParams

TARGETS = {"camargo_trial_s": 0.2, "camargo_floor_fraction": 0.5}  # ingest within 2x the bare floor
INGEST_ROUNDS_PER_REPEAT = 10  # a Camargo round (trial + floor) takes ~60 ms: more rounds, less noise
RETARGET_TARGETS = {"retarget_camargo_trial_s": 10.0}  # ~3000 frames in seconds, not minutes


def ingest_once(subject: Subject, trials: tuple[TrialSpec, ...], manifest: Manifest, p: IngestParams
                ) -> Callable[[], int]:
    """One timed unit: ingest `trials` of `subject` with a fresh manifest; returns their frames."""

    def once() -> int:
        fresh = Manifest(manifest.sources, manifest.mirror, manifest.cache)
        return sum(process_trial(load_trial(subject, spec, fresh), subject.markerset, p).trial.n_frames
                   for spec in trials)

    return once


def floor_once(path: Path, p: IngestParams) -> Callable[[], None]:
    """One timed unit of the bare floor of ingesting a marker file: pandas' parse of the .trc data
    rows plus one zero-phase low-pass (`sosfiltfilt`) over all its channels."""
    from scipy.signal import butter, sosfiltfilt

    def once() -> None:
        raw = pd.read_csv(path, sep="\t", header=None, skiprows=6, engine="c").to_numpy(float)
        rate = 1.0 / float(np.median(np.diff(raw[:, 1])))
        sos = butter(p.filter.order // 2, p.filter.cutoff_hz, fs=rate, output="sos")
        sosfiltfilt(sos, np.nan_to_num(raw[:, 2:]), axis=0)

    return once


def best_times(units: list[Callable[[], object]], repeat: int) -> list[float]:
    """Best wall time (s) of each unit over `repeat` rounds, after one untimed warm-up round. The
    units take turns within a round, so a slow spell of the machine hits them alike and a ratio of
    their times stays fair."""
    for unit in units:
        unit()
    best = [float("inf")] * len(units)
    for _ in range(repeat):
        for i, unit in enumerate(units):
            start = time.perf_counter()
            unit()
            best[i] = min(best[i], time.perf_counter() - start)
    return best


def time_retarget(params: Params, repeat: int) -> dict:
    """IK frames per second on camargo's trial and opencap4's free walks (see module docstring)."""
    from ingest.static import read_static_trial
    from sim.body.human import build_human
    from sim.body.scaling import scale_subject
    from sim.motion.retarget import retarget

    manifest, p = Manifest.load(), params.section("ingest", IngestParams)
    hp = params.section("human", HumanParams)
    ik = params.section("retarget", ReferenceParams).ik
    out = {}
    for sid, runs in (("camargo", min(repeat, 2)), ("opencap4", repeat)):
        subject = load_subject(sid)
        static = read_static_trial(subject, manifest, widths_per_height=hp.widths_per_height)
        model = build_human(scale_subject(subject, static, hp), hp).compile()
        markers = [process_trial(load_trial(subject, s, manifest), subject.markerset, p).trial.markers
                   for s in subject.trials if s.condition == "free"]
        best = float("inf")
        for _ in range(max(runs, 1)):
            start = time.perf_counter()
            for m in markers:
                retarget(model, m, ik)
            best = min(best, time.perf_counter() - start)
        n = sum(len(next(iter(m.values()))) for m in markers)
        out |= {f"retarget_{sid}_trial_s": round(best, 3), f"retarget_{sid}_frames": n,
                f"retarget_{sid}_frames_per_s": round(n / best)}
    return out


def time_human(params: Params, repeat: int, standing_s: float = 5.0) -> dict:
    """Human model: `build_human` + `MjSpec.compile` time (best of `repeat`, after the static trial
    is scaled once, untimed) and the raw `mj_step` rate of the human standing in its static pose
    under the pose-hold PD: only the `mj_step` calls are timed (the PD runs between them), so
    steps/s is the physics' own limit that rollout rates are compared to."""
    import mujoco

    from ingest.static import read_static_trial
    from sim.body.human import build_human, pose_hold_ctrl, pose_hold_gains
    from sim.body.scaling import scale_subject

    manifest, hp = Manifest.load(), params.section("human", HumanParams)
    out = {}
    for sid in ("camargo", "opencap4"):
        subject = load_subject(sid)
        static = read_static_trial(subject, manifest, widths_per_height=hp.widths_per_height)
        body = scale_subject(subject, static, hp)
        build = float("inf")
        for _ in range(max(repeat, 1)):
            start = time.perf_counter()
            model = build_human(body, hp).compile()
            build = min(build, time.perf_counter() - start)
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key("static").id)
        qref, (kp, kd) = data.qpos.copy(), pose_hold_gains(model, hp)
        n, stepping = round(standing_s / model.opt.timestep), 0.0
        for _ in range(n):
            data.ctrl[:] = pose_hold_ctrl(model, data, qref, kp, kd)
            start = time.perf_counter()
            mujoco.mj_step(model, data)
            stepping += time.perf_counter() - start
        out[f"human_{sid}_build_compile_s"] = round(build, 4)
        out[f"human_{sid}_mj_step_per_s"] = round(n / stepping)
        out[f"human_{sid}_realtime_factor"] = round(n * model.opt.timestep / stepping, 1)
    return out


def meets(section: dict, targets: dict[str, float]) -> bool:
    """Durations (keys ending in `_s`) are upper bounds; rates and ratios are lower bounds."""
    return all(section[k] <= v if k.endswith("_s") else section[k] >= v for k, v in targets.items())


def run_ingest_bench(p: IngestParams, repeat: int) -> dict:
    """Ingest timings of the Camargo trial and of all OpenCap subject-4 trials."""
    manifest = Manifest.load()
    camargo, opencap = load_subject("camargo"), load_subject("opencap4")
    cam = ingest_once(camargo, camargo.trials[:1], manifest, p)
    oc = ingest_once(opencap, opencap.trials, manifest, p)
    cam_frames, oc_frames = cam(), oc()
    cam_s, floor_s = best_times([cam, floor_once(manifest.resolve(camargo.trials[0].markers), p)],
                                INGEST_ROUNDS_PER_REPEAT * repeat)
    (oc_s,) = best_times([oc], repeat)
    return {
        "camargo_trial_s": round(cam_s, 4),
        "camargo_frames": cam_frames,
        "camargo_frames_per_s": round(cam_frames / cam_s),
        "camargo_floor_s": round(floor_s, 4),               # parse + one sosfiltfilt, same run
        "camargo_floor_fraction": round(floor_s / cam_s, 3),  # >= 0.5: within 2x the floor
        "opencap4_trials": len(opencap.trials),
        "opencap4_s": round(oc_s, 4),
        "opencap4_frames": oc_frames,
        "opencap4_frames_per_s": round(oc_frames / oc_s),
    }


def run_bench(params: Params, repeat: int = 5, sections: tuple[str, ...] = SECTIONS) -> dict:
    """The benchmark sections asked for, each with its own `targets` and `meets_targets`:
    ingest (`TARGETS`), retarget (`RETARGET_TARGETS`), human (no target: the physical limit that
    rollouts are compared to), store (`STORE_TARGETS`), rollout and policy_rollout (ratio to raw
    `mj_step`), sweep (Ray: parallel efficiency, overhead per job), train (training vs env-only steps/s),
    transfer (steps and wall time to a gate-passing transferred policy, `transfer.bench`)."""
    unknown = sorted(set(sections) - set(SECTIONS))
    if unknown:
        raise ValueError(f"unknown bench sections {unknown} (known: {', '.join(SECTIONS)})")
    result: dict = {"repeat": repeat}
    for name in sections:
        if name == "ingest":
            section, targets = run_ingest_bench(params.section("ingest", IngestParams), repeat), TARGETS
        elif name == "retarget":
            section, targets = time_retarget(params, repeat), RETARGET_TARGETS
        elif name == "human":
            section, targets = time_human(params, repeat), {}
        elif name == "store":
            from pipeline.bench.store import STORE_TARGETS, time_store

            section, targets = time_store(params, min(repeat, 3)), STORE_TARGETS
        elif name == "policy_rollout":
            from pipeline.bench.policy_rollout import POLICY_ROLLOUT_TARGETS, time_policy_rollout

            section, targets = time_policy_rollout(params, min(repeat, 3)), POLICY_ROLLOUT_TARGETS
        elif name == "sweep":
            from pipeline.bench.sweep import SWEEP_TARGETS, time_sweep

            section, targets = time_sweep(params), SWEEP_TARGETS
        elif name == "train":
            from pipeline.bench.train import TRAIN_TARGETS, time_training

            section, targets = time_training(params), TRAIN_TARGETS
        elif name == "transfer":
            from pipeline.bench.transfer import TRANSFER_TARGETS, time_transfer

            section, targets = time_transfer(params), TRANSFER_TARGETS
        else:
            from pipeline.bench.rollout import run_rollout_bench

            section = run_rollout_bench(params)
            targets = section.pop("targets", {})
            section.pop("meets_targets", None)
        section["targets"] = dict(targets)
        section["meets_targets"] = meets(section, targets)
        result[name] = section
    result["meets_targets"] = all(result[n]["meets_targets"] for n in sections)
    return result
