"""The generated tree: fresh, deterministic, float32-only, builds for the Cortex-M4, and
follows the model file when a user edits it."""
import functools
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from conftest import ROOT, require_arm_toolchain
from uavarm.build import firmware, generated, target
from uavarm.codegen import board_ioc, generate
from uavarm.model import config, kinematics

GENERATED = ROOT / "generated"
render_uncached = generate.render


@functools.cache
def rendered(model_path, text: str) -> dict[str, str]:
    return render_uncached(model_path)


@pytest.fixture(autouse=True)
def render_once(monkeypatch):
    """The SymPy behind a render takes seconds: each model file's text is rendered once here,
    whichever test asks (`generate.main` included)."""
    def render(model_path=config.DEFAULT_MODEL):
        return dict(rendered(model_path, model_path.read_text()))
    monkeypatch.setattr(generate, "render", render)


def test_committed_tree_is_fresh(tmp_path):
    """Regenerating equals the committed generated/ (CI fails on a stale tree)."""
    files = generate.render()
    stale = [n for n, text in files.items() if (GENERATED / n).read_text() != text]
    assert not stale, f"stale: {stale}; run `make codegen` and commit generated/"
    assert sorted(p.name for p in GENERATED.iterdir()) == sorted(files)


def test_a_fresh_process_with_another_hash_seed_renders_what_contexts_remembered_do(tmp_path):
    """render() remembers the kinematics, filters and estimator contexts by the model values
    each read (codegen/remember.py): after the committed model, a model with another
    accelerometer filter (its kinematics and estimator taken from memory, its filters not)
    renders in this process exactly what a fresh process writes for it, and that process runs
    with another hash seed (set and dict orders differ): the output is deterministic. (One
    fresh process for both: each is a SymPy render of seconds. The committed tree, written by
    `make codegen` in a process of its own, is compared with this process's render in
    test_committed_tree_is_fresh.)"""
    from uavarm.build import variants
    render_uncached()
    path = tmp_path / "manipulator.toml"
    path.write_text(variants.edited_text({"filters.accel.cutoff": 15.0}))
    here = render_uncached(path)
    out = tmp_path / "fresh"
    env = dict(os.environ, PYTHONHASHSEED="12345")
    subprocess.run([sys.executable, "-m", "uavarm.codegen", "--model", str(path), "--out", str(out)], env=env,
                   check=True, capture_output=True)
    assert here == {p.name: p.read_text() for p in out.iterdir()}


def test_headers_say_where_they_came_from(model):
    for path in GENERATED.iterdir():
        head = path.read_text()[:600]
        assert "DO NOT EDIT" in head and "make codegen" in head
        assert model.sha256[:16] in head and "model/manipulator.toml" in head


DOUBLE_PATTERNS = {
    "double type": r"\bdouble\b",
    "literal without f": r"(?<![\w.])(\d+\.\d*|\.\d+)(e[+-]?\d+)?(?![\w.])(?!f)",
    "M_PI": r"\bM_PI",
    "double libm call": r"\b(sin|cos|tan|asin|acos|atan|atan2|sqrt|pow|exp|log|fabs|floor|ceil|round|fmax|fmin)\s*\(",
}


FLOAT32_C = sorted(GENERATED.glob("*.[ch]")) + sorted((firmware.APP / "Src").glob("*.c")) + \
    sorted((firmware.APP / "Inc").glob("*.h"))


@pytest.mark.parametrize("what", DOUBLE_PATTERNS)
def test_no_double_precision_in_generated_or_application_c(what):
    for path in FLOAT32_C:
        code = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
        hits = re.findall(DOUBLE_PATTERNS[what], code)
        assert not hits, f"{path.name}: {what}: {hits[:5]}"


def test_target_build_has_no_double_arithmetic(tmp_path):
    """The generated code and the whole portable application compile for Cortex-M4F with
    warnings as errors, and the objects call no double-precision helper (__aeabi_d*) or
    double libm function. Prints flash and RAM per file."""
    require_arm_toolchain()
    sizes = target.cross_compile(firmware.app_sources(), [GENERATED, firmware.APP / "Inc"], tmp_path)
    for name, (text, data, bss) in sizes.items():
        print(f"{name}: text {text} data {data} bss {bss}")
    objs = sorted(tmp_path.glob("*.o"))
    assert len(objs) == len(firmware.app_sources())
    undefined = subprocess.run(["arm-none-eabi-nm", "-u", *map(str, objs)],
                               capture_output=True, text=True, check=True).stdout
    symbols = {line.split()[-1] for line in undefined.splitlines() if line.strip().startswith("U")}
    bad = {s for s in symbols if s.startswith("__aeabi_d") or s in
           {"sin", "cos", "atan2", "sqrt", "pow", "fabs", "acos", "asin", "atan", "floor", "round"}}
    assert not bad, bad


