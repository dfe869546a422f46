"""Quality gates end to end: a subject whose retarget marker RMS (5 cm) and policy free-walking speed
(30 % slow) must fail -> the metrics stage's quality table, the store's paper tables and the report."""

import json

import pandas as pd

from ingest.robot import ROBOT_COLUMNS, ROBOT_SIGNAL_COLUMNS
from pipeline.params import check_params
from pipeline.stages.ingest import run_ingest
from pipeline.stages.metrics import quality_checks, run_metrics
from pipeline.stages.report import run_report
from pipeline.stages.store import load_results
from pipeline.store.connection import StoreParams
from pipeline.store.read import query
from pipeline.store.write import store_results


def test_a_failing_subject_fails_its_gates_everywhere(tmp_path):
    params = check_params()
    processed, metrics = tmp_path / "processed", tmp_path / "metrics"
    real = run_ingest("camargo", params, processed, progress=False)
    model = processed / "camargo" / "model"
    model.mkdir(parents=True)
    lengths = {"thigh_l": 0.45, "thigh_r": 0.45, "shank_l": 0.42, "shank_r": 0.43}
    (model / "model.json").write_text(json.dumps({"segment_lengths_m": lengths}))
    (model / "reference.json").write_text(json.dumps({"marker_rms_m": 0.05, "angles": {}}))
    policy = processed / "camargo" / "sim_policy"
    policy.mkdir()
    paper = params.scenarios.paper
    extra = {"human_mode": "policy", "seed": 0, "scenario": paper.scenario, "phase": "steady"}
    strides = pd.read_parquet(real / "strides.parquet")
    slow = strides.assign(gait_speed_mps=strides["gait_speed_mps"] * 0.7, **extra)
    slow.to_parquet(policy / "strides.parquet")
    pd.read_parquet(real / "cycles.parquet").assign(**extra).to_parquet(policy / "cycles.parquet")
    # a few following samples per condition, so that paper_table1 (compliance) has rows too
    robot = pd.DataFrame([{"subject": "camargo", "source": "sim", "condition": c, "trial": "t1", "time_s": t,
                           **dict.fromkeys(ROBOT_SIGNAL_COLUMNS, 0.01), "fall": False, "locked": False}
                          for c in sorted(set(strides["condition"])) for t in (0.0, 0.01)])
    robot.assign(**extra)[[*ROBOT_COLUMNS, "scenario", "phase"]].to_parquet(policy / "robot.parquet")

    folder = run_metrics("camargo", params, processed, metrics)
    q = pd.read_parquet(folder / "quality.parquet").set_index("check")
    assert q.loc["retarget_marker_rms_m", "status"] == "fail"
    assert q.loc["speed_gap_pct:policy", "status"] == "fail"
    assert abs(q.loc["speed_gap_pct:policy", "value"] - 30.0) < 1e-6
    assert q.loc["segment_asymmetry_pct", "status"] == "ok"

    db = tmp_path / "results.duckdb"
    store_results(db, [load_results("camargo", metrics)], StoreParams())
    for view in ("paper_table1", "paper_table2", "paper_table3"):  # each row carries the worst status
        rows = query(db, f"SELECT * FROM {view} WHERE subject = 'camargo'")
        assert not rows.empty and set(rows["quality"]) == {"fail"}, view
    latest = query(db, "SELECT * FROM quality_latest")
    assert len(latest) == len(q) and "fail" in set(latest["status"])
    assert latest.set_index("check").loc["retarget_marker_rms_m", "cause"] == "0.05 above the fail limit 0.04"

    reports = tmp_path / "reports"
    run_report(["camargo"], ["camargo"], db, reports, p=params.report)
    head = (reports / "camargo" / "report.md").read_text().splitlines()[:8]
    assert head[0].startswith("# camargo") and head[2] == "## Quality gates"
    first = next(line for line in head if line.startswith("| reference/") or line.startswith("| simulate/"))
    assert "fail" in first  # failed gates come first
    summary = (reports / "summary.md").read_text()
    assert "| camargo | fail | reference/retarget_marker_rms_m: 0.05 above the fail limit 0.04 |" in summary
    assert 'class="q-fail"' in (reports / "index.html").read_text()


def test_bundled_subjects_gates_name_their_cause_and_too_few_cycles_is_not_a_failure(tmp_path):
    """opencap4's 1.3-1.45 s walks hold no complete left cycle and lenhart2015's one walk one: too few
    cycles for SPM, which used to `fail` like a 12 cm marker error. In the store's quality table every
    row with a status has a cause, those rows are `n/a` saying so, and neither subject's worst status
    is `fail` (here without model and simulation, whose checks are `n/a`: cannot be computed)."""
    params = check_params()
    processed, metrics = tmp_path / "processed", tmp_path / "metrics"
    subjects = ("opencap4", "lenhart2015")
    for s in subjects:
        run_ingest(s, params, processed, progress=False)
        run_metrics(s, params, processed, metrics)
    db = tmp_path / "results.duckdb"
    store_results(db, [load_results(s, metrics) for s in subjects], StoreParams())
    q = query(db, "SELECT * FROM quality_latest")
    assert set(q["subject"]) == set(subjects) and q["status"].notna().all()
    assert q["cause"].fillna("").str.len().gt(0).all()
    few = q[q["check"].str.startswith("spm_cycles:") & (q["value"] < params.metrics.spm.min_cycles)]
    assert set(few["subject"]) == set(subjects) and set(few["status"]) == {"n/a"}
    assert few["cause"].str.startswith("too few cycles for SPM").all()
    assert "cannot be computed: no reference.json" in set(q["cause"])
    assert "fail" not in set(query(db, "SELECT quality FROM quality_worst")["quality"])


def test_span_gates_read_the_processed_trials(tmp_path):
    """The recording-edge and file-span gates take the trial files' time columns from the ingest stage's
    processed trials (real/trials.npz), not from the raw recordings: without that file they cannot be
    computed, and say why."""
    params = check_params()
    real = run_ingest("lenhart2015", params, tmp_path, progress=False)
    graded = quality_checks("lenhart2015", params, tmp_path).set_index("check")
    assert graded.loc["edge_heel_strike_share", "status"] != "n/a"
    assert graded.index.str.startswith("grf_span_samples:").any()
    (real / "trials.npz").unlink()
    bare = quality_checks("lenhart2015", params, tmp_path).set_index("check")
    assert bare.loc["edge_heel_strike_share", "status"] == "n/a"
    assert bare.loc["edge_heel_strike_share", "cause"] == (
        "cannot be computed: no processed trials: the ingest stage's real/trials.npz is missing")
    assert not bare.index.str.startswith("grf_span_samples:").any()
