"""Coverage of laminid's 95 % confidence intervals on synthetic data with known truth and noise.

For each of N trials: the frequencies of a specimen's plate model with known constants (default:
S1.1 with the paper's Table 2 values) are perturbed by Gaussian noise of known relative standard
deviation, identified from the specimen file's initial guess exactly as ``laminid identify``
does, and the linearised 95 % intervals are checked against the truth, for the stated-sigma
intervals and for the default ``--covariance-scale larger``. Also reported: the empirical spread
of the N estimates beside the mean linearised standard error (the true sampling distribution),
and, for trial 1, the library Monte Carlo check (re-identification from perturbed frequencies)
beside its linearised spread.

Run on demand (a few minutes on two cores)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/validate_coverage.py --trials 200
    .venv/bin/python scripts/validate_coverage.py --specimen specimens/example2/S2.1.yaml \\
        --fix G13,G23 --trials 200 --json coverage.json

Truth: ``--truth`` "E1=161.1e9,E2=9.3e9,..." overrides the paper's identified values; the
data are generated on the same mesh as the identification (no discretisation error), so the
only error is the noise.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from laminid_cli.forward import build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions, identify  # noqa: E402
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants  # noqa: E402
from laminid_cli.specimen import Measured, read_specimen  # noqa: E402
from laminid_cli.uncertainty import (frequency_sigma, monte_carlo,  # noqa: E402
                                     uncertainty_of)

_STATE: dict = {}


def _init(spec_path, mesh, truth, n_modes, options):
    spec = read_specimen(spec_path)
    fm = build_forward_model(spec, mesh)
    f_true = fm.solve(truth, n_modes).freq
    _STATE.update(spec=spec, fm=fm, f_true=f_true, options=options)


def _with_freq(f):
    spec = _STATE["spec"]
    meas = Measured(freq=f, weight=np.ones(f.size))
    return dataclasses.replace(_STATE["fm"], specimen=dataclasses.replace(spec, measured=meas))


def _trial(args):
    """Identify from noisy frequencies; return values, stated and default half-widths."""
    index, noise, sigma_rel = args
    fm = _with_freq(_STATE["f_true"] * (1 + sigma_rel * noise))
    try:
        r = identify(fm, _STATE["options"])
    except Exception as exc:                     # report, do not stop the whole validation
        return index, None, repr(exc)
    if not r.converged:
        return index, None, r.status
    sig = frequency_sigma(fm.specimen.measured, sigma_rel)
    stated = uncertainty_of(r, fm, sig, scaling="stated")
    larger = uncertainty_of(r, fm, sig, scaling="larger")
    return index, {"labels": stated.labels, "value": stated.value, "std": stated.std,
                   "half_stated": stated.half_width, "half_larger": larger.half_width,
                   "at_bound": bool(r.bounds_hit)}, ""


def parse_truth(text, default):
    if not text:
        return default
    values = dict(default.as_dict())
    for item in text.split(","):
        k, v = item.split("=")
        values[k.strip()] = float(v)
    return ElasticConstants(**values)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--specimen", default="specimens/example1/S1.1.yaml")
    ap.add_argument("--truth", default="", help="constants, e.g. E1=161.1e9,nu12=0.17")
    ap.add_argument("--mesh", default="8x8")
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--sigma-rel", type=float, default=0.002)
    ap.add_argument("--fix", default="", help="constants held at the file's initial values")
    ap.add_argument("--mc-trials", type=int, default=200,
                    help="library Monte Carlo trials on trial 1 (0: skip)")
    ap.add_argument("--seed", type=int, default=2000)
    ap.add_argument("--jobs", type=int, default=os.cpu_count())
    ap.add_argument("--json", default="", help="write the numbers to this file")
    a = ap.parse_args(argv)

    os.chdir(ROOT)
    from tests.data.paper import IDENTIFIED

    spec = read_specimen(a.specimen)
    if len(spec.materials) != 1:
        ap.error("one material per specimen in this script")
    name = next(iter(spec.materials))
    default = ElasticConstants(**IDENTIFIED[a.specimen][name]) if a.specimen in IDENTIFIED \
        else spec.materials[name].constants
    truth = parse_truth(a.truth, default)
    mesh = tuple(int(x) for x in a.mesh.lower().split("x"))
    n_modes = int(np.sum(np.isfinite(spec.measured.freq)))
    options = IdentifyOptions(fix=tuple(x for x in a.fix.split(",") if x))
    rng = np.random.default_rng(a.seed)
    jobs = [(i, rng.standard_normal(n_modes), a.sigma_rel) for i in range(a.trials)]
    t0 = time.perf_counter()
    results = [None] * a.trials
    failures = []
    init = (a.specimen, mesh, [truth], n_modes, options)
    with ProcessPoolExecutor(max_workers=a.jobs, initializer=_init, initargs=init) as pool:
        for k, (i, res, msg) in enumerate(pool.map(_trial, jobs, chunksize=4)):
            results[i] = res
            if res is None:
                failures.append(f"trial {i + 1}: {msg}")
            if sys.stderr.isatty():
                print(f"\r  trial {k + 1}/{a.trials}", end="", file=sys.stderr)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    ok = [r for r in results if r is not None]
    labels = ok[0]["labels"]
    t = np.array([getattr(truth, lab.rsplit(".", 1)[1]) for lab in labels])
    V = np.array([r["value"] for r in ok])
    Hs = np.array([r["half_stated"] for r in ok])
    Hl = np.array([r["half_larger"] for r in ok])
    S = np.array([r["std"] for r in ok])
    cov_stated = np.mean(np.abs(V - t) <= Hs, axis=0)
    cov_larger = np.mean(np.abs(V - t) <= Hl, axis=0)
    emp_std = V.std(axis=0, ddof=1)
    lin_std = np.median(S, axis=0)
    n_bound = sum(r["at_bound"] for r in ok)
    out = {"specimen": a.specimen, "mesh": a.mesh, "trials": a.trials, "converged": len(ok),
           "sigma_rel": a.sigma_rel, "seed": a.seed, "fix": a.fix, "truth": truth.as_dict(),
           "at_bound": n_bound, "time_s": time.perf_counter() - t0, "failures": failures[:10],
           "constants": {}}
    print(f"{a.specimen}, mesh {a.mesh}, noise {a.sigma_rel * 100:g} % of each frequency, "
          f"{len(ok)} of {a.trials} identifications converged ({n_bound} ended on a bound), "
          f"{out['time_s']:.0f} s")
    print(f"{'constant':<10} {'truth':>10} {'mean est.':>10} {'cover stated':>13} "
          f"{'cover larger':>13} {'emp. std':>10} {'lin. std':>10} {'ratio':>6}")
    for k, lab in enumerate(labels):
        c = lab.rsplit(".", 1)[1]
        scale = 1 if c == "nu12" else 1e9
        out["constants"][c] = {"truth": t[k], "mean": float(V[:, k].mean()),
                               "coverage_stated": float(cov_stated[k]),
                               "coverage_larger": float(cov_larger[k]),
                               "empirical_std": float(emp_std[k]),
                               "median_linearized_std": float(lin_std[k]),
                               "ratio": float(emp_std[k] / lin_std[k])}
        print(f"{c:<10} {t[k] / scale:>10.4g} {V[:, k].mean() / scale:>10.4g} "
              f"{cov_stated[k] * 100:>12.1f}% {cov_larger[k] * 100:>12.1f}% "
              f"{emp_std[k] / scale:>10.3g} {lin_std[k] / scale:>10.3g} "
              f"{emp_std[k] / lin_std[k]:>6.2f}")
    print("(moduli in GPa; coverage of the 95 % intervals over the converged trials; emp. std: "
          "spread of the estimates over the trials; lin. std: median linearised standard error)")
    if a.mc_trials:
        _init(*init)
        first = jobs[0]
        fm = _with_freq(_STATE["f_true"] * (1 + a.sigma_rel * first[1]))
        r = identify(fm, options)
        sig = frequency_sigma(fm.specimen.measured, a.sigma_rel)
        u = uncertainty_of(r, fm, sig, scaling="stated")
        mc = monte_carlo(r, fm, sig, u, a.mc_trials, jobs=a.jobs, seed=a.seed + 1)
        out["monte_carlo"] = {"trials": mc.n_trials, "converged": mc.n_converged,
                              "time_s": mc.time_s, "constants": {}}
        print(f"\nMonte Carlo check on trial 1: {mc.n_converged} of {mc.n_trials} "
              f"re-identifications converged, {mc.time_s:.0f} s")
        print(f"{'constant':<10} {'lin. std':>10} {'MC std':>10} {'ratio':>6}")
        for k, lab in enumerate(u.labels):
            c = lab.rsplit(".", 1)[1]
            scale = 1 if c == "nu12" else 1e9
            out["monte_carlo"]["constants"][c] = {"linearized_std": float(u.std[k]),
                                                  "std": float(mc.std[k]),
                                                  "ratio": float(mc.ratio[k])}
            print(f"{c:<10} {u.std[k] / scale:>10.3g} {mc.std[k] / scale:>10.3g} "
                  f"{mc.ratio[k]:>6.2f}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=2, default=float))
    return out


if __name__ == "__main__":
    main()
