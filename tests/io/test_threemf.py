"""3MF colours and textures read (issue 33): colour groups, base materials' displaycolor, 2-D texture groups,
multiproperties, and a document with an undeclared namespace prefix. Each minimal file is written here with values
worked out by hand; three of the consortium's own samples are kept in tests/data/models (LICENSES.md). On main
every one of them read grey (trimesh's reader keeps only the geometry), and multiprop-metallic.3mf was refused.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes.source import mesh_source, read_mesh

MODELS = Path(__file__).resolve().parents[1] / "data" / "models"
runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")
CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
MATERIAL = "http://schemas.microsoft.com/3dmanufacturing/material/2015/02"
SQUARE = ('<vertices><vertex x="0" y="0" z="0"/><vertex x="10" y="0" z="0"/><vertex x="10" y="10" z="0"/>'
          '<vertex x="0" y="10" z="0"/></vertices>')


def write_3mf(path: Path, resources: str, triangles: str, files: dict | None = None, extra_ns: str = "") -> Path:
    """A 3MF package of one object (the square above, `triangles`) after `resources`, built once."""
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}" xmlns:m="{MATERIAL}"'
             f'{extra_ns}><resources>{resources}<object id="1" type="model"><mesh>{SQUARE}<triangles>{triangles}'
             '</triangles></mesh></object></resources><build><item objectid="1"/></build></model>')
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
        for name, data in (files or {}).items():
            archive.writestr(name, data)
    return path


def read(path: Path) -> mesh_file.MeshFile:
    return read_mesh(path, str(path))


def test_a_colour_group_gives_each_corner_its_colour(tmp_path):
    """p1, p2, p3 index a colorgroup per corner; a triangle with only p1 is one colour; #RRGGBBAA's alpha is not
    read. The two triangles share the square's diagonal, so its corners have one colour each."""
    resources = ('<m:colorgroup id="5"><m:color color="#FF0000"/><m:color color="#00FF00FF"/>'
                 '<m:color color="#0000FF80"/></m:colorgroup>')
    triangles = ('<triangle v1="0" v2="1" v3="2" pid="5" p1="0" p2="1" p3="2"/>'
                 '<triangle v1="0" v2="2" v3="3" pid="5" p1="1"/>')
    mesh = read(write_3mf(tmp_path / "c.3mf", resources, triangles))
    assert mesh.face_group.tolist() == [-1, -1]  # no material: the colour replaces k_a and k_d
    first = {tuple(mesh.vertices[v]): tuple(np.round(c * 255).astype(int))
             for v, c in zip(mesh.faces[0], mesh.corner_colour[0])}
    assert first == {(0, 0, 0): (255, 0, 0), (10, 0, 0): (0, 255, 0), (10, 10, 0): (0, 0, 255)}
    assert (np.round(mesh.corner_colour[1] * 255) == [0, 255, 0]).all()


def test_base_materials_become_named_materials_with_their_display_colour(tmp_path):
    """A basematerials group: each base a material of its name, k_a = k_d = displaycolor; the object's pid and
    pindex colour the triangles that name none."""
    resources = ('<basematerials id="2"><base name="Red PLA" displaycolor="#FF0000"/>'
                 '<base name="Blue" displaycolor="#3366CCFF"/></basematerials>')
    triangles = '<triangle v1="0" v2="1" v3="2" pid="2" p1="1"/><triangle v1="0" v2="2" v3="3"/>'
    path = write_3mf(tmp_path / "b.3mf", resources, triangles)
    text = path.read_bytes()
    with zipfile.ZipFile(io.BytesIO(text)) as archive:
        model = archive.read("3D/3dmodel.model").decode().replace('<object id="1" type="model">',
                                                                   '<object id="1" type="model" pid="2" pindex="0">')
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    mesh = read(path)
    names = [mesh.materials[g].name for g in mesh.face_group]
    assert sorted(names) == ["Blue", "Red PLA"]
    blue = mesh.materials[names.index("Blue")]
    assert blue.kd == blue.ka == pytest.approx((0x33 / 255, 0x66 / 255, 0xCC / 255))
    assert mesh.corner_colour is None


def test_a_texture_group_maps_its_image_with_v_up_from_the_lower_left(tmp_path):
    """A texture2dgroup's tex2coord per corner, its texture2d the k_d map (tilestyle clamp kept). Materials §3.1:
    v runs up from the image's lower left corner, as the renderer's does: read as written."""
    from PIL import Image
    png = io.BytesIO()
    Image.new("RGB", (2, 2), (200, 10, 10)).save(png, "PNG")
    resources = ('<m:texture2d id="3" path="/3D/Texture/t.png" contenttype="image/png" tilestyleu="clamp"/>'
                 '<m:texture2dgroup id="4" texid="3"><m:tex2coord u="0" v="0"/><m:tex2coord u="1" v="0.25"/>'
                 '<m:tex2coord u="1" v="1"/></m:texture2dgroup>')
    triangles = '<triangle v1="0" v2="1" v3="2" pid="4" p1="0" p2="1" p3="2"/>'
    mesh = read(write_3mf(tmp_path / "t.3mf", resources, triangles, {"3D/Texture/t.png": png.getvalue()}))
    np.testing.assert_allclose(mesh.corner_uv[0], [[0, 0], [1, 0.25], [1, 1]])
    material = mesh.materials[mesh.face_group[0]]
    assert material.kd_map >= 0 and material.kd == (1.0, 1.0, 1.0)
    source = mesh.texture_sources[material.kd_map]
    assert (source.wrap_s, source.wrap_t) == ("clamp", "repeat")
    image = rp.render_file(tmp_path / "t.3mf", ["render.width=60", "render.height=60", "render.background=[0,0,0]",
                                              "lights.0.specular=[0,0,0]"], view="top").image
    covered = image.max(axis=2) > 0
    assert covered.any() and (image[covered][:, 0] > 4 * image[covered][:, 1]).all()  # red, as the texture


