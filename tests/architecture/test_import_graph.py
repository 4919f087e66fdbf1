"""The project's modules import one way: no import circles (at module level, inside functions
or under `if TYPE_CHECKING:`: an import moved there only to break a circle is still one) and no private names imported from another
module's namespace across packages. Found by walking every module's AST."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: Where each installed package's source lives in the checkout (pyproject's package-dir).
SOURCES = {
    "featherstar": ROOT / "src" / "featherstar",
    "featherstar.fmu_src": ROOT / "fmu_src",
    "featherstar.cosim": ROOT / "cosim",
    "featherstar.optimizer": ROOT / "optimizer",
    "featherstar.hil": ROOT / "hil",
    "featherstar.dashboard": ROOT / "bench" / "dashboard",
}


def _modules() -> dict[str, Path]:
    """Every installed module of the project, by its installed name."""
    out = {}
    for package, folder in SOURCES.items():
        nested = [f for f in SOURCES.values() if f != folder and folder in f.parents]
        for path in sorted(folder.rglob("*.py")):
            if any(n in path.parents for n in nested):
                continue
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
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


#: The rooms of docs/architecture.md, by module-name prefix (the longest prefix wins), and the
#: rooms each may import. The generic master (framework, fmi, scene, ssp, scenes, coupling) never
#: imports the swimmer's domain; the packages' own __init__ facades may import their rooms.
ROOMS = {
    "featherstar": "app",
    "featherstar.fmu_src": "fmu_src",
    "featherstar.cosim": "cosim",
    "featherstar.cosim.errors": "cosim.base",
    "featherstar.cosim.jsonable": "cosim.base",
    "featherstar.cosim.sccs": "cosim.base",
    "featherstar.cosim.plotstyle": "cosim.base",
    "featherstar.cosim.framework": "cosim.framework",
    "featherstar.cosim.fmi": "cosim.fmi",
    "featherstar.cosim.scene": "cosim.scene",
    "featherstar.cosim.ssp": "cosim.ssp",
    "featherstar.cosim.scenes": "cosim.scenes",
    "featherstar.cosim.coupling": "cosim.coupling",
    "featherstar.cosim.swimmer": "cosim.swimmer",
    "featherstar.hil": "hil",
    "featherstar.optimizer": "optimizer",
    "featherstar.optimizer.bench": "optimizer.bench",
    "featherstar.optimizer.calibration": "optimizer.calibration",
    "featherstar.optimizer.paper": "optimizer.paper",
    "featherstar.optimizer.cli": "optimizer.cli",
    "featherstar.dashboard": "dashboard",
}
MASTER = {"cosim.base", "cosim.framework", "cosim.fmi", "cosim.scene", "cosim.ssp", "cosim.scenes", "cosim.coupling"}
COSIM = MASTER | {"cosim.swimmer", "cosim"}
OPTIMIZER = {"optimizer", "optimizer.bench", "optimizer.calibration", "optimizer.paper"}
DOORS = {
    "fmu_src": set(),
    "cosim.base": {"fmu_src"},
    "cosim.framework": {"cosim.base", "fmu_src"},
    "cosim.fmi": {"cosim.framework", "cosim.base", "fmu_src"},
    "cosim.scene": {"cosim.fmi", "cosim.framework", "cosim.base", "fmu_src"},
    "cosim.ssp": {"cosim.scene", "cosim.fmi", "cosim.framework", "cosim.base", "fmu_src"},
    "cosim.scenes": {"cosim.ssp", "cosim.scene", "cosim.base"},
    "cosim.coupling": {"cosim.scene", "cosim.fmi", "cosim.framework", "cosim.base", "fmu_src"},
    "cosim.swimmer": MASTER | {"fmu_src"},
    "cosim": COSIM | {"fmu_src"},
    "hil": COSIM | {"fmu_src"},
    "optimizer": COSIM | {"hil", "fmu_src"},
    "optimizer.calibration": {"optimizer"} | COSIM | {"hil", "fmu_src"},
    "optimizer.bench": {"optimizer", "optimizer.calibration"} | COSIM | {"hil", "fmu_src"},
    "optimizer.paper": {"optimizer"} | COSIM | {"fmu_src"},
    "optimizer.cli": OPTIMIZER | COSIM | {"hil", "fmu_src"},
    "dashboard": OPTIMIZER | COSIM | {"hil", "fmu_src"},
    "app": set(ROOMS.values()),
}


def _room(module: str) -> str:
    prefix = max((p for p in ROOMS if module == p or module.startswith(p + ".")), key=len)
    return ROOMS[prefix]


def test_every_room_has_its_doors():
    assert set(DOORS) == set(ROOMS.values())
    assert all(doors <= set(ROOMS.values()) for doors in DOORS.values())


def test_packages_import_through_the_doors_only():
    _, imports = _graph()
    bad = sorted({f"{module}:{line} ({_room(module)}) imports {target} ({_room(target)})"
                  for module, imps in imports.items() for target, _, line in imps
                  if _room(target) != _room(module) and _room(target) not in DOORS[_room(module)]})
    assert not bad, "imports against docs/architecture.md:\n" + "\n".join(bad)


def test_pyproject_installs_every_package_of_the_checkout():
    """Each folder with an __init__.py under a mapped source is listed in pyproject's packages
    (a new room left out would be missing from a wheel while an editable install still finds it)."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["packages"])
    found = {m for m, p in _modules().items() if p.name == "__init__.py"}
    assert found == listed, f"in the tree, not in pyproject: {sorted(found - listed)}; listed, not found: {sorted(listed - found)}"
