"""Marker sets: which marker of a lab's files stands for each landmark role, and roles derived from
other markers where a lab has no such marker.

A marker set is a YAML file, landmark role -> marker name, shipped in `data/markersets/<name>.yaml`
or given by path (absolute, or relative to the working directory or the repository root). Every
role of `ROLES` x (left, right) is required. A role may instead be derived:

- `psis_left: {derive: sacral, marker: SACR}` (optional `ratio`): a lab with one sacral marker
  (Plug-in Gait SACR, OpenSim V.Sacral). Each PSIS is the sacral marker moved sideways along the
  ASIS-ASIS line by `ratio` x half the ASIS distance (`ratio: 0`: both PSIS on the sacral marker).
- `asis_left: {derive: hip_keypoints, hips: [LHip, RHip], trunk: [Neck]}` (asis and psis roles):
  video keypoints (COCO, HALPE, OpenPose) have hip joint centres, not pelvis landmarks. The pelvis
  frame is the hip centres' line (lateral) and the trunk direction (hips' midpoint -> the mean of
  `trunk`, made orthogonal: up); ASIS and PSIS are placed where Harrington et al. (2007, J Biomech
  40:595) would put these hip centres (`ingest.kinematics.hip_joint_centres` inverted), with the
  pelvis depth and PSIS width as ratios of the pelvis width (`PELVIS_DEPTH_RATIO`,
  `PSIS_WIDTH_RATIO`). The pelvis then has no tilt relative to the trunk.
- `knee_left: {derive: cluster, markers: [A, B, C], offset_m: [x, y, z]}` (any role): a landmark
  the lab did not record, rigid on a segment that carries a cluster of three markers. The point is
  fixed in the cluster's frame: origin at A, x toward B, z = x cross (C - A), y = z cross x; the
  offset (m) is measured once for the subject and written in the marker set (kgc6_clusters.yaml:
  functional joint centres from the walks). A cluster marker written as exactly (0, 0, 0), the gap
  convention of Vicon and of kgc6's files, is missing there.

A loaded marker set is a plain `dict[str, str]`: a derived role maps to a virtual marker name
(`Derivation.name`, starting with `@`) that spells out its recipe, and `with_derived` adds those
virtual markers to a trial's markers when it is loaded (`ingest.canonical.load_trial`), so every
consumer sees plain marker names. `pick_markerset` chooses the shipped set that fits a file.

Markers without a landmark role (thigh and shank clusters, arm markers of a set without arm roles)
may be given the body they ride on: `segments: {thigh_l: [LTH1, LTH2], forearm_r: [RW1]}` (bodies
as the human model names them, `sim.body.scaling.BODIES`), in the marker set or in its static-only
roles file (`data/markersets/scaling/<name>.yaml`); `load_segments` reads it (marker -> body).
Scaling puts the other markers without a role on the nearest bone within a limit and leaves the
rest out of the model (`sim.body.scaling.assign_markers`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ingest.errors import SubjectError

REPO_ROOT = Path(__file__).resolve().parent.parent
MARKERSETS_DIR = REPO_ROOT / "data" / "markersets"
ROLES = ("heel", "toe", "ankle", "knee", "asis", "psis")
ALL_ROLES = tuple(f"{r}_{s}" for r in ROLES for s in ("left", "right"))
PELVIS = ("asis_left", "asis_right", "psis_left", "psis_right")
DERIVE_KINDS = ("sacral", "hip_keypoints", "cluster")
VIRTUAL_PREFIX = "@"
SEGMENTS_KEY = "segments"

# Measured here: medians over the six lab recordings of ../shared/data with ASIS and PSIS markers
# (camargo, opencap4, lenhart2015, kgc6 DM, falisse2019, moissenet NP1014): PSIS-PSIS / ASIS-ASIS
# distance 0.19-0.47 (median 0.38); pelvis depth (mid-ASIS to mid-PSIS) / width 0.67-0.95 (0.72).
# Their sacral markers (lenhart S2, kgc6 Sacral, moissenet SACR) lie 0-13 mm from the mid-PSIS.
PSIS_WIDTH_RATIO = 0.38
PELVIS_DEPTH_RATIO = 0.72


@dataclass(frozen=True)
class Derivation:
    """A role computed from markers: `kind` (DERIVE_KINDS), its input markers and width ratio, or
    (`cluster`) the offset in the cluster's frame (m)."""

    role: str
    kind: str
    inputs: tuple[str, ...]
    ratio: float = PSIS_WIDTH_RATIO
    offset_m: tuple[float, ...] = ()

    @property
    def name(self) -> str:
        """The virtual marker's name, which spells out the recipe (`parse_virtual` reads it back)."""
        last = ",".join(f"{v:.6g}" for v in self.offset_m) if self.kind == "cluster" else f"{self.ratio:g}"
        return f"{VIRTUAL_PREFIX}{self.role}:{self.kind}:{','.join(self.inputs)}:{last}"


