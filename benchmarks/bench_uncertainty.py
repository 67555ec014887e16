"""Monte Carlo benchmark: one identification of S1.1 against --monte-carlo N trials.

In one run (ratios are what to compare; the machine may be loaded): the wall time of one
identification (median of REPEAT), then ``monte_carlo`` with N trials (default 200) with
``-j 1`` and ``-j 2`` for each trial route ("reduced": the optimum's TrialModel; "identify":
identify() from the optimum with its basis, the route before the trial model, run on
--identify-trials trials and scaled to N), the time per trial, the ratio of the whole Monte
Carlo to one identification, and the work per trial
counted by laminid_cli.modal.WORK (factorisations, solve pairs, Lanczos runs, the reduced
models' dense eigenproblems, one per trial-model evaluation; with -j 1, in
this process, model build and its enrichment by the first trials included; a trial check's
triangular solve counts as half a solve pair). Single-threaded BLAS, as the CLI.

``--fix G13,G23,nu12``: the trials identify only the other constants, as after
``--fix-undetermined`` on S1.1 (those three are flagged there): the result they start from is
identified with them fixed, from the first identification's basis (as assess() does); the
ratio is still to the one identification with every constant free.

``--cli N``: also the whole commands as a user runs them, N times each, alternated:
``laminid identify SPEC --json --no-output`` against ``laminid identify SPEC --monte-carlo
TRIALS -j 2 --json --no-output`` (from bytecode; the mesh the specimen file gives), their
median wall times and ratio.

Run: .venv/bin/python benchmarks/bench_uncertainty.py [--trials 200] [--mesh 12x12]
     [--routes reduced,identify] [--jobs 1,2] [--fix LIST] [--cli N] [SPEC]
"""

from _timing import median_time  # first: sets single-threaded BLAS

import argparse  # noqa: E402
import os  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from laminid_cli.forward import bending_model, build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions, identify  # noqa: E402
from laminid_cli.modal import WORK, reset_work  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402
from laminid_cli.uncertainty import frequency_sigma, monte_carlo, uncertainty_of  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REPEAT = 3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("spec", nargs="?", default=str(ROOT / "specimens/example1/S1.1.yaml"))
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--mesh", default="12x12")
    ap.add_argument("--routes", default="reduced,identify")
    ap.add_argument("--identify-trials", type=int, default=20,
                    help="trials of the (slow) identify route; the ratio is scaled to --trials")
    ap.add_argument("--jobs", default="1,2")
    ap.add_argument("--fix", default="", help="constants fixed for the trials, e.g. G13,G23,nu12")
    ap.add_argument("--cli", type=int, default=0, metavar="N",
                    help="also time the whole commands N times each, alternated")
    a = ap.parse_args()
    if a.cli:
        cli_ratio(a.spec, a.trials, a.cli)
    mesh = tuple(int(v) for v in a.mesh.split("x"))
    spec = read_specimen(a.spec)
    fm = bending_model(build_forward_model(spec, mesh))
    t_id, r = median_time(lambda: identify(fm), REPEAT)
    reset_work()
    c = time.process_time()
    identify(fm)
    cpu_id = time.process_time() - c
    w_id = dict(WORK)
    print(f"{spec.name} {a.mesh}: one identification {t_id:.2f} s (median of {REPEAT}; CPU "
          f"{cpu_id:.2f} s), "
          f"factorisations {w_id['factorizations']}, solve pairs {w_id['solve_pairs']}, "
          f"Lanczos {w_id['lanczos_runs']}, reduced eigenproblems "
          f"{w_id['reduced_eigenproblems']}", flush=True)
    sig = frequency_sigma(fm.specimen.measured)
    if a.fix:
        fix = tuple(k.strip() for k in a.fix.split(",") if k.strip())
        t, c = time.perf_counter(), time.process_time()
        r = identify(fm, IdentifyOptions(fix=fix), basis=r.basis.copy())
        print(f"  with {', '.join(fix)} fixed (from the first identification's basis): "
              f"{time.perf_counter() - t:.2f} s, {r.evaluations} evaluations; the trials "
              f"identify {', '.join(n for n in r.free[r.material_names[0]])}", flush=True)
    u = uncertainty_of(r, fm, sig)
    for route in a.routes.split(","):
        n = a.trials if route == "reduced" else a.identify_trials
        for jobs in (int(j) for j in a.jobs.split(",")):
            reset_work()
            t, c = time.perf_counter(), time.process_time()
            mc = monte_carlo(r, fm, sig, u, n, jobs=jobs, seed=0, method=route)
            dt, cpu = time.perf_counter() - t, time.process_time() - c
            per = ""
            if jobs == 1:
                per = (f"  per trial: factorisations {WORK['factorizations'] / n:.2f}, solve pairs "
                       f"{WORK['solve_pairs'] / n:.1f}, Lanczos {WORK['lanczos_runs'] / n:.2f}, "
                       f"reduced eigenproblems {WORK['reduced_eigenproblems'] / n:.1f}; "
                       f"CPU {cpu / n * 1e3:.1f} ms per trial, {a.trials} trials = "
                       f"{cpu / n * a.trials / cpu_id:.1f} x one identification's CPU")
            scaled = dt / n * a.trials
            print(f"  MC {route:<8} -j {jobs}: {n} trials {dt:7.2f} s, {dt / n * 1e3:6.1f} ms "
                  f"per trial = {dt / n / t_id:.3f} identifications; {a.trials} trials = "
                  f"{scaled / t_id:6.1f} x one identification; converged "
                  f"{mc.n_converged}, re-identified {mc.n_reidentified}, eigenvalue bound "
                  f"{mc.trial_bound:.1e}{per}", flush=True)


def cli_ratio(spec, trials: int, repeat: int):
    """The whole commands, alternated, from bytecode (as bench_identify.cli_ratio)."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "laminid_cli")],
                   check=True, stdout=subprocess.DEVNULL)
    base = [sys.executable, "-m", "laminid_cli", "identify", str(spec), "--json",
            "--no-output"]
    cmds = {"identify": base, "monte-carlo": base + ["--monte-carlo", str(trials), "-j", "2"]}
    times = {k: [] for k in cmds}
    for _ in range(repeat):
        for k, c in cmds.items():
            t = time.perf_counter()
            subprocess.run(c, check=True, stdout=subprocess.DEVNULL, env=dict(os.environ),
                           cwd=ROOT)
            times[k].append(time.perf_counter() - t)
    ti, tm = (statistics.median(times[k]) for k in cmds)
    print(f"CLI: identify --json --no-output {ti:.2f} s, with --monte-carlo {trials} -j 2 "
          f"{tm:.2f} s: {tm / ti:.2f} x (median of {repeat}, alternated; each run: "
          + ", ".join(f"{a:.2f}/{b:.2f}" for a, b in zip(*times.values())) + ")", flush=True)


if __name__ == "__main__":
    main()
