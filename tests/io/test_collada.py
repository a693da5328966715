"""COLLADA files whose geometry trimesh's reader dropped ("holds no triangles", issue 33): a skinned mesh
(`<instance_controller>`) renders in its bind-shape pose, and a material whose effect has no profile_COMMON
renders with the default material. Minimal documents written here, after assimp's box_nested_animation.dae
(a skinned cube from Blender) and cube_emptyTags.dae (a material it does not define)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes.source import mesh_source, read_mesh

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")

EFFECTS = {
    "common": '<profile_COMMON><technique sid="t"><lambert><diffuse><color>1 0 0 1</color></diffuse></lambert>'
              '</technique></profile_COMMON>',
    "glsl": '<profile_GLSL><technique sid="t"><pass sid="p"/></technique></profile_GLSL>',
    "phong": '<profile_COMMON><technique sid="t"><phong><emission><color>0 0 0.25 1</color></emission>'
             '<ambient><color>0.1 0.2 0.3 1</color></ambient><diffuse><color>0.8 0.2 0.2 1</color></diffuse>'
             '<specular><color>0.5 0.5 0.5 1</color></specular><shininess><float>20</float></shininess>'
             '</phong></technique></profile_COMMON>',
    "shiny": '<profile_COMMON><technique sid="t"><blinn><diffuse><color>0.8 0.2 0.2 1</color></diffuse>'
             '<specular><color>0.5 0.5 0.5 1</color></specular><shininess><float>200</float></shininess>'
             '</blinn></technique></profile_COMMON>',
    "rgb": '<profile_COMMON><technique sid="t"><phong><emission><color>0 0 0.25</color></emission>'
           '<ambient><color>0.1 0.2 0.3</color></ambient><diffuse><color>0.8 0.2 0.2 1</color></diffuse>'
           '<specular><color>0.5 0.5 0.5</color></specular><shininess><float>20</float></shininess>'
           '</phong></technique></profile_COMMON>',  # colours of three numbers, no alpha
    "constant": '<profile_COMMON><technique sid="t"><constant><emission><color>0 1 0 1</color></emission>'
                '</constant></technique></profile_COMMON>',
}


def write_dae(path: Path, effect: str, skinned: bool, bind_shape: str = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1") -> Path:
    """One triangle (0,0,0) (1,0,0) (0,1,0) bound to material `m`, instanced directly or through a skin."""
    controller = ('<library_controllers><controller id="skin"><skin source="#tri">'
                  f'<bind_shape_matrix>{bind_shape}</bind_shape_matrix></skin></controller></library_controllers>')
    binding = ('<bind_material><technique_common><instance_material symbol="m" target="#mat"/>'
               '</technique_common></bind_material>')
    instance = (f'<instance_controller url="#skin">{binding}</instance_controller>' if skinned
                else f'<instance_geometry url="#tri">{binding}</instance_geometry>')
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">'
        f'<library_effects><effect id="fx">{EFFECTS[effect]}</effect></library_effects>'
        '<library_materials><material id="mat"><instance_effect url="#fx"/></material></library_materials>'
        '<library_geometries><geometry id="tri"><mesh><source id="p"><float_array id="pa" count="9">'
        '0 0 0 1 0 0 0 1 0</float_array><technique_common><accessor source="#pa" count="3" stride="3">'
        '<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor>'
        '</technique_common></source><vertices id="v"><input semantic="POSITION" source="#p"/></vertices>'
        '<triangles material="m" count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2</p>'
        f'</triangles></mesh></geometry></library_geometries>{controller if skinned else ""}'
        f'<library_visual_scenes><visual_scene id="s"><node id="n">{instance}</node></visual_scene>'
        '</library_visual_scenes><scene><instance_visual_scene url="#s"/></scene></COLLADA>')
    return path


def read(path: Path) -> mesh_file.MeshFile:
    return read_mesh(path, str(path))


def test_a_skinned_mesh_renders_in_its_bind_shape_pose(tmp_path):
    """The skin's source triangle, moved by its bind_shape_matrix (translate x by 5), with its material."""
    mesh = read(write_dae(tmp_path / "skin.dae", "common", True, "1 0 0 5 0 1 0 0 0 0 1 0 0 0 0 1"))
    assert sorted(map(tuple, mesh.vertices[mesh.faces[0]].round(9).tolist())) == [(5, 0, 0), (5, 1, 0), (6, 0, 0)]
    assert mesh.materials[mesh.face_group[0]].kd == pytest.approx((1, 0, 0))
    assert any("bind-shape pose" in note for note in mesh.notes), mesh.notes


