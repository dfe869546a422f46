"""Errors raised by ingest: each names the file (or subject) and what is wrong with it."""

from __future__ import annotations

from pathlib import Path


class GaitloopError(Exception):
    """Base class of every error gaitloop raises on purpose."""


class IngestError(GaitloopError):
    """A recording or subject file that cannot be turned into a trustworthy canonical Trial."""

    def __init__(self, source: str | Path, problem: str) -> None:
        self.source = str(source)
        self.problem = problem
        super().__init__(f"{self.source}: {problem}")


class ManifestError(IngestError):
    """A data file that cannot be resolved from the mirror or its origin, or whose hash differs."""


class SubjectError(IngestError):
    """An unknown subject id or an invalid subject file."""
