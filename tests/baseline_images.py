"""The GUI's reference images: how they are rendered, and the one explicit step that renews them.

The image test only ever compares a fresh render with the committed baseline;
it never writes one. Renewing the baselines is its own command, run by a person
who then looks at the pictures before committing them::

    make baselines            # or: python -m tests.baseline_images [pattern|scene ...]

It renders into the baseline folder and prints how much each image changed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

BASELINES = Path(__file__).parent / "baselines"
#: Each baseline: the preset and the view it shows, one per family of pattern (the rosette, a Risley track, a wide
#: track band, a 360-degree panorama) and the scene, in the urban scene after 0.5 s of scan, 480 x 360 pixels.
VIEWS: dict[str, tuple[str, str]] = {
    "pattern": ("livox_mid70", "pattern"), "scene": ("livox_mid70", "scene"),
    "risley": ("livox_mid70_risley", "pattern"), "band": ("livox_horizon", "pattern"),
    "panorama": ("livox_mid360", "pattern"),
}
SCAN_SECONDS = 0.5
SIZE = (480, 360)


def render_view(view: str, out: Path, scene=None) -> Path:
    """Render one baseline's picture (a key of :data:`VIEWS`) exactly as it was rendered."""
    from livox_viz.widgets.app import render_offscreen
    from livox_viz.widgets.session import Session

    from livox_viz import load_preset
    from livox_viz.scene.scenes import open_scene

    preset, shown = VIEWS[view]
    session = Session(load_preset(preset), scene or open_scene("urban"), seed=0, preset_name=preset)
    return render_offscreen(session, SCAN_SECONDS, out, views=shown, size=SIZE)


#: The panel's baseline: the window's parameter dock for the default preset, in a 1600 x 900 window.
PANEL = "panel"


def grab_panel(window, out: Path) -> Path:
    """Save the window's parameter dock as drawn (Qt's own grab of the widget)."""
    window.dock.widget().grab().toImage().save(str(out))
    return out


_PANEL_SCRIPT = """
import sys
from livox_viz.widgets.mainwindow import MainWindow, application
from livox_viz.widgets.session import Session
from livox_viz import load_preset
from livox_viz.scene.scenes import open_scene
from tests.baseline_images import grab_panel
app = application()
window = MainWindow(Session(load_preset("livox_mid70"), open_scene("urban"), preset_name="livox_mid70"),
                    size=(1600, 900), warm=False)
window.show()
for _ in range(20):
    app.processEvents()
grab_panel(window, sys.argv[1])
window.close()
"""


def render_panel(out: Path) -> Path:
    """Render the panel's baseline in a child process on a private X server."""
    import os
    import subprocess

    from tests.xserver import private_display

    with private_display("1920x1200x24") as display:
        env = {**os.environ, "DISPLAY": display, "QT_QPA_PLATFORM": "xcb"}
        subprocess.run([sys.executable, "-c", _PANEL_SCRIPT, str(out)], env=env, check=True,
                       cwd=Path(__file__).resolve().parent.parent)
    return out


def read_image(path: Path) -> np.ndarray:
    """``(h, w, 3)`` uint8 RGB."""
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"))


def changed_fraction(a: np.ndarray, b: np.ndarray, tolerance: int = 24) -> float:
    """The share of pixels whose colour differs by more than ``tolerance`` in any channel."""
    if a.shape != b.shape:
        return 1.0
    return float((np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > tolerance).mean())


def update(views: list[str]) -> None:
    """Render the baselines anew, saying how much each changed; look at them before committing."""
    for view in views:
        target = BASELINES / f"{view}.png"
        before = read_image(target) if target.exists() else None
        if view == PANEL:
            render_panel(target)
        else:
            render_view(view, target)
        after = read_image(target)
        change = "new" if before is None else f"{100 * changed_fraction(before, after):.2f} % of the pixels changed"
        print(f"{target}: {change}")
    print("look at each image before committing it: the image test trusts them")


if __name__ == "__main__":
    known = [*VIEWS, PANEL]
    chosen = sys.argv[1:] or known
    unknown = sorted(set(chosen) - set(known))
    if unknown:
        sys.exit(f"unknown view {', '.join(unknown)}; allowed: {', '.join(known)}")
    update(chosen)