def parse_virtual(name: str) -> Derivation | None:
    """The derivation a virtual marker name spells out; None for a plain marker name."""
    if not name.startswith(VIRTUAL_PREFIX):
        return None
    parts = name[len(VIRTUAL_PREFIX):].split(":")
    if len(parts) != 4 or parts[1] not in DERIVE_KINDS:
        return None
    try:
        if parts[1] == "cluster":
            offset = tuple(float(v) for v in parts[3].split(","))
            return Derivation(parts[0], parts[1], tuple(parts[2].split(",")), offset_m=offset)
        return Derivation(parts[0], parts[1], tuple(parts[2].split(",")), float(parts[3]))
    except ValueError:
        return None


def shipped_markersets(directory: Path = MARKERSETS_DIR) -> tuple[str, ...]:
    return tuple(p.stem for p in sorted(directory.glob("*.yaml")))


def markerset_path(spec: str | Path, directory: Path = MARKERSETS_DIR) -> Path:
    """The YAML file of `spec`: a shipped set's name, or a path (absolute, or relative to the working
    directory, else to the repository root)."""
    text = str(spec)
    if not (text.endswith((".yaml", ".yml")) or "/" in text or "\\" in text):
        return directory / f"{text}.yaml"
    path = Path(text).expanduser()
    if path.is_absolute() or path.is_file():
        return path
    return REPO_ROOT / path if (REPO_ROOT / path).is_file() else path


def load_markerset(spec: str | Path, directory: Path = MARKERSETS_DIR) -> dict[str, str]:
    """Role -> marker name (or a derived role's virtual marker name) of the set named or pointed to
    by `spec`; `SubjectError` naming the file for an unknown set, bad YAML, a missing or unknown role
    or a bad derivation."""
    path = markerset_path(spec, directory)
    if not path.is_file():
        raise SubjectError(path, f"unknown marker set {str(spec)!r}: not a shipped set "
                           f"({', '.join(shipped_markersets(directory))}) nor a readable YAML file")
    try:
        doc = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise SubjectError(path, f"marker set is not readable YAML ({exc})") from None
    if not isinstance(doc, dict):
        raise SubjectError(path, "a marker set maps landmark role -> marker name")
    return parse_markerset({str(k): v for k, v in doc.items()}, path)


def parse_markerset(doc: dict[str, object], path: Path | str) -> dict[str, str]:
    """A marker set's YAML mapping checked and resolved (module docstring); its `segments` are
    checked here and read by `load_segments`."""
    doc = dict(doc)
    parse_segments(doc.pop(SEGMENTS_KEY, None), path)
    unknown = sorted(set(doc) - set(ALL_ROLES))
    missing = [r for r in ALL_ROLES if r not in doc or doc[r] is None]
    if unknown:
        raise SubjectError(path, f"unknown roles {', '.join(unknown)} (roles: {', '.join(ALL_ROLES)})")
    if missing:
        raise SubjectError(path, f"missing roles {', '.join(missing)}: give each a marker name or "
                           "{derive: ...} (ingest/markersets.py)")
    plain = {r: str(v) for r, v in doc.items() if not isinstance(v, dict)}
    out = dict(plain)
    for role, spec in doc.items():
        if isinstance(spec, dict):
            out[role] = _derivation(role, spec, plain, path).name
    return {r: out[r] for r in ALL_ROLES}


