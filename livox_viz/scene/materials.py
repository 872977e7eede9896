"""Surface materials: what a lidar's beam sees of a triangle, its reflectance and whether it is retroreflective.

A material has a Lambertian **reflectance** (0-1, at the lidar's 905 nm) and a
**retroreflective gain** (1 for a Lambertian surface; a retroreflective sign
sends back hundreds of times what a white Lambertian surface of the same
reflectance would). Every triangle of a scene carries its material in two
per-face arrays of the trimesh mesh, ``mesh.face_attributes["reflectance"]`` and
``["retro_gain"]``, so the material travels with the mesh to the ray caster;
``["part"]`` numbers the object (primitive or mesh part) each triangle belongs to.

Where the materials come from:

* built-in scene objects name one (``"material": "asphalt"``, a number for a
  Lambertian reflectance, or ``{"reflectance": 0.8, "retroreflective": true}``);
* a mesh file takes, per part, a sidecar JSON beside it (``city.materials.json``
  for ``city.glb``) mapping mesh (node) or material names, or glob patterns of
  them, to a material; else the part's material colour, taken as linear RGB
  (glTF's ``baseColorFactor``, OBJ's ``Kd``), whose luminance
  ``0.2126 R + 0.7152 G + 0.0722 B`` is the reflectance;
* anything else gets ``--reflectance`` (default :data:`DEFAULT_REFLECTANCE`, about
  dry concrete at 905 nm).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from livox_viz.core.errors import LivoxVizError, not_a_file, quoted
from livox_viz.core.jsonfile import read_json_file

if TYPE_CHECKING:
    import trimesh

#: Reflectance of a surface that has no material of its own (about dry concrete at 905 nm).
DEFAULT_REFLECTANCE = 0.3
#: A retroreflective material's gain over a Lambertian surface of the same reflectance, unless it says.
DEFAULT_RETRO_GAIN = 300.0
REFLECTANCE_ATTRIBUTE = "reflectance"
RETRO_GAIN_ATTRIBUTE = "retro_gain"
PART_ATTRIBUTE = "part"
SIDECAR_SUFFIX = ".materials.json"


@dataclass(frozen=True)
class Material:
    """A surface as the lidar sees it.

    Parameters
    ----------
    name : str
    reflectance : float
        Lambertian reflectance at 905 nm, 0-1.
    retro_gain : float
        1 for a Lambertian surface; a retroreflector's echo is this many times brighter.
    """

    name: str
    reflectance: float
    retro_gain: float = 1.0

    def __post_init__(self) -> None:
        if not (isinstance(self.reflectance, (int, float)) and math.isfinite(self.reflectance)
                and 0.0 <= self.reflectance <= 1.0):
            raise LivoxVizError(f"material {quoted(self.name)}: reflectance {quoted(self.reflectance)}; allowed: "
                                "0 to 1")
        if not (isinstance(self.retro_gain, (int, float)) and math.isfinite(self.retro_gain)
                and 1.0 <= self.retro_gain <= 1e5):
            raise LivoxVizError(f"material {quoted(self.name)}: retro_gain {quoted(self.retro_gain)}; allowed: "
                                "1 to 100000")

    @property
    def retroreflective(self) -> bool:
        """Whether the surface sends light back where it came from (gain above 1)."""
        return self.retro_gain > 1.0


#: Plausible surfaces at 905 nm (near infrared: vegetation is bright, asphalt dark).
MATERIALS: dict[str, Material] = {m.name: m for m in (
    Material("asphalt", 0.12),
    Material("concrete", 0.35),
    Material("brick", 0.40),
    Material("roof_tiles", 0.30),
    Material("vegetation", 0.50),
    Material("grass", 0.40),
    Material("soil", 0.25),
    Material("bark", 0.30),
    Material("wood", 0.45),
    Material("painted_metal", 0.35),
    Material("white_paint", 0.80),
    Material("black_rubber", 0.04),
    Material("retroreflective_sign", 0.80, DEFAULT_RETRO_GAIN),
)}


def parse_material(value: Any, where: str) -> Material:
    """A material from JSON: a name of :data:`MATERIALS`, a reflectance, or an object.

    Parameters
    ----------
    value : str, float or dict
        ``"asphalt"``, ``0.3``, or ``{"reflectance": 0.8, "retroreflective": true, "retro_gain": 300}``.
    where : str
        Named in the error message.
    """
    allowed = (f"allowed: a material name ({', '.join(MATERIALS)}), a reflectance 0-1, or "
               '{"reflectance": R, "retroreflective": true|false, "retro_gain": G}')
    if isinstance(value, str):
        if value not in MATERIALS:
            raise LivoxVizError(f"{where}: unknown material {quoted(value)}; {allowed}")
        return MATERIALS[value]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return Material(f"reflectance {value:g}", _reflectance(value, where, allowed))
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - {"reflectance", "retroreflective", "retro_gain", "name"})
        if unknown or "reflectance" not in value:
            raise LivoxVizError(f"{where}: material {quoted(dict(value))}; {allowed}")
        retro = value.get("retroreflective", "retro_gain" in value)
        if not isinstance(retro, bool):
            raise LivoxVizError(f"{where}: retroreflective = {quoted(retro)}; allowed: true or false")
        if not retro and "retro_gain" in value:
            raise LivoxVizError(f"{where}: retro_gain = {quoted(value['retro_gain'])} with retroreflective = false; "
                                "allowed: a retro_gain only on a retroreflective material")
        gain = value.get("retro_gain", DEFAULT_RETRO_GAIN) if retro else 1.0
        if isinstance(gain, bool) or not isinstance(gain, (int, float)) or not math.isfinite(gain) or not (
                1 < gain <= 1e5 or not retro):
            raise LivoxVizError(f"{where}: retro_gain = {quoted(gain)}; allowed: a number in (1, 100000]")
        name = str(value.get("name", "retroreflective" if retro else "custom"))
        return Material(name, _reflectance(value["reflectance"], where, allowed), float(gain))
    raise LivoxVizError(f"{where}: material {quoted(value)}; {allowed}")


def _reflectance(value: Any, where: str, allowed: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not (
            0 <= value <= 1):
        raise LivoxVizError(f"{where}: reflectance {quoted(value)}; {allowed}")
    return float(value)


def check_reflectance(value: float) -> float:
    """``--reflectance``: a number in [0, 1], else a one-line error."""
    return _reflectance(value, "--reflectance", "allowed: a Lambertian reflectance from 0 to 1")


def reflectance_from_colour(rgba: Sequence[float]) -> float:
    """The reflectance a material colour stands for: the luminance of its RGB (0-255, taken as linear).

    Parameters
    ----------
    rgba : (3,) or (4,) of 0-255
    """
    r, g, b = (float(c) / 255.0 for c in list(rgba)[:3])
    return float(np.clip(0.2126 * r + 0.7152 * g + 0.0722 * b, 0.0, 1.0))


# Per-face arrays ---------------------------------------------------------------------------------
def set_face_materials(mesh: trimesh.Trimesh, reflectance: np.ndarray, retro_gain: np.ndarray,
                       part: np.ndarray | None = None) -> trimesh.Trimesh:
    """Attach per-face materials (and object numbers) to ``mesh``; returns it.

    Parameters
    ----------
    reflectance : (F,) float
        NaN where a face has no material (filled by :func:`fill_reflectance`).
    retro_gain : (F,) float
    part : (F,) int, optional
    """
    faces = len(mesh.faces)
    mesh.face_attributes[REFLECTANCE_ATTRIBUTE] = np.asarray(reflectance, dtype=np.float64).reshape(faces)
    mesh.face_attributes[RETRO_GAIN_ATTRIBUTE] = np.asarray(retro_gain, dtype=np.float64).reshape(faces)
    if part is not None:
        mesh.face_attributes[PART_ATTRIBUTE] = np.asarray(part, dtype=np.int32).reshape(faces)
    return mesh


def fill_reflectance(mesh: trimesh.Trimesh, reflectance: float = DEFAULT_REFLECTANCE) -> trimesh.Trimesh:
    """Give every face without a material the Lambertian ``reflectance``; returns the mesh."""
    reflectance = check_reflectance(reflectance)
    own, gain = face_materials(mesh, reflectance)
    return set_face_materials(mesh, own, gain, mesh.face_attributes.get(PART_ATTRIBUTE))


def face_materials(mesh: trimesh.Trimesh, default: float = DEFAULT_REFLECTANCE) -> tuple[np.ndarray, np.ndarray]:
    """Reflectance and retroreflective gain of every face, ``(F,)`` float64 each.

    Faces without a material (no attribute, or NaN) get the Lambertian ``default``.
    """
    faces = len(mesh.faces)
    reflectance = np.asarray(mesh.face_attributes.get(REFLECTANCE_ATTRIBUTE, np.full(faces, np.nan)),
                             dtype=np.float64)
    gain = np.asarray(mesh.face_attributes.get(RETRO_GAIN_ATTRIBUTE, np.ones(faces)), dtype=np.float64)
    if reflectance.shape != (faces,) or gain.shape != (faces,):
        raise LivoxVizError(f"the mesh's material arrays have {reflectance.shape}/{gain.shape} entries for "
                            f"{faces} faces")
    missing = np.isnan(reflectance)
    if missing.any():
        reflectance = np.where(missing, default, reflectance)
        gain = np.where(missing, 1.0, gain)
    return reflectance, gain


def face_parts(mesh: trimesh.Trimesh) -> np.ndarray:
    """The object number of every face, ``(F,)`` int32 (all 0 when the mesh does not say)."""
    part = mesh.face_attributes.get(PART_ATTRIBUTE)
    return np.zeros(len(mesh.faces), np.int32) if part is None else np.asarray(part, dtype=np.int32)


# Sidecar files -------------------------------------------------------------------------------------
#: Characters of one key of a material map (a name or a glob pattern) at most.
MAX_KEY_CHARS = 256
#: Glob patterns (keys with ``*``, ``?`` or ``[``) in one material map at most: each is tried on every name.
MAX_PATTERNS = 1000
_STAR = object()


def is_pattern(key: str) -> bool:
    """Whether a material map's key is a glob pattern (holds ``*``, ``?`` or ``[``) rather than a plain name."""
    return "*" in key or "?" in key or "[" in key


