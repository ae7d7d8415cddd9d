"""Mitsuba 3 as an oracle: where its Python is, and scripts run in it.

Mitsuba is not a dependency of the project; it lives in a venv of its own, and the
tests that ask it are skipped where it is missing. Its Python is
``$VLIGHTS_MITSUBA_PYTHON``, else ``/work/mitsuba-venv/bin/python`` (``python3 -m venv
/work/mitsuba-venv && /work/mitsuba-venv/bin/pip install mitsuba``): the first that
imports mitsuba. A script there gets its inputs as files or arguments and answers on
stdout or in files; it may not find numpy (mitsuba does not need it).
"""

import functools
import os
import subprocess
from pathlib import Path

import pytest

DEFAULT_PYTHON = "/work/mitsuba-venv/bin/python"
MISSING = "Mitsuba 3 is not installed (/work/mitsuba-venv or $VLIGHTS_MITSUBA_PYTHON)"


@functools.cache
def mitsuba_python():
    """The path of a Python that imports mitsuba, or None."""
    for python in (os.environ.get("VLIGHTS_MITSUBA_PYTHON"), DEFAULT_PYTHON):
        if python and Path(python).exists():
            probe = subprocess.run([python, "-c", "import mitsuba"], capture_output=True, timeout=300)
            if probe.returncode == 0:
                return python
    return None


def require_mitsuba():
    """``mitsuba_python()``, or the test skipped saying Mitsuba is missing."""
    python = mitsuba_python()
    if python is None:
        pytest.skip(MISSING)
    return python


def run_mitsuba(script, *args, timeout=600):
    """The stdout of ``script`` (Python source) run by Mitsuba's Python with ``args``
    (skipped where there is none); the test fails with its stderr's end if it fails."""
    run = subprocess.run([require_mitsuba(), "-c", script, *map(str, args)], capture_output=True, text=True,
                         timeout=timeout)
    assert run.returncode == 0, run.stderr[-3000:]
    return run.stdout
