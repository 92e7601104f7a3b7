import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import time
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
    from uavarm.build import generated
    return generated.default()


def once_per_run(tmp_path_factory, name: str, make):
    """make(folder) once per test run, whichever of its processes (pytest-xdist workers) asks
    first; the others wait for it and get the same result (JSON) and folder. A module fixture
    alone runs again in every worker that gets one of its module's tests (--dist worksteal
    splits modules)."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent                  # the run's folder, above each worker's own
    from uavarm.build.cbuild import exclusive
    done = root / f"{name}.json"
    with exclusive(root / f"{name}.lock"):
        if not done.exists():
            folder = root / name
            shutil.rmtree(folder, ignore_errors=True)     # (what a failed attempt left)
            folder.mkdir()
            done.write_text(json.dumps(make(folder)))
    return json.loads(done.read_text())


def sympy_at_30_digits(exprs):
    """The SymPy model's expressions as one mpmath function of a {symbol: value} dict, at 30
    digits: the oracle the generated float32 C is held to."""
    import mpmath as mp
    import sympy as sp
    syms = sorted(set().union(*(sp.sympify(e).free_symbols for e in exprs)), key=str)
    f = sp.lambdify(syms, exprs, modules="mpmath", cse=True)   # (shared subexpressions once: same values)

    def evaluate(subs):
        with mp.workdps(30):
            return [float(v) for v in f(*[mp.mpf(float(subs[s])) for s in syms])]
    return evaluate


def skip_unless_ci(missing: str, how: str):
    """A tool a test needs is missing: skipped on a developer machine, a failure in CI (CI set)."""
    if os.environ.get("CI"):
        pytest.fail(f"{missing} missing in CI: {how}")
    pytest.skip(f"{missing} not installed: {how}")


def require_arm_toolchain():
    """The target checks may only be skipped on a developer machine, never in CI."""
    if shutil.which("arm-none-eabi-gcc") is None:
        skip_unless_ci("arm-none-eabi-gcc", "apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi")


def require_ros():
    """rospy (and roscore, roslaunch, genpy) for the ROS node tests: skipped on a developer
    machine without ROS 1, never in CI."""
    missing = None
    try:
        from uavarm.link.ros_node import STD_MSGS_DEFINITIONS, import_ros
        rospy = import_ros()
        import genpy  # noqa: F401  (generates the node's msg and srv classes)
        import nav_msgs.msg, sensor_msgs.msg, std_srvs.srv, tf2_ros  # noqa: E401,F401
    except ImportError as exc:
        missing = exc.name or str(exc)
    if missing is None:
        missing = next((tool for tool in ("roscore", "roslaunch") if shutil.which(tool) is None), None)
    if missing is None and not Path("/usr/lib/robot_state_publisher/robot_state_publisher").exists():
        missing = "robot_state_publisher"
    if missing is None and not STD_MSGS_DEFINITIONS.exists():
        missing = "ros-std-msgs"
    if missing is not None:
        packages = ("ros-core python3-rospy python3-std-srvs python3-geometry-msgs python3-sensor-msgs "
                    "python3-nav-msgs python3-genpy ros-robot-state-publisher python3-tf2-ros ros-std-msgs")
        if os.environ.get("CI"):
            pytest.fail(f"ROS 1 ({missing}) missing in CI: .ci/run must install {packages}")
        pytest.skip(f"ROS 1 not installed ({missing} missing): apt-get install {packages}")
    return rospy


CATKIN_PACKAGES = "catkin ros-message-generation python3-gencpp catkin-lint ros-std-msgs libstd-msgs-dev"
# a shell with the system's tools only (no virtualenv): as on the robot
SYSTEM_ENV = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}


def catkin_workspace(folder: Path) -> Path:
    """ros/uavarm_ros in a fresh catkin workspace at `folder`, built with Debian's catkin and
    the system Python (`catkin_make`); `source folder/devel/setup.bash` then finds it."""
    require_catkin()
    shutil.copytree(ROOT / "ros" / "uavarm_ros", folder / "src" / "uavarm_ros")
    out = subprocess.run(["catkin_make", "-DPYTHON_EXECUTABLE=/usr/bin/python3"], cwd=folder, env=SYSTEM_ENV,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return folder


def require_catkin():
    """Debian's catkin with message generation, and catkin_lint, for the package's build:
    skipped on a developer machine without them, never in CI."""
    missing = next((tool for tool in ("catkin_make", "catkin_lint") if shutil.which(tool) is None), None)
    if missing is None and not Path("/usr/share/message_generation/cmake").exists():
        missing = "message_generation"
    if missing is None and not Path("/usr/include/std_msgs/Header.h").exists():
        missing = "libstd-msgs-dev"
    if missing is not None:
        if os.environ.get("CI"):
            pytest.fail(f"{missing} missing in CI: .ci/run must install {CATKIN_PACKAGES}")
        pytest.skip(f"{missing} not installed: apt-get install {CATKIN_PACKAGES}")


def require_clang_fuzzer():
    """clang with libFuzzer, ASan and UBSan, and atheris, for the fuzz harnesses (fuzz/):
    skipped on a developer machine without them, never in CI."""
    import subprocess
    import tempfile
    missing = None
    cc = shutil.which("clang") or shutil.which("clang-14")
    if cc is None:
        missing = "clang"
    else:
        with tempfile.TemporaryDirectory() as tmp:
            src = Path(tmp) / "probe.c"
            src.write_text("#include <stddef.h>\n#include <stdint.h>\n"
                           "int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; return (int)(n & 0); }\n")
            proc = subprocess.run([cc, "-fsanitize=fuzzer,address,undefined", str(src), "-o", str(Path(tmp) / "probe")],
                                  capture_output=True)
            if proc.returncode != 0:
                missing = "libFuzzer/sanitizer runtimes (libclang-rt-14-dev)"
    if missing is None:
        try:
            import atheris  # noqa: F401
        except ImportError:
            missing = "atheris (pip)"
    if missing is not None:
        skip_unless_ci(missing, "apt-get install clang libclang-rt-14-dev; pip install atheris")


def pytest_report_header(config):
    """The hypothesis seed of this run (pyproject.toml sets one; --hypothesis-seed=N for another)."""
    return f"hypothesis seed: {config.getoption('hypothesis_seed', None)}"


def pytest_terminal_summary(terminalreporter, config):
    terminalreporter.write_line(pytest_report_header(config))


def wait_simulated(sitl, seconds: float, until=lambda: False) -> bool:
    """Wait until until() holds or the SITL's board has run `seconds` of simulated time (its
    clock, not the wall's: a busy machine slows both alike); until()'s last value. The SITL's
    clock raises if the board stops moving, so this never hangs."""
    end = sitl.clock() + seconds
    while not until():
        if sitl.clock() >= end:
            return bool(until())
        time.sleep(0.002)        # (a poll's interval)
    return True


def free_port() -> int:
    """A TCP port free now, chosen below the kernel's ephemeral range: a port the kernel hands
    out (bind to port 0, a connection out) could be taken by another process between this
    check and its user's bind, as a roscore once found."""
    try:
        low = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        low = 32768
    pick = random.SystemRandom()
    for _ in range(200):
        port = pick.randrange(10000, max(low, 10001))
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError(f"no free TCP port between 10000 and {low}")


def stop_group(proc: subprocess.Popen, timeout: float = 10.0) -> None:
    """SIGINT the process group (roslaunch / roscore shut their children down), then kill."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=timeout)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=timeout)

