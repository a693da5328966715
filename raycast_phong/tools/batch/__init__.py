"""Render many scene files into one folder, in worker processes or on a Dask cluster, and keep a manifest.

find_jobs turns files, folders, globs and sweep files into Jobs; prepare_job (in the calling process) loads
each scene and hashes it to decide whether its outputs are current; render_job (in a worker) renders one scene
and writes its image atomically. run_batch drives both through any executor and rewrites DIR/manifest.json
as scenes finish (at most every MANIFEST_INTERVAL, and at the end or on an interrupt), so an interrupted
batch keeps what it finished. A failing scene becomes a failed entry
with a one-line reason; it never stops the others.

Under faults (docs/batch.md, "Faults"): one batch at a time per folder (flock on DIR/.batch.lock); SIGINT or
SIGTERM kills the workers at once and the manifest marks what did not render; workers die with the batch
process (PR_SET_PDEATHSIG); a worker that dies fails only its scene and is replaced.

The package, one job per module: jobs (which scenes, whether each is current, one scene from load to image),
manifest (the manifest, the folder lock, temporaries), supervisor (this process or a worker pool), cluster
(Dask), run (run_batch, the driver). The names below are its public face.
"""

from ...errors import BatchBusy, CorruptManifest  # raised here; defined with every other error
from ...stops import STOP_SIGNALS  # the stop signals a batch acts on (one home: stops.py)
from .cluster import CONNECT_TIMEOUT
from .jobs import (
    FAILED,
    INTERRUPTED,
    NOT_STARTED,
    RENDERED,
    UP_TO_DATE,
    BatchReport,
    Interrupted,
    Outcome,
    Settings,
    Task,
    find_jobs,
    input_paths,
    input_times,
    interrupt,
    is_current,
    job_hash,
    listed_paths,
    prepare_job,
    render_job,
)
from .manifest import (
    LOCK,
    MANIFEST,
    MANIFEST_FORMAT,
    folder_lock,
    is_own_manifest,
    open_manifest,
    read_manifest,
    remove_temporaries,
    write_manifest,
)
from .run import MANIFEST_INTERVAL, run_batch
from .supervisor import warm_up

__all__ = [
    "CONNECT_TIMEOUT",
    "FAILED",
    "INTERRUPTED",
    "LOCK",
    "MANIFEST",
    "MANIFEST_FORMAT",
    "MANIFEST_INTERVAL",
    "NOT_STARTED",
    "RENDERED",
    "STOP_SIGNALS",
    "UP_TO_DATE",
    "BatchBusy",
    "BatchReport",
    "CorruptManifest",
    "Interrupted",
    "Outcome",
    "Settings",
    "Task",
    "find_jobs",
    "folder_lock",
    "input_paths",
    "input_times",
    "interrupt",
    "is_current",
    "is_own_manifest",
    "job_hash",
    "listed_paths",
    "open_manifest",
    "prepare_job",
    "read_manifest",
    "remove_temporaries",
    "render_job",
    "run_batch",
    "warm_up",
    "write_manifest",
]
