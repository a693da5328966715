"""A glTF whose data trimesh would misread, rewritten as a plain glTF with the same content before trimesh sees it.

trimesh reads plain float accessors; what glTF's extensions store otherwise is decoded here, into a new buffer:
EXT_meshopt_compression / KHR_meshopt_compression bufferViews (with the `meshopt` package, meshoptimizer's own
codec), integer vertex attributes (KHR_mesh_quantization, and core glTF's normalized texture coordinates: trimesh
ignores `normalized`), KHR_draco_mesh_compression (DracoPy, so a corrupt stream is one line, not trimesh's
warnings and zero vertices), EXT_mesh_gpu_instancing (each instance a child node of its own matrix) and
KHR_materials_pbrSpecularGlossiness (its diffuse colour and map as the base colour: gltf.py maps the rest).
A file that needs none of this is handed to trimesh unchanged (needs_decoding). No trimesh here.
"""

from __future__ import annotations

import base64
import copy
from contextlib import suppress
from pathlib import Path

import numpy as np

from ...errors import FileProblem, SceneError, Where
from ..files import open_regular
from .gltf_json import MESHOPT, Document, uri_file

DRACO = "KHR_draco_mesh_compression"
INSTANCING = "EXT_mesh_gpu_instancing"
SPECULAR_GLOSSINESS = "KHR_materials_pbrSpecularGlossiness"
# meshoptimizer's filters each extension defines (COLOR is KHR_meshopt_compression's only).
FILTERS = {"EXT_meshopt_compression": ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL"),
           "KHR_meshopt_compression": ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL", "COLOR")}
MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
# glTF 2.0 §3.6.2.2: component types and element sizes.
DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
# The vertex attributes read as numbers (the others, joints and weights, are not used by the renderer).
NUMERIC = ("POSITION", "NORMAL", "TEXCOORD_", "COLOR_")
FAN = 6  # glTF 2.0 §3.7.2.1: TRIANGLE_FAN
DECODED_URI = "raycast-phong-decoded:"  # the buffers handed to trimesh by name (trimesh_parts.RegularFiles)


def needs_decoding(tree: dict) -> bool:
    """Whether trimesh would misread the document's data: compressed buffer views or primitives, integer
    positions, normals, texture coordinates or colours, an accessor of a primitive without a bufferView (all
    zeros, glTF 2.0 §3.6.2.1: trimesh raised UnboundLocalError), triangle fans (trimesh drops them), skinned
    meshes, instanced nodes, specular-glossiness materials, colour maps on a texture coordinate set other than 0."""
    used = tree.get("extensionsUsed")
    used = set(used) if isinstance(used, list) and all(isinstance(e, str) for e in used) else set()
    if used & {*MESHOPT, DRACO, INSTANCING, SPECULAR_GLOSSINESS}:
        return True
    nodes = tree.get("nodes")
    if isinstance(nodes, list) and any(isinstance(n, dict) and "skin" in n and "mesh" in n for n in nodes):
        return True  # a skinned mesh: trimesh draws its bind pose, not the pose its joints hold
    with suppress(AttributeError, IndexError, KeyError, TypeError):  # a malformed document: trimesh words it
        if colour_uv_sets(tree):  # trimesh maps every texture with TEXCOORD_0
            return True
        accessors = tree.get("accessors", [])
        for mesh in tree.get("meshes", []):
            for primitive in mesh.get("primitives", []):
                if primitive.get("mode") == FAN:
                    return True
                for name, index in primitive.get("attributes", {}).items():
                    if "bufferView" not in accessors[index] or (
                            name.startswith(NUMERIC) and accessors[index].get("componentType", 5126) != 5126):
                        return True
                if "indices" in primitive and "bufferView" not in accessors[primitive["indices"]]:
                    return True
    return False


class _Decoder:
    """The document being rewritten: its buffers as bytes, and the new buffer the decoded data is appended to."""

    def __init__(self, tree: dict, buffers: list[bytes], path: Path, notes: list[str]):
        self.tree, self.buffers, self.path, self.notes = tree, buffers, path, notes
        self.new = bytearray()  # the decoded buffer: its index is len(buffers)

    def refuse(self, key: str, problem: str) -> SceneError:
        return FileProblem(f"{str(self.path)!r}: {key}: {problem}")

    def place(self, data: bytes) -> tuple[int, int, int]:
        """`data` appended to the decoded buffer (4-byte aligned, as vertex data must be): buffer, offset, length."""
        self.new.extend(b"\0" * (-len(self.new) % 4))
        offset = len(self.new)
        self.new.extend(data)
        return len(self.buffers), offset, len(data)

    def append(self, data: bytes) -> int:
        """A new bufferView over `data` in the decoded buffer."""
        buffer, offset, length = self.place(data)
        views = self.tree.setdefault("bufferViews", [])
        views.append({"buffer": buffer, "byteOffset": offset, "byteLength": length})
        return len(views) - 1

    def view_bytes(self, index: int, key: str) -> memoryview:
        """The bytes of bufferView `index`, bounds checked."""
        try:
            view = self.tree["bufferViews"][index]
            buffer = view["buffer"]
            start, length = int(view.get("byteOffset", 0)), int(view["byteLength"])
            data = self.new if buffer == len(self.buffers) else self.buffers[buffer]
        except (IndexError, KeyError, TypeError, ValueError):
            raise self.refuse(key, f"names bufferView {index!r}, which is not a bufferView of the file with a "
                                   "buffer, a byteOffset and a byteLength") from None
        if start < 0 or length < 0 or start + length > len(data):
            raise self.refuse(f"bufferViews[{index}]", f"bytes {start}..{start + length} lie outside its buffer "
                                                       f"{buffer} of {len(data)} bytes; allowed: within the buffer")
        return memoryview(data)[start:start + length]

    # ------------------------------------------------------------ EXT/KHR_meshopt_compression

    def read_extents(self) -> dict[int, int]:
        """The bytes of each bufferView that accessors, sparse substitutions and images read (its used length)."""
        extents: dict[int, int] = {}

        def use(view, end) -> None:
            if isinstance(view, int):
                extents[view] = max(extents.get(view, 0), end)
        views = self.tree.get("bufferViews", [])
        for accessor in self.tree.get("accessors", []):
            with suppress(AttributeError, IndexError, KeyError, TypeError, ValueError):  # read_accessor words it
                size = np.dtype(DTYPES[accessor["componentType"]]).itemsize * WIDTHS[accessor["type"]]
                view = accessor.get("bufferView")
                stride = (views[view].get("byteStride") if isinstance(view, int) else None) or size
                count = int(accessor["count"])
                use(view, int(accessor.get("byteOffset", 0)) + (count - 1) * stride + size if count else 0)
                sparse = accessor.get("sparse") or {}
                if sparse:
                    use(sparse["indices"]["bufferView"], 10**12)  # small, read whole
                    use(sparse["values"]["bufferView"], 10**12)
        for image in self.tree.get("images", []):
            use(image.get("bufferView") if isinstance(image, dict) else None, 10**12)
        return extents

    def decode_meshopt(self) -> None:
        """Each meshopt-compressed bufferView that something reads replaced by its decoded bytes (meshoptimizer's
        decoder, through the `meshopt` package), its filter undone. A view is decoded to no more bytes than its
        readers read (the memory estimate counts accessors, not what a view claims); one nothing reads is left
        empty."""
        extents = self.read_extents()
        for index, view in enumerate(self.tree.get("bufferViews", [])):
            extensions = view.get("extensions") if isinstance(view, dict) else None
            found = [name for name in MESHOPT if isinstance(extensions, dict) and name in extensions]
            if not found:
                continue
            name = found[0]
            spec = extensions[name]
            key = f"bufferViews[{index}].extensions.{name}"
            try:
                count, stride = int(spec["count"]), int(spec["byteStride"])
                mode, kind = spec.get("mode"), spec.get("filter", "NONE")
                data = self.view_bytes_of(spec, key)
            except SceneError:
                raise  # a SceneError is a ValueError: it says its own problem
            except (KeyError, TypeError, ValueError):
                raise self.refuse(key, "needs buffer, byteLength, byteStride, count and mode") from None
            if mode not in MODES:
                raise self.refuse(f"{key}.mode", f"is {mode!r}; allowed: {', '.join(MODES)}")
            # The codec's own limits (EXT_meshopt_compression: attributes 4..256 bytes in fours, indices 2 or 4).
            strides = range(4, 257, 4) if mode == "ATTRIBUTES" else (2, 4)
            if stride not in strides:
                allowed = "4 to 256, a multiple of 4" if mode == "ATTRIBUTES" else "2 or 4"
                raise self.refuse(f"{key}.byteStride", f"is {stride}; allowed for {mode}: {allowed}")
            if count < 0 or (mode == "TRIANGLES" and count % 3):
                raise self.refuse(f"{key}.count", f"is {count}; allowed: 0 or more" + (", a multiple of 3"
                                                                                      if mode == "TRIANGLES" else ""))
            if kind not in FILTERS[name]:
                raise self.refuse(f"{key}.filter", f"is {kind!r}, which this renderer cannot decode; supported: "
                                                   f"{', '.join(FILTERS[name])}")
            if count * stride != int(view.get("byteLength", -1)):
                raise self.refuse(key, f"decodes to {count} × {stride} bytes, but the bufferView's byteLength is "
                                       f"{view.get('byteLength')!r}; allowed: equal")
            if index not in extents:
                decoded = b""
            elif count * stride > extents[index] + stride + 3:
                raise self.refuse(key, f"decodes to {count} × {stride} bytes, of which its accessors read "
                                       f"{extents[index]}; allowed: no more than they read")
            else:
                decoded = _meshopt_decode(bytes(data), count, stride, mode, kind, self.refuse, key)
            extensions.pop(name)
            if not extensions:
                view.pop("extensions")
            buffer, offset, length = self.place(decoded)  # the view itself now names the decoded bytes
            view.update(buffer=buffer, byteOffset=offset, byteLength=length)
            if mode == "ATTRIBUTES":
                view["byteStride"] = stride

    def view_bytes_of(self, spec: dict, key: str) -> memoryview:
        """The bytes a meshopt extension names (its own buffer, byteOffset and byteLength)."""
        buffer, start, length = spec["buffer"], int(spec.get("byteOffset", 0)), int(spec["byteLength"])
        try:
            data = self.buffers[buffer]
        except (IndexError, TypeError):
            raise self.refuse(f"{key}.buffer", f"is {buffer!r}, not a buffer of the file") from None
        if start < 0 or length < 0 or start + length > len(data):
            raise self.refuse(key, f"bytes {start}..{start + length} lie outside buffer {buffer} of {len(data)} "
                                   "bytes; allowed: within the buffer")
        return memoryview(data)[start:start + length]

    # ------------------------------------------------------------ accessors

    def read_accessor(self, index: int, key: str) -> np.ndarray:
        """Accessor `index` as stored: (count, width) of its component type (sparse values applied), from its
        bufferView, or zeros when it has none."""
        try:
            accessor = self.tree["accessors"][index]
            dtype = np.dtype(DTYPES[accessor["componentType"]]).newbyteorder("<")
            width, count = WIDTHS[accessor["type"]], int(accessor["count"])
        except (IndexError, KeyError, TypeError, ValueError):
            raise self.refuse(key, f"names accessor {index!r}, which is not an accessor of the file with a "
                                   "componentType, a type and a count") from None
        if count < 0:
            raise self.refuse(f"accessors[{index}].count", f"is {count}; allowed: 0 or more")
        if "bufferView" in accessor:
            data = self.view_bytes(accessor["bufferView"], f"accessors[{index}]")
            view = self.tree["bufferViews"][accessor["bufferView"]]
            element = dtype.itemsize * width
            stride = int(view.get("byteStride") or element)
            start = int(accessor.get("byteOffset", 0))
            end = start + (count - 1) * stride + element if count else start
            if stride < element:  # a decoded view's stride (gltf.check_references sees the file's own)
                raise FileProblem(f"{str(self.path)!r}: {short_stride(accessor['bufferView'], stride, index, element)}")
            if start < 0 or end > len(data):
                raise self.refuse(f"accessors[{index}]", f"its {count} element(s) of {element} bytes every "
                                                         f"{stride} from byte {start} overrun its bufferView of "
                                                         f"{len(data)} bytes; allowed: within the bufferView")
            raw = np.frombuffer(data, np.uint8, end - start, start) if count else np.zeros(0, np.uint8)
            rows = np.lib.stride_tricks.as_strided(raw, (count, element), (stride, 1)) if count else \
                np.zeros((0, element), np.uint8)
            values = np.ascontiguousarray(rows).view(dtype).reshape(count, width)
        else:
            values = np.zeros((count, width), dtype)
        sparse = accessor.get("sparse")
        if isinstance(sparse, dict):
            values = self.apply_sparse(values, sparse, dtype, width, index)
        return values

    def apply_sparse(self, values, sparse: dict, dtype, width: int, index: int) -> np.ndarray:
        """glTF 2.0 §3.6.2.3: the sparse substitutions of accessor `index` applied to a copy of `values`."""
        key = f"accessors[{index}].sparse"
        try:
            count = int(sparse["count"])
            where, stored = sparse["indices"], sparse["values"]
            kind = np.dtype(DTYPES[where["componentType"]]).newbyteorder("<")
            at = np.frombuffer(self.view_bytes(where["bufferView"], key), kind, count,
                               int(where.get("byteOffset", 0))).astype(np.int64)
            new = np.frombuffer(self.view_bytes(stored["bufferView"], key), dtype, count * width,
                                int(stored.get("byteOffset", 0))).reshape(count, width)
        except SceneError:
            raise  # a SceneError is a ValueError: it says its own problem
        except (KeyError, TypeError, ValueError):
            raise self.refuse(key, "needs count, indices (bufferView, componentType) and values (bufferView) "
                                   "within their bufferViews") from None
        if count and (at.min() < 0 or at.max() >= len(values)):
            raise self.refuse(f"{key}.indices", f"reach {int(at.max())}; allowed: below the accessor's count "
                                                f"{len(values)}")
        values = values.copy()
        values[at] = new
        return values

    def float_accessor(self, index: int, key: str) -> np.ndarray:
        """Accessor `index` as float64: a normalized integer as glTF 2.0 §3.11 decodes it (signed: max(c / (2^(b−1)
        − 1), −1); unsigned: c / (2^b − 1)), any other integer as its value (KHR_mesh_quantization)."""
        values = self.read_accessor(index, key)
        accessor = self.tree["accessors"][index]
        if values.dtype.kind == "f" or not accessor.get("normalized", False):
            return values.astype(np.float64)
        top = float(np.iinfo(values.dtype).max)
        decoded = values.astype(np.float64) / top
        return np.maximum(decoded, -1.0) if values.dtype.kind == "i" else decoded

    def store_floats(self, index: int, values: np.ndarray) -> None:
        """Accessor `index` rewritten as float32 `values` (count, width) in the decoded buffer, tightly packed."""
        accessor = self.tree["accessors"][index]
        accessor.pop("normalized", None)
        accessor["componentType"] = 5126
        self.store_values(index, values.astype("<f4"))
        accessor.pop("min", None)  # the stored integers' bounds; trimesh does not need them
        accessor.pop("max", None)

    def store_values(self, index: int, values: np.ndarray) -> None:
        """Accessor `index` rewritten as `values` (count, width), of its component type, in the decoded buffer,
        tightly packed, its sparse substitutions applied."""
        accessor = self.tree["accessors"][index]
        accessor.pop("sparse", None)
        accessor.pop("byteOffset", None)
        accessor["bufferView"] = self.append(np.ascontiguousarray(values, values.dtype.newbyteorder("<")).tobytes())

    # ------------------------------------------------------------ KHR_draco_mesh_compression

    def decode_draco(self) -> None:
        """Each Draco-compressed primitive's accessors filled from its decoded stream (DracoPy), the extension
        removed. A stream that does not decode is refused in one line (trimesh warned and left zeros)."""
        for m, mesh in enumerate(self.tree.get("meshes", [])):
            for p, primitive in enumerate(mesh.get("primitives", [])):
                extensions = primitive.get("extensions")
                if not isinstance(extensions, dict) or DRACO not in extensions:
                    continue
                key = f"meshes[{m}].primitives[{p}].extensions.{DRACO}"
                spec = extensions[DRACO]
                try:
                    data = bytes(self.view_bytes(spec["bufferView"], key))
                    ids = {int(v): k for k, v in spec["attributes"].items()}
                except SceneError:
                    raise  # a SceneError is a ValueError: it says its own problem
                except (KeyError, TypeError, ValueError, AttributeError):
                    raise self.refuse(key, "needs a bufferView and attributes") from None
                decoded = _draco_decode(data, self.path)
                attributes = primitive.get("attributes", {})
                found = {name: np.asarray(attribute["data"]) for attribute in getattr(decoded, "attributes", [])
                         if (name := ids.get(attribute.get("unique_id"))) in attributes}
                if "POSITION" in attributes and "POSITION" not in found:
                    found["POSITION"] = np.asarray(decoded.points)
                for name, values in found.items():
                    accessor = self.tree["accessors"][attributes[name]]
                    dtype = np.dtype(DTYPES.get(accessor.get("componentType"), np.float32)).newbyteorder("<")
                    values = values.reshape(len(values), -1)
                    if len(values) != accessor.get("count"):  # what the stream holds is drawn, as f3d does
                        self.notes.append(f"{self.path}: {key}: its Draco data decodes to {len(values)} {name} "
                                          f"values where the accessor counts {accessor.get('count')!r}; the "
                                          "decoded values are drawn")
                        accessor["count"] = len(values)
                    accessor.pop("byteOffset", None)
                    accessor["bufferView"] = self.append(np.ascontiguousarray(values, dtype).tobytes())
                faces = getattr(decoded, "faces", None)
                if "indices" in primitive and faces is not None:
                    faces = np.asarray(faces, np.uint32).reshape(-1)
                    accessor = self.tree["accessors"][primitive["indices"]]
                    accessor.update(componentType=5125, count=len(faces))
                    accessor.pop("byteOffset", None)
                    accessor["bufferView"] = self.append(faces.astype("<u4").tobytes())
                extensions.pop(DRACO)
                if not extensions:
                    primitive.pop("extensions")

    # ------------------------------------------------------------ TRIANGLE_FAN

    def fans(self) -> None:
        """Each TRIANGLE_FAN primitive as indexed triangles: fan triangle i is (v_i+1, v_i+2, v_0) (glTF 2.0
        §3.7.2.1), wound as (v_0, v_i+1, v_i+2); its vertices in index order, or in order without indices."""
        for m, mesh in enumerate(self.tree.get("meshes", [])):
            for p, primitive in enumerate(mesh.get("primitives", [])):
                if primitive.get("mode") != FAN:
                    continue
                key = f"meshes[{m}].primitives[{p}]"
                if "indices" in primitive:
                    order = self.read_accessor(primitive["indices"], f"{key}.indices").astype(np.int64).reshape(-1)
                else:
                    order = np.arange(int(self.tree["accessors"][primitive["attributes"]["POSITION"]]["count"]))
                step = np.arange(1, max(len(order) - 1, 1))
                faces = np.column_stack([np.full(len(step), order[:1].sum()), order[step], order[step + 1]]) \
                    if len(order) >= 3 else np.zeros((0, 3), np.int64)
                primitive.update(indices=self.new_accessor(faces, indices=True), mode=4)

    # ------------------------------------------------------------ skins

    def skins(self) -> None:
        """Each skinned mesh in the pose its joints' nodes hold (glTF 2.0 §3.7.3): a vertex moves to
        Σ_k w_k (G(joint_k) · IBM_k) v, G a node's global transform and IBM the skin's inverse bind matrix
        (identity without one), its normal by each such matrix's inverse transpose (the geometry stage makes its
        length 1). The result is in the scene's frame (the spec ignores the skinned node's own transform), so
        the mesh moves to a new root node without one; the skin and its animations are not read further."""
        nodes = self.tree.get("nodes", [])
        skinned = [i for i, node in enumerate(nodes) if isinstance(node, dict) and "skin" in node and "mesh" in node]
        if not skinned:
            return
        placed = node_globals(nodes)
        scene = self.tree.setdefault("scenes", [{"nodes": []}])[self.tree.get("scene", 0)]
        for i in skinned:
            node, key = nodes[i], f"nodes[{i}]"
            try:
                skin = self.tree["skins"][node["skin"]]
                joints = np.asarray(skin["joints"], np.int64)
                primitives = self.tree["meshes"][node["mesh"]]["primitives"]
            except (IndexError, KeyError, TypeError):
                raise self.refuse(f"{key}.skin", "names a skin with joints and a mesh the file does not define") \
                    from None
            if joints.size == 0 or joints.min() < 0 or joints.max() >= len(nodes):
                raise self.refuse(f"skins[{node['skin']}].joints", f"allowed: node indices 0..{len(nodes) - 1}")
            inverse = np.tile(np.eye(4), (len(joints), 1, 1))
            if "inverseBindMatrices" in skin:  # MAT4 stored column by column
                stored = self.float_accessor(skin["inverseBindMatrices"], f"skins[{node['skin']}].inverseBindMatrices")
                inverse[:len(stored)] = stored.reshape(-1, 4, 4).transpose(0, 2, 1)[:len(joints)]
            pose = placed[joints] @ inverse  # (J, 4, 4)
            posed = [self.posed(primitive, pose, f"meshes[{node['mesh']}].primitives[{p}]")
                     for p, primitive in enumerate(primitives)]
            self.tree["meshes"].append({"name": f"{self.tree['meshes'][node['mesh']].get('name', 'mesh')} posed",
                                        "primitives": posed})
            node.pop("mesh")
            node.pop("skin")
            nodes.append({"mesh": len(self.tree["meshes"]) - 1, "name": f"{node.get('name', key)} posed"})
            scene.setdefault("nodes", []).append(len(nodes) - 1)

    def posed(self, primitive: dict, pose: np.ndarray, key: str) -> dict:
        """A skinned primitive's copy with POSITION and NORMAL moved by its vertices' joint mix (skins())."""
        attributes = primitive.get("attributes", {})
        positions = self.float_accessor(attributes["POSITION"], f"{key}.attributes.POSITION")
        mix = np.zeros((len(positions), 4, 4))
        for set_ in range(8):
            if f"JOINTS_{set_}" not in attributes or f"WEIGHTS_{set_}" not in attributes:
                break
            joint = self.read_accessor(attributes[f"JOINTS_{set_}"], f"{key}.attributes.JOINTS_{set_}").astype(np.int64)
            weight = self.float_accessor(attributes[f"WEIGHTS_{set_}"], f"{key}.attributes.WEIGHTS_{set_}")
            if len(joint) != len(positions) or len(weight) != len(positions) or (joint < 0).any() \
                    or (joint >= len(pose)).any():
                raise self.refuse(f"{key}.attributes.JOINTS_{set_}", f"allowed: one row per vertex of joint numbers "
                                                                     f"0..{len(pose) - 1}")
            mix += np.einsum("vk,vkij->vij", weight, pose[joint])
        moved = np.einsum("vij,vj->vi", mix[:, :3, :3], positions) + mix[:, :3, 3]
        copy = {**primitive, "attributes": {name: index for name, index in attributes.items()
                                            if not name.startswith(("JOINTS_", "WEIGHTS_"))}}
        copy["attributes"]["POSITION"] = self.new_accessor(moved)
        if "NORMAL" in attributes:
            normals = self.float_accessor(attributes["NORMAL"], f"{key}.attributes.NORMAL")
            linear = mix[:, :3, :3]
            turned = np.einsum("vji,vj->vi", np.linalg.pinv(linear), normals)  # n · L⁻¹ = L⁻ᵀ n
            copy["attributes"]["NORMAL"] = self.new_accessor(turned)
        return copy

    # ------------------------------------------------------------ KHR_mesh_quantization

    def dequantize(self) -> None:
        """Every integer POSITION, NORMAL, TEXCOORD_n and COLOR_n accessor a primitive uses, as float32 (trimesh
        ignores `normalized`: a COLOR_0 of normalized uint16 came out pastel), whether or not the file uses
        KHR_mesh_quantization: the node transforms (gltfpack's dequantizing scale and offset) stay as they are,
        trimesh applies them. An attribute or index accessor without a bufferView (zeros, glTF 2.0 §3.6.2.1, and
        its sparse values) is written out as stored."""
        done = set()
        accessors = self.tree.get("accessors", [])
        for m, mesh in enumerate(self.tree.get("meshes", [])):
            for p, primitive in enumerate(mesh.get("primitives", [])):
                used = list((primitive.get("attributes") or {}).items())
                if "indices" in primitive:
                    used.append(("indices", primitive["indices"]))
                for name, index in used:
                    if index in done:
                        continue
                    try:
                        accessor = accessors[index]
                        integer = name.startswith(NUMERIC) and accessor.get("componentType", 5126) != 5126
                        empty = "bufferView" not in accessor
                    except (IndexError, TypeError, AttributeError):
                        continue  # trimesh words it
                    key = f"meshes[{m}].primitives[{p}]." + (name if name == "indices" else f"attributes.{name}")
                    if integer:
                        self.store_floats(index, self.float_accessor(index, key))
                    elif empty:
                        self.store_values(index, self.read_accessor(index, key))
                    done.add(index)

    # ------------------------------------------------------------ EXT_mesh_gpu_instancing

    def instance(self) -> None:
        """Each instanced node's mesh placed once per instance at the instance's T · R · S (EXT_mesh_gpu_instancing:
        instance transforms apply before the node's own): as one new mesh of every instance's triangles
        (merged_instances: 20,000 child nodes took trimesh 7 s), else (a primitive that is not triangles) as one
        child node per instance, whose matrix is the instance's."""
        nodes = self.tree.get("nodes", [])
        for n, node in enumerate(list(nodes)):  # not the child nodes it adds
            extensions = node.get("extensions") if isinstance(node, dict) else None
            if not isinstance(extensions, dict) or INSTANCING not in extensions or "mesh" not in node:
                continue
            key = f"nodes[{n}].extensions.{INSTANCING}.attributes"
            attributes = (extensions[INSTANCING] or {}).get("attributes") or {}
            columns = {}
            for name, width in (("TRANSLATION", 3), ("ROTATION", 4), ("SCALE", 3)):
                if name in attributes:
                    values = self.float_accessor(attributes[name], f"{key}.{name}")
                    if values.shape[1] != width:
                        raise self.refuse(f"{key}.{name}", f"has {values.shape[1]} components; allowed: {width}")
                    if not np.isfinite(values).all():
                        raise self.refuse(f"{key}.{name}", "holds a NaN or infinite value; allowed: finite numbers")
                    columns[name] = values
            counts = {len(v) for v in columns.values()}
            if len(counts) != 1:
                raise self.refuse(key, f"its accessors count {sorted(counts)} instances; allowed: one count, the "
                                       "same for TRANSLATION, ROTATION and SCALE" if counts else
                                       "names none of TRANSLATION, ROTATION, SCALE")
            matrices = instance_matrices(columns.get("TRANSLATION"), columns.get("ROTATION"),
                                         columns.get("SCALE"), counts.pop())
            merged = self.merged_instances(node["mesh"], matrices, f"nodes[{n}]")
            if merged is not None:
                node["mesh"] = merged
                continue
            first = len(nodes)
            nodes.extend({"mesh": node["mesh"], "matrix": m.T.reshape(-1).tolist()} for m in matrices)
            node.pop("mesh")
            node["children"] = [*node.get("children", []), *range(first, len(nodes))]

    def merged_instances(self, mesh: int, matrices: np.ndarray, key: str) -> int | None:
        """A new mesh holding mesh `mesh`'s triangle primitives once per instance (matrices (K, 4, 4)), placed:
        positions by each matrix, normals by its inverse transpose (dropped if one is singular: the geometry
        stage makes them), texture coordinates and colours repeated, each instance's faces after the previous
        one's (turned over where the matrix mirrors). None when a primitive is not indexed-or-plain triangles."""
        try:
            primitives = self.tree["meshes"][mesh]["primitives"]
        except (IndexError, KeyError, TypeError):
            raise self.refuse(f"{key}.mesh", f"is {mesh!r}, not a mesh of the file with primitives") from None
        if any(not isinstance(p, dict) or p.get("mode", 4) != 4 or "POSITION" not in (p.get("attributes") or {})
               for p in primitives):
            return None
        linear, shift = matrices[:, :3, :3], matrices[:, :3, 3]
        with np.errstate(invalid="ignore", over="ignore"):  # a non-finite matrix: the read's values check words it
            determinant = np.linalg.det(linear)
        copies = len(matrices)
        merged = []
        for p, primitive in enumerate(primitives):
            where = f"meshes[{mesh}].primitives[{p}]"
            attributes = {}
            positions = self.float_accessor(primitive["attributes"]["POSITION"], f"{where}.attributes.POSITION")
            count = len(positions)
            if copies * count >= 2**32:
                raise self.refuse(key, f"places {copies:,} × {count:,} vertices; allowed: fewer than 2³²")
            with np.errstate(invalid="ignore", over="ignore"):
                placed = np.einsum("kij,vj->kvi", linear, positions) + shift[:, None, :]
            attributes["POSITION"] = self.new_accessor(placed.reshape(-1, 3))
            for name, index in primitive["attributes"].items():
                if name == "NORMAL" and (determinant != 0).all():
                    normals = self.float_accessor(index, f"{where}.attributes.NORMAL")
                    with np.errstate(invalid="ignore", over="ignore"):
                        turned = np.einsum("vj,kji->kvi", normals, np.linalg.inv(linear))  # n · L⁻¹ = L⁻ᵀ n
                    attributes[name] = self.new_accessor(turned.reshape(-1, 3))
                elif name.startswith(("TEXCOORD_", "COLOR_")):
                    values = self.float_accessor(index, f"{where}.attributes.{name}")
                    attributes[name] = self.new_accessor(np.tile(values, (copies, 1)))
            if "indices" in primitive:
                faces = self.read_accessor(primitive["indices"], f"{where}.indices").astype(np.int64).reshape(-1, 3)
                if faces.size and (faces.min() < 0 or faces.max() >= count):
                    raise self.refuse(f"{where}.indices", f"reach {int(faces.max())}; allowed: 0..{count - 1}")
            else:
                faces = np.arange(count - count % 3, dtype=np.int64).reshape(-1, 3)
            every = faces[None, :, :] + (np.arange(copies) * count)[:, None, None]
            every = np.where((determinant < 0)[:, None, None], every[:, :, ::-1], every)  # a mirror keeps them outward
            merged.append({"attributes": attributes, "indices": self.new_accessor(every, indices=True), "mode": 4,
                           **({"material": primitive["material"]} if "material" in primitive else {})})
        self.tree["meshes"].append({"name": self.tree["meshes"][mesh].get("name", f"mesh {mesh}") + " instanced",
                                    "primitives": merged})
        return len(self.tree["meshes"]) - 1

    def new_accessor(self, values: np.ndarray, indices: bool = False) -> int:
        """A new accessor in the decoded buffer: of float32 `values` (count, width), or with `indices` of every one
        of `values` as a uint32 index (SCALAR)."""
        if indices:
            data, component, count, kind = values.astype("<u4").tobytes(), 5125, values.size, "SCALAR"
        else:
            data, component, count = np.ascontiguousarray(values, "<f4").tobytes(), 5126, len(values)
            kind = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}[values.shape[1]]
        self.tree.setdefault("accessors", []).append({"bufferView": self.append(data), "componentType": component,
                                                      "count": count, "type": kind})
        return len(self.tree["accessors"]) - 1

    # ------------------------------------------------------------ KHR_materials_pbrSpecularGlossiness

    def specular_glossiness(self) -> None:
        """A specular-glossiness material's diffuse factor and map given trimesh as its base colour (trimesh's own
        conversion would change them); io.gltf.gltf_samplers reads its specular and glossiness from the file."""
        for material in self.tree.get("materials", []):
            extensions = material.get("extensions") if isinstance(material, dict) else None
            if not isinstance(extensions, dict) or not isinstance(extensions.get(SPECULAR_GLOSSINESS), dict):
                continue
            spec = extensions.pop(SPECULAR_GLOSSINESS)
            base = {"metallicFactor": 0.0}
            if "diffuseFactor" in spec:
                base["baseColorFactor"] = spec["diffuseFactor"]
            if "diffuseTexture" in spec:
                base["baseColorTexture"] = spec["diffuseTexture"]
            material["pbrMetallicRoughness"] = base


