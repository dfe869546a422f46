"""`pipeline.commands.repro`: DVC's lock file through libyaml gives the bytes DVC's own dumper gives."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import OrderedDict
from contextlib import contextmanager
from pathlib import Path

import pytest

from pipeline import paths
from pipeline.commands.repro import (
    dump_lock_text,
    dvc_dump_text,
    fast_modify_yaml,
    libyaml_lock_text,
    load_lock_text,
    lock_text,
)

ROOT = paths.REPO_ROOT


def test_the_projects_own_lock_reads_and_dumps_to_the_same_bytes():
    text = (ROOT / "dvc.lock").read_text()
    data = load_lock_text(text)
    assert len(data["stages"]) > 40
    assert dump_lock_text(data) == text == dvc_dump_text(data)


def test_a_stage_written_through_the_fast_path_is_what_dvc_would_write(tmp_path, monkeypatch):
    import dvc.utils.serialize._yaml as dvc_yaml

    def slow_path(*_):
        raise AssertionError("DVC's round trip was used")

    monkeypatch.setattr(dvc_yaml, "parse_yaml_for_update", slow_path)
    lock = tmp_path / "dvc.lock"
    lock.write_text((ROOT / "dvc.lock").read_text())
    seen = []

    @contextmanager
    def original(path, fs=None):
        seen.append(path)
        yield {}

    stage = OrderedDict(cmd="python -m x", deps=[OrderedDict(path="a", hash="md5", md5="0" * 32, size=3)],
                        params={"params.yaml": {"robot.mass_kg": 60.0, "names": ["start", "stop"],
                                                "flag": True, "none": None}})
    with fast_modify_yaml(original)(lock) as data:
        expected = dict(data)
        data["stages"].update({"new@stage": stage})
    assert seen == []  # the fast path, not DVC's
    expected["stages"] = {**expected["stages"], "new@stage": stage}
    assert lock.read_text() == dvc_dump_text(expected)
    assert load_lock_text(lock.read_text())["stages"]["new@stage"]["params"]["params.yaml"]["flag"] is True


def test_a_lock_it_wrote_is_not_parsed_again_and_gives_the_same_bytes(tmp_path, monkeypatch):
    import pipeline.commands.repro as repro

    def nothing(path, fs=None):
        raise AssertionError("dvc.lock goes through the fast path")

    text = (ROOT / "dvc.lock").read_text()
    assert load_lock_text(dump_lock_text(load_lock_text(text))) == load_lock_text(text)
    def entry(cmd: str) -> OrderedDict:
        return OrderedDict(cmd=cmd, outs=[OrderedDict(path="b", hash="md5", md5="1" * 32, size=1)])

    twice, fresh = tmp_path / "twice" / "dvc.lock", tmp_path / "fresh" / "dvc.lock"
    for lock in (twice, fresh):
        lock.parent.mkdir()
        lock.write_text(text)
    modify = fast_modify_yaml(nothing)
    with modify(twice) as data:
        data["stages"]["one@stage"] = entry("python -m y")
    parsed = []
    monkeypatch.setattr(repro, "load_lock_text", lambda t: parsed.append(t) or load_lock_text(t))
    with modify(twice) as data:  # the next stage: the text this modifier wrote, not parsed again
        data["stages"]["two@stage"] = entry("python -m z")
    assert parsed == []
    with fast_modify_yaml(nothing)(fresh) as data:  # both changes at once, from the file as read
        data["stages"]["one@stage"] = entry("python -m y")
        data["stages"]["two@stage"] = entry("python -m z")
    assert len(parsed) == 1 and twice.read_text() == fresh.read_text()


def _lock_with_param(value) -> tuple[str, dict, dict]:
    """A one-stage lock's text, as loaded, and with a stage added that tracks the param `x: value`."""
    text = "schema: '2.0'\nstages:\n  a:\n    cmd: echo a\n"
    before = load_lock_text(text)
    entry = {"cmd": "echo", "params": {"p.yaml": {"x": value}}}
    return text, before, {**before, "stages": {**before["stages"], "s": entry}}


