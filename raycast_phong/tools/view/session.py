"""The view's socket: each page's session (its queue, its frames, its exact errors) and the scene file's watcher.

Split by job: `Client` is one page's state; `View` owns what the pages share (the opened scene, the renderer, the
server's render and reference threads, the open pages) and answers a socket; `Session` runs one page (its
receive loop, its render loop, its reference loop); `Watcher` re-reads the scene file while a page is open.
Work is bounded per server: every page's frames run on the server's FRAME_THREADS threads and its exact
references on REFERENCE_THREADS, whatever the number of pages; each page keeps at most one job on them, and
the frame threads take the cheapest and the oldest job by turns (frame_queue.py).
"""

from __future__ import annotations

import asyncio
import json
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from starlette.websockets import WebSocket, WebSocketDisconnect

import raycast_phong as rp
from raycast_phong.errors import RenderCancelled, SceneError, ViewError
from raycast_phong.io.files import present_version
from raycast_phong.io.scene_file import syntax_limit

from .access import Access
from .frame_queue import COST, FrameQueue

if TYPE_CHECKING:
    from raycast_phong.renderer.prepare import Renderer
    from raycast_phong.renderer.reuse import FrameCache

FRAME_THREADS = 2       # frames rendered at once by one server, over all its pages (each frame uses every core)
# The frames' bands run on the server's band threads (io.system.default_threads(): the cores, at most 8), kept
# for its life and shared by its frames: a pool started for every frame would wait 1-2 ms for its threads.
REFERENCE_THREADS = 1   # exact references at once (at nice 19: they use what the frames leave)
REFERENCE_REST = 0.3    # seconds without a newer request before the exact errors of a full frame are computed
WATCH_EVERY = 0.5       # seconds between looks at the scene file: an edit shows within a second, the disk idle
GONE_AFTER = 2.0        # a scene file missing this long is said to be gone (an editor's save replaces it faster)
MAX_SCENE_BYTES = 60_000     # a scene file the page opens (`load`), in UTF-8 bytes: docs/view.md's 60 kB
# A page message: a render request is a few hundred bytes of settings; a load carries its scene escaped as JSON,
# at worst 6 bytes a byte (a control character is \u0001), so a scene of MAX_SCENE_BYTES always fits. The socket
# takes twice as much (SOCKET_MAX_BYTES), so that a message past this limit gets parse's one line, not a close.
MAX_MESSAGE_BYTES = 1 << 19
SOCKET_MAX_BYTES = 2 * MAX_MESSAGE_BYTES  # uvicorn's ws_max_size: larger messages close the socket (1009) unread
PROGRESS_EVERY = 0.1    # seconds between progress messages: the page's bar moves smoothly, the socket stays quiet
SAVES_WAITING = 2       # saves a page may have waiting (capture asks for the image and the scene at once)
WARM_AFTER = 1.0        # seconds after the app is made that the kernels' warm-up starts if no page came first


def lowest_priority() -> None:
    """Run this thread (the exact-error reference's) at nice 19: Linux schedules threads one by one, so the
    render's threads, at the server's own priority, get the cores first while a reference runs beside them."""
    if hasattr(os, "setpriority"):
        with suppress(OSError):  # not allowed or not supported: the reference then competes as before
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)


def frame_cache() -> FrameCache:
    """A page's FrameCache; imported when a page opens, so that the server answers before numba is loaded."""
    from raycast_phong.renderer.reuse import FrameCache
    return FrameCache()


def page_renderer(bands: ThreadPoolExecutor, budget: int | None) -> Renderer:
    """A page's renderer session: its FrameCache (the geometry and BVH its frames share, released with the
    page), its frames' bands on the server's band threads, each frame within `budget` (frame_budget)."""
    from raycast_phong.renderer.prepare import Renderer
    return Renderer(max_memory=budget, pool=bands, cache=frame_cache())


