"""The one decorator for compiled kernels: numba's njit, cached under a key of the sources each kernel compiles in.

numba's on-disk cache checks only the source file a function is defined in, but a kernel compiles in
the helpers it calls from other modules (illumination.py's `diffuse_terms`, `specular_terms` inside shading's
`_shade_rays`): edit illumination.py and the cached `_shade_rays` would keep running the old model.
So each kernel module (a .py file here that uses `@kernel`) is cached in a folder of its own, named after a hash
of its text and of the package modules it imports, transitively: an edit starts fresh folders for the modules
that read the edited one, and only those (an edit to illumination.py recompiles shading.py's kernels, not the
tile's, the camera's or the mesh preparation's); stale folders are removed. Only numba's documented cache
directory setting (`numba.config.CACHE_DIR`, the NUMBA_CACHE_DIR variable) is used, set for the moment a kernel
is decorated and restored at once, so other numba code in the process is unaffected.
Each kernel's cache is numba's own with a lighter load (`_CacheLoadedAsIs`: no typing or lowering registries
for a kernel that is already compiled, nor imports of the numba modules whose implementations it holds), or
numba's unchanged where its internals differ.

The fast paths on numba's internals, each with its plain fallback, behind one switch (PLAIN:
RAYCAST_PHONG_PLAIN_NUMBA=1 turns every one off; each is also off by itself where what it relies on is missing):
  LIGHT_LOAD   a cached kernel loaded without numba's registries       else numba's own load
  NRT_CACHED   numba's runtime functions loaded from the cache too      else compiled in each process
  LINK_LAZILY  a cached kernel's bitcode parsed only to link it          else parsed at each load
  BY_ADDRESS   a callee handed to its caller by address (`callee`)     else the dispatcher, linked into the caller
  two processes for a first compile (renderer/split_compile.py)        else one (it relies on both above)
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import os
import pickle
import re
import shutil
import sys
import tempfile
import weakref
from collections.abc import Callable
from functools import cache, lru_cache
from pathlib import Path

from .compiles import compiled, compiling


@contextlib.contextmanager
def _unimportable(name: str):
    """Within the block, `import name` raises ImportError (sys.modules[name] is None), unless it is imported already;
    as it was after. How numba's import and its set-up are kept from modules they would import for nothing."""
    blocked = name not in sys.modules
    if blocked:
        sys.modules[name] = None
    try:
        yield
    finally:
        if blocked and sys.modules.get(name, False) is None:
            del sys.modules[name]


# numba's import imports PyYAML (9 ms of a 0.55 s start-up) to read a .numba_config.yaml in the working folder:
# only where there is one. (A compile reads that file again: one made later, elsewhere, would get numba's warning.)
NUMBA_CONFIG = ".numba_config.yaml"
with contextlib.nullcontext() if os.path.isfile(NUMBA_CONFIG) else _unimportable("yaml"):
    import numba
    from numba import njit, typeof, types
    from numba.core import environment
    from numba.core.caching import FunctionCache, NullCache
    from numba.core.codegen import JITCodeLibrary, JITCPUCodegen, JitEngine
    from numba.core.compiler_lock import global_compiler_lock
    from numba.core.runtime import nrtdynmod
    from numba.core.runtime.nrt import rtsys

PACKAGE = Path(__file__).resolve().parent  # raycast_phong/: a kernel may import from anywhere in it
OWN_CACHE = PACKAGE / "__pycache__"
MARK = "@kernel("          # how a module declares a kernel; such a module is cached under its own key
CACHE = "raycast-phong-kernels"  # the cache under its base: a folder <module>-<key> per kernel module
OUTSIDE = "outside."       # the folders of kernels defined outside the package (a test's, a user's)
NRT_PREFIX = "nrt-"        # the files of numba's NRT functions, one per numba, llvmlite and CPU (initialise_nrt)
RELATIVE_IMPORT = re.compile(rb"^from (\.+)([\w.]*) import (\([^)]*\)|[^\n]*)", re.MULTILINE)


