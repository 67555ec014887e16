"""Forward-model benchmark: element matrices, assembly, one 20-mode solve (S1.1, 12x12 and 24x24),
and the two factorisations of K - sigma M (CHOLMOD through cvxopt, and the banded Cholesky):
factorisation, solves of 1 and 16 right-hand sides, the factor's size.

Run: .venv/bin/python benchmarks/bench_forward.py   (median of REPEAT runs, single-threaded BLAS)
"""

from _timing import median_time as _median_time  # first: sets single-threaded BLAS

from pathlib import Path  # noqa: E402

from laminid_cli.fe import element as fe_el  # noqa: E402
from laminid_cli.fe.assembly import _unique_elements, build_plate_model, element_matrices  # noqa: E402
from laminid_cli.fe.mesh import rectangular_mesh  # noqa: E402
from laminid_cli.laminate import laminate_from_specimen  # noqa: E402
from laminid_cli.material import c_basis  # noqa: E402
import numpy as np  # noqa: E402

from laminid_cli.modal import (FACTORIZERS, cholmod_available, make_factorizer,  # noqa: E402
                                solve_modes)
from laminid_cli.specimen import read_specimen  # noqa: E402

REPEAT = 7
ROOT = Path(__file__).resolve().parents[1]


def median_time(fn, repeat=REPEAT):
    return _median_time(fn, repeat, warmup=False)


def main():
    spec = read_specimen(ROOT / "specimens/example1/S1.1.yaml")
    lam = laminate_from_specimen(spec)
    print(f"S1.1: {lam.n_plies} plies, a = {spec.a} m, b = {spec.b} m, h = {spec.h} m")
    print(f"{'mesh':>6} {'DOF':>6} {'elem (all el.) ms':>18} {'elem (unique) ms':>17} "
          f"{'assembly ms':>12} {'factorisation':>13} {'factor ms':>10} {'solve 1 ms':>11} "
          f"{'solve 16 ms':>12} {'factor MB':>10} {'solve 20 modes ms':>18}")
    kinds = [k for k in FACTORIZERS if k != "cholmod" or cholmod_available()]
    for n in (12, 24):
        mesh = rectangular_mesh(spec.a, spec.b, n, n)
        xy = mesh.nodes[mesh.elements]
        C = c_basis(lam.angle)[None]
        D_p, D_s = fe_el.laminate_operators(lam.z, lam.h, C.reshape(6, lam.n_plies, 5, 5))
        J = fe_el.inertia_operator(lam.z, lam.h, lam.density)
        t_all, _ = median_time(lambda: element_matrices(xy, lam.h, D_p, D_s, J), 3)
        first, _ = _unique_elements(xy)
        t_unique, _ = median_time(lambda: element_matrices(xy[first], lam.h, D_p, D_s, J))
        t_asm, pm = median_time(lambda: build_plate_model(
            mesh, lam.h, lam.z, lam.angle, lam.material_index, lam.density))
        coef = pm.coefficients(lam.constants)
        sigma = -0.5 * pm.shift_estimate(coef)
        K = pm.stiffness(coef=coef)
        data = K.data - sigma * pm.M_on_K
        R = pm.rigid_modes()
        rng = np.random.default_rng(0)
        b1, b16 = rng.standard_normal(pm.n_dofs), rng.standard_normal((pm.n_dofs, 16))
        t_m1, _ = median_time(lambda: pm.M @ b16)
        t_m2, _ = median_time(lambda: pm.mass @ b16)
        print(f"{n}x{n}: M @ (16 columns): assembled CSR {t_m1 * 1e3:.2f} ms, S kron J "
              f"(KroneckerMass) {t_m2 * 1e3:.2f} ms")
        for kind in kinds:
            fac = make_factorizer(pm.indptr, pm.indices, block=9, kind=kind)
            t_fac, f = median_time(lambda: fac.factor(data))
            t_1, _ = median_time(lambda: f(b1))
            t_16, _ = median_time(lambda: f(b16))
            t_solve, modes = median_time(lambda: solve_modes(K, pm.M, 20, rigid=R, sigma=sigma,
                                                             factorizer=fac,
                                                             M_on_pattern=pm.M_on_K,
                                                             M_products=pm.mass))
            print(f"{n}x{n:<3} {pm.n_dofs:>6} {t_all * 1e3:>18.1f} {t_unique * 1e3:>17.2f} "
                  f"{t_asm * 1e3:>12.1f} {kind:>13} {t_fac * 1e3:>10.1f} {t_1 * 1e3:>11.2f} "
                  f"{t_16 * 1e3:>12.1f} {factor_megabytes(fac, f):>10.1f} "
                  f"{t_solve * 1e3:>18.1f}")
    print("assembly = basis matrices (6 per material) + mass, CSR; factor = K - sigma M on the "
          "plan made once; factor MB = the factor's entries, 8 bytes each (CHOLMOD: the "
          "entries of L; banded: the band); solve 20 modes = factorisation + Lanczos (eigsh "
          "shift-invert), 20 elastic modes + 6 rigid")


def factor_megabytes(plan, f):
    if plan.name == "banded":
        return f.cb.nbytes / 1e6
    from cvxopt import cholmod

    # entries of L (a simplicial factor of the same matrix): 8 bytes each
    F = plan._analyse(supernodal=0)
    cholmod.numeric(plan._matrix(), F)
    return len(cholmod.getfactor(F)) * 8 / 1e6


if __name__ == "__main__":
    main()
