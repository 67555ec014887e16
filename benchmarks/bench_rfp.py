"""RFP benchmark: fit 5 FRFs x 1601 lines over the full band (issue 4: under 1 s).

Run: .venv/bin/python benchmarks/bench_rfp.py   (median of REPEAT runs, single-threaded BLAS)

Cases: the full axis with automatic bands, the full axis given as one band (split internally
into overlapping sub-bands), and the same without the output-error pole refinement; 3 %
proportional noise. Exits 1 if the default case takes 1 s or more.

Also the read of the same FRFs from laminid's HDF5 file, whose damaged-file probe (a child
process reads the file first: frf/store.py) is a fork of this process or a new interpreter.
"""

from _timing import median_time as _median_time  # first: sets single-threaded BLAS

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from laminid_cli.frf import rfp  # noqa: E402
from tests.frf_synth import plate_case  # noqa: E402

REPEAT = 5
LIMIT_S = 1.0


def median_time(fn, repeat=REPEAT):
    return _median_time(fn, repeat, warmup=True)


def main() -> int:
    case = plate_case(n_points=5, n_lines=1601, noise=0.03, seed=0)
    cases = {
        "auto bands": dict(),
        "one band 1-1601 Hz": dict(bands=[(1.0, 1601.0)]),
        "auto bands, no refinement": dict(criteria=rfp.PoleCriteria(refine=False)),
    }
    print(f"RFP: {case.frf.shape[0]} FRFs x {case.freq.size} lines, 3 % noise")
    status = 0
    for name, kw in cases.items():
        t, fit = median_time(lambda: rfp.find_modes(case.freq, case.frf, **kw))
        err = max(np.min(np.abs(fit.freq_hz - f)) / f for f in case.freq_hz)
        print(f"  {name:28s} {t * 1e3:7.1f} ms   {len(fit.modes)} modes, "
              f"max error {100 * err:.4f} %")
        if name == "auto bands" and t >= LIMIT_S:
            status = 1
    read_times(case)
    return status


def read_times(case) -> None:
    """Median time of reading the FRF HDF5 file with each probe route, and without one."""
    import tempfile
    from unittest import mock

    from laminid_cli.frf import io, store

    with tempfile.TemporaryDirectory() as tmp:
        path = io.write_frf(Path(tmp) / "plate.frf.h5",
                               store.FrfSet(freq=case.freq, frf=case.frf, units="m/N"))
        routes = {"probe in a fork": lambda: True, "probe in a new interpreter": lambda: False}
        print(f"read {path.name} ({path.stat().st_size / 1e6:.1f} MB):")
        for name, fork in routes.items():
            with mock.patch.object(store, "_fork_is_safe", fork):
                t, _ = median_time(lambda: store.read_frf_h5(path))
            print(f"  {name:28s} {t * 1e3:7.1f} ms")
        t, _ = median_time(lambda: store.read_frf_h5(path, probe=False))
        print(f"  {'no probe':28s} {t * 1e3:7.1f} ms")


if __name__ == "__main__":
    sys.exit(main())
