"""Planar angles: headings and yaw differences wrapped to one turn, so that an error between two
headings is the short way round. Shared by the steering of the walking human (sim.learn) and the
follow-me controllers (sim.robot), which do not import each other."""

from __future__ import annotations

import math


def wrap_angle(a: float) -> float:
    """`a` (rad) wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


__all__ = ["wrap_angle"]
