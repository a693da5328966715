"""Mutation testing of the package: apply realistic one-line bugs one at a time, see if a test fails.

    .venv/bin/python tests/mutation/mutate.py --list --module renderer/kernels/shading    # the mutants, not run
    .venv/bin/python tests/mutation/mutate.py --sample 2 --seed 3 --budget 1200           # every module
    .venv/bin/python tests/mutation/mutate.py --core --sample 25 --seed 14 --out build/mutation  # the kernels
    .venv/bin/python tests/mutation/mutate.py --rerun build/mutation/mutants.json         # re-run the survivors

Modules are named by their path below raycast_phong/ (io/atomic, renderer/kernels/shading); every module
with code is a candidate (MODULES). Each is tested against its mirror folder in tests/ plus the folders that
exercise it from outside (tests_for: tests/image for the renderer and geometry, tests/contracts for files,
scenes and the CLI), unless --tests names one subset for all.

Mutants come from the module's AST, one node at a time, and are written back as a one-line textual edit
(the node's source span replaced by its mutated `ast.unparse`), so line numbers never move:
  operator   + ↔ -, * ↔ /, < ↔ <=, > ↔ >=, == ↔ !=, and ↔ or
  constant   0 → 1, 1 → 0, 2 → 1, other numbers × 2 (bools and strings are left alone)
  name       zero ↔ one, two → one (the kernels' dtype-typed constants)
  sign       -x → x
  drop       a + b → a, a + b → b, a - b → a, a * b → a (a dropped term or factor)
  swap       f(a, b, …) → f(b, a, …) (first two plain-name arguments)
  negate     `if c` / `c if … else` / `while c` → `not c`
Docstrings, decorators, annotations, imports and `raise` statements are not mutated.

Each mutant runs in a copy of the repository (COPIED: the package, tests, scenes, docs, benchmarks) at
one fixed work path, imported through PYTHONPATH ahead of the editable install, with its own NUMBA_CACHE_DIR
seeded from the unmutated run's. A mutated kernel module cannot reuse a stale kernel: raycast_phong/jit.py keys the
kernels' cache folder on the source of every kernel module and its imports. The mutant is *killed* when the
test subset fails, *timeout* when it runs past --timeout, *survived* when the subset passes. Not collected by pytest
(tests/mutation has no test_*.py).
"""

from __future__ import annotations

import argparse
import ast
import copy
import json
import os
import random
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PACKAGE = "raycast_phong"  # modules are named by their path below it, e.g. renderer/kernels/shading
CORE_MODULES = (  # where a pixel's value is decided: the kernels and the stages feeding them
"renderer/kernels/illumination", "renderer/kernels/shading", "renderer/kernels/shadows",
                "renderer/kernels/camera", "renderer/film", "geometry/build", "geometry/templates", "geometry/placing",
                "geometry/scene_mesh", "renderer/intersect", "renderer/frame", "renderer/plan", "geometry/normals",
                "geometry/mesh_repair", "shapes/icosphere", "shapes/surfaces",
                "renderer/kernels/tile", "renderer/kernels/ray_queries")
EXTRA_TESTS = {"renderer": ("tests/image",), "geometry": ("tests/image",), "io": ("tests/contracts",),
               "scene": ("tests/contracts", "tests/cli"), "cli": ("tests/contracts",), "tools": (),
               "shapes": ("tests/geometry", "tests/scene"), "values": ("tests/scene", "tests/contracts"),
               "": ("tests/project", "tests/renderer", "tests/io")}  # "": the package's top-level modules
MODULE_TESTS = {"renderer/budget": ("tests/contracts/test_resource_guards.py",  # the memory guard's own tests
                                    "tests/geometry/test_map_keys.py"),  # every stage over every map key
                "tools/batch/jobs": ("tests/contracts/test_bad_input.py", "tests/contracts/test_batch_faults.py"),
                "tools/batch/cluster": ("tests/contracts",),
                "pytest_plugin": ("tests/image", "tests/project/test_pytest_plugin.py"),  # its own, and the references
                "io/system": ("tests/project/test_one_home.py",),  # the budget rule's one home
                "tools/batch/manifest": ("tests/contracts/test_batch_faults.py",),
                "tools/batch/run": ("tests/contracts/test_image_guards.py",),  # the workers the budget holds
                "geometry/checks": ("tests/scene/test_limits_at_edges.py",  # the 1/d² gain bound at its edges
                                    "tests/contracts/test_float_edges.py"),
                "jit": ("tests/contracts/test_kernel_cache_fallback.py",),
                "errors": ("tests/contracts/test_file_guards.py", "tests/contracts/test_batch_faults.py")}  # names


def _has_code(path: Path) -> bool:
    body = ast.parse(path.read_text(encoding="utf-8")).body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]  # the docstring
    return any(not isinstance(node, (ast.Import, ast.ImportFrom)) for node in body)


MODULES = tuple(sorted(str(path.relative_to(REPO / PACKAGE).with_suffix(""))
                       for path in (REPO / PACKAGE).rglob("*.py") if _has_code(path)))


def tests_for(module: str) -> list[str]:
    """The test subset for a module: its mirror folder (tests/renderer for renderer/kernels/x too) and the
    folders that reach it from outside."""
    top = module.split("/")[0] if "/" in module else ""
    mirror = [f"tests/{top}"] if top and (REPO / "tests" / top).is_dir() else []
    return [*mirror, *EXTRA_TESTS.get(top, ()), *MODULE_TESTS.get(module, ())]
COPIED = ("raycast_phong", "tests", "scenes", "cli.py", "pyproject.toml", "README.md", "LICENSE", "docs", "benchmarks",
          ".ci")
WORK = Path(os.environ.get("TMPDIR", "/tmp")) / "raycast-phong-mutation"