def test_the_image_s_top_row_is_drawn_where_v_is_1(tmp_path):
    """A 2 × 2 image, top row red and bottom row blue, on the square with v along +y: seen from the top (+y up
    the picture), red is at the top. lib3mf's smiley box, ladybug and lettered cube were drawn upside down when
    v was read from the image's top. filter="nearest" is said to be sampled bilinearly (one note)."""
    from PIL import Image
    png = io.BytesIO()
    image = Image.new("RGB", (2, 2), (0, 0, 255))
    image.putpixel((0, 0), (255, 0, 0))
    image.putpixel((1, 0), (255, 0, 0))
    image.save(png, "PNG")
    resources = ('<m:texture2d id="3" path="/3D/Texture/t.png" contenttype="image/png" filter="nearest" '
                 'tilestylev="clamp"/>'
                 '<m:texture2dgroup id="4" texid="3"><m:tex2coord u="0" v="0"/><m:tex2coord u="1" v="0"/>'
                 '<m:tex2coord u="1" v="1"/><m:tex2coord u="0" v="1"/></m:texture2dgroup>')
    triangles = ('<triangle v1="0" v2="1" v3="2" pid="4" p1="0" p2="1" p3="2"/>'
                 '<triangle v1="0" v2="2" v3="3" pid="4" p1="0" p2="2" p3="3"/>')
    path = write_3mf(tmp_path / "v.3mf", resources, triangles, {"3D/Texture/t.png": png.getvalue()})
    assert any("nearest filter" in note for note in read(path).notes)
    picture = rp.render_file(path, ["render.width=40", "render.height=40", "render.background=[0,0,0]",
                                    "lights.0.specular=[0,0,0]"], view="top").image
    rows = np.flatnonzero(picture.max(axis=(1, 2)) > 0)  # the square's rows: a quarter down is the top texel's
    top, bottom = (picture[rows[len(rows) * k // 4]].max(axis=0) for k in (1, 3))
    assert top[0] > 4 * top[2] and bottom[2] > 4 * bottom[0], (top, bottom)


@pytest.mark.parametrize(("values", "expected"), [
    ("0.5 0.5", (0.735, 0, 0.735)),     # mixed in linear RGB, then sRGB again
    ("0.2 0.2", (0.735, 0, 0.735)),     # divided by the sum
    ("0 0", (0.735, 0, 0.735)),         # a zero sum: equal shares
    ("1", (1, 0, 0)),                   # a value not given is 0
])
def test_composite_materials_mix_their_bases_display_colours(tmp_path, values, expected):
    """Materials §4: for visualization the bases' displaycolors SHOULD be mixed in the composite's proportions
    (it was drawn in the default grey, noted)."""
    resources = ('<basematerials id="1"><base name="Red" displaycolor="#FF0000"/>'
                 '<base name="Blue" displaycolor="#0000FF"/></basematerials>'
                 f'<m:compositematerials id="2" matid="1" matindices="0 1"><m:composite values="{values}"/>'
                 '</m:compositematerials>')
    triangles = '<triangle v1="0" v2="1" v3="2" pid="2" p1="0"/>'
    mesh = read(write_3mf(tmp_path / "c.3mf", resources, triangles))
    np.testing.assert_allclose(mesh.corner_colour[0], [expected] * 3, atol=1e-3)


RED_BASE = '<basematerials id="1"><base name="Red" displaycolor="#FF0000"/></basematerials>'


@pytest.mark.parametrize(("resources", "said"), [
    (RED_BASE + '<m:compositematerials id="2" matid="1" matindices="0 3"><m:composite values="0.5 0.5"/>'
     '</m:compositematerials>', "compositematerials 2 has matindices '0 3'; allowed: one or more indices of "
     "basematerials 1's bases, 0..0"),
    (RED_BASE + '<m:compositematerials id="2" matid="1" matindices="0 1"><m:composite values="0.5 0.5"/>'
     '</m:compositematerials>', "compositematerials 2 has matindices '0 1'; allowed: one or more indices of "
     "basematerials 1's bases, 0..0"),  # an index equal to the count of bases
    (RED_BASE + '<m:compositematerials id="2" matid="1" matindices="-1 0"><m:composite values="0.5 0.5"/>'
     '</m:compositematerials>', "compositematerials 2 has matindices '-1 0'"),
    (RED_BASE + '<m:compositematerials id="2" matid="1"><m:composite values="1"/></m:compositematerials>',
     "compositematerials 2 has matindices ''"),  # required (§4): it mixed nothing, black
    (RED_BASE + '<m:compositematerials id="2" matid="1" matindices="0"><m:composite values="nan"/>'
     '</m:compositematerials>', "composite value outside 0..1"),
    ('<m:colorgroup id="1"><m:color color="#FF0000"/></m:colorgroup>'
     '<m:compositematerials id="2" matid="1" matindices="0"><m:composite values="1"/></m:compositematerials>',
     "names matid 1, which is not a basematerials group"),
    ('<basematerials id="1"><base name="Red" displaycolor="#FF0000"/></basematerials>'
     '<m:compositematerials id="2" matid="1" matindices="0"><m:composite values="-1"/></m:compositematerials>',
     "composite value outside 0..1"),
])
def test_a_bad_composite_is_one_line_naming_it(tmp_path, resources, said):
    with pytest.raises(SceneError) as caught:
        read(write_3mf(tmp_path / "c.3mf", resources, '<triangle v1="0" v2="1" v3="2" pid="2" p1="0"/>'))
    assert said in str(caught.value) and "\n" not in str(caught.value), str(caught.value)


def test_multiproperties_multiply_colour_layers_and_read_the_first_texture(tmp_path):
    """A multiproperties of a base material and a colour group: per corner, displaycolor × colour; an undeclared
    prefix elsewhere in the document (as in the consortium's samples) is one note, not a refusal."""
    resources = ('<basematerials id="1"><base name="Grey" displaycolor="#808080"/></basematerials>'
                 '<m:colorgroup id="2"><m:color color="#FF0000"/><m:color color="#FFFFFF"/></m:colorgroup>'
                 '<m:multiproperties id="6" pids="1 2"><m:multi pindices="0 0"/><m:multi pindices="0 1"/>'
                 '</m:multiproperties><m:pbmetallicdisplayproperties id="9"><ms:pbmetallic name="x" metallicness="1"/>'
                 '</m:pbmetallicdisplayproperties>')
    triangles = '<triangle v1="0" v2="1" v3="2" pid="6" p1="0" p2="1" p3="1"/>'
    mesh = read(write_3mf(tmp_path / "m.3mf", resources, triangles))
    np.testing.assert_allclose(mesh.corner_colour[0], np.array([[128, 0, 0], [128, 128, 128], [128, 128, 128]]) / 255,
                               atol=1e-6)
    assert any("namespace prefix" in note and "ms" in note for note in mesh.notes), mesh.notes


@pytest.mark.parametrize(("name", "colours"), [("pyramid_vertexcolor.3mf", 4), ("rhombicuboctahedron_color.3mf", 5)])
def test_the_consortiums_colour_samples_read_their_colours(name, colours):
    """The samples' colour groups (4 corner colours; 5 face colours) all reach the corners."""
    mesh = read(MODELS / name)
    assert mesh.corner_colour is not None and mesh.up == (0.0, 0.0, 1.0)
    assert len(np.unique(np.round(mesh.corner_colour.reshape(-1, 3) * 255), axis=0)) == colours


def test_the_consortiums_multiproperties_sample_renders_its_base_colour(tmp_path):
    """multiprop-metallic.3mf declares no `ms:` prefix (trimesh refused it with lxml's namespace error, lib3mf too):
    its 12 triangles render in the base material's #C0C0C0; its texture layers carry alpha, which a map that
    multiplies cannot mix (a note)."""
    done = runner.invoke(app, ["render", str(MODELS / "multiprop-metallic.3mf"), "-o", str(tmp_path / "m.png"),
                               "--set", "render.width=64", "--set", "render.height=48"])
    assert done.exit_code == 0, done.output
    notes = " ".join(done.stderr.split())
    assert "namespace prefix" in notes and "alpha channel" in notes, notes
    mesh = read(MODELS / "multiprop-metallic.3mf")
    assert len(mesh.faces) == 12
    metal = [mesh.materials[g] for g in mesh.face_group if g >= 0]
    assert len(metal) == 10 and {m.name for m in metal} == {"Metal"} and metal[0].kd == pytest.approx((0xC0 / 255,) * 3)
    layered = mesh.face_group < 0  # the two multiproperties triangles: the base's colour per corner
    assert layered.sum() == 2 and np.allclose(mesh.corner_colour[layered], 0xC0 / 255)


@pytest.mark.parametrize(("resources", "triangles", "says"), [
    ("", '<triangle v1="0" v2="1" v3="2" pid="7" p1="0"/>', "property group 7"),
    ('<m:colorgroup id="2"><m:color color="#FF0000"/></m:colorgroup>',
     '<triangle v1="0" v2="1" v3="2" pid="2" p1="3"/>', "property index 3"),
    # An index equal to the group's count (one past its last entry): refused, not read past the end.
    ('<m:colorgroup id="2"><m:color color="#FF0000"/></m:colorgroup>',
     '<triangle v1="0" v2="1" v3="2" pid="2" p1="1"/>', "property index 1 is outside property group 2's 0..0"),
    ('<m:colorgroup id="2"><m:color color="red"/></m:colorgroup>', '<triangle v1="0" v2="1" v3="9"/>', "colour 'red'"),
    ('<m:colorgroup id="2"><m:color color="#FF0000"/></m:colorgroup><m:multiproperties id="6" pids="2">'
     '<m:multi pindices="-1"/><m:multi pindices="0"/></m:multiproperties>',
     '<triangle v1="0" v2="1" v3="2" pid="6" p1="0" p2="1"/>', "property index -1 is outside"),  # not 0's
    ("", '<triangle v1="0" v2="1" v3="9"/>', "vertex index outside 0..3"),
    # An index equal to the vertex count (one past the last): 3MF's own line, naming the object.
    ("", '<triangle v1="0" v2="4" v3="2"/>', "object 1 has a triangle with a vertex index outside 0..3"),
    ("", '<triangle v1="-1" v2="1" v3="2"/>', "object 1 has a triangle with a vertex index outside 0..3"),
    ("", '<triangle v1="0" v2="1" v3="2"/></triangles></mesh></object></resources></model', "not well-formed"),
])
def test_a_broken_3mf_is_one_line(tmp_path, resources, triangles, says):
    write_3mf(tmp_path / "bad.3mf", resources, triangles)
    done = runner.invoke(app, ["render", str(tmp_path / "bad.3mf"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert says in line, line


SLICE = "http://schemas.microsoft.com/3dmanufacturing/slice/2015/07"
BEAMS = "http://schemas.microsoft.com/3dmanufacturing/beamlattice/2017/02"
SECURE = "http://schemas.microsoft.com/3dmanufacturing/securecontent/2019/04"
TWO = '<triangle v1="0" v2="1" v3="2"/><triangle v1="0" v2="2" v3="3"/>'


@pytest.mark.parametrize(("extra_ns", "says"), [
    (f' xmlns:s="{SLICE}" requiredextensions="s"', "Slice (the model as stacks of 2-D slices)"),
    (f' xmlns:b="{BEAMS}" requiredextensions="b"', "Beam Lattice"),
    (f' xmlns:sc="{SECURE}" requiredextensions="sc"', "Secure Content (encrypted parts)"),
    (' xmlns:x="http://example.com/x/2030/01" requiredextensions="x"', "http://example.com/x/2030/01"),
    (' requiredextensions="q"', "'q' (a prefix the model does not declare)"),
])
def test_a_required_extension_not_read_is_refused_naming_it(tmp_path, extra_ns, says):
    """Core §2.3.1: a consumer must not read a file whose required extensions it does not support."""
    write_3mf(tmp_path / "r.3mf", "", TWO, extra_ns=extra_ns)
    with pytest.raises(SceneError) as caught:
        read(tmp_path / "r.3mf")
    assert f"requires the 3MF extension(s) {says}" in str(caught.value), str(caught.value)


def test_a_required_extension_that_is_read_reads(tmp_path):
    mesh = read(write_3mf(tmp_path / "m.3mf", "", TWO, extra_ns=' requiredextensions="m"'))
    assert len(mesh.faces) == 2


def test_a_slice_stack_s_2d_vertices_are_not_the_mesh_s(tmp_path):
    """A slice stack before the object: its <s:vertex x y> are 2-D (they were read as mesh vertices, NaN z)."""
    stack = ('<s:slicestack id="9" zbottom="0"><s:slice ztop="1"><s:vertices><s:vertex x="1" y="2"/>'
             '<s:vertex x="3" y="4"/></s:vertices><s:polygon startv="0"><s:segment v2="1"/></s:polygon></s:slice>'
             '</s:slicestack>')
    mesh = read(write_3mf(tmp_path / "s.3mf", stack, TWO, extra_ns=f' xmlns:s="{SLICE}"'))
    assert len(mesh.faces) == 2 and np.allclose(np.ptp(mesh.vertices, axis=0), [10, 10, 0])
    assert any("slice stack" in note for note in mesh.notes), mesh.notes


def test_a_beam_lattice_is_noted_with_its_beams(tmp_path):
    lattice = ('<b:beamlattice minlength="0.1" radius="1"><b:beams><b:beam v1="0" v2="2"/><b:beam v1="1" v2="3"/>'
               '</b:beams></b:beamlattice>')
    path = tmp_path / "b.3mf"
    write_3mf(path, "", TWO, extra_ns=f' xmlns:b="{BEAMS}"')
    with zipfile.ZipFile(path) as archive:
        model = archive.read("3D/3dmodel.model").decode()
    model = model.replace("</triangles></mesh>", f"</triangles>{lattice}</mesh>")
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    mesh = read(path)
    assert len(mesh.faces) == 2 and any("beam lattice of 2 beam(s)" in note for note in mesh.notes), mesh.notes


DRAFT_SQUARE = SQUARE + ('<texturevertices><texturevertex u="0" v="0"/><texturevertex u="1" v="0"/>'
                         '<texturevertex u="1" v="1"/><texturevertex u="0" v="1"/></texturevertices>')


def write_draft(path: Path, resources: str, triangles: str, object_attributes: str = "", files=None) -> Path:
    """A 0.93 draft package (namespace 2013/01): the square with texture vertices at its corners."""
    model = ('<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" '
             f'xmlns="http://schemas.microsoft.com/3dmanufacturing/2013/01"><resources>{resources}'
             f'<object id="9" type="model"{object_attributes}><mesh>{DRAFT_SQUARE}<triangles>{triangles}</triangles>'
             '</mesh></object></resources><build><item objectid="9"/></build></model>')
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
        for name, data in (files or {}).items():
            archive.writestr(name, data)
    return path


DRAFT_COLOURS = ('<color id="5" value="#FF0000"/><color id="6" value="#00FF00"/><color id="7" value="#0000FF"/>'
                 '<material id="3" name="Green ABS" colorid="6" type="ABS"/>')


def test_a_0_93_draft_model_s_colours_and_materials_are_read(tmp_path):
    """The draft (lib3mf's 3mfbase2_material093, its own samples) colours a triangle by `colorid` (one id, or
    "a,b,c" per corner) or `materialid` (a <material> shown in its colorid), or the object's; they were drawn
    grey, noted."""
    triangles = ('<triangle v1="0" v2="1" v3="2" colorid="5"/><triangle v1="0" v2="2" v3="3" colorid="5,6,7"/>'
                 '<triangle v1="1" v2="2" v3="3" materialid="3"/><triangle v1="0" v2="1" v3="3"/>')
    mesh = read(write_draft(tmp_path / "d.3mf", DRAFT_COLOURS, triangles, ' colorid="7"'))
    colour = np.round(mesh.corner_colour * 255).astype(int)  # -1: a triangle of a material (its k_d)
    corner = {(0, 0): 0, (10, 0): 1, (10, 10): 2, (0, 10): 3}  # the square's vertex numbers, by position
    number = [[corner[tuple(int(x) for x in mesh.vertices[v][:2])] for v in face] for face in mesh.faces]
    by_corners = {tuple(sorted(face)): k for k, face in enumerate(number)}
    assert (colour[by_corners[(0, 1, 2)]] == (255, 0, 0)).all()
    first = by_corners[(0, 2, 3)]
    assert {v: tuple(c) for v, c in zip(number[first], colour[first])} == {
        0: (255, 0, 0), 2: (0, 255, 0), 3: (0, 0, 255)}
    assert (colour[by_corners[(0, 1, 3)]] == (0, 0, 255)).all()  # the object's colorid
    material = mesh.materials[mesh.face_group[by_corners[(1, 2, 3)]]]
    assert material.name == "Green ABS" and material.kd == pytest.approx((0, 1, 0))
    assert not any("0.93" in note for note in mesh.notes), mesh.notes


def test_a_0_93_draft_texture_maps_its_texture_vertices(tmp_path):
    """A colour "tex(T)" names texture T; a triangle of that colour takes cv1..cv3 of its object's texture
    vertices (v up, as 1.0's tex2coord): the 2 × 2 image's red top row is at the square's +y side."""
    from PIL import Image
    png = io.BytesIO()
    image = Image.new("RGB", (2, 2), (0, 0, 255))
    image.putpixel((0, 0), (255, 0, 0))
    image.putpixel((1, 0), (255, 0, 0))
    image.save(png, "PNG")
    resources = '<texture id="1" path="/3D/Texture/t.texture" contenttype="image/png"/><color id="2" value="tex(1)"/>'
    triangles = ('<triangle v1="0" v2="1" v3="2" colorid="2" cv1="0" cv2="1" cv3="2"/>'
                 '<triangle v1="0" v2="2" v3="3" colorid="2" cv1="0" cv2="2" cv3="3"/>')
    path = write_draft(tmp_path / "t.3mf", resources, triangles, files={"3D/Texture/t.texture": png.getvalue()})
    mesh = read(path)
    np.testing.assert_allclose(mesh.corner_uv, mesh.vertices[mesh.faces][:, :, :2] / 10)
    assert mesh.materials[mesh.face_group[0]].kd_map >= 0
    # The memory check weighs the map though its name has no image suffix (the samples' "0000.texture").
    assert mesh_source(path).format.texture_sizes(mesh_source(path)) == ((2, 2),)


@pytest.mark.parametrize(("triangle", "said"), [
    ('colorid="8"', "colorid '8' names no plain colour"),
    ('colorid="5,6"', "colorid '5,6' names no plain colour"),
    ('colorid="tex(x)"', "names id 'x'"),
    ('materialid="99999999999"', "names id '99999999999'"),
    ('materialid="2147483648"', "names id '2147483648'; allowed: a resource id 0 .. 2147483647"),  # 2^31
])
def test_a_bad_0_93_draft_reference_is_one_line(tmp_path, triangle, said):
    path = write_draft(tmp_path / "b.3mf", DRAFT_COLOURS, f'<triangle v1="0" v2="1" v3="2" {triangle}/>')
    with pytest.raises(SceneError) as caught:
        read(path)
    assert said in str(caught.value) and "\n" not in str(caught.value), str(caught.value)


def test_the_count_the_memory_check_weighs_is_what_components_and_items_build(tmp_path):
    """Object 1 is 2 triangles; object 2 places it 3 times; object 3 places object 2 twice and object 1 once; the
    build places 3 twice and 1 once: 2 × (2 × 3 × 2 + 2) + 2 = 30 triangles, counted by a scan of the bytes
    before the read (a 2 kB file of components nested 8 deep builds 10^8 boxes: the count is what is refused)."""
    shift = 'transform="1 0 0 0 1 0 0 0 1 {} 0 0"'
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}"><resources>'
             f'<object id="1" type="model"><mesh>{SQUARE}<triangles><triangle v1="0" v2="1" v3="2"/>'
             '<triangle v1="0" v2="2" v3="3"/></triangles></mesh></object>'
             '<object id="2" type="model"><components>'
             + "".join(f'<component objectid="1" {shift.format(20 * k)}/>' for k in range(3)) +
             '</components></object><object id="3" type="model"><components>'
             f'<component objectid="2" {shift.format(100)}/><component objectid="2" {shift.format(200)}/>'
             f'<component objectid="1" {shift.format(300)}/></components></object></resources>'
             f'<build><item objectid="3"/><item objectid="3" {shift.format(1000)}/><item objectid="1"/></build>'
             '</model>')
    path = tmp_path / "nested.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    assert mesh_source(path).triangles() == 30
    assert len(read(path).faces) == 30


def chain_3mf(path: Path, objects: int) -> Path:
    """Object 1 the two-triangle square, each object k + 1 one component placing object k, the build the last:
    the square is reached through objects − 1 nested components."""
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}"><resources>'
             f'<object id="1" type="model"><mesh>{SQUARE}<triangles><triangle v1="0" v2="1" v3="2"/>'
             '<triangle v1="0" v2="2" v3="3"/></triangles></mesh></object>'
             + "".join(f'<object id="{k + 1}" type="model"><components><component objectid="{k}"/></components>'
                       "</object>" for k in range(1, objects)) +
             f'</resources><build><item objectid="{objects}"/></build></model>')
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    return path


def test_components_nested_32_deep_read_and_33_deep_are_refused(tmp_path):
    """MAX_DEPTH (32) nested components are a tree: read, and counted by the memory check's scan; one level more is
    refused in one line by the read, and weighs nothing in the scan. Catches `>` made `>=` in either the read or
    the scan, and the limit moved by one."""
    deep = chain_3mf(tmp_path / "deep.3mf", 33)
    assert mesh_source(deep).triangles() == 2
    assert len(read(deep).faces) == 2
    deeper = chain_3mf(tmp_path / "deeper.3mf", 34)
    assert mesh_source(deeper).triangles() == 0
    with pytest.raises(SceneError, match=r"components nest deeper than 32 \(a component that contains itself\?\)"):
        read(deeper)


# ---------------------------------------------------------------- placement: transforms, components, mirrors
# 3MF core §3.4.1: transform="m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32" places a point as the row vector
# (x y z 1) times the 4 × 3 matrix of those rows: p' = (x·m00 + y·m10 + z·m20 + m30, x·m01 + ..., ...). Every
# expectation below is that product worked out by hand.
MODEL_RELATION = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
TURN_Z = "0 1 0 -1 0 0 0 0 1"  # rows (0 1 0), (-1 0 0), (0 0 1): (x, y, z) → (-y, x, z), +90° about +Z
CONTENT_TYPES = ('<?xml version="1.0" encoding="UTF-8"?>\n<Types xmlns="http://schemas.openxmlformats.org/package/'
                 '2006/content-types"><Default Extension="rels" ContentType="application/vnd.openxmlformats-package.'
                 'relationships+xml"/><Default Extension="model" ContentType="application/vnd.ms-package.3dmanufac'
                 'turing-3dmodel+xml"/></Types>')
RELS = ('<?xml version="1.0" encoding="UTF-8"?>\n<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/'
        f'relationships"><Relationship Target="/3D/3dmodel.model" Id="rel0" Type="{MODEL_RELATION}"/></Relationships>')
ONE = '<triangle v1="0" v2="1" v3="2"/>'  # the square's (0 0 0), (10 0 0), (10 10 0)


def write_package(path: Path, resources: str, build: str) -> Path:
    """A full 3MF package (content types, relationships, model part) of `resources` and `build`."""
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}" xmlns:m="{MATERIAL}">'
             f'<resources>{resources}</resources><build>{build}</build></model>')
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("[Content_Types].xml", CONTENT_TYPES)
        archive.writestr("_rels/.rels", RELS)
        archive.writestr("3D/3dmodel.model", model)
    return path


