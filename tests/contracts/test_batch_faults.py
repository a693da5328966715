"""`raycast-phong batch` under faults: real signals, a killed parent, a killed worker, two batches in one folder,
scene files that break the loader, the output folder inside an input folder, paths spelled differently, a
corrupt manifest (docs/batch.md, "Faults").

The signal tests run the command in a subprocess of its own session (a background job of a shell ignores
SIGINT; a new session does not) and find its processes by scanning /proc for that session. Waits are bounded
polls; nothing asserts a duration.
"""

from __future__ import annotations

import fcntl
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))  # test_batch.py's helpers, beside it
from test_batch import ROOT, TETRAHEDRON, five_scenes, images, manifest, run, scene_text, statuses  # noqa: F401

import raycast_phong as rp
from raycast_phong.tools import batch
from raycast_phong.values.messages import shorten

LINUX_PROC = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="finds processes through /proc")
SIZE = 192  # 192×192 with 3×3 samples: ~0.1-0.3 s a scene, so a signal lands mid-batch


def slow_scenes(folder: Path, count: int) -> Path:
    folder.mkdir()
    for index in range(count):
        (folder / f"s{index:02d}.toml").write_text(scene_text(extra="subdivisions = 3", size=SIZE, samples=3))
    return folder


@pytest.fixture
def start_batch():
    """Start the command in a new session (its id is the process id), so its signals and processes are its
    own; whatever of the session is left at the end (a test that failed) is killed."""
    started = []

    def start(folder: Path, out: Path, jobs: int) -> subprocess.Popen:
        command = [sys.executable, "-m", "raycast_phong.cli", "batch", str(folder), "--out", str(out), "--jobs",
                   str(jobs)]
        started.append(subprocess.Popen(command, cwd=ROOT, start_new_session=True, stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, text=True))
        return started[-1]

    yield start
    for process in started:
        for pid in session_processes(process.pid):
            os.kill(pid, signal.SIGKILL)
        process.kill()
        process.communicate()


def wait_for_first_image(process: subprocess.Popen, out: Path) -> int:
    """Poll (at most a minute) until the batch has written an image; the number of images then."""
    deadline = time.monotonic() + 60
    while not images(out) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert process.poll() is None, process.communicate()
    return len(images(out))


def _processes() -> list[tuple[int, str, int, int]]:
    """(pid, state, parent pid, session id) of every process, from /proc/PID/stat."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue  # it has just exited
            state, ppid, _group, sid = stat[stat.rindex(")") + 2:].split()[:4]
            found.append((int(entry.name), state, int(ppid), int(sid)))
    return found


def session_processes(session: int) -> list[int]:
    """The live (not zombie) processes of a session."""
    return [pid for pid, state, _, sid in _processes() if sid == session and state != "Z"]


def children(pid: int) -> list[int]:
    return [child for child, _, parent, _ in _processes() if parent == pid]


def wait_until_gone(session: int, seconds: float = 10) -> list[int]:
    """Poll until no process of the session is left, or `seconds` pass; those left."""
    deadline = time.monotonic() + seconds
    while (left := session_processes(session)) and time.monotonic() < deadline:
        time.sleep(0.05)
    return left


def hidden(folder: Path) -> list[str]:
    """Temporary files left in the folder (the lock file is meant to stay)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") and p.name != batch.LOCK)


# ---------------------------------------------------------------- signals


@LINUX_PROC
@pytest.mark.parametrize(("number", "jobs"), [(signal.SIGINT, 2), (signal.SIGTERM, 2), (signal.SIGINT, 1),
                                             (signal.SIGHUP, 2), (signal.SIGQUIT, 2)],
                         ids=["SIGINT", "SIGTERM", "SIGINT-jobs-1", "SIGHUP-to-the-group", "SIGQUIT"])
