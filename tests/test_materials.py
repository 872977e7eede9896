"""Surface materials: built-in scenes, mesh files' colours and sidecars, the default, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from livox_viz import LivoxVizError
from livox_viz.scene.materials import DEFAULT_REFLECTANCE, MATERIALS, face_materials, face_parts
from livox_viz.scene.scenes import load_mesh_file, open_scene


def luminance(rgb: tuple[int, int, int]) -> float:
    r, g, b = (c / 255 for c in rgb)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def coloured(rgb: tuple[int, int, int], name: str, offset: float) -> trimesh.Trimesh:
    box = trimesh.creation.box((1, 1, 1), trimesh.transformations.translation_matrix((offset, 0, 0)))
    box.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.SimpleMaterial(
        name=name, diffuse=[*rgb, 255]))
    return box


def test_every_built_in_scene_has_plausible_materials() -> None:
    for name in ("urban", "open_field", "dense_terrain"):
        reflectance, gain = face_materials(open_scene(name).mesh, np.nan)
        assert not np.isnan(reflectance).any() and np.all((reflectance > 0) & (reflectance <= 1)), name
    urban = open_scene("urban")
    reflectance, gain = face_materials(urban.mesh)
    parts = face_parts(urban.mesh)
    ground = parts == 0  # the first object
    assert np.all(reflectance[ground] == MATERIALS["asphalt"].reflectance)
    assert (gain > 1).sum() == 24  # two retroreflective signs, 12 triangles each
    assert np.isin(MATERIALS["white_paint"].reflectance, reflectance) and np.isin(
        MATERIALS["vegetation"].reflectance, reflectance)
    assert len(np.unique(parts)) == 33


def test_mesh_file_parts_take_their_material_colours(tmp_path: Path) -> None:
    scene = trimesh.Scene({"road": coloured((30, 30, 30), "Road", 0.0),
                           "sign": coloured((250, 250, 250), "Paint", 3.0)})
    for suffix in (".obj", ".glb"):
        path = tmp_path / f"street{suffix}"
        scene.export(path)
        mesh = load_mesh_file(path)
        reflectance, _ = face_materials(mesh)
        x = mesh.triangles_center[:, 0]
        assert np.allclose(reflectance[x < 1.5], luminance((30, 30, 30)), atol=2e-3), suffix
        assert np.allclose(reflectance[x > 1.5], luminance((250, 250, 250)), atol=2e-3), suffix


def test_face_colours_and_the_default_reflectance(tmp_path: Path) -> None:
    box = trimesh.creation.box((1, 1, 1))
    colours = np.tile([200, 100, 50, 255], (len(box.faces), 1))
    colours[:6] = [10, 20, 30, 255]
    box.visual.face_colors = colours
    box.export(tmp_path / "faces.ply")
    reflectance, _ = face_materials(load_mesh_file(tmp_path / "faces.ply"))
    assert sorted({round(v, 4) for v in reflectance}) == sorted({round(luminance((10, 20, 30)), 4),
                                                                  round(luminance((200, 100, 50)), 4)})
    trimesh.creation.box((1, 1, 1)).export(tmp_path / "plain.stl")
    assert np.all(face_materials(load_mesh_file(tmp_path / "plain.stl"))[0] == DEFAULT_REFLECTANCE)
    assert np.all(face_materials(open_scene(tmp_path / "plain.stl", reflectance=0.7).mesh)[0] == 0.7)


def test_a_sidecar_maps_names_and_patterns(tmp_path: Path) -> None:
    scene = trimesh.Scene({"road": coloured((30, 30, 30), "Road", 0.0), "sign_stop": coloured((90, 0, 0), "Red", 3.0),
                           "wall": coloured((120, 120, 120), "Grey", 6.0)})
    # glTF keeps the meshes' (nodes') names: they and glob patterns of them pick materials.
    path = tmp_path / "street.glb"
    scene.export(path)
    (tmp_path / "street.materials.json").write_text(json.dumps({
        "road": "asphalt", "sign_*": {"reflectance": 0.7, "retroreflective": True}}))
    mesh = load_mesh_file(path)
    reflectance, gain = face_materials(mesh)
    x = mesh.triangles_center[:, 0]
    assert np.all(reflectance[x < 1.5] == MATERIALS["asphalt"].reflectance) and np.all(gain[x < 1.5] == 1)
    sign = (x > 1.5) & (x < 4.5)
    assert np.all(reflectance[sign] == 0.7) and np.all(gain[sign] > 1)
    assert np.allclose(reflectance[x > 4.5], luminance((120, 120, 120)), atol=2e-3)  # not in the sidecar
    # OBJ parts are named by their materials (usemtl): those names work too.
    obj = tmp_path / "street2.obj"
    scene.export(obj)
    (tmp_path / "street2.materials.json").write_text(json.dumps({"Grey": 0.9}))
    mesh = load_mesh_file(obj)
    reflectance, _ = face_materials(mesh)
    assert np.all(reflectance[mesh.triangles_center[:, 0] > 4.5] == 0.9)


@pytest.mark.parametrize(("material", "message"), [
    ("unobtainium", "unknown material 'unobtainium'"), (1.5, "reflectance 1.5"),
    ({"reflectance": 0.5, "retroreflective": "yes"}, "true or false"),
    ({"reflectance": 0.5, "retro_gain": 0.5}, "retro_gain"), ({"shiny": True}, "allowed"),
    ({"reflectance": 0.5, "retroreflective": False, "retro_gain": 500}, "only on a retroreflective material"),
])
def test_bad_materials_are_one_line_errors(tmp_path: Path, material: object, message: str) -> None:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps({"objects": [{"type": "box", "center": [5, 0, 0], "size": [1, 1, 1],
                                             "material": material}]}))
    with pytest.raises(LivoxVizError, match=message) as error:
        open_scene(path)
    assert "\n" not in str(error.value) and "object 0" in str(error.value)


def test_a_broken_sidecar_is_a_one_line_error(tmp_path: Path) -> None:
    trimesh.creation.box((1, 1, 1)).export(tmp_path / "b.obj")
    (tmp_path / "b.materials.json").write_text("{not json")
    with pytest.raises(LivoxVizError, match=r"b\.materials\.json: not a readable material sidecar"):
        load_mesh_file(tmp_path / "b.obj")


def test_the_guides_scene_json_loads_as_it_says(tmp_path: Path) -> None:
    """The scene file the user guide documents, taken from docs/files.md itself: every object type, materials by
    name, number and pattern, the default vehicle pose when the file gives none."""
    import re

    from livox_viz.core.poses import Pose

    guide = (Path(__file__).resolve().parents[1] / "docs" / "files.md").read_text(encoding="utf-8")
    block = re.search(r"\n## Scene files\n.*?```json\n(.*?)```", guide, re.S)
    assert block is not None
    scene = json.loads(block.group(1))
    car = trimesh.creation.box((4.0, 1.5, 1.8))  # y up in the file, as the guide's object says
    car.visual.face_colors = [200, 200, 200, 255]
    car.metadata["name"] = "glass_windows"
    car.export(tmp_path / "car.glb")
    (tmp_path / "with_pose.json").write_text(json.dumps(scene))
    loaded = open_scene(str(tmp_path / "with_pose.json"))
    assert len({int(p) for p in face_parts(loaded.mesh)}) == len(scene["objects"])
    reflectance, _ = face_materials(loaded.mesh)
    assert np.isclose(reflectance, MATERIALS["asphalt"].reflectance).any()
    assert np.isclose(reflectance, MATERIALS["brick"].reflectance).any()
    assert np.isclose(reflectance, 0.05).any()  # the mesh's part named glass_windows, by the "glass*" pattern
    assert loaded.vehicle_pose.origin.tolist() == [0.0, 0.0, -1.5]
    del scene["vehicle_pose"]
    scene["objects"] = scene["objects"][:2]
    (tmp_path / "no_pose.json").write_text(json.dumps(scene))
    assert open_scene(str(tmp_path / "no_pose.json")).vehicle_pose == Pose((0.0, 0.0, -1.5))
    scene["vehicle_pose"] = [3, 4, -2, 0, 0, 90]
    (tmp_path / "posed.json").write_text(json.dumps(scene))
    posed = open_scene(str(tmp_path / "posed.json")).vehicle_pose
    assert posed.origin.tolist() == [3.0, 4.0, -2.0] and posed == Pose((3.0, 4.0, -2.0), yaw=90.0)


def wall_obj(folder: Path, mtl: str = "") -> Path:
    """Two walls side by side at x = 20 m, objects ``white_wall`` (y 0..10) and ``dark_wall`` (y -10..0), each
    with the material ``mtl`` names (none when empty)."""
    lines = ["mtllib walls.mtl" if mtl else ""]
    for k, (name, y0) in enumerate((("white_wall", 0), ("dark_wall", -10))):
        lines += [f"o {name}"] + ([f"usemtl {mtl}"] if mtl else [])
        lines += [f"v 20 {y0} -1", f"v 20 {y0 + 10} -1", f"v 20 {y0 + 10} 6", f"v 20 {y0} 6"]
        lines += [f"f {4 * k + 1} {4 * k + 2} {4 * k + 3}", f"f {4 * k + 1} {4 * k + 3} {4 * k + 4}"]
    path = folder / "walls.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def by_wall(mesh: trimesh.Trimesh) -> dict[str, float]:
    """The reflectance of each wall, told apart by where its faces lie: the file's y (left, z up) is NED's -y."""
    reflectance, _ = face_materials(mesh)
    east = mesh.triangles_center[:, 1]
    return {"white_wall": float(np.unique(reflectance[east < 0])[0]),
            "dark_wall": float(np.unique(reflectance[east > 0])[0])}


def test_a_sidecar_names_an_obj_files_objects_each_its_own(tmp_path: Path) -> None:
    """trimesh joins an OBJ's objects of one material into one part named after the first: the sidecar's two
    names must still reach their own walls, with a material (usemtl) and without."""
    for mtl in ("", "Paint"):
        folder = tmp_path / (mtl or "none")
        folder.mkdir()
        if mtl:
            (folder / "walls.mtl").write_text(f"newmtl {mtl}\nKd 0.5 0.5 0.5\n")
        path = wall_obj(folder, mtl)
        (folder / "walls.materials.json").write_text('{"white_wall": 0.9, "dark_wall": 0.05}')
        assert by_wall(load_mesh_file(path)) == {"white_wall": 0.9, "dark_wall": 0.05}, mtl


def test_a_sidecar_name_that_matches_nothing_is_an_error_naming_what_there_is(tmp_path: Path) -> None:
    path = wall_obj(tmp_path)
    (tmp_path / "walls.materials.json").write_text('{"white_wall": 0.9, "dark_wal": 0.05}')
    with pytest.raises(LivoxVizError, match=r"'dark_wal' names nothing in .*walls\.obj; allowed: .*'dark_wall'"):
        load_mesh_file(path)
    (tmp_path / "walls.materials.json").write_text('{"*_wall": 0.7, "glass*": 0.05}')
    with pytest.raises(LivoxVizError, match=r"'glass\*' names nothing"):
        load_mesh_file(path)


def test_a_scene_jsons_map_for_a_mesh_comes_before_its_sidecar(tmp_path: Path) -> None:
    """The scene's map names one wall; the sidecar beside the mesh still gives the other its value."""
    wall_obj(tmp_path)
    (tmp_path / "walls.materials.json").write_text('{"white_wall": 0.2, "dark_wall": 0.05}')
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps({"objects": [{"type": "mesh", "path": "walls.obj",
                                              "materials": {"white_wall": 0.9}}]}))
    assert by_wall(open_scene(scene).mesh) == {"white_wall": 0.9, "dark_wall": 0.05}


