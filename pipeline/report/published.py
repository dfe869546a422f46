"""The published values the reports print beside this project's numbers: the reference paper's
Tables I-III (`data/paper/wang2025.yaml`, `load_paper`) and the clinical ranges the virtual cohort
is read against (`data/paper/clinical_ranges.yaml`, `load_clinical_ranges`), each file checked
against its schema on reading."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, Field, RootModel, ValidationError, model_validator

from ingest.errors import GaitloopError
from metrics.findings import Pair
from pipeline.paths import PAPER_FILE

# -- the reference paper's published values (data/paper/wang2025.yaml) --------------------------------
# Wang, Chan et al., ICRA 2025 (arXiv:2503.05825), Tables I-III, for their own participant: printed
# beside each subject's Real and Sim columns for orientation (the file cites its source). Keys mirror
# the tables: condition -> `real` (their recorded trials) or `sim` (their simulation) -> values.

Source = Literal["real", "sim"]

# The paper's two controllers: its finding is its speed-adaptive controller below its PID baseline. The
# reports name them here, once; metrics/ takes them as data (`metrics.findings.Pair`, the plots' `order`).
PAPER_PAIR = Pair("adaptive", "pid")
CONTROLLER_ORDER = (PAPER_PAIR.b, PAPER_PAIR.a)  # tables and figures: the baseline first; others after


class PaperError(GaitloopError):
    """A file of published values (the paper's, the clinical ranges) is missing, not YAML, or not in
    the expected layout."""

    def __init__(self, path: str | Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PaperCompliance(_Strict):
    """Table I: mean |e_x| and |e_y| (cm); no SD published."""

    mean_abs_ex_cm: float
    mean_abs_ey_cm: float


class PaperGait(_Strict):
    """Table II: (mean, SD) of stride length (m) and gait speed (m/s)."""

    stride_length_m: tuple[float, float]
    gait_speed_mps: tuple[float, float]


class PaperValues(_Strict):
    """The whole file: citation, the paper's participant, and the three tables by condition."""

    citation: str
    participant: str
    table1: dict[str, dict[Source, PaperCompliance]]
    table2: dict[str, dict[Source, PaperGait]]
    table3: dict[str, dict[Source, dict[str, float]]]  # inter-cycle SD (deg) per joint

    def note(self) -> str:
        """The sentence that goes under the tables that show these values."""
        return (f"Paper columns: the values published by {self.citation}, for their own participant: "
                f"{self.participant}. Paper real = their recorded trials, paper sim = their simulation. "
                "They describe another person and robot: shown for orientation only, not as targets.")


M = TypeVar("M", bound=BaseModel)


def _published(path: Path, model: type[M], what: str) -> M:
    """Read a YAML file of published values and check it against `model`; `PaperError` names the
    file and the problem."""
    try:
        return model.model_validate(yaml.safe_load(Path(path).read_text()))
    except OSError as exc:
        raise PaperError(path, f"cannot read the {what} ({exc.strerror})") from None
    except yaml.YAMLError as exc:
        raise PaperError(path, f"not YAML ({exc})") from None
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(k) for k in first["loc"])
        raise PaperError(path, f"{where}: {first['msg']}") from None


def load_paper(path: Path = PAPER_FILE) -> PaperValues:
    """Read and check the paper values file; `PaperError` names the file and the problem."""
    return _published(path, PaperValues, "paper values")


# -- published clinical reference values (data/paper/clinical_ranges.yaml) ---------------------------
# Printed beside the virtual cohort's gait so a reader can place each variant: the stroke walking
# categories, healthy adults' comfortable speed, the symmetry ratios counted as asymmetric and the
# stride-time variability of healthy young adults, each with its citation.

CLINICAL_FILE = PAPER_FILE.parent / "clinical_ranges.yaml"
# measure key (unit in the name) -> how the report names it
CLINICAL_MEASURES = {"speed_mps": "gait speed (m/s)",
                     "stance_ratio": "stance time ratio, larger / smaller side",
                     "swing_ratio": "swing time ratio, larger / smaller side",
                     "step_length_ratio": "step length ratio, larger / smaller side",
                     "stride_time_cv_pct": "stride time CV (%)"}
Bound = float | None


class ClinicalRange(_Strict):
    """One published reference: exactly one measure, as [low, high] (None: an open end) or a single
    published value, what it describes (`meaning`) and where it was published (`source`)."""

    speed_mps: tuple[Bound, Bound] | float | None = None
    stance_ratio: tuple[Bound, Bound] | float | None = None
    swing_ratio: tuple[Bound, Bound] | float | None = None
    step_length_ratio: tuple[Bound, Bound] | float | None = None
    stride_time_cv_pct: tuple[Bound, Bound] | float | None = None
    meaning: Annotated[str, Field(min_length=1)]
    source: Annotated[str, Field(min_length=1)]

    @model_validator(mode="after")
    def _one_measure(self) -> ClinicalRange:
        given = [m for m in CLINICAL_MEASURES if getattr(self, m) is not None]
        if len(given) != 1:
            raise ValueError(f"needs exactly one measure of {list(CLINICAL_MEASURES)}, got {given}")
        value = getattr(self, given[0])
        low, high = value if isinstance(value, tuple) else (value, value)
        if (low is None and high is None) or (None not in (low, high) and low > high):
            raise ValueError(f"{given[0]}: [low, high] needs low <= high and one end at least, "
                             f"got {list(value)}")
        return self

    @property
    def measure(self) -> str:
        return next(m for m in CLINICAL_MEASURES if getattr(self, m) is not None)

    def value_text(self) -> str:
        """The value as printed: "0.4–0.8", "< 0.4", "> 0.8" or the single value."""
        value = getattr(self, self.measure)
        if not isinstance(value, tuple):
            return f"{value:g}"
        low, high = value
        return f"< {high:g}" if low is None else f"> {low:g}" if high is None else f"{low:g}–{high:g}"


class ClinicalRanges(RootModel[dict[str, ClinicalRange]]):
    """The whole file: entry name -> `ClinicalRange`."""


def load_clinical_ranges(path: Path = CLINICAL_FILE) -> dict[str, ClinicalRange]:
    """Read and check the clinical ranges file; `PaperError` names the file and the problem."""
    return _published(path, ClinicalRanges, "clinical ranges").root


def paper_compliance(paper: PaperValues) -> dict[str, tuple[float, float]]:
    """condition -> the paper's simulated (mean |e_x|, mean |e_y|) in cm (Table I)."""
    return {c: (v["sim"].mean_abs_ex_cm, v["sim"].mean_abs_ey_cm)
            for c, v in paper.table1.items() if "sim" in v}
