"""Shared by the benchmark scripts: single-threaded BLAS (as the CLI) and a median timer.

Import this module before numpy: the BLAS thread count is read when numpy loads.
"""

import os
import statistics
import time

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")


def median_time(fn, repeat: int, warmup: bool = True):
    """(median wall time in s over ``repeat`` calls, result of the last call); one untimed
    call first when ``warmup`` (imports, caches)."""
    if warmup:
        fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out
