"""Embree's C API (renderer/embree_library.py, renderer/kernels/ray_queries.py) against embreex's own API, its
kernel cache and its errors.

embreex renders nothing (docs/pipeline.md, Backends): it stays here only as the independent cross-check.
The same library answers the same rays through its one-ray API, so a future embreex or Embree whose layout
no longer matches ray_queries.py's structs shows here as different hits.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer import embree_library as embree
from raycast_phong.renderer.intersect import Accelerator, TileHits, unit_frame
from raycast_phong.renderer.pack import camera_rig, generate_rays

SCENES = Path(__file__).resolve().parents[3] / "scenes"

# Both paths run Embree's own float32 ray–triangle test (robust mode) on the same vertices and rays, but the
# 16-wide packet kernel may evaluate the same products in another order or fused (FMA): u, v and t are ratios
# of sums of three products, each rounded within a few float32 ulps of its largest term. 16 ε relative (ε =
# 2^-23), and 16 ε absolute for u, v ∈ [0, 1], bounds that for any triangle not seen edge-on.
EPS32 = float(np.finfo(np.float32).eps)


class Embreex:
    """embreex's one-ray API on the same unit-frame mesh: the independent answers the C API is checked against."""

    def __init__(self, geometry, frame):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
        self.scene = rtcore_scene.EmbreeScene(robust=True)  # robust, as embree.EmbreeScene
        TriangleMesh(self.scene, frame.to_unit(geometry.vertices).astype(np.float32),
                     np.ascontiguousarray(geometry.faces, np.int32))

    def closest_hits(self, origins, directions) -> TileHits:
        found = self.scene.run(origins, directions, output=1)
        return TileHits(face=found["primID"], u=found["u"], v=found["v"], t=found["tfar"])

    def occluded(self, origins, directions, t_max) -> np.ndarray:
        return self.scene.run(origins, directions, dists=t_max, query="OCCLUDED") == 0  # 0: blocked


def _both_ways(geometry, origins, directions):
    frame = unit_frame(geometry.vertices)
    c_api, embreex = Accelerator(geometry, frame), Embreex(geometry, frame)
    return c_api.closest_hits(origins, directions), embreex.closest_hits(origins, directions), c_api, embreex


@pytest.mark.parametrize("name", sorted(path.stem for path in SCENES.glob("*.toml")))
def test_the_c_api_finds_the_hits_embreex_finds(name):
    """Every camera ray of every example scene (one 48-row band of tiles): same face, u, v, t to float32 rounding."""
    scene = rp.load_scene(SCENES / f"{name}.toml", ["render.width=160", "render.height=120"])
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    origins, directions = generate_rays(camera_rig(scene), frame, 160, 120, 1, 0, 120)
    ours, theirs, _, _ = _both_ways(geometry, origins, directions)
    hit = theirs.face >= 0
    assert hit.any() and (~hit).any()
    np.testing.assert_array_equal(ours.face, theirs.face)
    np.testing.assert_allclose(ours.u[hit], theirs.u[hit], rtol=16 * EPS32, atol=16 * EPS32)
    np.testing.assert_allclose(ours.v[hit], theirs.v[hit], rtol=16 * EPS32, atol=16 * EPS32)
    np.testing.assert_allclose(ours.t[hit], theirs.t[hit], rtol=16 * EPS32)
    assert (ours.t[~hit] == theirs.t[~hit]).all()  # 1e37, the "no limit" both paths start from


