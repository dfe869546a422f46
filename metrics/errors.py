"""Errors raised by metrics: each names the table (or subject) and what is wrong with it."""

from __future__ import annotations

from ingest.errors import GaitloopError


class MetricsError(GaitloopError):
    """A gait or robot table that lacks the columns or rows a metric needs."""

    def __init__(self, table: str, problem: str) -> None:
        self.table = table
        self.problem = problem
        super().__init__(f"{table}: {problem}")
