"""Ply loss factors from measured modal damping: the modal strain energy method.

Model (Adams & Bacon 1973; Ni & Adams 1984; Maheri & Adams 1994 for plates with transverse
shear). The loss factor of mode i is the energy-weighted mean of the ply loss factors::

    eta_i = sum_m sum_k eta_mk U_mik / U_i,     U_i = sum_m sum_k U_mik = phi_i^T K phi_i / 2

with U_mik the strain energy of mode i stored in the stress-strain term k of material m, in the
material's own axes (1 fibre, 2 transverse, 3 normal), and eta_mk the loss factor of that term
(specific damping capacity psi = 2 pi eta). The five terms k (:data:`TERMS`) are::

    11:  sigma_1 eps_1 / 2  = (Q11 eps_1^2 + Q12 eps_1 eps_2) / 2
    22:  sigma_2 eps_2 / 2  = (Q22 eps_2^2 + Q12 eps_1 eps_2) / 2
    12:  tau_12 gamma_12 / 2 = G12 gamma_12^2 / 2
    13:  tau_13 gamma_13 / 2 = G13 gamma_13^2 / 2
    23:  tau_23 gamma_23 / 2 = G23 gamma_23^2 / 2

The nu12 coupling term Q12 eps_1 eps_2 is split equally between 11 and 22: this is Adams and
Bacon's partition of the energy into the products sigma_k eps_k of each direction (the energy
that each direction's stress does on its own strain), which Ni & Adams use; the five terms add up
to the whole strain energy exactly. In complex-modulus form it is the damping model
Q11 (1 + i eta11), Q22 (1 + i eta22), Q12 (1 + i (eta11 + eta22)/2), G12 (1 + i eta12), ...
(:func:`complex_coefficients`, ``moduli="terms"``), of which the strain-energy loss factors are
the exact first-order eigenvalue perturbation. Complex engineering moduli E1 (1 + i eta11),
E2 (1 + i eta22) with a real nu12 (``moduli="engineering"``) are another damping model: to first
order Q11, Q22 and Q12 gain i d (eta22 - eta11) with d = nu12^2 E2 / (E1 - nu12^2 E2), and Q12
carries eta22 rather than the mean; with eta11 = 0.2 %, eta22 = 1.2 % that moves the loss
factor of fibre-dominated modes by 3-5 % (S1.1, S2.1); with eta11 = eta22 both coincide.

Computation. The plate's stiffness is linear in the coefficients of the six basis matrices of
each material (laminid_cli.material, Eq. 8), and a term matrix in material axes is an
orthotropic matrix too, so it is a fixed combination of the same six basis matrices in *every*
ply orientation (the rotation is linear and the basis matrices are rotations of their 0 deg
forms). :func:`term_coefficients` gives that combination (5, 6) per material; the term energies
of all modes then follow from the basis strain energies ``phi^T K_basis[m, j] phi`` that
PlateModel.basis_energies already computes element-wise as batched products (paper Eq. 27):
no new assembly, no loop over elements or plies.

Identification. Measured modal loss factors eta_i = 2 zeta_i (zeta: viscous damping ratio of the
RFP fit or the specimen file) with standard deviations 2 sigma_zeta are fitted by bounded linear
least squares (eta >= 0, scipy.optimize.lsq_linear), each mode weighted by 1/sigma. Intervals and
verdicts follow laminid_cli.uncertainty: covariance (A^T W A)^-1 of the free, not-at-bound loss
factors, a-posteriori factor s2 = chi2/(n - p), the same scaling choices (stated / residuals /
larger), normal or Student-t quantile, verdict from the relative half-width (5 % well
determined, 30 % weak). Intervals are linear and clipped at 0. A loss factor that ends on its
bound eta = 0 is "at bound — not identified" and gets no interval (``lower``/``upper`` NaN),
as an elastic constant on a search limit (laminid_cli.uncertainty): the one-sided
0 .. q std of the unconstrained spread it had ran to 1e+06 % where the damping does not
determine it, a number no lab can act on.

On thin plates the transverse-shear terms 13 and 23 hold a tiny share of every mode's energy
(first 12 modes of S1.1, a/h = 69: at most 1.5 %; of S2.1: at most 0.5 %), so their loss
factors are not determined by the modal damping: the verdict says so; fix them
(``--fix eta13=0.01,eta23=0.01``) to free the other three.

No click, no h5py: pure library code. Shapes: ``shares`` (n_modes, n_materials * 5);
``phi`` (n_dofs, n_modes) mass-normalised.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from laminid_cli.errors import FitInputError, SpecimenError
from laminid_cli.material import ElasticConstants, c_basis, ply_stiffness
from laminid_cli.units import parse_fraction
from laminid_cli.intervals import (LEANS_WORDS, SCALINGS, VERDICT_AT_BOUND,  # noqa: F401
                                   VERDICT_FIXED, VERDICT_NOT, flag_word, interval_scale,
                                   verdict as verdict_of)

#: a loss factor the modal damping does not determine (the advice: fix it with a value);
#: ``{term}`` is the loss factor's own name (eta11 ...), so the advice names the right one
VERDICT_NOT_DAMPING = ("not determined by the measured damping — fix it (--fix {term}=<value>) "
                       "or measure more modes")


def not_determined(label: str) -> str:
    """:data:`VERDICT_NOT_DAMPING` for the loss factor ``label`` ("material.eta13"): the
    words that replace :data:`VERDICT_NOT` in its verdicts (the interval's and the Monte
    Carlo's)."""
    return VERDICT_NOT_DAMPING.format(term=label.rsplit(".", 1)[-1])


#: stress-strain terms in material axes (module docstring)
TERMS = ("11", "22", "12", "13", "23")
#: loss-factor names of the terms
LOSS_NAMES = tuple(f"eta{k}" for k in TERMS)
METHOD = "modal strain energy"
#: a loss factor is below this: twice the specimen file's largest damping ratio zeta (0.5)
MAX_LOSS_FACTOR = 1.0
#: relative standard deviation of a measured damping ratio where none is given (5 %)
DEFAULT_DAMPING_SIGMA_REL = 0.05
#: a term whose largest energy share over the fitted modes is below this is called out
SMALL_SHARE = 0.01

# material-axes entries (Q11, Q22, Q12, Q66, Q44 = G23, Q55 = G13) of a 5x5 matrix in the
# strain order [xx, yy, yz, xz, xy] at theta = 0
_ENTRY = ((0, 0), (1, 1), (0, 1), (4, 4), (2, 2), (3, 3))


def _entries(Q) -> np.ndarray:
    return np.array([Q[..., i, j] for i, j in _ENTRY]).T


def term_coefficients(c: ElasticConstants) -> np.ndarray:
    """Coefficients of the five term matrices on the six stiffness basis matrices, (5, 6), Pa.

    ``sum_j X[k, j] c_basis(theta)[j]`` is the term-k part of the ply matrix Q(theta) in
    laminate axes for every angle theta; the rows add up to
    :func:`laminid_cli.material.basis_coefficients` (the whole Q).
    """
    B = _entries(c_basis(0.0))                          # (6 basis, 6 entries)
    q11, q22, q12, q66, q44, q55 = _entries(ply_stiffness(c, 0.0))
    T = np.zeros((5, 6))
    T[0, 0], T[0, 2] = q11, q12 / 2                     # 11: sigma_1 eps_1
    T[1, 1], T[1, 2] = q22, q12 / 2                     # 22: sigma_2 eps_2
    T[2, 3] = q66                                       # 12
    T[3, 5] = q55                                       # 13
    T[4, 4] = q44                                       # 23
    return np.linalg.solve(B.T, T.T).T


def complex_coefficients(c: ElasticConstants, eta, moduli: str = "terms") -> np.ndarray:
    """Complex stiffness-basis coefficients (6,) of a ply material with loss factors ``eta``.

    eta : (5,) loss factors of the terms 11, 22, 12, 13, 23
    moduli : "terms" — each term matrix times (1 + i eta_k) (the model of the strain-energy
        method, module docstring); "engineering" — complex E1 (1 + i eta11), E2 (1 + i eta22),
        G12, G13, G23 with real nu12
    """
    eta = np.asarray(eta, float)
    if moduli == "terms":
        return (1 + 1j * eta) @ term_coefficients(c).astype(complex)
    if moduli != "engineering":
        raise ValueError(f"moduli '{moduli}' unknown (terms or engineering)")
    E1, E2 = c.E1 * (1 + 1j * eta[0]), c.E2 * (1 + 1j * eta[1])
    a0 = 1 - c.nu12**2 * E2 / E1
    entries = np.array([E1 / a0, E2 / a0, c.nu12 * E2 / a0, c.G12 * (1 + 1j * eta[2]),
                        c.G23 * (1 + 1j * eta[4]), c.G13 * (1 + 1j * eta[3])])
    B = _entries(c_basis(0.0))
    return np.linalg.solve(B.T.astype(complex), entries)


def term_energies(plate, constants, phi) -> np.ndarray:
    """Strain energies ``phi_i^T K_mk phi_i`` of every term, (n_materials, 5, n_modes), J·2/kg.

    ``plate``: PlateModel; ``constants``: one ElasticConstants per material; ``phi``
    (n_dofs, n_modes) mass-normalised, so that the sum over m and k is the eigenvalue.
    """
    E = plate.basis_energies(np.asarray(phi, float))                # (n_mat, 6, n_modes)
    X = np.array([term_coefficients(c) for c in constants])         # (n_mat, 5, 6)
    return np.einsum("mkj,mji->mki", X, E)


def energy_shares(plate, constants, phi) -> np.ndarray:
    """U_mik / U_i, (n_modes, n_materials * 5), columns material-major (m, k); rows sum to 1."""
    return shares_of_energies(plate.basis_energies(np.asarray(phi, float)), constants)


def shares_of_energies(E, constants) -> np.ndarray:
    """:func:`energy_shares` from the basis strain energies ``E = phi_i^T K_basis[m, j] phi_i``
    (n_materials, 6, n_modes) of the modes: PlateModel.basis_energies, or a reduced model's
    ``y^T Kr_mj y`` (the same quadratic form of the Ritz vector V y; the Monte Carlo trials',
    laminid_cli.uncertainty.TrialModes.energies)."""
    X = np.array([term_coefficients(c) for c in constants])         # (n_mat, 5, 6)
    U = np.einsum("mkj,mji->mki", X, np.asarray(E, float))
    U = U.reshape(-1, U.shape[-1]).T                                # (n_modes, n_mat * 5)
    return U / U.sum(axis=1, keepdims=True)


def share_labels(material_names) -> tuple[str, ...]:
    """Column labels of :func:`energy_shares`: "material.11", ... ("material.k")."""
    return tuple(f"{m}.{k}" for m in material_names for k in TERMS)


def modal_loss_factors(shares, eta) -> np.ndarray:
    """eta_i = sum shares[i, c] eta[c] (module docstring); shares (n_modes, n_cols)."""
    return np.asarray(shares, float) @ np.asarray(eta, float)


# ----------------------------------------------------------------------------------------------
# --fix for loss factors


def split_fix(items) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Split --fix items into (elastic constants, loss factors): an item whose name (after the
    last '.' before any '=') starts with 'eta' is a loss factor, e.g. "carbon.eta13=0.01"."""
    elastic, loss = [], []
    for item in items:
        item = item.strip()
        if not item:
            continue
        name = item.split("=", 1)[0].strip().rsplit(".", 1)[-1]
        (loss if name.startswith("eta") else elastic).append(item)
    return tuple(elastic), tuple(loss)


def parse_loss_fix(items, material_names) -> dict[str, float]:
    """--fix loss-factor items -> {"material.eta13": value}; "eta13=0.01" fixes every material.

    A value is required (there is no initial value to hold), written as in the specimen file
    (0.01 or "1 %", :func:`laminid_cli.units.parse_fraction`), 0 <= value <
    :data:`MAX_LOSS_FACTOR`. A material's
    own item ("carbon.eta13=0.02") holds over one for every material, in either order; the
    same loss factor given two values at the same level is refused.
    """
    out: dict[str, float] = {}
    given: dict[str, tuple[bool, float, str]] = {}   # label: (material's own, value, item)
    for item in items:
        if "=" not in item:
            raise FitInputError(f"--fix {item}: a loss factor needs a value, e.g. "
                                f"--fix {item.strip()}=0.01")
        name, text = (s.strip() for s in item.split("=", 1))
        try:
            value = parse_fraction(text)      # the specimen file's reader: 0.01 or '1 %'
        except SpecimenError as exc:
            raise FitInputError(f"--fix {item}: {name} = {text!r}: {exc}") from None
        # the specimen file takes a damping ratio zeta in (0, 0.5), i.e. eta = 2 zeta < 1; a
        # held loss factor may be 0 (the term taken as undamped), as the fit's own bound
        if not 0 <= value < MAX_LOSS_FACTOR:
            raise FitInputError(f"--fix {item}: {name} must be between 0 and "
                                f"{MAX_LOSS_FACTOR:g} (a loss factor eta = 2 zeta, the "
                                f"specimen file's damping ratios zeta < 0.5), got {text}; "
                                "write 0.01 or 1%")
        if "." in name:
            mat, const = name.rsplit(".", 1)
            if mat not in material_names:
                raise FitInputError(f"--fix {item}: no material '{mat}' (materials: "
                                    f"{', '.join(material_names)})")
            targets = [mat]
        else:
            const, targets = name, list(material_names)
        if const not in LOSS_NAMES:
            raise FitInputError(f"--fix {item}: '{const}' is not a loss factor; choose from "
                                f"{', '.join(LOSS_NAMES)}")
        own = "." in name
        for t in targets:
            label = f"{t}.{const}"
            if label in given:
                was_own, was, was_item = given[label]
                if was_own != own:
                    if was_own:
                        continue              # the material's own value stands
                elif was != value:
                    raise FitInputError(f"--fix {item}: {name} is already fixed at {was:g} "
                                        f"(--fix {was_item}); give each loss factor one value")
            given[label] = (own, value, item)
            out[label] = value
    return out


def check_loss_fix(items, fms, joint: bool = False) -> None:
    """Refuse loss-factor --fix items early (before the stiffness fit): bad names or values,
    a specimen without measured damping, or a joint fit (its damping is not identified)."""
    if not items:
        return
    fms = list(fms)
    if joint:
        raise FitInputError(f"--fix {items[0]}: loss factors are identified for single "
                            "plates only, not with --joint")
    spec = fms[0].specimen
    parse_loss_fix(items, fms[0].material_names)
    if spec.measured is None or spec.measured.damping is None:
        raise FitInputError(f"--fix {items[0]}: {spec.path} has no measured damping "
                            "(measured.damping or measured.frf_file)")


# ----------------------------------------------------------------------------------------------
# measured damping


@dataclass(frozen=True)
class MeasuredDamping:
    """Measured viscous damping ratios of the measured modes and their standard deviations.

    zeta, sigma : (n_modes,), dimensionless, NaN where not measured; source: per mode "file"
    (specimen measured.damping_sigma or the FRF fit's spread) or "relative"
    (:data:`DEFAULT_DAMPING_SIGMA_REL` times zeta) or ""
    """

    zeta: np.ndarray
    sigma: np.ndarray
    source: tuple[str, ...]

    @property
    def loss_factor(self) -> np.ndarray:
        return 2 * self.zeta

    @property
    def loss_sigma(self) -> np.ndarray:
        return 2 * self.sigma


def measured_damping(measured, sigma_rel: float = DEFAULT_DAMPING_SIGMA_REL
                     ) -> MeasuredDamping | None:
    """The damping of a specimen's ``measured`` block (None when it gives none)."""
    zeta = getattr(measured, "damping", None)
    if measured is None or zeta is None:
        return None
    zeta = np.asarray(zeta, float)
    given = getattr(measured, "damping_sigma", None)
    given = np.full(zeta.size, np.nan) if given is None else np.asarray(given, float)
    ok = np.isfinite(zeta)
    use = ok & np.isfinite(given)
    sigma = np.where(use, given, np.where(ok, sigma_rel * zeta, np.nan))
    source = tuple("file" if u else ("relative" if o else "") for u, o in zip(use, ok))
    return MeasuredDamping(zeta=zeta, sigma=sigma, source=source)


# ----------------------------------------------------------------------------------------------
# the fit


@dataclass(frozen=True)
class DampingFit:
    """Identified ply loss factors with their intervals (module docstring).

    labels : free loss factors "material.eta11", ...; value, std, lower, upper, rel_half_width,
        verdict, at_bound : per label (lower, upper NaN and rel_half_width inf where at_bound:
        held at 0, no interval)
    fixed : {"material.eta13": value} held by --fix
    measured_loss_factor, measured_sigma, model_loss_factor : (n_modes,) over the measured
        modes (NaN where not measured); used : (n_modes,) bool, the modes in the fit
    energy_shares : (n_modes, n_cols) with ``share_labels``
    """

    labels: tuple[str, ...]
    value: np.ndarray
    std: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    rel_half_width: np.ndarray
    verdict: tuple[str, ...]
    at_bound: np.ndarray
    fixed: dict
    measured_loss_factor: np.ndarray
    measured_sigma: np.ndarray
    model_loss_factor: np.ndarray
    used: np.ndarray
    energy_shares: np.ndarray
    share_labels: tuple[str, ...]
    s2: float
    chi2: float
    dof: int
    confidence: float
    quantile: float
    scaling: str
    scale_used: str
    sigma_source: str
    notes: tuple[str, ...] = ()
    method: str = METHOD
    #: the variance factor of the intervals (s2 where they are scaled by the residuals, else 1)
    variance_factor: float = 1.0
    #: the loss factors refitted in each Monte Carlo trial (:func:`with_monte_carlo_damping`)
    monte_carlo: "DampingMonteCarlo | None" = None
    #: per free loss factor: the Monte Carlo range's half-width / value, and the width for
    #: sure that the verdicts use (NaN: too few trials); None without a Monte Carlo
    mc_rel_half_width: np.ndarray | None = None
    mc_rel_half_width_lower: np.ndarray | None = None
    #: the loss factors whose verdict the Monte Carlo range made worse
    verdict_from_monte_carlo: tuple[str, ...] = ()

    def loss_factors(self) -> dict[str, float]:
        """Every loss factor (free and fixed), "material.etaXY" -> value."""
        out = dict(self.fixed)
        out.update({lab: float(v) for lab, v in zip(self.labels, self.value)})
        return out

    def as_dict(self) -> dict:
        """The JSON block "damping" (SI; loss factors as plain numbers)."""
        per: dict[str, dict] = {}
        for k, lab in enumerate(self.labels):
            mat, name = lab.rsplit(".", 1)
            per.setdefault(mat, {})[name] = {
                "value": float(self.value[k]), "std": float(self.std[k]),
                "lower": float(self.lower[k]), "upper": float(self.upper[k]),
                "rel_half_width": float(self.rel_half_width[k]), "verdict": self.verdict[k],
                "at_bound": bool(self.at_bound[k]),
                "bound_side": "lower" if self.at_bound[k] else "",
                "bound_limit": 0.0 if self.at_bound[k] else None}
            if self.mc_rel_half_width is not None:
                per[mat][name].update(
                    monte_carlo_rel_half_width=float(self.mc_rel_half_width[k]),
                    monte_carlo_rel_half_width_lower=float(self.mc_rel_half_width_lower[k]),
                    verdict_from=("monte_carlo" if lab in self.verdict_from_monte_carlo
                                  else "interval"))
        for lab, v in self.fixed.items():
            mat, name = lab.rsplit(".", 1)
            per.setdefault(mat, {})[name] = {"value": float(v), "verdict": VERDICT_FIXED}
        # the word summary.csv's and summary.json's flag gives the same loss factor of the
        # same run (a script testing "flag" read eta13 "not determined" here as plain)
        for entries in per.values():
            for entry in entries.values():
                entry["flag"] = flag_word(entry)
        out = {
            "method": self.method, "terms": ",".join(TERMS), "unit": "1",
            "loss_factors": per,
            "labels": list(self.labels), "value": self.value, "std": self.std,
            "lower": self.lower, "upper": self.upper, "verdict": list(self.verdict),
            "at_bound": [bool(b) for b in self.at_bound],
            "fixed": dict(self.fixed),
            "measured_loss_factor": self.measured_loss_factor,
            "measured_sigma": self.measured_sigma,
            "model_loss_factor": self.model_loss_factor,
            "used": [bool(u) for u in self.used],
            "energy_shares": self.energy_shares, "energy_share_labels": list(self.share_labels),
            "s2": self.s2, "chi2": self.chi2, "dof": self.dof,
            "confidence": self.confidence, "quantile": self.quantile,
            "scaling": {"requested": self.scaling, "used": self.scale_used},
            "sigma_source": self.sigma_source, "notes": list(self.notes),
        }
        if self.monte_carlo is not None:
            out["monte_carlo"] = self.monte_carlo.as_dict()
            out["verdict_from_monte_carlo"] = list(self.verdict_from_monte_carlo)
        return out


def _bounded_solve(A_all, y_all, s_all, used, eta_fixed, free):
    """The fit's bounded weighted least squares (eta >= 0, the ``eta_fixed`` columns held):
    (x of the free columns, at_bound, weighted design Aw, weighted data b, column scale).
    :func:`fit_loss_factors` and the Monte Carlo refits (:func:`monte_carlo_loss_factors`)
    both solve with it."""
    from scipy.optimize import lsq_linear

    A = A_all[used][:, free]
    w = 1.0 / s_all[used]
    b = (y_all[used] - A_all[used] @ eta_fixed) * w
    Aw = A * w[:, None]
    scale = np.linalg.norm(Aw, axis=0)
    scale[scale == 0] = 1.0
    sol = lsq_linear(Aw / scale, b, bounds=(0.0, np.inf), method="bvls", tol=1e-14,
                     lsmr_tol=None)
    x = np.maximum(sol.x / scale, 0.0)
    at_bound = np.asarray(sol.active_mask) == -1          # held at eta = 0 by the bound
    x[at_bound] = 0.0
    return x, at_bound, Aw, b, scale


def fit_loss_factors(shares, eta_measured, eta_sigma, labels, *, fixed=None,
                     scaling: str = "larger", confidence: float = 0.95,
                     sigma_source: str = "", source: str = "") -> DampingFit:
    """Bounded weighted linear least squares of the ply loss factors (module docstring).

    shares : (n_modes, n_cols) energy shares; eta_measured, eta_sigma : (n_modes,) measured
    modal loss factors and standard deviations (NaN: mode not used); labels : (n_cols,)
    "material.etaXY"; fixed : {label: value} columns held; source : where the damping was
    read ("plate.yaml, field 'measured.damping'"), named where too few modes have it.
    """
    from laminid_cli.intervals import small_chi2_note
    from laminid_cli.quantiles import chi2_ppf

    if scaling not in SCALINGS:
        raise FitInputError(f"covariance scaling '{scaling}' unknown: choose {', '.join(SCALINGS)}")
    A_all = np.asarray(shares, float)
    y_all = np.asarray(eta_measured, float)
    s_all = np.asarray(eta_sigma, float)
    labels = tuple(labels)
    fixed = dict(fixed or {})
    unknown = [lab for lab in fixed if lab not in labels]
    if unknown:
        raise FitInputError(f"--fix {unknown[0]}: not a loss factor of this plate "
                            f"({', '.join(labels)})")
    used = np.isfinite(y_all) & np.isfinite(s_all) & (s_all > 0)
    free = [j for j, lab in enumerate(labels) if lab not in fixed]
    n, p = int(used.sum()), len(free)
    if p == 0:
        raise FitInputError("every loss factor is fixed; nothing to identify")
    if n < p:
        # the specimen file and its field named (was the bare count, after the whole
        # identification had run)
        at = f"{source}: " if source else ""
        raise FitInputError(f"{at}{n} modes with measured damping for {p} free loss factors; "
                            "measure the damping of more modes or fix loss factors "
                            "(--fix eta13=0.01,eta23=0.01)")
    eta_fixed = np.array([fixed.get(lab, 0.0) for lab in labels])
    x, at_bound, Aw, b, scale = _bounded_solve(A_all, y_all, s_all, used, eta_fixed, free)
    inner = ~at_bound

    # covariance of the interior loss factors (pseudo-inverse: null directions get inf)
    def cov_of(cols):
        G = Aw[:, cols] / scale[cols]
        U_, S, Vt = np.linalg.svd(G, full_matrices=False)
        null = S <= 1e-10 * (S[0] if S.size else 1.0)
        Sinv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, S))
        C = (Vt.T * Sinv**2) @ Vt / np.outer(scale[cols], scale[cols])
        var = np.diag(C).copy()
        if null.any():
            var[np.any(np.abs(Vt[null]) > 1e-6, axis=0)] = np.inf
        return var
    var = np.full(p, np.nan)
    if inner.any():
        var[inner] = cov_of(np.flatnonzero(inner))
    if at_bound.any():                    # their std: the unconstrained spread (no interval)
        var[at_bound] = cov_of(np.arange(p))[at_bound]
    r = Aw @ x - b
    chi2 = float(r @ r)
    dof = n - int(inner.sum())
    s2 = chi2 / dof if dof > 0 else float("nan")
    used_scale, factor, q, note = interval_scale(scaling, dof, s2, confidence,
                                                 f"{n} modes for {p} loss factors")
    notes = [note] if note else []
    overstated = small_chi2_note(chi2, dof, "damping sigma")
    if overstated:
        notes.append(overstated)
    if dof > 0 and chi2 > chi2_ppf(0.99, dof):
        notes.append(f"the strain-energy model misses the measured damping by more than its "
                     f"stated noise (chi2 {chi2:.3g} for {dof} degrees of freedom): damping "
                     "not of the ply materials (air, supports, joints) or sigma too small")
    std = np.sqrt(var * factor)
    half = q * std
    # held at 0: no interval (module docstring); std stays the unconstrained spread
    lower = np.where(at_bound, np.nan, np.maximum(x - half, 0.0))
    upper = np.where(at_bound, np.nan, x + half)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(x > 0, half / x, np.inf)
    # the damping's own words: it is the measured damping, not the modes' frequencies, that
    # does not determine a loss factor
    free_labels = tuple(labels[j] for j in free)
    verdict = [verdict_of(rel[k], at_bound[k]).replace(VERDICT_NOT, not_determined(free_labels[k]))
               for k in range(p)]
    top = A_all[used].max(axis=0) if n else np.zeros(len(labels))
    small = [labels[j] for j in free if top[j] < SMALL_SHARE]
    if small:
        notes.append(small_terms_note(small))
    eta_all = eta_fixed.copy()
    eta_all[free] = x
    meas = np.where(np.isfinite(y_all), y_all, np.nan)
    return DampingFit(
        labels=free_labels, value=x, std=std, lower=lower, upper=upper, rel_half_width=rel,
        verdict=tuple(verdict), at_bound=at_bound, fixed=fixed, measured_loss_factor=meas,
        measured_sigma=np.where(np.isfinite(y_all), s_all, np.nan),
        model_loss_factor=A_all @ eta_all, used=used, energy_shares=A_all,
        share_labels=(), s2=float(s2), chi2=chi2, dof=int(dof), confidence=confidence,
        quantile=q, scaling=scaling, scale_used=used_scale, sigma_source=sigma_source,
        notes=tuple(notes), variance_factor=float(factor))


