"""Tables of the closed-loop simulator: `uavarm sim` (one scenario) and `make sim-report`
(every scenario x estimator preset x draws of the errors, uavarm.sim.error_ranges), with plots.

    python -m uavarm.sim.report --out build/sim-report   # what `make sim-report` runs
"""
from __future__ import annotations

import argparse
import math
import multiprocessing
import re
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..build import generated, variants
from . import ax12_sim, closed_loop, error_ranges, imu_model, scenarios

REPORT_SCENARIOS = ("bench", "hover", "manoeuvre")
REPORT_ESTIMATORS = ("quaternion", "link", "imu-velocity", "link-velocity")
REPORT_DRAWS = 16
REPORT_SECONDS = 30.0


@dataclass
class Row:
    scenario: str
    label: str
    seeds: int
    seconds: float
    rms: float
    p95: float
    max: float
    att_rms: float
    att_max: float
    out_of_reach: int
    wall_s: float
    unreachable: int = 0             # ticks with the set position refused as unreachable
    ticks: int = 0                   # ticks recorded (from engage)
    refused: int = 0                 # drone messages the gate refused (honest ones, in the simulator)
    dropped: int = 0                 # times a stream was dropped for disagreeing


def summarise(runs: list[closed_loop.Run], wall_s: float = 0.0) -> Row:
    """Pooled over the seeds' scored samples: RMS, 95th percentile and maximum of |e|."""
    e = np.concatenate([np.linalg.norm(r.error_mm[r.scored], axis=1) for r in runs])
    a = np.concatenate([np.linalg.norm(np.degrees(r.est_att[r.scored] - r.true_att[r.scored]), axis=1)
                        for r in runs])
    m = runs[0].metrics()
    return Row(runs[0].scenario, runs[0].label, len(runs), m["seconds"], float(np.sqrt(np.mean(e ** 2))),
               float(np.percentile(e, 95)), float(e.max()), float(np.sqrt(np.mean(a ** 2))), float(a.max()),
               sum(r.out_of_reach_ticks for r in runs), wall_s, sum(r.unreachable_ticks for r in runs),
               sum(len(r.t) for r in runs), sum(n for r in runs for n, _ in r.gate_refusals.values()),
               sum(d for r in runs for _, d in r.gate_refusals.values()))


@dataclass
class Spread:
    """Each draw's EE RMS, across the draws: the figure a claim about a range of hardware makes."""
    median: float
    p95: float
    worst: float
    worst_seed: int


def spread(runs: list[closed_loop.Run]) -> Spread:
    rms = np.array([r.metrics()["rms"] for r in runs])
    k = int(np.argmax(rms))
    return Spread(float(np.median(rms)), float(np.percentile(rms, 95)), float(rms[k]), runs[k].seed)


HEADER = ("scenario", "estimator", "seeds", "s each", "EE RMS mm", "EE p95 mm", "EE max mm",
          "att RMS deg", "att max deg", "out of reach ticks", "drone msgs refused (drops)")
DRAWS_HEADER = ("scenario", "estimator", "draws", "s each", "EE RMS median mm", "EE RMS p95 mm",
                "EE RMS worst mm (seed)", "EE p95 mm, pooled", "EE max mm", "att RMS deg", "out of reach ticks",
                "drone msgs refused (drops)")


def cells(r: Row) -> tuple:
    return (r.scenario, r.label, str(r.seeds), f"{r.seconds:.0f}", f"{r.rms:.2f}", f"{r.p95:.2f}",
            f"{r.max:.2f}", f"{r.att_rms:.2f}", f"{r.att_max:.2f}", str(r.out_of_reach), f"{r.refused} ({r.dropped})")


def draw_cells(row: tuple[Row, Spread]) -> tuple:
    r, d = row
    return (r.scenario, r.label, str(r.seeds), f"{r.seconds:.0f}", f"{d.median:.2f}", f"{d.p95:.2f}",
            f"{d.worst:.2f} ({d.worst_seed})", f"{r.p95:.2f}", f"{r.max:.2f}", f"{r.att_rms:.2f}",
            str(r.out_of_reach), f"{r.refused} ({r.dropped})")


def notes(r: Row, target) -> list[str]:
    """What the table cannot say: a set position the firmware refused as unreachable, so the
    error is the distance from where the arm stayed to a point it never went for."""
    if not r.unreachable:
        return []
    when = "on every tick" if r.unreachable == r.ticks else f"on {r.unreachable} of {r.ticks} ticks"
    return [f"{r.scenario}, {r.label}: the target {tuple(target)} mm is unreachable (outside the reach, in the "
            f"body or a leg, from a level base): the firmware refused it {when}, the arm stayed where it was and "
            f"the error is its distance from the target; choose a reachable one (`uavarm workspace`)"]


