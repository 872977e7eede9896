"""The one key table: it drives the key bindings, the help overlay, the keys line and the README's table."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class KeyRow:
    """One line of the key table.

    Parameters
    ----------
    label : str
        The keys as a user reads them, e.g. ``"Up / Down"``.
    action : str
        What they do.
    bindings : tuple of (str, str)
        (VTK key symbol, name of the window's method it calls), one per key.
    short : str
        The few words the always-visible keys line shows ("" = not shown there).
    """

    label: str
    action: str
    bindings: tuple[tuple[str, str], ...]
    short: str = ""


KEYS: tuple[KeyRow, ...] = (
    KeyRow("space", "pause / play (real time by default, 0.01x to 10x)", (("space", "toggle_pause"),),
           "play/pause"),
    KeyRow("Right / u", "step one unit of the pattern (arc, petal, figure-8, flower or frame) / choose the unit",
           (("Right", "step"), ("u", "cycle_step_unit")), "step"),
    KeyRow("x", "reset the scan to t = 0", (("x", "reset"),)),
    KeyRow("Up / Down", "speed x2 / /2", (("Up", "faster"), ("Down", "slower")), "speed"),
    KeyRow("i", "integration window: 0.1, 0.5, 1, 2 s, unlimited (1 M points)", (("i", "cycle_window"),),
           "window"),
    KeyRow("c / k", "pattern colours (time, figure-8, petal, flower, arc; laser for Risley) / scene colours "
           "(range, height, time, reflectivity, return/tag)", (("c", "cycle_pattern_colour"),
                                                               ("k", "cycle_scene_colour")), "colours"),
    KeyRow("d / t", "return model: ideal (each ray's exact first hit, as RflySim) / datasheet (the sensor's sheet: "
           "noise, detection range, beam footprint, returns, reflectivity, tags) / the sliders of the pattern or of "
           "the return model", (("d", "toggle_returns_model"), ("t", "toggle_slider_page")), "returns"),
    KeyRow("j", "add the random rotation after each flower / after each figure", (("j", "toggle_jitter_scope"),)),
    KeyRow("v", "pattern model: RflySim's rosette / the track (a configuration with Risley or track parameters)",
           (("v", "toggle_pattern_model"),), "model"),
    KeyRow("s", "screenshot PNG into `screenshots/` with a JSON sidecar (configuration, seed, scan time, cameras)",
           (("s", "take_screenshot"),), "screenshot"),
    KeyRow("p", "save the sliders as a user preset (`~/.config/livox-viz/presets`, never over a shipped one)",
           (("p", "save_preset"),), "preset"),
    KeyRow("n / b", "next / previous preset", (("n", "next_preset"), ("b", "previous_preset")), "presets"),
    KeyRow("w", "moving sensor: the cloud in the world (each point with the pose of its own time: walls stay sharp) "
           "/ as the sensor sees it (the motion's smear shows)", (("w", "toggle_cloud_frame"),)),
    KeyRow("g", "drawing: auto (the pattern as a density image once points outnumber pixels, the scene's cloud "
           "thinned to 250 000 points) / every point / density", (("g", "cycle_drawing"),)),
    KeyRow("m", "next scene: the built-in ones, then mesh files in `~/.config/livox-viz/scenes` (a file that fails "
           "to load leaves a message, not a crash)", (("m", "cycle_scene"),)),
    KeyRow("o / l", "reference overlay on/off / its own integration window (its coverage shows beside ours)",
           (("o", "toggle_reference"), ("l", "cycle_reference_window"))),
    KeyRow("e", "reference: the next preset with a track in the pattern's plane (or the table of `--reference`)",
           (("e", "cycle_reference"),), "reference"),
    KeyRow("f", "fit the rosette's parameters to the reference and move the sliders there",
           (("f", "fit_to_reference"),), "fit"),
    KeyRow("r", "reset the cameras", (("r", "reset_cameras"),)),
    KeyRow("h", "help overlay", (("h", "toggle_help"),), "help"),
    KeyRow("q", "quit", (), "quit"),
)


def keys_line() -> str:
    """The always-visible one-line summary."""
    return "  ".join(f"{row.label.replace(' / ', '/')} {row.short}" for row in KEYS if row.short)


def help_text() -> str:
    """The help overlay: every key and what it does, wrapped to fit the pattern view."""
    import textwrap

    lines = ["livox-viz keys"]
    for row in KEYS:
        wrapped = textwrap.wrap(row.action.replace("`", ""), 60) or [""]
        lines.append(f"{row.label:<10} {wrapped[0]}")
        lines.extend(f"{'':<10} {more}" for more in wrapped[1:])
    return "\n".join(lines)


def markdown_table() -> str:
    """The README's key table."""
    lines = ["| key | action |", "|---|---|"]
    lines += [f"| {row.label} | {row.action} |" for row in KEYS]
    return "\n".join(lines)
