"""params.yaml: every tunable number of gaitloop, read once per command and passed down typed.

`load_params` reads the file once and validates it against `Params`, a pydantic schema that mirrors
params.yaml key for key: every key of the file is required (the optional keys of a synthetic tuning
walk excepted, which default to `sim.motion.synthetic.WalkParams`), an unknown key is an error, and
every value is checked against its type. Any problem raises `ParamsError` naming the file and the
key path, e.g. `params.yaml: robot.base.mass_kg: Input should be a valid number`.

Each section model turns itself into the dataclass the library code takes with `build()`, the one
place where that happens: `ingest` -> `IngestParams`, `metrics` -> `MetricsParams`, `store` ->
`StoreParams`, `report` -> `ReportParams`, `retarget` -> `RetargetSection` (IK and reference
settings), `robot` -> `RobotParams` (and `controller_specs()`), `robot.tuning` -> `TuningParams`,
`rollout.replay` -> `ReplayParams`, `human` -> `HumanParams`, `train` -> `TrainParams`,
`evaluate_policy` -> `EvalParams`; `Params.batch_setup()` -> the rollout batch runner's
`BatchSetup` (robot, controllers, rollout and ingest settings together). The library dataclasses
keep defaults equal to params.yaml (tests/pipeline/test_params.py checks it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    field_validator,
    model_validator,
)

from ingest.errors import GaitloopError
from ingest.process import IngestParams
from ingest.static import StaticCheckParams
from metrics import JOINTS, SpmParams
from metrics.fall_intervention import FallRuleParams
from metrics.outcomes import ObjectiveWeights
from metrics.phases import EventWindow
from metrics.policy_checks import PolicyChecks
from metrics.quality import Limits, QualityParams
from metrics.scenario_checks import ScenarioChecks
from pipeline.paths import PARAMS_FILE, TUNED_GAINS, repo_path
from pipeline.store import StoreParams
from sim.body.balance_loss import BalanceLoss
from sim.body.human_params import HumanParams
from sim.body.variant import HEALTHY, Variant, variant_from_dict
from sim.errors import SimulationError
from sim.learn.pool import UniversalParams
from sim.learn.transfer import FeatureWeights
from sim.motion.reference import ReferenceParams
from sim.motion.replay import ReplayParams
from sim.motion.retarget import RetargetParams
from sim.motion.synthetic import WalkParams
from sim.robot.mrba import RobotParams
from sim.rollout.scenarios import ProfileParams, Segment
from sim.rollout.tuning import TuningParams

if TYPE_CHECKING:
    from sim.learn.train import TrainParams
    from sim.rollout.batch import BatchSetup, DriverSource

__all__ = ["PARAMS_FILE", "EvalParams", "MetricsParams", "Params", "ParamsError", "ReportParams",
           "RetargetSection", "load_params", "parse_params"]

MAX_REPORTED_ERRORS = 5


class ParamsError(GaitloopError):
    """A params file that is missing, not YAML, or does not match the schema."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


# -- pipeline-side parameter sets (the library ones live beside the code that takes them) ----------

@dataclass(frozen=True)
class MetricsParams:
    """The `metrics` section of params.yaml."""

    pool_sides: bool = True
    exclude_locked: bool = True
    joints: tuple[str, ...] = JOINTS
    tracking_rate_hz: float = 20.0
    spm: SpmParams = field(default_factory=SpmParams)
    events: EventWindow = field(default_factory=EventWindow)


@dataclass(frozen=True)
class ReportParams:
    """The `report` section of params.yaml."""

    dpi: int = 110
    # event -> the scenario its column of the phase-aligned figure is drawn from
    event_scenarios: dict[str, str] = field(default_factory=lambda: {"start": "walk_10m", "turn": "turn_90",
                                                                     "stop": "walk_10m"})
    caught_drop_m: float = 0.22  # fall intervention: robot.fall.drop_m + fall_intervention.caught_margin_m
    detection_window_s: float = 1.5  # fall intervention: a lock this soon after the onset detects it
    paper_scenario: str = "walk_10m"  # the scenario the paper tables and findings come from (scenarios.paper)


@dataclass(frozen=True)
class RetargetSection:
    """The `retarget` section of params.yaml: IK settings and reference-motion settings."""

    ik: RetargetParams
    reference: ReferenceParams


@dataclass(frozen=True)
class EvalParams:
    """`evaluate_policy` of params.yaml."""

    n_seeds: int = 10
    free_s: float = 20.0
    robot_s: float = 15.0
    push_n: float = 200.0
    push_duration_s: float = 0.2
    push_time_s: float = 5.0
    fall_height_fraction: float = 0.7
    spm_min_real_cycles: int = 5  # fewer real cycles: SPM reported but not judged (too few to test)
    push_recovery_s: float = 5.0  # the pushed walk goes on this long after the push


# -- the schema -----------------------------------------------------------------------------------

class Schema(BaseModel):
    """A block of params.yaml: every key required, no other key allowed, values type-checked."""

    model_config = ConfigDict(extra="forbid", frozen=True, coerce_numbers_to_str=True)


Pair = tuple[float, float]
Vec3 = tuple[float, float, float]
Vec6 = tuple[float, float, float, float, float, float]


