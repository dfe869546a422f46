"""Process one canonical Trial: gap filling, filtering, events, strides, cycles (DESIGN.md steps 1-6).

`process_trial` is pure: a Trial and parameters in, three tidy tables out (events, strides,
cycles), each with the trial's identity columns first, and the robot table of a robot-assisted
trial's robot log (`ingest.robot_log`) on the trial's own samples. Real and simulated trials go through
exactly this function: that is what makes the datasets matched.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
import pandas as pd
from pydantic import Field, with_config

from ingest.bouts import PelvisPath, pelvis_path, straight_bouts
from ingest.concurrency import helper_pool
from ingest.cycles import normalise_cycles
from ingest.errors import IngestError
from ingest.events import EventParams, detect_events, force_plate_events, kinematic_events
from ingest.filtering import lowpass
from ingest.gaps import fill_rigid, fill_short_all
from ingest.kinematics import marker_angles
from ingest.phases import PhaseParams, motion_phases
from ingest.robot import ROBOT_COLUMNS
from ingest.robot_log import log_from_markers, robot_table
from ingest.static import StaticCheckParams
from ingest.strides import StrideParams, segment_strides
from ingest.treadmill import Treadmill, TreadmillParams, check_treadmill, decide, overground_equivalent
from ingest.trial import SIDES, Provenance, Trial
from ingest.weighing import check_mass, stride_masses

ID_COLUMNS = ["subject", "source", "condition", "trial"]
PELVIS_ROLES = ("asis_left", "asis_right", "psis_left", "psis_right")


@with_config(extra="forbid")
@dataclass(frozen=True)
class FilterParams:
    """Zero-phase Butterworth low-pass of every marker and angle (`ingest.filtering.lowpass`)."""

    order: int = 4  # forward + backward: a 2nd-order design run twice (Winter 2009)
    cutoff_hz: Annotated[float, Field(gt=0.0)] = 12.0  # Wang, Chan et al. ICRA 2025


@with_config(extra="forbid")
@dataclass(frozen=True)
class GapParams:

    max_gap_s: float = 0.1  # spline-fill interior dropouts up to this long (s); longer ones reject strides


@with_config(extra="forbid")
@dataclass(frozen=True)
class BoutParams:
    """Straight walking bouts from the pelvis path (`ingest.bouts`)."""

    smooth_hz: float = 0.8  # low-pass on the pelvis path before taking its heading (Hz)
    min_walk_speed_mps: float = 0.3
    max_facing_angle_deg: float = 45.0
    min_bout_s: float = 1.0
    max_yaw_rate_deg_s: float = 60.0


@with_config(extra="forbid")
@dataclass(frozen=True)
class CycleParams:

    n_points: int = 101  # samples of a time-normalised gait cycle (0-100 %)


@with_config(extra="forbid")
@dataclass(frozen=True)
class IngestParams:
    """The `ingest` section of params.yaml: how a trial is cleaned, cut and normalised."""

    filter: FilterParams = field(default_factory=FilterParams)
    gaps: GapParams = field(default_factory=GapParams)
    bouts: BoutParams = field(default_factory=BoutParams)
    events: EventParams = field(default_factory=EventParams)
    strides: StrideParams = field(default_factory=StrideParams)
    cycles: CycleParams = field(default_factory=CycleParams)
    phases: PhaseParams = field(default_factory=PhaseParams)
    static: StaticCheckParams = field(default_factory=StaticCheckParams)  # the static (scaling) trial
    treadmill: TreadmillParams = field(default_factory=TreadmillParams)


@dataclass(frozen=True)
class ProcessedTrial:
    trial: Trial  # gap-filled and filtered
    events: pd.DataFrame
    strides: pd.DataFrame
    cycles: pd.DataFrame
    robot: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=ROBOT_COLUMNS))
    treadmill: Treadmill | None = None  # a treadmill trial, processed as its overground equivalent
    phases: np.ndarray | None = None  # walk phase label per frame of `trial` (`walk_phases`)


def clean_markers(trial: Trial, markerset: dict[str, str], p: IngestParams) -> Trial:
    """Gap-fill (rigid pelvis cluster, then short splines) and low-pass every marker and angle."""
    markers = dict(trial.markers)
    pelvis_names = [markerset[r] for r in PELVIS_ROLES if markerset.get(r) in markers]
    if len(pelvis_names) == 4:
        cluster = fill_rigid(np.stack([markers[n] for n in pelvis_names], axis=1))
        markers.update({n: cluster[:, j] for j, n in enumerate(pelvis_names)})
    rate, fc = trial.rate_hz, p.filter.cutoff_hz
    if trial.n_frames <= 9:
        raise IngestError(trial.origin, f"only {trial.n_frames} frames: too short to filter")
    if fc >= rate / 2:
        raise IngestError(trial.origin, f"cutoff {fc} Hz is above Nyquist of a {rate} Hz recording")
    markers = _filtered(markers, rate, p)
    angles = _filtered(trial.angles, rate, p)
    return trial.with_(markers=markers, angles=angles)


def _filtered(signals: dict[str, np.ndarray], rate_hz: float, p: IngestParams) -> dict[str, np.ndarray]:
    """Gap-fill (`fill_short_all`, only the signals with a gap) and low-pass many signals at once: the
    gap-free ones (after filling) in one call, while a helper thread filters the others one by one
    (`ingest.concurrency`). Each channel is filtered on its own whatever it is stacked with."""
    gapped = [n for n, x in signals.items() if not np.isfinite(x).all()]
    if gapped:  # the signals of a dict (markers, or angles) share one shape
        filled = fill_short_all([signals[n] for n in gapped], rate_hz, p.gaps.max_gap_s)
        signals = signals | dict(zip(gapped, filled, strict=True))
    gapped = [n for n in gapped if not np.isfinite(signals[n]).all()]  # gaps too long to fill
    complete = [n for n in signals if n not in gapped]
    rest = helper_pool().submit(lambda: {n: lowpass(signals[n], rate_hz, p.filter.cutoff_hz, p.filter.order)
                                         for n in gapped}) if gapped else None
    out: dict[str, np.ndarray] = {}
    if complete:
        flat = [signals[n].reshape(len(signals[n]), -1) for n in complete]
        filtered = lowpass(np.column_stack(flat), rate_hz, p.filter.cutoff_hz, p.filter.order)
        starts = np.cumsum([0] + [f.shape[1] for f in flat])
        out = {n: filtered[:, a:b].reshape(signals[n].shape)
               for n, a, b in zip(complete, starts[:-1], starts[1:], strict=True)}
    if rest is not None:
        out |= rest.result()
    return {n: out[n] for n in signals}


def landmarks(trial: Trial, markerset: dict[str, str]) -> dict[str, np.ndarray] | None:
    """Landmark trajectories by role, or None when a role's marker is absent from the trial."""
    try:
        return {role: trial.markers[name] for role, name in markerset.items()}
    except KeyError:
        return None


