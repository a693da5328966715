"""One exception tree: every error (Exception) the package defines derives from errors.RaycastPhongError, the public
ones are defined in errors.py alone, and its docstring draws every one of them."""

from __future__ import annotations

import ast
import importlib
import inspect
from pathlib import Path

import raycast_phong
from raycast_phong import errors

ROOT = Path(raycast_phong.__file__).parent
# Defined outside errors.py on purpose; shrinks only.
PENDING: set[str] = set()


def _exception_classes() -> dict[str, type]:
    """module.Class → the class, for every Exception class defined in the package's source (a BaseException
    that is a signal, batch.Interrupted, is no error and stands outside the tree)."""
    found = {}
    for path in ROOT.rglob("*.py"):
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        names = [node.name for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                 if isinstance(node, ast.ClassDef)]
        if not names:
            continue
        try:
            loaded = importlib.import_module(f"raycast_phong.{module}")
        except ImportError:  # an optional extra (the view's) is not installed here
            continue
        for name in names:
            value = getattr(loaded, name, None)
            if inspect.isclass(value) and issubclass(value, Exception) and value.__module__ == loaded.__name__:
                found[f"{module}.{name}"] = value
    return found


def test_every_exception_derives_from_the_one_base():
    classes = _exception_classes()
    assert "errors.SceneError" in classes and "scene.schema._KeyError" in classes
    outside = {name for name, cls in classes.items() if not issubclass(cls, errors.RaycastPhongError)}
    assert outside <= PENDING, sorted(outside - PENDING)
    assert PENDING <= set(classes) and PENDING <= outside, "fixed: remove from PENDING"


def test_public_exceptions_are_defined_in_errors_alone():
    elsewhere = sorted(name for name in _exception_classes()
                       if not name.startswith("errors.") and not name.rsplit(".", 1)[1].startswith("_"))
    assert set(elsewhere) <= PENDING, elsewhere


def test_the_docstring_draws_every_class_of_the_tree():
    defined = [name for name, value in vars(errors).items()
               if inspect.isclass(value) and issubclass(value, BaseException) and value.__module__ == errors.__name__]
    assert len(defined) >= 10
    drawn = {line.split("─ ")[-1].split()[0] for line in errors.__doc__.splitlines() if "─ " in line}
    assert set(defined) - {"RaycastPhongError"} == drawn, (sorted(set(defined) - drawn), sorted(drawn - set(defined)))
    for name in defined:  # each hangs under its parent in the drawing: the parent's line comes first
        parent = getattr(errors, name).__bases__[0].__name__
        if name != "RaycastPhongError":
            assert errors.__doc__.index(f" {parent}") < errors.__doc__.index(f"─ {name}"), name


def test_the_branches_keep_the_builtin_classes_callers_catch():
    """`except ValueError` around scene loading and `except OSError` around writes still catch them."""
    assert issubclass(errors.SceneError, ValueError) and issubclass(errors.CorruptManifest, ValueError)
    assert issubclass(errors.WriteError, OSError) and issubclass(errors.ImageError, OSError)
    assert issubclass(errors.EmbreeError, RuntimeError)
    assert not issubclass(errors.BatchBusy, errors.ImageError)  # a busy folder is no image problem
    assert not issubclass(errors.OptionError, errors.SceneError)  # a missing Dask is no scene problem
