"""A module imported at its first use, for libraries only some scenes need (trimesh: mesh files only).

    trimesh = OnFirstUse("trimesh")   # then trimesh.load(...), isinstance(x, trimesh.Trimesh) as usual

Importing trimesh costs 0.2–0.3 s, more than the rest of a small render; a stand-in keeps the module's
`trimesh.` calls (and tests that monkeypatch them) as they are. importlib's import lock makes the first
use from two threads safe, and later uses cost one dictionary look-up.
"""

from __future__ import annotations

import importlib


class OnFirstUse:
    """Stands for module `name`: the first attribute looked up imports it."""

    def __init__(self, name: str):
        self._name = name

    def __getattr__(self, attribute: str):
        return getattr(importlib.import_module(self._name), attribute)
