"""OpenSim/Motion Analysis `.trc` marker files.

Layout: line 1 file type; lines 2-3 header keys and values (DataRate, NumFrames, NumMarkers,
Units, ...); line 4 `Frame#`, `Time` and one name per marker (spanning X/Y/Z); line 5 the
X1 Y1 Z1 ... labels; then tab-separated rows. Empty cells are missing samples (NaN).

The header's DataRate is the rate: a Time column written with few decimals (60 Hz rounded to
0.001 s steps 0.016 and 0.017 s apart, whose median reads as 58.82 Hz) is replaced by the header's
grid when every row lies within the column's rounding of it (`regular_time`); a Time column that
departs further from the header's rate is refused, naming both.

Header lines 2-3 and the marker-name line are also read when aligned with repeated tabs or spaces
(some exporters pad them): keys, values and names never contain spaces, so when the tab cells do
not pair up, the runs of whitespace separate them. Data rows stay strictly tab-separated.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pandas as pd

from ingest.errors import IngestError
from ingest.readers.delimited import NON_SPACE, strict_float_rows
from ingest.readers.table import UNIT_TO_M, MarkerTable


def _header_fields(path: Path, keys: str, values: str) -> dict[str, str]:
    """Header keys (line 2) -> values (line 3): tab cells as written, or, when padding tabs or
    spaces leave empty cells or unequal counts, the whitespace-separated words."""
    k = [c.strip() for c in keys.rstrip("\r\n").split("\t")]
    v = [c.strip() for c in values.rstrip("\r\n").split("\t")]
    if len(k) != len(v) or any(len(c.split()) != 1 for c in k + v):  # empty cells, or cells with spaces
        words_k, words_v = keys.split(), values.split()
        if len(words_k) == len(words_v):
            k, v = words_k, words_v
    if "DataRate" not in k or "Units" not in k:
        raise IngestError(path, "not a TRC file: header line 2 lacks DataRate/Units")
    return dict(zip(k, v, strict=False))


def _marker_names(line: str, n_markers: int) -> tuple[str, ...]:
    """Marker names of line 4 after `Frame#` and `Time`: the non-empty tab cells (each name is
    followed by empty cells over its Y and Z columns), else the whitespace-separated words."""
    cells = [c.strip() for c in line.rstrip("\r\n").split("\t") if c.strip()]
    if len(cells) - 2 != n_markers and len(line.split()) - 2 == n_markers:
        cells = line.split()
    return tuple(cells[2:])


def _layout(raw: bytes, n_head: int = 5) -> tuple[list[str], bool, bool, list[str]]:
    """The first `n_head` lines of the file's bytes `raw` (decoded), whether a line follows them,
    whether any following line holds more than whitespace, and the last two lines, all as
    `str.splitlines` gives them, found without decoding or splitting the thousands of rows in
    between (that cost more than the header checks); lines ending in anything but \\n or \\r\\n fall
    back to decoding the whole file."""
    start = 0
    for _ in range(n_head):
        start = raw.find(b"\n", start) + 1
        if start == 0:
            break
    head = raw[:start].decode(errors="replace").splitlines() if start else []
    if len(head) != n_head:
        lines = raw.decode(errors="replace").splitlines()
        return lines[:n_head], len(lines) > n_head, any(ln.strip() for ln in lines[n_head:]), lines[-2:]
    cut = len(raw)
    for _ in range(3):  # the last two lines start after the third newline from the end
        cut = raw.rfind(b"\n", start, cut) if cut > start else -1
    tail = raw[cut + 1 if cut >= 0 else start:].decode(errors="replace").splitlines()[-2:]
    return head, start < len(raw), NON_SPACE.search(raw, start) is not None, tail


def _rows(raw: bytes, n_cols: int) -> np.ndarray | None:
    """The data rows after the 5 header lines by the strict fast reader (`ingest.readers.delimited`):
    rows of `n_cols` cells, or of one more that is empty in every row (a trailing tab); None when
    neither reads (pandas then reads, or names what is wrong)."""
    data = strict_float_rows(raw, n_cols, skip_rows=5)  # rows ending in a tab fail at the first row
    if data is None:
        data = strict_float_rows(raw, n_cols + 1, skip_rows=5)
        if data is None or not np.isnan(data[:, n_cols]).all():
            return None
        data = data[:, :n_cols]
    return data


def time_resolution(time_s: np.ndarray) -> float:
    """The coarsest power of ten (0.1 s down to 1e-9 s) of which every time is a whole multiple: the
    rounding of a Time column written with that many decimals (1e-9 s for one written in full)."""
    for decimals in range(1, 10):
        step = 10.0 ** -decimals
        if np.abs(time_s / step - np.round(time_s / step)).max() < 1e-3:
            return step
    return 1e-9


def regular_time(path: Path, time_s: np.ndarray, rate_hz: float) -> np.ndarray:
    """`time_s` on the header's grid `time_s[0] + k / rate_hz`: as it is when it lies there already (to
    1e-9 s), the grid when every row lies within the column's rounding of it (`time_resolution`: the
    first time and each row rounded); `IngestError` naming the file and both rates when it departs
    further (a wrong DataRate, dropped frames, another clock)."""
    grid = time_s[0] + np.arange(len(time_s)) / rate_hz
    off = np.abs(time_s - grid)
    worst = int(np.argmax(off)) if len(off) else 0
    if not len(off) or off[worst] <= 1e-9:
        return time_s
    resolution = time_resolution(time_s)
    if off[worst] <= resolution * (1 + 1e-6):
        return grid
    steps = np.diff(time_s)
    column = f"{1.0 / float(np.median(steps)):.6g} Hz" if len(steps) and np.median(steps) > 0 else "no rate"
    raise IngestError(path, f"header DataRate {rate_hz:g} Hz but the Time column steps at {column} "
                            f"(median step): row {worst + 1} is at {time_s[worst]:.6g} s, {off[worst]:.3g} s "
                            f"off the header's {grid[worst]:.6g} s, more than the column's rounding "
                            f"({resolution:g} s); fix DataRate or the Time column")


def read_trc(path: str | Path) -> MarkerTable:
    """Read a `.trc` file; raises `IngestError` naming the file on any structural problem. The file
    is read once: its header from the text, its rows from the same bytes by the strict fast reader
    (`ingest.readers.delimited`), or by pandas when that refuses them."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise IngestError(path, f"cannot read file ({exc.strerror})") from None
    lines, more, has_rows, tail = _layout(raw)
    if not more:
        raise IngestError(path, f"truncated: only {len(raw.decode(errors='replace').splitlines())} lines, "
                                "a TRC header needs 5")
    header = _header_fields(path, lines[1], lines[2])
    unit = header["Units"].strip()
    if unit not in UNIT_TO_M:
        raise IngestError(path, f"unknown Units {unit!r} (expected one of {sorted(UNIT_TO_M)})")
    try:
        rate = float(header["DataRate"])
        n_frames = int(header["NumFrames"])
        n_markers = int(header["NumMarkers"])
    except (KeyError, ValueError) as exc:
        raise IngestError(path, f"bad header value: {exc}") from None
    if not (np.isfinite(rate) and rate > 0):
        raise IngestError(path, f"header DataRate {rate:g} Hz: must be a positive number of frames per "
                                "second")
    names = _marker_names(lines[3], n_markers)
    if len(names) != n_markers:
        raise IngestError(path, f"header declares {n_markers} markers, line 4 names {len(names)}")
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise IngestError(path, f"duplicate marker name(s) on line 4: {', '.join(twice)} (each marker's "
                                "three columns need a name of their own)")
    n_cols = 2 + 3 * n_markers
    if not has_rows:
        raise IngestError(path, "no data rows")
    data = _rows(raw, n_cols)
    if data is None:
        try:
            table = pd.read_csv(  # in one piece (low_memory=False): a marker file is a few MB at most
                io.BytesIO(raw), sep="\t", header=None, names=range(n_cols + 1), skiprows=5,
                skip_blank_lines=True, dtype=float, engine="c", low_memory=False,
            )
        except ValueError as exc:
            raise IngestError(path, f"malformed data rows: {exc}") from None
        if table.shape[1] > n_cols and table[n_cols].notna().any():
            raise IngestError(path, f"rows hold more than the {n_cols} cells the header declares")
        data = table.to_numpy()[:, :n_cols]
    last = tail[-1] if tail[-1].strip() else tail[-2]
    if len(last.rstrip("\r\n").split("\t")) < n_cols:
        raise IngestError(path, f"truncated: the last row has fewer than {n_cols} cells")
    rows = data
    if len(rows) < n_frames:
        raise IngestError(path, f"truncated: header declares {n_frames} frames, file holds {len(rows)}")
    time = data[:, 1].copy()  # not a view: it would hold the whole table for the trial's lifetime
    if np.isnan(time).any():
        raise IngestError(path, "Time column has empty cells")
    back = np.flatnonzero(~(np.diff(time) > 0))
    if len(back):
        k = int(back[0]) + 1
        raise IngestError(path, f"Time column not strictly increasing: row {k + 1} is at {time[k]:.6g} s "
                                f"after {time[k - 1]:.6g} s")
    time = regular_time(path, time, rate)
    xyz = data[:, 2:].reshape(len(rows), n_markers, 3)  # a view: metres need no copy
    if np.isinf(xyz).any():
        row, marker = (int(i) for i in np.argwhere(np.isinf(xyz).any(axis=2))[0])
        raise IngestError(path, f"marker {names[marker]} has an infinite coordinate at row {row + 1} "
                                f"({time[row]:.6g} s): a missing sample must be an empty cell")
    if UNIT_TO_M[unit] != 1.0:
        xyz = xyz * UNIT_TO_M[unit]
    return MarkerTable(path, rate, time, names, xyz, unit)


