"""`batch --scheduler`: the same renders on a Dask cluster (a LocalCluster on loopback here), and a batch given
relative paths on a scheduler and a worker started as processes of their own in another folder."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from test_batch import ROOT, SWEEP, TETRAHEDRON, five_scenes, images, manifest, scene_text  # noqa: F401

import raycast_phong as rp
from raycast_phong.errors import OptionError
from raycast_phong.tools import batch

distributed = pytest.importorskip("distributed", reason="pip install 'raycast-phong[distributed]'")


@pytest.fixture(scope="module")
def cluster():
    """One in-process worker with two threads on 127.0.0.1; closed after the module."""
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp",
                                  host="127.0.0.1",
                                  dashboard_address=":0", timeout=30) as local:
        yield local.scheduler_address


def test_a_dask_batch_writes_the_same_images_bit_for_bit(five_scenes, tmp_path, cluster):
    (five_scenes / "base.toml").write_text(scene_text())
    (five_scenes / "sweep.toml").write_text(SWEEP)
    jobs = batch.find_jobs([five_scenes])
    local = batch.run_batch(jobs, tmp_path / "local", workers=1)
    remote = batch.run_batch(jobs, tmp_path / "dask", scheduler=cluster)
    assert [o.status for o in remote.outcomes] == [o.status for o in local.outcomes]
    assert remote.count(batch.RENDERED) == 17 and [o.name for o in remote.failed] == ["broken"]
    assert remote.failed[0].reason == local.failed[0].reason
    names = sorted(p.name for p in (tmp_path / "local").glob("*.png"))
    assert len(names) == 4 + 1 + 12 + 1  # four scenes, the base scene, twelve cells, the contact sheet
    for name in names:
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name
    # The same up-to-date check: a second run on the cluster renders nothing.
    again = batch.run_batch(jobs, tmp_path / "dask", scheduler=cluster)
    assert again.count(batch.UP_TO_DATE) == 17 and again.count(batch.RENDERED) == 0
    entries = json.loads((tmp_path / "dask" / "manifest.json").read_text())["scenes"]
    assert entries["broken"]["status"] == "failed" and entries["sphere0"]["hash"].startswith("sha256:")


def test_a_scheduler_without_workers_is_bad_input_not_a_hang(five_scenes, tmp_path, monkeypatch):
    """Its tasks would wait for ever: the batch waits WORKER_WAIT seconds for a worker, then says so."""
    monkeypatch.setattr(batch.cluster, "WORKER_WAIT", 1.0)
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp", host="127.0.0.1",
                                  dashboard_address=":0") as empty:
        with pytest.raises(OptionError, match=r"the scheduler has no worker \(waited 1 s\); start one there"):
            batch.run_batch(batch.find_jobs([five_scenes]), tmp_path / "out", scheduler=empty.scheduler_address)


def test_a_scheduler_that_dies_before_a_worker_joins_is_one_line_and_dask_says_nothing(five_scenes, tmp_path,
                                                                                       monkeypatch):
    """Dask's client logs an error (mid-batch, a 30-line traceback) on stderr when its scheduler goes away; the
    batch keeps its loggers quiet and says one line of its own. (Heard by a handler on Dask's client logger:
    Dask's own handler writes to the stderr it found at import, which pytest's capture does not see.)"""
    import logging
    heard: list[logging.LogRecord] = []
    listener = logging.Handler()
    listener.emit = heard.append
    logging.getLogger("distributed.client").addHandler(listener)
    monkeypatch.setattr(batch.cluster, "WORKER_WAIT", 60.0)
    monkeypatch.setattr(batch.cluster, "CONNECT_TIMEOUT", "2s")
    port = free_port()
    scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                  "--port", str(port), "--no-dashboard"], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:  # until it listens
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                time.sleep(0.2)
        killer = threading.Timer(2.0, scheduler.kill)
        killer.start()
        with pytest.raises(OptionError, match="the scheduler stopped answering after"):
            batch.run_batch(batch.find_jobs([five_scenes]), tmp_path / "out", scheduler=f"tcp://127.0.0.1:{port}")
    finally:
        scheduler.kill()
        scheduler.wait()
        logging.getLogger("distributed.client").removeHandler(listener)
    assert [record.getMessage() for record in heard if record.levelno >= logging.WARNING] == []


def test_an_unreachable_scheduler_is_bad_input(five_scenes, tmp_path, monkeypatch):
    monkeypatch.setattr(batch.cluster, "CONNECT_TIMEOUT", "0.5s")  # port 9 (discard) never answers; don't wait 10 s
    with pytest.raises(OptionError, match=r"--scheduler tcp://127\.0\.0\.1:9: cannot connect"):
        batch.run_batch(batch.find_jobs([five_scenes]), tmp_path / "out", scheduler="tcp://127.0.0.1:9")


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now (the scheduler takes it a moment later)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def stop_group(process: subprocess.Popen) -> None:
    """End a process started with start_new_session=True and every process it started (a worker's nanny
    starts the worker): SIGTERM to its group, SIGKILL after 10 s."""
    for number, wait in ((signal.SIGTERM, 10), (signal.SIGKILL, 10)):
        try:
            os.killpg(process.pid, number)
        except ProcessLookupError:
            return
        try:
            process.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def wait_for_scheduler(address: str, port: int, processes: list[subprocess.Popen], logs: Path) -> None:
    """Until the scheduler accepts connections and has one worker, at most 60 s each."""
    deadline = time.monotonic() + 60
    while True:
        assert all(p.poll() is None for p in processes), tails(logs)
        assert time.monotonic() < deadline, "the scheduler did not answer in 60 s\n" + tails(logs)
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            break
        except OSError:
            time.sleep(0.2)
    with distributed.Client(address, timeout="30s") as client:
        client.wait_for_workers(1, timeout=60)


def tails(logs: Path) -> str:
    return "\n".join(f"{path.name}: {path.read_text()[-2000:]}" for path in sorted(logs.glob("*.log")))


@pytest.mark.slow
def test_a_cluster_started_elsewhere_renders_a_batch_given_relative_paths(tmp_path):
    """`dask scheduler` and `dask worker` started as a user would, in a folder of their own, and a batch run
    from a third folder with relative scene and output paths, whose scenes name a mesh (with its .mtl and
    map_Kd image) and a colour map by relative paths: every path the workers use must be absolute, resolved
    where the batch runs (the scene's own folder for the scene's paths), not in the worker's folder."""
    cluster, user = tmp_path / "cluster", tmp_path / "user"
    scenes = user / "in"
    (scenes / "meshes").mkdir(parents=True)
    (scenes / "textures").mkdir()
    cluster.mkdir()
    rp.write_image(scenes / "textures" / "wood.png", np.full((4, 4, 3), 0.25, np.float32))
    rp.write_image(scenes / "meshes" / "paint.png", np.full((4, 4, 3), 0.75, np.float32))
    (scenes / "meshes" / "box.mtl").write_text("newmtl p\nKd 1 1 1\nmap_Kd paint.png\n")
    (scenes / "meshes" / "box.obj").write_text(
        "mtllib box.mtl\nusemtl p\n" + TETRAHEDRON.replace("f 1 2 3", "vt 0 0\nf 1 2 3"))
    (scenes / "mesh.toml").write_text(scene_text(shape="mesh", extra='path = "meshes/box.obj"').replace(
        'material = "red"\n', ""))
    (scenes / "mapped.toml").write_text(scene_text().replace(
        "shininess = 32\n", 'shininess = 32\nkd_map = "textures/wood.png"\n'))
    (scenes / "sphere.toml").write_text(scene_text())
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    commands = {"scheduler": ["scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
                "worker": ["worker", address, "--host", "127.0.0.1", "--nworkers", "1", "--nthreads", "1",
                           "--no-dashboard", "--death-timeout", "60", "--local-directory", str(cluster)]}
    processes: list[subprocess.Popen] = []
    try:
        for name, arguments in commands.items():
            with open(cluster / f"{name}.log", "wb") as log:
                processes.append(subprocess.Popen([sys.executable, "-m", "dask", *arguments], cwd=cluster, env=env,
                                                  stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                                  start_new_session=True))
        wait_for_scheduler(address, port, processes, cluster)
        result = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "batch", "in", "--out", "renders",
                                 "--scheduler", address], cwd=user, env=env, stdin=subprocess.DEVNULL,
                                capture_output=True, text=True, timeout=600)
    finally:
        for process in reversed(processes):
            stop_group(process)
    assert result.returncode == 0, result.stderr + tails(cluster)
    assert "3 scenes: 3 rendered, 0 up to date, 0 failed" in result.stdout, result.stdout
    assert {name: entry["status"] for name, entry in manifest(user / "renders").items()} == \
        {"mapped": "rendered", "mesh": "rendered", "sphere": "rendered"}
    assert [path.name for path in images(user / "renders")] == ["mapped.png", "mesh.png", "sphere.png"]
    assert not (cluster / "renders").exists()
    # The same images as a local batch (so the cluster read the same texture and mesh files), and the colour
    # map darkened the sphere it is on.
    local = batch.run_batch(batch.find_jobs([scenes]), tmp_path / "local", workers=1)
    assert local.count(batch.RENDERED) == 3
    for path in images(user / "renders"):
        assert path.read_bytes() == (tmp_path / "local" / path.name).read_bytes(), path.name
    mapped, plain = (rp.read_image(user / "renders" / name)[0] for name in ("mapped.png", "sphere.png"))
    assert mapped.max() < plain.max()


