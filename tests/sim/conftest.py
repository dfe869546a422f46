"""Fixtures of the sim tests: the `human` section built, the data manifest, and a training budget
callback that fails at a known step."""

from __future__ import annotations

import pytest

from ingest.manifest import Manifest
from sim.learn.train import Budget


@pytest.fixture(scope="module")
def hp(params):
    """The `human` section: scaling and model parameters."""
    return params.human


@pytest.fixture(scope="module")
def manifest():
    return Manifest.load()


@pytest.fixture
def failing_budget() -> type[Budget]:
    """The trainers' `Budget` callback (both `train` and `train_universal` use it), raising at env
    step 300: a run that fails mid-training at a known step, monkeypatched in by a test."""

    class FailAt300(Budget):
        def _on_step(self) -> bool:
            if self.num_timesteps == 300:
                raise RuntimeError("a failing callback")
            return super()._on_step()

    return FailAt300
