"""Scenes to cast the scan into: built-in scene presets and mesh files, in the world NED frame.

A scene preset is a JSON file in ``presets/scenes/`` listing primitives in
world NED coordinates (x north, y east, z down, metres; ground at z = 0) and a
default vehicle pose. Mesh files (OBJ, STL, PLY, GLB/GLTF, OFF, anything
trimesh reads) are taken in metres with a stated up axis and turned into NED:

* ``up="z"``: x forward, y left, z up (ROS, most CAD) -> NED (x, -y, -z);
* ``up="y"``: the glTF convention, +y up, +z forward, -x right -> NED (z, -x, -y).

Every triangle carries its material (:mod:`~livox_viz.scene.materials`): a scene
object's ``"material"``, a mesh file's sidecar or material colours, else the
``reflectance`` given (``--reflectance``).

trimesh is imported by the functions that build meshes, not with the module: the
commands that only list scenes or look at the pattern never pay its second of import.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

import numpy as np

from livox_viz.config.presets import DESCRIPTION_KEY, shipped_preset_dir, user_config_dir
from livox_viz.core.errors import LivoxVizError, quoted, require_file
from livox_viz.core.jsonfile import read_json_file
from livox_viz.core.portable import path_in_file
from livox_viz.core.poses import MAX_POSITION_M, Pose
from livox_viz.core.workload import TriangleBudget
from livox_viz.scene.materials import (
    DEFAULT_REFLECTANCE,
    SIDECAR_SUFFIX,
    MaterialMap,
    face_materials,
    fill_reflectance,
    parse_material,
    part_material,
    read_sidecar,
    set_face_materials,
)
from livox_viz.scene.meshcount import triangles_at_least

if TYPE_CHECKING:
    import trimesh

DEFAULT_SCENE = "urban"
UP_AXES = ("z", "y")
#: A scene's largest extent in any axis, metres: Embree casts in float32 (a scene 100 km across casts within
#: 3 mm; one reaching 1000 km out met wrong triangles near the sensor).
MAX_SCENE_SPAN_M = 100_000.0
#: The smallest size, radius, height, amplitude or wavelength of a scene object, metres: a sphere of 1e-300 m
#: made triangles of no area (NaN normals), and a millimetre is below every sensor's range noise.
MIN_SIZE_M = 1e-3
#: Where a scene JSON without a ``vehicle_pose`` puts the vehicle: x, y, z (m, NED), roll, pitch, yaw (rad).
DEFAULT_VEHICLE_POSE = (0.0, 0.0, -1.5, 0.0, 0.0, 0.0)
#: A scene JSON's most objects.
MAX_SCENE_OBJECTS = 10_000
#: A terrain's most cells a side (two million triangles).
MAX_TERRAIN_CELLS = 1000
_TO_NED = {
    "z": np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]]),
    "y": np.array([[0, 0, 1.0], [-1, 0, 0], [0, -1, 0]]),
}


@dataclass(frozen=True)
class Scene:
    """A scene ready to cast into.

    Parameters
    ----------
    name : str
        Preset name or file name.
    mesh : trimesh.Trimesh
        All triangles, world NED, metres.
    vehicle_pose : Pose
        Where the vehicle stands by default.
    description : str
        One line for listings.
    """

    name: str
    mesh: trimesh.Trimesh
    vehicle_pose: Pose
    description: str = ""


def scene_dir() -> Path:
    """Folder of the shipped scene presets."""
    return shipped_preset_dir() / "scenes"


def list_scenes() -> list[tuple[str, str]]:
    """``(name, description)`` of every shipped scene preset."""
    found = []
    for path in sorted(scene_dir().glob("*.json")):
        try:
            description = json.loads(path.read_text(encoding="utf-8")).get(DESCRIPTION_KEY, "")
        except (OSError, json.JSONDecodeError, AttributeError):
            description = "(unreadable)"
        found.append((path.stem, description))
    return found


MESH_SUFFIXES = (".obj", ".stl", ".ply", ".glb", ".gltf", ".off", ".json")
#: The mesh formats, as messages name them.
MESH_FORMATS = "OBJ, STL, PLY, GLB, glTF or OFF"


def user_scene_dir() -> Path:
    """The user's own scenes (mesh files or scene JSON): ``$LIVOX_VIZ_SCENES``, else ``scenes`` in the
    platform's folder (``~/.config/livox-viz/scenes`` on Linux, :func:`~livox_viz.config.presets.user_config_dir`)."""
    return user_config_dir("scenes")