@pytest.mark.parametrize("skinned", [False, True])
def test_a_skinned_mesh_counts_its_source_s_triangles_before_the_read(tmp_path, skinned):
    """The memory estimate's count follows an <instance_controller> to the mesh its <skin> names in `source`
    (COLLADA 1.4.1: <skin source="#geometry">, as <morph source=...>): one triangle either way. Before, it
    looked for a `mesh` attribute no skin has and counted 0."""
    from raycast_phong.io.meshes.source import mesh_source
    assert mesh_source(write_dae(tmp_path / "m.dae", "common", skinned)).triangles() == 1


def test_an_effect_without_profile_common_renders_with_the_default_material(tmp_path):
    write_dae(tmp_path / "glsl.dae", "glsl", False)
    done = runner.invoke(app, ["render", str(tmp_path / "glsl.dae"), "-o", str(tmp_path / "x.png"), "--set",
                               "render.width=20", "--set", "render.height=20"])
    assert done.exit_code == 0, done.output
    assert "profile_COMMON" in " ".join(done.stderr.split())
    mesh = read(tmp_path / "glsl.dae")
    assert len(mesh.faces) == 1 and (mesh.face_group == -1).all()


def test_a_document_that_needs_no_change_is_read_as_it_was(tmp_path):
    """A plain instance with a profile_COMMON effect: the bytes go to trimesh unchanged, no note."""
    from raycast_phong.io.meshes.collada import collada_text
    data = write_dae(tmp_path / "plain.dae", "common", False).read_bytes()
    notes: list[str] = []
    assert collada_text(data, tmp_path / "plain.dae", notes) is data and notes == []
    assert np.allclose(read(tmp_path / "plain.dae").vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


def write_triangle(path: Path, positions: str = "0 0 0 1 0 0 0 1 0", asset: str = "", colours: str = "") -> Path:
    """One triangle: `positions` as the float_array's text, `asset` inside <asset>, and `colours` (three RGB
    triples) as a COLOR input beside the VERTEX one when given, then with a white material `m` (trimesh keeps
    colours beside a material elsewhere than without one)."""
    colour_source = ('<source id="c"><float_array id="ca" count="9">' f'{colours}</float_array><technique_common>'
                     '<accessor source="#ca" count="3" stride="3"><param name="R" type="float"/>'
                     '<param name="G" type="float"/><param name="B" type="float"/></accessor></technique_common>'
                     '</source>') if colours else ""
    colour_input = '<input semantic="COLOR" source="#c" offset="1" set="0"/>' if colours else ""
    indices = "0 0 1 1 2 2" if colours else "0 1 2"
    library = ('<library_effects><effect id="fx"><profile_COMMON><technique sid="t"><lambert><diffuse><color>'
               '1 1 1 1</color></diffuse></lambert></technique></profile_COMMON></effect></library_effects>'
               '<library_materials><material id="mat"><instance_effect url="#fx"/></material></library_materials>'
               ) if colours else ""
    binding = ('<bind_material><technique_common><instance_material symbol="m" target="#mat"/>'
               '</technique_common></bind_material>') if colours else ""
    bound = 'material="m" ' if colours else ""
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">'
        f'<asset>{asset}</asset>{library}'
        '<library_geometries><geometry id="tri"><mesh><source id="p"><float_array id="pa" count="9">'
        f'{positions}</float_array><technique_common><accessor source="#pa" count="3" stride="3">'
        '<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor>'
        f'</technique_common></source>{colour_source}<vertices id="v"><input semantic="POSITION" source="#p"/>'
        f'</vertices><triangles {bound}count="1">'
        '<input semantic="VERTEX" source="#v" offset="0"/>'
        f'{colour_input}<p>{indices}</p></triangles></mesh></geometry></library_geometries>'
        '<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#tri">'
        f'{binding}</instance_geometry></node>'
        '</visual_scene></library_visual_scenes><scene><instance_visual_scene url="#s"/></scene></COLLADA>')
    return path


