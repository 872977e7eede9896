"""The text over the views: what each view shows, in words, drawn into the view itself.

It is part of the picture (a screenshot or ``render`` says what it shows):
the pattern view names the configuration, the scan time and the window, and
says honestly how many of the points fired it holds; the scene view names the
scene, the return model and how many of the cloud's points are drawn. The
window's status bar, menus and help live in Qt (:mod:`~livox_viz.widgets.mainwindow`).
"""

from __future__ import annotations

import re
import textwrap
import time

import pyvista as pv

from .colour_range import range_words
from .overlay import window_label
from .panel import number_text
from .session import Session

#: The views' text: large enough to read at 1280 x 720, light on a dark band so it reads over any point.
FONT_SIZE = 11
TEXT_COLOUR = "#e6ebf2"
#: The longest line drawn: VTK's corner text shrinks every line to fit the longest in the view, and one line of
#: 110 characters (the unlimited window's note) made the whole text 6 px tall.
LINE_CHARS = 64


#: A number and its unit: never broken apart ("coverage 44.1" and " %" came out on two lines).
_NUMBER_AND_UNIT = re.compile(r"(\d) (%|s|ms|m|deg|Hz|pts/s)(?=[\s,:;)]|$)")


def wrapped(text: str, width: int = LINE_CHARS) -> str:
    """``text`` with each line longer than ``width`` broken at spaces (not between a number and its unit), the
    rest of it indented."""
    lines = []
    for line in text.split("\n"):
        if len(line) > width:
            # textwrap breaks only at ASCII whitespace: a no-break space holds the pair together.
            line = textwrap.fill(_NUMBER_AND_UNIT.sub("\\1\u00a0\\2", line), width, subsequent_indent="  ",
                                 break_long_words=False).replace("\u00a0", " ")
        lines.append(line)
    return "\n".join(lines)


def _text(plotter: pv.Plotter, name: str) -> object:
    actor = plotter.add_text("", position="upper_left", font_size=FONT_SIZE, color=TEXT_COLOUR, name=name)
    style = actor.GetTextProperty()
    style.SetBackgroundColor(0.06, 0.08, 0.11)
    style.SetBackgroundOpacity(0.55)
    return actor


def window_line(session: Session) -> str:
    """How many points the pattern view holds of those fired in its window, saying why when it holds fewer."""
    held = session.pattern_ring.count
    fired = session.points_fired_in_window()
    line = f"window {window_label(session.window)}: {held:,} points"
    if session.source is None and fired > held:
        if session.window is None:
            capacity = session.pattern_ring.capacity
            line += f" (the last {held:,} of {fired:,} fired: the unlimited window holds {capacity:,})"
        elif session.skipped_points:
            line += (f" of {fired:,} fired ({session.skipped_points:,} skipped since the start: this machine could "
                     f"not draw {session.config.point_rate:,} pts/s)")
        else:
            line += f" of {fired:,} fired"
    return line


def coverage_words(session: Session) -> str:
    """"of these " when the view holds fewer points than its window fired: the coverage is that of the points
    shown (98.5 % of a 5 M pts/s pattern drawn as points, 100 % as a density image, which drops fewer)."""
    held = session.pattern_ring.count
    return "of these " if session.source is None and session.points_fired_in_window() > held else ""


