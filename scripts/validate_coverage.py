"""Coverage of laminid's 95 % confidence intervals on synthetic data with known truth and noise.

For each of N trials: the frequencies of a specimen's plate model with known constants (default:
S1.1 with the paper's Table 2 values) are perturbed by Gaussian noise of known relative standard
deviation, identified from the specimen file's initial guess exactly as ``laminid identify``
does, and the 95 % intervals of the result (lower, upper: on ln P for the moduli, asymmetric;
linear for nu12) are checked against the truth, for the stated-sigma intervals and for the
default ``--covariance-scale larger``: the coverage, and the two tails separately (truth below
the interval, truth above it; 2.5 % each for an exact interval). A constant that ended at a
bound in a trial has no interval (NaN) and is counted apart. Also reported: the empirical
spread of the N estimates beside the median linearised standard error (the true sampling
distribution), and, for trial 1, the library Monte Carlo check (re-identification from
perturbed frequencies): its quantiles beside the interval's ends.

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
    at_bound = stated.at_bound if stated.at_bound is not None else np.zeros(len(stated.labels),
                                                                            bool)
    return index, {"labels": stated.labels, "value": stated.value, "std": stated.std,
                   "scale": stated.scale,
                   "lower_stated": stated.lower, "upper_stated": stated.upper,
                   "lower_larger": larger.lower, "upper_larger": larger.upper,
                   "at_bound": np.asarray(at_bound, bool)}, ""


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
    S = np.array([r["std"] for r in ok])
    B = np.array([r["at_bound"] for r in ok])                  # (trials, p) at a bound
    n_free = np.maximum((~B).sum(axis=0), 1)

    def tails(kind):
        """(coverage, truth below the interval, truth above it) over the trials where the
        constant has an interval (not at a bound)."""
        lo = np.array([r[f"lower_{kind}"] for r in ok])
        hi = np.array([r[f"upper_{kind}"] for r in ok])
        below = (t < lo) & ~B
        above = (t > hi) & ~B
        inside = (lo <= t) & (t <= hi) & ~B
        return inside.sum(0) / n_free, below.sum(0) / n_free, above.sum(0) / n_free

    cov_stated, below_stated, above_stated = tails("stated")
    cov_larger, below_larger, above_larger = tails("larger")
    Vf = np.where(B, np.nan, V)                                # estimates not at a bound
    emp_std = np.nanstd(Vf, axis=0, ddof=1)
    lin_std = np.nanmedian(np.where(B, np.nan, S), axis=0)
    n_bound = int(B.any(axis=1).sum())
    out = {"specimen": a.specimen, "mesh": a.mesh, "trials": a.trials, "converged": len(ok),
           "sigma_rel": a.sigma_rel, "seed": a.seed, "fix": a.fix, "truth": truth.as_dict(),
           "at_bound": n_bound, "time_s": time.perf_counter() - t0, "failures": failures[:10],
           "constants": {}}
    print(f"{a.specimen}, mesh {a.mesh}, noise {a.sigma_rel * 100:g} % of each frequency, "
          f"{len(ok)} of {a.trials} identifications converged ({n_bound} ended on a bound), "
          f"{out['time_s']:.0f} s")
    print(f"{'constant':<9} {'scale':<6} {'truth':>9} {'mean est.':>9} "
          f"{'stated: cover  below  above':>28} {'larger: cover  below  above':>28} "
          f"{'bound':>5} {'emp. std':>9} {'lin. std':>9} {'ratio':>5}")
    for k, lab in enumerate(labels):
        c = lab.rsplit(".", 1)[1]
        scale = 1 if c == "nu12" else 1e9
        out["constants"][c] = {"truth": t[k], "mean": float(np.nanmean(Vf[:, k])),
                               "scale": ok[0]["scale"][k] if ok[0]["scale"] else "",
                               "coverage_stated": float(cov_stated[k]),
                               "below_stated": float(below_stated[k]),
                               "above_stated": float(above_stated[k]),
                               "coverage_larger": float(cov_larger[k]),
                               "below_larger": float(below_larger[k]),
                               "above_larger": float(above_larger[k]),
                               "trials_at_bound": int(B[:, k].sum()),
                               "empirical_std": float(emp_std[k]),
                               "median_linearized_std": float(lin_std[k]),
                               "ratio": float(emp_std[k] / lin_std[k])}
        print(f"{c:<9} {out['constants'][c]['scale']:<6} {t[k] / scale:>9.4g} "
              f"{np.nanmean(Vf[:, k]) / scale:>9.4g} "
              f"{cov_stated[k] * 100:>13.1f}% {below_stated[k] * 100:>5.1f}% "
              f"{above_stated[k] * 100:>5.1f}% "
              f"{cov_larger[k] * 100:>13.1f}% {below_larger[k] * 100:>5.1f}% "
              f"{above_larger[k] * 100:>5.1f}% {int(B[:, k].sum()):>5d} "
              f"{emp_std[k] / scale:>9.3g} {lin_std[k] / scale:>9.3g} "
              f"{emp_std[k] / lin_std[k]:>5.2f}")
    print("(moduli in GPa; cover: truth inside the result's 95 % interval [lower, upper], "
          "below/above: truth below the lower end / above the upper end (2.5 % each when "
          "exact), over the converged trials where the constant is not at a bound (bound: "
          "trials at a bound); mean est., emp. std: mean and spread of the estimates not at a "
          "bound; lin. std: their median linearised standard error)")
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
        print(f"{'constant':<10} {'lower':>10} {'MC lower':>10} {'upper':>10} "
              f"{'MC upper':>10} {'lin. std':>10} {'MC std':>10} {'ratio':>6}")
        for k, lab in enumerate(u.labels):
            c = lab.rsplit(".", 1)[1]
            scale = 1 if c == "nu12" else 1e9
            out["monte_carlo"]["constants"][c] = {
                "lower": float(u.lower[k]), "upper": float(u.upper[k]),
                "mc_lower": float(mc.lower[k]), "mc_upper": float(mc.upper[k]),
                "linearized_std": float(u.std[k]), "std": float(mc.std[k]),
                "ratio": float(mc.ratio[k])}
            print(f"{c:<10} {u.lower[k] / scale:>10.4g} {mc.lower[k] / scale:>10.4g} "
                  f"{u.upper[k] / scale:>10.4g} {mc.upper[k] / scale:>10.4g} "
                  f"{u.std[k] / scale:>10.3g} {mc.std[k] / scale:>10.3g} {mc.ratio[k]:>6.2f}")
        print("(lower/upper: the result's 95 % interval on trial 1; MC lower/upper: the "
              "2.5 %/97.5 % quantiles of the re-identifications)")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=2, default=float))
    return out


if __name__ == "__main__":
    main()