def slow_render_job(task):
    """render_job a second later: a batch long enough to lose a worker in (run by in-process workers)."""
    time.sleep(1.0)
    return batch.jobs.render_job(task)


@pytest.mark.parametrize("left", [1, 0])
def test_a_worker_lost_mid_batch_is_said_and_none_left_fails_the_rest_not_a_hang(five_scenes, tmp_path,
                                                                                  monkeypatch, left):
    """Two workers, one scene a second each; 1.5 s in, the cluster shrinks to `left` workers. One left: every
    scene renders (Dask runs the lost worker's again) and the report says which worker left. None left: the
    scenes not rendered fail after WORKER_WAIT, each with one line, instead of the batch waiting for ever."""
    monkeypatch.setattr(batch.cluster, "render_job", slow_render_job)
    monkeypatch.setattr(batch.cluster, "WORKER_WAIT", 1.0)
    monkeypatch.setattr(batch.cluster, "WATCH_SECONDS", 0.2)
    jobs = [job for job in batch.find_jobs([five_scenes]) if job.name != "broken"]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                                  host="127.0.0.1", dashboard_address=":0") as local:
        shrink = threading.Timer(1.5, local.scale, (left,))
        shrink.start()
        started, reports = time.monotonic(), []
        running = threading.Thread(target=lambda: reports.append(
            batch.run_batch(jobs, tmp_path / "out", scheduler=local.scheduler_address)), daemon=True)
        running.start()
        running.join(60)  # a batch that waits for ever fails here, not by hanging the suite
        shrink.cancel()
        assert not running.is_alive(), "the batch still waits 60 s after its workers left"
        (report,) = reports
    took = time.monotonic() - started
    lost = [w for w in report.warnings if "left the cluster" in w]
    assert len(lost) == 2 - left and all(w.startswith(f"--scheduler {local.scheduler_address}: worker tcp://")
                                         for w in lost), (report.warnings, took)
    if left:
        assert report.count(batch.RENDERED) == 4, [(o.name, o.status, o.reason) for o in report.outcomes]
    else:
        failed = [o for o in report.outcomes if o.status == batch.FAILED]
        assert failed and all("no worker left on the scheduler for 1 s" in o.reason for o in failed), failed
        assert report.count(batch.RENDERED) + len(failed) == 4 and took < 30, took
