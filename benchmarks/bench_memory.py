"""Peak memory of one render, measured in a fresh process (issue 2: 4000×4000 under 1.5 GB).

Usage: python benchmarks/bench_memory.py [--size 4000] [--output out.exr]
Prints the peak resident set size of the process (ru_maxrss) after import, and after the render
(and the write, if --output is given), so the render's own share is visible.
"""

from __future__ import annotations

import argparse
import resource
import time

from bench_frame import benchmark_scene

import raycast_phong as rp


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux reports KiB


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=4000)
    parser.add_argument("--output", default=None)
    args = parser.parse_args()
    rp.render(benchmark_scene(16))  # numba kernels loaded, so their memory counts as the baseline
    baseline = peak_mib()
    start = time.perf_counter()
    result = rp.render(benchmark_scene(args.size))
    seconds = time.perf_counter() - start
    after_render = peak_mib()
    if args.output:
        rp.write_image(args.output, result.image, colour=result.colour)
    print(f"{args.size}×{args.size}: {seconds:.2f} s; peak RSS {baseline:.0f} MiB after imports, "
          f"{after_render:.0f} MiB after the render" + (f", {peak_mib():.0f} MiB after writing {args.output}"
                                                        if args.output else "")
          + f"; the image alone is {result.image.nbytes / 2**20:.0f} MiB")


if __name__ == "__main__":
    main()
