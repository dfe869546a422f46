"""Turn files as read into the canonical Trial: Z up, X along progression, metres, degrees,
hip/knee flexion, ankle dorsiflexion and pelvis anterior tilt positive.

What a file's header says (units, inDegrees) is applied; what it cannot say (up axis, knee sign)
comes from the subject file. Both are then checked against the body: a pelvis that is not
0.4-1.6 m above the feet along the up axis, or a knee that flexes backwards, is reported as a
wrong declaration instead of passing silently.

Up axis `auto` (the default of a subject file that does not say): the axis of the marker file
along which the pelvis markers stand 0.4-1.6 m above the foot markers in at least 90 % of the
frames holding both; exactly one of +X, +Y, +Z must qualify, else the file is refused with the
heights measured per axis. The decision is logged (logger `gaitloop.ingest`) and kept in the
trial's provenance (`reader`, e.g. `markers:trc up=y(auto)`). A declared axis is used as declared
and checked the same way.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path

import numpy as np

from ingest.concurrency import helper_pool
from ingest.errors import IngestError
from ingest.manifest import Manifest
from ingest.markersets import required_markers, with_derived
from ingest.readers import MarkerTable, MotTable, read_c3d, read_csv, read_markers, read_mot, read_robot_log
from ingest.subject import FileFormat, Subject, TrialSpec
from ingest.trial import ForcePlates, Provenance, Trial

# OpenSim coordinate -> (canonical name, sign). OpenSim's pelvis_tilt is a right-handed rotation
# about the lateral axis, positive for posterior tilt: anterior tilt + needs the sign flipped.
# knee_angle's sign differs between models and is taken from the subject file (knee_flexion_sign).
OPENSIM_COORDINATES = {
    "hip_flexion_l": ("hip_flexion_left", 1.0),
    "hip_flexion_r": ("hip_flexion_right", 1.0),
    "knee_angle_l": ("knee_flexion_left", None),
    "knee_angle_r": ("knee_flexion_right", None),
    "ankle_angle_l": ("ankle_dorsiflexion_left", 1.0),
    "ankle_angle_r": ("ankle_dorsiflexion_right", 1.0),
    "pelvis_tilt": ("pelvis_tilt", -1.0),
    "hip_adduction_l": ("hip_adduction_left", 1.0),
    "hip_adduction_r": ("hip_adduction_right", 1.0),
    "hip_rotation_l": ("hip_rotation_left", 1.0),
    "hip_rotation_r": ("hip_rotation_right", 1.0),
    "pelvis_list": ("pelvis_list", 1.0),
    "pelvis_rotation": ("pelvis_rotation", 1.0),
}
# The GRF columns a plate needs (<plate>_vx ... _pz: force and centre of pressure), the only ones read.
PLATE_COLUMNS = tuple(f"_{q}{a}" for q in "vp" for a in "xyz")
PELVIS_ABOVE_FEET_M = (0.4, 1.6)
# Up axis `auto`: share of the frames (holding pelvis and foot markers) in which the pelvis must
# stand PELVIS_ABOVE_FEET_M above the feet along the axis; 90 % tolerates jumps, falls and gaps.
AUTO_UP_MIN_FRACTION = 0.9
UP_AXES = ("x", "y", "z")
PELVIS_ROLES = ("asis_left", "asis_right", "psis_left", "psis_right")
FOOT_ROLES = ("heel_left", "heel_right", "toe_left", "toe_right")
log = logging.getLogger("gaitloop.ingest")


# Lab axes -> canonical Z up, right-handed: canonical = lab[..., order] * sign.
# Y up: (x, y, z) -> (x, -z, y); X up: (x, y, z) -> (y, z, x).
UP_ROTATIONS = {"x": ((1, 2, 0), (1.0, 1.0, 1.0)), "y": ((0, 2, 1), (1.0, -1.0, 1.0))}


def up_to_z(xyz: np.ndarray, up_axis: str) -> np.ndarray:
    """Rotate lab axes so the declared up axis becomes Z (`UP_ROTATIONS`)."""
    if up_axis == "z":
        return xyz
    if up_axis not in UP_AXES:
        raise ValueError(f"up axis {up_axis!r} is not one of {UP_AXES} (resolve 'auto' first)")
    order, sign = UP_ROTATIONS[up_axis]
    out = np.empty(np.shape(xyz))
    for k, (j, s) in enumerate(zip(order, sign, strict=True)):  # axis by axis: a quarter of a gather's cost
        np.multiply(xyz[..., j], s, out=out[..., k])
    return out


def z_up_to(xyz: np.ndarray, up_axis: str) -> np.ndarray:
    """The inverse of `up_to_z`: canonical Z-up points into a file's `up_axis` (Y-up: (x, z, -y))."""
    if up_axis == "z":
        return xyz
    if up_axis not in UP_AXES:
        raise ValueError(f"up axis {up_axis!r} is not one of {UP_AXES}")
    order, sign = UP_ROTATIONS[up_axis]
    inverse = np.argsort(order)
    return xyz[..., inverse] * np.array(sign)[inverse]


