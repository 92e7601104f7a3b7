"""The X-series servo simulator (XM430-W350, XL430-W250), driven by the official DynamixelSDK.

Oracles: DynamixelSDK's Protocol2PacketHandler, GroupSyncWrite and GroupSyncRead (through
`SdkPort` on an `AX12Bus`, the SDK's byte stuffing put on the wire by
sdk_capture.packet_handler); the Protocol 2.0 e-manual's worked examples and its written
status-packet format (`status` of test_dxl_protocol2: stuffing, LEN, CRC-16 bit by bit from
the polynomial 0x8005); the servos' e-manual pages for the control table, units, the
profile's times (t1 = 64 Vprf / Aprf ms, t2 = 64 dPos / Vprf ms) and the no-load speeds.
"""
from __future__ import annotations

import dynamixel_sdk as sdk
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from sdk_capture import packet_handler, sdk_packet
from test_dxl_protocol2 import packet, status, stuff, with_crc
from uavarm.sim.ax12_sim import AX12Bus, SdkPort, Supply
from uavarm.sim.xseries_sim import XL430_W250, XM430_W350, XServo, unstuffed

PH = packet_handler(2.0)
BAUD = 1_000_000
FAST = {"baud_rate": 3, "return_delay_time": 0}      # 1 Mbps (Baud Rate 3), no delay

# e-manual control tables: address -> (size, initial value), XM430-W350 and XL430-W250
FACTS_XM430 = {
    0: (2, 1020), 7: (1, 1), 8: (1, 1), 9: (1, 250), 10: (1, 0), 11: (1, 3), 24: (4, 10),
    31: (1, 80), 32: (2, 160), 34: (2, 95), 36: (2, 885), 44: (4, 350), 48: (4, 4095), 52: (4, 0),
    63: (1, 52), 64: (1, 0), 65: (1, 0), 68: (1, 2), 69: (1, 0), 70: (1, 0), 100: (2, 885),
    108: (4, 0), 112: (4, 0), 122: (1, 0),
}
FACTS_XL430 = {**FACTS_XM430, 0: (2, 1060), 31: (1, 72), 32: (2, 140), 34: (2, 60), 44: (4, 265)}
NO_LOAD_RPM_12V = {"XM430-W350": 46.0, "XL430-W250": 61.0}   # e-manual: 57 at 11.1 V, 61 at 12 V
UNITS_PER_S_PER_RPM = 4096 / 60


def make(*servos):
    bus = AX12Bus(servos or [XServo(XM430_W350, 1, table=FAST)], baud=BAUD)
    return bus, SdkPort(bus)


def raw(bus, data: bytes) -> bytes:
    bus.write(data)
    bus.settle()
    return bus.read()


def signed(value: int, size: int) -> int:
    return int.from_bytes(value.to_bytes(size, "little"), "little", signed=True)


def run_until_at(bus, servo, goal, limit, dt=0.001):
    """Step until Moving(122) clears; the time it took (Present Position then reads goal)."""
    start = bus.time
    bus.step(dt)
    while servo.register("moving"):
        bus.step(dt)
        assert bus.time - start < limit, "never arrived"
    assert servo.register("present_position") == goal
    return bus.time - start


# ------------------------------------------------------------ e-manual packets

