"""The last line of defence on its own: a host build of the whole application in which the
IK that motion.c asks every tick (kin_ik_branch) returns bad poses on demand (NaN, a joint
past its limit, reaching into a leg's sector, above the body plane, the far branch;
tests/csrc/bad_ik.c). Whatever the IK says, the final check in app.c and the servo map must
keep every such pose, and every move toward it that passes through a limit, the body or a
leg, off the servo bus.

Oracles, independent of the C under test: tests/invariants.py (every SYNC_WRITE goal and the
servos' path to it by plain geometry, with the AX-12A's unit map) and the servo positions of
the bad poses by the AX-12A's written facts (arm_spec)."""
import hashlib
import math

import numpy as np
import pytest

import arm_spec
from conftest import ROOT
from invariants import Invariants
from simboard_tools import FK_TOL_MM, BusLog, make_board, ready, shaft_units, ee_of_units
from uavarm.build import cbuild, firmware, generated

HARNESS = ROOT / "tests" / "csrc"
TARGET = (0.0, 110.0, -90.0)   # joint 1 at -90 deg, reaching past the leg distance
BAD = {"nan": 1, "limit": 2, "leg": 3, "body": 4, "far_branch": 5}
# the fixed bad poses of bad_ik.c (deg), as the servo would be told them
FIXED_POSES = {"leg": (45.0, 90.0, 0.0), "body": (0.0, 110.0, 60.0)}


@pytest.fixture(scope="module")
def bad_ik_lib():
    """The application built with bad_ik.c in place of generated/kinematics.c (which it
    includes: its hash joins the build's flags so an edited kinematics.c rebuilds)."""
    kin = generated.GENERATED / "kinematics.c"
    sources = [s for s in firmware.app_sources() if s.name != "kinematics.c"]
    sources += [HARNESS / "bad_ik.c", *firmware.host_sources()]
    headers = (generated.headers() + [firmware.APP / "Inc" / h for h in firmware.APP_HEADERS]
               + firmware.host_headers() + [HARNESS / "bad_ik.h"])
    tag = hashlib.sha256(kin.read_bytes()).hexdigest()[:16]
    return cbuild.load("firmware_bad_ik", sources, headers,
                       include_dirs=[generated.GENERATED, firmware.APP / "Inc", firmware.HOST_PORT, HARNESS],
                       extra_flags=[f"-DKINEMATICS_C_SHA=0x{tag}"])


def fixed_units(name):
    return [round(arm_spec.units_exact(j, math.radians(d))) for j, d in enumerate(FIXED_POSES[name])]


@pytest.mark.parametrize("bad", list(BAD))
def test_bad_ik_poses_never_reach_the_servos(bad_ik_lib, bad):
    """Engaged and holding the target, then the IK turns bad for 2 s, the board rocking its
    target round (a new set position every 0.25 s): every SYNC_WRITE is still safe and so is
    the path to it (Invariants), and no goal is the bad pose itself (the arm may move toward it
    as far as that is safe, as on the way to a joint limit). Without app.c's final check the
    NaN, limit, leg and body cases fail here; the far branch's straight move (joints 2-3
    pass through hanging down while joint 1 turns) is clear by itself, a case where the
    check must not get in the way."""
    board = make_board(lib=bad_ik_lib)
    lib = board.lib
    lib.bad_ik_set(0)
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.5) is not None
    board.send("set_position", x=TARGET[0], y=TARGET[1], z=TARGET[2])
    board.send("engage", on=1)
    assert inv.run_until(lambda: np.linalg.norm(ee_of_units(shaft_units(board)) - TARGET) < FK_TOL_MM, 3.0) is not None
    t_bad = board.time
    lib.bad_ik_set(BAD[bad])
    for k in range(8):
        p = (TARGET[0] + 5.0 * math.cos(k), TARGET[1] + 5.0 * math.sin(k), TARGET[2])
        board.send("set_position", x=p[0], y=p[1], z=p[2])
        inv.run(0.25)
    goals = inv.goals(t_bad)
    assert len(goals) >= 150                                   # the ticks went on
    if bad in FIXED_POSES:
        assert not (goals == fixed_units(bad)).all(axis=1).any()
    lib.bad_ik_set(0)
    inv.run(0.5)
