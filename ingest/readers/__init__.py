"""Readers: one per file format, each returning plain arrays with the units its header declares.

Conversion to the canonical frame happens in `ingest.canonical`, driven by what the header says
and what the subject file declares; readers never guess.
"""

from ingest.readers.c3d import read_c3d
from ingest.readers.csv import read_csv
from ingest.readers.mot import MotTable, read_mot
from ingest.readers.trc import MarkerTable, read_markers, read_trc

__all__ = ["MarkerTable", "MotTable", "read_c3d", "read_csv", "read_markers", "read_mot", "read_trc"]
