"""Quality gates: numbers that can be wrong without any stage failing, graded ok / warn / fail.

Each check is one row of `QUALITY_COLUMNS`: the subject, the stage whose output it judges, the check's
name, its value, the warn and fail thresholds, the status, its cause (why this status: the value
against the limit it passed or kept, or why no value) and a note (what the check measures). Most
checks are worse the higher the value (`status = fail` above `fail_above`); cycle counts are worse
the lower (below the thresholds; the note says so). A check that cannot be computed (no IK file to
compare with, no static trial, too few cycles for SPM) is `n/a` with its reason as the cause, never
`ok` and never `fail`: `fail` is kept for a measured defect. `worst` ranks fail > warn > ok and
leaves `n/a` out. Thresholds: params.yaml `quality` (`QualityParams`), each documented there with
the spread of the bundled subjects' values. A transferred walking policy's gate (`transfer_checks`)
adds one `policy` row per scenario check, pass = 1.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import Annotated, NamedTuple

import numpy as np
import pandas as pd
from pydantic import Field, with_config

QUALITY_COLUMNS = ["subject", "stage", "check", "value", "warn_above", "fail_above", "status", "cause",
                   "note"]
STATUS_ORDER = {"ok": 0, "warn": 1, "fail": 2}
NOT_COMPUTED = "n/a"  # a check without a value to grade: ranks nowhere in `worst`
SIDES = ("left", "right")
PAIRED_SEGMENTS = ("thigh", "shank", "foot", "upper_arm", "forearm", "hand")


class Limits(NamedTuple):
    """Warn and fail thresholds of one check (the value is graded against them); params.yaml writes
    them as [warn, fail]."""

    warn: float
    fail: float


@with_config(extra="forbid")
@dataclass(frozen=True)
class QualityParams:
    """The `quality` section of params.yaml: each limit is [warn, fail] in the check's unit."""

    marker_rms_m: Limits = field(default_factory=lambda: Limits(0.02, 0.04))
    asymmetry_pct: Limits = field(default_factory=lambda: Limits(5.0, 10.0))
    knee_alignment_deg: Limits = field(default_factory=lambda: Limits(5.0, 10.0))
    ik_angle_rms_deg: Limits = field(default_factory=lambda: Limits(5.0, 10.0))
    edge_window_s: Annotated[float, Field(gt=0.0)] = 0.05
    edge_strike_share: Limits = field(default_factory=lambda: Limits(0.2, 0.5))
    span_samples: Limits = field(default_factory=lambda: Limits(1.0, 10.0))
    speed_gap_pct: Limits = field(default_factory=lambda: Limits(10.0, 25.0))
    missing_sides: Limits = field(default_factory=lambda: Limits(0.0, 1.0))
    non_steady_share: Limits = field(default_factory=lambda: Limits(0.0, 0.25))
    repeated_walks: Limits = field(default_factory=lambda: Limits(0.0, 1.0))

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, tuple) and not value[0] <= value[1]:
                raise ValueError(f"{f.name}: warn must not exceed fail (got {list(value)})")


@dataclass(frozen=True)
class QualityCheck:
    """One row of the quality table."""

    subject: str
    stage: str
    check: str
    value: float
    warn_above: float
    fail_above: float
    status: str
    cause: str
    note: str = ""


def _missing(value: float | None) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def grade(value: float | None, warn: float, fail: float, higher_is_worse: bool = True) -> str:
    """'fail' past `fail`, 'warn' past `warn`, else 'ok' (past: above, or below when lower is worse);
    a missing value is 'n/a'."""
    if _missing(value):
        return NOT_COMPUTED
    v = float(value)
    if higher_is_worse:
        return "fail" if v > fail else "warn" if v > warn else "ok"
    return "fail" if v < fail else "warn" if v < warn else "ok"


def worst(statuses: Iterable[str]) -> str:
    """The worst of `statuses` (fail > warn > ok; `n/a` is not graded and left out); 'unknown' when
    there are none."""
    found = [s for s in statuses if s in STATUS_ORDER]
    return max(found, key=STATUS_ORDER.__getitem__) if found else "unknown"


def worst_check(q: pd.DataFrame) -> pd.Series | None:
    """The row of the quality table `q` with the worst graded status (the first such row in the
    table's order); None without a graded row."""
    graded = q[q["status"].isin(list(STATUS_ORDER))]
    if graded.empty:
        return None
    return graded.iloc[int(np.argmax(graded["status"].map(STATUS_ORDER).to_numpy()))]


