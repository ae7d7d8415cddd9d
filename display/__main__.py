"""``vlights``'s entry point: a Ctrl-C (or SIGTERM) while the heavy modules load
exits with one line too, not a traceback; then ``display.cli.main`` runs."""

import signal
import sys


def _stop(signum, _frame):
    raise KeyboardInterrupt(signum)


def main(argv=None):
    if hasattr(signal, "SIGTERM"):
        signal.signal(signal.SIGTERM, _stop)
    try:
        from display.cli import main as run
    except KeyboardInterrupt as exc:
        signum = exc.args[0] if exc.args and isinstance(exc.args[0], int) else signal.SIGINT
        print("vlights: interrupted while starting; nothing was written", file=sys.stderr)
        return 128 + int(signum)
    return run(argv)


if __name__ == "__main__":
    sys.exit(main())
