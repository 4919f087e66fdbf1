"""Register maps as data: TOML files parsed into frozen dataclasses.

Load-cell transmitters and servo controllers differ in function code, address base, number
format, word order and status bits, so a device's register map is a TOML file (`hil/maps/`)
parsed into frozen dataclasses here; `featherstar.hil.codec` encodes and decodes registers for both the
client blocks and the emulator.

Map file layout (see the shipped maps for complete examples):

    [device]   kind = "loadcell" | "servo", function = "holding" | "input" (how the readable
               fields are read: function code 3 or 4), address_base = 0 | 1 (how the addresses
               below are printed in the manual), description = "..." (optional)
    [value]    loadcell, required: a number field (below), unit kg | g | N
    [setpoint] servo, required: number field written with function code 16, unit rad | deg
    [position] servo, optional read-back: number field, unit rad | deg
    [status]   optional: address, stable_bit / overload_bit / error_bit / lag_bit (0-15, each
               optional). lag_bit: an emulated device's model fell behind real time since the
               status was last read (featherstar emulate sets it; real transmitters have none)
    [tare]     loadcell, optional: address, value (written with function code 6)
    [enable]   servo, optional: address, value (written on every new connection and after
               every device restart)
    [session]  optional, both kinds: address (one register: an id the device draws anew at every
               boot, never 0), uptime_address (two registers, ABCD: milliseconds since boot,
               unsigned). Read with every sample: a changed id or an uptime that went back is a
               device restart (behind a gateway the TCP connection does not show it), an uptime
               that stops is a frozen device (featherstar.hil.session)
    [watchdog] servo, optional: address (one holding register), timeout_ms (1..65535, written
               there with the enable): the device returns to its safe position when no command
               (write) reached it for that long (a client killed with -9, a PC that lost power)

Number field: address, type = "float32" | "int32", word_order = "ABCD" | "CDAB" | "BADC" |
"DCBA" (default ABCD), unit, scale (default 1), offset (default 0; engineering value =
raw * scale + offset), min / max (engineering range, optional), and for int32 exactly one of
decimals (fixed) or decimals_address (a register holding the number of decimals).
"""
from __future__ import annotations

import enum
import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any, Sequence

from .errors import HILConfigError
from .map_reader import MapReader, map_address
from .timed_registers import TimedTables, parse_timed


class Function(str, enum.Enum):
    HOLDING = "holding"   # read with function code 3
    INPUT = "input"       # read with function code 4


class ValueType(str, enum.Enum):
    FLOAT32 = "float32"
    INT32 = "int32"


class WordOrder(str, enum.Enum):
    """Where bytes A (most significant) .. D land in the two registers."""

    ABCD = "ABCD"
    CDAB = "CDAB"
    BADC = "BADC"
    DCBA = "DCBA"


_UNIT_SCALE = {"loadcell": {"kg": 9.80665, "g": 9.80665e-3, "N": 1.0},
               "servo": {"rad": 1.0, "deg": math.pi / 180.0}}
MAX_DECIMALS = 9


@dataclass(frozen=True)
class NumberField:
    """A 32-bit number in two registers. `address` is the 0-based protocol address."""

    address: int
    type: ValueType
    word_order: WordOrder
    unit: str
    to_si: float                 # engineering unit -> N or rad
    scale: float = 1.0
    offset: float = 0.0
    decimals: int | None = None
    decimals_address: int | None = None
    min: float | None = None
    max: float | None = None

    def spans(self) -> list[tuple[int, int]]:
        """(address, register count) of the value and of its decimals register, if any."""
        spans = [(self.address, 2)]
        if self.decimals_address is not None:
            spans.append((self.decimals_address, 1))
        return spans


@dataclass(frozen=True)
class StatusField:
    address: int
    stable_bit: int | None = None
    overload_bit: int | None = None
    error_bit: int | None = None
    lag_bit: int | None = None


@dataclass(frozen=True)
class Status:
    stable: bool = True
    overload: bool = False
    error: bool = False
    lagging: bool = False    # an emulator's plant fell behind real time since the last read


@dataclass(frozen=True)
class CommandField:
    address: int
    value: int


@dataclass(frozen=True)
class SessionField:
    address: int           # boot id, one register
    uptime_address: int    # milliseconds since boot, two registers (ABCD)

    def spans(self) -> list[tuple[int, int]]:
        return [(self.address, 1), (self.uptime_address, 2)]


@dataclass(frozen=True)
class WatchdogField:
    address: int
    timeout_ms: int


@dataclass(frozen=True)
class LoadCellMap:
    name: str
    source: str
    description: str
    read_function: Function
    value: NumberField
    status: StatusField | None
    tare: CommandField | None
    session: SessionField | None = None
    timed: TimedTables = TimedTables(None, None, None)


@dataclass(frozen=True)
class ServoMap:
    name: str
    source: str
    description: str
    read_function: Function
    setpoint: NumberField
    position: NumberField | None
    status: StatusField | None
    enable: CommandField | None
    session: SessionField | None = None
    watchdog: WatchdogField | None = None
    timed: TimedTables = TimedTables(None, None, None)