# Bugs written by hand (issue 19's independent sample, outside the kernels): (module, original text, mutated
# text), each text found exactly once in the module; --hand runs them against tests_for(module).
HAND_MUTANTS = (
    ("io/meshes/read", "rgb = np.asarray(visual.face_colors)[:, :3].astype(np.float32) / 255.0",
     "rgb = np.asarray(visual.face_colors)[:, :3].astype(np.float32) / 765.0"),  # a face colour summed over 3 corners
    ("io/meshes/mtl", 'current = raw.setdefault(" ".join(words[1:]), {})',
     "current = raw.setdefault(words[1], {})"),  # a material name with a space cut at the space
    ("renderer/budget", "rays = tile_rays * threads * (1 + shadow_lights) * RAY_BYTES",
     "rays = tile_rays * (1 + shadow_lights) * RAY_BYTES"),  # the memory estimate's thread term
    ("io/atomic", "            _settle(temporary, made)\n            os.replace(temporary, target)\n",
     "            os.replace(temporary, target)\n            _settle(str(target), made)\n"),  # fsync after the rename
    # issue 50's guards, written by hand as the bugs a reviewer would plant
    ("io/meshes/collada", 'if name in INDEX_LISTS and element.text and "-" in element.text:',
     'if name in INDEX_LISTS and element.text and element.text.lstrip().startswith("-"):'),  # the first index only
    ("io/meshes/collada", "if values is not None and values.text and NOT_FINITE.search(values.text):",
     "if values is not None and values.text and NOT_FINITE.match(values.text):"),  # NaN only as the first value
    ("io/meshes/gltf", "        images * EMBEDDED_IMAGE_BYTES_PER_TEXEL", "        images"),  # texels, not bytes
    ("io/meshes/threemf", "sum(placed(child_part, child, depth + 1) for child_part, child in found)",
     "max((placed(child_part, child, depth + 1) for child_part, child in found), default=0)"),  # one component
    ("io/meshes/read", "        raise SceneError(problem.problem, mesh.where) from None",
     "        raise SceneError(problem.problem) from None"),  # a reader's problem without the scene key
    ("io/meshes/read", "        squared += np.square(block[:, 1] - centre[1])\n"
     "        squared += np.square(block[:, 2] - centre[2])", "        squared += np.square(block[:, 2] - centre[2])\n"
     "        squared += np.square(block[:, 1] - centre[1])"),  # the radius's sum in another order: other bits
    ("io/meshes/stl", "        if handle.readinto(some.view(np.uint8)) != some.nbytes:",
     "        if handle.readinto(some.view(np.uint8)) is None:"),  # a file cut under the read: zeros read as points
    ("io/meshes/stl", "return len(head) >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], \"little\")",
     "return len(head) >= 84 and size >= 84 + 50 * int.from_bytes(head[80:84], \"little\")"),  # trailing bytes
    ("io/textures", "    mismatch = image_suffix_mismatch(path)\n    if mismatch:",
     "    mismatch = None\n    if mismatch:"),  # the suffix believed: OpenImageIO tries every reader
    ("io/image_io", "    return values * (2 * 4 + max(spec.format.size(), 1))", "    return values * 4"),  # one copy
    ("io/system", "    if not 0 < size < math.inf:", "    if not 0 < size:"),  # 400 digits: int(inf)
    ("io/atomic", "DEFERRED = STOP_SIGNALS", "DEFERRED = (signal.SIGINT, signal.SIGTERM)"),  # SIGHUP mid-write
    ("tools/batch/jobs", '        text.encode("utf-8")', '        text.encode("utf-8", "surrogateescape")'),
    ("tools/batch/jobs", "    return [line for _, line in lines if \"\\0\" not in line]",
     "    return [line for _, line in lines]"),  # a NUL byte kept in a path
    ("tools/batch/jobs", "    if not jobs:  #", "    if not jobs and not warnings:  #"),  # refused only when silent
    ("tools/batch/cluster", "    with _dask_quiet(), client:", "    with client:"),  # Dask's loggers on stderr
    ("renderer/split_compile", "                    self.process.kill()\n                    return",
     "                    return"),  # a stalled helper left running
    ("cli/batch", "HOST_CHARACTERS, LABEL_CHARACTERS = 253, 63", "HOST_CHARACTERS, LABEL_CHARACTERS = 253, 253"),
    # issue 50's guards again, a second set written apart from the first (none repeats a bug above)
    ("io/image_io", "if budget is not None and needed > budget:", "if budget is not None and needed > 2 * budget:"),
    ("io/system", "or not budget > 0:", "or budget < 0:"),  # a budget of 0 bytes accepted
    ("io/system", "return None if available is None else int(available * BUDGET_SHARE)",
     "return None if available is None else int(available)"),  # all the available memory
    ("io/meshes/collada", 'NOT_FINITE = re.compile(r"(?i)\\b(nan|inf|infinity)\\b")',
     'NOT_FINITE = re.compile(r"(?i)\\b(nan)\\b")'),  # infinite positions read
    ("tools/batch/manifest", 'with open_regular(path, str(path), "batch manifest") as handle:',
     'with open(path, "rb") as handle:'),  # a planted FIFO or device opened
    ("tools/batch/manifest", "if len(text) > MANIFEST_LIMIT:", "if len(text) > MANIFEST_LIMIT + 1:"),  # never true
    ("jit", "        except Exception:  # noqa: BLE001 - whatever the bytes make the unpickler or numba raise\n"
     "            self.drop()", "        except (OSError, EOFError):\n            self.drop()"),  # too narrow
    ("jit", "            self.drop()\n            return None", "            return None"),  # a corrupt entry kept
    ("jit", "    return data[32:] if hashlib.sha256(data[32:]).digest() == data[:32] else None",
     "    return data[32:]"),  # a cache file its sha256 does not match believed (NRT or symbols)
    ("jit", "        _checked_write(path, pickle.dumps(", "        0 and _checked_write(path, pickle.dumps("),  # no NRT
    ("jit", "        listed = _checked_read(path)  # the names", "        listed = None  # the names"),  # parsed always
    ("jit", "        if self._bitcode is not None:  # a compile links",
     "        if False:  # a compile links"),  # a loaded kernel that cannot be linked
    ("jit", 'with contextlib.nullcontext() if os.path.isfile(NUMBA_CONFIG) else _unimportable("yaml"):',
     'with _unimportable("yaml"):'),  # a .numba_config.yaml ignored
    ("tools/view/server", "if len(scene.lights) > MAX_VIEW_LIGHTS:", "if len(scene.lights) > 10 * MAX_VIEW_LIGHTS:"),
    ("tools/view/session", "    if size > MAX_MESSAGE_BYTES:", "    if size > SOCKET_MAX_BYTES:"),
    ("tools/view/server", "        if size > MAX_SCENE_BYTES:", "        if size > MAX_SCENE_BYTES << 10:"),  # KiB
    ("cli/batch", "for warning in refused[:MAX_LEFT_OUT]:", "for warning in refused:"),  # thousands of warnings
    ("io/meshes/threemf", "    return sum(placed(part, identity, 0) for part, identity in objects(root).get(None, []))",
     "    return sum(placed(part, identity, 0) for part, identity in objects(root).get(None, [])[:1])"),
    ("io/atomic", "            with suppress(OSError):\n                os.unlink(temporary)", "            pass"),
    ("renderer/split_compile", "if now - moved >= (STALL_SECONDS if spent is not None else 10 * STALL_SECONDS):",
     "if now - moved >= 10 * STALL_SECONDS:"),  # a stopped helper waited for as if its CPU time were unknown
    ("io/meshes/ply", "and element.rows for element in header.elements):", "for element in header.elements):"),
    # issue 50's guards, a third set: an independent replay's survivors, each with the test written for it
    ("io/files", "whole >= path_max", "whole > path_max"),  # PATH_MAX counts the NUL
    ("io/image_io", "need = sum(w * h * c for w, h, c in filter(None, sizes.values())) * per_sample",
     "need = max((w * h * c for w, h, c in filter(None, sizes.values())), default=0) * per_sample"),
    ("io/image_io", "for part in range(parts):", "for part in range(1):"),  # a cut last EXR part
    ("io/files", "len(os.fsencode(path.name)), len(os.fsencode(str(path)))", "len(path.name), len(str(path))"),
    ("io/textures", "    except (SceneError, OSError):\n        return None\n    if image_suffix_mismatch",
     "    except SceneError:\n        return None\n    if image_suffix_mismatch"),  # a missing map raises
    ("io/meshes/collada", 'INDEX_LISTS = ("p", "v", "vcount")', 'INDEX_LISTS = ("p",)'),
    ("io/meshes/gltf", "and stride < element:", "and stride < 0:"),  # overlapping elements read
    ("io/meshes/gltf_decode", "if copies * count >= 2**32:", "if count >= 2**32:"),
    ("io/meshes/size", "triangles * (MESH_READ_BYTES + mesh.format.parse_bytes)", "triangles * MESH_READ_BYTES"),
    ("io/meshes/size", "return size // SMALLEST_TRIANGLE if found is None else found", "return found or 0"),
    ("tools/view/server", 'size = len(text.encode("utf-8", "surrogatepass"))', "size = len(text)"),  # characters
    # a fourth set, by a session that saw none of the above: its survivors, each with the test written for it
    ("io/files", "if limit is not None and info.st_size > limit:", "if limit is not None and info.st_size >= limit:"),
    ("io/meshes/collada", "                    total += node(target)\n",
     "                    total = max(total, node(target))\n"),  # instance_nodes side by side
    ("io/meshes/gltf_decode", "elif count * stride > extents[index] + stride + 3:",
     "elif count * stride > 10 * extents[index] + stride + 3:"),  # a meshopt view decoding 10x its accessors
    ("io/meshes/threemf_draft", "int(word) < 1 << 31):", "int(word) <= 1 << 31):"),
    ("io/meshes/ply_lists", "if prop.count is None or (each in (1, 2) and (length == each * corners).all()):",
     "if prop.count is None or (each in (1, 2) and (length[:1] == each * corners[:1]).all()):"),
    ("io/meshes/polygons", "usable = ((vertices >= 0) & (vertices < len(points))).all(axis=1)",
     "usable = ((vertices >= 0) & (vertices <= len(points))).all(axis=1)"),  # a quad's index V: IndexError
    ("tools/batch/jobs", "data = stream.read(MAX_LISTED_BYTES + 1)", "data = stream.read(MAX_LISTED_BYTES)"),
    ("cli/batch", "not 0 < int(found[3]) < 65536", "not 0 < int(found[3]) <= 65536"),
    ("tools/view/server", "if opts.width * opts.height * opts.samples ** 2 > MAX_VIEW_RAYS:",
     "if opts.width * opts.height * opts.samples > MAX_VIEW_RAYS:"),
    ("jit", "and not info.st_mode & 0o022:", "and not info.st_mode & 0o002:"),  # a group-writable cache used
    ("tools/view/session", "    except (RecursionError, ValueError) as error:  # nested thousands deep",
     "    except ValueError as error:  # nested thousands deep"),  # the page's socket hangs: the test's timeout
    # a fifth set, by another session that saw none of the lists: its survivors, each with the test written for it
    ("io/meshes/gltf", "missing = [e for e in required if e not in SUPPORTED_REQUIRED and e not in LOOK_ONLY]",
     "missing = [e for e in required[:1] if e not in SUPPORTED_REQUIRED and e not in LOOK_ONLY]"),
    ("io/meshes/read", "if faces.size and not (0 <= faces.min() and faces.max() < len(vertices)):",
     "if faces.size and not (0 <= faces.min() and faces.max() <= len(vertices)):"),
    ("io/meshes/off", "if 6 * vertices + 8 * faces <= size:", "if 6 * vertices + 8 * faces <= size * 10:"),
    ("tools/view/session", '    size = len(text.encode("utf-8", "surrogatepass"))  # bytes, as the socket',
     "    size = len(text)  # bytes, as the socket"),  # a page message in characters
    # issue 50's limits at their value and one past (each killed by a test beside its area's, by hand)
    ("scene/schema", 'le=MAX_SIZE, description="image height',
     'le=MAX_SIZE + 1, description="image height'),  # height's bound one past 16384
    ("scene/schema", "MAX_SAMPLES = 16 ",
     "MAX_SAMPLES = 17 "),  # samples' bound one past 16
    ("scene/schema", "MAX_PIXEL_RAYS = 2**31 - 1",
     "MAX_PIXEL_RAYS = 2**31"),  # the ray limit one past 2³¹ − 1
    ("scene/schema", "gt=0.0, lt=180.0",
     "gt=0.0, le=180.0"),  # fov 180 allowed
    ("scene/schema", "gt=0.0, le=POSITION_LIMIT",
     "gt=0.0, lt=POSITION_LIMIT"),  # view_height 1e18 refused
    ("scene/schema", "if not total <= INTENSITY_LIMIT",
     "if not total < INTENSITY_LIMIT"),  # the brightness bound strict
    ("scene/schema", "sum(term[c] for term in terms)",
     "sum(term[c] for term in terms[:1])"),  # the first light's brightness only
    ("scene/schema", 'return (("lights", k),',
     'return (("lights", 0),'),  # the brightness line always naming lights.0
    ("scene/bulk", "good &= passed",
     "good &= passed[0]"),  # a bulk column judged by its first row
    ("scene/bulk", "low < v) and v <= high",
     "low < v) and v <= high + 1"),  # bulk's whole-number bound one past
    ("values/fields", "for s in value)",
     "for s in value[:1])"),  # segments' first count checked only
    ("tools/view/session", "if size > MAX_MESSAGE_BYTES:",
     "if size >= MAX_MESSAGE_BYTES:"),  # a message of exactly the limit refused
    ("tools/view/server", "len(settings) > MAX_SETTINGS",
     "len(settings) > MAX_SETTINGS + 1"),  # 257 settings taken
    ("tools/view/server", "samples ** 2 > MAX_VIEW_RAYS",
     "samples ** 2 >= MAX_VIEW_RAYS"),  # the view's largest frame refused
    ("tools/view/server", "if size > MAX_SCENE_BYTES:",
     "if size > MAX_SCENE_BYTES + 1:"),  # a page-opened scene of 60,001 bytes read
    ("renderer/fit", "len(scene.lights) > MAX_LIGHTS",
     "len(scene.lights) >= MAX_LIGHTS"),  # global mode refusing 63 lights
    ("io/meshes/obj", "np.float64)) > UV_LIMIT).any()",
     "np.float64)) >= UV_LIMIT).any()"),  # float32's largest uv refused
    ("io/meshes/read", "(np.abs(uv) > UV_LIMIT).any()",
     "(np.abs(uv) >= UV_LIMIT).any()"),  # the same in the common reader
    ("io/scene_file", "data = sys.stdin.buffer.read(MAX_SCENE_BYTES + 1)",
     "data = sys.stdin.buffer.read(MAX_SCENE_BYTES)"),  # a piped scene cut at the limit
    ("io/scene_file", "if len(data) > MAX_SCENE_BYTES:",
     "if len(data) >= MAX_SCENE_BYTES:"),  # a scene of exactly the limit refused
    ("tools/sweep", "if cells > MAX_SWEEP_CELLS:",
     "if cells >= MAX_SWEEP_CELLS:"),  # a sweep of exactly 4096 cells refused
    ("io/meshes/threemf", "        if depth > MAX_DEPTH:",
     "        if depth >= MAX_DEPTH:"),  # components 32 deep refused
    ("io/meshes/threemf", "0 if depth > MAX_DEPTH else",
     "0 if depth >= MAX_DEPTH else"),  # the scan's count of 32 deep
    ("cli/batch", "if len(refused) > MAX_LEFT_OUT:",
     "if len(refused) >= MAX_LEFT_OUT:"),  # 'and 0 more' after 20 warnings
    # Issue 50's sixth independent set: the seven it left alive, and a default only the schema's text held.
    ("renderer/kernels/illumination", "return one if x >= one else zero",
     "return one if x > one else zero"),  # f = inf loses the exact mirror direction
    ("io/meshes/off", "floats = not (rgba[:, :3] > 1).any()",
     "floats = not (rgba[:, :3] >= 1).any()"),  # OFF's 0..1 colours of 1 read as 0..255
    ("renderer/budget", "wide_normals = FLOAT64_NORMAL_BYTES if float64 or shadow_lights else 0",
     "wide_normals = FLOAT64_NORMAL_BYTES if float64 else 0"),  # global mode's float64 normals unweighed
    ("renderer/budget", "if size > largest_bytes:",
     "if size >= largest_bytes:"),  # a tie for the largest named by the later object
    ("tools/batch/jobs", "    stops.record(number)\n    raise Interrupted(number)",
     "    stops.record(number)"),  # a stop signal that waits for the scenes in flight
    ("tools/study", "reaching = [r for r in rows if r.rmse <= target]",
     "reaching = [r for r in rows if r.rmse < target]"),  # an RMSE exactly at the target not reaching it
    ("renderer/reuse", "if same_bits(vertices, geometry.vertices) and same_bits(faces, geometry.faces):",
     "if same_bits(vertices, geometry.vertices):"),  # the BVH kept when only the faces change
    ("scene/schema", "two_sided: Annotated[bool, Strict()] = Field(True,",
     "two_sided: Annotated[bool, Strict()] = Field(False,"),  # one-sided by default
    # Issue 50's seventh independent set: the three it left alive.
    ("io/meshes/threemf", "faces.max() >= len(points)):",
     "faces.max() > len(points)):"),  # 3MF's own index check one past (read.py's then words it)
    ("geometry/normals", "least = math.cos(math.radians(crease_angle)) - 1e-12",
     "least = math.cos(math.radians(crease_angle)) + 1e-12"),  # faces at exactly crease_angle split
    ("tools/study", "if options.repeats < 1 or",
     "if options.repeats < 0 or"),  # run_study of no repeat: a raw ValueError
    # Issue 50's eighth independent set: the nine it left alive.
    ("io/meshes/ply_rows", "if signed[k] and value >= 1 << (8 * width - 1):",
     "if signed[k] and value > 1 << (8 * width - 1):"),  # a char count of 0x80 read as +128
    ("io/meshes/gltf_decode", "if count and (at.min() < 0 or at.max() >= len(values)):",
     "if count and (at.min() < 0 or at.max() > len(values)):"),  # a sparse index equal to the count
    ("io/textures", "if pixels.shape[2] in (2, 4) else",
     "if pixels.shape[2] == 4 else"),  # a grey + alpha map's alpha read as 1
    ("renderer/pack", "spread = 2.0 * rig.half_height / (scene.render.height * scene.render.samples)",
     "spread = 2.0 * rig.half_height / scene.render.height"),  # mip level of the pixel, not the sample
    ("io/meshes/source", "return (*self.side_files, *self.images)",
     "return (*self.side_files[:0], *self.images)"),  # an .mtl changed alone is up to date
    ("tools/batch/jobs", '"overrides": list(job.overrides),',
     '"overrides": [],'),  # a sweep's set list changed is up to date
    ("tools/view/access", 'httponly=True, samesite="strict")',
     'httponly=True, samesite="lax")'),  # the page's cookie sent by other sites' links
    ("scene/keypaths", "if not part.isdigit() or int(part) >= len(node):",
     "if not part.isdigit() or int(part) > len(node):"),  # lights.1 of one light: an IndexError
    ("tools/sweep", "return [part if last.count(part) == 1 else key",
     "return [part if last.count(part) >= 1 else key"),  # axes sharing a last part named alike
    # The ninth independent set's survivors (each now killed by a test written for it):
    ("io/textures", "floats = spec.format.basetype in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE)",
     "floats = spec.format.basetype in (oiio.FLOAT, oiio.DOUBLE)"),  # a half-float map read as 8-bit sRGB
    ("io/system", "1 <= int(threads) <= 1024)",
     "1 <= int(threads) < 1024)"),  # NUMBA_NUM_THREADS=1024 refused
    ("io/meshes/content", 'head = head.removeprefix(b"\\xef\\xbb\\xbf")',
     "head = head"),  # a UTF-8 BOM before a text format's first word: the file refused as another format
    ("scene/output", 'Path(output).suffix.lower() != ".exr"',
     'Path(output).suffix != ".exr"'),  # layers refused for -o OUT.EXR
    ("scene/load", "data = read_scene_file(path, max_memory)",
     "data = read_scene_file(path)"),  # a scene file read under the machine's budget, not --max-memory
    ("renderer/budget", "for key in MAP_COLUMNS if getattr(material, key) is not None}",
     "for key in MAP_COLUMNS[:2] if getattr(material, key) is not None}"),  # an emission map not weighed
    ("tools/batch/run", "max_memory = budget // max(processes, 1) if budget else None",
     "max_memory = budget if budget else None"),  # every worker process given the whole budget
    # The tenth independent set's survivors (each now killed by a test written for it):
    ("io/atomic", "reason = reason.splitlines()[0] if reason.strip() else type(error).__name__",
     "reason = reason if reason.strip() else type(error).__name__"),  # a write failure's reason of several lines
    ("errors", "if len(text) <= SHOWN_NAME_CHARACTERS:",
     "if len(text) < SHOWN_NAME_CHARACTERS:"),  # a shown name of exactly 100 characters shortened
    ("io/files", "return (str(Path(path).resolve()), info.st_mtime_ns, info.st_size, info.st_ino)",
     "return (str(Path(path).resolve()), info.st_mtime_ns, info.st_size)"),  # a file swapped in: the same version
    ("io/image_io", "path, (w, h, c) = max(((p, s) for p, s in sizes.items() if s)",
     "path, (w, h, c) = min(((p, s) for p, s in sizes.items() if s)"),  # the budget's refusal names the smallest
    ("io/meshes/off", "if len(lines) < vertex_count + face_count:",
     "if len(lines) < vertex_count + face_count - 1:"),  # a text OFF one face line short not cut short
    ("io/meshes/off", "if faces.size and (faces.min() < 0 or faces.max() >= len(points)):",
     "if faces.size and (faces.min() < 0 or faces.max() > len(points)):"),  # an OFF face index N of N
    ('scene/overrides', '"objects": objects})',
     '"objects": scene.objects})'),
    ('scene/overrides', 'update={"shading": model}),',
     'update={}),'),
    ('scene/overrides', 'key, text = (part.strip() for part',
     'key, text = (part for part'),
    ('scene/keypaths', '[] if parts[depth + 1].isdigit() else {}',
     '{}'),
    ('scene/output', 'or scene.output.path.startswith("~") or',
     'or'),
    ('scene/output', 'or ".." in path.parts:',
     'or path.parts[:1] == ("..",):'),
    ('scene/framing', 'and OUTPUT_PATH not in touched:',
     ':'),
    ('scene/framing', 'touched = {tuple(a.split("=", 1)[0].strip().split(".")) for a in overrides}',
     'touched = {tuple(a.split("=", 1)[0].split(".")) for a in overrides}'),
    ('scene/framing', '0.8 * camera_up - 0.6 * right',
     '0.8 * camera_up + 0.6 * right'),
    ('scene/framing', 'distance = float(np.linalg.norm(to_eye)) or 1.0',
     'distance = 1.0'),
    ('scene/framing', 'sign, axis = (-1.0, text[1:])',
     'sign, axis = (1.0, text[1:])'),
    ('scene/framing', 'value = float(srgb_to_linear(BACKGROUND)) if colour == LINEAR else BACKGROUND',
     'value = BACKGROUND'),
    ('scene/framing', 'if not found.radius >= MIN_EXTENT:',
     'if not found.radius > MIN_EXTENT:'),
    ('scene/framing', 'return (width, height) if width > 0 and height > 0 else (640.0, 480.0)',
     'return (width, height) if width > 0 else (640.0, 480.0)'),
    ('scene/framing', '"output": {"path": f"{stem}.png"},',
     '"output": {"path": "out.png"},'),
    ('scene/load', '("materials", dict)',
     '("materials", list)'),
    ('scene/load', 'if allowed is not None and need > allowed:',
     'if allowed is not None and need >= allowed:'),
    ('scene/load', 'if view is not None or up is not None:',
     'if view is not None:'),
    ('scene/load', 'scene.mesh_sources.update(sources)',
     'pass'),
    ('scene/mesh_arrays', 'used = points[np.unique(corners)]',
     'used = points'),
    ('scene/mesh_arrays', 'if corners.min() < 0 or corners.max() >= len(points):',
     'if corners.max() >= len(points):'),
    ('scene/mesh_arrays', 'if normals is None and "vertex_normals" in getattr(mesh, "_cache", {}):',
     'if False:'),
    ('scene/mesh_arrays', 'return tuple((size[1], size[0]) for size',
     'return tuple((size[0], size[1]) for size'),
    ('geometry/placing', 'return turns[2] @ turns[1] @ turns[0]',
     'return turns[0] @ turns[1] @ turns[2]'),
    ('geometry/placing', '(rotation[:, None, :, k] / scale[:, None, k:k + 1])',
     '(rotation[:, None, :, k] * scale[:, None, k:k + 1])'),
    ('geometry/checks', 'gains[k] = 1.0 / max(d, floor) ** 2',
     'gains[k] = 1.0 / d ** 2 if d else 1.0 / floor ** 2'),
    ('tools/sweep', 'text = re.sub(r"[\\[\\]\\"\' ]", "", text)',
     'text = re.sub(r"[\\[\\]\\"\']", "", text)'),
    ('tools/sweep', 'return re.sub(r"[^A-Za-z0-9._,+=-]", "-", text) or "empty"',
     'return re.sub(r"[^A-Za-z0-9._,+=-]", "-", text)'),
    ('tools/sweep', '    if rows > 1:\n',
     '    if rows > 2:\n'),
    ('tools/sweep', 'room = max(2 * width, ROW_LABEL_MIN)',
     'room = max(width, ROW_LABEL_MIN)'),
    ('tools/sweep', 'if path.suffix.lower() != ".toml"',
     'if path.suffix != ".toml"'),
    ('tools/sweep', 'if path.is_file() and not force and all(',
     'if path.is_file() and all('),
    ('tools/sweep', 'canvas[y:y + height, x:x + width] = FAILED_RGB',
     'canvas[y:y + height, x:x + width] = BACKDROP'),
    ('tools/batch/manifest', 'data.get("format") == MANIFEST_FORMAT',
     'data.get("format", MANIFEST_FORMAT) == MANIFEST_FORMAT'),
    ('tools/batch/manifest', ' or match["name"].endswith("-contact"))',
     ')'),
    ('tools/batch/manifest', 'f"more than the {MANIFEST_LIMIT >> 20} MiB',
     'f"more than the {MANIFEST_LIMIT >> 10} MiB'),
    ('tools/batch/run', 'manifest["sheets"].update(done.sheets)',
     'manifest["sheets"] = done.sheets'),
    ('tools/batch/run', '"processes": processes, "threads": threads,',
     '"processes": threads, "threads": processes,'),
    ('tools/metrics', 'both = (coverage == 1) & (reference.coverage == 1)',
     'both = (coverage == 1)'),
    ('tools/metrics', 'mae=float(diff.mean()) if diff.size else math.nan',
     'mae=float(np.sqrt((diff ** 2).mean())) if diff.size else math.nan'),
    ('tools/metrics', 'peak = mask & (specular >= HIGHLIGHT_LEVEL * peak_value)',
     'peak = mask & (specular >= peak_value)'),
    ('tools/metrics', 'sum(axis=-1) - base, 0, specular)',
     'sum(axis=-1) - base, 0, None)'),
    ('tools/difference', 'return colour_map(np.where(np.isfinite(diff), t, 1.0))',
     'return colour_map(t)'),
    ('tools/difference', 'float(finite.max()) if finite.size else 0.0',
     'float(finite.mean()) if finite.size else 0.0'),
    ('tools/lists', 'return tuple(kind(item) for item in text.split(",") if item.strip())',
     'return tuple(kind(item) for item in text.split(","))'),
    ('cli/progress', 'else f"{minute}:{second:02}"',
     'else f"{minute}:{second}"'),
    ('cli/progress', 'filled = round(share * cells)',
     'filled = int(share * cells)'),
    ("geometry/grouping", "OWN_KEYS[obj.shape]), obj.normals, obj.crease_angle)",
     "OWN_KEYS[obj.shape]), obj.crease_angle)"),  # two boxes of other normals rules share one build
    ("compiles", 'PARTS = (("renderer.kernels.shadows.no_shadow_rays", None),', "PARTS = ("),  # local: "global mode"
    ("io/meshes/ply_lists", "added = int((corners[concave] - 3).sum())",
     "added = int((corners[concave] - 2).sum())"),  # set 13: the cut header counts a face line too many
    ('tools/accuracy', '(4 ** levels - 1)',
     '(4 ** levels)'),
    ('tools/accuracy', 'need = render.width * render.height * REFERENCE_PIXEL_BYTES',
     'need = render.width * render.width * REFERENCE_PIXEL_BYTES'),
    ('tools/compare', 'elif char in "\\"\'":',
     'elif char in "\\"":'),
    ('tools/reference', 'return np.where(p < n, p, 2 * n - 1 - p)',
     'return np.where(p < n, p, 2 * n - p)'),
    ('tools/reference', '("ke", 9)',
     '("ke", 6)'),
    ('tools/reference', '(oiio.HALF, oiio.FLOAT, oiio.DOUBLE)',
     '(oiio.FLOAT, oiio.DOUBLE)'),
    ('tools/reference', 'if pixels.shape[2] < 3:',
     'if pixels.shape[2] < 2:'),
    ('tools/stability', '    progress(len(names), len(names), "done")',
     '    progress(len(names) - 1, len(names), "done")'),
    ('tools/stability', 'named == len(bad) + 1, value=named',
     'named >= len(bad), value=named'),
    ('tools/study', 'return (statistics.median(times) - fastest) / fastest if',
     'return (max(times) - fastest) / fastest if'),
    ('tools/study', '    return (slice(max(rows[0] - margin, 0), rows[-1] + margin + 1),',
     '    return (slice(max(rows[0] - margin, 0), rows[-1] + margin),'),
    ('tools/study', 'return low, max(low, getattr(row, RANGES.get(cost, cost)))',
     'return low, getattr(row, RANGES.get(cost, cost))'),
    ('tools/study', 'digits = 0 if low >= 100 else 1',
     'digits = 0 if low > 100 else 1'),
    ('tools/study', 'if b.image_rmse > STALL * a.image_rmse and b.rmse < 2 / 3 * a.rmse)',
     'if b.image_rmse > STALL * a.image_rmse and b.rmse < a.rmse)'),
    ('tools/study', 'return row.edge_length * math.sqrt(f) if f > 0 and math.isfinite(f) else row.edge_length',
     'return row.edge_length * f if f > 0 and math.isfinite(f) else row.edge_length'),
    ('cli/accuracy', '"margin": None if r.margin is None else (r.margin if math.isfinite(r.margin) else None)',
     '"margin": None if r.margin is None else r.margin'),
    ("renderer/split_compile", "real, types.float64, real, typeof(np.zeros(3, inputs.materials.dtype))",
     "real, real, real, typeof(np.zeros(3, inputs.materials.dtype))"),  # the footprint typed in the precision
    ("io/meshes/stl_ascii", "if kind != SOLID and kind != ENDSOLID and not _plain_rest(data, i, stop):",
     "if False:"),  # "vertex" on an outer loop line, which trimesh's split cuts at
    ("io/meshes/stl_ascii", "                if column != 3:", "                if False:"),  # a two-number vertex
    ("io/meshes/stl_ascii", "(kind == ENDSOLID and expected == FACET and corners > 0)",
     "(kind == ENDSOLID and expected == FACET)"),  # a solid of no facet read as plain
    ("io/meshes/stl_ascii", "vertex_text[written] = SPACE", "vertex_text[written] = 48"),  # numbers run together
    ("io/meshes/decimals", "if c < 48 or c > 57 or exponent > 1000:",
     "if c < 48 or c > 57:"),  # an exponent of 2^64 + 5 wraps round to 5
    ("io/meshes/ply_lists", "else numpy_rows(data[at:read[2]], count, each)",
     "else numpy_rows(data[at:], count, each)"),  # a line past the faces parsed with them
    ("io/meshes/ply_lists", "if read is None or (read[0] != each).any():",
     "if read is None:"),  # rows of uneven word counts adding up read as rows
    ("io/meshes/decimals", "and not _blank(data[at]) and not (comments and data[at] == HASH):",
     "and not _blank(data[at]):"),  # an OFF comment against a number
    ("io/meshes/decimals", "if count == 0 and comments:", "if count == 0 and False:"),  # OFF blank lines as rows
    ("io/meshes/off", "vertices = lines_of_numbers(text, at, vertex_count, True, 3 * vertex_count, True)",
     "vertices = lines_of_numbers(text, at, vertex_count, True, 3 * vertex_count, False)"),  # colours: no room
    ("io/meshes/obj_plain", "elif c < 48 or c > 57 or i - start >= 18:",
     "elif c < 48 or c > 57 or i - start >= 19:"),  # a 19-digit face index wraps an int64
    ("io/meshes/gltf_json", "text = handle.read(JSON_LIMIT + 1)",
     "text = handle.read(JSON_LIMIT)"),  # a .gltf's JSON over the limit parsed cut short
    ("io/meshes/obj", 'if encoding == "utf-8":\n                return data[len(mark):]',
     'if encoding == "utf-8":\n                return data[len(mark) - 1:]'),  # a UTF-8 mark stripped one byte short
    ("io/meshes/gltf", "if start + length > document.binary[1]:",
     "if start > document.binary[1]:"),  # an embedded image's view past the binary chunk read
    # Found in the eleventh round by its own practice set and by the eleventh set's writer (each fails a test):
    ("io/meshes/off", "rgba[np.isnan(rgba)] = 1.0 if floats else 255.0",
     "rgba[np.isnan(rgba)] = 1.0"),  # an uncoloured OFF face among 0..255 colours at 1/255 (the bug it found)
    ("io/meshes/collada", 'by_id.get((found.get("source") or "").lstrip("#"))',
     'by_id.get((found.get("mesh") or "").lstrip("#"))'),  # a skin's mesh looked up by an attribute it lacks
    ("tools/view/session", "stale = [client.pending, client.committed] if full else [client.pending]",
     "stale = [client.pending]"),  # a waiting full request replaced without a dropped message
    # The eleventh independent set's survivors (each now killed by a test written for it, or by one its subset lacked):
    ('jit', 'digest = hashlib.sha256(numba.__version__.encode())',
     'digest = hashlib.sha256()'),  # the kernel key without numba's version
    ('scene/overrides', 'assignment.split("=", 1))',
     'assignment.rsplit("=", 1))'),  # --set split at the last '='
    ('tools/batch/run', 'budget // (2 * WORKER_BYTES)',
     'budget // WORKER_BYTES'),  # a batch worker's scenes left out of its room
    ('geometry/checks', 'gains[k] = 1.0 / max(d, floor) ** 2',
     'gains[k] = 1.0 / max(d, floor)'),  # the 1/d² gain bound as 1/d
    ('io/meshes/mtl', '"-mm": 2,',
     '"-mm": 1,'),  # -mm taking one value
    ('io/meshes/mtl', 'values.get("illum", [2])[0]',
     'values.get("illum", [1])[0]'),  # the default illum 1
    ('io/meshes/gltf', 'total += copies * (accessors[indexed]["count"] // 3)',
     'total += accessors[indexed]["count"] // 3'),  # instances left off the triangle count
    # the twelfth set's survivors (docs/testing.md)
    ('io/meshes/off', 'block[:, width + 3 * normals:width + 3 * normals + min(spare, 4)]',
     'block[:, width:width + min(spare, 4)]'),  # CNOFF's colours read from the normal's columns
    ('io/meshes/format', 'normals @ np.linalg.inv(linear)',
     'normals @ linear.T'),  # normals turned by the matrix, not its inverse transpose
    ('io/scene_file', '(stdin and text.lstrip("\\ufeff \\t\\r\\n").startswith("{"))',
     '(stdin and text.startswith("{"))'),  # JSON on stdin after a blank line read as TOML
    ('geometry/textures', 'else id(found.source), found.wrap_s, found.wrap_t, channel)',
     'else id(found.source), found.wrap_s, found.wrap_t)'),  # one image's colour and alpha as one texture
    ('renderer/plan', 'if light.type == "point" and light.attenuation != "none"]',
     'if light.attenuation != "none"]'),  # a directional light's attenuation kept as a stage
    # the bugs the coverage pass found (docs/testing.md), each back as it was
    ('io/image_io', 'config.attribute("oiio:UnassociatedAlpha", 1)',
     'config.attribute("oiio:UnassociatedAlpha", 0)'),  # a map's colour multiplied by its alpha
    ('io/meshes/ply', 'folder / (names[0] if names else resolved(name, reading.path))',
     'folder / resolved(name, reading.path)'),  # the last TextureFile read, the note saying the first
    ('io/meshes/threemf', 'parent = element.getparent()\n                    if parent is not None:\n'
     '                        del parent[:parent.index(element)]',
     'del element.getparent()[:-1]'),  # the batch drop deleting siblings read ahead
    ('io/meshes/threemf',
     '        raise _not_a_number(what, path) from None\n    if dtype is np.float64 or ("." not in text and "e" not '
     'in text.lower()):',
     '        text = None\n    if text is not None and (dtype is np.float64 or ("." not in text and "e" not in '
     'text.lower())):'),  # a missing coordinate read as NaN
    ('tools/sweep', 'if not isinstance(data.get("grid"), dict)',
     'if not isinstance(data["grid"], dict)'),  # a sweep without grid a KeyError
    ('tools/view/session', 'refused.id = request.get("id") if isinstance(request, dict) else None',
     'refused.id = None'),  # an unknown type answered without its id
    ('tools/view/server', 'except (SceneError, ViewError) as error:  # the format',
     'except SceneError as error:  # the format'),  # a loaded file past the view's limits not named
    ('io/meshes/format',
     '    with np.errstate(invalid="ignore", over="ignore"):\n        determinant = np.linalg.det(linear)',
     '    if True:\n        determinant = np.linalg.det(linear)'),  # numpy's det and matmul warnings on a placement
    # this session's fixes, each planted once and seen to fail its test
    ("io/meshes/content", "    if head.startswith(LFS_POINTER):", "    if head.startswith(LFS_POINTER * 2):"),  # LFS
    ("io/meshes/content", "    for pattern, foreign in FOREIGN:",
     "    for pattern, foreign in FOREIGN[:0]:"),  # an MNI .obj read as Wavefront
    ("io/image_io", "needed > BOMB_FLOOR and needed > BOMB_RATIO * size:",
     "needed > BOMB_FLOOR and needed > BOMB_RATIO * size * 100:"),  # a decompression bomb read
    ("io/meshes/gltf_decode", "        if colour_uv_sets(tree):  # trimesh maps",
     "        if False:  # trimesh maps"),  # texCoord 1 drawn with TEXCOORD_0
    ("io/meshes/collada", "    if largest >= int(count):", "    if largest > int(count):"),  # an index one past
    ("scene/output", "check_output_path(output, inputs=inputs)",
     "check_output_path(output, inputs=inputs[:1])"),  # render -o onto the scene's own map
    ("io/meshes/gltf_json", "and container != 2:", "and container == 0:"),  # a glTF 1.0 GLB
    ("io/meshes/gltf", "TextureSource(getattr(material, key), wrap_s, wrap_t,",
     "TextureSource(getattr(material, key), wrap_t, wrap_s,"),  # a sampler's wrapS and wrapT swapped
    ("io/meshes/gltf_json", ' and not row["uri"].startswith("data:")]', "]"),  # a data: URI taken for a file
    ("tools/view/session", "return self.pending is not None or self.committed is not None",
     "return self.pending is not None"),  # a stale full frame rendered after a newer full request came
    ("scene/schema", "else inverse_square.get(k, 0.0)", "else inverse_square.get(k, 1.0)"),  # a far 1/d² light
)
OPERATOR_SWAPS = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
                  ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
                  ast.NotEq: ast.Eq, ast.And: ast.Or, ast.Or: ast.And}