def test_decimal_commas_are_read_as_decimal_points(tmp_path):
    """assimp's teapots.DAE and earthCylindrical.DAE write `0,5` (a comma locale): pycollada dropped every such
    array ("holds no triangles"); the triangle (0,0,0) (1.5,0,0) (0,2.25,0) is read with a note."""
    mesh = read(write_triangle(tmp_path / "comma.dae", "0 0 0 1,5 0 0 0 2,25 0"))
    assert sorted(map(tuple, mesh.vertices[mesh.faces[0]].tolist())) == [(0, 0, 0), (0, 2.25, 0), (1.5, 0, 0)]
    assert any("decimal comma" in note for note in mesh.notes), mesh.notes


def test_a_stated_up_axis_is_the_framing_up(tmp_path):
    """<up_axis>Z_UP</up_axis> makes +Z the up (as 3MF's is; teapot_instancenodes.DAE was seen from above),
    X_UP +X; none, or Y_UP, leaves +Y (COLLADA's default)."""
    for axis, up in (("Z", (0, 0, 1)), ("X", (1, 0, 0)), ("Y", (0, 1, 0))):
        assert read(write_triangle(tmp_path / f"{axis}.dae", asset=f"<up_axis>{axis}_UP</up_axis>")).up == up
    assert read(write_triangle(tmp_path / "none.dae")).up is None
    done = runner.invoke(app, ["scene", str(tmp_path / "Z.dae")])
    assert done.exit_code == 0, done.output
    assert "up = [0.0, 0.0, 1.0]" in done.stdout, done.stdout


@pytest.mark.parametrize(("padding", "up"), [(0, (0.0, 0.0, 1.0)), (1, None)])
def test_the_up_axis_is_looked_for_in_the_first_64_kib(padding, up):
    """The up axis is searched for in the document's first 64 KiB (ASSET_LIMIT; exporters write <asset> first):
    an <up_axis> ending exactly at byte 65,536 is found, one a byte later is not (COLLADA's default then).
    Catches the limit one off or doubled (the size is written here, not taken from the module)."""
    from raycast_phong.io.meshes.collada import collada_up
    tag = b"<up_axis>Z_UP</up_axis>"
    data = b" " * ((1 << 16) - len(tag) + padding) + tag
    assert collada_up(data) == up


def test_a_colour_input_gives_vertex_colours(tmp_path):
    """A COLOR input beside a material (kwxport_test_vcolors.dae rendered white): red, green, blue at the
    three corners."""
    mesh = read(write_triangle(tmp_path / "colours.dae", colours="1 0 0 0 1 0 0 0 1"))
    assert mesh.corner_colour is not None
    corners = {tuple(mesh.vertices[v].tolist()): tuple(mesh.corner_colour[0, k].tolist())
               for k, v in enumerate(mesh.faces[0])}
    assert corners == {(0, 0, 0): (1, 0, 0), (1, 0, 0): (0, 1, 0), (0, 1, 0): (0, 0, 1)}


