"""`raycast-phong view`: a local page that re-renders one scene as a person changes its settings.

The page sends settings as {dotted scene key: value}; each is applied to the scene file's table with
scene.apply_override and the whole checked by validate_scene, exactly as `render --set` does, so a
bad value is answered with the CLI's one-line message. Frames are rendered by rp.render on the server's render
threads (session.py: at most one job of each page at a time) and sent back as PNG (image_io.write_image, the CLI's
own 8-bit encoding), or a draft as the same 8-bit values raw (RGBA rows, when the page asks: it paints them into
a canvas, nothing to decode). Each page keeps a FrameCache: its frames reuse the geometry and the committed BVH,
rebuilding only what a change touched (a light move rebuilds nothing). At rest a frame of several samples a pixel
is refined: a preview of one sample, then the full frame; a newer request cancels that full frame between two
bands. A full request (a release) is never coalesced away by a later draft, nor its first full-size frame cancelled.

Security (access.py): a random token opens the page once and is then a Strict, HttpOnly cookie (the permalink
holds settings only); the socket's Origin must be the page's; only files inside static/ are served;
page values are data for the scene schema only (never code, never a file path); one client holds
at most one running render, one waiting draft and one waiting full request (latest wins in each; a newer request
cancels a running refinement, the full frame after a preview).
"""

from __future__ import annotations

import copy
import errno
import json
import math
import re
import struct
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from starlette.applications import Starlette
from starlette.routing import Mount, Route, WebSocketRoute

import raycast_phong as rp
from raycast_phong.codes import OUTPUT_PATH, ShadingModel
from raycast_phong.errors import SceneError, ViewError
from raycast_phong.io.encoding import DISPLAY, display_values
from raycast_phong.io.scene_file import syntax_limit
from raycast_phong.io.scene_toml import scene_toml, toml_value
from raycast_phong.renderer.kernels.layout import MAX_LIGHTS
from raycast_phong.scene.load import is_mesh_file, read_scene_dict
from raycast_phong.scene.overrides import apply_override
from raycast_phong.values.messages import dotted

from .access import Access, Guard, host_of
from .session import MAX_MESSAGE_BYTES, MAX_SCENE_BYTES, Client, View, frame_budget  # noqa: F401 (Client: the tests')

if TYPE_CHECKING:
    from raycast_phong.renderer.reuse import FrameCache

MAX_SETTINGS = 256            # keys per request: far more than the page has controls
MAX_VIEW_RAYS = 1920 * 1080 * 16  # rays per frame: ~2 s here; a larger frame is a batch job, not a view
DRAFT_PIXELS = 320 * 180  # a draft's pixels at most: a 640×360 frame's, whose drafts paint in 33-45 ms
LEVELS = range(7)          # tessellation levels the page offers (reference.refined: level 6 = 81,920 faces)
# Lights per scene: each is shaded at every hit, so 2,500 held a render thread over a minute at the largest frame. The
# view allows what global mode can (renderer.kernels.layout.MAX_LIGHTS, 63): the page's mode switch always applies.
MAX_VIEW_LIGHTS = MAX_LIGHTS


# ---------------------------------------------------------------- scenes from page settings

@dataclass
class Opened:
    """The scene the view was started with: its parsed table, the name errors use, its folder, and the scene
    file the server watches (None for a mesh file, which render() itself reads anew when it changes)."""
    data: dict
    name: str
    folder: Path
    watched: Path | None = None
    files: dict[tuple, str] = field(default_factory=dict)  # Scene.named_files(): the only files a page may use


def open_scene(path: str | Path | None) -> Opened:
    """A scene file (.toml/.json), a mesh file (mesh_scene: framed by a camera and lit by a key light), or the
    default scene; validated now, so a bad file is refused before the server starts."""
    path = Path(path) if path is not None else rp.default_scene_path()
    opened = Opened(read_scene_dict(path), str(path), path.parent, None if is_mesh_file(path) else path)
    opened.files = scene_with(opened, {}).named_files()
    return opened


KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z0-9_-]+))*")
# The page never changes a file path: a mesh or texture path would let a page make the server read (or probe
# for) any file. These keys are refused by name; a path set any other way (a whole material or object table)
# is caught by comparing the validated scene's named_files with the opened scene's, before any file is opened.
PATH_KEYS = re.compile(r"(objects\.\d+\.path|materials\.[^.]+\.k[ade]_map(\.path)?|output(\..*)?|folder)")


