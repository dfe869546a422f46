"""Cohort variants of a subject's simulated human: the same body with changed strength, goals or
steadiness (issue 13's virtual cohort).

A variant changes three things, each measured by the same ingest code afterwards, never asserted:
- `torque_scale`: factors on the torque limits of the motors whose names start with a key (``all``
  for every motor): ``weak`` x0.6 everywhere, ``hemiparetic_left`` x0.4 on hip_l, knee_l, ankle_l;
- the preferred speed: `speed_mps` (absolute) or `speed_scale` (x the subject's own);
- `action_noise`: the std of Gaussian noise added to the policy's actions (in its [-1, 1] units,
  x `action_scale_rad` in joint targets) every policy step, so steps vary from one to the next
  (``unsteady``); seeded by the rollout's seed;
- `swing_time_ratio`: (side, ratio): the imitation reference is the subject's cycle time-warped so
  that this side's swing lasts `ratio` x the other's (`sim.motion.reference.with_longer_swing`):
  the paretic leg's longer swing of hemiparetic gait (Patterson et al. 2010, Gait Posture 31:241).
The healthy twin is the variant with nothing changed. Training a variant (fine-tuning from the
subject's own policy) and rolling it out use the same `Variant`, so the policy learns the body it
is evaluated on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

import mujoco
from pydantic import BaseModel, ConfigDict, Field, model_validator

HEALTHY = "healthy"


@dataclass(frozen=True)
class Variant:
    name: str = HEALTHY
    torque_scale: tuple[tuple[str, float], ...] = ()  # (motor-name prefix or "all", factor)
    speed_scale: float = 1.0
    speed_mps: float | None = None
    action_noise: float = 0.0
    swing_time_ratio: tuple[str, float] | None = None  # (side, this side's swing / the other's)
    train_action_noise: float | None = None  # fine-tuning's motor noise (`action_noise` unless set)

    @property
    def training_noise(self) -> float:
        """The motor noise the variant's policy is fine-tuned under."""
        return self.action_noise if self.train_action_noise is None else self.train_action_noise

    def torque_factor(self, motor: str) -> float:
        """The product of every factor whose key matches `motor` (1 when none does)."""
        f = 1.0
        for key, factor in self.torque_scale:
            if key == "all" or motor.startswith(key):
                f *= factor
        return f

    def scale_torques(self, spec: mujoco.MjSpec) -> None:
        """Scale the force ranges of the spec's actuators in place (after `pd_servo_spec`)."""
        for act in spec.actuators:
            f = self.torque_factor(act.name)
            if f != 1.0:
                act.forcerange = [float(act.forcerange[0]) * f, float(act.forcerange[1]) * f]

    def preferred_speed(self, subject_speed_mps: float) -> float:
        """The variant's preferred walking speed, given the subject's own (its reference cycle's)."""
        return float(self.speed_mps) if self.speed_mps is not None else self.speed_scale * subject_speed_mps


def variant_from_dict(name: str, d: dict) -> Variant:
    """A variant from its params entry (`cohort.variants.<name>`)."""
    scale = tuple((str(k), float(v)) for k, v in (d.get("torque_scale") or {}).items())
    speed = d.get("speed_mps")
    swing = d.get("swing_time_ratio") or {}  # one side at most (`VariantSpec` checks)
    return Variant(name, scale, float(d.get("speed_scale", 1.0)), None if speed is None else float(speed),
                   float(d.get("action_noise", 0.0)),
                   next(((str(k), float(v)) for k, v in swing.items()), None),
                   None if d.get("train_action_noise") is None else float(d["train_action_noise"]))


class VariantSpec(BaseModel):
    """One variant as params.yaml declares it (`cohort.variants.<name>`); `Variant` is what runs."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    torque_scale: dict[str, Annotated[float, Field(gt=0.0)]] = {}
    speed_scale: Annotated[float, Field(gt=0.0)] = 1.0
    speed_mps: Annotated[float, Field(gt=0.0)] | None = None
    action_noise: Annotated[float, Field(ge=0.0)] = 0.0
    train_action_noise: Annotated[float, Field(ge=0.0)] | None = None  # fine-tuning's (else action_noise)
    swing_time_ratio: Annotated[dict[Literal["left", "right"], Annotated[float, Field(ge=1.0, le=2.0)]],
                                Field(max_length=1)] = {}  # one side: its swing / the other's
    fine_tune_steps: Annotated[int, Field(ge=1)] | None = None  # this variant's budget (cohort's unless set)


class CohortSection(BaseModel):
    """The `cohort` section of params.yaml: the subjects whose policy humans get variants, the variants
    and their fine-tuning budget (env steps)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    subjects: tuple[str, ...]
    fine_tune_steps: Annotated[int, Field(ge=1)]
    curriculum_fraction: Annotated[float, Field(ge=0.0, le=1.0)]
    variants: dict[Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9_]*$")], VariantSpec]

    @model_validator(mode="after")
    def _not_healthy(self) -> CohortSection:
        if HEALTHY in self.variants:
            raise ValueError(f"variants: {HEALTHY!r} is the subject's own policy, not a variant to declare")
        return self

    def variant(self, name: str) -> Variant:
        """Variant `name` (`healthy`: nothing changed); a ValueError lists the declared ones."""
        if name == HEALTHY:
            return Variant()
        if name not in self.variants:
            raise ValueError(f"cohort.variants: no variant {name!r} ({', '.join([HEALTHY, *self.variants])})")
        return variant_from_dict(name, self.variants[name].model_dump(exclude={"fine_tune_steps"}))

    def budget(self, variant: str) -> int:
        """Env steps of `variant`'s fine-tuning: its own `fine_tune_steps`, else the cohort's."""
        self.variant(variant)
        return self.variants[variant].fine_tune_steps or self.fine_tune_steps