def glob_regex(pattern: str) -> str:
    """The regular expression (for ``fullmatch``) of a shell glob: ``*``, ``?``, ``[seq]``, ``[!seq]``, ``[a-z]``.

    The same matches as :func:`fnmatch.fnmatchcase`, made in time linear in the pattern's length: fnmatch
    searches for a closing ``]`` afresh from every ``[`` (100 000 of them took minutes); here once no ``]``
    follows, every later ``[`` is a literal without a search. Stars become atomic lazy groups, as in fnmatch, so
    matching never backtracks through them.
    """
    pieces: list[object] = []
    i, n = 0, len(pattern)
    closing = True  # whether a ']' may still follow
    while i < n:
        c = pattern[i]
        i += 1
        if c == "*":
            if not pieces or pieces[-1] is not _STAR:
                pieces.append(_STAR)
        elif c == "?":
            pieces.append(".")
        elif c == "[" and closing:
            j = i + (i < n and pattern[i] == "!")
            j += j < n and pattern[j] == "]"
            j = pattern.find("]", j)
            if j < 0:
                closing = False
                pieces.append(re.escape(c))
            else:
                pieces.append(_char_class(pattern[i:j]))
                i = j + 1
        else:
            pieces.append(re.escape(c))
    text: list[str] = []
    k = 0
    while k < len(pieces) and pieces[k] is not _STAR:
        text.append(str(pieces[k]))
        k += 1
    while k < len(pieces):  # a star, then the fixed run up to the next star (or the end)
        k += 1
        fixed = []
        while k < len(pieces) and pieces[k] is not _STAR:
            fixed.append(str(pieces[k]))
            k += 1
        text.append(f".*{''.join(fixed)}" if k == len(pieces) else f"(?>.*?{''.join(fixed)})")
    return f"(?s:{''.join(text)})"


