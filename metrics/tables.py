"""The metric tables, in the order they are computed, written and stored (`metrics.table.MetricTable`).

Adding a table: a module in `metrics/` with its function and its `MetricTable` (name, typed columns,
group, compute), and one line here. The metrics stage writes it (`data/metrics/<subject>/tables/`),
the results store creates `result_<name>` and `latest_<name>` for it, and the report lists it when it
has a title (`report_tables`). A table linked to another comes after it.
"""

from __future__ import annotations

from collections.abc import Iterable

from metrics import compliance, curves, gait, harness, phases, rom, spm, stability, tracking
from metrics.errors import MetricsError
from metrics.table import MetricTable

REGISTRY: tuple[MetricTable, ...] = (
    gait.TABLE,
    stability.TABLE,
    rom.TABLE,
    curves.TABLE,  # kinematics
    compliance.TABLE,
    harness.TABLE,
    tracking.TABLE,
    spm.TEST_TABLE,
    phases.TABLE,
    phases.EVENT_TABLE,
    spm.CURVE_TABLE,
    spm.CLUSTER_TABLE,
)
# the tables the report shows, in its order (each has a title)
REPORTED = ("compliance", "gait", "stability", "phases")


def checked(tables: Iterable[MetricTable]) -> tuple[MetricTable, ...]:
    """`tables` as a registry: names unique, a linked table after the table it links to and sharing
    its link column; raises `MetricsError` naming the table otherwise."""
    seen: dict[str, MetricTable] = {}
    for table in tables:
        if table.name in seen:
            raise MetricsError(table.name, "registered twice")
        if table.linked:
            parent, column = table.linked
            if parent not in seen:
                raise MetricsError(table.name, f"linked to {parent!r}, which is not registered before it")
            if column not in seen[parent].columns:
                raise MetricsError(table.name, f"linked by {column!r}, which {parent!r} lacks")
        seen[table.name] = table
    return tuple(seen.values())


def by_name(name: str, registry: Iterable[MetricTable] = REGISTRY) -> MetricTable:
    for table in registry:
        if table.name == name:
            return table
    raise MetricsError(name, f"no such metric table (registered: {', '.join(t.name for t in registry)})")


def names(registry: Iterable[MetricTable] = REGISTRY) -> tuple[str, ...]:
    return tuple(t.name for t in registry)


def report_tables(registry: Iterable[MetricTable] = REGISTRY) -> tuple[MetricTable, ...]:
    """The tables the report shows (`REPORTED`), each with its title."""
    return tuple(by_name(n, registry) for n in REPORTED)


REGISTRY = checked(REGISTRY)