def trial_path(lm: dict[str, np.ndarray], rate_hz: float, p: IngestParams) -> PelvisPath:
    """Pelvis path of a trial from its pelvis landmarks (see `ingest.bouts`)."""
    pelvis = np.mean([lm[r] for r in PELVIS_ROLES], axis=0)
    facing = (lm["asis_left"] + lm["asis_right"] - lm["psis_left"] - lm["psis_right"]) / 2
    return pelvis_path(pelvis, facing, rate_hz, p.bouts.smooth_hz, p.bouts.min_walk_speed_mps,
                       p.bouts.max_yaw_rate_deg_s, p.bouts.max_facing_angle_deg)


def as_overground(clean: Trial, markerset: dict[str, str], p: IngestParams, treadmill: bool | None = None,
                  belt_speed_mps: float | None = None) -> tuple[Trial, Treadmill | None]:
    """A cleaned trial, or when it is treadmill walking (declared: `treadmill`, `belt_speed_mps` of
    the subject file; or detected) its overground equivalent (`ingest.treadmill`), noted in its
    provenance."""
    lm = landmarks(clean, markerset)
    if lm is None or (treadmill is False):
        return clean, None
    check = check_treadmill(lm, clean.time_s, clean.rate_hz, p.treadmill)
    found = decide(check, p.treadmill, treadmill, belt_speed_mps, clean.origin)
    if found is None:
        return clean, None
    walk = overground_equivalent(clean, found)
    note = Provenance("treadmill", "", found.note)
    return walk.with_(provenance=(*clean.provenance, note)), found


def walk_phases(trial: Trial, markerset: dict[str, str], p: IngestParams) -> np.ndarray:
    """Phase label per frame (standing, start, steady, speed_change, turn, stop) from the trial's
    gap-filled, filtered pelvis path (`ingest.phases`); a treadmill trial's from its overground
    equivalent. `process_trial` keeps the same labels in `ProcessedTrial.phases`."""
    clean, _ = as_overground(clean_markers(trial, markerset, p), markerset, p)
    lm = landmarks(clean, markerset)
    if lm is None:
        missing = sorted(set(markerset.values()) - set(clean.markers))
        raise IngestError(trial.origin, f"no pelvis path: markers {', '.join(missing)} are missing")
    return motion_phases(trial_path(lm, clean.rate_hz, p), clean.rate_hz, p.phases)


