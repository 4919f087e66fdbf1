"""The `python` block kind, and the one way a scene's string names Python code (`import_code`).

`factory = "pkg.module:Class"` is constructed as Class(name=NAME, **parameters): any object
implementing featherstar.cosim.framework.block.Block (hardware blocks from featherstar.hil go here;
their constructors must not touch hardware before start()).
"""
from __future__ import annotations

import dataclasses
import importlib
import re
from typing import Any

from ...fmu_src.errors import FeatherstarError
from ..errors import SceneError
from ..framework.block import Block, MemorylessBlock, RollbackBlock, can_iterate
from .block_kind import BlockKind, ResolvedBlock, where
from .specs import BlockSpec, parse_value

#: A reference to Python code, exactly the strings `import_code` accepts: "package.module:name", dotted
#: Python identifiers on both sides. Every kind imports through `import_code`, from one string as the
#: scene wrote it; so a package (featherstar.cosim.ssp.code_refs refuses every string of this shape
#: in one) can make featherstar import nothing.
CODE_REFERENCE = re.compile(r"[^\W\d]\w*(?:\.[^\W\d]\w*)*:[^\W\d]\w*(?:\.[^\W\d]\w*)*")
_BLOCK_METHODS = ("start", "set_inputs", "get_outputs", "do_step", "close")


def import_code(ref: str, where: str) -> Any:
    """The object `ref` ("package.module:name") names, or a SceneError saying why not."""
    if not CODE_REFERENCE.fullmatch(ref):
        raise SceneError(f"{where}: '{ref}' must read 'package.module:name'")
    module, _, attr = ref.partition(":")
    try:
        obj = importlib.import_module(module)
    except ImportError as exc:
        raise SceneError(f"{where}: cannot import module '{module}' ({exc})") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise SceneError(f"{where}: module '{module}' has no '{attr}'")
        obj = getattr(obj, part)
    return obj


def featherstar_block_class(ref: str) -> bool:
    """Whether `ref` names one of featherstar's own block classes (featherstar.hil.blocks:Servo,
    featherstar.optimizer.calibration.playback:RecordedRoot): a public class of a public module of
    the featherstar package (no name part starting with '_': never featherstar.__main__) with the
    Block methods. Deciding it imports that featherstar module, which runs featherstar's code only."""
    if not CODE_REFERENCE.fullmatch(ref):
        return False
    module, _, attr = ref.partition(":")
    parts = [*module.split("."), *attr.split(".")]
    if parts[0] != "featherstar" or "." not in module or any(p.startswith("_") for p in parts):
        return False
    try:
        obj = import_code(ref, ref)
    except SceneError:
        return False
    return isinstance(obj, type) and all(callable(getattr(obj, m, None)) for m in _BLOCK_METHODS)


class PythonKind(BlockKind):
    name = "python"

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, parse_value(raw)))

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        factory_ref = spec.settings.get("factory")
        if not isinstance(factory_ref, str):
            raise SceneError(f"{where(spec)}: needs factory = \"package.module:Class\"")
        unknown = [k for k in spec.settings if k not in ("factory", "parameters")]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; known: factory, parameters")
        factory = import_code(factory_ref, where(spec))
        params = {**dict(spec.settings.get("parameters", {})), **spec.overrides}
        try:
            obj = factory(name=spec.name, **params)
        except FeatherstarError as exc:
            raise SceneError(f"{where(spec)}: {exc}") from None
        except TypeError as exc:
            raise SceneError(f"{where(spec)}: {factory_ref}(name=..., **parameters) failed: {exc}") from None
        if not isinstance(obj, Block):
            raise SceneError(f"{where(spec)}: {factory_ref} did not return a Block (needs name, inputs, "
                             "outputs, start, set_inputs, get_outputs, do_step, close)")
        memoryless = isinstance(obj, MemorylessBlock)
        return ResolvedBlock(spec, dict(obj.inputs), dict(obj.outputs), memoryless=memoryless,
                             iterable=can_iterate(obj), continuous=memoryless, identity=None,
                             period_s=getattr(obj, "period_s", None), obj=obj,
                             can_rollback=memoryless or isinstance(obj, RollbackBlock),
                             passivity=getattr(obj, "passivity", None))