def zero_gaps(xyz: np.ndarray) -> np.ndarray:
    """(n, m, 3) markers with those written as exactly (0, 0, 0) set to NaN: the gap convention of
    Vicon and of kgc6's files; `xyz` itself when there is none. Compared axis by axis: numpy's
    `.all` over a length-3 last axis costs several times more (0.9 ms against 0.13 ms on Camargo's
    trial)."""
    gap = (xyz[..., 0] == 0.0) & (xyz[..., 1] == 0.0) & (xyz[..., 2] == 0.0)
    return np.where(gap[..., None], np.nan, xyz) if gap.any() else xyz


def pelvis_above_feet(xyz: np.ndarray, names: tuple[str, ...] | list[str],
                      roles: dict[str, str]) -> np.ndarray | None:
    """Per frame and lab axis, the pelvis markers' mean minus the foot markers' mean, (n, 3) m in
    the file's own axes (NaN where either is missing); None without pelvis or foot markers."""
    index = {n: j for j, n in enumerate(names)}
    pelvis = [index[roles[r]] for r in PELVIS_ROLES if roles.get(r) in index]
    feet = [index[roles[r]] for r in FOOT_ROLES if roles.get(r) in index]
    if not pelvis or not feet:
        return None
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # frames without any pelvis or foot marker
        return np.nanmean(xyz[:, pelvis], axis=1) - np.nanmean(xyz[:, feet], axis=1)


def detect_up_axis(xyz: np.ndarray, names: tuple[str, ...] | list[str], roles: dict[str, str],
                   origin: str) -> tuple[str, dict[str, float]]:
    """The file's up axis (module docstring, `auto`) and the median pelvis height above the feet
    measured along each of its axes; raises `IngestError` when no axis, or more than one, fits."""
    height = pelvis_above_feet(xyz, names, roles)
    fix = "declare it: format.up_axis in the subject file, or --up-axis (x, y or z)"
    if height is None:
        raise IngestError(origin, f"cannot detect the up axis: the marker set's pelvis and foot markers "
                          f"are not in the file; {fix}")
    ok = np.isfinite(height).all(axis=1)
    if not ok.any():
        raise IngestError(origin, f"cannot detect the up axis: no frame holds both pelvis and foot markers; "
                          f"{fix}")
    lo, hi = PELVIS_ABOVE_FEET_M
    h = height[ok]
    share = ((h >= lo) & (h <= hi)).mean(axis=0)
    medians = {a: float(np.median(h[:, j])) for j, a in enumerate(UP_AXES)}
    fits = [a for j, a in enumerate(UP_AXES) if share[j] >= AUTO_UP_MIN_FRACTION]
    if len(fits) != 1:
        measured = ", ".join(f"{a.upper()} {medians[a]:+.3g} m ({share[j]:.0%} of frames in range)"
                             for j, a in enumerate(UP_AXES))
        raise IngestError(origin, f"cannot detect the up axis: pelvis above the feet per axis {measured}; "
                          f"expected {lo}-{hi} m in >= {AUTO_UP_MIN_FRACTION:.0%} of frames along exactly "
                          f"one axis; {fix}")
    return fits[0], medians


def resolve_up_axis(xyz: np.ndarray, names: tuple[str, ...] | list[str], roles: dict[str, str],
                    fmt: FileFormat, origin: str) -> tuple[str, bool]:
    """(up axis, detected?): the declared `fmt.up_axis`, or for `auto` the detected one (logged)."""
    if fmt.up_axis != "auto":
        return fmt.up_axis, False
    axis, medians = detect_up_axis(xyz, names, roles, origin)
    log.info("%s: up axis %s detected (pelvis above the feet: %s)", origin, axis.upper(),
             ", ".join(f"{a.upper()} {m:+.2f} m" for a, m in medians.items()))
    return axis, True