def loss_labels(material_names) -> tuple[str, ...]:
    return tuple(f"{m}.{k}" for m in material_names for k in LOSS_NAMES)


def identify_damping(fm, result, damping: MeasuredDamping, *, fix=(), scaling: str = "larger",
                     confidence: float = 0.95) -> DampingFit:
    """Ply loss factors of an identified plate (after the stiffness fit).

    fm : ForwardModel; result : its Identification (``phi_paired``, ``constants``, ``weight``);
    damping : the measured damping of the same modes; fix : --fix loss-factor items.
    Modes with frequency weight 0 are left out.
    """
    names = tuple(result.material_names)
    zeta = np.asarray(damping.zeta, float)
    n_meas = np.asarray(result.measured_hz).size
    if zeta.size != n_meas:
        raise FitInputError(f"{fm.specimen.path}: {zeta.size} damping ratios for {n_meas} "
                            "measured frequencies (field 'measured.damping')")
    shares = energy_shares(fm.plate, result.constants, result.phi_paired)
    eta = np.where(np.asarray(result.weight) > 0, damping.loss_factor, np.nan)
    src = sorted({s for s in damping.source if s})
    frf_file = getattr(fm.specimen.measured, "frf_file", "")
    # how they were made (fit-frf --into writes it; an frf_file's fit gives it): where the RFP
    # fit's assumed 2 % floor set them, that is said, not read as a measured spread
    made = getattr(fm.specimen.measured, "damping_sigma_source", "")
    source = {"file": (f"the RFP fit of the specimen's measured.frf_file {frf_file} ("
                       + (made or "spread over the stable orders, at least 2 % of the fitted "
                          "ratio") + ")" if frf_file else
                       "the specimen file's measured.damping_sigma"
                       + (f" (made by: {made})" if made else "")),
              "relative": f"{DEFAULT_DAMPING_SIGMA_REL:.0%} of each damping ratio (none given)"}
    fit = fit_loss_factors(shares, eta, damping.loss_sigma, loss_labels(names),
                           fixed=parse_loss_fix(fix, names), scaling=scaling,
                           confidence=confidence,
                           sigma_source="; ".join(source[s] for s in src),
                           source=(f"{fm.specimen.path}, field 'measured."
                                   f"{'frf_file' if frf_file else 'damping'}'"
                                   if getattr(fm.specimen, "path", "") else ""))
    import dataclasses

    return dataclasses.replace(fit, share_labels=share_labels(names),
                               measured_loss_factor=damping.loss_factor.copy())


