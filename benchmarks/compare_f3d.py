"""Our default picture of every corpus model against f3d's from the same camera: coverage and mean colour.

    .venv/bin/python benchmarks/compare_f3d.py [--manifest docs/figures/corpus.toml] [--root /work/corpus]
        [--table docs/meshes/f3d.csv] [--pictures DIR]

For each model of the manifest (docs/figures/corpus.toml, built by docs/figures/make_corpus.py):
  ours   render_file(MODEL) with the defaults at 200 × 150 (the framing camera, the key light, the format's
         colour setting), encoded as `raycast-phong render` writes the PNG; its coverage is the `face` layer ≥ 0
  f3d    the f3d package (`pip install f3d`, offscreen through EGL: f3d.Engine.create(True)) loads the same file
         and renders it from our camera (position, look-at point, up, vertical field of view) at the same size,
         with its own lights and materials (its defaults: a light kit, PBR shading, tone mapping off); its
         coverage is every pixel that differs from a background of pure magenta by more than 12 levels
and writes one row: the IoU of the two coverage masks (1 when both are empty), each picture's mean colour over
its own coverage (8-bit sRGB-encoded values), the distance between the two means (0..441) and the ratio of
their mean luminance. A row says `refused` for the side that could not read the file.
A large disagreement is an IoU below 0.8, a hue apart (the two means' chromaticities, r/(r+g+b) and g/(r+g+b),
more than 0.06 apart: a colour or texture one of them dropped) or a mean luminance ratio outside 0.4..2.5 (f3d's
light kit is brighter than our one key light: grey models read 0.6-0.8); docs/meshes.md explains each one.
--pictures DIR writes each pair side by side (NNN.png: ours left, f3d right) for a person's check.
--summary reads an existing --table and prints only the large disagreements.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import os
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
from PIL import Image

WIDTH, HEIGHT = 200, 150
MAGENTA = np.array([255, 0, 255])


def ours(model: Path, scratch: Path) -> tuple[np.ndarray, np.ndarray, object] | str:
    """Our picture (8-bit, as the CLI writes it), its coverage, and the scene's camera; or the refusal."""
    import raycast_phong as rp

    try:
        with open(os.devnull, "w") as quiet, contextlib.redirect_stderr(quiet), contextlib.redirect_stdout(quiet):
            scene = rp.load_scene(model, [f"render.width={WIDTH}", f"render.height={HEIGHT}",
                                          "output.aovs=['face']", "output.path='out.exr'"])
            result = rp.render(scene)
            png = rp.write_image(scratch / "ours.png", result.image, colour=result.colour)
    except (SystemExit, Exception) as error:  # noqa: BLE001 (any refusal or reader failure: its one line)
        return f"refused: {str(error).splitlines()[0] if str(error) else type(error).__name__}"
    pixels = np.asarray(Image.open(png).convert("RGB"))
    return pixels, result.aovs["face"][..., 0] >= 0, scene.camera


def f3d_picture(engine, model: Path, camera) -> tuple[np.ndarray, np.ndarray] | str:
    """f3d's picture of `model` from `camera` (ours) and its coverage; or why it could not read it."""
    try:
        engine.scene.clear()
        engine.scene.add(str(model))
    except Exception as error:  # noqa: BLE001 (f3d raises on a file it cannot read)
        return f"refused: {str(error).splitlines()[0] if str(error) else type(error).__name__}"
    view = engine.window.camera
    view.position, view.focal_point = tuple(camera.position), tuple(camera.look_at)
    view.view_up, view.view_angle = tuple(camera.up), float(camera.fov)
    image = engine.window.render_to_image()
    pixels = np.frombuffer(image.content, np.uint8).reshape(image.height, image.width, image.channel_count)[..., :3]
    pixels = pixels[::-1].copy()  # f3d's rows run bottom to top (OpenGL's order)
    covered = np.abs(pixels.astype(np.int16) - MAGENTA).max(axis=2) > 12
    return pixels, covered


