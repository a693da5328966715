"""`batch --scheduler`: the same renders on a Dask cluster (a LocalCluster on loopback here)."""

from __future__ import annotations

import json

import pytest
from test_batch import SWEEP, five_scenes, scene_text  # noqa: F401  (five_scenes is a fixture)

from raycast_phong.errors import OptionError
from raycast_phong.tools import batch

distributed = pytest.importorskip("distributed", reason="pip install 'raycast-phong[distributed]'")


@pytest.fixture(scope="module")
def cluster():
    """One in-process worker with two threads on 127.0.0.1; closed after the module."""
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp",
                                  host="127.0.0.1",
                                  dashboard_address=None, timeout=30) as local:
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


def test_an_unreachable_scheduler_is_bad_input(five_scenes, tmp_path, monkeypatch):
    monkeypatch.setattr(batch.cluster, "CONNECT_TIMEOUT", "0.5s")  # port 9 (discard) never answers; don't wait 10 s
    with pytest.raises(OptionError, match=r"--scheduler tcp://127\.0\.0\.1:9: cannot connect"):
        batch.run_batch(batch.find_jobs([five_scenes]), tmp_path / "out", scheduler="tcp://127.0.0.1:9")
