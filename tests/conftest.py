import os
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).parent))   # the oracles module


@pytest.fixture(scope="session")
def model():
    from uavarm.model import config
    return config.load()


@pytest.fixture(scope="session")
def gen():
    """(ffi, lib) of the committed generated C, built with the strict flags."""
    from uavarm import generated
    return generated.default()


def require_arm_toolchain():
    """The target checks may only be skipped on a developer machine, never in CI."""
    if shutil.which("arm-none-eabi-gcc") is None:
        if os.environ.get("CI"):
            pytest.fail("arm-none-eabi-gcc missing in CI: .ci/run must install gcc-arm-none-eabi")
        pytest.skip("arm-none-eabi-gcc not installed (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi)")
