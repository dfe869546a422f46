"""Stage outputs written all-or-nothing: every file goes to a temp file beside its target and
replaces it (`os.replace`) only once all of them are written, so a failure leaves no half-written
output and keeps whatever was stored before. A writer killed outright (kill -9) cannot delete its
temp files: the next writer into the folder deletes those whose writer is gone (`remove_stale_temps`)."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import pandas as pd


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_stale_temps(folder: Path) -> list[Path]:
    """Delete the temp files `replacing` left in `folder` (`.<name>.<pid>.tmp`) whose writing process no
    longer runs; returns them. A live writer's temp files are kept."""
    stale = []
    for temp in folder.glob(".*.tmp"):
        pid = temp.name[:-len(".tmp")].rpartition(".")[2]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            temp.unlink(missing_ok=True)
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


def json_text(doc: dict) -> str:
    return json.dumps(doc, indent=2) + "\n"


def write_outputs(folder: Path, tables: Mapping[str, pd.DataFrame], metrics: Mapping[str, dict]) -> None:
    """`<folder>/<name>.parquet` for each table and `<folder>/<name>.json` for each metrics dict."""
    files = {folder / f"{n}.parquet": t for n, t in tables.items()}
    files |= {folder / f"{n}.json": d for n, d in metrics.items()}
    with replacing(*files) as temps:
        for temp, content in zip(temps, files.values(), strict=True):
            if isinstance(content, pd.DataFrame):
                content.to_parquet(temp, index=False)
            else:
                temp.write_text(json_text(content))


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