def short_stride(view: int, stride: int, accessor: int, element: int) -> str:
    """The problem of a bufferView whose byteStride is shorter than an accessor's elements (glTF 2.0 §3.6.2.4:
    an element fits its stride): read so, the elements would overlap."""
    return (f"bufferViews[{view}].byteStride is {stride}, less than the {element} bytes of accessors[{accessor}]'s "
            f"elements; allowed: {element} or more")


INDEX_TYPES = (5121, 5123, 5125)  # glTF 2.0 §3.7.2.1: unsigned byte, short and int indices


def node_globals(nodes: list) -> np.ndarray:
    """(N, 4, 4) every node's global transform: its parents' local transforms, outermost first, times its own
    (a `matrix`, stored column by column, or T · R · S). A node listed as the child of two parents takes the
    last; a chain is followed at most N steps, so a cycle ends (the file is not refused here)."""
    local = np.tile(np.eye(4), (len(nodes), 1, 1))
    parent = np.full(len(nodes), -1)
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            continue
        if "matrix" in node:
            local[i] = np.asarray(node["matrix"], np.float64).reshape(4, 4).T
        else:
            t, r, s = (np.asarray(node[k], np.float64)[None] if k in node else None
                       for k in ("translation", "rotation", "scale"))
            local[i] = instance_matrices(t, r, s, 1)[0]
        for child in node.get("children", []):
            if isinstance(child, int) and 0 <= child < len(nodes):
                parent[child] = i
    placed = np.empty_like(local)
    for i in range(len(nodes)):
        chain, at = [], i
        while at >= 0 and len(chain) <= len(nodes):
            chain.append(at)
            at = parent[at]
        matrix = np.eye(4)
        for k in reversed(chain):
            matrix = matrix @ local[k]
        placed[i] = matrix
    return placed


