"""Modbus RTU for the bench emulator: the units of featherstar.hil.modbus_server on a serial line.

An RTU ADU is unit id + PDU + CRC-16/MODBUS (low byte first), per the MODBUS over Serial Line
Specification V1.02. The PDUs are answered by the same `handle_pdu` as on TCP; only the
framing and the addressing differ:
    a frame with a bad CRC                  -> discarded, no response (and the line is
                                               resynchronised at the next silence)
    a unit id this line does not serve      -> no response (another slave's request)
    unit 0 (broadcast)                      -> writes (FC 6, 16) executed on every unit,
                                               no response
A frame ends where its function code says (FC 3, 4, 6: 8 bytes; FC 16: 9 + byte count), so
back-to-back requests and bursts split by a USB adapter or a pty are framed alike. Anything
else (an unknown function code, a truncated frame) ends at a silence of `gap_s`: the
specification's 3.5 characters, but at least GAP_MIN_S, because ptys and USB adapters deliver
bytes in bursts with gaps far above 3.5 characters at 115200 baud.

`device` is a tty path (opened raw at `baudrate`, 8N1 unless told), an open file descriptor (e.g.
the master end of `os.openpty()`), or "pty": a new pseudo-terminal pair whose slave path clients
open (`path` after start()).
"""
from __future__ import annotations

import asyncio
import logging
import os
import termios
import tty

from .errors import HILError
from .modbus_server import RateLimitedLog, Units, handle_pdu