def damping_of(fm, assessment, fix=()) -> DampingFit | None:
    """The damping step of ``identify``/``batch``: loss factors when the specimen has measured
    damping, else None. ``assessment``: laminid_cli.uncertainty.Assessment of ``fm``; when it
    has a Monte Carlo whose trials kept their energy shares, each trial refits the loss
    factors (:func:`monte_carlo_loss_factors`, :func:`with_monte_carlo_damping`)."""
    d = measured_damping(fm.specimen.measured)
    if d is None:
        return None
    u = assessment.uncertainty
    fit = identify_damping(fm, assessment.result, d, fix=fix, scaling=u.scaling,
                           confidence=u.confidence)
    mc = getattr(assessment, "monte_carlo", None)
    counted = mc is not None and mc.energy_shares is not None
    note = stiffness_doubt_note(fit, u, assessment.fixed_undetermined, counted,
                                tuple(getattr(mc, "fixed_labels", ()) or ()) if counted else ())
    if note:
        fit = dataclasses.replace(fit, notes=fit.notes + (note,))
    if not counted:
        # no Monte Carlo range counts the constants' doubt: the verdict of a loss factor whose
        # interval is too narrow for it says so itself (summary.csv and summary.json, which
        # carry no notes, gave eta12 "weak", flag empty, beside G12 "not determined")
        fit = with_leaning_verdicts(fit, u, assessment.fixed_undetermined)
    if counted:
        fit = with_monte_carlo_damping(fit, monte_carlo_loss_factors(fit, mc))
    return fit