# ingest

class FilterSchema(Schema):
    order: int
    cutoff_hz: Annotated[float, Field(gt=0.0)]


class GapsSchema(Schema):
    max_gap_s: float


class BoutsSchema(Schema):
    smooth_hz: float
    min_walk_speed_mps: float
    max_facing_angle_deg: float
    min_bout_s: float
    max_yaw_rate_deg_s: float


class EventsSchema(Schema):
    method: Literal["auto", "force", "kinematic"]
    force_threshold_n: float
    min_contact_s: float
    force_window_s: float
    min_event_interval_s: float
    min_prominence_m: float
    heel_settle_mps: float
    settle_window_s: float
    start_heel_height_m: float
    start_heel_speed_mps: float
    start_toe_descent_mps: float


class StridesSchema(Schema):
    max_stride_time_s: float
    min_speed_mps: float
    min_stride_length_m: float
    max_heading_change_deg: float
    max_speed_change: float
    speed_tolerance: float


class CyclesSchema(Schema):
    n_points: int


class PhasesSchema(Schema):
    standing_speed_mps: float
    steady_fraction: float
    turn_rate_deg_s: float
    speed_change_mps2: float
    min_speed_change_s: float


class StaticCheckSchema(Schema):
    min_duration_s: Annotated[float, Field(gt=0.0)]
    max_pelvis_speed_mps: Annotated[float, Field(gt=0.0)]
    max_foot_spread_m: Annotated[float, Field(gt=0.0)]
    max_knee_flexion_deg: Annotated[float, Field(gt=0.0)]
    speed_window_s: Annotated[float, Field(gt=0.0)]
    max_marker_spread_m: Annotated[float, Field(gt=0.0)]

    def build(self) -> StaticCheckParams:
        return StaticCheckParams(**self.model_dump())


class TreadmillSchema(Schema):
    max_pelvis_speed_mps: Annotated[float, Field(gt=0.0)]
    min_foot_excursion_m: Annotated[float, Field(gt=0.0)]
    min_belt_speed_mps: Annotated[float, Field(gt=0.0)]
    stance_height_m: Annotated[float, Field(gt=0.0)]


class IngestSchema(Schema):
    filter: FilterSchema
    gaps: GapsSchema
    bouts: BoutsSchema
    events: EventsSchema
    strides: StridesSchema
    cycles: CyclesSchema
    phases: PhasesSchema
    static: StaticCheckSchema  # the static trial's check: `ingest.static.StaticCheckParams` (static.build())
    treadmill: TreadmillSchema  # treadmill detection: `ingest.treadmill.TreadmillParams`

    def build(self) -> IngestParams:
        return IngestParams.from_dict(self.model_dump())


# metrics, store, report

class SpmSchema(Schema):
    alpha: Annotated[float, Field(gt=0.0, lt=1.0)]
    test: Literal["anova1", "ttest2"]
    min_cycles: Annotated[int, Field(ge=2)]
    reference_condition: str


class EventWindowSchema(Schema):
    names: tuple[str, ...]
    window_s: Pair
    step_s: Annotated[float, Field(gt=0.0)]

    @model_validator(mode="after")
    def _window(self) -> EventWindowSchema:
        if not self.window_s[0] < 0.0 < self.window_s[1]:
            raise ValueError(f"window_s: must run from before to after the event (got {list(self.window_s)})")
        return self


class MetricsSchema(Schema):
    pool_sides: bool
    exclude_locked: bool
    joints: tuple[str, ...]
    tracking_rate_hz: float
    events: EventWindowSchema
    spm: SpmSchema

    def build(self) -> MetricsParams:
        s = self.spm
        spm = SpmParams(alpha=s.alpha, test=s.test, min_cycles=s.min_cycles,
                        reference_condition=s.reference_condition, pool_sides=self.pool_sides,
                        joints=self.joints)
        return MetricsParams(self.pool_sides, self.exclude_locked, self.joints, self.tracking_rate_hz, spm,
                             EventWindow(**self.events.model_dump()))


class QualitySchema(Schema):
    """Each limit is [warn, fail] (metrics/quality.py)."""

    marker_rms_m: Pair
    asymmetry_pct: Pair
    knee_alignment_deg: Pair
    ik_angle_rms_deg: Pair
    edge_window_s: Annotated[float, Field(gt=0.0)]
    edge_strike_share: Pair
    span_samples: Pair
    speed_gap_pct: Pair
    missing_sides: Pair
    non_steady_share: Pair
    repeated_walks: Pair

    @model_validator(mode="after")
    def _ordered(self) -> QualitySchema:
        for name, value in self:
            if isinstance(value, tuple) and not value[0] <= value[1]:
                raise ValueError(f"{name}: warn must not exceed fail (got {list(value)})")
        return self

    def build(self) -> QualityParams:
        return QualityParams(**{name: Limits(*value) if isinstance(value, tuple) else value
                                for name, value in self})


class StoreSchema(Schema):
    path: str  # relative paths are taken from the repository root
    busy_timeout_s: float
    retry_interval_s: float

    def build(self) -> StoreParams:
        return StoreParams(repo_path(self.path), self.busy_timeout_s, self.retry_interval_s)


