"""`raycast-phong view`: a local page that re-renders one scene as a person changes its settings.

The page sends settings as {dotted scene key: value}; each is applied to the scene file's table with
scene.apply_override and the whole checked by validate_scene, exactly as `render --set` does, so a
bad value is answered with the CLI's one-line message. Frames are rendered by rp.render on one worker
thread per page and sent back as PNG (image_io.write_image, the CLI's own 8-bit encoding). Each page keeps a
FrameCache: its frames reuse the geometry and the committed BVH, rebuilding only what a change touched (a light
move rebuilds nothing). At rest a frame of several samples a pixel is refined: a preview of one sample, then
the full frame; a newer request cancels a running preview or full frame between two bands.

Security (as Jupyter): a random token in the URL (then a same-site cookie for the page's own files)
and on the socket; the socket's Origin must be the page's; only files inside static/ are served;
page values are data for the scene schema only (never code, never a file path); one client holds
at most one running and one pending render (latest wins: a newer request replaces a waiting one, and
cancels a running preview or full frame).
"""

from __future__ import annotations

import asyncio
import copy
import json
import math
import os
import re
import secrets
import struct
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import HTMLResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

import raycast_phong as rp
from raycast_phong.codes import OUTPUT_PATH, ShadingModel
from raycast_phong.errors import RenderCancelled, SceneError, ViewError
from raycast_phong.io.encoding import DISPLAY, display_values
from raycast_phong.io.image_io import image_bytes
from raycast_phong.io.scene_file import syntax_limit
from raycast_phong.io.scene_toml import scene_toml, toml_value
from raycast_phong.renderer.reuse import FrameCache
from raycast_phong.scene.load import read_scene_dict
from raycast_phong.scene.messages import dotted
from raycast_phong.scene.overrides import apply_override

STATIC = Path(__file__).parent / "static"
MAX_MESSAGE_BYTES = 1 << 16   # a page message is a few hundred bytes of settings; refuse anything larger
MAX_SETTINGS = 256            # keys per request: far more than the page has controls
MAX_VIEW_RAYS = 1920 * 1080 * 16  # rays per frame: ~2 s here; a larger frame is a batch job, not a view
LEVELS = range(7)          # tessellation levels the page offers (reference.refined: level 6 = 81,920 faces)
STATIC_LINK = re.compile(r'(src|href)="static/([A-Za-z0-9_.-]+)"')  # index.html's links to its own files
COOKIE = "raycast_phong_view_{port}"  # cookies ignore the port: one name per server, as Jupyter's


# ---------------------------------------------------------------- scenes from page settings

@dataclass
class Source:
    """The scene the view was started with: its parsed table, the name errors use, its folder, and the scene
    file the server watches (None for a mesh file, which render() itself reads anew when it changes)."""
    data: dict
    name: str
    folder: Path
    watched: Path | None = None
    files: dict[tuple, str] = field(default_factory=dict)  # Scene.named_files(): the only files a page may use


def open_source(path: str | Path | None) -> Source:
    """A scene file (.toml/.json), a mesh file (mesh_scene: framed by a camera and lit by a key light), or the
    default scene; validated now, so a bad file is refused before the server starts."""
    path = Path(path) if path is not None else rp.default_scene_path()
    scene_file = path.suffix.lower() in (".toml", ".json")
    source = Source(read_scene_dict(path), str(path), path.parent, path if scene_file else None)
    source.files = scene_with(source, {}).named_files()
    return source


WATCH_EVERY = 0.5  # seconds between looks at the scene file: an edit shows within a second, the disk stays idle