#: the loss factor whose strain-energy share each elastic constant sets (nu12 couples 11, 22)
TERMS_OF = {"E1": ("11",), "E2": ("22",), "G12": ("12",), "G13": ("13",), "G23": ("23",),
            "nu12": ("11", "22")}


#: what a loss factor's verdict gets when its interval leans on elastic constants the modes do
#: not determine and no Monte Carlo range counts their doubt (:func:`with_leaning_verdicts`;
#: the words LEANS_WORDS are intervals', whose flag_word gives such a loss factor "leans")
_LEANS_END = ", not determined by the modes"
VERDICT_LEANS = f" — {LEANS_WORDS} {{labels}}{_LEANS_END}"


def leans_on(verdict: str) -> str:
    """The constants a loss factor's verdict says its interval leans on (the ``labels`` of
    :data:`VERDICT_LEANS`, "IM7/977-2.nu12"); "" where it says none."""
    if LEANS_WORDS not in verdict:
        return ""
    return verdict.partition(LEANS_WORDS + " ")[2].partition(_LEANS_END)[0]


def leaning(fit, u, fixed_undetermined=()) -> dict[str, list[str]]:
    """{free loss factor: [the elastic constants the modes did not determine (flagged, at a
    limit, or fixed by --fix-undetermined) whose strain-energy share it takes]} (:data:`TERMS_OF`);
    only the loss factors that lean on some."""
    doubtful = set(u.flagged) | set(fixed_undetermined)
    if u.at_bound is not None:
        doubtful |= {lab for lab, b in zip(u.labels, u.at_bound) if b}
    free = set(fit.labels)
    out: dict[str, list[str]] = {}
    for lab in sorted(doubtful):
        name, k = lab.rsplit(".", 1)
        for t in TERMS_OF.get(k, ()):
            if f"{name}.eta{t}" in free:
                out.setdefault(f"{name}.eta{t}", []).append(lab)
    return out


