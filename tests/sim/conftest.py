"""Fixtures of the human-model tests: the `human` section built, and the data manifest."""

from __future__ import annotations

import pytest

from ingest.manifest import Manifest


@pytest.fixture(scope="module")
def hp(params):
    """The `human` section: scaling and model parameters."""
    return params.human


@pytest.fixture(scope="module")
def manifest():
    return Manifest.load()
