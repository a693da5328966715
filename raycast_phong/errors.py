"""Every exception the package raises on purpose, defined here once, in one tree:

    RaycastPhongError                   the base: `except RaycastPhongError` catches every refusal
    ├── InputError (ValueError)         bad input; the CLI prints one line and exits 2
    │   ├── SceneError                  a scene, a mesh file or a scene key the renderer refuses
    │   │   └── Problem                 said without where: the boundary that knows the scene key adds it
    │   │       └── FileProblem         a mesh file's own problem
    │   ├── OptionError                 a command-line option that cannot be honoured (--scheduler
    │   │                               without Dask, or a cluster that does not answer)
    │   ├── CorruptManifest             a batch folder's manifest.json that is no manifest of this version
    │   └── ViewError                   a live-view request that cannot be applied (shown on the page)
    ├── OutputError (OSError)           an output that cannot be made; the CLI prints one line and exits 2
    │   ├── WriteError                  a write that failed whole (full disk, a size limit): the old file stays
    │   ├── ImageError                  an image that cannot be written or read back, or a bad output path
    │   └── BatchFolderError            a batch folder whose manifest or lock cannot be read or made
    │       └── BatchBusy               a batch folder another batch is writing into (its lock is held)
    ├── EngineError (RuntimeError)      the engine underneath failed; an internal error, exit 1
    │   └── EmbreeError                 Embree's library could not be loaded, or reported an error
    └── RenderCancelled                 render(cancelled=...) was told to stop: its caller wants another frame

Outside the tree, on purpose: tools.batch.Interrupted, a KeyboardInterrupt carrying a batch's report when
SIGINT or SIGTERM stops it; it stays a BaseException so no `except Exception` swallows the signal.

Each branch also derives from the built-in class its kind of failure is (SceneError is a ValueError,
WriteError an OSError), so an `except ValueError` or `except OSError` catches it too.
"""

from __future__ import annotations


class RaycastPhongError(Exception):
    """The base of every exception the package raises on purpose."""


class InputError(RaycastPhongError, ValueError):
    """Input the program refuses: the message is one line naming the file or option, the key and what is allowed."""


Where = object  # where a problem is: a values.messages.Location, or any value whose str() says it


class SceneError(InputError):
    """A scene the renderer refuses: the message is one line naming file, key and what is allowed.

    `where` is where the problem is: a values.messages.Location (the file, the key path), which words itself, or
    None when `problem` is the whole line. The line is `where: problem`.
    """

    def __init__(self, problem: str, where: Where | None = None):
        self.problem, self.where = problem, where
        super().__init__(problem if where is None else f"{where}: {_once(problem, str(where))}")


SHOWN_NAME_CHARACTERS = 100  # a file name echoed in a message: its start and its end, never 5,000 characters


def shortened(text: str) -> str:
    """`text` (a quoted file name) for a one-line message: a long one keeps its first and last
    SHOWN_NAME_CHARACTERS / 2 characters (the folder it starts in, the file it ends with) and says how many it
    leaves out."""
    half = SHOWN_NAME_CHARACTERS // 2
    if len(text) <= SHOWN_NAME_CHARACTERS:
        return text
    return f"{text[:half]}…({len(text) - 2 * half:,} characters)…{text[-half:]}"


def _once(problem: str, where: str) -> str:
    """`problem` with its own quoted copy of `where` (a mesh file's path, when the file is what was given; a long
    one as io.files.shown_name shortens it) said once: the line starts with `where:` already."""
    quoted = repr(where)
    if quoted not in problem:
        quoted = shortened(quoted)
        if quoted not in problem:
            return problem
    problem = next((problem[len(start):] for start in (f"{quoted}: ", f"{quoted} ") if problem.startswith(start)),
                   problem)
    if problem.endswith(f" {quoted}"):  # "no such mesh file 'm.obj'" at m.obj: "m.obj: no such mesh file"
        problem = problem[:-len(quoted) - 1]
    return problem.replace(quoted, "the file")


class Problem(SceneError):
    """A problem said without where it is (a shape's, a mesh reader's): the one boundary that knows the scene
    key (geometry.templates.object_mesh, io.meshes.read.read_file) raises it again as a SceneError there, so
    no function below is handed a `where` to thread through. Uncaught, it is still one line."""


class FileProblem(Problem):
    """A problem of the mesh file being read (io.meshes.read.read_file places it at the file's scene key)."""


class OptionError(InputError):
    """A command-line option the program cannot honour; the message names the option."""


class CorruptManifest(InputError):
    """DIR/manifest.json exists but is not a batch manifest this version can read."""


class ViewError(InputError):
    """A request the live view refuses; the message is one line, shown on the page."""


class OutputError(RaycastPhongError, OSError):
    """An output that cannot be made; the message names the path."""


class WriteError(OutputError):
    """An output that could not be written whole; the message names it, the OS reason and the old file's state."""


class ImageError(OutputError):
    """An image that cannot be written or read; the message names the path."""


class BatchFolderError(OutputError):
    """A batch output folder whose manifest or lock cannot be read, moved aside or created."""


class BatchBusy(BatchFolderError):
    """A batch output folder another batch holds (flock on DIR/.batch.lock); the message names its process."""


class EngineError(RaycastPhongError, RuntimeError):
    """The engine underneath (Embree, the compiled kernels) failed: an internal error, not the input's."""


class EmbreeError(EngineError):
    """Embree reported an error (the kernel layer's own class is to derive from this one)."""


class RenderCancelled(RaycastPhongError):
    """A render stopped between two bands because its `cancelled()` said so (a live view's newer request made
    the frame stale); `done` of `total` bands were rendered. Neither an input's fault nor an engine's."""

    def __init__(self, done: int, total: int):
        super().__init__(f"cancelled after {done} of {total} bands")
        self.done, self.total = done, total