@pytest.mark.parametrize(("positions", "indices", "words"), [
    ("0 0 0 1 NaN 0 0 1 0", "0 1 2", "positions pa hold NaN or infinite numbers"),
    ("0 0 0 1 0 0 0 INF 0", "0 1 2", "positions pa hold NaN or infinite numbers"),
    ("0 0 0 1 0 0 0 1 0", "<p>0 1 -1</p>", "a <p> list holds a negative index (-1)"),
    ("0 0 0 1 0 0 0 1 0", "<vcount>-3</vcount><p>0 1 2</p>", "a <vcount> list holds a negative index (-3)"),
    ("0 0 0 1 0 0 0 1 0", "<p>0 1 3</p>", "names vertex 3 of the 3 its positions p hold; allowed: 0..2"),
])
def test_what_pycollada_reads_silently_wrong_is_refused(tmp_path, positions, indices, words):
    """pycollada read NaN as 0 and numpy wrapped index -1 to the last vertex, silently (a polygon's negative
    corner count in a <polylist>'s <vcount> too); an index past the positions made trimesh drop the geometry
    without a word ("holds no triangles" for a file of one)."""
    path = write_triangle(tmp_path / "t.dae", positions)
    text = path.read_text().replace("<p>0 1 2</p>", indices)
    if "<vcount>" in indices:
        text = text.replace("<triangles ", "<polylist ").replace("</triangles>", "</polylist>")
    path.write_text(text)
    with pytest.raises(rp.SceneError, match=re.escape(words)):
        read(path)


def test_the_count_the_memory_check_weighs_is_what_instance_nodes_build(tmp_path):
    """A node placing the triangle, a library node instancing it three times and the scene instancing that twice
    beside one more triangle: 1 × 3 × 2 + 1 = 7 triangles, counted before trimesh expands them (a 2 kB
    document of instance_nodes ten wide and eight deep places 10^8 boxes)."""
    path = write_triangle(tmp_path / "t.dae")
    text = path.read_text()
    library = ('<library_nodes><node id="one"><instance_geometry url="#tri"/></node><node id="three">'
               + '<node><instance_node url="#one"/></node>' * 3 + '</node></library_nodes>')
    text = text.replace("<library_visual_scenes>", library + "<library_visual_scenes>")
    text = text.replace('<node id="n"><instance_geometry url="#tri"></instance_geometry></node>',
                        '<node><instance_node url="#three"/></node><node><instance_node url="#three"/></node>'
                        '<node><instance_geometry url="#tri"/></node>')
    path.write_text(text)
    assert mesh_source(path).triangles() == 7
    assert len(read(path).faces) == 7
    # Two instance_nodes side by side in one node add up too (2 × 3 + 1).
    path.write_text(text.replace('<node><instance_node url="#three"/></node><node><instance_node url="#three"/></node>',
                                 '<node><instance_node url="#three"/><instance_node url="#three"/></node>'))
    assert mesh_source(path).triangles() == 7


@pytest.mark.parametrize(("effect", "ka", "kd", "ks", "shininess", "ke"), [
    # phong: f = 20 is wider than the scene's lobe (32), so k_s is lowered by (20 + 2)/(32 + 2) (docs/meshes.md)
    ("phong", (0.1, 0.2, 0.3), (0.8, 0.2, 0.2), (0.5 * 22 / 34,) * 3, 20.0, (0, 0, 0.25)),
    ("rgb", (0.1, 0.2, 0.3), (0.8, 0.2, 0.2), (0.5 * 22 / 34,) * 3, 20.0, (0, 0, 0.25)),  # the same as RGB alone
    ("shiny", (0.8, 0.2, 0.2), (0.8, 0.2, 0.2), (0.5,) * 3, 200.0, (0, 0, 0)),  # no ambient: k_a = k_d
    ("common", (1, 0, 0), (1, 0, 0), (0, 0, 0), None, (0, 0, 0)),  # lambert: no specular term
    ("constant", (0, 0, 0), (0, 0, 0), (0, 0, 0), None, (0, 1, 0)),  # emission only
])
def test_collada_s_own_effects_are_the_lecture_s_model_read_as_written(tmp_path, effect, ka, kd, ks, shininess, ke):
    """<profile_COMMON>'s phong, blinn, lambert and constant are the lecture's model: trimesh turned them into
    metallic-roughness (specular and ambient dropped, s = 20 read back as f = 240, k_s = 0.04), and the note named
    a workflow the file does not use. Now read as written, with no approximation note."""
    mesh = read(write_dae(tmp_path / f"{effect}.dae", effect, False))
    material = mesh.materials[mesh.face_group[0]]
    assert material.ka == pytest.approx(ka, abs=2e-3) and material.kd == pytest.approx(kd, abs=2e-3)
    assert material.ks == pytest.approx(ks, abs=1e-6) and material.ke == pytest.approx(ke, abs=1e-6)
    if shininess is not None:
        assert material.shininess == pytest.approx(shininess)
    assert not any("approximated" in note for note in mesh.notes), mesh.notes