def opensim_coordinates(angles: dict[str, np.ndarray], knee_flexion_sign: int = 1,
                        extra: dict[str, tuple[str, float]] | None = None) -> dict[str, np.ndarray]:
    """Canonical joint angles (deg) as OpenSim coordinates, the inverse of `canonical_angles`
    (`OPENSIM_COORDINATES`, plus `extra` OpenSim name -> (canonical name, sign)); angles the trial
    lacks are left out."""
    out = {}
    for column, (name, sign) in {**OPENSIM_COORDINATES, **(extra or {})}.items():
        if name in angles:
            out[column] = np.asarray(angles[name], float) * (knee_flexion_sign if sign is None else sign)
    return out


def _check_body_scale(markers: dict[str, np.ndarray], roles: dict[str, str], origin: str,
                      up_axis: str, unit: str) -> None:
    """Pelvis must sit 0.4-1.6 m above the feet along +Z: catches lying units and up axes."""
    pelvis = [markers[roles[r]][:, 2] for r in PELVIS_ROLES if roles.get(r) in markers]
    feet = [markers[roles[r]][:, 2] for r in FOOT_ROLES if roles.get(r) in markers]
    if not pelvis or not feet:
        return
    with np.errstate(all="ignore"):
        height = np.nanmedian(np.nanmean(pelvis, axis=0) - np.nanmean(feet, axis=0))
    lo, hi = PELVIS_ABOVE_FEET_M
    if not np.isfinite(height):
        raise IngestError(origin, "pelvis or foot markers hold no samples")
    if not lo <= height <= hi:
        raise IngestError(
            origin,
            f"pelvis is {height:.4g} m above the feet along the up axis ({up_axis.upper()} "
            f"declared, Units {unit!r}); expected {lo}-{hi} m: the file's units or the subject's "
            "format.up_axis are wrong (fix the Units header, or the up axis: format.up_axis in the "
            "subject file, --up-axis of add-subject / events; 'auto' detects it)",
        )


def heading_rotation(markers: dict[str, np.ndarray], roles: dict[str, str], rate_hz: float,
                     window_s: float = 2.0) -> float:
    """Heading (rad) of the pelvis over the `window_s` stretch in which it travels farthest: the
    main walking direction, which the canonical frame puts on +X (shuffling into place at the
    start of a recording does not count)."""
    parts = [markers[roles[r]] for r in ("asis_left", "asis_right", "psis_left", "psis_right")
             if roles.get(r) in markers]
    if not parts:
        return 0.0
    with np.errstate(all="ignore"):
        xy = np.nanmean([p[:, :2] for p in parts], axis=0)
    ok = np.flatnonzero(np.isfinite(xy).all(axis=1))
    if len(ok) < 2:
        return 0.0
    xy = xy[ok]
    lag = int(np.clip(np.searchsorted(ok, ok[0] + window_s * rate_hz), 1, len(ok) - 1))
    d = xy[lag:] - xy[:-lag]
    best = d[np.argmax(np.hypot(d[:, 0], d[:, 1]))]
    return float(np.arctan2(best[1], best[0]))


def turned_canonical(xyz: np.ndarray, up_axis: str, heading_rad: float) -> np.ndarray:
    """`rotate_z(up_to_z(xyz, up_axis), heading_rad)` in one pass: the up axis's signs are folded
    into the rotation's coefficients (a product with +-1 is exact: the same bits), and the new array
    is written axis by axis through one scratch array (a trial's markers are MBs: every temporary is
    fresh memory to fault in, which costs more than the arithmetic)."""
    if up_axis not in UP_AXES:
        raise ValueError(f"up axis {up_axis!r} is not one of {UP_AXES} (resolve 'auto' first)")
    order, sign = UP_ROTATIONS.get(up_axis, ((0, 1, 2), (1.0, 1.0, 1.0)))
    xyz = np.asarray(xyz, dtype=float)
    x, y, z = (xyz[..., j] for j in order)
    c, s = np.cos(-heading_rad), np.sin(-heading_rad)
    out, scratch = np.empty(xyz.shape), np.empty(xyz.shape[:-1])
    np.multiply(z, sign[2], out=out[..., 2])
    np.multiply(s * sign[1], y, out=scratch)
    np.subtract(np.multiply(c * sign[0], x, out=out[..., 0]), scratch, out=out[..., 0])  # c x - s y
    np.multiply(c * sign[1], y, out=scratch)
    np.add(np.multiply(s * sign[0], x, out=out[..., 1]), scratch, out=out[..., 1])  # s x + c y
    return out