class ReportSchema(Schema):
    dpi: int
    event_scenarios: dict[str, str]

    def build(self) -> ReportParams:
        return ReportParams(self.dpi, dict(self.event_scenarios))


# retarget

class IkSchema(Schema):
    iterations: int
    first_frame_iterations: int
    step_tolerance: float
    damping: float
    posture_weight: float
    default_marker_weight: float
    min_markers: int
    marker_weights: dict[str, float]  # fnmatch pattern -> weight

    def build(self) -> RetargetParams:
        return RetargetParams.from_dict(self.model_dump())


class RetargetSchema(Schema):
    conditions: tuple[str, ...]
    qvel_cutoff_hz: Annotated[float, Field(gt=0.0)]
    cycle_samples: int
    cycle_side: Literal["left", "right"]
    floor_align: bool
    ik: IkSchema

    def build(self) -> RetargetSection:
        return RetargetSection(self.ik.build(), ReferenceParams.from_dict(self.model_dump(exclude={"ik"})))


# robot

class BaseSchema(Schema):
    mass_kg: float
    length_m: float
    width_m: float
    height_m: float
    reach_m: float
    drive_gain_n_per_mps: float
    yaw_gain_nm_per_radps: float
    max_force_n: float
    max_torque_nm: float
    max_speed_mps: float
    max_yaw_rate_rps: float
    max_accel_mps2: float
    max_yaw_accel_rps2: float
    latency_s: float
    control_rate_hz: float


class ArmSchema(Schema):
    link_mass_kg: float
    damping_ns_per_m: Vec3
    frictionloss_n: Vec3
    range_m: Vec3
    lock_timeconst_s: float


class HarnessSchema(Schema):
    stiffness: Vec6
    damping: Vec6
    range: Vec6
    mass_kg: float
    weld_timeconst_s: float
    limit_timeconst_s: float


class FallSchema(Schema):
    drop_speed_mps: float
    drop_m: float
    deflection_m: float


class SensorsSchema(Schema):
    arm_noise_m: float
    velocity_noise_mps: float


class WalkSchema(Schema):
    """One synthetic tuning walk; the keys after `rate_hz` are optional (a plain, straight walk)."""

    speed_mps: float
    stride_s: float
    surge_mps: float
    asym_mps: float
    sway_m: float
    bounce_m: float
    ramp_s: float
    rest_s: float
    duration_s: float
    pelvis_height_m: float
    mass_kg: float
    rate_hz: float
    turn_rate_rps: float = WalkParams.turn_rate_rps
    drift_mps: float = WalkParams.drift_mps
    drift_period_s: float = WalkParams.drift_period_s
    turn_onset_s: float = WalkParams.turn_onset_s
    turn_ramp_s: float = WalkParams.turn_ramp_s
    turn_slowdown: float = WalkParams.turn_slowdown


class TuningSchema(Schema):
    method: str
    max_evaluations: int
    seed: int
    force_weight_m_per_n: float
    limit_weight_m: float
    sample_rate_hz: float
    walks: Annotated[tuple[WalkSchema, ...], Field(min_length=1)]
    initial: dict[str, dict[str, float]]  # controller name -> starting gains of the search

    def build(self) -> TuningParams:
        return TuningParams.from_dict(self.model_dump(exclude={"initial"}))


class ControllerSchema(Schema):
    """A `robot.controllers` entry; its gains are checked against the class's declaration, with the
    tuned gains on top, by `parse_params` (`sim.robot.controllers.specs.merge_specs`)."""

    class_: str = Field(alias="class")  # registry name or package.module:Class
    gains: dict[str, float]

    def spec(self) -> dict:
        """The {class, gains} dict `sim.robot.controllers.make_controller` takes."""
        return {"class": self.class_, "gains": dict(self.gains)}


class RobotSchema(Schema):
    base: BaseSchema
    arm: ArmSchema
    harness: HarnessSchema
    fall: FallSchema
    sensors: SensorsSchema
    tuning: TuningSchema
    controllers: dict[str, ControllerSchema]

    _specs: dict[str, dict] | None = PrivateAttr(default=None)  # with the tuned gains (`with_tuned_gains`)

    def build(self) -> RobotParams:
        return RobotParams.from_dict(self.model_dump(include={"base", "arm", "harness", "fall", "sensors"}))

    def controller_specs(self) -> dict[str, dict]:
        """name -> {class, gains}: `robot.controllers` with the tuned-gains file's gains on top
        (`sim.robot.controllers.specs`; as params.yaml has them before `parse_params` adds those)."""
        specs = self._specs if self._specs is not None else {n: c.spec() for n, c in self.controllers.items()}
        return {name: {"class": s["class"], "gains": dict(s["gains"])} for name, s in specs.items()}


# rollout

class ReplaySchema(Schema):
    kp_n_per_m: float
    kd_ns_per_m: float
    kp_nm_per_rad: float
    kd_nms_per_rad: float
    max_force_n: float
    max_torque_nm: float
    max_vertical_bodyweights: float

    def build(self) -> ReplayParams:
        return ReplayParams(**self.model_dump())


class FallTestSchema(Schema):
    drop_m: float
    duration_s: float


