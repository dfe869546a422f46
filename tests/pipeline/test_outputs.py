"""All-or-nothing stage outputs: a failure keeps what was stored and leaves no temp file."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from pipeline.stages.outputs import replacing, write_json, write_outputs

ROOT = Path(__file__).resolve().parents[2]


def test_outputs_replace_previous_ones(tmp_path):
    write_outputs(tmp_path, {"t": pd.DataFrame({"a": [1]})}, {"m": {"n": 1}})
    write_outputs(tmp_path, {"t": pd.DataFrame({"a": [2]})}, {"m": {"n": 2}})
    assert pd.read_parquet(tmp_path / "t.parquet")["a"].tolist() == [2]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "t.parquet"]


def test_failure_keeps_stored_outputs(tmp_path):
    kept = tmp_path / "a.json"
    kept.write_text("old")
    with pytest.raises(RuntimeError), replacing(kept, tmp_path / "b.json") as (a, b):
        a.write_text("new")
        raise RuntimeError("writing b failed")
    assert kept.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


WRITER = """
import sys, time
from pathlib import Path
from pipeline.stages.outputs import replacing
with replacing(Path(sys.argv[1])) as (temp,):
    temp.write_bytes(b"")  # a figure begun, then the writer is killed (issue 34 case 13: kill -9 of report)
    time.sleep(60)
"""


def test_a_writer_killed_with_sigkill_leaves_no_temp_file_behind_the_next_writer(tmp_path):
    """kill -9 of a stage while it writes leaves its `.<name>.<pid>.tmp` (nothing can delete it then);
    the next write into the folder deletes it, whatever file it writes, and keeps a live writer's."""
    figures = tmp_path / "figures"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(figures / "tracking.png")], cwd=ROOT)
    temp = figures / f".tracking.png.{writer.pid}.tmp"
    deadline = time.monotonic() + 30
    while not temp.exists():
        assert writer.poll() is None and time.monotonic() < deadline, "the writer did not start writing"
        time.sleep(0.05)
    writer.send_signal(signal.SIGKILL)
    assert writer.wait(timeout=10) == -signal.SIGKILL
    assert temp.exists() and not (figures / "tracking.png").exists()  # what the kill left
    live = figures / f".other.png.{os.getpid()}.tmp"  # this process is alive: its temp file is kept
    live.write_bytes(b"")
    write_json(figures / "summary.json", {"ok": True})  # another file of the same folder
    assert sorted(p.name for p in figures.iterdir()) == [live.name, "summary.json"]