def mean_colour(pixels: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """The mean 8-bit colour over the covered pixels (NaN when none is)."""
    return pixels[covered].mean(axis=0) if covered.any() else np.full(3, np.nan)


def luminance(colour: np.ndarray) -> float:
    return float(colour @ np.array([0.2126, 0.7152, 0.0722]))


def disagreement(row: dict) -> str:
    """Why a row is a large disagreement ("" when it is not)."""
    if row.get("iou", "") == "":
        return ""
    why = []
    if float(row["iou"]) < 0.8:
        why.append(f"IoU {float(row['iou']):.2f}")
    a, b = (np.array(row[k].split(), float) for k in ("mean_ours", "mean_f3d"))
    if np.isfinite(a).all() and np.isfinite(b).all() and a.sum() > 0 and b.sum() > 0:
        if np.abs(a[:2] / a.sum() - b[:2] / b.sum()).max() > 0.06:
            why.append(f"hue ({row['mean_ours']} against {row['mean_f3d']})")
        if not 0.4 <= float(row["luminance_ratio"]) <= 2.5:
            why.append(f"luminance ×{float(row['luminance_ratio']):.2f}")
    return ", ".join(why)


def summary(table: Path) -> None:
    """The large disagreements of a written table, one a line."""
    with table.open() as handle:
        rows = list(csv.DictReader(handle))
    both = [row for row in rows if row.get("iou")]
    large = [(row, disagreement(row)) for row in both if disagreement(row)]
    for row, why in large:
        print(f"{row['number']:>3} {row['path']}: {why}")
    print(f"{table}: {len(rows)} models, {len(both)} rendered by both, {len(large)} large disagreements; "
          f"f3d refused {sum(row['f3d'].startswith('refused') for row in rows)}")


def compare(entries: list[dict], root: Path, start: int, rows_file: Path, pictures: Path | None) -> None:
    """Compare entries[start:] one by one, appending each row to `rows_file` (JSON lines) as it is made."""
    import f3d

    f3d.Log.set_verbose_level(f3d.Log.VerboseLevel.QUIET)
    engine = f3d.Engine.create(True)
    engine.window.size = (WIDTH, HEIGHT)
    engine.options["render.background.color"] = [1.0, 0.0, 1.0]
    with tempfile.TemporaryDirectory() as scratch:
        for k in range(start, len(entries)):
            model = root / entries[k]["path"]
            mine = ours(model, Path(scratch))
            theirs = f3d_picture(engine, model, mine[2]) if not isinstance(mine, str) else "not tried"
            row = {"number": k, "path": entries[k]["path"], "ours": "ok" if not isinstance(mine, str) else mine,
                   "f3d": "ok" if not isinstance(theirs, str) else theirs}
            if not isinstance(mine, str) and not isinstance(theirs, str):
                (a, a_covered, _), (b, b_covered) = mine, theirs
                union = (a_covered | b_covered).sum()
                a_mean, b_mean = mean_colour(a, a_covered), mean_colour(b, b_covered)
                row |= {"iou": f"{(a_covered & b_covered).sum() / union if union else 1.0:.3f}",
                        "coverage_ours": f"{a_covered.mean():.3f}", "coverage_f3d": f"{b_covered.mean():.3f}",
                        "mean_ours": " ".join(f"{v:.0f}" for v in a_mean),
                        "mean_f3d": " ".join(f"{v:.0f}" for v in b_mean),
                        "colour_distance": f"{np.linalg.norm(a_mean - b_mean):.0f}",
                        "luminance_ratio": f"{luminance(a_mean) / max(luminance(b_mean), 1e-9):.2f}"}
                if pictures:
                    Image.fromarray(np.concatenate([a, b], axis=1)).save(pictures / f"{k:03d}.png")
            with rows_file.open("a") as handle:
                handle.write(json.dumps(row) + "\n")
            print(" ".join(f"{key}={value}" for key, value in row.items()), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--manifest", type=Path, default=Path("docs/figures/corpus.toml"))
    parser.add_argument("--root", type=Path, default=Path("/work/corpus"))
    parser.add_argument("--table", type=Path, default=Path("docs/meshes/f3d.csv"))
    parser.add_argument("--pictures", type=Path)
    parser.add_argument("--summary", action="store_true")
    parser.add_argument("--start", type=int, help=argparse.SUPPRESS)  # a child: compare from this entry on
    parser.add_argument("--rows", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.summary:
        summary(args.table)
        return
    entries = tomllib.loads(args.manifest.read_text())["model"]
    if args.pictures:
        args.pictures.mkdir(parents=True, exist_ok=True)
    if args.start is not None:
        compare(entries, args.root, args.start, args.rows, args.pictures)
        return
    # The comparison runs in a child process, restarted after the model it died on: f3d (VTK's readers) can
    # crash the process on a file (a segmentation fault on MeshLab's texturedknot.ply), which is recorded.
    with tempfile.TemporaryDirectory() as scratch:
        rows_file = Path(scratch) / "rows.jsonl"
        rows_file.touch()
        start = 0
        while start < len(entries):
            child = [sys.executable, __file__, "--manifest", str(args.manifest), "--root", str(args.root),
                     "--start", str(start), "--rows", str(rows_file)]
            done = subprocess.run(child + (["--pictures", str(args.pictures)] if args.pictures else []))
            made = [json.loads(line) for line in rows_file.read_text().splitlines()]
            start = (made[-1]["number"] + 1) if made else start
            if done.returncode and start < len(entries):
                row = {"number": start, "path": entries[start]["path"], "ours": "?",
                       "f3d": f"crashed (exit status {done.returncode})"}
                with rows_file.open("a") as handle:
                    handle.write(json.dumps(row) + "\n")
                print(" ".join(f"{key}={value}" for key, value in row.items()), flush=True)
                start += 1
        rows = [json.loads(line) for line in rows_file.read_text().splitlines()]
    fields = ["number", "path", "ours", "f3d", "iou", "coverage_ours", "coverage_f3d", "mean_ours", "mean_f3d",
              "colour_distance", "luminance_ratio"]
    with args.table.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    summary(args.table)


if __name__ == "__main__":
    main()
