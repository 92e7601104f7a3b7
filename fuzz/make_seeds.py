"""Writes the seed corpora of the fuzz harnesses into fuzz/corpus/<harness>/ (committed).

    .venv/bin/python fuzz/make_seeds.py

Every seed is a small valid input built with the project's own Python codecs: LLCP frames
from uavarm.link.llcp / uavarm.link.messages, status packets answered by the AX-12A and XM430-W350 simulators
(uavarm.sim.ax12_sim, uavarm.sim.xseries_sim), command sessions for the whole application in the op encoding that
fuzz/app_link.c documents, and the model file. The folders are rebuilt; regress-* inputs found by
the fuzzers and committed by hand are kept.
"""
from __future__ import annotations

import hashlib
import math
import shutil
import struct
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from uavarm.link import llcp, messages  # noqa: E402
from uavarm.model import config  # noqa: E402
from uavarm.sim import ax12_sim, xseries_sim

CORPUS = Path(__file__).resolve().parent / "corpus"
MAX_LEN = {"llcp_rx": 1024, "dxl_parser": 1024, "dxl2_parser": 2048, "app_link": 1024, "app_link_x": 1024,
           "model_loader": 16384}   # fuzz/run.py


def frame(name: str, **fields) -> bytes:
    return llcp.encode(messages.encode(name, **fields))


def heartbeat(**given) -> bytes:
    """A heartbeat payload: the given fields, every other one 0."""
    fields = {name: 0 for name, _ in messages.BY_NAME["heartbeat"].fields}
    fields.update(given)
    return messages.encode("heartbeat", **fields)


# ------------------------------------------------------------------ llcp_rx

def llcp_seeds() -> list[bytes]:
    """config byte (bit 0: 50 ms gap, bit 1: length check), then characters; 0xFF d
    advances the clock by d ms (see fuzz/llcp_rx.c)."""
    enable = frame("enable", on=1)
    setp = frame("set_position", x=70.0, y=-20.0, z=-95.0)
    att = frame("drone_attitude", seq=7, stamp_us=123456, roll=0.1, pitch=-0.05)
    hb = llcp.encode(heartbeat(seq=3, uptime_ms=1500, enabled=1, faults=8, set_x=1.0, set_y=2.0, set_z=-3.0,
                               q2=1.0, q3=-1.9, link_frames_ok=5, link_errors=1), llcp.TX_MAX_PAYLOAD)
    longest = llcp.encode(bytes(range(255)))
    bad_sum = bytearray(enable)
    bad_sum[-1] = ord("0") if bad_sum[-1] != ord("0") else ord("1")
    return [
        b"\x03" + enable + b"\n" + setp + b"\n" + att,
        b"\x01" + setp[:9] + b"\xff\x3c" + setp,            # idle gap drops the partial frame
        b"\x00" + hb + longest,
        b"\x02" + bytes(bad_sum) + b"b00" + enable.lower() + enable,
        b"\x03" + enable[:5] + b"\xff\xf0" + enable[5:] + b"\xff\xff" + att,   # clock jumps
    ]


# ------------------------------------------------------------------ dxl_parser

def status_replies() -> list[bytes]:
    """Status packets of a simulated AX-12A: the per-tick status read, the configuration
    read-back, a PING and a write with Status Return Level 2, one with an error bit."""
    servo = ax12_sim.AX12(2, position=700.0)
    out = []
    for inst, params in ((ax12_sim.INST_READ, bytes([36, 8])), (ax12_sim.INST_READ, bytes([5, 31])),
                         (ax12_sim.INST_PING, b""), (ax12_sim.INST_WRITE, bytes([25, 1])),
                         (ax12_sim.INST_WRITE, bytes([30, 0xFF, 0x0F]))):    # goal 4095: range error
        reply = None
        for t, byte in enumerate(ax12_sim.packet(servo.id, inst, params)):
            reply = servo.receive(byte, t * 1e-5) or reply
        assert reply is not None, (inst, params)
        out.append(reply.data)
    return out


def dxl_seeds() -> list[bytes]:
    """size byte (small window 6 + b % 44), then received bytes; "RST!" resets."""
    read, verify, ping, write, err = status_replies()
    echo = ax12_sim.packet(2, ax12_sim.INST_READ, bytes([36, 8]))
    return [
        b"\x08" + read,
        b"\x2a" + echo + read + b"RST!" + verify,
        b"\x00" + b"\xff\xff\xff" + read[:7] + ping + write,
        b"\x10" + read[:-1] + bytes([read[-1] ^ 1]) + err,
        b"\x2b" + b"\x00\x55" + verify[:20] + verify + read,
    ]


