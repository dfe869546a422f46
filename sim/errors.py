"""Errors raised by sim: each names the subject, model file or stage and what is wrong."""

from __future__ import annotations

from pathlib import Path

from ingest.errors import GaitloopError


class SimulationError(GaitloopError):
    """A model that cannot be built, loaded or simulated as asked."""

    def __init__(self, source: str | Path, problem: str) -> None:
        self.source = str(source)
        self.problem = problem
        super().__init__(f"{self.source}: {problem}")

    def __reduce__(self):  # picklable across process pools
        return type(self), (self.source, self.problem)


class ScalingError(SimulationError):
    """A static trial or subject that cannot be turned into segment lengths and joint centres."""