def test_emanual_read_example():
    bus, _ = make(XServo(XM430_W350, 1, position=166, table=FAST))
    # READ Present Position(132), 4 bytes; the servo at 166 (0xA6)
    assert raw(bus, bytes.fromhex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")) == \
        bytes.fromhex("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0")


def test_emanual_write_reboot_and_sync_examples():
    """The Protocol 2.0 page's WRITE, REBOOT, SYNC_WRITE and SYNC_READ examples, byte for byte."""
    one, two = XServo(XM430_W350, 1, table=FAST), XServo(XM430_W350, 2, table=FAST)
    bus, port = make(one, two)
    done = bytes.fromhex("FF FF FD 00 01 04 00 55 00 A1 0C")
    # WRITE 512 to Goal Position(116)
    assert raw(bus, bytes.fromhex("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")) == done
    assert one.register("goal_position") == 512
    assert raw(bus, bytes.fromhex("FF FF FD 00 01 03 00 08 2F 4E")) == done          # REBOOT
    # SYNC_WRITE Goal Position: ID 1 <- 150, ID 2 <- 170 (not answered: broadcast)
    assert raw(bus, bytes.fromhex("FF FF FD 00 FE 11 00 83 74 00 04 00"
                                  "01 96 00 00 00 02 AA 00 00 00 82 87")) == b""
    assert (one.register("goal_position"), two.register("goal_position")) == (150, 170)
    # SYNC_READ Present Position(132) of IDs 1, 2 at 166 and 2079
    one.turn_by_hand(166)
    two.turn_by_hand(2079)
    assert raw(bus, bytes.fromhex("FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA")) == \
        bytes.fromhex("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0"
                      "FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE")


@pytest.mark.parametrize("model, firmware", [(XM430_W350, 45), (XL430_W250, 46)])
def test_ping_answers_model_number_and_firmware(model, firmware):
    bus, port = make(XServo(model, 3, firmware_version=firmware, table=FAST))
    assert PH.ping(port, 3) == (model.number, sdk.COMM_SUCCESS, 0)
    pkt = with_crc(bytes.fromhex("FF FF FD 00 03 03 00 01"))
    assert raw(bus, pkt) == status(3, 0, model.number.to_bytes(2, "little") + bytes([firmware]))


@pytest.mark.parametrize("model, facts", [(XM430_W350, FACTS_XM430), (XL430_W250, FACTS_XL430)])
def test_factory_table(model, facts):
    bus, port = make(XServo(model, 1, table={"baud_rate": 3}))
    for addr, (size, value) in facts.items():
        read = {1: PH.read1ByteTxRx, 2: PH.read2ByteTxRx, 4: PH.read4ByteTxRx}[size]
        if addr == 8:
            value = 3                       # set to talk at 1 Mbps; 1 (57 600) at the factory
        assert read(port, 1, addr) == (value, sdk.COMM_SUCCESS, 0), addr


def test_read_answer_bytes_follow_the_written_format():
    bus, port = make(XServo(XM430_W350, 7, position=1234.4, voltage=11.1, temperature=41, table=FAST))
    pkt = packet(7, bytes([0x02]) + (132).to_bytes(2, "little") + (15).to_bytes(2, "little"))
    expected = (1234).to_bytes(4, "little") + bytes(8) + (111).to_bytes(2, "little") + bytes([41])
    assert raw(bus, pkt) == status(7, 0, expected)


def test_writes_and_reads_through_the_sdk():
    bus, port = make()
    assert PH.write1ByteTxRx(port, 1, 65, 1) == (sdk.COMM_SUCCESS, 0)       # LED
    assert PH.write4ByteTxRx(port, 1, 112, 123) == (sdk.COMM_SUCCESS, 0)    # Profile Velocity
    assert PH.read1ByteTxRx(port, 1, 65) == (1, sdk.COMM_SUCCESS, 0)
    assert PH.read4ByteTxRx(port, 1, 112) == (123, sdk.COMM_SUCCESS, 0)


def test_indirect_data_reads_what_its_indirect_address_points_at():
    """e-manual, Indirect Address/Data: Indirect Address 1..4 (168..174) pointed at Present
    Position(132..135), a READ of Indirect Data 1..4 (224..227) is the position; at power-on
    each Indirect Address holds its own Indirect Data's address (224 + k - 1), which reads 0."""
    bus, port = make(XServo(XM430_W350, 1, position=1234, table=FAST))
    assert PH.read4ByteTxRx(port, 1, 224) == (0, sdk.COMM_SUCCESS, 0)
    assert PH.read2ByteTxRx(port, 1, 168) == (224, sdk.COMM_SUCCESS, 0)
    assert PH.read2ByteTxRx(port, 1, 222) == (251, sdk.COMM_SUCCESS, 0)    # Indirect Address 28
    for k in range(4):
        assert PH.write2ByteTxRx(port, 1, 168 + 2 * k, 132 + k) == (sdk.COMM_SUCCESS, 0)
    assert PH.read4ByteTxRx(port, 1, 224) == (1234, sdk.COMM_SUCCESS, 0)
    assert PH.write2ByteTxRx(port, 1, 168, 0) == (sdk.COMM_SUCCESS, 0x04), "an EEPROM address: Data Range error"
    assert PH.read4ByteTxRx(port, 1, 224) == (1234, sdk.COMM_SUCCESS, 0)
    bus.servos[0].power_on()
    assert PH.read4ByteTxRx(port, 1, 224) == (0, sdk.COMM_SUCCESS, 0), "the map is RAM"


def test_corrupted_instruction_gets_no_answer():
    bus, port = make()
    good = sdk_packet("write1ByteTxOnly", 1, 65, 1, protocol=2.0)
    for i in range(4, len(good)):
        bad = bytearray(good)
        bad[i] ^= 0x10
        assert raw(bus, bytes(bad)) == b"", i
    assert PH.read1ByteTxRx(port, 1, 65) == (0, sdk.COMM_SUCCESS, 0)
    assert raw(bus, good) == status(1, 0)


def test_stuffed_instruction_is_unstuffed():
    bus, _ = make()
    # WRITE at address 0xFFFF the byte FD: INST 03, FF FF, FD is stuffed to FF FF FD FD
    pkt = packet(1, bytes([0x03, 0xFF, 0xFF, 0xFD]))
    assert b"\xff\xff\xfd\xfd" in pkt
    assert raw(bus, pkt) == status(1, 0x07)                  # Access error: no such address


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(st.binary(max_size=12), st.sampled_from([
    b"\xff\xff\xfd\x00", b"\x01", b"\x00\x00", b"\x02\x00", b"\x03\x00\x02", b"\xfe"])), max_size=12))