class RolloutSchema(Schema):
    max_physics_dt_s: Annotated[float, Field(gt=0.0)]
    start_offset_m: Annotated[float, Field(ge=0.0)]
    n_seeds: Annotated[int, Field(ge=1)]
    conditions: tuple[str, ...]
    bout_margin_s: float
    bout_join_gap_s: float
    workers: int
    lead_in_s: float
    lead_in_ramp_s: float
    policy_sample_rate_hz: Annotated[float, Field(gt=0.0)]
    policy_motor_noise: Annotated[float, Field(ge=0.0)] = 0.0
    stop_after_fall_s: Annotated[float, Field(ge=0.0)] | None
    replay: ReplaySchema
    fall_test: FallTestSchema


# human

class JointValues(Schema):
    """One value per joint kind (`sim.body.human_params.joint_kind`)."""

    lumbar: float
    hip: float
    knee: float
    ankle: float
    shoulder: float
    elbow: float


class RangeDegSchema(Schema):
    """Ball joints: total rotation from upright; hinges: [min, max] in canonical signs."""

    lumbar: float
    hip: float
    shoulder: float
    knee: Pair
    ankle: Pair
    elbow: Pair


class GeomRadiusSchema(Schema):
    pelvis: float
    torso: float
    thigh: float
    shank: float
    foot: float
    upper_arm: float
    forearm: float
    hand: float


class HumanSchema(Schema):
    anthropometry: Literal["de_leva_male", "de_leva_female"]
    timestep_s: float
    neutral: Literal["static_ik", "static_upright", "asis_psis"]
    ankle_axis: Literal["knee", "malleoli"]
    talocrural_axis: Vec3
    subtalar_axis: Vec3
    knee_width_per_height: float
    ankle_width_per_height: float
    sjc_below_acromion_fraction: float
    head_radius_per_height: float
    floor_tolerance_m: float
    marker_bone_distance_max_m: Annotated[float, Field(gt=0.0)]
    contact_radius_m: float
    friction: float
    contact_solref: Pair
    joint_damping_nms_per_rad: float
    armature_kg_m2: float
    range_deg: RangeDegSchema
    torque_limit_nm_per_kg: JointValues
    pd_kp_nm_per_rad: JointValues
    pd_kd_nms_per_rad: JointValues
    geom_radius_per_height: GeomRadiusSchema

    def build(self) -> HumanParams:
        return HumanParams.from_dict(self.model_dump())


# train, evaluate_policy

class TrainSubjectSchema(Schema):
    args: str  # extra `python -m pipeline train` arguments of the dvc train stage


class ImitationSchema(Schema):
    pose: float
    velocity: float
    feet: float
    height: float
    root_velocity: float


class HarnessTwistSchema(Schema):
    probability: Annotated[float, Field(ge=0.0, le=1.0)]
    lag_s: Pair


class CommandsSchema(Schema):
    standing_start_probability: Annotated[float, Field(ge=0.0, le=1.0)]
    speed_range: Pair
    walk_s_range: Pair
    stand_s_range: Pair
    turn_deg_range: Pair
    event_probabilities: tuple[float, float, float]
    full_gait_fraction: Annotated[float, Field(gt=0.0, le=1.0)]
    stride_speed_exponent: Annotated[float, Field(gt=0.0, le=1.0)] | None
    min_cadence: Annotated[float, Field(gt=0.0, le=1.0)] | None
    turn_lean: Annotated[float, Field(gt=0.0, le=2.0)] | None
    turn_lean_time_constant_s: Annotated[float, Field(gt=0.0)]
    max_lean_tan: Annotated[float, Field(gt=0.0, le=1.0)]
    heading_lead_deg: Annotated[float, Field(gt=0.0, le=180.0)] | None
    start_s_range: Pair
    stop_s_range: Pair
    turn_rate_deg_s_range: Pair


class EnvSchema(Schema):
    control_dt_s: float
    action_scale_rad: float
    pd_kp_nm_per_rad: JointValues
    pd_kd_ratio_s: float
    episode_s: float
    min_pelvis_height_fraction: float
    max_tilt_deg: float
    w_imitation: float
    w_task: float
    w_style: float
    imitation_weights: ImitationSchema
    imitation_scales: ImitationSchema
    task_scale: float
    push_force_n: Pair
    push_duration_s: float
    push_interval_s: Pair
    push_probability: float
    heading_scale: float
    turn_imitation_scale: Annotated[float, Field(ge=0.0, le=1.0)]
    harness_twist: HarnessTwistSchema
    commands: CommandsSchema


class AmpSchema(Schema):
    hidden: tuple[int, ...]
    learning_rate: float
    grad_penalty: float
    weight_decay: float
    epochs: int
    batch_size: int
    replay_size: int
    reward_scale: float
    motion_share: Annotated[float, Field(ge=0.0, le=1.0)]


class TrainSchema(Schema):
    subjects: dict[str, TrainSubjectSchema]
    total_steps: int
    n_envs: int
    threads: int
    subprocess: bool
    n_steps: int
    batch_size: int
    n_epochs: int
    learning_rate: float
    gamma: float
    gae_lambda: float
    clip_range: float
    ent_coef: float
    max_grad_norm: float
    target_kl: float
    log_std_init: float
    net_arch: tuple[int, ...]
    checkpoint_steps: int
    seed: int
    env: EnvSchema
    amp: AmpSchema

    def build(self) -> TrainParams:
        from sim.learn.train import TrainParams  # torch: imported by the commands that train only

        return TrainParams.from_dict(self.model_dump(exclude={"subjects"}))


