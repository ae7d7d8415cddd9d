"""Is there a display to open the walkthrough window on? DISPLAY must be set and an X
server must answer there; otherwise ``vlights view`` refuses in one line (exit 2).
No X server is needed: a listening socket stands for one."""

import os
import socket
import sys

import pytest
from display_fixtures import assert_refused

import display.window
from display.window import display_problem, has_display

pytestmark = pytest.mark.skipif(sys.platform in ("darwin", "win32"), reason="a display always exists there")


def free_display_number():
    """A display number nothing answers on (no socket file, nothing listening)."""
    for number in range(150, 400):
        if os.path.exists(f"/tmp/.X11-unix/X{number}") or os.path.exists(f"/tmp/.X{number}-lock"):
            continue
        if display_problem({"DISPLAY": f":{number}"}) is not None:
            return number
    pytest.skip("no free display number")


def test_no_display_variable():
    assert display_problem({}) == "DISPLAY is not set"
    assert "needs X" in display_problem({"WAYLAND_DISPLAY": "wayland-0"})
    assert not has_display({})


def test_a_display_with_no_server_behind_it():
    number = free_display_number()
    assert display_problem({"DISPLAY": f":{number}"}) == f"no X server answers on DISPLAY=:{number}"
    assert display_problem({"DISPLAY": f":{number}.0"}) == f"no X server answers on DISPLAY=:{number}.0"
    assert "not an X display name" in display_problem({"DISPLAY": "garbage"})


def test_a_listening_unix_socket_is_a_display(tmp_path, monkeypatch):
    monkeypatch.setattr(display.window, "X11_SOCKET_DIR", str(tmp_path))
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        server.bind(str(tmp_path / "X5"))
        server.listen(1)
        assert display_problem({"DISPLAY": ":5"}) is None
        assert display_problem({"DISPLAY": "unix:5.0"}) is None
    finally:
        server.close()
    assert display_problem({"DISPLAY": ":5"}) == "no X server answers on DISPLAY=:5"  # the file stays, nobody listens


def test_a_listening_tcp_port_is_a_remote_display(monkeypatch):
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        port = server.getsockname()[1]
        monkeypatch.setattr(display.window, "X11_TCP_PORT", port - 10)
        assert display_problem({"DISPLAY": "127.0.0.1:10"}) is None
    finally:
        server.close()
    assert display_problem({"DISPLAY": "127.0.0.1:10"}) == "no X server answers on DISPLAY=127.0.0.1:10"


def test_view_refuses_a_display_with_no_server(tiny_pair, cli, monkeypatch):
    number = free_display_number()
    monkeypatch.setenv("DISPLAY", f":{number}")
    assert_refused(cli("view", tiny_pair[0]), "no display to open a window on",
                   f"no X server answers on DISPLAY=:{number}", "vlights render", command="view")
