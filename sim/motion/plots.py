"""Figures of motion on the model: what needs the MuJoCo model to draw (joint angles read from
model configurations), so it lives beside the motion rather than in `metrics.plots`, whose figures
draw stored tables only.

Each function returns a matplotlib Figure (Agg); the caller writes and closes it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from ingest.trial import JOINTS
from sim.motion.reference import RetargetedTrial
from sim.motion.retarget import joint_angles

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def retarget_figure(subject: str, model: mujoco.MjModel, trials: list[RetargetedTrial],
                    real: dict[str, dict[str, np.ndarray]]) -> Figure:
    """Hip, knee, ankle flexion over time: retargeted (colour) vs real `.mot` (black), one column
    per trial (at most three), left dashed, right solid; `real` holds each trial's recorded angles
    by trial id."""
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
    return fig