@pytest.mark.parametrize("value", [5e-05, 1e16, -3e-07, 0.5, float("nan"), "1e5", "5e-05", 100.0])
def test_floats_and_float_like_strings_dump_through_libyaml_as_dvc_writes_them(value):
    # YAML 1.1 (PyYAML) writes 5e-05 as 5.0e-05 and the string "1e5" plain; DVC (YAML 1.2) does not
    text, before, after = _lock_with_param(value)
    assert dump_lock_text(after) == dvc_dump_text(after)
    assert libyaml_lock_text(text, before, after) == dvc_dump_text(after)
    # by repr: as strict as == on these plain values (types included), and nan reads back as nan
    assert repr(load_lock_text(dump_lock_text(after))) == repr(after)


@pytest.mark.parametrize("value", ["0o17", "it's a: b", "yes", "a\nb", [None, 1]])
def test_entries_libyaml_writes_otherwise_get_dvcs_bytes(value):
    # YAML 1.1 (PyYAML) writes "0o17" plain, which YAML 1.2 (how DVC reads) takes for a number; the
    # rest it writes in another style than DVC's
    text, before, after = _lock_with_param(value)
    assert dump_lock_text(after) != dvc_dump_text(after)
    assert lock_text(text, before, after) == dvc_dump_text(after)


def test_a_lock_libyaml_would_rewrite_differently_is_kept_in_dvcs_format():
    text = "schema: '2.0'\nstages:\n  a:\n    cmd: echo\n    params:\n      p.yaml:\n        x: yes\n"
    before = load_lock_text(text)
    after = {**before, "stages": {**before["stages"], "b": {"cmd": "true"}}}
    assert dump_lock_text(before) != text
    assert lock_text(text, before, after) == text + "  b:\n    cmd: 'true'\n" == dvc_dump_text(after)


def test_a_removed_stage_is_gone():
    text = (ROOT / "dvc.lock").read_text()
    before = load_lock_text(text)
    name = next(iter(before["stages"]))
    after = {**before, "stages": {k: v for k, v in before["stages"].items() if k != name}}
    assert lock_text(text, before, after) == dvc_dump_text(after)


def test_other_yaml_files_go_through_dvcs_modify_yaml(tmp_path):
    other = tmp_path / "dvc.yaml"
    other.write_text("# a comment DVC keeps\nstages: {}\n")
    seen = []

    @contextmanager
    def original(path, fs=None):
        seen.append(Path(path).name)
        yield {}

    with fast_modify_yaml(original)(other):
        pass
    assert seen == ["dvc.yaml"] and other.read_text().startswith("# a comment")


@pytest.fixture
def tiny_repo(tmp_path) -> Path:
    root = tmp_path / "repo"
    root.mkdir()
    env = {**os.environ, "DVC_NO_ANALYTICS": "1"}
    subprocess.run([sys.executable, "-m", "dvc", "init", "--no-scm", "-q"], cwd=root, env=env, check=True)
    (root / "params.yaml").write_text("a: {rate_hz: 100.0, names: [x, y]}\nb: 2\n")
    (root / "dvc.yaml").write_text(
        "stages:\n  first:\n    cmd: echo one > one.txt\n    params: [a]\n    outs: [one.txt]\n"
        "  second:\n    cmd: cat one.txt > two.txt\n    deps: [one.txt]\n    params: [b]\n"
        "    outs: [two.txt]\n")
    return root


def test_repro_writes_the_lock_plain_dvc_writes(tiny_repo):
    env = {**os.environ, "DVC_NO_ANALYTICS": "1", "PYTHONPATH": str(ROOT)}
    fast = subprocess.run([sys.executable, "-m", "pipeline.commands.repro"], cwd=tiny_repo, env=env,
                          capture_output=True, text=True)
    assert fast.returncode == 0, fast.stderr
    ours = (tiny_repo / "dvc.lock").read_text()
    (tiny_repo / "dvc.lock").unlink()
    plain = subprocess.run([sys.executable, "-m", "dvc", "repro", "-f"], cwd=tiny_repo, env=env,
                           capture_output=True, text=True)
    assert plain.returncode == 0, plain.stderr
    assert ours == (tiny_repo / "dvc.lock").read_text()
    assert set(load_lock_text(ours)["stages"]) == {"first", "second"}
    assert (tiny_repo / "two.txt").read_text() == "one\n"
