"""`uavarm servos setup PORT` (uavarm/calibrate/servo_setup.py) on the simulated servo bus
behind a pseudo-terminal (`uavarm sitl --servo-bus`, uavarm.sim.sitl.ServoBusPort), as a user
at the bench runs it: each servo connected alone when asked, each write confirmed.

Oracles: the official DynamixelSDK (its Protocol 1.0 packets), the AX-12A simulator's
control table (uavarm/sim/ax12_sim.py: what each servo holds afterwards), the model file
(each joint's id, the bus's baud: Baud Rate = 2,000,000 / (n + 1))."""
import threading

import pytest

from sdk_capture import sdk_packet
from uavarm.calibrate import dxl, servo_setup
from uavarm.cli import main as cli_main
from uavarm.sim.ax12_sim import AX12
from uavarm.sim.sitl import ServoBusPort

pytestmark = pytest.mark.realtime   # a reply counts as missing after a wall-clock timeout: run apart
TIMEOUT = 1.0                       # s; the simulated bus answers at once


def test_the_packets_are_the_dynamixel_sdks():
    assert sdk_packet("ping", 1) == dxl.instruction(1, dxl.PING)
    assert sdk_packet("readTx", 3, dxl.MODEL_NUMBER, 5) == dxl.instruction(3, dxl.READ, bytes([0, 5]))
    assert sdk_packet("write1ByteTxOnly", 1, dxl.ID, 2) == dxl.instruction(1, dxl.WRITE, bytes([3, 2]))
    assert sdk_packet("write1ByteTxOnly", 2, dxl.BAUD_RATE, 9) == dxl.instruction(2, dxl.WRITE, bytes([4, 9]))


@pytest.fixture
def bench():
    port = ServoBusPort(servos=[])
    thread = threading.Thread(target=port.run, daemon=True)
    thread.start()
    yield port
    port.stop()
    thread.join()


class User:
    """At the bench: before each joint's Enter, unplugs what is connected and plugs in the
    next of `servos` (a list of lists: what is connected for each joint); answers `answer`
    to each confirmation, and keeps what was asked."""

    def __init__(self, bench, servos, answer=True):
        self.bench, self.servos, self.answer = bench, list(servos), answer
        self.asked, self.confirmed = [], []

    def ask(self, text):
        self.asked.append(text)
        with self.bench.lock:
            self.bench.bus.servos = self.servos.pop(0)

    def confirm(self, question):
        self.confirmed.append(question)
        return self.answer


def run(bench, model, user, lines=None):
    out = [] if lines is None else lines
    return servo_setup.setup(bench.device, model, user.ask, user.confirm, timeout=TIMEOUT, out=out.append)


def test_three_servos_as_shipped_get_the_models_ids_and_baud_read_back(bench, model):
    new = [AX12(1), AX12(1), AX12(1)]                    # all id 1 at 1 Mbit/s, as shipped
    assert {s.register("baud_rate") for s in new} == {1}
    user, out = User(bench, [[s] for s in new]), []
    written = run(bench, model, user, out)
    baud_register = 2_000_000 // model.servo_baud - 1
    assert 2_000_000 / (baud_register + 1) == model.servo_baud
    for servo, expected in zip(new, model.servos):
        assert (servo.id, servo.register("baud_rate")) == (expected.id, baud_register)
    # joint 1's id is the one it ships with: only its baud is written; each write was asked for
    assert written == 5 and len(user.confirmed) == 5 and len(user.asked) == 3
    assert sum("read back" in line for line in out) == 5


def test_a_servo_already_set_up_is_left_as_it_is(bench, model):
    done = AX12(model.servos[1].id, table={"baud_rate": 2_000_000 // model.servo_baud - 1})
    table = bytes(done.table)
    user, out = User(bench, [[AX12(1)], [done], [AX12(1)]]), []
    assert run(bench, model, user, out) == 3
    assert bytes(done.table) == table and any(line.startswith("joint 2: already") for line in out)


def test_two_servos_connected_at_once_are_refused_before_any_write(bench, model):
    """Two servos as shipped both answer id 1: their replies overlap, which is no status packet."""
    pair = [AX12(1), AX12(1)]
    with pytest.raises(dxl.DxlError, match="more than one servo"):
        run(bench, model, User(bench, [pair]))
    assert all((s.id, s.register("baud_rate")) == (1, 1) for s in pair)


def test_no_servo_or_another_model_is_named_and_nothing_written(bench, model):
    with pytest.raises(servo_setup.SetupError, match="joint 1: no servo answers as id 1 at 1000000 bit/s"):
        run(bench, model, User(bench, [[]]))
    other = AX12(1, table={"model_number": 18})
    with pytest.raises(servo_setup.SetupError, match="model number 18, not an AX-12A"):
        run(bench, model, User(bench, [[other]]))
    assert (other.id, other.register("baud_rate")) == (1, 1)


def test_a_write_not_confirmed_is_not_made(bench, model):
    servo = AX12(1)
    user = User(bench, [[servo]], answer=False)
    with pytest.raises(servo_setup.SetupError, match="joint 1: baud rate not written"):
        run(bench, model, user)
    assert (servo.id, servo.register("baud_rate")) == (1, 1) and len(user.confirmed) == 1


def test_the_command_names_a_missing_port_without_a_traceback(tmp_path, capsys):
    assert cli_main(["servos", "setup", str(tmp_path / "ttyUSB9")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err


def test_a_write_the_servo_does_not_take_is_caught_by_the_read_back(bench, model):
    """A locked servo (Lock = 1) refuses EEPROM writes; with Status Return Level 1 it does not
    say so (no status to a WRITE): only reading back shows it."""
    servo = AX12(1, table={"status_return_level": 1, "lock": 1})
    with pytest.raises(servo_setup.SetupError, match=f"id 1 at {model.servo_baud} bit/s did not answer a READ"):
        run(bench, model, User(bench, [[servo]]))
    assert servo.register("baud_rate") == 1
    loud = AX12(1, table={"lock": 1})                    # Status Return Level 2: the refusal is seen
    with pytest.raises(servo_setup.SetupError, match=f"id 1 refused the write of {2_000_000 // model.servo_baud - 1} at address 4"):
        run(bench, model, User(bench, [[loud]]))
