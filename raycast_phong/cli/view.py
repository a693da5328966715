"""`view`: explore a scene live in the browser (docs/view.md)."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path
from typing import Annotated

import typer

from raycast_phong import stops

from .common import _max_memory, app, check_verbosity, exit_codes, fail


@app.command(epilog="""
**Examples**

  raycast-phong view                                    # the default figure, in the browser

  raycast-phong view scenes/specular.toml --port 0 --no-browser   # any free port; open the printed URL

  raycast-phong view scenes/meshes/torus_knot.ply       # a mesh file, framed and lit
""")
def view(
    scene: Annotated[Path | None, typer.Argument(help="Scene file (.toml, .json) or a mesh file (any format "
                     "trimesh reads). Omit it for the built-in default scene.", show_default=False,
                     dir_okay=False)] = None,
    port: Annotated[int, typer.Option(min=0, max=65535, help="Port to listen on; 0 for any free one.")] = 8765,
    host: Annotated[str, typer.Option(help="Address to listen on. Anything but 127.0.0.1 lets other machines "
                    "reach the page (they still need the token).")] = "127.0.0.1",
    no_browser: Annotated[bool, typer.Option("--no-browser", help="Only print the URL.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print only warnings, errors and the page's URL "
                     "(the server logs nothing else either way).")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", help="Also log every request the server answers.")] = False,
    max_memory: Annotated[str | None, typer.Option(
        "--max-memory", metavar="SIZE", callback=_max_memory, show_default=False,
        help="The server's memory budget, e.g. 8G or 500M, shared by the frames it renders at once (2): a page's "
             "scene whose frame needs more than its share is refused on the page. Default: 3/4 of the memory "
             "available when it starts.")] = None,
) -> None:
    """Explore a scene live in the browser: switch shading models, drag the light, compare two settings
    (docs/view.md). Prints the page's URL with its access token; Ctrl-C stops the server."""
    check_verbosity(quiet, verbose)
    if "numpy" not in sys.modules:  # read once, when numpy loads OpenBLAS
        # The frames' bands run on the server's own threads. OpenBLAS would start threads of its own, at the
        # server's priority, that spin for a while after each product: the exact reference's products (at nice 19)
        # then kept a core busy at full priority beside the frames. One BLAS thread, unless the user chose.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    try:
        from raycast_phong.tools import view as live
    except ImportError as error:
        fail(f"the view needs its extra packages ({error.name} is missing): pip install 'raycast-phong[view]'")
    if host not in ("127.0.0.1", "localhost", "::1"):
        typer.secho(f"warning: --host {host}: the page is reachable from other machines; anyone with the URL's "
                    "token can use it", err=True, fg=typer.colors.YELLOW)
    # Ctrl-C and `kill` stop the server (uvicorn shuts it down, then raises the signal again): recorded here, so
    # the command ends with the status a stopped program has, after its clean-up, not an exit as if finished.
    previous = {number: signal.signal(number, stops.record) for number in (signal.SIGINT, signal.SIGTERM)}
    with exit_codes():
        try:
            live.serve(scene, host=host, port=port, open_browser=not no_browser,
                       announce=lambda url: typer.echo(f"raycast-phong view: open {url}"),
                       log_level="info" if verbose else "warning", max_memory=max_memory,
                       stopped=lambda number: typer.secho(f"raycast-phong view: stopped by "
                                                          f"{signal.Signals(number).name}", err=True))
        except OSError as error:
            fail(str(error))
        except KeyboardInterrupt:  # a SIGINT no handler of ours recorded (raised while it started)
            stops.record(signal.SIGINT)
            typer.secho("raycast-phong view: stopped by SIGINT", err=True)
        finally:
            if stops.received() is None:  # stopping: a second Ctrl-C while it ends is recorded, not raised
                for number, handler in previous.items():
                    signal.signal(number, handler)
    stopped = stops.received()
    if stopped is not None:  # stopped, not finished: 128 + the signal's number, as batch and every shell say it
        stops.clear()
        raise typer.Exit(code=128 + stopped)