class PolicyChecksSchema(Schema):
    free_no_fall_fraction: float
    robot_no_fall_fraction: float
    push_recovered_fraction: float
    max_speed_error_pct: float
    max_stride_error_pct: float
    max_knee_peak_difference_deg: float
    swing_start_pct: float
    spm_alpha: float
    max_spm_cluster_pct: float

    def build(self) -> PolicyChecks:
        return PolicyChecks(**self.model_dump())


class ScenarioChecksSchema(Schema):
    seeds: Annotated[int, Field(ge=1)]
    no_fall_fraction: Annotated[float, Field(ge=0.0, le=1.0)]
    start_tolerance_pct: float
    start_range_s: Pair
    steady_speed_tolerance_pct: float
    stop_within_s: float
    standing_mps: float
    end_standing_s: float
    speed_change_tolerance_pct: float
    speed_change_within_s: float

    def build(self) -> ScenarioChecks:
        return ScenarioChecks(**self.model_dump())


class EvaluatePolicySchema(Schema):
    n_seeds: Annotated[int, Field(ge=1)]
    free_s: float
    robot_s: float
    push_n: float
    push_duration_s: float
    push_time_s: float
    fall_height_fraction: float
    spm_min_real_cycles: int
    push_recovery_s: float
    checks: PolicyChecksSchema
    scenario_checks: ScenarioChecksSchema

    def build(self) -> EvalParams:
        return EvalParams(**self.model_dump(exclude={"checks", "scenario_checks"}))


# scenarios

class ProfileSchema(Schema):
    start_s: Annotated[float, Field(gt=0.0)]
    stop_s: Annotated[float, Field(gt=0.0)]
    speed_change_s: Annotated[float, Field(gt=0.0)]
    turn_rate_deg_s: Annotated[float, Field(gt=0.0)]
    turn_speed_fraction: Annotated[float, Field(gt=0.0)]

    def build(self) -> ProfileParams:
        return ProfileParams(**self.model_dump())


class SegmentSchema(Schema):
    """One scenario segment: exactly one of stand_s, walk_s, walk_m, turn_deg, stop."""

    stand_s: Annotated[float, Field(ge=0.0)] | None = None
    walk_s: Annotated[float, Field(gt=0.0)] | None = None
    walk_m: Annotated[float, Field(gt=0.0)] | None = None
    speed: Annotated[float, Field(gt=0.0)] = 1.0
    turn_deg: float | None = None
    stop: bool = False

    @model_validator(mode="after")
    def _one_kind(self) -> SegmentSchema:
        try:
            Segment(**self.model_dump()).kind  # noqa: B018 (the library's own check)
        except SimulationError as exc:
            raise ValueError(str(exc)) from None
        return self


SCENARIO_NAMES = ("walk_10m", "speed_change", "turn_90", "turnaround_180", "steady")


class PaperSamplingSchema(Schema):
    scenario: str
    walks: Annotated[int, Field(ge=1)]
    cycles_per_walk: Annotated[int, Field(ge=1)]


class ScenariosSchema(Schema):
    paper: PaperSamplingSchema
    seeds: Annotated[int, Field(ge=1)]
    phase_tolerance_s: Annotated[float, Field(ge=0.0)]
    profile: ProfileSchema
    commands: dict[str, list[SegmentSchema]]

    @model_validator(mode="after")
    def _named(self) -> ScenariosSchema:
        missing = [n for n in SCENARIO_NAMES if n not in self.commands]
        if missing:
            raise ValueError(f"missing scenario(s) {', '.join(missing)} (every subject walks "
                             f"{', '.join(SCENARIO_NAMES)})")
        if self.paper.scenario not in self.commands:
            raise ValueError(f"paper.scenario: no scenario {self.paper.scenario!r} in commands")
        return self

    def walks(self, name: str) -> int:
        """Walks per condition of scenario `name` in `dvc repro`."""
        return self.paper.walks if name == self.paper.scenario else self.seeds

    def build(self) -> dict[str, list[Segment]]:
        """Scenario name -> its segments."""
        return {name: [Segment(**s.model_dump()) for s in segments]
                for name, segments in self.commands.items()}


# sweeps and tuning (Ray)

NO_EVENT = "none"  # a study's normal walking (no balance-loss event)


class RaySchema(Schema):
    num_cpus: Annotated[int, Field(ge=1)]
    max_retries: Annotated[int, Field(ge=0)]


class SweepSchema(Schema):
    study: Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9_-]*$")]
    subjects: tuple[str, ...]
    variants: tuple[str, ...]
    conditions: tuple[str, ...]
    scenarios: tuple[str, ...]
    seeds: Annotated[int, Field(ge=1)]
    events: tuple[str, ...] = (NO_EVENT,)   # balance-loss events (fall_intervention.balance_loss) or none
    onset_jitter_s: Annotated[float, Field(ge=0.0)] = 0.3


class BalanceLossSchema(Schema):
    duration_s: Annotated[float, Field(gt=0.0)]
    magnitude: float