def _char_class(body: str) -> str:
    """A ``[...]`` of a glob (without its brackets) as a regular expression's set; ranges that run backwards
    match nothing, as in fnmatch."""
    negate = body.startswith("!")
    body = body[1:] if negate else body
    items = []
    k = 0
    while k < len(body):
        if k + 2 < len(body) and body[k + 1] == "-":
            if body[k] <= body[k + 2]:
                items.append(f"{_set_escape(body[k])}-{_set_escape(body[k + 2])}")
            k += 3
        else:
            items.append(_set_escape(body[k]))
            k += 1
    if not items:
        return "." if negate else "(?!)"
    return f"[{'^' if negate else ''}{''.join(items)}]"


def _set_escape(char: str) -> str:
    return "\\" + char if char in "\\]^-[&~|" else char


@dataclass(frozen=True)
class MaterialMap:
    """A sidecar's mapping from mesh or material names (or glob patterns) to materials, in file order.

    A name is looked up in a table and the patterns are one regular expression, so a map of any size is read
    and used in one pass over its keys (at most :data:`MAX_PATTERNS` patterns, each at most
    :data:`MAX_KEY_CHARS` long, are tried on each name).

    Parameters
    ----------
    entries : tuple of (str, Material)
    source : str
        Where it came from, for messages.
    """

    entries: tuple[tuple[str, Material], ...]
    source: str = ""

    @cached_property
    def _names(self) -> dict[str, int]:
        """Each key (a pattern too: a name may hold ``*``) to the number of its first entry."""
        keys = [key for key, _ in self.entries]
        return dict(zip(reversed(keys), range(len(keys) - 1, -1, -1), strict=True))  # the first of a repeated key

    @cached_property
    def _patterns(self) -> list[int]:
        """The numbers of the entries whose keys are glob patterns, in order."""
        return [index for index, (key, _) in enumerate(self.entries) if "*" in key or "?" in key or "[" in key]

    @cached_property
    def _first_pattern(self) -> re.Pattern[str] | None:
        """All patterns as one alternation: ``fullmatch`` tries them in order, and its ``lastindex`` is the first
        that matches (each pattern is group k + 1; their own groups capture nothing)."""
        if not self._patterns:
            return None
        return re.compile("|".join(f"({glob_regex(self.entries[i][0])})" for i in self._patterns))

    def _first_pattern_matching(self, names: Sequence[str]) -> int | None:
        """The number of the first pattern entry that matches any of ``names``, or None."""
        matcher = self._first_pattern
        if matcher is None:
            return None
        found = [m.lastindex for m in map(matcher.fullmatch, names) if m is not None and m.lastindex]
        return self._patterns[min(found) - 1] if found else None

    def lookup(self, names: Sequence[str]) -> Material | None:
        """The material of the first entry matching any of ``names`` exactly, else by pattern; None if none does."""
        present = [n for n in names if n]
        exact = [self._names[n] for n in present if n in self._names]
        index = min(exact) if exact else self._first_pattern_matching(present)
        return None if index is None else self.entries[index][1]

    def require_matches(self, names: Sequence[str], where: str) -> None:
        """Raise :class:`LivoxVizError` naming the first entry that matches none of ``names`` (a mesh's part,
        geometry and material names), and the names there are."""
        present = sorted({n for n in names if n})
        matcher = self._first_pattern
        matched = set() if matcher is None else {
            self._patterns[m.lastindex - 1] for m in map(matcher.fullmatch, present) if m is not None and m.lastindex}
        for index, (key, _) in enumerate(self.entries):
            if key in present or index in matched:
                continue
            if is_pattern(key):
                single = re.compile(glob_regex(key))
                if any(single.fullmatch(n) for n in present):
                    continue
            shown = ", ".join(repr(n) for n in present[:12]) + (", ..." if len(present) > 12 else "")
            raise LivoxVizError(f"{self.source}: {quoted(key)} names nothing in {where}; allowed: its part, "
                                f"geometry and material names ({shown}) or glob patterns of them")

    @classmethod
    def merged(cls, first: MaterialMap | None, then: MaterialMap | None) -> MaterialMap | None:
        """One map of ``first``'s entries, then ``then``'s (a name both give takes ``first``'s); None if neither."""
        if first is None or then is None:
            return first if then is None else then
        return cls(first.entries + then.entries, f"{first.source} and {then.source}")

    @classmethod
    def from_json(cls, data: Any, source: str) -> MaterialMap:
        """Read ``{"name or pattern": material, ...}`` (see :func:`parse_material`).

        Keys are at most :data:`MAX_KEY_CHARS` long, at most :data:`MAX_PATTERNS` of them patterns. A material
        given as a name or a number is read once however many keys give it.
        """
        if not isinstance(data, Mapping) or not data:
            raise LivoxVizError(f"{source}: a material sidecar must be a JSON object mapping mesh or material "
                                "names (or glob patterns) to materials")
        read: dict[tuple[type, Any], Material] = {}
        entries = []
        patterns = 0
        for key, value in data.items():
            if len(key) > MAX_KEY_CHARS:
                raise LivoxVizError(f"{source}: the key {quoted(key)} is longer than {MAX_KEY_CHARS} characters; "
                                    f"allowed: a mesh or material name, or a glob pattern, of at most "
                                    f"{MAX_KEY_CHARS}")
            patterns += is_pattern(key)
            if patterns > MAX_PATTERNS:
                raise LivoxVizError(f"{source}: more than {MAX_PATTERNS} glob patterns (keys with *, ? or [); "
                                    f"allowed: at most {MAX_PATTERNS}, and any number of plain names")
            plain = isinstance(value, (str, int, float)) and not isinstance(value, bool)
            material = read.get((type(value), value)) if plain else None
            if material is None:
                material = parse_material(value, f"{source}: {quoted(key)}")
                if plain:
                    read[(type(value), value)] = material
            entries.append((key, material))
        return cls(tuple(entries), source)


