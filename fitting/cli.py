"""The fitting stage's subcommands: ``fit``."""

from __future__ import annotations


def register(subparsers, not_built):
    p = subparsers.add_parser("fit", help="fit virtual lights to a solution (fit.npz)")
    p.set_defaults(func=not_built("fit", "the virtual-light fitter (issue #4)"))
