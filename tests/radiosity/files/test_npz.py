"""The one npz reader/writer of both file formats."""

import json

import numpy as np
import pytest

from radiosity.files.errors import InputError
from radiosity.files.npz import file_format, open_archive, write_archive


def test_round_trip_and_format(tmp_path):
    path = tmp_path / "x.npz"
    write_archive(path, {"format": "vlights.fit", "version": 1, "n": np.int64(3)}, {"a/b": np.arange(6).reshape(2, 3)})
    assert file_format(path) == "vlights.fit"
    with open_archive(path, "vlights.fit", (1,)) as archive:
        assert archive.meta["n"] == 3
        assert archive.array("a/b", "iu", (None, 3)).shape == (2, 3)
        with pytest.raises(InputError, match=r"'a/b' has shape \(2, 3\), expected \(N, 4\)"):
            archive.array("a/b", "iu", (None, 4))
        with pytest.raises(InputError, match="'a/b' has dtype int64, expected numbers"):
            archive.array("a/b", "f")
        with pytest.raises(InputError, match="no 'c' array"):
            archive.array("c")


def test_meta_must_be_strict_json(tmp_path):
    with pytest.raises(ValueError):
        write_archive(tmp_path / "x.npz", {"format": "f", "bad": float("inf")}, {})
    assert list(tmp_path.iterdir()) == []


def test_what_a_file_is(tmp_path):
    (tmp_path / "text.npz").write_text("hello")
    assert file_format(tmp_path / "text.npz") is None
    np.savez(tmp_path / "nometa.npz", a=np.zeros(2))
    assert file_format(tmp_path / "nometa.npz") is None
    np.savez(tmp_path / "listmeta.npz", meta=np.array(json.dumps([1, 2])))
    assert file_format(tmp_path / "listmeta.npz") is None
    with pytest.raises(InputError, match="not found"):
        file_format(tmp_path / "missing.npz")


@pytest.mark.parametrize(
    "meta, fragment",
    [
        ({"format": "vlights.solution", "version": 1}, "format 'vlights.solution', expected 'vlights.fit': it is a solution file"),
        ({"format": "vlights.fit", "version": 7}, "version 7 is not supported"),
        ({"format": "vlights.fit", "version": True}, "version True is not supported"),
        (["not", "an", "object"], "'meta' is a JSON list"),
    ],
)
def test_wrong_files_are_refused(tmp_path, meta, fragment):
    path = tmp_path / "x.npz"
    np.savez(path, meta=np.array(json.dumps(meta)))
    with pytest.raises(InputError) as info:
        open_archive(path, "vlights.fit", (1, 2))
    assert fragment in str(info.value) and "\n" not in str(info.value)
