"""Reports from the store: per-subject Markdown, figures, summary and a static index whose every
image and link resolves: checked with the standard library HTML parser (every PNG decoded) and,
where Debian's `chromium` is installed, by loading the index in headless Chromium."""

import functools
import html
import http.server
import json
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from html.parser import HTMLParser
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

from pipeline.params import load_params
from pipeline.paths import ADOPTION_FILE, UNIVERSAL_DIR
from pipeline.report.queries import load_report_data
from pipeline.runs.report_params import ReportParams
from pipeline.stages.ingest import run_ingest
from pipeline.stages.metrics import run_metrics
from pipeline.stages.report import run_report, subject_report
from pipeline.stages.store import load_results
from pipeline.store.connection import StoreError, StoreParams
from pipeline.store.read import query
from pipeline.store.records import SWEEP_COLUMNS
from pipeline.store.write import store_results

ROBOT_FORCES = [
    "harness_fx_n",
    "harness_fy_n",
    "harness_fz_n",
    "harness_tx_nm",
    "harness_ty_nm",
    "harness_tz_nm",
]


def sim_like(real: pd.DataFrame, condition: str, shift: float, rng) -> pd.DataFrame:
    """A simulated-looking copy of real tables (test input for the report, not a simulation)."""
    out = real.assign(source="sim", human_mode="replay", condition=condition, seed=0)
    if "angle_deg" in out:
        out["angle_deg"] = out["angle_deg"] + shift + rng.normal(0, 0.5, len(out))
    return out


def robot(subject: str, condition: str, amp_m: float) -> pd.DataFrame:
    t = np.arange(0, 4, 0.01)
    df = pd.DataFrame(
        {
            "subject": subject,
            "source": "sim",
            "human_mode": "replay",
            "condition": condition,
            "trial": "t1",
            "seed": 0,
            "time_s": t,
            "e_x_m": amp_m * np.sin(2 * np.pi * t),
            "e_y_m": amp_m / 2 * np.cos(2 * np.pi * t),
            "fall": False,
            "locked": False,
        }
    )
    for c in ROBOT_FORCES:
        df[c] = 100 * df["e_x_m"]
    return df


def policy_robot(subject: str, condition: str, scenario: str, seed: int, amp_m: float) -> pd.DataFrame:
    """A policy-human robot log with commanded phases: standing, start at 1 s, steady, a turn at
    3.5 s (turn_90 only), stop at 4.5 s, standing from 5.5 s."""
    t = np.arange(0, 6.5, 0.01)
    phase = np.select([t < 1.0, t < 2.5, t < 3.5, t < 4.5, t < 5.5],
                      ["standing", "start", "steady", "turn" if scenario == "turn_90" else "steady", "stop"],
                      "standing")
    df = pd.DataFrame({"subject": subject, "source": "sim", "human_mode": "policy", "condition": condition,
                       "trial": f"{scenario}_{condition}_seed{seed}", "seed": seed, "time_s": t,
                       "e_x_m": amp_m * np.sin(2 * np.pi * t) + 0.001 * seed, "e_y_m": amp_m / 2 * np.cos(t),
                       "fall": False, "locked": False, "scenario": scenario, "phase": phase})
    for c in ROBOT_FORCES:
        df[c] = 100 * df["e_x_m"]
    return df


