"""The board port (firmware_stm32/Board/Src/board_port.c) on the host, over a test double
of the HAL functions it calls (tests/csrc/fake_hal.c, compiled against the CI HAL
declarations, so every call matches the HAL's prototypes).

Oracles: the HAL's documented conventions (UM1725: I2C DevAddress is the 7-bit address
shifted left by one, MemAddSize I2C_MEMADD_SIZE_8BIT for one-byte register addresses;
HAL_UART_TxCpltCallback comes at transmission complete), UART framing (8N1: 10 bit times a
byte), the I2C specification's bus-clear procedure (UM10204 3.1.16: up to nine SCL
pulses), the pin map (Core/Inc/main.h, docs/board-project.md) and board_config.h's polarities.
"""
import pytest

from conftest import ROOT
from uavarm.build import cbuild, firmware
from uavarm.model import config

FW = firmware.FIRMWARE
MODEL = config.load()
GPIOA, GPIOB, GPIOC = 0, 1, 2
SERVO_PWR = (GPIOA, 8)
LED0, LED1 = (GPIOA, 5), (GPIOA, 6)
CFG = [(GPIOC, 0), (GPIOC, 1), (GPIOB, 0)]
HAL_OK, HAL_ERROR, HAL_BUSY, HAL_TIMEOUT = 0, 1, 2, 3
USBD_OK, USBD_BUSY, USBD_FAIL = 0, 1, 3
I2C_MEMADD_SIZE_8BIT = 1
BAUD = 200_000                                  # the fake's huart1.Init.BaudRate


@pytest.fixture(scope="module")
def built():
    lists = firmware.source_lists()
    sources = [FW / "Board" / "Src" / "board_port.c", ROOT / "tests" / "csrc" / "fake_hal.c"]
    sources += [FW / p for p in lists["BOARD_LOGIC_SOURCES"]]
    includes = [FW / "ci" / "hal_decls"] + [FW / d for d in lists["FIRMWARE_INCLUDES"]] + [ROOT / "tests" / "csrc"]
    headers = [FW / "App" / "Inc" / "port.h", FW / "Board" / "Inc" / "board_port.h", ROOT / "tests" / "csrc" / "fake_hal.h"]
    return cbuild.load("board_port", sources, headers, include_dirs=includes, extra_flags=["-pthread"])


@pytest.fixture
def board(built):
    ffi, lib = built
    lib.fake_reset()
    port = lib.board_port_start()
    yield ffi, lib, port
    lib.fake_clock_run(False)


@pytest.fixture
def running_clock(board):
    """TIM2 counts by itself: the bus-clear pulses busy-wait on it."""
    board[1].fake_clock_run(True)
    return board


def level(lib, pin):
    port, n = pin
    return bool(lib.fake.odr[port] >> n & 1)


def send(ffi, port, data):
    return port.servo_send(port.ctx, data, len(data))


def read_servo(ffi, port, cap=256):
    buf = ffi.new("uint8_t[]", cap)
    n = port.servo_read(port.ctx, buf, cap)
    return bytes(ffi.buffer(buf, n))


def test_start_leaves_the_servo_supply_off_and_the_bus_receiving(board):
    ffi, lib, port = board
    assert not level(lib, SERVO_PWR)
    assert lib.fake.transmitter_on == 0 and lib.fake.receive_arms == 1


def test_servo_send_switches_to_transmit_and_back_at_transmit_complete(board):
    ffi, lib, port = board
    packet = bytes([0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB])
    assert send(ffi, port, packet)
    assert lib.fake.transmitter_on == 1 and bytes(lib.fake.tx[0:lib.fake.tx_len]) == packet
    assert port.servo_busy(port.ctx)
    assert not send(ffi, port, packet)                       # one send at a time
    assert not lib.fake_uart_rx_byte(0x55)                   # the line is not listening while sending
    lib.fake_uart_tx_complete()                              # TC: last stop bit out
    assert lib.fake.transmitter_on == 0 and not port.servo_busy(port.ctx)
    for b in b"\xff\xff\x01\x02\x00\xfc":                    # the servo's status packet
        assert lib.fake_uart_rx_byte(b)
    assert read_servo(ffi, port) == b"\xff\xff\x01\x02\x00\xfc"
    assert read_servo(ffi, port) == b""


def test_a_send_that_never_completes_is_aborted_after_twice_its_wire_time_plus_1ms(board):
    ffi, lib, port = board
    packet = bytes(20)
    wire_us = 10 * len(packet) * 1_000_000 // BAUD           # 8N1: 10 bit times a byte
    lib.fake_set_time_us(2**32 - 500)                        # across the clock's wrap
    assert send(ffi, port, packet)
    lib.fake_set_time_us((2**32 - 500 + 2 * wire_us + 1000) % 2**32)
    assert port.servo_busy(port.ctx) and lib.fake.aborts == 0
    lib.fake_set_time_us((2**32 - 500 + 2 * wire_us + 1001) % 2**32)
    assert not port.servo_busy(port.ctx)
    assert lib.fake.aborts == 1 and lib.fake.transmitter_on == 0
    assert send(ffi, port, packet)                           # usable again


