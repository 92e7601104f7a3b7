"""The model's numbers in the STM32CubeIDE project (firmware_stm32/): the user constants of
manipulator.ioc and the #defines CubeMX writes from them into Core/Inc/main.h.

The .ioc names the constants where CubeMX uses them (USART1.BaudRate=SERVO_BAUD,
TIM3.Period=TICK_PERIOD), so "Generate Code" writes the model's values into the
peripherals' set-up. `make codegen` keeps both files as CubeMX would write them for the
current model, so the command-line build needs no CubeMX run after a model change.
Only those lines change; everything else in the two files is CubeMX's and the user's.
"""
from __future__ import annotations

import re
from pathlib import Path

from ..model import config

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "firmware_stm32"
IOC = "manipulator.ioc"
MAIN_H = "Core/Inc/main.h"
_PRIVATE_DEFINES = "/* Private defines -----------------------------------------------------------*/\n"


def user_constants(m: config.Model) -> dict[str, str]:
    """The model's user constants: the servo baud, and TIM3's period for one tick of its
    1 MHz count (the timer prescaler takes the .ioc's 96 MHz timer clock to 1 MHz)."""
    tick_us = round(1e6 / m.sample_rate)
    return {"SERVO_BAUD": str(m.servo_baud), "TICK_PERIOD": str(tick_us - 1)}


def _constants_of(ioc: str) -> dict[str, str]:
    line = re.search(r"^Mcu\.UserConstants=(.*)$", ioc, re.M).group(1)
    return dict(pair.split(",", 1) for pair in line.split(";") if pair)


def _with_constants(ioc: str, ours: dict[str, str]) -> tuple[str, dict[str, str]]:
    """The .ioc with our constants set (others kept, in CubeMX's NAME,VALUE;... form)."""
    constants = _constants_of(ioc) | ours
    line = "Mcu.UserConstants=" + ";".join(f"{k},{v}" for k, v in constants.items())
    return re.sub(r"^Mcu\.UserConstants=.*$", lambda _: line, ioc, count=1, flags=re.M), constants


def _with_defines(main_h: str, constants: dict[str, str]) -> str:
    """main.h with every user constant as CubeMX writes it: first in its private defines."""
    head, sep, rest = main_h.partition(_PRIVATE_DEFINES)
    if not sep:
        raise ValueError(f"{MAIN_H}: no CubeMX private defines section")
    names = "|".join(map(re.escape, constants))
    rest = re.sub(rf"\A(?:#define (?:{names}) .*\n)+", "", rest) if constants else rest
    return head + sep + "".join(f"#define {k} {v}\n" for k, v in constants.items()) + rest


def render(model_path: Path, board: Path = BOARD) -> dict[str, str]:
    """{path relative to board: text} of the two files for the model."""
    ioc, constants = _with_constants((board / IOC).read_text(), user_constants(config.load(model_path)))
    return {IOC: ioc, MAIN_H: _with_defines((board / MAIN_H).read_text(), constants)}


def write(files: dict[str, str], board: Path) -> list[str]:
    changed = []
    for name, text in files.items():
        path = board / name
        if path.read_text() != text:
            path.write_text(text)
            changed.append(name)
    return changed
