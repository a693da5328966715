"""render()'s bookkeeping: what it reports about itself must add up (no speed is asserted)."""

import time

import numpy as np

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


def test_every_caller_prepares_through_the_one_sequencer(monkeypatch, tmp_path):
    """render, render_file, the plan command, warm_kernels and accuracy.mesh_coverage each run prepare() once:
    its memory check (the one home of that check) sees each call once, with the same arguments for the
    plan command and render. Then Prepared.render() twice gives the same image, bit for bit."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    from raycast_phong.renderer import fit
    from raycast_phong.renderer import prepare as module
    from raycast_phong.renderer.frame import warm_kernels
    from raycast_phong.tools.accuracy import mesh_coverage
    checks = []
    check_memory = fit.check_memory

    def counted(*args, **kwargs):
        checks.append(kwargs)
        return check_memory(*args, **kwargs)

    monkeypatch.setattr(fit, "check_memory", counted)  # prepare()'s check, made by fit.fitted
    path = tmp_path / "s.toml"
    path.write_text('[render]\nwidth = 32\nheight = 24\nmode = "global"\n[[lights]]\ntype = "point"\n'
                    'position = [2, 2, 3]\n[[objects]]\nshape = "icosphere"\n')
    scene = rp.load_scene(path)
    for call in (lambda: rp.render(scene, max_memory="1G"), lambda: rp.render_file(path, max_memory="1G"),
                 lambda: mesh_coverage(scene), lambda: warm_kernels((np.float32,)),
                 lambda: runner_plan(CliRunner(), app, path)):
        before = len(checks)
        call()
        assert len(checks) == before + 1, call
    assert checks[1] == checks[4]  # render_file and the plan command: the same estimate's arguments
    ready = module.prepare(scene)
    np.testing.assert_array_equal(ready.render().image, ready.render().image)


def runner_plan(runner, app, path):
    done = runner.invoke(app, ["plan", str(path), "--max-memory", "1G"])
    assert done.exit_code == 0, done.output
