"""params.yaml: read once per command, each section validated by the library class that uses it.

Every section of params.yaml is defined once, beside the code that reads it: a dataclass or pydantic
model with its defaults and units (`SECTIONS` names it, "module:Class"); a key left out of the file
takes the class's default. `load_params` checks that every top-level section is known and present and
runs the checks that span sections (a condition names a controller of `robot.controllers`, ...); a
stage then validates only the sections it reads, passing their class: `params.section("metrics",
MetricsParams)`. So a stage imports only the code it uses (dvc.yaml's deps follow its imports) and an
unknown key or a wrong type still fails when the section is loaded. `check_params` validates the whole
file against every class of `SECTIONS`, then runs `CHECKS` (`python -m pipeline check-params`, `make run`,
the tests); it imports them by name, at run time, and is meant for commands outside dvc.yaml.

Problems raise `ParamsError` naming the file and the key path, e.g.
`params.yaml: robot.base.mass_kg: Input should be a valid number`.
"""

from __future__ import annotations

import copy
import importlib
from functools import cache
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import TypeAdapter, ValidationError

from ingest.errors import GaitloopError
from pipeline.paths import PARAMS_FILE, TUNED_GAINS

__all__ = ["PARAMS_FILE", "SECTIONS", "CheckedParams", "Params", "ParamsError", "check_params", "checked",
           "load_params", "parse_params"]

MAX_REPORTED_ERRORS = 5
HEALTHY = "healthy"  # a subject's own policy: no cohort variant (`sim.body.variant.HEALTHY`)
NO_EVENT = "none"  # a study's normal walking, no balance-loss event (the studies' `events`)
T = TypeVar("T")

# section -> the class that validates it ("module:Class", imported by `check_params` only)
SECTIONS = {
    "subjects": "pipeline.params:Subjects",
    "ingest": "ingest.process:IngestParams",
    "metrics": "metrics.section:MetricsParams",
    "quality": "metrics.quality:QualityParams",
    "store": "pipeline.store.connection:StoreParams",
    "report": "pipeline.runs.report_params:ReportParams",
    "retarget": "sim.motion.reference:ReferenceParams",
    "robot": "sim.robot.section:RobotSection",
    "rollout": "sim.rollout.section:RolloutSection",
    "human": "sim.body.human_params:HumanParams",
    "train": "sim.learn.train:TrainParams",
    "evaluate_policy": "pipeline.runs.evaluation:EvalParams",
    "scenarios": "sim.rollout.scenarios:ScenariosSection",
    "ray": "pipeline.runs.studies:RaySection",
    "sweep": "pipeline.runs.studies:SweepSection",
    "tune": "pipeline.runs.studies:TuneSection",
    "cohort": "sim.body.variant:CohortSection",
    "fall_intervention": "pipeline.runs.studies:FallInterventionSection",
    "sensitivity": "pipeline.runs.studies:SensitivitySection",
    "universal": "sim.learn.pool:UniversalParams",
    "transfer": "sim.learn.transfer:TransferSection",
}
CHECKS = ("pipeline.runs.setup:check_controllers",)  # "module:function"s `checked` runs on valid sections
Subjects = tuple[str, ...]
# values other sections set (pipeline/runs/setup.py, pipeline.runs.studies.report_params), never the file
DERIVED = {
    "report.caught_drop_m": "robot.fall.drop_m + fall_intervention.caught_margin_m",
    "report.detection_window_s": "fall_intervention.detection_window_s",
    "report.paper_scenario": "scenarios.paper.scenario",
    "train.env.profile": "scenarios.profile",
    "train.env.variant": "cohort.variants and the command's --variant",
    "train.env.harness_twist.stiffness_nm_per_rad": "robot.harness.stiffness[5]",
    "train.env.harness_twist.damping_nms_per_rad": "robot.harness.damping[5]",
    "train.env.harness_twist.range_rad": "robot.harness.range[5]",
}