def scene_choices() -> list[str]:
    """What the GUI cycles through: shipped scene names, then the user's scene files (paths)."""
    choices = [name for name, _ in list_scenes()]
    folder = user_scene_dir()
    if folder.is_dir():
        choices += [str(p) for p in sorted(folder.iterdir())
                    if p.suffix.lower() in MESH_SUFFIXES and not p.name.endswith(SIDECAR_SUFFIX)]
    return choices


def default_scene() -> trimesh.Trimesh:
    """The built-in default scene's mesh (world NED, metres)."""
    return load_scene_preset(DEFAULT_SCENE).mesh


def load_scene(name_or_path: str | os.PathLike[str] = DEFAULT_SCENE, up: str = "z",
               reflectance: float = DEFAULT_REFLECTANCE) -> trimesh.Trimesh:
    """The mesh of a scene preset (by name or JSON path) or of a mesh file, in world NED.

    Parameters
    ----------
    name_or_path : str or path-like
        A scene preset name (``livox-viz scenes``), a scene JSON, or a mesh file.
    up : {"z", "y"}
        Up axis of a mesh file.
    reflectance : float
        Lambertian reflectance (0-1) of surfaces that have no material of their own.
    """
    return open_scene(name_or_path, up, reflectance).mesh


def open_scene(name_or_path: str | os.PathLike[str] = DEFAULT_SCENE, up: str = "z",
               reflectance: float = DEFAULT_REFLECTANCE, triangles: TriangleBudget | None = None) -> Scene:
    """Like :func:`load_scene`, with the scene's name, description and default vehicle pose.

    ``triangles`` counts the scene's triangles against the budget as they are read, before anything is built
    (default: :data:`~livox_viz.core.workload.TRIANGLE_BUDGET`, not forced).
    """
    triangles = TriangleBudget() if triangles is None else triangles
    text = os.fspath(name_or_path)
    names = [name for name, _ in list_scenes()]
    if text in names:
        return load_scene_preset(text, reflectance, triangles)
    path = Path(text)
    if path.suffix.lower() == ".json":
        return _scene_from_json(path, reflectance, triangles)
    if not path.exists():
        raise LivoxVizError(f"scene {quoted(text)} is neither a scene preset ({', '.join(names)}) nor an existing file")
    return Scene(path.name, load_mesh_file(path, up, reflectance, triangles=triangles), Pose((0.0, 0.0, -1.5)),
                 f"mesh file {path}")


def scene_files(name_or_path: str | os.PathLike[str]) -> list[Path]:
    """The files a scene is read from: none for a built-in scene; a scene JSON and its objects' mesh files; each
    mesh file with its materials sidecar's path (whether there is one or not: one that comes changes the scene)
    and what trimesh reads beside it (an OBJ's material libraries, a glTF's external buffers and images). Files
    named but missing are listed too. What changes any of them can change the scene (a batch job runs again
    when one of them changed).
    """
    text = os.fspath(name_or_path)
    if text in {name for name, _ in list_scenes()}:
        return []
    path = Path(text)
    if path.suffix.lower() != ".json":
        return _mesh_files(path)
    files = [path]
    try:
        data = read_json_file(path, "scene JSON")
    except LivoxVizError:
        return files
    for obj in data.get("objects", []) if isinstance(data, dict) and isinstance(data.get("objects"), list) else []:
        if isinstance(obj, dict) and obj.get("type") == "mesh":
            try:
                files += _mesh_files(path_in_file(str(obj.get("path", "")), path.parent))
            except LivoxVizError:
                continue
    return list(dict.fromkeys(files))


def _mesh_files(path: Path) -> list[Path]:
    """A mesh file, its materials sidecar's path, and the files it names that trimesh reads beside it."""
    files = [path, path.with_name(path.stem + SIDECAR_SUFFIX)]  # the sidecar even when there is none: one may come
    suffix = path.suffix.lower()
    try:
        if suffix == ".obj":
            with open(path, "rb") as handle:
                for line in handle:
                    if line.startswith(b"mtllib"):
                        files += [path.parent / name.decode("utf-8", "replace") for name in line.split()[1:]]
        elif suffix == ".gltf":
            data = read_json_file(path, "glTF")
            for key in ("buffers", "images"):
                for item in data.get(key, []) if isinstance(data, dict) and isinstance(data.get(key), list) else []:
                    uri = item.get("uri") if isinstance(item, dict) else None
                    if isinstance(uri, str) and uri and not uri.startswith("data:"):
                        files.append(path.parent / unquote(uri))
    except (OSError, LivoxVizError):
        pass  # an unreadable mesh is the scene's own error, when it loads
    return files


