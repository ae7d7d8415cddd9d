"""``vlights``: the one command. Each stage registers its own subcommands (radiosity
and fitting in their ``cli``, display in ``display.commands``, one module per
command); this module, the only one that sees all three stages, dispatches to them.

A user's mistake (InputError) prints one line and exits with status 2; Ctrl-C
exits with 130; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import textwrap
import threading
import warnings

import display.commands
import fitting.cli
import radiosity.cli
from radiosity.files.errors import InputError

PROG = "vlights"


class _HelpFormatter(argparse.HelpFormatter):
    """argparse's help, wrapped at spaces alone (a name such as cornell-teapot or
    probe+lights is never cut at its hyphen), a blank line in a description or epilog
    kept as a paragraph break."""

    def _split_lines(self, text, width):
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)

    def _fill_text(self, text, width, indent):
        paragraphs = [" ".join(p.split()) for p in text.split("\n\n")]
        return "\n\n".join(textwrap.fill(p, width, initial_indent=indent, subsequent_indent=indent,
                                          break_on_hyphens=False) for p in paragraphs if p)


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error message and help wrapped at spaces alone (every
    subcommand's parser is one of these too)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def not_built(command, what):
    """A handler for a subcommand whose stage does not exist yet: says so, exits 2."""

    def handler(_args):
        print(f"{PROG} {command}: not available yet: {what} is not built in this version", file=sys.stderr)
        return 2

    return handler


def build_parser():
    parser = _Parser(
        prog=PROG,
        description="virtual-lights: a view-independent glossy global-illumination solution of a triangle "
        "scene, and per glossy object a model a plain shader draws in real time (the emitters' highlights, "
        "a reflection probe, virtual lights), for walkthroughs in a window or a browser; after Walter et al., "
        "Fitting Virtual Lights for Non-Diffuse Walkthroughs (1997).",
        epilog="A scene of your own: 'vlights scene-info SCENE' says how it was understood; 'vlights solve "
        "SCENE -o solution.npz', then 'vlights fit solution.npz -o fit.npz'; then 'vlights view fit.npz', "
        "'vlights render fit.npz -o picture.png' or 'vlights export fit.npz -o web --serve'; 'vlights compare "
        "fit.npz solution.npz' measures it. 'vlights COMMAND --help' for each.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    radiosity.cli.register(subparsers, not_built)
    fitting.cli.register(subparsers, not_built)
    display.commands.register(subparsers)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {message}", file=sys.stderr)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP: stop as Ctrl-C does (every ``with atomic_output`` removes its
    temporary file on the way out), then exit with 128 + the signal's number."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


_SIGNALLED = []  # the interruptions that reached this run, as their exceptions (``_interruption``)


def _raise_terminated(signum, _frame):
    _SIGNALLED.append(Terminated(signum))
    raise _SIGNALLED[-1]


def _raise_interrupt(signum, frame):
    """Ctrl-C as Python's own handler raises it, remembered: an extension module being
    imported when it comes (scipy's) reports it as "ImportError: initialization failed",
    with nothing that says a KeyboardInterrupt was behind it."""
    _SIGNALLED.append(KeyboardInterrupt())
    signal.default_int_handler(signum, frame)


def _install_signal_handlers(previous):
    """SIGTERM and SIGHUP unwind like Ctrl-C; only possible from the main thread. Each
    previous handler goes into ``previous`` as soon as it is replaced, to restore (a
    signal in between leaves none unrestored)."""
    if threading.current_thread() is not threading.main_thread():
        return
    _SIGNALLED.clear()
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signum = getattr(signal, name)
            previous[signum] = signal.getsignal(signum)
            signal.signal(signum, _raise_terminated)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not where the caller chose to ignore it
        previous[signal.SIGINT] = signal.default_int_handler
        signal.signal(signal.SIGINT, _raise_interrupt)


def _interruption(exc):
    """The KeyboardInterrupt behind ``exc``, if a Ctrl-C surfaced wrapped inside another
    exception (numba and scipy's Fortran can report one as a SystemError), or an
    ImportError from an extension module that a signal stopped while it was imported."""
    seen = set()
    first = exc
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    if isinstance(first, ImportError) and _SIGNALLED:
        return _SIGNALLED[-1]
    return None


def main(argv=None):
    previous = {}
    try:
        _install_signal_handlers(previous)
        return _run(argv)
    except KeyboardInterrupt as exc:  # before the command runs: while the parser is built or reads the arguments
        return _interrupted(None, exc)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _run(argv):
    args = build_parser().parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        return args.func(args)
    except InputError as exc:
        _close_progress_bars()
        print(f"{PROG} {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        return _interrupted(args.command, exc)
    except Exception as exc:
        interrupt = _interruption(exc)
        if interrupt is None:
            raise
        return _interrupted(args.command, interrupt)


def _close_progress_bars():
    """End every progress bar a stopped stage left open (tqdm's live bars), so that the
    one line that follows starts a line of its own in a terminal, and no bar is drawn
    again after it when the interpreter exits."""
    tqdm = sys.modules.get("tqdm")
    unfinished = False
    for bar in list(getattr(getattr(tqdm, "tqdm", None), "_instances", ())):
        # a signal inside tqdm's __init__, after its first draw and before its clock is
        # set: close() returns without ending the line it drew
        half_made = not getattr(bar, "disable", True) and hasattr(bar, "sp") and not hasattr(bar, "last_print_t")
        with contextlib.suppress(Exception):
            bar.close()
        unfinished = unfinished or half_made
    if unfinished:  # give that line its end, so that the next is a line of its own
        sys.stderr.write("\n")


def _interrupted(command, exc):
    """The one line and the exit status of a run stopped by ``exc`` (``command`` None:
    before the command was known)."""
    _close_progress_bars()
    who = PROG if command is None else f"{PROG} {command}"
    if isinstance(exc, Terminated):
        name = signal.Signals(exc.signum).name
        print(f"{who}: stopped by {name}", file=sys.stderr)
        return 128 + exc.signum
    print(f"{who}: interrupted", file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
