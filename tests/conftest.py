"""Shared fixtures: params.yaml as the typed `Params`, committed folders the tests read, and stage
outputs built by the stages themselves in a temporary root, so tests never depend on what
`dvc repro` left in data/processed (a fresh clone has nothing there).

This harness may import `pipeline`; the tests of the library packages (tests/ingest, tests/sim,
tests/metrics) take what they need from these fixtures instead (tests/test_architecture.py)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def params():
    """params.yaml, loaded and checked (`pipeline.params.Params`); sections build the library's
    parameter objects (`params.robot.build()`, `params.ingest.build()`, ...)."""
    from pipeline.params import load_params

    return load_params()


@pytest.fixture(scope="session")
def ingest_params(params):
    """The `ingest` section built (`ingest.process.IngestParams`): what processes a trial."""
    return params.ingest.build()


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