def test_random_rays_and_occlusion_agree_with_embreex():
    """Rays from everywhere in every direction (not a coherent packet), in counts that leave a partial last
    packet, and occlusion within random limits: the same answers both ways."""
    rng = np.random.default_rng(12)
    scene = rp.load_scene(SCENES / "shadows.toml")
    geometry = build_geometry(scene)
    count = 16 * 997 + 5
    origins = rng.uniform(-1.5, 1.5, (count, 3)).astype(np.float32)
    directions = rng.normal(size=(count, 3))
    directions = (directions / np.linalg.norm(directions, axis=1)[:, None]).astype(np.float32)
    ours, theirs, c_api, embreex = _both_ways(geometry, origins, directions)
    hit = theirs.face >= 0
    assert 0.1 < hit.mean() < 0.9
    np.testing.assert_array_equal(ours.face >= 0, hit)
    # The box stands on the floor: its bottom faces and the floor's coincide, and a ray that meets them there
    # has two closest hits at the same t; which one a traversal reports depends on its order (4 of 2110 hits
    # here). Such a tie is the only difference allowed: the same t, and both faces in one plane.
    tie = ours.face != theirs.face
    assert tie.sum() < 0.01 * hit.sum()
    normals = geometry.face_normals
    assert (np.abs(np.einsum("ij,ij->i", normals[ours.face[tie]], normals[theirs.face[tie]])) > 1 - 1e-12).all()
    np.testing.assert_allclose(ours.t[hit], theirs.t[hit], rtol=16 * EPS32)
    # Limits well away from the hit distance, where a rounding of t could not flip the answer.
    t_max = (np.where(rng.random(count) < 0.5, 0.5, 2.0) * np.where(hit, theirs.t, 3.0)).astype(np.float32)
    blocked = c_api.occluded(origins, directions, t_max.copy())
    np.testing.assert_array_equal(blocked, embreex.occluded(origins, directions, t_max.copy()))
    np.testing.assert_array_equal(blocked, hit & (t_max > theirs.t))


RENDER = """
import sys
import numpy as np
import raycast_phong as rp
from raycast_phong.renderer import embree_library as embree
from raycast_phong.renderer.kernels import tile
result = rp.render_file(sys.argv[1], ["render.width=48", "render.height=36"], threads=2)
np.save(sys.argv[2], result.image)
stats = tile.render_band.stats  # the tile kernel: rays, rtcIntersect16, [rtcOccluded16,] shading
print(embree.library().path, sum(stats.cache_hits.values()), sum(stats.cache_misses.values()))
"""


def _run(code: str, *args: str, env: dict | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess:
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})}, cwd=cwd)
    assert done.returncode == 0, done.stderr
    return done


@pytest.mark.parametrize("library", ["missing", "without-symbols"])
def test_without_the_library_a_render_stops_with_one_clear_line(tmp_path, library):
    """A library that is not there, or one without Embree's symbols (libtbb beside it), named by the variable: the
    CLI exits 2 (the variable is the user's input) with one line that names it and says what to do; nothing falls
    back."""
    path = tmp_path / "libembree4.so.4" if library == "missing" else next(
        embree.library_path().parent.glob("libtbb*"))
    cli = ("import sys; sys.argv = ['raycast-phong', 'render', '--width', '8', '--height', '6', '-o', "
           f"{str(tmp_path / 'x.png')!r}]; from raycast_phong.cli import app; app()")
    done = subprocess.run([sys.executable, "-c", cli], capture_output=True, text=True, timeout=300,
                          env={**os.environ, embree.LIBRARY_VARIABLE: str(path)}, cwd=tmp_path)
    lines = [line for line in done.stderr.splitlines() if line.strip() and "compiling" not in line]
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0].startswith(f"error: {embree.LIBRARY_VARIABLE}={path}: ") and "or unset it" in lines[0], lines[0]
    assert not (tmp_path / "x.png").exists()


@pytest.mark.slow
def test_a_cached_kernel_that_calls_embree_loads_without_compiling(cold_package, tmp_path):
    """The queries link by name (llvmlite add_symbol), so numba's cache serves a fresh process: no recompile.
    The shared copy's kernels were compiled by another process (its first `render`) into its own cache."""
    scene = str(SCENES / "default.toml")
    fresh = cold_package.python(RENDER, scene, str(tmp_path / "fresh.npy")).stdout.split()
    assert int(fresh[1]) > 0 and int(fresh[2]) == 0, f"hits, misses = {fresh[1:]}: the cached kernel recompiled"
    here = rp.render_file(scene, ["render.width=48", "render.height=36"], threads=2).image  # this process's
    np.testing.assert_array_equal(np.load(tmp_path / "fresh.npy"), here)


