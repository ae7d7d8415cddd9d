"""What a fit will need in memory, said before it starts, and a refusal in one line when
the machine cannot hold it.

The fit reads a solution an object at a time (``fit.fit`` with a ``SolutionFile``), so
its peak is the process's base, the fitted model it gathers (every object's mesh and
coefficients: about the solution's geometry twice), and, in each worker at once, one
glossy object's working set (``object_bytes``): its radiance as the file holds it
(float32, 12 bytes a sample: vertex x direction), the search for its model on at most
``search_samples`` of its samples (``fitting.blocks``; float64 arrays of every sample
searched, up to about 1.1 kB a sample measured on the scaling interior for an object
whose model gets lights: ``SAMPLE_BYTES`` above that), then its per-vertex pass, a
block of at most ``block_samples`` samples at a time (``BLOCK_BYTES`` a sample of the
block), and its stored model (``VERTEX_BYTES`` a vertex). The search and the pass do
not overlap: the larger counts.
"""

from __future__ import annotations

import os
import sys

from radiosity.files.errors import InputError
from radiosity.policies.limits import available_memory

from .blocks import BLOCK_SAMPLES, SEARCH_SAMPLES

__all__ = ["SAMPLE_BYTES", "check_dask_memory", "check_fit_memory", "cores", "costs", "fit_estimate", "object_bytes"]

SAMPLE_BYTES = 1_200  # the search's working set per sample searched, upper figure measured
BLOCK_BYTES = 1_200  # the per-vertex pass's working set per sample of a block
RADIANCE_BYTES = 12  # the object's radiance as read: float32 RGB per sample
VERTEX_BYTES = 1_000  # per vertex: its mesh, frames, coefficients (float64 and their float32 copies), visibility
PROCESS_BYTES = 200 * 2**20  # a fitting process before its object: Python, numpy, scipy, numba
GIB = 2**30


def object_bytes(vertices, directions, search_samples=SEARCH_SAMPLES, block_samples=BLOCK_SAMPLES):
    """The working set of fitting one glossy object of ``vertices`` x ``directions``
    samples: its radiance, the larger of the search and a block of the per-vertex
    pass, and its per-vertex arrays."""
    samples = vertices * directions
    searched = min(samples, max(int(search_samples), directions))
    block = min(samples, max(int(block_samples), directions))
    return samples * RADIANCE_BYTES + max(searched * SAMPLE_BYTES, block * BLOCK_BYTES) + vertices * VERTEX_BYTES


def cores():
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def costs(source):
    """{glossy object: its samples (vertices x directions)} of a ``SolutionFile``."""
    sizes = {n: source.sizes(n) for n in source.names}
    return {n: v * d for n, (v, d, _) in sizes.items() if d > 1}


def _objects(source):
    """(bytes of the fitted model's geometry, [(samples, name, V, D) of each glossy
    object], costliest first) of the ``SolutionFile`` ``source``, from its headers.
    "Costliest" is by samples: with a bounded search the working set still grows
    with them (``object_bytes``)."""
    geometry, glossy = 0, []
    for name in source.names:
        v, d, mesh = source.sizes(name)
        geometry += mesh + 3 * v * 3 * 4  # and normals, tangents, emitted: float32 (V, 3)
        if d > 1:
            glossy.append((v * d, name, v, d))
    return geometry, sorted(glossy, reverse=True)


def fit_estimate(source, workers, search_samples=SEARCH_SAMPLES, block_samples=BLOCK_SAMPLES, threads=False):
    """(peak bytes, the costliest object's (name, vertices, directions)) of fitting the
    ``SolutionFile`` ``source`` with ``workers`` processes (``threads``: threads of this
    process, no process each), each object's model searched for on at most
    ``search_samples`` samples and its per-vertex pass in blocks of ``block_samples``
    (``fitting.blocks``)."""
    geometry, glossy = _objects(source)
    main = PROCESS_BYTES + 2 * geometry
    if not glossy:
        return main, None

    def one(v, d):
        return object_bytes(v, d, search_samples, block_samples)

    busy = sorted(glossy, key=lambda g: -one(*g[2:]))[: max(1, workers)]
    if workers <= 1:
        return main + one(*busy[0][2:]), busy[0][1:]
    process = 0 if threads else PROCESS_BYTES
    return main + sum(process + one(v, d) for _, _, v, d in busy), busy[0][1:]


def check_fit_memory(source, workers, available=None, out=None, search_samples=SEARCH_SAMPLES,
                     block_samples=BLOCK_SAMPLES, threads=False):
    """The workers to fit ``source`` with: ``workers`` (processes, or ``threads`` of this
    process), or fewer if their objects at once would not fit in the memory left
    (``available`` bytes, default the machine's). Says the estimate (``out``, default a
    line on stderr, beside the progress bar: stdout is the report); InputError (one
    line) when even one process would not fit."""
    out = out or (lambda line: print(line, file=sys.stderr))
    available = available_memory() if available is None else available
    chosen = max(1, workers)
    need, biggest = fit_estimate(source, chosen, search_samples, block_samples, threads)
    while available is not None and need > available and chosen > 1:
        chosen -= 1
        need, biggest = fit_estimate(source, chosen, search_samples, block_samples, threads)
    largest = "" if biggest is None else f"; largest glossy object {biggest[0]!r}: {biggest[1]:,} vertices x {biggest[2]:,} directions"
    have = "" if available is None else f" of {available / GIB:.1f} GB available"
    if available is not None and need > available:
        raise InputError(f"fit needs about {need / GIB:.1f} GB{have}{largest}; fit with fewer --search-samples, "
                         "solve with a coarser --grid or a larger --max-edge, or free memory")
    note = f" (fewer than the {workers} asked: memory)" if chosen < workers else ""
    kind = "thread" if threads and chosen > 1 else "worker"
    out(f"fit: about {need / GIB:.2f} GB at most{have}, {chosen} {kind}{'s' if chosen > 1 else ''}{note}{largest}")
    return chosen


def check_dask_memory(source, in_flight, available=None, out=None, search_samples=SEARCH_SAMPLES,
                      block_samples=BLOCK_SAMPLES):
    """Says what a fit on Dask needs: here, the base, the fitted model and the arrays of
    the ``in_flight`` costliest glossy objects (their radiance, float32 (V, D, 3), on
    their way to the workers); on each worker, one object's working set (its machine's
    memory is the cluster's to check). InputError (one line) when this machine cannot
    hold its part."""
    out = out or (lambda line: print(line, file=sys.stderr))
    available = available_memory() if available is None else available
    geometry, glossy = _objects(source)
    here = PROCESS_BYTES + 2 * geometry + sum(samples * 12 for samples, *_ in glossy[:in_flight])
    have = "" if available is None else f" of {available / GIB:.1f} GB available"
    if available is not None and here > available:
        raise InputError(f"fit needs about {here / GIB:.1f} GB here{have} to send its objects to Dask; free memory")
    largest = 0 if not glossy else PROCESS_BYTES + object_bytes(glossy[0][2], glossy[0][3], search_samples, block_samples)
    worker = "" if not glossy else (f"; each Dask worker about {largest / GIB:.2f} GB "
                                    f"for the largest glossy object {glossy[0][1]!r}")
    out(f"fit: about {here / GIB:.2f} GB at most here{have}{worker}")
