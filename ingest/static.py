"""The static (scaling) trial of a subject, read: the standing pose's marker positions and IK
angles, and the landmark roles that name its markers.

Markers are the median over the static window (`static.window_s` of the subject file; the whole
file without one), Z up (the declared up axis turned to Z), lab axes and origin otherwise. Angles
are the median of `static.angles` (the dataset's IK of the static pose, canonical names and signs,
degrees) over the same window, plus `subtalar_left` / `subtalar_right` when the file has OpenSim's
subtalar coordinates (not canonical angles; the model folds them into its ankle hinge); none when
the subject file names no static angles. Roles are the subject's marker set plus the static-only
landmarks of `data/markersets/scaling/<markerset>.yaml` (absent file: none).
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
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ingest.canonical import _check_body_scale, canonical_angles, resolve_up_axis, up_to_z
from ingest.errors import IngestError, SubjectError
from ingest.filtering import finite_runs
from ingest.kinematics import hip_joint_centres
from ingest.manifest import Manifest
from ingest.readers import MarkerTable, read_markers, read_mot
from ingest.subject import MARKERSETS_DIR, STATIC_AUTO, StaticSpec, Subject
from ingest.trial import SIDES

SCALING_ROLES_DIR = MARKERSETS_DIR / "scaling"
log = logging.getLogger("gaitloop.ingest")


@dataclass(frozen=True)
class StaticCheckParams:
    """Quiet standing (module docstring). Sources: pelvis speed 0.1 m/s is the walk phases' standing
    speed (`ingest.phases`, the walk_10m stop check); quiet standing measured here: pelvis <= 0.04 m/s,
    foot markers within 0.021 m of each other, marker knee flexion 12-14 deg (lateral markers'
    offset) on camargo's standing and opencap4's static; walking: feet 0.08-0.24 m apart, pelvis
    > 1 m/s. `speed_window_s`: the pelvis speed is its displacement over this span (noise of 1 mm
    gives 0.01 m/s)."""

    min_duration_s: float = 0.5
    max_pelvis_speed_mps: float = 0.1
    max_foot_spread_m: float = 0.04
    max_knee_flexion_deg: float = 25.0
    speed_window_s: float = 0.1


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
    """Up axis (declared or detected, and checked against the body) and the standing signals."""
    up, _ = resolve_up_axis(table.xyz_m, table.names, subject.markerset, subject.format, origin)
    xyz = up_to_z(table.xyz_m, up)
    _check_body_scale({n: xyz[:, j] for j, n in enumerate(table.names)}, subject.markerset, origin, up,
                      table.declared_unit)
    return up, standing_signals(xyz, table.names, subject.markerset, table.rate_hz, p, origin)


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
    (errors name them)."""

    subject: str
    markers: dict[str, np.ndarray]
    roles: dict[str, str]
    source: str
    angles_deg: dict[str, float] = field(default_factory=dict)
    angles_source: str | None = None


def scaling_roles(subject: Subject, directory: Path = SCALING_ROLES_DIR) -> dict[str, str]:
    """The subject's landmark roles: its marker set plus the static-only ones in
    `data/markersets/scaling/<markerset>.yaml` (absent file: none)."""
    roles = dict(subject.markerset)
    name = None
    if subject.path is not None and subject.path.is_file():
        name = (yaml.safe_load(subject.path.read_text()) or {}).get("markerset")
    path = directory / f"{name}.yaml"
    if name and path.is_file():
        roles.update({str(k): str(v) for k, v in (yaml.safe_load(path.read_text()) or {}).items()})
    return roles


def static_markers(path: Path, subject: Subject) -> dict[str, np.ndarray]:
    """Median marker positions of the static file `path` over the subject's static window, Z up
    (lab axes otherwise); markers without a finite median are left out."""
    table = read_markers(path)
    up, _ = resolve_up_axis(table.xyz_m, table.names, subject.markerset, subject.format, str(path))
    xyz = up_to_z(table.xyz_m, up)
    if subject.static.window_s is not None:
        t0, t1 = subject.static.window_s
        keep = (table.time_s >= t0) & (table.time_s <= t1)
        if keep.sum() < 2:
            raise SubjectError(path, f"static window {t0}-{t1} s holds {keep.sum()} frames")
        xyz = xyz[keep]
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(xyz, axis=0)
    return {n: med[j] for j, n in enumerate(table.names) if np.isfinite(med[j]).all()}


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
                      check: StaticCheckParams = StaticCheckParams()) -> StaticTrial:
    """Read `subject`'s static trial (field `static` of the subject file), checked to be quiet
    standing; `static: auto` first finds the window in the subject's trials."""
    if subject.static is None:
        raise SubjectError(subject.path, "no static trial (field 'static') to scale the model from")
    if subject.static.markers == STATIC_AUTO:
        subject = _with_auto_static(subject, manifest, check)
    path = manifest.resolve(subject.static.markers)
    check_static(path, subject, subject.static.window_s, check)
    markers, roles = static_markers(path, subject), scaling_roles(subject, roles_dir)
    if subject.static.angles is None:
        return StaticTrial(subject.id, markers, roles, str(path))
    angles_path = manifest.resolve(subject.static.angles)
    return StaticTrial(subject.id, markers, roles, str(path), static_ik_angles(angles_path, subject),
                       str(angles_path))


def _with_auto_static(subject: Subject, manifest: Manifest, p: StaticCheckParams) -> Subject:
    """`subject` with `static: auto` replaced by the window found in its trials (and that trial's IK)."""
    trials = [t for t in subject.trials if t.markers]
    paths = [manifest.resolve(t.markers) for t in trials]
    found = find_standing_window(paths, subject, p)
    trial = trials[[str(x) for x in paths].index(found.source)]
    spec = StaticSpec(trial.markers, (found.t0_s, found.t1_s), trial.angles)
    return dataclasses.replace(subject, static=spec)
