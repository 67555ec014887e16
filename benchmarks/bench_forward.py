"""Forward-model benchmark: element matrices, assembly, one 20-mode solve (S1.1, 12x12 and 24x24).

Run: .venv/bin/python benchmarks/bench_forward.py   (median of REPEAT runs, single-threaded BLAS)
"""

from _timing import median_time as _median_time  # first: sets single-threaded BLAS

from pathlib import Path  # noqa: E402

from laminid_cli.fe import element as fe_el  # noqa: E402
from laminid_cli.fe.assembly import _unique_elements, build_plate_model, element_matrices  # noqa: E402
from laminid_cli.fe.mesh import rectangular_mesh  # noqa: E402
from laminid_cli.laminate import laminate_from_specimen  # noqa: E402
from laminid_cli.material import c_basis  # noqa: E402
from laminid_cli.modal import BandedCholesky, solve_modes  # noqa: E402
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
          f"{'assembly ms':>12} {'solve 20 ms':>12} {'band':>5}")
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
        fac = BandedCholesky.from_pattern(pm.indptr, pm.indices, block=9)
        sigma = -0.5 * pm.shift_estimate(coef)
        R = pm.rigid_modes()
        t_solve, modes = median_time(lambda: solve_modes(pm.stiffness(coef=coef), pm.M, 20, rigid=R,
                                                         sigma=sigma, factorizer=fac,
                                                         M_on_pattern=pm.M_on_K))
        print(f"{n}x{n:<3} {pm.n_dofs:>6} {t_all * 1e3:>18.1f} {t_unique * 1e3:>17.2f} "
              f"{t_asm * 1e3:>12.1f} {t_solve * 1e3:>12.1f} {fac.bandwidth:>5}")
    print("assembly = basis matrices (6 per material) + mass, CSR; solve = K(p) + banded "
          "Cholesky + Lanczos (eigsh shift-invert), 20 elastic modes + 6 rigid")


if __name__ == "__main__":
    main()
