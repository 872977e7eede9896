"""Undo and redo of the window's configuration: every parameter, preset, return-model or fit change is a step.

Qt-free, as the session: the window's Edit menu and keys call :meth:`Session.undo` / :meth:`Session.redo`, which
apply a step through the same path as any other change (a restart, the panel following).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from livox_viz.config.sensor import PARAM_RANGES, SensorConfig
from livox_viz.core.errors import LivoxVizError

#: Steps kept each way: a long tuning session keeps its last hundred changes (a configuration is a few KiB).
HISTORY_DEPTH = 100


@dataclass(frozen=True)
class ConfigState:
    """What one step gives back: the configuration, the preset it is shown as, and that preset's own values (a
    parameter's reset goes back to those)."""

    config: SensorConfig
    preset_name: str
    preset_config: SensorConfig


def _param_values(config: SensorConfig) -> dict[str, float]:
    values = {}
    for name in PARAM_RANGES:
        try:
            values[name] = config.param_value(name)
        except LivoxVizError:  # a Risley or track field of a configuration that has none
            continue
    return values


def param_title(name: str) -> str:
    """A parameter as the panel names it: ``"DataWidth"``, ``"[1] petal height h"``, ``"prism A speed"``."""
    spec = PARAM_RANGES[name]
    meaning = spec.label.split(",")[0]
    if spec.name.startswith("otherParams["):
        return f"[{spec.name[len('otherParams['):-1]}] {meaning}"
    return meaning if spec.name.startswith("LivoxViz") else spec.name


def _number(value: float) -> str:
    return f"{value:.9g}" if math.isfinite(value) else str(value)


def describe_change(before: ConfigState, after: ConfigState, most: int = 3) -> str:
    """A few words naming what differs between two states, e.g. ``"DataWidth 250 -> 116"``.

    Parameters
    ----------
    before, after : ConfigState
    most : int
        Parameters named at most; more are counted ("and 4 more").
    """
    if before.preset_name != after.preset_name:
        return f"preset {before.preset_name or '(none)'} -> {after.preset_name or '(none)'}"
    old, new = before.config, after.config
    if old.pattern_model != new.pattern_model:
        return f"pattern model {old.pattern_model} -> {new.pattern_model}"
    if old.returns_model != new.returns_model:
        return f"returns {old.returns_model} -> {new.returns_model}"
    old_values, new_values = _param_values(old), _param_values(new)
    changed = [name for name in PARAM_RANGES if name in old_values and name in new_values
               and old_values[name] != new_values[name]]
    if not changed:
        return "the configuration"
    named = ", ".join(f"{param_title(name)} {_number(old_values[name])} -> {_number(new_values[name])}"
                      for name in changed[:most])
    return named + (f" and {len(changed) - most} more" if len(changed) > most else "")


class ConfigHistory:
    """The undo and redo stacks of a session's configuration.

    A change made by the user (:meth:`record`) clears what could be redone, as every editor does; an undone
    change can be redone until then.
    """

    def __init__(self, depth: int = HISTORY_DEPTH) -> None:
        self.depth = depth
        self._undo: list[ConfigState] = []
        self._redo: list[ConfigState] = []
        #: Counted up at every change of either stack: a view of the history redraws only when it moved.
        self.version = 0

    def record(self, before: ConfigState) -> None:
        """A new change was made from ``before``."""
        self.version += 1
        self._undo.append(before)
        del self._undo[:-self.depth]
        self._redo.clear()

    def undo_target(self) -> ConfigState | None:
        """The state an undo gives back, or None (nothing to undo)."""
        return self._undo[-1] if self._undo else None

    def redo_target(self) -> ConfigState | None:
        """The state a redo gives back, or None."""
        return self._redo[-1] if self._redo else None

    def undone(self, current: ConfigState) -> ConfigState:
        """Take the undo step (the caller shows it); ``current`` becomes the redo step."""
        self.version += 1
        state = self._undo.pop()
        self._redo.append(current)
        return state

    def redone(self, current: ConfigState) -> ConfigState:
        """Take the redo step; ``current`` becomes the undo step again."""
        self.version += 1
        state = self._redo.pop()
        self._undo.append(current)
        del self._undo[:-self.depth]
        return state

    def clear(self) -> None:
        self.version += 1
        self._undo.clear()
        self._redo.clear()