def parse_segments(spec: object, path: Path | str) -> dict[str, str]:
    """Marker -> body of a `segments: {body: [marker, ...]}` mapping (None: {}); `SubjectError`
    naming `path` for another shape or a marker given two bodies."""
    if spec is None:
        return {}
    if not isinstance(spec, dict) or not all(
            isinstance(v, list) and all(isinstance(m, str) for m in v) for v in spec.values()):
        raise SubjectError(path, f"{SEGMENTS_KEY}: maps a body of the model to its markers, "
                           "{thigh_l: [marker, ...], ...}")
    out: dict[str, str] = {}
    for body, names in spec.items():
        for name in names:
            if out.get(name, str(body)) != str(body):
                raise SubjectError(path, f"{SEGMENTS_KEY}: marker {name} is given two bodies "
                                   f"({out[name]}, {body})")
            out[name] = str(body)
    return out


def load_segments(spec: str | Path, directory: Path = MARKERSETS_DIR) -> dict[str, str]:
    """Marker -> body of the `segments` of the marker set named or pointed to by `spec` ({} without
    them, or for a file that is not there; `load_markerset` reports those)."""
    path = markerset_path(spec, directory)
    if not path.is_file():
        return {}
    try:
        doc = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise SubjectError(path, f"marker set is not readable YAML ({exc})") from None
    return parse_segments(doc.get(SEGMENTS_KEY), path) if isinstance(doc, dict) else {}


def _derivation(role: str, spec: dict, plain: dict[str, str], path: Path | str) -> Derivation:
    kind = spec.get("derive")
    ratio = float(spec.get("ratio", PSIS_WIDTH_RATIO))
    if kind == "sacral":
        if not role.startswith("psis_") or "marker" not in spec:
            raise SubjectError(path, f"{role}: derive sacral gives a psis role from "
                               "{marker: <sacral marker>}")
        if "asis_left" not in plain or "asis_right" not in plain:
            raise SubjectError(path, f"{role}: derive sacral needs both ASIS roles as markers")
        return Derivation(role, kind, (str(spec["marker"]), plain["asis_left"], plain["asis_right"]), ratio)
    if kind == "hip_keypoints":
        hips, trunk = spec.get("hips"), spec.get("trunk")
        if role not in PELVIS or not isinstance(hips, list) or len(hips) != 2 or not trunk:
            raise SubjectError(path, f"{role}: derive hip_keypoints gives an asis or psis role from "
                               "{hips: [left, right], trunk: [marker, ...]}")
        trunk = [trunk] if isinstance(trunk, str) else list(trunk)
        return Derivation(role, kind, tuple(str(m) for m in [*hips, *trunk]), ratio)
    if kind == "cluster":
        markers, offset = spec.get("markers"), spec.get("offset_m")
        if not (isinstance(markers, list) and len(markers) == 3 and isinstance(offset, list)
                and len(offset) == 3 and all(isinstance(v, int | float) for v in offset)):
            raise SubjectError(path, f"{role}: derive cluster gives a role from "
                               "{markers: [origin, x toward, plane], offset_m: [x, y, z]}")
        offset_m = tuple(float(v) for v in offset)
        return Derivation(role, kind, tuple(str(m) for m in markers), offset_m=offset_m)
    raise SubjectError(path, f"{role}: unknown derivation {kind!r} (known: {', '.join(DERIVE_KINDS)})")


def required_markers(markerset: dict[str, str]) -> dict[str, tuple[str, ...]]:
    """Role -> the file markers it needs (its marker, or its derivation's inputs)."""
    out = {}
    for role, name in markerset.items():
        d = parse_virtual(name)
        out[role] = d.inputs if d else (name,)
    return out


def with_derived(markers: dict[str, np.ndarray], markerset: dict[str, str]) -> dict[str, np.ndarray]:
    """`markers` ((n, 3) m, any axes with Z up for `hip_keypoints`) plus the set's derived virtual
    markers whose inputs are all present; unchanged when the set derives nothing."""
    derived = [d for d in map(parse_virtual, markerset.values()) if d is not None]
    out = dict(markers)
    for d in derived:
        if all(m in markers for m in d.inputs):
            out[d.name] = derive(d, markers)
    return out


