"""A grid of model edits through the closed-loop simulator: how the end-effector error
depends on gains, so that they are chosen by measurement.

    python -m uavarm.sim.sweep --estimator link-velocity \\
        --vary estimator.link_gain=0.05,0.2,0.5 --vary estimator.velocity_bandwidth=0.3,0.5,1.0 \\
        --scenarios hover manoeuvre --seeds 2 --seconds 30

Every combination of the --vary values runs every scenario with every seed (the same seeds
for each combination); the table lists each combination's EE RMS and p95 per scenario,
pooled over the seeds, best first by the worst scenario's RMS, and the drone's messages the
gate refused (and the streams it dropped) in all of them.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import time
from dataclasses import replace
from pathlib import Path

from ..build import generated, variants
from . import closed_loop, report, scenarios


def parse_vary(text: str) -> tuple[str, list[str]]:
    key, eq, values = text.partition("=")
    items = [v.strip() for v in values.split(",") if v.strip()]
    if not eq or not key or not items:
        raise variants.VariantError(f"--vary {text!r}: expected KEY=V1,V2,...")
    return key.strip(), items


def combinations(varies: list[tuple[str, list[str]]]) -> list[list[str]]:
    """Each combination as --set strings."""
    keys = [k for k, _ in varies]
    return [[f"{k}={v}" for k, v in zip(keys, values)] for values in itertools.product(*(vs for _, vs in varies))]


def table(results: list[tuple[list[str], dict]], scenario_names: list[str]) -> str:
    header = (["edits"] + [f"{s} {what}" for s in scenario_names for what in ("RMS mm", "p95 mm")]
              + ["worst RMS mm", "drone msgs refused (drops)"])
    rows = [header, ["---"] + ["---:"] * (len(header) - 1)]
    for sets, rows_of in sorted(results, key=lambda r: max(v.rms for v in r[1].values())):
        cells = [" ".join(sets) or "(none)"]
        for s in scenario_names:
            cells += [f"{rows_of[s].rms:.2f}", f"{rows_of[s].p95:.2f}"]
        cells.append(f"{max(v.rms for v in rows_of.values()):.2f}")
        cells.append(f"{sum(v.refused for v in rows_of.values())} ({sum(v.dropped for v in rows_of.values())})")
        rows.append(cells)
    return "\n".join("| " + " | ".join(r) + " |" for r in rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m uavarm.sim.sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--estimator", default=None, help=f"a preset ({', '.join(variants.PRESETS)}); default the model's")
    ap.add_argument("--vary", action="append", default=[], metavar="KEY=V1,V2,...", required=True)
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="edits every combination shares")
    ap.add_argument("--scenarios", nargs="+", default=["hover", "manoeuvre"])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="also write the table to this Markdown file")
    args = ap.parse_args(argv)
    try:
        varies = [parse_vary(v) for v in args.vary]
        combos = combinations(varies)
        changes = [variants.edits(args.estimator, args.sets + sets) for sets in combos]
        for ch in changes:
            variants.build(ch)   # an unknown key or a bad value stops before any run
        loaded = {name: scenarios.load(name) for name in args.scenarios}
    except (variants.VariantError, scenarios.ScenarioError, generated.StaleCode) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    settings = replace(closed_loop.Settings(), seconds=args.seconds)
    jobs = [(loaded[s], ch, " ".join(sets), seed, settings)
            for sets, ch in zip(combos, changes) for s in args.scenarios for seed in range(args.seeds)]
    t0 = time.monotonic()
    runs = report.run_jobs(jobs, args.jobs)
    results, k = [], 0
    for sets in combos:
        per_scenario = {}
        for s in args.scenarios:
            per_scenario[s] = report.summarise([r for r, _ in runs[k:k + args.seeds]])
            k += args.seeds
        results.append((sets, per_scenario))
    text = table(results, args.scenarios)
    head = (f"Sweep: estimator {args.estimator or 'model'}, shared edits {args.sets or 'none'}; "
            f"{args.seeds} seeds x {args.seconds:g} s per scenario; wall time {time.monotonic() - t0:.0f} s.")
    print(head)
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(f"{head}\n\nCommand: `python -m uavarm.sim.sweep {' '.join(argv or sys.argv[1:])}`\n\n"
                            f"{text}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