# ------------------------------------------------------------------ dxl2_parser

def x_instruction(id_: int, inst: int, params: bytes) -> bytes:
    """A Protocol 2.0 instruction packet (the e-manual's layout, stuffed, with its CRC)."""
    body = xseries_sim.stuffed(bytes([inst]) + params)
    head = xseries_sim.HEADER + bytes([id_]) + (len(body) + 2).to_bytes(2, "little")
    return head + body + xseries_sim.crc16(head + body).to_bytes(2, "little")


def x_status_replies() -> list[bytes]:
    """Status packets of a simulated XM430-W350: the per-tick status read (Torque Enable ..
    Present Temperature), the configuration read-back, a PING, a WRITE's answer, one with
    the Data Limit error; and one whose parameters the servo had to stuff."""
    servo = xseries_sim.XServo(xseries_sim.XM430_W350, 2, position=3000.0)
    out = []
    for inst, params in ((xseries_sim.INST_READ, bytes([64, 0, 83, 0])), (xseries_sim.INST_READ, bytes([9, 0, 138, 0])),
                         (xseries_sim.INST_PING, b""), (xseries_sim.INST_WRITE, bytes([65, 0, 1])),
                         (xseries_sim.INST_WRITE, bytes([52, 0, 0x00, 0x10, 0, 0]))):   # 4096: range error
        reply = None
        for t, byte in enumerate(x_instruction(servo.id, inst, params)):
            reply = servo.receive(byte, t * 1e-6) or reply
        assert reply is not None, (inst, params)
        out.append(reply.data)
    return out + [xseries_sim.status_packet(2, 0, bytes([0xFF, 0xFF, 0xFD, 0x01, 0xFF, 0xFF, 0xFD]))]


def dxl2_seeds() -> list[bytes]:
    """size byte (small window 11 + b % 64), then received bytes; "RST!" resets."""
    read, verify, ping, write, err, stuffed = x_status_replies()
    echo = x_instruction(2, xseries_sim.INST_READ, bytes([64, 0, 83, 0]))
    return [
        b"\x08" + read,
        b"\x3f" + echo + read + b"RST!" + verify,
        b"\x00" + b"\xff\xff\xfd\xff" + read[:9] + ping + write,
        b"\x10" + read[:-1] + bytes([read[-1] ^ 1]) + err,
        b"\x05" + stuffed + stuffed[:12] + stuffed[13:],   # then again, its added FD lost
    ]


# ------------------------------------------------------------------ app_link

(OP_ADVANCE, OP_FRAME, OP_LINK, OP_SERVO, OP_SAMPLE, OP_IMUREG, OP_FLAGS, OP_SERVOREG, OP_TICK, OP_CORRUPT,
 OP_ERROR) = range(11)
F_IMU_ABSENT, F_RESPOND, F_ECHO, F_LINK_FULL, F_CORRUPT, F_IMU_READ_FAIL, F_IMU_WRITE_FAIL, F_IMU_WRITE_LOST = (
    1, 2, 4, 8, 16, 32, 64, 128)
STEPS = {50: 0, 250: 1, 1000: 2, 2500: 3, 10000: 4, 100000: 5, 1000000: 6, 0x40000000: 7}


class Session:
    """An app_link input: header, then operations (fuzz/app_link.c)."""

    def __init__(self, start_us: int = 0, flags: int = F_RESPOND):
        self.data = bytearray(struct.pack("<I", start_us & 0xFFFFFFFF) + bytes([flags]))

    def run(self, seconds: float, step_us: int = 250) -> "Session":
        polls = max(1, round(seconds * 1e6 / step_us))
        while polls > 0:
            n = min(polls, 32)
            self.data += bytes([OP_ADVANCE, STEPS[step_us] | (n - 1) << 3])
            polls -= n
        return self

    def send(self, name: str, **fields) -> "Session":
        if name in ("enable", "engage"):
            self.data += bytes([OP_FRAME, 0 if name == "enable" else 1, fields["on"]])
        elif name == "set_position":
            self.data += bytes([OP_FRAME, 2]) + struct.pack("<3f", fields["x"], fields["y"], fields["z"])
        elif name == "drone_attitude":
            self.data += bytes([OP_FRAME, 4]) + messages.encode(name, **fields)[1:]
        else:
            raise ValueError(name)
        return self

    def raw_frame(self, payload: bytes) -> "Session":
        self.data += bytes([OP_FRAME, 5, len(payload) - 1]) + payload
        return self

    def link(self, data: bytes) -> "Session":
        self.data += bytes([OP_LINK, len(data)]) + data
        return self

    def servo_bytes(self, data: bytes) -> "Session":
        self.data += bytes([OP_SERVO, len(data)]) + data
        return self

    def tilt(self, roll: float, pitch: float, gyro=(0, 0, 0)) -> "Session":
        """An IMU sample at rest tilted by roll/pitch (rad), 4 g range: 8192 LSB/g."""
        up = (-math.sin(pitch), math.sin(roll) * math.cos(pitch), math.cos(roll) * math.cos(pitch))
        accel = [round(8192 * a) for a in up]
        self.data += bytes([OP_SAMPLE]) + struct.pack(">3hh3h", *accel, 0, *gyro)
        return self

    def flags(self, f: int) -> "Session":
        self.data += bytes([OP_FLAGS, f])
        return self

    def corrupt(self, at: int, xor: int) -> "Session":
        self.data += bytes([OP_CORRUPT, at, xor])
        return self

    def servo_reg(self, servo: int, addr: int, value: int) -> "Session":
        self.data += bytes([OP_SERVOREG, servo, addr, value])
        return self

    def servo_error(self, error: int) -> "Session":
        self.data += bytes([OP_ERROR, error])
        return self

    def tick(self) -> "Session":
        self.data += bytes([OP_TICK])
        return self

    def imu_reg(self, reg: int, value: int) -> "Session":
        self.data += bytes([OP_IMUREG, reg, value])
        return self


