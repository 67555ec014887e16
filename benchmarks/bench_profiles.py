"""Profiles benchmark: the fits behind the profiles of the constants on a search limit.

``laminid identify``'s assessment (laminid_cli.uncertainty.assess, the model the command uses)
with the profiles made in this process one after the other (``jobs=1``: their work, not the
pool's wall). Per fit (laminid_cli.uncertainty.refit_held): the constant and the value held,
where the fit started (the optimum, or the initial values: the check of a rejection; a
reduced fit "from the optimum" starts at the answer of the nearest value held before between
the limit and its own where there is one), its
identify() evaluations (reduced ones included) against its cap and the evaluations of the
profile's reduced model (laminid_cli.uncertainty.refit_reduced: a fit from the optimum tries
it first; ``reduced`` where its answer was taken, ``identify`` where identify() made the fit,
the reduced model's evaluations then spent on an answer it refused), whether it finished,
its chi2 rise (scaled, as the profile measures it) and its wall time; per profile: fits,
evaluations, time and its statement; in all, wall and CPU time of the fits. The code before
the reduced refits runs it too (``cd`` to its checkout, ``PYTHONPATH=.``): its fits are all
``identify``. Hybrid CM (the default) is the one paper specimen whose profiles cost
more than its identification; S2.1's one profile takes two fits.

``--budget N`` raises the three evaluation caps of a profile's fits (PROFILE_EVALUATIONS,
PROFILE_MID_EVALUATIONS, PROFILE_INITIAL_EVALUATIONS) to N: what the profiles conclude when
their fits finish, the reference for a faster fit (``benchmarks/HISTORY.md``, stop 40).

Run: .venv/bin/python benchmarks/bench_profiles.py [SPEC] [--mesh 12x12] [--budget N]
"""

from _timing import median_time  # noqa: F401  first: sets single-threaded BLAS

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import laminid_cli.uncertainty as unc  # noqa: E402
from laminid_cli.forward import bending_model, build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("spec", nargs="?", default=str(ROOT / "specimens/example3/hybrid-cm.yaml"))
    ap.add_argument("--mesh", default="12x12")
    ap.add_argument("--budget", type=int, default=0,
                    help="evaluation cap of every profile fit (default: the library's)")
    a = ap.parse_args()
    if a.budget:
        unc.PROFILE_EVALUATIONS = unc.PROFILE_MID_EVALUATIONS = a.budget
        unc.PROFILE_INITIAL_EVALUATIONS = a.budget
    spec = read_specimen(a.spec)
    fm = bending_model(build_forward_model(spec, tuple(int(v) for v in a.mesh.split("x"))))

    fits = []
    made = {}
    refit, profiles = unc.refit_held, unc.with_profiles

    def counted_refit(result, fms, sigmas, kw, joint, label, value=None, **k):
        t = time.perf_counter()
        c = time.process_time()
        model = k.get("model")
        n0 = model.n_evaluations if model is not None else 0
        r, uc = refit(result, fms, sigmas, kw, joint, label, value, **k)
        u = made["u"]
        # the reduced model's evaluations (laminid_cli.uncertainty.refit_reduced), those of a
        # fit it refused included (identify() then made the fit)
        reduced = model.n_evaluations - n0 if model is not None else 0
        route = "reduced" if "reduced_evaluations" in r.work else "identify"
        fits.append((label, value, "initial" if k.get("from_initial") else "optimum",
                     r.evaluations if route == "identify" else 0, r.options.max_evaluations,
                     r.converged,
                     (uc.chi2 - u.chi2) / (u.variance_factor if u.variance_factor > 0 else 1.0),
                     time.perf_counter() - t, reduced, time.process_time() - c, route))
        return r, uc

    def timed_profiles(u, *args, **kw):
        made["u"] = u
        t = time.perf_counter()
        out = profiles(u, *args, **kw)
        made["t"] = time.perf_counter() - t
        return out

    unc.refit_held, unc.with_profiles = counted_refit, timed_profiles
    t = time.perf_counter()
    cpu = time.process_time()
    a_ = unc.assess(fm, IdentifyOptions(), unc.UncertaintyOptions(jobs=1))
    total = time.perf_counter() - t
    cpu = time.process_time() - cpu
    r = a_.result
    print(f"{spec.name} {a.mesh}: assessment {total:.2f} s ({cpu:.2f} s CPU), "
          f"identification {r.time_s:.2f} s "
          f"({r.evaluations} evaluations), profiles {made.get('t', 0.0):.2f} s, one process"
          + (f"; every profile fit capped at {a.budget} evaluations" if a.budget else ""))
    print("  (the rise omits a prior row of the constant held; a finished fit's rise is its "
          "minimum's, an unfinished one's an upper bound)")
    for lab, p in (a_.uncertainty.profiles or {}).items():
        mine = [f for f in fits if f[0] == lab]
        print(f"{lab}: {len(mine)} fits, {sum(f[3] for f in mine)} evaluations + "
              f"{sum(f[8] for f in mine)} reduced, {sum(f[7] for f in mine):.2f} s")
        for _, v, start, n, cap, done, rise, dt, nr, cpu, route in mine:
            print(f"    held {v:10.4g} from the {start:7s} {n:4d} / {cap:4d} evaluations "
                  f"+ {nr:4d} reduced ({route:8s}) "
                  f"{'finished  ' if done else 'unfinished'} rise {rise:9.3f}  {dt:5.2f} s")
        print(f"    -> {p.text}")
    print(f"all profiles: {len(fits)} fits, {sum(f[3] for f in fits)} evaluations of "
          f"identify() + {sum(f[8] for f in fits)} of the profiles' reduced models, "
          f"{sum(f[7] for f in fits):.2f} s wall, {sum(f[9] for f in fits):.2f} s CPU")


if __name__ == "__main__":
    main()
