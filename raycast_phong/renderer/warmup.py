"""Have a scene's kernels ready before its render, so a frame's time (and the Mrays/s printed from it) holds
neither compilation nor loading from numba's cache."""

from __future__ import annotations

import time
from collections.abc import Callable

from ..scene.schema import Scene


def ready_kernels(scene: Scene, announce: Callable[[str], None] | None = None) -> tuple[str, float]:
    """("compile", seconds) when the cache does not hold this scene's kernels (the first render after an install
    or an edit; `announce` is told first, as it takes 10-30 s), else ("kernels", seconds) for loading them
    from the cache, most of it numba's one-time set-up in a process (≈ 0.25 s)."""
    from ..jit import compiled_before
    from .frame import tile_kernel, warm_kernels_for
    from .plan import build_plan
    cached = compiled_before(tile_kernel())
    if not cached and announce is not None:
        announce("compiling the shading kernels, once after an install or an edit (about 10-30 s)...")
    started = time.perf_counter()
    warm_kernels_for([build_plan(scene)])
    return ("kernels" if cached else "compile"), time.perf_counter() - started
