"""Identification benchmark: S1.1 on the paper's 12x12 mesh.

Reports the wall time of the whole identification, the model evaluations, the time of one
forward solve (same mesh, same number of modes) and the ratio of the two (median of REPEAT).
Run: .venv/bin/python benchmarks/bench_identify.py [SPEC ...]
"""

from _timing import median_time  # first: sets single-threaded BLAS

import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from laminid_cli.forward import build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions, identify  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402

REPEAT = 3
ROOT = Path(__file__).resolve().parents[1]


def bench(path, mesh=(12, 12)):
    spec = read_specimen(path)
    t0 = time.perf_counter()
    fm = build_forward_model(spec, mesh)
    t_build = time.perf_counter() - t0
    n = spec.measured.freq.size + IdentifyOptions().extra_modes
    t_solve, _ = median_time(lambda: fm.solve(n_modes=n), 5, warmup=False)
    runs = []
    for _ in range(REPEAT):
        fm = build_forward_model(spec, mesh)
        t = time.perf_counter()
        r = identify(fm)
        runs.append((time.perf_counter() - t, r))
    t_id = statistics.median(t for t, _ in runs)
    r = runs[0][1]
    print(f"{spec.name:<12} {mesh[0]}x{mesh[1]}  build {t_build:5.2f} s  identify {t_id:5.2f} s  "
          f"evaluations {r.evaluations:3d}  one solve ({n} modes) {t_solve * 1e3:6.1f} ms  "
          f"identify/solve {t_id / t_solve:5.1f}  RMS {r.rms_residual_percent:.3f} %  "
          f"{'converged' if r.converged else 'NOT converged'}")


if __name__ == "__main__":
    paths = sys.argv[1:] or [ROOT / "specimens/example1/S1.1.yaml"]
    for p in paths:
        bench(p)
