"""Serving the bench emulator (featherstar.hil.emulated_bench.Emulator) over Modbus TCP
(or RTU on a serial line: `serve_rtu`, `rtu=` of the starters).

Use `start_emulator()` (background thread, in-process, supports fault injection) or
`spawn_emulator()` (child process, can be killed like a real device) in tests and benches, and
`featherstar emulate` on the command line. `serve` ticks the emulator (TICK_S while its plant
moves, seldom once it rests, back to back while a device-timed plant catches up).
"""
from __future__ import annotations

import abc
import asyncio
import json
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Callable, Mapping

from .emulated_bench import IDLE_TIMEOUT_S, LOADCELL_UNIT, SERVO_UNIT, Emulator
from .errors import HILError
from .modbus_server import ModbusTcpServer
from .rtu_server import ModbusRtuServer
from .plant import Plant, PlantValue
from .registers import load_loadcell_map, load_servo_map


async def serve(emulator: Emulator, host: str, port: int, stop: asyncio.Event,
                on_ready: Callable[[int], None], *,
                idle_timeout_s: float = IDLE_TIMEOUT_S) -> None:
    """Serve until `stop` is set; `on_ready(bound_port)` once listening."""
    await _serve_until(emulator, ModbusTcpServer(emulator.units(), host, port, idle_timeout_s=idle_timeout_s),
                       stop, on_ready)


async def serve_rtu(emulator: Emulator, device: str | int, baudrate: int, stop: asyncio.Event,
                    on_ready: Callable[[str], None]) -> None:
    """Serve Modbus RTU on `device` (a tty path, an open fd, or "pty") until `stop` is set;
    `on_ready(path clients open)` once answering."""
    await _serve_until(emulator, ModbusRtuServer(emulator.units(), device, baudrate=baudrate), stop, on_ready)


async def _serve_until(emulator: Emulator, server: Any, stop: asyncio.Event, on_ready: Callable[[Any], None]) -> None:
    """Start `server` (TCP or RTU: `start()` returns where clients connect), keep the emulator's
    time while it answers, close it once `stop` is set."""
    where = await server.start()
    ticker = asyncio.create_task(_keep_time(emulator, stop))
    try:
        on_ready(where)
        await stop.wait()
    finally:
        ticker.cancel()
        await server.close()


async def _keep_time(emulator: Emulator, stop: asyncio.Event) -> None:
    """Tick the emulator every TICK_S, telling it when each tick was due."""
    due = time.monotonic()
    while not stop.is_set():
        interval_s = emulator.tick_interval_s()
        due += interval_s
        await asyncio.sleep(max(0.0, due - time.monotonic()))
        emulator.tick(due)
        if time.monotonic() - due > interval_s:
            due = time.monotonic()   # held up: do not fire the missed ticks in a burst


class _Handle(abc.ABC):
    host: str
    port: int
    rtu_path: str = ""      # the tty clients open when served over RTU
    baudrate: int = 115200

    def _url(self, unit: int) -> str:
        if self.rtu_path:
            return f"modbus-rtu://{self.rtu_path}?baudrate={self.baudrate}&unit={unit}"
        return f"modbus-tcp://{self.host}:{self.port}?unit={unit}"

    @property
    def loadcell_url(self) -> str:
        return self._url(LOADCELL_UNIT)

    @property
    def servo_url(self) -> str:
        return self._url(SERVO_UNIT)

    def __enter__(self) -> _Handle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @abc.abstractmethod
    def stop(self) -> None: ...


class EmulatorThread(_Handle):
    """An emulator served from a background thread of this process."""

    def __init__(self, emulator: Emulator, host: str, port: int, *,
                 idle_timeout_s: float = IDLE_TIMEOUT_S, rtu: str | int | None = None,
                 baudrate: int = 115200) -> None:
        self.emulator, self.host, self.port = emulator, host, port
        self.idle_timeout_s = idle_timeout_s
        self.rtu, self.baudrate = rtu, baudrate     # RTU instead of TCP when rtu is given
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._loop = asyncio.new_event_loop()
        self._stop = asyncio.Event()
        self._thread = threading.Thread(target=self._run, name="hil-emulator", daemon=True)
        self._thread.start()
        if not self._ready.wait(10.0) or self._error is not None:
            raise HILError(f"emulator did not start on {host}:{port}: {self._error}")

    def _run(self) -> None:
        def ready(port: int) -> None:
            self.port = port
            self._ready.set()
        def rtu_ready(path: str) -> None:
            if not isinstance(self.rtu, int):    # an fd's far end has a path only its opener knows
                self.rtu_path = path
            self._ready.set()
        try:
            if self.rtu is not None:
                self._loop.run_until_complete(serve_rtu(self.emulator, self.rtu, self.baudrate,
                                                        self._stop, rtu_ready))
            else:
                self._loop.run_until_complete(serve(self.emulator, self.host, self.port,
                                                    self._stop, ready,
                                                    idle_timeout_s=self.idle_timeout_s))
        except BaseException as exc:   # reported to the starting thread
            self._error = exc
            self._ready.set()
        finally:
            self._loop.close()

    def stop(self) -> None:
        """Close the server and every client connection (like a device losing power)."""
        if self._thread.is_alive():
            self.emulator.inject("loadcell", None)
            self.emulator.inject("servo", None)
            self._loop.call_soon_threadsafe(self._stop.set)
            self._thread.join(10.0)


