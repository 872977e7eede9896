"""livox-viz: the simulated Livox rosette lidar of RflySim (TypeID 6), as a model.

This package never imports VTK or pyvista and never names the GUI: the GUI adds its
commands through the ``livox_viz.commands`` entry point.

Its names (``load_preset``, ``ScanPattern``, ...) are loaded on first use: ``import
livox_viz`` alone loads nothing heavy, so the command line can take Ctrl-C before
numpy and the model load (:func:`livox_viz.cli.main`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

#: Each public name and the module that holds it.
_LAZY = {
    "DEFAULT_PRESET": "livox_viz.config.presets",
    "list_presets": "livox_viz.config.presets",
    "load_preset": "livox_viz.config.presets",
    "PARAM_RANGES": "livox_viz.config.sensor",
    "SensorConfig": "livox_viz.config.sensor",
    "load_config": "livox_viz.config.sensor",
    "save_config": "livox_viz.config.sensor",
    "ConfigError": "livox_viz.core.errors",
    "LivoxVizError": "livox_viz.core.errors",
    "make_pattern": "livox_viz.patterns.factory",
    "ScanPattern": "livox_viz.patterns.rosette",
    "PatternChunk": "livox_viz.patterns.stream",
}

if TYPE_CHECKING:
    from livox_viz.config.presets import DEFAULT_PRESET, list_presets, load_preset
    from livox_viz.config.sensor import PARAM_RANGES, SensorConfig, load_config, save_config
    from livox_viz.core.errors import ConfigError, LivoxVizError
    from livox_viz.patterns.factory import make_pattern
    from livox_viz.patterns.rosette import ScanPattern
    from livox_viz.patterns.stream import PatternChunk

__all__ = [
    "DEFAULT_PRESET",
    "PARAM_RANGES",
    "ConfigError",
    "LivoxVizError",
    "PatternChunk",
    "ScanPattern",
    "SensorConfig",
    "list_presets",
    "load_config",
    "load_preset",
    "make_pattern",
    "save_config",
]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # once loaded, an ordinary attribute
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])