NAME_SWAPS = {"zero": ["one"], "one": ["zero"], "two": ["one"]}


@dataclass
class Mutant:
    module: str
    line: int
    col: int
    end_col: int
    kind: str
    original: str   # the node's source text
    mutated: str    # its replacement
    status: str = "pending"
    seconds: float = 0.0
    failed: str = ""   # the first failing test, for a killed mutant
    tests: str = ""    # the test subset it ran against, space-separated

    @property
    def key(self) -> str:
        return f"{self.module}.py:{self.line}:{self.col} {self.kind}: {self.original} → {self.mutated}"


def _skipped_spans(tree: ast.Module) -> set[int]:
    """ids of nodes never mutated: docstrings, decorators, annotations, imports, raise statements."""
    skip: set[int] = set()

    def mark(node):
        for sub in ast.walk(node):
            skip.add(id(sub))

    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                mark(first)
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            for decorator in node.decorator_list:
                mark(decorator)
            if isinstance(node, ast.FunctionDef):
                if node.returns:
                    mark(node.returns)
                for arg in [*node.args.args, *node.args.kwonlyargs, *node.args.posonlyargs]:
                    if arg.annotation:
                        mark(arg.annotation)
        if isinstance(node, ast.AnnAssign):
            mark(node.annotation)
        if isinstance(node, (ast.Import, ast.ImportFrom, ast.Raise, ast.JoinedStr)):
            mark(node)
    return skip


