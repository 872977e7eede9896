"""The layering: stages import only down the pipeline, no circles, the model never names or loads the GUI;
one key table; the user guide (docs/) matches the code."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GUI_PACKAGE = "livox_viz.widgets"


def test_model_imports_no_vtk() -> None:
    code = (
        "import sys, importlib, pkgutil, livox_viz\n"
        "for m in pkgutil.walk_packages(livox_viz.__path__, 'livox_viz.'):\n"
        "    if not m.name.endswith('__main__'): importlib.import_module(m.name)\n"
        "bad = sorted(n for n in sys.modules\n"
        f"             if n.split('.')[0] in ('vtkmodules', 'vtk', 'pyvista') or n.startswith('{GUI_PACKAGE}'))\n"
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


def test_the_guides_key_table_is_the_key_table() -> None:
    """docs/window.md holds the table ``markdown_table`` makes from the key table, whole, under its "## Keys"."""
    from livox_viz.widgets.keys import KEYS, markdown_table

    window = (ROOT / "docs" / "window.md").read_text(encoding="utf-8")
    keys = window[window.index("\n## Keys\n"):]
    assert markdown_table() in keys[: keys.index("\n## ", 3)]
    bound = [key for row in KEYS for key, _ in row.bindings]
    assert len(bound) == len(set(bound)), "a key is bound twice"


#: The model's stage packages, bottom first: a module may import from its own stage or an earlier one.
STAGES = ("core", "config", "patterns", "fitting", "motion", "scene", "casting", "wire", "files", "cli")


def _model_imports() -> dict[str, set[str]]:
    """Every module of livox_viz and the livox_viz modules it imports (at the top or inside a function)."""
    graph: dict[str, set[str]] = {}
    for path in (ROOT / "livox_viz").rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        package = parts[:-1]  # the package a relative import starts from, for a module and an __init__ alike
        name = ".".join(parts if parts[-1] != "__init__" else parts[:-1])
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                target = ".".join([*base, *([node.module] if node.module else [])])
                for alias in node.names:
                    candidate = f"{target}.{alias.name}"
                    found.add(candidate if (ROOT / Path(*candidate.split("."))).with_suffix(".py").exists()
                              else target)
            elif isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
        graph[name] = {m for m in found if m.startswith("livox_viz.") and m != name}
    return graph


def _stage(module: str) -> int:
    parts = module.split(".")
    return STAGES.index(parts[1]) if len(parts) > 1 and parts[1] in STAGES else len(STAGES)


def test_every_model_module_sits_in_a_stage() -> None:
    loose = sorted(m for m in _model_imports() if _stage(m) == len(STAGES)
                   and m not in ("livox_viz", "livox_viz.__main__"))
    assert loose == [], "modules outside the stage packages"


def test_imports_point_down_the_pipeline() -> None:
    """No module imports from a later stage (the package's __init__ re-exports are the top)."""
    backwards = sorted(f"{module} -> {target}" for module, targets in _model_imports().items()
                       for target in targets if _stage(target) > _stage(module))
    assert backwards == []


def _circles(graph: dict[str, set[str]]) -> list[str]:
    """Every import circle a depth-first walk meets, as ``a -> b -> a``."""
    state: dict[str, int] = {}
    circles: list[str] = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                circles.append(" -> ".join([*path[path.index(nxt):], nxt]))
            elif nxt not in state:
                visit(nxt, [*path, nxt])
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    return circles


def test_no_import_circles() -> None:
    modules = _model_imports()
    graph = {m: {t for t in targets if t in modules} for m, targets in modules.items()}
    graph.pop("livox_viz", None)  # the package's own __init__ re-exports: the top, imported by nobody below
    assert _circles(graph) == []


def test_the_graph_checks_see_what_they_claim() -> None:
    """A planted circle is found; relative and lazy imports resolve to the modules they name."""
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a -> b -> c -> a"]
    assert _circles({"a": {"b"}, "b": set()}) == []
    assert _stage("livox_viz.casting.scan") > _stage("livox_viz.motion.trajectory") > _stage("livox_viz.core.errors")
    graph = _model_imports()
    assert "livox_viz.motion.trajectory" in graph["livox_viz.casting.scan"]
    assert "livox_viz.core.errors" in graph["livox_viz.core.atomic"]
    assert "livox_viz.cli.common" in graph["livox_viz.cli.scan_commands"]  # a relative import


def test_the_guides_architecture_table_lists_every_module() -> None:
    table = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert table.startswith("# Architecture\n")
    named = set(re.findall(r"`((?:livox_viz|widgets)/[\w/]+\.py)`", table))
    modules = {str(p.relative_to(ROOT)) for pkg in ("livox_viz", "widgets") for p in (ROOT / pkg).rglob("*.py")
               if p.name not in ("__init__.py", "__main__.py")}
    assert sorted(named - modules) == [], "the table names modules that do not exist"
    assert sorted(modules - named) == [], "modules missing from docs/architecture.md's table"