def instance_matrices(translation, rotation, scale, count: int) -> np.ndarray:
    """(count, 4, 4) T · R · S of each instance, R from a unit quaternion (x, y, z, w) (glTF 2.0 §3.5.2); a
    quaternion that is not unit is normalised, a zero one is no rotation."""
    matrices = np.zeros((count, 4, 4))
    matrices[:, 3, 3] = 1.0
    if rotation is None:
        rotation = np.tile([0.0, 0.0, 0.0, 1.0], (count, 1))
    length = np.linalg.norm(rotation, axis=1)
    rotation = np.where(length[:, None] > 0, rotation / np.where(length > 0, length, 1.0)[:, None], [0, 0, 0, 1])
    x, y, z, w = rotation.T
    matrices[:, 0, :3] = np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)])
    matrices[:, 1, :3] = np.column_stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)])
    matrices[:, 2, :3] = np.column_stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)])
    if scale is not None:
        matrices[:, :3, :3] *= scale[:, None, :]  # R · S: column j scaled by s_j
    if translation is not None:
        matrices[:, :3, 3] = translation
    return matrices


def _meshopt_decode(data: bytes, count: int, stride: int, mode: str, kind: str, refuse, key: str) -> bytes:
    """meshoptimizer's decoder (the `meshopt` package) on one bufferView's compressed bytes."""
    try:
        import meshopt
    except ImportError:
        raise refuse(key, "decoding meshoptimizer-compressed data needs the meshopt package: pip install "
                          "meshopt") from None
    try:
        decoded = meshopt.decode_gltf_buffer(data, count, stride, mode, None if kind == "NONE" else kind)
    except (ValueError, RuntimeError) as error:
        raise refuse(key, f"its compressed data could not be decoded ({error}); the file is corrupt or cut "
                          "short") from None
    return np.ascontiguousarray(decoded).tobytes()


