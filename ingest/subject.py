"""Subject registry: `data/subjects/<id>.yaml` describes one person and their recordings.

Fields: id, height_m, mass_kg, dataset, markerset (name of `data/markersets/<name>.yaml` or a YAML
path, landmark role -> marker name: `ingest.markersets`), format (how the files are written: up_axis,
knee_flexion_sign, and for files without a unit header, angle_unit; up_axis x, y, z or auto, auto
when not given: `ingest.canonical.detect_up_axis`), static (scaling trial: markers, optional window_s, and
optional `angles`, the manifest key of the static pose's IK coordinates, median over the same
window, used to calibrate the model's joint zeros; or `static: auto`, the quietest standing window
found in the trials: `ingest.static.find_standing_window`; or `static: none`, scaled from the
walking trials: `ingest.static.walking_static`), trials (id, condition, and
manifest keys of the markers / angles / grf files, and of the `robot_log` of a robot-assisted
trial: `ingest.readers.robot_log`; optional `treadmill` true/false and `belt_speed_mps` of a treadmill
trial, `treadmill` also at the top level for every trial: `ingest.treadmill`), `robot_markers`
(markers on the robot that stand in for a robot log: `RobotMarkers`) and `round_trip_of` (the
subject whose simulated trials these files are, exported and read back: `python -m pipeline
export`; reports and the store label it).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import yaml

from ingest import markersets
from ingest.errors import SubjectError

REPO_ROOT = Path(__file__).resolve().parent.parent
SUBJECTS_DIR = REPO_ROOT / "data" / "subjects"
MARKERSETS_DIR = markersets.MARKERSETS_DIR
ROLES = ("heel", "toe", "ankle", "knee", "asis", "psis")
UP_AXIS_CHOICES = ("x", "y", "z", "auto")
HEIGHT_RANGE_M = (0.5, 2.5)
MASS_RANGE_KG = (10.0, 300.0)
STATIC_AUTO = "auto"  # `static: auto`: the quietest standing window of the subject's trials
STATIC_NONE = "none"  # `static: none`: no standing at all; scaled from the walking trials


@dataclass(frozen=True)
class FileFormat:
    """How a subject's files are written, declared once so nothing is guessed downstream."""

    up_axis: str = "z"  # x | y | z | auto (subject files default to auto; a bare FileFormat to z)
    knee_flexion_sign: int = 1
    angle_unit: str | None = None  # 'deg' | 'rad' for files whose header does not say


@dataclass(frozen=True)
class TrialSpec:
    id: str
    condition: str
    markers: str | None = None
    angles: str | None = None
    grf: str | None = None
    robot_log: str | None = None
    treadmill: bool | None = None  # True: treadmill walking, False: overground, None: detected
    belt_speed_mps: float | None = None  # declared belt speed (None: estimated: ingest.treadmill)


@dataclass(frozen=True)
class RobotMarkers:
    """Markers on the robot, in the trials' marker files: two on the base along its heading and one
    on the arm's end; `neutral_in_base_m` is the arm's neutral point relative to the base markers'
    midpoint, in the base frame (x forward, y left, z up). They give the robot's signals of a
    robot-assisted trial without a robot log (`ingest.robot_log.log_from_markers`)."""

    base_front: str
    base_rear: str
    arm_end: str
    neutral_in_base_m: tuple[float, float, float]

    @property
    def names(self) -> tuple[str, str, str]:
        return self.base_front, self.base_rear, self.arm_end


@dataclass(frozen=True)
class StaticSpec:
    markers: str
    window_s: tuple[float, float] | None = None
    angles: str | None = None  # manifest key of the static pose's joint coordinates (.mot)


@dataclass(frozen=True)
class Subject:
    id: str
    height_m: float
    mass_kg: float
    dataset: str
    markerset: dict[str, str]
    format: FileFormat
    static: StaticSpec | None
    trials: tuple[TrialSpec, ...] = field(default_factory=tuple)
    path: Path | None = None
    round_trip_of: str | None = None
    robot_markers: RobotMarkers | None = None

    @property
    def conditions(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(t.condition for t in self.trials))


def _require(doc: dict, key: str, path: Path):
    if key not in doc or doc[key] is None:
        raise SubjectError(path, f"missing required field {key!r}")
    return doc[key]


