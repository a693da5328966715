"""Compile time on an empty kernel cache, as a new user meets it (issue 31).

    .venv/bin/python benchmarks/bench_compile.py [--rounds 2] [--serial]

first     the README's first command (`raycast-phong render -o default.png`, the default scene) on an empty cache:
          the `compile` seconds it reports (wall), and the CPU of the command and its children; per round.
          With --serial, each round also runs it pinned to one core (`taskset -c 0`: one core, so the frame kernel
          compiles in one process), interleaved with the two-core run, for the ratio.
hour      the first hour of use on one empty cache, in order: the default scene, `creases.toml --shading gouraud`,
          `mesh.toml` (a PLY), `meshes/dice.obj`, the default scene in float64, `meshes/still_life.glb` (textured
          glTF), `shadows.toml` (global mode). Per command: the `compile` it reports, the compile inside its file
          read (an OBJ's reader kernels: the `load` of a cold run less the `load` of a warm one), and how many
          compile notices it printed.
The load average is printed beside each figure. Targets (issue 31, a quiet 2-core machine): first ≤ 10 s of compile,
the hour ≤ 30 s in all, every compile announced.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = Path(sys.executable).parent / "raycast-phong"  # the installed command, as the README runs it
CLI = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-c", "from raycast_phong.cli import app; app()"]
HOUR = [["default.toml"], ["creases.toml", "--shading", "gouraud"], ["mesh.toml"], ["meshes/dice.obj"],
        ["default.toml", "--set", "render.precision=float64"], ["meshes/still_life.glb"], ["shadows.toml"]]


def load() -> str:
    return f"{os.getloadavg()[0]:.1f}"


def render(arguments: list[str], cache: str, pin: bool = False) -> dict:
    """One `render` run: its reported compile and load seconds, notices, wall and CPU (with children)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    command = (["taskset", "-c", "0"] if pin else []) + CLI + ["render", *arguments, "-o",
                                                               str(Path(cache) / "out.png")]
    done = subprocess.run(command, cwd=ROOT / "scenes", env=env, capture_output=True, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        sys.exit(f"render {' '.join(arguments)} failed:\n{done.stderr}")

    def seconds(name: str) -> float:
        found = re.search(rf"\b{name} ([0-9.]+)s", done.stdout)
        return float(found.group(1)) if found else 0.0

    return {"compile": seconds("compile"), "load": seconds("load"), "wall": wall,
            "cpu": after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime,
            "notices": sum(line.startswith("compiling") for line in done.stderr.splitlines())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--serial", action="store_true", help="also the first command pinned to one core")
    args = parser.parse_args()
    print(f"# {os.cpu_count()} CPUs; {sys.version.split()[0]}")
    for round_ in range(args.rounds):
        for pin in ((False, True) if args.serial else (False,)):
            cache = tempfile.mkdtemp(prefix="bench-compile-")
            try:
                at = load()
                run = render([], cache, pin)
                print(f"first{' (one core)' if pin else ''} round {round_ + 1}: compile {run['compile']:.1f} s, "
                      f"wall {run['wall']:.1f} s, CPU {run['cpu']:.1f} s, notices {run['notices']}  "
                      f"[load {at} -> {load()}]")
            finally:
                shutil.rmtree(cache, ignore_errors=True)
    cache = tempfile.mkdtemp(prefix="bench-compile-")
    try:
        total = cpu = 0.0
        for arguments in HOUR:
            at = load()
            cold = render(arguments, cache)
            warm = render(arguments, cache)
            read = max(0.0, cold["load"] - warm["load"])
            total += cold["compile"] + read
            cpu += cold["cpu"]
            print(f"hour: {' '.join(arguments):45s} compile {cold['compile']:5.1f} s + in the read {read:4.1f} s, "
                  f"notices {cold['notices']}  [load {at}]")
        print(f"hour: {total:.1f} s of compile in all (CPU of the cold commands {cpu:.1f} s)  [load {load()}]")
    finally:
        shutil.rmtree(cache, ignore_errors=True)


if __name__ == "__main__":
    main()
