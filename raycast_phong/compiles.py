"""Who hears that a kernel is about to compile, before it does: numba's cache, on a miss for the very signature
asked (jit._CacheLoadedAsIs, jit._NothingCached), tells the innermost listener here, so no compile is silent:
a float64 call after float32 ones is a miss too. No numba import here: the CLI listens from its start at no cost.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

_listeners: list[Callable[[str, str], None]] = []


def compiling(name: str, signature: object) -> None:
    """Kernel `name` is about to compile for `signature` (it is not in the cache): tell the innermost listener."""
    if _listeners:
        _listeners[-1](name, str(signature))


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
