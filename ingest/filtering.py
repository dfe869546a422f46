"""Zero-phase Butterworth low-pass filter, in the convention of the gait-analysis literature.

Convention (Winter 2009, *Biomechanics and Motor Control of Human Movement*, 4th ed., sec. 3.4;
the same as Pose2Sim's "order 4" filter): an ``order``-th order zero-phase filter is a Butterworth
of order ``order / 2`` applied forward then backward (`scipy.signal.filtfilt`, odd padding of
``3 * max(len(a), len(b))`` samples). The design cutoff is *not* corrected for the two passes, so
the combined magnitude response is ``|H(f)| = 1 / (1 + (tan(pi f / fs) / tan(pi fc / fs))^order)``:
exactly 0.5 (-6.02 dB) at ``cutoff_hz``, -3 dB at about 0.80 ``cutoff_hz`` for order 4, and a
roll-off of ``-20 * order`` dB/decade. With ``order: 4``, ``cutoff_hz: 12`` (params.yaml) this is
the "4th-order zero-lag Butterworth at 12 Hz" of the paper.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy  # scipy.signal loads on first use (~0.7 s): stages that never filter skip it

from ingest.concurrency import helper_pool, on_helper_thread


def butter_coefficients(order: int, cutoff_hz: float, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of one pass: Butterworth of order ``order // 2`` at ``cutoff_hz`` (read-only arrays:
    designed once per order, cutoff and rate, since a trial filters many signals alike)."""
    if order % 2 or order < 2:
        raise ValueError(f"zero-phase filter order must be even and >= 2, got {order}")
    if not 0 < cutoff_hz < rate_hz / 2:
        raise ValueError(f"cutoff {cutoff_hz} Hz must lie between 0 and Nyquist ({rate_hz / 2} Hz)")
    return _butter(order // 2, cutoff_hz / (rate_hz / 2))


@lru_cache(maxsize=64)
def _butter(order: int, wn: float) -> tuple[np.ndarray, np.ndarray]:
    b, a = scipy.signal.butter(order, wn, btype="low")
    b.flags.writeable = a.flags.writeable = False
    return b, a


def magnitude_response(freq_hz: np.ndarray, order: int, cutoff_hz: float, rate_hz: float) -> np.ndarray:
    """Gain of the combined forward-backward filter at `freq_hz` (the formula in the module doc)."""
    ratio = np.tan(np.pi * np.asarray(freq_hz) / rate_hz) / np.tan(np.pi * cutoff_hz / rate_hz)
    return 1.0 / (1.0 + ratio ** order)


def lowpass(x: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase low-pass along axis 0; NaN runs are left in place and each finite run is
    filtered on its own (a run too short to pad is returned unfiltered)."""
    b, a = butter_coefficients(order, cutoff_hz, rate_hz)
    x = np.asarray(x, dtype=float)
    finite = finite_frames(x)
    if finite.all():
        return _filtfilt(b, a, x)
    out = np.full_like(x, np.nan)
    padlen = 3 * max(len(a), len(b))
    for start, stop in finite_runs(finite):
        if stop - start > padlen:
            out[start:stop] = scipy.signal.filtfilt(b, a, x[start:stop], axis=0)
        else:
            out[start:stop] = x[start:stop]
    if x.ndim > 1:  # columns finite where others are not: filter them column by column
        partial = ~finite & np.isfinite(x).any(axis=tuple(range(1, x.ndim)))
        if partial.any():
            flat = x.reshape(len(x), -1)
            res = out.reshape(len(x), -1)
            for j in range(flat.shape[1]):
                res[:, j] = lowpass(flat[:, j], rate_hz, cutoff_hz, order)
            out = res.reshape(x.shape)
    return out


CHUNK_CHANNELS = 16  # wider gap-free arrays are filtered in chunks of at most this many channels


def _filtfilt(b: np.ndarray, a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """`filtfilt` along axis 0; an array of more than `CHUNK_CHANNELS` channels in chunks of at most
    that many, whose passes stay in cache (Camargo's 78 gap-free marker channels, 3067 frames, on
    one thread: 2.9 ms in 5 chunks against 5 ms in one call), the first half of the chunks on a
    helper thread (`ingest.concurrency`: scipy's filter loop releases the GIL). The channels are
    independent, so the result is the same bytes. On a helper thread itself, all on that thread."""
    flat = x.reshape(len(x), -1)
    width = flat.shape[1]
    if width <= CHUNK_CHANNELS:
        return scipy.signal.filtfilt(b, a, x, axis=0)
    bounds = np.linspace(0, width, -(-width // CHUNK_CHANNELS) + 1).round().astype(int)
    chunks = list(zip(bounds[:-1], bounds[1:], strict=True))
    out = np.empty_like(flat)

    def run(part: list[tuple[int, int]]) -> None:
        for start, stop in part:
            out[:, start:stop] = scipy.signal.filtfilt(b, a, flat[:, start:stop], axis=0)

    if on_helper_thread():
        run(chunks)
    else:
        half = len(chunks) // 2
        first = helper_pool().submit(run, chunks[:half])
        run(chunks[half:])
        first.result()
    return out.reshape(x.shape)


def finite_frames(x: np.ndarray) -> np.ndarray:
    """Per frame (axis 0), whether every channel of `x` is finite: `np.isfinite(x).all(axis=1)`
    for (n,) and (n, ...) arrays, channel by channel when there are few (a marker's three), where
    numpy's reduction over a short last axis costs several times more."""
    finite = np.isfinite(x)
    if finite.ndim == 1:
        return finite
    finite = finite.reshape(len(finite), -1)
    if not 0 < finite.shape[1] <= 8:
        return finite.all(axis=1)
    out = finite[:, 0].copy()
    for j in range(1, finite.shape[1]):
        out &= finite[:, j]
    return out


def finite_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the True runs of a boolean vector."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))