def sweep_row(subject: str, variant: str, cond: str, event: str, seed: int) -> dict:
    """One sweep rollout (`SWEEP_COLUMNS`; test input for the report, not a simulation). Both variants
    fall free after a trip at 3 s and the robot catches it at 3.25 s; only weak falls free after a push,
    and the robot locks at 3.7 s, too late; pid's seed 1 locks once in normal walking: a false alarm."""
    robot, onset = cond != "free", (np.nan if event == "none" else 3.0)
    locks = {"none": 5.0 if (cond, seed) == ("pid", 1) else np.nan, "trip": 3.25,
             "push": 3.7 if variant == "weak" else np.nan}
    lock = locks[event] if robot else np.nan
    falls_free = event == "trip" or (event == "push" and variant == "weak")
    human_fall = 3.9 if falls_free and (not robot or event == "push") else np.nan
    drop = (0.05 if event == "trip" else 0.3) if onset > 0 and lock > 0 else np.nan  # NaN > 0 is False
    speed = (1.7 if variant == "healthy" else 1.1) - (0.02 if robot else 0.0) + 0.01 * seed
    row = dict.fromkeys(SWEEP_COLUMNS, np.nan)
    row.update(study="test", job_key=f"{subject}-{variant}-{cond}-{event}-{seed}", subject=subject,
               variant=variant, condition=cond, gains_hash="g", scenario="steady", seed=seed, params_hash="p",
               mean_abs_ex_cm=(1.0 if cond == "pid" else 0.5) if robot else np.nan,
               mean_abs_ey_cm=0.8 if robot else np.nan, force_rms_n=20.0 if robot else np.nan,
               fell=not np.isnan(human_fall), gait_speed_mps=speed, stride_length_m=0.9 * speed, n_strides=12,
               n_samples=1000, event=event, onset_s=onset, human_fall_s=human_fall, robot_fall_s=lock,
               before_onset=False, detected=bool(lock - onset <= 1.5), caught=event == "trip" and robot,
               latency_s=lock - onset, pelvis_drop_at_lock_m=drop,
               max_pelvis_drop_m=0.4, max_harness_force_n=300.0 + 100 * seed if robot else np.nan,
               false_alarm=event == "none" and not np.isnan(lock),
               walk_s=3.0 if event != "none" else (10.0 if np.isnan(lock) else lock),
               stance_l_s=0.62, stance_r_s=0.6, swing_l_s=0.4, swing_r_s=0.42, stance_ratio_lr=0.62 / 0.6,
               swing_ratio_lr=0.4 / 0.42, stride_time_cv_pct=1.5 if variant == "healthy" else 3.0, wall_s=1.0)
    return row


def sweep_rows(subject: str) -> pd.DataFrame:
    """Two cohort variants walking free and with pid / adaptive, without an event and with a trip and
    a push, two seeds each (`sweep_row`)."""
    rows = [sweep_row(subject, v, c, e, seed) for v in ("healthy", "weak")
            for c in ("free", "pid", "adaptive") for e in ("none", "trip", "push") for seed in (0, 1)]
    # healthy walking free from standing (walk_10m): both seeds the same walk, as a deterministic one is
    same = sweep_row(subject, "healthy", "free", "none", 0)
    rows += [{**same, "scenario": "walk_10m", "seed": seed, "job_key": f"{same['job_key']}-walk_10m-{seed}"}
             for seed in (0, 1)]
    # weak falling free before a stride in walk_10m: two walks, told apart by when they fell
    fell = {**sweep_row(subject, "weak", "free", "none", 0), "scenario": "walk_10m", "fell": True,
            "gait_speed_mps": np.nan, "stride_length_m": np.nan, "stride_time_cv_pct": np.nan, "n_strides": 0}
    rows += [{**fell, "seed": seed, "human_fall_s": 1.5 + seed, "job_key": f"{fell['job_key']}-w10-{seed}"}
             for seed in (0, 1)]
    return pd.DataFrame(rows, columns=SWEEP_COLUMNS)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """camargo with real tables, sim-like replay free/pid tables and robot logs, and a policy human
    (walk_10m strides and cycles in free/pid/adaptive, robot logs of walk_10m and turn_90 with their
    phases) and cohort sweep rollouts (`sweep_rows`); opencap4 real only."""
    root = tmp_path_factory.mktemp("report")
    params = load_params()
    rng = np.random.default_rng(1)
    for sid in ("camargo", "opencap4"):
        real = run_ingest(sid, params, root / "processed", progress=False)
        if sid == "camargo":
            sim = root / "processed" / sid / "sim"
            sim.mkdir()
            for name in ("strides", "cycles"):
                t = pd.read_parquet(real / f"{name}.parquet")
                pd.concat([sim_like(t, "free", 0.0, rng), sim_like(t, "pid", 3.0, rng)]).to_parquet(
                    sim / f"{name}.parquet"
                )
            pd.concat([robot(sid, "pid", 0.04), robot(sid, "adaptive", 0.02)]).to_parquet(
                sim / "robot.parquet"
            )
            policy = root / "processed" / sid / "sim_policy"
            policy.mkdir()
            for name in ("strides", "cycles"):
                t = pd.read_parquet(real / f"{name}.parquet")
                pd.concat([sim_like(t, c, k, rng).assign(human_mode="policy", seed=seed, scenario="walk_10m",
                                                        phase="steady")
                           for k, c in enumerate(("free", "pid", "adaptive")) for seed in (0, 1)]
                          ).to_parquet(policy / f"{name}.parquet")
            amplitudes = {"pid": 0.04, "adaptive": 0.02}
            logs = [policy_robot(sid, c, scenario, seed, amp) for c, amp in amplitudes.items()
                    for scenario in ("walk_10m", "turn_90") for seed in (0, 1)]
            pd.concat(logs).to_parquet(policy / "robot.parquet")
        run_metrics(sid, params, root / "processed", root / "metrics")
    db = root / "results.duckdb"
    store_results(db, [load_results(s, root / "metrics") for s in ("camargo", "opencap4")], StoreParams(),
                  sweeps=[sweep_rows("camargo")])
    return root, db


class Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.images, self.links, self.tables = [], [], 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.images.append(a["src"])
        elif tag == "a":
            self.links.append(a["href"])
        elif tag == "table":
            self.tables += 1


@pytest.fixture(scope="module")
def reports(store, tmp_path_factory):
    _, db = store
    out = tmp_path_factory.mktemp("reports")
    written = run_report(
        ["camargo", "opencap4"], ["camargo", "opencap4"], db, out, True, ReportParams(dpi=60)
    )
    assert out / "index.html" in written and out / "summary.md" in written
    return out


CAMARGO_FIGURES = ("events", "kinematics_policy", "tracking", "harness", "kinematics", "spm", "cohort",
                   "fall_intervention")


def test_reports_index_and_figures_resolve(reports):
    text = (reports / "index.html").read_text()
    page = Links()
    page.feed(text)
    assert page.tables == 5  # subject summary, Tables I-III, per-phase compliance
    assert text.index("<img") < text.index("<table")  # figures lead, tables below
    assert page.images == [f"camargo/figures/{n}.png" for n in CAMARGO_FIGURES] + [
        f"opencap4/figures/{n}.png" for n in ("kinematics", "spm")] + ["universal_progress.png"]
    assert {"summary.md", "camargo/report.md", "opencap4/report.md"} <= set(page.links)
    for target in page.images + page.links:
        assert (reports / target).is_file(), target
    for src in page.images:
        img = mpimg.imread(reports / src)  # decodes the PNG
        assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    for sid in ("camargo", "opencap4"):
        for line in (reports / sid / "report.md").read_text().splitlines():
            if line.startswith("!["):
                assert (reports / sid / line.split("(")[1].rstrip(")")).is_file()
    assert "No simulated robot runs for this subject yet." in (reports / "opencap4" / "report.md").read_text()
    md = (reports / "camargo" / "report.md").read_text()
    for name in ("events", "kinematics_policy"):
        assert f"![{name}](figures/{name}.png)" in md


def test_the_universal_policy_progress_is_plotted(reports):
    """The committed run's progress record (data/universal/progress.json): its figure and
    its last gate, subject by subject, in the summary."""
    progress = json.loads((UNIVERSAL_DIR / "progress.json").read_text())
    last = progress["checkpoints"][-1]
    md = (reports / "summary.md").read_text()
    assert "![training progress](universal_progress.png)" in md
    assert f"{last['passed']} of {last['checks']} checks" in md
    adoption = json.loads((UNIVERSAL_DIR / ADOPTION_FILE).read_text())  # checks passed at each evaluation
    for e in adoption["evaluations"]:
        passed = sum(r["checks_passed"] for r in e["subjects"].values())
        assert f"{passed} of {sum(r['checks'] for r in e['subjects'].values())} at " \
               f"{e['universal_steps'] / 1e6:.2f} M" in md
    for subject, rows in last["gate"].items():
        assert f"- {subject}: {sum(r['pass'] for r in rows.values())} of {len(rows)}" in md
    assert mpimg.imread(reports / "universal_progress.png").shape[1] > 300


def test_paper_values_are_shown_with_their_citation(reports):
    """The published values of Wang, Chan et al. (data/paper/wang2025.yaml) beside Real and Sim."""
    md, index = (reports / "camargo" / "report.md").read_text(), (reports / "index.html").read_text()
    for text in (md, index):
        assert "not retrieved" not in text and "arXiv:2503.05825" in text
        assert "shown for orientation only" in text
    assert "| 4.25 / 3.32 | 7.65 / 7.73 |" in md  # Table I, pid: paper real, paper sim
    assert "| 1.29 ± 0.04 / 1.04 ± 0.02 | 1.17 ± 0.01 / 1.12 ± 0.01 |" in md  # Table II, free
    assert "| knee_flexion | policy | – | " in md and "| 3.16 | 4.43 |" in md  # Table III, pid
    assert "<td>0.37 / 0.72</td><td>0.70 / 0.53</td>" in index  # Table I, adaptive


