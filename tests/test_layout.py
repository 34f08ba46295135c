"""The floor plan (docs/development.md, Architecture): folders by concept, short faces, no import circles.

The oracle is the source itself, parsed with :mod:`ast`: every ``import`` / ``from ... import`` of a
``vcprep`` or ``vctrain`` module (including those under ``if TYPE_CHECKING``), resolved to the
module it names.
"""
from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TOPS = ("vcprep", "vctrain")
MAX_MODULES = 15


def _modname(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules(tops=TOPS) -> dict[str, Path]:
    return {_modname(p): p for top in tops for p in (ROOT / top).rglob("*.py")}


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module, names) of every import in ``path`` that reaches vcprep or vctrain, absolute."""
    name = _modname(path)
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")[: len(pkg.split(".")) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] in TOPS:
                out.append((mod, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names if a.name.split(".")[0] in TOPS]
    return out


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, path in mods.items():
        for target, names in _imports(path):
            for t in [target] + [f"{target}.{n}" for n in names]:
                if t in mods and t != m and not m.startswith(t + "."):  # a package's own face is not an edge
                    graph[m].add(t)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_two_modules_import_each_other():
    assert _cycles(_graph()) == []


def test_cycle_finder_finds_a_known_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


@pytest.mark.parametrize("top", TOPS)
def test_no_folder_holds_more_than_15_modules(top):
    folders = {p.parent for p in (ROOT / top).rglob("*.py")}
    crowded = {str(f.relative_to(ROOT)): n for f in folders if (n := len(list(f.glob("*.py")))) > MAX_MODULES}
    assert crowded == {}


def _faces() -> dict[str, set[str]]:
    """Each subpackage of vcprep/vctrain with a face: its ``__all__``."""
    faces = {}
    for name, path in _modules().items():
        if path.name == "__init__.py" and "." in name:
            mod = importlib.import_module(name)
            if hasattr(mod, "__all__"):
                faces[name] = set(mod.__all__)
    return faces


def test_every_face_name_exists():
    for face, names in _faces().items():
        mod = importlib.import_module(face)
        assert [n for n in names if not hasattr(mod, n)] == [], face


def test_subpackages_have_faces():
    faces = _faces()
    for sub in ("io", "camera", "vp", "warp", "store", "simulate"):
        assert f"vcprep.{sub}" in faces
    for sub in ("networks", "training", "predict", "deploy", "study"):
        assert f"vctrain.{sub}" in faces


def test_the_commands_start_without_torch():
    """vctrain's commands take their options' defaults from the training face (TrainConfig), which
    loads a module on first use of its names: starting the CLI imports no torch (about 1.5 s a
    process); the names are all there when asked for."""
    import subprocess
    import sys

    code = ("import sys, vctrain.cli, vcprep.cli; assert 'torch' not in sys.modules, 'torch'; "
            "import vctrain.training as t; assert all(hasattr(t, n) for n in t.__all__); "
            "assert 'torch' in sys.modules")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr


def test_vctrain_keeps_at_most_8_modules_at_the_top():
    """The rest lives in folders by concept (networks, training, predict, deploy, study, cli)."""
    top = sorted(p.name for p in (ROOT / "vctrain").glob("*.py"))
    assert len(top) <= 8, top


def _face_of(mod: str, faces: dict[str, set[str]]) -> str | None:
    return next((f for f in faces if mod.startswith(f + ".")), None)


@pytest.mark.parametrize("top, outside", [("vcprep", ("vctrain", "benchmarks", "tests")),
                                          ("vctrain", ("benchmarks", "tests"))])
def test_outside_code_uses_the_faces(top, outside):
    """Code outside a package takes a subpackage's public names from its face, not from the module
    behind it (private ``_names`` may be reached in the module, by tests)."""
    faces = {f: n for f, n in _faces().items() if f.startswith(top + ".")}
    files = [p for d in outside for p in (ROOT / d).rglob("*.py")]
    behind = []
    for path in files:
        for mod, names in _imports(path):
            face = _face_of(mod, faces)
            if face:
                behind += [f"{path.relative_to(ROOT)}: {n} from {mod}" for n in names if n in faces[face]]
    assert behind == []


@pytest.mark.parametrize("top", TOPS)
def test_modules_import_by_module_path(top):
    """Inside a package a module imports another subpackage's module, never its face (a face that
    loads while another is half-loaded would see missing names)."""
    faces = _faces()
    bad = []
    for name, path in _modules((top,)).items():
        if path.name == "__init__.py":
            continue
        bad += [f"{name}: from {mod}" for mod, _ in _imports(path)
                if mod in faces and mod.startswith(top + ".") and not name.startswith(mod + ".")]
    assert bad == []


def test_every_import_names_a_module_that_exists():
    """Also the imports inside functions (run only when called): a module moved without its importers
    moving along fails here, not in a user's hands."""
    missing = []
    for name, path in _modules().items():
        for mod, names in _imports(path):
            if mod in _modules() or any(f"{mod}.{n}" in _modules() for n in names):
                continue
            missing.append(f"{path.relative_to(ROOT)}: {mod}")
    assert missing == []


def _is_cli(mod: str) -> bool:
    """A module of the command layer: ``vcprep.cli*`` and ``vctrain.cli*`` (``vcprep.cliutil`` too)."""
    return any(mod == f"{top}.cli" or mod.startswith((f"{top}.cli.", f"{top}.cliutil")) for top in TOPS)


def test_library_modules_never_import_the_cli():
    """The library does the work, the commands call it (docs/development.md): no module outside
    ``vcprep/cli``, ``vctrain/cli`` and ``vcprep/cliutil.py`` imports one of them, at the top or
    inside a function."""
    bad = []
    for name, path in _modules().items():
        if _is_cli(name):
            continue
        for mod, names in _imports(path):
            targets = [mod] + [f"{mod}.{n}" for n in names]
            bad += [f"{path.relative_to(ROOT)}: {t}" for t in targets if _is_cli(t)]
    assert bad == []


def test_the_cli_finder_knows_the_cli():
    """The check above would notice: the command modules are told from library modules of like names."""
    assert _is_cli("vcprep.cliutil") and _is_cli("vctrain.cli.common") and _is_cli("vcprep.cli")
    assert not _is_cli("vctrain.client") and not _is_cli("vcprep.progress")


MAX_FUNCTION_LINES = 80


def _long_functions(path: Path, limit: int = MAX_FUNCTION_LINES) -> list[str]:
    """``name (lines)`` of each function in ``path`` longer than ``limit`` lines, from ``def`` to the end of
    its body (decorators left out; a nested function counts on its own and inside its parent)."""
    return [f"{path.relative_to(ROOT)}:{n.lineno} {n.name} ({n.end_lineno - n.lineno + 1} lines)"
            for n in ast.walk(ast.parse(path.read_text()))
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno + 1 > limit]


def test_no_function_is_over_80_lines():
    """No function in vcprep/ or vctrain/ passes 80 lines, the commands included (issue 79): a long command
    declares its options as module-level constants and hands its work to helpers."""
    assert [f for path in _modules().values() for f in _long_functions(path)] == []


def test_the_length_check_finds_a_long_function():
    """The check above would notice: at a lower limit it names fit's command with its length."""
    found = _long_functions(ROOT / "vctrain" / "cli" / "fit.py", 20)
    assert any(" fit_cmd (" in f and f.startswith("vctrain/cli/fit.py:") for f in found)