def process_trial(trial: Trial, markerset: dict[str, str], p: IngestParams, treadmill: bool | None = None,
                  belt_speed_mps: float | None = None) -> ProcessedTrial:
    """Events, strides and cycles of one trial (see module docstring). `treadmill` True/False
    declares treadmill or overground walking (None: detected), `belt_speed_mps` the belt speed
    (None: estimated); a treadmill trial is processed as its overground equivalent
    (`ingest.treadmill`)."""
    clean, found = as_overground(clean_markers(trial, markerset, p), markerset, p, treadmill, belt_speed_mps)
    lm = landmarks(clean, markerset)
    kin = force = None
    angles = dict(clean.angles)
    time = clean.time_s
    if lm is not None:
        pelvis = np.mean([lm[r] for r in PELVIS_ROLES], axis=0)
        path = trial_path(lm, clean.rate_hz, p)
        bouts = straight_bouts(path, int(p.bouts.min_bout_s * clean.rate_hz))
        heel = {s: lm[f"heel_{s}"] for s in SIDES}
        toe = {s: lm[f"toe_{s}"] for s in SIDES}
        kin = kinematic_events(heel, toe, pelvis, path.heading_rad, time, clean.rate_hz, p.events)
        if clean.plates is not None:
            feet = {s: (heel[s][:, :2] + toe[s][:, :2]) / 2 for s in SIDES}
            force = force_plate_events(clean.plates, feet, time, p.events)
        if not all(k in angles for k in ("hip_flexion_left", "knee_flexion_left")):
            angles = {**marker_angles(lm, path.heading_rad), **angles}
    elif p.events.method != "force":
        missing = sorted(set(markerset.values()) - set(clean.markers))
        raise IngestError(trial.origin, f"kinematic gait events need the marker set's landmarks; "
                          f"missing: {', '.join(missing[:6])}")
    events = detect_events(p.events.method, plates=clean.plates, kin=kin, force=force,
                           window_s=p.events.force_window_s, origin=trial.origin)
    if lm is None:
        raise IngestError(trial.origin, "strides need heel, toe and pelvis markers")
    strides = segment_strides(events, time, heel, toe, pelvis, path, bouts, p.strides, kin,
                              p.events.force_window_s)
    cycles = normalise_cycles(strides, time, angles, p.cycles.n_points)
    ident = {"subject": trial.subject, "source": trial.source, "condition": trial.condition,
             "trial": trial.trial}
    log = trial.robot_log
    if log is None and trial.robot_markers is not None:  # filtered like every marker
        log = log_from_markers(clean.markers, time, trial.robot_markers, clean.rate_hz, p.gaps.max_gap_s,
                               trial.origin)
    robot = (robot_table(log, trial.time_s, trial.subject, trial.condition, trial.trial) if log is not None
             else pd.DataFrame(columns=ROBOT_COLUMNS))
    return ProcessedTrial(clean, _with_id(events, ident), _with_id(strides, ident),
                          _with_id(cycles, ident), robot, found,
                          motion_phases(path, clean.rate_hz, p.phases))


def _with_id(df: pd.DataFrame, ident: dict[str, str]) -> pd.DataFrame:
    """`df` behind the identity columns (one concat: cheaper than inserting them one by one)."""
    return pd.concat([pd.DataFrame(ident, index=df.index), df], axis=1)


@dataclass(frozen=True)
class SubjectTables:
    """A subject's processed tables, all trials stacked; `robot` holds the robot-assisted trials'
    robot logs as robot tables (`ingest.robot`), empty when there are none. `trials`: each processed
    trial in the subject file's order (the tables stack their rows in that order), which the ingest
    stage writes once for the stages that need a trial's signals (`ingest.trial_file`)."""

    events: pd.DataFrame
    strides: pd.DataFrame
    cycles: pd.DataFrame
    robot: pd.DataFrame
    trials: tuple[ProcessedTrial, ...] = ()


def process_subject(subject, manifest, p: IngestParams, progress: bool = False) -> SubjectTables:
    """Load and process every trial of a `Subject`; raises `IngestError` when no trial yields a
    kept stride (naming the subject file), since nothing downstream could use the subject."""
    from tqdm import tqdm

    from ingest.canonical import load_trial

    results = []
    for spec in tqdm(subject.trials, desc=f"ingest {subject.id}", unit="trial", disable=not progress):
        results.append(process_trial(load_trial(subject, spec, manifest), subject.markerset, p,
                                     spec.treadmill, spec.belt_speed_mps))
    masses = [m for r in results if r.trial.plates is not None
              for m in stride_masses(r.trial.plates, r.events, p.events.force_threshold_n)]
    check_mass(subject.mass_kg, masses, subject.path)
    logs = [r.robot for r in results if not r.robot.empty]
    robot = pd.concat(logs, ignore_index=True) if logs else pd.DataFrame(columns=ROBOT_COLUMNS)
    tables = SubjectTables(*(pd.concat([getattr(r, name) for r in results], ignore_index=True)
                             for name in ("events", "strides", "cycles")), robot, tuple(results))
    if not tables.strides["kept"].any():
        reasons = tables.strides["reason"].value_counts().to_dict() if len(tables.strides) else {}
        raise IngestError(subject.path, f"no steady complete stride in {len(subject.trials)} "
                          f"trial(s) (rejected: {reasons or 'no heel-strike pair at all'})")
    return tables