def test_phase_table_and_event_traces_match_the_store(store, reports):
    _, db = store
    phases = query(db, "select * from phase_compliance where subject = 'camargo' and scenario = 'walk_10m' "
                       "and phase = 'start' order by condition")
    assert list(phases["condition"]) == ["adaptive", "pid"] and (phases["n_runs"] == 2).all()
    md = (reports / "camargo" / "report.md").read_text()
    for r in phases.itertuples():
        assert (f"| walk_10m | start | {r.condition} | policy | 0/2 | {r.abs_ex_cm_mean:.2f} ± "
                f"{r.abs_ex_cm_ci95:.2f} |") in md
    events = query(db, "select event, scenario, count(*) as n, min(t_s) as t0, max(t_s) as t1 "
                       "from event_aligned where subject = 'camargo' and condition = 'pid' "
                       "group by all order by all")
    # walk_10m: start and stop; turn_90: start, turn, stop; -1 s .. 3 s at 0.05 s (params metrics.events)
    assert list(zip(events["event"], events["scenario"], strict=True)) == [
        ("start", "turn_90"), ("start", "walk_10m"), ("stop", "turn_90"), ("stop", "walk_10m"),
        ("turn", "turn_90")]
    assert (events["n"] == 81).all() and (events["t0"] == -1.0).all() and (events["t1"] == 3.0).all()


def test_table1_numbers_match_the_query(store, reports):
    _, db = store
    t1 = query(db, "select * from paper_table1 where subject = 'camargo' order by condition, sim_human_mode")
    assert list(zip(t1["condition"], t1["sim_human_mode"], strict=True)) == [
        ("adaptive", "policy"), ("adaptive", "replay"), ("pid", "policy"), ("pid", "replay")]
    t1 = t1[t1["sim_human_mode"] == "replay"]
    md = (reports / "camargo" / "report.md").read_text()
    amplitude_m = {"pid": 0.04, "adaptive": 0.02}
    for r in t1.itertuples():
        # mean |A sin| over whole periods is 2A/pi
        assert r.sim_mean_abs_ex_cm == pytest.approx(100 * amplitude_m[r.condition] * 2 / np.pi, rel=0.01)
        cell = f"{r.sim_mean_abs_ex_cm:.2f} ± {r.sim_sd_abs_ex_cm:.2f}"
        assert f"| {r.condition} | replay | – | – | {cell} |" in md
        assert f"| 0/{r.sim_n_trials} |" in md
    t2 = query(db, "select * from paper_table2 where subject = 'camargo' and condition = 'free'").iloc[0]
    assert f"{t2.real_gait_speed_mps_mean:.3f}" in md and f"{t2.sim_gait_speed_mps_mean:.3f}" in md
    tests = query(db, "select comparison, condition_b from latest_spm_tests where subject = 'camargo'")
    assert {("real_vs_sim", "free"), ("real_vs_sim", "pid"), ("real_vs_sim", "adaptive"),
            ("within_source", "pid"), ("within_source", "adaptive")} == set(
        zip(tests["comparison"], tests["condition_b"], strict=True)
    )