def scene_with(opened: Opened, settings: dict) -> rp.Scene:
    """The opened scene with the page's settings applied and validated, as `render --set KEY=VALUE` would."""
    if not isinstance(settings, dict):
        raise ViewError("settings must be a table of KEY.PATH: value")
    if len(settings) > MAX_SETTINGS:
        raise ViewError(f"settings: {len(settings)} keys; allowed: at most {MAX_SETTINGS}")
    data = copy.deepcopy(opened.data)
    for key, value in settings.items():
        if not KEY.fullmatch(key):
            raise ViewError(f"{opened.name}: {key!r} is not a key path; expected names and list indices joined "
                            "by dots, e.g. render.width")
        if PATH_KEYS.fullmatch(key):
            raise ViewError(f"{opened.name}: {key}: the view does not change file paths or outputs; edit the "
                            "scene file instead")
        apply_override(data, f"{key}={toml_value(value)}", source=opened.name)
    scene = rp.validate_scene(data, source=opened.name, folder=opened.folder)
    if settings:
        named = scene.named_files()
        moved = next((key for key in named if opened.files.get(key) != named[key]), None)
        if moved is not None:
            raise ViewError(f"{opened.name}: {dotted(moved)}: the view does not change file paths or outputs; "
                            "edit the scene file instead")
    if len(scene.lights) > MAX_VIEW_LIGHTS:
        raise ViewError(f"{opened.name}: lights: {len(scene.lights):,} lights; allowed: 0 to {MAX_VIEW_LIGHTS} in the "
                        "view; render it with `raycast-phong render` instead")
    opts = scene.render
    if opts.width * opts.height * opts.samples ** 2 > MAX_VIEW_RAYS:
        raise ViewError(f"{opened.name}: render.samples: {opts.width}×{opts.height} pixels × {opts.samples}² "
                        f"samples is more than the view's {MAX_VIEW_RAYS:,} rays per frame; render it with "
                        "`raycast-phong render` instead")
    return scene


def draft_of(scene: rp.Scene) -> rp.Scene:
    """The frame shown while dragging: one sample, no layers, a quarter of the pixels (half each side), and at
    most DRAFT_PIXELS: a larger frame's draft is scaled down on both sides alike and shown upscaled, so it costs
    what a 640×360 frame's does (a 1280×720 frame's half-size drafts took 91-138 ms on the page)."""
    opts = scene.render
    width, height = (opts.width + 1) // 2, (opts.height + 1) // 2
    if width * height > DRAFT_PIXELS:
        scale = math.sqrt(DRAFT_PIXELS / (opts.width * opts.height))
        width, height = max(1, int(opts.width * scale)), max(1, int(opts.height * scale))
    draft = opts.model_copy(update={"width": width, "height": height, "samples": 1})
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


def settings_from(opened: Opened, text: str, name: str) -> dict:
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
    theirs = rp.validate_scene(data, source=name, folder=opened.folder)
    def dump(scene: rp.Scene) -> dict:  # paths and outputs are compared apart
        table = leaves(scene.model_dump(mode="json", exclude={"folder"}))
        return {key: value for key, value in table.items() if not PATH_KEYS.fullmatch(key)}

    ours = scene_with(opened, {})
    for kind in ("objects", "lights"):
        if len(getattr(theirs, kind)) != len(getattr(ours, kind)):
            raise ViewError(f"{name}: {len(getattr(theirs, kind))} {kind}, this view's scene has "
                            f"{len(getattr(ours, kind))}; open it with `raycast-phong view {name}` instead")
    mine, other = ours.named_files(), theirs.named_files()

    def where(files: dict, key: tuple) -> Path | None:
        """The file a key names, its links followed; one that cannot be followed (a symlink loop: RuntimeError on
        Python 3.11, OSError later) is refused in one line naming it, not a dropped socket."""
        try:
            return None if key not in files else (opened.folder / files[key]).resolve()
        except (OSError, RuntimeError) as error:
            loop = not isinstance(error, OSError) or error.errno == errno.ELOOP
            why = "a symlink loop" if loop else error.strerror or str(error)
            raise ViewError(f"{name}: {dotted(key)}: {files[key]}: {why}") from None

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
        made = dump(scene_with(opened, settings))
    except (SceneError, ViewError) as error:  # the format's refusal, or the view's own limits
        raise ViewError(f"{name}: these settings do not apply to this view's scene: {error}") from None
    if made != wanted:
        differs = sorted(key for key in wanted.keys() | made.keys() if made.get(key) != wanted.get(key))
        raise ViewError(f"{name}: {', '.join(differs[:3])} cannot be set from the page; open it with "
                        f"`raycast-phong view {name}` instead")
    return settings


