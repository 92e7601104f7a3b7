"""The whole firmware application (firmware_stm32/App + generated/) built for the host with
the host port (uavarm/csrc), via cffi: the code the STM32 runs, driven from Python."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from . import cbuild, generated

APP = cbuild.ROOT / "firmware_stm32" / "App"
HOST_PORT = Path(__file__).resolve().parent / "csrc"
# cffi sees the headers in this order: every type before its first use.
APP_HEADERS = ("llcp.h", "dxl_protocol.h", "port.h", "servo_bus.h", "imu_mpu6050.h",
               "stabiliser.h", "servo_track.h", "app.h")


def app_sources(gen_dir: Path = generated.GENERATED) -> list[Path]:
    """Every C source of the firmware application that needs no HAL, generated code included."""
    return sorted((APP / "Src").glob("*.c")) + generated.sources(gen_dir)


def load(gen_dir: Path = generated.GENERATED):
    """(ffi, lib) of the application, the generated code and the host port."""
    headers = generated.headers(gen_dir) + [APP / "Inc" / h for h in APP_HEADERS] + [HOST_PORT / "host_port.h"]
    return cbuild.load("firmware", app_sources(gen_dir) + [HOST_PORT / "host_port.c"], headers,
                       include_dirs=[gen_dir, APP / "Inc", HOST_PORT])


@lru_cache(maxsize=None)
def default():
    return load()
