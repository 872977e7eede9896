"""Start-up: the model-only commands load no heavy library they do not use (issue 19, start-up <= 0.5 s).

Their time is measured by ``benchmarks/bench_startup.py``; what is asserted here is which heavy modules a
fresh interpreter holds after each command ran: importing trimesh (which brings scipy) cost over a second.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

#: Libraries none of info, presets and coverage needs (top-level module names).
HEAVY = ("trimesh", "scipy", "embreex", "vtkmodules", "pyvista", "matplotlib", "rosbags", "laspy", "numba")


def heavy_loaded_after(argv: list[str], cwd: Path | None = None) -> list[str]:
    """The heavy top-level modules a fresh interpreter holds after ``livox-viz ARGV``."""
    code = (
        "import sys\n"
        "from livox_viz.cli import main\n"
        f"assert main({argv!r}) == 0\n"
        f"heavy = set({HEAVY!r})\n"
        "print('LOADED:' + ','.join(sorted({n.split('.')[0] for n in sys.modules} & heavy)))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=cwd)
    listed = result.stdout.strip().splitlines()[-1].removeprefix("LOADED:")
    return [name for name in listed.split(",") if name]


@pytest.mark.parametrize("argv", [["info"], ["info", "--preset", "livox_mid70_risley", "--json"], ["presets"],
                                  ["coverage", "--seconds", "0.1,0.2"], ["--version"]])
def test_model_only_commands_load_no_heavy_library(argv: list[str]) -> None:
    assert heavy_loaded_after(argv) == []


def test_the_probe_sees_a_heavy_import(tmp_path: Path) -> None:
    """The same probe after a command that casts into a scene reports the mesh and ray-casting libraries."""
    loaded = heavy_loaded_after(["scan", "--seconds", "0.01", "--out", str(tmp_path / "cloud.npz")], tmp_path)
    assert {"trimesh", "embreex"} <= set(loaded)