def material_colour(material: Any) -> np.ndarray | None:
    """The RGB(A) 0-255 a mesh file's material gives its surface, or None when it gives none.

    A glTF material's base colour factor times its base colour texture's mean (a factor left out is white, as
    glTF says); an OBJ material's diffuse colour (``Kd``). What trimesh fills in for a colour the file left out
    (its placeholder grey, 102 of 255) is no colour: such a surface takes ``--reflectance``. For an OBJ material
    that placeholder is told from a ``Kd`` of 0.4 by its ambient and specular colours, which trimesh fills the
    same way: all three at the placeholder means the file gave none of them.
    """
    from trimesh.visual.color import DEFAULT_COLOR

    placeholder = np.asarray(DEFAULT_COLOR, dtype=np.float64)
    if hasattr(material, "baseColorFactor"):  # glTF's PBR material
        factor = getattr(material, "baseColorFactor", None)
        texture = getattr(material, "baseColorTexture", None)
        if factor is None and texture is None:
            return None
        rgba = np.full(4, 255.0) if factor is None else np.asarray(factor, dtype=np.float64).reshape(-1)
        if rgba.size == 4 and rgba.max() <= 1.0 and np.issubdtype(np.asarray(factor).dtype, np.floating):
            rgba = rgba * 255.0
        if texture is not None:
            from PIL import Image

            # The mean of a box-filtered 256 x 256 copy: a 4k texture's own pixels would take 400 MB as floats.
            image = texture.convert("RGB")
            if image.width * image.height > 256 * 256:
                image = image.resize((256, 256), Image.Resampling.BOX)
            pixels = np.asarray(image, dtype=np.float64).reshape(-1, 3)
            rgba[:3] = rgba[:3] * pixels.mean(axis=0) / 255.0
        return rgba
    colours = [getattr(material, key, None) for key in ("diffuse", "ambient", "specular")]
    if colours[0] is None:
        return None
    if all(c is not None and np.array_equal(np.asarray(c, dtype=np.float64), placeholder) for c in colours):
        return None
    return np.asarray(colours[0], dtype=np.float64)


