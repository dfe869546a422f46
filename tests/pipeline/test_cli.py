"""`python -m pipeline` on the real example data: events quick look, errors, ingest, bench, dvc.yaml."""

import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from ingest.robot import ROBOT_COLUMNS
from pipeline.cli import main

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("GAITLOOP_MIRROR", ROOT.parent / "shared" / "data"))
CAMARGO_TRC = DATA / "camargo2021_levelground" / "MarkerData" / "levelground_ccw_fast_01_01.trc"
ID_COLUMNS = ["subject", "source", "condition", "trial"]
COLUMNS = {
    "events": [*ID_COLUMNS, "side", "event", "time_s", "method"],
    "strides": [*ID_COLUMNS, "side", "stride", "t_start_s", "t_end_s", "kept", "reason",
                "stride_length_m", "stride_time_s", "cadence_spm", "gait_speed_mps", "step_width_m"],
    "cycles": [*ID_COLUMNS, "side", "stride", "pct", "joint", "angle_deg"],
}


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)


def test_events_quick_look_prints_csv():
    run = _cli("events", str(CAMARGO_TRC), "--method", "kinematic", "--up-axis", "y", "--format", "csv")
    assert run.returncode == 0, run.stderr
    lines = run.stdout.strip().splitlines()
    assert lines[0] == "side,event,time_s"
    rows = [line.split(",") for line in lines[1:]]
    assert all(len(r) == 3 and r[0] in ("left", "right") for r in rows)
    assert sum(r[1] == "heel_strike" for r in rows) >= 10


def test_unknown_subject_is_one_line_error():
    run = _cli("ingest", "nosuchsubject")
    assert run.returncode == 2
    assert "Traceback" not in run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: ") and "nosuchsubject" in lines[0]


def test_events_wrong_up_axis_names_the_file(capsys):
    assert main(["events", str(CAMARGO_TRC), "--markerset", "camargo", "--up-axis", "z"]) == 2  # Y-up as Z-up
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {CAMARGO_TRC.resolve()}") and "up_axis" in err and "\n" not in err


def test_events_detects_the_up_axis_without_a_flag(capsys):
    """Issue 34 case 8: `events` rejected `--up-axis auto` and read a Y-up OpenCap file as Z-up when no
    flag was given; now no flag (or `auto`) detects Y, and the events are those of `--up-axis y`."""
    trc = DATA / "opencap_labval_subject4" / "MarkerData" / "walking1.trc"
    grf = DATA / "opencap_labval_subject4" / "ID" / "walking1_grf.mot"
    printed = {}
    for flag in ([], ["--up-axis", "auto"], ["--up-axis", "y"]):
        assert main(["events", str(trc), "--grf", str(grf), *flag]) == 0, capsys.readouterr().err
        printed[" ".join(flag)] = capsys.readouterr().out
    lines = printed["--up-axis y"].strip().splitlines()
    assert lines[0] == "side,event,time_s" and len(lines) > 2
    assert printed[""] == printed["--up-axis auto"] == printed["--up-axis y"]