KINDS = ("operator", "compare", "drop", "constant", "name", "sign", "swap", "negate")


def _variants(node: ast.AST) -> list[tuple[str, ast.AST]]:
    """(kind, mutated copy) for one node."""
    out = []
    if isinstance(node, ast.BinOp):
        if type(node.op) in OPERATOR_SWAPS:
            new = copy.deepcopy(node)
            new.op = OPERATOR_SWAPS[type(node.op)]()
            out.append(("operator", new))
        if isinstance(node.op, (ast.Add, ast.Sub, ast.Mult)):
            out.append(("drop", node.left))
        if isinstance(node.op, ast.Add):
            out.append(("drop", node.right))
    elif isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in OPERATOR_SWAPS:
        new = copy.deepcopy(node)
        new.ops = [OPERATOR_SWAPS[type(node.ops[0])]()]
        out.append(("compare", new))
    elif isinstance(node, ast.BoolOp):
        new = copy.deepcopy(node)
        new.op = OPERATOR_SWAPS[type(node.op)]()
        out.append(("operator", new))
    elif isinstance(node, ast.Constant) and type(node.value) in (int, float):
        value = node.value
        replacement = {0: 1, 1: 0, 2: 1}.get(value, value * 2) if value in (0, 1, 2) else value * 2
        if isinstance(value, float):
            replacement = float(replacement)
        if replacement != value:
            out.append(("constant", ast.Constant(replacement)))
    elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id in NAME_SWAPS:
        out += [("name", ast.Name(other, ast.Load())) for other in NAME_SWAPS[node.id]]
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        out.append(("sign", node.operand))
    elif isinstance(node, ast.Call) and len(node.args) >= 2 and all(isinstance(a, ast.Name) for a in node.args[:2]) \
            and node.args[0].id != node.args[1].id:
        new = copy.deepcopy(node)
        new.args[0], new.args[1] = new.args[1], new.args[0]
        out.append(("swap", new))
    return out


