"""Output paths and atomic writes: refused before the work when they cannot be
written, cleaned up when writing fails half-way, never the input file."""

import errno
import os

import pytest

from radiosity.files.atomic import OutputError, atomic_output, check_output
from radiosity.files.errors import InputError


def test_a_good_path_is_returned(tmp_path):
    assert check_output(tmp_path / "a.npz", ".npz") == tmp_path / "a.npz"


@pytest.mark.parametrize("case", ["directory", "missing parent", "parent is a file", "suffix"])
def test_bad_outputs_are_refused_in_one_line(tmp_path, case):
    (tmp_path / "file").write_text("x")
    (tmp_path / "dir.npz").mkdir()
    path, fragment = {
        "directory": (tmp_path / "dir.npz", "is a directory"),
        "missing parent": (tmp_path / "nowhere" / "a.npz", "does not exist"),
        "parent is a file": (tmp_path / "file" / "a.npz", "is a file, not a directory"),
        "suffix": (tmp_path / "a.txt", "must end in .npz"),
    }[case]
    with pytest.raises(InputError) as info:
        check_output(path, ".npz", flag="-o")
    message = str(info.value)
    assert fragment in message and message.startswith("-o ") and "\n" not in message


def test_an_unwritable_directory_is_refused(tmp_path, monkeypatch):
    # root may write anywhere, so the permission answer is what is checked here
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if os.fspath(p) == os.fspath(tmp_path) else real(p, mode))
    with pytest.raises(InputError, match="permission denied"):
        check_output(tmp_path / "a.npz", ".npz")


def test_the_input_is_never_the_output(tmp_path):
    source = tmp_path / "s.npz"
    source.write_bytes(b"data")
    link = tmp_path / "link.npz"
    link.symlink_to(source)
    for same in (source, link, tmp_path / "." / "s.npz"):
        with pytest.raises(InputError, match="is the input file"):
            check_output(same, ".npz", inputs=(source,))
    check_output(tmp_path / "other.npz", ".npz", inputs=(source,))  # a different file is fine


def test_a_full_disk_is_one_line_and_leaves_nothing(tmp_path):
    target = tmp_path / "a.npy"

    def full(*_args, **_kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OutputError) as info:
        with atomic_output(target) as f:
            f.write(b"partial")
            full()
    assert "No space left on device" in str(info.value) and str(target) in str(info.value)
    assert isinstance(info.value, InputError) and isinstance(info.value, OSError)
    assert list(tmp_path.iterdir()) == []


def test_a_device_is_never_replaced(tmp_path):
    # the rename would replace /dev/null itself (as root, it can)
    with pytest.raises(InputError, match="not a regular file"):
        check_output("/dev/null")
    with pytest.raises(OutputError, match="not a regular file"):
        with atomic_output("/dev/null") as f:
            f.write(b"x")
    assert os.path.exists("/dev/null") and not os.path.isfile("/dev/null")


def test_an_interrupt_while_writing_keeps_the_old_file(tmp_path):
    target = tmp_path / "a.bin"
    target.write_bytes(b"old")
    with pytest.raises(KeyboardInterrupt):
        with atomic_output(target) as f:
            f.write(b"new, partial")
            raise KeyboardInterrupt
    assert target.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.bin"]


def test_the_longest_name_the_file_system_takes_is_written(tmp_path):
    # the temporary name used to be 18 characters longer than the name: a valid
    # 249-character output was refused only after the whole solve
    for length in (237, 238, 249, 255):
        name = "s" * (length - 4) + ".npz"
        check_output(tmp_path / name, ".npz")
        with atomic_output(tmp_path / name) as f:
            f.write(b"x")
        assert (tmp_path / name).read_bytes() == b"x"
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_a_name_longer_than_the_file_system_takes_is_refused_up_front(tmp_path):
    with pytest.raises(InputError, match="256 bytes long, more than the 255"):
        check_output(tmp_path / ("s" * 252 + ".npz"), ".npz", flag="-o")
    assert list(tmp_path.iterdir()) == []


def test_the_probe_leaves_nothing_and_a_nul_is_refused(tmp_path):
    check_output(tmp_path / "a.npz", ".npz")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError, match="NUL"):
        check_output(str(tmp_path / "a\0b.npz"), ".npz")


def test_a_symlink_output_writes_its_target(tmp_path):
    target = tmp_path / "real.npz"
    target.write_bytes(b"old")
    link = tmp_path / "link.npz"
    link.symlink_to(target)
    check_output(link, ".npz")
    with atomic_output(link) as f:
        f.write(b"new")
    assert link.is_symlink() and target.read_bytes() == b"new"
    dangling = tmp_path / "dangling.npz"
    dangling.symlink_to(tmp_path / "made.npz")
    check_output(dangling, ".npz")
    with atomic_output(dangling) as f:
        f.write(b"made")
    assert dangling.is_symlink() and (tmp_path / "made.npz").read_bytes() == b"made"
    nowhere = tmp_path / "nowhere.npz"
    nowhere.symlink_to(tmp_path / "missing" / "x.npz")
    with pytest.raises(InputError, match="a symlink to .*does not exist"):
        check_output(nowhere, ".npz")
