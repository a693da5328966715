"""An unwritable kernel cache (a read-only install and home) made every run compile the kernels again, about
15 s, while saying it happens "once after an install" (issue 21, item 7): a private folder in the temporary
folder is the last fallback, used only when this user owns it and no one else can write it.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest

from raycast_phong import jit


@pytest.fixture
def unwritable(tmp_path, monkeypatch):
    """The package's __pycache__ and the user's cache folder both under a regular file: not even root can
    make a folder there."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setattr(jit, "OWN_CACHE", blocker / "pycache")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker / "cache"))
    monkeypatch.setattr(jit.numba.config, "CACHE_DIR", "")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    jit.cache_folder.cache_clear()
    yield tmp_path / "tmp"
    jit.cache_folder.cache_clear()


def test_an_unwritable_cache_falls_back_to_a_private_temporary_folder(unwritable):
    folder = jit.cache_folder()
    assert folder is not None and folder.parent == unwritable / f"raycast-phong-{os.getuid()}"
    assert not os.stat(folder.parent).st_mode & 0o077


def test_a_temporary_folder_others_can_write_is_not_used(unwritable):
    shared = unwritable / f"raycast-phong-{os.getuid()}"
    shared.mkdir()
    shared.chmod(0o777)
    assert jit.cache_folder() is None


def test_the_usual_folder_comes_first(tmp_path, monkeypatch):
    monkeypatch.setattr(jit.numba.config, "CACHE_DIR", str(tmp_path / "mine"))
    jit.cache_folder.cache_clear()
    try:
        assert Path(jit.cache_folder()).parent == tmp_path / "mine"
    finally:
        jit.cache_folder.cache_clear()


TINY = """
from raycast_phong.jit import kernel


@kernel()
def plus_one(x):
    return x + 1
"""
CALL = """
import sys
sys.path.insert(0, sys.argv[1])
from raycast_phong.compiles import told
import tiny
with told(lambda name, signature: print("compiling", name)):
    print(tiny.plus_one(41))
"""


TWO = """
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from raycast_phong.compiles import told
import tiny
with told(lambda name, signature: print("compiling", name)):
    print(tiny.plus_one(np.arange(3)).tolist(), tiny.plus_one(np.full(2, 0.5, np.float32)).tolist())
"""


@pytest.mark.slow
def test_an_entry_holding_another_signature_s_code_is_compiled_over(tmp_path):
    """Two processes compiling two signatures of a kernel at once (pytest's workers, the split compile's helper)
    both named their data file `.1.nbc` from the index each had read, so one signature's entry held the other's
    code, and every later call failed with numba's "can't unbox array" (a fresh clone's CI: 89 tests). Here the
    two data files are swapped by hand, as the race leaves them: the entries are compiled over, then loaded."""
    import subprocess
    import sys
    (tmp_path / "tiny.py").write_text(TINY, encoding="utf-8")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run() -> str:
        done = subprocess.run([sys.executable, "-c", TWO, str(tmp_path)], capture_output=True, text=True, env=env,
                              timeout=300)
        assert done.returncode == 0 and not done.stderr, done.stderr
        return done.stdout

    assert "compiling" in run()
    data = sorted((tmp_path / "cache").rglob("tiny.plus_one-*.nbc"))
    assert len(data) == 2
    first, second = (path.read_bytes() for path in data)
    data[0].write_bytes(second)
    data[1].write_bytes(first)
    out = run()
    assert "compiling" in out and out.strip().endswith("[1, 2, 3] [1.5, 1.5]"), out
    assert run().strip() == "[1, 2, 3] [1.5, 1.5]"  # loaded, as compiled over


@pytest.mark.slow
def test_a_corrupt_kernel_cache_is_compiled_over_and_then_loaded(tmp_path):
    """The kernel cache is input: a truncated data file, an empty index or random bytes gave `internal error` on
    every later run, for good (issue 50). Now the entry that does not load is removed and the kernel compiles over
    it, announced; the next process loads the new entry."""
    import subprocess
    import sys
    (tmp_path / "tiny.py").write_text(TINY, encoding="utf-8")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run() -> list[str]:
        done = subprocess.run([sys.executable, "-c", CALL, str(tmp_path)], capture_output=True, text=True, env=env,
                              timeout=300)
        assert done.returncode == 0 and not done.stderr, done.stderr
        return done.stdout.split()

    assert run() == ["compiling", "tiny.plus_one", "42"]  # the first run compiles
    assert run() == ["42"]  # the control: loaded
    damages = {"truncated data": lambda path: path.write_bytes(path.read_bytes()[:100]) if path.suffix == ".nbc" else 0,
               "empty index": lambda path: path.write_bytes(b"") if path.suffix == ".nbi" else 0,
               "random bytes": lambda path: path.write_bytes(os.urandom(3000))}
    for damage, spoil in damages.items():
        for path in (tmp_path / "cache").rglob("tiny.plus_one-*"):
            spoil(path)
        assert run() == ["compiling", "tiny.plus_one", "42"], damage
        assert run() == ["42"], damage


def test_a_missing_home_folder_is_not_made_for_the_cache(tmp_path, monkeypatch):
    """Run as a user whose HOME does not exist, the cache's fallback made that home folder (its
    .cache/raycast-phong with parents=True, issue 50): nothing is made outside the user's own cache folder, and the
    private temporary folder serves instead."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setattr(jit, "OWN_CACHE", blocker / "pycache")  # the package's own cache unwritable
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "gone" / "home"))
    monkeypatch.setattr(jit.numba.config, "CACHE_DIR", "")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    jit.cache_folder.cache_clear()
    try:
        folder = jit.cache_folder()
        assert folder is not None and folder.parent == tmp_path / "tmp" / f"raycast-phong-{os.getuid()}"
        assert not (tmp_path / "gone").exists()
    finally:
        jit.cache_folder.cache_clear()


@pytest.mark.parametrize(("mode", "used"), [(0o700, True), (0o755, True), (0o770, False), (0o707, False),
                                            (0o777, False)])
def test_the_private_cache_folder_is_used_only_if_no_one_else_can_write_it(tmp_path, monkeypatch, mode, used):
    """numba's cache holds code this process loads: a raycast-phong-<uid> folder that the group or others may
    write (made so before this user's first run, or changed since) is never used."""
    monkeypatch.setattr(jit.tempfile, "gettempdir", lambda: str(tmp_path))
    folder = tmp_path / f"raycast-phong-{os.getuid()}"
    folder.mkdir()
    folder.chmod(mode)
    assert (jit._private_temporary() == folder) is used
