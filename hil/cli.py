"""`featherstar emulate`: the bench emulator on the command line.

`featherstar.app:main` calls `register(subparsers)` and dispatches `args.func(args)`; `python -m featherstar.hil`
offers the same commands without the rest of featherstar.
"""
from __future__ import annotations

import argparse
import asyncio
import ipaddress
import logging
import errno
import math
import os
import signal
import socket
import sys
import termios

from .emulator import IDLE_TIMEOUT_S, LOADCELL_UNIT, SERVO_UNIT, Emulator, serve, serve_rtu
from .errors import HILError
from .plant import feather_build_options, flat_plate_plant, fmu_plant_form, read_plant_parameters
from .registers import available_maps, load_loadcell_map, load_servo_map

_DESCRIPTION = f"""\
Serve a Modbus TCP emulator of the feather test bench: a load-cell transmitter (unit
{LOADCELL_UNIT}) and a servo controller (unit {SERVO_UNIT}) behind register maps, with a plant
(the servo and feather FMUs, or an analytic flat plate) advanced in real time at every request.
The FMU plant starts at rest (feather in its buoyant equilibrium); each load-cell reading is the
mean force since the previous one, at most the last 20 ms, as a sigma-delta converter reports.

Point the hardware blocks at it:
  modbus-tcp://HOST:PORT?unit={LOADCELL_UNIT}   (LoadCell)
  modbus-tcp://HOST:PORT?unit={SERVO_UNIT}   (Servo)

With --rtu it serves Modbus RTU on a serial line instead (same units; --rtu pty makes a
pseudo-terminal and prints the path to open):
  modbus-rtu:///dev/ttyUSB0?baudrate=115200&unit={LOADCELL_UNIT}

Shipped register maps: {', '.join(available_maps())}; a path to a TOML map works too.
`kill -USR1 PID` restarts both devices behind the "gateway" (new boot ids, tare and enable
lost, TCP connections kept). Stop with Ctrl-C."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the `emulate` command to a featherstar-style subparser set."""
    p = subparsers.add_parser(
        "emulate", help="serve a Modbus emulator of the test bench (load cell + servo)",
        description=_DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--host", default="127.0.0.1",
                   help="interface to bind (default: %(default)s). Modbus has no "
                        "authentication: anything but loopback needs --allow-remote")
    p.add_argument("--allow-remote", action="store_true",
                   help="allow binding a non-loopback interface (anyone who reaches it can move "
                        "the emulated servo); a warning is printed")
    p.add_argument("--idle-timeout-s", type=float, default=IDLE_TIMEOUT_S, metavar="S",
                   help="close a connection silent for this long, e.g. a client that vanished "
                        "without closing it (default: %(default)s)")
    p.add_argument("--port", type=int, default=5020,
                   help="TCP port; 0 picks a free one (default: %(default)s). The bound port is "
                        "printed on the first line of output")
    p.add_argument("--rtu", default=None, metavar="PATH",
                   help="serve Modbus RTU on this serial line (a tty, or the slave end of a pty) "
                        "instead of TCP; 'pty' creates a pseudo-terminal pair and prints its path")
    p.add_argument("--baudrate", type=int, default=115200,
                   help="serial speed of --rtu, 8N1 (default: %(default)s)")
    p.add_argument("--loadcell-map", default="loadcell-float32-abcd", metavar="NAME",
                   help="load-cell register map, shipped name or TOML path "
                        "(default: %(default)s)")
    p.add_argument("--servo-map", default="servo-default", metavar="NAME",
                   help="servo register map, shipped name or TOML path (default: %(default)s)")
    p.add_argument("--noise-N", type=float, default=0.01, metavar="SD",
                   help="standard deviation of the Gaussian load-cell noise, N "
                        "(default: %(default)s)")
    p.add_argument("--seed", type=int, default=None, metavar="S",
                   help="seed of the noise generator (default: random)")
    p.add_argument("--plant", choices=("fmu", "flat-plate"), default="fmu",
                   help="what moves behind the registers: the project's servo and feather FMUs "
                        "(default; the testbed scene's physics) or an analytic rigid flat plate")
    p.add_argument("--morphology", choices=("plain", "chordwise", "spanwise"), default="chordwise",
                   help="feather of the fmu plant (default: %(default)s)")
    p.add_argument("--plant-parameters", default=None, metavar="FILE",
                   help="JSON object of plant settings that differ from the defaults, e.g. "
                        '{"feather.wake": "plate", "feather.wake_drag_coeff": 1.4} (fmu plant: feather.NAME, '
                        "servo.NAME, coefficients and the feather's build options "
                        f"{', '.join(feather_build_options())}, i.e. its model form; flat plate: c_n, c_a, ...). "
                        "They are hidden: not printed, not served over Modbus, so a client must measure them "
                        "(featherstar calibrate). Names and values are checked before the FMUs build")
    p.add_argument("--plant-set", action="append", default=[], metavar="NAME=VALUE",
                   help="one plant setting, e.g. feather.wake=plate or feather.drag_coeff=1.6 (repeatable; "
                        "wins over --plant-parameters; visible in the process list, unlike the file)")
    p.set_defaults(func=emulate)


