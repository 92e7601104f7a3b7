"""kin_check_joints against the plain-geometry oracle on a dense joint-space grid."""
import numpy as np

import oracles


def test_joint_space_grid(model, gen):
    ffi, lib = gen
    # 1.5-degree steps in joint 1 (legs are 20 degrees wide), 5 degrees in joints 2 and 3,
    # past the limits so refusals are covered too; offset so no point sits on a boundary
    axes = [np.radians(np.arange(-179.7, 180.0, 1.5)),
            np.radians(np.arange(-136.3, 137.0, 5.0)),
            np.radians(np.arange(-131.3, 132.0, 5.0))]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3).astype(np.float32)
    q = ffi.new("float[3]")
    got = np.empty(len(grid), dtype=int)
    for i, v in enumerate(grid):
        q[0], q[1], q[2] = float(v[0]), float(v[1]), float(v[2])
        got[i] = lib.kin_check_joints(q)
    want, clear = oracles.check_pose(model, grid.astype(np.float64), margin=1e-4)
    counts = np.bincount(got, minlength=5)
    print(f"\n{len(grid)} joint vectors: ok {counts[0]}, limit {counts[2]}, body {counts[3]}, "
          f"leg {counts[4]}; {(~clear).sum()} within 1e-4 of a boundary")
    mismatch = (got != want) & clear
    assert mismatch.sum() == 0, grid[mismatch][:5]
    assert min(counts[0], counts[2], counts[3], counts[4]) > 1000     # every outcome exercised
    assert (~clear).mean() < 0.02


def test_non_finite_joints_are_refused(gen):
    ffi, lib = gen
    for bad in (float("nan"), float("inf")):
        assert lib.kin_check_joints(ffi.new("float[3]", [0.0, bad, 0.0])) != 0