# ---------------------------------------------------------------- frames

def encode(image: np.ndarray, suffix: str, aovs: dict | None = None, colour: str = DISPLAY) -> bytes:
    """An image rendered in `colour` as the bytes of the file `raycast-phong render -o x.png|.exr` would write
    (OpenImageIO, ~0.5 s to import, loaded with the first frame rather than before the page is served)."""
    from raycast_phong.io.image_io import image_bytes
    return image_bytes(image, suffix, aovs, colour)


def rgba_bytes(image: np.ndarray, colour: str = DISPLAY) -> bytes:
    """A draft's pixels as the page paints them into its canvas (ImageData: rows of R, G, B, A, top row first):
    the 8-bit values the PNG would hold (encoding.to_8bit), opaque. No compression: a 320×180 draft is 230 kB on
    a local socket, and the page neither inflates nor decodes it (a PNG's decode through an <img> costs ~18 ms of
    a draft's ~100 ms on the page)."""
    from raycast_phong.io.encoding import to_8bit
    rgb8 = to_8bit(image, colour)
    rgba = np.full((*rgb8.shape[:2], 4), 255, np.uint8)
    rgba[..., :3] = rgb8
    return rgba.tobytes()


PIXELS = ("png", "rgba")  # how a frame's panels are sent: PNG files, or raw RGBA rows (the page's, from this machine)


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


MAX_SPHERES = 64  # objects whose bounding spheres a frame names; past that, one sphere round them all


def object_spheres(cache: FrameCache, objects: int) -> list[list[float]]:
    """[x, y, z, radius] of each object's bounding sphere in the newest frame's geometry (the values the plan's
    diagnosis keeps in the cache), or one round them all past MAX_SPHERES: the page's near limit, so that a
    zoom stops outside the object it walks towards."""
    from raycast_phong.renderer.diagnosis import ObjectFigures
    geometry = cache.geometry
    if geometry is None or not len(geometry.faces):
        return []
    centre, radius = ObjectFigures(geometry, objects, cache.derived(geometry)).bounds()
    used = radius > 0
    centre, radius = centre[used], radius[used]
    if len(radius) > MAX_SPHERES:
        low, high = (centre - radius[:, None]).min(axis=0), (centre + radius[:, None]).max(axis=0)
        middle = (low + high) / 2
        centre, radius = middle[None], np.array([float(np.max(np.linalg.norm(centre - middle, axis=1) + radius))])
    return [[round(float(x), 6) for x in (*c, r)] for c, r in zip(centre, radius)]


def analytic(scene: rp.Scene) -> bool:
    """Whether the exact surfaces (reference.ExactScene) cover the scene: no mesh file, so errors() can measure it."""
    from raycast_phong.tools.reference import ExactScene
    try:
        ExactScene(scene)
    except SceneError:
        return False
    return True


def left_out(plan) -> list[dict]:
    return [{"name": s.name, "reason": s.reason} for s in plan.stages if not s.kept]


def session_render(session: rp.Renderer | None, scene: rp.Scene, **options) -> rp.RenderResult:
    """session.render(scene, ...), or a one-off session's (rp.render) where there is none."""
    return session.render(scene, **options) if session is not None else rp.render(scene, **options)


