"""The package layout is the architecture: each subpackage of `uavarm` imports only the layers
below it, so the folder tree can be read as the dependency graph (README, "Layout")."""
from __future__ import annotations

import ast
import importlib
from pathlib import Path

import uavarm

PACKAGE = Path(uavarm.__file__).parent
# what each subpackage may import from uavarm besides itself (model and codegen are the base;
# link is the ROS package's, which runs on the robot without the rest)
ALLOWED = {
    "m4": set(),
    "build": {"model", "codegen", "toml_text"},
    "link": set(),
    "sim": {"model", "build", "link", "toml_text", "rotation"},
    "calibrate": {"model", "link", "rotation"},
}


def uavarm_imports(path: Path, package: str) -> set[str]:
    """The uavarm subpackages a module imports, relative imports resolved."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level == 0:
                parts = (node.module or "").split(".")
                if parts[0] != "uavarm":
                    continue
                rest = parts[1:]
            else:
                base = ["uavarm", package][: 3 - node.level] if node.level <= 2 else []
                rest = (base + (node.module or "").split("."))[1:] if node.module else base[1:]
            if rest and rest[0]:
                found.add(rest[0])
            elif node.level == 0 or not node.module:
                found.update(a.name for a in node.names)
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "uavarm" and len(parts) > 1:
                    found.add(parts[1])
    return found


def test_each_subpackage_imports_only_the_layers_below_it():
    wrong = []
    for package, allowed in ALLOWED.items():
        folder = Path(list(importlib.import_module(f"uavarm.{package}").__path__)[0])
        assert list(folder.glob("*.py")), folder
        for path in sorted(folder.glob("*.py")):
            used = uavarm_imports(path, package) - {package}
            for name in sorted(used - allowed):
                wrong.append(f"uavarm/{package}/{path.name} imports uavarm.{name}")
    assert not wrong, "\n".join(wrong)


def test_the_layering_check_sees_a_forbidden_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from ..sim import board\nfrom uavarm.calibrate import fit\nfrom . import llcp\n")
    assert uavarm_imports(bad, "link") == {"sim", "calibrate", "link"}


def test_the_public_names_stay_where_users_import_them():
    from uavarm import sim
    from uavarm.calibrate import command, imu, mounting, servos  # noqa: F401
    from uavarm.link import ArmLink, CommandRefused, LinkError  # noqa: F401
    assert callable(sim.simulate) and callable(sim.Settings)
