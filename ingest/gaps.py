"""Gap filling of marker dropouts.

Two passes, both bounded by params (`gaps`):
1. rigid-cluster fill: a missing marker of a rigid segment (the pelvis markers) is rebuilt from
   the segment's other markers with the best-fit rigid transform (Kabsch/Söderkvist & Wedin 1993)
   of a frame where all were seen; needs at least three visible partners.
2. interpolation: remaining gaps up to `max_gap_s` are bridged with a cubic (Hermite) curve that
   joins the neighbouring samples with matching position and velocity (cubic gap filling is the
   usual mocap practice, e.g. Howarth & Callaghan 2010). Longer gaps stay NaN: the strides they
   touch are rejected downstream with reason ``marker gap``.
"""

from __future__ import annotations

import numpy as np

from ingest.filtering import finite_frames


def _kabsch(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations R and translations t with dst ~ src @ R.T + t (least squares), for a stack of
    point sets: `src`, `dst` (..., k, 3) give R (..., 3, 3) and t (..., 1, 3)."""
    cs, cd = src.mean(axis=-2, keepdims=True), dst.mean(axis=-2, keepdims=True)
    u, _, vt = np.linalg.svd(np.swapaxes(src - cs, -1, -2) @ (dst - cd))
    v, ut = np.swapaxes(vt, -1, -2), np.swapaxes(u, -1, -2)
    flip = np.broadcast_to(np.eye(3), v.shape).copy()
    flip[..., 2, 2] = np.sign(np.linalg.det(v @ ut))
    rot = v @ flip @ ut
    return rot, cd - cs @ np.swapaxes(rot, -1, -2)


def fill_rigid(cluster: np.ndarray) -> np.ndarray:
    """Fill frames of an (n, k, 3) rigid cluster where one or more markers are missing, each from
    the nearest frame where all were seen (the earlier one on a tie); the frames are solved
    together, one stack per set of visible markers."""
    cluster = cluster.copy()
    seen = np.isfinite(cluster).all(axis=2)
    full = np.flatnonzero(seen.all(axis=1))
    if len(full) == 0 or cluster.shape[1] < 4:
        return cluster
    todo = np.flatnonzero(~seen.all(axis=1) & (seen.sum(axis=1) >= 3))
    after = np.clip(np.searchsorted(full, todo), 1, len(full) - 1) if len(full) > 1 else np.zeros_like(todo)
    before = np.maximum(after - 1, 0)
    nearest = full[np.where(np.abs(todo - full[before]) <= np.abs(full[after] - todo), before, after)]
    for vis in np.unique(seen[todo], axis=0):
        rows = (seen[todo] == vis).all(axis=1)
        ref, frames = cluster[nearest[rows]], todo[rows]
        rot, t = _kabsch(ref[:, vis], cluster[frames][:, vis])
        cluster[np.ix_(frames, ~vis)] = ref[:, ~vis] @ np.swapaxes(rot, -1, -2) + t
    return cluster


def _hermite(x: np.ndarray, signal: np.ndarray, start: np.ndarray, stop: np.ndarray,
             valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite bridges over the gaps x[start:stop, signal] of a stack of signals (n, k, ...)
    (one per element of `signal`, `start`, `stop`, all at once) from the samples either side of each
    gap, with end slopes from one-sided differences (continuous position and velocity at both ends);
    a gap whose outer neighbour is missing too (`valid`, (n, k)) is bridged by a straight line.
    Returns the gaps' frames, their signals and their values."""
    n, a, b = len(x), start - 1, stop
    both = ((a >= 1) & valid[np.maximum(a - 1, 0), signal] & (b + 1 < n)
            & valid[np.minimum(b + 1, n - 1), signal])
    h = b - a
    col = (slice(None),) + (None,) * (x.ndim - 2)  # per-gap values against each sample's channels
    xa, xb = x[a, signal], x[b, signal]
    line = (xb - xa) / h[col]
    slope_a = np.where(both[col], xa - x[a - 1, signal], line)
    slope_b = np.where(both[col], x[np.minimum(b + 1, n - 1), signal] - xb, line)
    length = stop - start
    gap = np.repeat(np.arange(len(start)), length)  # the gap of each frame
    frames = start[gap] + np.arange(len(gap)) - np.repeat(np.cumsum(length) - length, length)
    t = ((frames - a[gap]) / h[gap])[col]
    hh = h[gap][col]
    h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
    h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
    values = h00 * xa[gap] + h10 * hh * slope_a[gap] + h01 * xb[gap] + h11 * hh * slope_b[gap]
    return frames, signal[gap], values


def fill_short(x: np.ndarray, rate_hz: float, max_gap_s: float) -> np.ndarray:
    """Fill interior NaN runs of at most `max_gap_s` in an (n,) or (n, 3) signal with a cubic
    Hermite bridge (`_hermite`): each fill depends only on the gap's two neighbours on each side,
    so a long recording costs no more than its gaps."""
    return fill_short_all([x], rate_hz, max_gap_s)[0]


def fill_short_all(signals: list[np.ndarray], rate_hz: float, max_gap_s: float) -> list[np.ndarray]:
    """`fill_short` of each of several signals of one shape (new arrays), their gaps found and
    bridged together: numpy's overhead per call, not the gaps, is most of a signal's cost
    (Camargo's trial has 12 markers with gaps)."""
    x = np.stack(signals, axis=1).astype(float, copy=False)  # (n, k) or (n, k, 3): a new array
    n, k = x.shape[:2]
    missing = ~finite_frames(x.reshape(n * k, *x.shape[2:])).reshape(n, k)
    edges = np.diff(missing.astype(np.int8), axis=0, prepend=0, append=0).T  # (k, n + 1)
    signal, start = np.nonzero(edges == 1)  # signal by signal, each one's runs in order
    stop = np.nonzero(edges == -1)[1]
    short = (start > 0) & (stop < n) & (stop - start <= int(round(max_gap_s * rate_hz)))
    if short.any():
        frames, signal, values = _hermite(x, signal[short], start[short], stop[short], ~missing)
        x[frames, signal] = values
    return [x[:, j] for j in range(k)]


def long_gaps(x: np.ndarray) -> np.ndarray:
    """Boolean mask of frames still missing after filling."""
    return ~finite_frames(x)