def test_events_force_with_a_nan_vertical_force_is_an_error(tmp_path, capsys):
    """Issue 34 case 2: a GRF file with NaN vertical forces made `events --method force` print a bare
    header with exit 0; now exit 2 and one line naming the file and the column."""
    grf = DATA / "camargo2021_levelground" / "ID" / "levelground_ccw_fast_01_01_grf.mot"
    head, body = grf.read_text().split("endheader\n", 1)
    lines = body.splitlines()
    vy = [j for j, name in enumerate(lines[0].split("\t")) if name.endswith("_vy")]
    for k in range(1, len(lines) - 1):  # all but the last row (a NaN there read as "truncated")
        cells = lines[k].split("\t")
        for j in vy:
            cells[j] = "NaN"
        lines[k] = "\t".join(cells)
    bad = tmp_path / grf.name
    bad.write_text(head + "endheader\n" + "\n".join(lines) + "\n")
    code = main(["events", str(CAMARGO_TRC), "--grf", str(bad), "--method", "force", "--up-axis", "y"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", out
    assert err.startswith(f"error: {bad}: empty or NaN cells: ground_force_1_vy rows 1-3066 "), err
    assert "\n" not in err.strip()


def test_missing_params_file_is_one_line_error(tmp_path, capsys):
    assert main(["--params", str(tmp_path / "none.yaml"), "ingest", "camargo"]) == 2
    assert "none.yaml" in capsys.readouterr().err


def read_only_folder(tmp_path: Path) -> Path:
    """A folder this process cannot write in: a chmod 555 one, or for root, who writes in those,
    sysfs's root (read-only for everyone)."""
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o555)
    return folder if not os.access(folder, os.W_OK) else Path("/sys")


def test_a_read_only_output_folder_is_one_line_error(tmp_path, capsys):
    """Issue 34 case 15: a permission error ends in `error: <what> (<file>)`, not a traceback."""
    folder = read_only_folder(tmp_path)
    assert main(["ingest", "camargo", "--out-root", str(folder)]) == 2
    last = capsys.readouterr().err.replace("\r", "\n").strip().splitlines()[-1]  # after the progress bar
    what = "(Permission denied|Operation not permitted)"
    assert re.fullmatch(rf"error: {what} \({re.escape(str(folder))}/camargo\)", last), last


def test_ctrl_c_is_one_line_error(tmp_path):
    """Issue 34 case 15: SIGINT (Ctrl-C) during a stage ends in `error: interrupted (<command>)` and exit
    130, not a KeyboardInterrupt traceback."""
    command = ["ingest", "camargo", "--out-root", str(tmp_path)]
    run = subprocess.Popen([sys.executable, "-m", "pipeline", *command], cwd=ROOT, stderr=subprocess.PIPE,
                           text=True, start_new_session=True)  # its own process group, as a terminal's job
    try:
        seen = ""
        while "ingest camargo:" not in seen:  # its progress bar: at work in the stage
            char = run.stderr.read(1)
            assert char, seen
            seen += char
        os.killpg(run.pid, signal.SIGINT)  # at once: the trial takes longer than its progress bar's start
        err = run.communicate(timeout=60)[1]
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode == 130 and "Traceback" not in err, err
    last = err.replace("\r", "\n").strip().splitlines()[-1]
    assert last == f"error: interrupted (python -m pipeline {' '.join(command)})"
    assert not (tmp_path / "camargo" / "real").exists() or not any((tmp_path / "camargo" / "real").iterdir())


def test_ingest_writes_documented_tables_reproducibly(tmp_path):
    def ingest() -> dict[str, pd.DataFrame]:
        assert main(["ingest", "opencap4", "--out-root", str(tmp_path)]) == 0
        return {name: pd.read_parquet(folder / f"{name}.parquet") for name in COLUMNS}

    folder = tmp_path / "opencap4" / "real"
    first = ingest()
    for name, table in first.items():
        assert list(table.columns) == COLUMNS[name]
        assert len(table) > 0
    assert first["strides"]["kept"].any()
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["n_trials"] == 12
    assert summary["n_strides"] == len(first["strides"])
    assert sum(summary["n_kept"].values()) == first["strides"]["kept"].sum()
    second = ingest()
    for name in COLUMNS:
        pd.testing.assert_frame_equal(first[name], second[name])
    robot = pd.read_parquet(folder / "robot.parquet")  # no robot-assisted trial: empty, documented columns
    assert robot.empty and list(robot.columns) == ROBOT_COLUMNS
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [f"{n}.parquet" for n in (*COLUMNS, "robot")] + ["summary.json", "trials.npz"])  # no temp files left


def test_bench_writes_report(tmp_path):
    out = tmp_path / "reports" / "bench.json"
    assert main(["bench", "--out", str(out), "--repeat", "1", "--only", "ingest"]) == 0
    report = json.loads(out.read_text())
    ingest = report["ingest"]
    for key in ("camargo_trial_s", "camargo_frames_per_s", "opencap4_frames_per_s"):
        assert ingest[key] > 0
    assert ingest["targets"] == {"camargo_trial_s": 0.2, "camargo_floor_fraction": 0.5}
    assert ingest["meets_targets"] == (ingest["camargo_trial_s"] <= 0.2
                                       and ingest["camargo_floor_fraction"] >= 0.5)
    assert 0 < ingest["camargo_floor_s"] < ingest["camargo_trial_s"]
    assert ingest["camargo_frames"] == 3067
    # a partial run refreshes its section and keeps the others' last numbers
    report["rollout"] = {"ratio_to_mj_step": 0.5, "targets": {"ratio_to_mj_step": 0.8},
                         "meets_targets": False}
    out.write_text(json.dumps(report))
    assert main(["bench", "--out", str(out), "--repeat", "1", "--only", "ingest"]) == 0
    again = json.loads(out.read_text())
    assert again["rollout"]["ratio_to_mj_step"] == 0.5 and again["meets_targets"] is False


def test_bench_rejects_unknown_section(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "--out", str(tmp_path / "b.json"), "--only", "nosuch"])
    assert exit_.value.code == 2 and "nosuch" in capsys.readouterr().err
    assert not (tmp_path / "b.json").exists()


def test_dvc_expands_one_ingest_stage_per_subject():
    dvc = Path(sys.executable).with_name("dvc")
    if not dvc.exists():
        pytest.skip("dvc is not installed beside this interpreter")
    run = subprocess.run([str(dvc), "stage", "list", "--all"], cwd=ROOT, capture_output=True, text=True,
                         timeout=120, env={**os.environ, "DVC_NO_ANALYTICS": "1"})
    assert run.returncode == 0, run.stderr
    stages = {line.split()[0] for line in run.stdout.splitlines() if line.strip()}
    assert {"ingest@camargo", "ingest@opencap4", "bench"} <= stages


def test_policy_rollout_bench_replays_the_rollouts_own_steps(params):
    """The policy_rollout baseline is raw mj_step on the rollout's recorded inputs: it must retrace
    the rollout exactly, else the ratio would time other physics (pipeline/bench/policy_rollout.py)."""
    from pipeline.bench.policy_rollout import time_policy_rollout

    out = time_policy_rollout(params, repeat=1, duration_s=2.0)
    assert out["baseline_reproduces_rollout"] is True and out["baseline_max_qpos_diff"] == 0.0
    assert out["baseline_mj_step_calls"] > 0
    assert 0 < out["raw_mj_step_s"] and 0 < out["rollout_loop_s"]