def test_editing_the_model_changes_the_code_and_it_stays_correct(tmp_path):
    """A user changes L2 in the model file; the regenerated C follows and is still exact."""
    text = config.DEFAULT_MODEL.read_text().replace("L2 = 65.0", "L2 = 70.0")
    model_path = tmp_path / "manipulator.toml"
    model_path.write_text(text)
    out = tmp_path / "generated"
    assert generate.main(["--model", str(model_path), "--out", str(out)]) == 0
    assert (out / "kinematics.c").read_text() != (GENERATED / "kinematics.c").read_text()

    m = config.load(model_path)
    ffi, lib = generated.load(out)
    f = sp.lambdify(kinematics.JOINT_SYMBOLS, list(kinematics.fk_points(m)[1]), modules="numpy")
    rng = np.random.default_rng(11)
    q_in, ee, res = ffi.new("float[3]"), ffi.new("float[3]"), ffi.new("kin_ik_t *")
    for q in rng.uniform(-1.5, 1.5, size=(2000, 3)).astype(np.float32):
        q_in[0:3] = q.tolist()
        lib.kin_fk_ee(q_in, ee)
        want = np.array(f(*q.astype(np.float64)))
        assert np.max(np.abs(np.array(list(ee)) - want)) < 1e-3
        lib.kin_ik(ee, q_in, res)
        for i in range(4):
            if res.status[i] != 1:
                got = np.array(f(*np.array(list(res.q[i]), dtype=np.float64)))
                assert np.max(np.abs(got - np.array(list(ee)))) < 2e-3


def test_check_mode_reports_staleness(tmp_path):
    out = tmp_path / "gen"
    assert generate.main(["--out", str(out)]) == 0
    assert generate.main(["--out", str(out), "--check"]) == 0
    (out / "filters.c").write_text("/* edited by hand */\n")
    assert generate.main(["--out", str(out), "--check"]) == 1


def copy_board(dest):
    """The two board project files make codegen writes, copied to dest."""
    for name in (board_ioc.IOC, board_ioc.MAIN_H):
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(board_ioc.BOARD / name, dest / name)
    return dest


def test_committed_board_project_carries_the_model_numbers():
    """manipulator.ioc's user constants and main.h's #defines of them are the model's
    (CI fails if make codegen would change them)."""
    files = board_ioc.render(config.DEFAULT_MODEL)
    stale = [n for n, text in files.items() if (board_ioc.BOARD / n).read_text() != text]
    assert not stale, f"stale: {stale}; run `make codegen` and commit firmware_stm32/"


def test_a_model_change_reaches_the_ioc_and_main_h(tmp_path):
    board = copy_board(tmp_path / "fw")
    ioc = board / board_ioc.IOC
    ioc.write_text(ioc.read_text().replace("Mcu.UserConstants=", "Mcu.UserConstants=LED_CNT,999;"))
    text = config.DEFAULT_MODEL.read_text().replace("baud = 200000", "baud = 1000000")
    model_path = tmp_path / "manipulator.toml"
    model_path.write_text(text.replace("sample_rate = 100.0", "sample_rate = 200.0"))
    assert generate.main(["--model", str(model_path), "--out", str(tmp_path / "gen"), "--board", str(board)]) == 0
    assert "\nMcu.UserConstants=LED_CNT,999;SERVO_BAUD,1000000;TICK_PERIOD,4999\n" in ioc.read_text()
    main_h = (board / board_ioc.MAIN_H).read_text()
    assert "#define LED_CNT 999\n#define SERVO_BAUD 1000000\n#define TICK_PERIOD 4999\n#define CFG0_Pin" in main_h


def test_check_mode_covers_the_board_project(tmp_path):
    board, out = copy_board(tmp_path / "fw"), tmp_path / "gen"
    assert generate.main(["--out", str(out), "--board", str(board)]) == 0
    assert generate.main(["--out", str(out), "--board", str(board), "--check"]) == 0
    ioc = board / board_ioc.IOC
    ioc.write_text(ioc.read_text().replace("SERVO_BAUD,200000", "SERVO_BAUD,115200"))
    assert generate.main(["--out", str(out), "--board", str(board), "--check"]) == 1
    assert generate.main(["--out", str(out), "--board", str(board)]) == 0
    assert "SERVO_BAUD,200000" in ioc.read_text()