# The simulated servos' registers the seeds set (fuzz/app_link.c; the e-manuals' control tables)
AX_REGS = {"present": 36, "torque_enable": 24, "torque_limit": 34}
X_REGS = {"present": 132, "torque_enable": 64, "indirect_address_2": 170}


def app_seeds(regs: dict[str, int] = AX_REGS) -> list[bytes]:
    def started(**kw) -> Session:
        # servo boot, configuration, then the estimator's settling (engage is refused before)
        return Session(**kw).send("enable", on=1).run(0.1, 100000).run(0.08).run(0.5, 2500)

    engaged = (started().send("set_position", x=70.0, y=-20.0, z=-95.0).send("engage", on=1)
               .run(0.05).tilt(0.2, -0.1, gyro=(30, -20, 5)).run(0.05).send("enable", on=0).run(0.01))
    wrap = (started(start_us=0xFFFFFFFF - 150_000).send("engage", on=1)
            .send("set_position", x=40.0, y=45.0, z=-120.0).run(0.1)
            .send("drone_attitude", seq=1, stamp_us=5, roll=0.0, pitch=0.0)
            .raw_frame(messages.encode("drone_velocity", seq=1, stamp_us=5, vx=0.5, vy=0.0, vz=0.0))
            .run(0.02, 10000)
            .raw_frame(messages.encode("drone_velocity", seq=2, stamp_us=20_005, vx=0.6, vy=-0.1, vz=0.0))
            .run(1.2, 10000))
    faults = (started().send("engage", on=1).flags(F_RESPOND | F_ECHO | F_CORRUPT).corrupt(7, 0x10)
              .run(0.05).corrupt(9, 0).servo_bytes(b"\xff\xff\x01\x02\x00\xfc\xff").run(0.03)
              .flags(F_RESPOND | F_IMU_READ_FAIL | F_LINK_FULL).run(0.6, 2500)
              .flags(F_RESPOND).servo_reg(1, regs["present"], 0xFF).servo_error(0x20).run(0.05).servo_error(0)
              .tick().tick().run(0.02))
    refused = (Session(flags=F_RESPOND).send("engage", on=1)
               .send("set_position", x=math.nan, y=0.0, z=-100.0)
               .send("set_position", x=500.0, y=0.0, z=0.0)
               .raw_frame(b"\x10\x01\x02").link(b"b0210xx" + frame("enable", on=1)[:6])
               .raw_frame(heartbeat(enabled=1))                              # an echo
               .run(0.2, 2500).flags(F_IMU_READ_FAIL).run(0.05, 10000)
               .flags(0).imu_reg(117, 0x70).run(1.1, 10000)             # not an MPU-6050
               .flags(F_IMU_WRITE_LOST).imu_reg(117, 0x68).run(1.1, 10000)   # settings do not stick
               .flags(F_IMU_WRITE_FAIL).run(1.1, 10000).flags(0).run(1.1, 10000))
    no_servos = Session(flags=F_IMU_ABSENT).send("enable", on=1).run(0.3, 2500).run(0.1, 1000)
    # the IMU resets asleep (no DATA_RDY): park; set up again after 1 s; engage; a sample at
    # full scale (MPU-6050 register map: int16 range) is skipped and flagged
    imu = (started().send("set_position", x=70.0, y=-20.0, z=-95.0).send("engage", on=1).run(0.05, 10000)
           .imu_reg(107, 0x40).run(1.2, 10000).send("engage", on=1).run(0.05, 10000))
    imu.data += bytes([OP_SAMPLE]) + struct.pack(">3hh3h", 32767, 0, 8192, 0, 0, -32768, 0)
    imu.tick()
    # servo 1's shaft stays at 768 units (AX-12A; 3072, X-series) whatever it is sent (stuck):
    # its status reads, between each tick's SYNC_WRITE and the next, show it not following
    stuck = started().send("engage", on=1).run(0.02, 10000)
    high = 0x03 if regs is AX_REGS else 0x0C
    for _ in range(33):
        stuck.run(0.01, 10000).servo_reg(0, regs["present"], 0x00).servo_reg(0, regs["present"] + 1, high)
        stuck.run(0.005, 2500)
    # servo 2 browns out: its RAM back at power-up values (torque off; the AX-12A's Torque Limit
    # = Max Torque; the X-series' status map lost, its Status Return Level's slot reading itself)
    stuck.servo_reg(1, regs["torque_enable"], 0)
    if regs is AX_REGS:
        stuck.servo_reg(1, regs["torque_limit"], 0xFF).servo_reg(1, regs["torque_limit"] + 1, 0x03)
    else:
        stuck.servo_reg(1, regs["indirect_address_2"], 225)
    stuck.run(0.05, 2500)
    return [engaged.data, wrap.data, faults.data, refused.data, no_servos.data, imu.data, stuck.data]


