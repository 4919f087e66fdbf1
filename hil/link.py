"""Device URLs and the Modbus links behind them.

    modbus-tcp://HOST[:PORT][?unit=N]                    (PORT default 502, unit default 1)
    modbus-rtu:///dev/ttyUSB0[?baudrate=115200&unit=1&parity=N&stopbits=1&bytesize=8]

Blocks on the same TCP endpoint or serial line share one pymodbus client (a serial port can be
opened once only, and an RS-485 line or a TCP gateway serves several unit ids). Clients use
pymodbus' synchronous API with retries=0: the control loop, not the library, decides what a
missing reply means.
"""
from __future__ import annotations

import importlib.util
import threading
from dataclasses import dataclass, replace
from typing import Sequence
from urllib.parse import parse_qs, urlsplit

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from .errors import Fault, HILConfigError
from .registers import Function

_RTU_OPTIONS = {"baudrate": (int, None), "parity": (str, ("N", "E", "O")),
                "stopbits": (int, (1, 2)), "bytesize": (int, (7, 8)), "unit": (int, None)}
_TCP_OPTIONS = {"unit": (int, None)}


@dataclass(frozen=True)
class DeviceURL:
    scheme: str                 # "modbus-tcp" or "modbus-rtu"
    unit: int                   # Modbus unit (slave / device) id
    host: str = ""
    port: int = 502
    serial_port: str = ""
    baudrate: int = 19200
    parity: str = "N"
    stopbits: int = 1
    bytesize: int = 8

    @property
    def link_key(self) -> tuple[str, str, int]:
        """Blocks whose URLs share this key share one client."""
        if self.scheme == "modbus-tcp":
            return (self.scheme, self.host, self.port)
        return (self.scheme, self.serial_port, 0)

    def __str__(self) -> str:
        if self.scheme == "modbus-tcp":
            return f"modbus-tcp://{self.host}:{self.port}?unit={self.unit}"
        return (f"modbus-rtu://{self.serial_port}?baudrate={self.baudrate}&parity={self.parity}"
                f"&stopbits={self.stopbits}&bytesize={self.bytesize}&unit={self.unit}")


