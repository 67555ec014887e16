"""Joint identification benchmark: S1.1-S1.4 together against the single-plate identifications.

Per mesh: wall time, evaluations and work (laminid_cli.modal.WORK) of each single-plate
identification (S1.1 ... S1.4, reduced solver) and of the joint identification of the four
plates, and the ratios joint / S1.1 and joint / (sum of the four). The issue's target is joint
<= 4 x one single-plate identification (S1.1). Ratios come from one run: compare those, the
machine may be loaded.

Run: .venv/bin/python benchmarks/bench_joint.py [--meshes 12] [--repeat 3]
"""

from _timing import median_time  # noqa: F401  first: sets single-threaded BLAS

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from laminid_cli.forward import bending_model, build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions, identify  # noqa: E402
from laminid_cli.joint import identify_joint  # noqa: E402
from laminid_cli.modal import WORK, reset_work  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PLATES = [ROOT / f"specimens/example1/S1.{k}.yaml" for k in (1, 2, 3, 4)]


def timed(fn, repeat):
    """(median wall time, median CPU time of this process, result and work of the first run).

    On a loaded machine the CPU time is the steadier figure (the wall time includes waiting
    for a core)."""
    times, cpu, first = [], [], None
    for _ in range(repeat):
        reset_work()
        t, c = time.perf_counter(), time.process_time()
        r = fn()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
        if first is None:
            first = (r, dict(WORK))
    return statistics.median(times), statistics.median(cpu), first[0], first[1]


def bench(mesh, repeat):
    specs = [read_specimen(p) for p in PLATES]
    fms = [bending_model(build_forward_model(s, mesh)) for s in specs]
    opts = IdentifyOptions()
    identify(fms[0], opts)                                   # warm-up (imports, caches)
    single, single_cpu = [], []
    for s, fm in zip(specs, fms):
        t, c, r, w = timed(lambda: identify(fm, opts), repeat)
        single.append(t)
        single_cpu.append(c)
        print(f"{s.name:<6} {mesh[0]:>2}x{mesh[1]:<2} single {t:6.2f} s (CPU {c:6.2f} s)  evaluations "
              f"{r.evaluations:3d}  factorisations {w['factorizations']:2d}  solve pairs "
              f"{w['solve_pairs']:4d}  Lanczos {w['lanczos_runs']}", flush=True)
    t, c, r, w = timed(lambda: identify_joint(fms, opts), repeat)
    print(f"joint  {mesh[0]:>2}x{mesh[1]:<2} S1.1-S1.4 {t:6.2f} s (CPU {c:6.2f} s)  evaluations {r.evaluations:3d}  "
          f"factorisations {w['factorizations']:2d}  solve pairs {w['solve_pairs']:4d}  Lanczos "
          f"{w['lanczos_runs']}  converged {r.converged}", flush=True)
    print(f"       ratio joint / S1.1: wall {t / single[0]:.2f}, CPU {c / single_cpu[0]:.2f} "
          f"(target <= 4); joint / sum of the four: wall {t / sum(single):.2f}, CPU "
          f"{c / sum(single_cpu):.2f}", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", default="12")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    for m in a.meshes.split(","):
        bench((int(m), int(m)), a.repeat)