def frame_budget(max_memory: int | None) -> int | None:
    """The memory budget of each frame the server renders: the server's (`view --max-memory`, else 3/4 of the
    memory available when it starts) shared by the FRAME_THREADS frames that may render at once, over all its
    pages; None where the platform tells nothing. A page's scene over it is refused on the page in one line."""
    from raycast_phong.io.system import budget_of
    budget = budget_of(max_memory)
    return None if budget is None else budget // FRAME_THREADS


def frame_threads() -> FrameQueue:
    return FrameQueue(FRAME_THREADS, "view-render")


def band_threads() -> ThreadPoolExecutor:
    from raycast_phong.io.system import default_threads
    return ThreadPoolExecutor(default_threads(), "view-bands")


def reference_threads() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(REFERENCE_THREADS, "view-reference", initializer=lowest_priority)


@dataclass
class Client:
    """One socket's queue: at most one waiting draft (latest wins) and one waiting committed frame (a full
    request: a release, a key, a field; the newest wins, and a draft never replaces it), two waiting saves, one
    waiting reference; the threads its frames and references run on (the server's, shared by every page); its
    last full frame A (for the exact errors: request ids are each page's own); its renderer session (its
    FrameCache, the bands on the server's threads); and the quality being rendered with the event that cancels
    it, and whether it may be cancelled (a committed request's first full-size frame may not)."""
    pending: dict | None = None               # the newest waiting draft
    committed: dict | None = None             # the newest waiting full request: rendered before a waiting draft
    running: str | None = None                # the quality of the frame being rendered ("draft", "preview", "full")
    cancellable: bool = False                 # the running frame is a refinement a newer request makes stale
    cancel: threading.Event = field(default_factory=threading.Event)  # set: the running frame stops between bands
    saves: deque = field(default_factory=lambda: deque(maxlen=SAVES_WAITING))  # the newest saves asked for
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    dropped: int = 0
    asked_at: float = 0.0                     # time.monotonic() of the page's newest render request
    reference_next: dict | None = None        # the newest full frame whose exact errors are still owed
    reference_task: asyncio.Task | None = None
    executor: FrameQueue = field(default_factory=frame_threads)  # the server's frame threads, cheapest or oldest first
    bands: ThreadPoolExecutor = field(default_factory=band_threads)  # the bands of its frames (the server's)
    references: ThreadPoolExecutor = field(default_factory=reference_threads)
    shown: dict = field(default_factory=dict)
    budget: int | None = None                 # each frame's memory budget (frame_budget: the server's share)
    _renderer: Renderer | None = None

    @property
    def renderer(self) -> Renderer:
        """The page's renderer session, made at its first frame or save (after the kernels' warm-up has
        imported the renderer), so that the server answers before numba is loaded."""
        if self._renderer is None:
            self._renderer = page_renderer(self.bands, self.budget)
        return self._renderer

    @property
    def waiting(self) -> bool:
        """Whether a draft or a committed frame waits to be rendered."""
        return self.pending is not None or self.committed is not None


