"""render()'s bookkeeping: what it reports about itself must add up (no speed is asserted)."""

import time

import raycast_phong as rp


def test_timings_are_parts_of_the_wall_time():
    """Each stage's seconds lie in [0, wall time of the call]; rays, shadows and shade are summed over the
    worker threads, so each lies in [0, threads × wall time]."""
    scene = rp.validate_scene({
        "render": {"width": 64, "height": 48, "mode": "global"},
        "lights": [{"type": "point", "position": [2, 2, 3]}],
        "objects": [{"shape": "icosphere", "subdivisions": 2}],
    })
    threads = 2
    start = time.perf_counter()
    result = rp.render(scene, threads=threads)
    wall = time.perf_counter() - start
    timings = result.timings
    assert {"geometry", "build", "rays", "shadows", "shade", "frame"} <= set(timings)
    for name in ("geometry", "build", "frame"):
        assert 0 <= timings[name] <= wall, (name, timings[name], wall)
    for name in ("rays", "shadows", "shade"):
        assert 0 <= timings[name] <= threads * wall, (name, timings[name], wall)
    assert result.rays == 64 * 48
