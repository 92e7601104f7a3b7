"""A grid of model edits through the closed-loop simulator: how the end-effector error
depends on gains, so that they are chosen by measurement.

    python -m uavarm.sim.sweep --estimator link-velocity \\
        --vary estimator.link_gain=0.05,0.2,0.5 --vary estimator.velocity_bandwidth=0.3,0.5,1.0 \\
        --scenarios hover manoeuvre --seeds 2 --seconds 30

Every combination of the --vary values runs every scenario with every seed (the same seeds
for each combination); the table lists each combination's EE RMS and p95 per scenario,
pooled over the seeds, best first by the worst scenario's RMS, and the drone's messages the
gate refused (and the streams it dropped) in all of them. With --draw-errors each seed draws
its own errors across the ranges of `make sim-report` (uavarm.sim.error_ranges); the table
then also lists each scenario's 95th percentile of the seeds' RMS, and the best combination
is the one whose worst scenario has the smallest of those: gains chosen for the worst of
the range.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import time
from dataclasses import replace
from pathlib import Path

from ..build import generated, variants
from . import closed_loop, error_ranges, report, scenarios


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


def table(results: list[tuple[list[str], dict]], scenario_names: list[str], across: bool = False) -> str:
    """results: (edits, {scenario: (pooled Row, Spread across the seeds)})."""
    per = ("RMS mm", "p95 mm") + (("RMS p95 across seeds mm",) if across else ())
    header = (["edits"] + [f"{s} {what}" for s in scenario_names for what in per]
              + ["worst RMS mm", "drone msgs refused (drops)"])

    def worst(rows_of):
        return max(d.p95 if across else r.rms for r, d in rows_of.values())
    rows = [header, ["---"] + ["---:"] * (len(header) - 1)]
    for sets, rows_of in sorted(results, key=lambda r: worst(r[1])):
        cells = [" ".join(sets) or "(none)"]
        for s in scenario_names:
            r, d = rows_of[s]
            cells += [f"{r.rms:.2f}", f"{r.p95:.2f}"] + ([f"{d.p95:.2f}"] if across else [])
        cells.append(f"{max(r.rms for r, _ in rows_of.values()):.2f}")
        cells.append(f"{sum(r.refused for r, _ in rows_of.values())} ({sum(r.dropped for r, _ in rows_of.values())})")
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
    ap.add_argument("--draw-errors", action="store_true",
                    help="each seed draws its errors across the ranges of `make sim-report`")
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
    def scenario_of(name, seed):
        return error_ranges.drawn(loaded[name], seed) if args.draw_errors else loaded[name]
    jobs = [(scenario_of(s, seed), ch, " ".join(sets), seed, settings)
            for sets, ch in zip(combos, changes) for s in args.scenarios for seed in range(args.seeds)]
    t0 = time.monotonic()
    runs = report.run_jobs(jobs, args.jobs)
    results, k = [], 0
    for sets in combos:
        per_scenario = {}
        for s in args.scenarios:
            group = [r for r, _ in runs[k:k + args.seeds]]
            per_scenario[s] = (report.summarise(group), report.spread(group))
            k += args.seeds
        results.append((sets, per_scenario))
    text = table(results, args.scenarios, args.draw_errors)
    head = (f"Sweep: estimator {args.estimator or 'model'}, shared edits {args.sets or 'none'}; "
            f"{args.seeds} seeds x {args.seconds:g} s per scenario"
            f"{', errors drawn across the ranges' if args.draw_errors else ''}; wall time {time.monotonic() - t0:.0f} s.")
    print(head)
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(f"{head}\n\nCommand: `python -m uavarm.sim.sweep {' '.join(argv or sys.argv[1:])}`\n\n"
                            f"{text}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
