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

from ingest.filtering import finite_runs


def _kabsch(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t with dst ~ src @ R.T + t (least squares)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    u, _, vt = np.linalg.svd((src - cs).T @ (dst - cd))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rot, cd - cs @ rot.T


def fill_rigid(cluster: np.ndarray) -> np.ndarray:
    """Fill frames of an (n, k, 3) rigid cluster where one or more markers are missing."""
    cluster = cluster.copy()
    seen = np.isfinite(cluster).all(axis=2)
    full = np.flatnonzero(seen.all(axis=1))
    if len(full) == 0 or cluster.shape[1] < 4:
        return cluster
    for i in np.flatnonzero(~seen.all(axis=1) & (seen.sum(axis=1) >= 3)):
        ref = cluster[full[np.argmin(np.abs(full - i))]]
        vis = seen[i]
        rot, t = _kabsch(ref[vis], cluster[i, vis])
        cluster[i, ~vis] = ref[~vis] @ rot.T + t
    return cluster


def _hermite(x: np.ndarray, start: int, stop: int, valid: np.ndarray) -> np.ndarray:
    """Cubic Hermite bridge over x[start:stop] from the samples either side of the gap, with
    end slopes from one-sided differences (continuous position and velocity at both ends)."""
    a, b = start - 1, stop
    slope_a = x[a] - x[a - 1] if a >= 1 and valid[a - 1] else np.zeros_like(x[a])
    slope_b = x[b + 1] - x[b] if b + 1 < len(x) and valid[b + 1] else np.zeros_like(x[b])
    if not (a >= 1 and valid[a - 1]) or not (b + 1 < len(x) and valid[b + 1]):
        slope_a = slope_b = (x[b] - x[a]) / (b - a)  # a neighbour is missing too: straight line
    h = b - a
    t = (np.arange(start, stop) - a) / h
    t = t[:, None] if x.ndim == 2 else t
    h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
    h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
    return h00 * x[a] + h10 * h * slope_a + h01 * x[b] + h11 * h * slope_b


def fill_short(x: np.ndarray, rate_hz: float, max_gap_s: float) -> np.ndarray:
    """Fill interior NaN runs of at most `max_gap_s` in an (n,) or (n, 3) signal with a cubic
    Hermite bridge (`_hermite`): each fill depends only on the gap's two neighbours on each side,
    so a long recording costs no more than its gaps."""
    x = np.asarray(x, dtype=float).copy()
    missing = ~np.isfinite(x) if x.ndim == 1 else ~np.isfinite(x).all(axis=1)
    if not missing.any() or missing.all():
        return x
    max_len = int(round(max_gap_s * rate_hz))
    for start, stop in finite_runs(missing):
        if start > 0 and stop < len(x) and stop - start <= max_len:
            x[start:stop] = _hermite(x, start, stop, ~missing)
    return x


def long_gaps(x: np.ndarray) -> np.ndarray:
    """Boolean mask of frames still missing after filling."""
    return ~np.isfinite(x) if x.ndim == 1 else ~np.isfinite(x).all(axis=1)
