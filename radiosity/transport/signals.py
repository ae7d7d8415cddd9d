"""Ctrl-C and SIGTERM held back while the main thread hands work to threads.

Python raises a signal's exception (KeyboardInterrupt, or the CLI's ``Terminated``)
between any two bytecodes of the main thread. ``concurrent.futures`` is not safe
against that: a future's lock is taken in Python code (``threading.Condition.__enter__``,
and ``concurrent.futures.wait`` takes several in a loop), so an exception landing just
after an acquire leaves the lock held by the main thread; the worker that then finishes
that future blocks on it forever, and the executor's shutdown waits for that worker
(a known limitation of CPython's ``concurrent.futures``, not fixed in the versions this runs on). ``vlights truth`` hung that way once on SIGTERM.

``HeldSignals`` swaps the handlers of SIGINT, SIGTERM and SIGHUP for one that only
records the signal (and calls ``wake``, so that a wait can notice), and ``check``
raises what the original handler raises at a point the caller chose, where no lock is
held; leaving the block delivers a signal that arrived after the last check. Only the
main thread receives signals; elsewhere it does nothing.
"""

from __future__ import annotations

import signal
import threading

HELD = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class HeldSignals:
    """``with HeldSignals(wake) as held: ... held.check() ...``: SIGINT, SIGTERM and
    SIGHUP raise only at ``check`` or at the end of the block.

    wake    : called with no argument from the handler (in the main thread, between
              bytecodes; it must be reentrant, as ``queue.SimpleQueue.put`` is), or None
    signums : the signals held (the tests add SIGALRM, which a timer can send at any
              bytecode)
    """

    def __init__(self, wake=None, signums=HELD):
        self.wake, self.signums = wake, tuple(signums)
        self.received = None  # the first signal held back, until delivered
        self._previous = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for signum in self.signums:
                handler = signal.getsignal(signum)
                if handler is None or handler == signal.SIG_IGN:  # set outside Python, or ignored
                    continue
                self._previous[signum] = signal.signal(signum, self._hold)
        return self

    def _hold(self, signum, _frame):
        if self.received is None:
            self.received = signum
        if self.wake is not None:
            self.wake()

    def check(self):
        """Raise now what a signal held back would have raised where it arrived."""
        signum, self.received = self.received, None
        if signum is None:
            return
        handler = self._previous.get(signum, signal.SIG_DFL)
        if callable(handler):
            handler(signum, None)  # Python's default SIGINT handler, or the CLI's: raises
        else:  # SIG_DFL: the default action (the process ends), with the handlers put back
            self._restore()
            signal.raise_signal(signum)

    def _restore(self):
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous = {}

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is None:
                self.check()
        finally:
            self._restore()
