"""Who hears that a kernel is about to compile, before it does: numba's cache, on a miss for the very signature
asked (jit._CacheLoadedAsIs, jit._NothingCached), tells the innermost listener here, so no compile is silent:
a float64 call after float32 ones is a miss too. No numba import here: the CLI listens from its start at no cost.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

_listeners: list[Callable[[str, str], None]] = []
# What a compile notice calls the kernels of a first kernel that misses the cache, by its module and name (the
# first match); the shading kernels' (the renderer's, 13-18 s of CPU) are the rest: `part(name)` is None for them.
PARTS = (("renderer.kernels.shadows.no_shadow_rays", None),  # local mode's stand-in: the shading kernels' part
         ("renderer.kernels.shadows", "the shadow rays' kernels (global mode)"),
         ("crease", "the crease split's kernels"),
         ("geometry.", "the mesh preparation's kernels (merge, winding)"),
         (".io.", "the mesh reader's kernels"))
# Seconds spent compiling in this process: from a kernel's cache miss to its compiled code's save, a compile that
# compiles its callees within it counted once (the outermost). A command reports it as `compile`, whatever stage
# it happened in (a mesh reader's kernels compile while the scene loads).
_open = [0, 0.0]  # compiles under way, and when the outermost began
_spent = [0.0]


def part(name: str) -> str | None:
    """PARTS' words for kernel `name` (module.function), or None for the renderer's shading kernels."""
    return next((words for key, words in PARTS if key in name), None)


def compiling(name: str, signature: object) -> None:
    """Kernel `name` is about to compile for `signature` (it is not in the cache): tell the innermost listener."""
    if _open[0] == 0:
        _open[1] = time.perf_counter()
    _open[0] += 1
    if _listeners:
        _listeners[-1](name, str(signature))


def compiled() -> None:
    """A kernel's compile finished (numba saves it to the cache)."""
    if _open[0] > 0:
        _open[0] -= 1
        if _open[0] == 0:
            _spent[0] += time.perf_counter() - _open[1]


def seconds_compiling() -> float:
    """Seconds this process has spent compiling kernels so far (compiling ... compiled)."""
    return _spent[0]


@contextmanager
def told(listener: Callable[[str, str], None]) -> Iterator[list[str]]:
    """Within the block, `listener(kernel name, signature)` hears the first kernel numba is about to compile,
    before it compiles (once: the rest compile with it); yields the list of every kernel heard."""
    heard: list[str] = []

    def hear(name: str, signature: str) -> None:
        if not heard:
            listener(name, signature)
        heard.append(name)

    _listeners.append(hear)
    try:
        yield heard
    finally:
        _listeners.remove(hear)
