"""Real scans at millions of triangles for bench_mesh.py: public scans subdivided (trimesh's midpoint
subdivision, each step ×4 faces) and written as binary PLY, binary STL, GLB and OBJ into a cache folder
outside the repository (~/.cache/raycast-phong/scans, or $RAYCAST_PHONG_SCANS); made once, then reused.

Sources: the Stanford bunny (trimesh's models/bunny.ply in the corpus of docs/figures/make_corpus.py,
/work/corpus/mikedh+trimesh/models/bunny.ply, or /work/corpus/bunny.ply; 16,301 faces; BUNNY to override), and the
beast and the full-resolution Stanford bunny of alecjacobson/common-3d-test-models (data/beast.obj, 32,364 faces;
BEAST to override, a path to the .obj; data/stanford-bunny.obj, 69,451 faces).
Usage: python benchmarks/make_scans.py [--scan bunny-1m bunny-4m ...] [--formats ply stl glb obj]
"""

from __future__ import annotations

import argparse
import os
import subprocess
from pathlib import Path

SCANS = {  # name: (source, subdivision steps) → faces
    "bunny-1m": ("bunny", 3),   # 16,301 × 64 = 1,043,264
    "bunny-4m": ("bunny", 4),   # 16,301 × 256 = 4,173,056
    "beast-2m": ("beast", 3),   # 32,364 × 64 = 2,071,296
    "stanford-bunny-1m": ("stanford-bunny", 2),  # 69,451 × 16 = 1,111,216 (docs/view.md's scan)
}
FORMATS = ("ply", "stl", "glb", "obj")


def folder() -> Path:
    path = Path(os.environ.get("RAYCAST_PHONG_SCANS") or Path.home() / ".cache" / "raycast-phong" / "scans")
    path.mkdir(parents=True, exist_ok=True)
    return path


def _source(name: str):
    import trimesh

    if name == "bunny":
        corpus = Path("/work/corpus/mikedh+trimesh/models/bunny.ply")
        default = corpus if corpus.is_file() else Path("/work/corpus/bunny.ply")
        return trimesh.load(os.environ.get("BUNNY", str(default)), process=False)
    path = os.environ.get("BEAST")
    if path and name == "beast":
        return trimesh.load(path, process=False)
    repo = "/work/.mirror/alecjacobson+common-3d-test-models/repo"
    text = subprocess.run(["git", "-C", repo, "show", f"HEAD:data/{name}.obj"], capture_output=True,
                          check=True).stdout
    import io
    return trimesh.load(io.BytesIO(text), file_type="obj", process=False)


def scan(name: str, fmt: str) -> Path:
    """The path of scan `name` in format `fmt`, made if missing (written to a temporary name, then renamed)."""
    path = folder() / f"{name}.{fmt}"
    if path.exists():
        return path
    import numpy as np
    import trimesh
    from trimesh.remesh import subdivide

    source, steps = SCANS[name]
    mesh = _source(source)
    vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    for _ in range(steps):
        vertices, faces = subdivide(vertices, faces)
    out = trimesh.Trimesh(vertices.astype(np.float32), faces, process=False)
    temporary = path.with_name(path.name + ".part")
    data = out.export(file_type=fmt) if fmt != "ply" else out.export(file_type="ply", encoding="binary")
    temporary.write_bytes(data if isinstance(data, bytes) else data.encode())
    temporary.replace(path)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scan", nargs="+", default=["bunny-1m", "bunny-4m"], choices=sorted(SCANS))
    parser.add_argument("--formats", nargs="+", default=list(FORMATS), choices=FORMATS)
    args = parser.parse_args()
    for name in args.scan:
        for fmt in args.formats:
            path = scan(name, fmt)
            print(f"{path} {path.stat().st_size / 1e6:.0f} MB", flush=True)


if __name__ == "__main__":
    main()
