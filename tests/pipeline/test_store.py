"""The versioned DuckDB store: idempotence, new versions, busy writer, crash midway, views, CLI."""

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import duckdb
import pandas as pd
import pytest
import yaml

import pipeline.store.write
from pipeline.cli import main
from pipeline.params import load_params, parse_params
from pipeline.stages.ingest import run_ingest
from pipeline.stages.metrics import run_metrics
from pipeline.stages.store import load_results
from pipeline.store.connection import StoreError, StoreParams, open_store
from pipeline.store.read import query
from pipeline.store.write import store_results

ROOT = Path(__file__).resolve().parents[2]
SUBJECTS = ("camargo", "opencap4")
FAST = StoreParams(busy_timeout_s=1.0, retry_interval_s=0.05)


@pytest.fixture(scope="module")
def processed(tmp_path_factory) -> Path:
    """Real example subjects ingested (<tmp>/processed) and their metrics (<tmp>/metrics, returned)."""
    root = tmp_path_factory.mktemp("results")
    params = load_params()
    for sid in SUBJECTS:
        run_ingest(sid, params, root / "processed", progress=False)
        run_metrics(sid, params, root / "processed", root / "metrics")
    return root / "metrics"


def results(root: Path):
    return [load_results(sid, root) for sid in SUBJECTS]


def count(db: Path, sql: str) -> int:
    return int(query(db, sql).iloc[0, 0])


def test_rerun_unchanged_adds_no_version_and_param_change_adds_one(processed, tmp_path):
    db = tmp_path / "results.duckdb"
    first = store_results(db, results(processed), FAST, rev="rev1")
    n = count(db, "select count(*) from versions")
    assert n == len(first.new_versions) == first.n_groups == 5  # camargo free + 4 opencap4 conditions
    rows = count(db, "select count(*) from result_kinematics")
    again = store_results(db, results(processed), FAST, rev="rev2")
    assert again.new_versions == () and count(db, "select count(*) from versions") == n
    assert count(db, "select count(*) from result_kinematics") == rows
    assert count(db, "select count(*) from store_runs") == 2

    # a param that changes results: per-side instead of pooled cycles -> new versions, old kept
    changed_root = tmp_path / "changed"
    doc = load_params().document()
    doc["metrics"]["pool_sides"] = False
    params = parse_params(doc)
    for sid in SUBJECTS:
        run_metrics(sid, params, processed.parent / "processed", changed_root)
    new = store_results(db, results(changed_root), FAST, rev="rev3")
    assert len(new.new_versions) == 5 and count(db, "select count(*) from versions") == 10
    latest = query(db, "select * from latest_stability")
    assert set(latest["side"]) <= {"left", "right"} and set(latest["version_id"]) == set(new.new_versions)
    old = query(db, f"select * from result_stability where version_id in {tuple(first.new_versions)}")
    assert set(old["side"]) == {"both"}  # the old version is still queryable
    assert query(db, "select distinct params_hash from versions").shape[0] == 2

    # back to the original content: a new version again, so that latest is what was computed last
    back = store_results(db, results(processed), FAST, rev="rev4")
    assert len(back.new_versions) == 5
    assert set(query(db, "select side from latest_stability")["side"]) == {"both"}


def test_views_are_shaped_like_the_paper_tables(processed, tmp_path):
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed), FAST)
    t2 = query(db, "select * from paper_table2")
    assert {"real_stride_length_m_mean", "real_gait_speed_mps_sd", "sim_gait_speed_mps_mean"} <= set(
        t2.columns
    )
    assert set(zip(t2["subject"], t2["condition"], strict=True)) >= {
        ("camargo", "free"),
        ("opencap4", "toe_out"),
    }
    gait = load_results("camargo", processed).tables["gait"].iloc[0]
    row = t2[t2["subject"] == "camargo"].iloc[0]
    assert row["real_gait_speed_mps_mean"] == pytest.approx(gait["gait_speed_mps_mean"])
    t3 = query(db, "select * from paper_table3")
    assert set(t3["joint"]) == {"hip_flexion", "knee_flexion", "ankle_dorsiflexion"}
    assert {"real_intercycle_sd_deg", "sim_intercycle_sd_deg"} <= set(t3.columns)
    assert {"real_mean_abs_ex_cm", "sim_mean_abs_ey_cm"} <= set(
        query(db, "select * from paper_table1").columns
    )
    summary = query(db, "select * from subject_summary").set_index("subject")
    assert summary.loc["opencap4", "conditions"] == "free,toe_in,toe_out,trunk_sway"
    clusters = query(db, "select * from spm_clusters")
    assert (clusters["p"] < 0.05).all()


