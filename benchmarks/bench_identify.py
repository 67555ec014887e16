"""Identification benchmark: S1.1 with the reduced and the full solver, and the whole CLI.

Per mesh (8x8, 12x12, 16x16, 24x24 by default) and solver: wall time of the identification,
the model evaluations, and the work counted by laminid_cli.modal.WORK (Cholesky factorisations,
solve pairs = one right-hand side through forward and back substitution, Lanczos runs),
expressed in full-solve equivalents:

    FSE = (factorisations * t_factor + solve_pairs * t_pair) / (t_factor + s_full * t_pair)

with t_factor, t_pair the median times of one factorisation and one single-vector solve pair
on that mesh, and s_full the solve pairs of one full solve at the start (its Lanczos run).
Then the whole CLI process ``laminid identify S1.1.yaml --json --no-output`` against
``laminid modes S1.1.yaml --json``, run alternately (median of CLI_REPEAT each).
All ratios come from one run (the machine may be loaded; ratios are what to compare). The CPU
time of the process is printed beside the wall time: on a loaded machine it is the steadier.

The model is the one the identify command uses: a symmetric laminate's bending equations
alone where its membrane modes lie well above the measured ones (forward.bending_model).

Run: .venv/bin/python benchmarks/bench_identify.py [--meshes 8,12,16,24] [--no-cli] [SPEC]
"""

from _timing import median_time  # first: sets single-threaded BLAS

import argparse  # noqa: E402
import os  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from laminid_cli.forward import bending_model, build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions, identify  # noqa: E402
from laminid_cli.modal import WORK, reset_work  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402

REPEAT = 3
CLI_REPEAT = 5
ROOT = Path(__file__).resolve().parents[1]


def unit_costs(fm, n_modes):
    """(t_factor, t_pair, t_full_solve, solve pairs of one full solve)."""
    coef = fm.plate.coefficients(fm.initial_constants)
    K = fm.plate.stiffness(coef=coef)
    sigma = -0.5 * fm.plate.shift_estimate(coef)
    data = K.data - sigma * fm.plate.M_on_K
    t_factor, solve = median_time(lambda: fm.factorizer.factor(data), 7)
    x = np.random.default_rng(0).standard_normal(fm.plate.n_dofs)
    t_pair, _ = median_time(lambda: solve(x), 21)
    t_full, _ = median_time(lambda: fm.solve(n_modes=n_modes), 5)
    reset_work()
    fm.solve(n_modes=n_modes)
    return t_factor, t_pair, t_full, WORK["solve_pairs"]


def bench(path, mesh, repeat=REPEAT):
    spec = read_specimen(path)
    fm = bending_model(build_forward_model(spec, mesh))
    n = spec.measured.freq.size + IdentifyOptions().extra_modes
    t_f, t_s, t_full, s_full = unit_costs(fm, n)
    unit = t_f + s_full * t_s
    which = ("its bending equations, of " + str(fm.whole.plate.n_dofs) if fm.whole is not None
             else "the whole plate")
    print(f"{spec.name} {mesh[0]}x{mesh[1]}: {fm.plate.n_dofs} equations ({which}; as the "
          f"pipeline, forward.bending_model), factorisation "
          f"{fm.factorizer.name} (LAMINID_FACTORIZER=banded|cholmod chooses)", flush=True)
    rows = {}
    for solver in ("reduced", "full"):
        runs = []
        cpu = []
        for _ in range(repeat):
            fm = bending_model(build_forward_model(spec, mesh))
            reset_work()
            t, c = time.perf_counter(), time.process_time()
            r = identify(fm, IdentifyOptions(solver=solver))
            runs.append((time.perf_counter() - t, r, dict(WORK)))
            cpu.append(time.process_time() - c)
        t_id = statistics.median(t for t, _, _ in runs)
        t_cpu = statistics.median(cpu)
        _, r, w = runs[0]
        fse = (w["factorizations"] * t_f + w["solve_pairs"] * t_s) / unit
        rows[solver] = (t_id, r, w, fse)
        print(f"{spec.name:<6} {mesh[0]:>2}x{mesh[1]:<2} {solver:<7} identify {t_id:6.2f} s "
              f"(CPU {t_cpu:6.2f} s)  "
              f"= {t_id / t_full:5.1f} full solves ({t_full * 1e3:5.1f} ms)  "
              f"evaluations {r.evaluations:3d}  factorisations {w['factorizations']:2d}  "
              f"solve pairs {w['solve_pairs']:4d}  Lanczos {w['lanczos_runs']:2d}  "
              f"FSE {fse:5.1f}  objective {r.objective:.9e}", flush=True)
    red, full = rows["reduced"], rows["full"]
    print(f"       {'':5}   reduced/full: time {red[0] / full[0]:.2f}, FSE "
          f"{red[3] / full[3]:.2f}; objective rel. diff "
          f"{red[1].objective / full[1].objective - 1:+.1e}; (t_factor {t_f * 1e3:.2f} ms, "
          f"t_pair {t_s * 1e3:.3f} ms, full solve = 1 factorisation + {s_full} pairs)",
          flush=True)


def cli_ratio(path):
    # as installed, from bytecode: with PYTHONDONTWRITEBYTECODE set (as in some CI and sandbox
    # environments) every run would compile laminid's sources again, and identify imports
    # several times the laminid code modes does (~50 ms more CPU per run, measured 2026-11-23)
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "laminid_cli")],
                   check=True, stdout=subprocess.DEVNULL)
    exe = [sys.executable, "-m", "laminid_cli"]
    env = dict(os.environ)
    cmds = {"identify": exe + ["identify", str(path), "--json", "--no-output"],
            "modes": exe + ["modes", str(path), "--json"]}
    times = {k: [] for k in cmds}
    cpu = {k: [] for k in cmds}
    for _ in range(CLI_REPEAT):
        for k, c in cmds.items():
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            subprocess.run(c, check=False, stdout=subprocess.DEVNULL, env=env, cwd=ROOT)
            times[k].append(time.perf_counter() - t)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[k].append(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
    ti, tm = statistics.median(times["identify"]), statistics.median(times["modes"])
    ci, cm = statistics.median(cpu["identify"]), statistics.median(cpu["modes"])
    print(f"CLI: identify --json --no-output {ti:.2f} s, modes --json {tm:.2f} s, "
          f"ratio {ti / tm:.2f} (median of {CLI_REPEAT}, run alternately); CPU {ci:.2f} s / "
          f"{cm:.2f} s, ratio {ci / cm:.2f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("spec", nargs="?", default=str(ROOT / "specimens/example1/S1.1.yaml"))
    ap.add_argument("--meshes", default="8,12,16,24")
    ap.add_argument("--no-cli", action="store_true")
    ap.add_argument("--repeat", type=int, default=REPEAT, help="identifications per row")
    a = ap.parse_args()
    for m in a.meshes.split(","):
        bench(a.spec, (int(m), int(m)), a.repeat)
    if not a.no_cli:
        cli_ratio(a.spec)
