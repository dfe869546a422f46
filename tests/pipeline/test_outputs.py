"""All-or-nothing stage outputs: a failure keeps what was stored and leaves no temp file; a folder
output is replaced as a set."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from pipeline.stages import outputs
from pipeline.stages.outputs import remove_stale_temps, replacing, replacing_folder, write_json, write_outputs

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



def figure_set(folder, names: dict[str, bytes]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, content in names.items():
        (folder / name).write_bytes(content)


def contents(folder) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


@pytest.mark.parametrize("one_step", [True, False], ids=["exchange", "moved-aside"])
def test_a_folder_is_replaced_as_a_set(tmp_path, monkeypatch, one_step):
    """The new set takes the folder's place whole (a file it lacks is gone), the file beside it right
    after; nothing else is left in the parent, whether the system swaps folders in one step or not."""
    swaps = []
    exchange = outputs._exchange if one_step else (lambda a, b: False)
    monkeypatch.setattr(outputs, "_exchange", lambda a, b: swaps.append(exchange(a, b)) or swaps[-1])
    figures = tmp_path / "figures"
    figure_set(figures, {"a.png": b"old a", "gone.png": b"old gone"})
    (tmp_path / "report.md").write_text("old")
    with replacing_folder(figures, tmp_path / "report.md") as (temp, (report,)):
        assert temp.parent == tmp_path and temp.name == f".figures.{os.getpid()}.tmp"
        figure_set(temp, {"a.png": b"new a", "b.png": b"new b"})
        assert contents(figures) == {"a.png": b"old a", "gone.png": b"old gone"}  # untouched until the end
        report.write_text("new")
    assert contents(figures) == {"a.png": b"new a", "b.png": b"new b"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures", "report.md"]
    assert (tmp_path / "report.md").read_text() == "new"
    assert swaps == [one_step and sys.platform == "linux"]  # renameat2 swaps in one step on Linux


def test_a_folder_is_created_by_its_first_set(tmp_path):
    with replacing_folder(tmp_path / "s" / "figures") as (temp, _):
        figure_set(temp, {"a.png": b"a"})
    assert contents(tmp_path / "s" / "figures") == {"a.png": b"a"}
    assert [p.name for p in (tmp_path / "s").iterdir()] == ["figures"]


def test_a_failed_set_keeps_the_earlier_one(tmp_path):
    figures = tmp_path / "figures"
    figure_set(figures, {"a.png": b"old a", "b.png": b"old b"})
    with pytest.raises(RuntimeError), replacing_folder(figures, tmp_path / "report.md") as (temp, (report,)):
        figure_set(temp, {"a.png": b"new a"})
        report.write_text("new")
        raise RuntimeError("drawing b failed")
    assert contents(figures) == {"a.png": b"old a", "b.png": b"old b"}
    assert [p.name for p in tmp_path.iterdir()] == ["figures"]


def dead_pid() -> int:
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    return gone.pid


def test_a_set_moved_aside_by_a_killed_writer_is_moved_back(tmp_path):
    """Where folders cannot be swapped in one step the earlier set is moved aside first: a writer
    killed before moving its new set in leaves no folder at all; the next writer moves the earlier
    set back and deletes the unfinished new one."""
    pid = dead_pid()
    figure_set(tmp_path / f".figures.{pid}.old.tmp", {"a.png": b"old a", "b.png": b"old b"})
    figure_set(tmp_path / f".figures.{pid}.tmp", {"a.png": b"new a"})
    assert remove_stale_temps(tmp_path) == [tmp_path / f".figures.{pid}.tmp"]
    assert [p.name for p in tmp_path.iterdir()] == ["figures"]
    assert contents(tmp_path / "figures") == {"a.png": b"old a", "b.png": b"old b"}


def test_an_earlier_set_is_deleted_once_the_new_one_is_in_place(tmp_path):
    """Killed after its new set took the folder's place, a writer leaves the earlier set aside: the
    next writer deletes it and keeps the folder."""
    pid = dead_pid()
    figure_set(tmp_path / "figures", {"a.png": b"new a"})
    figure_set(tmp_path / f".figures.{pid}.old.tmp", {"a.png": b"old a"})
    remove_stale_temps(tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["figures"]
    assert contents(tmp_path / "figures") == {"a.png": b"new a"}


SET_WRITER = """
import sys, time
from pathlib import Path
from pipeline.stages.outputs import replacing_folder
figures = Path(sys.argv[1])
with replacing_folder(figures) as (temp, _):
    (temp / "a.png").write_bytes(b"new a")  # one figure of the new set written, then killed
    time.sleep(60)
"""


def test_a_set_writer_killed_with_sigkill_keeps_the_earlier_set(tmp_path):
    figures = tmp_path / "figures"
    figure_set(figures, {"a.png": b"old a", "b.png": b"old b"})
    writer = subprocess.Popen([sys.executable, "-c", SET_WRITER, str(figures)], cwd=ROOT)
    done = tmp_path / f".figures.{writer.pid}.tmp" / "a.png"
    deadline = time.monotonic() + 30
    while not done.exists():
        assert writer.poll() is None and time.monotonic() < deadline, "the writer did not start writing"
        time.sleep(0.05)
    writer.send_signal(signal.SIGKILL)
    assert writer.wait(timeout=10) == -signal.SIGKILL
    assert contents(figures) == {"a.png": b"old a", "b.png": b"old b"}
    write_json(tmp_path / "summary.json", {"ok": True})  # any next writer into the parent folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["figures", "summary.json"]
