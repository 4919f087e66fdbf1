"""The project's modules import one way: no import circles (at module level or inside
functions; `if TYPE_CHECKING:` imports excluded) and no private names imported from another
module's namespace across packages. Found by walking every module's AST."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("fmu_src", "cosim", "optimizer", "hil")


def _modules() -> dict[str, Path]:
    """Every module of the project's packages (featherstar/ holds them all after the rename)."""
    out = {}
    for pkg in ("featherstar", *PACKAGES):
        if not (ROOT / pkg).is_dir():
            continue
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    return out


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(module: str, path: Path, known: set[str]) -> list[tuple[str, str, int]]:
    """(imported module, imported name or "", line) for every runtime import of the module."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: list[tuple[str, str, int]] = []

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for sub in child.orelse:
                    visit(sub)
                continue
            if isinstance(child, ast.Import):
                for alias in child.names:
                    found.append((alias.name, "", child.lineno))
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = package.split(".")
                    base = base[: len(base) - (child.level - 1)]
                    target = ".".join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ""
                for alias in child.names:
                    sub = f"{target}.{alias.name}"
                    if sub in known:   # `from . import x`: the submodule x
                        found.append((sub, "", child.lineno))
                    else:
                        found.append((target, alias.name, child.lineno))
            visit(child)
    visit(tree)
    return [(m, n, line) for m, n, line in found if m in known]


def _graph() -> tuple[dict[str, Path], dict[str, list[tuple[str, str, int]]]]:
    modules = _modules()
    known = set(modules)
    return modules, {m: _imports(m, p, known) for m, p in modules.items()}


def _cycles(edges: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (or a self-import)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                connect(w)
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
            if len(comp) > 1 or v in edges[v]:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            connect(v)
    return out


def test_the_finder_sees_a_circle():
    assert _cycles({"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a"]}) == [["a", "b", "c"]]
    assert _cycles({"a": ["b"], "b": []}) == []


def test_no_import_circles():
    modules, imports = _graph()
    assert len(modules) > 40, "the walker found too few modules"
    edges = {m: sorted({target for target, _, _ in imps}) for m, imps in imports.items()}
    circles = _cycles(edges)
    detail = []
    for comp in circles:
        members = set(comp)
        for m in comp:
            detail += sorted({f"  {m}:{line} imports {t}" for t, _, line in imports[m] if t in members})
    assert not circles, "import circles:\n" + "\n".join(detail)


def test_no_private_names_imported_from_other_modules():
    """A leading underscore means "this module's business": no other module imports it."""
    _, imports = _graph()
    bad = [f"{module}:{line} imports {target}.{name}" for module, imps in imports.items()
           for target, name, line in imps if name.startswith("_") and target != module]
    assert not bad, "private names imported from another module:\n" + "\n".join(bad)


#: The one-way doors of docs/architecture.md: which rooms each room may import.
DOORS = {
    "fmu_src": set(),
    "cosim": {"fmu_src"},
    "hil": {"cosim", "fmu_src"},
    "optimizer": {"hil", "cosim", "fmu_src"},
    "app": {"optimizer", "hil", "cosim", "fmu_src"},
}


def _room(module: str) -> str:
    parts = module.split(".")
    if parts[0] == "featherstar":
        return parts[1] if len(parts) > 1 and parts[1] in PACKAGES else "app"
    return parts[0]


def test_packages_import_through_the_doors_only():
    _, imports = _graph()
    bad = sorted({f"{module}:{line} ({_room(module)}) imports {target} ({_room(target)})"
                  for module, imps in imports.items() for target, _, line in imps
                  if _room(target) != _room(module) and _room(target) not in DOORS[_room(module)]})
    assert not bad, "imports against docs/architecture.md:\n" + "\n".join(bad)
