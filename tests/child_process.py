"""A ``vlights`` child process the tests can wait on: readiness signals, not sleeps.

``Child(argv)`` starts the command with its stderr on a pseudo-terminal of 160 columns
(so its progress bars show, as in a user's terminal; tqdm draws nothing on a pipe) or,
with ``terminal=False``, on a pipe; a thread keeps reading it, so the child never
blocks on a full buffer. ``wait_for(pattern)`` returns once the stderr so far matches
(a regular expression), or fails the test with what was seen when the child ends first
or the deadline passes. ``finish()`` waits for the exit: (status, stdout, stderr).
"""

import fcntl
import os
import pty
import re
import signal
import struct
import subprocess
import sys
import termios
import threading
import time

import pytest

DEADLINE = 300.0  # seconds: a cold numba cache on a loaded machine is slow, a hang is not


def _default_sigint():
    """A child of a background job inherits SIGINT ignored; a user's terminal does not."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def vlights(*args):
    """The command line of ``vlights`` (the installed entry point's code, display.__main__)."""
    return [sys.executable, "-m", "display", *map(str, args)]


class Child:
    def __init__(self, argv, terminal=True, python_flags=()):
        if python_flags:
            argv = [argv[0], *python_flags, *argv[1:]]
        if terminal:
            reader, writer = pty.openpty()
            fcntl.ioctl(writer, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 160, 0, 0))
        else:
            reader, writer = os.pipe()
        self._reader = reader
        self._chunks = []
        self._changed = threading.Condition()
        self._done = False
        try:
            self.proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=writer,
                                         preexec_fn=_default_sigint)
        finally:
            os.close(writer)
        self._out = []
        self._threads = [threading.Thread(target=self._drain, daemon=True),
                         threading.Thread(target=lambda: self._out.append(self.proc.stdout.read()), daemon=True)]
        for thread in self._threads:
            thread.start()

    def _drain(self):
        while True:
            try:
                data = os.read(self._reader, 65536)
            except OSError:  # a pseudo-terminal whose other end is closed: EIO
                data = b""
            with self._changed:
                if not data:
                    self._done = True
                    self._changed.notify_all()
                    break
                self._chunks.append(data)
                self._changed.notify_all()

    @property
    def stderr(self):
        with self._changed:
            text = b"".join(self._chunks).decode(errors="replace")
        return text.replace("\r\n", "\n")

    def wait_for(self, pattern, timeout=DEADLINE):
        """Block until the stderr so far matches ``pattern``; returns the match."""
        expression = re.compile(pattern)
        end = time.monotonic() + timeout
        with self._changed:
            while True:
                found = expression.search(b"".join(self._chunks).decode(errors="replace"))
                if found:
                    return found
                if self._done or time.monotonic() > end:
                    break
                self._changed.wait(min(1.0, max(end - time.monotonic(), 0.01)))
        try:  # stderr closed: the child is ending
            code = self.proc.wait(timeout=10) if self._done else self.proc.poll()
        except subprocess.TimeoutExpired:
            code = None
        self.kill()
        pytest.fail(f"never saw {pattern!r} ({'exit status ' + str(code) if code is not None else 'timed out'}); "
                    f"stderr: {self.stderr[-2000:]!r}")

    def send(self, signum):
        self.proc.send_signal(signum)

    def finish(self, timeout=120):
        """(exit status, stdout, stderr) once the child has exited."""
        try:
            code = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise
        for thread in self._threads:
            thread.join(timeout=30)
        os.close(self._reader)
        out = self._out[0].decode(errors="replace") if self._out else ""
        return code, out, self.stderr

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
