"""The fit's glossy objects as Dask tasks (``vlights fit --scheduler dask | tcp://HOST:PORT``,
``fit(..., client=)``): the same ``fit_object`` as in this process or the worker
processes, the same bits.

What goes where
  - the scene's triangles (the lights' seeds read what a mirror ray hits) and the
    probe's proxy box are scattered to every worker once;
  - each glossy object's task carries the object's arrays and the file's emitters (a
    one-object ``Solution``, ``SolutionFile.alone``, without the environment's image,
    which no object's fit reads), so the workers need no shared disk.
    This process reads them from the solution file one object at a time, costliest
    (vertices x directions) first, and keeps at most 2 x (the cluster's threads) + 1
    objects in flight: its memory is that of a few objects, whatever the scene;
  - a task returns the object's ``FittedObject``; this process copies the diffuse
    objects while the workers fit, and puts every object back in the file's order;
  - numba's threads in a task: the cores of the worker's machine shared out between
    that machine's worker threads (two tasks on a two-core machine: one each);
  - the same bits as ``fit`` without Dask: a task is a pure function of its inputs,
    and the fit does not depend on numba's thread count (``lobes.ordered_sum``). A lost
    worker's tasks are run again elsewhere. Ctrl-C cancels what is pending.

Warnings a task raises stay in the worker's log (the fit in this process and its
worker processes show them as the command's one-line warnings).
"""

from __future__ import annotations

from dataclasses import replace

__all__ = ["fit_on_dask"]


def fit_on_dask(client, source, options, place, bar):
    """The ``FittedObject`` of every object of the ``SolutionFile`` ``source``, in file
    order, the glossy ones fitted on the ``distributed.Client`` ``client``; place =
    (scene geometry, probe box, ``fit.fit_object``); bar: a progress bar (``update``)
    or None."""
    from distributed import as_completed
    from distributed.comm import get_address_host

    from .memory import costs

    scene, box, fit_object = place
    cost = costs(source)
    order = sorted(cost, key=lambda n: -cost[n])  # costliest first
    threads = client.nthreads()  # {worker address: its threads}
    window = 2 * max(1, sum(threads.values())) + 1
    host_threads = {}
    for address, n in threads.items():
        host = get_address_host(address)
        host_threads[host] = host_threads.get(host, 0) + n
    [shared] = client.scatter([(scene, box)], broadcast=True, hash=False)
    queue = iter(order)
    names = {}
    done = {}
    running = as_completed()

    def submit():
        name = next(queue, None)
        if name is not None:
            alone = replace(source.alone(name), environment=None)  # the fit of an object never reads it
            future = client.submit(_fit_task, fit_object, alone, options, shared, host_threads, pure=False)
            names[future] = name
            running.add(future)

    def collect(future):
        done[names.pop(future)] = future.result()
        future.release()
        if bar is not None:
            bar.update(1)
        submit()

    try:
        for _ in range(window):
            submit()
        for name in source.names:
            if name not in cost:  # a diffuse object, here while the workers fit
                done[name] = fit_object(source.object(name), options, scene, bar, None, box)
                if bar is not None:
                    bar.update(1)
                while running.has_ready():
                    for future in running.next_batch(block=False):
                        collect(future)
        for future in running:
            collect(future)
    except BaseException:
        client.cancel(list(names), force=True)
        raise
    finally:
        client.cancel([shared], force=True)
    return [done[n] for n in source.names]


def _fit_task(fit_object, alone, options, shared, host_threads):
    """One glossy object fitted on a Dask worker by ``fit_object``: alone, the object
    with the file's emitters (a one-object ``Solution``); shared, the scattered (scene,
    box)."""
    import numba
    from distributed import get_worker
    from distributed.comm import get_address_host

    from .memory import cores

    sharing = host_threads.get(get_address_host(get_worker().address), 1)
    threads = max(1, cores() // max(1, sharing))
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    scene, box = shared
    [obj] = alone.objects
    return fit_object(obj, options, scene, None, alone, box)