def version(path: Path) -> tuple | None:
    """What changes when a file is rewritten (an editor's save replaces it: a new inode); None if it is gone."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return stat.st_mtime_ns, stat.st_size, stat.st_ino


KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z0-9_-]+))*")
# The page never changes a file path: a mesh or texture path would let a page make the server read (or probe
# for) any file. These keys are refused by name; a path set any other way (a whole material or object table)
# is caught by comparing the validated scene's named_files with the source's, before any file is opened.
PATH_KEYS = re.compile(r"(objects\.\d+\.path|materials\.[^.]+\.k[ade]_map(\.path)?|output(\..*)?|folder)")


def scene_with(source: Source, settings: dict) -> rp.Scene:
    """The source scene with the page's settings applied and validated, as `render --set KEY=VALUE` would."""
    if not isinstance(settings, dict):
        raise ViewError("settings must be a table of KEY.PATH: value")
    if len(settings) > MAX_SETTINGS:
        raise ViewError(f"settings: {len(settings)} keys; allowed: at most {MAX_SETTINGS}")
    data = copy.deepcopy(source.data)
    for key, value in settings.items():
        if not KEY.fullmatch(key):
            raise ViewError(f"{source.name}: {key!r} is not a key path; expected names and list indices joined "
                            "by dots, e.g. render.width")
        if PATH_KEYS.fullmatch(key):
            raise ViewError(f"{source.name}: {key}: the view does not change file paths or outputs; edit the "
                            "scene file instead")
        apply_override(data, f"{key}={toml_value(value)}", source=source.name)
    scene = rp.validate_scene(data, source=source.name, folder=source.folder)
    if settings:
        named = scene.named_files()
        moved = next((key for key in named if source.files.get(key) != named[key]), None)
        if moved is not None:
            raise ViewError(f"{source.name}: {dotted(moved)}: the view does not change file paths or outputs; "
                            "edit the scene file instead")
    opts = scene.render
    if opts.width * opts.height * opts.samples ** 2 > MAX_VIEW_RAYS:
        raise ViewError(f"{source.name}: render.samples: {opts.width}×{opts.height} pixels × {opts.samples}² "
                        f"samples is more than the view's {MAX_VIEW_RAYS:,} rays per frame; render it with "
                        "`raycast-phong render` instead")
    return scene