def test_a_document_lxml_cannot_parse_is_passed_on_as_it_is(tmp_path):
    """collada_text changes only what it can parse: a document cut short is given to trimesh byte for byte (which
    words what is wrong), with no note; the memory estimate counts nothing for it (None: the size bound stands)."""
    import io

    from raycast_phong.io.meshes import collada
    data = b'<COLLADA><library_visual_scenes><node><instance_material target="#m"/>'
    notes: list[str] = []
    assert collada.collada_text(data, tmp_path / "cut.dae", notes) is data and notes == []
    assert collada.count(io.BytesIO(data), len(data), None) is None


def test_a_controller_whose_source_is_not_a_geometry_is_left_as_written(tmp_path):
    """<skin source> names the mesh a controller deforms; one naming an effect (not a <geometry>) is not turned
    into a geometry instance of it: the document is passed on unchanged, with no bind-shape note."""
    from raycast_phong.io.meshes.collada import collada_text
    path = write_dae(tmp_path / "skin.dae", "common", True)
    data = path.read_bytes().replace(b'<skin source="#tri">', b'<skin source="#fx">')
    notes: list[str] = []
    assert collada_text(data, path, notes) is data and notes == []


def test_a_bind_shape_matrix_that_is_not_16_numbers_is_not_applied(tmp_path):
    """A bind_shape_matrix with a word among its numbers cannot place the mesh: the skin's source triangle is
    drawn where its positions put it (the bind-shape note still said), not refused or moved."""
    from raycast_phong.io.meshes.collada import collada_text
    path = write_dae(tmp_path / "skin.dae", "common", True, "1 0 0 5 0 1 0 0 0 0 1 0 0 0 0 one")
    assert b"<matrix>" not in collada_text(path.read_bytes(), path, [])  # no node placing it by that matrix
    mesh = read(path)
    assert sorted(map(tuple, mesh.vertices[mesh.faces[0]].round(9).tolist())) == [(0, 0, 0), (0, 1, 0), (1, 0, 0)]
    assert any("bind-shape pose" in note for note in mesh.notes), mesh.notes


def test_an_effect_colour_that_is_not_numbers_is_no_colour():
    """A <color> whose text holds a word is no colour (None: as if the effect had none) rather than a refusal;
    the effect's other colours are read (COLLADA 1.4.1: <color> is four floats)."""
    from raycast_phong.io.meshes.collada import _tree, common_effects
    effect = EFFECTS["phong"].replace("<color>0.5 0.5 0.5 1</color>", "<color>0.5 half 0.5 1</color>")
    document = (f'<COLLADA><library_effects><effect id="fx">{effect}</effect></library_effects><library_materials>'
                '<material id="mat"><instance_effect url="#fx"/></material></library_materials></COLLADA>')
    [found] = common_effects(_tree(document.encode()))
    assert found.specular is None and found.diffuse == (0.8, 0.2, 0.2, 1.0) and found.shininess == 20.0


