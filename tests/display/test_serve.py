"""vlights serve: the directory over HTTP on 127.0.0.1, with the types a module page and a
binary glTF need, nothing above it (no traversal, no symlink out), and clear refusals."""

import http.client
import os
import signal
import socket
import subprocess
import sys
import urllib.error
import urllib.request

import pytest

from display.serve import inside, start
from radiosity.files.errors import InputError

SECRET = b"outside the served directory"


def fetch(url):
    with urllib.request.urlopen(url, timeout=10) as response:
        return response.status, response.headers["Content-Type"], response.read()


def test_files_come_back_with_their_types(tmp_path):
    (tmp_path / "scene.glb").write_bytes(b"glTF\x02\x00\x00\x00")
    (tmp_path / "app.js").write_text("export const x = 1;\n")
    (tmp_path / "index.html").write_text("<!doctype html><title>t</title>")
    with start(tmp_path, port=0) as server:
        assert server.url.startswith("http://127.0.0.1:")
        assert fetch(server.url + "scene.glb") == (200, "model/gltf-binary", b"glTF\x02\x00\x00\x00")
        status, kind, body = fetch(server.url + "app.js")
        assert status == 200 and kind == "text/javascript" and body == b"export const x = 1;\n"
        assert fetch(server.url)[2].startswith(b"<!doctype html>")  # index.html for the directory
        with pytest.raises(urllib.error.HTTPError) as missing:
            fetch(server.url + "nothing.js")
        assert missing.value.code == 404
        with pytest.raises(urllib.error.HTTPError):  # nothing above the directory
            fetch(server.url + "../" + tmp_path.name + "/app.js")


def test_bad_directories_and_ports_are_refused(tmp_path):
    with pytest.raises(InputError, match="not found"):
        start(tmp_path / "missing")
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="is not a directory"):
        start(tmp_path / "file")
    with pytest.raises(InputError, match="--port"):
        start(tmp_path, port=70000)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        with pytest.raises(InputError, match="cannot serve on 127.0.0.1"):
            start(tmp_path, port=taken.getsockname()[1])


def raw_get(url, path):
    """(status, body) of GET ``path`` sent as it is (no client-side normalisation)."""
    host, port = url.split("//")[1].rstrip("/").split(":")
    connection = http.client.HTTPConnection(host, int(port), timeout=10)
    try:
        connection.putrequest("GET", path, skip_host=True, skip_accept_encoding=True)
        connection.putheader("Host", f"{host}:{port}")
        connection.endheaders()
        response = connection.getresponse()
        return response.status, response.read()
    finally:
        connection.close()


@pytest.fixture
def served(tmp_path):
    """A directory to serve with a page, a file outside it, and symlinks inside it to
    that file, to the directory above, and to a file inside (fine)."""
    outside = tmp_path / "secret.txt"
    outside.write_bytes(SECRET)
    root = tmp_path / "web"
    (root / "sub").mkdir(parents=True)
    (root / "index.html").write_text("<!doctype html>")
    (root / "sub" / "app.js").write_text("export {};\n")
    os.symlink(outside, root / "link.txt")
    os.symlink(tmp_path, root / "up")
    os.symlink(root / "sub" / "app.js", root / "alias.js")
    return root


TRAVERSALS = [
    "/../secret.txt", "/sub/../../secret.txt", "/%2e%2e/secret.txt", "/%2E%2E/%2e%2e/secret.txt",
    "/..%2fsecret.txt", "/sub/%2e%2e/%2e%2e/secret.txt", "//secret.txt", "/link.txt", "/up/secret.txt", "/up/",
    "/up", "/sub/..%5c..%5csecret.txt",
]


def test_nothing_outside_the_directory_is_served(served):
    """Traversal (``..``, encoded, absolute) and symlinks out of the directory: never the
    file outside; one server for every request (each server takes up to 0.5 s to stop)."""
    absolute = str(served.parent / "secret.txt")
    with start(served, port=0) as server:
        answers = {request: raw_get(server.url, request) for request in TRAVERSALS + [absolute, "/" + absolute.lstrip("/")]}
        assert raw_get(server.url, "/sub/app.js") == (200, b"export {};\n")
        assert raw_get(server.url, "/alias.js") == (200, b"export {};\n")  # a link inside to inside is fine
        assert raw_get(server.url, "/sub/../index.html")[0] == 200
    leaked = {request: status for request, (status, body) in answers.items() if SECRET in body or status not in (301, 404)}
    assert leaked == {}
    assert answers["/link.txt"][0] == 404 and answers["/up/secret.txt"][0] == 404


def test_inside_follows_links(served):
    assert inside(served / "sub" / "app.js", served) and inside(served, served)
    assert inside(served / "alias.js", served)
    assert not inside(served / "link.txt", served) and not inside(served / "up", served)
    assert not inside(str(served) + "-other", served)  # a sibling whose name starts the same


@pytest.mark.subprocess
def test_the_command_prints_its_url_and_stops_on_ctrl_c(tmp_path):
    (tmp_path / "scene.glb").write_bytes(b"glTF")
    proc = subprocess.Popen(
        [sys.executable, "-m", "display", "serve", str(tmp_path), "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    line = proc.stdout.readline()
    assert "serving" in line and "http://127.0.0.1:" in line, (line, proc.stderr.read() if proc.poll() else "")
    url = line.split(" at ")[1].split()[0]
    assert fetch(url + "scene.glb")[2] == b"glTF"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and "Traceback" not in err, err
    with pytest.raises(OSError):  # the process has exited: nothing listens any more
        fetch(url + "scene.glb")


def test_the_command_refuses_a_missing_directory_in_one_line(tmp_path, cli):
    code, out, err = cli("serve", tmp_path / "missing")
    assert code == 2 and out == "" and err.count("\n") == 1 and "not found" in err


def test_a_busy_port_is_one_line_exit_2(tmp_path, cli):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        code, out, err = cli("serve", tmp_path, "--port", taken.getsockname()[1])
    assert code == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("vlights serve: error: cannot serve on 127.0.0.1:") and "in use" in err
