"""The target side of the bench and the target tests: the project's flags for the Cortex-M4F
counter (uavarm/m4), the plain reference's model numbers, and per-file object sizes."""
from __future__ import annotations

import math
from pathlib import Path

from . import cbuild

# uavarm.m4.build adds -O2 and the CPU/FPU flags itself; these are the project's own.
M4_CFLAGS = [f for f in cbuild.COMMON_FLAGS if not f.startswith("-O")]
# The firmware's Makefile links its own sources with link-time optimisation: a build of the
# whole firmware (the bench's tick) adds this.
FIRMWARE_LTO = ["-flto=auto"]


def reference_defines(m) -> list[str]:
    """-D flags giving bench/reference.c the model's numbers (it writes none itself)."""
    from ..model import filters
    f = lambda v: f"{float(v)!r}f"
    arr = lambda vs: "{" + ",".join(f(v) for v in vs) + "}"
    from ..model import attitude, servo
    sections = filters.sensor_filters(m)
    accel, gyro = sections["accel"][0], sections["gyro"][0]
    mount = "{" + ",".join(arr(float(v) for v in row) for row in attitude.mounting(m).tolist()) + "}"
    return [
        f"-DREF_L1={f(m.L1)}", f"-DREF_L2={f(m.L2)}", f"-DREF_L3={f(m.L3)}",
        f"-DREF_QMIN={arr(l.min_rad for l in m.limits)}",
        f"-DREF_QMAX={arr(l.max_rad for l in m.limits)}",
        f"-DREF_BODY_Z={f(m.body_z)}",
        f"-DREF_NLEGS={len(m.leg_angles)}",
        f"-DREF_LEGS={arr(math.radians(a) for a in m.leg_angles)}",
        f"-DREF_LEG_HALF_WIDTH={f(math.radians(m.leg_half_width))}",
        f"-DREF_LEG_DISTANCE={f(m.leg_distance)}",
        f"-DREF_ACCEL_B={arr(accel.b)}", f"-DREF_ACCEL_A={arr(accel.a)}",
        f"-DREF_GYRO_B={arr(gyro.b)}", f"-DREF_GYRO_A={arr(gyro.a)}",
        f"-DREF_MOUNT={mount}",
        f"-DREF_ACCEL_SCALE={f(m.accel_range_g / 32768)}",
        f"-DREF_GYRO_SCALE={f(math.radians(m.gyro_range_dps) / 32768)}",
        f"-DREF_DT={f(1 / m.sample_rate)}", f"-DREF_W={f(m.complementary_gyro_weight)}",
        f"-DREF_SERVO_ZERO={arr(s.zero for s in m.servos)}",
        f"-DREF_SERVO_DIR={arr(s.direction for s in m.servos)}",
        f"-DREF_UNITS_PER_RAD={f(servo.units_per_rad(m))}",
    ]


def cross_compile(sources, include_dirs, out_dir: Path) -> dict[str, tuple[int, int, int]]:
    """Compile each source for the Cortex-M4F with the project's warning flags (errors raise
    cbuild.CBuildError); returns {file name: (text, data, bss) bytes}."""
    import subprocess
    out_dir.mkdir(parents=True, exist_ok=True)
    sizes = {}
    for src in map(Path, sources):
        obj = out_dir / (src.stem + ".o")
        cmd = ["arm-none-eabi-gcc", *cbuild.TARGET_FLAGS, "-ffunction-sections", "-fdata-sections",
               *[f"-I{d}" for d in include_dirs], "-c", str(src), "-o", str(obj)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise cbuild.CBuildError(f"{' '.join(cmd)}\n{proc.stderr}")
        line = subprocess.run(["arm-none-eabi-size", str(obj)], capture_output=True, text=True,
                              check=True).stdout.splitlines()[1].split()
        sizes[src.name] = (int(line[0]), int(line[1]), int(line[2]))
    return sizes