def mesh_object(identity: int, triangles: str = ONE) -> str:
    return f'<object id="{identity}" type="model"><mesh>{SQUARE}<triangles>{triangles}</triangles></mesh></object>'


def corners(mesh) -> list[list[tuple]]:
    """Each face's corners as positions, rounded (the read's vertex numbering is its own)."""
    return [[tuple(np.round(mesh.vertices[v], 9) + 0.0) for v in face] for face in mesh.faces]



def test_a_build_item_s_transform_places_its_object_as_row_vector_times_matrix(tmp_path):
    """Item transform TURN_Z + (5, 6, 7): (x, y, z) → (5 - y, 6 + x, 7 + z). Catches the 3 × 3 applied transposed
    (a turn the wrong way: (10, 0, 0) → (5, -4, 7))."""
    mesh = read(write_package(tmp_path / "t.3mf", mesh_object(1), f'<item objectid="1" transform="{TURN_Z} 5 6 7"/>'))
    assert corners(mesh) == [[(5, 6, 7), (5, 16, 7), (-5, 16, 7)]]


def test_nested_components_compose_child_first_then_parent_then_item(tmp_path):
    """Object 3 holds object 2 translated by (10, 0, 0); object 2 holds object 1 turned by TURN_Z; the item scales
    x by 2: p' = p · B · A · I, so (10, 0, 0) → (0, 10, 0) → (10, 10, 0) → (20, 10, 0). Catches the composition
    parent after child reversed ((10, 0, 0) → (0, 30, 0)) at either level."""
    resources = (mesh_object(1)
                 + f'<object id="2" type="model"><components><component objectid="1" transform="{TURN_Z} 0 0 0"/>'
                 '</components></object><object id="3" type="model"><components>'
                 '<component objectid="2" transform="1 0 0 0 1 0 0 0 1 10 0 0"/></components></object>')
    mesh = read(write_package(tmp_path / "n.3mf", resources,
                              '<item objectid="3" transform="2 0 0 0 1 0 0 0 1 0 0 0"/><item objectid="2"/>'))
    assert corners(mesh) == [[(20, 0, 0), (20, 10, 0), (0, 10, 0)],   # item 1: B, then A, then I
                             [(0, 0, 0), (0, 10, 0), (-10, 10, 0)]]    # item 2: B alone


