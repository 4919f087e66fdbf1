"""The `fmu` block kind: a catalog model (built symbolically, no binary loaded) or any FMI 2.0/3.0
FMU file (only its modelDescription.xml read) resolved to ports, feedthrough and capabilities."""
from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any

from ...fmu_src.errors import FeatherstarError
from ..errors import SceneError
from ..fmi.fmi_types import parameter_value
from ..framework.block import Port, passivity_by_convention
from ..framework.feedthrough import model_feedthrough
from .block_kind import BlockKind, ResolvedBlock, where
from .python_blocks import import_code
from .specs import BlockSpec, FrozenMap, parse_value


def _catalog_options(kind: str) -> tuple[str, ...]:
    """A catalog model's build options; none for a "pkg.module:function" model."""
    try:
        from ...fmu_src import catalog
    except ImportError:
        return ()
    try:
        return tuple(catalog.build_options(kind))
    except FeatherstarError:   # not a catalog kind
        return ()


@functools.lru_cache(maxsize=64)
def _model(model_ref: str, options: FrozenMap) -> Any:
    if ":" in model_ref:
        fn = import_code(model_ref, f"model '{model_ref}'")
        return fn(**options)
    try:
        from ...fmu_src.catalog import build_model
    except ImportError as exc:  # pragma: no cover - the catalog ships with featherstar
        raise SceneError(f"model '{model_ref}': the model catalog is not available ({exc})") from None
    return build_model(model_ref, dict(options))


class FmuKind(BlockKind):
    name = "fmu"
    KEYS = ("model", "fmu", "options", "parameters", "interface")

    def override(self, spec: BlockSpec, key: str, raw: Any) -> BlockSpec:
        return dataclasses.replace(spec, overrides=spec.overrides.set(key, parse_value(raw)))

    def resolve(self, spec: BlockSpec) -> ResolvedBlock:
        unknown = [k for k in spec.settings if k not in self.KEYS]
        if unknown:
            raise SceneError(f"{where(spec)}: unknown key(s) {unknown}; known: {', '.join(self.KEYS)}")
        model_ref, fmu_ref = spec.settings.get("model"), spec.settings.get("fmu")
        if bool(model_ref) == bool(fmu_ref):
            raise SceneError(f"{where(spec)}: give exactly one of model = \"feather\" (a catalog model or "
                             "\"pkg.module:function\") or fmu = \"path/to/file.fmu\"")
        if model_ref:
            return self._resolve_model(spec, str(model_ref))
        return self._resolve_file(spec, str(fmu_ref))

    def _resolve_model(self, spec: BlockSpec, model_ref: str) -> ResolvedBlock:
        options = dict(spec.settings.get("options", {}))
        option_names = set(options) | set(_catalog_options(model_ref))
        param_overrides = {}
        for key, value in spec.overrides.items():
            if key in option_names:
                options[key] = value
            else:
                param_overrides[key] = value
        try:
            model = _model(model_ref, FrozenMap(options))
        except SceneError:
            raise
        except FeatherstarError as exc:
            raise SceneError(f"{where(spec)}: {exc}") from None
        except TypeError as exc:
            raise SceneError(f"{where(spec)}: model '{model_ref}' does not take options {options}: {exc}") from None
        names = {p.name for p in model.parameters}
        params, notes = {}, []
        for key, value in dict(spec.settings.get("parameters", {})).items():
            if key in names:
                params[key] = value
            else:  # e.g. width_ratio in the scene file while --set morphology=plain
                notes.append(f"scene parameter '{key}' ignored: model '{model.name}' "
                             f"({', '.join(f'{k}={v}' for k, v in options.items())}) has no such parameter")
        for key, value in param_overrides.items():
            if key not in names:
                raise SceneError(
                    f"{where(spec)}: model '{model_ref}' "
                    f"{'(' + ', '.join(f'{k}={v}' for k, v in options.items()) + ') ' if options else ''}"
                    f"has no parameter or build option '{key}'; parameters: {', '.join(sorted(names))}"
                    f"{'; build options: ' + ', '.join(sorted(option_names)) if option_names else ''}")
            if isinstance(value, (str, bool)):
                raise SceneError(f"{where(spec)}: parameter {key} = {value!r} is not a number")
            params[key] = value
        try:
            model.parameter_vector(params)  # range checks
        except FeatherstarError as exc:
            raise SceneError(f"{where(spec)}: {exc}") from None
        feed = model_feedthrough(model)
        inputs = {v.name: Port(v.name, v.unit, v.description) for v in model.inputs}
        outputs = {v.name: Port(v.name, v.unit, v.description, feed[v.name]) for v in model.outputs}
        identity = ("model", model_ref, FrozenMap(options), FrozenMap(params))
        return ResolvedBlock(spec, inputs, outputs, iterable=True, continuous=True, identity=identity,
                             model=model, parameters={k: float(v) for k, v in params.items()}, notes=notes,
                             can_rollback=True, passivity=passivity_by_convention(inputs, outputs))

    def _resolve_file(self, spec: BlockSpec, fmu_ref: str) -> ResolvedBlock:
        from ..fmi.archive import check_fmu_archive
        from ..fmi.fmu_info import read_fmu_info

        path = Path(fmu_ref).expanduser()
        if not path.exists():
            raise SceneError(f"{where(spec)}: FMU file '{fmu_ref}' does not exist")
        check_fmu_archive(path, where(spec))
        info = read_fmu_info(path, spec.name)
        overrides = dict(spec.overrides)
        interface = overrides.pop("interface", spec.settings.get("interface"))
        if interface is not None:
            info = _choose_interface(info, str(interface), where(spec))
        params = {**dict(spec.settings.get("parameters", {})), **overrides}
        if "options" in spec.settings:
            raise SceneError(f"{where(spec)}: build options apply to models, not to an FMU file")
        typed = {}
        for key, value in params.items():
            if key not in info.parameters:
                raise SceneError(f"{where(spec)}: FMU '{path.name}' has no tunable/fixed parameter '{key}'; "
                                 f"it has: {', '.join(sorted(info.parameters)) or 'none'}")
            try:
                typed[key] = parameter_value(info.parameter_types[key], value,
                                             f"{where(spec)}: parameter {key} ({info.parameter_types[key]})")
            except ValueError as exc:
                raise SceneError(str(exc)) from None
        return ResolvedBlock(spec, dict(info.inputs), dict(info.outputs), iterable=True,
                             continuous=info.has_me, identity=("fmu", str(path.resolve()), interface, FrozenMap(params)),
                             parameters=typed, fmu_path=path, fmu_info=info,
                             can_rollback=info.can_get_set_state,
                             passivity=passivity_by_convention(info.inputs, info.outputs))


def _choose_interface(info: Any, interface: str, where: str) -> Any:
    """The FMU seen through one interface only (`interface = "me"` or `"cs"`)."""
    md = info.model_description
    if interface == "me" and info.has_me:
        return dataclasses.replace(info, has_cs=False, can_get_set_state=bool(md.modelExchange.canGetAndSetFMUstate))
    if interface == "cs" and info.has_cs:
        return dataclasses.replace(info, has_me=False)
    if interface in ("me", "cs"):
        raise SceneError(f"{where}: interface = \"{interface}\" but the FMU has no "
                         f"{'Model Exchange' if interface == 'me' else 'Co-Simulation'} interface")
    raise SceneError(f"{where}: interface = {interface!r}; use \"me\" (Model Exchange) or \"cs\" (Co-Simulation)")