def test_a_material_no_effect_makes_keeps_its_own_reading():
    """_as_effect reads a material as the effect trimesh made it from (its base colour = the diffuse × 255, its
    emission, roughness √(2/(2 + s))); a material no effect makes (blue, where the only effect is red) is
    None: it keeps the glTF rule's reading. The red one is the effect's."""
    from types import SimpleNamespace

    from raycast_phong.io.meshes.collada import CommonEffect, _as_effect
    from raycast_phong.io.meshes.materials import FileMaterial
    red = CommonEffect("lambert", None, None, (1.0, 0.0, 0.0, 1.0), None, None, 1.0)
    built = FileMaterial("m", (0.5, 0.5, 0.5), (0.5, 0.5, 0.5), (0.1, 0.1, 0.1), (0.0, 0.0, 0.0), 10.0)

    def material(rgba):
        return SimpleNamespace(baseColorFactor=rgba, emissiveFactor=None, roughnessFactor=None)
    assert _as_effect([red], material([0, 0, 255, 255]), built) is None
    assert _as_effect([red], material([255, 0, 0, 255]), built).ks == (0.0, 0.0, 0.0)


def test_an_image_in_a_data_uri_is_not_said_missing(tmp_path):
    """_check_images notes each image file <init_from> names that is not beside the document; an image given
    inline as a data: URI is no file and is not said missing (a file name that is missing is)."""
    path = write_triangle(tmp_path / "t.dae")
    images = ('<library_images><image id="inline"><init_from>data:image/png;base64,iVBORw0KGgo=</init_from></image>'
              '<image id="gone"><init_from>gone.png</init_from></image></library_images>')
    path.write_text(path.read_text().replace("<library_geometries>", images + "<library_geometries>"))
    said = [note for note in read(path).notes if "is missing" in note]
    assert len(said) == 1 and "gone.png" in said[0], said


def test_a_polylist_counts_each_polygon_s_triangles_and_a_corner_count_below_3_none(tmp_path):
    """COLLADA 1.4.1 <polylist>: <vcount> gives each polygon's corners; a polygon of n corners is n − 2
    triangles, one of fewer than 3 none: vcount 3 4 5 2 1 is 1 + 2 + 3 + 0 + 0 = 6 triangles for the memory
    check.
    A polylist without a vcount counts none."""
    from raycast_phong.io.meshes.source import mesh_source
    path = write_triangle(tmp_path / "t.dae")
    text = path.read_text().replace("<triangles ", "<polylist ").replace("</triangles>", "</polylist>")
    path.write_text(text.replace("<p>0 1 2</p>", "<vcount>3 4 5 2 1</vcount><p>" + "0 1 2 " * 5 + "</p>"))
    assert mesh_source(path).triangles() == 6
    (tmp_path / "none").mkdir()
    other = tmp_path / "none" / "t.dae"
    other.write_text(text)
    assert mesh_source(other).triangles() == 0


@pytest.mark.parametrize("transform", ["<translate>nan 0 0</translate>", "<scale>1e300 1 1</scale>"])
def test_a_node_transform_past_float_range_is_one_line_and_no_numpy_warning(transform, tmp_path, recwarn):
    """A node moved by NaN or scaled by 1e300 places the triangle out of range: one line from the read's values
    check, and no numpy warning before it (the placement's determinant; trimesh's graph, which trimesh's load
    itself raises inside the reader's quiet load: so not warnings as errors, but none recorded)."""
    path = write_triangle(tmp_path / "far.dae")
    text = path.read_text().replace('<visual_scene id="s"><node id="n">',
                                    f'<visual_scene id="s"><node id="outer">{transform}<node id="n">')
    path.write_text(text.replace("</node></visual_scene>", "</node></node></visual_scene>"))  # a parent node's
    with pytest.raises(rp.SceneError, match=r"vertex\(es\) with NaN or infinite"):
        read(path)
    assert [str(w.message) for w in recwarn] == []