def test_a_mirrored_item_flips_the_winding_and_its_corner_colours_stay_at_their_corners(tmp_path):
    """An item mirrored in x (determinant -1) with p1 p2 p3 = red, green, blue at (0 0 0), (10 0 0), (10 10 0):
    the placed corners (0 0 0), (-10 0 0), (-10 10 0) keep red, green, blue, and the winding is reversed so the
    face still faces +Z. Catches the colours left in file order while the corners are reversed (red at -10 10 0)
    and the winding kept (the face turned to -Z)."""
    resources = ('<m:colorgroup id="5"><m:color color="#FF0000"/><m:color color="#00FF00"/><m:color color="#0000FF"/>'
                 '</m:colorgroup>' + mesh_object(1, '<triangle v1="0" v2="1" v3="2" pid="5" p1="0" p2="1" p3="2"/>'))
    mesh = read(write_package(tmp_path / "m.3mf", resources,
                              '<item objectid="1" transform="-1 0 0 0 1 0 0 0 1 0 0 0"/>'))
    [face] = corners(mesh)
    colour = {corner: tuple(np.round(c * 255).astype(int).tolist()) for corner, c in zip(face, mesh.corner_colour[0])}
    assert colour == {(0, 0, 0): (255, 0, 0), (-10, 0, 0): (0, 255, 0), (-10, 10, 0): (0, 0, 255)}
    a, b, c = (np.array(corner) for corner in face)
    assert np.cross(b - a, c - a)[2] > 0  # counter-clockwise seen from +Z: the mirrored face still faces up


