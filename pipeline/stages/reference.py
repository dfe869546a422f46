"""Stage `reference <subject>`: the subject's real walking retargeted onto the scaled human.

Inputs: `<root>/<subject>/model/human.xml` (the `scale` stage) and the subject's processed trials and
tables in `<root>/<subject>/real/` (the `ingest` stage: `pipeline.stages.ingest.read_ingested`). Each
trial whose condition is in `retarget.conditions` (gap-filled, filtered and segmented by ingest) is
solved frame by frame by marker IK (`sim.motion.retarget`). Outputs:
`<root>/<subject>/model/reference.npz` (`sim.motion.reference.Reference`), `reference.json` (fit metrics,
`sim.motion.reference.fit_metrics` and `cycle_summary`; a DVC metrics file) and
`reports/<subject>/retarget.png` (`sim.motion.plots.retarget_figure`: hip, knee, ankle of the
retargeted motion against the real `.mot` angles), written all-or-nothing. The stage only gathers
the inputs, calls the library and writes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ingest.process import SubjectTables
from pipeline.params import Params
from pipeline.paths import PROCESSED_ROOT, REPORTS_ROOT, human_xml, model_dir, reference_npz, report_dir
from pipeline.runs.report_params import ReportParams
from pipeline.stages.ingest import read_ingested
from pipeline.stages.outputs import json_text, replacing, write_figure
from sim.errors import SimulationError
from sim.motion.plots import retarget_figure
from sim.motion.reference import (
    Reference,
    ReferenceParams,
    RetargetedTrial,
    cycle_from_trials,
    cycle_summary,
    fit_metrics,
    left_right_shift,
    retarget_trial,
    save_reference,
)


def load_model(path: Path):
    """The scaled human written by the `scale` stage (via the model's own loader)."""
    if not path.exists():
        raise SimulationError(path, "no scaled human model: run `python -m pipeline scale <subject>` first")
    from sim.body.human import load_human_model

    return load_human_model(path)


def retarget_subject(subject_id: str, model, ingested: SubjectTables, section: ReferenceParams,
                     progress: bool = False) -> tuple[Reference, dict, list[RetargetedTrial],
                                                      dict[str, dict[str, np.ndarray]]]:
    """Retarget the subject's processed trials (`ingested.trials`) of the configured conditions;
    returns the reference, the metrics document, the retargeted trials and the real (filtered) angles
    per trial."""
    chosen = [p for p in ingested.trials if p.trial.condition in section.conditions]
    if not chosen:
        raise SimulationError(subject_id, f"no trial with condition in {section.conditions}")
    trials, real, strides = [], {}, []
    for processed in chosen:
        trials.append(retarget_trial(model, processed, section.ik, section, progress=progress))
        real[processed.trial.trial] = processed.trial.angles
        strides.append(processed.strides)
    cycle, used = cycle_from_trials(model, trials, pd.concat(strides, ignore_index=True), section)
    reference = Reference.from_trials(trials, cycle)
    doc = fit_metrics(subject_id, model, trials, real, section.conditions[0])
    doc["cycle"] = cycle_summary(cycle, used) | {"left_right": left_right_shift(model, cycle)}
    return reference, doc, trials, real


def run_reference(subject_id: str, params: Params, root: Path = PROCESSED_ROOT,
                  reports: Path = REPORTS_ROOT, progress: bool = True) -> dict:
    """Retarget a subject and write reference.npz, reference.json and retarget.png; returns the
    metrics document."""
    section = params.section("retarget", ReferenceParams)
    folder = model_dir(root, subject_id)
    model = load_model(human_xml(root, subject_id))
    ingested, dpi = read_ingested(subject_id, root), params.section("report", ReportParams).dpi
    reference, doc, trials, real = retarget_subject(subject_id, model, ingested, section, progress=progress)
    npz, js = reference_npz(root, subject_id), folder / "reference.json"
    png = report_dir(reports, subject_id) / "retarget.png"
    with replacing(npz, js) as (t_npz, t_js):  # a failing figure leaves npz and json as they were
        with open(t_npz, "wb") as fh:
            save_reference(fh, reference)
        t_js.write_text(json_text(doc))
        write_figure(retarget_figure(subject_id, model, trials, real), png, dpi)
    return doc
