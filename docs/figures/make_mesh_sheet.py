"""A contact sheet of every model in a folder or in the corpus manifest, each rendered with the defaults.

    .venv/bin/python docs/figures/make_mesh_sheet.py FOLDER [OUT.png] [--columns 8]
    .venv/bin/python docs/figures/make_mesh_sheet.py --manifest docs/figures/corpus.toml [--root /work/corpus]
        [OUT.png] [--tiles DIR] [--table docs/meshes/corpus.csv] [--parts DIR]

Each model is rendered by `raycast-phong render MODEL` (its own materials, the framing camera, the key light) at
200 × 150, one after another, in this process (the CLI's app; `--processes`: a new process each), and labelled
with its number and file name and, when it is refused, the start of the one-line error. With `--manifest`
(docs/figures/corpus.toml, the public corpus of issue 33, rebuilt by docs/figures/make_corpus.py) the models are
the manifest's, in its order; `--table` writes one row per model (number, path, format, exit status, seconds, the
last line the command printed to stderr) and `--tiles` keeps each picture and its row (NNN.png and NNN.json, the
number of the row; `--resume` keeps those made); `--parts` writes the sheet again in pages of 24 tiles, for a
person's check.
`FOLDER = tests/data/models` gives the sheet of the models the tests keep.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

SIDE_FILES = {".mtl", ".jpg", ".jpeg", ".png", ".bin", ".md", ".txt", ".tga", ".bmp"}
WIDTH, HEIGHT, LABEL = 200, 150, 14
GREY = 40
TIMEOUT = 600


def command(model: Path, out: Path) -> list[str]:
    return ["render", str(model), "-o", str(out), "--width", str(WIDTH), "--height", str(HEIGHT), "-q"]


def render(model: Path, out: Path) -> tuple[int, float, str]:
    """Run `raycast-phong render MODEL` at the sheet's size in a new process: the exit status, the wall seconds
    and the last line it printed to stderr."""
    start = time.perf_counter()
    try:
        done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", *command(model, out)],
                              capture_output=True, text=True, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        return -1, time.perf_counter() - start, f"timed out after {TIMEOUT} s"
    lines = [line.strip() for line in done.stderr.splitlines() if line.strip()]
    return done.returncode, time.perf_counter() - start, lines[-1] if lines else ""


def render_here(model: Path, out: Path) -> tuple[int, float, str]:
    """The same command in this process (the CLI's app, its exit status from SystemExit): no start-up per model
    (≈ 1.5 s of imports and kernel loading each), so a corpus of hundreds renders in minutes on a loaded machine."""
    from raycast_phong.cli import app

    def stop(*_):
        raise TimeoutError(f"timed out after {TIMEOUT} s")

    errors, start = io.StringIO(), time.perf_counter()
    signal.signal(signal.SIGALRM, stop)
    signal.alarm(TIMEOUT)
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            app(command(model, out))
        status = 0
    except SystemExit as done:
        status = done.code if isinstance(done.code, int) else 1
    except TimeoutError as error:
        status, errors = -1, io.StringIO(str(error))
    finally:
        signal.alarm(0)
    lines = [line.strip() for line in errors.getvalue().splitlines() if line.strip()]
    return status, time.perf_counter() - start, lines[-1] if lines else ""


def tile(out: Path, status: int) -> np.ndarray:
    """The picture at `out`, or a grey tile when the render was refused."""
    if status == 0 and out.is_file():
        return np.asarray(Image.open(out).convert("RGB"))
    return np.full((HEIGHT, WIDTH, 3), GREY, np.uint8)


def label(k: int, model: Path, status: int, message: str) -> str:
    """The tile's caption: its number, the file name and, if refused, the end of the message."""
    text = f"{k} {model.name}"
    return text if status == 0 else f"{text}: {message.split(': ')[-1]}"


def sheet(tiles: list[np.ndarray], labels: list[str], columns: int, scale: int = 1) -> Image.Image:
    """The tiles in rows of `columns`, each captioned, each `scale` times its size."""
    w, h = WIDTH * scale, HEIGHT * scale
    rows = -(-len(tiles) // columns)
    image = Image.new("RGB", (columns * w, rows * (h + LABEL)), (255, 255, 255))
    draw = ImageDraw.Draw(image)
    for k, (pixels, text) in enumerate(zip(tiles, labels)):
        x, y = (k % columns) * w, (k // columns) * (h + LABEL)
        image.paste(Image.fromarray(pixels).resize((w, h), Image.NEAREST), (x, y))
        draw.text((x + 2, y + h + 1), text[: 34 * scale], fill=(0, 0, 0))
    return image


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, nargs="?")
    parser.add_argument("out", type=Path, nargs="?", default=Path("docs/meshes/corpus.png"))
    parser.add_argument("--columns", type=int, default=8)
    parser.add_argument("--manifest", type=Path)
    parser.add_argument("--root", type=Path, default=Path("/work/corpus"))
    parser.add_argument("--tiles", type=Path)
    parser.add_argument("--table", type=Path)
    parser.add_argument("--parts", type=Path)
    parser.add_argument("--processes", action="store_true",
                        help="a new process per model (default: the CLI's app in this process)")
    parser.add_argument("--resume", action="store_true", help="keep the --tiles results already made")
    args = parser.parse_args()
    if args.manifest:
        if args.folder and args.folder.suffix == ".png":  # `--manifest M OUT.png`: the one positional is OUT
            args.out = args.folder
        entries = tomllib.loads(args.manifest.read_text())["model"]
        models = [args.root / entry["path"] for entry in entries]
    elif args.folder:
        models = sorted(p for p in args.folder.iterdir() if p.is_file() and p.suffix.lower() not in SIDE_FILES)
    else:
        parser.error("give a FOLDER or --manifest")
    tiles, labels, rows = [], [], []
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.tiles or Path(scratch)
        folder.mkdir(parents=True, exist_ok=True)
        for k, model in enumerate(models):
            out, record = folder / f"{k:03d}.png", folder / f"{k:03d}.json"
            if args.resume and record.is_file():
                status, seconds, message = json.loads(record.read_text())
            else:
                out.unlink(missing_ok=True)
                status, seconds, message = (render if args.processes else render_here)(model, out)
                record.write_text(json.dumps([status, seconds, message]))
            tiles.append(tile(out, status))
            labels.append(label(k, model, status, message))
            rows.append([k, str(model.relative_to(args.root)) if args.manifest else model.name,
                         model.suffix.lower().lstrip("."), status, f"{seconds:.2f}", message])
            print(f"{k} {model}: exit {status}, {seconds:.1f} s {message}", flush=True)
    if args.table:
        with args.table.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["number", "path", "format", "exit", "seconds", "message"])
            writer.writerows(rows)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet(tiles, labels, args.columns).save(args.out, optimize=True)  # full colour: a palette shifts hues
    if args.parts:
        args.parts.mkdir(parents=True, exist_ok=True)
        for start in range(0, len(tiles), 24):
            part = sheet(tiles[start:start + 24], labels[start:start + 24], 6)
            part.save(args.parts / f"part-{start // 24:02d}.png")
    print(f"{args.out}: {len(models)} models, {sum(row[3] == 0 for row in rows)} rendered")


if __name__ == "__main__":
    main()