def test_a_flattening_build_transform_keeps_the_faces_winding(tmp_path):
    """A build item transform that scales z by 0 (determinant exactly 0, not a mirror) leaves the square in
    z = 0 as it is, its faces wound as written and each corner's colour at its corner; only a negative
    determinant turns faces (and their property indices) over. Catches the mirror test taken as
    `determinant <= 0`, for the faces or for their corners' properties."""
    resources = ('<m:colorgroup id="5"><m:color color="#FF0000"/><m:color color="#00FF00"/>'
                 '<m:color color="#0000FF"/></m:colorgroup>')
    triangles = ('<triangle v1="0" v2="1" v3="2" pid="5" p1="0" p2="1" p3="2"/>'
                 '<triangle v1="0" v2="2" v3="3" pid="5" p1="2" p2="1" p3="0"/>')
    plain = read(write_3mf(tmp_path / "plain.3mf", resources, triangles))
    path = write_3mf(tmp_path / "flat.3mf", resources, triangles)
    with zipfile.ZipFile(path) as archive:
        model = archive.read("3D/3dmodel.model").decode()
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model.replace(
            '<item objectid="1"/>', '<item objectid="1" transform="1 0 0 0 1 0 0 0 0 0 0 0"/>'))
    flat = read(path)
    np.testing.assert_array_equal(flat.vertices[flat.faces], plain.vertices[plain.faces])
    np.testing.assert_array_equal(flat.corner_colour, plain.corner_colour)