class View:
    """What every page of one server shares, and the socket's entry point."""

    def __init__(self, opened, renderer, access: Access, origins: list[str], any_host: bool,
                 hello: Callable[[Any], dict], open_scene: Callable, loaded: Callable[[dict], dict]):
        self.opened, self.renderer, self.access = opened, renderer, access
        self.origins, self.any_host = origins, any_host
        self.hello, self.loaded = hello, loaded
        self.frames, self.bands, self.references = frame_threads(), band_threads(), reference_threads()
        self.pages: set[WebSocket] = set()   # the open pages, told when the scene file changes
        self.watcher = Watcher(self, open_scene)
        self.warming: Future | None = None    # the kernels' warm-up: a page's first frame waits for it
        self._warm: tuple[ThreadPoolExecutor, Callable[[], None]] | None = None
        self._lock = threading.Lock()

    def prepare(self, executor: ThreadPoolExecutor, job: Callable[[], None]) -> Future:
        """Run `job` (the kernels' warm-up: numba's import and every kernel loaded or compiled) on `executor`
        once: when the first page is served or a socket opens, or WARM_AFTER seconds from now, whichever is
        first, not at once: it holds the GIL, which the page's HTML would wait for. `warming` is its Future."""
        self.warming, self._warm = Future(), (executor, job)
        self.warming.set_running_or_notify_cancel()  # running from now on: a page that waits cannot cancel it
        timer = threading.Timer(WARM_AFTER, self.start_warming)
        timer.daemon = True
        timer.start()
        return self.warming

    def start_warming(self) -> None:
        with self._lock:
            if self._warm is None:
                return
            (executor, job), self._warm = self._warm, None
        try:
            started = executor.submit(job)
        except RuntimeError as error:  # the server stopped first
            self.warming.set_exception(error)
            return
        started.add_done_callback(self._warmed)

    def _warmed(self, done: Future) -> None:
        if done.cancelled():
            self.warming.set_exception(RuntimeError("the warm-up was cancelled: the server is stopping"))
        elif done.exception() is not None:
            self.warming.set_exception(done.exception())
        else:
            self.warming.set_result(done.result())

    def allowed(self, websocket: WebSocket) -> bool:
        origin = websocket.headers.get("origin")
        own = self.any_host and origin == f"http://{websocket.headers.get('host', '')}"  # the page of its host
        return self.access.authorised(websocket) and (origin in self.origins or own)

    def greeting(self) -> dict:
        """hello, with whether the kernels are still being prepared and the scene file's standing problem."""
        return {**self.hello(self.opened), "warming": self.warming is not None and not self.warming.done(),
                "problem": self.watcher.problem}

    async def socket(self, websocket: WebSocket) -> None:
        if not self.allowed(websocket):
            # Refused before the handshake completes (the browser sees 1006); the page asks /access why.
            await websocket.close(code=1008)
            return
        await websocket.accept()
        self.start_warming()
        await Session(self, websocket).run()

    def shutdown(self) -> None:
        """Stop the render, band and reference threads: waiting jobs are dropped, idle threads end at once; a
        frame still running ends at its band (its bands not started are cancelled)."""
        self.frames.shutdown(wait=False, cancel_futures=True)
        self.bands.shutdown(wait=False, cancel_futures=True)
        self.references.shutdown(wait=False, cancel_futures=True)


