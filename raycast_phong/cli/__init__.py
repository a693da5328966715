"""The raycast-phong command line: parses and prints; the package does the work.

One module per command group, each registering its commands on the one app (common.app): render (render,
plan), compare (side-by-side, compare), accuracy (reference, study, stability), batch, view, scene (scene,
schema). Importing them here, in this order, is what assembles the app and orders its --help. `main` is the
program (the console script): app() and an exit without the interpreter's teardown (common.main).
"""

import sys

if sys.argv[1:2] == ["batch"]:  # the program, started as `raycast-phong batch`
    from raycast_phong import stops
    stops.listen()  # a signal in the first seconds (the imports below) is recorded, then acted on by the batch

# isort: off
from . import render, compare, accuracy, batch, view, scene  # noqa: F401  (each registers its commands)
# isort: on
from .common import app, main

__all__ = ["app", "main"]
