"""Write a file so that no reader, crash, kill or failed write ever sees half of it: temporary file, checked
write, fsync, then rename.

Every writer of the package (images, the batch manifest, the study's CSV, plot and summary) goes through
replaced_atomically, the one home of the rule: a write that fails at any step (a full disk, a file-size
limit, a quota, an I/O error at fsync) raises WriteError with one line naming the file and the OS reason,
removes the temporary file and leaves the old file as it was. No write follows a link: the temporary file is
made new (O_EXCL), reopened with O_NOFOLLOW, and a link at the target is replaced, never written through.

The stop signals (SIGINT, SIGTERM, SIGHUP, SIGQUIT: stops.STOP_SIGNALS) are held back while the temporary
file exists (their handlers run right after), so a `kill` or a closed terminal cannot land between creating
it and removing or renaming it (and leave a stray `.manifest-XXXXXXXX.json` behind).
"""

from __future__ import annotations

import errno
import os
import signal
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from ..errors import WriteError
from ..stops import STOP_SIGNALS

DEFERRED = STOP_SIGNALS


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold the stop signals until the block ends, then deliver them (main thread only: elsewhere
    Python runs no signal handlers anyway)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = {number: signal.signal(number, lambda number, frame: received.append(number)) for number in DEFERRED}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        if received:
            signal.raise_signal(received[0])


@contextmanager
def replaced_atomically(target: Path, prefix: str) -> Iterator[Path]:
    """A temporary path beside `target`; fsynced and renamed over it if the block succeeds, removed otherwise.

    The block writes the temporary file and raises OSError on any failure (its strerror, or its text, is the
    reason). Raises WriteError "TARGET: write failed: REASON (the old file is unchanged)" for that or for a
    failure here (creating, fsync, rename). The file gets the permissions a plain open() would give (mkstemp
    makes it 0600).
    """
    target = Path(target)
    existed = target.exists()
    with signals_deferred():
        try:
            descriptor, temporary = tempfile.mkstemp(prefix=prefix, suffix=target.suffix, dir=target.parent)
            made = os.fstat(descriptor)
            os.close(descriptor)
        except OSError as error:
            raise WriteError(_failed(target, error, existed)) from None
        try:
            yield Path(temporary)
            _settle(temporary, made)
            os.replace(temporary, target)
        except WriteError:
            raise
        except OSError as error:
            raise WriteError(_failed(target, error, existed)) from None
        finally:
            # Nothing more can be done if this fails too; the original error is the one to report.
            with suppress(OSError):
                os.unlink(temporary)


def _settle(temporary: str, made: os.stat_result) -> None:
    """Give the file open()'s permissions and push it to the disk: fsync is where a full disk (delayed
    allocation, NFS, quotas) reports what write() did not. Only the file mkstemp made is settled (and then
    renamed into place): a link or another file swapped in under its name, in a folder others can write,
    is refused."""
    descriptor = os.open(temporary, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    try:
        info = os.fstat(descriptor)
        if (info.st_dev, info.st_ino) != (made.st_dev, made.st_ino):
            raise OSError(errno.EEXIST, "the temporary file was replaced by another file while it was written")
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(descriptor, 0o666 & ~umask)
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _failed(target: Path, error: OSError, existed: bool) -> str:
    """One line: the file, the OS reason, and what is on disk now."""
    reason = error.strerror or str(error) or type(error).__name__
    reason = reason.splitlines()[0] if reason.strip() else type(error).__name__
    state = "the old file is unchanged" if existed else "no file was written"
    return f"{target}: write failed: {reason} ({state})"


def write_bytes(target: str | Path, data: bytes, prefix: str | None = None) -> Path:
    """Replace `target` with `data` atomically, checking every write, the written size and the close.

    Raises WriteError (see replaced_atomically).
    """
    target = Path(target)
    with replaced_atomically(target, prefix or f".{target.stem}-") as temporary:
        descriptor = os.open(temporary, os.O_WRONLY | os.O_TRUNC | os.O_NOFOLLOW)
        try:
            view = memoryview(data)
            while view:  # os.write may write less than asked; the next call then raises the reason
                view = view[os.write(descriptor, view):]
            if os.fstat(descriptor).st_size != len(data):
                raise OSError(errno.EIO, f"{os.fstat(descriptor).st_size} of {len(data)} bytes on disk")
        finally:
            os.close(descriptor)  # raises if the close itself reports a deferred error
    return target


def write_text(target: str | Path, text: str, prefix: str | None = None) -> Path:
    """Replace `target` with `text` in UTF-8, as write_bytes does."""
    return write_bytes(target, text.encode("utf-8"), prefix)


def os_reason(temporary: str | Path, fallback: str) -> OSError:
    """The OS error behind a failed write by a library that reports only its own text (OpenImageIO).

    Appending to the temporary file (it is discarded anyway) meets the same limit the library met: a
    file-size limit (EFBIG), a full disk (ENOSPC), a quota (EDQUOT). If that append succeeds the
    condition has passed; the library's first line is the reason then.
    """
    probe = b"\0" * (1 << 16)  # larger than any write buffer, so a full disk cannot absorb it in a partial block
    try:
        descriptor = os.open(temporary, os.O_WRONLY | os.O_APPEND | os.O_NOFOLLOW)
        try:
            os.write(descriptor, probe)
            os.fsync(descriptor)
        finally:
            os.close(descriptor)
    except OSError as error:
        if error.errno is not None:
            return OSError(error.errno, os.strerror(error.errno))
    lines = [line.strip() for line in fallback.splitlines() if line.strip()]
    return OSError(lines[0] if lines else "the image writer failed without saying why")
