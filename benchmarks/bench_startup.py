"""How long a command takes to start: ``vlights serve --help`` and ``vlights render
--help`` (parsing alone), and a whole ``vlights render`` of a small fit (what it
imports, then its work), in two checkouts run interleaved, each in a fresh process.

    python benchmarks/bench_startup.py --old ../old-checkout --fit fit.npz [--repeats 9]

``--old`` is a checkout whose modules are put first on the path (PYTHONPATH); the
new one is this checkout. Each row: the case, the checkout, the median seconds of
--repeats runs and whether numba, trimesh and scipy were imported.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import Recorder  # noqa: E402

REPOSITORY = Path(__file__).resolve().parent.parent
PROBE = """
import sys
from display.cli import main
try:
    status = main(sys.argv[1:])
except SystemExit as exc:
    status = exc.code
sys.stderr.write("loaded: " + " ".join(m for m in ("numba", "trimesh", "scipy") if m in sys.modules) + "\\n")
"""


def once(checkout, argv):
    """(seconds, the heavy modules loaded) of one run of ``vlights argv`` from ``checkout``."""
    env = dict(os.environ, PYTHONPATH=str(checkout))
    start = time.perf_counter()
    run = subprocess.run([sys.executable, "-c", PROBE, *argv], env=env, cwd=checkout, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    loaded = [line for line in run.stderr.splitlines() if line.startswith("loaded:")]
    if not loaded:
        raise SystemExit(f"vlights {' '.join(argv)} in {checkout} failed: {run.stderr.strip()[-300:]}")
    return seconds, loaded[-1].split()[1:]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="the checkout to compare with")
    parser.add_argument("--fit", type=Path, required=True, help="a fit.npz to render")
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()
    old, new = args.old.resolve(), REPOSITORY
    with tempfile.TemporaryDirectory() as tmp:
        cases = {
            "serve --help": ["serve", "--help"],
            "render --help": ["render", "--help"],
            "render 64x64": ["render", str(args.fit.resolve()), "-o", str(Path(tmp) / "x.png"), "--size", "64x64"],
        }
        record = Recorder(benchmark="startup", old=str(old), cores=os.cpu_count())
        for case, argv in cases.items():
            times = {"old": [], "new": []}
            loaded = {}
            once(old, argv), once(new, argv)  # warm: numba's cache, the file system's
            for _ in range(args.repeats):  # interleaved: old, new, old, new ...
                for which, checkout in (("old", old), ("new", new)):
                    seconds, heavy = once(checkout, argv)
                    times[which].append(seconds)
                    loaded[which] = heavy
            for which in ("old", "new"):
                record({"case": case, "checkout": which, "seconds": statistics.median(times[which]),
                        "repeats": args.repeats, "loaded": loaded[which]})
    record.save("startup.jsonl")


if __name__ == "__main__":
    main()
