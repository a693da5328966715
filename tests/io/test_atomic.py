"""io/atomic.py: the data reaches the disk before the new name does, so a failure leaves the old file."""

from __future__ import annotations

import errno
import os

import pytest

from raycast_phong.io import atomic


def test_a_failing_fsync_raises_write_error_and_leaves_the_old_file(tmp_path, monkeypatch):
    """A full disk may show only at fsync (delayed allocation, NFS, quotas): the rename must not have
    happened yet, so the old file is still the one on disk, and no temporary file is left beside it."""
    target = tmp_path / "image.png"
    target.write_bytes(b"old")

    def full(descriptor):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(atomic.os, "fsync", full)
    with pytest.raises(atomic.WriteError, match="No space left on device"):
        atomic.write_bytes(target, b"new")
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["image.png"]


def test_the_file_is_synced_before_it_is_renamed(tmp_path, monkeypatch):
    """The order a crash needs: fsync of the temporary file, then the rename over the target."""
    events: list[str] = []
    fsync, replace = os.fsync, os.replace
    monkeypatch.setattr(atomic.os, "fsync", lambda fd: events.append("fsync") or fsync(fd))
    monkeypatch.setattr(atomic.os, "replace", lambda a, b: events.append("replace") or replace(a, b))
    atomic.write_bytes(tmp_path / "a.bin", b"data")
    assert events == ["fsync", "replace"]
    assert (tmp_path / "a.bin").read_bytes() == b"data"


@pytest.mark.parametrize("name", ["SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"])
def test_a_stop_signal_during_a_write_waits_for_it_and_leaves_no_temporary(tmp_path, name):
    """A closed terminal (SIGHUP) during render's write left its hidden temporary file: every stop signal is
    held while the temporary exists, then delivered (the process ends by it, the file whole in place)."""
    import signal
    import subprocess
    import sys
    number = getattr(signal, name)
    code = ("import os, signal\nfrom pathlib import Path\nfrom raycast_phong.io.atomic import replaced_atomically\n"
            f"signal.signal({number}, signal.SIG_DFL)\n"
            f"with replaced_atomically(Path({str(tmp_path / 'out.txt')!r}), '.out-') as temporary:\n"
            "    temporary.write_text('whole')\n"
            f"    os.kill(os.getpid(), {number})\n"
            "print('after the signal')\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == -number, (done.returncode, done.stderr)
    assert "after the signal" not in done.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]
    assert (tmp_path / "out.txt").read_text() == "whole"


def test_a_reason_of_several_lines_is_worded_in_its_first_line(tmp_path):
    """A write failure is one line (the file, the reason's first line, what is on disk): an OSError whose text
    runs over several lines (a library's report) keeps only its first, and no temporary file stays behind."""
    target = tmp_path / "out.txt"
    with pytest.raises(atomic.WriteError) as caught:
        with atomic.replaced_atomically(target, ".out-"):
            raise OSError("the first line\nthe second line")
    assert str(caught.value) == f"{target}: write failed: the first line (no file was written)"
    assert list(tmp_path.iterdir()) == []