def text_table(rows, header=HEADER, cell=cells) -> str:
    data = [header] + [cell(r) for r in rows]
    widths = [max(len(row[i]) for row in data) for i in range(len(header))]
    lines = ["  ".join(c.rjust(w) if i > 1 else c.ljust(w) for i, (c, w) in enumerate(zip(row, widths)))
             for row in data]
    lines.insert(1, "-" * len(lines[0]))
    return "\n".join(lines)


def markdown_table(rows, header=HEADER, cell=cells) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] * 2 + ["---:"] * (len(header) - 2)) + "|"]
    out += ["| " + " | ".join(cell(r)) + " |" for r in rows]
    return "\n".join(out)


def label_of(preset: str | None, sets) -> str:
    return (preset or "model") + "".join(f" {s}" for s in sets)


def _run_one(job):
    scenario, changes, label, seed, settings = job
    variant = variants.build(changes)
    t0 = time.monotonic()
    run = closed_loop.simulate(scenario, variant, seed=seed, settings=settings, label=label)
    return run, time.monotonic() - t0


def run_jobs(jobs, workers: int = 1):
    if workers <= 1:
        return [_run_one(j) for j in jobs]
    with multiprocessing.get_context("fork").Pool(workers) as pool:
        return pool.map(_run_one, jobs, chunksize=1)


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_run(run: closed_loop.Run, out_dir: Path) -> list[Path]:
    """Error over time and estimated vs true attitude of one run, as PNG files."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = re.sub(r"[^A-Za-z0-9._=-]+", "_", f"{run.scenario}-{run.label}-seed{run.seed}").strip("_")
    paths = []
    fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for i, name in enumerate("xyz"):
        ax[0].plot(run.t, run.error_mm[:, i], lw=0.6, label=f"e{name}")
    ax[0].plot(run.t, np.linalg.norm(run.error_mm, axis=1), "k", lw=0.8, label="|e|")
    ax[0].axvspan(run.t[0], run.t[~run.scored][-1] if (~run.scored).any() else run.t[0], color="0.9",
                  label="settling (not scored)")
    ax[0].set_ylabel("end-effector error, mm")
    ax[0].legend(loc="upper right", ncol=5, fontsize=8)
    m = run.metrics()
    ax[0].set_title(f"{run.scenario}, {run.label}, seed {run.seed}: RMS {m['rms']:.2f} mm, "
                    f"p95 {m['p95']:.2f} mm, max {m['max']:.2f} mm")
    tilt = np.degrees(np.arccos(np.cos(run.true_att[:, 0]) * np.cos(run.true_att[:, 1])))
    ax[1].plot(run.t, tilt, lw=0.6, color="0.4")
    ax[1].set_ylabel("drone tilt, deg")
    ax[1].set_xlabel("time since engage, s")
    paths.append(_save(fig, out_dir / f"{stem}-error.png"))

    fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for i, name in enumerate(("roll", "pitch")):
        ax[i].plot(run.t, np.degrees(run.true_att[:, i]), "k", lw=0.8, label=f"true {name}")
        ax[i].plot(run.t, np.degrees(run.est_att[:, i]), "r", lw=0.6, label=f"estimated {name}")
        ax[i].plot(run.t, np.degrees(run.est_att[:, i] - run.true_att[:, i]), "b", lw=0.5, label="error")
        ax[i].set_ylabel("deg")
        ax[i].legend(loc="upper right", ncol=3, fontsize=8)
    ax[0].set_title(f"{run.scenario}, {run.label}, seed {run.seed}: attitude error RMS {m['att_rms']:.2f} deg, "
                    f"max {m['att_max']:.2f} deg")
    ax[1].set_xlabel("time since engage, s")
    paths.append(_save(fig, out_dir / f"{stem}-attitude.png"))
    return paths


def build_variants(estimators, sets) -> dict[str, dict]:
    """Every estimator's key edits, built now so that an unknown key stops before any run."""
    out = {}
    for est in estimators:
        preset = None if est == "model" else est
        try:
            changes = variants.edits(preset, sets)
            variants.build(changes)
        except variants.VariantError as exc:
            raise variants.VariantError(f"estimator {est}: {exc}") from None
        out[est] = changes
    return out