def test_any_bytes_from_the_wire_leave_it_answering(chunks):
    """Garbage, short lengths, headers cut short: no exception, and a clean PING after the
    byte gap timeout (100 ms) is answered."""
    bus, port = make()
    raw(bus, b"".join(chunks))
    bus.step(0.2)
    assert PH.ping(port, 1)[1:] == (sdk.COMM_SUCCESS, 0)


@given(st.lists(st.sampled_from([b"\xff", b"\xfd", b"\x00", b"\xff\xff\xfd"]), max_size=16))
def test_unstuffing_undoes_the_written_stuffing(pieces):
    body = b"".join(pieces)
    assert unstuffed(stuff(body)) == body


def test_eeprom_write_with_torque_on_is_refused():
    bus, port = make()
    assert PH.write1ByteTxRx(port, 1, 64, 1) == (sdk.COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 11, 1) == (sdk.COMM_SUCCESS, 0x07)   # Access error
    assert PH.write1ByteTxRx(port, 1, 7, 9) == (sdk.COMM_SUCCESS, 0x07)
    assert PH.read1ByteTxRx(port, 1, 11) == (3, sdk.COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 64, 0) == (sdk.COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 11, 1) == (sdk.COMM_SUCCESS, 0)
    assert PH.read1ByteTxRx(port, 1, 11) == (1, sdk.COMM_SUCCESS, 0)


@pytest.mark.parametrize("addr, size, value, error", [
    (132, 4, 5, 0x07),          # read-only: Access error
    (71, 1, 1, 0x07),           # not in the table: Access error
    (116, 2, 5, 0x05),          # half of Goal Position: Data Length error
    (64, 1, 2, 0x04),           # Torque Enable 2: Data Range error
    (116, 4, 4096, 0x04),       # past a turn: Data Range error
])
def test_refused_writes(addr, size, value, error):
    bus, port = make()
    write = {1: PH.write1ByteTxRx, 2: PH.write2ByteTxRx, 4: PH.write4ByteTxRx}[size]
    assert write(port, 1, addr, value) == (sdk.COMM_SUCCESS, error)


def test_goal_outside_position_limits_is_refused():
    bus, port = make()
    assert PH.write4ByteTxRx(port, 1, 48, 3000) == (sdk.COMM_SUCCESS, 0)   # Max Position Limit
    assert PH.write4ByteTxRx(port, 1, 116, 3001) == (sdk.COMM_SUCCESS, 0x06)
    assert PH.write4ByteTxRx(port, 1, 116, 3000) == (sdk.COMM_SUCCESS, 0)


