"""Shared fixtures for the hil tests: emulators that stop themselves, a plant with known
outputs, map files in tmp_path."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import pytest

from featherstar.hil.emulator import start_emulator


@dataclass
class ConstantPlant:
    """A plant that sits still, so a register round trip compares against known values."""

    angle_rad: float = 0.0
    thrust_N: float = 0.0
    setpoint_rad: float = math.nan

    def set_setpoint_rad(self, x: float) -> None:
        self.setpoint_rad = x

    def advance(self, dt_s: float) -> None:
        pass


@pytest.fixture
def constant_plant():
    return ConstantPlant


@pytest.fixture
def make_emulator():
    """start_emulator(...) whose handles are stopped at teardown."""
    handles = []

    def make(**kwargs):
        handles.append(start_emulator(**kwargs))
        return handles[-1]
    yield make
    for handle in handles:
        handle.stop()


@pytest.fixture
def emulator(make_emulator):
    return make_emulator(seed=0)


@pytest.fixture
def write_toml(tmp_path: Path):
    def write(text: str, name: str = "map.toml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path
    return write