def rotate_z(xyz: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotate points about Z by -angle so a heading of `angle_rad` maps onto +X."""
    return turned_canonical(xyz, "z", angle_rad)


def canonical_angles(mot: MotTable, fmt: FileFormat, time_s: np.ndarray | None) -> dict[str, np.ndarray]:
    """Canonical joint angles (deg) from an OpenSim coordinates table, resampled to `time_s`."""
    in_degrees = mot.in_degrees
    if in_degrees is None:
        if fmt.angle_unit is None:
            raise IngestError(mot.path, "header has no inDegrees line and the subject file declares "
                              "no format.angle_unit: cannot tell radians from degrees")
        in_degrees = fmt.angle_unit == "deg"
    t = mot.time_s
    resample = time_s is not None and (len(t) != len(time_s) or not np.allclose(t, time_s, atol=1e-6))
    present = [c for c in OPENSIM_COORDINATES if c in mot.table.columns]
    table = mot.values(present)
    angles = {}
    for k, column in enumerate(present):
        name, sign = OPENSIM_COORDINATES[column]
        values = table[:, k]
        if not in_degrees:
            values = np.degrees(values)
        values = values * (fmt.knee_flexion_sign if sign is None else sign)
        if resample:
            values = np.interp(time_s, t, values, left=np.nan, right=np.nan)
        angles[name] = values
    sagittal = [v for k, v in angles.items() if k.startswith(("hip_flexion", "knee_flexion"))]
    if in_degrees and sagittal and np.nanmax(np.abs(sagittal)) <= np.pi:
        raise IngestError(mot.path, f"hip and knee angles never exceed {np.pi:.2f}: the values are "
                          "radians although the header says inDegrees=yes")
    for side in ("left", "right"):
        knee = angles.get(f"knee_flexion_{side}")
        if knee is not None and np.nanpercentile(knee, 5) < -25:
            raise IngestError(
                mot.path, f"knee_flexion_{side} reaches {np.nanmin(knee):.0f} deg: knees do not "
                "hyperextend that far, so the file's knee sign is flexion-negative; set "
                "format.knee_flexion_sign: -1 in the subject file (or fix inDegrees)")
        hip = angles.get(f"hip_flexion_{side}")
        if hip is not None and np.nanmax(np.abs(hip)) > 180:
            raise IngestError(mot.path, f"hip_flexion_{side} exceeds 180 deg: the header's "
                              "inDegrees is wrong (values look like degrees read as radians)")
    return angles


def plates_from_grf(mot: MotTable, fmt: FileFormat, heading_rad: float) -> ForcePlates:
    """Per-plate vertical force and centre of pressure from an OpenSim GRF table."""
    cols = set(mot.table.columns)
    prefixes = sorted({c[:-3] for c in cols if c.endswith("_vx")}, key=lambda p: (len(p), p))
    prefixes = [p for p in prefixes if {f"{p}_vy", f"{p}_vz", f"{p}_px", f"{p}_pz"} <= cols]
    if not prefixes:
        raise IngestError(mot.path, "no force plate columns (<name>_vx/_vy/_vz/_px/_py/_pz)")
    columns = [f"{p}{suffix}" for p in prefixes for suffix in PLATE_COLUMNS]
    values = mot.values(columns).reshape(len(mot.table), len(prefixes), 2, 3)
    force, cop = (np.ascontiguousarray(values[:, :, q]) for q in (0, 1))
    force, cop = up_to_z(force, fmt.up_axis), turned_canonical(cop, fmt.up_axis, heading_rad)
    if np.nanmax(force[..., 2]) < 100 and np.nanmax(-force[..., 2]) > 100:
        force = -force  # plates that report the action on the plate instead of the reaction
    return ForcePlates(mot.rate_hz, float(mot.time_s[0]), force[..., 2], cop)


def _provenance(manifest: Manifest, key: str, path, reader: str) -> Provenance:
    return Provenance(str(path), manifest.sources[key].sha256, reader, key)


def _read_mot(manifest: Manifest, key: str, columns: Callable[[str], bool]) -> tuple[Path, MotTable]:
    """(verified path, table) of a storage file, only the `columns` it keeps converted."""
    path = manifest.resolve(key)
    return path, read_mot(path, columns=columns)


def load_trial(subject: Subject, spec: TrialSpec, manifest: Manifest, source: str = "real") -> Trial:
    """Read a subject's trial files through the manifest into one canonical Trial. The helper
    threads (`ingest.concurrency`) check the marker file's sha256 and read the IK and GRF files
    while this one parses the marker file (hashing and pyarrow's parser release the GIL: Camargo's
    trial reads in ~13 ms instead of ~22 ms on 2 cores); what they hold is turned canonical after
    the markers, which fix the trial's time, up axis and heading. A marker file that is not the
    manifest's is refused as before, and before any error its contents would raise."""
    pool = helper_pool()
    marker_path = manifest.resolve(spec.markers, verify=False) if spec.markers else None
    verified = pool.submit(manifest.verify, spec.markers, marker_path) if marker_path else None
    angles_read = pool.submit(_read_mot, manifest, spec.angles,  # the other columns are not read
                              OPENSIM_COORDINATES.__contains__) if spec.angles else None
    grf_read = pool.submit(_read_mot, manifest, spec.grf,  # moments are not read
                           lambda c: c.endswith(PLATE_COLUMNS)) if spec.grf else None
    return _canonical_trial(subject, spec, manifest, source, marker_path, verified, angles_read, grf_read)


def _canonical_trial(subject: Subject, spec: TrialSpec, manifest: Manifest, source: str,
                     marker_path: Path | None, verified: Future | None, angles_read: Future | None,
                     grf_read: Future | None) -> Trial:
    provenance = []
    markers: dict[str, np.ndarray] = {}
    angles: dict[str, np.ndarray] = {}
    time = rate = None
    file_time_s: dict[str, np.ndarray] = {}
    heading = 0.0
    up = subject.format.up_axis
    if marker_path is not None:
        path = marker_path
        try:
            table: MarkerTable = read_markers(path)
            if path.suffix.lower() == ".csv":
                angles.update(read_csv(path).angles_deg)
        finally:
            verified.result()  # a sha256 mismatch is raised first, whatever the reading gave
        up, detected = resolve_up_axis(table.xyz_m, table.names, subject.markerset, subject.format, str(path))
        lab = zero_gaps(table.xyz_m)
        # Z up, the landmarks only (they fix the scale check and the heading): all are turned below
        landmarks = {m for inputs in required_markers(subject.markerset).values() for m in inputs}
        z_up = {n: up_to_z(lab[:, j], up) for j, n in enumerate(table.names) if n in landmarks}
        markers = with_derived(z_up, subject.markerset)
        _check_body_scale(markers, subject.markerset, str(path), up, table.declared_unit)
        heading = heading_rotation(markers, subject.markerset, table.rate_hz)
        turned = turned_canonical(lab, up, heading)  # the file's markers in one pass, derived ones after them
        markers = {n: turned[:, j] for j, n in enumerate(table.names)} | {
            n: rotate_z(v, heading) for n, v in markers.items() if n not in table.names}
        time, rate = table.time_s, table.rate_hz
        file_time_s["markers"] = table.time_s
        reader = f"markers:{path.suffix.lower().lstrip('.')} up={up}{'(auto)' if detected else ''}"
        provenance.append(_provenance(manifest, spec.markers, path, reader))
    if angles_read is not None:
        path, mot = angles_read.result()
        angles.update(canonical_angles(mot, subject.format, time))
        file_time_s["angles"] = mot.time_s
        if time is None:
            time, rate = mot.time_s, mot.rate_hz
        provenance.append(_provenance(manifest, spec.angles, path, "angles:mot"))
    if time is None:
        raise IngestError(f"{subject.path}", f"trial {spec.id!r} lists neither markers nor angles")
    plates = None
    if grf_read is not None:
        path, grf = grf_read.result()
        if up == "auto":
            raise IngestError(path, "up axis 'auto' is detected from the trial's marker file, and this trial "
                              "has none: declare format.up_axis in the subject file (or --up-axis)")
        plates = plates_from_grf(grf, dataclasses.replace(subject.format, up_axis=up), heading)
        file_time_s["grf"] = grf.time_s
        provenance.append(_provenance(manifest, spec.grf, path, "grf:mot"))
    log = None
    if spec.robot_log:
        path = manifest.resolve(spec.robot_log)
        log = read_robot_log(path)
        provenance.append(_provenance(manifest, spec.robot_log, path, "robot:csv"))
    robot_markers = subject.robot_markers if log is None and spec.condition != "free" else None
    return Trial(subject.id, spec.condition, source, spec.id, float(rate), np.asarray(time, float),
                 markers, angles, plates, tuple(provenance), log, robot_markers, file_time_s)


__all__ = ["load_trial", "canonical_angles", "up_to_z", "rotate_z", "read_c3d", "detect_up_axis",
           "resolve_up_axis"]