def test_status_return_level_and_broadcast():
    bus, port = make()
    assert PH.write1ByteTxRx(port, 1, 68, 1) == (sdk.COMM_SUCCESS, 0)      # answered the old way
    assert PH.write1ByteTxRx(port, 1, 65, 1)[0] == sdk.COMM_RX_TIMEOUT
    assert PH.read1ByteTxRx(port, 1, 65) == (1, sdk.COMM_SUCCESS, 0)
    assert raw(bus, packet(0xFE, bytes([0x03, 65, 0, 0]))) == b""           # broadcast write
    assert PH.read1ByteTxRx(port, 1, 65) == (0, sdk.COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 68, 0)[0] == sdk.COMM_RX_TIMEOUT
    assert PH.read1ByteTxRx(port, 1, 68)[1] == sdk.COMM_RX_TIMEOUT
    assert PH.ping(port, 1) == (1020, sdk.COMM_SUCCESS, 0)


@pytest.mark.parametrize("delay_units", [0, 250])
def test_reply_after_return_delay_time(delay_units):
    bus, _ = make(XServo(XM430_W350, 1, table={"baud_rate": 3, "return_delay_time": delay_units}))
    byte = 10 / BAUD
    pkt = packet(1, bytes([0x02, 65, 0, 1, 0]))                   # READ LED: 14 out, 12 back
    bus.write(pkt)
    end = 14 * byte + 2e-6 * delay_units + 12 * byte              # 2 us per unit
    bus.run_until(end - byte / 2)
    assert len(bus.read()) == 11
    bus.run_until(end + byte / 2)
    assert len(bus.read()) == 1


def test_group_sync_write_and_read_two_servos():
    xm, xl = XServo(XM430_W350, 1, table=FAST), XServo(XL430_W250, 2, table=FAST)
    bus, port = make(xm, xl)
    for id_ in (1, 2):
        assert PH.write1ByteTxRx(port, id_, 64, 1) == (sdk.COMM_SUCCESS, 0)
    write = sdk.GroupSyncWrite(port, PH, 116, 4)
    assert write.addParam(1, list((1000).to_bytes(4, "little")))
    assert write.addParam(2, list((3000).to_bytes(4, "little")))
    assert write.txPacket() == sdk.COMM_SUCCESS
    for _ in range(200):
        bus.step(0.01)
    read = sdk.GroupSyncRead(port, PH, 132, 4)
    assert read.addParam(1) and read.addParam(2)
    assert read.txRxPacket() == sdk.COMM_SUCCESS
    assert read.getData(1, 132, 4) == 1000 and read.getData(2, 132, 4) == 3000
    # the answers' bytes, one status packet per servo in the order asked
    pkt = packet(0xFE, bytes([0x82, 132, 0, 4, 0, 2, 1]))
    assert raw(bus, pkt) == status(2, 0, (3000).to_bytes(4, "little")) + \
        status(1, 0, (1000).to_bytes(4, "little"))


# ------------------------------------------------------------------ motion

def profile_time(dpos, v_units, a_units):
    """The e-manual's trapezoidal profile: t1 = 64 V/A ms, t2 = 64 dPos/V ms, t3 = t1 + t2."""
    t1 = 64 * v_units / a_units
    t2 = 64 * dpos / v_units
    return (t1 + t2) / 1000


@pytest.mark.parametrize("model", [XM430_W350, XL430_W250])
@pytest.mark.parametrize("v_units, a_units, dpos", [(100, 20, 2000), (150, 60, 1500), (60, 5, 1000)])
def test_trapezoidal_profile_time(model, v_units, a_units, dpos):
    servo = XServo(model, 1, position=1000, table=FAST)
    bus, port = make(servo)
    assert PH.write4ByteTxRx(port, 1, 108, a_units) == (sdk.COMM_SUCCESS, 0)
    assert PH.write4ByteTxRx(port, 1, 112, v_units) == (sdk.COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 64, 1) == (sdk.COMM_SUCCESS, 0)
    assert PH.write4ByteTxRx(port, 1, 116, 1000 + dpos) == (sdk.COMM_SUCCESS, 0)
    expected = profile_time(dpos, v_units, a_units)
    took = run_until_at(bus, servo, 1000 + dpos, 2 * expected)
    # the e-manual's 64 stands for 60000 / (0.229 * 4096) = 63.97: 0.05 %; 2 ms of stepping
    assert took == pytest.approx(expected, rel=0.002, abs=0.003)


