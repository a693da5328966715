"""`raycast-phong view`: a local web page that re-renders a scene live (server.py; the page is in static/)."""

from __future__ import annotations

import os
import re
import secrets
import socket
import sys
import threading
import webbrowser
from contextlib import contextmanager, suppress
from pathlib import Path

from ... import stops
from .server import Opened, create_app, open_scene
from .session import SOCKET_MAX_BYTES

__all__ = ["Opened", "bind", "create_app", "open_scene", "remembered_token", "running", "serve"]

TOKEN = re.compile(r"[A-Za-z0-9_-]{32,128}")  # what secrets.token_urlsafe(32) gives, and no less


def token_folder() -> Path:
    """Where the view keeps its token: $XDG_STATE_HOME/raycast-phong (~/.local/state/raycast-phong)."""
    return Path(os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state") / "raycast-phong"


def remembered_token() -> str:
    """This user's view token, kept between runs so that a restarted server accepts the open pages: they
    reconnect by themselves and a reload works (as Jupyter keeps its runtime files). The folder is made
    private (0700) and a token in a folder others can read is not reused; if nothing can be kept, a fresh
    token serves this run only."""
    from raycast_phong.io.atomic import WriteError, write_text
    folder = token_folder()
    path = folder / "view-token"
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        private = folder.stat().st_mode & 0o077 == 0
        kept = path.read_text(encoding="ascii").strip() if private and path.exists() else ""
    except (OSError, UnicodeDecodeError):
        return secrets.token_urlsafe(32)
    if TOKEN.fullmatch(kept):
        return kept
    token = secrets.token_urlsafe(32)
    if private:  # unwritten: this run's token only, and the page needs the new URL after a restart
        with suppress(WriteError):
            write_text(path, token + "\n")
    return token


def bind(host: str, port: int) -> socket.socket:
    """A listening socket on host:port (port 0: a free one), so the URL can name the real port."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as error:
        sock.close()
        raise OSError(f"cannot listen on {host}:{port} ({error.strerror or error}); choose another --port, "
                      "or --port 0 for any free one") from None
    sock.listen(64)
    sock.set_inheritable(True)
    return sock


WILDCARDS = ("0.0.0.0", "::", "")  # every address of the machine: any host name may reach the page


def origins_for(host: str, port: int) -> list[str]:
    """The page's origins the socket accepts: the address it is served on (and localhost for 127.0.0.1, and
    the loopback names for a wildcard address, which answers any host name besides)."""
    loopback = {"localhost", "127.0.0.1"} if host in ("127.0.0.1", "localhost", "0.0.0.0", "") else set()
    names = ({host} - set(WILDCARDS)) | loopback | ({"::1", "localhost"} if host in ("::1", "::") else set())
    shown = lambda name: f"[{name}]" if ":" in name else name  # an IPv6 address in a URL
    return sorted(f"http://{shown(name)}:{port}" for name in names)


def page_url(host: str, port: int, token: str) -> str:
    """The URL to open: a wildcard address is reached here through loopback; an IPv6 address in brackets."""
    shown = {"0.0.0.0": "127.0.0.1", "": "127.0.0.1", "::": "::1"}.get(host, host)
    shown = f"[{shown}]" if ":" in shown else shown
    return f"http://{shown}:{port}/?token={token}"


def close(app) -> None:
    """Stop the app's warm-up, render and reference threads."""
    app.state.executor.shutdown(wait=False, cancel_futures=True)
    app.state.view.shutdown()


def server_config(app, log_level: str = "warning"):
    """uvicorn's settings for the view; log_level "info" logs every request (`view --verbose`)."""
    import uvicorn
    # ws_max_size: refuse a flood at the protocol level, above the limit parse() answers in one line.
    # lifespan off: the app has no start-up or shut-down events, and uvicorn's lifespan task logs a
    # traceback when Ctrl-C's KeyboardInterrupt cancels it.
    return uvicorn.Config(app, log_level=log_level, ws_max_size=SOCKET_MAX_BYTES, ws_ping_interval=None, lifespan="off",
                          ws_per_message_deflate=False)


@contextmanager
def running(path: str | Path | None, host: str = "127.0.0.1", port: int = 0, token: str | None = None, **options):
    """Serve the view on a background thread (tests, the benchmark, the screenshots); yields the page's URL."""
    import uvicorn
    token = token or secrets.token_urlsafe(32)
    sock = bind(host, port)
    port = sock.getsockname()[1]
    app = create_app(open_scene(path), token, origins_for(host, port), any_host=host in WILDCARDS, **options)
    server = uvicorn.Server(server_config(app))
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        while not server.started and thread.is_alive():
            threading.Event().wait(0.01)
        yield page_url(host, port, token)
    finally:
        server.should_exit = True
        thread.join(30)
        sock.close()
        close(app)


def serve(path: str | Path | None, host: str = "127.0.0.1", port: int = 8765, open_browser: bool = True,
          announce=print, token: str | None = None, log_level: str = "warning", stopped=None,
          max_memory: int | None = None) -> None:
    """Serve the view of `path` (scene, mesh, or None for the default scene) until interrupted; the token is
    remembered_token() unless given; uvicorn logs at `log_level` ("info": every request). `stopped(number)` is
    told the stop signal the caller recorded (stops.record), once the server has shut down. `max_memory`: the
    server's memory budget (create_app)."""
    import uvicorn
    opened = open_scene(path)
    sock = bind(host, port)
    port = sock.getsockname()[1]
    token = token or remembered_token()
    app = create_app(opened, token, origins_for(host, port), any_host=host in WILDCARDS, max_memory=max_memory)
    url = page_url(host, port, token)
    announce(url)
    if open_browser:
        webbrowser.open(url)
    try:
        if stops.received() is None:  # not stopped while it started (the command records SIGINT and SIGTERM)
            uvicorn.Server(server_config(app, log_level)).run(sockets=[sock])
    finally:
        sock.close()
        close(app)
        if stops.received() is not None and stopped is not None:
            stopped(stops.received())
        leave_if_rendering()


def leave_if_rendering() -> None:
    """End the process now if a render is still running after the server stopped (Ctrl-C mid-frame): Python
    joins worker threads at exit, so the exit would wait for the frame (seconds at 8 samples; the renderer's
    tile pool runs every queued band), and a second Ctrl-C would break that join with a traceback. Nothing
    is owed to the disk: frames and saves go to the browser only."""
    others = [t for t in threading.enumerate() if t is not threading.current_thread() and not t.daemon]
    if any(t.is_alive() for t in others):
        sys.stdout.flush()
        sys.stderr.flush()
        stopped = stops.received()
        os._exit(0 if stopped is None else 128 + stopped)  # a signal's exit status, as the command's own