def load_scene_preset(name: str, reflectance: float = DEFAULT_REFLECTANCE,
                      triangles: TriangleBudget | None = None) -> Scene:
    """A shipped scene preset by name."""
    path = scene_dir() / f"{name}.json"
    if not path.is_file():
        names = ", ".join(n for n, _ in list_scenes())
        raise LivoxVizError(f"unknown scene {quoted(name)}; allowed: {names}")
    return _scene_from_json(path, reflectance, triangles)


def load_mesh_file(path: str | os.PathLike[str], up: str = "z", reflectance: float | None = DEFAULT_REFLECTANCE,
                   materials: MaterialMap | None = None, triangles: TriangleBudget | None = None) -> trimesh.Trimesh:
    """Read a mesh file (metres) and turn it into world NED, each part with its material.

    Parameters
    ----------
    path : path-like
    up : {"z", "y"}
    reflectance : float or None
        For parts that have no material (no sidecar entry, no colour); None leaves them without one.
    materials : MaterialMap, optional
        Names to materials (a scene JSON's map for this mesh), before the sidecar ``<stem>.materials.json``
        beside the file, if any: what the map does not name, the sidecar may.
    triangles : TriangleBudget, optional
        The scene's triangles so far: the file's are checked against the budget from what its header says before
        trimesh parses it, then counted (default: a budget of its own).

    Raises
    ------
    LivoxVizError
        If the file is missing, not a mesh, empty, or has non-finite vertices, or a name of the map or the
        sidecar matches no part (a misspelt name would silently leave its part at its colour).
    """
    import trimesh

    path = Path(path)
    if up not in UP_AXES:
        raise LivoxVizError(f"up axis {quoted(up)}; allowed: {' or '.join(UP_AXES)}")
    require_file(path, "mesh file")
    triangles = TriangleBudget() if triangles is None else triangles
    triangles.check(triangles_at_least(path) or 0, str(path))
    # A scene JSON's map for this mesh first, then the sidecar beside the file for what the map does not name.
    table = MaterialMap.merged(materials, read_sidecar(path))
    # Where names choose materials, an OBJ's objects ("o") stay parts of their own, named as the file names them:
    # trimesh otherwise joins those of one material into one, named after the first (a sidecar naming two walls
    # gave both the first's). Only then: a city of 3000 objects loads in 0.66 s split, 0.06 s joined.
    options = {"split_objects": True} if path.suffix.lower() == ".obj" and table is not None else {}
    if path.suffix.lower() == ".gltf":
        # A glTF is JSON: a truncated or garbage one gets our reader's line (trimesh's named a missing file).
        read_json_file(path, "glTF file (JSON)")
    try:
        loaded = trimesh.load(path, force="scene", process=False, **options)
    except Exception as exc:  # trimesh raises many types for unreadable files
        # trimesh's own words are kept for the detail (a face naming vertex 9 of 8 is an IndexError), after ours.
        raise LivoxVizError(f"{path}: not a mesh trimesh can read; allowed: a well-formed {MESH_FORMATS} file "
                            f"(trimesh said {type(exc).__name__}: {exc})") from None
    parts = []
    names_seen: list[str] = []
    triangles.add(sum(len(getattr(loaded.geometry.get(loaded.graph[node][1]), "faces", ()))
                      for node in loaded.graph.nodes_geometry), str(path))
    for node in loaded.graph.nodes_geometry:
        transform, geometry_name = loaded.graph[node]
        geometry = loaded.geometry.get(geometry_name)
        if not isinstance(geometry, trimesh.Trimesh) or len(geometry.faces) == 0:
            continue
        material_name = str(getattr(getattr(geometry.visual, "material", None), "name", None) or "")
        names = [str(node), str(geometry_name), material_name]
        if material_name and str(geometry_name).endswith("_" + material_name):
            names.append(str(geometry_name)[: -len(material_name) - 1])  # an OBJ object's own name
        names_seen += names
        own, gain = part_material(geometry, names, table)
        vertices = trimesh.transform_points(np.asarray(geometry.vertices, dtype=np.float64), transform)
        parts.append(set_face_materials(trimesh.Trimesh(vertices, np.asarray(geometry.faces), process=False),
                                        own, gain, np.full(len(geometry.faces), len(parts))))
    if not parts:
        raise LivoxVizError(
            f"{path}: holds no triangles; allowed: a mesh with at least one face ({MESH_FORMATS})"
        )
    if table is not None:
        table.require_matches(names_seen, str(path))
    mesh = _join(parts)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.isfinite(vertices)):
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise LivoxVizError(f"{path}: {bad} vertices are NaN or infinite; allowed: finite coordinates in metres")
    check_span(mesh, str(path))
    mesh.vertices = vertices @ _TO_NED[up].T
    return mesh if reflectance is None else fill_reflectance(mesh, reflectance)


