"""Shared fixtures: stage outputs built by the stages themselves in a temporary root, so tests never
depend on what `dvc repro` left in data/processed (a fresh clone has nothing there)."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def camargo_model(tmp_path_factory) -> Path:
    """Folder with camargo's scaled `human.xml` and `reference.npz` (its real tables beside it in
    `../real/`), as `dvc repro ingest@camargo scale@camargo reference@camargo` makes them."""
    from pipeline.params import load_params
    from pipeline.stages.ingest import run_ingest
    from pipeline.stages.reference import run_reference
    from pipeline.stages.scale import run_scale

    root, reports = tmp_path_factory.mktemp("processed"), tmp_path_factory.mktemp("reports")
    params = load_params()
    run_ingest("camargo", params, root, progress=False)
    run_scale("camargo", params, root, reports)
    run_reference("camargo", params, root, reports, progress=False)
    return root / "camargo" / "model"
