"""`dvc repro` with `dvc.lock` rewritten through libyaml: what `python -m pipeline run` executes.

DVC rewrites the whole `dvc.lock` after every stage it runs, loading it with ruamel.yaml's
round-trip parser (pure Python, it keeps comments) and dumping it the same way. Our lock is ~340 KB
(61 stages, most of it the params each stage tracks); measured on the 2-core machine: round-trip
load 1.19 s + dump 0.73 s per stage, ~100 s of a `make run`'s 53 stages. A lock file has no
comments to keep, so here it is loaded with ruamel's C-backed safe loader (the YAML 1.2 loader DVC
reads it with everywhere else, 0.29 s) and dumped with PyYAML's C emitter in DVC's layout (0.09 s),
when that gives DVC's bytes (`lock_text` checks it each time); otherwise DVC's own round trip
writes it. Plain `dvc repro` writes the same file.
"""

from __future__ import annotations

import copy
import io
import math
import os
import re
import sys
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

LOCK_NAME = "dvc.lock"


class _LockDumper(yaml.CSafeDumper):
    """PyYAML's C safe dumper that writes DVC's mappings (dicts, OrderedDicts) in their order."""


def _null(dumper: yaml.SafeDumper, _: None) -> yaml.ScalarNode:
    return dumper.represent_scalar("tag:yaml.org,2002:null", "")  # ruamel: `key:` with no value


def _float(dumper: yaml.SafeDumper, value: float) -> yaml.ScalarNode:
    """A float as ruamel writes it for YAML 1.2 (`5e-05`, where PyYAML's YAML 1.1 gives `5.0e-05`)."""
    if not math.isfinite(value):  # .nan, .inf, -.inf: the same in both
        return yaml.representer.SafeRepresenter.represent_float(dumper, value)
    return dumper.represent_scalar("tag:yaml.org,2002:float", repr(value).lower())


_LockDumper.add_representer(OrderedDict, yaml.representer.SafeRepresenter.represent_dict)
_LockDumper.add_representer(type(None), _null)
_LockDumper.add_representer(float, _float)
# YAML 1.2's float without a dot (`5e-05`): plain, as the float it is, not quoted as a string
_LockDumper.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9]+[eE][-+]?[0-9]+$"), list("-+0123456789"))


def dump_lock_text(data: dict) -> str:
    """`data` as YAML text in the layout DVC's ruamel dumper gives a lock file (block style, keys in
    insertion order, sequences not indented under their key)."""
    return yaml.dump(data, Dumper=_LockDumper, sort_keys=False, default_flow_style=False,
                     allow_unicode=True)


def load_lock_text(text: str) -> dict:
    """A lock file's text as DVC reads it (ruamel.yaml safe, YAML 1.2; C parser when available)."""
    from ruamel.yaml import YAML

    return YAML(typ="safe").load(text) or {}


def dvc_dump_text(data: Any) -> str:
    """`data` as DVC's own dumper writes it (ruamel.yaml round-trip, block style)."""
    from dvc.utils.serialize._yaml import _dump

    buf = io.StringIO()
    _dump(data, buf)
    return buf.getvalue()


def libyaml_lock_text(text: str, before: dict, after: dict, round_trips: bool = False) -> str | None:
    """`lock_text` through libyaml, or None when that would not give DVC's bytes: the file as read
    must dump back to itself (known when `round_trips`: this module wrote `text` from `before`), and
    every stage entry DVC replaced or added must dump the same with both dumpers (a block file is
    its entries one after the other)."""
    old, new = before.get("stages", {}), after.get("stages", {})
    changed = [n for n in new if n not in old or new[n] != old[n]]
    same_top = [k for k in after if k != "stages"] == [k for k in before if k != "stages"] and \
        all(after[k] == before[k] for k in after if k != "stages")
    try:
        if same_top and (round_trips or dump_lock_text(before) == text) and all(
                dump_lock_text({"stages": {n: new[n]}}) == dvc_dump_text({"stages": {n: new[n]}})
                for n in changed):
            return dump_lock_text(after)
    except (yaml.YAMLError, TypeError, ValueError):
        pass
    return None


def lock_text(text: str, before: dict, after: dict) -> str:
    """The lock file DVC writes when it changes the lock read from `text` (`before`, as loaded)
    into `after`. Through libyaml when that gives DVC's bytes (`libyaml_lock_text`); otherwise
    DVC's own way: its round-trip parse of `text` with the same changes, dumped by its dumper."""
    fast = libyaml_lock_text(text, before, after)
    return fast if fast is not None else dvc_lock_text(text, before, after)


def dvc_lock_text(text: str, before: dict, after: dict) -> str:
    """`lock_text` DVC's way: its round-trip parse of `text` with the same changes, its dumper."""
    old, new = before.get("stages", {}), after.get("stages", {})
    changed = [n for n in new if n not in old or new[n] != old[n]]
    removed = [n for n in old if n not in new]
    from dvc.utils.serialize._yaml import parse_yaml_for_update

    data = parse_yaml_for_update(text, LOCK_NAME) if text else {}
    for k in after:
        if k != "stages" and not (k in before and after[k] == before[k]):
            data[k] = after[k]
    if "stages" in after:
        stages = data.setdefault("stages", {})
        for n in removed:
            del stages[n]
        for n in changed:
            stages[n] = new[n]
    return dvc_dump_text(data)


def fast_modify_yaml(original: Any) -> Any:
    """DVC's `modify_yaml(path, fs=None)` with `lock_text` for `dvc.lock` on the local filesystem;
    `original` for every other file. A lock this modifier wrote through libyaml is not parsed again
    when it comes back unchanged (the next stage of the same `dvc repro`): its data is the copy kept
    when it was written, which parses to the same (`load_lock_text(dump_lock_text(d)) == d`, tested),
    and it is known to dump back to itself (~0.4 s a stage of the lock's parse and re-dump)."""
    written: dict[str, dict] = {}  # the last lock text written through libyaml -> its data

    @contextmanager
    def modify_yaml(path: Any, fs: Any = None) -> Iterator[dict]:
        local = fs is None or getattr(fs, "protocol", None) in ("local", "file") or \
            type(fs).__name__ == "LocalFileSystem"
        if os.path.basename(os.fspath(path)) != LOCK_NAME or not local:
            with original(path, fs=fs) as data:
                yield data
            return
        text = Path(path).read_text(encoding="utf-8") if os.path.exists(path) else ""
        known = written.pop(text, None)
        written.clear()
        before = known if known is not None else (load_lock_text(text) if text else {})
        data = copy.deepcopy(before)  # DVC changes it in place; `before` stays as read (~25 ms)
        yield data
        fast = libyaml_lock_text(text, before, data, round_trips=known is not None)
        out = fast if fast is not None else dvc_lock_text(text, before, data)
        Path(path).write_text(out, encoding="utf-8")
        if fast is not None:
            written[fast] = copy.deepcopy(data)

    return modify_yaml


def main(argv: list[str]) -> int:
    """`dvc repro ARGV` in this process, the lock file written as above."""
    import dvc.dvcfile
    from dvc.cli import main as dvc_main

    dvc.dvcfile.modify_yaml = fast_modify_yaml(dvc.dvcfile.modify_yaml)
    return int(dvc_main(["repro", *argv]) or 0)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
