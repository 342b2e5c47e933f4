#!/usr/bin/env python3
"""Runs shell commands in turn, N rounds, removing the --fresh folders before every run, and
prints per command the mean and median wall seconds, the fastest, and the median CPU seconds
(user + system of the command's processes). Alternating the commands spreads the machine's
drift over all of them: how docs/benchmarks.md compares two builds or two layouts of a log,
where `cargo xtask bench` runs one program at a time.

    python3 xtask/alternate-runs.py 30 --fresh /dev/shm/o \
        'target/release/gravcal-ingest target/bench-data/bench-250hz-2h-csv --out /dev/shm/o' \
        'target/release/gravcal-ingest target/bench-data/bench-250hz-2h-lab --out /dev/shm/o'
"""
import argparse
import resource
import shutil
import statistics
import subprocess
import time

p = argparse.ArgumentParser()
p.add_argument("rounds", type=int)
p.add_argument("commands", nargs="+")
p.add_argument("--fresh", action="append", default=[], help="folder removed before each run")
a = p.parse_args()
runs = {c: [] for c in a.commands}
for _ in range(a.rounds):
    for c in a.commands:
        for d in a.fresh:
            shutil.rmtree(d, ignore_errors=True)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(c, shell=True, check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
        runs[c].append((wall, cpu))
for c, r in runs.items():
    w = [x for x, _ in r]
    print(f"mean {statistics.mean(w):.4f} median {statistics.median(w):.4f} "
          f"fastest {min(w):.4f} cpu {statistics.median([u for _, u in r]):.4f}  {c}")