def test_query_is_read_only(processed, tmp_path):
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed), FAST)
    with pytest.raises(StoreError, match="query failed"):
        query(db, "delete from versions")
    with pytest.raises(StoreError, match="no results store here yet"):
        query(tmp_path / "none.duckdb", "select 1")


HOLD = """
import sys, time
import duckdb
con = duckdb.connect(sys.argv[1])  # any other DuckDB client writing the file
print("holding", flush=True)
time.sleep(float(sys.argv[2]))
"""


def test_second_writer_gets_store_is_busy(processed, tmp_path):
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed), FAST)
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(db), "20"], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "holding"
        start = time.monotonic()
        with pytest.raises(StoreError, match="store is busy: another process holds its lock; waited 1 s"):
            store_results(db, results(processed), FAST)
        assert 0.9 < time.monotonic() - start < 10
    finally:
        holder.kill()
        holder.wait()
    assert store_results(db, results(processed), FAST).new_versions == ()  # free again


READ = """
import sys
import duckdb
con = duckdb.connect(sys.argv[1], read_only=True)  # a notebook keeping the store open
count = "select count(*) from versions"
print(con.execute(count).fetchone()[0], flush=True)
sys.stdin.readline()  # until the test has stored again
print(con.execute(count).fetchone()[0], flush=True)
"""


def test_readers_holding_the_store_open_never_block_the_writer(processed, tmp_path):
    """Issue 34 case 16: a reader in this process and one in another hold the store open read-only;
    a store run that adds versions succeeds at once, both readers keep reading their snapshot, and
    a connection opened afterwards sees every version, old and new."""
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed)[:1], FAST, rev="before")  # camargo: 1 version
    here = duckdb.connect(str(db), read_only=True)
    there = subprocess.Popen([sys.executable, "-c", READ, str(db)], cwd=ROOT, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert there.stdout.readline().strip() == "1"
        report = store_results(db, results(processed), FAST, rev="after")  # + opencap4's 4 (no busy)
        assert len(report.new_versions) == 4
        assert here.execute("select count(*) from versions").fetchone()[0] == 1
        there.stdin.write("\n")
        there.stdin.flush()
        assert there.stdout.readline().strip() == "1"
    finally:
        here.close()
        there.kill()
        there.wait()
    revs = query(db, "select code_rev, count(*) as n from versions group by 1 order by 1")
    assert revs.to_dict("list") == {"code_rev": ["after", "before"], "n": [4, 1]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.duckdb", "results.duckdb.lock"]


class FullDiskAtCommit:
    """A store connection whose COMMIT fails as DuckDB's does when the disk is full: the transaction
    has ended when the error comes."""

    def __init__(self, con):
        self.con = con

    def __getattr__(self, name):
        return getattr(self.con, name)

    def execute(self, sql, *args):
        if sql == "COMMIT":
            self.con.execute("ROLLBACK")
            raise duckdb.IOException('IO Error: Could not write file "results.duckdb.wal": '
                                     "No space left on device")
        return self.con.execute(sql, *args)


def test_a_full_disk_is_named_and_the_store_keeps_its_state(processed, tmp_path, monkeypatch, capsys):
    """Issue 34 case 15: the disk filling up during the commit ended in DuckDB's `cannot rollback - no
    transaction is active`, which hid the cause, and a full disk while copying the store in a
    traceback; both now end in one line naming the cause and the file, the store as it was."""
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed)[:1], FAST, rev="before")
    real_open = pipeline.store.write.open_store

    @contextmanager
    def full_at_commit(path, read_only=False, *args):
        with real_open(path, read_only, *args) as con:
            yield con if read_only else FullDiskAtCommit(con)

    monkeypatch.setattr(pipeline.store.write, "open_store", full_at_commit)
    with pytest.raises(StoreError, match=rf"^{re.escape(str(db))}: cannot write the store \(IO Error: "
                       r"Could not write file .*No space left on device\)$"):
        store_results(db, results(processed), FAST, rev="full")
    monkeypatch.undo()

    def full_while_copying(src, dst):
        Path(dst).write_bytes(Path(src).read_bytes()[:4096])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))

    monkeypatch.setattr(shutil, "copyfile", full_while_copying)
    doc = load_params().document()
    doc["subjects"] = list(SUBJECTS)
    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump(doc))
    assert main(["--params", str(params), "store", "--root", str(processed), "--db", str(db)]) == 2
    err = capsys.readouterr().err.replace("\r", "\n").strip().splitlines()[-1]
    assert err == f"error: No space left on device ({db}.{os.getpid()}.tmp)"
    monkeypatch.undo()
    assert query(db, "select code_rev from versions")["code_rev"].tolist() == ["before"]
    assert not list(tmp_path.glob("*.tmp*"))