class HeadsUp:
    """Text actors over the views, updated from the session.

    Parameters
    ----------
    pattern_plotter, scene_plotter : pyvista.Plotter or None
        The views' plotters (None: that view is not shown).
    """

    def __init__(self, pattern_plotter: pv.Plotter | None, scene_plotter: pv.Plotter | None) -> None:
        self.state = _text(pattern_plotter, "hud") if pattern_plotter is not None else None
        self.scene_state = _text(scene_plotter, "scene-hud") if scene_plotter is not None else None
        self._reference_at = -1.0
        self._reference_coverage: float | None = None

    def pattern_text(self, session: Session, density_shown: bool = False) -> str:
        """The pattern view's lines."""
        cfg = session.config
        state = "paused" if session.playback.paused else f"{session.playback.speed:g}x"
        overlay = session.overlay
        reference = ""
        if overlay.source is not None:
            # The overlay's coverage is counted afresh, so only twice a second (or when paused).
            now = time.monotonic()
            if now - self._reference_at > 0.5 or session.playback.paused or self._reference_coverage is None:
                self._reference_at = now
                self._reference_coverage = overlay.coverage()
            shown = " (grey)" if overlay.visible else " (hidden)"
            value = self._reference_coverage
            held = f", held at {overlay.source.end:.3g} s" if overlay.ended else ""
            reference = (f"\nreference {overlay.source.name}{shown}, window {window_label(overlay.window)}{held}: "
                         f"coverage {'-' if value is None else f'{100 * value:.1f} %'}")
        model = {"risley": "Risley track", "track": "track"}.get(cfg.pattern_model, "RflySim rosette")
        lasers = f"   {cfg.lasers} lasers" if cfg.lasers > 1 else ""
        fov = cfg.field_of_view
        # As the panel's box shows it: "70.1232" here beside the box's "70.123" read as two values (a first-use
        # trial); both now show the value the scan uses.
        fov_text = f"FOV {number_text(cfg.camera_fov)} deg" if fov.shape == "cone" else f"FOV {fov.describe()}"
        drawing = "density image" if density_shown else "points"
        return (
            # The field of view on a line of its own: after the rate, a band's "elevation -7.212 to 52.16 deg" ran
            # past a narrow view's edge.
            f"{session.preset_name or 'custom'}   {model}{lasers}   {cfg.point_rate:,} pts/s\n"
            + (f"{session.live_line()}\n" if session.live is not None else "")
            + f"{fov_text}\n"
            f"t = {session.shown_time:8.3f} s   frame {max(session.shown_frame, 0)}   {state}\n"
            f"{window_line(session)}, coverage {coverage_words(session)}{100 * session.visible_coverage():.1f} %"
            f"{reference}\n"
            f"colour: {session.display.pattern_colour}   drawn as {drawing} ({session.display.drawing})"
            + (f"   jitter per {cfg.jitter_scope}" if cfg.pattern_model == "rflysim" else "")
        )

    def scene_text(self, session: Session, drawn: int, opened: str = "", filtered: str = "") -> str:
        """The scene view's lines; ``drawn`` is how many of the cloud's points the view draws, ``opened`` the line
        of a cloud opened from a file, ``filtered`` the filter's ("" with none)."""
        cfg = session.config
        count = session.scene_ring.count
        thinned = f" (drawing {drawn:,}: 1 in {round(count / max(drawn, 1))})" if drawn < count else ""
        mode = session.display.scene_colour
        bounds = session.display.scene_colour_ranges.get(mode)
        fixed = f", {range_words(mode, bounds)}" if bounds is not None else ""
        lines = [f"scene {session.scene.name}: {len(session.scene.mesh.faces):,} triangles",
                 f"decoded cloud: {count:,} returns in the window{thinned}",
                 *([filtered] if filtered else []),
                 f"returns: {cfg.returns_model}   colour: {session.display.scene_colour}{fixed}"]
        if session.display.scene_colour == "reflectivity" and cfg.returns_model == "ideal":
            lines.append("ideal returns carry no intensity (reflectivity 0): turn on the datasheet returns (d)")
        if session.trajectory is not None:
            lines.append(f"trajectory {session.trajectory.name}, cloud in the {session.display.cloud_frame} frame")
        if opened:
            lines.append(opened)
        return "\n".join(lines)

    def update(self, session: Session, density_shown: bool = False, drawn: int = 0, opened: str = "",
               filtered: str = "") -> None:
        """All text from the session's state (``opened``, ``filtered``: as :meth:`scene_text`)."""
        if self.state is not None:
            self.state.SetText(2, wrapped(self.pattern_text(session, density_shown)))
        if self.scene_state is not None:
            self.scene_state.SetText(2, wrapped(self.scene_text(session, drawn, opened, filtered)))
