"""`MetricsParams`: the `metrics` section of params.yaml (what the metrics stage computes and how)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from pydantic import with_config

from metrics.groups import JOINTS
from metrics.phases import EventWindow
from metrics.spm import SpmParams


@with_config(extra="forbid")
@dataclass(frozen=True)
class MetricsParams:
    """The `metrics` section of params.yaml; `spm` takes `pool_sides` and `joints` from it."""

    pool_sides: bool = True      # left and right cycles pooled as one group
    exclude_locked: bool = True  # leave out robot samples while the arm is locked (fall caught)
    joints: tuple[str, ...] = JOINTS  # joint angles compared (SPM, range of motion)
    tracking_rate_hz: float = 20.0  # robot tracking table resampled to this rate (Hz)
    spm: SpmParams = field(default_factory=SpmParams)
    events: EventWindow = field(default_factory=EventWindow)

    def __post_init__(self) -> None:
        object.__setattr__(self, "spm", replace(self.spm, pool_sides=self.pool_sides, joints=self.joints))
