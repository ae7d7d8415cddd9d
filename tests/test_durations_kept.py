"""The slowest tests' durations are kept with the results (``VLIGHTS_DURATIONS``)."""

import json
import os
import subprocess
import sys
from types import SimpleNamespace

import pytest
from durations import slowest_tests
from source_imports import REPOSITORY


def test_the_slowest_phases_come_first_and_no_more_than_asked():
    reports = [SimpleNamespace(nodeid=f"t{i}", when=w, duration=d)
               for i, (w, d) in enumerate([("call", 0.5), ("setup", 3.0), ("call", 1.25), ("teardown", 0.0)])]
    reports.append(SimpleNamespace(nodeid="collected", when=None, duration=None))  # a collection report: no phase
    rows = slowest_tests(reports, count=2)
    assert rows == [{"test": "t1", "phase": "setup", "seconds": 3.0}, {"test": "t2", "phase": "call", "seconds": 1.25}]


@pytest.mark.subprocess
def test_a_run_keeps_its_slowest_tests_where_asked(tmp_path):
    target = tmp_path / "durations.jsonl"
    env = dict(os.environ, VLIGHTS_DURATIONS=str(target))
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                          "tests/test_durations_kept.py::test_the_slowest_phases_come_first_and_no_more_than_asked"],
                         cwd=REPOSITORY, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-2000:]
    rows = [json.loads(line) for line in target.read_text().splitlines()]
    assert rows and rows[0]["test"].endswith("test_the_slowest_phases_come_first_and_no_more_than_asked")
    assert {"commit", "cores", "passed", "phase", "seconds"} <= set(rows[0]) and rows[0]["passed"] == 1
