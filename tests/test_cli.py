"""The `uavarm` command line."""
from uavarm import cli


def test_demo_reaches_engaged_state(capsys):
    assert cli.main(["demo", "--seconds", "2.5"]) == 0
    out = capsys.readouterr().out
    assert "engaged 1" in out and "faults []" in out


def test_codegen_check_passes_through(capsys):
    assert cli.main(["codegen", "--check"]) == 0
    assert "up to date" in capsys.readouterr().out