CRASH = """
import sys, time
from pathlib import Path
from pipeline.store.connection import StoreParams
from pipeline.store.write import store_results
from pipeline.stages.store import load_results
root = Path(sys.argv[2])
res = [load_results(s, root) for s in ("camargo", "opencap4")]
def midway(step):
    print("midway", step, flush=True)
    time.sleep(60)
store_results(Path(sys.argv[1]), res, StoreParams(), rev="crash", progress=midway)
"""


def test_killed_store_run_leaves_previous_state(processed, tmp_path):
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed)[:1], FAST, rev="before")  # camargo only
    before = query(db, "select * from versions")
    rows = count(db, "select count(*) from result_gait")
    crash = subprocess.Popen(
        [sys.executable, "-c", CRASH, str(db), str(processed)], cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    try:
        line = crash.stdout.readline()
        assert line.startswith("midway"), line
    finally:
        crash.send_signal(signal.SIGKILL)
        crash.wait()
    after = query(db, "select * from versions")
    assert after.equals(before) and count(db, "select count(*) from result_gait") == rows
    assert count(db, "select count(*) from store_runs") == 1
    assert [p.name for p in tmp_path.glob("*.tmp")] == [f"results.duckdb.{crash.pid}.tmp"]  # its copy
    done = store_results(db, results(processed), FAST)  # the next run completes normally
    assert len(done.new_versions) == 4 and count(db, "select count(*) from versions") == 5
    assert not list(tmp_path.glob("*.tmp*"))  # and deletes the killed run's copy


def test_store_and_query_commands(processed, tmp_path, capsys):
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed), FAST)
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "query",
            "select subject, condition, real_n_strides from paper_table2 order by subject, condition",
            "--db",
            str(db),
            "--format",
            "json",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode == 0, run.stderr
    rows = json.loads(run.stdout)
    assert [r["condition"] for r in rows] == ["free", "free", "toe_in", "toe_out", "trunk_sway"]
    assert main(["query", "select * from nope", "--db", str(db)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "query failed" in err and "nope" in err
    with open_store(db, read_only=True) as con:
        assert con.execute("select count(*) from latest_versions").fetchone()[0] == 5


def test_a_condition_a_subject_no_longer_has_leaves_the_latest_views(processed, tmp_path):
    db = tmp_path / "results.duckdb"
    store_results(db, results(processed), FAST)
    cam, oc = results(processed)
    no_toe_in = {
        name: df[~(df.filter(like="condition").eq("toe_in").any(axis=1))] for name, df in oc.tables.items()
    }
    tests = oc.tables["spm_tests"]
    dropped = set(tests.loc[tests["condition_b"] == "toe_in", "test_id"])
    no_toe_in = {
        n: (df[~df["test_id"].isin(dropped)] if "test_id" in df else df) for n, df in no_toe_in.items()
    }
    again = store_results(db, [cam, type(oc)(oc.subject, no_toe_in, oc.params_hash)], FAST)
    assert again.new_versions == () and again.n_groups == 4
    latest = query(db, "select condition from latest_versions where subject = 'opencap4'")
    assert set(latest["condition"]) == {"free", "toe_out", "trunk_sway"}
    assert count(db, "select count(*) from versions where condition = 'toe_in'") == 1  # still there
    assert count(db, "select count(*) from latest_spm_tests where condition_b = 'toe_in'") == 0
    assert count(db, "select count(*) from latest_versions where subject = 'camargo'") == 1


def test_round_trip_subject_is_labelled_in_the_store_and_report(processed, tmp_path):
    from dataclasses import replace

    from pipeline.stages.report import load_report_data, subject_report

    db = tmp_path / "results.duckdb"
    camargo = load_results("camargo", processed)
    tables = {name: df.assign(subject="camargo_rt") for name, df in camargo.tables.items()}
    round_trip = replace(camargo, subject="camargo_rt", tables=tables, round_trip_of="camargo")
    store_results(db, [camargo, round_trip], FAST, rev="rev1")
    summary = query(db, "select subject, coalesce(round_trip_of, '-') as of from subject_summary "
                        "order by subject")
    assert summary.set_index("subject")["of"].to_dict() == {"camargo": "-", "camargo_rt": "camargo"}
    data = load_report_data(db)
    head = subject_report("camargo_rt", data, tmp_path / "reports").read_text().splitlines()[:8]
    assert any("Round trip" in line and "camargo's simulated" in line for line in head)
    plain = subject_report("camargo", data, tmp_path / "reports").read_text()
    assert "Round trip" not in plain


def test_a_tuning_whose_every_search_rollout_fell_is_marked_no_signal(tmp_path):
    """A search in which every rollout fell has no signal: every trial scored the fall penalty and
    the "tuned" gains are the generic ones by a tie; the view and the report say so. The committed
    camargo results, with hemiparetic_left's made into such a search (as it was before the tuning's
    walk window: 96 of 96 search rollouts fell), stored into a store from before the search columns."""
    from pipeline.stages.store import load_tunings

    tunings = [dict(t) for t in load_tunings()]
    for t in tunings:
        if (t["subject"], t["variant"]) == ("camargo", "hemiparetic_left"):
            t.update(search_falls=t["search_rollouts"], tuned_gains=t["generic_gains"])
    db = tmp_path / "results.duckdb"
    with open_store(db, False, 1.0, 0.05) as con:  # a store from before the search columns
        con.execute("CREATE TABLE tuned_gains (version_id BIGINT NOT NULL, subject VARCHAR, "
                    "variant VARCHAR, controller VARCHAR, method VARCHAR, n_trials BIGINT, seed BIGINT, "
                    "generic_gains VARCHAR, "
                    "tuned_gains VARCHAR, search_best_objective DOUBLE, generic_mean DOUBLE, "
                    "generic_ci95 DOUBLE, generic_falls BIGINT, tuned_mean DOUBLE, tuned_ci95 DOUBLE, "
                    "tuned_falls BIGINT, n_heldout BIGINT, content_hash VARCHAR, run_id BIGINT, "
                    "created_at TIMESTAMP)")
    store_results(db, [], FAST, rev="rev1", tunings=tunings)
    view = query(db, "SELECT variant, controller, search_falls, search_rollouts, search_status, "
                     "generic_gains = tuned_gains AS same FROM tuning_comparison WHERE subject = 'camargo'")
    by = {(r.variant, r.controller): r for r in view.itertuples(index=False)}
    for c in ("pid", "adaptive"):
        hemi = by[("hemiparetic_left", c)]
        assert hemi.search_falls == hemi.search_rollouts == 96 and hemi.search_status == "no signal"
        assert hemi.same  # the first trial (the generic gains) wins the tie
        healthy = by[("healthy", c)]
        assert healthy.search_falls < healthy.search_rollouts and healthy.search_status == "ok"
        assert not healthy.same
    from pipeline.report import sections
    from pipeline.report.render import section_markdown

    view = query(db, "SELECT * FROM tuning_comparison WHERE subject = 'camargo'")
    lines = section_markdown("tuning", sections.tuning(view, False))
    rows = [ln for ln in lines.splitlines() if ln.startswith("| ")]
    assert all(("**no signal**" in ln) == ("hemiparetic_left" in ln) for ln in rows[2:]), rows
    healthy_pid = by[("healthy", "pid")]
    assert "96/96 **no signal**" in lines and f"{healthy_pid.search_falls}/96" in lines


def test_policy_checks_of_a_store_from_before_walks_gain_the_column(tmp_path):
    """A store whose `policy_checks` predates `walks` takes new rows with it (older rows: NULL)."""
    from pipeline.stages.store import evaluation_rows

    db = tmp_path / "results.duckdb"
    with open_store(db, False, 1.0, 0.05) as con:
        con.execute('CREATE TABLE policy_checks (version_id BIGINT NOT NULL, subject VARCHAR NOT NULL, '
                    'variant VARCHAR NOT NULL, "check" VARCHAR NOT NULL, passed BOOLEAN, value DOUBLE, '
                    "low DOUBLE, high DOUBLE, unit VARCHAR, content_hash VARCHAR, run_id BIGINT, "
                    "created_at TIMESTAMP)")
    gate = {"free": {"rollouts": 2}, "checks": {"scenario_steady_free_no_fall": True}}
    rows = pd.DataFrame(evaluation_rows(gate, "kgc6", "healthy"))
    store_results(db, [], FAST, rev="rev1", policy_checks=rows)
    stored = query(db, 'SELECT "check", passed, walks FROM policy_checks_latest')
    assert stored.to_dict("records") == [
        {"check": "scenario_steady_free_no_fall", "passed": True, "walks": 2}]


def test_policy_checks_come_from_each_policy_folders_evaluation(tmp_path):
    """The committed camargo evaluation.json (from before `check_rows`) gives one row per check with
    its pass flag and NULL value and bound; a cohort variant's evaluation with `check_rows` gives
    their values and bounds. Unchanged evaluations add no version; a changed one adds one, and
    `policy_checks_latest` holds the newest."""
    from pipeline.paths import POLICIES_ROOT
    from pipeline.stages.store import load_policy_checks

    committed = json.loads((POLICIES_ROOT / "camargo" / "evaluation.json").read_text())
    root = tmp_path / "policies"
    (root / "camargo" / "cohort" / "slow").mkdir(parents=True)
    (root / "camargo" / "cohort" / "weak").mkdir()  # a variant not evaluated: no rows
    shutil.copy(POLICIES_ROOT / "camargo" / "evaluation.json", root / "camargo" / "evaluation.json")
    rows = [{"check": c, "passed": p, "value": 0.5 if p else 2.0, "bound": [None, 1.0], "unit": "s"}
            for c, p in committed["checks"].items()]
    slow = {**committed, "variant": "slow", "check_rows": rows}
    (root / "camargo" / "cohort" / "slow" / "evaluation.json").write_text(json.dumps(slow))
    checks = load_policy_checks(["camargo", "opencap4"], root)  # opencap4: no policy folder here
    db = tmp_path / "results.duckdb"
    store_results(db, [], FAST, rev="rev1", policy_checks=checks)
    stored = query(db, 'SELECT * FROM policy_checks_latest ORDER BY variant, "check"')
    healthy, cohort = stored[stored["variant"] == "healthy"], stored[stored["variant"] == "slow"]
    assert len(healthy) == len(cohort) == len(committed["checks"]) == 29
    assert dict(zip(healthy["check"], healthy["passed"], strict=True)) == committed["checks"]
    assert healthy[["value", "low", "high", "unit"]].isna().all().all()
    assert set(stored["walks"]) == {committed["free"]["rollouts"]} == {10}  # the sample each pass rests on
    assert dict(zip(cohort["check"], cohort["passed"], strict=True)) == committed["checks"]
    assert (cohort["passed"] == (cohort["value"] <= cohort["high"])).all() and cohort["low"].isna().all()
    assert set(stored["unit"].dropna()) == {"s"}
    failing = query(db, 'SELECT "check" FROM policy_checks_latest WHERE subject = \'camargo\' '
                        "AND variant = 'healthy' AND NOT passed")
    assert set(failing["check"]) == {c for c, p in committed["checks"].items() if p is False}
    store_results(db, [], FAST, rev="rev2", policy_checks=load_policy_checks(["camargo"], root))
    assert count(db, "SELECT count(DISTINCT version_id) FROM policy_checks") == 2
    slow["check_rows"][0] = {**rows[0], "value": 0.25}
    (root / "camargo" / "cohort" / "slow" / "evaluation.json").write_text(json.dumps(slow))
    store_results(db, [], FAST, rev="rev3", policy_checks=load_policy_checks(["camargo"], root))
    assert count(db, "SELECT count(DISTINCT version_id) FROM policy_checks") == 3
    assert count(db, "SELECT count(*) FROM policy_checks") == 3 * 29
    newest = query(db, "SELECT value FROM policy_checks_latest WHERE variant = 'slow' AND \"check\" = "
                       f"'{rows[0]['check']}'")
    assert newest["value"].tolist() == [0.25]
    (root / "camargo" / "evaluation.json").write_text("{}")
    with pytest.raises(StoreError, match=r"camargo/evaluation.json: not an evaluate-policy result"):
        load_policy_checks(["camargo"], root)
