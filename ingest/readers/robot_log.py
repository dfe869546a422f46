"""The robot log of a real robot-assisted trial: "gaitloop robot log v1", a CSV file.

A follow-me robot (a mobile base with a passive 3-DoF arm attached to the pelvis by a harness)
records what it did; `ingest.robot_log` turns this log into the robot table the metrics read.

Format:

- UTF-8 text (a byte-order mark is tolerated), comma separated, no quoting. Optional leading
  comment lines starting with ``#`` (and blank lines before the header); then one header line
  of ``name [unit]`` cells; then one numeric row per sample. Column order is free, names and
  units are case-sensitive, each column appears at most once.
- Required columns (an empty cell, NaN or infinity in them is an error):

  - ``time [s]`` or ``time [ms]``: sample time, strictly increasing, on the same clock as the
    mocap file of the trial;
  - ``arm_forward``, ``arm_lateral``, ``arm_vertical`` [m, cm or mm]: the arm's joint positions
    from its neutral point, robot frame (x forward, y left, z up);
  - ``base_x``, ``base_y`` [m, cm or mm] and ``base_yaw`` [rad or deg]: the base pose in the
    robot's odometry frame.

- Optional groups, each with all of its columns or none (a partial group is an error):

  - load-cell forces ``harness_fx``, ``harness_fy``, ``harness_fz`` [N] and load-cell torques
    ``harness_tx``, ``harness_ty``, ``harness_tz`` [N m, Nm or N.m]: the wrench the harness
    exerts on the pelvis, robot frame (forces and torques are two groups: either may come alone);
  - commands ``cmd_speed`` [m/s] and ``cmd_yaw_rate`` [rad/s or deg/s];
  - flags ``fall`` [-] and ``locked`` [-], each on its own: 0 or 1 in every row.

  Empty cells in the load-cell and command columns are missing samples (NaN).
- At least 2 rows.

`read_robot_log` converts to SI (s, m, rad, N, N m); `write_robot_log` writes the same format in
those units, with ``# gaitloop robot log v1`` as its first line, so a written log reads back
unchanged.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ingest.errors import IngestError

FORMAT_LINE = "# gaitloop robot log v1"

_LENGTH = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
_TORQUE = {"N m": 1.0, "Nm": 1.0, "N.m": 1.0}
# column -> (unit -> factor to SI); the first unit of each is the SI unit the writer uses
_UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3},
    **{f"arm_{axis}": _LENGTH for axis in ("forward", "lateral", "vertical")},
    "base_x": _LENGTH, "base_y": _LENGTH, "base_yaw": {"rad": 1.0, "deg": np.pi / 180},
    **{f"harness_f{axis}": {"N": 1.0} for axis in "xyz"},
    **{f"harness_t{axis}": _TORQUE for axis in "xyz"},
    "cmd_speed": {"m/s": 1.0}, "cmd_yaw_rate": {"rad/s": 1.0, "deg/s": np.pi / 180},
    "fall": {"-": 1.0}, "locked": {"-": 1.0},
}
_REQUIRED = ("time", "arm_forward", "arm_lateral", "arm_vertical", "base_x", "base_y", "base_yaw")
_GROUPS = {
    "load-cell force": ("harness_fx", "harness_fy", "harness_fz"),
    "load-cell torque": ("harness_tx", "harness_ty", "harness_tz"),
    "command": ("cmd_speed", "cmd_yaw_rate"),
    "fall flag": ("fall",),
    "locked flag": ("locked",),
}
_FLAGS = ("fall", "locked")
_HEADER_CELL = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*\[(?P<unit>[^\[\]]*)\]$")


@dataclass(frozen=True, eq=False)
class RobotLog:
    """A robot log in SI units (s, m, rad, N, N m); absent optional groups are None.

    `wrench` columns are fx, fy, fz, tx, ty, tz; a half the file lacks (forces or torques) is NaN.
    Arrays do not compare with ``==``: compare the fields with numpy.
    """

    path: Path
    time_s: np.ndarray  # (n,)
    arm_m: np.ndarray  # (n, 3) forward, lateral, vertical
    base_xy_m: np.ndarray  # (n, 2) odometry frame
    base_yaw_rad: np.ndarray  # (n,)
    wrench: np.ndarray | None = None  # (n, 6)
    cmd: np.ndarray | None = None  # (n, 2) speed m/s, yaw rate rad/s
    fall: np.ndarray | None = None  # (n,) bool
    locked: np.ndarray | None = None  # (n,) bool


def _header(path: Path, line: str, line_no: int) -> list[tuple[str, float]]:
    """Parse and check the header line: (column name, factor to SI) per cell."""
    columns: list[tuple[str, float]] = []
    for cell in (c.strip() for c in line.split(",")):
        match = _HEADER_CELL.match(cell)
        if match is None:
            raise IngestError(path, f"header (line {line_no}) cell {cell!r} is not 'name [unit]'")
        name, unit = match["name"], " ".join(match["unit"].split())
        if name not in _UNITS:
            raise IngestError(path, f"unknown column {name!r} (known: {', '.join(_UNITS)})")
        if any(name == seen for seen, _ in columns):
            raise IngestError(path, f"duplicate column {name!r}")
        if unit not in _UNITS[name]:
            raise IngestError(path, f"column {name!r} has unit {unit!r}; accepted: "
                                    f"{', '.join(repr(u) for u in _UNITS[name])}")
        columns.append((name, _UNITS[name][unit]))
    names = {name for name, _ in columns}
    missing = [name for name in _REQUIRED if name not in names]
    if missing:
        raise IngestError(path, f"missing required columns: {', '.join(missing)}")
    for group, members in _GROUPS.items():
        absent = [m for m in members if m not in names]
        if absent and len(absent) < len(members):
            raise IngestError(path, f"partial {group} group: missing {', '.join(absent)} "
                                    f"(a group has all of {', '.join(members)} or none)")
    return columns


def _cells(path: Path, lines: list[str], first: int, n_columns: int) -> tuple[np.ndarray, np.ndarray]:
    """The data rows from line index `first` on as strings (n, n_columns), and their line numbers."""
    rows, line_nos = [], []
    for i in range(first, len(lines)):
        if not lines[i].strip():
            continue
        cells = lines[i].split(",")
        if len(cells) != n_columns:
            raise IngestError(path, f"line {i + 1} has {len(cells)} cells, the header {n_columns}")
        rows.append([c.strip() for c in cells])
        line_nos.append(i + 1)
    return np.array(rows, dtype=str).reshape(len(rows), n_columns), np.array(line_nos, dtype=int)


def read_robot_log(path: str | Path) -> RobotLog:
    """Read a gaitloop robot log v1 (see the module docstring); raises `IngestError` naming the file."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except OSError as exc:
        raise IngestError(path, f"cannot read file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise IngestError(path, f"not UTF-8 text (byte {exc.start})") from None
    lines = text.splitlines()
    head = next((i for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")), None)
    if head is None:
        raise IngestError(path, "empty: no header line")
    columns = _header(path, lines[head], head + 1)
    cells, line_nos = _cells(path, lines, head + 1, len(columns))
    if len(cells) < 2:
        raise IngestError(path, f"{len(cells)} data rows; a robot log needs at least 2")
    numbers = pd.to_numeric(pd.Series(cells.ravel()), errors="coerce").to_numpy(dtype=float)
    numbers = numbers.reshape(cells.shape)
    bad = np.isnan(numbers) & (cells != "") & (np.char.lower(cells) != "nan")
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise IngestError(path, f"non-numeric cell {str(cells[r, c])!r} in column {columns[c][0]!r} "
                                f"at line {line_nos[r]}")
    names = [name for name, _ in columns]
    data = {name: numbers[:, j] * factor for j, (name, factor) in enumerate(columns)}
    for name in _REQUIRED:
        finite = np.isfinite(data[name])
        if not finite.all():
            r = int(np.argmin(finite))
            what = "empty cell" if cells[r, names.index(name)] == "" else "NaN or infinity"
            raise IngestError(path, f"{what} in required column {name!r} at line {line_nos[r]}")
    time = data["time"]
    steps = np.diff(time)
    if (steps <= 0).any():
        r = int(np.argmax(steps <= 0)) + 1
        raise IngestError(path, f"time not strictly increasing at line {line_nos[r]}: "
                                f"{time[r]:.9g} s after {time[r - 1]:.9g} s")
    for name in _FLAGS:
        if name in data:
            off = ~np.isin(data[name], (0.0, 1.0))
            if off.any():
                r = int(np.argmax(off))
                raise IngestError(path, f"flag {name!r} is {str(cells[r, names.index(name)])!r} "
                                        f"at line {line_nos[r]}; flags are 0 or 1")
    n = len(time)

    def group(names: tuple[str, ...]) -> np.ndarray:
        return np.column_stack([data.get(c, np.full(n, np.nan)) for c in names])

    has_wrench = any(c in data for c in _GROUPS["load-cell force"] + _GROUPS["load-cell torque"])
    return RobotLog(
        path=path, time_s=time,
        arm_m=group(("arm_forward", "arm_lateral", "arm_vertical")),
        base_xy_m=group(("base_x", "base_y")), base_yaw_rad=data["base_yaw"],
        wrench=group(_GROUPS["load-cell force"] + _GROUPS["load-cell torque"]) if has_wrench else None,
        cmd=group(_GROUPS["command"]) if "cmd_speed" in data else None,
        fall=data["fall"].astype(bool) if "fall" in data else None,
        locked=data["locked"].astype(bool) if "locked" in data else None,
    )


def write_robot_log(path: str | Path, log: RobotLog) -> None:
    """Write `log` as a gaitloop robot log v1 in SI units; groups that are None (or all NaN) are left out.

    Floats are written in their shortest exact form (Python's `repr`), so reading the file back gives
    the same values.
    """
    n = len(log.time_s)
    columns: dict[str, np.ndarray] = {"time [s]": log.time_s}
    for j, axis in enumerate(("forward", "lateral", "vertical")):
        columns[f"arm_{axis} [m]"] = log.arm_m[:, j]
    columns |= {"base_x [m]": log.base_xy_m[:, 0], "base_y [m]": log.base_xy_m[:, 1],
                "base_yaw [rad]": log.base_yaw_rad}
    if log.wrench is not None:
        for half, unit in ((slice(0, 3), "N"), (slice(3, 6), "N m")):
            names = [f"harness_{q} [{unit}]" for q in ("fx", "fy", "fz", "tx", "ty", "tz")[half]]
            if not np.isnan(log.wrench[:, half]).all():
                columns |= dict(zip(names, log.wrench[:, half].T, strict=True))
    if log.cmd is not None:
        columns |= {"cmd_speed [m/s]": log.cmd[:, 0], "cmd_yaw_rate [rad/s]": log.cmd[:, 1]}
    for name in _FLAGS:
        flag = getattr(log, name)
        if flag is not None:
            columns[f"{name} [-]"] = np.asarray(flag, dtype=bool).astype(int)
    body = []
    values = [np.asarray(v) for v in columns.values()]
    for i in range(n):
        body.append(",".join("" if v.dtype.kind == "f" and np.isnan(v[i]) else
                             (str(v[i]) if v.dtype.kind in "iub" else repr(float(v[i]))) for v in values))
    text = "\n".join([FORMAT_LINE, ",".join(columns), *body]) + "\n"
    Path(path).write_text(text, encoding="utf-8")


__all__ = ["FORMAT_LINE", "RobotLog", "read_robot_log", "write_robot_log"]
