"""A person geometrically similar to a recorded one: the same recordings with every length x `k`.

Geometric similarity about the lab origin (the floor z = 0 stays the floor): marker positions (m),
the subject's standing height and every length or speed of the processed tables (columns `*_m`,
`*_mps`) x k, body mass x k^3 (same density, volume x k^3); times and sampling rates are kept, so
speeds scale by k too (not the dynamic similarity of equal Froude number, where time would scale by
sqrt(k): `sim.learn.bodies`). Joint angles, phases, events and counts are unchanged. The robot
table's forces and torques are kept as recorded (an assisting robot follows no similarity law).
Scaling the ingested trials, the static trial and the subject's metadata, before the model and the
reference are made, lets the scale and retarget steps build the new person's human and reference
cycle by their own code. All functions are pure.
"""

from __future__ import annotations

import dataclasses

import pandas as pd

from ingest.process import ProcessedTrial, SubjectTables
from ingest.static import StaticTrial
from ingest.subject import Subject, check_body_size
from ingest.treadmill import Treadmill
from ingest.trial import Trial

SCALED_SUFFIXES = ("_m", "_mps")  # table columns in metres and metres per second


def _factor(k: float) -> float:
    """`k` as a float, refused unless positive and finite."""
    k = float(k)
    if not 0.0 < k < float("inf"):
        raise ValueError(f"a geometric scale factor must be positive and finite, not {k!r}")
    return k


def scaled_id(subject_id: str, k: float) -> str:
    """A name for the person `subject_id` scaled by `k` (for labels), e.g. `lenhart2015_x0.9`."""
    return f"{subject_id}_x{_factor(k):g}"


def scaled_subject(subject: Subject, k: float) -> Subject:
    """`subject` with height x k and mass x k^3 (id, marker set and trials kept); the result must
    still be a human's size (`check_body_size`)."""
    k = _factor(k)
    height, mass = subject.height_m * k, subject.mass_kg * k**3
    check_body_size(height, mass, f"{subject.id} x {k:g}")
    return dataclasses.replace(subject, height_m=height, mass_kg=mass)


def scaled_static(static: StaticTrial, k: float) -> StaticTrial:
    """The static trial with every marker position x k (angles kept)."""
    k = _factor(k)
    return dataclasses.replace(static, markers={n: p * k for n, p in static.markers.items()})


def scaled_table(table: pd.DataFrame, k: float) -> pd.DataFrame:
    """A copy of `table` with its length and speed columns (`SCALED_SUFFIXES`) x k."""
    k = _factor(k)
    out = table.copy()
    for column in out.columns:
        if str(column).endswith(SCALED_SUFFIXES) and pd.api.types.is_numeric_dtype(out[column]):
            out[column] = out[column] * k
    return out


def _scaled_treadmill(treadmill: Treadmill | None, k: float) -> Treadmill | None:
    if treadmill is None:
        return None
    c = treadmill.check
    check = dataclasses.replace(c, pelvis_speed_mps=c.pelvis_speed_mps * k,
                                foot_excursion_m=c.foot_excursion_m * k,
                                stance_speed_mps=c.stance_speed_mps * k)
    return dataclasses.replace(treadmill, belt_speed_mps=treadmill.belt_speed_mps * k, check=check)


def scaled_trial(processed: ProcessedTrial, k: float) -> ProcessedTrial:
    """A processed trial with its markers, its rows' lengths and speeds and its treadmill's belt
    speed x k. What the processed trials' file does not keep (force plates, a robot log or robot
    markers: ingest has turned them into tables) is left out rather than scaled."""
    k = _factor(k)
    t: Trial = processed.trial
    trial = dataclasses.replace(t, markers={n: xyz * k for n, xyz in t.markers.items()}, plates=None,
                                robot_log=None, robot_markers=None)
    return dataclasses.replace(
        processed, trial=trial, events=scaled_table(processed.events, k),
        strides=scaled_table(processed.strides, k), cycles=scaled_table(processed.cycles, k),
        robot=scaled_table(processed.robot, k), treadmill=_scaled_treadmill(processed.treadmill, k))


def scaled_tables(tables: SubjectTables, k: float) -> SubjectTables:
    """A subject's ingested tables and processed trials, every length and speed x k."""
    k = _factor(k)
    return SubjectTables(scaled_table(tables.events, k), scaled_table(tables.strides, k),
                         scaled_table(tables.cycles, k), scaled_table(tables.robot, k),
                         tuple(scaled_trial(p, k) for p in tables.trials))


__all__ = ["SCALED_SUFFIXES", "scaled_id", "scaled_static", "scaled_subject", "scaled_table", "scaled_tables",
           "scaled_trial"]