def emulate(args: argparse.Namespace) -> int:
    """Run the emulator until interrupted; returns the exit status."""
    if not 0 <= args.port <= 65535:
        raise HILError(f"--port {args.port}: valid values are 0..65535")
    if not (math.isfinite(args.noise_N) and args.noise_N >= 0):
        raise HILError(f"--noise-N {args.noise_N}: must be a finite number >= 0 (N)")
    if not (math.isfinite(args.idle_timeout_s) and args.idle_timeout_s > 0):
        raise HILError(f"--idle-timeout-s {args.idle_timeout_s}: must be a positive number")
    if not is_loopback(args.host):
        if not args.allow_remote:
            raise HILError(f"--host {args.host}: not a loopback address; Modbus has no "
                           "authentication, so binding it needs --allow-remote")
        print(f"featherstar emulate: WARNING: serving on {args.host}: anyone who can reach it "
              "can read the load cell and move the emulated servo", file=sys.stderr)
    # Maps and the port first: a typo or a busy port must not wait for the FMUs to build.
    loadcell_map, servo_map = load_loadcell_map(args.loadcell_map), load_servo_map(args.servo_map)
    if args.rtu is None:
        check_port_free(args.host, args.port)
    elif not hasattr(termios, f"B{args.baudrate}"):
        raise HILError(f"--baudrate {args.baudrate}: not a standard serial speed")
    elif args.rtu != "pty":
        check_serial_line(args.rtu)
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s: %(message)s")
    hidden = read_plant_parameters(args.plant_parameters, args.plant_set)
    if args.plant == "fmu":
        from .fmu_plant import FmuPlant, plant_plan  # builds FMUs: only when asked for

        form = fmu_plant_form(hidden)
        plant_plan(args.morphology, form)   # every name and value checked before the FMUs build
        plant = FmuPlant(args.morphology, feather_parameters=form.feather, servo_parameters=form.servo,
                         feather_options=form.feather_options)
    else:
        plant = flat_plate_plant(hidden)
    emulator = Emulator(loadcell_map, servo_map, plant, noise_N=args.noise_N, seed=args.seed)

    def ready(where: int | str) -> None:
        url = f"modbus-tcp://{args.host}:{where}" if args.rtu is None \
            else f"modbus-rtu://{where}?baudrate={args.baudrate}"
        print(f"featherstar emulate: listening on {url} "
              f"(load cell unit {LOADCELL_UNIT}: {emulator.loadcell_map.name}, "
              f"servo unit {SERVO_UNIT}: {emulator.servo_map.name})"
              + (f"; {len(hidden)} hidden plant setting(s) differ from the defaults" if hidden else ""),
              flush=True)

    async def run() -> None:
        # kill -USR1: both devices restart behind the gateway, connections kept (fault tests).
        asyncio.get_running_loop().add_signal_handler(
            signal.SIGUSR1, lambda: [emulator.reboot(d) for d in ("loadcell", "servo")])
        if args.rtu is not None:
            await serve_rtu(emulator, args.rtu, args.baudrate, asyncio.Event(), ready)
        else:
            await serve(emulator, args.host, args.port, asyncio.Event(), ready,
                        idle_timeout_s=args.idle_timeout_s)

    try:
        asyncio.run(run())
    except KeyboardInterrupt:
        pass
    except OSError as exc:   # the port was taken between the check and the bind
        where = f"--rtu {args.rtu}" if args.rtu is not None \
            else f"--host {args.host} --port {args.port}"
        raise HILError(f"{where}: cannot listen there ({exc.strerror or exc})") from None
    return 0


def check_port_free(host: str, port: int) -> None:
    """Refuse a port already in use (or a host that is not ours) before any work starts."""
    try:
        with socket.create_server((host, port)):
            pass
    except OSError as exc:
        hint = "; another emulator running? pick another --port or 0" \
            if exc.errno == errno.EADDRINUSE else ""
        raise HILError(f"--host {host} --port {port}: cannot listen there "
                       f"({exc.strerror or exc}){hint}") from None


def check_serial_line(path: str) -> None:
    """Refuse a path that is not an openable tty before any work starts (the FMUs build)."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as exc:
        raise HILError(f"--rtu {path}: cannot open ({exc.strerror}); a serial device such as "
                       "/dev/ttyUSB0, or 'pty'") from None
    try:
        if not os.isatty(fd):
            raise HILError(f"--rtu {path}: not a serial line (a tty such as /dev/ttyUSB0, or 'pty')")
    finally:
        os.close(fd)


def is_loopback(host: str) -> bool:
    """Whether binding `host` keeps the emulator on this machine (a name may resolve anywhere)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False   # a host name: it may resolve to anything


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m featherstar.hil",
                                     description="featherstar hardware-in-the-loop tools")
    subparsers = parser.add_subparsers(dest="command", required=True)
    register(subparsers)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except HILError as exc:
        parser.exit(2, f"error: {exc}\n")