SUBJECT_KEYS = ("id", "height_m", "mass_kg", "dataset", "markerset", "format", "static", "trials",
                "treadmill", "robot_markers", "round_trip_of")
TRIAL_KEYS = tuple(f.name for f in fields(TrialSpec))
FORMAT_KEYS = tuple(f.name for f in fields(FileFormat))
STATIC_KEYS = tuple(f.name for f in fields(StaticSpec))


def _mapping(doc, where: str, known: tuple[str, ...], path: Path) -> dict:
    """`doc` when it is a mapping of known keys (`where` names it in the error), else `SubjectError`
    naming the unknown keys and the known ones: a misspelt key is never silently ignored."""
    if not isinstance(doc, dict):
        raise SubjectError(path, f"{where} must be a mapping of {', '.join(known)}, not {doc!r}")
    unknown = [str(k) for k in doc if k not in known]
    if unknown:
        raise SubjectError(path, f"{where}: unknown key(s) {', '.join(map(repr, unknown))} "
                                 f"(known: {', '.join(known)})")
    return doc


def _number(doc: dict, key: str, path: Path) -> float:
    value = _require(doc, key, path)
    try:
        if isinstance(value, bool):
            raise TypeError
        return float(value)
    except (TypeError, ValueError):
        raise SubjectError(path, f"{key} {value!r} is not a number") from None


def load_markerset(name: str, directory: Path = MARKERSETS_DIR) -> dict[str, str]:
    """Role -> marker name of the marker set `name`: a shipped set's name or a YAML path
    (`ingest.markersets.load_markerset`)."""
    return markersets.load_markerset(name, directory)


def _treadmill(value, path: Path) -> bool | None:
    """A trial's `treadmill` (or the subject's, for every trial that does not say): true, false or
    absent (detected: `ingest.treadmill`)."""
    if value is None or isinstance(value, bool):
        return value
    raise SubjectError(path, f"treadmill must be true or false, not {value!r}")


def _belt_speed(value, path: Path) -> float | None:
    if value is None:
        return None
    try:
        speed = float(value)
    except (TypeError, ValueError):
        speed = float("nan")
    if not 0.0 < speed < 10.0:
        raise SubjectError(path, f"belt_speed_mps {value!r} is not a belt speed in m/s")
    return speed


def check_body_size(height_m: float, mass_kg: float, source: str | Path) -> None:
    """`SubjectError` naming `source` and the accepted range when the height (m) or the mass (kg) is
    outside `HEIGHT_RANGE_M` / `MASS_RANGE_KG` (the force plates check the mass closer:
    `ingest.weighing`)."""
    for name, value, (lo, hi), unit, what in (("height_m", height_m, HEIGHT_RANGE_M, "m", "metres"),
                                              ("mass_kg", mass_kg, MASS_RANGE_KG, "kg", "kilograms")):
        if not lo <= value <= hi:
            raise SubjectError(source, f"{name} {value:g} is outside the accepted {lo:g}-{hi:g} {unit} "
                                       f"(a human's, in {what})")


