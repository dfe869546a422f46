"""`ReportParams`: the `report` section of params.yaml, with the numbers the report takes from other
sections (`pipeline.runs.studies.report_params` sets them: the fall-intervention rule's caught threshold
and detection window, the paper's scenario)."""

from __future__ import annotations

from dataclasses import dataclass, field

from pydantic import with_config


@with_config(extra="forbid")
@dataclass(frozen=True)
class ReportParams:
    """The `report` section of params.yaml; the last three come from other sections
    (`studies.report_params`), never from the file."""

    dpi: int = 110  # PNG resolution of the report figures
    # event -> the scenario its column of the phase-aligned figure is drawn from (the paper's protocol)
    event_scenarios: dict[str, str] = field(default_factory=lambda: {"start": "walk_10m", "turn": "turn_90",
                                                                     "stop": "walk_10m"})
    caught_drop_m: float = 0.22  # fall intervention: robot.fall.drop_m + fall_intervention.caught_margin_m
    detection_window_s: float = 1.5  # fall intervention: a lock this soon after the onset detects it
    paper_scenario: str = "walk_10m"  # the scenario the paper tables and findings come from (scenarios.paper)
