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

from ingest.filtering import finite_frames, finite_runs


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


def _hermite(x: np.ndarray, gaps: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Hermite bridges over the gaps x[start:stop] (rows of `gaps`, all at once) from the
    samples either side of each gap, with end slopes from one-sided differences (continuous
    position and velocity at both ends); a gap whose outer neighbour is missing too is bridged by
    a straight line. Returns the gaps' frames and their values."""
    n, a, b = len(x), gaps[:, 0] - 1, gaps[:, 1]
    both = (a >= 1) & valid[np.maximum(a - 1, 0)] & (b + 1 < n) & valid[np.minimum(b + 1, n - 1)]
    h = b - a
    col = (slice(None),) + (None,) * (x.ndim - 1)  # per-gap values against each sample's channels
    line = (x[b] - x[a]) / h[col]
    slope_a = np.where(both[col], x[a] - x[a - 1], line)
    slope_b = np.where(both[col], x[np.minimum(b + 1, n - 1)] - x[b], line)
    frames = np.concatenate([np.arange(start, stop) for start, stop in gaps])
    gap = np.repeat(np.arange(len(gaps)), gaps[:, 1] - gaps[:, 0])  # the gap of each frame
    t = ((frames - a[gap]) / h[gap])[col]
    hh = h[gap][col]
    h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
    h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
    return frames, h00 * x[a][gap] + h10 * hh * slope_a[gap] + h01 * x[b][gap] + h11 * hh * slope_b[gap]


def fill_short(x: np.ndarray, rate_hz: float, max_gap_s: float) -> np.ndarray:
    """Fill interior NaN runs of at most `max_gap_s` in an (n,) or (n, 3) signal with a cubic
    Hermite bridge (`_hermite`): each fill depends only on the gap's two neighbours on each side,
    so a long recording costs no more than its gaps."""
    x = np.asarray(x, dtype=float).copy()
    missing = ~finite_frames(x)
    if not missing.any() or missing.all():
        return x
    max_len = int(round(max_gap_s * rate_hz))
    gaps = np.array([(start, stop) for start, stop in finite_runs(missing)
                     if start > 0 and stop < len(x) and stop - start <= max_len], dtype=int).reshape(-1, 2)
    if len(gaps):
        frames, values = _hermite(x, gaps, ~missing)
        x[frames] = values
    return x


def long_gaps(x: np.ndarray) -> np.ndarray:
    """Boolean mask of frames still missing after filling."""
    return ~finite_frames(x)