def write_trc(path: str | Path, time_s: np.ndarray, names: tuple[str, ...] | list[str], xyz_m: np.ndarray,
              unit: str = "mm") -> Path:
    """Write markers (n_frames, n_markers, 3) in metres, in the axes given, as an OpenSim `.trc` in
    `unit` (the layout `read_trc` reads; NaN -> empty cell). The rate is taken from `time_s`."""
    path = Path(path)
    time_s = np.asarray(time_s, float)
    xyz = np.asarray(xyz_m, float) / UNIT_TO_M[unit]
    n, m = len(time_s), len(names)
    if xyz.shape != (n, m, 3):
        raise IngestError(path, f"markers have shape {xyz.shape}, expected ({n}, {m}, 3)")
    rate = (n - 1) / (time_s[-1] - time_s[0]) if n > 1 else 0.0
    head = [f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
            f"{rate:.10g}\t{rate:.10g}\t{n}\t{m}\t{unit}\t{rate:.10g}\t1\t{n}",
            "\t".join(["Frame#", "Time", *(f"{name}\t\t" for name in names)]).rstrip("\t"),
            "\t".join(["", "", *(f"X{j}\tY{j}\tZ{j}" for j in range(1, m + 1))]), ""]
    cells = np.char.mod("%.6f", xyz.reshape(n, 3 * m))
    cells[~np.isfinite(xyz.reshape(n, 3 * m))] = ""
    rows = ["\t".join([str(k + 1), f"{t:.6f}", *row])
            for k, (t, row) in enumerate(zip(time_s, cells, strict=True))]
    path.write_text("\n".join(head + rows) + "\n")
    return path
