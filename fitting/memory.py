"""What a fit will need in memory, said before it starts, and a refusal in one line when
the machine cannot hold it (issue 25).

The fit reads a solution an object at a time (``fit.fit`` with a ``SolutionFile``), so
its peak is the process's base, the fitted model it gathers (every object's mesh and
coefficients: about the solution's geometry twice), and, in each worker at once, one
glossy object's working set. That working set grows with the object's samples
(vertices x directions): the model search's arrays of every sample, float64. Measured on
the scaling interior (``benchmarks/bench_scale.py``) at up to about 1.1 kB a sample for
an object whose model gets lights, less for the others; the estimate uses
``SAMPLE_BYTES``, above that figure.
"""

from __future__ import annotations

import os
import sys

from radiosity.formats.errors import InputError
from radiosity.formats.limits import available_memory

__all__ = ["SAMPLE_BYTES", "check_fit_memory", "cores", "fit_estimate"]

SAMPLE_BYTES = 1_200  # a glossy object's working set per sample (vertex x direction), upper figure measured
PROCESS_BYTES = 200 * 2**20  # a fitting process before its object: Python, numpy, scipy, numba
GIB = 2**30


def cores():
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def fit_estimate(source, workers):
    """(peak bytes, the costliest object's (name, vertices, directions)) of fitting the
    ``SolutionFile`` ``source`` with ``workers`` processes."""
    geometry, glossy = 0, []
    for name in source.names:
        v, d, mesh = source.sizes(name)
        geometry += mesh + 3 * v * 3 * 4  # and normals, tangents, emitted: float32 (V, 3)
        if d > 1:
            glossy.append((v * d, name, v, d))
    glossy.sort(reverse=True)
    main = PROCESS_BYTES + 2 * geometry
    if not glossy:
        return main, None
    busy = glossy[: max(1, workers)]
    if workers <= 1:
        return main + busy[0][0] * SAMPLE_BYTES, busy[0][1:]
    return main + sum(PROCESS_BYTES + samples * SAMPLE_BYTES for samples, *_ in busy), busy[0][1:]


def check_fit_memory(source, workers, available=None, out=None):
    """The workers to fit ``source`` with: ``workers``, or fewer if their objects at once
    would not fit in the memory left (``available`` bytes, default the machine's). Says
    the estimate (``out``, default a line on stderr, beside the progress bar: stdout
    is the report); InputError (one line) when even one process would not fit."""
    out = out or (lambda line: print(line, file=sys.stderr))
    available = available_memory() if available is None else available
    chosen = max(1, workers)
    need, biggest = fit_estimate(source, chosen)
    while available is not None and need > available and chosen > 1:
        chosen -= 1
        need, biggest = fit_estimate(source, chosen)
    largest = "" if biggest is None else f"; largest glossy object {biggest[0]!r}: {biggest[1]:,} vertices x {biggest[2]:,} directions"
    have = "" if available is None else f" of {available / GIB:.1f} GB available"
    if available is not None and need > available:
        raise InputError(f"fit needs about {need / GIB:.1f} GB{have}{largest}; solve it with a coarser "
                         "--grid or a larger --max-edge, or free memory")
    note = f" (fewer than the {workers} asked: memory)" if chosen < workers else ""
    out(f"fit: about {need / GIB:.2f} GB at most{have}, {chosen} worker{'s' if chosen > 1 else ''}{note}{largest}")
    return chosen
