"""`python -m mutation [--jobs N] [--target TEXT] [--every K] [--list]`: run the mutants of
the chosen targets (mutation/targets.py) against their tests, resuming from the results
file, and print the score table. `--remap` moves the judged mutants of equivalent.toml to
where an edit moved their lines."""
from __future__ import annotations

import argparse
import queue
import threading
import time
from pathlib import Path

from .catalogue import ROOT, file_digest, target_mutants
from .remap import remap
from .results import Results, equivalents
from .targets import TARGETS
from .worker import TestsFail, Worker

BASE = ROOT / "build" / "mutate"


def chosen(args):
    targets = [t for t in TARGETS if not args.target or any(s.lower() in t.name.lower() for s in args.target)]
    work = []
    for t in targets:
        digest = file_digest(t.path)
        for k, mu in enumerate(target_mutants(t)):
            if k % args.every == args.offset % args.every and (not args.only or args.only in mu.id):
                work.append((t, mu, digest))
    return targets, work


def run_all(work, results: Results, jobs: int, timeout: float | None, again: str = "") -> None:
    """Runs each mutant of `work` without a result (again="survivors": also the survivors;
    again="all": every one)."""
    todo: queue.Queue = queue.Queue()
    for item in work:
        rec = results.get(item[1].id, item[2])
        if rec is None or again == "all" or (again == "survivors" and rec["status"] == "survived"):
            todo.put(item)
    total = todo.qsize()
    print(f"{len(work)} mutants, {len(work) - total} already in {results.path.relative_to(ROOT)}, {total} to run "
          f"on {jobs} job(s)", flush=True)
    counter = iter(range(1, total + 1))

    def loop() -> None:
        worker = Worker(BASE, timeout)
        worker.prepare()
        while True:
            try:
                target, mu, digest = todo.get_nowait()
            except queue.Empty:
                return
            try:
                out = worker.run(target, mu)
            except TestsFail as exc:
                print(f"error: {exc}", flush=True)
                return
            results.add({"id": mu.id, "digest": digest, "target": target.name, "status": out.status,
                         "seconds": round(out.seconds, 1), "detail": out.detail})
            print(f"[{next(counter)}/{total}] {out.status:9} {out.seconds:5.1f} s  {mu.id}", flush=True)

    threads = [threading.Thread(target=loop) for _ in range(jobs)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()


def score_table(targets, work, results: Results) -> str:
    eq = equivalents()
    rows = ["| target | mutants run (of) | killed | survived | timed out | equivalent | not compiled | score |",
            "|---|---:|---:|---:|---:|---:|---:|---:|"]
    survivors, hung = [], []
    sums = [0] * 6
    for t in targets:
        everything = [results.get(mu.id, d) for tt, mu, d in work if tt is t]
        recs = [r for r in everything if r is not None]
        killed = sum(r["status"] == "killed" and not timed_out(r) for r in recs)
        equivalent = sum(r["status"] == "same_code" or (r["status"] == "survived" and r["id"] in eq) for r in recs)
        survived = [r for r in recs if r["status"] == "survived" and r["id"] not in eq]
        timeouts = [r for r in recs if timed_out(r)]
        stillborn = sum(r["status"] == "stillborn" for r in recs)
        judged = killed + len(survived)
        score = f"{100 * killed / judged:.1f} %" if judged else "-"
        rows.append(f"| {t.name} | {len(recs)} ({len(everything)}) | {killed} | {len(survived)} | {len(timeouts)} | "
                    f"{equivalent} | {stillborn} | {score} |")
        for k, v in enumerate((len(recs), killed, len(survived), len(timeouts), equivalent, stillborn)):
            sums[k] += v
        survivors += [r["id"] for r in survived]
        hung += [r["id"] for r in timeouts]
    judged = sums[1] + sums[2]
    rows.append(f"| **all** | {sums[0]} | {sums[1]} | {sums[2]} | {sums[3]} | {sums[4]} | {sums[5]} | "
                f"{100 * sums[1] / judged:.1f} % |" if judged else "| **all** | 0 | | | | | | - |")
    text = "\n".join(rows)
    if survivors:
        text += "\n\nSurvivors not in mutation/equivalent.toml:\n" + "\n".join(f"  {s}" for s in survivors)
    if hung:
        text += ("\n\nTimed out (not in the score: a test that hangs on them, or a machine too busy; run "
                 "them again alone):\n" + "\n".join(f"  {s}" for s in hung))
    return text


def timed_out(rec: dict) -> bool:
    """A mutant whose tests were still running at the timeout (results from before timeouts
    were told apart: killed with a timeout as the reason)."""
    return rec["status"] == "timeout" or (rec["status"] == "killed" and rec.get("detail", "").startswith("timeout"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m mutation", description=__doc__)
    ap.add_argument("--jobs", type=int, default=1, help="workers in parallel (each a copy of the tree)")
    ap.add_argument("--target", action="append", help="run only targets whose name contains this (repeatable)")
    ap.add_argument("--every", type=int, default=1, help="a representative subset: every K-th mutant of each target")
    ap.add_argument("--offset", type=int, default=0, help="which of the K (with --every)")
    ap.add_argument("--only", help="run only mutants whose id contains this text")
    ap.add_argument("--results", type=Path, default=BASE / "results.jsonl")
    ap.add_argument("--timeout", type=float, default=None,
                    help="seconds before a mutant's test run counts as hung (default: 10 x the target's tests on "
                         "the unmutated tree, measured first, at least 60)")
    ap.add_argument("--again", choices=("survivors", "all"), default="",
                    help="run the survivors (after the tests were strengthened), or all chosen, again")
    ap.add_argument("--list", action="store_true", help="list the mutants and stop")
    ap.add_argument("--table", action="store_true",
                    help="print the table of every mutant with a result in the results file, run nothing")
    ap.add_argument("--remap", metavar="REV", nargs="?", const="HEAD",
                    help="move equivalent.toml's ids to the lines they named at git revision REV (HEAD) and stop")
    args = ap.parse_args(argv)
    if args.remap:
        moved, left = remap(args.remap)
        for old, new in moved:
            print(f"moved  {old}\n    -> {new}")
        for old in left:
            print(f"judge again (its line is gone or not unique): {old}")
        if not moved and not left:
            print("every judged mutant names the code as it is")
        return 1 if left else 0
    if args.table:
        args.every = 1
    targets, work = chosen(args)
    if args.list:
        for t, mu, _ in work:
            print(f"{t.name}: {mu.id}")
        print(f"{len(work)} mutants")
        return 0
    results = Results(args.results.resolve())
    if not args.table:
        t0 = time.monotonic()
        run_all(work, results, args.jobs, args.timeout, args.again)
        print(f"done in {time.monotonic() - t0:.0f} s")
    print(score_table(targets, work, results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