# ---------------------------------------------------------------- the package: parts, relationships, broken members
PRODUCTION = "http://schemas.microsoft.com/3dmanufacturing/production/2015/06"


def test_a_zip_without_a_model_part_is_refused_and_not_counted(tmp_path):
    """A zip holding no 3D/3dmodel.model (and no relationship naming another) is no 3MF (core §2.1): refused in
    one line, and the cheap count gives none (the read words it). Catches the missing part read as None."""
    path = tmp_path / "empty.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("readme.txt", "no model here")
    with path.open("rb") as handle:
        assert mesh_source(path).format.count(handle, path.stat().st_size, None) is None
    with pytest.raises(SceneError) as caught:
        read(path)
    assert str(caught.value) == (f"{path}: cannot read the file as 3MF: it holds no model part "
                                 "(3D/3dmodel.model); allowed: a 3MF package with a 3D model"), str(caught.value)


def test_a_broken_relationships_part_falls_back_on_the_usual_model_part(tmp_path):
    """_rels/.rels that is not well-formed XML names no model part; the read falls back on 3D/3dmodel.model (the
    name every producer writes) and the count too. Catches the XML error let out of the fallback."""
    path = write_package(tmp_path / "r.3mf", mesh_object(1), '<item objectid="1"/>')
    with zipfile.ZipFile(path) as archive:
        parts = {name: archive.read(name) for name in archive.namelist()}
    parts["_rels/.rels"] = b"<Relationships><Relationship Target="
    with zipfile.ZipFile(path, "w") as archive:
        for name, data in parts.items():
            archive.writestr(name, data)
    assert corners(read(path)) == [[(0, 0, 0), (10, 0, 0), (10, 10, 0)]]
    assert mesh_source(path).triangles() == 1


def test_a_build_item_in_another_model_part_is_read_from_that_part(tmp_path):
    """The Production extension: a build item's p:path names the model part holding its object (here
    /3D/other.model, object 1: the square's triangle), read once and placed by the item's transform (x + 5).
    Catches the other part not read (the object then undefined) and p:path taken without its leading /."""
    root = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}" xmlns:p="{PRODUCTION}">'
            '<resources/><build><item objectid="1" p:path="/3D/other.model" transform="1 0 0 0 1 0 0 0 1 5 0 0"/>'
            '</build></model>')
    other = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}"><resources>'
             f'{mesh_object(1)}</resources><build/></model>')
    path = tmp_path / "p.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", root)
        archive.writestr("3D/other.model", other)
    assert corners(read(path)) == [[(5, 0, 0), (15, 0, 0), (15, 10, 0)]]
    assert mesh_source(path).triangles() == 1


