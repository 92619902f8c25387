"""The one atomic writer: all or nothing, and the first error is the one raised."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from viewcomp.calib.io import atomic
from viewcomp.calib.io.atomic import (
    AtomicFile,
    atomic_open,
    atomic_path,
    write_bytes_atomic,
    write_text_atomic,
)


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_success_replaces_the_target_and_leaves_nothing_else(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    target.write_text("old")
    write_text_atomic(target, "new")
    assert target.read_text() == "new"
    with atomic_path(tmp_path / "v.mp4") as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".mp4" and tmp.name.startswith(".")
        tmp.write_bytes(b"video")
    assert (tmp_path / "v.mp4").read_bytes() == b"video"
    assert _names(tmp_path) == ["out.txt", "v.mp4"]
    assert (tmp_path / "v.mp4").stat().st_mode & 0o777 == 0o666 & ~atomic._umask()


@pytest.mark.parametrize("kind", ["stream", "path"])
def test_failure_inside_the_block_leaves_nothing(tmp_path: Path, kind: str) -> None:
    target = tmp_path / "new.bin"
    with pytest.raises(RuntimeError, match="boom"):
        if kind == "stream":
            with atomic_open(target) as f:
                f.write(b"half")
                raise RuntimeError("boom")
        else:
            with atomic_path(target) as tmp:
                tmp.write_bytes(b"half")
                raise RuntimeError("boom")
    assert _names(tmp_path) == []


def test_interrupt_leaves_the_old_content(tmp_path: Path) -> None:
    target = tmp_path / "keep.txt"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_open(target) as f:
        f.write(b"half")
        raise KeyboardInterrupt
    assert target.read_text() == "old"
    assert _names(tmp_path) == ["keep.txt"]


def test_failed_rename_or_sync_keeps_the_old_content(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "keep.txt"
    target.write_text("old")

    def disk_full(*args: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    with pytest.raises(OSError, match="No space left"):
        write_bytes_atomic(target, b"new")
    monkeypatch.undo()
    monkeypatch.setattr(os, "replace", disk_full)
    with pytest.raises(OSError, match="No space left"):
        write_bytes_atomic(target, b"new")
    monkeypatch.undo()
    assert target.read_text() == "old"
    assert _names(tmp_path) == ["keep.txt"]


def test_first_error_is_kept_when_the_clean_up_fails_too(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A folder that turned read-only: the write fails (disk full), then removing the
    temporary file fails as well; the disk-full error is raised, the clean-up's is a note."""
    target = tmp_path / "keep.txt"
    target.write_text("old")

    def read_only(self: Path, missing_ok: bool = False) -> None:
        raise PermissionError(errno.EROFS, "Read-only file system", str(self))

    monkeypatch.setattr(Path, "unlink", read_only)
    with pytest.raises(OSError, match="No space left") as info, atomic_open(target) as f:
        f.write(b"half")
        raise OSError(errno.ENOSPC, "No space left on device")
    assert not isinstance(info.value, PermissionError)
    notes = getattr(info.value, "__notes__", [])
    assert len(notes) == 1 and "could not be removed" in notes[0] and "Read-only" in notes[0]
    monkeypatch.undo()
    assert target.read_text() == "old"


def test_a_folder_that_cannot_take_the_file_raises_before_anything_is_written(
    tmp_path: Path,
) -> None:
    with pytest.raises(FileNotFoundError):
        write_text_atomic(tmp_path / "missing" / "x.txt", "x")
    assert _names(tmp_path) == []


def test_explicit_commit_and_discard(tmp_path: Path) -> None:
    done = AtomicFile(tmp_path / "a.txt")
    done.tmp.write_text("a")
    done.commit()
    with pytest.raises(RuntimeError, match="already finished"):
        done.commit()
    dropped = AtomicFile(tmp_path / "b.txt")
    dropped.tmp.write_text("b")
    dropped.discard()
    dropped.discard()  # a second discard does nothing
    assert _names(tmp_path) == ["a.txt"]
    assert (tmp_path / "a.txt").read_text() == "a"


def test_an_encoding_error_writes_nothing(tmp_path: Path) -> None:
    with pytest.raises(UnicodeEncodeError):
        write_text_atomic(tmp_path / "x.glsl", "caf\u00e9", encoding="ascii")
    assert _names(tmp_path) == []


def test_the_file_and_its_folder_are_synced(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    synced: list[str] = []
    real = os.fsync

    def spy(fd: int) -> None:
        synced.append("dir" if os.path.isdir(f"/proc/self/fd/{fd}") else "file")
        real(fd)

    monkeypatch.setattr(os, "fsync", spy)
    write_bytes_atomic(tmp_path / "x.bin", b"x")
    assert synced == ["file", "dir"]


@pytest.mark.parametrize("fail", [False, True])
def test_the_demo_clip_writer_is_atomic(tmp_path: Path, fail: bool) -> None:
    """The demo's video output goes through the atomic VideoWriter: a failure mid-encode leaves no
    partial file (it used to leave a `.part` file behind)."""
    import numpy as np

    from viewcomp.commands.demo import _write_frames

    frames: list = [np.zeros((16, 16, 3), np.uint8) for _ in range(3)]
    if fail:
        frames.append(np.zeros((16, 16), np.float32))  # PyAV refuses it mid-stream
        with pytest.raises((ValueError, TypeError)):
            _write_frames(tmp_path / "clip.mp4", frames, 25)
        assert _names(tmp_path) == []
    else:
        _write_frames(tmp_path / "clip.mp4", frames, 25)
        assert _names(tmp_path) == ["clip.mp4"] and (tmp_path / "clip.mp4").stat().st_size > 0


@pytest.mark.gl
def test_sigterm_mid_render_leaves_nothing_behind(tmp_path: Path) -> None:
    """`viewcomp render` terminated (SIGTERM) while it writes a video: exit status 143, one
    line saying so, and no partial file left in the output's folder."""
    import signal
    import subprocess
    import sys
    import time

    from tests.support.synthetic import smooth_frame, write_clip
    from viewcomp.cli import main

    assert main(["simulate", str(tmp_path / "caps"), "--size", "64x32"]) == 0
    assert main(["calibrate", str(tmp_path / "caps"), "-o", str(tmp_path / "m.vcb")]) == 0
    write_clip(str(tmp_path / "in.mp4"), [smooth_frame(64, 32, seed=i % 7) for i in range(900)], 30)
    out = tmp_path / "out"
    out.mkdir()
    p = subprocess.Popen(
        [sys.executable, "-m", "viewcomp", "render", str(tmp_path / "m.vcb"),
         str(tmp_path / "in.mp4"), "-o", str(out / "o.mp4"), "--angle", "60", "--backend",
         "cpu", "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not list(out.iterdir()) and time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.05)  # until the encoder has opened its partial file
    assert list(out.iterdir()), "the render never started writing"
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143, err
    assert "viewcomp render: terminated" in err
    assert list(out.iterdir()) == []