OUT_OF_ADDRESS_SPACE = """
import re, resource, sys
import raycast_phong as rp
from raycast_phong.renderer import embree_library as embree
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.intersect import Accelerator
geometry = build_geometry(rp.load_scene(sys.argv[1]))
embree.library()  # mapped now: this test is about the device, not about loading the library
# Leave 20 MB of address space above what the process uses now: Embree reserves more for a device
# (its thread pool's stacks alone take 8 MB a thread).
used = int(re.search(r"VmSize:\\s+(\\d+)", open("/proc/self/status").read()).group(1)) * 1024
resource.setrlimit(resource.RLIMIT_AS, (used + 20 * 2**20, resource.RLIM_INFINITY))
try:
    Accelerator(geometry)
except embree.EmbreeError as error:
    print(error)
"""


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads VmSize from Linux's /proc")
def test_an_embree_device_error_becomes_one_clear_error():
    """A real fault: too little address space for Embree's device. EmbreeError names what failed and why."""
    done = _run(OUT_OF_ADDRESS_SPACE, str(SCENES / "default.toml"))
    assert done.stdout.startswith("Embree failed while creating a device: out of memory"), done.stdout + done.stderr


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="reads the resident size from Linux's /proc")
def test_dropping_an_accelerator_releases_embrees_scene_and_device():
    """40 BVHs of 82k triangles built and dropped in turn: resident memory stays within a few BVHs' worth.
    Without rtcReleaseScene / rtcReleaseDevice each would stay (≈ 5 MB apiece: 202 MB measured)."""
    scene = rp.validate_scene({"objects": [{"shape": "icosphere", "subdivisions": 6}]}, source="test")
    geometry = build_geometry(scene, vertex_normals=False)
    page = os.sysconf("SC_PAGE_SIZE")

    def resident() -> int:
        return int(Path("/proc/self/statm").read_text().split()[1]) * page

    Accelerator(geometry)  # the first one also brings up Embree's thread pool and allocator
    before = resident()
    for _ in range(40):
        Accelerator(geometry)
    assert resident() - before < 60 * 2**20, f"{(resident() - before) / 2**20:.0f} MB kept after 40 dropped BVHs"


def test_the_tile_kernel_in_global_mode_gives_the_same_image_on_one_and_three_threads():
    """Shadow rays from Embree's C API on a thread pool: bands on 3 threads (concurrent rtcIntersect16 and
    rtcOccluded16 on one scene) give the image one thread gives, bit for bit, with shadows where lights are
    blocked and local mode's light where none is."""
    overrides = ["render.width=320", "render.height=200", "render.samples=2"]
    one = rp.render_file(SCENES / "shadows.toml", overrides, threads=1)
    three = rp.render_file(SCENES / "shadows.toml", overrides, threads=3)
    local = rp.render_file(SCENES / "shadows.toml", [*overrides, 'render.mode="local"'], threads=3)
    np.testing.assert_array_equal(one.image, three.image)
    assert (local.image - three.image).max() > 0.1  # somewhere a light is blocked in global mode only
    # ... and somewhere every light reaches a brightly lit point, exactly as in local mode.
    assert ((local.image.max(axis=2) > 0.3) & (local.image == three.image).all(axis=2)).any()


# Embree 4.4's verbose device report on an AVX-512 CPU (abridged): the targets line without a parenthesis
# lists what the library knows, the other two what the CPU supports and what the build enabled.
REPORT = """
Embree Ray Tracing Kernels 4.4.0 (e794a4799e1ec68c7141f382864481095edd9c48)
  CPU       : Unknown CPU (AuthenticAMD)
   ISA      : XMM YMM ZMM SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 POPCNT AVX F16C RDRAND AVX2 FMA3 AVX512F
   Targets  : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 AVX AVXI AVX2 AVX512
  Config
    Targets : SSE SSE2 SSE3 SSSE3 SSE4.1 SSE4.2 AVX AVXI {cpu}  (supported)
              SSE2 SSE4.2 AVX {build}  (compile time enabled)
"""