@pytest.mark.parametrize("model", [b"", b"not xml at all"])
def test_a_model_part_that_is_not_xml_is_refused_as_not_well_formed(tmp_path, model):
    """A model part with no <model> element at all (empty, or plain text): no required extension to check, and the
    XML parse refuses it in one line. Catches the missing <model> tag taken as an error of its own (None[1])."""
    path = tmp_path / "x.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    with pytest.raises(SceneError) as caught:
        read(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: cannot read the file as 3MF: 3D/3dmodel.model is not well-formed XML ("), \
        message
    assert "\n" not in message


def test_a_model_part_corrupt_past_its_first_64_kib_is_refused_naming_the_part(tmp_path):
    """A stored model part of ~100 kB whose bytes past the first 64 KiB (the required-extension check's read) are
    changed: zipfile's CRC check fails while the XML is parsed, refused in one line naming the part. Catches the
    zip error let out of the parse (an internal error)."""
    resources = "".join(f"<!-- {'x' * 90} -->" for _ in range(1100))  # 100 kB of comments before the object
    path = write_3mf(tmp_path / "c.3mf", resources, TWO)
    data = bytearray(path.read_bytes())
    at = data.index(b"x" * 90, 80_000)
    data[at] = ord("y")  # still well-formed XML: only the checksum tells
    path.write_bytes(bytes(data))
    with pytest.raises(SceneError) as caught:
        read(path)
    assert str(caught.value) == (f"{path}: cannot read the file as 3MF: 3D/3dmodel.model: Bad CRC-32 for file "
                                 "'3D/3dmodel.model'"), str(caught.value)


@pytest.mark.parametrize("batch", [1, 2, 3, 5])
def test_more_vertices_and_triangles_than_a_batch_are_read_across_it(tmp_path, monkeypatch, batch):
    """The parse drops every BATCH vertices or triangles it has read (the tree is never held whole): with a batch
    of 1 to 5, a strip's 7 vertices and 5 triangles cross several drops, and every value is still its own. The
    drop took every sibling but the last the parser had made, which may be one read ahead and not yet yielded:
    at the next drop that one had no parent (TypeError, an internal error) for batches 1, 2 and 5; 8192 hid it (the
    read-ahead of a 32 kB block holds fewer elements)."""
    from raycast_phong.io.meshes import threemf
    monkeypatch.setattr(threemf, "BATCH", batch)
    strip = "".join(f'<vertex x="{10 * (k // 2)}" y="{10 * (k % 2)}" z="{k}"/>' for k in range(7))
    triangles = "".join(f'<triangle v1="{k}" v2="{k + 1}" v3="{k + 2}"/>' for k in range(5))
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model unit="millimeter" xmlns="{CORE}"><resources>'
             f'<object id="1" type="model"><mesh><vertices>{strip}</vertices><triangles>{triangles}</triangles>'
             '</mesh></object></resources><build><item objectid="1"/></build></model>')
    path = tmp_path / "b.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    mesh = read(path)
    assert corners(mesh) == [[(10 * (j // 2), 10 * (j % 2), j) for j in (k, k + 1, k + 2)] for k in range(5)]


@pytest.mark.parametrize(("transform", "shown"), [("1 0 0 0 1 0 0 0 1 a b c", "'1 0 0 0 1 0 0 0 1 a b c'"),
                                                  ("1 0 0 0 1 0 0 0 1 0 0", "'1 0 0 0 1 0 0 0 1 0 0'"),
                                                  ("1 0 0 0 1 0 0 0 1 0 0 nan", "'1 0 0 0 1 0 0 0 1 0 0 nan'")])
def test_a_transform_that_is_not_12_finite_numbers_is_refused(tmp_path, transform, shown):
    """Core §3.4.1: a transform is 12 numbers (the 3 × 3 matrix by rows, then the translation). Words, 11 numbers
    or a NaN are refused in one line quoting it. Catches the words let through as a ValueError, or a short or
    non-finite matrix used."""
    path = write_package(tmp_path / "t.3mf", mesh_object(1), f'<item objectid="1" transform="{transform}"/>')
    with pytest.raises(SceneError) as caught:
        read(path)
    assert str(caught.value) == (f"{path}: transform {shown} is not 12 finite numbers; allowed: "
                                 "'m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32'"), str(caught.value)


@pytest.mark.parametrize("vertex", ['x="abc" y="0"', 'x="10"'])
def test_a_vertex_coordinate_that_is_not_a_number_is_refused(tmp_path, vertex):
    """x="abc" (numpy's text reader stops at it: a ValueError in numpy 2) or y left out (core §4.1.1: x, y and z
    are required): refused in one line saying what it is. A missing y was read as NaN (np.array makes None a
    float NaN) and refused as a NaN coordinate, or drawn when no face used the vertex. Catches either error let
    out, or the column read short."""
    path = write_3mf(tmp_path / "v.3mf", "", TWO)
    with zipfile.ZipFile(path) as archive:
        model = archive.read("3D/3dmodel.model").decode().replace('x="10" y="0"', vertex, 1)
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("3D/3dmodel.model", model)
    with pytest.raises(SceneError) as caught:
        read(path)
    assert str(caught.value) == (f"{path}: a vertex coordinate that is not a number (or is missing); "
                                 "allowed: numbers as the 3MF core specification writes them"), str(caught.value)


def test_a_tex2coord_beyond_float32_is_refused(tmp_path):
    """Texture coordinates are kept as float32 per corner: u = 1e39 cannot be one (it would be inf); refused
    naming the group and the range. Catches the limit check dropped."""
    resources = ('<m:texture2d id="3" path="/3D/Texture/t.png" contenttype="image/png"/>'
                 '<m:texture2dgroup id="4" texid="3"><m:tex2coord u="1e39" v="0"/></m:texture2dgroup>')
    path = write_3mf(tmp_path / "u.3mf", resources, '<triangle v1="0" v2="1" v3="2" pid="4" p1="0"/>')
    with pytest.raises(SceneError) as caught:
        read(path)
    assert str(caught.value) == (f"{path}: texture2dgroup 4 has a tex2coord beyond float32's range; "
                                 "allowed: -3.403e+38 .. 3.403e+38"), str(caught.value)


def test_a_build_item_naming_an_undefined_object_is_refused(tmp_path):
    """Core §3.4: an item's objectid must be an object of its part. Refused in one line naming it. Catches the
    missing object skipped silently or an internal KeyError."""
    path = write_package(tmp_path / "o.3mf", mesh_object(1), '<item objectid="7"/>')
    with pytest.raises(SceneError) as caught:
        read(path)
    assert str(caught.value) == (f"{path}: the build names object 7 of 3D/3dmodel.model, which it does "
                                 "not define; allowed: the id of an <object> of that part"), str(caught.value)


# ---------------------------------------------------------------- textures: shared, missing, not images, in layers
def png(colour=(200, 10, 10), mode="RGB") -> bytes:
    from PIL import Image
    data = io.BytesIO()
    Image.new(mode, (2, 2), colour).save(data, "PNG")
    return data.getvalue()


TEXTURE = ('<m:texture2d id="3" path="/3D/Texture/t.png" contenttype="image/png"/>'
           '<m:texture2dgroup id="4" texid="3"><m:tex2coord u="0" v="0"/><m:tex2coord u="1" v="0"/>'
           '<m:tex2coord u="1" v="1"/></m:texture2dgroup>')
TEXTURED = '<triangle v1="0" v2="1" v3="2" pid="4" p1="0" p2="1" p3="2"/>'


def not_read(mesh) -> list[str]:
    return [note.split(": not read: ", 1)[1] for note in mesh.notes if ": not read: " in note]


def test_a_texture_placed_twice_is_one_map(tmp_path):
    """Two build items of one textured object: both instances' triangles use the one material and map (the image
    is opened once). Catches the texture made again for each instance (two maps of one image)."""
    path = write_package(tmp_path / "two.3mf", TEXTURE + mesh_object(1, TEXTURED),
                         '<item objectid="1"/><item objectid="1" transform="1 0 0 0 1 0 0 0 1 20 0 0"/>')
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("3D/Texture/t.png", png())
    mesh = read(path)
    assert len(mesh.faces) == 2 and len(mesh.texture_sources) == 1 and len(set(mesh.face_group.tolist())) == 1
    assert mesh.materials[mesh.face_group[0]].kd_map == 0


@pytest.mark.parametrize(("resources", "files", "said"), [
    (TEXTURE, {"3D/Texture/t.png": b"not an image"}, "'3D/Texture/t.png', missing or not an image"),
    (TEXTURE, {}, "'3D/Texture/t.png', missing or not an image"),
    (TEXTURE.replace('texid="3"', 'texid="9"'), {}, "'texture2d 9', missing or not an image"),
    (TEXTURE.replace('texid="3"', 'texid="2"') + '<m:colorgroup id="2"><m:color color="#FF0000"/></m:colorgroup>',
     {}, "'texture2d 2', missing or not an image"),  # texid names a colour group, not a texture2d
])
def test_a_texture_missing_or_not_an_image_leaves_the_default_material_with_a_note(tmp_path, resources, files, said):
    """A texture2d whose part is not an image PIL reads, is missing, or a texid naming no texture2d: the triangles
    keep their texture coordinates but no map, the default material, one note naming it; the memory estimate
    weighs no image for it. Catches PIL's error let out, and the note dropped."""
    mesh = read(write_3mf(tmp_path / "t.3mf", resources, TEXTURED, files))
    assert (mesh.face_group == -1).all() and mesh.texture_sources == ()
    assert not_read(mesh) == [f"{said} (its triangles use the default material)"], mesh.notes
    source = mesh_source(tmp_path / "t.3mf")
    assert source.format.texture_sizes(source) == ()


def test_the_texture_sizes_skip_a_member_that_is_not_an_image(tmp_path):
    """The memory estimate weighs each image in the zip by its header: a .png member that is not one is skipped
    (the read notes it), the others still weighed. Catches PIL's error ending the scan (no sizes at all)."""
    path = write_3mf(tmp_path / "s.3mf", TEXTURE, TEXTURED, {"3D/Texture/a.png": b"not an image",
                                                            "3D/Texture/t.png": png()})
    source = mesh_source(path)
    assert source.format.texture_sizes(source) == ((2, 2),)


def test_the_texture_sizes_of_a_file_that_is_no_zip_are_none(tmp_path):
    """The memory estimate asks for the images' sizes before the read: a .3mf that is no zip has none (the read
    then refuses it), and its unzipped size is 0, so its floor is its own size. Catches zipfile's error let out
    of either."""
    from types import SimpleNamespace

    from raycast_phong.io.meshes import threemf
    path = tmp_path / "z.3mf"
    path.write_bytes(b"PK but no zip" * 10)
    assert threemf.FORMAT.texture_sizes(SimpleNamespace(path=path)) == ()
    assert threemf._unzipped(path) == 0 and threemf._unzipped(tmp_path / "gone.3mf") == 0
    assert threemf.FORMAT.floor(path, 130, None) == 130


def test_a_texture2d_named_as_a_triangle_s_property_group_is_the_default_material(tmp_path):
    """A triangle's pid must name a property group (basematerials, colorgroup, texture2dgroup, compositematerials
    or multiproperties; materials §1); a texture2d is none (a texture2dgroup's texid names it). Its triangles are
    drawn in the default material, noted naming it a texture2d. The note named it by its image's path
    ("3D/Texture/t.png resources"); catches that and the note dropped."""
    mesh = read(write_3mf(tmp_path / "p.3mf", TEXTURE, '<triangle v1="0" v2="1" v3="2" pid="3" p1="0"/>',
                          {"3D/Texture/t.png": png()}))
    assert (mesh.face_group == -1).all() and mesh.corner_colour is None and mesh.corner_uv is None
    assert not_read(mesh) == ["texture2d resources named as a triangle's property group (their triangles use the "
                              "default material)"], mesh.notes


def test_multiproperties_read_the_first_texture_layer_and_note_the_rest(tmp_path):
    """A multiproperties of a colour group and two texture groups (pids 2 4 5): per corner, the colour group's
    colour and the first texture group's coordinates with its image as the map; the second texture layer is not
    read, noted. Corners' rows: (0 0 0), (1 1 0), (0 2 0): red at (0,0), green at (1,0), red at (1,1). Catches the
    first texture layer not taken (no map), its coordinates taken from the wrong column, the later layer taking
    its place, and the note dropped."""
    resources = (TEXTURE + '<m:texture2dgroup id="5" texid="3"><m:tex2coord u="0.5" v="0.5"/></m:texture2dgroup>'
                 '<m:colorgroup id="2"><m:color color="#FF0000"/><m:color color="#00FF00"/></m:colorgroup>'
                 '<m:multiproperties id="6" pids="2 4 5"><m:multi pindices="0 0 0"/><m:multi pindices="1 1 0"/>'
                 '<m:multi pindices="0 2 0"/></m:multiproperties>')
    triangle = '<triangle v1="0" v2="1" v3="2" pid="6" p1="0" p2="1" p3="2"/>'
    mesh = read(write_3mf(tmp_path / "m.3mf", resources, triangle, {"3D/Texture/t.png": png()}))
    np.testing.assert_array_equal(mesh.corner_colour[0], [[1, 0, 0], [0, 1, 0], [1, 0, 0]])
    np.testing.assert_array_equal(mesh.corner_uv[0], [[0, 0], [1, 0], [1, 1]])
    material = mesh.materials[mesh.face_group[0]]
    assert material.kd_map == 0 and material.kd == (1.0, 1.0, 1.0)
    assert not_read(mesh) == ["multiproperties' texture layers after the first"], mesh.notes


@pytest.mark.parametrize(("pids", "said"), [("2 99", "undefined"), ("2 3", "texture2d"), ("2 7", "multiproperties")])
def test_a_multiproperties_layer_that_is_no_colour_or_texture_group_is_noted(tmp_path, pids, said):
    """A layer id naming nothing, a texture2d (no property group) or another multiproperties (which materials §5
    forbids as a layer): not read, one note saying what it is; the colour layer still colours. The note said
    "undefined" of the last two; catches that and the note dropped."""
    resources = (TEXTURE + '<m:colorgroup id="2"><m:color color="#00FF00"/></m:colorgroup>'
                 '<m:multiproperties id="7" pids="2"><m:multi pindices="0"/></m:multiproperties>'
                 f'<m:multiproperties id="6" pids="{pids}"><m:multi pindices="0 0"/></m:multiproperties>')
    mesh = read(write_3mf(tmp_path / "u.3mf", resources, '<triangle v1="0" v2="1" v3="2" pid="6" p1="0"/>',
                          {"3D/Texture/t.png": png()}))
    np.testing.assert_array_equal(mesh.corner_colour[0], [[0, 1, 0]] * 3)
    assert not_read(mesh) == [f"multiproperties' {said} layers"], mesh.notes


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("transform", ["1e300 0 0 0 1e300 0 0 0 1e300 0 0 0", "1 0 0 0 1 0 0 0 1 nan 0 0"])
def test_an_item_transform_past_float_range_is_one_line_and_no_numpy_warning(transform, tmp_path):
    """An item scaled by 1e300 (its determinant overflows) or moved by NaN: the read's values check words it;
    numpy's "overflow encountered in det" or "invalid value" must not reach the user first."""
    path = write_package(tmp_path / "far.3mf", mesh_object(1), f'<item objectid="1" transform="{transform}"/>')
    with pytest.raises(SceneError, match=r"vertex\(es\) with a coordinate beyond|is not 12 finite numbers"):
        read(path)