def _conditions(tree: ast.Module) -> list[ast.AST]:
    return [n.test for n in ast.walk(tree) if isinstance(n, (ast.If, ast.IfExp, ast.While))]


def generate(module: str, source: str | None = None) -> list[Mutant]:
    """Every one-line mutant of raycast_phong/<module>.py (or of `source`), in source order."""
    if source is None:
        source = (REPO / PACKAGE / f"{module}.py").read_text(encoding="utf-8")
    lines = source.splitlines()
    tree = ast.parse(source)
    skip = _skipped_spans(tree)
    conditions = {id(c) for c in _conditions(tree)}
    mutants, seen = [], set()
    for node in ast.walk(tree):
        if id(node) in skip or not hasattr(node, "lineno") or node.lineno != node.end_lineno:
            continue
        variants = _variants(node)
        if id(node) in conditions:
            variants.append(("negate", ast.UnaryOp(ast.Not(), copy.deepcopy(node))))
        line = lines[node.lineno - 1]
        # ast's offsets count UTF-8 bytes; the line is sliced by characters (a "×" before a node shifts it)
        head = line.encode("utf-8")
        col, end_col = (len(head[:offset].decode("utf-8")) for offset in (node.col_offset, node.end_col_offset))
        original = line[col:end_col]
        for kind, new in variants:
            text = ast.unparse(new)
            if kind in ("operator", "compare", "negate", "sign", "drop", "swap") \
                    and isinstance(node, (ast.BinOp, ast.BoolOp, ast.Compare)):
                text = f"({text})"  # keep the precedence the original had in its context
            key = (node.lineno, col, end_col, text)
            if text == original or key in seen:
                continue
            seen.add(key)
            mutated_line = line[:col] + text + line[end_col:]
            try:
                ast.parse("\n".join([*lines[:node.lineno - 1], mutated_line, *lines[node.lineno:]]))
            except SyntaxError:
                continue
            mutants.append(Mutant(module, node.lineno, col, end_col, kind, original, text))
    return sorted(mutants, key=lambda m: (m.line, m.col, m.kind, m.mutated))