class FallInterventionSchema(SweepSchema):
    balance_loss: dict[Literal["trip", "slip", "collapse", "push"], BalanceLossSchema]
    detection_window_s: Annotated[float, Field(gt=0.0)]
    confirm_s: Annotated[float, Field(gt=0.0)]
    baseline_s: Annotated[float, Field(gt=0.0)]
    caught_margin_m: Annotated[float, Field(ge=0.0)]

    def events_of(self, names: tuple[str, ...]) -> list[BalanceLoss | None]:
        """The named events as `BalanceLoss` (no onset: placed per walk), `none` as None."""
        return [None if n == NO_EVENT else BalanceLoss(n, **self.balance_loss[n].model_dump()) for n in names]

    def rule(self, fall_drop_m: float) -> FallRuleParams:
        """The rule given the robot's fall-detection drop threshold (`robot.fall.drop_m`)."""
        return FallRuleParams(self.detection_window_s, self.confirm_s, self.baseline_s,
                              fall_drop_m + self.caught_margin_m)


class SensitivitySchema(SweepSchema):
    """The responsiveness study (`sim.robot.responsiveness`): each factor's levels, one factor at a time
    around the twin's point (the others at the twin's values)."""

    pid_gain_scale: tuple[Annotated[float, Field(gt=0.0)], ...]
    drive_tau_s: tuple[Annotated[float, Field(gt=0.0)], ...]
    latency_s: tuple[Annotated[float, Field(ge=0.0)], ...]

    def levels(self) -> dict[str, tuple[float, ...]]:
        """factor -> its levels (`sim.robot.responsiveness.FACTORS`)."""
        return {"pid_gain_scale": self.pid_gain_scale, "drive_tau_s": self.drive_tau_s,
                "latency_s": self.latency_s}


class VariantSchema(Schema):
    torque_scale: dict[str, Annotated[float, Field(gt=0.0)]] = {}
    speed_scale: Annotated[float, Field(gt=0.0)] = 1.0
    speed_mps: Annotated[float, Field(gt=0.0)] | None = None
    action_noise: Annotated[float, Field(ge=0.0)] = 0.0
    train_action_noise: Annotated[float, Field(ge=0.0)] | None = None  # fine-tuning's (else action_noise)
    swing_time_ratio: Annotated[dict[Literal["left", "right"], Annotated[float, Field(ge=1.0, le=2.0)]],
                                Field(max_length=1)] = {}  # one side: its swing / the other's
    fine_tune_steps: Annotated[int, Field(ge=1)] | None = None  # this variant's budget (cohort's unless set)


class CohortSchema(Schema):
    subjects: tuple[str, ...]
    fine_tune_steps: Annotated[int, Field(ge=1)]
    curriculum_fraction: Annotated[float, Field(ge=0.0, le=1.0)]
    variants: dict[Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9_]*$")], VariantSchema]

    @model_validator(mode="after")
    def _not_healthy(self) -> CohortSchema:
        if HEALTHY in self.variants:
            raise ValueError(f"variants: {HEALTHY!r} is the subject's own policy, not a variant to declare")
        return self


class TuneSchema(Schema):
    method: Literal["tpe", "cmaes"]
    n_trials: Annotated[int, Field(ge=2)]
    seed: int
    scenarios: tuple[str, ...]
    seeds: tuple[int, ...]
    heldout_seeds: tuple[int, ...]
    force_weight_m_per_n: Annotated[float, Field(ge=0.0)]
    gait_weight_m: Annotated[float, Field(ge=0.0)]
    fall_penalty_m: Annotated[float, Field(ge=0.0)]
    search: dict[str, dict[str, tuple[float, float]]]

    @model_validator(mode="after")
    def _disjoint(self) -> TuneSchema:
        if set(self.seeds) & set(self.heldout_seeds):
            raise ValueError("heldout_seeds must differ from seeds (held-back evaluation)")
        for name, space in self.search.items():
            for gain, (lo, hi) in space.items():
                if not lo < hi:
                    raise ValueError(f"search.{name}.{gain}: low {lo} must be below high {hi}")
        return self

    def weights(self) -> ObjectiveWeights:
        return ObjectiveWeights(self.force_weight_m_per_n, self.gait_weight_m, self.fall_penalty_m)


# transfer: a policy for a subject without a committed one (the subjects `transfer.subjects` lists)

class FeatureWeightsSchema(Schema):
    height: Annotated[float, Field(ge=0.0)]
    mass: Annotated[float, Field(ge=0.0)]
    leg_length: Annotated[float, Field(ge=0.0)]
    speed: Annotated[float, Field(ge=0.0)]

    @model_validator(mode="after")
    def _some(self) -> FeatureWeightsSchema:
        if not any(v > 0 for _, v in self):
            raise ValueError("at least one weight must be positive")
        return self

    def build(self) -> FeatureWeights:
        return FeatureWeights(**self.model_dump())


class TransferBenchSchema(Schema):
    subject: str
    max_wall_s: Annotated[float, Field(gt=0.0)]