def cause(value: float, limits: Limits, status: str, higher_is_worse: bool = True) -> str:
    """Why a graded `value` got `status`: the value against the limit it passed, or the one it kept."""
    past, within = ("above", "at or below") if higher_is_worse else ("below", "at or above")
    if status == "fail":
        return f"{value:.4g} {past} the fail limit {limits.fail:g}"
    if status == "warn":
        return f"{value:.4g} {past} the warn limit {limits.warn:g}"
    return f"{value:.4g} {within} the warn limit {limits.warn:g}"


def check(subject: str, stage: str, name: str, value: float | None, limits: Limits, note: str = "",
          higher_is_worse: bool = True, missing: str = "") -> QualityCheck:
    """A graded row with its cause; a missing value is `n/a` with `missing` (else `note`) as the
    reason it cannot be computed."""
    status = grade(value, limits.warn, limits.fail, higher_is_worse)
    if _missing(value):
        return QualityCheck(subject, stage, name, float("nan"), limits.warn, limits.fail, status,
                            f"cannot be computed: {missing or note or 'value unavailable'}", note)
    if not higher_is_worse:
        note = (note + "; " if note else "") + "lower is worse (thresholds are minima)"
    return QualityCheck(subject, stage, name, float(value), limits.warn, limits.fail, status,
                        cause(float(value), limits, status, higher_is_worse), note)


def quality_table(checks: Iterable[QualityCheck]) -> pd.DataFrame:
    """The checks as a DataFrame of `QUALITY_COLUMNS`."""
    rows = [[getattr(c, k) for k in QUALITY_COLUMNS] for c in checks]
    df = pd.DataFrame(rows, columns=QUALITY_COLUMNS)
    return df.astype({"value": float, "warn_above": float, "fail_above": float})


# -- scale and reference ----------------------------------------------------------------------------

def segment_asymmetry_pct(lengths_m: Mapping[str, float]) -> tuple[float, str]:
    """Largest left/right length difference of the paired segments, % of the pair's mean, and the
    segment it belongs to (NaN, '' without any pair)."""
    best, name = float("nan"), ""
    for seg in PAIRED_SEGMENTS:
        left, right = lengths_m.get(f"{seg}_l"), lengths_m.get(f"{seg}_r")
        if left is None or right is None or left + right <= 0:
            continue
        pct = 200.0 * abs(left - right) / (left + right)
        if not pct <= best:
            best, name = pct, seg
    return best, name


def knee_alignment_check(subject: str, valgus_deg: Mapping[str, float] | None,
                         p: QualityParams) -> QualityCheck:
    """The scaled legs' frontal alignment in the static pose (`model.json` static_knee_valgus_deg,
    `sim.body.scaling.knee_valgus_deg`), graded on the side furthest from straight: knee centres
    estimated too far in or out (a generic width ratio, a mislabelled marker) show here first."""
    sides = {s: float(v) for s, v in (valgus_deg or {}).items() if not _missing(v)}
    if not sides:
        return check(subject, "scale", "knee_alignment_deg", None, p.knee_alignment_deg,
                     "hip-knee-ankle in the static: not measured",
                     missing="no static_knee_valgus_deg in model.json (static: none stands the "
                     "synthesised pose's legs straight)")
    side = max(sides, key=lambda s: abs(sides[s]))
    kind = "valgus" if sides[side] >= 0 else "varus"
    return check(subject, "scale", "knee_alignment_deg", abs(sides[side]), p.knee_alignment_deg,
                 f"hip-knee-ankle in the static, largest: {kind} {abs(sides[side]):.1f} deg ({side}); "
                 "healthy adults 1.3 +- 2 deg varus")


