"""The whole firmware application (firmware_stm32/App + generated/) built for the host with
the host port (uavarm/build/csrc), via cffi: the code the STM32 runs, driven from Python."""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from . import cbuild, generated

FIRMWARE = cbuild.ROOT / "firmware_stm32"
APP = FIRMWARE / "App"
SOURCES_MK = FIRMWARE / "sources.mk"
HOST_PORT = Path(__file__).resolve().parent / "csrc"
# cffi sees the headers in this order: every type before its first use.
APP_HEADERS = ("llcp.h", "dxl_protocol.h", "dxl_protocol2.h", "port.h", "servo_bus.h", "imu_mpu6050.h",
               "stabiliser.h", "servo_track.h", "motion.h", "app.h")


def source_lists(path: Path = SOURCES_MK) -> dict[str, list[str]]:
    """The variables of firmware_stm32/sources.mk, the firmware's one source list: plain
    `NAME = a b \\` lines (continued with backslashes) and $(NAME) references."""
    text = re.sub(r"\\\n", " ", path.read_text())
    lists: dict[str, list[str]] = {}
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        name, sep, value = line.partition("=")
        if not sep or not re.fullmatch(r"[A-Z_]+", name.strip()):
            raise ValueError(f"{path}: not a plain assignment: {line!r}")
        words = []
        for word in value.split():
            ref = re.fullmatch(r"\$\(([A-Z_]+)\)", word)
            words += lists[ref.group(1)] if ref else [word]
        lists[name.strip()] = words
    return lists


def listed(name: str) -> list[Path]:
    """The files of one sources.mk list, as absolute paths."""
    return [(FIRMWARE / rel).resolve() for rel in source_lists()[name]]


def app_sources(gen_dir: Path = generated.GENERATED) -> list[Path]:
    """Every C source of the firmware application that needs no HAL, generated code included
    (sources.mk's APP_SOURCES and GENERATED_SOURCES; the latter taken from gen_dir)."""
    gen = [Path(gen_dir) / p.name for p in listed("GENERATED_SOURCES")]
    return listed("APP_SOURCES") + gen


def host_sources() -> list[Path]:
    """The host's side of the port (in place of the board's HAL) and its main loop."""
    return [HOST_PORT / "host_port.c", HOST_PORT / "host_loop.c"]


def host_headers() -> list[Path]:
    return [HOST_PORT / "host_port.h", HOST_PORT / "host_loop.h"]


def load(gen_dir: Path = generated.GENERATED):
    """(ffi, lib) of the application, the generated code and the host port."""
    headers = generated.headers(gen_dir) + [APP / "Inc" / h for h in APP_HEADERS] + host_headers()
    return cbuild.load("firmware", app_sources(gen_dir) + host_sources(), headers,
                       include_dirs=[gen_dir, APP / "Inc", HOST_PORT])


@lru_cache(maxsize=None)
def default():
    return load()