def _at_least_one(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return n


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m uavarm.sim.report",
                                 description="The closed-loop simulator's full table (make sim-report)")
    ap.add_argument("--out", type=Path, default=Path("build/sim-report"))
    ap.add_argument("--scenarios", nargs="+", default=list(REPORT_SCENARIOS))
    ap.add_argument("--estimators", nargs="+", default=list(REPORT_ESTIMATORS),
                    help=f"presets ({', '.join(variants.PRESETS)}) or `model` (the model file as it is)")
    ap.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--draws", "--seeds", dest="draws", type=_at_least_one, default=REPORT_DRAWS,
                    help="seeds per scenario and estimator, each drawing its own errors (default: %(default)s)")
    ap.add_argument("--fixed-errors", action="store_true",
                    help="every seed with the scenario's own stated errors instead of draws across the ranges")
    ap.add_argument("--imu", choices=sorted(imu_model.PROFILES), default=None,
                    help="the draws' IMU error profile instead of the ranges' (e.g. calibrated: the accelerometer's "
                         "bias a fresh calibration leaves)")
    ap.add_argument("--without", action="append", default=[], choices=sorted(error_ranges.LEFT_OUT),
                    help="an error of the drone's data left out of the draws (0), to see what it costs (repeatable)")
    ap.add_argument("--sizes-as-drawn", action="store_true",
                    help="state each draw's own error sizes to the split's Kalman filter (the flight controller's "
                         "slow and white errors, the accelerometer bias's spread): a filter that knows each drone's "
                         "sizes, though not its errors")
    ap.add_argument("--seconds", type=float, default=REPORT_SECONDS)
    ap.add_argument("--preflight", type=float, default=closed_loop.Settings.preflight, metavar="SECONDS",
                    help="on the ground from power-up before the flight, still and level (default: %(default)s)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--supply", type=float, default=None, metavar="VOLTS",
                    help="the simulated servos' battery, open circuit (default: ax12_sim.Supply's)")
    args = ap.parse_args(argv)
    for option, given in (("--without", args.without), ("--sizes-as-drawn", args.sizes_as_drawn)):
        if given and args.fixed_errors:
            print(f"error: {option} needs the draws; with --fixed-errors there are none", file=sys.stderr)
            return 2
    if not (math.isfinite(args.seconds) and args.seconds > 0 and math.isfinite(args.preflight) and args.preflight >= 0):
        print("error: --seconds must be above 0 and --preflight at least 0", file=sys.stderr)
        return 2
    settings = replace(closed_loop.Settings(), seconds=args.seconds, supply=args.supply, preflight=args.preflight)
    try:
        changes = build_variants(args.estimators, args.sets)
        loaded = {name: scenarios.load(name) for name in args.scenarios}
        if args.imu and args.fixed_errors:
            loaded = {name: replace(sc, imu_profile=args.imu) for name, sc in loaded.items()}
        servo_lag = closed_loop.servo_lag_of(settings, variants.build({}).model)
    except (variants.VariantError, scenarios.ScenarioError, generated.StaleCode) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    def scenario_of(name, seed):
        if args.fixed_errors:
            return loaded[name]
        return error_ranges.drawn(loaded[name], seed, args.imu, tuple(args.without))

    def changes_of(estimator, scenario):
        if not args.sizes_as_drawn:
            return changes[estimator]
        return {**changes[estimator], **variants.edits(None, error_ranges.stated_sizes(scenario))}
    drawn = {(s, seed): scenario_of(s, seed) for s in args.scenarios for seed in range(args.draws)}
    jobs = [(drawn[s, seed], changes_of(e, drawn[s, seed]), e, seed, settings)
            for s in args.scenarios for e in args.estimators for seed in range(args.draws)]
    t0 = time.monotonic()
    results = run_jobs(jobs, args.jobs)
    rows, remarks, k = [], [], 0
    plots = args.out / "plots"
    for s in args.scenarios:
        for e in args.estimators:
            runs = [r for r, _ in results[k:k + args.draws]]
            rows.append((summarise(runs, sum(w for _, w in results[k:k + args.draws])), spread(runs)))
            worst = rows[-1][1].worst_seed
            if not args.fixed_errors:
                remarks.append(f"{s}, {e}: the worst draw (seed {worst}): "
                               + error_ranges.describe(scenario_of(s, worst), runs[worst].imu))
            remarks += notes(rows[-1][0], loaded[s].target)
            plot_run(runs[worst], plots)
            k += args.draws
    text = text_table(rows, DRAWS_HEADER, draw_cells)
    print(text)
    for line in remarks:
        print(line)
    args.out.mkdir(parents=True, exist_ok=True)
    errors = ("each seed's errors drawn across the ranges (" + error_ranges.ranges_text() + ")"
              + (f", but the IMU's from its `{args.imu}` profile (uavarm/sim/imu_model.py)" if args.imu else "")
              + "".join(f", without the {name.replace('-', ' ')} error" for name in args.without)
              + ("; the split told each draw's own error sizes" if args.sizes_as_drawn else "")
              if not args.fixed_errors else
              "each scenario's own stated errors, IMU profile " + ", ".join(f"{n}: {sc.imu_profile}"
                                                                          for n, sc in loaded.items()))
    settings_line = (f"{args.draws} seeds x {args.seconds:.0f} s scored per scenario and estimator, after "
                     f"{settings.preflight:.0f} s on the ground from power-up, engage {settings.engage_at:g} s "
                     f"into the flight and {settings.settle:.0f} s settling; main loop every {settings.poll_us} us; "
                     f"servo lag {servo_lag * 1e3:.1f} ms, servo supply {ax12_sim.supply_of(settings.supply).volts:g} V "
                     f"sagging as they move; {errors}; extra model edits: {args.sets or 'none'}")
    md = ["# Closed-loop simulator report", "", "Command: `make sim-report` "
          f"(`python -m uavarm.sim.report {' '.join(argv or sys.argv[1:])}`)", "", settings_line, "",
          "End-effector error |e| in the gravity-aligned, heading-following frame. EE RMS: each seed's RMS, "
          "its median, 95th percentile (interpolated) and worst across the seeds; EE p95 and max pooled over "
          "the seeds' samples; attitude error = |estimate - truth| of (roll, pitch), RMS pooled. The plots "
          "are each row's worst seed.", "", markdown_table(rows, DRAWS_HEADER, draw_cells), "", *remarks, "",
          f"Wall time: {time.monotonic() - t0:.0f} s with {args.jobs} workers. Plots: `plots/`.", ""]
    (args.out / "report.md").write_text("\n".join(md))
    print(f"\nwrote {args.out / 'report.md'} and {plots}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())


def sim_command(args) -> int:
    """`uavarm sim`: one scenario, one firmware variant, some seeds: table and plots."""
    try:
        scenario = scenarios.load(args.scenario)
        if args.imu:
            scenario = replace(scenario, imu_profile=args.imu)
        if args.show:   # a starting point for a scenario file of one's own
            print(scenarios.dump(scenario), end="")
            return 0
        changes = variants.edits(args.estimator, args.sets)
        ignored = variants.unused(variants.edits(None, args.sets), variants.model_of(changes).estimator)
        if ignored:   # said before the build, which takes a while
            raise variants.VariantError("--set " + "; ".join(ignored))
        build_variants([args.estimator or "model"], args.sets)
    except (variants.VariantError, scenarios.ScenarioError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    settings = replace(closed_loop.Settings(), seconds=args.seconds, settle=args.settle, poll_us=args.poll_us,
                       preflight=args.preflight,
                       servo_lag=None if args.servo_lag_ms is None else args.servo_lag_ms / 1000,
                       supply=args.supply,
                       drone_attitude={"auto": None, "on": True, "off": False}[args.link_attitude],
                       drone_velocity={"auto": None, "on": True, "off": False}[args.link_velocity])
    label = label_of(args.estimator, args.sets)
    seeds = range(args.seed, args.seed + args.seeds)
    jobs = [(error_ranges.drawn(scenario, seed, args.imu) if args.draw_errors else scenario, changes, label, seed,
             settings) for seed in seeds]
    try:
        results = run_jobs(jobs, min(args.jobs, len(jobs)))
    except scenarios.ScenarioError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    rows = [summarise([r], w) for r, w in results]
    for row, (r, _) in zip(rows, results):
        row.label = f"{label} (seed {r.seed})"
    if len(results) > 1:
        rows.append(summarise([r for r, _ in results], sum(w for _, w in results)))
        rows[-1].label = f"{label} (all {len(results)} seeds)"
    print(f"scenario {scenario.name} ({args.scenario}), IMU {jobs[0][0].imu_profile}, "
          f"drone messages over the link: {results[0][0].link_messages or 'none'}, servo lag "
          f"{closed_loop.servo_lag_of(settings, variants.build(changes).model) * 1e3:.1f} ms, servo supply "
          f"{ax12_sim.supply_of(settings.supply).volts:g} V; scored {args.seconds:g} s "
          f"after {args.settle:g} s settling; wall time {sum(w for _, w in results):.1f} s")
    print(text_table(rows))
    if args.draw_errors:
        for (job, (r, _)) in zip(jobs, results):
            print(f"seed {r.seed}: {error_ranges.describe(job[0], r.imu)}")
    for line in notes(rows[-1], scenario.target):
        print(line)
    if getattr(args, "export_log", None):
        scenarios.write_csv(closed_loop.scenario_flight(scenario, args.seed, settings), Path(args.export_log))
        print(f"wrote {args.export_log} (replay it with a scenario file: kind = \"replay\", "
              f"[motion] csv = ...)")
    if args.plots:
        for r, _ in results:
            for p in plot_run(r, Path(args.plots)):
                print(f"wrote {p}")
    never = rows[-1].ticks > 0 and rows[-1].unreachable == rows[-1].ticks
    return 1 if never else 0   # (the figures measure a target the arm never went for)
