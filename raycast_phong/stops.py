"""Stop signals for a command that must finish its bookkeeping (`batch`: workers killed, temporaries removed,
the manifest written): each signal is recorded, so a raise that someone else's code swallowed (trimesh's
imports catch BaseException) is still acted on at the command's next safe point.

`listen` is called as the program starts (cli/__init__.py, before the imports of the first seconds): its
handler only records, so nothing is raised into code that is importing; the command then installs a handler
that records and raises, and checks `received` between its steps. No imports here beyond the standard library.
"""

from __future__ import annotations

import signal

STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
                     if hasattr(signal, name))
_received: list[int] = []


def record(number: int, frame=None) -> None:
    """A signal handler that remembers the signal and returns: the program goes on to its next safe point."""
    _received.append(int(number))


def listen() -> None:
    """Record STOP_SIGNALS from now on (main thread only, as Python runs handlers there)."""
    for number in STOP_SIGNALS:
        signal.signal(number, record)


def received() -> int | None:
    """The first stop signal received so far, or None."""
    return _received[0] if _received else None


def clear() -> None:
    """Forget the signals received: the command that acted on them has ended (the next one in this process,
    a test's, starts afresh)."""
    _received.clear()