@dataclass
class Replies:
    """Turns one request into one reply; runs on the view's worker thread."""
    opened: Opened
    # session_render; a test may wrap it (to hold a render while it sends more)
    render: Callable[..., Any] = None
    budget: int | None = None  # each frame's memory budget (session.frame_budget); None: no limit known

    def __post_init__(self):
        self.render = self.render or session_render

    def scenes(self, request: dict) -> dict[str, rp.Scene]:
        """The validated scenes of a render request: A, and B to compare (or A's three shading models)."""
        quality = request.get("quality", "full")
        if quality not in ("draft", "full"):
            raise ViewError(f"quality: {quality!r}; allowed: 'draft' or 'full'")
        scenes = {"a": scene_with(self.opened, settings_of(request))}
        if request.get("models"):
            # The lecture's figure: A in flat, Gouraud and Phong shading, as panels a, b and c.
            from raycast_phong.scene.overrides import shaded
            scenes = dict(zip("abc", (shaded(scenes["a"], model) for model in ShadingModel)))
        elif request.get("compare") is not None:
            scenes["b"] = scene_with(self.opened, settings_of(request, "compare"))
        return scenes

    def steps(self, request: dict) -> list[str]:
        """The qualities a request is rendered at, in order: a draft; or at rest the full frame, after a preview
        of one sample a pixel when a scene asks for more (refined: the image comes at once, the samples after)."""
        if request.get("quality", "full") == "draft":
            return ["draft"]
        many = any(scene.render.samples > 1 for scene in self.scenes(request).values())
        return ["preview", "full"] if many else ["full"]

    def frame(self, request: dict, session: rp.Renderer | None = None,
              progress: Callable[[float], None] | None = None, shown: dict | None = None,
              cancelled: Callable[[], bool] | None = None, step: str | None = None) -> bytes:
        """Render settings A (and B, to compare) at the requested quality (or at `step`, one of steps()); the
        PNGs, the heat map, the figures. `session` is the page's renderer (its FrameCache keeps the geometry and
        BVH between its frames; its bands run on the server's band threads); `progress(share)` is told the
        share of the tiles done, 0..1 over A and B together; `shown` (the page's own table) keeps (request id,
        RenderResult) of its last full frame A for errors(); `cancelled()` answering True stops the frame between
        bands (RenderCancelled)."""
        started = time.perf_counter()
        scenes = self.scenes(request)
        quality = step or request.get("quality", "full")
        pixels = request.get("pixels", "png")
        if pixels not in PIXELS:
            raise ViewError(f"pixels: {pixels!r}; allowed: 'png' or 'rgba'")
        raw = pixels == "rgba"  # the page asks so for every frame from this machine (capture then asks a save)
        header: dict = {"type": "frame", "id": request.get("id"), "quality": quality,
                        "pixels": "rgba" if raw else "png"}
        shaped = SHAPED[quality]
        parts, images, stats = [], {}, {}
        for k, (name, scene) in enumerate(scenes.items()):
            told = None
            if progress is not None:
                told = lambda done, total, k=k: progress((k + done / max(total, 1)) / len(scenes))
            result = self.render(session, shaped(scene), progress=told, cancelled=cancelled)
            if name == "a" and quality == "full" and not request.get("models") and shown is not None:
                shown["a"] = (request.get("id"), result)  # errors() measures this image, not a new one
            images[name] = display_values(result.image, result.colour)  # A and B compared as shown
            parts.append((name, rgba_bytes(result.image, result.colour) if raw
                          else encode(result.image, ".png", colour=result.colour)))
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
        if session is not None and session.cache is not None:
            header["spheres"] = object_spheres(session.cache, len(scenes["a"].objects))
        header["seconds"] = time.perf_counter() - started
        return pack(header, parts)

    def errors(self, request: dict, shown: dict | None = None) -> dict | None:
        """RMSE, max error and highlight loss of A against the exact surfaces; None for a mesh scene. The image
        measured is the page's last full frame (`shown`, as frame() kept it) if it is this request's."""
        from raycast_phong.tools.accuracy import measured
        scene = frame_of(scene_with(self.opened, settings_of(request)))
        if not analytic(scene):
            return None
        shown_id, image = (shown or {}).get("a", (None, None))
        if shown_id != request.get("id"):
            image = self.render(rp.Renderer(max_memory=self.budget), scene)
        result = measured(scene, image, "analytic", 2)
        e = result.errors
        finite = lambda x: None if x is None or not math.isfinite(x) else x  # JSON has no nan or inf
        return {"type": "errors", "id": request.get("id"), "rmse": finite(e.rmse), "max_error": finite(e.max_error),
                "psnr": finite(e.psnr), "highlight_loss": finite(e.highlight_loss),
                "seconds": result.reference_seconds}

    def save(self, request: dict, session: rp.Renderer | None = None) -> bytes:
        """The current settings as a scene file (toml), or the full-resolution image (png, exr with layers);
        `session`: the page's renderer, whose geometry and BVH the image may reuse."""
        what = request.get("what")
        scene = scene_with(self.opened, settings_of(request))
        side = request.get("side", "a")
        if side not in ("a", "b"):
            raise ViewError(f"save: side {side!r}; allowed: 'a' or 'b'")
        stem = f"{Path(self.opened.name).stem or 'scene'}-view-{side.upper()}"  # which setting it is
        if what == "toml":
            data = scene_toml(scene).encode("utf-8")
        elif what in ("png", "exr"):
            result = self.render(session, scene if what == "exr" else frame_of(scene))
            data = encode(result.image, f".{what}", result.aovs if what == "exr" else None, result.colour)
        else:
            raise ViewError(f"save: {what!r}; allowed: 'toml', 'png' or 'exr'")
        return pack({"type": "saved", "id": request.get("id"), "what": what, "filename": f"{stem}.{what}"},
                    [("file", data)])


