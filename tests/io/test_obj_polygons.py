"""An OBJ's concave polygons are found by one compiled scan (io/meshes/obj_polygons.py) and cut as the
regular-expression reading did (obj_polygons_reference.py, the oracle); CRLF files as LF ones; numbers read within
a few units in the last place; and a polygon with a bad corner or vertex is left to the reader."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from obj_polygons_reference import triangulate_concave as reference

from raycast_phong.io.meshes.obj_polygons import _number, triangulate_concave


def random_obj(seed: int) -> bytes:
    """Vertices (some with a w, tabs, leading blanks) and faces of 3 to 7 corners, convex and concave (star-shaped
    polygons with every other corner pulled in), with v/vt/vn tokens, negative indices, comments and other
    records between them."""
    rng = np.random.default_rng(seed)
    lines, vertices = ["# made by a test", "mtllib none.mtl", "o thing"], 0
    for _ in range(60):
        corners = int(rng.integers(3, 8))
        angle = np.sort(rng.uniform(0, 2 * np.pi, corners))
        radius = np.where(np.arange(corners) % 2 & (rng.random() < 0.5), 0.3, 1.0)  # half the polygons bent
        centre, tilt = rng.normal(size=3) * 5, rng.normal(size=3) * 0.2
        for a, r in zip(angle, radius, strict=True):
            x, y = r * math.cos(a), r * math.sin(a)
            point = centre + np.array([x, y, tilt[0] * x + tilt[1] * y])
            lead = rng.choice(["", " ", "\t"])
            gap = rng.choice([" ", "  ", "\t"])
            w = " 1.0" if rng.random() < 0.1 else ""
            lines.append(f"{lead}v{gap}{point[0]:.6f}{gap}{point[1]:.6g} {point[2]:.7e}{w}")
            lines.append(f"vt {rng.random():.4f} {rng.random():.4f}")
        vertices += corners
        numbers = list(range(vertices - corners + 1, vertices + 1))
        if rng.random() < 0.3:
            numbers = [n - vertices - 1 for n in numbers]  # negative: back from the last vertex
        style = rng.integers(0, 4)
        tokens = [str(n) if style == 0 else f"{n}/{n}" if style == 1 else f"{n}//{n}" if style == 2 else f"{n}/{n}/{n}"
                  for n in numbers]
        comment = " # a face" if rng.random() < 0.2 else ""
        lines.append(rng.choice(["", " "]) + "f " + rng.choice([" ", "\t"]).join(tokens) + comment)
        if rng.random() < 0.2:
            lines.append("s off")
    return ("\n".join(lines) + "\n").encode()


@pytest.mark.parametrize("seed", range(8))
def test_concave_polygons_are_cut_as_the_regular_expressions_cut_them(seed):
    data = random_obj(seed)
    found, cut = triangulate_concave(data)
    expected, expected_cut = reference(data)
    assert cut == expected_cut > 0 and found == expected


@pytest.mark.parametrize("seed", range(4))
def test_a_crlf_file_is_cut_as_its_lf_twin(seed):
    """The regular expressions saw no polygon in a CRLF file (their $ stops at LF, after the CR): its concave
    polygons were fanned over their holes. A CRLF line keeps its CR; the triangles' own lines end in LF."""
    data = random_obj(seed)
    found, cut = triangulate_concave(data.replace(b"\n", b"\r\n"))
    assert reference(data.replace(b"\n", b"\r\n"))[1] == 0  # the control: the old reading found none
    assert (found.replace(b"\r\n", b"\n"), cut) == triangulate_concave(data) and cut > 0
    assert found.count(b"\r\n") == data.count(b"\n")


def test_a_polygon_with_a_bad_corner_or_vertex_is_left_to_the_reader():
    """A concave polygon is cut; the same one with a corner that is no integer, names no vertex or reaches a
    vertex whose coordinate is no number is left as it is (the reader reports it), and its neighbours still cut."""
    ring = b"v 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 0.5 0\nv 0 2 0\n"
    good = b"f 1 2 3 4 5\n"
    assert triangulate_concave(ring + good)[1] == 1
    for bad in (b"f 1 2 3 4.5 5\n", b"f 1 2 3 4 9\n", b"f 1 2 3 x 5\n", b"f 0 2 3 4 5\n", b"f 1 2 3 4 -6\n"):
        assert triangulate_concave(ring + bad) == (ring + bad, 0), bad
        assert triangulate_concave(ring + bad + good)[1] == 1, bad
    broken = ring.replace(b"v 1 0.5 0", b"v 1 0.5x 0")
    assert triangulate_concave(broken + good) == (broken + good, 0)
    assert triangulate_concave(b"f 1 2 3 4\n") == (b"f 1 2 3 4\n", 0)  # no vertices: the reader says so


def test_numbers_are_read_within_a_few_units_in_the_last_place():
    """_number against Python's correctly rounded float() on decimals of every shape from 1e-300 to 1e300, and NaN
    for what is not one.
    Its error: the 18-digit mantissa rounded once (1/2 unit), times or over a power of ten (exact up to 10^22,
    else 1/2 unit from pow), rounded again: under 2 units; asserted at 4."""
    rng = np.random.default_rng(7)
    words = ["0", "-0", "+1", "1.", ".5", "-.25", "1e3", "1E-3", "123456789012345678901234", "0.000000000000001234",
             "6.02214076e23", "1.5e300", "-2.5e-300", "2.2250738585072014e-290", "007.500", "1e+0"]
    words += [f"{x:.{d}e}" for x, d in zip(rng.normal(size=300) * 10.0 ** rng.integers(-30, 30, 300),
                                            rng.integers(0, 17, 300), strict=True)]
    words += [f"{x:.{d}f}" for x, d in zip(rng.normal(size=300) * 1000, rng.integers(0, 12, 300), strict=True)]
    for word in words:
        data = np.frombuffer(word.encode(), np.uint8)
        found, exact = _number(data, 0, len(data)), float(word)
        assert found == exact or abs(found - exact) <= 4 * math.ulp(exact), (word, found, exact)
    for word in ["", "-", ".", "e5", "1e", "1e+", "1.2.3", "1x", "nan", "inf", "--1", "1 "]:
        data = np.frombuffer(word.encode(), np.uint8)
        assert math.isnan(_number(data, 0, len(data))), word


def test_records_that_prove_not_to_be_vertices_or_polygons_write_inside_the_scan_s_arrays(tmp_path):
    """The scan's second pass writes a line's words before it knows the line is a polygon (or a vertex): an
    "f" line of three corners, or a "v" line of two numbers, after the last real one must not write past the
    arrays the first pass sized. Run with numba's bounds checks on (an index past the end raises)."""
    code = ("import sys\nfrom raycast_phong.io.meshes.obj_polygons import _scan\nimport numpy as np\n"
            "data = b'v 0 0 0\\nv 2 0 0\\nv 2 2 0\\nv 1 0.5 0\\nv 0 2 0\\nf 1 2 3 4 5\\n"
            "f 1 2 3\\nf 1 2 3 4 x\\rq\\nv 1 2\\nv 1\\n'\n"
            "points, line, first, count, before, whole, word, index = _scan(np.frombuffer(data, np.uint8))\n"
            "print(len(points), len(line), len(word), index.tolist())\n")
    env = {**os.environ, "NUMBA_BOUNDSCHECK": "1", "NUMBA_CACHE_DIR": str(tmp_path)}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split("\n")[0] == "5 1 5 [1, 2, 3, 4, 5]"