def with_leaning_verdicts(fit, u, fixed_undetermined=()):
    """``fit`` with :data:`VERDICT_LEANS` after the verdict of each free loss factor that leans
    on constants the modes did not determine (:func:`leaning`), unless it is not determined or
    held at 0 already (its verdict says more)."""
    lean = leaning(fit, u, fixed_undetermined)
    verdict = list(fit.verdict)
    for k, lab in enumerate(fit.labels):
        if lab in lean and not fit.at_bound[k] and not verdict[k].startswith("not determined"):
            verdict[k] += VERDICT_LEANS.format(labels=", ".join(lean[lab]))
    return dataclasses.replace(fit, verdict=tuple(verdict))


def stiffness_doubt_note(fit, u, fixed_undetermined=(), monte_carlo: bool = False,
                         drawn=()) -> str:
    """A note when free loss factors lean on elastic constants the modes did not determine
    (flagged, at a limit, or fixed by --fix-undetermined): the loss factors' intervals take
    the constants as identified (the energy shares are computed with them), so those loss
    factors are known less well than their intervals say. "" when none does. With
    ``monte_carlo`` (each trial refitted the loss factors at its own constants) the note
    says that the Monte Carlo ranges count it: the free constants' doubt, and that of the
    constants fixed by --fix-undetermined that the trials drew from their spread before
    fixing (``drawn``, laminid_cli.uncertainty.FixedDraw; one fixed on a limit of the
    search is held by the trials, its doubt not in them)."""
    lean = leaning(fit, u, fixed_undetermined)
    if not lean:
        return ""
    hit = list(lean)                                  # in the order the constants hit them
    why = sorted({lab for labs in lean.values() for lab in labs})
    return (", ".join(hit) + ": the loss factors' intervals take the elastic constants as "
            "identified, and " + ", ".join(why) + (" is" if len(why) == 1 else " are")
            + " not determined by the modes (or fixed because of it): "
            + ("this loss factor is" if len(hit) == 1 else "these loss factors are")
            + " known less well than the interval says"
            + ("; the Monte Carlo range counts the free constants' doubt"
               + (" and that of the fixed " + ", ".join(drawn) + " (each trial draws them "
                  "from their spread before fixing and" if drawn else " (each trial")
               + " refits the loss factors at its own constants)" if monte_carlo else ""))