class Session:
    """One page: its receive loop (requests queued, latest wins), its render loop and its reference loop."""

    def __init__(self, view: View, websocket: WebSocket):
        self.view, self.websocket = view, websocket
        self.client = Client(executor=view.frames, bands=view.bands, references=view.references,
                             budget=view.renderer.budget)

    async def send(self, message: dict) -> None:
        await self.websocket.send_text(json.dumps(message))

    async def run(self) -> None:
        view, client = self.view, self.client
        view.pages.add(self.websocket)
        view.watcher.start()
        await self.send(view.greeting())
        worker = asyncio.create_task(self.work())
        try:
            while True:
                text = await self.websocket.receive_text()
                try:
                    request = parse(text)
                except ViewError as error:
                    await self.send({"type": "error", "id": getattr(error, "id", None), "message": str(error)})
                    continue
                if request.get("type") == "load":
                    await self.send(view.loaded(request))
                elif request.get("type") == "save":
                    client.saves.append(request)
                else:
                    await self.queue(request)
                client.wake.set()
        except (WebSocketDisconnect, RuntimeError, KeyError):
            pass  # the page closed (or sent a binary frame: receive_text's KeyError); nothing is owed to it
        finally:
            view.pages.discard(self.websocket)
            worker.cancel()
            # A frame still rendering stops at its next band; the page's FrameCache goes with the Client (nothing
            # else holds it once that frame's thread lets go of it). The threads are the server's: they stay.
            client.cancel.set()
            if client.reference_task is not None:
                client.reference_task.cancel()

    async def queue(self, request: dict) -> None:
        """Latest wins, but a committed frame is never coalesced away: a newer draft replaces only the waiting
        draft (the committed frame waiting goes first: it is older), a newer full request replaces both. A
        running refinement (the samples after a preview) is cancelled between bands, and so is a running draft
        when a full request comes (a release's frame waits for no stale draft, nor does the page paint one); a
        committed request's first full-size frame is not (every release is answered by a full frame, even when
        the next stroke starts at once; a draft waits for it, ~one frame's time)."""
        client = self.client
        client.asked_at = time.monotonic()
        full = request.get("quality", "full") != "draft"
        stale = [client.pending, client.committed] if full else [client.pending]
        for old in stale:
            if old is not None:
                client.dropped += 1
                await self.send({"type": "dropped", "id": old.get("id")})
        client.pending = None
        if full:
            client.committed = request
        else:
            client.pending = request
        if client.cancellable or (full and client.running == "draft"):
            client.cancel.set()  # stale: stop it between bands

    def next_request(self) -> dict | None:
        """The committed frame waiting, else the draft waiting (the committed one is always the older)."""
        client = self.client
        if client.committed is not None:
            request, client.committed = client.committed, None
        else:
            request, client.pending = client.pending, None
        return request

    async def work(self) -> None:
        view, client, renderer = self.view, self.client, self.view.renderer
        loop = asyncio.get_running_loop()
        with suppress(Exception):  # the kernels first (compiled once, shared); a failed warm-up shows in the frame
            if view.warming is not None:
                await asyncio.shield(asyncio.wrap_future(view.warming))
        while True:
            await client.wake.wait()
            client.wake.clear()
            request = self.next_request()
            if client.waiting:
                client.wake.set()  # a draft waits behind the committed frame: this loop comes back for it
            while client.saves:
                save = client.saves.popleft()
                saved = await self.answer(save, client.executor.at(COST["full"]), renderer.save, save,
                                          client.renderer)
                if saved is not None:
                    await self.websocket.send_bytes(saved)
            if request is None:
                continue
            if request.get("quality", "full") == "draft":
                steps = ["draft"]  # no hop to the render thread to be told so
            else:  # a preview first if a scene asks for several samples: its scenes are validated to know
                steps = await self.answer(request, client.executor.at(COST["check"]), renderer.steps, request)
            for step in steps or ():
                if step != steps[0] and client.waiting:
                    break  # a newer request came while the preview rendered: the full frame is stale
                client.cancel.clear()
                client.running = step
                # A draft ends within its ~frame time, and a committed request's first frame must be shown: only
                # a refinement (the samples after a preview) is cancelled by a newer request.
                client.cancellable = step != steps[0]
                told = progress_to(self.websocket, loop, request.get("id"))
                reply = await self.answer(request, client.executor.at(COST[step]), renderer.frame, request,
                                          client.renderer, told, client.shown, client.cancel.is_set, step)
                client.running, client.cancellable = None, False
                if reply is None:
                    break
                await self.websocket.send_bytes(reply)
            else:
                if steps and steps[-1] == "full" and request.get("reference"):
                    client.reference_next = request  # latest wins here too
                    if client.reference_task is None or client.reference_task.done():
                        client.reference_task = asyncio.create_task(self.measure())

    async def answer(self, request: dict, executor: Executor, job: Callable, *args) -> Any:
        """job(*args) on a render thread; a refusal, a cancellation or our own bug is told to the page in one
        line (and None returned), so the page's socket keeps serving."""
        try:
            return await asyncio.get_running_loop().run_in_executor(executor, job, *args)
        except RenderCancelled as stop:  # a newer request made it stale: the page knows, it sent that one
            message = {"type": "cancelled", "id": request.get("id"), "done": stop.done, "of": stop.total}
        except (ViewError, SceneError, rp.ImageError) as error:
            message = {"type": "error", "id": request.get("id"), "message": str(error)}
        except Exception as error:  # noqa: BLE001 — our bug: say so on the page in one line and keep serving
            message = {"type": "error", "id": request.get("id"),
                       "message": f"internal error: {type(error).__name__}: {error}"}
        await self.send(message)
        return None

    async def measure(self) -> None:
        """The exact errors of the newest full frame, on the reference threads: the reference costs several
        frames' time, and the next frame must not wait for it."""
        client, loop = self.client, asyncio.get_running_loop()
        while client.reference_next is not None:
            # Start only once the page has rested a moment: a drag that goes on makes it stale before it starts.
            # Rested: no request for REFERENCE_REST seconds and no frame running (nothing waiting is not enough: a
            # drag keeps one draft in flight and none waiting, and a reference costs ~30 % of the server's CPU).
            await asyncio.sleep(max(0.05, client.asked_at + REFERENCE_REST - time.monotonic()))
            if client.waiting or client.running is not None or time.monotonic() - client.asked_at < REFERENCE_REST:
                continue  # a newer frame is on its way (a full one brings its own reference request)
            request, client.reference_next = client.reference_next, None
            try:
                errors = await loop.run_in_executor(client.references, self.view.renderer.errors, request,
                                                    client.shown)
            except Exception as error:  # noqa: BLE001 — the frame was fine; say why its errors are missing and go on
                errors = {"type": "error", "id": request.get("id"), "message": f"exact reference: {error}"}
            if errors is not None:
                await self.send(errors)


