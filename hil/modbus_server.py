"""A small Modbus TCP server for the bench emulator, written to the MODBUS Application Protocol
V1.1b3 and the Messaging Implementation Guide V1.0b rather than bent out of a library.

It serves function codes 3, 4 (read holding / input registers), 6 (write one register) and 16
(write registers) for the units it is given, and answers everything else as the specification's
state diagrams say, in their order:
    function code not implemented                       -> code|0x80, exception 01
    quantity outside 1..125 (3, 4) or 1..123 (16), byte count != 2 x quantity, or a PDU whose
    length does not match its function                  -> code|0x80, exception 03
    an address range with a register the unit lacks (or writing a read-only one) -> 02
    the unit's own verdict (a refused value: 03, a failing device: 04)
    a unit id nobody answers to                         -> code|0x80, exception 0B (gateway:
                                                           target device failed to respond)
Frames are read from a stream buffer, so requests pipelined in one TCP segment are all answered,
in order. A header that is not Modbus (protocol id != 0, length outside 2..254) cannot be
resynchronised: the connection is closed. A connection idle for `idle_timeout_s` is closed
(a client that vanished without a FIN would otherwise hold it forever). Log lines are
truncated and rate-limited, so a client sending garbage cannot fill the disk.
"""
from __future__ import annotations

import asyncio
import logging
import struct
import time
from dataclasses import dataclass, field
from typing import Awaitable, Callable, Sequence

log = logging.getLogger(__name__)

ILLEGAL_FUNCTION, ILLEGAL_ADDRESS, ILLEGAL_VALUE, DEVICE_FAILURE = 0x01, 0x02, 0x03, 0x04
GATEWAY_TARGET_FAILED = 0x0B
MAX_READ, MAX_WRITE = 125, 123          # registers per FC3/FC4 and per FC16 request
HOLDING, INPUT = "holding", "input"
_MAX_PDU = 253                            # an ADU is at most 260 bytes: 7 MBAP + 253 PDU

# A unit's handler: (function code, space, address, count, values to write or None) ->
# registers read (list), None after a write, or an int exception code. It may await (a
# silent device), and it sees only requests that passed the protocol checks.
Handler = Callable[[int, str, int, int, "list[int] | None"], Awaitable["list[int] | int | None"]]


@dataclass
class UnitSpace:
    """Which registers a unit has: address -> writable, per space (holding, input)."""

    holding: dict[int, bool] = field(default_factory=dict)
    input: dict[int, bool] = field(default_factory=dict)

    def check(self, space: str, address: int, count: int, write: bool) -> bool:
        table = self.holding if space == HOLDING else self.input
        return all((a in table) and (table[a] or not write)
                   for a in range(address, address + count))


# Unit id -> (its register spaces, its handler): what a server (TCP or RTU) answers for.
Units = dict[int, tuple[UnitSpace, Handler]]


class RateLimitedLog:
    """At most `burst` lines per `window_s`, each at most `max_chars`; the rest are counted
    and reported once the window has passed."""

    def __init__(self, burst: int = 20, window_s: float = 10.0, max_chars: int = 200) -> None:
        self.burst, self.window_s, self.max_chars = burst, window_s, max_chars
        self._t0 = time.monotonic()
        self._n = self._dropped = 0

    def __call__(self, level: int, message: str) -> None:
        now = time.monotonic()
        if now - self._t0 > self.window_s:
            if self._dropped:
                log.warning("%d log lines suppressed in the last %.0f s", self._dropped,
                            self.window_s)
            self._t0, self._n, self._dropped = now, 0, 0
        if self._n >= self.burst:
            self._dropped += 1
            return
        self._n += 1
        log.log(level, "%s", message[:self.max_chars])


def exception_pdu(function_code: int, code: int) -> bytes:
    return bytes([(function_code | 0x80) & 0xFF, code])


