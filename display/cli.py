"""``vlights``: the one command. Each stage registers its own subcommands; this
module, the only one that sees all three stages, dispatches to them.

A user's mistake (InputError) prints one line and exits with status 2; Ctrl-C
exits with 130; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import sys
import warnings

import fitting.cli
import radiosity.cli
from radiosity.errors import InputError

PROG = "vlights"


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error message."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def not_built(command, what):
    """A handler for a subcommand whose stage does not exist yet: says so, exits 2."""

    def handler(_args):
        print(f"{PROG} {command}: not available yet: {what} is not built in this version", file=sys.stderr)
        return 2

    return handler


def register(subparsers, not_built):
    for command, help_text in (
        ("render", "render a solution or fitted model to an image"),
        ("view", "walk through a scene in a window"),
        ("compare", "the paper's comparison figures with error images and numbers"),
        ("demo", "solve, fit and compare the built-in cornell-teapot scene"),
    ):
        p = subparsers.add_parser(command, help=help_text)
        p.set_defaults(func=not_built(command, "the display stage (issue #5)" if command != "demo" else "the end-to-end demo (issue #6)"))


def build_parser():
    parser = _Parser(
        prog=PROG,
        description="virtual-lights: view-independent glossy global illumination, fitted with "
        "virtual Phong lights for real-time walkthroughs (after Walter et al. 1997).",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    radiosity.cli.register(subparsers, not_built)
    fitting.cli.register(subparsers, not_built)
    register(subparsers, not_built)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"{PROG}: warning: {message}", file=sys.stderr)


def main(argv=None):
    args = build_parser().parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        return args.func(args)
    except InputError as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG} {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
