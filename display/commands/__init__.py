"""The display stage's subcommands, one module each; ``display.cli`` (the dispatcher)
registers them, in this order, through ``register``.

    render   render.py    a picture (or a walkthrough video) of a fit or a solution
    compare  compare.py   the paper's figures 5-7 with error images and numbers
    view     view.py      the walkthrough window
    demo     demo.py      the whole pipeline on the built-in scenes
    truth    truth.py     the path-traced ground truth of a view
    export   export.py    a fit as glTF with the WebGL page (the writer: display.export)
    serve    serve.py     a static web server for an export

``common.py`` holds what several of them share: the camera and sample flags and the
checks of the input files. Each module's ``add_command(subparsers)`` adds its parser
and sets its handler; a handler takes the parsed arguments and returns the exit
status, raising ``InputError`` for a user's mistake (the dispatcher prints it in one
line and exits 2). No command imports the dispatcher.
"""

from __future__ import annotations

from . import compare, demo, export, render, serve, truth, view

__all__ = ["register"]


def register(subparsers):
    """Add every display command to ``subparsers``."""
    for module in (render, compare, view, demo, truth, export, serve):
        module.add_command(subparsers)
