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
