"""Opening the results store: one writer at a time, readers never blocked (see `pipeline.store`)."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path

import duckdb
from pydantic import with_config

from ingest.errors import GaitloopError
from pipeline.paths import REPO_ROOT, STORE_FILE, repo_path


class StoreError(GaitloopError):
    """The results store cannot be opened, is busy, or is missing its inputs."""

    def __init__(self, where: str | Path, problem: str) -> None:
        self.where = str(where)
        super().__init__(f"{self.where}: {problem}")


@with_config(extra="forbid")
@dataclass(frozen=True)
class StoreParams:
    """The `store` section of params.yaml."""

    path: Path = STORE_FILE  # a relative path is taken from the repository root
    busy_timeout_s: float = 10.0  # a second writer waits this long (s) for the file lock, then "busy"
    retry_interval_s: float = 0.2

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", repo_path(self.path))



def code_rev(root: Path = REPO_ROOT) -> str:
    """`git rev-parse HEAD` of `root`, 'unknown' when not a git checkout."""
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True,
                             timeout=10)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return out.stdout.strip() if out.returncode == 0 and out.stdout.strip() else "unknown"


def connect(path: Path, read_only: bool = False, busy_timeout_s: float = 10.0,
            retry_interval_s: float = 0.2) -> duckdb.DuckDBPyConnection:
    """Open the store, waiting up to `busy_timeout_s` while another process holds its lock."""
    path = Path(path)
    if read_only and not path.is_file():
        raise StoreError(path, "no results store here yet: run `python -m pipeline store` first")
    deadline = time.monotonic() + busy_timeout_s
    while True:
        try:
            return duckdb.connect(str(path), read_only=read_only)
        except duckdb.IOException as exc:
            if "lock" not in str(exc).lower():
                raise StoreError(path, f"cannot open the store ({exc})") from None
            if time.monotonic() >= deadline:
                raise StoreError(path, f"store is busy: another process holds its lock; waited "
                                 f"{busy_timeout_s:g} s ({str(exc).splitlines()[0]})") from None
            time.sleep(retry_interval_s)
        except duckdb.Error as exc:
            raise StoreError(path, f"cannot open the store ({exc})") from None


@contextmanager
def _writer_lock(path: Path, busy_timeout_s: float, retry_interval_s: float) -> Iterator[None]:
    """Hold `<path>.lock` (flock, released when this process ends whatever happens), waiting up to
    `busy_timeout_s` for another store run to finish."""
    fd = os.open(path.with_name(f"{path.name}.lock"), os.O_RDWR | os.O_CREAT, 0o644)
    try:
        deadline = time.monotonic() + busy_timeout_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise StoreError(path, f"store is busy: another store run is writing it; waited "
                                     f"{busy_timeout_s:g} s") from None
                time.sleep(retry_interval_s)
        yield
    finally:
        os.close(fd)


@contextmanager
def writing_copy(path: Path, busy_timeout_s: float = 10.0, retry_interval_s: float = 0.2) -> Iterator[Path]:
    """A copy of the store at `path` (empty when there is none) to write to; once the block ends
    cleanly, the copy replaces the store at once (`os.replace`), otherwise it is deleted and the
    store stays as it was. Readers are never waited for and keep their snapshot; another store run,
    or a client holding the store open for writing, is waited for up to `busy_timeout_s`."""
    path = Path(path)
    with _writer_lock(path, busy_timeout_s, retry_interval_s):
        for stale in path.parent.glob(f"{path.name}.*.tmp*"):  # of runs killed midway: none runs now
            stale.unlink(missing_ok=True)
        temp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        try:
            with ExitStack() as held:
                if path.is_file():
                    if path.with_name(f"{path.name}.wal").is_file():  # a writer's log: fold it in first
                        connect(path, False, busy_timeout_s, retry_interval_s).close()
                    # readers share this read-only lock; it keeps other clients from writing the store
                    # in place until the copy has replaced it
                    held.enter_context(open_store(path, True, busy_timeout_s, retry_interval_s))
                    shutil.copyfile(path, temp)
                yield temp
                os.replace(temp, path)
        finally:
            temp.unlink(missing_ok=True)
            temp.with_name(f"{temp.name}.wal").unlink(missing_ok=True)


@contextmanager
def open_store(path: Path, read_only: bool = False, busy_timeout_s: float = 10.0,
               retry_interval_s: float = 0.2) -> Iterator[duckdb.DuckDBPyConnection]:
    """`connect`, closed on exit whatever happens."""
    con = connect(path, read_only, busy_timeout_s, retry_interval_s)
    try:
        yield con
    finally:
        con.close()