_SECTIONS = {"loadcell": {"device", "value", "status", "tare", "session", "clock", "log"},
             "servo": {"device", "setpoint", "position", "status", "enable", "session",
                       "watchdog", "clock", "trajectory", "log"}}
_NUMBER_KEYS = {"address", "type", "word_order", "unit", "scale", "offset", "decimals",
                "decimals_address", "min", "max"}


def _number_field(r: MapReader, section: str, table: dict[str, Any], kind: str,
                  base: int) -> NumberField:
    r.check_keys(section, table, _NUMBER_KEYS)
    value_type = ValueType(r.choice(section, table, "type", [t.value for t in ValueType]))
    order = WordOrder(r.choice(section, table, "word_order", [o.value for o in WordOrder], "ABCD"))
    unit = r.choice(section, table, "unit", list(_UNIT_SCALE[kind]))
    scale = r.number(section, table, "scale", 1.0)
    if scale == 0.0:
        raise r.fail(f"[{section}] scale = 0", "must be non-zero")
    decimals = r.integer(section, table, "decimals", 0, MAX_DECIMALS)
    decimals_address = map_address(r, section, table, "decimals_address", base, required=False)
    if value_type is ValueType.FLOAT32 and (decimals is not None or decimals_address is not None):
        raise r.fail(f"[{section}]", "decimals / decimals_address apply to type = 'int32' only")
    if value_type is ValueType.INT32 and (decimals is None) == (decimals_address is None):
        raise r.fail(f"[{section}]", "type = 'int32' needs exactly one of decimals (fixed) "
                                     "or decimals_address (register)")
    lo, hi = r.number(section, table, "min", None), r.number(section, table, "max", None)
    if lo is not None and hi is not None and lo >= hi:
        raise r.fail(f"[{section}] min = {lo}, max = {hi}", "min must be below max")
    return NumberField(address=map_address(r, section, table, "address", base), type=value_type,
                       word_order=order, unit=unit, to_si=_UNIT_SCALE[kind][unit], scale=scale,
                       offset=r.number(section, table, "offset", 0.0), decimals=decimals,
                       decimals_address=decimals_address, min=lo, max=hi)


def _status_field(r: MapReader, table: dict[str, Any], base: int) -> StatusField:
    names = ("stable_bit", "overload_bit", "error_bit", "lag_bit")
    r.check_keys("status", table, {"address", *names})
    bits = {k: r.integer("status", table, k, 0, 15) for k in names}
    used = [b for b in bits.values() if b is not None]
    if len(used) != len(set(used)):
        raise r.fail("[status]", f"two meanings share one bit: {bits}")
    return StatusField(address=map_address(r, "status", table, "address", base), **bits)


def _command_field(r: MapReader, section: str, table: dict[str, Any], base: int) -> CommandField:
    r.check_keys(section, table, {"address", "value"})
    return CommandField(address=map_address(r, section, table, "address", base),
                        value=r.integer(section, table, "value", 0, 65535, required=True))


def _session_field(r: MapReader, table: dict[str, Any], base: int) -> SessionField:
    r.check_keys("session", table, {"address", "uptime_address"})
    return SessionField(address=map_address(r, "session", table, "address", base),
                        uptime_address=map_address(r, "session", table, "uptime_address", base))


def _watchdog_field(r: MapReader, table: dict[str, Any], base: int) -> WatchdogField:
    r.check_keys("watchdog", table, {"address", "timeout_ms"})
    return WatchdogField(address=map_address(r, "watchdog", table, "address", base),
                         timeout_ms=r.integer("watchdog", table, "timeout_ms", 1, 65535,
                                              required=True))


def _check_overlaps(r: MapReader, spaces: dict[str, list[tuple[str, int, int]]],
                    timed: TimedTables, read_space: str) -> None:
    for space, name, address, count, _writable in timed.spans(read_space):
        spaces[space].append((name, address, count))
    for space, fields in spaces.items():
        fields.sort(key=lambda f: f[1])
        for (name_a, start_a, n_a), (name_b, start_b, _) in zip(fields, fields[1:]):
            if start_b < start_a + n_a:
                raise r.fail(f"{name_a} and {name_b}",
                             f"overlap in the {space} registers (protocol address {start_b})")


def _layout(read_function: Function, readable: dict[str, Any],
            writable: dict[str, Any]) -> dict[str, list[tuple[str, int, int]]]:
    """(name, protocol address, register count) per register space, for the overlap check."""
    spaces: dict[str, list[tuple[str, int, int]]] = {"holding": [], "input": []}
    for group, space in ((readable, read_function.value), (writable, "holding")):
        for name, f in group.items():
            if isinstance(f, SessionField):
                spaces[space] += [(f"[{name}] address", f.address, 1),
                                  (f"[{name}] uptime_address", f.uptime_address, 2)]
            elif isinstance(f, NumberField):
                spaces[space].append((f"[{name}]", f.address, 2))
                if f.decimals_address is not None:
                    spaces[read_function.value].append(
                        (f"[{name}] decimals_address", f.decimals_address, 1))
            elif f is not None:
                spaces[space].append((f"[{name}]", f.address, 1))
    return spaces