def draft_of(scene: rp.Scene) -> rp.Scene:
    """The frame shown while dragging: a quarter of the pixels (half each side), one sample, no layers."""
    opts = scene.render
    draft = opts.model_copy(update={"width": max(1, (opts.width + 1) // 2),
                                    "height": max(1, (opts.height + 1) // 2), "samples": 1})
    return scene.model_copy(update={"render": draft, "output": scene.output.model_copy(update={"aovs": ()})})


def frame_of(scene: rp.Scene) -> rp.Scene:
    """The scene as the view renders it at rest: every pixel and sample, no extra layers."""
    return scene.model_copy(update={"output": scene.output.model_copy(update={"aovs": ()})})


def preview_of(scene: rp.Scene) -> rp.Scene:
    """The first step of a full frame of several samples a pixel: every pixel, one sample, no layers."""
    return frame_of(scene).model_copy(update={"render": scene.render.model_copy(update={"samples": 1})})


# Each quality a frame is rendered at: draft while dragging; at rest, a preview (one sample a pixel, only when the
# scene asks for more) and then the full frame. A newer request cancels a preview or a full frame mid-way.
SHAPED = {"draft": draft_of, "preview": preview_of, "full": frame_of}


def leaves(node: Any, prefix: str = "") -> dict[str, Any]:
    """A scene table as {dotted key: value}, the keys `render --set` takes: tables and lists of tables are
    opened (objects.0.shading), anything else (numbers, strings, [x, y, z]) is one value."""
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list) and node and all(isinstance(item, dict) for item in node):
        items = enumerate(node)
    else:
        return {prefix[:-1]: node}
    found: dict[str, Any] = {}
    for key, value in items:
        found.update(leaves(value, f"{prefix}{key}."))
    return found


def settings_from(source: Source, text: str, name: str) -> dict:
    """The page's settings that turn the view's scene into the scene file `text` (a TOML or JSON scene, as
    the Save button writes it): the keys whose values differ. Refused in one line when no settings can (a
    different mesh file, another number of lights or objects) or the file is not a valid scene."""
    import tomllib
    is_json = name.lower().endswith(".json")
    try:
        data = json.loads(text) if is_json else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as error:
        raise ViewError(f"{name}: not a {'JSON' if is_json else 'TOML'} scene: {error}") from None
    except (RecursionError, ValueError) as error:  # nested thousands deep, an integer of 5000 digits
        raise ViewError(f"{name}: {syntax_limit(error)}") from None
    if not isinstance(data, dict):
        raise ViewError(f"{name}: a scene file is a table of tables")
    theirs = rp.validate_scene(data, source=name, folder=source.folder)
    def dump(scene: rp.Scene) -> dict:  # paths and outputs are compared apart
        table = leaves(scene.model_dump(mode="json", exclude={"folder"}))
        return {key: value for key, value in table.items() if not PATH_KEYS.fullmatch(key)}

    ours = scene_with(source, {})
    for kind in ("objects", "lights"):
        if len(getattr(theirs, kind)) != len(getattr(ours, kind)):
            raise ViewError(f"{name}: {len(getattr(theirs, kind))} {kind}, this view's scene has "
                            f"{len(getattr(ours, kind))}; open it with `raycast-phong view {name}` instead")
    mine, other = ours.named_files(), theirs.named_files()
    where = lambda files, key: None if key not in files else (source.folder / files[key]).resolve()
    for key in sorted((mine.keys() | other.keys()) - {OUTPUT_PATH}, key=dotted):
        if where(mine, key) != where(other, key):
            raise ViewError(f"{name}: {dotted(key)} is {other.get(key)}, not this view's {mine.get(key)}; the page "
                            f"does not change files: open it with `raycast-phong view {name}` instead")
    wanted = dump(theirs)
    current = dump(ours)
    settings = {key: value for key, value in wanted.items() if current.get(key, ...) != value}
    if any(value is None for value in settings.values()):
        unset = next(key for key, value in settings.items() if value is None)
        raise ViewError(f"{name}: {unset} is unset there and set here; a page setting cannot unset a key")
    try:
        made = dump(scene_with(source, settings))
    except SceneError as error:
        raise ViewError(f"{name}: these settings do not apply to this view's scene: {error}") from None
    if made != wanted:
        differs = sorted(key for key in wanted.keys() | made.keys() if made.get(key) != wanted.get(key))
        raise ViewError(f"{name}: {', '.join(differs[:3])} cannot be set from the page; open it with "
                        f"`raycast-phong view {name}` instead")
    return settings


# ---------------------------------------------------------------- frames

def encode(image: np.ndarray, suffix: str, aovs: dict | None = None, colour: str = DISPLAY) -> bytes:
    """An image rendered in `colour` as the bytes of the file `raycast-phong render -o x.png|.exr` would write."""
    return image_bytes(image, suffix, aovs, colour)


def pack(header: dict, parts: list[tuple[str, bytes]]) -> bytes:
    """One binary socket message: uint32 LE header length, the JSON header (with each part's name and
    length), then the parts' bytes in order."""
    header = {**header, "parts": [{"name": name, "length": len(data)} for name, data in parts]}
    text = json.dumps(header).encode("utf-8")
    return struct.pack("<I", len(text)) + text + b"".join(data for _, data in parts)


def unpack(message: bytes) -> tuple[dict, dict[str, bytes]]:
    """The inverse of pack (for tests and the benchmark)."""
    (length,) = struct.unpack_from("<I", message)
    header = json.loads(message[4:4 + length])
    parts, at = {}, 4 + length
    for part in header["parts"]:
        parts[part["name"]] = message[at:at + part["length"]]
        at += part["length"]
    return header, parts


def settings_of(request: dict, key: str = "settings") -> dict:
    """A request's table of settings (a copy), refused in one line if it is not a table."""
    value = request.get(key) or {}
    if not isinstance(value, dict):
        raise ViewError(f"{key} must be a table of KEY.PATH: value")
    return dict(value)


def left_out(plan) -> list[dict]:
    return [{"name": s.name, "reason": s.reason} for s in plan.stages if not s.kept]


@dataclass
class Renderer:
    """Turns one request into one reply; runs on the view's worker thread."""
    source: Source
    render: Callable[..., Any] = None  # rp.render; a test may wrap it (to hold a render while it sends more)

    def __post_init__(self):
        self.render = self.render or rp.render

    def scenes(self, request: dict) -> dict[str, rp.Scene]:
        """The validated scenes of a render request: A, and B to compare (or A's three shading models)."""
        quality = request.get("quality", "full")
        if quality not in ("draft", "full"):
            raise ViewError(f"quality: {quality!r}; allowed: 'draft' or 'full'")
        scenes = {"a": scene_with(self.source, settings_of(request))}
        if request.get("models"):
            # The lecture's figure: A in flat, Gouraud and Phong shading, as panels a, b and c.
            from raycast_phong.scene.overrides import shaded
            scenes = dict(zip("abc", (shaded(scenes["a"], model) for model in ShadingModel)))
        elif request.get("compare") is not None:
            scenes["b"] = scene_with(self.source, settings_of(request, "compare"))
        return scenes

    def steps(self, request: dict) -> list[str]:
        """The qualities a request is rendered at, in order: a draft; or at rest the full frame, after a preview
        of one sample a pixel when a scene asks for more (refined: the image comes at once, the samples after)."""
        if request.get("quality", "full") == "draft":
            return ["draft"]
        many = any(scene.render.samples > 1 for scene in self.scenes(request).values())
        return ["preview", "full"] if many else ["full"]

    def frame(self, request: dict, progress: Callable[[float], None] | None = None, shown: dict | None = None,
              cache: FrameCache | None = None, cancelled: Callable[[], bool] | None = None,
              step: str | None = None) -> bytes:
        """Render settings A (and B, to compare) at the requested quality (or at `step`, one of steps()); the
        PNGs, the heat map, the figures. `progress(share)` is told the share of the tiles done, 0..1 over A and
        B together; `shown` (the page's own table) keeps (request id, RenderResult) of its last full frame A for
        errors(); `cache` is the page's FrameCache (geometry and BVH kept between its frames); `cancelled()`
        answering True stops the frame between bands (RenderCancelled)."""
        started = time.perf_counter()
        scenes = self.scenes(request)
        quality = step or request.get("quality", "full")
        header: dict = {"type": "frame", "id": request.get("id"), "quality": quality}
        shaped = SHAPED[quality]
        parts, images, stats = [], {}, {}
        for k, (name, scene) in enumerate(scenes.items()):
            told = None
            if progress is not None:
                told = lambda done, total, k=k: progress((k + done / max(total, 1)) / len(scenes))
            result = self.render(shaped(scene), source=self.source.name, progress=told, cache=cache,
                                 cancelled=cancelled)
            if name == "a" and quality == "full" and not request.get("models") and shown is not None:
                shown["a"] = (request.get("id"), result)  # errors() measures this image, not a new one
            images[name] = display_values(result.image, result.colour)  # A and B compared as shown
            parts.append((name, encode(result.image, ".png", colour=result.colour)))
            stats[name] = {"frame": result.timings["frame"], "rays_per_second": result.rays_per_second,
                           "rays": result.rays, "triangles": result.triangles, "left_out": left_out(result.plan),
                           "warnings": list(result.plan.warnings),
                           "width": result.image.shape[1], "height": result.image.shape[0]}
        if "b" in images and "c" not in images:
            from raycast_phong.tools.difference import difference, heat_map
            if images["a"].shape == images["b"].shape:
                diff = difference(images["a"], images["b"])
                scale = float(diff.max())
                header["difference"] = {"max": scale, "mean": float(diff.mean())}
                parts.append(("heat", encode(heat_map(diff, scale), ".png")))
            else:
                header["difference"] = {"note": "A and B differ in size; no heat map"}
        header["stats"] = stats
        header["seconds"] = time.perf_counter() - started
        return pack(header, parts)

    def errors(self, request: dict, shown: dict | None = None) -> dict | None:
        """RMSE, max error and highlight loss of A against the exact surfaces; None for a mesh scene. The image
        measured is the page's last full frame (`shown`, as frame() kept it) if it is this request's."""
        from raycast_phong.tools.accuracy import measured
        from raycast_phong.tools.reference import ExactScene
        scene = frame_of(scene_with(self.source, settings_of(request)))
        try:
            ExactScene(scene, self.source.name)
        except SceneError:
            return None
        shown_id, image = (shown or {}).get("a", (None, None))
        if shown_id != request.get("id"):
            image = self.render(scene, source=self.source.name)
        result = measured(scene, image, "analytic", 2, self.source.name)
        e = result.errors
        finite = lambda x: None if x is None or not math.isfinite(x) else x  # JSON has no nan or inf
        return {"type": "errors", "id": request.get("id"), "rmse": finite(e.rmse), "max_error": finite(e.max_error),
                "psnr": finite(e.psnr), "highlight_loss": finite(e.highlight_loss),
                "seconds": result.reference_seconds}

    def save(self, request: dict, cache: FrameCache | None = None) -> bytes:
        """The current settings as a scene file (toml), or the full-resolution image (png, exr with layers);
        `cache`: the page's FrameCache, whose geometry and BVH the image may reuse."""
        what = request.get("what")
        scene = scene_with(self.source, settings_of(request))
        side = request.get("side", "a")
        if side not in ("a", "b"):
            raise ViewError(f"save: side {side!r}; allowed: 'a' or 'b'")
        stem = f"{Path(self.source.name).stem or 'scene'}-view-{side.upper()}"  # which setting it is
        if what == "toml":
            data = scene_toml(scene).encode("utf-8")
        elif what in ("png", "exr"):
            result = self.render(scene if what == "exr" else frame_of(scene), source=self.source.name, cache=cache)
            data = encode(result.image, f".{what}", result.aovs if what == "exr" else None, result.colour)
        else:
            raise ViewError(f"save: {what!r}; allowed: 'toml', 'png' or 'exr'")
        return pack({"type": "saved", "id": request.get("id"), "what": what, "filename": f"{stem}.{what}"},
                    [("file", data)])


# ---------------------------------------------------------------- the app

@dataclass
class Client:
    """One socket's queue: at most one waiting render (latest wins), one waiting save, one waiting reference;
    its own render thread, so a page asking for a slow frame never holds another page's frames; its last full
    frame A (for the exact errors: request ids are each page's own); its FrameCache (the geometry and BVH its
    frames share, released with the page); and the quality being rendered with the event that cancels it."""
    pending: dict | None = None
    cache: FrameCache = field(default_factory=lambda: FrameCache())
    running: str | None = None                # the quality of the frame being rendered ("draft", "preview", "full")
    cancel: threading.Event = field(default_factory=threading.Event)  # set: the running frame stops between bands
    pending_save: dict | None = None
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    dropped: int = 0
    reference_next: dict | None = None        # the newest full frame whose exact errors are still owed
    reference_task: asyncio.Task | None = None
    executor: ThreadPoolExecutor = field(default_factory=lambda: ThreadPoolExecutor(1, "view-page"))
    # Its exact references on a thread of their own at nice 19: a closed page's reference still running (it
    # cannot be stopped midway) then delays no other page's, and the frames get the cores first.
    references: ThreadPoolExecutor = field(default_factory=lambda: ThreadPoolExecutor(
        1, "view-page-reference", initializer=lowest_priority))
    shown: dict = field(default_factory=dict)


def create_app(source: Source, token: str, origins: list[str], *, render: Callable | None = None,
               executor: ThreadPoolExecutor | None = None, any_host: bool = False) -> Starlette:
    """The view's Starlette app. `origins` are the page's own (scheme://host:port); the socket accepts no other.
    `any_host` (served on 0.0.0.0 or ::): any Host name, and then the socket's Origin must be that host's page."""
    renderer = Renderer(source, render)
    executor = executor or ThreadPoolExecutor(max_workers=1, thread_name_prefix="view-render")
    hosts = {host_of(o.split("://", 1)[1]) for o in origins}

    def authorised(connection) -> bool:
        given = connection.query_params.get("token") or connection.cookies.get(cookie_name(connection)) or ""
        return secrets.compare_digest(given.encode(), token.encode())

    def refused() -> Response:
        return PlainTextResponse("403: this page needs the token the `raycast-phong view` command printed; open "
                                 "the URL it printed (its token is kept in ~/.local/state/raycast-phong, so a "
                                 "restarted server prints the same one)\n", status_code=403)

    async def index(request: Request) -> Response:
        if not authorised(request):
            return refused()
        # The page's own files (script, style) come with the token in their URLs, as the page's own did: a
        # page framed by a notebook of another site gets no same-site cookie. The cookie serves the rest.
        page = STATIC_LINK.sub(lambda m: f'{m[1]}="static/{m[2]}?token={quote(token, safe="")}"',
                               (STATIC / "index.html").read_text(encoding="utf-8"))
        response = HTMLResponse(page, headers={"Cache-Control": "no-store"})
        response.set_cookie(cookie_name(request), token, httponly=True, samesite="strict")
        return response

    static_files = StaticFiles(directory=STATIC)

    async def static(scope, receive, send):
        request = Request(scope)
        if not authorised(request):
            return await refused()(scope, receive, send)
        await static_files(scope, receive, send)

    async def socket(websocket: WebSocket) -> None:
        origin = websocket.headers.get("origin")
        own = any_host and origin == f"http://{websocket.headers.get('host', '')}"  # the page of the host it asked
        if not authorised(websocket) or not (origin in origins or own):
            await websocket.close(code=1008)  # policy violation, before the handshake completes
            return
        await websocket.accept()
        client = Client()
        pages.add(websocket)
        if source.watched is not None and (not watcher or watcher[0].done()):
            watcher[:] = [asyncio.create_task(watch())]
        await websocket.send_text(json.dumps({**hello(source), "warming": not app.state.warming.done()}))
        worker = asyncio.create_task(work(websocket, client))
        try:
            while True:
                text = await websocket.receive_text()
                try:
                    request = parse(text)
                except ViewError as error:
                    await websocket.send_text(json.dumps({"type": "error", "id": None, "message": str(error)}))
                    continue
                if request.get("type") == "load":
                    await websocket.send_text(json.dumps(loaded(request)))
                elif request.get("type") == "save":
                    client.pending_save = request
                else:
                    if client.pending is not None:  # a newer request replaces the one still waiting
                        client.dropped += 1
                        await websocket.send_text(json.dumps({"type": "dropped", "id": client.pending.get("id")}))
                    client.pending = request
                    if client.running in ("preview", "full"):
                        client.cancel.set()  # stale: stop it between bands (a draft ends within its ~frame time)
                client.wake.set()
        except (WebSocketDisconnect, RuntimeError, KeyError):
            pass  # the page closed (or sent a binary frame: receive_text's KeyError); nothing is owed to it
        finally:
            pages.discard(websocket)
            worker.cancel()
            # A frame still rendering stops at its next band; the page's FrameCache goes with the Client (nothing
            # else holds it once that frame's thread lets go of it).
            client.cancel.set()
            client.executor.shutdown(wait=False, cancel_futures=True)
            client.references.shutdown(wait=False, cancel_futures=True)
            if client.reference_task is not None:
                client.reference_task.cancel()

    pages: set[WebSocket] = set()   # the open pages, told when the scene file changes
    watcher: list[asyncio.Task] = []  # the one task watching it, while a page is open

    async def watch() -> None:
        """Re-read the scene file when it changes, while a page is open: each page gets the new hello (and keeps
        its own settings over it), or the file's one-line message while it is invalid (the old scene stays)."""
        path, seen = source.watched, version(source.watched)
        while pages:
            await asyncio.sleep(WATCH_EVERY)
            now = version(path)
            if now == seen or now is None:  # gone: an editor between its delete and its write, or removed
                continue
            seen = now
            try:
                fresh = await asyncio.get_running_loop().run_in_executor(None, open_source, path)
            except (SceneError, ViewError, OSError, ValueError) as error:
                message = {"type": "error", "id": None,
                           "message": f"{error} (the page keeps the scene as it was until the file is valid)"}
            else:
                source.data = fresh.data  # scene_with copies it per request: a running render is unaffected
                message = {**hello(source), "warming": False, "reloaded": True}
            for page in list(pages):
                with suppress(Exception):  # a page closing meanwhile: nothing is owed to it
                    await page.send_text(json.dumps(message))

    def loaded(request: dict) -> dict:
        """A scene file the page opened, as the settings that make it; milliseconds, so on the event loop."""
        text, name = request.get("text"), request.get("name") or "scene.toml"
        try:
            if not isinstance(text, str) or not isinstance(name, str):
                raise ViewError("load: text and name must be strings")
            name = Path(name).name  # a name for messages only: nothing is read from the disk by it
            return {"type": "loaded", "id": request.get("id"), "settings": settings_from(source, text, name)}
        except (ViewError, SceneError) as error:
            return {"type": "error", "id": request.get("id"), "message": str(error)}

    async def work(websocket: WebSocket, client: Client) -> None:
        loop = asyncio.get_running_loop()
        with suppress(Exception):  # the kernels first (compiled once, shared); a failed warm-up shows in the frame
            await asyncio.wrap_future(app.state.warming)
        while True:
            await client.wake.wait()
            client.wake.clear()
            save, request = client.pending_save, client.pending
            client.pending_save = client.pending = None
            if save is not None:
                saved = await answer(websocket, save, client.executor, renderer.save, save, client.cache)
                if saved is not None:
                    await websocket.send_bytes(saved)
            if request is None:
                continue
            if request.get("quality", "full") == "draft":
                steps = ["draft"]  # no hop to the render thread to be told so
            else:  # a preview first if a scene asks for several samples: its scenes are validated to know
                steps = await answer(websocket, request, client.executor, renderer.steps, request)
            for step in steps or ():
                if step != steps[0] and client.pending is not None:
                    break  # a newer request came while the preview rendered: the full frame is stale
                client.cancel.clear()
                client.running = step
                told = progress_to(websocket, loop, request.get("id"))
                reply = await answer(websocket, request, client.executor, renderer.frame, request, told, client.shown,
                                     client.cache, client.cancel.is_set, step)
                client.running = None
                if reply is None:
                    break
                await websocket.send_bytes(reply)
            else:
                if steps and steps[-1] == "full" and request.get("reference"):
                    client.reference_next = request  # latest wins here too
                    if client.reference_task is None or client.reference_task.done():
                        client.reference_task = asyncio.create_task(measure(websocket, client))

    async def answer(websocket: WebSocket, request: dict, executor: ThreadPoolExecutor, job: Callable,
                     *args) -> Any:
        """job(*args) on the page's render thread; a refusal, a cancellation or our own bug is told to the page
        in one line (and None returned), so the page's socket keeps serving."""
        try:
            return await asyncio.get_running_loop().run_in_executor(executor, job, *args)
        except RenderCancelled as stop:  # a newer request made it stale: the page knows, it sent that one
            message = {"type": "cancelled", "id": request.get("id"), "done": stop.done, "of": stop.total}
        except (ViewError, SceneError, rp.ImageError) as error:
            message = {"type": "error", "id": request.get("id"), "message": str(error)}
        except Exception as error:  # noqa: BLE001 — our bug: say so on the page in one line and keep serving
            message = {"type": "error", "id": request.get("id"),
                       "message": f"internal error: {type(error).__name__}: {error}"}
        await websocket.send_text(json.dumps(message))
        return None

    async def measure(websocket: WebSocket, client: Client) -> None:
        """The exact errors of the newest full frame, on their own thread: the reference costs several frames'
        time, and the next frame must not wait for it."""
        loop = asyncio.get_running_loop()
        while client.reference_next is not None:
            # Start only once the page has rested a moment: a drag that goes on makes it stale before it starts.
            await asyncio.sleep(REFERENCE_REST)
            if client.pending is not None:
                continue  # a newer frame is on its way, and brings its own reference request
            request, client.reference_next = client.reference_next, None
            try:
                errors = await loop.run_in_executor(client.references, renderer.errors, request, client.shown)
            except Exception as error:  # noqa: BLE001 — the frame was fine; say why its errors are missing and go on
                errors = {"type": "error", "id": request.get("id"), "message": f"exact reference: {error}"}
            if errors is not None:
                await websocket.send_text(json.dumps(errors))

    routes = [Route("/", index), Mount("/static", app=static), WebSocketRoute("/socket", socket)]
    app = Starlette(routes=routes)
    app.add_middleware(Guard, hosts=hosts, any_host=any_host)
    app.state.executor, app.state.renderer = executor, renderer
    # Load or compile every kernel the page can ask for (float32 and float64 shading, shadow rays) before
    # it asks: a first switch to float64 used to wait ~35 s for numba mid-session. The page shows
    # "preparing the renderer" while this runs (hello's `warming`); the first frame queues behind it.
    app.state.warming = executor.submit(warm, source)
    return app


REFERENCE_REST = 0.3  # seconds without a newer request before the exact errors of a full frame are computed


def lowest_priority() -> None:
    """Run this thread (the exact-error reference's) at nice 19: Linux schedules threads one by one, so the
    render's threads, at the server's own priority, get the cores first while a reference runs beside them."""
    if hasattr(os, "setpriority"):
        with suppress(OSError):  # not allowed or not supported: the reference then competes as before
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)


def warm(source: Source) -> None:
    """warm_kernels for both precisions with shadows, then one draft frame (geometry, BVH and the PNG path)."""
    from raycast_phong.renderer.frame import warm_kernels
    warm_kernels((np.float32, np.float64))
    rp.render(draft_of(scene_with(source, {})), source=source.name)


PROGRESS_EVERY = 0.1  # seconds between progress messages: the page's bar moves smoothly, the socket stays quiet


def progress_to(websocket: WebSocket, loop: asyncio.AbstractEventLoop, request_id) -> Callable[[float], None]:
    """A progress callback for the render thread: sends {"type": "progress", "id", "done": 0..1} to the page
    through the event loop, at most every PROGRESS_EVERY seconds."""
    last = [0.0]

    def told(share: float) -> None:
        now = time.perf_counter()
        if now - last[0] >= PROGRESS_EVERY and share < 1:
            last[0] = now
            message = json.dumps({"type": "progress", "id": request_id, "done": round(share, 3)})
            asyncio.run_coroutine_threadsafe(websocket.send_text(message), loop)
    return told


def host_of(header: str) -> str:
    """The host name in a Host header or an origin's authority, without the port, lower case: `[::1]:8765` →
    `::1`, `localhost:8765` → `localhost`; "" when it is malformed (an IPv6 address without brackets)."""
    header = header.strip().lower()
    if header.startswith("["):
        return header[1:header.index("]")] if "]" in header else ""
    if header.count(":") > 1:
        return ""
    return header.split(":", 1)[0]


class Guard:
    """ASGI middleware: refuse a Host the server was not asked for (DNS rebinding; 400, or the socket closed),
    and give every response the headers that keep the page to itself: a Content-Security-Policy (own scripts,
    styles and socket only; framed only by local pages, so a notebook can embed it), no referrer (the URL
    holds the token), no MIME sniffing."""

    def __init__(self, app, hosts: set[str], any_host: bool):
        self.app, self.hosts, self.any_host = app, hosts, any_host

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        host = dict(scope["headers"]).get(b"host", b"").decode("latin-1")
        if not (host_of(host) and (self.any_host or host_of(host) in self.hosts)):
            if scope["type"] == "websocket":
                return await send({"type": "websocket.close", "code": 1008})
            return await PlainTextResponse("400: this server does not answer to that host name\n",
                                           status_code=400)(scope, receive, send)
        policy = ("default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
                  f"connect-src 'self' blob: ws://{host}; base-uri 'none'; form-action 'none'; "
                  "frame-ancestors 'self' http://localhost:* http://127.0.0.1:* http://[::1]:*")
        extra = [(b"content-security-policy", policy.encode("latin-1")), (b"referrer-policy", b"no-referrer"),
                 (b"x-content-type-options", b"nosniff")]

        async def with_headers(message):
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)
        await self.app(scope, receive, with_headers)


def cookie_name(connection) -> str:
    return COOKIE.format(port=connection.url.port or 80)


def parse(text: str) -> dict:
    """One page message: a JSON table with type 'render', 'save' or 'load', bounded in size."""
    if len(text) > MAX_MESSAGE_BYTES:
        raise ViewError(f"message of {len(text)} characters; allowed: at most {MAX_MESSAGE_BYTES}")
    try:
        request = json.loads(text)
    except json.JSONDecodeError as error:
        raise ViewError(f"message is not JSON: {error}") from None
    except (RecursionError, ValueError) as error:  # nested thousands deep, an `id` of 5000 digits
        raise ViewError(f"message: {syntax_limit(error)}") from None
    if not isinstance(request, dict) or request.get("type", "render") not in ("render", "save", "load"):
        raise ViewError("message must be a table with type 'render', 'save' or 'load'")
    return request


def hello(source: Source) -> dict:
    """What the page needs to build its controls: the scene's own settings and the choices it offers."""
    from raycast_phong.tools.accuracy import refined
    from raycast_phong.tools.reference import ExactScene
    scene = rp.validate_scene(copy.deepcopy(source.data), source=source.name, folder=source.folder)
    try:
        ExactScene(scene, source.name)
        analytic = True
    except SceneError:
        analytic = False
    levels = {}
    for level in LEVELS:
        levels[level] = {f"objects.{i}.{key}": value for i, obj in enumerate(scene.objects)
                         for key, value in refined(obj, level).items()}
    used = sorted({obj.material for obj in scene.objects})
    return {"type": "hello", "source": source.name, "analytic": analytic, "levels": levels,
            "scene": scene.model_dump(mode="json", exclude={"folder"}), "materials": used,
            "material_values": {name: scene.material_of(next(o for o in scene.objects if o.material == name))
                                .model_dump(mode="json") for name in used}}
