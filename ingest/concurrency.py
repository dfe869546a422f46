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
import signal
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
        _start_threads(pool)
        _pool = (os.getpid(), pool)
    return _pool[1]


def _start_threads(pool: ThreadPoolExecutor) -> None:
    """Start all of `pool`'s threads now, with SIGINT held back in this thread meanwhile: a Ctrl-C
    that lands while a thread starts can leave it unjoinable, and the process then hangs at exit
    after its error line. The held-back signal arrives as soon as the threads run."""
    main = threading.current_thread() is threading.main_thread()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if main else None
    try:
        barrier = threading.Barrier(HELPER_THREADS)  # every task waits for the others: one thread each
        for f in [pool.submit(barrier.wait, 10.0) for _ in range(HELPER_THREADS)]:
            f.result()
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


def on_helper_thread() -> bool:
    """Whether this code runs as a task of the helper pool (where it must not wait on the pool)."""
    return threading.current_thread().name.startswith(THREAD_PREFIX)
