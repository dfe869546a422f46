"""Shared fixtures: params.yaml as the typed `CheckedParams`, committed folders the tests read, and stage
outputs built by the stages themselves in a temporary root, so tests never depend on what
`dvc repro` left in data/processed (a fresh clone has nothing there).

This harness may import `pipeline`; the tests of the library packages (tests/ingest, tests/sim,
tests/metrics) take what they need from these fixtures instead (tests/test_architecture.py)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def params():
    """params.yaml with every section checked (`pipeline.params.CheckedParams`): each section is an
    attribute holding its library object (`params.ingest` is `ingest.process.IngestParams`)."""
    from pipeline.params import check_params

    return check_params()


@pytest.fixture(scope="session")
def controller_specs(params):
    """`pipeline.runs.setup.controller_specs` of params.yaml: name -> {class, gains}, params
    `robot.controllers` with the tuned-gains file (data/tuning/controllers.yaml) on top, what a run's
    controllers get."""
    from pipeline.runs.setup import controller_specs as merged

    return merged(params)


@pytest.fixture(scope="session")
def train_params(params):
    """`pipeline.runs.setup.train_params` of params.yaml: the training recipe with the scenarios'
    timing and a cohort variant's body (`train_params("weak")`)."""
    from pipeline.runs.setup import train_params as build

    return lambda variant="healthy": build(params, variant)


@pytest.fixture(scope="session")
def ingest_params(params):
    """The `ingest` section (`ingest.process.IngestParams`): what processes a trial."""
    return params.ingest


@pytest.fixture(scope="session")
def policies_root() -> Path:
    """The committed policies folder (data/policies): one subfolder per trained subject."""
    from pipeline.paths import POLICIES_ROOT

    return POLICIES_ROOT


@pytest.fixture(scope="session")
def camargo_model(tmp_path_factory, params) -> Path:
    """Folder with camargo's scaled `human.xml` and `reference.npz` (its real tables beside it in
    `../real/`), as `dvc repro ingest@camargo scale@camargo reference@camargo` makes them."""
    from pipeline.stages.ingest import run_ingest
    from pipeline.stages.reference import run_reference
    from pipeline.stages.scale import run_scale

    root, reports = tmp_path_factory.mktemp("processed"), tmp_path_factory.mktemp("reports")
    run_ingest("camargo", params, root, progress=False)
    run_scale("camargo", params, root, reports)
    run_reference("camargo", params, root, reports, progress=False)
    return root / "camargo" / "model"
