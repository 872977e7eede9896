"""livox-viz: the simulated Livox rosette lidar of RflySim (TypeID 6), as a model.

This package never imports VTK or pyvista and never names the GUI: the GUI adds its
commands through the ``livox_viz.commands`` entry point.
"""

from __future__ import annotations

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
