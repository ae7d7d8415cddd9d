"""``vlights serve DIR``: serve an exported walkthrough to a browser on this machine
(``display.serve``)."""

from __future__ import annotations

__all__ = ["add_command", "run"]


def add_command(subparsers):
    p = subparsers.add_parser(
        "serve",
        help="serve a directory (an export) to a browser on this machine",
        description="A static web server on 127.0.0.1 for a directory such as 'vlights export' writes: browsers load "
        "ES modules only over HTTP. Prints the URL; Ctrl-C stops it.",
    )
    p.add_argument("directory", help="the directory to serve (nothing above it is reachable)")
    p.add_argument("--port", type=int, default=8000, help="TCP port on 127.0.0.1, 0 for any free one (default: %(default)s)")
    p.set_defaults(func=run)


def run(args):
    from display.serve import serve_until_interrupted, start

    server = start(args.directory, args.port)
    try:
        serve_until_interrupted(server, args.directory)
    finally:
        server.close()
