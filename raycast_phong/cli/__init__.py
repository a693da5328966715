"""The raycast-phong command line: parses and prints; the package does the work.

One module per command group, each registering its commands on the one app (common.app): render (render,
plan), compare (side-by-side, compare), accuracy (reference, study, stability), batch, view, scene (scene,
schema). Importing them here, in this order, is what assembles the app and orders its --help.
"""

# isort: off
from . import render, compare, accuracy, batch, view, scene  # noqa: F401  (each registers its commands)
# isort: on
from .common import app

__all__ = ["app"]
