"""The static (scaling) trial of a subject, read: the standing pose's marker positions and IK
angles, and the landmark roles that name its markers.

Markers are the median over the static window (`static.window_s` of the subject file; the whole
file without one), Z up (the declared up axis turned to Z), lab axes and origin otherwise. Angles
are the median of `static.angles` (the dataset's IK of the static pose, canonical names and signs,
degrees) over the same window, plus `subtalar_left` / `subtalar_right` when the file has OpenSim's
subtalar coordinates (not canonical angles; the model folds them into its ankle hinge); none when
the subject file names no static angles. Roles are the subject's marker set plus the static-only
landmarks of `data/markersets/scaling/<markerset>.yaml` (absent file: none); segments (marker ->
body, for markers without a role) are the `segments` of both (`ingest.markersets.load_segments`).
`sim.body.scaling.scale_subject` turns a `StaticTrial` into the scaled body.

The static trial must be quiet standing, checked frame by frame from the markers (Z up): pelvis
speed at most `max_pelvis_speed_mps`, every heel and toe marker of both feet within
`max_foot_spread_m` of the lowest one (both feet flat on the floor), knees flexed at most
`max_knee_flexion_deg` (180 deg minus the hip centre-knee-ankle angle, Harrington hip centres), for
at least `min_duration_s` without a break, inside the static window (the whole file without one).
A walking or jumping trial given as static is refused naming the file, the failed check, its value
and threshold. `static: auto` (subject file; `--static auto` of add-subject) searches the subject's
trials (`find_standing_window`): in each file the first passing stretch (the standing before the
walk, where labs have the subject take the calibration pose; standing after a stop is wherever the
walk ended), across files the longest (the quietest on ties); its angles are the chosen trial's IK.

`static: none` (`--static none`): a subject that never stands still is scaled from its walking
trials, as AddBiomechanics scales without a static trial (Werling et al. 2023, PLoS ONE 18:e0295152,
"AddBiomechanics"): `walking_static` synthesises the standing pose's markers from per-segment median
geometry over all walking frames with the frame-defining markers present (see there). Its angles are
none: the joint zeros fall back to `static_upright` (`sim.body.scaling`), because the median IK over
walking frames is not a neutral pose and the synthetic pose has no IK of its own.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np
import yaml
from pydantic import Field, with_config

from ingest.canonical import _check_body_scale, canonical_angles, resolve_up_axis, up_to_z, zero_gaps
from ingest.errors import IngestError, SubjectError
from ingest.filtering import finite_runs
from ingest.kinematics import hip_joint_centres
from ingest.manifest import Manifest
from ingest.markersets import SEGMENTS_KEY, load_segments, parse_segments, with_derived
from ingest.readers import MarkerTable, read_markers, read_mot
from ingest.subject import MARKERSETS_DIR, STATIC_AUTO, STATIC_NONE, StaticSpec, Subject
from ingest.trial import SIDES

SCALING_ROLES_DIR = MARKERSETS_DIR / "scaling"
log = logging.getLogger("gaitloop.ingest")


@with_config(extra="forbid")
@dataclass(frozen=True)
class StaticCheckParams:
    """Quiet standing (module docstring). Sources: pelvis speed 0.1 m/s is the walk phases' standing
    speed (`ingest.phases`, the walk_10m stop check); quiet standing measured here: pelvis <= 0.04 m/s,
    foot markers within 0.021 m of each other, marker knee flexion 12-14 deg (lateral markers'
    offset) on camargo's standing and opencap4's static; walking: feet 0.08-0.24 m apart, pelvis
    > 1 m/s. `speed_window_s`: the pelvis speed is its displacement over this span (noise of 1 mm
    gives 0.01 m/s)."""

    min_duration_s: Annotated[float, Field(gt=0.0)] = 0.5
    max_pelvis_speed_mps: Annotated[float, Field(gt=0.0)] = 0.1
    max_foot_spread_m: Annotated[float, Field(gt=0.0)] = 0.04
    max_knee_flexion_deg: Annotated[float, Field(gt=0.0)] = 25.0
    speed_window_s: Annotated[float, Field(gt=0.0)] = 0.1
    # static: none: a marker rides on a segment this rigidly (median)
    max_marker_spread_m: Annotated[float, Field(gt=0.0)] = 0.02


@dataclass(frozen=True)
class StandingWindow:
    """A stretch of quiet standing: the file, its start and end (s) and its mean pelvis speed."""

    source: str
    t0_s: float
    t1_s: float
    pelvis_speed_mps: float

    @property
    def duration_s(self) -> float:
        return self.t1_s - self.t0_s


# (signal, what failing it means, its threshold in StaticCheckParams, unit)
CHECKS = (("pelvis_speed_mps", "pelvis moving: speed", "max_pelvis_speed_mps", "m/s"),
          ("foot_spread_m", "feet not flat on the floor: heel/toe heights spread", "max_foot_spread_m", "m"),
          ("knee_flexion_deg", "knees not extended: knee flexion", "max_knee_flexion_deg", "deg"))


def standing_signals(xyz: np.ndarray, names: tuple[str, ...], roles: dict[str, str], rate_hz: float,
                     p: StaticCheckParams, origin: str) -> dict[str, np.ndarray]:
    """Per frame (Z-up markers `xyz`, (n, m, 3)): pelvis speed, foot marker height spread and the
    larger knee flexion of the two sides (NaN where a marker is missing)."""
    index = {n: j for j, n in enumerate(names)}
    needed = [f"{r}_{s}" for r in ("asis", "psis", "heel", "toe", "knee", "ankle") for s in SIDES]
    missing = [f"{r} ({roles.get(r)})" for r in needed if roles.get(r) not in index]
    if missing:
        raise IngestError(origin, f"cannot check quiet standing: markers missing for {', '.join(missing)}")
    m = {r: xyz[:, index[roles[r]]] for r in needed}
    pelvis = (m["asis_left"] + m["asis_right"] + m["psis_left"] + m["psis_right"]) / 4
    lag = max(1, int(round(p.speed_window_s * rate_hz / 2)))
    speed = np.full(len(pelvis), np.nan)
    if len(pelvis) > 2 * lag:
        speed[lag:-lag] = np.linalg.norm(pelvis[2 * lag:] - pelvis[:-2 * lag], axis=1) * rate_hz / (2 * lag)
        speed[:lag], speed[-lag:] = speed[lag], speed[-lag - 1]  # the ends: their nearest span
    feet = np.stack([m[f"{r}_{s}"][:, 2] for r in ("heel", "toe") for s in SIDES], axis=1)
    hjc = hip_joint_centres(m["asis_left"], m["asis_right"], m["psis_left"], m["psis_right"])
    knee = []
    for side in SIDES:
        thigh, shank = hjc[side] - m[f"knee_{side}"], m[f"ankle_{side}"] - m[f"knee_{side}"]
        with np.errstate(all="ignore"):
            norms = np.linalg.norm(thigh, axis=1) * np.linalg.norm(shank, axis=1)
            cos = np.einsum("ij,ij->i", thigh, shank) / norms
        knee.append(180.0 - np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    return {"pelvis_speed_mps": speed, "foot_spread_m": feet.max(axis=1) - feet.min(axis=1),
            "knee_flexion_deg": np.maximum(knee[0], knee[1])}


def _standing_runs(signals: dict[str, np.ndarray], keep: np.ndarray, rate_hz: float,
                   p: StaticCheckParams) -> list[tuple[int, int]]:
    """Frame runs [start, stop) inside `keep` passing every check for at least `min_duration_s`."""
    ok = keep.copy()
    for name, _, limit, _ in CHECKS:
        with np.errstate(invalid="ignore"):
            ok &= signals[name] <= getattr(p, limit)  # NaN (missing marker) fails
    n_min = int(np.ceil(p.min_duration_s * rate_hz))
    return [(a, b) for a, b in finite_runs(ok) if b - a >= n_min]


def _best(runs: list[tuple[int, int]], speed: np.ndarray) -> tuple[int, int]:
    """The longest run; the quietest (lowest mean pelvis speed) among equally long ones."""
    return min(runs, key=lambda r: (-(r[1] - r[0]), float(np.nanmean(speed[r[0]:r[1]]))))


def _why_not(signals: dict[str, np.ndarray], keep: np.ndarray, rate_hz: float, p: StaticCheckParams) -> str:
    """The checks that fail: for each, its best (lowest) maximum over any `min_duration_s` inside the
    window, with the threshold."""
    n_min = max(1, int(np.ceil(p.min_duration_s * rate_hz)))
    failed = []
    for name, label, limit, unit in CHECKS:
        v = np.where(keep & np.isfinite(signals[name]), signals[name], np.inf)
        if len(v) < n_min:
            best = np.inf
        else:
            best = float(np.min(np.lib.stride_tricks.sliding_window_view(v, n_min).max(axis=1)))
        if not best <= getattr(p, limit):
            value = "(markers missing)" if not np.isfinite(best) else f"{best:.3g} {unit}"
            failed.append(f"{label} {value} > {getattr(p, limit):g} {unit}")
    return "; ".join(failed) or "no stretch passes all checks at once"


def _signals_of(table: MarkerTable, subject: Subject, origin: str, p: StaticCheckParams):
    """Up axis (declared or detected, and checked against the body) and the standing signals, from the
    file's markers and the marker set's derived ones (PSIS from a sacral marker, ...)."""
    up, _ = resolve_up_axis(table.xyz_m, table.names, subject.markerset, subject.format, origin)
    xyz = up_to_z(table.xyz_m, up)
    markers = with_derived({n: xyz[:, j] for j, n in enumerate(table.names)}, subject.markerset)
    _check_body_scale(markers, subject.markerset, origin, up, table.declared_unit)
    names = tuple(markers)
    return up, standing_signals(np.stack([markers[n] for n in names], axis=1), names, subject.markerset,
                                table.rate_hz, p, origin)


def check_static(path: Path, subject: Subject, window_s: tuple[float, float] | None,
                 p: StaticCheckParams = StaticCheckParams()) -> StandingWindow:
    """The quiet standing in `path` (inside `window_s`, else the whole file): the longest passing
    stretch; raises `IngestError` naming the file, the failed checks, their values and thresholds."""
    table = read_markers(path)
    _, signals = _signals_of(table, subject, str(path), p)
    t = table.time_s
    keep = np.ones(len(t), bool) if window_s is None else (t >= window_s[0]) & (t <= window_s[1])
    runs = _standing_runs(signals, keep, table.rate_hz, p)
    where = f"in {window_s[0]}-{window_s[1]} s" if window_s is not None else "anywhere"
    if not runs:
        raise IngestError(path, f"not a static (quiet standing) trial: no {p.min_duration_s:g} s {where} "
                          f"passes the standing checks: {_why_not(signals, keep, table.rate_hz, p)}")
    a, b = _best(runs, signals["pelvis_speed_mps"])
    return StandingWindow(str(path), float(t[a]), float(t[b - 1]),
                          float(np.nanmean(signals["pelvis_speed_mps"][a:b])))


def find_standing_window(paths: list[Path], subject: Subject,
                         p: StaticCheckParams = StaticCheckParams()) -> StandingWindow:
    """`static: auto`: each file's first stretch of quiet standing, the longest (then quietest) over
    the files `paths` (the subject's marker files); raises `SubjectError` when none has one."""
    found = []
    for path in paths:
        table = read_markers(path)
        _, signals = _signals_of(table, subject, str(path), p)
        runs = _standing_runs(signals, np.ones(len(table.time_s), bool), table.rate_hz, p)
        if runs:
            a, b = runs[0]  # the standing before the walk (module docstring)
            found.append(StandingWindow(str(path), float(table.time_s[a]), float(table.time_s[b - 1]),
                                        float(np.nanmean(signals["pelvis_speed_mps"][a:b]))))
    if not found:
        raise SubjectError(subject.path or subject.id, f"static auto: no {p.min_duration_s:g} s of quiet "
                           f"standing in any of the {len(paths)} marker files; give the static trial "
                           "(--static FILE, static.markers)")
    best = min(found, key=lambda w: (-w.duration_s, w.pelvis_speed_mps))
    log.info("%s: static auto: quiet standing %.2f-%.2f s of %s", subject.id, best.t0_s, best.t1_s,
             best.source)
    return best


@dataclass(frozen=True)
class StaticTrial:
    """A subject's static trial as arrays (module docstring).

    markers: marker name -> (3,) position (m); angles_deg: canonical angle name -> degrees ({} without
    static angles); roles: landmark role -> marker name; source / angles_source: the files read
    (errors name them); segments: marker -> the body it rides on, for markers without a role
    (`scaling_segments`)."""

    subject: str
    markers: dict[str, np.ndarray]
    roles: dict[str, str]
    source: str
    angles_deg: dict[str, float] = field(default_factory=dict)
    angles_source: str | None = None
    segments: dict[str, str] = field(default_factory=dict)


def _markerset_name(subject: Subject) -> str | None:
    if subject.path is not None and subject.path.is_file():
        return (yaml.safe_load(subject.path.read_text()) or {}).get("markerset")
    return None


def scaling_roles(subject: Subject, directory: Path = SCALING_ROLES_DIR) -> dict[str, str]:
    """The subject's landmark roles: its marker set plus the static-only ones in
    `data/markersets/scaling/<markerset>.yaml` (absent file: none)."""
    roles = dict(subject.markerset)
    name = _markerset_name(subject)
    path = directory / f"{name}.yaml"
    if name and path.is_file():
        roles.update({str(k): str(v) for k, v in (yaml.safe_load(path.read_text()) or {}).items()
                      if k != SEGMENTS_KEY})
    return roles


def scaling_segments(subject: Subject, directory: Path = SCALING_ROLES_DIR) -> dict[str, str]:
    """Marker -> body for the subject's markers without a role: the `segments` of its marker set,
    then those of `data/markersets/scaling/<markerset>.yaml` (which win)."""
    name = _markerset_name(subject)
    if not name:
        return {}
    out = load_segments(str(name))
    path = directory / f"{name}.yaml"
    if path.is_file():
        out.update(parse_segments((yaml.safe_load(path.read_text()) or {}).get(SEGMENTS_KEY), path))
    return out


def static_markers(path: Path, subject: Subject) -> dict[str, np.ndarray]:
    """Median marker positions of the static file `path` over the subject's static window, Z up
    (lab axes otherwise), with the marker set's derived markers; markers without a finite median are
    left out."""
    table = read_markers(path)
    up, _ = resolve_up_axis(table.xyz_m, table.names, subject.markerset, subject.format, str(path))
    xyz = up_to_z(table.xyz_m, up)
    derived = with_derived({n: xyz[:, j] for j, n in enumerate(table.names)}, subject.markerset)
    names = tuple(derived)
    xyz = np.stack([derived[n] for n in names], axis=1)
    if subject.static.window_s is not None:
        t0, t1 = subject.static.window_s
        keep = (table.time_s >= t0) & (table.time_s <= t1)
        if keep.sum() < 2:
            raise SubjectError(path, f"static window {t0}-{t1} s holds {keep.sum()} frames")
        xyz = xyz[keep]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(xyz, axis=0)
    return {n: med[j] for j, n in enumerate(names) if np.isfinite(med[j]).all()}


def static_ik_angles(path: Path, subject: Subject) -> dict[str, float]:
    """The dataset's IK angles of the static pose in `path` (canonical names and signs, degrees,
    plus the subtalar angles): medians over the static window (whole file without a window)."""
    mot = read_mot(path)
    angles = canonical_angles(mot, subject.format, None)
    keep = np.ones(len(mot.time_s), bool)
    if subject.static.window_s is not None:
        t0, t1 = subject.static.window_s
        keep = (mot.time_s >= t0) & (mot.time_s <= t1)
    if keep.sum() < 1:
        raise SubjectError(path, f"static window {subject.static.window_s} s holds no IK frames")
    out = {k: float(np.nanmedian(v[keep])) for k, v in angles.items()}
    in_degrees = mot.in_degrees if mot.in_degrees is not None else subject.format.angle_unit == "deg"
    for side in SIDES:  # not a canonical angle: the model folds it into its ankle hinge
        column = f"subtalar_angle_{side[0]}"
        if column in mot.table.columns:
            values = mot.table[column].to_numpy(float)[keep]
            out[f"subtalar_{side}"] = float(np.nanmedian(values if in_degrees else np.degrees(values)))
    return out


def read_static_trial(subject: Subject, manifest: Manifest, roles_dir: Path = SCALING_ROLES_DIR,
                      check: StaticCheckParams = StaticCheckParams(),
                      widths_per_height: tuple[float, float] | None = None) -> StaticTrial:
    """Read `subject`'s static trial (field `static` of the subject file), checked to be quiet
    standing; `static: auto` first finds the window in the subject's trials; `static: none`
    synthesises one from its walks (`walking_static`, which needs `widths_per_height`)."""
    if subject.static is None:
        raise SubjectError(subject.path, "no static trial (field 'static') to scale the model from")
    segments = scaling_segments(subject, roles_dir)
    if subject.static.markers == STATIC_NONE:
        paths = [manifest.resolve(t.markers) for t in subject.trials if t.markers]
        return dataclasses.replace(walking_static(subject, paths, scaling_roles(subject, roles_dir), check,
                                                  widths_per_height), segments=segments)
    if subject.static.markers == STATIC_AUTO:
        subject = _with_auto_static(subject, manifest, check)
    path = manifest.resolve(subject.static.markers)
    check_static(path, subject, subject.static.window_s, check)
    markers, roles = static_markers(path, subject), scaling_roles(subject, roles_dir)
    if subject.static.angles is None:
        return StaticTrial(subject.id, markers, roles, str(path), segments=segments)
    angles_path = manifest.resolve(subject.static.angles)
    return StaticTrial(subject.id, markers, roles, str(path), static_ik_angles(angles_path, subject),
                       str(angles_path), segments)


def _with_auto_static(subject: Subject, manifest: Manifest, p: StaticCheckParams) -> Subject:
    """`subject` with `static: auto` replaced by the window found in its trials (and that trial's IK)."""
    trials = [t for t in subject.trials if t.markers]
    paths = [manifest.resolve(t.markers) for t in trials]
    found = find_standing_window(paths, subject, p)
    trial = trials[[str(x) for x in paths].index(found.source)]
    spec = StaticSpec(trial.markers, (found.t0_s, found.t1_s), trial.angles)
    return dataclasses.replace(subject, static=spec)


# static: none. Segment -> the roles whose markers define its frame (they ride on it by construction).
FRAME_ROLES = {"pelvis": ("asis", "psis"), "thigh": ("knee",), "shank": ("ankle",), "foot": ("heel", "toe")}


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _frames_xy(x: np.ndarray, y_ref: np.ndarray) -> np.ndarray:
    """(n, 3, 3) frames (columns x, y, z) with x along `x` and y as close to `y_ref` as allowed."""
    x = _unit_rows(x)
    z = _unit_rows(np.cross(x, y_ref))
    return np.stack([x, np.cross(z, x), z], axis=-1)


def _frames_zy(z: np.ndarray, y_ref: np.ndarray) -> np.ndarray:
    """(n, 3, 3) frames with z along `z` and y as close to `y_ref` as allowed."""
    z = _unit_rows(z)
    x = _unit_rows(np.cross(y_ref, z))
    return np.stack([x, np.cross(z, x), z], axis=-1)


def _walking_frames(paths: list[Path], subject: Subject) -> tuple[np.ndarray, list[str]]:
    """All frames of the marker files `paths`, Z up, stacked: ((n, m, 3), names; NaN where a file
    lacks a marker, and for markers written as exactly (0, 0, 0): the gap convention of Vicon and
    of kgc6's files, whose static-only landmarks are zeros in the walks), plus the marker set's derived
    markers (`ingest.markersets.with_derived`, as `load_trial` adds them)."""
    tables = []
    for path in paths:
        table = read_markers(path)
        xyz = zero_gaps(table.xyz_m)
        up, _ = resolve_up_axis(xyz, table.names, subject.markerset, subject.format, str(path))
        xyz = up_to_z(xyz, up)
        markers = with_derived({n: xyz[:, j] for j, n in enumerate(table.names)}, subject.markerset)
        tables.append((np.stack(list(markers.values()), axis=1), list(markers)))
    names = list(dict.fromkeys(n for _, ns in tables for n in ns))
    out = []
    for xyz, ns in tables:
        full = np.full((len(xyz), len(names), 3), np.nan)
        full[:, [names.index(n) for n in ns]] = xyz
        out.append(full)
    return np.concatenate(out), names


def _segment_frames(m: dict[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per frame, segment -> (origin (n, 3), frame (n, 3, 3)) from the role markers `m`: pelvis at
    mid-ASIS (x toward it from mid-PSIS, y left); trunk there, upright, facing the pelvis' heading;
    thigh at the hip centre (Harrington), z toward it from the knee marker; shank at the knee
    marker, z toward it from the ankle marker (both y near the pelvis' left); foot at the ankle
    marker, x heel -> toe, y near the shank's."""
    pelvis_y = _unit_rows(m["asis_left"] - m["asis_right"])
    mid_asis = (m["asis_left"] + m["asis_right"]) / 2
    pelvis = _frames_xy(mid_asis - (m["psis_left"] + m["psis_right"]) / 2, pelvis_y)
    heading = pelvis[:, :, 0] * [1.0, 1.0, 0.0]
    out = {"pelvis": (mid_asis, pelvis), "trunk": (mid_asis, _frames_zy(np.tile([0.0, 0.0, 1.0], (len(
        heading), 1)), np.cross([0.0, 0.0, 1.0], heading)))}
    hjc = hip_joint_centres(m["asis_left"], m["asis_right"], m["psis_left"], m["psis_right"])
    for side in SIDES:
        knee, ankle = m[f"knee_{side}"], m[f"ankle_{side}"]
        shank = _frames_zy(knee - ankle, pelvis_y)
        out[f"thigh_{side}"] = (hjc[side], _frames_zy(hjc[side] - knee, pelvis_y))
        out[f"shank_{side}"] = (knee, shank)
        out[f"foot_{side}"] = (ankle, _frames_xy(m[f"toe_{side}"] - m[f"heel_{side}"], shank[:, :, 1]))
    return out


def _local(origin: np.ndarray, frame: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points `p` (n, 3) in the moving frames (n, 3, 3) at `origin` (n, 3)."""
    return np.einsum("nji,nj->ni", frame, p - origin)


def _roll(angle: float) -> np.ndarray:
    """Rotation about x (forward) by `angle` (rad): a segment leaning in the frontal plane."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _half_width(local: dict[str, tuple[str, np.ndarray]], roles: dict[str, str], joint: str, side: str,
                width_m: float) -> float:
    """How far the joint centre lies medial of its lateral marker, as scaling will place it
    (`sim.body.scaling.scale_subject`): half the lateral-medial marker distance when both ride on the
    same segment, else half of `width_m` (the body-height ratio's width)."""
    lat, med = (local.get(roles.get(r, "")) for r in (f"{joint}_{side}", f"{joint}_medial_{side}"))
    if lat is not None and med is not None and lat[0] == med[0]:
        return float(np.linalg.norm(lat[1] - med[1]) / 2)
    return width_m / 2


def walking_static(subject: Subject, paths: list[Path], roles: dict[str, str],
                   p: StaticCheckParams = StaticCheckParams(),
                   widths_per_height: tuple[float, float] | None = None) -> StaticTrial:
    """`static: none`: a standing pose synthesised from the walking trials `paths` (Werling et al.
    2023, AddBiomechanics, scale from motion without a static trial).

    Over every frame with all ASIS, PSIS, knee, ankle, heel and toe markers (Z up), segment frames
    are built from them (`_segment_frames`) and each marker gets its median position in the frame
    of the segment it rides on: the frame-defining markers on their own segment (knee on the thigh,
    ankle on the shank, heel and toe on the foot), any other marker on the segment where that
    median is the most rigid (median distance from it), kept when at most `max_marker_spread_m`
    (swinging arms are dropped: stature ratios replace them in scaling). The pose: pelvis with no
    list or rotation at its median walking tilt; the leg's mechanical axis vertical: knee and ankle
    centres under the hip centre, each lateral marker half its joint's width outside it
    (`_half_width`; `widths_per_height`: knee and ankle width / body height, params `human`, as
    scaling uses them), thigh and shank leaning in the frontal plane to put them there (the
    hip-knee and knee-ankle marker distances, medians, are kept: segment lengths); each foot
    at its median toe-out relative to the pelvis' heading, pitched so that heel and toe markers
    stand at their foot-flat heights (10th percentile over the frames), the heels on them. No
    angles: the joint zeros are not calibrated (module docstring)."""
    origin = "walking trials " + ", ".join(Path(x).name for x in paths)
    if widths_per_height is None:
        raise SubjectError(subject.path or subject.id, "static none: the knee and ankle widths per body "
                           "height (params human) are needed to stand the legs on their joint centres")
    if not paths:
        raise SubjectError(subject.path or subject.id, "static none: the subject has no marker files to "
                           "scale from")
    xyz, names = _walking_frames(paths, subject)
    needed = [f"{r}_{s}" for r in ("asis", "psis", "knee", "ankle", "heel", "toe") for s in SIDES]
    missing = [f"{r} ({roles.get(r)})" for r in needed if roles.get(r) not in names]
    if missing:
        raise IngestError(origin, f"static none: markers missing for {', '.join(missing)}")
    col = {n: j for j, n in enumerate(names)}
    complete = np.isfinite(xyz[:, [col[roles[r]] for r in needed]]).all(axis=(1, 2))
    if complete.sum() < 10:
        seen = {r: int(np.isfinite(xyz[:, col[roles[r]]]).all(axis=1).sum()) for r in needed}
        raise IngestError(origin, f"static none: {complete.sum()} frames hold all the frame-defining markers "
                          f"(frames per role: {', '.join(f'{r} ({roles[r]}) {n}' for r, n in seen.items())})")
    xyz = xyz[complete]
    m = {r: xyz[:, col[roles[r]]] for r in needed}
    frames = _segment_frames(m)
    fixed = {roles[f"{r}_{s}"]: (seg if seg == "pelvis" else f"{seg}_{s}")
             for seg, rs in FRAME_ROLES.items() for r in rs for s in SIDES}
    local: dict[str, tuple[str, np.ndarray]] = {}
    dropped = []
    for name, j in col.items():
        ok = np.isfinite(xyz[:, j]).all(axis=1)
        if ok.sum() < max(10, 0.1 * len(xyz)):
            dropped.append(name)
            continue
        best = None
        for seg in [fixed[name]] if name in fixed else list(frames):
            o, f = frames[seg]
            loc = _local(o[ok], f[ok], xyz[ok, j])
            med = np.median(loc, axis=0)
            spread = float(np.median(np.linalg.norm(loc - med, axis=1)))
            if best is None or spread < best[0]:
                best = (spread, seg, med)
        if name in fixed or best[0] <= p.max_marker_spread_m:
            local[name] = (best[1], best[2])
        else:
            dropped.append(name)
    if dropped:
        log.info("%s: static none: markers left out (not rigid on a leg or pelvis segment): %s", subject.id,
                 ", ".join(dropped))

    x_p = frames["pelvis"][1][:, :, 0]
    tilt = float(np.median(np.arcsin(np.clip(x_p[:, 2], -1.0, 1.0))))
    pose = {"pelvis": (np.zeros(3), _frames_xy(np.array([[np.cos(tilt), 0.0, np.sin(tilt)]]),
                                               np.array([[0.0, 1.0, 0.0]]))[0]),
            "trunk": (np.zeros(3), np.eye(3))}
    place = lambda seg, name: pose[seg][0] + pose[seg][1] @ local[name][1]  # noqa: E731
    pelvis = {r: place("pelvis", roles[r]) for r in ("asis_left", "asis_right", "psis_left", "psis_right")}
    hjc = hip_joint_centres(*(pelvis[r][None] for r in ("asis_left", "asis_right", "psis_left",
                                                          "psis_right")))
    heel_h = {}
    for side in SIDES:
        sign = 1.0 if side == "left" else -1.0  # +y is left: lateral
        half_knee, half_ankle = (_half_width(local, roles, joint, side, ratio * subject.height_m)
                                 for joint, ratio in zip(("knee", "ankle"), widths_per_height, strict=True))
        # each segment's frame-defining marker lies at (0, 0, -length) in its frame: a roll about x by
        # asin(offset / length) moves it `offset` sideways
        thigh_m, shank_m = (-local[roles[f"{j}_{side}"]][1][2] for j in ("knee", "ankle"))
        pose[f"thigh_{side}"] = (hjc[side][0], _roll(np.arcsin(np.clip(sign * half_knee / thigh_m, -1, 1))))
        knee = place(f"thigh_{side}", roles[f"knee_{side}"])
        lean = sign * (half_ankle - half_knee) / shank_m
        pose[f"shank_{side}"] = (knee, _roll(np.arcsin(np.clip(lean, -1, 1))))
        ankle = place(f"shank_{side}", roles[f"ankle_{side}"])
        heel, toe = m[f"heel_{side}"], m[f"toe_{side}"]
        along = toe - heel
        heading = frames["trunk"][1][:, :, 0]
        cos_sin = np.einsum("ij,ij->i", heading, along), np.cross(heading, along)[:, 2]
        yaw = float(np.median(np.arctan2(cos_sin[1], cos_sin[0])))
        h_heel, h_toe = (float(np.percentile(v[:, 2], 10)) for v in (heel, toe))
        pitch = float(np.arcsin(np.clip((h_toe - h_heel) / np.median(np.linalg.norm(along, axis=1)), -1, 1)))
        x = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
        pose[f"foot_{side}"] = (ankle, _frames_xy(x[None], np.array([[0.0, 1.0, 0.0]]))[0])
        heel_h[side] = (h_heel, place(f"foot_{side}", roles[f"heel_{side}"])[2])
    lift = np.mean([h - z for h, z in heel_h.values()])
    markers = {name: place(seg, name) + [0.0, 0.0, lift] for name, (seg, _) in local.items()}
    log.info("%s: static none: standing pose from %d walking frames of %d files (pelvis tilt %.1f deg)",
             subject.id, len(xyz), len(paths), np.degrees(tilt))
    return StaticTrial(subject.id, markers, roles, origin)