# ---------------------------------------------------------------- the app

def create_app(opened: Opened, token: str, origins: list[str], *, render: Callable | None = None,
               executor: ThreadPoolExecutor | None = None, any_host: bool = False,
               max_memory: int | None = None) -> Starlette:
    """The view's Starlette app. `origins` are the page's own (scheme://host:port); the socket accepts no other.
    `any_host` (served on 0.0.0.0 or ::): any Host name, and then the socket's Origin must be that host's page.
    `executor` runs the warm-up (tests pass one); the pages' frames run on the server's own render threads.
    `max_memory`: the server's memory budget in bytes (default: 3/4 of the memory available now), shared by the
    frames that may render at once (session.frame_budget)."""
    access = Access(token, on_page=lambda: view.start_warming())
    renderer = Replies(opened, render, frame_budget(max_memory))
    view = View(opened, renderer, access, origins, any_host, hello, open_scene,
                lambda request: loaded(opened, request))
    routes = [Route("/", access.index), Route("/access", access.access), Mount("/static", app=access.static),
              WebSocketRoute("/socket", view.socket)]
    app = Starlette(routes=routes)
    hosts = {host_of(o.split("://", 1)[1]) for o in origins}
    app.add_middleware(Guard, hosts=hosts, any_host=any_host, access=access)
    executor = executor or ThreadPoolExecutor(max_workers=1, thread_name_prefix="view-warm")
    app.state.executor, app.state.renderer, app.state.view = executor, renderer, view
    # Load or compile every kernel the page can ask for (float32 and float64 shading, shadow rays) before
    # it asks, or a first switch to float64 waits ~35 s for numba mid-session. The page shows
    # "preparing the renderer" while this runs (hello's `warming`); the first frame queues behind it.
    # It starts once the first page is served (the HTML first), or within a second if none comes.
    app.state.warming = view.prepare(executor, lambda: warm(opened))
    return app


def loaded(opened: Opened, request: dict) -> dict:
    """A scene file the page opened, as the settings that make it; milliseconds, so on the event loop."""
    text, name = request.get("text"), request.get("name") or "scene.toml"
    try:
        if not isinstance(text, str) or not isinstance(name, str):
            raise ViewError("load: text and name must be strings")
        name = Path(name).name  # a name for messages only: nothing is read from the disk by it
        size = len(text.encode("utf-8", "surrogatepass"))
        if size > MAX_SCENE_BYTES:
            raise ViewError(f"{name}: {size:,} bytes; a scene file the page opens is at most {MAX_SCENE_BYTES:,} bytes")
        return {"type": "loaded", "id": request.get("id"), "settings": settings_from(opened, text, name)}
    except (ViewError, SceneError) as error:
        return {"type": "error", "id": request.get("id"), "message": str(error)}
    except Exception as error:  # noqa: BLE001 — our bug: one line on the page, and its socket keeps serving
        return {"type": "error", "id": request.get("id"), "message": f"internal error: {type(error).__name__}: {error}"}


def warm(opened: Opened) -> None:
    """warm_kernels for both precisions with shadows, then one draft frame (geometry, BVH and the PNG path)."""
    from raycast_phong.renderer.frame import warm_kernels
    warm_kernels((np.float32, np.float64))
    rp.render(draft_of(scene_with(opened, {})))


def hello(opened: Opened) -> dict:
    """What the page needs to build its controls: the scene's own settings, the choices it offers and the sizes
    the server takes (the page refuses a larger file or message in one line rather than have its socket closed)."""
    from raycast_phong.tools.accuracy import refined
    scene = rp.validate_scene(copy.deepcopy(opened.data), source=opened.name, folder=opened.folder)
    levels = {level: {f"objects.{i}.{key}": value for i, obj in enumerate(scene.objects)
                      for key, value in refined(obj, level).items()} for level in LEVELS}
    used = sorted({obj.material for obj in scene.objects})
    return {"type": "hello", "source": opened.name, "analytic": analytic(scene), "levels": levels,
            "scene": scene.model_dump(mode="json", exclude={"folder"}), "materials": used,
            "limits": {"scene_bytes": MAX_SCENE_BYTES, "message_bytes": MAX_MESSAGE_BYTES},
            "material_values": {name: scene.material_of(next(o for o in scene.objects if o.material == name))
                                .model_dump(mode="json") for name in used}}