def derive(d: Derivation, markers: dict[str, np.ndarray]) -> np.ndarray:
    """The virtual marker of `d` from `markers` (module docstring)."""
    side = 1.0 if d.role.endswith("_left") else -1.0
    if d.kind == "cluster":
        origin, toward, plane = (np.where((np.asarray(markers[m], float) == 0.0).all(axis=-1, keepdims=True),
                                          np.nan, np.asarray(markers[m], float)) for m in d.inputs)
        x = toward - origin
        x = x / np.linalg.norm(x, axis=-1, keepdims=True)
        z = np.cross(x, plane - origin)
        z = z / np.linalg.norm(z, axis=-1, keepdims=True)
        offset = np.asarray(d.offset_m)
        return origin + x * offset[0] + np.cross(z, x) * offset[1] + z * offset[2]
    if d.kind == "sacral":
        sacrum, asis_l, asis_r = (np.asarray(markers[m], float) for m in d.inputs)
        return sacrum + side * d.ratio * (asis_l - asis_r) / 2
    hip_l, hip_r = (np.asarray(markers[m], float) for m in d.inputs[:2])
    top = np.mean([np.asarray(markers[m], float) for m in d.inputs[2:]], axis=0)
    centre = (hip_l + hip_r) / 2
    left = hip_l - hip_r
    hjc_width = np.linalg.norm(left, axis=1, keepdims=True)
    y = left / hjc_width
    up = top - centre
    up -= np.sum(up * y, axis=1, keepdims=True) * y
    z = up / np.linalg.norm(up, axis=1, keepdims=True)
    x = np.cross(y, z)  # anterior
    # Harrington: hip = mid-ASIS + x (-0.24 PD - 9.9 mm) + z (-0.30 PW - 10.9 mm) +/- y (0.33 PW + 7.3 mm)
    pw = (hjc_width / 2 - 0.0073) / 0.33
    pd = PELVIS_DEPTH_RATIO * pw
    mid_asis = centre + x * (0.24 * pd + 0.0099) + z * (0.30 * pw + 0.0109)
    if d.role.startswith("asis_"):
        return mid_asis + side * y * pw / 2
    return mid_asis - x * pd + side * y * d.ratio * pw / 2


@dataclass(frozen=True)
class Fit:
    """How a shipped set covers a file: its missing roles (role -> the markers they need)."""

    name: str
    missing: dict[str, tuple[str, ...]]
    n_derived: int
    n_markers: int

    @property
    def fits(self) -> bool:
        return not self.missing


def coverage(names: tuple[str, ...] | list[str], directory: Path = MARKERSETS_DIR) -> list[Fit]:
    """Every shipped set's coverage of a file holding markers `names`, best first: fitting sets
    before the others, then the fewest derived roles, then the fewest markers (the most direct
    description); sets that do not fit by their number of missing roles."""
    present = set(names)
    fits = []
    for name in shipped_markersets(directory):
        ms = load_markerset(name, directory)
        need = required_markers(ms)
        missing = {r: tuple(m for m in need[r] if m not in present) for r in need}
        fits.append(Fit(name, {r: m for r, m in missing.items() if m},
                        sum(parse_virtual(v) is not None for v in ms.values()),
                        len({m for ms_ in need.values() for m in ms_})))
    return sorted(fits, key=lambda f: (len(f.missing), f.n_derived, f.n_markers, f.name))


def pick_markerset(names: tuple[str, ...] | list[str], origin: Path | str,
                   directory: Path = MARKERSETS_DIR, closest: int = 3) -> str:
    """The shipped set that fits a file's markers `names` (`coverage` order); `SubjectError` naming
    `origin` when none fits (the `closest` sets' missing roles and the markers they expect) or when
    two fit equally well."""
    ranked = coverage(names, directory)
    fitting = [f for f in ranked if f.fits]
    if not fitting:
        detail = "; ".join(f"{f.name} lacks " + ", ".join(f"{r} ({'+'.join(m)})"
                                                           for r, m in f.missing.items())
                           for f in ranked[:closest])
        raise SubjectError(origin, f"no shipped marker set fits this file (closest: {detail}); write a "
                           "marker set YAML for it and pass its path (--markerset, or markerset: of the "
                           "subject file)")
    best = fitting[0]
    tied = [f.name for f in fitting if (f.n_derived, f.n_markers) == (best.n_derived, best.n_markers)]
    if len(tied) > 1:
        raise SubjectError(origin, f"marker sets {', '.join(tied)} all fit this file; pass --markerset")
    return best.name


__all__ = ["load_markerset", "load_segments", "parse_segments", "with_derived", "pick_markerset", "coverage",
           "markerset_path", "shipped_markersets", "Derivation", "parse_virtual"]
