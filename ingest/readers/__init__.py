"""Readers: one per file format, each returning plain arrays with the units its header declares.

Conversion to the canonical frame happens in `ingest.canonical`, driven by what the header says
and what the subject file declares; readers never guess. `read_markers` picks the marker reader by
the file's suffix.
"""

from __future__ import annotations

from pathlib import Path

from ingest.errors import IngestError
from ingest.readers.c3d import C3dRecording, read_c3d
from ingest.readers.csv import CsvRecording, read_csv
from ingest.readers.mot import MotTable, read_mot
from ingest.readers.robot_log import RobotLog, read_robot_log, write_robot_log
from ingest.readers.table import UNIT_TO_M, MarkerTable
from ingest.readers.trc import read_trc


def read_markers(path: str | Path) -> MarkerTable:
    """Dispatch on the suffix to the TRC, C3D or CSV marker reader."""
    suffix = Path(path).suffix.lower()
    if suffix == ".trc":
        return read_trc(path)
    if suffix == ".c3d":
        return read_c3d(path).markers
    if suffix == ".csv":
        return read_csv(path).markers
    raise IngestError(path, f"unknown marker file type {suffix!r} (expected .trc, .c3d or .csv)")


__all__ = ["UNIT_TO_M", "C3dRecording", "CsvRecording", "MarkerTable", "MotTable", "RobotLog", "read_c3d",
           "read_csv", "read_markers", "read_mot", "read_robot_log", "read_trc", "write_robot_log"]
