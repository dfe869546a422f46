"""Stage outputs written all-or-nothing: every file goes to a temp file beside its target and
replaces it (`os.replace`) only once all of them are written, so a failure leaves no half-written
output and keeps whatever was stored before. A folder output (a report's figures) is replaced as a
set (`replacing_folder`): written whole into a temp folder beside it that takes its place in one
step, so a reader or DVC sees the earlier set or the new one, never a mix. A writer killed outright
(kill -9) cannot delete its temp files: the next writer into the folder deletes those whose writer
is gone (`remove_stale_temps`)."""

from __future__ import annotations

import ctypes
import errno
import json
import os
import shutil
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

import pandas as pd


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def remove_stale_temps(folder: Path) -> list[Path]:
    """Delete the temp files and folders `replacing` and `replacing_folder` left in `folder`
    (`.<name>.<pid>.tmp`) whose writing process no longer runs; returns them. A live writer's are
    kept. An earlier set a killed writer had moved aside (`.<name>.<pid>.old.tmp`) before moving its
    new one in is moved back to `<name>` when nothing took that place."""
    stale = []
    for temp in folder.glob(".*.tmp"):
        stem = temp.name[1:-len(".tmp")]
        aside = stem.endswith(".old")
        name, _, pid = stem.removesuffix(".old").rpartition(".")
        if not pid.isdigit() or int(pid) == os.getpid() or _alive(int(pid)):
            continue
        if aside and not (folder / name).exists():
            os.rename(temp, folder / name)
            continue
        _remove(temp)
        stale.append(temp)
    return stale


@contextmanager
def replacing(*targets: Path) -> Iterator[list[Path]]:
    """Temp paths beside `targets` to write to; on a clean exit each replaces its target, on an
    error they are deleted and the targets stay as they were. Temp files a killed writer left in
    the targets' folders are deleted first (`remove_stale_temps`)."""
    temps = []
    try:
        for folder in dict.fromkeys(target.parent for target in targets):
            folder.mkdir(parents=True, exist_ok=True)
            remove_stale_temps(folder)
        for target in targets:
            temps.append(target.with_name(f".{target.name}.{os.getpid()}.tmp"))
        yield temps
        for temp, target in zip(temps, targets, strict=True):
            os.replace(temp, target)
    finally:
        for temp in temps:
            temp.unlink(missing_ok=True)


_AT_FDCWD, _RENAME_EXCHANGE = -100, 2  # linux/fcntl.h, linux/fs.h


def _exchange(a: Path, b: Path) -> bool:
    """Swap two existing paths in one step (Linux `renameat2(RENAME_EXCHANGE)`); False where the
    system or its file system cannot."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(a), None, str(b))


def _swap_in(temp: Path, target: Path) -> Path | None:
    """Put the folder `temp` in `target`'s place; returns where the earlier `target` now is (None:
    there was none). Where the swap cannot be one step, the earlier set is first moved aside
    (`.<name>.<pid>.old.tmp`), which `remove_stale_temps` moves back if the writer dies before
    moving the new one in."""
    if not target.exists():
        os.rename(temp, target)
        return None
    if _exchange(temp, target):
        return temp
    aside = target.with_name(f".{target.name}.{os.getpid()}.old.tmp")
    os.rename(target, aside)
    os.rename(temp, target)
    return aside


@contextmanager
def replacing_folder(target: Path, *files: Path) -> Iterator[tuple[Path, list[Path]]]:
    """A temp folder beside the folder `target` (`.<name>.<pid>.tmp`) to write its whole new set of
    files into, and temp paths for `files` beside theirs (as `replacing`). On a clean exit the temp
    folder takes `target`'s place in one step, then each file replaces its target and the earlier
    set is deleted: a file of the earlier set the new one lacks is gone. On an error the temps are
    deleted and `target` and `files` stay as they were."""
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(target.parent)
    temp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    _remove(temp)  # an earlier process of the same pid
    temp.mkdir()
    earlier = None
    try:
        with replacing(*files) as temps:
            yield temp, temps
            earlier = _swap_in(temp, target)
    finally:
        _remove(temp)
        if earlier is not None:
            _remove(earlier)


def json_text(doc: dict) -> str:
    return json.dumps(doc, indent=2) + "\n"


def _write(temp: Path, content: pd.DataFrame | dict | Callable[[BinaryIO], None]) -> None:
    if isinstance(content, pd.DataFrame):
        content.to_parquet(temp, index=False)
    elif callable(content):
        with open(temp, "wb") as fh:
            content(fh)
    else:
        temp.write_text(json_text(content))


def write_outputs(folder: Path, tables: Mapping[str, pd.DataFrame], metrics: Mapping[str, dict],
                  table_set: tuple[Path, Mapping[str, pd.DataFrame]] | None = None,
                  others: Mapping[str, Callable[[BinaryIO], None]] | None = None) -> None:
    """`<folder>/<name>.parquet` for each table, `<folder>/<name>.json` for each metrics dict and
    `<folder>/<name>` for each of `others`, written by its function into the open binary file; with
    `table_set` (a folder, its tables), also `<that folder>/<name>.parquet` for each of its tables, the
    folder replaced as a set (`replacing_folder`: a table no longer written is gone)."""
    files: dict[Path, object] = {folder / f"{n}.parquet": t for n, t in tables.items()}
    files |= {folder / f"{n}.json": d for n, d in metrics.items()}
    files |= {folder / n: write for n, write in (others or {}).items()}
    if table_set is None:
        with replacing(*files) as temps:
            for temp, content in zip(temps, files.values(), strict=True):
                _write(temp, content)
        return
    target, members = table_set
    with replacing_folder(target, *files) as (temp_folder, temps):
        for name, table in members.items():
            _write(temp_folder / f"{name}.parquet", table)
        for temp, content in zip(temps, files.values(), strict=True):
            _write(temp, content)


def read_json(path: Path) -> dict | None:
    """A stage's JSON input, None when the file is absent (an optional input: no policy, no gate)."""
    return json.loads(path.read_text()) if path.is_file() else None


def write_json(path: Path, doc: dict) -> None:
    """One JSON document, written all-or-nothing."""
    with replacing(path) as (temp,):
        temp.write_text(json_text(doc))


def write_figure(fig, path: Path, dpi: int) -> None:
    """A matplotlib figure as PNG, written all-or-nothing; the figure is closed."""
    import matplotlib.pyplot as plt

    try:
        with replacing(path) as (temp,):
            fig.savefig(temp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
