"""The ingest's helper threads: one small pool per process, for work that releases the GIL.

Reading (pyarrow's parser, sha256) and filtering (scipy's filter loop) release the GIL, so a trial
ingests on two cores from one process. Starting threads per trial cost 0.1-2 ms a start on the
2-core machine (Camargo's trial ingests in ~40 ms), so the pool lives as long as its process. A
forked child does not have its parent's threads: the pool is made again on first use in each
process. Tasks given to it must not wait on other tasks of the pool (two threads: no deadlock).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

HELPER_THREADS = 2  # the reads of a trial's IK and GRF files beside its marker file
_pool: tuple[int, ThreadPoolExecutor] | None = None


def helper_pool() -> ThreadPoolExecutor:
    """This process's helper pool (made on first use in each process)."""
    global _pool
    if _pool is None or _pool[0] != os.getpid():
        _pool = (os.getpid(), ThreadPoolExecutor(max_workers=HELPER_THREADS, thread_name_prefix="ingest"))
    return _pool[1]