def _draco_decode(data: bytes, path: Path):
    try:
        import DracoPy
    except ImportError:
        raise FileProblem(f"{str(path)!r}: decoding its Draco-compressed meshes needs DracoPy: pip install "
                          "DracoPy") from None
    try:
        return DracoPy.decode(data)
    except Exception as error:  # noqa: BLE001 - DracoPy raises its own types (and ValueError) on a bad stream
        raise FileProblem(f"{str(path)!r}: its Draco-compressed data could not be decoded "
                          f"({type(error).__name__}); the file is corrupt or cut short") from None


def read_buffers(tree: dict, path: Path, document: Document, where: Where) -> list[bytes]:
    """Every buffer of the document as bytes: a .glb's binary chunk, external files (regular files only), data:
    URIs; b"" for a buffer without data (a meshopt fallback buffer, which only compressed views name)."""
    found = []
    for index, buffer in enumerate(tree.get("buffers", []) if isinstance(tree.get("buffers"), list) else []):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if isinstance(uri, str) and uri.startswith("data:"):
            try:
                found.append(base64.b64decode(uri.partition(",")[2], validate=False))
            except ValueError:
                raise FileProblem(f"{str(path)!r}: buffers[{index}].uri is a data: URI that is not base64") \
                    from None
        elif isinstance(uri, str):
            file = uri_file(path.parent, uri)
            with open_regular(file, where, "glTF buffer") as handle:
                found.append(handle.read())
        elif index == 0 and document.binary is not None:
            with open_regular(path, where, "mesh file") as handle:
                handle.seek(document.binary[0])
                found.append(handle.read(document.binary[1]))
        else:
            found.append(b"")
    return found


