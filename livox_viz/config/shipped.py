"""Where the shipped presets live: ``presets/`` of a checkout, or the wheel's copy.

Below :mod:`~livox_viz.config.sensor` (which reads the Mid-360's track from here for RflySim's TypeID 23) and
:mod:`~livox_viz.config.presets` (which lists them).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

DEFAULT_PRESET = "livox_mid70"


def shipped_preset_dir() -> Path:
    """The folder of the shipped presets: ``presets/`` of a checkout, or the wheel's copy."""
    checkout = Path(__file__).resolve().parent.parent / "presets"
    if (checkout / f"{DEFAULT_PRESET}.json").is_file():
        return checkout
    return Path(str(resources.files("livox_viz.shipped_presets")))