# ----------------------------------------------------------------------------------------------
# Monte Carlo: each trial refits the loss factors at its own constants

#: the stream of the measured damping's draws: ``numpy.random.default_rng([seed, 16])``, of
#: its own, so that the frequencies (stream ``seed``) and the priors' draws (``[seed, 15]``)
#: are what they are without damping
DAMPING_STREAM = 16


@dataclass(frozen=True)
class DampingMonteCarlo:
    """The free loss factors refitted in each converged Monte Carlo trial.

    Trial t (0-based, in the order the frequencies were drawn) takes its modes' strain-energy
    shares at its own identified constants (laminid_cli.uncertainty.MonteCarlo.energy_shares)
    and the measured modal loss factors perturbed by ``eta_sigma_i * sigma_factor *
    N(0, 1)`` (row t of :data:`DAMPING_STREAM`'s (n_trials, n_modes) draws), and solves the
    main fit's bounded least squares (eta >= 0, the fixed loss factors held, the same modes).

    labels : the free loss factors; samples (n_refits, p); mean, std, lower, upper (the
    (1 - confidence)/2 quantiles), inner_lower, inner_upper (the range for sure,
    laminid_cli.uncertainty.inner_range_of) per label; trials_at_zero : refits that held
    the loss factor at 0; lower_at_zero : that end of the range is the bound's, not the
    data's (laminid_cli.uncertainty.range_ends_at_bound); linearized_std : the fit's std;
    sigma_factor : sqrt of the fit's variance factor (so both describe the same noise);
    time_s : the refits' time (the energy shares came with the trials)
    """

    labels: tuple[str, ...]
    n_trials: int
    n_refits: int
    samples: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    inner_lower: np.ndarray
    inner_upper: np.ndarray
    trials_at_zero: np.ndarray
    lower_at_zero: np.ndarray
    linearized_std: np.ndarray
    sigma_factor: float
    seed: int | None
    confidence: float
    evidence_level: float
    time_s: float

    def as_dict(self) -> dict:
        per: dict[str, dict] = {}
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = self.std / self.linearized_std
        for k, lab in enumerate(self.labels):
            mat, name = lab.rsplit(".", 1)
            per.setdefault(mat, {})[name] = {
                "mean": float(self.mean[k]), "std": float(self.std[k]),
                "lower": float(self.lower[k]), "upper": float(self.upper[k]),
                "inner_lower": float(self.inner_lower[k]),
                "inner_upper": float(self.inner_upper[k]),
                "linearized_std": float(self.linearized_std[k]), "ratio": float(ratio[k]),
                "trials_at_zero": int(self.trials_at_zero[k]),
                "lower_at_zero": bool(self.lower_at_zero[k])}
        return {"trials": self.n_trials, "refits": self.n_refits, "loss_factors": per,
                "sigma_factor": self.sigma_factor, "seed": self.seed,
                "confidence": self.confidence, "evidence_level": self.evidence_level,
                "time_s": self.time_s, "stream": DAMPING_STREAM}