def _colour_maps(material: dict) -> list[tuple[str, dict]]:
    """A material's colour maps' texture infos, the one the base colour comes from first (baseColorTexture, or a
    specular-glossiness diffuseTexture), then emissiveTexture: the maps this renderer draws."""
    glossy = (material.get("extensions") or {}).get(SPECULAR_GLOSSINESS)
    tables = ((material.get("pbrMetallicRoughness"), "baseColorTexture"), (glossy, "diffuseTexture"),
              (material, "emissiveTexture"))
    return [(key, table[key]) for table, key in tables if isinstance(table, dict) and isinstance(table.get(key), dict)]


def _uv_set(info: dict) -> int:
    """The texture coordinate set a texture info maps with: its texCoord (glTF 2.0 §5.22, default 0), which its
    KHR_texture_transform's own texCoord overrides."""
    transform = (info.get("extensions") or {}).get("KHR_texture_transform") or {}
    value = transform.get("texCoord", info.get("texCoord", 0))
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise TypeError(f"texCoord {value!r} is not a set index")
    return value


def colour_uv_sets(tree: dict) -> dict[int, int]:
    """Material index → the texture coordinate set its colour maps are drawn with, where it is not 0: its base
    colour map's, else its emissive map's (a surface holds one set here)."""
    sets = {}
    for index, material in enumerate(tree.get("materials") or []):
        maps = _colour_maps(material) if isinstance(material, dict) else []
        if maps and (chosen := _uv_set(maps[0][1])):
            sets[index] = chosen
    return sets


