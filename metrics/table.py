"""A metric table: its name, its typed columns, the group its rows belong to, how it is computed.

Each metric module declares the tables it makes (`gait.TABLE`, `spm.TESTS`, ...) beside the function
that computes them; `metrics.tables.REGISTRY` lists them, and everything downstream follows from
that list: the metrics stage's outputs, the results store's `result_<name>` tables and `latest_<name>`
views, the report's table list.

A row's group is `metrics.groups.GROUP` (subject, source, human_mode, condition), read from the
table's `group` columns (in GROUP's order: the SPM tests name theirs `*_b`, the group of their
second sample); a table `linked` to another (table, column) takes the group of that table's row
with the same value in that column (an SPM curve or cluster: its test's, by `test_id`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from metrics.errors import MetricsError
from metrics.groups import GROUP

TYPES = ("VARCHAR", "BIGINT", "DOUBLE", "BOOLEAN")  # DuckDB column types a metric table may use
# the group columns as a table's first columns (most tables start with them)
GROUP_COLUMNS: dict[str, str] = {c: "VARCHAR" for c in GROUP}


@dataclass(frozen=True)
class MetricInputs:
    """What a metric table is computed from: one subject's strides, cycles and robot rows of every
    source (robot may be empty) and the policy human's robot rows of every scenario."""

    strides: pd.DataFrame
    cycles: pd.DataFrame
    robot: pd.DataFrame = field(default_factory=pd.DataFrame)
    scenario_robot: pd.DataFrame = field(default_factory=pd.DataFrame)
    _shared: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def has_robot(self) -> bool:
        return not self.robot.empty

    def shared(self, key: str, make: Callable[[], Any]) -> Any:
        """`make()`, computed once for these inputs: a computation that gives several tables (the
        SPM tests, curves and clusters) runs once for all of them."""
        if key not in self._shared:
            self._shared[key] = make()
        return self._shared[key]


Compute = Callable[[MetricInputs, Any], pd.DataFrame]  # (inputs, the `metrics` params section) -> rows


@dataclass(frozen=True)
class MetricTable:
    """One metric table. `columns`: name -> DuckDB type, in the order the table is written and stored;
    `compute(inputs, p)`: its rows (`p`: the `metrics` params section); `group`: its columns that
    hold GROUP, in GROUP's order; `linked`: (table, column) whose rows give its rows' group instead;
    `title`: what the report calls it (empty: the report shows no table of it)."""

    name: str
    columns: Mapping[str, str]
    compute: Compute
    group: tuple[str, ...] = tuple(GROUP)
    linked: tuple[str, str] | None = None
    title: str = ""

    def __post_init__(self) -> None:
        if not self.name.isidentifier() or not self.name.islower():
            raise MetricsError(self.name, "a metric table's name must be a lower-case identifier")
        bad = {c: t for c, t in self.columns.items() if t not in TYPES}
        if bad:
            raise MetricsError(self.name, f"column types must be one of {list(TYPES)}; got {bad}")
        needed = [self.linked[1]] if self.linked else list(self.group)
        missing = [c for c in needed if c not in self.columns]
        if missing:
            raise MetricsError(self.name, f"its group columns {missing} are not among its columns "
                               f"{list(self.columns)}")
        if not self.linked and len(self.group) != len(GROUP):
            raise MetricsError(self.name, f"group must name {len(GROUP)} columns ({GROUP}); got {self.group}")

    @property
    def column_names(self) -> list[str]:
        return list(self.columns)

    def ddl(self) -> str:
        """The columns as SQL (`name TYPE, ...`)."""
        return ", ".join(f"{c} {t}" for c, t in self.columns.items())

    def empty(self) -> pd.DataFrame:
        """No rows, its columns."""
        return pd.DataFrame(columns=self.column_names)
