"""Shared fixtures. Markers (pyproject.toml): ``slow`` (not run by default), ``gl``."""

import numpy as np
import pytest
from durations import slowest_tests


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


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """With ``VLIGHTS_DURATIONS=FILE`` set, the run's slowest tests are kept in FILE (one
    JSON row per test, with the commit, the cores and the run's totals), where
    ``benchmarks/report.py`` reads them (``benchmarks/results/test_durations.jsonl``)."""
    import json
    import os
    import subprocess

    target = os.environ.get("VLIGHTS_DURATIONS")
    if not target:
        return
    reports = [r for key in ("passed", "failed", "error", "skipped") for r in terminalreporter.stats.get(key, [])]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=config.rootpath).stdout.strip()
    context = {"commit": commit, "cores": os.cpu_count(), "workers": getattr(config.option, "numprocesses", None),
               "passed": len(terminalreporter.stats.get("passed", [])), "exit_status": int(exitstatus)}
    try:
        with open(target, "w") as f:
            for row in slowest_tests(reports):
                f.write(json.dumps(context | row) + "\n")
    except OSError as exc:
        terminalreporter.write_line(f"VLIGHTS_DURATIONS: cannot keep the durations in {target!r}: {exc.strerror}")
