"""A package is data: the scene read from an SSP package may name featherstar's own block classes
and nothing else that is Python code.

Rather than knowing which fields a block kind imports (and missing the next kind's), every string
of the package's featherstar annotation as written — keys and values, at any depth: its blocks,
their parameters, master and metrics settings, overrides, whatever else — that has the shape of a
code reference (featherstar.cosim.scene.python_blocks.CODE_REFERENCE, exactly what the master's one
import accepts) is judged; only free text the master never interprets (`description`) is skipped.
The rest of a package (component names, FMU paths, numeric parameter values) names no code.
"""
from __future__ import annotations

from typing import Any, Iterator

from ..errors import SceneError
from ..scene.python_blocks import CODE_REFERENCE, featherstar_block_class

#: Free text: shown, never interpreted.
_TEXT_KEYS = frozenset({"description"})


def _strings(value: Any, path: tuple[str, ...]) -> Iterator[tuple[tuple[str, ...], str]]:
    if isinstance(value, str):
        yield path, value
    elif isinstance(value, dict):
        for key, item in value.items():
            key = str(key)
            yield path, key
            if key not in _TEXT_KEYS:
                yield from _strings(item, (*path, key))
    elif isinstance(value, (list, tuple)):
        for index, item in enumerate(value):
            yield from _strings(item, (*path, str(index)))


def _label(path: tuple[str, ...]) -> str:
    if len(path) >= 2 and path[0] == "blocks":
        return f"block '{path[1]}'" + (f" {'.'.join(path[2:])}" if len(path) > 2 else "")
    if path[:1] == ("overrides",):
        return "overrides" + (f" '{'.'.join(path[1:])}'" if len(path) > 1 else "")
    return f"annotation field '{'.'.join(path)}'" if path else "the annotation"


def foreign_code(annotation: Any) -> list[tuple[str, str]]:
    """(where, reference) of every reference to Python code other than featherstar's own blocks."""
    found = []
    for path, text in _strings(annotation, ()):
        if CODE_REFERENCE.fullmatch(text.strip()) and not featherstar_block_class(text.strip()):
            found.append((_label(path), text))
    return list(dict.fromkeys(found))


def refuse_foreign_code(annotation: Any, where: str) -> None:
    """SceneError (one line, naming the package, the blocks and the references) if the package's
    annotation names Python code."""
    found = foreign_code(annotation)
    if found:
        named = ", ".join(f"{label} names '{ref}'" for label, ref in found)
        raise SceneError(f"{where}: {named}: Python code, which a package may not run (it may use featherstar's "
                         "block kinds, featherstar's own blocks and its FMUs); if you trust who made it, run it with "
                         "--allow-code (API: allow_code=True)")