def hand_mutants(listed=HAND_MUTANTS) -> list[Mutant]:
    """HAND_MUTANTS (or another list of (module, original, mutated[, why])) as Mutants (kind "hand": a text
    replacement, which may span lines)."""
    mutants = []
    for module, original, mutated, *_ in listed:
        source = (REPO / PACKAGE / f"{module}.py").read_text(encoding="utf-8")
        if source.count(original) != 1:  # the code moved on: rewrite the mutant against today's text
            print(f"{module}: a hand mutant's text is not there once, left out: {original!r}", file=sys.stderr)
            continue
        line = source[:source.index(original)].count("\n") + 1
        mutants.append(Mutant(module, line, 0, 0, "hand", original, mutated))
    return mutants


def _fresh_copy(origin: Path | None = None) -> Path:
    """The files of `origin` (default: the snapshot taken at the start) at WORK/repo; always the same path,
    so numba's cache folder name is stable, and never the working tree, which may change during a run."""
    origin = origin or WORK / "snapshot"
    target = WORK / ("snapshot" if origin == REPO else "repo")
    shutil.rmtree(target, ignore_errors=True)
    target.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache")
    for name in COPIED:
        source = origin / name
        if source.is_dir():
            shutil.copytree(source, target / name, ignore=ignore)
        else:
            shutil.copy2(source, target / name)
    return target


