"""A large mesh's preparation on several threads (normals.parts / run_parts, issue 22) gives the bits of one
thread: the face slices and vertex ranges the passes split into change no sum's order. Below PARALLEL_FACES no
thread is started, and the render's `threads` bounds the preparation's."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong import shapes
from raycast_phong.geometry import mesh_repair, normals
from raycast_phong.geometry.mesh_repair import merge_duplicate_vertices, repair_winding, winding_state
from raycast_phong.geometry.normals import PARALLEL_FACES, compute_corner_normals, face_normals, parts, prep_threads


def noisy_sphere(subdivisions: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """An icosphere with its points moved at random (no two faces share a normal), stored as an STL stores it
    (every corner its own point: the merge and the renumbering run), a few faces flipped and one face twice,
    wound both ways (inconsistent: the orientation runs)."""
    vertices, faces = shapes.icosphere(subdivisions)
    rng = np.random.default_rng(seed)
    vertices = vertices * (1 + 0.05 * rng.standard_normal((len(vertices), 1)))
    faces = np.asarray(faces, np.int64).copy()
    faces[::97] = faces[::97, ::-1]
    faces = np.concatenate([faces, faces[:1, ::-1]])
    return vertices[faces].reshape(-1, 3), np.arange(3 * len(faces)).reshape(-1, 3)


def prepared(points: np.ndarray, corners: np.ndarray, threads: int, rules) -> list[np.ndarray]:
    """Every array the preparation makes, on `threads` threads: merged points and faces, the winding state and its
    buckets, repaired faces, face normals and the corner normals of each (weighting, crease, dtype) rule."""
    with prep_threads(threads):
        vertices, faces = merge_duplicate_vertices(points, corners)
        key, edge = np.empty(3 * len(faces), np.int32), np.empty(3 * len(faces), np.int32)
        consistent, closed, flippable, start = winding_state(faces, len(vertices), key, edge)
        repaired, flipped, _ = repair_winding(vertices, faces)
        unit, area = face_normals(vertices, repaired)
        found = [vertices, faces, np.array([consistent, closed, flippable, flipped]), start, key, edge, repaired, unit,
                 area]
        for weighting, crease, dtype in rules:
            found.append(compute_corner_normals(vertices, repaired, weighting, crease, dtype, normals=(unit, area)))
    return found


def same_bits(found: list[np.ndarray], expected: list[np.ndarray]) -> bool:
    return all(a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))
               for a, b in zip(found, expected, strict=True))


def split_runs(monkeypatch) -> list[tuple[int, int]]:
    """Record each run_parts call's (ranges, distinct threads that ran them)."""
    used, original = [], normals.run_parts

    def counting(step, ranges):
        threads: set[int] = set()
        result = original(lambda low, high: threads.add(threading.get_ident()) or step(low, high), ranges)
        used.append((len(ranges), len(threads)))
        return result
    monkeypatch.setattr(normals, "run_parts", counting)
    monkeypatch.setattr(mesh_repair, "run_parts", counting)
    return used


def test_above_the_threshold_two_threads_give_the_bits_of_one():
    """A noisy icosphere of 327,680 faces (983,043 points before the merge), mean normals with the file default
    crease of 30° and area normals uncreased, in float32 as a render asks."""
    points, corners = noisy_sphere(7)
    assert len(corners) >= PARALLEL_FACES
    rules = [("mean", 30.0, np.float32), ("area", 180.0, np.float32)]
    assert same_bits(prepared(points, corners, 2, rules), prepared(points, corners, 1, rules))


@pytest.mark.parametrize("threads", [2, 3])
def test_with_no_threshold_every_pass_splits_and_gives_the_bits_of_one_thread(monkeypatch, threads):
    """PARALLEL_FACES = 0 sends a small mesh through every split pass, in 2 and 3 (uneven) parts, every weighting
    with and without a crease, both dtypes; the passes did run on that many threads."""
    points, corners = noisy_sphere(3)
    rules = [(w, c, d) for w in ("mean", "area", "angle") for c in (180.0, 25.0) for d in (np.float32, np.float64)]
    expected = prepared(points, corners, 1, rules)
    monkeypatch.setattr(normals, "PARALLEL_FACES", 0)
    used = split_runs(monkeypatch)
    assert same_bits(prepared(points, corners, threads, rules), expected)
    assert used and {ranges for ranges, _ in used} == {threads} and all(ran > 1 for _, ran in used)


def test_below_the_threshold_no_thread_is_started(monkeypatch):
    used = split_runs(monkeypatch)
    points, corners = noisy_sphere(3)
    prepared(points, corners, 2, [("mean", 25.0, np.float32)])
    assert used and set(used) == {(1, 1)}
    assert parts(10_000, PARALLEL_FACES - 1) == [(0, 10_000)]
    with prep_threads(2):
        assert parts(10_000, PARALLEL_FACES) == [(0, 5_000), (5_000, 10_000)]
        assert parts(4, PARALLEL_FACES, lambda: np.array([0, 9, 9, 9, 10])) == [(0, 1), (1, 4)]  # equal work
    with prep_threads(1):
        assert parts(10_000, PARALLEL_FACES) == [(0, 10_000)]


@pytest.mark.parametrize("threads", [1, 2])
def test_the_render_threads_bound_the_preparation(monkeypatch, threads):
    """render(threads=N) prepares on N threads (a batch worker's one thread stays one), with the same image."""
    monkeypatch.setattr(normals, "PARALLEL_FACES", 0)
    used = split_runs(monkeypatch)
    scene = rp.validate_scene({"render": {"width": 16, "height": 16},
                               "objects": [{"shape": "icosphere", "subdivisions": 2, "crease_angle": 30}]},
                              source="t")
    rp.render(scene, threads=threads)
    assert used and {ranges for ranges, _ in used} == {threads}