def test_cohort_and_fall_sections_match_the_views(store, reports):
    """The "Virtual cohort" and "Fall intervention" sections print the store's views (`sweep_rows`)."""
    _, db = store
    md = (reports / "camargo" / "report.md").read_text()
    assert md.index("## Virtual cohort") < md.index("## Fall intervention")
    assert "is missing from these tables: here hemiparetic_left, hemiparetic_right, slow, unsteady." in md
    gait = query(db, "select * from cohort_gait where subject = 'camargo' and scenario = 'steady' "
                     "order by variant")
    assert list(gait["variant"]) == ["healthy", "weak"] and list(gait["distinct_walks"]) == [2, 2]
    walk_10m = query(db, "select * from cohort_gait where scenario = 'walk_10m'").set_index("variant")
    fallen, repeated = walk_10m.loc["weak"], walk_10m.loc["healthy"]
    assert fallen["walks"] == 2 and fallen["distinct_walks"] == 2 and fallen["falls"] == 2
    assert repeated["walks"] == 2 and repeated["distinct_walks"] == 1 and pd.isna(repeated["gait_speed_sd"])
    assert (fallen["status"], repeated["status"]) == ("fell", "walked")
    # each controller row carries how the same variant walked free (cohort_gait's status)
    free = query(db, "select distinct c.free_status, g.status from cohort_controllers c "
                     "join cohort_gait g using (subject, variant, scenario)")
    assert len(free) and (free["free_status"] == free["status"]).all()
    assert f"| healthy | walk_10m | 2 (1 distinct) | 0/2 | {repeated['gait_speed_mps']:.3f} | " in md
    for r in gait.itertuples():
        assert (f"| {r.variant} | steady | 2 | 0/2 | {r.gait_speed_mps:.3f} ± {r.gait_speed_sd:.3f} | "
                f"{r.stride_length_m:.3f} | {r.stance_ratio_lr:.3f} | {r.swing_ratio_lr:.3f} | "
                f"{r.stride_time_cv_pct:.2f} | 24 |") in md
    assert "Perry J, Garrett M, Gronley JK, Mulroy SJ" in md  # the clinical ranges with their sources
    # both fall free after the trip and are caught; weak falls free after the push, locked 0.7 s late
    assert "| healthy | trip | pid | 2 | 0 | 2/2 | 0/2 | 2/2 | 0.25 | 0.050 (0.050) | 2/2 | 400 (350) |" in md
    assert "| healthy | push | adaptive | 2 | 0 | 0/2 | 0/2 | 0/2 | – | – | – | 400 (350) |" in md
    assert "| weak | push | pid | 2 | 0 | 2/2 | 2/2 | 2/2 | 0.70 | 0.300 (0.300) | 0/2 | 400 (350) |" in md
    assert "| weak | pid | 2 | 0.004 | 1 | 1 | 240.00 |" in md  # 15 s of walking, one false alarm
    assert "| healthy | adaptive | 2 | 0.006 | 0 | 0 | 0.00 |" in md
    assert "no stored results" not in md and "No fall-intervention rollouts" in (
        reports / "opencap4" / "report.md").read_text()


def test_unknown_subject_is_refused(store, tmp_path):
    _, db = store
    with pytest.raises(StoreError, match="no stored results for this subject"):
        run_report(["nobody"], ["nobody"], db, tmp_path, False)


KILLED_REPORT = """
import sys, time
from pathlib import Path
from pipeline.runs.report_params import ReportParams
from pipeline.stages import report
db, reports, marker = map(Path, sys.argv[1:])
write = report.write_figure
written = []
def write_then_stop(fig, path, dpi):  # the third figure written, then the run is killed
    write(fig, path, dpi)
    written.append(path)
    if len(written) == 3:
        marker.write_text(str(path.parent))
        time.sleep(120)
report.write_figure = write_then_stop
report.subject_report("camargo", report.load_report_data(db), reports, ReportParams(dpi=50))
"""


def report_files(folder) -> dict[str, bytes]:
    """report.md and every figure of a subject's report, by path in its folder."""
    files = [folder / "report.md", *(folder / "figures").iterdir()]
    return {str(f.relative_to(folder)): f.read_bytes() for f in files}


def test_a_report_killed_with_sigkill_keeps_the_earlier_figures_whole(store, tmp_path):
    """kill -9 midway through a subject's figures (issue 34 case 13): the earlier figures and report
    are all there with the same bytes, the new ones only in the killed run's temp folder, which the
    next successful run deletes."""
    _, db = store
    data = load_report_data(db)
    subject_report("camargo", data, tmp_path, ReportParams(dpi=60))
    folder = tmp_path / "camargo"
    before = report_files(folder)
    assert sorted(before) == sorted(["report.md", *(f"figures/{n}.png" for n in CAMARGO_FIGURES)])
    marker = tmp_path / "killed_here"
    run = subprocess.Popen([sys.executable, "-c", KILLED_REPORT, str(db), str(tmp_path), str(marker)],
                           cwd=Path(__file__).resolve().parents[2])
    deadline = time.monotonic() + 120
    while not marker.exists():
        assert run.poll() is None and time.monotonic() < deadline, "the report did not write 3 figures"
        time.sleep(0.1)
    run.send_signal(signal.SIGKILL)
    assert run.wait(timeout=10) == -signal.SIGKILL
    temp = folder / f".figures.{run.pid}.tmp"
    assert marker.read_text() == str(temp)
    assert sorted(p.name for p in temp.iterdir()) == sorted(f"{n}.png" for n in CAMARGO_FIGURES[:3])
    assert report_files(folder) == before
    subject_report("camargo", data, tmp_path, ReportParams(dpi=60))
    assert sorted(p.name for p in folder.iterdir()) == ["figures", "report.md"]
    assert sorted(report_files(folder)) == sorted(before)


