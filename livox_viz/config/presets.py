"""Finding sensor presets: shipped ones (checkout or installed wheel) and the user's own."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import platformdirs

from livox_viz.config.sensor import SensorConfig, load_config
from livox_viz.config.shipped import DEFAULT_PRESET, shipped_preset_dir
from livox_viz.core.errors import ConfigError, quoted
from livox_viz.core.jsonfile import read_json_file

DESCRIPTION_KEY = "LivoxVizDescription"
#: The folder name of the user's own files in the platform's configuration folder.
APP_NAME = "livox-viz"
_INDEX_FILE = "index.json"


@dataclass(frozen=True)
class PresetInfo:
    """A preset file and what it is.

    Parameters
    ----------
    name : str
        The file name without ``.json``, used to load it by name.
    path : Path
        Where the file is.
    description : str
        One line for listings.
    shipped : bool
        True for the presets that come with livox-viz (never overwritten).
    """

    name: str
    path: Path
    description: str
    shipped: bool


def user_config_dir(kind: str) -> Path:
    """A folder of the user's own files: ``$LIVOX_VIZ_<KIND>``, else the platform's folder for them.

    That is ``$XDG_CONFIG_HOME/livox-viz/<kind>`` (``~/.config/livox-viz/<kind>``) on Linux,
    ``%APPDATA%\\livox-viz\\<kind>`` on Windows and ``~/Library/Application Support/livox-viz/<kind>`` on
    macOS, as ``platformdirs`` knows them.

    Parameters
    ----------
    kind : str
        ``"presets"`` or ``"scenes"``.
    """
    explicit = os.environ.get(f"LIVOX_VIZ_{kind.upper()}")
    if explicit:
        return Path(explicit)
    # Roaming on Windows: %APPDATA%, where a user's settings follow them (the local folder is for caches).
    return Path(platformdirs.PlatformDirs(APP_NAME, appauthor=False, roaming=True).user_config_dir) / kind


def user_preset_dir() -> Path:
    """The user's own presets: ``$LIVOX_VIZ_PRESETS``, else ``presets`` in the platform's folder
    (:func:`user_config_dir`)."""
    return user_config_dir("presets")


def _index_descriptions(folder: Path) -> dict[str, str]:
    index = folder / _INDEX_FILE
    if not index.is_file():
        return {}
    try:
        data = json.loads(index.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def _describe(path: Path, index: dict[str, str]) -> str:
    try:
        data = read_json_file(path)
    except ConfigError as exc:
        return f"(unreadable: {exc})"
    if isinstance(data, dict) and isinstance(data.get(DESCRIPTION_KEY), str):
        return data[DESCRIPTION_KEY]
    if path.stem in index:
        return index[path.stem]
    try:
        cfg = SensorConfig.from_json_dict(data)
    except ConfigError as exc:
        return f"(invalid: {exc})"
    return (
        f"FOV {cfg.camera_fov:g} deg, {cfg.point_rate} pts/s, "
        f"{2 * cfg.figure8_per_flower} petals per flower, {cfg.flowers_per_figure} flowers per figure"
    )


def list_presets() -> list[PresetInfo]:
    """Every sensor preset, shipped first, then the user's, each sorted by name."""
    found: list[PresetInfo] = []
    for folder, shipped in ((shipped_preset_dir(), True), (user_preset_dir(), False)):
        if not folder.is_dir():
            continue
        index = _index_descriptions(folder)
        for path in sorted(folder.glob("*.json")):
            # Only files: a pipe named *.json among the user's presets would block every command reading it.
            if path.name == _INDEX_FILE or not path.is_file():
                continue
            found.append(PresetInfo(path.stem, path, _describe(path, index), shipped))
    return found


def preset_path(name: str) -> Path:
    """The file of the preset ``name`` (a user preset shadows nothing: shipped wins)."""
    for info in list_presets():
        if info.name == name:
            return info.path
    names = ", ".join(sorted({info.name for info in list_presets()}))
    raise ConfigError(f"unknown preset {quoted(name)}; allowed: {names}")


def load_preset(name_or_path: str | os.PathLike[str] = DEFAULT_PRESET) -> SensorConfig:
    """Load a preset by name (``"livox_mid70"``) or by the path of a JSON file."""
    text = os.fspath(name_or_path)
    if text.endswith(".json") or "/" in text or "\\" in text or os.sep in text:  # a path (either separator)
        return load_config(text)
    return load_config(preset_path(text))
