"""The thread runner stops cleanly whenever a signal lands (radiosity/transport/signals.py).

A KeyboardInterrupt raised between two bytecodes of the main thread while it holds one
of ``concurrent.futures``' locks leaves the lock held; the worker finishing that future
then blocks forever, and so does the pool's shutdown (a known limitation of CPython's
``concurrent.futures``). A timer
(SIGALRM, held like SIGINT here) interrupts a run of tiny jobs at thousands of moments;
every run must stop and its pool shut down. Without the held signals the same loop
hung within about 60 trials (run by hand on the code before this test).
"""

import signal
import subprocess
import sys
import textwrap
import threading
from concurrent.futures import Future

import pytest

from radiosity.transport import threads
from radiosity.transport.signals import HeldSignals

STRESS = textwrap.dedent("""
    import signal, sys, threading, time
    from concurrent.futures import ThreadPoolExecutor
    from radiosity.transport import threads
    from radiosity.transport.signals import HELD, HeldSignals

    class Alarm(Exception):
        pass

    def ring(signum, frame):
        raise Alarm

    signal.signal(signal.SIGALRM, ring)
    held = {held}
    stopped = 0
    for trial in range({trials}):
        executor = ThreadPoolExecutor(2)
        pool = threads._ThreadPool(executor, lambda job: time.sleep(0.0002) or job, 2)
        if held:
            pool.held = HeldSignals(wake=lambda: pool.finished.put(None), signums=HELD + (signal.SIGALRM,))
        signal.setitimer(signal.ITIMER_REAL, 0.001 + (trial % 97) * 0.0001)
        try:
            with pool.held:
                threads.in_order(pool, range(10**9), lambda r: None, threads._NullProgress(), iter(lambda: 1, 0))
        except Alarm:
            stopped += 1
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        closer = threading.Thread(target=executor.shutdown, daemon=True)
        closer.start()
        closer.join(10)
        if closer.is_alive():
            print("hung at trial", trial, flush=True)
            import os
            os._exit(3)
    print("stopped", stopped, flush=True)
""")


def _stress(trials, held):
    return subprocess.run(
        [sys.executable, "-c", STRESS.format(trials=trials, held=held)], capture_output=True, text=True, timeout=600
    )


def test_a_signal_at_any_moment_stops_the_run_and_the_pool():
    run = _stress(500, held=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert run.stdout.split() == ["stopped", "500"]  # every run stopped by its timer, none hung


@pytest.mark.slow
def test_without_holding_the_signals_the_same_loop_hangs():
    """The hazard is real (why the handlers are held): the bare pool hangs."""
    run = _stress(3000, held=False)
    assert run.returncode == 3 and "hung at trial" in run.stdout, run.stdout + run.stderr


def test_a_held_signal_raises_at_the_check_with_the_original_handler():
    def original(signum, frame):
        raise LookupError(signum)

    before = signal.signal(signal.SIGUSR1, original)
    try:
        woken = []
        with pytest.raises(LookupError) as raised, HeldSignals(wake=lambda: woken.append(1), signums=(signal.SIGUSR1,)) as held:
            signal.raise_signal(signal.SIGUSR1)  # recorded, not raised
            assert held.received == signal.SIGUSR1 and woken == [1]
            held.check()
            pytest.fail("check() did not raise")
        assert raised.value.args == (signal.SIGUSR1,)
        assert signal.getsignal(signal.SIGUSR1) is original  # put back
        with pytest.raises(LookupError), HeldSignals(signums=(signal.SIGUSR1,)):
            signal.raise_signal(signal.SIGUSR1)  # not checked inside: raised on leaving the block
        with HeldSignals(signums=(signal.SIGUSR1,)) as held:
            held.check()  # nothing received: nothing raised
    finally:
        signal.signal(signal.SIGUSR1, before)


def test_a_held_signal_with_the_default_action_still_ends_the_process():
    code = (
        "import signal\nfrom radiosity.transport.signals import HeldSignals\n"
        "with HeldSignals() as held:\n    signal.raise_signal(signal.SIGTERM)\n    print('held', flush=True)\n"
        "    held.check()\nprint('survived')\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert run.stdout.split() == ["held"] and run.returncode == -signal.SIGTERM


class _DoneAtTheSecondLook(Future):
    """A job's future that is running when first looked at and done from the second look
    on: the job finishes (its done-callback fed the pool's queue) between ``in_order``'s
    check of the window's head and the list of unfinished futures it waits for, as a
    worker thread can at any moment on a loaded machine."""

    def __init__(self, value):
        super().__init__()
        self.value, self.looks = value, 0

    def done(self):
        self.looks += 1
        if self.looks == 2:
            self.set_result(self.value)
        return super().done()


class _LateExecutor:
    def submit(self, fn, job):
        return _DoneAtTheSecondLook(fn(job))


def test_a_job_done_between_two_looks_at_it_does_not_hang_the_run():
    """One job in flight (a path tracer's one-pixel image has one tile a pass) that
    finishes after the head check: nothing is left to wait for, and the wait must end
    (it once blocked forever on the queue, a hang seen in CI under load)."""
    pool = threads._ThreadPool(_LateExecutor(), lambda job: 10 * job, 2)
    combined = []
    for job in (1, 2, 3):  # passes of one job each
        run = threading.Thread(target=threads.in_order, daemon=True,
                               args=(pool, [job], combined.append, threads._NullProgress(), [1]))
        run.start()
        run.join(10)
        assert not run.is_alive(), f"in_order hung on job {job}"
    assert combined == [10, 20, 30]