def test_a_report_replaces_its_figures_as_a_set(store, tmp_path):
    """A figure the new run no longer draws (no cohort rollouts) is gone with its link."""
    _, db = store
    data = load_report_data(db)
    subject_report("camargo", data, tmp_path, ReportParams(dpi=60))
    figures = tmp_path / "camargo" / "figures"
    assert (figures / "cohort.png").is_file()
    without = {**data, "cohort_controllers": data["cohort_controllers"].iloc[0:0]}
    subject_report("camargo", without, tmp_path, ReportParams(dpi=60))
    assert sorted(p.name for p in figures.iterdir()) == sorted(
        f"{n}.png" for n in CAMARGO_FIGURES if n != "cohort")
    assert "figures/cohort.png" not in (tmp_path / "camargo" / "report.md").read_text()
    assert sorted(p.name for p in (tmp_path / "camargo").iterdir()) == ["figures", "report.md"]


CHECK_PAGE = """<!DOCTYPE html><html><body><iframe id="f" src="index.html" width="1200" height="800"></iframe>
<script>
const f = document.getElementById("f");
f.onload = async () => {
  const d = f.contentDocument;
  const imgs = [...d.images];
  await Promise.all(imgs.map(i => i.complete ? 0 : new Promise(r => { i.onload = i.onerror = r; })));
  // displayed: loaded, decoded (naturalWidth > 0) and laid out with a visible size on the page
  const shown = i => i.complete && i.naturalWidth > 0 && i.getBoundingClientRect().width > 0
    && i.getBoundingClientRect().height > 0 && getComputedStyle(i).visibility !== "hidden";
  const badImages = imgs.filter(i => !shown(i)).map(i => i.getAttribute("src"));
  const links = [...d.querySelectorAll("a")].map(a => a.href);
  const failed = await Promise.all(links.map(u => fetch(u).then(r => r.ok ? "" : u).catch(() => u)));
  const rows = [...d.querySelectorAll("table")].map(t => t.querySelectorAll("tbody tr").length);
  const badLinks = failed.filter(x => x);
  document.body.setAttribute("data-result", JSON.stringify(
    {images: imgs.length, bad_images: badImages, links: links.length, bad_links: badLinks, rows}));
};
</script></body></html>
"""


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@pytest.mark.skipif(shutil.which("chromium") is None, reason="headless Chromium is not installed")
def test_index_loads_in_headless_chromium(reports, tmp_path):
    """Serve the reports on localhost and let Chromium load index.html: every figure (each <img>
    of the page) is displayed (loaded, naturalWidth > 0, laid out with a size), every link answers
    200, every table has rows."""
    page = Links()
    page.feed((reports / "index.html").read_text())
    (reports / "_check.html").write_text(CHECK_PAGE)
    handler = functools.partial(QuietHandler, directory=str(reports))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        run = subprocess.run(
            [
                shutil.which("chromium"),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                f"--user-data-dir={tmp_path / 'profile'}",
                "--virtual-time-budget=20000",
                "--dump-dom",
                f"http://127.0.0.1:{server.server_address[1]}/_check.html",
            ],
            capture_output=True,
            text=True,
            timeout=90,
        )
    finally:
        server.shutdown()
        (reports / "_check.html").unlink()
    match = re.search(r'data-result="([^"]*)"', run.stdout)
    assert match, run.stderr[-2000:]
    result = json.loads(html.unescape(match.group(1)))
    assert result["images"] == len(page.images) == len(CAMARGO_FIGURES) + 3 and result["bad_images"] == []
    assert result["links"] >= 3 and result["bad_links"] == []
    assert len(result["rows"]) == page.tables and all(n > 0 for n in result["rows"])


