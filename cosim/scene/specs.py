"""The items scene data is made of: frozen maps, port references, connections, block specs and
--set values. Block kinds (featherstar.cosim.scene.blocks) read these; featherstar.cosim.scene.data assembles them into a Scene."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator, Mapping

from ..errors import SceneError


class FrozenMap(Mapping[str, Any]):
    """An immutable, hashable mapping (scene data must not change under a run)."""

    __slots__ = ("_d", "_h")

    def __init__(self, data: Mapping[str, Any] | None = None, **kw: Any) -> None:
        d = dict(data or {})
        d.update(kw)
        self._d = {k: _freeze(v) for k, v in d.items()}
        self._h: int | None = None

    def __getitem__(self, key: str) -> Any:
        return self._d[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)

    def __hash__(self) -> int:
        if self._h is None:
            self._h = hash(tuple(sorted((k, v) for k, v in self._d.items())))
        return self._h

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Mapping) and dict(self._d) == dict(other)

    def __repr__(self) -> str:
        return f"FrozenMap({self._d!r})"

    def set(self, key: str, value: Any) -> "FrozenMap":
        d = dict(self._d)
        d[key] = value
        return FrozenMap(d)

    def without(self, key: str) -> "FrozenMap":
        return FrozenMap({k: v for k, v in self._d.items() if k != key})

    def to_plain(self) -> dict[str, Any]:
        return {k: _thaw(v) for k, v in self._d.items()}


def _freeze(v: Any) -> Any:
    if isinstance(v, FrozenMap):
        return v
    if isinstance(v, Mapping):
        return FrozenMap(v)
    if isinstance(v, (list, tuple)):
        return tuple(_freeze(x) for x in v)
    return v


def _thaw(v: Any) -> Any:
    if isinstance(v, FrozenMap):
        return v.to_plain()
    if isinstance(v, tuple):
        return [_thaw(x) for x in v]
    return v


@dataclass(frozen=True, order=True)
class PortRef:
    block: str
    port: str

    @classmethod
    def parse(cls, text: str, what: str = "port") -> "PortRef":
        block, dot, port = text.strip().partition(".")
        if not dot or not block or not port:
            raise SceneError(f"{what} '{text}' must read 'block.port'")
        return cls(block, port)

    def __str__(self) -> str:
        return f"{self.block}.{self.port}"


@dataclass(frozen=True)
class Connection:
    src: PortRef  # an output
    dst: PortRef  # an input

    def __str__(self) -> str:
        return f"{self.src} -> {self.dst}"


@dataclass(frozen=True)
class BlockSpec:
    """One block of a scene. `settings` is the block's TOML table without `kind`/`description`;
    `overrides` are the user's --set values for it (kept apart: they must all be used)."""

    name: str
    kind: str
    settings: FrozenMap = field(default_factory=FrozenMap)
    overrides: FrozenMap = field(default_factory=FrozenMap)
    description: str = ""


def parse_value(raw: Any) -> Any:
    """A --set value: numbers and booleans from text, anything else kept as a string."""
    if not isinstance(raw, str):
        return raw
    text = raw.strip()
    low = text.lower()
    if low in ("true", "yes", "on"):
        return True
    if low in ("false", "no", "off"):
        return False
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text