def load_subject(subject_id: str, directory: Path = SUBJECTS_DIR) -> Subject:
    """Load and validate `<directory>/<subject_id>.yaml`."""
    path = directory / f"{subject_id}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in directory.glob("*.yaml"))
        raise SubjectError(path, f"unknown subject {subject_id!r} (known: {', '.join(known)})")
    try:
        doc = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as exc:
        raise SubjectError(path, f"not valid YAML ({exc})") from None
    _mapping(doc, "subject file", SUBJECT_KEYS, path)
    if _require(doc, "id", path) != subject_id:
        raise SubjectError(path, f"id {doc['id']!r} does not match the file name {subject_id!r}")
    height, mass = _number(doc, "height_m", path), _number(doc, "mass_kg", path)
    check_body_size(height, mass, path)
    fmt_doc = _mapping(doc.get("format") or {}, "format", FORMAT_KEYS, path)
    sign = fmt_doc.get("knee_flexion_sign", 1)
    fmt = FileFormat(
        up_axis=str(fmt_doc.get("up_axis", "auto")).lower(),
        knee_flexion_sign=sign if sign in (1, -1) and not isinstance(sign, bool) else 0,
        angle_unit=fmt_doc.get("angle_unit"),
    )
    if fmt.up_axis not in UP_AXIS_CHOICES or fmt.knee_flexion_sign not in (1, -1):
        raise SubjectError(path, "format.up_axis must be x, y, z or auto and knee_flexion_sign 1 or -1 "
                                 f"(got {fmt_doc.get('up_axis', 'auto')!r}, {sign!r})")
    if fmt.angle_unit not in (None, "deg", "rad"):
        raise SubjectError(path, f"format.angle_unit must be deg or rad, not {fmt.angle_unit!r}")
    trial_docs = _require(doc, "trials", path)
    if not isinstance(trial_docs, list):
        raise SubjectError(path, f"trials must be a list of trials, not {trial_docs!r}")
    for k, t in enumerate(trial_docs):
        _mapping(t, f"trials[{k}]", TRIAL_KEYS, path)
    trials = tuple(
        TrialSpec(
            id=str(_require(t, "id", path)),
            condition=str(_require(t, "condition", path)),
            markers=t.get("markers"),
            angles=t.get("angles"),
            grf=t.get("grf"),
            robot_log=t.get("robot_log"),
            treadmill=_treadmill(t.get("treadmill", doc.get("treadmill")), path),
            belt_speed_mps=_belt_speed(t.get("belt_speed_mps"), path),
        )
        for t in trial_docs
    )
    if not trials:
        raise SubjectError(path, "no trials listed")
    ids = [t.id for t in trials]
    if len(set(ids)) != len(ids):
        twice = sorted({i for i in ids if ids.count(i) > 1})
        raise SubjectError(path, f"trial id(s) {', '.join(map(repr, twice))} listed twice: each trial needs "
                                 "an id of its own")
    for t in trials:
        if t.belt_speed_mps is not None and t.treadmill is False:
            raise SubjectError(path, f"trial {t.id!r} has a belt_speed_mps but treadmill: false")
        if t.robot_log and t.condition == "free":
            raise SubjectError(path, f"trial {t.id!r} is free walking but has a robot_log: name the "
                               "controller that ran as its condition")
    robot_markers = None
    if doc.get("robot_markers"):
        rm = doc["robot_markers"]
        try:
            neutral = tuple(float(x) for x in rm["neutral_in_base_m"])
            robot_markers = RobotMarkers(str(rm["base_front"]), str(rm["base_rear"]), str(rm["arm_end"]),
                                         neutral)
        except (KeyError, TypeError, ValueError) as exc:
            raise SubjectError(path, f"robot_markers needs base_front, base_rear, arm_end (marker names) and "
                               f"neutral_in_base_m [x, y, z] in metres ({exc!r})") from None
        if len(neutral) != 3:
            raise SubjectError(path, "robot_markers.neutral_in_base_m must be [x, y, z] in metres")
    static_doc = doc.get("static")
    static = None
    if static_doc in (STATIC_AUTO, STATIC_NONE):
        static = StaticSpec(static_doc)
    elif static_doc:
        if isinstance(static_doc, str):
            raise SubjectError(path, f"static must be {STATIC_AUTO}, {STATIC_NONE} or a mapping of "
                                     f"{', '.join(STATIC_KEYS)}, not {static_doc!r}")
        _mapping(static_doc, "static", STATIC_KEYS, path)
        if not static_doc.get("markers"):
            raise SubjectError(path, "static: missing required field 'markers' (the static trial's "
                                     "manifest key)")
        window = static_doc.get("window_s")
        angles = static_doc.get("angles")
        if window is not None and not (isinstance(window, list) and len(window) == 2
                                       and all(isinstance(w, int | float) for w in window)
                                       and window[0] < window[1]):
            raise SubjectError(path, f"static.window_s must be [start, end] in seconds with start < end, "
                                     f"not {window!r}")
        static = StaticSpec(str(static_doc["markers"]), tuple(window) if window else None,
                            str(angles) if angles else None)
    return Subject(
        id=subject_id,
        height_m=height,
        mass_kg=mass,
        dataset=str(_require(doc, "dataset", path)),
        markerset=load_markerset(str(_require(doc, "markerset", path))),
        format=fmt,
        static=static,
        trials=trials,
        path=path,
        round_trip_of=str(doc["round_trip_of"]) if doc.get("round_trip_of") else None,
        robot_markers=robot_markers,
    )