def test_policy_checks_section_names_every_check():
    from pipeline.report import sections
    from pipeline.report.render import section_markdown

    doc = {"checks": {"free_no_fall": True, "scenario_walk_10m_free_no_fall": False, "spm_hip_flexion": None},
           "scenarios": {"own_start_s": 1.54, "start_window_s": [1.07, 2.0],
                         "walk_10m free": {"walks": 10, "human_falls": 3, "start_s": [1.2], "stop_s": [1.0],
                                           "steady_speed_mps": [1.8]}, "checks": {}}}
    text = section_markdown("policy_checks", sections.policy_checks(doc))
    assert "1 of 3 checks pass" in text
    assert "| scenario_walk_10m_free_no_fall | FAIL |" in text and "| spm_hip_flexion | not judged |" in text
    assert "| walk_10m free | 10 | 3 |" in text
    assert "No `evaluate-policy` result" in section_markdown("policy_checks", None).splitlines()[2]


def test_progress_curves_average_the_one_walk_checks_and_count_evaluations():
    from pipeline.report.figures import progress_curves

    gate = lambda a, b: {"camargo": {"x": {"pass": a}, "y": {"pass": b}}}  # noqa: E731
    progress = {"checkpoints": [{"steps": 0, "passed": 2, "checks": 2, "gate": gate(True, True)},
                                {"steps": 10 ** 6, "passed": 0, "checks": 2, "gate": gate(False, False)},
                                {"steps": 2 * 10 ** 6, "passed": 1, "checks": 2, "gate": gate(True, False),
                                 "training": {"episodes": {  # 10 calm episodes, 2 calm falls; none calm
                                     "camargo": {"episodes": 14, "falls": 5, "pushed": 4, "pushed_falls": 3},
                                     "drawn": {"episodes": 3, "falls": 3, "pushed": 3, "pushed_falls": 3}}}}],
                "runs": [{"steps": 10 ** 6, "cpu_count": 16, "device": "cuda"},
                         {"steps": 5 * 10 ** 5, "cpu_count": 2},
                         {"steps": 5 * 10 ** 5, "cpu_count": 2, "teachers": ["opencap4"],
                          "env": {"push_probability": 0.25}, "first_step": "left", "bound_weight": 10.0}],
                "statistics": [{"steps": 17 * 10 ** 5, "samples": 100}],
                "widened": [{"steps": 15 * 10 ** 5, "obs_size": [79, 81]},
                            {"steps": 18 * 10 ** 5, "net_arch": [[256, 256], [512, 512]]}],
                "discarded": [{"from_steps": 10 ** 6, "to_steps": 2 * 10 ** 6,
                               "checkpoints": [{"steps": 2 * 10 ** 6, "passed": 1}]}]}
    adoption = {"evaluations": [{"policy": "a start without steps"},
                                {"universal_steps": 2 * 10 ** 6,
                                 "subjects": {"camargo": {"checks_passed": 5, "checks": 29},
                                              "kgc6": {"checks_passed": 7, "checks": 29}}}]}
    c = progress_curves(progress, adoption, window=2)
    assert c["steps"] == [0.0, 1.0, 2.0] and c["passed"] == [2.0, 0.0, 1.0] and c["checks"] == 2
    assert c["passed_mean"] == [2.0, 1.0, 0.5] and c["own_mean"]["camargo"] == [2.0, 1.0, 0.5]
    assert c["segments"] == [(0.0, "16 cores, cuda"), (1.0, "2 cores")] and c["taught"] == [(1.5, 2.0)]
    assert c["evaluations"] == [(2.0, 12, 58, False)]  # 2.0 M is a checkpoint of the run itself
    gone = {**adoption, "evaluations": [{**adoption["evaluations"][1], "universal_steps": 25 * 10 ** 5}]}
    given_up = [{"steps": 25 * 10 ** 5, "passed": 1}]
    branch = {**progress, "discarded": [{**progress["discarded"][0], "checkpoints": given_up}]}
    assert progress_curves(branch, gone)["evaluations"] == [(2.5, 12, 58, True)]  # on the branch given up
    assert c["changes"] == [(1.5, "inputs 79 -> 81"), (1.8, "layers [256, 256] -> [512, 512]"),
                            (1.0, "taken back from 2.00 M"), (1.7, "statistics re-estimated"),
                            (1.5, "trained with push_probability 0.25, first_step left, bound_weight 10.0")]
    assert c["discarded"] == [([2.0], [1])]
    assert c["calm_falls"] == {"camargo": ([2.0], [0.2])}  # falls per episode without random pushes
    assert progress_curves({}, None)["steps"] == [] and progress_curves({}, None)["changes"] == []