def _join(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh of ``parts`` (no vertex merging), their per-face materials and part numbers kept."""
    import trimesh

    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    vertices = np.concatenate([np.asarray(p.vertices, dtype=np.float64) for p in parts])
    faces = np.concatenate([np.asarray(p.faces, dtype=np.int64) + o for p, o in zip(parts, offsets, strict=True)])
    joined = trimesh.Trimesh(vertices, faces, process=False)
    materials = [face_materials(p, np.nan) for p in parts]
    return set_face_materials(joined, np.concatenate([m[0] for m in materials]),
                              np.concatenate([m[1] for m in materials]),
                              np.concatenate([p.face_attributes["part"] for p in parts]))


# Scene descriptions ------------------------------------------------------------------
def _scene_from_json(path: Path, reflectance: float, triangles: TriangleBudget | None) -> Scene:
    triangles = TriangleBudget() if triangles is None else triangles
    data = read_json_file(path, "scene JSON")
    if not isinstance(data, dict) or not isinstance(data.get("objects"), list):
        raise LivoxVizError(f"{path}: a scene JSON needs an 'objects' list")
    if len(data["objects"]) > MAX_SCENE_OBJECTS:  # each is built on its own: 10 000 boxes take about 5 s
        raise LivoxVizError(f"{path}: {len(data['objects']):,} objects; allowed: at most {MAX_SCENE_OBJECTS:,} (put "
                            "a city of parts in a mesh file)")
    # The whole scene's triangles from its description and its mesh files' headers before anything is built;
    # then each mesh file's are counted as trimesh reads it.
    primitives = sum(_primitive_triangles(obj) for obj in data["objects"])
    triangles.check(primitives + sum(_mesh_triangles(obj, path.parent) for obj in data["objects"]), str(path))
    triangles.add(primitives, str(path))
    parts = [_with_material(_primitive(obj, index, path.parent, triangles), obj, index)
             for index, obj in enumerate(data["objects"])]
    if not parts:
        raise LivoxVizError(f"{path}: the scene has no objects")
    pose_values = data.get("vehicle_pose", DEFAULT_VEHICLE_POSE)
    pose = Pose.from_values(pose_values, f"{path}: 'vehicle_pose' = {quoted(pose_values)}")
    mesh = _join(parts)
    check_span(mesh, str(path))
    return Scene(path.stem, fill_reflectance(mesh, reflectance), pose, str(data.get(DESCRIPTION_KEY, "")))


def _with_material(mesh: trimesh.Trimesh, obj: dict[str, Any], index: int) -> trimesh.Trimesh:
    """The object's mesh with its ``"material"`` (a mesh file keeps its own where the object names none)."""
    faces = len(mesh.faces)
    if "material" in obj:
        material = parse_material(obj["material"], f"object {index} ({obj.get('type')})")
        return set_face_materials(mesh, np.full(faces, material.reflectance), np.full(faces, material.retro_gain),
                                  np.full(faces, index))
    own, gain = face_materials(mesh, np.nan)
    return set_face_materials(mesh, own, gain, np.full(faces, index))


def _numbers(obj: dict[str, Any], key: str, length: int, where: str, bound: float, positive: bool) -> np.ndarray:
    """``obj[key]``: ``length`` numbers of size at most ``bound`` (NaN and inf fail that), and at least
    :data:`MIN_SIZE_M` if ``positive``."""
    value = obj.get(key)
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        array = np.zeros(0)
    if array.shape != (length,) or not np.all((np.abs(array) <= bound) & ((array >= MIN_SIZE_M) | (not positive))):
        allowed = (f"numbers from {MIN_SIZE_M:g} to {bound:g} m" if positive else
                   f"finite numbers within {bound:g} m of the origin")
        raise LivoxVizError(f"{where}: '{key}' = {quoted(value)}; allowed: {length} {allowed}")
    return array


def _vector(obj: dict[str, Any], key: str, length: int, where: str) -> np.ndarray:
    """A centre: ``length`` finite numbers within :data:`~livox_viz.core.poses.MAX_POSITION_M` of the origin."""
    return _numbers(obj, key, length, where, MAX_POSITION_M, positive=False)


def _size(obj: dict[str, Any], length: int, where: str) -> np.ndarray:
    """An object's ``size``: ``length`` numbers from :data:`MIN_SIZE_M` to :data:`MAX_SCENE_SPAN_M`."""
    return _numbers(obj, "size", length, where, MAX_SCENE_SPAN_M, positive=True)


def check_span(mesh: trimesh.Trimesh, where: str) -> None:
    """Refuse a scene wider than :data:`MAX_SCENE_SPAN_M` in any axis.

    Embree casts in float32 around the scene's middle: with geometry 1000 km away, rays near the sensor met the
    wrong triangles (a hit at 18.9 m came back at 0.8 m), and farther out every ray missed.
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    span = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.0
    if not span <= MAX_SCENE_SPAN_M:
        raise LivoxVizError(f"{where}: the scene spans {span:.4g} m; allowed: at most {MAX_SCENE_SPAN_M:g} m across "
                            "(rays are cast in float32: move far parts nearer or leave them out)")


def check_reach(mesh: trimesh.Trimesh, positions: np.ndarray, what: str) -> None:
    """Refuse a sensor that goes so far from the scene that the two together span more than
    :data:`MAX_SCENE_SPAN_M` in an axis: the rule of :func:`check_span` for where the rays start.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The scene, world NED.
    positions : (n, 3) float64
        Where the sensor goes (the vehicle's poses), world NED, metres.
    what : str
        The poses in the user's words, e.g. ``"--pose"`` or ``"trajectory turns.txt"``.
    """
    bounds = np.asarray(mesh.bounds, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    low = np.minimum(bounds[0], positions.min(axis=0))
    high = np.maximum(bounds[1], positions.max(axis=0))
    span = float((high - low).max())
    if not span <= MAX_SCENE_SPAN_M:
        centre = bounds.mean(axis=0)
        far = positions[np.argmax(np.abs(positions - centre).max(axis=1))]
        raise LivoxVizError(f"{what} takes the sensor to {', '.join(f'{v:.4g}' for v in far)} m, and with the scene it "
                            f"spans {span:.4g} m; allowed: the scene and the sensor's path within "
                            f"{MAX_SCENE_SPAN_M:g} m across (rays are cast in float32 around the scene)")


def _number(obj: dict[str, Any], key: str, where: str, default: float | None = None) -> float:
    """``obj[key]`` (or ``default``): a length from :data:`MIN_SIZE_M` to :data:`MAX_SCENE_SPAN_M` metres."""
    value = obj.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not MIN_SIZE_M <= value <= MAX_SCENE_SPAN_M:
        raise LivoxVizError(f"{where}: '{key}' = {quoted(value)}; allowed: a number from {MIN_SIZE_M:g} to "
                            f"{MAX_SCENE_SPAN_M:g} m")
    return float(value)


def _mesh_path(obj: dict[str, Any], folder: Path, where: str) -> Path:
    """A mesh object's file: its ``path`` beside the scene file (or absolute), as Windows or Linux writes it."""
    try:
        return path_in_file(str(obj.get("path", "")), folder)
    except LivoxVizError as exc:
        raise LivoxVizError(f"{where} path: {exc}") from None


#: Triangles of each primitive (a terrain's are 2 x cells^2): the sections of a cylinder, the subdivisions of a sphere.
PRIMITIVE_TRIANGLES = {"ground": 2, "box": 12, "roof": 8, "cylinder": 96, "sphere": 1280}


def _primitive_triangles(obj: Any) -> int:
    """The triangles a scene object will make, counted from its description (0 for a mesh file, counted as it is
    read, and for what is not an object: refused when it is built)."""
    if not isinstance(obj, dict):
        return 0
    kind = obj.get("type")
    if kind == "terrain":
        cells = obj.get("cells", 100)
        return 2 * cells * cells if isinstance(cells, int) and 1 <= cells <= MAX_TERRAIN_CELLS else 0
    return PRIMITIVE_TRIANGLES.get(kind, 0) if isinstance(kind, str) else 0


def _mesh_triangles(obj: Any, folder: Path) -> int:
    """At least the triangles of a scene object's mesh file, from its header (0 for anything else)."""
    if not isinstance(obj, dict) or obj.get("type") != "mesh":
        return 0
    try:
        path = path_in_file(str(obj.get("path", "")), folder)
    except LivoxVizError:
        return 0  # refused with its object's name when it is built
    return (triangles_at_least(path) or 0) if path.is_file() else 0


def _primitive(obj: Any, index: int, folder: Path, triangles: TriangleBudget) -> trimesh.Trimesh:
    import trimesh

    where = f"object {index}"
    if not isinstance(obj, dict):
        raise LivoxVizError(f"{where}: must be a JSON object")
    kind = obj.get("type")
    where = f"object {index} ({kind})"
    if kind == "mesh":
        names = obj.get("materials")
        up = obj.get("up", "z")
        if not isinstance(up, str) or up not in UP_AXES:
            raise LivoxVizError(f"{where}: 'up' = {quoted(up)}; allowed: {' or '.join(map(repr, UP_AXES))}")
        mesh = load_mesh_file(_mesh_path(obj, folder, where), up, None,
                              None if names is None else MaterialMap.from_json(names, f"{where} materials"),
                              triangles)
        mesh.apply_translation(_vector(obj, "center", 3, where) if "center" in obj else np.zeros(3))
        return mesh
    center = _vector(obj, "center", 3, where)
    if kind == "box":
        return trimesh.creation.box(_size(obj, 3, where), trimesh.transformations.translation_matrix(center))
    if kind == "ground":
        size = _size(obj, 2, where)
        return _grid(center, size, 1, lambda x, y: np.zeros_like(x))
    if kind == "terrain":
        size = _size(obj, 2, where)
        cells = obj.get("cells", 100)
        if isinstance(cells, bool) or not isinstance(cells, int) or not 1 <= cells <= MAX_TERRAIN_CELLS:
            raise LivoxVizError(f"{where}: 'cells' = {quoted(cells)}; allowed: a whole number from 1 to "
                                f"{MAX_TERRAIN_CELLS} (cells a side, two triangles each)")
        amplitude = _number(obj, "amplitude", where, 2.0)
        wavelength = _number(obj, "wavelength", where, 20.0)
        k = 2 * math.pi / wavelength

        def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            return -amplitude * (0.5 + 0.25 * np.sin(k * x) + 0.25 * np.cos(0.7 * k * y + 0.3 * k * x))

        return _grid(center, size, cells, height)
    if kind == "cylinder":
        radius, height_m = _number(obj, "radius", where), _number(obj, "height", where)
        return trimesh.creation.cylinder(radius, height_m, sections=24,
                                         transform=trimesh.transformations.translation_matrix(center))
    if kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=_number(obj, "radius", where))
        mesh.apply_translation(center)
        return mesh
    if kind == "roof":
        return _roof(center, _size(obj, 3, where))
    raise LivoxVizError(f"{where}: unknown type {quoted(kind)}; allowed: ground, terrain, box, cylinder, sphere, "
                        "roof, mesh")


def _grid(center: np.ndarray, size: np.ndarray, cells: int, height) -> trimesh.Trimesh:
    """A ``cells`` x ``cells`` height field (2 triangles a cell) centred on ``center``."""
    import trimesh

    xs = center[0] + np.linspace(-size[0] / 2, size[0] / 2, cells + 1)
    ys = center[1] + np.linspace(-size[1] / 2, size[1] / 2, cells + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    gz = center[2] + height(gx, gy)
    vertices = np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])
    idx = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return trimesh.Trimesh(vertices, faces, process=False)


def _roof(center: np.ndarray, size: np.ndarray) -> trimesh.Trimesh:
    """A gabled roof: base ``size[0]`` x ``size[1]`` at ``center``, ridge ``size[2]`` higher (NED: z smaller)."""
    import trimesh

    hx, hy, rise = size[0] / 2, size[1] / 2, size[2]
    x0, y0, z0 = center
    vertices = np.array([
        [x0 - hx, y0 - hy, z0], [x0 + hx, y0 - hy, z0], [x0 + hx, y0 + hy, z0], [x0 - hx, y0 + hy, z0],
        [x0 - hx, y0, z0 - rise], [x0 + hx, y0, z0 - rise],
    ])
    faces = np.array([[0, 1, 5], [0, 5, 4], [2, 3, 4], [2, 4, 5], [0, 4, 3], [1, 2, 5], [0, 3, 2], [0, 2, 1]])
    return trimesh.Trimesh(vertices, faces, process=False)
