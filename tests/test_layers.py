"""The package's layers point one way and its modules import each other in no circle.

The map is docs/development.md's (Layers): a module may import its own folder and the
layers below it, never a layer above or beside it. Every import counts, those inside
functions and under ``TYPE_CHECKING`` too (a lazy import is still a dependency). The
imports are read from the source with :mod:`ast`; nothing is imported.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "odmd_bench"

#: Each part of ``odmd_bench`` (a folder, or a module at the top) and its layer: a part
#: may import parts of lower layers only. Mirrors docs/development.md.
LAYERS: dict[str, int] = {
    "errors": 0,
    "_version": 0,
    "_interrupt": 0,  # imported first by the package: a Ctrl-C while the command starts
    "data_folder": 0,  # the data folder's default place
    "os_errors": 1,  # the OS-error vocabulary, below both inputs and outputs
    "project": 1,
    "extras": 1,
    "documents": 1,
    "inputs": 2,
    "outputs": 2,  # atomic writes, temporary files, the writers' lock
    "data": 3,
    "evaluation": 4,
    "methods": 4,
    "datasets": 4,
    "predict": 5,
    "kitti": 6,  # beside the public names: it uses predict (5), and nothing imports it but the CLI
    "leaderboard": 5,
    "": 6,  # odmd_bench/__init__.py, the public names
    "cli": 7,
    "__main__": 8,  # python -m odmd_bench: the command line
}


def _modules(root: Path = PACKAGE, package: str = "odmd_bench") -> dict[str, Path]:
    """``{dotted name: file}`` of every module of a package (a package by its ``__init__``)."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = [package, *path.relative_to(root).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _part(module: str) -> str:
    """The layer part a module belongs to: ``odmd_bench.data.store`` -> ``data``."""
    return module.split(".")[1] if "." in module else ""


def _imports(path: Path, modules: dict[str, Path] | None = None) -> Iterator[tuple[int, str]]:
    """``(line, module)`` of every import of a package's modules in a file, resolved to a module.

    ``from odmd_bench import methods`` imports the module ``odmd_bench.methods``;
    ``from odmd_bench import load`` the package itself (its ``__init__``). ``modules``:
    the package's modules (default: odmd_bench's); relative imports are resolved.
    """
    modules = MODULES if modules is None else modules
    me = next((m for m, p in modules.items() if p == path), "")
    here = me if path.name == "__init__.py" else me.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and (node.level or node.module):
            base = node.module or ""
            if node.level:
                up = here
                for _ in range(node.level - 1):
                    up = up.rpartition(".")[0]
                base = f"{up}.{base}" if base else up
            names = [f"{base}.{a.name}" for a in node.names]
        else:
            continue
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name:
                yield node.lineno, name


def _edges() -> dict[str, set[str]]:
    return {m: {t for _, t in _imports(p) if t != m} for m, p in MODULES.items()}


def test_every_part_of_the_package_has_a_layer() -> None:
    unknown = sorted({_part(m) for m in MODULES} - set(LAYERS))
    assert not unknown, f"give these parts a layer in tests/test_layers.py and docs/development.md: {unknown}"


def test_each_layer_imports_only_the_layers_below_it() -> None:
    wrong = []
    for module, path in MODULES.items():
        here = _part(module)
        for line, target in _imports(path):
            there = _part(target)
            if there != here and LAYERS.get(there, -1) >= LAYERS.get(here, -1):
                where = path.relative_to(PACKAGE.parent)
                wrong.append(f"{where}:{line} imports {target} ({there or 'odmd_bench'} is not below {here})")
    assert not wrong, "\n".join(wrong)


def test_the_package_never_imports_the_baselines() -> None:
    """Methods are found through their entry points, never named by the library."""
    named = [
        f"{path.relative_to(PACKAGE.parent)}:{node.lineno}"
        for path in MODULES.values()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Import | ast.ImportFrom)
        and any(
            n.startswith("odmd_bench_baselines")
            for n in ([a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""])
        )
    ]
    assert not named, named


def _circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_the_circle_finder_finds_circles() -> None:
    """The check below can fail: a circle through three modules, and a chain that is none."""
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_modules_import_each_other_in_no_circle() -> None:
    edges = _edges()
    circles = _circles(edges)
    described = [
        " <-> ".join(m for m in circle)
        + ": "
        + "; ".join(f"{m} -> {sorted(edges[m] & set(circle))}" for m in circle)
        for circle in circles
    ]
    assert not circles, "\n".join(described)


BASELINES = PACKAGE.parent / "baselines"


def _baseline_edges() -> dict[str, set[str]]:
    """``{module: modules of odmd_bench_baselines it imports}``."""
    modules = _modules(BASELINES, "odmd_bench_baselines")
    return {m: {t for _, t in _imports(p, modules) if t != m} for m, p in modules.items()}


def test_the_baselines_import_each_other_in_no_circle() -> None:
    """Each method's modules point one way too (a package's ``__init__`` re-exports, never is read back)."""
    edges = _baseline_edges()
    assert (
        "odmd_bench_baselines.dbox.weights" in edges["odmd_bench_baselines.dbox.method"]
    )  # it reads imports
    circles = _circles(edges)
    described = [" <-> ".join(circle) for circle in circles]
    assert not circles, "\n".join(described)


ROOT = PACKAGE.parent
DEVELOPMENT = ROOT / "docs" / "development.md"
MAX_LINES = 450  # issue 44: a room a newcomer can read; split a longer module by concern


def _sources() -> list[Path]:
    return sorted(
        p for folder in (PACKAGE, BASELINES) for p in folder.rglob("*.py") if "__pycache__" not in p.parts
    )


def _room_map(text: str) -> set[str]:
    """The modules docs/development.md's room map names: ```folder/``` headings, then ``| `room.py` |`` rows."""
    rooms, folder = set(), None
    for line in text.splitlines():
        if line.startswith("`") and line.endswith("/`") and " " not in line:
            folder = line.strip("`")
        elif folder and line.startswith("| `") and ".py` |" in line:
            rooms.add(folder + line.split("`")[1])
        elif line.startswith("#"):
            folder = None
    return rooms


def test_the_room_map_names_every_module_and_no_other() -> None:
    mapped = _room_map(DEVELOPMENT.read_text(encoding="utf-8"))
    there = {p.relative_to(ROOT).as_posix() for p in _sources()}
    assert not there - mapped, (
        f"modules missing from docs/development.md's room map: {sorted(there - mapped)}"
    )
    assert not mapped - there, (
        f"docs/development.md's room map names modules that are gone: {sorted(mapped - there)}"
    )


def test_the_room_map_reader_sees_a_missing_room() -> None:
    text = (
        "### Rooms\n\n`odmd_bench/outputs/`\n\n| room | concern |\n| --- | --- |\n| `lock.py` | the lock |\n"
    )
    assert _room_map(text) == {"odmd_bench/outputs/lock.py"}


def test_no_module_is_longer_than_450_lines() -> None:
    long = {
        p.relative_to(ROOT).as_posix(): n
        for p in _sources()
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert not long, f"modules over {MAX_LINES} lines (split them by concern): {long}"