@pytest.mark.parametrize("model", [XM430_W350, XL430_W250])
@pytest.mark.parametrize("volts, v_units", [(12.0, 0), (9.0, 0), (12.0, 1000), (10.0, 400)])
def test_speed_capped_by_no_load_speed(model, volts, v_units):
    """Profile Velocity 0 (or above the motor's speed), no acceleration profile: the shaft
    travels at the no-load speed at its supply, in proportion to the voltage."""
    servo = XServo(model, 1, position=500, voltage=volts, table=FAST)
    bus, port = make(servo)
    PH.write4ByteTxRx(port, 1, 112, v_units)
    PH.write1ByteTxRx(port, 1, 64, 1)
    PH.write4ByteTxRx(port, 1, 116, 3500)
    rpm = NO_LOAD_RPM_12V[model.name] * volts / 12
    expected = 3000 / (rpm * UNITS_PER_S_PER_RPM)
    assert v_units == 0 or v_units * 0.229 > rpm
    assert run_until_at(bus, servo, 3500, 2 * expected) == pytest.approx(expected, abs=0.002)


def test_first_order_lag_behind_the_profile():
    """At a constant profile speed v the shaft, lagging by tau, trails it by v * tau."""
    tau = 0.03
    servo = XServo(XM430_W350, 1, position=0, time_constant=tau, table=FAST)
    bus, port = make(servo)
    v_units, a_units = 100, 50
    PH.write4ByteTxRx(port, 1, 108, a_units)
    PH.write4ByteTxRx(port, 1, 112, v_units)
    PH.write1ByteTxRx(port, 1, 64, 1)
    start = bus.time
    PH.write4ByteTxRx(port, 1, 116, 4000)
    v = v_units * 0.229 * UNITS_PER_S_PER_RPM                    # units/s
    t1 = v_units / (a_units * 214.577 / 3600 / 0.229 * 60)       # s: V / A in SI
    t = 1.0
    bus.run_until(start + t)
    profile = v * (t - t1 / 2)                                   # trapezoid's area
    assert servo.position == pytest.approx(profile - v * tau, abs=1.0)
    assert PH.read4ByteTxRx(port, 1, 128) == (v_units, sdk.COMM_SUCCESS, 0)   # Present Velocity


# ---------------------------------------------------- current, load, errors

@pytest.mark.parametrize("load", [1.0, -2.5, 0.0])
def test_present_current_from_the_load(load):
    servo = XServo(XM430_W350, 1, table=FAST)
    bus, port = make(servo)
    servo.load_torque = load
    assert PH.read2ByteTxRx(port, 1, 126) == (0, sdk.COMM_SUCCESS, 0)      # limp: 0
    PH.write1ByteTxRx(port, 1, 64, 1)
    value, result, error = PH.read2ByteTxRx(port, 1, 126)
    amps = -load / (4.1 / 2.3)                 # holding it: the torque constant at stall
    assert (result, error) == (sdk.COMM_SUCCESS, 0)
    assert signed(value, 2) == round(amps / 0.00269)


def test_xl430_present_load_in_tenths_of_a_percent():
    servo = XServo(XL430_W250, 1, voltage=12.0, table=FAST)
    bus, port = make(servo)
    servo.load_torque = -0.75                  # pulls CW; 1.5 N m stall at 12 V
    PH.write1ByteTxRx(port, 1, 64, 1)
    value, _, _ = PH.read2ByteTxRx(port, 1, 126)
    assert signed(value, 2) == 500