def scale_checks(subject: str, model: Mapping | None, reference: Mapping | None,
                 p: QualityParams) -> list[QualityCheck]:
    """Left/right asymmetry of the scaled model (`model.json` segment_lengths_m) and the retarget's
    marker RMS and joint-angle RMS against the dataset's IK (`reference.json`)."""
    out = []
    if model is None:
        out.append(check(subject, "scale", "segment_asymmetry_pct", None, p.asymmetry_pct, "no model.json"))
    else:
        pct, seg = segment_asymmetry_pct(model.get("segment_lengths_m", {}))
        out.append(check(subject, "scale", "segment_asymmetry_pct", pct, p.asymmetry_pct,
                         f"largest: {seg}" if seg else "no left/right segment pairs"))
        out.append(knee_alignment_check(subject, model.get("static_knee_valgus_deg"), p))
    if reference is None:
        out.append(check(subject, "reference", "retarget_marker_rms_m", None, p.marker_rms_m,
                         "no reference.json"))
        out.append(check(subject, "reference", "ik_angle_rms_deg", None, p.ik_angle_rms_deg,
                         "no reference.json"))
        return out
    out.append(check(subject, "reference", "retarget_marker_rms_m", reference.get("marker_rms_m"),
                     p.marker_rms_m, "marker IK on the scaled model, all frames" + worst_markers(reference)))
    angles = {k: v.get("rms_deg") for k, v in (reference.get("angles") or {}).items()
              if isinstance(v, Mapping) and not _missing(v.get("rms_deg"))}
    if angles:
        joint = max(angles, key=angles.get)
        out.append(check(subject, "reference", "ik_angle_rms_deg", angles[joint], p.ik_angle_rms_deg,
                         f"retargeted vs the dataset's IK, largest: {joint}"))
    else:
        out.append(check(subject, "reference", "ik_angle_rms_deg", None, p.ik_angle_rms_deg,
                         "retargeted vs the dataset's IK", missing="no dataset IK angles to compare with"))
    return out


def worst_markers(reference: Mapping, n: int = 3) -> str:
    """'; largest: M1 4.9 cm, ...': the `n` markers of the largest RMS in any trial of `reference.json`
    (`trials` -> `markers_rms_m`); '' without per-marker values."""
    rms: dict[str, float] = {}
    for trial in (reference.get("trials") or {}).values():
        for name, v in ((trial or {}).get("markers_rms_m") or {}).items():
            if not _missing(v):
                rms[name] = max(rms.get(name, 0.0), float(v))
    top = sorted(rms, key=rms.get, reverse=True)[:n]
    return "; largest: " + ", ".join(f"{m} {rms[m] * 100:.1f} cm" for m in top) if top else ""


# -- ingest ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TrialSpan:
    """Time columns of one trial's files: markers and, where the trial has them, angles and GRF (s)."""

    trial: str
    marker_t: np.ndarray | None
    angles_t: np.ndarray | None = None
    grf_t: np.ndarray | None = None


def edge_strike_share(events: pd.DataFrame, spans: Mapping[str, tuple[float, float]], window_s: float
                      ) -> float:
    """Share of heel strikes within `window_s` of their trial's start or end (`spans`: trial ->
    (start, end) s); NaN without heel strikes of a spanned trial."""
    hs = events[(events["event"] == "heel_strike") & events["trial"].isin(list(spans))]
    if hs.empty:
        return float("nan")
    start = hs["trial"].map(lambda t: spans[t][0]).to_numpy(float)
    end = hs["trial"].map(lambda t: spans[t][1]).to_numpy(float)
    t = hs["time_s"].to_numpy(float)
    return float(np.mean((t - start <= window_s) | (end - t <= window_s)))


def uncovered_samples(marker_t: np.ndarray, other_t: np.ndarray) -> float:
    """How many marker samples lie outside `other_t`'s span, at the marker rate (the larger of the
    start and end gaps)."""
    marker_t, other_t = np.asarray(marker_t, float), np.asarray(other_t, float)
    dt = float(np.median(np.diff(marker_t))) if marker_t.size > 1 else 1.0
    gap = max(other_t.min() - marker_t.min(), marker_t.max() - other_t.max(), 0.0)
    return gap / dt


def kept_cycles(cycles: pd.DataFrame) -> pd.DataFrame:
    """Distinct cycles per condition and side (columns condition, side, n)."""
    keys = [c for c in ("condition", "trial", "seed", "side", "stride") if c in cycles.columns]
    distinct = cycles[keys].drop_duplicates()
    return distinct.groupby(["condition", "side"]).size().rename("n").reset_index()


