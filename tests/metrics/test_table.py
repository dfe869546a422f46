"""metrics.table and metrics.tables: a metric table's declaration is checked once, where it is made, and
the registry holds each table once, a linked table after the table it links to."""

import pandas as pd
import pytest

from metrics.errors import MetricsError
from metrics.groups import GROUP
from metrics.table import GROUP_COLUMNS, MetricInputs, MetricTable
from metrics.tables import REGISTRY, by_name, checked, names, report_tables


def rows(inputs, p):
    return pd.DataFrame(columns=list(GROUP_COLUMNS))


def test_registry_names_are_unique_and_every_table_is_typed():
    assert len(set(names())) == len(REGISTRY)
    for table in REGISTRY:
        assert table.columns and set(table.columns.values()) <= {"VARCHAR", "BIGINT", "DOUBLE", "BOOLEAN"}
        assert table.empty().columns.tolist() == table.column_names


def test_group_columns_follow_the_one_group_key():
    assert by_name("gait").group == tuple(GROUP)
    assert list(by_name("gait").columns)[:4] == list(GROUP)
    assert by_name("spm_tests").group == ("subject", "source_b", "human_mode_b", "condition_b")
    assert by_name("spm_clusters").linked == ("spm_tests", "test_id")


def test_report_tables_have_titles_in_report_order():
    tables = report_tables()
    assert [t.name for t in tables] == ["compliance", "gait", "stability", "phases"]
    assert tables[0].title.startswith("Table I:") and all(t.title for t in tables)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"name": "Bad-Name"}, r"^Bad-Name: a metric table's name must be a lower-case identifier$"),
    ({"columns": {**GROUP_COLUMNS, "n": "INTEGER"}},
     r"^tiny: column types must be one of \['VARCHAR', 'BIGINT', 'DOUBLE', 'BOOLEAN'\]; "
     r"got \{'n': 'INTEGER'\}$"),
    ({"columns": {"subject": "VARCHAR", "n": "BIGINT"}},
     r"^tiny: its group columns \['source', 'human_mode', 'condition'\] are not among its columns "
     r"\['subject', 'n'\]$"),
    ({"group": ("subject",)}, r"^tiny: group must name 4 columns"),
    ({"linked": ("gait", "test_id")}, r"^tiny: its group columns \['test_id'\] are not among its columns"),
])
def test_a_bad_declaration_is_named(kwargs, message):
    spec = {"name": "tiny", "columns": {**GROUP_COLUMNS, "n": "BIGINT"}, "compute": rows, **kwargs}
    with pytest.raises(MetricsError, match=message):
        MetricTable(**spec)


def test_checked_registry_refuses_twins_and_links_to_later_tables():
    tiny = MetricTable("tiny", {**GROUP_COLUMNS, "n": "BIGINT"}, rows)
    child = MetricTable("child", {"test_id": "VARCHAR"}, rows, linked=("spm_tests", "test_id"))
    with pytest.raises(MetricsError, match=r"^tiny: registered twice$"):
        checked([tiny, tiny])
    with pytest.raises(MetricsError, match=r"^child: linked to 'spm_tests', which is not registered before"):
        checked([child, *REGISTRY])
    with pytest.raises(MetricsError, match=r"^child: linked by 'test_id', which 'gait' lacks$"):
        checked([*REGISTRY, MetricTable("child", {"test_id": "VARCHAR"}, rows, linked=("gait", "test_id"))])
    assert checked([*REGISTRY, tiny, child])[-2:] == (tiny, child)


def test_shared_work_runs_once_per_inputs():
    calls = []
    inputs = MetricInputs(pd.DataFrame(), pd.DataFrame())
    for _ in range(3):
        assert inputs.shared("x", lambda: calls.append(1) or 42) == 42
    assert calls == [1] and not inputs.has_robot