def test_oversized_or_empty_sends_are_refused(board):
    ffi, lib, port = board
    assert not send(ffi, port, b"")
    assert not send(ffi, port, bytes(129))
    assert lib.fake.transmit_calls == 0


def test_reception_lost_in_the_interrupt_is_rearmed_by_the_next_read(board):
    ffi, lib, port = board
    lib.fake.refuse_receive_arm = 1                          # e.g. the handle was locked
    assert lib.fake_uart_rx_byte(0x11)
    assert not lib.fake_uart_rx_byte(0x22)                   # nothing armed: this byte is lost
    lib.fake.refuse_receive_arm = 0
    assert read_servo(ffi, port) == b"\x11"
    assert lib.fake_uart_rx_byte(0x33)
    assert read_servo(ffi, port) == b"\x33"


def test_a_receiver_switch_refused_in_the_interrupt_is_retried_by_the_main_loop(board):
    ffi, lib, port = board
    assert send(ffi, port, b"\x01\x02")
    lib.fake.refuse_enable_receiver = 1                      # the handle was locked at TC
    lib.fake_uart_tx_complete()
    assert lib.fake.transmitter_on == 1
    lib.fake.refuse_enable_receiver = 0
    assert not port.servo_busy(port.ctx)
    assert lib.fake.transmitter_on == 0 and lib.fake_uart_rx_byte(0x7E)


def test_an_overrun_rearms_reception_at_once(board):
    ffi, lib, port = board
    lib.fake_uart_overrun()
    assert lib.fake_uart_rx_byte(0x44)
    assert read_servo(ffi, port) == b"\x44"


def test_supply_leds_and_configuration_inputs_follow_the_pin_map(board):
    ffi, lib, port = board
    port.servo_power(port.ctx, True)
    assert level(lib, SERVO_PWR)                             # BOARD_SERVO_POWER_ACTIVE_HIGH
    port.servo_power(port.ctx, False)
    assert not level(lib, SERVO_PWR)
    port.led(port.ctx, 0, True)
    assert level(lib, LED0) and not level(lib, LED1)
    port.led(port.ctx, 1, True)
    port.led(port.ctx, 0, False)
    assert level(lib, LED1) and not level(lib, LED0)
    port.led(port.ctx, 7, True)                              # no such LED: nothing else moves
    assert not level(lib, LED0) and not level(lib, SERVO_PWR)
    assert lib.board_config_inputs() == 0                    # all pulled up: no bridge closed
    for bit, (p, n) in enumerate(CFG):
        lib.fake.idr[p] &= ~(1 << n)                         # a closed bridge pulls to ground
        assert lib.board_config_inputs() >> bit & 1


def test_time_is_timer2s_counter(board):
    ffi, lib, port = board
    for t in (0, 12345, 2**32 - 1):
        lib.fake_set_time_us(t)
        assert port.time_us(port.ctx) == t


def test_imu_transfers_use_the_hals_address_convention(board):
    ffi, lib, port = board
    lib.fake.regs[0x75] = 0x68
    lib.fake.regs[0x3B:0x3B + 14] = bytes(range(1, 15))
    buf = ffi.new("uint8_t[14]")
    assert port.imu_read(port.ctx, MODEL.imu_address, 0x3B, buf, 14)
    assert lib.fake.dev_address == MODEL.imu_address << 1 and lib.fake.mem_address == 0x3B
    assert lib.fake.mem_add_size == I2C_MEMADD_SIZE_8BIT and lib.fake.size == 14
    assert bytes(buf) == bytes(range(1, 15))
    assert 0 < lib.fake.timeout <= 10                        # bounded: ms, never HAL_MAX_DELAY
    assert port.imu_write(port.ctx, MODEL.imu_address, 0x6B, 0x01)
    assert lib.fake.regs[0x6B] == 0x01 and lib.fake.mem_address == 0x6B and lib.fake.size == 1


def test_a_nack_fails_without_resetting_the_bus_a_timeout_resets_it(running_clock):
    ffi, lib, port = running_clock
    buf = ffi.new("uint8_t[1]")
    lib.fake.i2c_status = HAL_ERROR                          # no device at the address
    assert not port.imu_read(port.ctx, 0x68, 0x75, buf, 1)
    assert lib.fake.i2c_deinits == 0
    lib.fake.i2c_status = HAL_TIMEOUT
    assert not port.imu_read(port.ctx, 0x68, 0x75, buf, 1)
    assert lib.fake.i2c_deinits == 1 and lib.fake.i2c_inits == 1
    lib.fake.i2c_status = HAL_OK
    assert port.imu_read(port.ctx, 0x68, 0x75, buf, 1)


@pytest.mark.parametrize("release_after", [1, 3, 8])
def test_a_stuck_bus_is_freed_by_clock_pulses_before_the_transfer(running_clock, release_after):
    ffi, lib, port = running_clock
    lib.fake_i2c_bus_stuck(release_after)
    buf = ffi.new("uint8_t[1]")
    assert port.imu_read(port.ctx, 0x68, 0x75, buf, 1)
    assert lib.fake.scl_pulses == release_after and lib.fake.transfers == 1