def _check_logged(r: MapReader, field: NumberField, timed: TimedTables) -> None:
    if timed.log is not None and field.decimals_address is not None:
        raise r.fail("[log]", "a logged field needs fixed decimals (or float32), not a "
                              "decimals_address")


def parse_map(doc: dict[str, Any], name: str, source: str) -> LoadCellMap | ServoMap:
    """Validate a parsed TOML document; HILConfigError names source, key and valid values."""
    r = MapReader(source)
    device = r.table(doc, "device", required=True)
    r.check_keys("device", device, {"kind", "function", "address_base", "description"})
    kind = r.choice("device", device, "kind", list(_SECTIONS))
    r.check_keys("top level", doc, _SECTIONS[kind])
    function = Function(r.choice("device", device, "function", [f.value for f in Function]))
    base = r.choice("device", device, "address_base", [0, 1])
    description = str(device.get("description", ""))
    status = r.table(doc, "status", required=False)
    status_field = None if status is None else _status_field(r, status, base)
    session = r.table(doc, "session", required=False)
    session_field = None if session is None else _session_field(r, session, base)
    timed = parse_timed(r, doc, kind, base)
    if kind == "loadcell":
        value = _number_field(r, "value", r.table(doc, "value", True), kind, base)
        tare = r.table(doc, "tare", required=False)
        tare_field = None if tare is None else _command_field(r, "tare", tare, base)
        _check_overlaps(r, _layout(function, {"value": value, "status": status_field,
                                              "session": session_field}, {"tare": tare_field}),
                        timed, function.value)
        _check_logged(r, value, timed)
        return LoadCellMap(name, source, description, function, value, status_field, tare_field,
                           session_field, timed)
    setpoint = _number_field(r, "setpoint", r.table(doc, "setpoint", True), kind, base)
    if setpoint.decimals_address is not None:
        # A write-only field cannot follow a decimals register without an extra read per step.
        raise r.fail("[setpoint] decimals_address", "not supported; use fixed decimals")
    position = r.table(doc, "position", required=False)
    position_field = None if position is None else _number_field(r, "position", position, kind,
                                                                 base)
    enable = r.table(doc, "enable", required=False)
    enable_field = None if enable is None else _command_field(r, "enable", enable, base)
    watchdog = r.table(doc, "watchdog", required=False)
    watchdog_field = None if watchdog is None else _watchdog_field(r, watchdog, base)
    _check_overlaps(r, _layout(function, {"position": position_field, "status": status_field,
                                          "session": session_field},
                               {"setpoint": setpoint, "enable": enable_field,
                                "watchdog": watchdog_field}), timed, function.value)
    if timed.log is not None and position_field is None:
        raise r.fail("[log]", "a servo logs its [position]: add one, or drop [log]")
    if position_field is not None:
        _check_logged(r, position_field, timed)
    return ServoMap(name, source, description, function, setpoint, position_field, status_field,
                    enable_field, session_field, watchdog_field, timed)


def _maps_dir() -> Traversable:
    return resources.files(__package__).joinpath("maps")


def available_maps() -> list[str]:
    """Names of the maps shipped in hil/maps/."""
    return sorted(p.name.removesuffix(".toml") for p in _maps_dir().iterdir()
                  if p.name.endswith(".toml"))


def load_map(name_or_path: str | Path) -> LoadCellMap | ServoMap:
    """A shipped map by name (`loadcell-float32-abcd`) or a TOML file by path."""
    text_name = str(name_or_path)
    if text_name in available_maps():
        resource = _maps_dir() / f"{text_name}.toml"
        source, text = f"hil/maps/{text_name}.toml", resource.read_text(encoding="utf-8")
    else:
        path = Path(name_or_path)
        if not path.is_file():
            raise HILConfigError(f"register map {text_name!r}: no such file and not a shipped "
                                 f"map; shipped maps: {', '.join(available_maps())}")
        source = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise HILConfigError(f"register map {source}: not UTF-8 text (byte {exc.start}: "
                                 f"{exc.reason}); save it as UTF-8") from None
        except OSError as exc:
            raise HILConfigError(f"register map {source}: cannot read it "
                                 f"({exc.strerror or exc})") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise HILConfigError(f"register map {source}: not valid TOML: {exc}") from None
    return parse_map(doc, Path(text_name).stem, source)


def load_loadcell_map(name_or_path: str | Path) -> LoadCellMap:
    m = load_map(name_or_path)
    if not isinstance(m, LoadCellMap):
        raise HILConfigError(f"register map {m.source}: [device] kind = 'servo', "
                             "a load cell needs kind = 'loadcell'")
    return m


def load_servo_map(name_or_path: str | Path) -> ServoMap:
    m = load_map(name_or_path)
    if not isinstance(m, ServoMap):
        raise HILConfigError(f"register map {m.source}: [device] kind = 'loadcell', "
                             "a servo needs kind = 'servo'")
    return m
