"""The syntax of a scene file: TOML, or JSON for .json, read safely into a dict (the schema judges the keys).
`-` (or /dev/stdin) reads the scene from standard input: TOML, or JSON when it starts with `{`.

Only a regular file of at most MAX_SCENE_BYTES is read, and only when its parse fits in memory (SCENE_READ_BYTES
a byte of text, under the command's --max-memory too); a JSON key given twice in one object is refused
(JSON parsers keep the last silently); every problem is one SceneError naming the file.
"""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path
from typing import Any

from ..errors import SceneError
from .files import open_regular
from .system import format_bytes, memory_allowed

MAX_SCENE_BYTES = 16 << 20  # 16 MiB: a scene is keys and numbers; 40,000 objects take about 3.5 MiB of TOML
# Memory a byte of scene text takes once parsed, the worst measured (tomllib, Python 3.11): nested empty lists
# `[[]],` 35, empty tables or lists 25, `{shape="box"},` 25, floats 11, integers 5; so a 16 MiB scene ≈ 670 MB.
SCENE_READ_BYTES = 40


def read_scene_file(path: Path, max_memory: int | None = None) -> dict:
    """Parse the file's syntax only (TOML, or JSON for .json), with a one-line error on failure; refused
    before the parse when SCENE_READ_BYTES a byte would not fit in what io.system.memory_allowed leaves."""
    path = Path(path)
    stdin = is_stdin(path)
    try:
        if stdin:  # a pipe: read to its end, one byte past the cap at most
            if sys.stdin is None:  # the program was started with stdin closed (`<&-`)
                raise SceneError("standard input is closed; pipe a scene to `-`, or give a scene file", path)
            data = sys.stdin.buffer.read(MAX_SCENE_BYTES + 1)
        else:
            with open_regular(path, str(path), "scene file", MAX_SCENE_BYTES) as handle:
                # One byte over the cap tells a file that grew after fstat from one that fits.
                data = handle.read(MAX_SCENE_BYTES + 1)
        if len(data) > MAX_SCENE_BYTES:
            raise SceneError(f"the scene is more than the {MAX_SCENE_BYTES >> 20} MiB allowed", path)
        need, allowed = len(data) * SCENE_READ_BYTES, memory_allowed(max_memory)
        if allowed is not None and need > allowed:
            raise SceneError(f"reading its {format_bytes(len(data))} of text needs ≈ {format_bytes(need)} of memory, "
                             f"more than the {format_bytes(allowed)} available; allowed: a scene whose text fits, so "
                             "split it or raise the budget (--max-memory)", path)
        if b"\0" in data[:4096] or (not data[:4096].isascii() and _not_utf8(data)):
            from .meshes import unread  # a binary file under a scene's name: say what it is, not a decode error
            reason = unread(Path(""), data[:64])
            if reason is not None:
                raise SceneError(reason, path)
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise SceneError("no such scene file", path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise SceneError(f"cannot read the scene file ({error})", path) from None
    text = text.removeprefix("\ufeff")  # a byte-order mark, as some Windows editors write, is no syntax error
    try:
        if path.suffix.lower() == ".json" or (stdin and text.lstrip("\ufeff \t\r\n").startswith("{")):
            data = json.loads(text, object_pairs_hook=_JSONObject)
            twice = _duplicate_key(data)
            if twice:
                raise SceneError(f"{'.'.join(map(str, twice))}: the key is given twice in one object (JSON "
                                 "would keep the last silently); allowed: each key once", path)
        else:
            data = tomllib.loads(text)
    except SceneError:
        raise
    except json.JSONDecodeError as error:
        where = f"line {error.lineno}, column {error.colno}"
        raise SceneError(f"JSON syntax error at {where}: {error.msg}", path) from None
    except tomllib.TOMLDecodeError as error:
        if not stdin and path.suffix.lower() not in ("", ".toml"):  # README.md, notes.txt: not a scene at all
            from .meshes import read_names
            raise SceneError(f"not a scene file (read as TOML: {error}); allowed: a scene file (.toml, .json) or "
                             f"a mesh file ({read_names()})", path) from None
        raise SceneError(f"TOML syntax error: {error}", path) from None
    except (RecursionError, ValueError) as error:
        raise SceneError(syntax_limit(error), path) from None
    if not isinstance(data, dict):
        raise SceneError("the top level must be a table of keys", path)
    return data


def _not_utf8(data: bytes) -> bool:
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return True
    return False


STDIN_NAMES = ("-", "/dev/stdin")  # a scene piped in: TOML, or JSON when it starts with "{" (TOML cannot)


def is_stdin(path: str | Path) -> bool:
    """Whether a scene path means standard input: `-`, or /dev/stdin (a pipe the FIFO guard would refuse)."""
    return str(path) in STDIN_NAMES


def syntax_limit(error: RecursionError | ValueError) -> str:
    """What a parser's RecursionError (lists or tables nested thousands deep) or ValueError (an integer of more
    than 4300 digits, Python's limit) means, as the rest of a one-line message."""
    if isinstance(error, RecursionError):
        return "lists or tables nested too deep to read; allowed: a few levels, as docs/scene-format.md shows"
    return ("a number with more digits than can be read (Python's limit is 4300); allowed: a number within "
            "the key's range")


class _JSONObject(dict):
    """A JSON object (json's object_pairs_hook) that remembers the keys it was given more than once."""

    def __init__(self, pairs: list[tuple[str, Any]]):
        super().__init__(pairs)
        self.repeated = []
        if len(self) < len(pairs):
            seen: set[str] = set()
            self.repeated = [key for key, _ in pairs if key in seen or seen.add(key)]


def _duplicate_key(data: Any) -> tuple | None:
    """The key path of the first key given twice in a JSON object, or None (a walk with a stack, not
    recursion, so a nesting as deep as json accepts cannot overflow Python's stack here)."""
    stack = [((), data)]
    while stack:
        loc, node = stack.pop()
        if isinstance(node, _JSONObject) and node.repeated:
            return (*loc, node.repeated[0])
        children = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        stack.extend(reversed([((*loc, key), child) for key, child in children]))
    return None
