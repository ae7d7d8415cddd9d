"""The same commands under two checkouts of the project, interleaved: is a change as fast?

Each checkout is a folder with its own ``.venv`` (``python3 -m venv .venv && .venv/bin/pip
install -e .`` there; a ``git worktree`` of the commit to compare against). Every case
runs once in each checkout first, unmeasured (numba compiles into the checkout's cache),
then --repeats times in each, alternating old and new, so that a noisy neighbour slows
both alike. Per case: the medians of the wall time and of the time the command reports
itself (``solve``'s "total", ``truth``'s "path traced ... in T s"; ``fit``: the wall time alone, of
--solution), their ratio new / old,
and every run.

    python benchmarks/bench_checkouts.py --old /work/wt/before [--new .] [--repeats 5] [--cases solve,fit,truth --solution S]

Writes results/checkouts.jsonl (one row per case).
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import Recorder  # noqa: E402

CASES = {
    "solve": (["solve", "cornell-teapot", "--quality", "draft", "-o", "{out}/solution.npz"],
              r"^\s*total\s+([0-9.]+) s"),
    "solve-plates": (["solve", "plates", "--quality", "draft", "-o", "{out}/solution.npz"],
                     r"^\s*total\s+([0-9.]+) s"),
    "fit": (["fit", "{solution}", "-o", "{out}/fit.npz"], None),  # wall time alone: the fit prints per object
    "truth": (["truth", "cornell-teapot", "--spp", "32", "--size", "512x512", "-o", "{out}/truth.png"],
              r"path traced .* in ([0-9.]+) s"),
}


def run(checkout, case, out, solution=None):
    args, pattern = CASES[case]
    command = [str(checkout / ".venv" / "bin" / "vlights"), *(a.format(out=out, solution=solution) for a in args)]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, cwd=out)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{checkout}: {' '.join(command)} failed: {done.stderr.strip()[-400:]}")
    found = re.search(pattern, done.stderr + done.stdout, re.MULTILINE) if pattern else None
    return wall, float(found.group(1)) if found else None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", type=Path, required=True, help="the checkout to compare against")
    parser.add_argument("--new", type=Path, default=Path(__file__).resolve().parent.parent)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--cases", default="solve,truth")
    parser.add_argument("--solution", type=Path, help="the solution.npz the case 'fit' fits (both checkouts the same)")
    args = parser.parse_args()
    if "fit" in args.cases.split(",") and args.solution is None:
        parser.error("the case 'fit' needs --solution")
    solution = args.solution.resolve() if args.solution else None
    record = Recorder(benchmark="checkouts", old=str(args.old), new=str(args.new.resolve()))
    for case in args.cases.split(","):
        runs = {"old": [], "new": []}
        with tempfile.TemporaryDirectory() as tmp:
            for which in ("old", "new"):
                run(getattr(args, which).resolve(), case, tmp, solution)  # compiles, unmeasured
            for _ in range(args.repeats):
                for which in ("old", "new"):
                    runs[which].append(run(getattr(args, which).resolve(), case, tmp, solution))
        row = {"case": case, "repeats": args.repeats}
        for k, name in ((0, "wall"), (1, "reported")):
            old = [r[k] for r in runs["old"] if r[k] is not None]
            new = [r[k] for r in runs["new"] if r[k] is not None]
            if old and new:
                row[name] = {"old_s": statistics.median(old), "new_s": statistics.median(new),
                             "ratio": statistics.median(new) / statistics.median(old), "old_runs": old,
                             "new_runs": new}
        record(row)
    record.save("checkouts.jsonl")


if __name__ == "__main__":
    main()
