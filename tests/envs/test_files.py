"""envs.files: a file appears whole or not at all, with the permissions an ordinary open
would give it, and leaves no temporary file behind."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from ikbranch_gym.envs.files import write_all_atomically, write_atomically


@pytest.fixture
def umask():
    """Set the process's umask for one test (put back after it)."""
    before = os.umask(0o022)
    os.umask(before)

    def set_umask(value: int) -> None:
        os.umask(value)

    yield set_umask
    os.umask(before)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_text_bytes_and_a_saving_function_are_written_as_given(tmp_path):
    text = tmp_path / "a.csv"
    assert write_atomically(text, "x,y\r\n1,2\nü\n") == text
    assert text.read_bytes() == "x,y\r\n1,2\nü\n".encode()  # UTF-8, newlines untouched
    data = tmp_path / "b.bin"
    write_atomically(str(data), b"\x00\xff")
    assert data.read_bytes() == b"\x00\xff"
    given = []

    def save(path: str) -> None:  # as a library's save(path) does: opens the path itself
        given.append(path)
        with open(path, "wb") as stream:
            stream.write(b"saved")

    model = tmp_path / "model.zip"
    write_atomically(model, save)
    assert model.read_bytes() == b"saved"
    # The function wrote a temporary file beside the target, not the target itself.
    assert Path(given[0]).parent == tmp_path and Path(given[0]) != model
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.bin", "model.zip"]


def test_an_existing_file_is_replaced(tmp_path):
    path = tmp_path / "record.json"
    path.write_text("old, and longer than the new content\n")
    write_atomically(path, "new\n")
    assert path.read_text() == "new\n"
    assert [p.name for p in tmp_path.iterdir()] == ["record.json"]


class Failure(Exception):
    pass


@pytest.mark.parametrize("existing", [True, False])
def test_a_failing_writer_leaves_the_target_untouched_and_no_temporary_file(tmp_path,
                                                                          existing):
    path = tmp_path / "latest.zip"
    if existing:
        path.write_bytes(b"the previous checkpoint")

    def half_then_fail(temporary: str) -> None:
        Path(temporary).write_bytes(b"half a check")
        raise Failure

    with pytest.raises(Failure):
        write_atomically(path, half_then_fail)
    if existing:
        assert path.read_bytes() == b"the previous checkpoint"
        assert [p.name for p in tmp_path.iterdir()] == ["latest.zip"]
    else:
        assert list(tmp_path.iterdir()) == []
    with pytest.raises(UnicodeEncodeError):  # content that cannot be written
        write_atomically(path, "\udcff")
    assert path.exists() == existing and len(list(tmp_path.iterdir())) == int(existing)


def test_several_files_appear_all_or_none(tmp_path):
    first, second = tmp_path / "plan.csv", tmp_path / "plan.json"
    first.write_text("previous\n")

    def fail(temporary: str) -> None:
        raise Failure

    with pytest.raises(Failure):
        write_all_atomically({first: "new\n", second: b"{}", tmp_path / "plan.gif": fail})
    assert first.read_text() == "previous\n" and not second.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["plan.csv"]
    assert write_all_atomically({first: "new\n", second: b"{}"}) == [first, second]
    assert first.read_text() == "new\n" and second.read_bytes() == b"{}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.csv", "plan.json"]


@pytest.mark.parametrize(("mask", "mode", "expected"),
                         [(0o022, 0o666, 0o644), (0o027, 0o666, 0o640), (0o002, 0o666, 0o664),
                          (0o022, 0o600, 0o600), (0o077, 0o666, 0o600)])
def test_a_new_file_gets_the_mode_an_open_would_give(tmp_path, umask, mask, mode, expected):
    umask(mask)
    path = write_atomically(tmp_path / "new.txt", "x", mode=mode)
    ordinary = tmp_path / "ordinary.txt"
    ordinary.write_text("x")
    assert _mode(path) == expected
    if mode == 0o666:
        assert _mode(path) == _mode(ordinary)
    # Also for files written by a function (it writes into the file it is given).
    saved = write_atomically(tmp_path / "saved.zip", lambda p: Path(p).write_bytes(b"z"))
    assert _mode(saved) == 0o666 & ~mask


def test_an_existing_file_keeps_its_permissions(tmp_path, umask):
    umask(0o022)
    path = tmp_path / "plan.csv"
    path.write_text("old\n")
    path.chmod(0o640)
    write_atomically(path, "new\n")
    assert _mode(path) == 0o640 and path.read_text() == "new\n"
    path.chmod(0o666)  # wider than the umask allows a new file: kept, as open() keeps it
    write_atomically(path, "newer\n")
    assert _mode(path) == 0o666


def test_the_content_is_flushed_to_disk_before_the_rename(tmp_path, monkeypatch):
    events = []
    fsync, replace = os.fsync, os.replace

    def spy_fsync(fd: int) -> None:
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")
                       if os.path.exists("/proc/self/fd") else fd))
        fsync(fd)

    def spy_replace(source, target) -> None:
        events.append(("replace", str(target)))
        replace(source, target)

    monkeypatch.setattr(os, "fsync", spy_fsync)
    monkeypatch.setattr(os, "replace", spy_replace)
    path = tmp_path / "evaluation.json"
    write_atomically(path, "{}\n")
    kinds = [kind for kind, _ in events]
    assert kinds.index("fsync") < kinds.index("replace") == 1
    assert events[1] == ("replace", str(path))


def test_a_relative_path_and_a_directory_in_the_way(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert write_atomically("here.txt", "x") == Path("here.txt")
    assert (tmp_path / "here.txt").read_text() == "x"
    (tmp_path / "folder").mkdir()
    with pytest.raises(OSError):
        write_atomically("folder", "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder", "here.txt"]
    assert list((tmp_path / "folder").iterdir()) == []
