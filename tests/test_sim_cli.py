"""`uavarm sim`, `uavarm workspace` and the report's entry point, from the shell's side."""
from __future__ import annotations

import math
import re

from dataclasses import replace

import numpy as np
import pytest

from uavarm import cli
from uavarm.model import config
from uavarm.sim import scenarios, report as sim_report, sweep, workspace


def test_sim_prints_the_table_and_writes_the_plots(tmp_path, capsys):
    rc = cli.main(["sim", "bench", "--seconds", "1", "--settle", "1", "--seeds", "2", "--estimator", "complementary",
                   "--set", "estimator.complementary_gyro_weight=0.97", "--plots", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
    assert "unreachable" not in out
    lines = [l for l in out.splitlines() if l.startswith("bench tilting")]
    assert len(lines) == 3 and "all 2 seeds" in lines[-1]
    assert "EE RMS mm" in out and "att RMS deg" in out
    pngs = sorted(p.name for p in tmp_path.glob("*.png"))
    assert len(pngs) == 4 and all(p.endswith(("-error.png", "-attitude.png")) for p in pngs)
    assert all((tmp_path / p).read_bytes()[:4] == b"\x89PNG" for p in pngs)


@pytest.mark.parametrize("argv, msg", [
    (["sim", "nowhere.toml"], "not a built-in scenario"),
    (["sim", "bench", "--set", "estimator.nope=1"], "estimator.nope: no such key"),
    (["sim", "bench", "--estimator", "kalman"], "unknown estimator preset"),
])
def test_sim_refuses_bad_input_with_a_reason(argv, msg, capsys):
    assert cli.main(argv + ["--plots", ""]) == 2
    assert msg in capsys.readouterr().err


def test_a_key_the_estimator_does_not_read_is_refused(capsys):
    """The committed model's estimator is the quaternion one with the drone's attitude and velocity."""
    est = config.load().estimator
    assert est.kind == "quaternion" and est.drone_attitude and est.drone_velocity
    assert cli.main(["sim", "bench", "--set", "estimator.complementary_gyro_weight=0.98", "--plots", ""]) == 2
    err = capsys.readouterr().err
    assert "estimator.complementary_gyro_weight: not used by the quaternion estimator" in err
    assert cli.main(["sim", "bench", "--estimator", "quaternion", "--set", "estimator.link_gain=0.2",
                     "--plots", ""]) == 2
    assert "estimator.link_gain: not used without the drone's attitude" in capsys.readouterr().err
    assert cli.main(["sim", "bench", "--estimator", "complementary", "--set", "estimator.accel_gain=0.2",
                     "--plots", ""]) == 2
    assert "estimator.accel_gain: not used by the complementary estimator" in capsys.readouterr().err
    assert cli.main(["sim", "bench", "--estimator", "link", "--set", "estimator.velocity_bandwidth=0.3",
                     "--plots", ""]) == 2
    assert "estimator.velocity_bandwidth: not used without the drone's velocity" in capsys.readouterr().err
    assert cli.main(["sim", "bench", "--estimator", "quaternion", "--set", "estimator.accel_bias_bandwidth=1.0",
                     "--plots", ""]) == 2
    assert "estimator.accel_bias_bandwidth: not used without the drone's velocity" in capsys.readouterr().err
    assert cli.main(["sim", "bench", "--estimator", "imu-velocity", "--set", "estimator.fc_error_gain=0.3",
                     "--plots", ""]) == 2
    assert "estimator.fc_error_gain: used only with both" in capsys.readouterr().err
    assert cli.main(["sim", "bench", "--estimator", "quaternion", "--set", "estimator.link_timeout=0.2",
                     "--plots", ""]) == 2
    assert "estimator.link_timeout: not used without the drone's attitude or velocity" in capsys.readouterr().err


def estimates(variant, seconds=3.0):
    """The firmware's (roll, pitch) estimate every tick on a rocking board."""
    from uavarm.sim.board import Rocking, SimBoard
    board = SimBoard(variant.model, lib=(variant.ffi, variant.lib), motion=Rocking(0.2, 0.1, 0.7), record=False)
    stab = variant.ffi.addressof(board.app, "stab")
    roll, pitch = variant.ffi.new("float *"), variant.ffi.new("float *")
    out = []
    while board.time < seconds:
        board.run(1 / board.model.sample_rate)
        variant.lib.stab_attitude(stab, roll, pitch)
        out.append((roll[0], pitch[0]))
    return np.array(out)


def test_the_refused_keys_change_nothing_and_the_others_do():
    """What the refusal rests on, in the firmware: the complementary weight changes nothing
    with the quaternion estimator, and does change the complementary one's estimate."""
    from uavarm.build import variants
    weight = "estimator.complementary_gyro_weight=0.5"
    assert variants.unused(variants.edits(None, [weight]), config.load().estimator)
    assert np.array_equal(estimates(variants.build({})), estimates(variants.build(variants.edits(None, [weight]))))
    complementary = variants.build(variants.edits("complementary"))
    assert not variants.unused(variants.edits(None, [weight]), complementary.model.estimator)
    assert not np.array_equal(estimates(complementary),
                              estimates(variants.build(variants.edits("complementary", [weight]))))


def test_a_target_never_reachable_is_named_and_the_run_fails(tmp_path, capsys):
    """300 mm out is beyond the reach L2 + L3 of the committed model (138.5 mm): named under the
    table, exit 1."""
    (tmp_path / "far.toml").write_text('name = "far"\nkind = "bench"\n[arm]\ntarget = [300.0, 0.0, -100.0]\n')
    assert cli.main(["sim", str(tmp_path / "far.toml"), "--seconds", "1", "--settle", "1", "--preflight", "1",
                     "--plots", ""]) == 1
    out = capsys.readouterr().out
    assert "the target (300.0, 0.0, -100.0) mm is unreachable" in out and "refused it on every tick" in out


@pytest.fixture
def stale_generated(tmp_path, monkeypatch):
    """generated/ as `make codegen` left it for another version of the model file."""
    from uavarm.build import generated
    for path in generated.GENERATED.iterdir():
        text = path.read_text()
        sha = config.load().sha256[:16]
        assert f"(sha256 {sha})" in text
        (tmp_path / path.name).write_text(text.replace(f"(sha256 {sha})", "(sha256 0123456789abcdef)"))
    monkeypatch.setattr(generated, "GENERATED", tmp_path)


@pytest.mark.parametrize("argv", [["sim", "hover", "--plots", ""], ["demo"], ["sitl"]])
def test_code_generated_from_another_model_is_refused(stale_generated, argv, capsys):
    assert cli.main(argv) == 1
    captured = capsys.readouterr()
    assert "run `make codegen`" in captured.err and "0123456789abcdef" in captured.err
    assert captured.out == ""


def test_exported_flight_log_replays(tmp_path, capsys):
    log = tmp_path / "flight.csv"
    assert cli.main(["sim", "hover", "--seconds", "1", "--settle", "1", "--plots", "", "--export-log", str(log)]) == 0
    (tmp_path / "replay.toml").write_text('kind = "replay"\n[motion]\ncsv = "flight.csv"\n')
    capsys.readouterr()
    assert cli.main(["sim", str(tmp_path / "replay.toml"), "--seconds", "1", "--settle", "1", "--plots", ""]) == 0
    assert "replay" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(scenarios.BUILTIN))
def test_show_prints_a_scenario_file_that_loads_as_the_scenario(name, tmp_path, capsys):
    assert cli.main(["sim", name, "--show", "--imu", "datasheet"]) == 0
    path = tmp_path / f"{name}.toml"
    path.write_text(capsys.readouterr().out)
    want = replace(scenarios.load(name), imu_profile="datasheet")
    assert replace(scenarios.load(path), base_dir=None) == want


def test_show_refuses_an_unknown_scenario(capsys):
    assert cli.main(["sim", "nowhere.toml", "--show"]) == 2
    assert "not a built-in scenario" in capsys.readouterr().err


def test_sim_rejects_nonsense_durations(capsys):
    with pytest.raises(SystemExit):
        cli.main(["sim", "bench", "--seconds", "0"])


def test_workspace_figure_png_and_pdf_with_the_reach_of_plain_geometry(tmp_path, capsys):
    """The horizontal reach ahead and behind is the stretched arm level with the shoulder
    (L2 + L3, below the body plane); beside a leg the leg distance; the lowest point the arm
    hanging straight down (L1 + L2 + L3). Within the figure's 0.5 mm grid."""
    m = config.load()
    out = tmp_path / "ws.png"
    assert cli.main(["workspace", "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG" and out.with_suffix(".pdf").read_bytes()[:4] == b"%PDF"
    printed = capsys.readouterr().out
    figures = {k: float(v) for k, v in re.findall(r"(reach|reach behind|reach beside a leg|lowest) (-?[\d.]+) mm",
                                                     printed)}
    assert figures["reach"] == pytest.approx(m.L2 + m.L3, abs=0.5)
    assert figures["reach behind"] == pytest.approx(m.L2 + m.L3, abs=0.5)
    assert figures["reach beside a leg"] == pytest.approx(m.leg_distance, abs=0.5)
    assert figures["lowest"] == pytest.approx(-(m.L1 + m.L2 + m.L3), abs=0.5)


def test_workspace_ik_reaches_each_point_through_the_models_own_kinematics():
    m = config.load()
    pred = workspace.Predicates(m)
    rng = np.random.default_rng(5)
    u, z = rng.uniform(-200, 200, 4000), rng.uniform(-220, 60, 4000)
    for q2, q3 in workspace.plane_ik(m, u, z):
        ok = np.isfinite(q3)
        _, _, fu, fz = pred.in_plane(0.0, q2[ok], q3[ok])
        assert np.allclose(fu, u[ok], atol=1e-9) and np.allclose(fz, z[ok], atol=1e-9)
    far = np.hypot(u, z + m.L1) > m.L2 + m.L3 + 1e-9
    assert far.any() and all(np.isnan(q3[far]).all() for _, q3 in workspace.plane_ik(m, u, z))


def test_workspace_classes_agree_with_the_models_predicates_and_plain_geometry():
    """The point of a pose valid by the model's predicates is classed valid; no point in or
    above the body plane is, nor one beyond the leg distance in a leg's plane."""
    m = config.load()
    pred = workspace.Predicates(m)
    rng = np.random.default_rng(6)
    lo = np.radians([l.min_deg - 20 for l in m.limits])
    hi = np.radians([l.max_deg + 20 for l in m.limits])
    q = rng.uniform(lo, hi, (3000, 3))
    valid_class = workspace.CLASSES.index("valid")
    for q1, leg_plane in ((0.0, False), (math.radians(m.leg_angles[0]), True)):
        q[:, 0] = q1
        ok = pred.limits(*q.T) & pred.body(*q.T) & pred.legs(*q.T)
        _, _, u, z = pred.in_plane(q1, q[:, 1], q[:, 2])
        cls = workspace.classify_plane(m, pred, q1, u, z)
        assert ok.sum() > 300 and (cls[ok] == valid_class).all()
        grid_u, grid_z = np.meshgrid(np.linspace(-200, 200, 201), np.linspace(-220, 60, 141))
        grid = workspace.classify_plane(m, pred, q1, grid_u, grid_z)
        assert not (grid[grid_z > m.body_z + 1e-6] == valid_class).any()   # (on it: rounding)
        if leg_plane:
            assert not (grid[np.abs(grid_u) > m.leg_distance + 1e-6] == valid_class).any()


def test_report_stops_on_an_unknown_estimator_key(tmp_path, capsys):
    rc = sim_report.main(["--out", str(tmp_path), "--estimators", "model", "--set", "estimator.kindd=1",
                          "--seconds", "1", "--seeds", "1"])
    assert rc == 2 and "estimator model" in capsys.readouterr().err
    assert not (tmp_path / "report.md").exists()


@pytest.mark.parametrize("option", [["--without", "attitude-slow"], ["--sizes-as-drawn"]])
def test_report_refuses_a_draws_option_without_draws(option, tmp_path, capsys):
    rc = sim_report.main(["--out", str(tmp_path), "--fixed-errors", *option, "--seconds", "1", "--seeds", "1"])
    assert rc == 2 and f"{option[0]} needs the draws" in capsys.readouterr().err
    assert not (tmp_path / "report.md").exists()


@pytest.mark.parametrize("option", [["--preflight", "-1"], ["--preflight", "inf"], ["--seconds", "nan"]])
def test_report_refuses_durations_it_cannot_run(option, tmp_path, capsys):
    rc = sim_report.main(["--out", str(tmp_path), *option, "--seeds", "1"])
    assert rc == 2 and "--preflight at least 0" in capsys.readouterr().err
    assert not (tmp_path / "report.md").exists()


def test_report_writes_the_markdown_table(tmp_path):
    rc = sim_report.main(["--out", str(tmp_path), "--estimators", "model", "--scenarios", "bench", "hover",
                          "--seconds", "1", "--seeds", "1", "--jobs", "1"])
    assert rc == 0
    text = (tmp_path / "report.md").read_text()
    assert "| bench tilting | model |" in text and "| hover in gusty wind | model |" in text
    assert "EE RMS median mm | EE RMS p95 mm | EE RMS worst mm (seed)" in text
    assert "bench, model: the worst draw (seed 0): drone attitude" in text and "accelerometer bias (" in text
    assert len(list((tmp_path / "plots").glob("*.png"))) == 4


def test_a_sweep_runs_every_combination_best_first(tmp_path, capsys):
    out = tmp_path / "sweep.md"
    rc = sweep.main(["--estimator", "complementary", "--vary", "estimator.complementary_gyro_weight=0.5,0.98",
                     "--scenarios", "bench", "--seeds", "1", "--seconds", "1", "--jobs", "1", "--out", str(out)])
    assert rc == 0
    rows = [l for l in capsys.readouterr().out.splitlines() if l.startswith("| estimator.")]
    assert len(rows) == 2
    worst = [float(r.strip("| ").split(" | ")[-2]) for r in rows]
    assert worst == sorted(worst)                                     # best first
    assert all(r.strip("| ").split(" | ")[-1] == "0 (0)" for r in rows)   # no drone messages: none refused
    assert "Command: `python -m uavarm.sim.sweep" in out.read_text()


def test_a_sweep_across_draws_ranks_by_the_worst_scenarios_95th_percentile_of_the_seeds():
    """Gains chosen for the worst of the range: a combination with the lower pooled RMS but a
    bad draw ranks below one whose draws are all moderate."""
    def row(rms):
        return sim_report.Row("hover", "x", 3, 30.0, rms, 0.0, 0.0, 0.0, 0.0, 0, 0.0)
    steady = {"hover": (row(0.9), sim_report.Spread(0.9, 1.0, 1.0, 1))}
    lucky = {"hover": (row(0.8), sim_report.Spread(0.6, 1.8, 2.0, 2))}
    pooled = sweep.table([(["a=1"], lucky), (["a=2"], steady)], ["hover"])
    across = sweep.table([(["a=1"], lucky), (["a=2"], steady)], ["hover"], across=True)
    assert [l.split(" | ")[0] for l in pooled.splitlines()[2:]] == ["| a=1", "| a=2"]
    assert [l.split(" | ")[0] for l in across.splitlines()[2:]] == ["| a=2", "| a=1"]
    assert "hover RMS p95 across seeds mm" in across.splitlines()[0]


@pytest.mark.parametrize("argv, msg", [
    (["--vary", "estimator.lead_time"], "expected KEY=V1,V2"),
    (["--vary", "estimator.nope=1,2"], "estimator.nope: no such key"),
    (["--vary", "estimator.lead_time=0.04,5"], "lead_time"),
    (["--vary", "estimator.lead_time=0.04", "--scenarios", "nowhere.toml"], "not a built-in scenario"),
])
def test_a_sweep_refuses_bad_input_before_any_run(argv, msg, capsys):
    assert sweep.main(argv) == 2
    assert msg in capsys.readouterr().err