def ingest_checks(subject: str, events: pd.DataFrame, cycles: pd.DataFrame, spans: list[TrialSpan] | None,
                  min_cycles: int, p: QualityParams) -> list[QualityCheck]:
    """Real recordings: heel strikes at the recording edges, files covering the marker span, and
    enough kept cycles per condition and side for SPM (`min_cycles`, metrics.spm)."""
    out = []
    if spans is None:
        out.append(check(subject, "ingest", "edge_heel_strike_share", None, p.edge_strike_share,
                         "no processed trials: the ingest stage's real/trials.npz is missing"))
    else:
        edges = {s.trial: (float(np.min(s.marker_t)), float(np.max(s.marker_t)))
                 for s in spans if s.marker_t is not None and len(s.marker_t)}
        out.append(check(subject, "ingest", "edge_heel_strike_share",
                         edge_strike_share(events, edges, p.edge_window_s), p.edge_strike_share,
                         f"heel strikes within {p.edge_window_s * 1000:g} ms of a trial's start or end"))
        for s in spans:
            for kind, t in (("angles", s.angles_t), ("grf", s.grf_t)):
                if t is None or s.marker_t is None:
                    continue
                out.append(check(subject, "ingest", f"{kind}_span_samples:{s.trial}",
                                 uncovered_samples(s.marker_t, t), p.span_samples,
                                 f"marker samples outside the {kind} file's span"))
    counts = kept_cycles(cycles) if not cycles.empty else pd.DataFrame(columns=["condition", "side", "n"])
    for cond in sorted(counts["condition"].unique()) if len(counts) else ["free"]:
        for side in SIDES:
            n = counts[(counts["condition"] == cond) & (counts["side"] == side)]["n"].sum()
            out.append(spm_cycles_check(subject, f"spm_cycles:{cond}:{side}", int(n), min_cycles))
    return out


def spm_cycles_check(subject: str, name: str, n: int, min_cycles: int) -> QualityCheck:
    """Real kept cycles of one condition and side: `ok` with at least `min_cycles`, else `n/a` (too few
    cycles for SPM: its tests of that group are skipped, which is not a measured defect)."""
    limits = Limits(float(min_cycles), float(min_cycles))
    note = "real kept cycles; lower is worse (thresholds are minima)"
    if n >= min_cycles:
        return QualityCheck(subject, "ingest", name, float(n), limits.warn, limits.fail, "ok",
                            cause(float(n), limits, "ok", higher_is_worse=False), note)
    return QualityCheck(subject, "ingest", name, float(n), limits.warn, limits.fail, NOT_COMPUTED,
                        f"too few cycles for SPM: {n} kept, {min_cycles} needed (its SPM tests are skipped)",
                        note)


# -- simulate -------------------------------------------------------------------------------------

def speed_gap_pct(real_strides: pd.DataFrame, sim_strides: pd.DataFrame, condition: str = "free") -> float:
    """|sim - real| / real mean gait speed of the kept strides of `condition`, %; NaN when either
    has none."""
    def mean_speed(df: pd.DataFrame) -> float:
        if df.empty:
            return float("nan")
        kept = df[df["kept"].astype(bool) & (df["condition"] == condition)]
        return float(kept["gait_speed_mps"].mean()) if len(kept) else float("nan")

    real, sim = mean_speed(real_strides), mean_speed(sim_strides)
    return 100.0 * abs(sim - real) / real if real > 0 else float("nan")


def missing_sides(real_strides: pd.DataFrame, sim_strides: pd.DataFrame, condition: str = "free") -> float:
    """How many sides the real kept strides of `condition` have and the simulated ones lack."""
    def sides(df: pd.DataFrame) -> set[str]:
        if df.empty:
            return set()
        return set(df[df["kept"].astype(bool) & (df["condition"] == condition)]["side"])

    return float(len(sides(real_strides) - sides(sim_strides)))


def non_steady_share(strides: pd.DataFrame) -> float:
    """Share of the given (table-entering) strides outside the steady phase; NaN when none or no
    phase column."""
    if strides.empty or "phase" not in strides.columns:
        return float("nan")
    return float((strides["phase"] != "steady").mean())