@lru_cache(maxsize=1)
def kernel_keys() -> dict[str, str]:
    """Each kernel module's key, by its dotted name in the package (`renderer.kernels.shading`): sha256 (16 hex
    digits) of numba's version and of the text of the module and of every package module it imports, transitively
    (a kernel also freezes in the constants it reads, e.g. tolerances.py, and compiles in the helpers it calls)."""
    texts = {path: path.read_bytes() for path in PACKAGE.rglob("*.py")}
    imported: dict[Path, list[Path]] = {}

    def imports(importer: Path) -> list[Path]:
        """The package modules `importer` imports, read off its relative imports ("from .x import …",
        "from ..x.y import …", "from . import x, y"): parsing every module with ast would cost 10× more at
        each start-up."""
        if importer not in imported:
            found = []
            for dots, module, names in RELATIVE_IMPORT.findall(texts[importer]):
                folder = importer.parents[len(dots) - 1]
                for target in [module] if module else re.findall(rb"\w+", names):
                    base = folder.joinpath(*target.decode().split("."))
                    found += [path for path in (base.with_suffix(".py"), base / "__init__.py") if path in texts]
            imported[importer] = found
        return imported[importer]

    keys = {}
    for module, text in texts.items():
        if MARK.encode() not in text or module.name == "jit.py":
            continue
        read, pending = {module}, [module]
        while pending:
            for path in imports(pending.pop()):
                if path not in read:
                    read.add(path)
                    pending.append(path)
        digest = hashlib.sha256(numba.__version__.encode())
        for path in sorted(read):
            digest.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0" + texts[path] + b"\0")
        keys[_dotted(module)] = digest.hexdigest()[:16]
    return keys


def _dotted(module: Path) -> str:
    return ".".join(module.relative_to(PACKAGE).with_suffix("").parts)


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


@lru_cache(maxsize=1)
def cache_folder() -> Path | None:
    """The kernel cache, holding a folder per kernel module and key (`kernel_folder`): under NUMBA_CACHE_DIR if
    the user set one, else the package's __pycache__, else the user's cache folder, else a private folder in the
    temporary folder; None if none is writable (kernels then compile per process).
    In the package's own __pycache__, folders of other keys are removed: they belong to sources of this tree that
    no longer exist (a shared folder may hold other installs' keys, so it is left alone)."""
    for base in _bases():
        folder = base / CACHE
        if _writable(folder):
            if base == OWN_CACHE:
                _remove_stale(folder)
            return folder
    return None


def _bases():
    """Where the cache may go, in order (the private temporary folder made only if it comes to that)."""
    if numba.config.CACHE_DIR:  # NUMBA_CACHE_DIR
        yield Path(numba.config.CACHE_DIR)
    yield OWN_CACHE
    with contextlib.suppress(RuntimeError):  # no home folder known at all
        user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        if user.parent.is_dir():  # never made: a missing home folder (a user whose HOME is gone)
            yield user / "raycast-phong"
    private = _private_temporary()  # last: a read-only install and home would otherwise compile every run
    if private is not None:
        yield private


def _remove_stale(folder: Path) -> None:
    """Remove the folders of keys this tree no longer has (and the cache as it was laid out before, one folder
    for all kernels, named after a key of them all)."""
    current = {f"{name}-{key}" for name, key in kernel_keys().items()}
    stale = list(folder.parent.glob(f"{CACHE}-*"))
    stale += [path for path in folder.iterdir()
              if path.name not in current and not path.name.startswith((OUTSIDE, NRT_PREFIX))]
    for path in stale:
        shutil.rmtree(path, ignore_errors=True)  # another process may be removing it too


@cache
def kernel_folder(module_file: Path) -> Path | None:
    """The cache folder of the kernel module `module_file` (made if need be); None if there is no cache. A kernel
    defined outside the package gets a folder of its own file (numba checks that file)."""
    root = cache_folder()
    if root is None:
        return None
    try:
        name = _dotted(module_file)
        folder = root / f"{name}-{kernel_keys()[name]}"
    except (ValueError, KeyError):  # not a kernel module of the package
        key = hashlib.sha256(numba.__version__.encode() + str(module_file).encode()).hexdigest()[:16]
        folder = root / f"{OUTSIDE}{module_file.stem}-{key}"
    return folder if _writable(folder) else None