class TransferSchema(Schema):
    """`transfer@<subject>` (pipeline/stages/transfer.py): fine-tune the nearest committed policy."""

    subjects: tuple[str, ...]   # every subject of `subjects` without a committed policy (train.subjects)
    steps: Annotated[int, Field(ge=1)]
    chunk_steps: Annotated[int, Field(ge=1)]
    max_wall_s: Annotated[float, Field(gt=0.0)]
    gate_seeds: Annotated[int, Field(ge=1)]
    gate: Literal["source", "all"]
    weights: FeatureWeightsSchema
    bench: TransferBenchSchema


class Params(Schema):
    """The whole params.yaml."""

    subjects: tuple[str, ...]
    ingest: IngestSchema
    metrics: MetricsSchema
    quality: QualitySchema
    store: StoreSchema
    report: ReportSchema
    retarget: RetargetSchema
    robot: RobotSchema
    rollout: RolloutSchema
    human: HumanSchema
    train: TrainSchema
    evaluate_policy: EvaluatePolicySchema
    scenarios: ScenariosSchema
    ray: RaySchema
    sweep: SweepSchema
    tune: TuneSchema
    cohort: CohortSchema
    fall_intervention: FallInterventionSchema
    sensitivity: SensitivitySchema
    transfer: TransferSchema
    universal: dict[str, Any]  # the schema is `sim.learn.pool.UniversalParams` (`_universal_keys`)

    _path: Path = PrivateAttr(default=PARAMS_FILE)

    @field_validator("universal")
    @classmethod
    def _universal_keys(cls, v: dict[str, Any]) -> dict[str, Any]:
        try:
            UniversalParams.from_dict(v)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(str(exc.args[0]).removeprefix("universal: ")) from None
        return v

    @model_validator(mode="after")
    def _controllers_exist(self) -> Params:
        controllers = self.robot.controllers
        for name in self.robot.tuning.initial:
            if name not in controllers:
                raise ValueError(f"robot.tuning.initial.{name}: no controller {name!r} in robot.controllers")
        for key, conditions in (("rollout.conditions", self.rollout.conditions),
                                ("sweep.conditions", self.sweep.conditions)):
            for cond in conditions:
                if cond != "free" and cond not in controllers:
                    raise ValueError(f"{key}: {cond!r} is neither free nor a controller in robot.controllers")
        for key, study in (("sweep", self.sweep), ("fall_intervention", self.fall_intervention),
                           ("sensitivity", self.sensitivity)):
            for variant in study.variants:
                if variant != HEALTHY and variant not in self.cohort.variants:
                    raise ValueError(f"{key}.variants: no variant {variant!r} in cohort.variants")
            for event in study.events:
                if event != NO_EVENT and event not in self.fall_intervention.balance_loss:
                    raise ValueError(f"{key}.events: no event {event!r} in fall_intervention.balance_loss")
            for cond in study.conditions:
                if cond != "free" and cond not in controllers:
                    raise ValueError(f"{key}.conditions: {cond!r} is neither free nor a controller")
            for name in study.scenarios:
                if name not in self.scenarios.commands:
                    raise ValueError(f"{key}.scenarios: no scenario {name!r} in scenarios.commands")
        if self.sweep.study == self.fall_intervention.study:
            raise ValueError("sweep.study and fall_intervention.study must differ")
        if self.sensitivity.study in (self.sweep.study, self.fall_intervention.study):
            raise ValueError("sensitivity.study must differ from sweep.study and fall_intervention.study")
        if "free" in self.sensitivity.conditions:
            raise ValueError("sensitivity.conditions: 'free' has no robot to make responsive")
        for name in self.tune.search:
            if name not in controllers:
                raise ValueError(f"tune.search.{name}: no controller {name!r} in robot.controllers")
        for name in self.transfer.subjects:
            if name in self.train.subjects:
                raise ValueError(f"transfer.subjects: {name!r} has a committed policy (train.subjects)")
        scenario_lists = (("sweep.scenarios", self.sweep.scenarios), ("tune.scenarios", self.tune.scenarios))
        for key, names in scenario_lists:
            for name in names:
                if name not in self.scenarios.commands:
                    raise ValueError(f"{key}: no scenario {name!r} in scenarios.commands")
        return self

    @property
    def path(self) -> Path:
        """The file these params were read from."""
        return self._path

    def train_params(self, variant: str = HEALTHY) -> TrainParams:
        """`train` with the scenarios' transition timing in its env (training commands and the
        evaluated scenarios share one profile) and the body and goals of cohort `variant`."""
        from dataclasses import replace

        p = self.train.build()
        h = self.robot.harness
        twist = replace(p.env.harness_twist, stiffness_nm_per_rad=h.stiffness[5],
                        damping_nms_per_rad=h.damping[5], range_rad=h.range[5])
        return replace(p, env=replace(p.env, profile=self.scenarios.profile.build(),
                                      variant=self.variant(variant), harness_twist=twist))

    def report_params(self) -> ReportParams:
        """`report`, with the fall-intervention caught threshold and detection window
        (`FallInterventionSchema.rule`) and the paper's scenario (`scenarios.paper`)."""
        from dataclasses import replace

        rule = self.fall_intervention.rule(self.robot.fall.drop_m)
        return replace(self.report.build(), caught_drop_m=rule.caught_drop_m,
                       detection_window_s=rule.detection_window_s,
                       paper_scenario=self.scenarios.paper.scenario)

    def variant(self, name: str) -> Variant:
        """Cohort variant `name` (`healthy`: nothing changed); `ParamsError` lists the declared ones."""
        if name == HEALTHY:
            return Variant()
        if name not in self.cohort.variants:
            raise ParamsError(self.path, f"cohort.variants: no variant {name!r} "
                                         f"({', '.join([HEALTHY, *self.cohort.variants])})")
        return variant_from_dict(name, self.cohort.variants[name].model_dump(exclude={"fine_tune_steps"}))

    def fine_tune_steps(self, variant: str) -> int:
        """Env steps of cohort `variant`'s fine-tuning: its own budget, else `cohort.fine_tune_steps`."""
        self.variant(variant)
        return self.cohort.variants[variant].fine_tune_steps or self.cohort.fine_tune_steps

    def batch_setup(self, subject: str, markerset: dict[str, str], human_xml: str | Path,
                    drivers: DriverSource, process: bool = True) -> BatchSetup:
        """What the rollout batch runner needs for `subject`'s world: robot, controllers, the
        rollout's physics step and start offset, and the ingest params that process its trials."""
        from sim.rollout.batch import BatchSetup

        r = self.rollout
        return BatchSetup(str(human_xml), subject, dict(markerset), self.robot.build(),
                          self.robot.controller_specs(), self.ingest.build(), r.max_physics_dt_s,
                          r.start_offset_m, drivers, process, r.stop_after_fall_s)

    def document(self) -> dict[str, Any]:
        """The params as the YAML document they came from: plain JSON types, keys as in params.yaml,
        optional keys the file leaves out left out."""
        return self.model_dump(mode="json", by_alias=True, exclude_unset=True)


