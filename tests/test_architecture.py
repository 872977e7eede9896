"""The layering: the model never names or loads the GUI; one key table; the README matches the code."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GUI_PACKAGE = "livox_viz_gui"


def test_model_imports_no_vtk() -> None:
    code = (
        "import sys, importlib, pkgutil, livox_viz\n"
        "for m in pkgutil.walk_packages(livox_viz.__path__, 'livox_viz.'):\n"
        "    if not m.name.endswith('__main__'): importlib.import_module(m.name)\n"
        "bad = sorted(n for n in sys.modules\n"
        f"             if n.split('.')[0] in ('vtkmodules', 'vtk', 'pyvista', '{GUI_PACKAGE}'))\n"
        "print(','.join(bad))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == ""


def test_model_never_names_the_gui_package() -> None:
    """Not as an import, not in a string: the GUI registers itself through an entry point."""
    named = [str(path.relative_to(ROOT)) for path in (ROOT / "livox_viz").rglob("*.py")
             if GUI_PACKAGE in path.read_text(encoding="utf-8") or "widgets" in path.read_text(encoding="utf-8")]
    assert named == []


def test_a_model_command_loads_no_vtk() -> None:
    """``livox-viz info`` in a fresh interpreter, with the GUI installed: no VTK module is loaded."""
    code = (
        "import sys\n"
        "from livox_viz.cli import main\n"
        "assert main(['info']) == 0\n"
        "bad = sorted(n for n in sys.modules if n.split('.')[0] in ('vtkmodules', 'vtk', 'pyvista'))\n"
        "print('LOADED:' + ','.join(bad))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip().splitlines()[-1] == "LOADED:"
    assert "gui" in subprocess.run([sys.executable, "-m", "livox_viz", "--help"], capture_output=True, text=True,
                                   check=True).stdout


def test_readme_key_table_is_the_key_table() -> None:
    from livox_viz_gui.keys import KEYS, markdown_table

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert markdown_table() in readme
    bound = [key for row in KEYS for key, _ in row.bindings]
    assert len(bound) == len(set(bound)), "a key is bound twice"


def test_readme_architecture_table_lists_every_module() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = readme[readme.index("## Architecture"):]
    table = table[: table.index("\n## ", 3)]
    named = set(re.findall(r"`((?:livox_viz|livox_viz_gui)/[\w/]+\.py)`", table))
    modules = {str(p.relative_to(ROOT)) for pkg in ("livox_viz", GUI_PACKAGE) for p in (ROOT / pkg).rglob("*.py")
               if p.name not in ("__init__.py", "__main__.py")}
    assert sorted(named - modules) == [], "the table names modules that do not exist"
    assert sorted(modules - named) == [], "modules missing from the README's architecture table"