def trial_damping(fit: DampingFit, n_trials: int, seed) -> np.ndarray:
    """The measured modal loss factors of every Monte Carlo trial, (n_trials, n_modes): the
    fit's measured ones plus ``measured_sigma * sqrt(variance_factor) * N(0, 1)`` from
    :data:`DAMPING_STREAM` (NaN where the fit uses no mode)."""
    rng = np.random.default_rng(None if seed is None else [int(seed), DAMPING_STREAM])
    y = np.where(fit.used, fit.measured_loss_factor, np.nan)
    noise = rng.standard_normal((int(n_trials), y.size))
    return y + noise * np.nan_to_num(fit.measured_sigma) * np.sqrt(fit.variance_factor)


def monte_carlo_loss_factors(fit: DampingFit, mc) -> DampingMonteCarlo:
    """Refit the free loss factors of ``fit`` in each converged trial of ``mc`` (a
    laminid_cli.uncertainty.MonteCarlo with ``energy_shares``): :class:`DampingMonteCarlo`.
    One small bounded least squares per trial (:func:`_bounded_solve`, the main fit's)."""
    import time

    from laminid_cli.uncertainty import (MC_EVIDENCE, inner_range_of, range_ends_at_bound,
                                         sample_spread)

    t0 = time.perf_counter()
    all_labels = tuple(lab.rsplit(".", 1)[0] + ".eta" + lab.rsplit(".", 1)[1]
                       for lab in fit.share_labels)
    free = [j for j, lab in enumerate(all_labels) if lab not in fit.fixed]
    eta_fixed = np.array([fit.fixed.get(lab, 0.0) for lab in all_labels])
    y_all = trial_damping(fit, mc.n_trials, mc.seed)
    s_all = np.where(fit.used, fit.measured_sigma, np.nan)
    rows, zero = [], np.zeros(len(free), int)
    for t, A in zip(np.asarray(mc.trials, int), np.asarray(mc.energy_shares, float)):
        x, at_bound = _bounded_solve(A, y_all[t], s_all, fit.used, eta_fixed, free)[:2]
        rows.append(x)
        zero += at_bound
    p = len(free)
    samples = np.array(rows) if rows else np.zeros((0, p))
    conf = fit.confidence
    mean, std, lower, upper = sample_spread(samples, p, conf)
    in_lo, in_hi = inner_range_of(samples, p, conf, MC_EVIDENCE)
    lower_at_zero = range_ends_at_bound(zero, np.zeros(p, int), samples.shape[0], conf)[0]
    return DampingMonteCarlo(
        labels=fit.labels, n_trials=mc.n_trials, n_refits=samples.shape[0], samples=samples,
        mean=mean, std=std, lower=lower, upper=upper, inner_lower=in_lo, inner_upper=in_hi,
        trials_at_zero=zero, lower_at_zero=lower_at_zero, linearized_std=fit.std,
        sigma_factor=float(np.sqrt(fit.variance_factor)), seed=mc.seed, confidence=conf,
        evidence_level=MC_EVIDENCE, time_s=time.perf_counter() - t0)


def small_terms_note(small) -> str:
    """The note on the loss factors ``small`` ("material.etaXY") that no fitted mode strains
    by SMALL_SHARE: why (transverse shear, which a thin plate's bending hardly strains, only
    where every one of them is eta13 or eta23: hybrid CM's glass.eta12 is in-plane shear of a
    ply its modes hardly strain) and the --fix that frees the others, naming them (by term
    alone where the plate has one material)."""
    terms = [lab.rsplit(".", 1)[-1] for lab in small]
    shear = all(t in ("eta13", "eta23") for t in terms)
    one_material = len({lab.rsplit(".", 1)[0] for lab in small}) == 1 and "." in small[0]
    items = sorted(set(terms)) if one_material else list(small)
    return (", ".join(small) + f": less than {SMALL_SHARE:.0%} of any fitted mode's strain "
            "energy is in these terms"
            + (" (transverse shear, which a thin plate's bending hardly strains)" if shear
               else "")
            + ", so the modal damping cannot determine them; fix them (--fix "
            + ",".join(f"{i}=0.01" for i in items) + ") to free the others")