def sim_checks(subject: str, real_strides: pd.DataFrame, sims: Mapping[str, pd.DataFrame],
               policy_table_strides: pd.DataFrame | None, p: QualityParams,
               policy_walks: pd.DataFrame | None = None,
               rollouts: Mapping[str, int] | None = None) -> list[QualityCheck]:
    """Sim vs real free-walking speed and sides, per human mode in `sims` (mode -> strides: 'replay'
    the sim/ human, 'policy' the policy human's free strides of its table scenario); the share of
    the policy strides entering the tables outside steady walking; and the share of the table
    scenario's walks that repeat another of their condition (`policy_walks`:
    `metrics.sampling.repeated_walks`; copies are left out of the tables, so the tables rest on
    fewer walks than asked). `rollouts`: mode -> how many rollouts ran (the simulation's summary.json),
    to tell a simulation that kept no stride from none at all."""
    out = []
    for mode, strides in sims.items():
        ran = (rollouts or {}).get(mode) or 0
        why = ("no kept free-walking strides, real or simulated" if not strides.empty
               else f"its {ran} {mode} rollouts kept no stride" if ran else f"no {mode} simulation")
        out.append(check(subject, "simulate", f"speed_gap_pct:{mode}", speed_gap_pct(real_strides, strides),
                         p.speed_gap_pct, "free walking, kept strides", missing=why))
        value = missing_sides(real_strides, strides) if not strides.empty else None
        out.append(check(subject, "simulate", f"missing_sides:{mode}", value, p.missing_sides,
                         "sides with real but without simulated free strides", missing=why))
    if policy_table_strides is not None:
        share = non_steady_share(policy_table_strides)
        out.append(check(subject, "simulate", "non_steady_share:policy", share, p.non_steady_share,
                         "policy strides entering the paper's tables"))
    if policy_walks is not None and not policy_walks.empty:
        copy = policy_walks["repeats"].notna()
        per = ", ".join(f"{c}: {int((~g).sum())} of {len(g)}"
                        for c, g in copy.groupby(policy_walks["condition"]))
        out.append(check(subject, "simulate", "repeated_walks:policy", float(copy.mean()), p.repeated_walks,
                         f"walks repeating another of their condition stride for stride, left out of the "
                         f"paper's tables (distinct walks {per})"))
    return out


# -- policy (transfer gate) ------------------------------------------------------------------------

GATE_LIMITS_REQUIRED = Limits(1.0, 1.0)  # value 1 = passed, 0 = failed: a failed required check fails
GATE_LIMITS_OPTIONAL = Limits(1.0, 0.0)  # ... a failed check the gate does not require warns


def policy_body_checks(subject: str, body: Mapping | None) -> list[QualityCheck]:
    """One `policy` row, `policy_body_current`: 1 when the policy rollouts walked the subject's
    current scaled model, 0 (warn) when they walked the older body the policy was trained on (a
    policy rolls out on its own human.xml; scaling changed since), so the policy rows describe that
    body. No rollouts (`body` None): no row."""
    if not body:
        return []
    current = bool(body.get("current_model"))
    note = (f"policy rollouts on {body.get('file')}, "
            + ("the subject's current model" if current else
               "the body the policy was trained on, not the subject's current model (scaling changed "
               "since training): the policy rows describe that body; retrain or transfer to update"))
    return [check(subject, "policy", "policy_body_current", float(current), GATE_LIMITS_OPTIONAL, note,
                  higher_is_worse=False)]


def transfer_checks(subject: str, gate: Mapping | None) -> list[QualityCheck]:
    """One `policy` row per scenario check of a transferred policy's gate (`pipeline.stages.transfer`:
    `checks` name -> {pass, required}): value 1 passed, 0 failed; a failed required check is `fail`,
    a failed one the gate does not require (its source policy fails it too) `warn`, an unjudged one
    `n/a`. No gate (a committed policy, or none at all): no rows. The note names the source (for the
    universal policy its checkpoint's steps) and the gate's walks per check, the sample a pass rests on."""
    if not gate:
        return []
    if gate.get("source") == "universal":
        source = (f"the universal policy at {gate.get('universal_steps')} steps, fine-tuned "
                  f"{gate.get('steps')} steps on this body")
    else:
        source = (f"fine-tuned from {gate.get('source')} (distance {gate.get('distance')}, "
                  f"{gate.get('steps')} steps)")
    walks = f" ({gate['gate_seeds']} walks per check)" if gate.get("gate_seeds") else ""
    out = []
    for name, c in (gate.get("checks") or {}).items():
        ok = c.get("pass")
        value = None if ok is None else float(bool(ok))
        limits = GATE_LIMITS_REQUIRED if c.get("required") else GATE_LIMITS_OPTIONAL
        what = "required by the transfer gate" if c.get("required") else "not required (its source fails it)"
        what += walks
        out.append(check(subject, "policy", name, value, limits, f"{source}; {what}", higher_is_worse=False,
                         missing="the gate did not judge it"))
    if not out:
        out.append(check(subject, "policy", "transfer_gate", float(bool(gate.get("pass"))),
                         GATE_LIMITS_REQUIRED, f"{source}; no scenario check judged", higher_is_worse=False))
    return out