def _private_temporary() -> Path | None:
    """raycast-phong-<uid> in the temporary folder, made 0700 and used only if this user owns it and no one
    else can write it (numba's cache holds code that is loaded: another user's folder must never be used)."""
    with contextlib.suppress(OSError, AttributeError):  # AttributeError: no getuid (Windows)
        base = Path(tempfile.gettempdir()) / f"raycast-phong-{os.getuid()}"
        base.mkdir(mode=0o700, exist_ok=True)
        info = os.lstat(base)
        import stat
        if stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid() and not info.st_mode & 0o022:
            return base
    return None


def kernel(**options):
    """njit(cache=True, nogil=True, error_model="numpy", **options), cached in `cache_folder()`.

    error_model="numpy": a division by zero gives inf/nan as numpy would, instead of a Python exception
    check in every division of the hot loop.
    """
    def decorate(function):
        folder = kernel_folder(Path(function.__code__.co_filename).resolve())
        settings = {"nogil": True, "error_model": "numpy", **options}
        if folder is None:
            set_up()  # every first call compiles: numba's registries load then, without the BLAS probe
            dispatcher = njit(cache=False, **settings)(function)
            dispatcher._cache = _NothingCached(function)  # each first call compiles, and is told so
            return dispatcher
        previous = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = str(folder)  # read once, when njit makes the function's cache locator
        try:
            dispatcher = njit(cache=True, **settings)(function)
            if isinstance(getattr(dispatcher, "_cache", None), FunctionCache):
                dispatcher._cache = _CacheLoadedAsIs(function)  # same folder, same files: only the load differs
            if not LIGHT_LOAD:
                set_up()  # numba's own load refreshes the registries: without the BLAS probe
            return dispatcher
        finally:
            numba.config.CACHE_DIR = previous
    return decorate


PLAIN = os.environ.get("RAYCAST_PHONG_PLAIN_NUMBA", "").strip() == "1"  # every fast path off (module docstring)
# The numba internals _CacheLoadedAsIs relies on (checked with numba 0.68); without them numba's own load is kept.
LIGHT_LOAD = not PLAIN and (
    all(hasattr(FunctionCache, name) for name in ("_load_overload", "_guard_against_spurious_io_errors"))
    and all(hasattr(environment, name) for name in ("_rebuild_env", "lookup_environment"))
    and isinstance(getattr(environment.Environment, "_memo", None), dict | weakref.WeakValueDictionary))
# What a cached kernel's linking bitcode is left unparsed through (_LinkedWhenAsked); without them numba parses it.
LINK_LAZILY = LIGHT_LOAD and (
    all(hasattr(JITCodeLibrary, name) for name in ("_unserialize", "_get_module_for_linking", "_set_compiled_object",
                                                    "enable_object_caching", "_finalize_final_module"))
    and isinstance(getattr(JITCPUCodegen, "_library_class", None), type) and hasattr(JitEngine, "is_symbol_defined"))
# What the NRT's functions come from the cache through (initialise_nrt); without them numba compiles them.
NRT_CACHED = LIGHT_LOAD and (all(hasattr(nrtdynmod, name) for name in ("compile_nrt_functions", "create_nrt_module"))
                             and isinstance(getattr(rtsys, "_init", None), bool))
# numba's first-class function type (numba.experimental), which ByAddress hands callees through.
BY_ADDRESS = not PLAIN and importlib.util.find_spec("numba.experimental.function_type") is not None