def sidecar_path(mesh_path: Path) -> Path:
    """``city.glb`` -> ``city.materials.json`` beside it."""
    return mesh_path.with_name(mesh_path.stem + SIDECAR_SUFFIX)


def read_sidecar(mesh_path: Path) -> MaterialMap | None:
    """The material sidecar of a mesh file, or None when there is none.

    Something under the sidecar's name that is no file (a folder, a named pipe, a device, a dangling link or a
    loop of links) is refused, not skipped: the user meant it to give the materials.
    """
    path = sidecar_path(mesh_path)
    if not os.path.lexists(path):
        return None
    kind = not_a_file(path)
    if kind is not None:
        raise LivoxVizError(f"{path}: the material sidecar of {mesh_path.name} is {kind}; allowed: a JSON file of "
                            "materials (or nothing by that name)")
    return MaterialMap.from_json(read_json_file(path, "material sidecar"), str(path))


def part_material(part: trimesh.Trimesh, names: Sequence[str], sidecar: MaterialMap | None) -> tuple[
        np.ndarray, np.ndarray]:
    """The per-face reflectance and gain of one mesh part: the sidecar by name, else its colours, else NaN.

    Parameters
    ----------
    part : trimesh.Trimesh
        One geometry of a mesh file, with trimesh's visual.
    names : sequence of str
        Its node, geometry and material names.
    sidecar : MaterialMap or None
    """
    faces = len(part.faces)
    if sidecar is not None:
        found = sidecar.lookup(names)
        if found is not None:
            return np.full(faces, found.reflectance), np.full(faces, found.retro_gain)
    visual = part.visual
    gain = np.ones(faces)
    material = getattr(visual, "material", None)
    if material is not None:
        colour = material_colour(material)
        if colour is not None:
            return np.full(faces, reflectance_from_colour(colour)), gain
    if getattr(visual, "kind", None) in ("face", "vertex") and getattr(visual, "defined", False):
        colours = np.asarray(visual.face_colors, dtype=np.float64)[:, :3] / 255.0
        return np.clip(colours @ np.array([0.2126, 0.7152, 0.0722]), 0.0, 1.0), gain
    return np.full(faces, np.nan), gain
