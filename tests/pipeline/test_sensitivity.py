"""The responsiveness study (issue 34): its one-factor-at-a-time design, a tiny grid run through the sweep
engine (resumable), the store's `sensitivity` view with 95 % CIs, the figure and the report's region column.
On the tiny grid a slower base and a longer latency raise pid's mean |e_x| above the twin's."""

from __future__ import annotations

import pandas as pd
import pytest

from metrics.findings import region_text, responsiveness_comparisons
from metrics.plots import sensitivity_figure
from pipeline.params import ParamsError, check_params, load_params, parse_params
from pipeline.paths import POLICIES_ROOT
from pipeline.report import sections
from pipeline.report.published import PAPER_PAIR, load_paper, paper_compliance
from pipeline.report.render import section_markdown
from pipeline.stages.sweep import run_sweep, sensitivity_jobs, sweep_jobs
from pipeline.store.read import query
from pipeline.store.write import store_results

pytestmark = pytest.mark.skipif(not (POLICIES_ROOT / "camargo" / "policy.zip").is_file(),
                                reason="camargo's committed policy is missing")


def tiny(seeds: int = 2):
    """params.yaml with a tiny study: camargo, walk_10m, the twin and one slow level of tau and latency."""
    doc = load_params().document()
    doc["sensitivity"].update(study="tiny_responsiveness", subjects=["camargo"], seeds=seeds,
                              pid_gain_scale=[1.0], drive_tau_s=[0.4], latency_s=[0.3])
    return parse_params(doc)


def test_design_one_factor_at_a_time():
    params = check_params()
    jobs, design, notes = sensitivity_jobs(params)
    sw = params.sensitivity
    assert notes == []
    # per subject and seed: the twin (2 controllers), pid at 3 other gain scales, both at 4 taus, 3 latencies
    assert len(jobs) == len(sw.subjects) * sw.seeds * (2 + 3 + 2 * 4 + 2 * 3)
    assert len({j.key for j in jobs}) == len(jobs)
    assert set(design["job_key"]) == {j.key for j in jobs}
    # every controller has every level of every factor, the twin's level included
    cells = design.merge(pd.DataFrame([{"job_key": j.key, "condition": j.condition} for j in jobs]))
    assert (cells.groupby(["factor", "level", "condition"]).size() == len(sw.subjects) * sw.seeds).all()
    # adaptive does not read PID gains: at each gain scale its jobs are the twin's
    adaptive = cells[(cells["factor"] == "pid_gain_scale") & (cells["condition"] == "adaptive")]
    assert adaptive["twin"].all() and adaptive["job_key"].nunique() == len(sw.subjects) * sw.seeds
    # the twin's jobs keep the key of a plain job (no responsiveness in it)
    twin = [j for j in jobs if j.responsiveness is None]
    assert len(twin) == 2 * len(sw.subjects) * sw.seeds
    assert sweep_jobs(params, sw=sw)[0] == jobs


def test_params_refuse_free_and_a_shared_study_name():
    doc = load_params().document()
    doc["sensitivity"]["conditions"] = ["free", "pid"]
    with pytest.raises(ParamsError, match="sensitivity.conditions: 'free' has no robot"):
        parse_params(doc)
    doc = load_params().document()
    doc["sensitivity"]["study"] = doc["sweep"]["study"]
    with pytest.raises(ParamsError, match="sensitivity.study must differ"):
        parse_params(doc)


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """The tiny study run on Ray (then rerun: it resumes), stored; the `sensitivity` view's rows."""
    root = tmp_path_factory.mktemp("sweeps")
    params = tiny()
    summary = run_sweep(params, root, progress=False, study="tiny_responsiveness")
    again = run_sweep(params, root, progress=False, study="tiny_responsiveness")
    results = pd.read_parquet(root / "tiny_responsiveness" / "results.parquet")
    db = tmp_path_factory.mktemp("store") / "results.duckdb"
    store_results(db, [], sweeps=[results], rev="test")
    return summary, again, results, db


def test_runs_and_resumes(stored):
    summary, again, results, _ = stored
    # twin 2 + tau 0.4 x 2 + latency 0.3 x 2 controllers, 2 seeds
    assert (summary["jobs"], summary["ran"], summary["failed"]) == (12, 12, [])
    assert (again["ran"], again["resumed"]) == (0, 12)
    # the twin's 4 jobs stand in each of the 3 factors' twin level: 12 jobs, 12 + 4 + 4 design rows
    assert len(results) == 20 and results["job_key"].nunique() == 12


def test_view_has_cis_and_pid_e_x_rises(stored):
    *_, db = stored
    v = query(db, "SELECT * FROM sensitivity")
    assert set(v["factor"]) == {"pid_gain_scale", "drive_tau_s", "latency_s"}
    assert (v["n"] == 2).all()
    for col in ("mean_abs_ex_cm_ci95", "mean_abs_ey_cm_ci95", "force_rms_n_ci95"):
        assert v[col].notna().all() and (v[col] >= 0).all()
    # 95 % CI over 2 walks: t(1) = 12.706 x SD / sqrt(2)
    sd = query(db, "SELECT stddev_samp(mean_abs_ex_cm) AS sd FROM sweep_results JOIN sensitivity_design "
                   "USING (study, job_key) WHERE factor = 'drive_tau_s' AND level = 0.4 "
                   "AND condition = 'pid'")
    row = v[(v["factor"] == "drive_tau_s") & (v["level"] == 0.4) & (v["condition"] == "pid")].iloc[0]
    assert row["mean_abs_ex_cm_ci95"] == pytest.approx(12.7062047 * sd["sd"].iloc[0] / 2 ** 0.5, rel=1e-6)
    pid = v[v["condition"] == "pid"].set_index(["factor", "level"])["mean_abs_ex_cm"]
    twin = pid[("drive_tau_s", 0.025)]
    assert pid[("drive_tau_s", 0.4)] > twin
    assert pid[("latency_s", 0.3)] > twin
    # the moved robots are not the twin: left out of the views over every study's rollouts
    assert query(db, "SELECT count(*) AS n FROM sweep_rollouts")["n"].iloc[0] == 4


def test_figure_and_report_region(stored, tmp_path):
    *_, db = stored
    v = query(db, "SELECT * FROM sensitivity")
    paper = load_paper()
    fig = sensitivity_figure(v, paper_compliance(paper), "camargo: responsiveness")
    path = tmp_path / "sensitivity.png"
    fig.savefig(path)
    assert path.stat().st_size > 10_000
    assert len(fig.axes) == 6
    text = region_text(responsiveness_comparisons(v, "mean_abs_ex_cm", PAPER_PAIR), PAPER_PAIR)
    assert text.startswith("twin (drive tau 25 ms, latency 30 ms, PID gains 1x): ")
    empty = pd.DataFrame(columns=["subject", "human_mode", "condition", "scenario", "phase"])
    t2 = pd.DataFrame(columns=["sim_human_mode", "condition", "sim_gait_speed_mps_mean",
                               "sim_gait_speed_mps_sd", "sim_n_strides"])
    t3 = pd.DataFrame(columns=["sim_human_mode", "joint", "condition", "sim_intercycle_sd_deg"])
    found = sections.findings(empty, t2, t3, paper, "walk_10m", v)
    assert found["table"].header[-1] == "Responsiveness region"
    assert f"| {text} |" in section_markdown("findings", found)
    section = section_markdown("sensitivity", sections.sensitivity(v, paper, "walk_10m", True))
    assert "## Follow-me responsiveness" in section and "figures/sensitivity.png" in section
