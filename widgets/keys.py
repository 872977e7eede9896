"""The one key table: it drives the key bindings, the help overlay, the keys line and the user guide's table."""

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
        (key, name of the method it calls: the window's, else the controller's), one per key; a key is a
        character (a letter or a digit) or one of ``space``, ``Right``, ``Up``, ``Down``.
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
    KeyRow("i", "integration window: 0.1, 0.5, 1, 2 s, unlimited (1 M points); any other from the panel or the "
           "Playback menu", (("i", "cycle_window"),), "window"),
    KeyRow("c / k", "pattern colours (time, figure-8, petal, flower, arc; laser for Risley) / scene colours "
           "(range, height, time, reflectivity, return/tag)", (("c", "cycle_pattern_colour"),
                                                               ("k", "cycle_scene_colour")), "colours"),
    KeyRow("d / t", "d: the return model, ideal (each ray's exact first hit, as RflySim) or datasheet (the "
           "sensor's sheet: noise, detection range, beam footprint, returns, reflectivity, tags); t: the panel "
           "shows the pattern's parameters or the return model's sheet",
           (("d", "toggle_returns_model"), ("t", "toggle_slider_page")), "returns"),
    KeyRow("j", "add the random rotation after each flower / after each figure", (("j", "toggle_jitter_scope"),)),
    KeyRow("v", "pattern model: RflySim's rosette / the track (a configuration with Risley or track parameters)",
           (("v", "toggle_pattern_model"),), "model"),
    KeyRow("Ctrl+Z / Ctrl+Shift+Z", "undo / redo the last change of the configuration: a parameter, the preset, the "
           "return or pattern model, a fit (the Edit menu names it; Ctrl+Y redoes too)",
           (("Ctrl+Z", "undo"), ("Ctrl+Shift+Z", "redo"))),
    KeyRow("s", "screenshot of the views (PNG) into `screenshots/` with a JSON sidecar from which `livox-viz render "
           "--sidecar` draws the same picture", (("s", "take_screenshot"),), "screenshot"),
    KeyRow("p", "save the parameters as a user preset (in your presets folder, which `livox-viz presets` names; "
           "never over a shipped one)",
           (("p", "save_preset"),), "preset"),
    KeyRow("n / b", "next / previous preset", (("n", "next_preset"), ("b", "previous_preset")), "presets"),
    KeyRow("w", "moving sensor: the cloud in the world (each point with the pose of its own time: walls stay sharp) "
           "/ as the sensor sees it (the motion's smear shows)", (("w", "toggle_cloud_frame"),)),
    KeyRow("g", "drawing: auto (the pattern as a density image once points outnumber pixels, the scene's cloud "
           "thinned to 250 000 points) / every point / density", (("g", "cycle_drawing"),)),
    KeyRow("m", "next scene: the built-in ones, then mesh files in your scenes folder (a file that fails to load "
           "leaves a message, not a crash)", (("m", "cycle_scene"),)),
    KeyRow("a", "the scene camera turns about the last pick (its focal point there, the view moved sideways only); "
           "r gives the default back", (("a", "turn_about_last_pick"),)),
    KeyRow("o / l", "reference overlay on/off / its own integration window (its coverage shows beside ours)",
           (("o", "toggle_reference"), ("l", "cycle_reference_window"))),
    KeyRow("e", "reference: the next preset with a track in the pattern's plane (or the table of `--reference`)",
           (("e", "cycle_reference"),), "reference"),
    KeyRow("f", "fit the rosette's parameters to the reference and move the sliders there",
           (("f", "fit_to_reference"),), "fit"),
    KeyRow("r", "reset the cameras to fit everything drawn (the reference too)", (("r", "reset_cameras"),)),
    KeyRow("5", "scene view: perspective / orthographic (as Blender's keypad 5), what is looked at kept the same "
           "size; with View > Scene camera > top, a map", (("5", "toggle_projection"),)),
    KeyRow("h", "the keys and the mouse", (("h", "toggle_help"),), "help"),
    KeyRow("q", "quit", (("q", "quit"),), "quit"),
)

#: What the mouse does in the views (the help lists it after the keys).
MOUSE: tuple[tuple[str, str], ...] = (
    ("left drag", "turn the scene's camera (pan the pattern view with the middle button or Shift)"),
    ("wheel / right drag", "zoom"),
    ("click a point (scene)", "picks a point drawn within 5 px of the click: its range, azimuth and elevation, "
                              "reflectivity, tag, return number, time and frame in the status bar, a row with its x, "
                              "y, z in the Picks panel and its number beside it in the view; a second click also "
                              "gives the distance between the two and the angle between their rays, a third the angle "
                              "at the middle one"),
    ("click (pattern)", "the angles and the time of the sample under the cursor (within 5 px)"),
)


def help_html() -> str:
    """The help dialog: every key and mouse action, as an HTML table."""
    from html import escape

    rows = "".join(f"<tr><td><b>{escape(row.label)}</b></td><td>{escape(row.action.replace('`', ''))}</td></tr>"
                   for row in KEYS)
    mouse = "".join(f"<tr><td><b>{escape(what)}</b></td><td>{escape(does)}</td></tr>" for what, does in MOUSE)
    return (f"<h3>Keys</h3><table cellspacing='4'>{rows}</table><h3>Mouse</h3><table cellspacing='4'>{mouse}</table>"
            "<p>Every key is also in the menus; hover over a parameter for what it does.</p>")


def markdown_table() -> str:
    """The key table of the user guide (docs/window.md, under "## Keys"; a test holds it there)."""
    lines = ["| key | action |", "|---|---|"]
    lines += [f"| {row.label} | {row.action} |" for row in KEYS]
    return "\n".join(lines)
