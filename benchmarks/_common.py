"""What every benchmark script records: the machine, and its rows as JSON lines."""

from __future__ import annotations

import json
import os
import platform
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def machine():
    return {"cores": os.cpu_count(), "machine": platform.machine(), "python": platform.python_version()}


class Recorder:
    """Rows of one benchmark run: each printed as it comes, all saved at the end."""

    def __init__(self, **context):
        self.context = machine() | context
        self.rows = []

    def __call__(self, row):
        row = self.context | row
        self.rows.append(row)
        print(json.dumps(row), flush=True)
        return row

    def save(self, name):
        RESULTS.mkdir(exist_ok=True)
        with open(RESULTS / name, "w") as f:
            for row in self.rows:
                f.write(json.dumps(row) + "\n")
