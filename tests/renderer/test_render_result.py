"""A RenderResult is frozen through and through (issue 32 item 7): its timings cannot change after it is
returned; a caller that times more (load, write, compile) gets a new record."""

from __future__ import annotations

from pathlib import Path

import pytest

import raycast_phong as rp

DEFAULT = Path(__file__).resolve().parents[2] / "scenes" / "default.toml"


def test_timings_are_read_only_and_with_timings_gives_a_new_record():
    result = rp.render_file(DEFAULT, ["render.width=16", "render.height=12"])
    assert {"load", "frame", "geometry"} <= set(result.timings)
    with pytest.raises(TypeError):
        result.timings["write"] = 1.0  # type: ignore[index]
    more = result.with_timings(write=0.25, load=9.0)
    assert more.timings["write"] == 0.25 and more.timings["load"] == 9.0
    assert "write" not in result.timings and result.timings["load"] != 9.0  # the returned one is unchanged
    assert type(more) is type(result) and more.image is result.image and more.plan is result.plan