def test_a_material_without_a_colour_takes_the_default_and_a_texture_its_mean(tmp_path: Path) -> None:
    """trimesh fills a colour the file left out with its placeholder grey (102, a reflectance of 0.4): a glTF
    material with neither a base colour nor a texture, and an OBJ material with no Kd, Ka or Ks, take
    ``--reflectance`` instead; a texture's mean colour counts (times its factor); a Kd of 0.4 stays 0.4."""
    from PIL import Image

    plain = trimesh.creation.box((1, 1, 1))
    plain.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(name="NoFactor"))
    plain.export(tmp_path / "plain.glb")
    assert np.all(face_materials(load_mesh_file(tmp_path / "plain.glb", reflectance=0.9))[0] == 0.9)
    textured = trimesh.creation.box((1, 1, 1))
    texture = Image.new("RGB", (8, 8), (200, 100, 50))
    texture.paste((0, 0, 0), (0, 0, 8, 4))  # half black: the mean is half the colour
    uv = np.tile([[0.5, 0.5]], (len(textured.vertices), 1))
    textured.visual = trimesh.visual.TextureVisuals(uv=uv, material=trimesh.visual.material.PBRMaterial(
        name="Tex", baseColorTexture=texture))
    textured.export(tmp_path / "textured.glb")
    found = face_materials(load_mesh_file(tmp_path / "textured.glb", reflectance=0.9))[0]
    np.testing.assert_allclose(found, luminance((100, 50, 25)), atol=1e-9)
    for mtl, expected in (("newmtl NoKd\nNs 10\n", 0.9), ("newmtl Grey\nKd 0.4 0.4 0.4\nKa 0 0 0\n", 0.4)):
        folder = tmp_path / str(expected)
        folder.mkdir()
        name = mtl.split()[1]
        (folder / "walls.mtl").write_text(mtl)
        found = face_materials(load_mesh_file(wall_obj(folder, name), reflectance=0.9))[0]
        np.testing.assert_allclose(found, expected, atol=0.003)