def _pct(rel: float) -> str:
    from laminid_cli.intervals import width_text

    return width_text(rel) if np.isfinite(rel) else "inf"


def with_monte_carlo_damping(fit: DampingFit, dmc: DampingMonteCarlo) -> DampingFit:
    """``fit`` with its Monte Carlo (:func:`monte_carlo_loss_factors`) and the verdicts the
    Monte Carlo makes worse, by the rule of the elastic constants'
    (laminid_cli.uncertainty.with_monte_carlo): the range's width for sure
    (``inner_upper - inner_lower``, half of it over the value) in a worse band than the
    interval's gives that band's verdict marked "(Monte Carlo)", and a note says why (the
    interval takes the constants as exact; the trials refit at their own). Never better;
    a loss factor held at 0 keeps its verdict. The intervals stay the linearised ones."""
    from laminid_cli.uncertainty import monte_carlo_verdict

    p = len(fit.labels)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel_mc = np.where(fit.value > 0, 0.5 * (dmc.upper - dmc.lower) / fit.value, np.inf)
        rel_lo = np.where(fit.value > 0, 0.5 * (dmc.inner_upper - dmc.inner_lower)
                          / fit.value, np.inf)
    rel_mc = np.where(np.isfinite(dmc.upper), rel_mc, np.nan)
    rel_lo = np.where(np.isfinite(dmc.inner_upper), rel_lo, np.nan)
    verdict, changed, why = list(fit.verdict), [], []
    for k, lab in enumerate(fit.labels):
        if fit.at_bound[k] or not np.isfinite(rel_lo[k]):
            continue
        # the damping's own words for "not determined" (as fit_loss_factors)
        worse = monte_carlo_verdict(rel_lo[k], fit.rel_half_width[k], not_determined(lab))
        if worse:
            verdict[k] = worse
            changed.append(lab)
            why.append(f"{lab} (Monte Carlo ±{_pct(rel_mc[k])}, at least ±{_pct(rel_lo[k])}; "
                       f"interval ±{_pct(fit.rel_half_width[k])})")
    notes = fit.notes
    if changed:
        sure = 100 * (2 * dmc.evidence_level - 1)
        notes = notes + (
            "verdict set by the Monte Carlo range, wider than the interval: " + ", ".join(why)
            + f" (the width its trials show with {sure:.0f} % confidence): the interval takes "
            "the elastic constants as exact, each trial refits the loss factors at its own "
            "identified constants, so the range counts their doubt",)
    return dataclasses.replace(fit, verdict=tuple(verdict), notes=notes, monte_carlo=dmc,
                               mc_rel_half_width=rel_mc, mc_rel_half_width_lower=rel_lo,
                               verdict_from_monte_carlo=tuple(changed))


# ----------------------------------------------------------------------------------------------
# verification: complex eigenvalues


@dataclass(frozen=True)
class ComplexModes:
    """Complex eigenvalues lambda* = omega^2 (1 + i eta) of the damped model, paired with the
    real modes: freq_hz (n,) from Re lambda*, loss_factor (n,) = Im / Re, mac (n,)."""

    freq_hz: np.ndarray
    loss_factor: np.ndarray
    mac: np.ndarray = field(default_factory=lambda: np.zeros(0))


def complex_modal_loss_factors(fm, constants, eta, n_modes: int, *, moduli: str = "terms",
                               method: str = "dense") -> ComplexModes:
    """Modal loss factors of the complex-modulus model (verification path, not the default).

    K* = sum_m sum_j coef*_mj K_basis[m, j] with coef* from :func:`complex_coefficients`
    (eta: (n_materials, 5)); K* phi = lambda* M phi solved densely (``method="dense"``, coarse
    meshes: all eigenvalues) or by shift-invert Arnoldi about each real eigenvalue
    (``"shift-invert"``); each complex mode is paired with the real mode of largest MAC.
    """
    import scipy.linalg as sla
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigs

    plate = fm.plate
    eta = np.atleast_2d(np.asarray(eta, float))
    coef = np.array([complex_coefficients(c, e, moduli) for c, e in zip(constants, eta)])
    data = np.tensordot(coef, plate.K_data.astype(complex), axes=([0, 1], [0, 1]))
    Kc = sp.csr_matrix((data, plate.indices, plate.indptr), shape=(plate.n_dofs,) * 2)
    real = fm.solve(constants, n_modes)
    lam_r, phi_r = real.eigenvalues[:n_modes], real.phi[:, :n_modes]
    if method == "dense":
        w, V = sla.eig(Kc.toarray(), plate.M.toarray())
        keep = np.isfinite(w) & (w.real > 1e-6 * lam_r[0])
        w, V = w[keep], V[:, keep]
        near = np.argsort(w.real)[: n_modes + 12]
        w, V = w[near], V[:, near]
    elif method == "shift-invert":
        ws, vs = [], []
        for lam in lam_r:
            wi, vi = eigs(Kc, k=1, M=plate.M.astype(complex), sigma=lam)
            ws.append(wi[0])
            vs.append(vi[:, 0])
        w, V = np.array(ws), np.array(vs).T
    else:
        raise ValueError(f"method '{method}' unknown (dense or shift-invert)")
    M = plate.M
    num = np.abs(phi_r.T @ (M @ V)) ** 2
    den = np.outer(np.einsum("ij,ij->j", phi_r, M @ phi_r),
                   np.real(np.einsum("ij,ij->j", V.conj(), M @ V)))
    macs = num / den
    pick = np.argmax(macs, axis=1)
    lam_c = w[pick]
    return ComplexModes(freq_hz=np.sqrt(lam_c.real) / (2 * np.pi),
                        loss_factor=lam_c.imag / lam_c.real,
                        mac=macs[np.arange(n_modes), pick])
