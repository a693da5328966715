"""Rebuild the public model corpus (docs/figures/corpus.toml) from the repositories' git snapshots.

    .venv/bin/python docs/figures/make_corpus.py [--mirrors /work/.mirror] [--out /work/corpus]

Each `[[model]]` of the manifest names a repository, a commit and the file's path in it; the file is written to
OUT/PATH with the side files it needs to render as its authors meant: for an OBJ its `mtllib` files and the maps
they name, for a .gltf its buffers and images (relative `uri`s, percent-decoded), and for every model the files
beside it whose suffix is a side file's (.mtl, .bin, images). Files over 50 MB are skipped, with a line saying so.
`--report` prints instead the person's check the manifest records (each model's `verdict` and `why`): the counts
and the models rendered wrong or refused, as the Markdown docs/meshes.md shows.
The snapshots are bare git directories (`MIRRORS/OWNER+NAME/repo`), read with `git show COMMIT:PATH`: nothing is
downloaded. The corpus lives outside the repository (its licences vary; the manifest names each one).
"""

from __future__ import annotations

import argparse
import json
import posixpath
import re
import subprocess
import sys
import tomllib
import urllib.parse
from pathlib import Path

MANIFEST = Path(__file__).with_name("corpus.toml")
SIDE = {".mtl", ".bin", ".png", ".jpg", ".jpeg", ".tga", ".bmp", ".ktx2", ".webp", ".dds", ".tif", ".tiff"}
LIMIT = 50 * 2**20
MAP = re.compile(r"^\s*(map_\w+|bump|disp|decal|refl|norm)\s+(.+)$", re.IGNORECASE)


class Snapshot:
    """One repository's bare git directory at one commit: list, size and read its files."""

    def __init__(self, gitdir: Path, commit: str) -> None:
        self.gitdir, self.commit = gitdir, commit
        listing = self._git("ls-tree", "-r", "-l", commit).decode("utf-8", "replace")
        self.sizes = {}
        for line in listing.splitlines():
            meta, path = line.split("\t", 1)
            size = meta.split()[3]
            self.sizes[path] = int(size) if size.isdigit() else -1

    def _git(self, *args: str) -> bytes:
        return subprocess.run(["git", f"--git-dir={self.gitdir}", *args], capture_output=True, check=True).stdout

    def read(self, path: str) -> bytes:
        return self._git("cat-file", "blob", f"{self.commit}:{path}")


def referenced(snap: Snapshot, path: str) -> set[str]:
    """The repository paths the model at `path` names: MTL files and their maps, glTF buffers and images."""
    folder, suffix, found = posixpath.dirname(path), posixpath.splitext(path)[1].lower(), set()
    text = snap.read(path).decode("utf-8", "replace") if snap.sizes.get(path, -1) < LIMIT else ""
    if suffix == ".obj":
        for line in text.splitlines():
            if line.startswith("mtllib"):
                names = [name.replace("\\ ", " ") for name in re.split(r"(?<!\\)\s+", line[6:].strip()) if name]
                found.update(posixpath.normpath(posixpath.join(folder, n)) for n in [*names, line[6:].strip()])
        for mtl in [p for p in found if p in snap.sizes and 0 <= snap.sizes[p] < LIMIT]:
            for line in snap.read(mtl).decode("utf-8", "replace").splitlines():
                if match := MAP.match(line):
                    name = match.group(2).strip().replace("\\", "/")
                    found.update(posixpath.normpath(posixpath.join(posixpath.dirname(mtl), n))
                                 for n in (name, name.split()[-1]))
    elif suffix == ".gltf":
        try:
            document = json.loads(text)
        except ValueError:
            return found
        for item in [*document.get("buffers", []), *document.get("images", [])]:
            uri = item.get("uri", "") if isinstance(item, dict) else ""
            if isinstance(uri, str) and uri and not uri.startswith("data:"):
                found.add(posixpath.normpath(posixpath.join(folder, urllib.parse.unquote(uri))))
    return {p for p in found if p in snap.sizes}


def build(manifest: Path, mirrors: Path, out: Path) -> int:
    """Write every model of `manifest` and its side files under `out`; the number of files written."""
    models = tomllib.loads(manifest.read_text())["model"]
    snapshots: dict[tuple[str, str], Snapshot] = {}
    written = 0
    for model in models:
        key = (model["repo"], model["commit"])
        if key not in snapshots:
            gitdir = mirrors / model["repo"].replace("/", "+") / "repo"
            snapshots[key] = Snapshot(gitdir / ".git" if (gitdir / ".git").is_dir() else gitdir, model["commit"])
        snap, source = snapshots[key], model["source"]
        root = out / model["path"][: len(model["path"]) - len(source)]
        folder = posixpath.dirname(source)
        beside = {p for p in snap.sizes if posixpath.dirname(p) == folder and posixpath.splitext(p)[1].lower() in SIDE}
        for path in sorted({source} | beside | referenced(snap, source)):
            target = root / path
            if snap.sizes[path] < 0 or snap.sizes[path] > LIMIT:
                why = "absent from the snapshot" if snap.sizes[path] < 0 else f"{snap.sizes[path]} bytes, over 50 MB"
                print(f"skipped {model['repo']}:{path} ({why})", file=sys.stderr)
                continue
            if target.is_file() and target.stat().st_size == snap.sizes[path]:
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(snap.read(path))
            written += 1
    print(f"{out}: {len(models)} models, {written} files written")
    return written


def report(manifest: Path) -> None:
    """The manifest's verdicts as Markdown: the counts, then each model that is not right, by verdict."""
    models = tomllib.loads(manifest.read_text())["model"]
    counts = {v: sum(m.get("verdict") == v for m in models)
              for v in ("right", "wrong", "refused-wrongly", "refused-correctly")}
    valid = counts["right"] + counts["wrong"] + counts["refused-wrongly"]
    print(f"{len(models)} models from {len({m['repo'] for m in models})} projects: {counts['right']} right, "
          f"{counts['wrong']} wrong, {counts['refused-wrongly']} valid files refused, {counts['refused-correctly']} "
          f"broken files refused correctly; {counts['right']} of {valid} valid files right "
          f"({100 * counts['right'] / valid:.1f} %).")
    for verdict in ("wrong", "refused-wrongly", "refused-correctly"):
        print(f"\n{verdict}:\n")
        for k, m in enumerate(models):
            if m.get("verdict") == verdict:
                print(f"- {k} `{m['path'].split('+', 1)[1]}` ({m['repo'].split('/')[0]}): {m.get('why', '')}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--manifest", type=Path, default=MANIFEST)
    parser.add_argument("--mirrors", type=Path, default=Path("/work/.mirror"))
    parser.add_argument("--out", type=Path, default=Path("/work/corpus"))
    parser.add_argument("--report", action="store_true")
    args = parser.parse_args()
    if args.report:
        report(args.manifest)
        return
    build(args.manifest, args.mirrors, args.out)


if __name__ == "__main__":
    main()
