"""Report figures from stored tidy tables. Plotting only: every number drawn was computed by the
metrics and read back from the store; nothing here computes a statistic.

Each function takes the tidy table(s) of one subject and returns a matplotlib Figure (Agg).
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

JOINT_LABELS = {"hip_flexion": "Hip flexion (deg)", "knee_flexion": "Knee flexion (deg)",
                "ankle_dorsiflexion": "Ankle dorsiflexion (deg)"}


def group_label(source: str, human_mode: str, condition: str) -> str:
    return f"{source} {condition}" if source == "real" else f"{source}/{human_mode} {condition}"


def kinematics_figure(bands: pd.DataFrame, title: str) -> Figure:
    """Mean ± SD joint angle over the gait cycle per source and condition (the paper's Fig. 4)."""
    joints = [j for j in JOINT_LABELS if j in set(bands["joint"])]
    fig, axes = plt.subplots(1, max(len(joints), 1), figsize=(4.2 * max(len(joints), 1), 3.6), squeeze=False)
    groups = bands[["source", "human_mode", "condition"]].drop_duplicates().sort_values(
        ["source", "human_mode", "condition"]).itertuples(index=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (source, mode, cond) in enumerate(groups):
        style = "-" if source == "real" else "--"
        for ax, joint in zip(axes[0], joints, strict=False):
            sel = ((bands["source"] == source) & (bands["human_mode"] == mode) & (bands["condition"] == cond)
                   & (bands["joint"] == joint))
            b = bands[sel].sort_values("pct")
            if b.empty:
                continue
            c = colors[k % len(colors)]
            n = int(b["n_cycles"].iloc[0])
            label = f"{group_label(source, mode, cond)} (n={n})"
            ax.plot(b["pct"], b["mean_deg"], style, color=c, label=label)
            sd = b["sd_deg"].fillna(0)
            ax.fill_between(b["pct"], b["mean_deg"] - sd, b["mean_deg"] + sd, color=c, alpha=0.18, lw=0)
    for ax, joint in zip(axes[0], joints, strict=False):
        ax.set_xlabel("Gait cycle (%)")
        ax.set_ylabel(JOINT_LABELS[joint])
        ax.grid(alpha=0.3)
    if joints:
        axes[0][0].legend(fontsize=7, loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def spm_figure(tests: pd.DataFrame, curves: pd.DataFrame, title: str) -> Figure:
    """SPM statistic curves with their critical threshold and supra-threshold clusters shaded (the
    paper's Fig. 3); one row per comparison, one column per joint. Skipped tests say why."""
    pairs = tests[["comparison", "source_a", "human_mode_a", "condition_a", "source_b", "human_mode_b",
                   "condition_b"]].drop_duplicates().sort_values(["comparison", "condition_b", "source_b"])
    joints = [j for j in JOINT_LABELS if j in set(tests["joint"])]
    nrows, ncols = max(len(pairs), 1), max(len(joints), 1)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.0 * ncols, 2.6 * nrows), squeeze=False)
    for i, pair in enumerate(pairs.itertuples(index=False)):
        label = (f"{group_label(pair.source_a, pair.human_mode_a, pair.condition_a)} vs "
                 f"{group_label(pair.source_b, pair.human_mode_b, pair.condition_b)}")
        for j, joint in enumerate(joints):
            ax = axes[i][j]
            t = tests[(tests["comparison"] == pair.comparison) & (tests["condition_a"] == pair.condition_a)
                      & (tests["source_a"] == pair.source_a) & (tests["condition_b"] == pair.condition_b)
                      & (tests["source_b"] == pair.source_b) & (tests["human_mode_b"] == pair.human_mode_b)
                      & (tests["joint"] == joint)]
            ax.set_title(f"{label}\n{JOINT_LABELS[joint].split(' (')[0]}", fontsize=8)
            if t.empty:
                ax.axis("off")
                continue
            row = t.iloc[0]
            if row["status"] != "ok":
                ax.text(0.5, 0.5, f"skipped:\n{row['reason']}", ha="center", va="center", fontsize=7,
                        wrap=True, transform=ax.transAxes)
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            c = curves[curves["test_id"] == row["test_id"]].sort_values("pct")
            ax.plot(c["pct"], c["value"], color="k", linewidth=1)
            ax.axhline(row["zstar"], color="r", linestyle="--", linewidth=0.8)
            if row["statistic"] == "t":
                ax.axhline(-row["zstar"], color="r", linestyle="--", linewidth=0.8)
            above = c["value"].abs() > row["zstar"] if row["statistic"] == "t" else c["value"] > row["zstar"]
            ax.fill_between(c["pct"], 0, c["value"], where=above, color="orange", alpha=0.5)
            ax.set_ylabel(f"SPM{{{row['statistic']}}}", fontsize=8)
            note = f"{row['statistic']}*={row['zstar']:.3g}"
            if row["h0_rejected"]:
                note += "; p_min<0.001" if row["min_p"] < 0.001 else f"; p_min={row['min_p']:.3f}"
            ax.text(0.98, 0.95, note, ha="right", va="top", fontsize=7, transform=ax.transAxes)
            ax.set_xlabel("Gait cycle (%)", fontsize=8)
    if pairs.empty:
        axes[0][0].text(0.5, 0.5, "no comparisons", ha="center", va="center")
        axes[0][0].axis("off")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def tracking_figure(tracking: pd.DataFrame, title: str) -> Figure:
    """Forward and lateral offset of the pelvis from the arm's neutral point and |F| of the harness
    over one run per condition."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for (source, mode, cond), g in tracking.groupby(["source", "human_mode", "condition"], sort=True):
        label = group_label(source, mode, cond)
        for ax, col in zip(axes, ("e_x_cm", "e_y_cm", "force_n"), strict=True):
            ax.plot(g["time_s"], g[col], label=label, linewidth=1)
    for ax, name in zip(axes, ("e_x (cm)", "e_y (cm)", "|F| harness (N)"), strict=True):
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("Time (s)")
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def harness_figure(harness: pd.DataFrame, title: str) -> Figure:
    """RMS and peak harness force and torque magnitude per condition."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, (quantity, unit) in zip(axes, (("f_norm", "N"), ("t_norm", "N m")), strict=True):
        h = harness[harness["quantity"] == quantity].sort_values(["source", "human_mode", "condition"])
        labels = [group_label(*r) for r in h[["source", "human_mode", "condition"]].itertuples(index=False)]
        x = range(len(h))
        ax.bar([i - 0.2 for i in x], h["rms"], width=0.4, label="RMS")
        ax.bar([i + 0.2 for i in x], h["peak"], width=0.4, label="peak")
        ax.set_xticks(list(x), labels, rotation=20, fontsize=8)
        ax.set_ylabel(f"|{'F' if quantity == 'f_norm' else 'T'}| ({unit})")
        ax.grid(alpha=0.3, axis="y")
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


EVENT_ROWS = {"ex_cm": "e_x (cm)", "ey_cm": "e_y (cm)", "force_n": "harness |f| (N)"}


def event_figure(traces: pd.DataFrame, events: list[str], title: str) -> Figure:
    """e_x, e_y and harness |f| around the commanded events (rows), one column per event in
    `events` (its scenario in the title, time 0 at the command's onset): one line per human mode and
    controller, mean across runs with its 95 % CI band (`metrics.phases.event_traces`)."""
    fig, axes = plt.subplots(len(EVENT_ROWS), max(len(events), 1), figsize=(4.2 * max(len(events), 1), 7.2),
                             sharex=True, squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    groups = sorted(set(zip(traces["human_mode"], traces["condition"], strict=True)))
    for j, event in enumerate(events):
        sel = traces[traces["event"] == event]
        scenarios = ", ".join(sorted(set(sel["scenario"])))
        axes[0][j].set_title(f"{event} ({scenarios})" if scenarios else event, fontsize=10)
        if not (sel["n_runs"] > 0).any():
            why = "no run has this event" if sel.empty else "no following samples\n(every run fell before)"
            mid = axes[1][j]
            mid.text(0.5, 0.5, why, ha="center", va="center", fontsize=9, transform=mid.transAxes)
        for k, (mode, cond) in enumerate(groups):
            g = sel[(sel["human_mode"] == mode) & (sel["condition"] == cond)].sort_values("t_s")
            if g.empty:
                continue
            label, c = f"{mode} {cond} (n={int(g['n_runs'].max())})", colors[k % len(colors)]
            for ax, q in zip(axes[:, j], EVENT_ROWS, strict=True):
                mean, ci = g[f"{q}_mean"], g[f"{q}_ci95"].fillna(0)
                ax.plot(g["t_s"], mean, color=c, label=label, linewidth=1.2)
                ax.fill_between(g["t_s"], mean - ci, mean + ci, color=c, alpha=0.2, lw=0)
    for ax in axes.flat:
        ax.axvline(0.0, color="k", linestyle=":", linewidth=0.8)
        ax.grid(alpha=0.3)
        if not traces.empty:
            ax.set_xlim(traces["t_s"].min(), traces["t_s"].max())
    for ax, name in zip(axes[:, 0], EVENT_ROWS.values(), strict=True):
        ax.set_ylabel(name)
    for ax in axes[-1]:
        ax.set_xlabel("Time from the command (s)")
    if axes[0][0].get_legend_handles_labels()[0]:
        axes[0][0].legend(fontsize=7, loc="best")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


POLICY_SPM_STYLES = {"real (dataset IK)": ("0.5", "--"), "real (same model)": ("k", "-"),
                     "policy (rollout means)": ("tab:blue", "-")}


def policy_spm_figure(curves_by_joint: dict, results: dict, subject: str) -> Figure:
    """Free walking of a policy human vs its subject (`evaluate-policy`): mean +- SD of the real
    curves (dataset IK and retargeted onto the model) and of the rollout means, with the
    supra-threshold clusters of the primary SPM test shaded."""
    import numpy as np

    fig, axes = plt.subplots(1, len(curves_by_joint), figsize=(5.5 * len(curves_by_joint), 4.0))
    for ax, (joint, groups) in zip(np.atleast_1d(axes), curves_by_joint.items(), strict=True):
        for name, data in groups.items():
            if data.size == 0:
                continue
            colour, ls = POLICY_SPM_STYLES[name]
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
    return fig


def tuning_figure(tuning: pd.DataFrame, title: str = "Controller tuning: held-back objective") -> Figure:
    """Generic vs tuned gains per controller and variant (`tune`): the held-back objective, mean with its
    95 % CI across rollouts (`tuning_comparison`), falls out of the held-back rollouts over each bar; a
    pair whose search had no signal (every search rollout fell) is labelled so."""
    rows = tuning.sort_values(["controller", "variant"]).reset_index(drop=True)
    fig, ax = plt.subplots(figsize=(max(6.0, 1.8 * len(rows) + 1.5), 3.8))
    for k, (which, colour) in enumerate((("generic", "0.6"), ("tuned", "tab:blue"))):
        x = [i + (k - 0.5) * 0.38 for i in range(len(rows))]
        mean, ci = rows[f"{which}_mean"].astype(float), rows[f"{which}_ci95"].astype(float).fillna(0.0)
        ax.bar(x, mean, width=0.36, yerr=ci, capsize=3, color=colour, label=f"{which} gains")
        for xi, m, c, falls, n in zip(x, mean, ci, rows[f"{which}_falls"], rows["n_heldout"], strict=True):
            ax.annotate(f"{int(falls)}/{int(n)} falls", (xi, m + c), xytext=(0, 2),
                        textcoords="offset points", ha="center", va="bottom", fontsize=7)
    # a search whose every rollout fell had no signal: its "tuned" gains are the generic ones
    status = rows["search_status"]
    flag = "\nno signal: all search\nrollouts fell"
    labels = [f"{r.controller}\n({r.variant})" + (flag if st == "no signal" else "")
              for r, st in zip(rows.itertuples(index=False), status, strict=True)]
    ax.set_xticks(list(range(len(rows))), labels, fontsize=8)
    ax.set_ylabel("objective (m), lower is better")
    ax.margins(y=0.15)
    ax.grid(alpha=0.3, axis="y")
    fig.legend(*ax.get_legend_handles_labels(), loc="lower center", ncol=2, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return fig


# -- virtual cohort and fall intervention (issue 13) --------------------------------------------------

# Cohort variants in the order params `cohort` lists them, the subject's own (healthy) twin first; a
# variant the tables hold that is not named here follows, sorted.
VARIANT_ORDER = ("healthy", "weak", "hemiparetic_left", "hemiparetic_right", "slow", "unsteady")


def ordered(names, known: tuple[str, ...]) -> list[str]:
    """The distinct `names` in the order of `known`, the others after it, sorted."""
    present = set(names)
    return [n for n in known if n in present] + sorted(present - set(known))


# column -> (panel title, colour map); speed change is diverging around 0 (faster / slower than free)
COHORT_PANELS = {"mean_abs_ex_cm": ("mean |e_x| (cm)", "viridis"),
                 "mean_abs_ey_cm": ("mean |e_y| (cm)", "viridis"),
                 "force_rms_n": ("harness force RMS (N)", "magma"),
                 "speed_change_pct": ("gait speed vs free (%)", "RdBu_r")}


def cohort_heatmap(controllers: pd.DataFrame, title: str, order: tuple[str, ...] = ()) -> Figure:
    """The virtual cohort under each controller (`cohort_controllers`): one panel per metric with its
    own colour scale, rows = variants, columns = controllers (in `order`, the caller's list of them;
    others after it, sorted), the value written in each cell (– where there is none). Drawn for
    scenario `steady`, or the first scenario the table has."""
    import numpy as np

    scenarios = sorted(set(controllers["scenario"])) if not controllers.empty else []
    scenario = "steady" if "steady" in scenarios else (scenarios[0] if scenarios else None)
    t = controllers[controllers["scenario"] == scenario] if scenario else controllers
    variants, conds = ordered(t["variant"], VARIANT_ORDER), ordered(t["condition"], order)
    size = (max(1.2 * len(conds) + 1.6, 3.0) * len(COHORT_PANELS), 0.45 * max(len(variants), 1) + 2.0)
    fig, axes = plt.subplots(1, len(COHORT_PANELS), figsize=size, squeeze=False)
    for ax, (col, (name, cmap)) in zip(axes[0], COHORT_PANELS.items(), strict=True):
        ax.set_title(name, fontsize=9)
        if t.empty:
            ax.text(0.5, 0.5, "no cohort walks with a robot", ha="center", va="center", fontsize=8,
                    transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
            continue
        grid = t.pivot_table(index="variant", columns="condition", values=col, aggfunc="first", dropna=False)
        values = grid.reindex(index=variants, columns=conds).to_numpy(float)
        finite = values[np.isfinite(values)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if cmap == "RdBu_r":  # centred on no change
            lo, hi = -max(abs(lo), abs(hi), 1e-9), max(abs(lo), abs(hi), 1e-9)
        else:  # from 0, so that close values look close
            lo, hi = min(lo, 0.0), max(hi, min(lo, 0.0) + 1e-9)
        image = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, vmin=lo, vmax=hi, aspect="auto")
        for (i, j), v in np.ndenumerate(values):
            shade = (v - lo) / (hi - lo) if np.isfinite(v) else 0.5
            light = 0.25 < shade < 0.75 if cmap == "RdBu_r" else shade > 0.6  # light cell: dark text
            ax.text(j, i, f"{v:.2f}" if np.isfinite(v) else "–", ha="center", va="center", fontsize=8,
                    color="k" if light or not np.isfinite(v) else "w")
        ax.set_xticks(range(len(conds)), conds, fontsize=8)
        ax.set_yticks(range(len(variants)), variants, fontsize=8)
        fig.colorbar(image, ax=ax, shrink=0.85)
    fig.suptitle(f"{title}, scenario {scenario}" if scenario else title)
    fig.tight_layout()
    return fig


# column -> y label of the fall-intervention panels, left to right
FALL_PANELS = {"detection_rate": "detected (share of events)", "latency_s": "onset to lock (s)",
               "pelvis_drop_at_lock_m": "pelvis drop at lock (m)",
               "peak_harness_force_n": "peak harness |f| (N)"}
# a second, marker-drawn column in some panels: the share caught of the events that fell free, the
# worst drop at the lock, the mean of the rollouts' peak forces
FALL_MARKERS = {"detection_rate": ("caught_rate_falling", "o", "caught, of events falling free"),
                "pelvis_drop_at_lock_m": ("worst_drop_at_lock_m", "v", "worst drop at lock"),
                "peak_harness_force_n": ("max_harness_force_n", "D", "mean of rollout peaks")}
EVENT_ORDER = ("trip", "slip", "collapse", "push")


def fall_intervention_figure(fall: pd.DataFrame, title: str, caught_drop_m: float,
                             order: tuple[str, ...] = ()) -> Figure:
    """How each controller met the scripted balance losses (`fall_intervention`): one row of panels
    per variant, event types on x, one bar per controller: the share of events detected (marker: the
    share caught of those that fell walking free), the latency from onset to the lock, the pelvis drop
    at the lock (marker: the worst; dashed: the caught threshold `caught_drop_m`) and the peak harness
    force (marker: the mean of the rollouts' peaks). Conditions without a robot (`free`) are left out;
    the controllers in `order` (the caller's list of them), others after it, sorted."""
    robot = fall[fall["condition"] != "free"] if not fall.empty else fall
    variants = ordered(robot["variant"], VARIANT_ORDER) or [""]
    events, conds = ordered(robot["event"], EVENT_ORDER), ordered(robot["condition"], order)
    size = (3.9 * len(FALL_PANELS), 2.9 * len(variants) + 0.6)
    fig, axes = plt.subplots(len(variants), len(FALL_PANELS), figsize=size, squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    width = 0.8 / max(len(conds), 1)
    for i, variant in enumerate(variants):
        rows = robot[robot["variant"] == variant]
        for ax, (col, label) in zip(axes[i], FALL_PANELS.items(), strict=True):
            ax.set_title(f"{variant}: {label}" if variant else label, fontsize=9)
            if rows.empty:
                ax.text(0.5, 0.5, "no rollouts with a robot", ha="center", va="center", fontsize=8,
                        transform=ax.transAxes)
                continue
            for k, cond in enumerate(conds):
                g = rows[rows["condition"] == cond].set_index("event").reindex(events)
                x = [e + (k - (len(conds) - 1) / 2) * width for e in range(len(events))]
                heights = g[col].astype(float)
                ax.bar(x, heights.fillna(0.0), width=width * 0.95, color=colors[k % len(colors)],
                       label=cond if i == 0 and col == "detection_rate" else None)
                for xi, h in zip(x, heights, strict=True):  # no value: a dash; zero: a 0 (no bar to see)
                    if pd.isna(h) or h == 0:
                        ax.text(xi, 0, "–" if pd.isna(h) else "0", ha="center", va="bottom", fontsize=8)
                if col in FALL_MARKERS:
                    other, marker, name = FALL_MARKERS[col]
                    ax.plot(x, g[other].astype(float), marker, color="k", markerfacecolor="none", ms=5,
                            linestyle="none", label=name if i == 0 and k == 0 else None)
            if col == "pelvis_drop_at_lock_m":
                ax.axhline(caught_drop_m, color="r", linestyle="--", linewidth=0.9,
                           label=f"caught threshold {caught_drop_m:.2f} m" if i == 0 else None)
            if col == "detection_rate":
                ax.set_ylim(0, 1.05)
            ax.set_xticks(range(len(events)), events, fontsize=8)
            ax.grid(alpha=0.3, axis="y")
    handles = {}
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=len(handles), fontsize=8)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.05 if handles else 0, 1, 1))
    return fig


def training_progress_figure(curves: dict, title: str = "Universal walking policy: checks passed against "
                             "training") -> Figure:
    """A training run's progress (`pipeline.report.figures.progress_curves`): the quick gate's checks
    passed at each checkpoint and their running mean (left), the running mean per subject's own body
    (second), evaluate-policy's checks passed over every body at each adoption evaluation (third),
    each body's share of falls in training's episodes without random pushes (right, from where the
    record has it); dotted lines where a run segment began (its machine in the label, where it
    changed), dashed red ones where the observation or the layers were widened or the run taken back
    (in the legend, below the panels: it grows with the run's history and would hide the curve),
    crosses for the checkpoints of a branch given up, shading where teachers taught."""
    height = 3.8  # the panels' (inches); the legend below adds to it
    fig, (ax, ax2, ax3, ax4) = plt.subplots(1, 4, figsize=(18, height))
    panels = (ax, ax2, ax3, ax4)
    if not curves["steps"]:
        ax.text(0.5, 0.5, "no checkpoint yet", ha="center", va="center", transform=ax.transAxes)
        return fig
    steps, w = curves["steps"], curves["window"]
    ax.plot(steps, curves["passed"], "o", color="0.6", ms=2, label="each checkpoint")
    ax.plot(steps, curves["passed_mean"], "-", color="k", label=f"mean of the last {w}")
    for i, (x, passed) in enumerate(curves.get("discarded", [])):
        ax.plot(x, passed, "x", color="tab:red", ms=3, label=None if i else "branch given up")
    ax.set_ylim(0, curves["checks"])
    ax.set_ylabel(f"quick gate: checks passed (of {curves['checks']})")
    for i, (start, end) in enumerate(curves.get("taught", [])):
        for a in panels:
            a.axvspan(start, end, color="tab:orange", alpha=0.12, lw=0,
                      label="with a teacher" if a is ax and not i else None)
    for at, label in curves.get("changes", []):
        for a in panels:
            a.axvline(at, color="tab:red", linestyle="--", linewidth=0.8, label=label if a is ax else None)
    handles, labels = ax.get_legend_handles_labels()
    rows = -(-len(handles) // 3)  # in 3 columns under the figure, 0.17 inch a row
    below = 0.17 * rows + 0.15
    fig.set_size_inches(18, height + below)
    fig.legend(handles, labels, fontsize=7, ncol=3, loc="lower left", bbox_to_anchor=(0.01, 0.0),
               frameon=False)
    for s, mean in curves["own_mean"].items():
        ax2.plot(steps, mean, "-", label=s)
    ax2.set_ylabel(f"own body, mean of the last {w}")
    ax2.legend(fontsize=7, ncol=2)
    if curves["evaluations"]:
        of = max(e[2] for e in curves["evaluations"])
        for gone, style, label in ((False, "o-", "the run's checkpoints"), (True, "x", "a branch given up")):
            kept = [(x, passed) for x, passed, _, g in curves["evaluations"] if g == gone]
            if kept:
                ax3.plot(*zip(*kept, strict=True), style, color="tab:red", label=label)
        if any(e[3] for e in curves["evaluations"]):
            ax3.legend(fontsize=7, loc="lower right")
        ax3.set_ylim(0, of)
        ax3.set_ylabel(f"evaluate-policy: checks passed (of {of})")
    else:
        ax3.text(0.5, 0.5, "no adoption evaluation yet", ha="center", va="center", transform=ax3.transAxes)
    for body, (x, share) in sorted(curves.get("calm_falls", {}).items()):
        ax4.plot(x, share, ".-", ms=2, lw=0.8, label=body, color="0.5" if body == "drawn" else None)
    ax4.set_ylim(0, 1)
    ax4.set_ylabel("training: falls per calm episode")
    if curves.get("calm_falls"):
        ax4.legend(fontsize=6, ncol=2, loc="upper left")
    else:
        ax4.text(0.5, 0.5, "not recorded yet", ha="center", va="center", transform=ax4.transAxes)
    shown = None
    for start, where in curves["segments"]:
        for a in panels:
            a.axvline(start, color="0.6", linestyle=":", linewidth=0.8)
        if where != shown:
            ax.text(start, curves["checks"], where, fontsize=6, rotation=90, va="top", ha="right")
            shown = where
    last = max([*steps, *(x for xs, _ in curves.get("discarded", []) for x in xs)])
    for a in panels:
        a.set_xlabel("env steps (M)")
        a.set_xlim(0, last * 1.02)
        a.grid(alpha=0.3)
    recorded = [x for xs, _ in curves.get("calm_falls", {}).values() for x in xs]
    if recorded:  # the record is recent: its own stretch
        ax4.set_xlim(min(recorded) - 0.5, max(recorded) + 0.5)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, below / (height + below), 1, 1))
    return fig


# -- the twin's follow-me responsiveness (issue 34, view `sensitivity`) -------------------------------

SENSITIVITY_COLUMNS = ("pid_gain_scale", "drive_tau_s", "latency_s")  # factor order, left to right
SENSITIVITY_AXES = {"pid_gain_scale": ("PID gains (x twin's)", 1.0, "log"),
                    "drive_tau_s": ("base drive time constant (ms)", 1000.0, "log"),
                    "latency_s": ("command latency (ms)", 1000.0, "linear")}
CONDITION_COLORS = ("tab:orange", "tab:blue", "tab:green", "tab:purple", "tab:brown")  # by place in `order`


def condition_colors(names, order: tuple[str, ...] = ()) -> dict[str, str]:
    """condition -> colour: by its place in `ordered(names, order)`, so a controller keeps its colour
    across the figures that are given the same `order`."""
    return {c: CONDITION_COLORS[i % len(CONDITION_COLORS)] for i, c in enumerate(ordered(names, order))}


def sensitivity_figure(sens: pd.DataFrame, paper_sim: dict[str, tuple[float, float]], title: str,
                       order: tuple[str, ...] = ()) -> Figure:
    """Mean |e_x| (top) and |e_y| (bottom) against each responsiveness factor (columns), one line per
    controller (in `order`, the caller's list of them; others after it, sorted) with its 95 % CI across
    walks (`sensitivity` view of one subject); the walks that fell (human fall or arm lock) written over
    each point as falls/walks; the twin's level of each factor a dotted vertical line (a level where
    every controller runs the twin's robot); `paper_sim`: condition -> the paper's simulated (|e_x|,
    |e_y|) in cm, dashed horizontal lines (their robot and participant, for orientation)."""
    factors = [f for f in SENSITIVITY_COLUMNS if f in set(sens["factor"])] or list(SENSITIVITY_COLUMNS)
    fig, axes = plt.subplots(2, len(factors), figsize=(4.0 * len(factors), 6.4), squeeze=False, sharey="row")
    rows = (("mean_abs_ex_cm", "mean |e_x| (cm)"), ("mean_abs_ey_cm", "mean |e_y| (cm)"))
    colors = condition_colors({*sens["condition"], *paper_sim}, order)
    for j, factor in enumerate(factors):
        label, scale, xscale = SENSITIVITY_AXES.get(factor, (factor, 1.0, "linear"))
        sel = sens[sens["factor"] == factor]
        for i, (col, ylabel) in enumerate(rows):
            ax = axes[i][j]
            for cond in ordered(set(sel["condition"]), order):
                g = sel[sel["condition"] == cond].sort_values("level")
                x = g["level"].astype(float) * scale
                colour = colors.get(cond, "0.3")
                ax.errorbar(x, g[col].astype(float), yerr=g[f"{col}_ci95"].astype(float).fillna(0.0),
                            color=colour, marker="o", ms=4, capsize=3, label=f"{cond} (this twin)")
                for xi, y, falls, n in zip(x, g[col], g["falls"], g["n"], strict=True):
                    if falls > 0:
                        ax.annotate(f"{int(falls)}/{int(n)}", (xi, y), xytext=(3, 3),
                                    textcoords="offset points", fontsize=6, color=colour)
            for cond, (ex, ey) in paper_sim.items():
                ax.axhline((ex, ey)[i], color=colors.get(cond, "0.3"), linestyle="--",
                           linewidth=0.9, label=f"{cond}, paper sim (e_x {ex:.2f}, e_y {ey:.2f} cm)")
            # a controller that does not read a factor runs the twin at every level: the twin's level
            # is the one where every controller does
            at_twin = sel[sel["twin"].astype(bool)].groupby("level")["condition"].nunique()
            twin = at_twin.index[at_twin == sel["condition"].nunique()]
            for level in twin:
                ax.axvline(float(level) * scale, color="0.5", linestyle=":", linewidth=0.9)
            ax.set_xscale(xscale)
            ticks = sorted(set(sel["level"].astype(float)))
            ax.set_xticks([t * scale for t in ticks], [f"{t * scale:g}" for t in ticks], fontsize=8)
            ax.minorticks_off()
            ax.grid(alpha=0.3)
            if i == 1:
                ax.set_xlabel(label)
            if j == 0:
                ax.set_ylabel(ylabel)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return fig
