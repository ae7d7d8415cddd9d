"""``vlights``'s entry point: a Ctrl-C (or SIGTERM) while the heavy modules load
exits with one line too, not a traceback; then ``display.cli.main`` runs."""

import signal
import sys


def _stop(signum, _frame):
    raise KeyboardInterrupt(signum)


def _status(exc):
    """The exit status of a run stopped by ``exc``: 128 + the signal's number."""
    signum = exc.args[0] if exc.args and isinstance(exc.args[0], int) else signal.SIGINT
    return 128 + int(signum)


def main(argv=None):
    if hasattr(signal, "SIGTERM"):
        signal.signal(signal.SIGTERM, _stop)
    try:
        from display.cli import main as run
    except KeyboardInterrupt as exc:
        print("vlights: interrupted while starting; nothing was written", file=sys.stderr)
        return _status(exc)
    try:
        return run(argv)
    except KeyboardInterrupt as exc:  # in the instant between the import and run's own handling
        from display.cli import Terminated, _interrupted

        signum = _status(exc) - 128
        return _interrupted(None, exc if signum == signal.SIGINT else Terminated(signum))


if __name__ == "__main__":
    sys.exit(main())
