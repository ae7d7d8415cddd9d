"""Shared fixtures. Markers (pyproject.toml): ``slow`` (not run by default), ``gl``."""

import numpy as np
import pytest


@pytest.fixture
def rng():
    """A seeded generator: tests are deterministic."""
    return np.random.default_rng(20261122)