# -- loading --------------------------------------------------------------------------------------

def load_params(path: str | Path = PARAMS_FILE, tuned: str | Path = TUNED_GAINS) -> Params:
    """Read and validate the params file, the tuned-gains file `tuned` on top of its controllers'
    gains; raises `ParamsError` naming the file (and the key path)."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ParamsError(path, f"cannot read params file ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise ParamsError(path, f"not valid YAML ({exc})") from None
    return parse_params(doc, path, tuned)


def parse_params(doc: Any, path: str | Path = PARAMS_FILE, tuned: str | Path = TUNED_GAINS) -> Params:
    """`Params` from a parsed params document (`path` names it in errors), the tuned-gains file
    `tuned` on top of its controllers' gains (`with_tuned_gains`)."""
    if not isinstance(doc, dict):
        raise ParamsError(path, "expected a mapping of sections (subjects, ingest, ...)")
    try:
        params = Params.model_validate(doc)
    except ValidationError as exc:
        raise ParamsError(path, describe(exc)) from None
    params = with_tuned_gains(params, path, tuned)
    params._path = Path(path)
    return params


def with_tuned_gains(params: Params, path: str | Path, tuned: str | Path) -> Params:
    """`params` whose `robot.controller_specs()` have the tuned-gains file's gains on top of
    `robot.controllers` (`document()` keeps the file's own), every controller's gains and tuning
    starts checked against its class's declaration (`sim.robot.controllers.specs`); a problem raises
    `ParamsError` naming its file and key path."""
    from sim.robot.controllers.specs import TUNED, controller_specs, read_tuned

    try:
        top = read_tuned(tuned)
    except SimulationError as exc:
        raise ParamsError(tuned, exc.problem) from None
    r = params.robot
    specs, problems = controller_specs({n: c.spec() for n, c in r.controllers.items()}, top, r.tuning.initial,
                                       params.tune.search)
    if problems:  # the first file's problems (params.yaml or the tuned-gains file)
        source = problems[0][0]
        said = "; ".join(p for s, p in problems if s == source)
        raise ParamsError(tuned if source == TUNED else path, said)
    r._specs = specs
    return params


def key_path(loc: tuple[int | str, ...]) -> str:
    """`('robot', 'tuning', 'walks', 2, 'speed_mps')` -> `robot.tuning.walks[2].speed_mps`."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _problem(error: dict) -> str:
    loc, kind = tuple(error["loc"]), error["type"]
    where, parent, last = key_path(loc), key_path(loc[:-1]), loc[-1] if loc else None
    if kind == "missing" and isinstance(last, str):
        return f"{parent}: missing key {last!r}" if parent else f"missing section {last!r}"
    if kind == "extra_forbidden":
        return f"{parent}: unknown key {last!r}" if parent else f"unknown section {last!r}"
    if kind == "missing":
        return f"{where}: missing item"
    message = str(error["ctx"]["error"]) if kind == "value_error" else error["msg"]
    value = error.get("input")
    if isinstance(value, str | int | float | bool) or value is None:
        message += f" (got {value!r})"
    return f"{where}: {message}" if where else message


def describe(exc: ValidationError) -> str:
    """The problems of a failed validation, one `key.path: problem` each, `; `-separated."""
    problems = [_problem(e) for e in exc.errors(include_url=False)]
    more = len(problems) - MAX_REPORTED_ERRORS
    return "; ".join(problems[:MAX_REPORTED_ERRORS]) + (f"; and {more} more" if more > 0 else "")