class _CacheLoadedAsIs(FunctionCache):
    """numba's cache of one kernel, loading a cached kernel without numba's typing and lowering registries.

    numba's Cache.load_overload first refreshes the target context — imports some 50 implementation modules
    (typed dict/list/set, random, datetime, polynomial, linalg, …) and installs their typing and lowering
    registries: 0.15–0.25 s at a process's first call, the largest part of a warm start-up. A cached kernel
    needs none of it: it is object code, linked against numba's C helpers (installed with the target context),
    the NRT (initialised here, as the refresh would) and the symbols its unpickled payload brings (its
    reload_init and referenced modules). What does need the registries is compiling: on a miss this returns
    None and numba's compiler refreshes the context itself (compiler.py) before typing the kernel — after
    set_up(), so the BLAS probe is still skipped."""

    def load_overload(self, sig, target_context):
        loaded = self._checked_load(sig, target_context)
        if loaded is None and LIGHT_LOAD:
            wait = compiled_elsewhere.pop(kernel_name(self._py_func), None)
            if wait is not None:  # another process is compiling this kernel into the cache: wait, then load it
                wait()
                loaded = self._checked_load(sig, target_context)
        if loaded is None:
            set_up()  # numba is about to compile (and load its registries)
            compiling(kernel_name(self._py_func), sig)
        return loaded

    def save_overload(self, sig, data):
        with self._locked(exclusive=True):
            super().save_overload(sig, data)
        compiled()  # the compile told by load_overload is done (compiles.seconds_compiling)

    @contextlib.contextmanager
    def _locked(self, exclusive: bool):
        """This kernel's cache entries held against other processes: numba names a new entry's data file by the
        index it read (the next free number), so two processes compiling two signatures at once (pytest's
        workers, the split compile's helper) both wrote `.1.nbc` and left one signature's index entry pointing at
        the other's code: every later call failed with numba's "can't unbox array". Writers take the lock
        alone, loads share it. Where files cannot be locked (no fcntl, a read-only cache) nothing is held."""
        try:
            import fcntl
            index = Path(self._cache_file._index_path)
            handle = open(index.parent / f"{index.stem}-lock", "a+b")  # not `stem.*`: drop() leaves it
        except (ImportError, OSError, AttributeError):
            yield
            return
        with handle:
            with contextlib.suppress(OSError):  # a file system without locks: as numba alone
                fcntl.flock(handle, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
            yield

    def _checked_load(self, sig, target_context):
        """The cached kernel for `sig`, or None. The cache is input like any file: an entry that cannot be loaded
        (truncated, empty, random bytes, another version's) is removed, so the kernel compiles over it, and a
        corrupt cache never breaks every later render."""
        try:
            with self._locked(exclusive=False):
                loaded = super().load_overload(sig, target_context) if not LIGHT_LOAD else \
                    self._light_load(sig, target_context)
        except Exception:  # noqa: BLE001 - whatever the bytes make the unpickler or numba raise
            self.drop()
            return None
        found = getattr(getattr(loaded, "signature", None), "args", None)
        if loaded is not None and found is not None and tuple(found) != tuple(sig):
            self.drop()  # an entry whose code is another signature's (written by a race, or swapped): compile over
            return None
        return loaded

    def drop(self) -> None:
        """Remove this kernel's cache entry: its index and data files (numba writes them afresh on the compile)."""
        index = Path(self._cache_file._index_path)
        for path in index.parent.glob(f"{index.stem}.*"):
            with contextlib.suppress(OSError):  # another process removed or replaced it
                path.unlink()

    def _light_load(self, sig, target_context):
        """The cached kernel for `sig`, loaded without numba's registries, or None."""
        initialise_nrt(target_context)  # what numba's refresh starts with (cpu.py); idempotent
        # numba holds this lock around every load and compile; taken again (it is re-entrant) so that the
        # unpickler's environment rebuild is swapped for this load alone, whoever calls.
        with global_compiler_lock, self._guard_against_spurious_io_errors():  # numba's own (Windows: busy file)
            rebuild, environment._rebuild_env = environment._rebuild_env, _environment_as_is
            codegen = target_context.codegen()
            if LINK_LAZILY:  # the libraries this load makes: the kernel's bitcode parsed only if a compile links it
                codegen._library_class, _LinkedWhenAsked.folder = _LinkedWhenAsked, self.cache_path
            try:
                return self._load_overload(sig, target_context)
            finally:
                environment._rebuild_env = rebuild
                if LINK_LAZILY:
                    del codegen._library_class  # numba's class attribute again
                    _LinkedWhenAsked.folder = None

    def holds(self, sig, target_context) -> bool:
        """Whether the cache has an entry for `sig`, or for any signature when `sig` is None (its index only:
        nothing is loaded)."""
        index = self._cache_file._load_index()
        return bool(index) if sig is None else index.get(self._index_key(sig, target_context.codegen())) is not None


# Kernels (kernel_name) another process is compiling into the cache, each with a function that returns once it is
# done (or gave up): a miss for one waits for it and loads the result instead of compiling (split_compile.py). Taken
# out at the first miss, so a kernel is waited for once; if it is still missing then, it compiles here as usual.
compiled_elsewhere: dict[str, Callable[[], object]] = {}


def kernel_name(function) -> str:
    """module.qualified_name of a kernel (its dispatcher or its Python function)."""
    function = getattr(function, "py_func", function)
    return f"{function.__module__}.{function.__qualname__}"


def cached(dispatcher, arguments: tuple | None = None) -> bool:
    """Whether `dispatcher` has code for these arguments' types (None: for any signature), in the process or in its
    cache (True also when that cannot be told: the caller then simply goes on as if it were). Only the cache's
    index is read: nothing is loaded."""
    signature = None if arguments is None else tuple(typeof(argument) for argument in arguments)
    if dispatcher.overloads if signature is None else signature in dispatcher.overloads:
        return True
    cache = getattr(dispatcher, "_cache", None)
    if not isinstance(cache, _CacheLoadedAsIs) or not LIGHT_LOAD:
        return True
    try:
        return cache.holds(signature, dispatcher.targetctx)
    except Exception:  # noqa: BLE001 - numba's internals moved, or a corrupt index: behave as if cached (the load
        return True    # then removes a corrupt entry and compiles)


def callee(dispatcher, arguments: tuple, returns=None):
    """`dispatcher` as another kernel receives it to call, for these arguments' types (example values) returning
    `returns` (a numba type; None: nothing): by address (ByAddress) where numba's first-class functions are there,
    else the dispatcher itself, which numba links into the caller (its code generated again in the caller's
    compile, and the caller not cached: numba caches no kernel that takes a dispatcher)."""
    return ByAddress(dispatcher, arguments, returns) if BY_ADDRESS else dispatcher


def ready(handle) -> None:
    """Load (or compile) now a callee handed by address (`callee`); a linked one compiles with its caller."""
    if isinstance(handle, ByAddress):
        handle.ready()


class ByAddress:
    """A kernel handed to another kernel as an argument and called there through its address (numba's first-class
    function type), for one signature: the caller's compile needs only the signature, not the callee's code.

    Called by name, a kernel is linked into its caller: numba compiles the callee first, then adds its code to
    the caller's and has LLVM optimise and generate all of it again (1.5-2 s of CPU for tile.render_band over
    shading._shade_rays), and the caller's compile must wait for the callee's. By address, the two compile
    apart (in two processes: split_compile.py) and each is generated once; the call goes through the callee's C
    wrapper, so an exception raised inside it is printed, not raised (none of the kernels called so raises).
    The address is asked when the caller is called (its argument is unpacked), which loads or compiles the
    callee then; numba reads the type from `_numba_type_`."""

    def __init__(self, dispatcher, arguments: tuple, returns=None):
        """`dispatcher` for these arguments' types (example values), returning `returns` (a numba type; None:
        nothing). The kernel's own return type is checked against it when its address is asked."""
        import numba.experimental.function_type  # noqa: F401  numba's first-class function types
        self.dispatcher = dispatcher
        self._signature = (returns or types.none)(*(typeof(argument) for argument in arguments))
        self._numba_type_ = types.FunctionType(self._signature)
        self._address: int | None = None

    def signature(self):
        return self._signature

    def __wrapper_address__(self) -> int:
        """The address of the callee's C wrapper for the signature (numba's function_type asks it)."""
        return self.ready()

    def ready(self) -> int:
        """Load (or compile) the callee for the signature; its C wrapper's address."""
        if self._address is None:
            arguments = self._signature.args  # a tuple, as a call compiles it: the cache's index key is the same
            if arguments not in self.dispatcher.overloads:
                self.dispatcher.compile(arguments)
            result = self.dispatcher.overloads[arguments]
            if result.signature.return_type != self._signature.return_type:  # the call would read garbage
                raise TypeError(f"{kernel_name(self.dispatcher)} returns {result.signature.return_type}, "
                                f"not {self._signature.return_type}")
            self._address = result.library.get_pointer_to_function(result.fndesc.llvm_cfunc_wrapper_name)
        return self._address


SYMBOLS = "symbols-"  # a cached kernel's defined symbols, by its linking bitcode's sha256 (_LinkedWhenAsked)


class _LinkedWhenAsked(JITCodeLibrary):
    """numba's code library of a kernel loaded from the cache, whose bitcode (kept beside the object code, for
    linking the kernel into a caller compiled later) is parsed only when such a compile links it. numba parses it at
    every load to learn the names the kernel defines (which its engine must know to hand out their addresses):
    loading a default render's kernels took 78 ms with it, 42 without; a small GLB's 100 and 55. The names are read
    instead from a file written at the first load (`SYMBOLS` + the bitcode's sha256, in the kernel's folder,
    _checked_write's); the library is otherwise made as numba makes it."""

    folder: str | None = None  # the folder of the kernel being loaded (set by _light_load for that load)
    _bitcode: bytes | None = None

    @classmethod
    def _unserialize(cls, codegen, state):
        name, kind, data = state
        if kind != "object" or cls.folder is None:
            return super()._unserialize(codegen, state)
        object_code, bitcode = data
        path = Path(cls.folder) / f"{SYMBOLS}{hashlib.sha256(bitcode).hexdigest()[:32]}"
        listed = _checked_read(path)  # the names, NUL between them: the one byte no LLVM name holds
        if not listed:  # numba's load, parsing the bitcode; its names kept for the next
            library = super()._unserialize(codegen, state)
            module = library._shared_module
            names = {value.name for values in (module.functions, module.global_variables) for value in values
                     if not value.is_declaration}
            _checked_write(path, "\0".join(sorted(names)).encode())
            return library
        names = set(listed.decode().split("\0"))
        library = codegen.create_library(name)
        library.enable_object_caching()
        library._set_compiled_object(object_code)
        library._bitcode = bitcode
        library._finalize_final_module()
        codegen._engine._defined_symbols |= names
        return library

    def _get_module_for_linking(self):
        if self._bitcode is not None:  # a compile links this kernel: its bitcode now, as numba would have it
            from llvmlite import binding
            self._shared_module, self._bitcode = binding.parse_bitcode(self._bitcode), None
        return super()._get_module_for_linking()


def initialise_nrt(target_context) -> None:
    """numba's rtsys.initialize, with the NRT's own functions (a small LLVM module numba compiles at a process's
    first kernel call: 15-18 ms of a 0.55 s start-up) loaded from the kernel cache as object code, as a cached
    kernel is (3 ms), when this numba has compiled them on this CPU before; otherwise compiled as numba does, and
    cached. Idempotent, as rtsys.initialize is."""
    if not NRT_CACHED or rtsys._init:
        rtsys.initialize(target_context)
        return
    with global_compiler_lock:  # numba's lock around every compile and load, held while its function is swapped
        compile_nrt = nrtdynmod.compile_nrt_functions
        nrtdynmod.compile_nrt_functions = _cached_nrt_functions  # what rtsys.initialize calls, once
        try:
            rtsys.initialize(target_context)
        finally:
            nrtdynmod.compile_nrt_functions = compile_nrt


def _cached_nrt_functions(context):
    """nrtdynmod.compile_nrt_functions' library: from the cache file of this numba, llvmlite and CPU (codegen's
    magic_tuple, which numba's own index keys a kernel on) when it holds it whole (its sha256), else compiled as
    numba compiles it, with object caching on so that it can be saved. A cache file that cannot be read or written
    only costs the compile."""
    codegen = context.codegen()
    path = _nrt_cache_file(codegen)
    payload = _checked_read(path) if path is not None else None
    if payload:
        with contextlib.suppress(Exception):  # a foreign payload, or numba refusing it: compile instead
            return codegen.unserialize_library(pickle.loads(payload))
    module, library = nrtdynmod.create_nrt_module(context)
    library.enable_object_caching()
    library.add_ir_module(module)
    library.finalize()
    if path is not None:
        _checked_write(path, pickle.dumps(library.serialize_using_object_code()))
    return library


def _checked_read(path: Path) -> bytes | None:
    """The payload of a cache file _checked_write wrote, or None if it is missing, unreadable or not whole (its
    first 32 bytes, the sha256 of the rest, do not match): the NRT's and the symbols' files."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    return data[32:] if hashlib.sha256(data[32:]).digest() == data[:32] else None


def _checked_write(path: Path, payload: bytes) -> None:
    """`payload` as the cache file `path`, after its sha256, whole or not at all (a new temporary file beside it,
    made exclusively, then renamed over it); a read-only or full cache leaves no file, and the next process
    compiles or parses again. Not io.atomic's writer, which the layers put above this module: nor is its fsync
    needed, as a file a crash cut fails its sha256 and is made again."""
    data = hashlib.sha256(payload).digest() + payload
    try:
        handle = tempfile.NamedTemporaryFile(dir=path.parent, prefix=path.name, suffix=".part", delete=False)
    except OSError:
        return
    try:
        with handle:
            handle.write(data)
        os.replace(handle.name, path)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(handle.name)


def _nrt_cache_file(codegen) -> Path | None:
    """nrt-<key>.nbc in the kernel cache, the key a hash of numba's and llvmlite's versions and codegen's
    magic_tuple (the target triple, CPU name and features); None if there is no cache."""
    root = cache_folder()
    if root is None:
        return None
    import llvmlite
    key = hashlib.sha256(repr((numba.__version__, llvmlite.__version__, codegen.magic_tuple())).encode())
    return root / f"{NRT_PREFIX}{key.hexdigest()[:16]}.nbc"


class _NothingCached(NullCache):
    """numba's cache of a kernel when no folder is writable: nothing is ever loaded, and each compile is told."""

    def __init__(self, function):
        self._py_func = function

    def load_overload(self, sig, target_context):
        compiling(kernel_name(self._py_func), sig)

    def save_overload(self, sig, data):
        compiled()


def _environment_as_is(module_name, consts, name):
    """numba's _rebuild_env for a cached kernel, without importing the module of an environment it references.

    A cached kernel's payload names the environment of every function compiled into it, numba's own
    implementations included (np.empty's in numba.np.arrayobj, min's in numba.cpython.builtins, str's in
    numba.cpython.unicode), and numba rebuilds each from its module's globals, importing the module:
    26–38 ms of a 0.6 s start-up for modules no cached kernel runs. Only object-mode code reads an environment's
    globals (pylowering); these kernels are nopython, and read only its constants, which are kept. A module
    already imported is used as numba would; otherwise the environment gets its name alone (so that it can
    still be cached, Environment.can_cache)."""
    if module_name is None or module_name in sys.modules or environment.lookup_environment(name) is not None:
        return _numba_rebuild_env(module_name, consts, name)
    rebuilt = environment.Environment({"__name__": module_name})
    rebuilt.consts[:] = consts
    rebuilt.env_name = name
    environment.Environment._memo[name] = rebuilt
    return rebuilt


_numba_rebuild_env = environment._rebuild_env


def set_up() -> None:
    """numba's one-time set-up of its CPU target (its registries of implementations, loaded at a process's first
    kernel call), without the BLAS probe numba makes there: with SciPy installed the probe imports scipy.linalg,
    0.15–0.2 s of a 0.6 s start-up, for nothing the kernels use (none calls np.dot or np.linalg).

    numba.np.arraymath asks once, at its import, whether `import scipy.linalg.cython_blas` works; scipy.linalg
    is made unimportable for that moment only, so the answer is no (numba's np.convolve/np.correlate then take
    its plain loop instead of BLAS; np.dot and np.linalg still import SciPy when a kernel uses them). Does
    nothing if numba's set-up already ran or SciPy's linalg is already imported (then the probe is free)."""
    if "numba.np.arraymath" in sys.modules:
        return
    with _unimportable("scipy.linalg"):
        import numba.np.arraymath  # noqa: F401  (the probe runs here)