def first_uv_set(tree: dict, path: Path, notes: list[str]) -> None:
    """The document rewritten (in place) so that each primitive's colour maps read TEXCOORD_0, as trimesh does:
    a primitive whose material draws its maps with set k gets TEXCOORD_k as TEXCOORD_0, and the maps' texCoord is
    0. A material whose maps name two sets is drawn with the first map's, and a note says which map is moved."""
    for index, material in enumerate(tree.get("materials") or []):
        maps = _colour_maps(material) if isinstance(material, dict) else []
        if not maps:
            continue
        chosen = _uv_set(maps[0][1])
        moved = [key for key, info in maps[1:] if _uv_set(info) != chosen]
        if moved:
            notes.append(f"{path}: material {material.get('name') or index!r}: its {', '.join(moved)} is drawn with "
                         f"its {maps[0][0]}'s TEXCOORD_{chosen}, not its own set (one set of texture coordinates a "
                         "surface here)")
        for _, info in maps:
            info["texCoord"] = 0
            ((info.get("extensions") or {}).get("KHR_texture_transform") or {}).pop("texCoord", None)
        if chosen:
            for mesh in tree.get("meshes") or []:
                for primitive in mesh.get("primitives") or []:
                    attributes = primitive.get("attributes") or {}
                    if primitive.get("material") == index and f"TEXCOORD_{chosen}" in attributes:
                        attributes["TEXCOORD_0"] = attributes[f"TEXCOORD_{chosen}"]


