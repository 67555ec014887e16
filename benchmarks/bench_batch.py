"""Wall time of `laminid batch` over the paper's eight specimens with -j 1 and -j 2.

Each run starts from an empty output folder (no cached results) and goes through the real
command in a subprocess, so process start-up, the pool and the result writing are included.
Usage: python benchmarks/bench_batch.py [--mesh 12x12] [--jobs 1,2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(mesh: str, jobs: int, out: Path) -> tuple[float, dict]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "laminid_cli", "batch", str(ROOT / "specimens"),
                        "--mesh", mesh, "-j", str(jobs), "--out", str(out), "--json"],
                       capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 1):
        sys.exit(f"batch failed ({p.returncode}): {p.stderr}")
    return wall, json.loads(p.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="12x12")
    ap.add_argument("--jobs", default="1,2")
    args = ap.parse_args()
    times = {}
    with tempfile.TemporaryDirectory() as tmp:
        for j in (int(x) for x in args.jobs.split(",")):
            wall, d = run(args.mesh, j, Path(tmp) / f"j{j}")
            work = sum(s["time_s"] or 0 for s in d["specimens"])
            times[j] = wall
            print(f"batch {d['n_specimens']} specimens, mesh {args.mesh}, -j {j}: wall "
                  f"{wall:6.1f} s (identification time summed over specimens {work:6.1f} s; "
                  + ", ".join(f"{n} {k}" for k, n in d["counts"].items() if n) + ")")
    if 1 in times:
        for j, t in times.items():
            if j != 1:
                print(f"speed-up -j {j} vs -j 1: {times[1] / t:.2f} (cores: {os.cpu_count()})")


if __name__ == "__main__":
    main()