def _query(url: str, query: str, options: dict[str, tuple[type, tuple | None]]) -> dict:
    try:
        pairs = parse_qs(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise HILConfigError(f"device URL {url!r}: malformed query {query!r}") from None
    values: dict[str, object] = {}
    for key, raw in pairs.items():
        if key not in options:
            raise HILConfigError(f"device URL {url!r}: unknown option {key!r}; "
                                 f"valid options: {', '.join(options)}")
        if len(raw) != 1:
            raise HILConfigError(f"device URL {url!r}: option {key!r} given {len(raw)} times")
        kind, valid = options[key]
        try:
            value = kind(raw[0])
        except ValueError:
            raise HILConfigError(f"device URL {url!r}: {key}={raw[0]!r} is not "
                                 f"{'an integer' if kind is int else 'valid'}") from None
        if valid is not None and value not in valid:
            raise HILConfigError(f"device URL {url!r}: {key}={raw[0]!r}; valid values: "
                                 f"{', '.join(map(str, valid))}")
        values[key] = value
    return values


def parse_url(url: str) -> DeviceURL:
    """Parse a device URL; raises HILConfigError saying what is wrong and what is valid."""
    if not isinstance(url, str) or "://" not in url:
        raise HILConfigError(f"device URL {url!r}: expected modbus-tcp://HOST:PORT?unit=N or "
                             "modbus-rtu:///dev/ttyUSB0?baudrate=115200&unit=N")
    parts = urlsplit(url)
    if parts.scheme == "modbus-tcp":
        if not parts.hostname:
            raise HILConfigError(f"device URL {url!r}: missing host (modbus-tcp://HOST:PORT)")
        if parts.path not in ("", "/"):
            raise HILConfigError(f"device URL {url!r}: unexpected path {parts.path!r}")
        try:
            port = parts.port if parts.port is not None else 502
        except ValueError:
            raise HILConfigError(f"device URL {url!r}: port must be an integer in 1..65535") \
                from None
        if port == 0:
            raise HILConfigError(f"device URL {url!r}: port must be an integer in 1..65535")
        options = _query(url, parts.query, _TCP_OPTIONS)
        unit = options.get("unit", 1)
        if not 0 <= unit <= 255:
            raise HILConfigError(f"device URL {url!r}: unit={unit}; valid values: 0..255")
        return DeviceURL("modbus-tcp", unit, host=parts.hostname, port=port)
    if parts.scheme == "modbus-rtu":
        if parts.netloc or not parts.path:
            raise HILConfigError(f"device URL {url!r}: expected modbus-rtu:///dev/PORT "
                                 "(three slashes, no host)")
        options = _query(url, parts.query, _RTU_OPTIONS)
        unit = options.pop("unit", 1)
        if not 1 <= unit <= 247:
            raise HILConfigError(f"device URL {url!r}: unit={unit}; valid values: 1..247")
        if options.get("baudrate", 19200) <= 0:
            raise HILConfigError(f"device URL {url!r}: baudrate must be positive")
        return DeviceURL("modbus-rtu", unit, serial_port=parts.path, **options)
    raise HILConfigError(f"device URL {url!r}: unknown scheme {parts.scheme!r}; "
                         "valid schemes: modbus-tcp, modbus-rtu")


def check_transport(url: DeviceURL) -> None:
    """Fail at configuration time, not at start, when a transport's library is missing."""
    if url.scheme == "modbus-rtu" and importlib.util.find_spec("serial") is None:
        raise HILConfigError(f"device URL {url}: modbus-rtu needs pyserial "
                             "(pip install pyserial), which is not installed")


class FaultSignal(Exception):
    """A fault seen by the I/O layer, before a device attributes it to itself and a time."""

    def __init__(self, fault: Fault, detail: str) -> None:
        super().__init__(detail)
        self.fault = fault
        self.detail = detail


class Link:
    """One pymodbus client; every method raises FaultSignal on failure."""

    def __init__(self, url: DeviceURL, timeout_s: float) -> None:
        self.url = url
        self.key = url.link_key
        self.refs = 0
        self.generation = 0     # counts connections made: a new one may face a rebooted device
        self.lock = threading.Lock()
        if url.scheme == "modbus-tcp":
            self.client: ModbusTcpClient | ModbusSerialClient = ModbusTcpClient(
                url.host, port=url.port, timeout=timeout_s, retries=0)
        else:
            self.client = ModbusSerialClient(
                url.serial_port, baudrate=url.baudrate, parity=url.parity,
                stopbits=url.stopbits, bytesize=url.bytesize, timeout=timeout_s, retries=0)
        self.where = f"{url.host}:{url.port}" if url.scheme == "modbus-tcp" else url.serial_port

    @property
    def timeout_s(self) -> float:
        return float(self.client.comm_params.timeout_connect)

    def set_timeout(self, timeout_s: float) -> None:
        # pymodbus reads comm_params.timeout_connect on every receive, so this takes effect
        # on the next request.
        self.client.comm_params.timeout_connect = timeout_s

    def reset(self) -> None:
        """Drop the connection so that a late reply to a failed request cannot be taken as
        the answer to the next one (the next request re-dials)."""
        self.client.close()

    def connect(self) -> int:
        """Connect if needed; returns the connection's generation."""
        with self.lock:
            self._connect()
            return self.generation

    def _connect(self) -> None:
        if not self.client.connected:
            if not self.client.connect():
                raise FaultSignal(Fault.CONNECT, f"cannot connect to {self.where}")
            self.generation += 1

    def _call(self, what: str, method, *args, **kwargs) -> object:
        with self.lock:
            self._connect()
            try:
                response = method(*args, **kwargs)
            except ConnectionException as exc:
                self.reset()
                raise FaultSignal(Fault.LINK_LOST, f"{what}: link to {self.where} lost ({exc})") \
                    from None
            except ModbusIOException as exc:
                self.reset()
                raise FaultSignal(Fault.TIMEOUT, f"{what}: no valid reply from {self.where} "
                                                 f"within {self.client.comm_params.timeout_connect}"
                                                 f" s ({exc})") from None
            except (ModbusException, OSError) as exc:
                self.reset()
                raise FaultSignal(Fault.LINK_LOST, f"{what}: {type(exc).__name__}: {exc}") \
                    from None
        if response.isError():
            code = getattr(response, "exception_code", 0)
            try:
                name = ExcCodes(code).name
            except ValueError:
                name = "unknown"
            raise FaultSignal(Fault.EXCEPTION_RESPONSE,
                              f"{what}: exception response code {code} ({name})")
        return response

    def read(self, function: Function, address: int, count: int, unit: int) -> list[int]:
        method = (self.client.read_holding_registers if function is Function.HOLDING
                  else self.client.read_input_registers)
        response = self._call(f"read {function.value} {address}+{count} unit {unit}", method,
                              address, count=count, device_id=unit)
        registers = list(response.registers)
        if len(registers) != count:
            raise FaultSignal(Fault.TIMEOUT, f"read {address}+{count}: got {len(registers)} "
                                             "registers")
        return registers

    def write(self, address: int, values: Sequence[int], unit: int) -> None:
        self._call(f"write holding {address}+{len(values)} unit {unit}",
                   self.client.write_registers, address, list(values), device_id=unit)

    def write_one(self, address: int, value: int, unit: int) -> None:
        self._call(f"write holding {address} unit {unit}", self.client.write_register,
                   address, value, device_id=unit)


_links: dict[tuple[str, str, int], Link] = {}
_links_lock = threading.Lock()


def acquire_link(url: DeviceURL, timeout_s: float) -> Link:
    """The shared link for `url`; sharers get the smallest timeout any of them asked for."""
    with _links_lock:
        link = _links.get(url.link_key)
        if link is None:
            link = _links[url.link_key] = Link(url, timeout_s)
        else:
            if replace(link.url, unit=url.unit) != url:
                raise HILConfigError(f"device URLs {link.url} and {url} share a serial line "
                                     "with different line settings")
            if timeout_s < link.client.comm_params.timeout_connect:
                link.set_timeout(timeout_s)
        link.refs += 1
        return link


def release_link(link: Link) -> None:
    with _links_lock:
        link.refs -= 1
        if link.refs <= 0:
            _links.pop(link.key, None)
            link.reset()