GAP_MIN_S = 0.02
_MAX_ADU = 256                 # unit + 253-byte PDU + 2 CRC bytes
_WRITES = (6, 16)
_RETRY_S = 0.5              # after a read error (device gone)
# A master waits for each answer; one flooding the line is dropped past this, not queued without end.
_MAX_PENDING = 16


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16/MODBUS (poly 0x8005 reflected, init 0xFFFF) of `data`."""
    crc = 0xFFFF
    for byte in data:
        crc = (crc >> 8) ^ _CRC_TABLE[(crc ^ byte) & 0xFF]
    return crc


def frame(unit: int, pdu: bytes) -> bytes:
    """The RTU ADU of `pdu` for `unit`: CRC appended low byte first."""
    body = bytes([unit]) + pdu
    return body + crc16(body).to_bytes(2, "little")


def expected_length(buffer: bytes) -> int | None:
    """Bytes in the request ADU starting `buffer`, once its function code says; None if it
    cannot (an unknown function code: the frame ends at a silence)."""
    if len(buffer) < 2:
        return None
    fc = buffer[1]
    if fc in (3, 4, 6):
        return 8
    if fc == 16:
        return 9 + buffer[6] if len(buffer) >= 7 else None
    return None


def _char_time_s(baudrate: int, bits_per_char: int = 11) -> float:
    return bits_per_char / baudrate


class ModbusRtuServer:
    """Serve `units` on the serial `device` until close()."""

    def __init__(self, units: Units, device: str | int, *, baudrate: int = 19200,
                 gap_s: float | None = None) -> None:
        self.units, self.device, self.baudrate = units, device, baudrate
        # Spec: t3.5 = 3.5 characters, fixed at 1.75 ms above 19200 baud.
        t35_s = 3.5 * _char_time_s(baudrate) if baudrate <= 19200 else 1.75e-3
        self.gap_s = gap_s if gap_s is not None else max(t35_s, GAP_MIN_S)
        self.log = RateLimitedLog()
        self.path = device if isinstance(device, str) else f"fd {device}"
        self._fd = -1
        self._held_fds: list[int] = []    # fds kept open so a pty master never reads EIO
        self._owns_fd = False
        self._buffer = bytearray()
        self._resync = False              # after a bad frame: drop bytes until a silence
        self._silence: asyncio.TimerHandle | None = None
        self._retry: asyncio.TimerHandle | None = None
        self._queue: asyncio.Queue[bytes] = asyncio.Queue(_MAX_PENDING)
        self._worker: asyncio.Task | None = None

    async def start(self) -> str:
        """Open the line and start answering; returns the path clients open."""
        self._fd = self._open()
        loop = asyncio.get_running_loop()
        loop.add_reader(self._fd, self._on_readable)
        self._worker = asyncio.create_task(self._answer_frames())
        return self.path

    def _open(self) -> int:
        if isinstance(self.device, int):
            os.set_blocking(self.device, False)
            return self.device
        self._owns_fd = True
        if self.device == "pty":
            master, slave = os.openpty()
            tty.setraw(slave)          # no echo, no line editing before a client opens it
            self.path = os.ttyname(slave)
            self._held_fds.append(slave)
            os.set_blocking(master, False)
            return master
        try:
            fd = os.open(self.device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as exc:
            raise HILError(f"--rtu {self.device}: cannot open ({exc.strerror})") from None
        try:
            speed = getattr(termios, f"B{self.baudrate}")
        except AttributeError:
            os.close(fd)
            raise HILError(f"--baudrate {self.baudrate}: not a standard serial speed") from None
        try:
            tty.setraw(fd)
            attrs = termios.tcgetattr(fd)
            attrs[4] = attrs[5] = speed
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
        except termios.error as exc:
            os.close(fd)
            raise HILError(f"--rtu {self.device}: not a serial line ({exc})") from None
        return fd

    async def close(self) -> None:
        if self._fd >= 0:
            asyncio.get_running_loop().remove_reader(self._fd)
        for timer in (self._silence, self._retry):
            if timer is not None:
                timer.cancel()
        if self._worker is not None:
            self._worker.cancel()
            await asyncio.gather(self._worker, return_exceptions=True)
        for fd in ([self._fd] if self._owns_fd and self._fd >= 0 else []) + self._held_fds:
            os.close(fd)
        self._fd, self._held_fds = -1, []

    def _on_readable(self) -> None:
        try:
            data = os.read(self._fd, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            # EIO: a pty whose last client closed, a USB adapter unplugged. The fd stays
            # readable, so stop watching it for a while instead of spinning on the error.
            self.log(logging.WARNING, f"{self.path}: {exc.strerror}; retrying in "
                                      f"{_RETRY_S} s")
            loop = asyncio.get_running_loop()
            loop.remove_reader(self._fd)
            self._retry = loop.call_later(_RETRY_S, loop.add_reader, self._fd,
                                          self._on_readable)
            return
        if not data:
            return
        loop = asyncio.get_running_loop()
        if self._silence is not None:
            self._silence.cancel()
        self._silence = loop.call_later(self.gap_s, self._on_silence)
        if self._resync:
            return
        self._buffer += data
        self._split_frames()

    def _split_frames(self) -> None:
        while True:
            n = expected_length(bytes(self._buffer[:7]))
            if n is None:
                if len(self._buffer) > _MAX_ADU:
                    self._discard("longer than any ADU")
                return
            if len(self._buffer) < n:
                return
            adu = bytes(self._buffer[:n])
            del self._buffer[:n]
            if not self._accept(adu):
                return

    def _on_silence(self) -> None:
        """A silence ends whatever frame is pending: one the length rule could not end."""
        self._silence = None
        if self._buffer:
            adu = bytes(self._buffer)
            if len(adu) >= 4:
                self._accept(adu)
            else:
                self._discard(f"{len(adu)}-byte fragment {adu.hex()}")
        self._buffer.clear()
        self._resync = False      # this silence is the resynchronisation

    def _accept(self, adu: bytes) -> bool:
        """Queue a checked frame; False (and resynchronise) on a bad CRC."""
        if crc16(adu[:-2]) != int.from_bytes(adu[-2:], "little"):
            self._discard(f"bad CRC in {adu.hex()}")
            return False
        if self._queue.full():
            self.log(logging.WARNING, f"{self.path}: {_MAX_PENDING} requests pending: "
                                      f"{adu.hex()} dropped, no response")
        else:
            self._queue.put_nowait(adu[:-2])
        return True

    def _discard(self, why: str) -> None:
        self.log(logging.WARNING, f"{self.path}: frame discarded, no response: {why}")
        self._buffer.clear()
        self._resync = True

    async def _answer_frames(self) -> None:
        while True:
            body = await self._queue.get()
            unit, pdu = body[0], body[1:]
            try:
                if unit == 0:
                    if pdu[0] in _WRITES:
                        for each in self.units:
                            await handle_pdu(self.units, each, pdu, self.log)
                    continue
                if unit not in self.units:
                    continue               # another slave's request
                reply = frame(unit, await handle_pdu(self.units, unit, pdu, self.log))
                os.write(self._fd, reply)
            except Exception as exc:   # one bad exchange must not take the line down
                self.log(logging.ERROR, f"{self.path}: {type(exc).__name__}: {exc}")