# ------------------------------------------------------------------ model_loader

def model_seeds() -> list[bytes]:
    text = config.DEFAULT_MODEL.read_text()
    bad_park = text.replace("q = [0.0, 60.0, -110.0]", "q = [0.0, 0.0, 0.0]")
    assert bad_park != text
    # 0x01 first: the rest drives edits of the default model (fuzz/model_loader.py)
    edits = [b"\x01" + bytes(range(1, 64, 3)), b"\x01" + b"\x02" * 40, b"\x01" + b"\x80\x10" * 20]
    return [text.encode(), bad_park.encode(),
            b"[geometry]\nL1 = 40.0\nL2 = -65.0\n", b"not = [toml\n", *edits]


def model_regressions() -> dict[str, bytes]:
    """What the model_loader harness found (tests/test_fuzz_regressions.py): each input
    raised something other than ModelError, or hung, before the fix."""
    text = config.DEFAULT_MODEL.read_text()

    def edit(old: str, new: str) -> bytes:
        assert old in text, old
        return text.replace(old, new, 1).encode()

    return {
        "regress-deep-inline-tables": b"r = " + b"{m = " * 500 + b"0" + b"}" * 500,
        "regress-deep-arrays": b"a = " + b"[" * 1500 + b"]" * 1500,
        "regress-int-beyond-64-bits": edit("L1 = 40.0", "L1 = " + "4" * 400),
        "regress-subnormal-sample-rate": edit("sample_rate = 100.0", "sample_rate = 5e-324"),
        "regress-tiny-servo-range": edit("range_deg = 300.0", "range_deg = 1e-300"),
        "regress-huge-length": edit("L3 = 73.5", "L3 = 1e300"),
        "regress-long-decimal-length": edit("L1 = 40.0", "L1 = 4.028633809204152"),
        "regress-tiny-length": edit("L2 = 65.0", "L2 = 2.2250738585072014e-308"),
    }


def write(name: str, seeds: list[bytes], named: dict[str, bytes] | None = None) -> None:
    """Seeds are named by their SHA-1, regression inputs by what they found."""
    folder = CORPUS / name
    # regress-* inputs that a fuzzer found (committed by hand) are kept; the rest is rebuilt
    found = {p.name: p.read_bytes() for p in folder.glob("regress-*")} if folder.is_dir() else {}
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    files = found | {hashlib.sha1(seed).hexdigest(): seed for seed in seeds} | (named or {})
    for file_name, seed in files.items():
        assert len(seed) <= MAX_LEN[name], (file_name, len(seed))   # the harness's -max_len
        (folder / file_name).write_bytes(seed)
    print(f"{folder.relative_to(ROOT)}: {len(files)} seeds, {sum(map(len, files.values()))} bytes")


def main() -> int:
    write("llcp_rx", llcp_seeds())
    write("dxl_parser", dxl_seeds())
    write("dxl2_parser", dxl2_seeds())
    write("app_link", app_seeds())
    write("app_link_x", app_seeds(X_REGS))
    write("model_loader", model_seeds(), model_regressions())
    return 0


if __name__ == "__main__":
    sys.exit(main())
