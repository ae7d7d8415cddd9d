"""The thread runner stops cleanly whenever a signal lands (radiosity/transport/signals.py).

A KeyboardInterrupt raised between two bytecodes of the main thread while it holds one
of ``concurrent.futures``' locks leaves the lock held; the worker finishing that future
then blocks forever, and so does the pool's shutdown (CPython issue 20319). A timer
(SIGALRM, held like SIGINT here) interrupts a run of tiny jobs at thousands of moments;
every run must stop and its pool shut down. Without the held signals the same loop
hung within about 60 trials (run by hand on the code before this test).
"""

import signal
import subprocess
import sys
import textwrap

import pytest

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