@pytest.mark.parametrize("fault, bit", [("temperature", 0x04), ("overload", 0x20)])
def test_hardware_error_shuts_down_and_alerts(fault, bit):
    servo = XServo(XM430_W350, 1, table=FAST)
    bus, port = make(servo)
    PH.write1ByteTxRx(port, 1, 64, 1)
    assert PH.ping(port, 1) == (1020, sdk.COMM_SUCCESS, 0)
    if fault == "temperature":
        servo.temperature = 81                 # Temperature Limit 80
    else:
        servo.load_torque = 4.2                # stall torque 4.1 N m at 12 V
    bus.step(0.01)
    assert PH.read1ByteTxRx(port, 1, 70) == (bit, sdk.COMM_SUCCESS, 0x80)
    assert PH.read1ByteTxRx(port, 1, 64) == (0, sdk.COMM_SUCCESS, 0x80)    # torque off
    assert PH.ping(port, 1) == (1020, sdk.COMM_SUCCESS, 0x80)
    assert PH.write1ByteTxRx(port, 1, 64, 1) == (sdk.COMM_SUCCESS, 0x81)   # Result Fail
    assert raw(bus, packet(1, bytes([0x02, 70, 0, 1, 0]))) == status(1, 0x80, bytes([bit]))
    servo.temperature, servo.load_torque = 30, 0.0
    assert PH.reboot(port, 1) == (sdk.COMM_SUCCESS, 0x80)    # answered, then rebooted
    bus.step(0.01)
    assert PH.read1ByteTxRx(port, 1, 70) == (0, sdk.COMM_SUCCESS, 0)
    assert PH.write1ByteTxRx(port, 1, 64, 1) == (sdk.COMM_SUCCESS, 0)


def test_input_voltage_error_only_where_shutdown_selects_it():
    servo = XServo(XM430_W350, 1, voltage=9.0, table=FAST)   # below Min Voltage Limit 9.5 V
    bus, port = make(servo)
    bus.step(0.01)
    assert PH.read1ByteTxRx(port, 1, 70) == (0, sdk.COMM_SUCCESS, 0)      # Shutdown 52
    assert PH.write1ByteTxRx(port, 1, 63, 52 | 0x01) == (sdk.COMM_SUCCESS, 0)
    bus.step(0.01)
    assert PH.read1ByteTxRx(port, 1, 70) == (0x01, sdk.COMM_SUCCESS, 0x80)
    assert PH.read2ByteTxRx(port, 1, 144) == (90, sdk.COMM_SUCCESS, 0x80)


def test_on_a_sagging_supply():
    """The AX-12A model's Supply carries X-series servos too: turning at full speed, the shaft
    draws idle + moving amps, the voltage sags by R times that, and Present Input Voltage reads
    it (12 V - 0.5 ohm * 0.84 A = 11.58 V)."""
    servo = XServo(XM430_W350, 1, position=0, table=FAST)
    bus = AX12Bus([servo], baud=BAUD, supply=Supply(volts=12.0, resistance=0.5, idle_amps=0.04,
                                                    moving_amps=0.8))
    port = SdkPort(bus)
    PH.write1ByteTxRx(port, 1, 64, 1)
    bus.step(0.01)
    assert PH.read2ByteTxRx(port, 1, 144) == (120, sdk.COMM_SUCCESS, 0)       # 11.98 V at rest
    PH.write4ByteTxRx(port, 1, 116, 4000)
    bus.step(0.2)
    assert PH.read2ByteTxRx(port, 1, 144) == (116, sdk.COMM_SUCCESS, 0)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.binary(max_size=5), st.lists(st.binary(min_size=8, max_size=8), min_size=1, max_size=3)),
                min_size=1, max_size=4), st.data())
def test_the_simulators_packet_reader_finds_the_sdks_sync_writes(parts, data):
    """SimBoard records an X-series arm's goals by reading the bus bytes: the SDK's
    GroupSyncWrite packets (stuffed where the data holds FF FF FD), between junk and beside a
    copy with a broken CRC, are found whole and unstuffed, and the broken one is not."""
    from sdk_capture import sdk_sync_write
    from uavarm.sim.xseries_sim import INST_SYNC_WRITE, instruction_packets
    handler = packet_handler(2.0)
    stream, want = b"", []
    for junk, entries in parts:
        ids = list(range(1, len(entries) + 1))
        pkt = sdk_sync_write(handler, 112, 8, ids, b"".join(entries))
        broken = pkt[:-1] + bytes([pkt[-1] ^ data.draw(st.integers(1, 255))])
        stream += junk.replace(b"\xff", b"") + broken + pkt
        want.append((0xFE, INST_SYNC_WRITE, bytes([112, 0, 8, 0]) + b"".join(bytes([i]) + e for i, e in zip(ids, entries))))
    assert instruction_packets(stream) == want
