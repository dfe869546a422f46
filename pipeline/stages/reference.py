"""Stage `reference <subject>`: the subject's real walking retargeted onto the scaled human.

Input: `<root>/<subject>/model/human.xml` (the `scale` stage). Each trial whose condition is in
`retarget.conditions` is loaded, gap-filled, filtered and segmented by ingest exactly as in the
`ingest` stage, then solved frame by frame by marker IK (`sim.motion.retarget`). Outputs:
`<root>/<subject>/model/reference.npz` (`sim.motion.reference.Reference`), `reference.json` (fit metrics,
a DVC metrics file) and `reports/<subject>/retarget.png` (hip, knee, ankle of the retargeted motion
against the real `.mot` angles), written all-or-nothing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ingest.canonical import load_trial
from ingest.manifest import Manifest
from ingest.process import IngestParams, process_trial
from ingest.subject import load_subject
from ingest.trial import JOINTS, SIDES
from pipeline.params import Params, RetargetSection
from pipeline.paths import PROCESSED_ROOT, REPORTS_ROOT, human_xml, model_dir, reference_npz, report_dir
from pipeline.stages.outputs import json_text, replacing
from sim.errors import SimulationError
from sim.motion.reference import (
    Reference,
    ReferenceCycle,
    RetargetedTrial,
    cycle_from_trials,
    left_right_shift,
    retarget_trial,
    save_reference,
)
from sim.motion.retarget import joint_angles


def load_model(path: Path):
    """The scaled human written by the `scale` stage (via the model's own loader)."""
    if not path.exists():
        raise SimulationError(path, "no scaled human model: run `python -m pipeline scale <subject>` first")
    from sim.body.human import load_human_model

    return load_human_model(path)


def angle_errors(model, trial: RetargetedTrial, real: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-frame retargeted-minus-real sagittal angles (deg) for hip, knee, ankle of both sides."""
    sim = joint_angles(model, trial.qpos)
    return {f"{j}_{s}": sim[f"{j}_{s}"] - real[f"{j}_{s}"]
            for j in JOINTS for s in SIDES if f"{j}_{s}" in sim and f"{j}_{s}" in real}


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


def angle_summary(errors: dict[str, list[np.ndarray]]) -> dict[str, dict[str, float]]:
    """Per joint: RMS of the raw difference, the constant offset (mean difference, e.g. differing
    neutral-pose definitions) and the RMS once that offset is removed."""
    out = {}
    for name, parts in errors.items():
        e = np.concatenate(parts)
        offset = float(np.nanmean(e))
        out[name] = {"rms_deg": round(_rms(e), 3), "offset_deg": round(offset, 3),
                     "rms_offset_removed_deg": round(_rms(e - offset), 3)}
    return out


def cycle_summary(cycle: ReferenceCycle, used: pd.DataFrame) -> dict:
    """The periodic cycle's stride length and speed against the real strides it was built from."""
    real_length = float(used["stride_length_m"].mean())
    real_speed = float(used["gait_speed_mps"].mean())
    return {
        "n_strides": cycle.n_strides, "side": cycle.side, "period_s": round(cycle.period_s, 4),
        "floor_shift_m": round(cycle.floor_shift_m, 4),
        "stride_length_m": round(cycle.stride_length_m, 4), "speed_mps": round(cycle.speed_mps, 4),
        "real_stride_length_m": round(real_length, 4), "real_speed_mps": round(real_speed, 4),
        "stride_length_rel_error": round(cycle.stride_length_m / real_length - 1, 4),
        "speed_rel_error": round(cycle.speed_mps / real_speed - 1, 4),
    }


def plot_retarget(path: Path, subject: str, model, trials: list[RetargetedTrial],
                  real: dict[str, dict[str, np.ndarray]]) -> None:
    """Hip, knee, ankle flexion over time: retargeted (colour) vs real `.mot` (black), one column
    per trial (at most three), left dashed, right solid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = trials[:3]
    widths = [max(t.time_s[-1] - t.time_s[0], 1.0) for t in shown]
    fig, axes = plt.subplots(len(JOINTS), len(shown), figsize=(4 + 1.2 * sum(widths), 7), squeeze=False,
                             sharey="row", gridspec_kw={"width_ratios": widths})
    for c, tr in enumerate(shown):
        sim = joint_angles(model, tr.qpos)
        for r, joint in enumerate(JOINTS):
            ax = axes[r, c]
            for side, style in (("left", "--"), ("right", "-")):
                key = f"{joint}_{side}"
                if key in real[tr.trial]:
                    ax.plot(tr.time_s, real[tr.trial][key], "k" + style, lw=0.9,
                            label=f".mot {side}" if r == c == 0 else None)
                if key in sim:
                    ax.plot(tr.time_s, sim[key], style, color="C3" if side == "right" else "C0", lw=1.0,
                            label=f"retargeted {side}" if r == c == 0 else None)
            if c == 0:
                ax.set_ylabel(f"{joint.replace('_', ' ')} (deg)")
            if r == 0:
                ax.set_title(f"{tr.trial}: marker RMS {tr.fit.overall_rms_m * 100:.2f} cm", fontsize=9)
            if r == len(JOINTS) - 1:
                ax.set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=7, ncol=2, loc="upper left")
    fig.suptitle(f"{subject}: retargeted motion vs real IK angles")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)


def retarget_subject(subject_id: str, model, ip: IngestParams, section: RetargetSection,
                     progress: bool = False) -> tuple[Reference, dict, list[RetargetedTrial],
                                                      dict[str, dict[str, np.ndarray]]]:
    """Retarget the subject's trials of the configured conditions; returns the reference, the
    metrics document, the retargeted trials and the real (filtered) angles per trial."""
    subject = load_subject(subject_id)
    manifest = Manifest.load()
    specs = [s for s in subject.trials if s.condition in section.reference.conditions]
    if not specs:
        raise SimulationError(subject.path, f"no trial with condition in {section.reference.conditions}")
    trials, real, strides = [], {}, []
    for spec in specs:
        processed = process_trial(load_trial(subject, spec, manifest), subject.markerset, ip)
        trials.append(retarget_trial(model, processed, section.ik, section.reference, progress=progress))
        real[spec.id] = processed.trial.angles
        strides.append(processed.strides)
    cycle, used = cycle_from_trials(model, trials, pd.concat(strides, ignore_index=True), section.reference)
    reference = Reference.from_trials(trials, cycle)
    doc = fit_metrics(subject_id, model, trials, real, section.reference.conditions[0])
    doc["cycle"] = cycle_summary(cycle, used) | {"left_right": left_right_shift(model, cycle)}
    return reference, doc, trials, real


def fit_metrics(subject_id: str, model, trials: list[RetargetedTrial], real: dict[str, dict[str, np.ndarray]],
                main_condition: str) -> dict:
    """Marker and angle fit per trial and pooled over the trials of `main_condition`."""
    per_trial, pooled_err, pooled_rms = {}, {}, []
    n_frames = sum(len(t.time_s) for t in trials)
    for t in trials:
        errs = angle_errors(model, t, real[t.trial])
        per_trial[t.trial] = {
            "condition": t.condition, "n_frames": len(t.time_s),
            "marker_rms_m": round(t.fit.overall_rms_m, 5),
            "marker_rms_max_frame_m": round(float(np.nanmax(t.fit.rms_m)), 5),
            "markers_rms_m": {n: round(float(v), 5) for n, v in zip(t.fit.marker_names, t.fit.marker_rms_m,
                                                                  strict=True)},
            "angles": angle_summary({k: [v] for k, v in errs.items()}),
        }
        if t.condition == main_condition:
            pooled_rms.append(t.fit.rms_m)
            for k, v in errs.items():
                pooled_err.setdefault(k, []).append(v)
    ik_s = sum(t.ik_s for t in trials)
    rms = np.concatenate(pooled_rms)
    return {
        "subject": subject_id, "condition": main_condition, "n_frames": n_frames,
        "ik_frames_per_s": round(n_frames / ik_s, 1),
        "marker_rms_m": round(float(np.sqrt(np.nanmean(rms ** 2))), 5),
        "angles": angle_summary(pooled_err),
        "trials": per_trial,
    }


def run_reference(subject_id: str, params: Params, root: Path = PROCESSED_ROOT,
                  reports: Path = REPORTS_ROOT, progress: bool = True) -> dict:
    """Retarget a subject and write reference.npz, reference.json and retarget.png; returns the
    metrics document."""
    section = params.retarget.build()
    folder = model_dir(root, subject_id)
    model = load_model(human_xml(root, subject_id))
    reference, doc, trials, real = retarget_subject(subject_id, model, params.ingest.build(), section,
                                                    progress=progress)
    npz, js = reference_npz(root, subject_id), folder / "reference.json"
    png = report_dir(reports, subject_id) / "retarget.png"
    with replacing(npz, js, png) as (t_npz, t_js, t_png):
        with open(t_npz, "wb") as fh:
            save_reference(fh, reference)
        t_js.write_text(json_text(doc))
        plot_retarget(t_png, subject_id, model, trials, real)
    return doc