class ParamsError(GaitloopError):
    """A params file that is missing, not YAML, or does not match the schema."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class Params:
    """params.yaml as read (and `tuned_file`, its controllers' tuned gains), each section validated on use."""

    def __init__(self, doc: dict[str, Any], path: str | Path = PARAMS_FILE, tuned: str | Path = TUNED_GAINS):
        self._doc, self._path, self.tuned_file, self._sections = doc, Path(path), Path(tuned), {}

    @property
    def path(self) -> Path:
        """The file these params were read from."""
        return self._path

    @property
    def subjects(self) -> tuple[str, ...]:
        """`subjects`: every subject the pipeline runs (data/subjects/<id>.yaml)."""
        return self.section("subjects", Subjects)

    def section(self, name: str, cls: type[T] | Any) -> T:
        """Section `name` (dotted for a part: `robot.fall`) validated as `cls`; `ParamsError` names
        the file and the key path of each problem."""
        key = (name, cls)
        if key not in self._sections:
            value: Any = self._doc
            for part in name.split("."):
                value = value.get(part) if isinstance(value, dict) else None
            try:
                self._sections[key] = _adapter(cls).validate_python(value)
            except ValidationError as exc:
                raise ParamsError(self._path, describe(exc, tuple(name.split(".")))) from None
        return self._sections[key]

    def replaced(self, name: str, cls: Any, value: Any) -> Params:
        """These params with section `name` (as `cls`) taken to be `value` (an override of the file)."""
        out = copy.copy(self)
        out._sections = {**self._sections, (name, cls): value}
        return out

    def fail(self, problem: str) -> ParamsError:
        """A `ParamsError` about these params (`raise params.fail(...)`)."""
        return ParamsError(self._path, problem)

    def document(self) -> dict[str, Any]:
        """The params as the YAML document they came from (a copy)."""
        return copy.deepcopy(self._doc)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Params) and (self._doc, self._path, self.tuned_file) == (
            other._doc, other._path, other.tuned_file)

    def __hash__(self) -> int:
        return hash(self._path)


class CheckedParams(Params):
    """Params whose every section has been validated (`check_params`): each section is also an
    attribute (`params.robot`), for commands that read many sections and no dvc stage."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_") or name not in SECTIONS:
            raise AttributeError(name)
        return self.section(name, section_class(name))

    def variant(self, name: str) -> Any:
        """Cohort variant `name` (`healthy`: nothing changed); `ParamsError` lists the declared ones."""
        try:
            return self.cohort.variant(name)
        except ValueError as exc:
            raise self.fail(str(exc)) from None


@cache
def _adapter(cls: Any) -> TypeAdapter:
    return TypeAdapter(cls)


def section_class(name: str, spec: str = "") -> Any:
    """The class of section `name` from `SECTIONS` (or what `spec`, "module:name", names), imported."""
    module, _, attr = (spec or SECTIONS[name]).partition(":")
    return getattr(importlib.import_module(module), attr)


# -- loading --------------------------------------------------------------------------------------

def load_params(path: str | Path = PARAMS_FILE, tuned: str | Path = TUNED_GAINS) -> Params:
    """Read the params file and check its sections' names and cross-references; raises `ParamsError`
    naming the file (and the key path). `tuned`: the tuned-gains file, read where the gains are."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ParamsError(path, f"cannot read params file ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise ParamsError(path, f"not valid YAML ({exc})") from None
    return parse_params(doc, path, tuned)


def parse_params(doc: Any, path: str | Path = PARAMS_FILE, tuned: str | Path = TUNED_GAINS) -> Params:
    """`Params` from a parsed params document (`path` names it in errors)."""
    if not isinstance(doc, dict):
        raise ParamsError(path, "expected a mapping of sections (subjects, ingest, ...)")
    problems = [f"unknown section {k!r}" for k in doc if k not in SECTIONS]
    problems += [f"missing section {k!r}" for k in SECTIONS if k not in doc]
    problems += cross_section_problems(doc)
    if problems:
        raise ParamsError(path, _joined(problems))
    return Params(doc, path, tuned)


def check_params(path: str | Path = PARAMS_FILE, tuned: str | Path = TUNED_GAINS) -> CheckedParams:
    """Load the params file and validate every section against its class (`SECTIONS`), then `CHECKS`;
    all the problems of the sections in one `ParamsError`."""
    return checked(load_params(path, tuned))


def checked(params: Params) -> CheckedParams:
    """`params` with every section validated against its class (`SECTIONS`), then `CHECKS` run."""
    out = CheckedParams(params.document(), params.path, params.tuned_file)
    out._sections = dict(params._sections)
    problems = []
    for name in SECTIONS:
        try:
            out.section(name, section_class(name))
        except ParamsError as exc:
            problems.append(exc.problem)
    if problems:
        raise ParamsError(out.path, _joined(problems))
    for check in CHECKS:
        section_class("", check)(out)
    return out


def _names(doc: dict, *keys: str) -> list:
    """The keys (of a mapping) or items (of a list) at `keys` in `doc`; none where it is not there."""
    for key in keys:
        doc = doc.get(key) if isinstance(doc, dict) else None
    return list(doc) if isinstance(doc, dict | list | tuple) else []


