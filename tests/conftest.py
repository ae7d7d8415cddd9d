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
    from radiosity.files.errors import InputError

    try:
        from display.gl import headless_context

        ctx = headless_context()
    except (ImportError, InputError) as exc:
        pytest.skip(f"no headless OpenGL: {exc}")
    yield ctx
    ctx.release()


@pytest.fixture(scope="module")
def client():
    """A Dask client of a LocalCluster of two one-thread worker processes (the tests
    marked ``dask``); skipped where Dask is not installed."""
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()