def test_a_bus_that_stays_stuck_fails_at_once_after_nine_pulses(running_clock):
    ffi, lib, port = running_clock
    lib.fake_i2c_bus_stuck(-1)
    buf = ffi.new("uint8_t[1]")
    assert not port.imu_read(port.ctx, 0x68, 0x75, buf, 1)
    assert lib.fake.scl_pulses == 9 and lib.fake.transfers == 0   # the HAL's 25 ms busy wait never runs
    assert not port.imu_write(port.ctx, 0x68, 0x6B, 0)


def test_link_goes_through_usb_cdc(board):
    ffi, lib, port = board
    lib.fake.cdc_answer = USBD_FAIL                          # no host yet
    assert port.link_write(port.ctx, b"b01AA", 5)
    lib.board_port_poll()
    assert lib.fake.cdc_sent_len == 0
    lib.board_link_connected()                               # the host opens the port
    lib.fake.cdc_answer = USBD_OK
    assert port.link_write(port.ctx, b"b01BB", 5)
    assert bytes(lib.fake.cdc_sent[0:lib.fake.cdc_sent_len]) == b"b01BB"   # stale AA dropped
    lib.board_link_received(b"b0203", 5)
    buf = ffi.new("uint8_t[16]")
    assert port.link_read(port.ctx, buf, 16) == 5 and bytes(buf[0:5]) == b"b0203"


def test_a_host_opening_the_port_gets_no_heartbeats_queued_before(board):
    """DTR rising (the host opened the port) drops what queued while nobody read it; DTR held
    or falling drops nothing."""
    ffi, lib, port = board
    lib.fake.cdc_answer = USBD_BUSY                          # nobody reads: frames queue
    for frame in (b"b01AA", b"b01BB"):
        assert port.link_write(port.ctx, frame, 5)
    lib.board_link_line_state(True)                          # a process opens the port
    lib.fake.cdc_answer = USBD_OK
    assert port.link_write(port.ctx, b"b01CC", 5)
    assert bytes(lib.fake.cdc_sent[0:lib.fake.cdc_sent_len]) == b"b01CC"
    assert port.link_write(port.ctx, b"b01DD", 5)            # queued behind CC's transfer
    lib.board_link_line_state(True)                          # DTR set again: the same reader
    lib.board_link_line_state(False)                         # the port closes: nothing dropped
    lib.board_link_transmitted()
    lib.board_port_poll()
    assert bytes(lib.fake.cdc_sent[0:lib.fake.cdc_sent_len]) == b"b01CCb01DD"


# ------------------------------------------------------------------ the servo set-up bridge

def test_cfg0_closed_at_reset_selects_the_servo_set_up_bridge(board):
    ffi, lib, port = board
    assert not lib.board_servo_bridge_selected()
    lib.fake.idr[CFG[0][0]] &= ~(1 << CFG[0][1])          # CFG0 bridged to ground
    assert lib.board_servo_bridge_selected()


def test_the_bridge_passes_set_up_packets_at_the_hosts_rate_and_the_replies_back(board):
    """LED0 lit; the servo supply on only while the host has the port open (DTR); the bus set to
    the bit rate the host's SET_LINE_CODING gave, reception stopped first and re-armed after; a
    goal position dropped, the PING after it sent; the servo's reply handed to USB."""
    from sdk_capture import sdk_packet
    ffi, lib, port = board
    lib.board_servo_bridge_start()
    lib.board_servo_bridge_poll()
    assert level(lib, LED0) and not level(lib, SERVO_PWR)
    lib.board_link_line_state(True)
    lib.board_link_line_coding(1_000_000)
    arms = lib.fake.receive_arms
    lib.board_servo_bridge_poll()
    assert level(lib, SERVO_PWR)
    assert (lib.fake.baud_set, lib.fake.halfduplex_inits, lib.fake.receive_aborts) == (1_000_000, 1, 1)
    assert not lib.fake.receive_armed_at_init and lib.fake.receive_arms == arms + 1 and not lib.fake.transmitter_on
    goal, ping = sdk_packet("write2ByteTxOnly", 1, 30, 512), sdk_packet("ping", 1)
    lib.board_link_received(goal + ping, len(goal + ping))
    lib.board_servo_bridge_poll()
    assert lib.fake.transmit_calls == 1 and bytes(lib.fake.tx[0:lib.fake.tx_len]) == ping
    lib.fake_uart_tx_complete()
    reply = b"\xff\xff\x01\x02\x00\xfc"                   # id 1, no error
    assert all(lib.fake_uart_rx_byte(b) for b in reply)
    lib.board_servo_bridge_poll()
    assert bytes(lib.fake.cdc_sent[0:lib.fake.cdc_sent_len]) == reply
    lib.board_link_line_state(False)
    lib.board_servo_bridge_poll()
    assert not level(lib, SERVO_PWR)
