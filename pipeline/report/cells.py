"""Table cells as the reports print them: numbers rounded (cm, N and deg to 2 decimals, m and m/s
to 3), "–" for a missing value, shares as the counts they are ("3/4"). The store keeps every number
exact; only these functions round."""

from __future__ import annotations

import math

import pandas as pd

MISSING = "–"


def num(x, digits: int) -> str:
    """`x` to `digits` decimals; "–" for None, NaN or NA."""
    if x is None or (isinstance(x, float) and math.isnan(x)) or x is pd.NA:
        return MISSING
    return f"{float(x):.{digits}f}"


def mean_sd(mean, sd, digits: int, n=None) -> str:
    """"mean ± sd (n=N)", each part left out when missing."""
    if num(mean, digits) == MISSING:
        return MISSING if n is None or num(n, 0) == MISSING else f"– (n={int(n)})"
    text = num(mean, digits) + ("" if num(sd, digits) == MISSING else f" ± {num(sd, digits)}")
    return text + ("" if n is None or num(n, 0) == MISSING else f" (n={int(n)})")


def walks(n, distinct) -> str:
    """`n` walks, and how many are distinct when fewer are."""
    text = num(n, 0)
    if text == MISSING or num(distinct, 0) == MISSING or int(distinct) >= int(n):
        return text
    return f"{text} ({int(distinct)} distinct)"


def mode(x) -> str:
    """A human mode, "–" when there is none."""
    return MISSING if x is None or (isinstance(x, float) and math.isnan(x)) else str(x)


def following(mean, sd, n_samples) -> str:
    """A compliance cell of Table I; says so when no sample was left to average."""
    if num(n_samples, 0) == "0":
        return "no samples (arm locked by a fall in every run)"
    return mean_sd(mean, sd, 2)


def falls(rate, n_trials) -> str:
    """A fall rate written as the count it is of `n_trials`."""
    if num(rate, 2) == MISSING:
        return MISSING
    return f"{round(float(rate) * int(n_trials))}/{int(n_trials)}"


def count(rate, n) -> str:
    """A share written as the count it is of `n` ("3/4"); "–" without a rate or with n = 0."""
    if num(rate, 4) == MISSING or num(n, 0) in (MISSING, "0"):
        return MISSING
    return f"{round(float(rate) * int(n))}/{int(n)}"


def falls_of(n_falls, n_walks) -> str:
    return MISSING if num(n_falls, 0) == MISSING else f"{int(n_falls)}/{int(n_walks)}"


def versus(c) -> str:
    """`pid ± ci vs adaptive ± ci` of a `metrics.findings.responsiveness_comparisons` row."""
    return f"{mean_sd(c.pid_mean, c.pid_ci95, 2)} vs {mean_sd(c.adaptive_mean, c.adaptive_ci95, 2)}"