@pytest.mark.parametrize(("cpu", "build", "picked"), [
    ("AVX2 AVX512", "AVX2 AVX512", "AVX512"),  # both: the best
    ("AVX2 AVX512", "AVX2", "AVX2"),           # a library built without AVX-512 on an AVX-512 CPU
    ("", "AVX2 AVX512", "AVX"),                # a CPU without AVX2: AVXI is not enabled in the build, AVX is
])
def test_the_isa_embree_picked_is_the_best_target_both_lists_name(cpu, build, picked):
    assert embree.picked_target(REPORT.format(cpu=cpu, build=build)) == picked


def test_a_report_without_targets_names_no_isa():
    assert embree.picked_target("Embree Ray Tracing Kernels 4.4.0\n   Targets  : SSE2 AVX2\n") is None
    assert embree.picked_target("") is None


def test_the_device_report_is_captured_from_the_library_and_names_an_isa(capfd):
    report = embree.device_report(embree.library())
    assert "Embree Ray Tracing Kernels" in report
    assert embree.picked_target(report) in embree.TARGETS
    assert "Embree Ray Tracing Kernels" not in capfd.readouterr().out  # captured, not printed


def test_prepared_packets_cast_alone_give_the_hits_closest_hits_gives():
    """intersect.packed_rays + cast_packets (bench_frame's yardstick): the same packets as closest_hits (4 × 4
    blocks of an image 37 rays wide, partial blocks at the edges), so the hits left in them are the same bits;
    cast twice, as the benchmark repeats it, they stay so (tfar and geomID are reset before each cast)."""
    from raycast_phong.renderer.intersect import packed_rays
    from raycast_phong.renderer.kernels import ray_queries as kernels
    scene = rp.load_scene(SCENES / "default.toml", ["render.width=37", "render.height=23"])
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    origins, directions = generate_rays(camera_rig(scene), frame, 37, 23, 1, 0, 23)
    accelerator = Accelerator(geometry, frame)
    expected = accelerator.closest_hits(origins, directions, 37)
    packets, valid = packed_rays(origins, directions, 37)
    assert packets.ctypes.data % 64 == 0 and valid.ctypes.data % 64 == 0
    assert len(packets) == 6 * 10  # ⌈23 / 4⌉ block rows × ⌈37 / 4⌉ block columns
    for _ in range(2):
        accelerator.cast_packets(packets, valid)
        face = np.full(37 * 23, -2, np.int64)
        u = np.full(37 * 23, np.nan, np.float32)
        ints = packets.view(np.int32)
        for p in range(len(packets)):
            r0, c0 = 4 * (p // 10), 4 * (p % 10)
            for lane in np.flatnonzero(valid[p]):
                k = (r0 + lane // 4) * 37 + c0 + lane % 4
                hit = ints[p, kernels.GEOM_ID + lane] != kernels.INVALID_ID
                face[k] = ints[p, kernels.PRIM_ID + lane] if hit else -1
                u[k] = packets[p, kernels.HIT_U + lane] if hit else 0
        assert (face == expected.face).all() and (face >= 0).any() and (face < 0).any()
        assert u.tobytes() == expected.u.tobytes()


@pytest.mark.parametrize("name", ["shadows", "mesh", "creases"])
def test_a_compact_bvh_finds_the_hits_the_default_one_finds(name, monkeypatch):
    """A mesh of embree.COMPACT_FACES triangles or more is built compact (checked with rtcGetSceneFlags); it
    answers every camera ray as the default layout does: the same triangle test on the same float32 vertices,
    so the same face, t, u, v, but for a tie between coplanar faces, which traversal order decides."""
    scene = rp.load_scene(SCENES / f"{name}.toml", ["render.width=160", "render.height=120"])
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    origins, directions = generate_rays(camera_rig(scene), frame, 160, 120, 1, 0, 120)
    lib = embree.library()
    flags_of = lib._lib.rtcGetSceneFlags
    flags_of.restype, flags_of.argtypes = ctypes.c_int, [ctypes.c_void_p]
    compact_flag = 1 << 1  # RTC_SCENE_FLAG_COMPACT in include/embree4/rtcore_scene.h
    default = Accelerator(geometry, frame)
    assert flags_of(default.embree_scene.scene) == embree.RTC_SCENE_FLAG_ROBUST
    monkeypatch.setattr(embree, "COMPACT_FACES", len(geometry.faces))
    compact = Accelerator(geometry, frame)
    assert flags_of(compact.embree_scene.scene) == embree.RTC_SCENE_FLAG_ROBUST | compact_flag
    assert_the_same_hits_but_ties(compact, default, geometry, origins, directions)


def assert_the_same_hits_but_ties(ours: Accelerator, theirs_bvh: Accelerator, geometry, origins, directions) -> None:
    """Two BVHs of one mesh answer every ray alike: the same triangle test on the same float32 vertices, so the
    same face, t, u, v, but for a tie between coplanar faces, which traversal order decides."""
    ours, theirs = ours.closest_hits(origins, directions), theirs_bvh.closest_hits(origins, directions)
    hit = theirs.face >= 0
    assert hit.any() and (~hit).any()
    np.testing.assert_array_equal(ours.face >= 0, hit)
    tie = ours.face != theirs.face
    normals = geometry.face_normals
    assert (np.abs(np.einsum("ij,ij->i", normals[ours.face[tie]], normals[theirs.face[tie]])) > 1 - 1e-12).all()
    np.testing.assert_allclose(ours.t[hit], theirs.t[hit], rtol=16 * EPS32)
    same = hit & ~tie
    np.testing.assert_allclose(ours.u[same], theirs.u[same], rtol=16 * EPS32, atol=16 * EPS32)
    np.testing.assert_allclose(ours.v[same], theirs.v[same], rtol=16 * EPS32, atol=16 * EPS32)


@pytest.mark.parametrize("name", ["shadows", "mesh", "creases"])
def test_a_large_mesh_is_built_by_the_morton_builder_with_the_same_hits(name, monkeypatch):
    """A mesh of embree.MORTON_FACES triangles or more is built by Embree's Morton builder on the compact layout
    (a third of the SAH build's CPU on a 1M-triangle scan); it answers every camera ray as the SAH build does.
    Below the limit (every scene file) the build is the SAH one on the default layout."""
    scene = rp.load_scene(SCENES / f"{name}.toml", ["render.width=160", "render.height=120"])
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    origins, directions = generate_rays(camera_rig(scene), frame, 160, 120, 1, 0, 120)
    flags_of = embree.library()._lib.rtcGetSceneFlags
    flags_of.restype, flags_of.argtypes = ctypes.c_int, [ctypes.c_void_p]
    sah = Accelerator(geometry, frame)
    assert sah.embree_scene.builder == "sah" and flags_of(sah.embree_scene.scene) == embree.RTC_SCENE_FLAG_ROBUST
    monkeypatch.setattr(embree, "MORTON_FACES", len(geometry.faces))
    morton = Accelerator(geometry, frame)
    assert morton.embree_scene.builder == "morton"
    assert flags_of(morton.embree_scene.scene) == embree.RTC_SCENE_FLAG_ROBUST | embree.RTC_SCENE_FLAG_COMPACT
    assert_the_same_hits_but_ties(morton, sah, geometry, origins, directions)


def test_a_refused_morton_build_falls_back_to_the_sah_build(monkeypatch):
    """A library that refuses the Morton config (another Embree 4 through RAYCAST_PHONG_EMBREE_LIBRARY) still
    builds: the SAH build, with no error left on its device."""
    scene = rp.load_scene(SCENES / "mesh.toml", ["render.width=160", "render.height=120"])
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    origins, directions = generate_rays(camera_rig(scene), frame, 160, 120, 1, 0, 120)
    monkeypatch.setattr(embree, "MORTON_FACES", 1)
    monkeypatch.setattr(embree, "MORTON_CONFIG", b"tri_builder=no_such_builder")
    refused = Accelerator(geometry, frame)
    assert refused.embree_scene.builder == "sah"
    monkeypatch.setattr(embree, "MORTON_FACES", len(geometry.faces) + 1)
    assert_the_same_hits_but_ties(refused, Accelerator(geometry, frame), geometry, origins, directions)
