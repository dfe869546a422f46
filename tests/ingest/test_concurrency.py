"""The ingest's helper threads (ingest/concurrency.py): the split filter gives the bytes of one
filter call, and a process forked after the pool ran still ingests (it gets its own pool)."""

from __future__ import annotations

import multiprocessing

import numpy as np
import scipy.signal

from ingest.canonical import load_trial
from ingest.concurrency import helper_pool
from ingest.filtering import CHUNK_CHANNELS, butter_coefficients, lowpass
from ingest.manifest import Manifest
from ingest.process import process_trial
from ingest.subject import load_subject


def test_split_filter_gives_the_bytes_of_one_call():
    rng = np.random.default_rng(3)
    for shape in [(500, CHUNK_CHANNELS + 1), (3067, 28, 3), (400, CHUNK_CHANNELS)]:
        x = rng.normal(size=shape).cumsum(axis=0)
        b, a = butter_coefficients(4, 12.0, 200.0)
        assert np.array_equal(lowpass(x, 200.0, 12.0, 4), scipy.signal.filtfilt(b, a, x, axis=0))


def test_a_helper_task_filters_a_wide_array_without_waiting_on_the_pool():
    """Both helper threads filter wide arrays at once: were they to split their work onto the pool,
    each would wait for a thread the other holds."""
    pool = helper_pool()
    x = np.random.default_rng(4).normal(size=(2000, 4 * CHUNK_CHANNELS)).cumsum(axis=0)
    b, a = butter_coefficients(4, 12.0, 200.0)
    futures = [pool.submit(lowpass, x, 200.0, 12.0, 4) for _ in range(2)]
    for f in futures:
        assert np.array_equal(f.result(timeout=30), scipy.signal.filtfilt(b, a, x, axis=0))


def _frames_in_child(queue) -> None:
    subject = load_subject("camargo")
    out = process_trial(load_trial(subject, subject.trials[0], Manifest.load()), subject.markerset,
                        _ingest_params())
    queue.put(out.trial.n_frames)


def _ingest_params():
    from ingest.process import IngestParams  # the defaults: this child needs no params.yaml

    return IngestParams()


def test_a_forked_process_ingests_with_its_own_pool():
    subject = load_subject("camargo")
    frames = process_trial(load_trial(subject, subject.trials[0], Manifest.load()), subject.markerset,
                           _ingest_params()).trial.n_frames  # the parent's pool has threads now
    parent_pool = helper_pool()
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_frames_in_child, args=(queue,))
    child.start()
    child.join(timeout=60)
    alive = child.is_alive()
    if alive:
        child.kill()
    assert not alive, "the forked child hung on its parent's pool"
    assert child.exitcode == 0
    assert queue.get(timeout=5) == frames
    assert helper_pool() is parent_pool  # the parent keeps its own
