"""The model never imports the GUI toolkit."""

from __future__ import annotations

import subprocess
import sys


def test_model_imports_no_vtk() -> None:
    code = (
        "import sys, importlib, pkgutil, livox_viz\n"
        "for m in pkgutil.walk_packages(livox_viz.__path__, 'livox_viz.'):\n"
        "    if not m.name.endswith('__main__'): importlib.import_module(m.name)\n"
        "bad = sorted(n for n in sys.modules if n.split('.')[0] in ('vtkmodules', 'vtk', 'pyvista', 'widgets'))\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == ""
