"""Write a file so that no reader, crash or kill ever sees half of it: temporary file, then rename.

SIGTERM and SIGINT are held back while the temporary file exists (their handlers run right after),
so a `kill` cannot land between creating it and removing or renaming it — the window that left a
stray `.manifest-XXXXXXXX.json` behind in one CI run.
"""

from __future__ import annotations

import os
import signal
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

DEFERRED = (signal.SIGTERM, signal.SIGINT)


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGTERM and SIGINT until the block ends, then deliver them (main thread only: elsewhere
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
    """A temporary path beside `target`; renamed over it if the block succeeds, removed otherwise.

    The file gets the permissions a plain open() would give (mkstemp makes it 0600).
    """
    with signals_deferred():
        descriptor, temporary = tempfile.mkstemp(prefix=prefix, suffix=target.suffix, dir=target.parent)
        os.close(descriptor)
        try:
            yield Path(temporary)
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(temporary, 0o666 & ~umask)
            os.replace(temporary, target)
        finally:
            if os.path.exists(temporary):
                os.unlink(temporary)
