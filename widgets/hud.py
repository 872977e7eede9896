"""The heads-up text: the state lines of both views, the keys line, the help overlay and messages."""

from __future__ import annotations

import time

import pyvista as pv

from .keys import help_text, keys_line
from .overlay import window_label
from .session import Session


class HeadsUp:
    """Text actors over the views, updated from the session.

    Parameters
    ----------
    plotter : pyvista.Plotter
    pattern_spot, scene_spot : tuple of int or None
        Subplots of the views shown (None: that view is not in the window).
    """

    def __init__(self, plotter: pv.Plotter, pattern_spot: tuple[int, int] | None,
                 scene_spot: tuple[int, int] | None) -> None:
        first = pattern_spot or scene_spot or (0, 0)
        plotter.subplot(*first)
        self.state = plotter.add_text("", position="upper_left", font_size=10, color="#dde3ea", name="hud")
        self.keys = plotter.add_text("", position="lower_left", font_size=9, color="#8a96a8", name="keys")
        self.help = plotter.add_text("", position=(0.03, 0.12), viewport=True, font_size=9, color="#ffffff",
                                     name="help")
        style = self.help.GetTextProperty()
        style.SetFontFamilyToCourier()
        style.SetBackgroundColor(0.05, 0.06, 0.09)
        style.SetBackgroundOpacity(0.92)
        style.SetFrame(True)
        style.SetFrameColor(0.95, 0.76, 0.31)
        # The text is scaled into a box of the view (every key fits, at any window size): at a fixed size the list
        # outgrew a 1600 x 900 window's view, its first lines above the top and each line past the right edge.
        self.help.SetTextScaleModeToProp()
        self.help.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        self.help.GetPositionCoordinate().SetValue(0.02, 0.08)
        self.help.GetPosition2Coordinate().SetCoordinateSystemToNormalizedViewport()
        self.help.GetPosition2Coordinate().SetValue(0.96, 0.86)
        self.keys.SetText(0, keys_line())
        self.help.SetInput(help_text())
        self.help.SetVisibility(False)
        self.help_visible = False
        self.scene_state = None
        if pattern_spot is not None and scene_spot is not None:
            plotter.subplot(*scene_spot)
            self.scene_state = plotter.add_text("", position="upper_left", font_size=10, color="#dde3ea",
                                                name="scene-hud")
        self.message = plotter.add_text("", position="lower_left" if self.scene_state else "lower_right",
                                        font_size=10, color="#ff7b72", name="message")
        self._message_corner = 0 if self.scene_state else 1
        self._reference_at = -1.0
        self._reference_coverage: float | None = None
        self.fps = 0.0

    def update(self, session: Session, show_scene: bool) -> None:
        """All text from the session's state."""
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
            shown = "" if overlay.visible else " (hidden, o)"
            value = self._reference_coverage
            reference = (f"reference {overlay.source.name}{shown}, window {window_label(overlay.window)} (l): "
                         f"coverage {'-' if value is None else f'{100 * value:.1f} %'}\n")
        model = {"risley": "Risley track", "track": "track"}.get(cfg.pattern_model, "RflySim rosette")
        lasers = f"   {cfg.lasers} lasers" if cfg.lasers > 1 else ""
        fov = cfg.field_of_view
        fov_text = f"FOV {cfg.camera_fov:g} deg" if fov.shape == "cone" else f"FOV {fov.describe()}"
        text = (
            f"{session.preset_name or 'custom'}   {model}{lasers}   {cfg.point_rate:,} pts/s   {fov_text}\n"
            f"t = {session.scan_time:8.3f} s   frame {max(session.frame_index, 0)}   {state}\n"
            f"window {window_label(session.window)}: {session.pattern_ring.count:,} pts, "
            f"coverage {100 * session.visible_coverage():.1f} %\n"
            f"{reference}"
            f"colour: {session.display.pattern_colour}   drawing: {session.display.drawing} (g)   "
            f"step: {session.display.step_unit}"
            + (f"   jitter per {cfg.jitter_scope}" if cfg.pattern_model == "rflysim" else "")
            + (f"   {self.fps:4.1f} fps" if self.fps else "")
        )
        scene_lines = ""
        if show_scene:
            moving = ""
            if session.trajectory is not None:
                moving = (f"\ntrajectory {session.trajectory.name}, cloud in the {session.display.cloud_frame} "
                          "frame (w)")
            scene_lines = (f"scene {session.scene.name}: {len(session.scene.mesh.faces):,} triangles\n"
                           f"decoded cloud: {session.scene_ring.count:,} returns in the window, "
                           f"returns {cfg.returns_model} (d)\n"
                           f"colour: {session.display.scene_colour}  (k){moving}")
        if self.scene_state is not None:
            self.scene_state.SetText(2, scene_lines)
        elif scene_lines:
            text += "\n" + scene_lines
        self.state.SetText(2, text)
        self.help.SetVisibility(self.help_visible)
        self.message.SetText(self._message_corner, session.message)
