"""`uavarm sim`, `uavarm workspace` and the report's entry point, from the shell's side."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from uavarm import cli, scenarios, sim_report, workspace
from uavarm.model import config


def test_sim_prints_the_table_and_writes_the_plots(tmp_path, capsys):
    rc = cli.main(["sim", "bench", "--seconds", "1", "--settle", "1", "--seeds", "2",
                   "--set", "estimator.complementary_gyro_weight=0.97", "--plots", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0
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


def test_workspace_plot(tmp_path, capsys):
    out = tmp_path / "ws.png"
    assert cli.main(["workspace", "--out", str(out)]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"
    assert "valid" in capsys.readouterr().out


def test_workspace_classes_follow_the_models_limits():
    """The sampled classes agree with the model's limits, computed plainly here."""
    m = config.load()
    ee, j3, cls = workspace.sample(m, steps=(9, 9, 9))
    assert ee.shape == (729, 3) and set(np.unique(cls)) <= {0, 1, 2, 3}
    axes = [np.linspace(max(l.min_deg - 20, -180), min(l.max_deg + 20, 180), 9) for l in m.limits]
    q = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    outside = np.zeros(len(q), bool)
    for j, l in enumerate(m.limits):
        outside |= (q[:, j] < l.min_deg - 1e-9) | (q[:, j] > l.max_deg + 1e-9)
    assert np.array_equal(cls == 1, outside)
    inside = ~outside
    above = (ee[:, 2] >= m.body_z) | (j3[:, 2] >= m.body_z)
    assert np.array_equal((cls == 2)[inside], above[inside])


def test_report_stops_on_an_unknown_estimator_key(tmp_path, capsys):
    rc = sim_report.main(["--out", str(tmp_path), "--estimators", "model", "--set", "estimator.kindd=1",
                          "--seconds", "1", "--seeds", "1"])
    assert rc == 2 and "estimator model" in capsys.readouterr().err
    assert not (tmp_path / "report.md").exists()


def test_report_writes_the_markdown_table(tmp_path):
    rc = sim_report.main(["--out", str(tmp_path), "--estimators", "model", "--scenarios", "bench", "hover",
                          "--seconds", "1", "--seeds", "1", "--jobs", "1"])
    assert rc == 0
    text = (tmp_path / "report.md").read_text()
    assert "| bench tilting | model |" in text and "| hover in gusty wind | model |" in text
    assert len(list((tmp_path / "plots").glob("*.png"))) == 4