MARKS = "not bench"  # --fast: "not bench and not slow"


def pytest_command(tests: list[str]) -> list[str]:
    """pytest on `tests`, stopping at the first failure. Lint is left out: a mutant is unidiomatic on purpose
    ("(points)"), so ruff would kill it for its style. A subset runs in one process (its tests in their order);
    the whole suite (--whole) on every core, as CI runs it. The check that each hand mutant's text occurs once is
    left out too: a mutant that edits one of those texts fails it, whatever the behaviour, and with -x that first
    failure would stand in for a kill."""
    spread = ["-n", "auto"] if tests == ["tests"] else []
    return [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-o", f"addopts=-m '{MARKS}'",
            *spread, "--deselect", "tests/project/test_project.py::test_ruff_is_clean",
            "--deselect", "tests/project/test_mutation_script.py::test_every_hand_mutant_still_finds_its_text_once",
            *tests]


def _run_tests(repo: Path, cache: Path, tests: list[str], timeout: float) -> tuple[str, str]:
    env = {**os.environ, "PYTHONPATH": str(repo), "NUMBA_CACHE_DIR": str(cache), "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("RAYCAST_PHONG_DEBUG", None)
    try:
        done = subprocess.run(pytest_command(tests), cwd=repo, env=env, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", ""
    if done.returncode == 0:
        return "survived", ""
    output = done.stdout.strip().splitlines() or [f"exit code {done.returncode}"]
    failed = next((line for line in output if line.startswith(("FAILED", "ERROR"))), output[-1])
    return "killed", failed[:200]


def imported_from(repo: Path) -> str:
    """Where the core package is imported from with `repo` on PYTHONPATH (or the error that stopped it)."""
    module = PACKAGE.replace("/", ".")
    check = subprocess.run([sys.executable, "-c", f"import {module}; print({module}.__file__)"], cwd=repo,
                           env={**os.environ, "PYTHONPATH": str(repo)}, capture_output=True, text=True)
    return check.stdout.strip() or check.stderr.strip()


def snapshot() -> Path:
    """Snapshot the repository once; the numba cache the baselines fill and every mutant starts from."""
    _fresh_copy(REPO)
    cache = WORK / "cache-base"
    shutil.rmtree(cache, ignore_errors=True)
    return cache


def baseline(tests: list[str], timeout: float, cache: Path) -> None:
    """Run a subset on an unmutated copy (it must pass), adding its kernels to the shared seed cache."""
    repo = _fresh_copy()
    imported = imported_from(repo)
    if not imported.startswith(str(repo)):
        sys.exit(f"the copy is not what gets imported ({imported})")
    status, failed = _run_tests(repo, cache, tests, timeout * 3)
    if status != "survived":  # once more: a test that is flaky under load should not end a long run
        print(f"baseline {' '.join(tests)} failed ({failed}); once more", flush=True)
        status, failed = _run_tests(repo, cache, tests, timeout * 3)
    if status != "survived":
        sys.exit(f"the unmutated code fails the test subset {' '.join(tests)} ({status}: {failed}); fix that first")


def run_one(mutant: Mutant, seed_cache: Path, tests: list[str], timeout: float) -> None:
    mutant.tests = " ".join(tests)
    repo = _fresh_copy()
    path = repo / PACKAGE / f"{mutant.module}.py"
    source = path.read_text(encoding="utf-8")
    if mutant.kind == "hand":
        assert source.count(mutant.original) == 1, f"source moved under {mutant.key}"
        path.write_text(source.replace(mutant.original, mutant.mutated), encoding="utf-8")
    else:
        lines = source.split("\n")
        line = lines[mutant.line - 1]
        assert line[mutant.col:mutant.end_col] == mutant.original, f"source moved under {mutant.key}"
        lines[mutant.line - 1] = line[:mutant.col] + mutant.mutated + line[mutant.end_col:]
        path.write_text("\n".join(lines), encoding="utf-8")
    cache = WORK / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    shutil.copytree(seed_cache, cache)
    # No stale kernels to delete: raycast_phong/jit.py keys the cache folder on the kernel modules' source.
    start = time.perf_counter()
    mutant.status, mutant.failed = _run_tests(repo, cache, tests, timeout)
    mutant.seconds = round(time.perf_counter() - start, 1)


def write_reports(mutants: list[Mutant], out: Path, tests: list[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "mutants.json").write_text(json.dumps({"tests": tests, "mutants": [asdict(m) for m in mutants]},
                                                 indent=1, ensure_ascii=False), encoding="utf-8")
    done = [m for m in mutants if m.status != "pending"]
    subset = " ".join(tests) if tests else "each module's own (tests_for), in mutants.json"
    lines = ["# Mutation run", "", f"Test subset: `{subset}`", "",
             "| module | mutants | killed | survived | timeout | score |", "|---|---|---|---|---|---|"]
    for module in [*sorted({m.module for m in done}), "all"]:
        ms = [m for m in done if module in ("all", m.module)]
        killed = sum(m.status in ("killed", "timeout") for m in ms)
        lines.append(f"| {module} | {len(ms)} | {sum(m.status == 'killed' for m in ms)} | "
                     f"{sum(m.status == 'survived' for m in ms)} | {sum(m.status == 'timeout' for m in ms)} | "
                     f"{killed / len(ms):.0%} |" if ms else f"| {module} | 0 | | | | |")
    lines += ["", "## Survivors", ""]
    lines += [f"- `raycast_phong/{m.key}`" for m in done if m.status == "survived"] or ["none"]
    (out / "report.md").write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--module", action="append", choices=MODULES, metavar="MODULE",
                        help="a module to mutate, its path below raycast_phong/ (repeatable; default: every module; "
                             "with --hand, the hand mutants of these modules)")
    parser.add_argument("--hand", action="store_true", help="run HAND_MUTANTS, the bugs written by hand")
    parser.add_argument("--hand-file", type=Path, help="a JSON list of [module, original, mutated, why] to run "
                        "instead of HAND_MUTANTS (a set written apart, measured before it joins them); implies --hand")
    parser.add_argument("--whole", action="store_true", help="run each survivor of its subset again against the "
                        "whole suite (a test elsewhere may kill it); slower, but what 'killed' means in a measure")
    parser.add_argument("--kind", action="append", choices=KINDS, help="only mutants of this kind (repeatable)")
    parser.add_argument("--core", action="store_true", help="the kernel and stage modules only (CORE_MODULES)")
    parser.add_argument("--outside-core", action="store_true", help="every module but CORE_MODULES and the kernels")
    parser.add_argument("--fast", action="store_true", help="leave the tests marked slow out of every subset")
    parser.add_argument("--sample", type=int, help="run a random sample of this many mutants of each module")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--budget", type=float, default=float("inf"), help="start no mutant after this many seconds")
    parser.add_argument("--timeout", type=float, default=240.0, help="seconds per mutant before it counts as timeout")
    parser.add_argument("--tests", nargs="+", help="one test subset for every module (default: tests_for each)")
    parser.add_argument("--out", type=Path, default=REPO / "build" / "mutation")
    parser.add_argument("--list", action="store_true", help="print the mutants and stop")
    parser.add_argument("--rerun", type=Path, help="re-run the survivors (and timeouts) of an earlier mutants.json")
    args = parser.parse_args()

    global MARKS
    if args.fast:
        MARKS = "not bench and not slow"
    if args.rerun:
        earlier = json.loads(args.rerun.read_text(encoding="utf-8"))
        mutants = [Mutant(**m) for m in earlier["mutants"]]
        todo = [m for m in mutants if m.status in ("survived", "timeout", "pending")]
    elif args.hand or args.hand_file:  # with --module: those of these modules only
        listed = json.loads(args.hand_file.read_text(encoding="utf-8")) if args.hand_file else HAND_MUTANTS
        mutants = todo = [m for m in hand_mutants(listed) if not args.module or m.module in args.module]
    else:
        mutants = []
        outside = [m for m in MODULES if m not in CORE_MODULES and not m.startswith("renderer/kernels/")]
        for module in args.module or (CORE_MODULES if args.core else outside if args.outside_core else MODULES):
            candidates = [m for m in generate(module) if not args.kind or m.kind in args.kind]
            if args.sample and args.sample < len(candidates):
                candidates = sorted(random.Random(f"{args.seed}-{module}").sample(candidates, args.sample),
                                    key=lambda m: m.line)
            mutants += candidates
        todo = mutants
    if args.list:
        print("\n".join(m.key for m in mutants), f"\n{len(mutants)} mutants", sep="")
        return
    start = time.perf_counter()
    seed_cache, passed = snapshot(), set()
    print(f"{len(todo)} mutants", flush=True)
    for index, mutant in enumerate(todo, 1):
        if time.perf_counter() - start > args.budget:
            print(f"budget spent: {len(todo) - index + 1} mutants not run", flush=True)
            break
        tests = args.tests or (mutant.tests.split() if args.rerun and mutant.tests else tests_for(mutant.module))
        if tuple(tests) not in passed:
            began = time.perf_counter()
            baseline(tests, args.timeout, seed_cache)
            passed.add(tuple(tests))
            print(f"baseline {' '.join(tests)} passed in {time.perf_counter() - began:.0f} s", flush=True)
        run_one(mutant, seed_cache, tests, args.timeout)
        if args.whole and mutant.status == "survived" and tests != ["tests"]:
            if ("tests",) not in passed:
                baseline(["tests"], args.timeout, seed_cache)
                passed.add(("tests",))
            run_one(mutant, seed_cache, ["tests"], args.timeout * 3)
        print(f"[{index}/{len(todo)}] {mutant.status:8} {mutant.seconds:5.1f} s  {mutant.key}  {mutant.failed}",
              flush=True)
        write_reports(mutants, args.out, args.tests or [])
    write_reports(mutants, args.out, args.tests or [])
    print(f"report: {args.out / 'report.md'}")


if __name__ == "__main__":
    main()