def cross_section_problems(doc: dict) -> list[str]:
    """What one section says of another that is not there (a scenario, controller, variant or
    event named but not declared), and the studies that must differ."""
    out = [f"{key}: set from {source}, not in the file" for key, source in DERIVED.items()
            if key.rpartition(".")[2] in _names(doc, *key.rpartition(".")[0].split("."))]
    controllers, scenarios = _names(doc, "robot", "controllers"), _names(doc, "scenarios", "commands")
    events = _names(doc, "fall_intervention", "balance_loss")
    for where in (("robot", "tuning", "initial"), ("tune", "search")):
        out += [f"{'.'.join(where)}.{name}: no controller {name!r} in robot.controllers"
                for name in _names(doc, *where) if name not in controllers]
    out += [f"rollout.conditions: {cond!r} is neither free nor a controller in robot.controllers"
            for cond in _names(doc, "rollout", "conditions") if cond != "free" and cond not in controllers]
    studies = {key: doc.get(key) if isinstance(doc.get(key), dict) else {}
               for key in ("sweep", "fall_intervention", "sensitivity")}
    for key, study in studies.items():
        for variant in _names(study, "variants"):
            if variant != HEALTHY and variant not in _names(doc, "cohort", "variants"):
                out.append(f"{key}.variants: no variant {variant!r} in cohort.variants")
        for event in _names(study, "events"):
            if event != NO_EVENT and event not in events:
                out.append(f"{key}.events: no event {event!r} in fall_intervention.balance_loss")
        for cond in _names(study, "conditions"):
            if cond != "free" and cond not in controllers:
                out.append(f"{key}.conditions: {cond!r} is neither free nor a controller")
        for name in _names(study, "scenarios"):
            if name not in scenarios:
                out.append(f"{key}.scenarios: no scenario {name!r} in scenarios.commands")
    sweep, fall, sens = (studies[k].get("study") for k in studies)
    if sweep is not None and sweep == fall:
        out.append("sweep.study and fall_intervention.study must differ")
    if sens is not None and sens in (sweep, fall):
        out.append("sensitivity.study must differ from sweep.study and fall_intervention.study")
    if "free" in _names(studies["sensitivity"], "conditions"):
        out.append("sensitivity.conditions: 'free' has no robot to make responsive")
    trained, transferred = _names(doc, "train", "subjects"), _names(doc, "transfer", "subjects")
    out += [f"transfer.subjects: {name!r} has a committed policy (train.subjects)"
            for name in transferred if name in trained]
    out += [f"transfer.adopted: {name!r} is also in {'train' if name in trained else 'transfer'}.subjects"
            for name in _names(doc, "transfer", "adopted") if name in trained or name in transferred]
    out += [f"tune.scenarios: no scenario {name!r} in scenarios.commands"
            for name in _names(doc, "tune", "scenarios") if name not in scenarios]
    return out


# -- error messages -------------------------------------------------------------------------------

def key_path(loc: tuple[int | str, ...]) -> str:
    """`('robot', 'tuning', 'walks', 2, 'speed_mps')` -> `robot.tuning.walks[2].speed_mps`."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _problem(error: dict, prefix: tuple[str, ...] = ()) -> str:
    loc, kind = (*prefix, *error["loc"]), error["type"]
    where, parent, last = key_path(loc), key_path(loc[:-1]), loc[-1] if loc else None
    if kind == "missing" and isinstance(last, str) and len(loc) > len(prefix):
        return f"{parent}: missing key {last!r}" if parent else f"missing section {last!r}"
    if kind in ("extra_forbidden", "unexpected_keyword_argument"):
        return f"{parent}: unknown key {last!r}" if parent else f"unknown section {last!r}"
    if kind == "missing":
        return f"{where}: missing item"
    message = str(error["ctx"]["error"]) if kind == "value_error" else error["msg"]
    value = error.get("input")
    if isinstance(value, str | int | float | bool) or value is None:
        message += f" (got {value!r})"
    return f"{where}: {message}" if where else message


def _joined(problems: list[str]) -> str:
    more = len(problems) - MAX_REPORTED_ERRORS
    return "; ".join(problems[:MAX_REPORTED_ERRORS]) + (f"; and {more} more" if more > 0 else "")


def describe(exc: ValidationError, prefix: tuple[str, ...] = ()) -> str:
    """The problems of a failed validation, one `key.path: problem` each (under the section path
    `prefix`), `; `-separated."""
    return _joined([_problem(e, prefix) for e in exc.errors(include_url=False)])