class ModbusTcpServer:
    """Serve `units` (unit id -> (UnitSpace, Handler)) on host:port until close()."""

    def __init__(self, units: Units, host: str, port: int, *,
                 idle_timeout_s: float = 30.0) -> None:
        self.units, self.host, self.port = units, host, port
        self.idle_timeout_s = idle_timeout_s
        self.log = RateLimitedLog()
        self.connections = 0
        self._server: asyncio.base_events.Server | None = None
        self._tasks: set[asyncio.Task] = set()

    async def start(self) -> int:
        """Listen; returns the bound port."""
        self._server = await asyncio.start_server(self._serve, self.host, self.port)
        return self._server.sockets[0].getsockname()[1]

    async def close(self) -> None:
        """Stop listening and drop every connection (like a device losing power)."""
        if self._server is not None:
            self._server.close()
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        if self._server is not None:
            await self._server.wait_closed()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._tasks.add(task)
        self.connections += 1
        peer = writer.get_extra_info("peername")
        try:
            while True:
                try:
                    header = await asyncio.wait_for(reader.readexactly(7), self.idle_timeout_s)
                    tid, pid, length, unit = struct.unpack(">HHHB", header)
                    if pid != 0 or not 2 <= length <= _MAX_PDU + 1:
                        self.log(logging.WARNING, f"{peer}: not a Modbus TCP header "
                                                  f"{header.hex()}: closing the connection")
                        return
                    pdu = await asyncio.wait_for(reader.readexactly(length - 1),
                                                 self.idle_timeout_s)
                except asyncio.TimeoutError:
                    self.log(logging.INFO, f"{peer}: idle for {self.idle_timeout_s} s: closed")
                    return
                reply = await handle_pdu(self.units, unit, pdu, self.log)
                writer.write(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            return      # the client went away: nothing to answer
        except Exception as exc:   # one broken connection must not take the server down
            self.log(logging.ERROR, f"{peer}: {type(exc).__name__}: {exc}")
        finally:
            self._tasks.discard(task)
            writer.close()


async def handle_pdu(units: Units, unit: int, pdu: bytes,
                     report: Callable[[int, str], None]) -> bytes:
    """The response PDU to request `pdu` for `unit`, whatever the transport (TCP and RTU
    share it); `report(level, message)` hears device bugs."""
    fc = pdu[0]
    if unit not in units:
        return exception_pdu(fc, GATEWAY_TARGET_FAILED)
    space_map, handler = units[unit]
    parsed = parse_request(pdu)
    if isinstance(parsed, int):
        return exception_pdu(fc, parsed)
    space, address, count, values = parsed
    if not space_map.check(space, address, count, write=values is not None):
        return exception_pdu(fc, ILLEGAL_ADDRESS)
    try:
        result = await handler(fc, space, address, count, values)
    except Exception as exc:   # a device bug is a device failure, never a dead server
        report(logging.ERROR, f"unit {unit} fc {fc}: {type(exc).__name__}: {exc}")
        return exception_pdu(fc, DEVICE_FAILURE)
    if isinstance(result, int):
        return exception_pdu(fc, result)
    if fc in (3, 4):
        registers = list(result or [])
        if len(registers) != count:
            return exception_pdu(fc, DEVICE_FAILURE)
        return struct.pack(f">BB{count}H", fc, 2 * count, *registers)
    return pdu[:5]   # FC6 echoes the request; FC16 answers address and quantity


def parse_request(pdu: bytes) -> tuple[str, int, int, list[int] | None] | int:
    """(space, address, count, values or None) of a valid request, else the exception code."""
    fc = pdu[0]
    if fc in (3, 4):
        if len(pdu) != 5:
            return ILLEGAL_VALUE
        address, count = struct.unpack(">HH", pdu[1:5])
        if not 1 <= count <= MAX_READ:
            return ILLEGAL_VALUE
        return (HOLDING if fc == 3 else INPUT), address, count, None
    if fc == 6:
        if len(pdu) != 5:
            return ILLEGAL_VALUE
        address, value = struct.unpack(">HH", pdu[1:5])
        return HOLDING, address, 1, [value]
    if fc == 16:
        if len(pdu) < 6:
            return ILLEGAL_VALUE
        address, count, n_bytes = struct.unpack(">HHB", pdu[1:6])
        if not 1 <= count <= MAX_WRITE or n_bytes != 2 * count or len(pdu) != 6 + n_bytes:
            return ILLEGAL_VALUE
        return HOLDING, address, count, list(struct.unpack(f">{count}H", pdu[6:]))
    return ILLEGAL_FUNCTION


def spaces_for(read_space: str, readable: Sequence[tuple[int, int]],
               writable: Sequence[tuple[int, int]]) -> UnitSpace:
    """A UnitSpace from (address, count) spans: readable ones read-only in `read_space`,
    writable ones in the holding space (real transmitters keep measured values read-only)."""
    spaces = UnitSpace()
    table = spaces.holding if read_space == HOLDING else spaces.input
    for address, count in readable:
        table.update(dict.fromkeys(range(address, address + count), False))
    for address, count in writable:
        spaces.holding.update(dict.fromkeys(range(address, address + count), True))
    return spaces
