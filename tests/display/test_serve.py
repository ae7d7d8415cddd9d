"""vlights serve: the directory over HTTP on 127.0.0.1, with the types a module page and a
binary glTF need, nothing above it, and clear refusals."""

import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

import pytest

from display.serve import start
from radiosity.formats import InputError


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
    time.sleep(0.1)
    with pytest.raises(OSError):
        fetch(url + "scene.glb")


def test_the_command_refuses_a_missing_directory_in_one_line(tmp_path, cli):
    code, out, err = cli("serve", tmp_path / "missing")
    assert code == 2 and out == "" and err.count("\n") == 1 and "not found" in err
