"""Sweeps on Ray: a two-node local cluster (`ray start --head` plus a worker node, reached through
RAY_ADDRESS) runs a small study; its worker node is killed after the first finished job, and the
study still completes, every job's row stored exactly once; a rerun resumes (runs nothing). A job
that raises (a plug-in controller that fails) is attempted twice, then reported with its error
while the rest of the study completes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest
import yaml

from pipeline.cli import EXIT_ERROR
from pipeline.params import load_params, parse_params
from pipeline.paths import POLICIES_ROOT, TUNED_GAINS
from pipeline.runs.studies import RaySection
from pipeline.runs.tuned_gains import read_tuned, write_tuned
from pipeline.stages.sweep import rollout_code_hash, rollout_params_hash, run_sweep, sweep_jobs
from pipeline.store.connection import StoreParams
from pipeline.store.read import query
from pipeline.store.write import store_results
from sim.rollout.cluster import RAY_ADDRESS, local_head
from tests.pipeline.failing_controller import ATTEMPTS_ENV, MESSAGE

REPO = Path(__file__).resolve().parents[2]
RAY = Path(sys.executable).with_name("ray")
FAILING = "tests.pipeline.failing_controller:Failing"  # a plug-in controller by import path that raises

pytestmark = pytest.mark.skipif(not (POLICIES_ROOT / "camargo" / "policy.zip").is_file(),
                                reason="camargo's committed policy is missing")


def small_study(study: str = "killed_worker", seeds: int = 3, conditions: tuple[str, ...] = ("free", "pid")):
    """params.yaml with a small study: camargo, a 3 s steady walk, `conditions` x `seeds`; a condition
    `failing` is the plug-in controller `FAILING`."""
    doc = load_params().document()
    if "failing" in conditions:
        doc["robot"]["controllers"]["failing"] = {"class": FAILING, "gains": {}}
    doc["sweep"].update(study=study, subjects=["camargo"], conditions=list(conditions), scenarios=["steady"],
                        seeds=seeds)
    doc["scenarios"]["commands"]["steady"] = [{"walk_s": 3.0, "speed": 1.0}]
    return parse_params(doc)


@pytest.fixture
def cluster(tmp_path):
    """A head node (`sim.rollout.cluster.local_head`, token-authenticated) and a worker node, 1 CPU
    each, on this machine; yields (the environment that reaches them, the worker's process)."""
    base = {k: v for k, v in os.environ.items() if k != RAY_ADDRESS} | {"OMP_NUM_THREADS": "1"}
    with local_head(1, REPO) as head:
        env = {**base, **head}
        cmd = [str(RAY), "start", f"--address={head[RAY_ADDRESS]}", "--num-cpus=1", "--block",
               "--node-ip-address=127.0.0.1"]
        worker = subprocess.Popen(cmd, env=env, cwd=REPO, start_new_session=True, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 90
            while not _cpus(head[RAY_ADDRESS], env) >= 2:
                assert time.monotonic() < deadline, "the worker node did not join"
                time.sleep(1)
            yield env, worker
        finally:
            try:
                os.killpg(worker.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            worker.wait(timeout=30)


def _cpus(address: str, env: dict) -> float:
    """The cluster's CPUs as `ray status` reports them (0 while it is not reachable)."""
    out = subprocess.run([str(RAY), "status", f"--address={address}"], env=env, capture_output=True,
                         text=True, timeout=60)
    for line in out.stdout.splitlines():  # e.g. " 0.0/2.0 CPU"
        if line.strip().endswith(" CPU") and "/" in line:
            return float(line.split("/")[1].split()[0])
    return 0.0


def test_sweep_completes_after_its_worker_node_is_killed(cluster, tmp_path):
    env, worker = cluster
    params = small_study(seeds=10)  # 20 jobs: a busy machine's test process still kills mid-sweep
    jobs, _ = sweep_jobs(params)
    params_file = tmp_path / "params.yaml"
    params_file.write_text(yaml.safe_dump(params.document(), sort_keys=False))
    sweeps = tmp_path / "sweeps"
    cmd = [sys.executable, "-m", "pipeline", "--params", str(params_file), "sweep", "--root", str(sweeps)]
    run = subprocess.Popen(cmd, env=env, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    job_dir = sweeps / "killed_worker" / "jobs"
    deadline = time.monotonic() + 300
    while not (job_dir.is_dir() and any(job_dir.glob("*.parquet"))):  # the first job has finished
        assert run.poll() is None and time.monotonic() < deadline, run.stdout.read() if run.stdout else ""
        time.sleep(0.1)
    os.killpg(worker.pid, signal.SIGKILL)
    assert len(list(job_dir.glob("*.parquet"))) < len(jobs)  # killed mid-sweep
    output, _ = run.communicate(timeout=300)
    assert run.returncode == 0, output
    summary = json.loads((sweeps / "killed_worker" / "summary.json").read_text())
    assert summary["failed"] == [] and summary["ran"] == len(jobs) == 20, output
    results = pd.read_parquet(sweeps / "killed_worker" / "results.parquet")
    assert sorted(results["job_key"]) == sorted(j.key for j in jobs)
    assert results["mean_abs_ex_cm"][results["condition"] == "pid"].notna().all()

    db = tmp_path / "results.duckdb"
    for _ in range(2):  # storing the study again adds nothing
        store_results(db, [], StoreParams(busy_timeout_s=1.0), rev="test", sweeps=[results])
    counts = query(db, "select count(*) as n, count(distinct job_key) as k from sweep_results")
    assert counts.iloc[0].tolist() == [20, 20]

    again = run_sweep(params, root=sweeps, progress=False)  # resumes: nothing left to run, no Ray needed
    assert again["ran"] == 0 and again["resumed"] == len(jobs)


def test_a_job_that_raises_is_retried_once_then_reported_while_the_rest_completes(tmp_path):
    """`python -m pipeline sweep` on a local Ray: the job whose plug-in controller raises runs twice
    (once, then `ray.max_retries` = 1 retry), is reported in summary.json and on stderr with its error,
    and the other jobs finish, each stored once; the sweep exits non-zero naming the failed job (issue 34
    case 11: it exited 0, and `dvc repro` recorded the stage as done)."""
    params = small_study("failed_job", seeds=1, conditions=("free", "failing", "pid"))
    doc = params.document()
    doc["ray"]["num_cpus"] = 1
    params = parse_params(doc)
    assert params.section("ray", RaySection).max_retries == 1
    jobs, _ = sweep_jobs(params)
    ok = sorted(j.key for j in jobs if j.condition != "failing")
    params_file = tmp_path / "params.yaml"
    params_file.write_text(yaml.safe_dump(params.document(), sort_keys=False))
    attempts = tmp_path / "attempts.txt"
    env = {k: v for k, v in os.environ.items() if k != RAY_ADDRESS} | {
        "OMP_NUM_THREADS": "1", "RAY_USAGE_STATS_ENABLED": "0", ATTEMPTS_ENV: str(attempts)}
    sweeps = tmp_path / "sweeps"
    cmd = [sys.executable, "-m", "pipeline", "--params", str(params_file), "sweep", "--root", str(sweeps)]
    run = subprocess.run(cmd, env=env, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert run.returncode == EXIT_ERROR, run.stderr
    [error] = [line for line in run.stderr.splitlines() if line.startswith("error: ")]
    assert error.startswith("error: sweep failed_job: 1 of 3 jobs failed after their retries: "
                            "camargo/healthy failing steady none seed 0 (RuntimeError: "), error

    assert len(attempts.read_text().splitlines()) == 2  # tried once, retried once
    summary = json.loads((sweeps / "failed_job" / "summary.json").read_text())
    assert (summary["jobs"], summary["ran"], summary["resumed"]) == (3, 2, 0), summary
    [failed] = summary["failed"]
    assert failed["condition"] == "failing" and failed["seed"] == 0, failed
    assert failed["error"] == f"RuntimeError: {MESSAGE}", failed
    assert f"failing steady none seed 0: RuntimeError: {MESSAGE}" in run.stderr
    results = pd.read_parquet(sweeps / "failed_job" / "results.parquet")
    assert sorted(results["job_key"]) == ok  # every other job, once
    assert sorted(p.stem for p in (sweeps / "failed_job" / "jobs").glob("*.parquet")) == ok


def test_job_keys_name_what_shapes_a_rollout(tmp_path):
    params = small_study(seeds=2)
    keys = {j.key for j in sweep_jobs(params)[0]}
    assert len(keys) == 4
    more_seeds = {j.key for j in sweep_jobs(small_study(seeds=3))[0]}
    assert keys < more_seeds  # adding seeds adds jobs and keeps the finished ones
    tuned = read_tuned(TUNED_GAINS)
    tuned["pid"]["kp_x"] *= 2
    write_tuned(tmp_path / "controllers.yaml", tuned)
    changed = parse_params(params.document(), tuned=tmp_path / "controllers.yaml")
    pid_keys = {j.key for j in sweep_jobs(changed)[0] if j.condition == "pid"}
    assert not pid_keys & keys  # other gains: other jobs
    assert rollout_params_hash(changed) == rollout_params_hash(params)  # gains are in the key itself
    job = sweep_jobs(params)[0][0]
    assert job.code_hash == rollout_code_hash()
    assert replace(job, code_hash="other code").key not in keys  # a row of other code is not resumed


def test_the_code_hash_follows_every_module_and_nothing_else(tmp_path):
    module = tmp_path / "sim" / "robot" / "pid.py"
    module.parent.mkdir(parents=True)
    module.write_text("KP = 1.0\n")
    (tmp_path / "sim" / "__pycache__").mkdir()
    before = rollout_code_hash(tmp_path, ("sim",))
    (tmp_path / "sim" / "__pycache__" / "pid.cpython-311.py").write_text("")
    (tmp_path / "sim" / "notes.txt").write_text("not code")
    assert rollout_code_hash(tmp_path, ("sim",)) == before
    module.write_text("KP = 2.0\n")
    assert rollout_code_hash(tmp_path, ("sim",)) != before
