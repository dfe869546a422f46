"""The ingest's helper threads: one small pool per process, for work that releases the GIL.

Reading (pyarrow's parser, sha256) and filtering (scipy's filter loop) release the GIL, so a trial
ingests on two cores from one process. Starting threads per trial cost 0.1-2 ms a start on the
2-core machine (Camargo's trial ingests in ~40 ms), so the pool lives as long as its process. A
forked child does not have its parent's threads: the pool is made again on first use in each
process. Its tasks never wait on other tasks of the pool (`on_helper_thread`: code that would split
its work runs it whole there instead), so two threads cannot deadlock.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

HELPER_THREADS = 2  # the reads of a trial's IK and GRF files beside its marker file
THREAD_PREFIX = "ingest-helper"
_pool: tuple[int, ThreadPoolExecutor] | None = None


def helper_pool() -> ThreadPoolExecutor:
    """This process's helper pool (made on first use in each process)."""
    global _pool
    if _pool is None or _pool[0] != os.getpid():
        pool = ThreadPoolExecutor(max_workers=HELPER_THREADS, thread_name_prefix=THREAD_PREFIX)
        _pool = (os.getpid(), pool)
    return _pool[1]


def on_helper_thread() -> bool:
    """Whether this code runs as a task of the helper pool (where it must not wait on the pool)."""
    return threading.current_thread().name.startswith(THREAD_PREFIX)
