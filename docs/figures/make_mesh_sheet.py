"""A contact sheet of every model in a folder, each rendered with the defaults (run from the repository root).

    .venv/bin/python docs/figures/make_mesh_sheet.py FOLDER [OUT.png] [--columns 8]

Each model is rendered as `raycast-phong render MODEL` does (its own materials, the framing camera, the key
light), at 200 × 150, and labelled with its file name and, when it is refused, the start of the one-line
error. docs/meshes.md shows the sheet of the public corpus of issue 20 (about 80 models from trimesh's
models/, assimp's test/models/ and alecjacobson/common-3d-test-models); `FOLDER = tests/data/models` gives
the sheet of the models the tests keep.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

SIDE_FILES = {".mtl", ".jpg", ".jpeg", ".png", ".bin", ".md", ".txt", ".tga", ".bmp"}
WIDTH, HEIGHT, LABEL = 200, 150, 14


def render(model: Path, out: Path) -> tuple[np.ndarray, str]:
    """The default picture of `model` (or a grey tile) and its label."""
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "render", str(model), "-o", str(out),
                           "--width", str(WIDTH), "--height", str(HEIGHT), "-q"], capture_output=True, text=True,
                          timeout=600)
    if done.returncode == 0 and out.is_file():
        return np.asarray(Image.open(out).convert("RGB")), model.name
    message = (done.stderr.strip().splitlines() or ["?"])[-1].split(": ")[-1]
    return np.full((HEIGHT, WIDTH, 3), 40, np.uint8), f"{model.name}: exit {done.returncode}: {message}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("out", type=Path, nargs="?", default=Path("docs/meshes/corpus.png"))
    parser.add_argument("--columns", type=int, default=8)
    args = parser.parse_args()
    models = sorted(p for p in args.folder.iterdir() if p.is_file() and p.suffix.lower() not in SIDE_FILES)
    rows = -(-len(models) // args.columns)
    sheet = Image.new("RGB", (args.columns * WIDTH, rows * (HEIGHT + LABEL)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    with tempfile.TemporaryDirectory() as folder:
        for k, model in enumerate(models):
            pixels, label = render(model, Path(folder) / f"{k}.png")
            x, y = (k % args.columns) * WIDTH, (k // args.columns) * (HEIGHT + LABEL)
            sheet.paste(Image.fromarray(pixels), (x, y))
            draw.text((x + 2, y + HEIGHT + 1), label[:34], fill=(0, 0, 0))
            print(label, flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out, optimize=True)
    print(f"{args.out}: {len(models)} models")


if __name__ == "__main__":
    main()