def decode_gltf(path: Path, document: Document, where: Where, notes: list[str]) -> tuple[dict, dict[str, bytes]]:
    """The glTF at `path` (its parsed `document`) as plain glTF for trimesh: a copy of the document rewritten, and
    the buffers it names (DECODED_URI + index): every buffer given to trimesh by name, the decoded data in one
    more. A document too malformed to decode is refused in one line."""
    tree = copy.deepcopy(document.tree)
    buffers = read_buffers(tree, path, document, where)
    try:
        first_uv_set(tree, path, notes)
        decoder = _Decoder(tree, buffers, path, notes)
        for step in (decoder.decode_meshopt, decoder.decode_draco, decoder.dequantize, decoder.fans, decoder.skins,
                     decoder.instance, decoder.specular_glossiness):
            step()  # in this order: each reads the document the ones before it rewrote
    except (AttributeError, IndexError, KeyError, TypeError, ValueError) as error:
        if isinstance(error, SceneError):
            raise
        raise FileProblem(f"{str(path)!r}: its document is malformed where its compressed, quantized or "
                          f"instanced data is described ({type(error).__name__}: {error}); allowed: a glTF 2.0 "
                          "document") from None
    named = {f"{DECODED_URI}{index}": bytes(data) for index, data in enumerate([*buffers, decoder.new])}
    tree["buffers"] = [{"uri": name, "byteLength": len(data)} for name, data in named.items()]
    for key in ("extensionsRequired", "extensionsUsed"):
        if isinstance(tree.get(key), list):
            tree[key] = [e for e in tree[key] if e not in (*MESHOPT, DRACO, INSTANCING, SPECULAR_GLOSSINESS,
                                                            "KHR_mesh_quantization")]
    return tree, named
