"""Shared fixtures. Markers (pyproject.toml): ``slow`` (not run by default), ``gl``."""

import numpy as np
import pytest


@pytest.fixture
def rng():
    """A seeded generator: tests are deterministic."""
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def gl_context():
    """A headless OpenGL context (EGL); tests using it are skipped where there is none."""
    from radiosity.formats.errors import InputError

    try:
        from display.gl import headless_context

        ctx = headless_context()
    except (ImportError, InputError) as exc:
        pytest.skip(f"no headless OpenGL: {exc}")
    yield ctx
    ctx.release()
