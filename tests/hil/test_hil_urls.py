"""Device URLs: what parses, and what each malformed URL is told."""
from __future__ import annotations

import importlib.util

import pytest

from featherstar.hil.blocks import LoadCell
from featherstar.hil.errors import HILConfigError
from featherstar.hil.link import parse_url


@pytest.mark.parametrize("url, expected", [
    ("modbus-tcp://127.0.0.1:5020", ("modbus-tcp", "127.0.0.1", 5020, 1)),
    ("modbus-tcp://bench.local?unit=7", ("modbus-tcp", "bench.local", 502, 7)),
    ("modbus-tcp://[::1]:1502?unit=0", ("modbus-tcp", "::1", 1502, 0)),
])
def test_tcp_urls_parse(url, expected):
    u = parse_url(url)
    assert (u.scheme, u.host, u.port, u.unit) == expected


def test_rtu_url_parses_with_line_settings():
    u = parse_url("modbus-rtu:///dev/ttyUSB0?baudrate=115200&unit=3&parity=E&stopbits=2")
    assert (u.serial_port, u.baudrate, u.unit, u.parity, u.stopbits, u.bytesize) == \
        ("/dev/ttyUSB0", 115200, 3, "E", 2, 8)


@pytest.mark.parametrize("url, expected", [
    ("http://127.0.0.1:502", r"unknown scheme 'http'; valid schemes: modbus-tcp, modbus-rtu"),
    ("127.0.0.1:502", r"expected modbus-tcp://HOST:PORT"),
    ("modbus-tcp://:502", r"missing host"),
    ("modbus-tcp://host:99999", r"port must be an integer in 1..65535"),
    ("modbus-tcp://host:abc", r"port must be an integer"),
    ("modbus-tcp://host:502?unit=x", r"unit='x' is not an integer"),
    ("modbus-tcp://host:502?unit=300", r"unit=300; valid values: 0..255"),
    ("modbus-tcp://host:502?baudrate=9600", r"unknown option 'baudrate'; valid options: unit"),
    ("modbus-tcp://host:502?unit=1&unit=2", r"option 'unit' given 2 times"),
    ("modbus-tcp://host:502/path", r"unexpected path"),
    ("modbus-rtu://dev/ttyUSB0", r"three slashes, no host"),
    ("modbus-rtu:///dev/ttyUSB0?parity=X", r"parity='X'; valid values: N, E, O"),
    ("modbus-rtu:///dev/ttyUSB0?unit=0", r"unit=0; valid values: 1..247"),
    ("modbus-rtu:///dev/ttyUSB0?speed=9600", r"unknown option 'speed'"),
])
def test_bad_urls_get_clear_errors(url, expected):
    with pytest.raises(HILConfigError, match=expected):
        parse_url(url)


def test_rtu_blocks_need_pyserial_and_say_so():
    url = "modbus-rtu:///dev/ttyUSB0?baudrate=115200&unit=1"
    if importlib.util.find_spec("serial") is None:
        with pytest.raises(HILConfigError, match="modbus-rtu needs pyserial"):
            LoadCell("cell", url)
    else:
        assert LoadCell("cell", url).url.baudrate == 115200     # no I/O before start()