class Watcher:
    """Re-reads the scene file when it changes, while a page is open: each page gets the new hello (and keeps
    its own settings over it, dropping those that no longer apply), or the file's one-line message while it is
    invalid (the old scene stays). The message stands (`problem`, told to pages that open meanwhile) until
    the file is valid again."""

    def __init__(self, view: View, open_scene: Callable):
        self.view, self.open_scene = view, open_scene
        self.task: asyncio.Task | None = None
        self.problem: str | None = None

    def start(self) -> None:
        if self.view.opened.watched is not None and (self.task is None or self.task.done()):
            self.task = asyncio.create_task(self.watch())

    async def watch(self) -> None:
        view = self.view
        path, seen = view.opened.watched, present_version(view.opened.watched)
        gone = 0.0  # seconds the file has been missing
        while view.pages:
            await asyncio.sleep(WATCH_EVERY)
            now = present_version(path)
            if now is None:  # an editor between its delete and its write, or removed: said once it stays away
                gone += WATCH_EVERY
                if gone < GONE_AFTER or seen is None:
                    continue
                seen = None
                self.problem = (f"{path.name}: the scene file is gone (deleted or moved); the page keeps the scene "
                                "as it was until the file is back")
                message = {"type": "error", "id": None, "file": True, "message": self.problem}
            elif now == seen:
                gone = 0.0
                continue
            else:
                gone, seen = 0.0, now
                message = await self.reread(path)
            for page in list(view.pages):
                with suppress(Exception):  # a page closing meanwhile: nothing is owed to it
                    await page.send_text(json.dumps(message))

    async def reread(self, path: Path) -> dict:
        """The file read again: the new hello for every page, or the one-line message of what is wrong with it."""
        view = self.view
        try:
            fresh = await asyncio.get_running_loop().run_in_executor(None, self.open_scene, path)
        except (SceneError, ViewError, OSError, ValueError) as error:
            self.problem = f"{error} (the page keeps the scene as it was until the file is valid)"
            return {"type": "error", "id": None, "file": True, "message": self.problem}
        view.opened.data, view.opened.files = fresh.data, fresh.files  # scene_with copies per request
        self.problem = None
        return {**view.greeting(), "reloaded": True}


def parse(text: str) -> dict:
    """One page message: a JSON table with type 'render', 'save' or 'load', bounded in size."""
    size = len(text.encode("utf-8", "surrogatepass"))  # bytes, as the socket and the page count them
    if size > MAX_MESSAGE_BYTES:
        raise ViewError(f"message of {size:,} bytes; allowed: at most {MAX_MESSAGE_BYTES:,}")
    try:
        request = json.loads(text)
    except json.JSONDecodeError as error:
        raise ViewError(f"message is not JSON: {error}") from None
    except (RecursionError, ValueError) as error:  # nested thousands deep, an `id` of 5000 digits
        raise ViewError(f"message: {syntax_limit(error)}") from None
    if not isinstance(request, dict) or request.get("type", "render") not in ("render", "save", "load"):
        refused = ViewError("message must be a table with type 'render', 'save' or 'load'")
        refused.id = request.get("id") if isinstance(request, dict) else None  # the page matches the answer by it
        raise refused
    return request


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