def start_emulator(host: str = "127.0.0.1", port: int = 0,
                   loadcell_map: str | Path = "loadcell-float32-abcd",
                   servo_map: str | Path = "servo-default", *, noise_N: float = 0.01,
                   seed: int | None = None, plant: Plant | None = None,
                   idle_timeout_s: float = IDLE_TIMEOUT_S,
                   rtu: str | int | None = None) -> EmulatorThread:
    """Serve a new emulator in a background thread; returns once it listens (port 0 = any).
    With `rtu` (a tty path, an open fd such as a pty master, or "pty") it serves Modbus RTU
    there instead of TCP."""
    emulator = Emulator(load_loadcell_map(loadcell_map), load_servo_map(servo_map), plant,
                        noise_N=noise_N, seed=seed)
    return EmulatorThread(emulator, host, port, idle_timeout_s=idle_timeout_s, rtu=rtu)


class EmulatorProcess(_Handle):
    """An emulator in a child process (`python -m featherstar.hil emulate`): kill() it like a device."""

    _LISTENING = re.compile(r"listening on (?:modbus-tcp://(\S+):(\d+)"
                            r"|modbus-rtu://([^?\s]+)\?baudrate=(\d+))")

    def __init__(self, args: list[str], start_timeout_s: float = 20.0,
                 plant_parameters: Mapping[str, PlantValue] | None = None) -> None:
        # stderr to a file: an unread pipe would fill and stall the child.
        self._stderr = tempfile.TemporaryFile("w+")
        # Hidden coefficients go through a file, not the command line (which `ps` shows).
        self._parameters_file = None
        if plant_parameters:
            self._parameters_file = tempfile.NamedTemporaryFile("w", suffix=".json", delete=False)
            json.dump(dict(plant_parameters), self._parameters_file)
            self._parameters_file.close()
            args = [*args, "--plant-parameters", self._parameters_file.name]
        self.proc = subprocess.Popen([sys.executable, "-m", "featherstar.hil", "emulate", *args],
                                     stdout=subprocess.PIPE, stderr=self._stderr, text=True)
        lines: list[str] = []
        reader = threading.Thread(target=lambda: lines.append(self.proc.stdout.readline()),
                                  daemon=True)
        reader.start()
        reader.join(start_timeout_s)
        match = self._LISTENING.search(lines[0]) if lines else None
        if match is None:
            self.kill()
            self._stderr.seek(0)
            errors = self._stderr.read()
            self.stop()
            raise HILError(f"emulator process did not start: {lines} {errors}")
        if match.group(3):
            self.host, self.port = "", 0
            self.rtu_path, self.baudrate = match.group(3), int(match.group(4))
        else:
            self.host, self.port = match.group(1), int(match.group(2))

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(10.0)
        self.proc.stdout.close()
        self._stderr.close()
        if self._parameters_file is not None:
            Path(self._parameters_file.name).unlink(missing_ok=True)

    def reboot(self) -> None:
        """SIGUSR1: both devices restart behind the gateway, TCP connections kept."""
        self.proc.send_signal(signal.SIGUSR1)

    def kill(self) -> None:
        """SIGKILL: the server vanishes mid-conversation, as a device losing power does."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10.0)


def spawn_emulator(host: str = "127.0.0.1", port: int = 0,
                   loadcell_map: str | Path = "loadcell-float32-abcd",
                   servo_map: str | Path = "servo-default", *, noise_N: float = 0.01,
                   seed: int | None = None, plant: str = "flat-plate",
                   morphology: str = "chordwise", start_timeout_s: float = 20.0,
                   plant_parameters: Mapping[str, PlantValue] | None = None,
                   rtu: str | None = None) -> EmulatorProcess:
    """Run the emulator in a child process; returns once it listens (port 0 = any).

    `plant` is "flat-plate" (analytic, starts at once) or "fmu" (the servo and feather FMUs;
    the first start compiles them, so give it a longer `start_timeout_s`). `plant_parameters`
    are hidden settings of the plant: coefficients and, for the fmu plant, the feather's build
    options such as {"feather.wake": "plate"} (see `featherstar emulate --plant-parameters`).
    `rtu` (a tty path or "pty") serves Modbus RTU there at 115200 baud instead of TCP."""
    args = ["--host", host, "--port", str(port), "--loadcell-map", str(loadcell_map),
            "--servo-map", str(servo_map), "--noise-N", str(noise_N), "--plant", plant,
            "--morphology", morphology]
    if seed is not None:
        args += ["--seed", str(seed)]
    if rtu is not None:
        args += ["--rtu", rtu]
    return EmulatorProcess(args, start_timeout_s, plant_parameters)
