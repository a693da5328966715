"""Which pieces build_geometry makes afresh: all of them (FRESH, a single render), or only those a change
touched (a BuildMemo, kept between the live view's frames of one changing scene), and the stamps (a file's
version now) a BuildMemo's keys hold."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, TypeVar

import numpy as np

from ..codes import MAP_COLUMNS
from ..records import Geometry
from ..scene.alike import alike, placements
from ..scene.schema import Scene
from ..shapes import from_file

T = TypeVar("T")

if TYPE_CHECKING:
    from .placing import Part
    from .templates import ObjectMesh, Template


def mesh_stamp(path: Path, sources: dict | None = None) -> tuple:
    """A mesh file's identity now (its version and its side files': its MeshSource, the one prepare() made when
    given), or (path, None) when it cannot be read: then no key matches and the read words the error."""
    from ..io.meshes.source import mesh_source
    source = (sources or {}).get(path) or mesh_source(path)
    return source.identity if source.version is not None else (str(path), None)


def file_stamp(path: Path) -> tuple:
    """A file's version now (io.files.file_version), or (path, None) when it cannot be stat'ed."""
    from ..io.files import file_version
    try:
        return file_version(path)
    except OSError:
        return (str(path), None)


class Memo:
    """Which pieces build_geometry makes afresh, asked for each template, part and texture: this one (FRESH, a
    single render's) makes every one and keeps none, so they may be changed in place; a BuildMemo keeps them."""

    shares = False  # whether what it hands out outlives the build (then nothing may change it in place)

    def begin(self, scene: Scene, vertex_normals: bool, normal_dtype: type) -> None:
        return None

    def geometry_for(self, whole: tuple | None) -> Geometry | None:
        return None

    def template(self, key: Callable[[], tuple], make: Callable[[], T]) -> T:
        return make()

    def part(self, scene: Scene, members: np.ndarray, template: ObjectMesh, vertex_normals: bool,
             normal_dtype: type, make: Callable[[bool], Part]) -> Part:
        return make(vertex_normals)

    def texture(self, key: tuple, stamp: Callable[[], object], decode: Callable[[], np.ndarray]) -> np.ndarray:
        return decode()

    def keep(self, whole: tuple | None, geometry: Geometry) -> None:
        pass

    def abandon(self) -> None:
        pass


FRESH = Memo()


class BuildMemo(Memo):
    """What build_geometry keeps between builds of one changing scene (a live view's frames of one page), so
    that a frame rebuilds only what its change touched:

    - the last Geometry, with the key of everything it was built from (begin) and the versions of the
      texture files it decoded: a scene that differs only in lights, camera or render settings other than
      shading and colour gets that Geometry back (the same object);
    - each group's template (a shape's triangles, or a mesh file read, merged and mended), keyed by what it
      reads, the mesh file's version among it: a material or shading change, or a new placement, reads nothing;
    - each group's placed part (world vertices, face and corner normals), keyed by its template and its objects'
      placements: a new tessellation or placement of one set of alike objects rebuilds that set's part only;
    - the textures decoded, keyed by the file's version (or the image object a mesh file holds) and the
      render.colour they were decoded for.

    Only what the last build used is kept (one scene's worth of geometry, and its parts: as much again for a
    scene of several objects, the parts' arrays being copied into one mesh). Not for two threads at once.
    """

    shares = True

    def __init__(self):
        self._whole: tuple | None = None            # whole_key of `_geometry`
        self._geometry: Geometry | None = None
        self._texture_stamps: dict[str, tuple] = {}  # texture files `_geometry` decoded → their versions then
        self._templates: dict[tuple, Template] = {}
        self._parts: dict[tuple, Part] = {}
        self._textures: dict[tuple, tuple[object, np.ndarray]] = {}  # (TextureBank key, colour) → (stamp, pixels)
        self._used: tuple[set, set, set] = (set(), set(), set())  # templates, parts and textures of this build
        self._kept: tuple[set, set, set] = (set(), set(), set())  # those of the last build that succeeded

    def begin(self, scene: Scene, vertex_normals: bool, normal_dtype: type) -> tuple:
        """Start a build: the key of everything build_geometry reads from `scene` and the disk: every object's
        keys but placement (once per set of alike objects, and whether it set crease_angle) and the placements'
        bits, the materials, the default shading, the colour the maps are decoded in (render.colour), the folder,
        the mesh files and maps as they are now; not the lights (check_float_range runs on every build), the
        camera or the other render settings."""
        self._used = (set(), set(), set())
        sets = alike(scene)
        files = tuple(mesh_stamp(scene.resolve(o.path)) for o in scene.objects if from_file(o))
        files += tuple(file_stamp(scene.resolve(getattr(m, key).path)) for m in scene.materials.values()
                       for key in MAP_COLUMNS if getattr(m, key) is not None)
        placed = tuple(array.tobytes() for array in placements(scene.objects))  # bits: -0.0 is not 0.0
        firsts = sets.firsts(scene.objects)
        # Objects compare by their values alone, but a mesh file's crease default depends on whether
        # crease_angle was set at all (templates.file_crease_angle): an unset 180 and a set one differ.
        creases = tuple("crease_angle" in o.model_fields_set for o in firsts)
        return (scene.origin, scene.folder, vertex_normals, np.dtype(normal_dtype).str, scene.render.shading,
                scene.render.colour, tuple(scene.materials.items()), tuple(firsts), creases,
                sets.of.tobytes(), placed, files)

    def geometry_for(self, whole: tuple | None) -> Geometry | None:
        """The last Geometry if `whole` is its key and the texture files it decoded are unchanged; else None."""
        if self._geometry is None or whole != self._whole:
            return None
        if any(file_stamp(Path(path)) != stamp for path, stamp in self._texture_stamps.items()):
            return None
        return self._geometry

    def template(self, key: Callable[[], tuple], make: Callable[[], T]) -> T:
        """The template `key()` names, made by make() if this memo has none."""
        key = key()
        found = self._templates.get(key)
        if found is None:
            found = self._templates[key] = make()
        self._used[0].add(key)
        return found

    def part(self, scene: Scene, members: np.ndarray, template: ObjectMesh, vertex_normals: bool,
             normal_dtype: type, make: Callable[[bool], Part]) -> Part:
        """The placed part of `members` sharing `template`: kept if the same template was placed the same way
        (a part made with corner normals serves a build without them), else made by make(vertex_normals)."""
        first = scene.objects[int(members[0])]
        where = tuple(array.tobytes() for array in placements(scene.objects, members))
        key = (id(template.vertices), id(template.faces), members.tobytes(), where, first.normals,
               first.crease_angle, np.dtype(normal_dtype).str)
        for normals in ((True, False) if not vertex_normals else (True,)):
            found = self._parts.get((*key, normals))
            if found is not None and found.template is template:
                self._used[1].add((*key, normals))
                return found.part if vertex_normals or found.part.corners is None else found.part._replace(corners=None)
        part = make(vertex_normals)
        self._parts[(*key, vertex_normals)] = _KeptPart(template, part)
        self._used[1].add((*key, vertex_normals))
        return part

    def texture(self, key: tuple, stamp: Callable[[], object], decode: Callable[[], np.ndarray]) -> np.ndarray:
        """The pixels of texture `key`, decoded again only when its stamp() (a file's version, or the image
        object a mesh file holds) is another."""
        stamp = stamp()
        found = self._textures.get(key)
        # A file's version is compared; an image object a mesh file holds must be the same object.
        if found is None or not (found[0] is stamp or (isinstance(stamp, tuple) and found[0] == stamp)):
            found = self._textures[key] = (stamp, decode())
        self._used[2].add(key)
        return found[1]

    def keep(self, whole: tuple | None, geometry: Geometry) -> None:
        """Remember this build's Geometry, and drop every template, part and texture it did not use."""
        self._kept, self._used = self._used, (set(), set(), set())
        self._prune()
        self._texture_stamps = {key[0]: stamp for key, (stamp, _) in self._textures.items()
                                if isinstance(stamp, tuple)}
        self._whole, self._geometry = whole, geometry

    def abandon(self) -> None:
        """A build failed (a refused scene): drop what it made, keep what the last good build used."""
        self._used = (set(), set(), set())
        self._prune()

    def _prune(self) -> None:
        templates, parts, textures = self._kept
        self._templates = {k: v for k, v in self._templates.items() if k in templates}
        self._parts = {k: v for k, v in self._parts.items() if k in parts}
        self._textures = {k: v for k, v in self._textures.items() if k in textures}


class _KeptPart(NamedTuple):
    template: ObjectMesh  # the template it was placed from (the key holds its arrays' ids: this keeps them alive)
    part: Part