@pytest.mark.slow
def test_a_signal_stops_the_workers_at_once_and_the_manifest_tells_the_truth(tmp_path, start_batch, number, jobs):
    count = 16
    folder, out = slow_scenes(tmp_path / "scenes", count), tmp_path / "out"
    process = start_batch(folder, out, jobs=jobs)
    wait_for_first_image(process, out)
    # Freeze the whole batch (its session is its process group) while counting, so a stall of this test
    # process on a loaded machine cannot let scenes finish between the count and the signal.
    os.killpg(process.pid, signal.SIGSTOP)
    written = len(images(out))
    # A closed terminal sends SIGHUP to the whole process group, the workers included (issue 21, item 7).
    (os.killpg if number == signal.SIGHUP else os.kill)(process.pid, number)
    os.killpg(process.pid, signal.SIGCONT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + number, stderr
    assert wait_until_gone(process.pid) == []
    assert stderr.strip().splitlines()[-1].startswith(f"interrupted by {signal.Signals(number).name}: ")
    assert "Traceback" not in stderr
    # At most the scenes rendering at the signal finish; no scene starts after it.
    on_disk = images(out)
    assert len(on_disk) <= written + jobs, f"{len(on_disk) - written} images written after the signal"
    assert hidden(out) == []
    # Every image on disk is whole and listed as rendered; every scene has an entry saying what happened.
    entries = manifest(out)
    assert sorted(entries) == [f"s{index:02d}" for index in range(count)]
    listed = sorted(name for entry in entries.values() if entry["status"] == "rendered" for name in entry["outputs"])
    assert listed == [path.name for path in on_disk]
    for path in on_disk:
        assert rp.read_image(path)[0].shape == (SIZE, SIZE, 3)
    kinds = {entry["status"] for entry in entries.values()}
    assert kinds <= {"rendered", "interrupted", "not started"} and "not started" in kinds, kinds
    # A rerun renders exactly the rest.
    result = run(str(folder), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 0, result.stderr
    assert list(statuses(out).values()).count("up to date") == len(on_disk)
    assert len(images(out)) == count


def large_scenes_in_flight(tmp_path: Path, start_batch) -> tuple[subprocess.Popen, Path]:
    """A batch of two workers, once its first (small) scene's image is written: each worker is then on a scene of
    ~36 M rays (seconds on one thread), with one more waiting. The batch process and its output folder."""
    folder, out = tmp_path / "scenes", tmp_path / "out"
    folder.mkdir()
    (folder / "a.toml").write_text(scene_text())
    for index in range(3):
        (folder / f"b{index}.toml").write_text(scene_text(extra="subdivisions = 3", size=2000, samples=3))
    process = start_batch(folder, out, jobs=2)
    wait_for_first_image(process, out)
    return process, out


@LINUX_PROC
def test_killing_the_batch_with_sigkill_leaves_no_worker_behind(tmp_path, start_batch):
    """Each worker is mid-way through a scene of ~36 M rays (seconds on one thread) when the batch is killed:
    they must die with it, not finish their scenes (nor wait for work) first."""
    process, out = large_scenes_in_flight(tmp_path, start_batch)
    assert len(session_processes(process.pid)) == 3  # the command and its two workers
    os.kill(process.pid, signal.SIGKILL)
    process.wait(timeout=60)  # not communicate(): a worker left behind would hold its pipes open
    assert wait_until_gone(process.pid) == []
    assert images(out) == [out / "a.png"]


@LINUX_PROC
@pytest.mark.parametrize("number", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_the_scenes_being_rendered_not_after_them(tmp_path, start_batch, number):
    """Both workers are mid-way through a scene of ~36 M rays (seconds on one thread) when the batch is told to
    stop: it ends within seconds with neither of those images, their scenes said to be interrupted, and the rest
    not started. Catches a stop that waits for the scenes in flight to finish (the signal recorded but not acted
    on until the next scene), which the test above allows for its small scenes."""
    process, out = large_scenes_in_flight(tmp_path, start_batch)
    os.kill(process.pid, number)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 128 + number, stderr
    assert images(out) == [out / "a.png"], stderr
    statuses = {name: entry["status"] for name, entry in manifest(out).items()}
    assert statuses["a"] == "rendered" and sorted(statuses.values()).count("interrupted") >= 1, statuses
    assert set(statuses.values()) <= {"rendered", "interrupted", "not started"}, statuses


@LINUX_PROC
@pytest.mark.slow
def test_a_killed_worker_fails_only_its_scene_and_is_replaced(tmp_path, start_batch):
    """The out-of-memory killer, simulated: SIGKILL to one worker mid-batch."""
    count = 10
    folder, out = slow_scenes(tmp_path / "scenes", count), tmp_path / "out"
    process = start_batch(folder, out, jobs=2)
    wait_for_first_image(process, out)
    workers = children(process.pid)
    assert len(workers) == 2, workers
    os.kill(workers[0], signal.SIGKILL)
    _, stderr = process.communicate(timeout=120)
    failed = {name: entry["reason"] for name, entry in manifest(out).items() if entry["status"] == "failed"}
    # Its scene failed, unless the kill landed between the image's rename and the worker's report: then the
    # image is whole and listed as rendered.
    assert len(failed) <= 1, stderr
    for name, reason in failed.items():
        assert reason == f"{folder / name}.toml: its worker process died (killed by SIGKILL; out of memory?)"
        assert f"failed: {reason}" in stderr
    assert process.returncode == (1 if failed else 0), stderr
    assert list(statuses(out).values()).count("rendered") == count - len(failed) == len(images(out))
    assert hidden(out) == []


# ---------------------------------------------------------------- two batches, one folder


@pytest.mark.slow
def test_a_second_batch_into_the_same_folder_is_refused(tmp_path, start_batch):
    count = 8
    folder, out = slow_scenes(tmp_path / "scenes", count), tmp_path / "out"
    first = start_batch(folder, out, jobs=1)
    wait_for_first_image(first, out)
    # Stopped while it holds the folder: under load it could otherwise finish its last scenes before the
    # second batch starts, and the second would then rightly go ahead (the test was flaky so).
    os.killpg(first.pid, signal.SIGSTOP)
    try:
        second = run(str(folder), "--out", str(out), "--jobs", "1", "--force")
    finally:
        os.killpg(first.pid, signal.SIGCONT)
    assert second.exit_code == 2
    assert second.stderr == (f"error: {out}: another batch (process {first.pid}) is writing into this folder; "
                             "wait for it to finish, or use another -o/--output\n")
    _, stderr = first.communicate(timeout=120)
    assert first.returncode == 0, stderr  # its temporaries and manifest were left alone
    assert set(statuses(out).values()) == {"rendered"} and len(images(out)) == count
    assert hidden(out) == []
    # The lock is the batch's for its run only: the next batch goes ahead.
    assert run(str(folder), "--out", str(out), "--jobs", "1").exit_code == 0


def test_the_folder_lock_is_an_flock(tmp_path, five_scenes):
    """Whoever holds DIR/.batch.lock (here this test) keeps a batch out; nothing is written meanwhile."""
    out = tmp_path / "out"
    out.mkdir()
    with open(out / batch.LOCK, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 2 and "another batch is writing into this folder" in result.stderr
    assert sorted(p.name for p in out.iterdir()) == [batch.LOCK]


@pytest.mark.parametrize("dangling", [False, True], ids=["to-a-file", "dangling"])
def test_a_link_planted_as_the_lock_is_refused_and_never_written_through(tmp_path, five_scenes, dangling):
    """`ln -s ~/precious out/.batch.lock` in a shared folder: the batch refuses the folder (exit 2, one line
    naming the lock) and neither writes the link's target nor creates it."""
    out, precious = tmp_path / "out", tmp_path / "precious"
    out.mkdir()
    if not dangling:
        precious.write_bytes(b"keep me\n")
    (out / batch.LOCK).symlink_to(precious)
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 2, result.stderr
    assert result.stderr == (f"error: {out / batch.LOCK}: the batch lock is a symbolic link, which the batch does "
                             "not write through; remove it, or use another -o/--output\n")
    assert (precious.read_bytes() == b"keep me\n") if not dangling else not precious.exists()
    assert sorted(p.name for p in out.iterdir()) == [batch.LOCK] and (out / batch.LOCK).is_symlink()


@pytest.mark.parametrize("kind", ["fifo", "hard link"])
def test_a_lock_that_is_a_fifo_or_a_second_name_is_refused(tmp_path, five_scenes, kind):
    out, precious = tmp_path / "out", tmp_path / "precious"
    out.mkdir()
    precious.write_bytes(b"keep me\n")
    if kind == "fifo":
        os.mkfifo(out / batch.LOCK)  # an O_RDWR open of a FIFO does not block; writing into it would
        says = "the batch lock is not a regular file"
    else:
        os.link(precious, out / batch.LOCK)
        says = "the batch lock is a file of 2 names"
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 2 and says in result.stderr and result.stderr.count("\n") == 1, result.stderr
    assert precious.read_bytes() == b"keep me\n"


def test_links_planted_at_the_batch_outputs_are_replaced_not_written_through(tmp_path, five_scenes):
    """Links at the images, the manifest and a sweep's contact sheet (every other path a batch writes) are
    replaced by the batch's own files, as a rename does; the files they aimed at keep their bytes."""
    out = tmp_path / "out"
    out.mkdir()
    aimed = {}
    for name in ("sphere0.png", "mesh.png", "manifest.json"):
        aimed[name] = tmp_path / f"precious-{name}"
        aimed[name].write_bytes(b"keep me\n")
        (out / name).symlink_to(aimed[name])
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 1 and statuses(out)["sphere0"] == "rendered", result.stderr  # broken.toml fails
    for name, target in aimed.items():
        assert target.read_bytes() == b"keep me\n", name
        assert not (out / name).is_symlink() and (out / name).stat().st_size > 8, name


# ---------------------------------------------------------------- scene files that break the loader


def test_each_broken_scene_file_fails_only_itself(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "good.toml").write_text(scene_text())
    broken = {
        "deep_json.json": "[" * 100_000 + "]" * 100_000,      # RecursionError in json
        "deep_toml.toml": "a = " + "[" * 100_000 + "]" * 100_000 + "\n",  # and in tomllib
        "digits.json": '{"render": {"width": 1' + "0" * 5000 + "}}",  # int() refuses over 4300 digits
        "binary.toml": bytes(range(256)) * 4,
    }
    for name, text in broken.items():
        (folder / name).write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "out"
    result = run(str(folder), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 1, result.stderr
    assert "Traceback" not in result.stderr
    entries = manifest(out)
    assert entries["good"]["status"] == "rendered"
    for name in broken:
        entry = entries[Path(name).stem]
        assert entry["status"] == "failed"
        assert entry["reason"].startswith(str(folder / name) + ": ") and "\n" not in entry["reason"]
        # A bug is told apart from bad input: "internal error", and its traceback kept in the manifest.
        assert (entry["traceback"] is not None) == ("internal error" in entry["reason"]), entry
        assert f"failed: {entry['reason']}" in result.stderr


def test_a_scene_whose_file_name_is_not_utf8_is_left_out_and_the_others_render(tmp_path):
    """Its name reaches the image's, the manifest and every message: it was an internal error that stopped the
    whole batch. Now one warning, and the rest of the folder renders; binary junk piped to `batch -` likewise, and
    when nothing is left the batch says so (exit 2)."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "good.toml").write_text(scene_text())
    bad = folder / os.fsdecode(b"bad\xff\xfe.toml")
    bad.write_text(scene_text())
    out = tmp_path / "out"
    result = run(str(folder), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 0, result.stderr
    left_out = [line for line in result.stderr.splitlines() if "not UTF-8" in line]
    assert left_out == [f"warning: {shorten(repr(os.fsencode(bad)))}: a file name that is not UTF-8; left out "
                        "(rename it)"]
    assert list(manifest(out)) == ["good"]
    junk = bytes(range(1, 10)) + b"\xff\xfe\n" + bytes(range(128, 256)) + b"\n"
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "batch", "-", "--out", str(tmp_path / "b")],
                          input=junk, capture_output=True, timeout=120)
    assert b"Traceback" not in done.stderr and done.returncode == 2, done.stderr  # nothing left: no success
    assert done.stderr.count(b"a file name that is not UTF-8; left out") == 2
    assert done.stderr.splitlines()[-1].startswith(b"error: stdin: no scene to render")


def test_an_internal_error_that_quotes_a_file_name_not_utf8_keeps_its_traceback(tmp_path, monkeypatch):
    """The log of an internal error is written whatever its text holds (the logger itself crashed)."""
    from raycast_phong.cli import common
    monkeypatch.setenv(common.ERROR_LOGS_VARIABLE, str(tmp_path))
    log = common._traceback_log(ValueError(os.fsdecode(b"no\xff")))
    assert log is not None and "no\\udcff" in Path(log).read_text()


def test_an_internal_error_keeps_its_traceback_and_the_batch_goes_on(five_scenes, tmp_path, monkeypatch):
    def load_scene(path, overrides=(), **options):
        if Path(path).stem == "sphere1":
            return 1 / 0  # a bug in the loader, on one scene
        return rp.load_scene(path, overrides, **options)

    monkeypatch.setattr(batch.jobs, "load_scene", load_scene)
    out = tmp_path / "out"
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 1, result.stderr
    entries = manifest(out)
    bug = entries["sphere1"]
    assert bug["status"] == "failed"
    assert bug["reason"] == f"{five_scenes / 'sphere1.toml'}: internal error: ZeroDivisionError: division by zero"
    assert bug["traceback"].startswith("Traceback") and "return 1 / 0" in bug["traceback"]
    assert entries["broken"]["traceback"] is None  # bad input: no traceback
    assert [name for name, entry in entries.items() if entry["status"] == "rendered"] == \
        ["mesh", "sphere0", "sphere2"]


# ---------------------------------------------------------------- the folder and the manifest


@pytest.mark.parametrize("layout", ["out is the scene folder", "out under a globbed folder"])
def test_the_batch_never_reads_its_own_manifest(tmp_path, layout):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "a.toml").write_text(scene_text())
    (folder / "b.json").write_text(json.dumps({"objects": [{"shape": "icosphere"}], "render": {"width": 8,
                                                                                              "height": 8}}))
    paths, out = ([str(folder)], folder) if layout.startswith("out is") else \
        ([str(folder / "**" / "*.json"), str(folder / "a.toml")], folder / "out")
    for _ in range(2):
        result = run(*paths, "--out", str(out), "--jobs", "1")
        assert result.exit_code == 0, result.stderr
    assert statuses(out) == {"a": "up to date", "b": "up to date"}


def test_the_up_to_date_check_does_not_depend_on_how_a_path_is_spelled(tmp_path, monkeypatch):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "tetra.obj").write_text(TETRAHEDRON)
    (folder / "mesh.toml").write_text(scene_text(shape="mesh", extra='path = "tetra.obj"'))
    (tmp_path / "link").symlink_to(folder)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    assert run("scenes/mesh.toml", "--out", str(out)).exit_code == 0
    for spelling in ("./scenes/mesh.toml", str(folder / "mesh.toml"), "scenes/../scenes/mesh.toml",
                     "link/mesh.toml", "scenes"):
        result = run(spelling, "--out", str(out))
        assert result.exit_code == 0, result.stderr
        assert statuses(out) == {"mesh": "up to date"}, spelling


@pytest.mark.parametrize("text", [b"{not json", b"\xff\xfe", json.dumps({"format": 1, "scenes": {"a": 3}}).encode(),
                                  json.dumps({"format": 99, "scenes": {}}).encode(), b"[" * 100_000])
def test_a_corrupt_manifest_is_reported_and_kept_aside(five_scenes, tmp_path, text):
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_bytes(text)
    (out / "manifest.json.corrupt-1").write_bytes(b"an earlier one")
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 1  # the broken scene
    # the batch's own warnings, not the scenes' render warnings (each after its scene file)
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:") and "/scenes/" not in line]
    assert len(warnings) == 1 and warnings[0].startswith(f"warning: {out / 'manifest.json'}: not ")
    assert warnings[0].endswith("; kept as manifest.json.corrupt-2, every scene renders again")
    assert (out / "manifest.json.corrupt-2").read_bytes() == text
    assert (out / "manifest.json.corrupt-1").read_bytes() == b"an earlier one"
    assert list(statuses(out).values()).count("rendered") == 4


def test_an_unreadable_manifest_is_refused(five_scenes, tmp_path):
    out = tmp_path / "out"
    (out / "manifest.json").mkdir(parents=True)
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 2
    assert result.stderr == (f"error: {out / 'manifest.json'}: is a folder, not a regular file; give a batch "
                             "manifest\n")
    assert images(out) == []


def test_a_signal_inside_the_bookkeeping_of_a_finished_scene_still_lists_it(tmp_path, monkeypatch):
    """The signal handler raises wherever the main thread is: here, inside record(), after the first scene's
    outcome is noted and before its manifest entry is (seen once in a loop of the signal test: s00 was
    missing from the manifest). The interrupted manifest must still list it, as rendered."""
    folder = slow_scenes(tmp_path / "scenes", 3)
    out = tmp_path / "out"
    real_asdict, calls = batch.run.asdict, []

    def asdict_then_signal(record):
        if isinstance(record, batch.Outcome) and record.status == batch.RENDERED and not calls:
            calls.append(record.name)
            raise batch.Interrupted(signal.SIGTERM)  # as batch.interrupt would, mid-record
        return real_asdict(record)

    monkeypatch.setattr(batch.run, "asdict", asdict_then_signal)
    with pytest.raises(batch.Interrupted) as stopped:
        batch.run_batch(batch.find_jobs([folder]), out, workers=1)
    assert stopped.value.report is not None
    entries = manifest(out)
    assert sorted(entries) == ["s00", "s01", "s02"]
    assert entries["s00"]["status"] == "rendered" and entries["s00"]["outputs"] == ["s00.png"]
    assert {entries["s01"]["status"], entries["s02"]["status"]} <= {"not started", "interrupted"}


def test_a_signal_whose_raise_foreign_code_swallowed_still_stops_the_batch(tmp_path, five_scenes, monkeypatch):
    """trimesh's imports catch BaseException, so a stop signal raised inside them was lost and the batch
    rendered everything with exit 0. The handler records the signal; the next safe point acts on it: the
    batch stops, and its manifest says what was done."""
    from raycast_phong import stops
    from raycast_phong.tools.batch import jobs, run
    loaded = []

    def prepare_with_a_swallowed_signal(job, *args, **kwargs):
        if not loaded:
            try:  # what trimesh's import guard does with the Interrupted our handler raises
                jobs.interrupt(signal.SIGTERM, None)
            except BaseException:  # noqa: BLE001
                pass
        loaded.append(job.name)
        return jobs.prepare_job(job, *args, **kwargs)

    monkeypatch.setattr(run, "prepare_job", prepare_with_a_swallowed_signal)
    out = tmp_path / "out"
    try:
        with pytest.raises(batch.Interrupted) as stopped:
            batch.run_batch(batch.find_jobs([five_scenes]), out, workers=1)
    finally:
        stops.clear()
    assert stopped.value.signal == signal.SIGTERM and len(loaded) == 1  # stopped at the first safe point
    assert set(statuses(out).values()) == {"not started"} and len(statuses(out)) == 5
    assert images(out) == []


def test_the_batch_records_stop_signals_from_its_first_imports():
    """`raycast-phong batch` listens for stop signals before the imports of its first seconds (a SIGTERM there
    killed it with -15, no line and no manifest); other commands keep Python's own handlers."""
    probe = ("import signal, sys; sys.argv = ['raycast-phong', sys.argv[1]]; import raycast_phong.cli; "
             "print(*(f'{h.__module__}.{h.__qualname__}' if callable(h) else str(h) "
             "for h in map(signal.getsignal, (signal.SIGTERM, signal.SIGHUP))))")
    listening = "raycast_phong.stops.record raycast_phong.stops.record"
    # Python's own: SIG_DFL (0), or SIG_IGN (1) where the test run itself inherited it (under nohup, SIGHUP)
    plain = subprocess.run([sys.executable, "-c", probe.replace("import raycast_phong.cli; ", ""), "render"],
                           capture_output=True, text=True, timeout=120)
    python_s = plain.stdout.strip()
    assert plain.returncode == 0 and python_s.replace("1", "0") == "0 0", (plain.stdout, plain.stderr)
    for command, expected in (("batch", listening), ("render", python_s)):
        done = subprocess.run([sys.executable, "-c", probe, command], capture_output=True, text=True, timeout=120)
        assert done.returncode == 0 and done.stdout.strip() == expected, (command, done.stdout, done.stderr)


@pytest.mark.parametrize("plant", ["fifo", "dev-zero"])
def test_a_planted_manifest_that_is_no_regular_file_is_one_line_not_a_hang(tmp_path, plant):
    """Anyone who can write a shared output folder could plant manifest.json as a FIFO (the batch waited for a
    writer forever) or as a link to /dev/zero (it read 3.6 GB in 5 s under a 300M budget): refused in one line,
    exit 2, before anything renders."""
    import shutil
    import subprocess
    import sys
    scene = tmp_path / "default.toml"
    shutil.copy(ROOT / "scenes" / "default.toml", scene)
    out = tmp_path / "out"
    out.mkdir()
    if plant == "fifo":
        os.mkfifo(out / "manifest.json")
    else:
        os.symlink("/dev/zero", out / "manifest.json")
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "batch", str(scene), "-o", str(out), "--jobs",
                           "1", "-q"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    [line] = done.stderr.strip().splitlines()
    assert "manifest.json" in line and "not a regular file" in line, line
    assert not (out / "default.png").exists()


def test_a_manifest_larger_than_the_limit_is_refused_as_too_large_not_read_in_part(tmp_path, monkeypatch):
    """A manifest is read up to MANIFEST_LIMIT + 1 bytes; one byte over the limit is refused as too large (a
    check one byte off would parse the first MANIFEST_LIMIT + 1 bytes of a larger file as its text)."""
    from raycast_phong.tools.batch import manifest
    monkeypatch.setattr(manifest, "MANIFEST_LIMIT", 100)
    text = json.dumps({"format": manifest.MANIFEST_FORMAT, "scenes": {}, "sheets": {}, "pad": ""})
    for size, refused in ((100, False), (101, True)):
        (tmp_path / "manifest.json").write_text(text[:-2] + "x" * (size - len(text)) + '"}')
        assert (tmp_path / "manifest.json").stat().st_size == size
        if refused:
            with pytest.raises(manifest.CorruptManifest, match="more than the"):
                manifest.read_manifest(tmp_path)
        else:
            assert manifest.read_manifest(tmp_path)["scenes"] == {}


def test_an_unreadable_manifest_under_a_long_path_names_it_once(tmp_path):
    """The refusal names the manifest once at the start of its line, however long its path (shown_name shortens
    a long one inside the message, which the line's start then did not recognise: the path twice, the message
    worded otherwise than for a short path). Found when a mutation run's long TMPDIR failed the test above."""
    out = tmp_path / ("d" * 120) / "out"
    (out / "manifest.json").mkdir(parents=True)
    (tmp_path / "s.toml").write_text('[[objects]]\nshape = "icosphere"\n')
    result = run(str(tmp_path / "s.toml"), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 2
    assert result.stderr == (f"error: {out / 'manifest.json'}: is a folder, not a regular file; give a batch "
                             "manifest\n"), result.stderr


@pytest.mark.parametrize("data", [{"scenes": {}}, {"format": 1, "scenes": []},
                                  {"format": 1, "scenes": {}, "sheets": 3}])
def test_a_manifest_without_its_format_or_with_fields_of_the_wrong_kind_is_corrupt(tmp_path, data):
    """read_manifest takes only a manifest of format 1 (docs/batch.md) whose scenes and sheets are tables: a JSON
    file without "format" is some other file, not an old manifest to trust."""
    from raycast_phong.tools.batch import manifest
    (tmp_path / "manifest.json").write_text(json.dumps(data))
    with pytest.raises(manifest.CorruptManifest, match="not a batch manifest of format 1"):
        manifest.read_manifest(tmp_path)


def test_a_manifest_over_the_limit_is_refused_naming_the_limit_in_mib(tmp_path, monkeypatch):
    """The refusal of a too-large manifest names the limit in MiB: with MANIFEST_LIMIT at 3 MiB, a file of
    3 MiB + 1 byte is "more than the 3 MiB a batch's manifest takes"."""
    from raycast_phong.tools.batch import manifest
    monkeypatch.setattr(manifest, "MANIFEST_LIMIT", 3 << 20)
    (tmp_path / "manifest.json").write_bytes(b" " * ((3 << 20) + 1))
    with pytest.raises(manifest.CorruptManifest) as refused:
        manifest.read_manifest(tmp_path)
    assert str(refused.value) == "more than the 3 MiB a batch's manifest takes"
