"""Reports from the store: per-subject Markdown, figures, summary and a static index whose every
image and link resolves: checked with the standard library HTML parser (every PNG decoded) and,
where Debian's `chromium` is installed, by loading the index in headless Chromium."""

import functools
import html
import http.server
import json
import re
import shutil
import subprocess
import threading
from html.parser import HTMLParser

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest

from pipeline.params import load_params
from pipeline.stages.ingest import run_ingest
from pipeline.stages.metrics import run_metrics
from pipeline.stages.report import ReportParams, run_report
from pipeline.stages.store import load_results
from pipeline.store import StoreError, StoreParams, query, store_results

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


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """camargo with real tables plus sim-like free/pid tables and robot logs; opencap4 real only."""
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
        run_metrics(sid, params, root / "processed", root / "metrics")
    db = root / "results.duckdb"
    store_results(db, [load_results(s, root / "metrics") for s in ("camargo", "opencap4")], StoreParams())
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


def test_reports_index_and_figures_resolve(reports):
    page = Links()
    page.feed((reports / "index.html").read_text())
    assert page.tables == 4  # subject summary + Tables I-III
    camargo = {f"camargo/figures/{n}.png" for n in ("kinematics", "spm", "tracking", "harness")}
    assert set(page.images) == camargo | {f"opencap4/figures/{n}.png" for n in ("kinematics", "spm")}
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


def test_table1_numbers_match_the_query(store, reports):
    _, db = store
    t1 = query(db, "select * from paper_table1 where subject = 'camargo' order by condition")
    assert list(t1["condition"]) == ["adaptive", "pid"]
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
    assert {("real_vs_sim", "free"), ("real_vs_sim", "pid"), ("within_source", "pid")} == set(
        zip(tests["comparison"], tests["condition_b"], strict=True)
    )


def test_unknown_subject_is_refused(store, tmp_path):
    _, db = store
    with pytest.raises(StoreError, match="no stored results for this subject"):
        run_report(["nobody"], ["nobody"], db, tmp_path, False)


CHECK_PAGE = """<!DOCTYPE html><html><body><iframe id="f" src="index.html" width="1200" height="800"></iframe>
<script>
const f = document.getElementById("f");
f.onload = async () => {
  const d = f.contentDocument;
  const imgs = [...d.images];
  await Promise.all(imgs.map(i => i.complete ? 0 : new Promise(r => { i.onload = i.onerror = r; })));
  const badImages = imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.getAttribute("src"));
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
    """Serve the reports on localhost and let Chromium load index.html: every image decodes
    (naturalWidth > 0), every link answers 200, every table has rows."""
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
    assert result["bad_images"] == [] and result["images"] == 6
    assert result["links"] >= 3 and result["bad_links"] == []
    assert len(result["rows"]) == 4 and all(n > 0 for n in result["rows"])
