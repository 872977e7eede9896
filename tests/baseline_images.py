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
VIEWS = ("pattern", "scene")
#: What the baselines show: the default preset in the urban scene, 0.5 s of scan, 480 x 360 pixels.
SCAN_SECONDS = 0.5
SIZE = (480, 360)


def render_view(view: str, out: Path, scene=None) -> Path:
    """Render one view exactly as its baseline was rendered."""
    from livox_viz.widgets.app import render_offscreen
    from livox_viz.widgets.session import Session

    from livox_viz import load_preset
    from livox_viz.scene.scenes import open_scene

    session = Session(load_preset("livox_mid70"), scene or open_scene("urban"), seed=0, preset_name="livox_mid70")
    return render_offscreen(session, SCAN_SECONDS, out, views=view, size=SIZE)


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
        render_view(view, target)
        after = read_image(target)
        change = "new" if before is None else f"{100 * changed_fraction(before, after):.2f} % of the pixels changed"
        print(f"{target}: {change}")
    print("look at each image before committing it: the image test trusts them")


if __name__ == "__main__":
    chosen = sys.argv[1:] or list(VIEWS)
    unknown = sorted(set(chosen) - set(VIEWS))
    if unknown:
        sys.exit(f"unknown view {', '.join(unknown)}; allowed: {', '.join(VIEWS)}")
    update(chosen)
