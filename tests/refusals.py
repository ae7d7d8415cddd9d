"""What every test of a refusal checks, in one place: an ``InputError`` of one line that
names what it should (``input_error``), or a command that exits 2 with one line on
stderr and no traceback (``assert_refused``)."""

import time

import pytest

from radiosity.files.errors import InputError


def input_error(call, *fragments, names=None, within=None):
    """The message of the ``InputError`` that ``call()`` raises: one line, holding
    ``names`` (the file it is about) and every fragment, raised within ``within`` seconds."""
    start = time.perf_counter()
    with pytest.raises(InputError) as info:
        call()
    if within is not None:
        assert time.perf_counter() - start < within
    message = str(info.value)
    assert "\n" not in message and "\r" not in message, message
    if names is not None:
        assert names in message, message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message


def assert_refused(result, *fragments, command=None, quiet=True):
    """A command's (exit status, stdout, stderr): status 2, one line on stderr holding
    every fragment and no traceback, nothing on stdout where ``quiet``; ``command``: the
    line starts with "vlights COMMAND: error: ". Returns stderr."""
    code, out, err = result
    assert code == 2, (code, out, err)
    if quiet:
        assert out == "", out
    assert err.count("\n") == 1 and "Traceback" not in err, err
    if command is not None:
        assert err.startswith(f"vlights {command}: error: "), err
    for fragment in fragments:
        assert fragment in err, (fragment, err)
    return err
