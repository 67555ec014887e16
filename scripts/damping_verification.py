"""Verification figures of the ply loss-factor identification (laminid_cli.damping).

For S1.1 and S2.1 with their file constants (12x12 mesh unless --mesh), ply loss factors
eta11 = 0.2 %, eta22 = 1.2 %, eta12 = 1.8 % (eta13 = eta23 = 1.2 %, fixed in the fits):

1. the energy shares: largest |sum - 1| over the modes, and the term energies against
   phi^T K phi of the assembled K;
2. the noise-free round trip (all five free, and 13/23 fixed);
3. coverage of the 95 % intervals over N seeded trials with 5 % noise on zeta, for the three
   covariance scalings;
4. strain-energy vs complex-eigenvalue loss factors on a coarse mesh (--coarse), for term
   moduli (the method's own model) and for complex engineering moduli with a real nu12.

Run::

    .venv/bin/python scripts/damping_verification.py [--trials 200] [--mesh 12x12]
"""

from __future__ import annotations

import argparse
import os
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from laminid_cli import damping as D  # noqa: E402
from laminid_cli.fe.mesh import parse_mesh  # noqa: E402
from laminid_cli.forward import build_forward_model  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402

ETA = np.array([0.002, 0.012, 0.018, 0.012, 0.012])
SPECS = ("specimens/example1/S1.1.yaml", "specimens/example2/S2.1.yaml")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--mesh", default="12x12")
    ap.add_argument("--coarse", default="4x4")
    ap.add_argument("--modes", type=int, default=12)
    args = ap.parse_args()
    for path in SPECS:
        spec = read_specimen(path)
        fm = build_forward_model(spec, parse_mesh(args.mesh))
        c = fm.initial_constants
        modes = fm.solve(c, args.modes)
        t0 = time.perf_counter()
        shares = D.energy_shares(fm.plate, c, modes.phi)
        t_sh = time.perf_counter() - t0
        U = D.term_energies(fm.plate, c, modes.phi).sum(axis=(0, 1))
        K = fm.plate.stiffness(c)
        direct = np.einsum("ij,ij->j", modes.phi, K @ modes.phi)
        labels = D.loss_labels(fm.material_names)
        fix = {labels[3]: ETA[3], labels[4]: ETA[4]}
        y = shares @ ETA
        print(f"== {spec.name} ({args.mesh}, {args.modes} modes)")
        print(f"  shares: max |sum - 1| = {np.abs(shares.sum(axis=1) - 1).max():.2e}; "
              f"term energies vs phi^T K phi: {np.abs(U / direct - 1).max():.2e}; "
              f"{t_sh * 1e3:.1f} ms")
        print(f"  largest share of 13 / 23: {shares[:, 3].max():.2%} / {shares[:, 4].max():.2%}")
        for name, fx in (("all free", {}), ("13,23 fixed", fix)):
            fit = D.fit_loss_factors(shares, y, 0.05 * y, labels, fixed=fx)
            print(f"  noise-free round trip ({name}): max |error| = "
                  f"{np.abs(fit.value - ETA[:fit.value.size]).max():.2e}")
        for scaling in ("larger", "residuals", "stated"):
            rng = np.random.default_rng(1)
            hits = np.zeros(3)
            t0 = time.perf_counter()
            for _ in range(args.trials):
                noisy = y * (1 + 0.05 * rng.standard_normal(y.size))
                fit = D.fit_loss_factors(shares, noisy, 0.05 * y, labels, fixed=fix,
                                         scaling=scaling)
                hits += (fit.lower <= ETA[:3]) & (ETA[:3] <= fit.upper)
            cov = ", ".join(f"{lab.rsplit('.', 1)[1]} {h / args.trials:.1%}"
                            for lab, h in zip(labels, hits))
            print(f"  coverage of the 95 % intervals, 5 % noise, {args.trials} trials, "
                  f"{scaling}: {cov} ({time.perf_counter() - t0:.2f} s)")
        fmc = build_forward_model(spec, parse_mesh(args.coarse))
        mc = fmc.solve(c, 8)
        for eta in (ETA, ETA * 0.02 / ETA.max(), np.array([0.015, 0.015, 0.02, 0.01, 0.01])):
            mse = D.modal_loss_factors(D.energy_shares(fmc.plate, c, mc.phi), eta)
            for moduli in ("terms", "engineering"):
                t0 = time.perf_counter()
                cm = D.complex_modal_loss_factors(fmc, c, [eta], 8, moduli=moduli,
                                                  method="shift-invert")
                dev = np.abs(cm.loss_factor / mse - 1).max()
                print(f"  complex eigenvalues ({args.coarse}, {fmc.plate.n_dofs} DOF, moduli "
                      f"{moduli}, eta {np.round(100 * eta, 2).tolist()} %): max relative "
                      f"difference {dev:.2e} ({time.perf_counter() - t0:.2f} s)")


if __name__ == "__main__":
    main()
