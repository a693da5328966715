"""A batch folder's bookkeeping: DIR/manifest.json (read, a corrupt one kept aside, rewritten atomically), the
folder lock (flock on DIR/.batch.lock: one batch at a time per folder; never through a link, a FIFO or a
second name someone planted there), and the temporaries a killed writer left.
"""

from __future__ import annotations

import errno
import json
import os
import re
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ...errors import BatchBusy, BatchFolderError, CorruptManifest, SceneError
from ...io.atomic import write_text
from ...io.files import open_regular

MANIFEST = "manifest.json"


MANIFEST_FORMAT = 1


LOCK = ".batch.lock"  # held (flock) by the batch writing into the folder


def is_own_manifest(path: Path, folder: Path) -> bool:
    """Whether `path` is the manifest of the batch folder `folder` (never a scene, however it is spelled)."""
    return path.resolve() == (folder / MANIFEST).resolve()


MANIFEST_LIMIT = 64 << 20  # bytes: entries of about 100,000 scenes; a larger file is no manifest of a batch's


def read_manifest(folder: Path) -> dict:
    """DIR/manifest.json, or an empty manifest if there is none.

    Raises CorruptManifest for a file that is not a batch manifest (format MANIFEST_FORMAT, at most
    MANIFEST_LIMIT bytes), BatchFolderError for one that cannot be read or is not a regular file (a folder, a FIFO
    that would block the batch forever, a link to /dev/zero that never ends: anyone who can write a shared output
    folder could plant one).
    """
    path = folder / MANIFEST
    try:
        with open_regular(path, str(path), "batch manifest") as handle:
            text = handle.read(MANIFEST_LIMIT + 1)
    except FileNotFoundError:
        return {"format": MANIFEST_FORMAT, "scenes": {}, "sheets": {}}
    except SceneError as error:  # not a regular file
        raise BatchFolderError(str(error)) from None
    except OSError as error:
        raise BatchFolderError(f"{path}: cannot read the batch manifest ({error.strerror})") from None
    if len(text) > MANIFEST_LIMIT:
        raise CorruptManifest(f"more than the {MANIFEST_LIMIT >> 20} MiB a batch's manifest takes")
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as error:  # not UTF-8, not JSON, or nested too deep
        raise CorruptManifest(f"not JSON ({type(error).__name__}: {str(error).splitlines()[0][:80]})") from None
    if not (isinstance(data, dict) and data.get("format") == MANIFEST_FORMAT and isinstance(data.get("scenes"), dict)
            and all(isinstance(entry, dict) for entry in data["scenes"].values())
            and isinstance(data.setdefault("sheets", {}), dict)):
        raise CorruptManifest(f"not a batch manifest of format {MANIFEST_FORMAT}")
    return data


def open_manifest(folder: Path) -> tuple[dict, str | None]:
    """read_manifest, but a corrupt manifest is renamed to manifest.json.corrupt-N (kept for a look) and the
    batch starts afresh: returns the manifest and that one-line warning (else None)."""
    try:
        return read_manifest(folder), None
    except CorruptManifest as error:
        path = folder / MANIFEST
        kept = next(path.with_name(f"{MANIFEST}.corrupt-{n}") for n in range(1, 1 << 20)
                    if not path.with_name(f"{MANIFEST}.corrupt-{n}").exists())
        try:
            path.rename(kept)  # the folder lock is held: nothing else writes these names meanwhile
        except OSError as failure:
            raise BatchFolderError(f"{path}: {error}, and cannot keep it aside ({failure.strerror})") from None
        return read_manifest(folder), f"{path}: {error}; kept as {kept.name}, every scene renders again"


@contextmanager
def folder_lock(folder: Path) -> Iterator[None]:
    """Hold DIR/.batch.lock (flock) while the block runs: two batches writing into one folder would delete
    each other's temporary files and overwrite each other's manifest entries. A second batch is refused at
    once (BatchBusy, exit 2), naming the process that holds the folder, rather than waiting unseen."""
    import fcntl
    path = folder / LOCK
    try:
        # O_NOFOLLOW: a link planted in a shared folder must not aim the batch's writes at someone's file;
        # O_NONBLOCK: a FIFO planted there opens at once (and is refused below) instead of waiting for a writer.
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o666)
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise BatchFolderError(f"{path}: the batch lock is a symbolic link, which the batch does not write "
                                   "through; remove it, or use another -o/--output") from None
        raise BatchFolderError(f"{path}: cannot create the batch lock ({error.strerror})") from None
    try:
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
            what = "not a regular file" if not stat.S_ISREG(info.st_mode) else f"a file of {info.st_nlink} names"
            raise BatchFolderError(f"{path}: the batch lock is {what}, which the batch does not write through; "
                                   "remove it, or use another -o/--output")
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(descriptor, 32, 0).decode(errors="replace").strip()
            raise BatchBusy(f"{folder}: another batch{f' (process {holder})' if holder.isdigit() else ''} is "
                             "writing into this folder; wait for it to finish, or use another -o/--output") from None
        try:
            os.ftruncate(descriptor, 0)
            os.pwrite(descriptor, f"{os.getpid()}\n".encode(), 0)  # for the message above; the lock is the flock
        except OSError as error:
            raise BatchFolderError(f"{path}: cannot write the batch lock ({error.strerror})") from None
        yield
    finally:
        os.close(descriptor)  # releases the flock


def write_manifest(folder: Path, manifest: dict) -> None:
    """Rewrite DIR/manifest.json atomically (temporary file, checked write, then rename); raises WriteError."""
    from ... import __version__
    manifest = {**manifest, "format": MANIFEST_FORMAT, "package_version": __version__}
    write_text(folder / MANIFEST, json.dumps(manifest, indent=2, ensure_ascii=False), prefix=".manifest-")


def remove_temporaries(folder: Path, names: list[str]) -> list[Path]:
    """Delete what a killed writer left: write_image's `.NAME-XXXXXXXX.png|exr` and `.manifest-*.json`."""
    pattern = re.compile(r"\.(?P<name>.+)-[A-Za-z0-9_]{8}\.(png|exr)$|\.manifest-[A-Za-z0-9_]{8}\.json$")
    wanted, removed = set(names) | {"contact"}, []
    for path in folder.iterdir():
        match = pattern.match(path.name)
        if match and (match["name"] is None or match["name"] in wanted or match["name"].endswith("-contact")):
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed
