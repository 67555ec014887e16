"""How well the identified constants are known: covariance, intervals, identifiability, Monte Carlo.

Frequency uncertainty
    Each measured frequency f_i has a standard deviation sigma_f,i (Hz): from the specimen file
    (``measured.sigma``, which ``fit-frf --into`` fills with the RFP fit's spread) or, where the
    file gives none, ``sigma_rel * f_i`` (:data:`DEFAULT_SIGMA_REL` = 0.2 % unless the user sets
    another value). On eigenvalues lambda = (2 pi f)^2 this is, to first order,
    ``sigma_lambda = 2 lambda sigma_f / f``.

Linearised covariance (sandwich form)
    The estimate minimises paper Eq. 17 (+ Eq. 15), i.e. the rows
    ``r_i = sqrt(w_i) (lt_i - l_i(P)) / lt_i`` whose noise has standard deviation
    ``tau_i = sqrt(w_i) 2 sigma_f,i / f_i``. With ``G = d r / d P`` over the *free engineering
    constants* P (``d lambda / d P = basis energies . d coef / d P``, so the result is in
    constants space whatever the design variables are — the delta method through the
    parametrisation is then the identity), the covariance of the estimate is::

        C = (G^T G)^-1  G^T diag(tau^2) G  (G^T G)^-1

    which is ``(G^T diag(tau^-2) G)^-1`` when the weights w_i / lt_i^2 are proportional to
    1 / sigma_lambda^2 (uniform relative sigma, unit weights: the default) and remains the right
    first-order covariance of the weighted estimate when they are not.

    A prior (Eq. 15) adds a row ``sqrt(wp) (P_j - P_j0) / P_j0`` per constant. It is read as a
    pseudo-measurement counted like a frequency of weight wp: its noise is
    ``sqrt(wp) sigma_unit`` with sigma_unit the RMS relative eigenvalue standard deviation
    2 sigma_f / f of the measured modes. A constant whose information comes mostly from its prior
    is marked "(held by the prior)".

A-posteriori variance factor
    ``s^2 = chi^2 / (n - p)``, ``chi^2 = sum (r_i / tau_i)^2`` at the optimum (n rows, p free
    constants). s^2 near 1: the residuals match the stated frequency noise. s^2 >> 1: the model
    misses the data by more than the noise (model error, wrong sigma). Scaling choices
    (:data:`SCALINGS`): ``stated`` — intervals from the stated sigma, normal quantile;
    ``residuals`` — covariance times s^2, Student-t quantile with n - p degrees of freedom;
    ``larger`` (default) — the wider of the two for the whole problem. The default never
    claims more precision than the stated noise allows, and widens the intervals when the fit is
    visibly worse than that noise (which for real plates is model error that the stated
    measurement noise does not cover).

Intervals on the constants' own scales
    Moduli are positive: their covariance is computed over ln P (the columns of G are
    d r / d ln P), so the interval is ``P exp(-q s) .. P exp(+q s)`` with ``s`` the standard
    error of ln P (``std / P``): asymmetric and never below zero. nu12 keeps its linear scale
    ``nu12 -/+ q std``, clipped to the search's feasibility bounds ``[-nu_max, nu_max]``
    (``scale`` "log" | "linear" per constant). ``half_width``/``rel_half_width`` stay
    ``q std`` and ``q std / |P|`` (for a modulus exactly ``q s``), which the verdicts use.

Constants at a bound
    A free constant that ends on a limit of the search (:func:`bounds_reached`: moduli at
    ``bound_factor`` times/over their initial value, shear moduli and E2 at
    ``MIN_MODULUS_RATIO * E1``, E2 = E1, |nu12| = nu_max) is not identified: the data would move
    it further. It gets no interval (``lower``/``upper`` NaN, ``at_bound`` true), the verdict
    :data:`VERDICT_AT_BOUND` and a one-sided statement in ``bound_text`` ("at its bound — not
    identified: G13 <= 0.0001 E1 (0.0154 GPa)"). The covariance of the other constants is
    computed with the constants at a bound held there (an active constraint), so one constant
    on its limit does not blow up every interval.

Identifiability
    Normalised sensitivities d ln f_i / d ln P_j (:attr:`Identification.sensitivity`), the
    condition number of the noise-whitened Jacobian over relative constants (moduli: d / d ln P;
    nu12: per 0.1 or per |nu12| when larger), the weakest combination of constants (its right
    singular vector), and a verdict per constant from the relative 95 % half-width
    (:data:`WELL_DETERMINED`, :data:`WEAK`). A constant whose relative half-width exceeds the
    user's ``max_rel_interval`` is flagged; :func:`assess` can fix flagged constants at their
    initial values and identify again.

Monte Carlo
    :func:`monte_carlo` re-identifies from frequencies perturbed by their (scaled) standard
    deviations, in parallel processes, each run starting at the optimum, and reports the
    empirical spread beside the linearised one.

No click, no h5py here: pure library code (DESIGN.md section 1).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import time
from dataclasses import dataclass, field

import numpy as np

from laminid_cli.errors import FitInputError
# thresholds, scalings and verdicts shared with the damping fit (re-exported here)
from laminid_cli.intervals import (SCALINGS, VERDICT_AT_BOUND, VERDICT_FIXED,  # noqa: F401
                                   VERDICT_NOT, VERDICT_WEAK, VERDICT_WELL, WEAK, WELL_DETERMINED,
                                   interval_scale, verdict as verdict_of)
from laminid_cli.material import CONSTANT_NAMES
from laminid_cli.parametrization import coefficients_and_jacobian

log = logging.getLogger(__name__)

#: default relative standard deviation of a measured frequency (0.2 %)
DEFAULT_SIGMA_REL = 0.002
#: nu12 columns are scaled by max(|nu12|, NU_SCALE) for the condition number
NU_SCALE = 0.1
#: relative singular value below which a direction counts as not determined at all
NULL_TOL = 1e-10


# ----------------------------------------------------------------------------------------------
# frequency uncertainty


@dataclass(frozen=True)
class FrequencySigma:
    """Standard deviation of each measured frequency of one plate.

    sigma_hz : (n_modes,) Hz, NaN where the mode is not measured
    source : per mode, "file" (specimen ``measured.sigma``), "relative" (sigma_rel * f) or ""
    sigma_rel : the relative default used where the file gives none
    note : how the file's sigmas were made (``measured.sigma_source``, e.g. by fit-frf)
    """

    sigma_hz: np.ndarray
    source: tuple[str, ...]
    sigma_rel: float
    note: str = ""

    @property
    def summary(self) -> str:
        """One line: where the sigmas come from."""
        n_file = self.source.count("file")
        n_rel = self.source.count("relative")
        rel = f"{self.sigma_rel * 100:.3g} % of each frequency (--sigma-rel)"
        file = "specimen file (measured.sigma" + (f"; {self.note})" if self.note else
                                                  ", origin not stated)")
        if n_file and not n_rel:
            return file
        if n_rel and not n_file:
            return rel
        return f"{file} for {n_file} modes, {rel} for {n_rel}"


def check_sigma_rel(sigma_rel: float) -> float:
    """A relative standard deviation must be a finite number > 0 (FitInputError otherwise)."""
    try:
        value = float(sigma_rel)
    except (TypeError, ValueError):
        raise FitInputError(f"relative frequency uncertainty {sigma_rel!r} is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise FitInputError(f"relative frequency uncertainty must be positive (e.g. 0.002 for "
                            f"0.2 %), got {sigma_rel:g}")
    if value >= 0.5:
        raise FitInputError(f"relative frequency uncertainty {value:g} is 50 % or more of each "
                            "frequency; give a fraction (0.002 = 0.2 %)")
    return value


def frequency_sigma(measured, sigma_rel: float = DEFAULT_SIGMA_REL, *, sigma_hz=None,
                    where: str = "") -> FrequencySigma:
    """Standard deviations of the measured frequencies of one plate.

    ``measured``: :class:`laminid_cli.specimen.Measured`. ``sigma_hz`` overrides the file's
    values (n_modes,) Hz, NaN = unknown. Zero, negative or non-finite given values are refused
    with a FitInputError naming ``where`` and the mode.
    """
    sigma_rel = check_sigma_rel(sigma_rel)
    if measured is None:
        raise FitInputError(f"{where + ': ' if where else ''}no measured frequencies: add "
                            "'measured: {frequencies: [...]}' (Hz) or 'measured: {frf_file: ...}' "
                            "to the specimen file, or run 'laminid fit-frf FRF --into SPEC'")
    freq = np.asarray(measured.freq, float)
    given = measured.sigma if sigma_hz is None else np.asarray(sigma_hz, float)
    n = freq.size
    out = np.full(n, np.nan)
    source = [""] * n
    if given is not None:
        given = np.asarray(given, float)
        if given.shape != (n,):
            raise FitInputError(f"{where}: {given.size} frequency standard deviations for {n} "
                                "frequencies")
        bad = np.flatnonzero(np.isfinite(given) & (given <= 0) | np.isinf(given))
        if bad.size:
            i = int(bad[0])
            raise FitInputError(f"{where}: standard deviation of mode {i + 1} is {given[i]:g} Hz;"
                                " it must be positive (null where unknown)")
    for i in range(n):
        if not np.isfinite(freq[i]):
            continue
        if given is not None and np.isfinite(given[i]):
            out[i], source[i] = given[i], "file"
        else:
            out[i], source[i] = sigma_rel * freq[i], "relative"
    note = getattr(measured, "sigma_source", "") if sigma_hz is None else ""
    return FrequencySigma(sigma_hz=out, source=tuple(source), sigma_rel=sigma_rel, note=note)


# ----------------------------------------------------------------------------------------------
# linearised uncertainty


@dataclass(frozen=True)
class Observations:
    """One plate's measured modes and the model's linearisation at the optimum.

    freq_hz : (n,) measured, NaN = none; weight : (n,) paper Eq. 17; sigma_hz : (n,) Hz
    lam : (n,) paired model eigenvalues, rad^2/s^2
    dlam_dP : (n, p) d lambda / d P over the free constants (global columns), SI
    """

    name: str
    freq_hz: np.ndarray
    weight: np.ndarray
    sigma_hz: np.ndarray
    lam: np.ndarray
    dlam_dP: np.ndarray


@dataclass(frozen=True)
class MaterialState:
    """A material's identified and initial constants, free constants and prior weights."""

    name: str
    constants: object          # ElasticConstants
    initial: object            # ElasticConstants
    free: tuple[str, ...]
    prior: dict


@dataclass(frozen=True)
class Uncertainty:
    """Linearised uncertainty of the free constants (SI; labels "material.constant").

    Every array is (p,) over ``labels`` unless stated. ``std`` is the standard error used for
    the intervals (after the scaling choice), ``std_stated`` the one from the stated frequency
    sigma alone. ``covariance``/``correlation`` (p, p). ``half_width`` = quantile * std;
    ``rel_half_width`` = half_width / |value| (inf for a zero value or a null direction).
    """

    labels: tuple[str, ...]
    value: np.ndarray
    std: np.ndarray
    std_stated: np.ndarray
    half_width: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    rel_half_width: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    verdict: tuple[str, ...]
    flagged: tuple[str, ...]
    fixed: tuple[str, ...]                  # labels of the fixed constants
    confidence: float
    quantile: float
    scaling: str                            # requested: stated | residuals | larger
    scale_used: str                         # stated | residuals
    variance_factor: float                  # multiplies the stated covariance (1 or s2)
    s2: float
    chi2: float
    dof: int
    n_rows: int
    condition: float
    weakest: tuple                          # ((label, coefficient), ...) largest first
    information_from_prior: np.ndarray      # (p,) fraction of each constant's information
    sigma_source: str
    thresholds: dict
    notes: tuple[str, ...] = ()
    scale: tuple[str, ...] = ()             # per label: "log" (moduli) | "linear" (nu12)
    at_bound: np.ndarray | None = None      # (p,) bool: ended on a limit of the search
    bound_text: tuple[str, ...] = ()        # per label: "" or the one-sided statement
    chi2_limit: float = float("nan")        # 99 % quantile of chi2 with dof degrees of freedom

    def as_dict(self) -> dict:
        """Plain data for JSON (per material and constant) and the report."""
        per: dict[str, dict] = {}
        for k, lab in enumerate(self.labels):
            mat, const = lab.rsplit(".", 1)
            per.setdefault(mat, {})[const] = {
                "value": float(self.value[k]), "std": float(self.std[k]),
                "std_stated": float(self.std_stated[k]),
                "lower": float(self.lower[k]), "upper": float(self.upper[k]),
                "half_width": float(self.half_width[k]),
                "rel_half_width": float(self.rel_half_width[k]),
                "verdict": self.verdict[k], "flagged": lab in self.flagged,
                "information_from_prior": float(self.information_from_prior[k]),
                "scale": self.scale[k] if self.scale else "",
                "at_bound": bool(self.at_bound[k]) if self.at_bound is not None else False,
                "bound_text": self.bound_text[k] if self.bound_text else ""}
        for lab in self.fixed:
            mat, const = lab.rsplit(".", 1)
            per.setdefault(mat, {})[const] = {"verdict": VERDICT_FIXED, "flagged": False}
        return {
            "constants": per,
            "labels": list(self.labels),
            "correlation": self.correlation,
            "covariance": self.covariance,
            "confidence": self.confidence,
            "quantile": self.quantile,
            "scaling": {"requested": self.scaling, "used": self.scale_used,
                        "variance_factor": self.variance_factor},
            "a_posteriori": {"s2": self.s2, "chi2": self.chi2, "dof": self.dof,
                             "rows": self.n_rows, "chi2_limit_99": self.chi2_limit},
            "condition_number": self.condition,
            "weakest_combination": [[lab, float(c)] for lab, c in self.weakest],
            "flagged": list(self.flagged),
            "fixed": list(self.fixed),
            "sigma_source": self.sigma_source,
            "thresholds": dict(self.thresholds),
            "notes": list(self.notes),
        }


def observations(fm, result, sigma: FrequencySigma, labels, name: str = "") -> Observations:
    """Linearise one plate at its identified optimum over the global free-constant ``labels``.

    ``result``: an Identification of ``fm`` (its ``phi_paired``, ``constants``,
    ``material_names``); d lambda_i / d P = E[m, :, i] . d coef[m] / d P (paper Eq. 26 with the
    chain rule through :func:`coefficients_and_jacobian`).
    """
    E = fm.plate.basis_energies(result.phi_paired)                 # (n_mat, 6, n_meas)
    lam = (2 * np.pi * np.asarray(result.model_hz, float)) ** 2
    col = {lab: j for j, lab in enumerate(labels)}
    D = np.zeros((lam.size, len(labels)))
    for k, (mname, c) in enumerate(zip(result.material_names, result.constants)):
        _, Jc = coefficients_and_jacobian(c)
        dP = E[k].T @ Jc                                              # (n_meas, 6)
        for i, cname in enumerate(CONSTANT_NAMES):
            j = col.get(f"{mname}.{cname}")
            if j is not None:
                D[:, j] += dP[:, i]
    return Observations(name=name or result.specimen.name, freq_hz=np.asarray(result.measured_hz),
                        weight=np.asarray(result.weight), sigma_hz=sigma.sigma_hz, lam=lam,
                        dlam_dP=D)


def material_states(result) -> tuple[MaterialState, ...]:
    """MaterialState of each material of an Identification or JointIdentification."""
    specs = [r.specimen for r in getattr(result, "specimens", ())] or [result.specimen]
    prior = {}
    for spec in specs:
        for n, m in spec.materials.items():
            prior.setdefault(n, dict(m.prior))
    return tuple(MaterialState(name=n, constants=c, initial=c0, free=tuple(result.free[n]),
                               prior=prior.get(n, {}))
                 for n, c, c0 in zip(result.material_names, result.constants, result.initial))


#: relative closeness to a limit of the search that counts as "at the bound"
BOUND_TOL = 1e-4


@dataclass(frozen=True)
class BoundHit:
    """A free constant on a limit of the search: side "lower" | "upper", the limit (SI) and the
    one-sided statement."""

    label: str
    side: str
    limit: float
    text: str


def _gpa(v: float) -> str:
    return f"{v / 1e9:.3g} GPa"


def bounds_reached(materials, nu_max: float = 0.95, bound_factor: float = 5.0
                   ) -> dict[str, BoundHit]:
    """The free constants that ended on a limit of the search (laminid_cli.parametrization),
    judged on the constants themselves whatever the design variables were:

    - a modulus at ``initial / bound_factor`` or ``initial * bound_factor`` (within
      :data:`BOUND_TOL`; with the alphas only E1 is held there, so a value beyond is not a hit);
    - G12, G13, G23 or E2 at most ``2 * MIN_MODULUS_RATIO * E1`` (the feasibility limit is
      ``MIN_MODULUS_RATIO * E1`` on the alphas, i.e. slightly above it in the constants);
    - E2 >= E1 (limit E2 <= E1, paper Eq. 22);
    - |nu12| at ``nu_max``.

    Returns {label: BoundHit}. A lower bound says "the data push it lower": the statement is
    one-sided ("G13 <= 0.0001 E1 (0.0154 GPa)").
    """
    from laminid_cli.parametrization import MIN_MODULUS_RATIO as r

    tol = BOUND_TOL
    out: dict[str, BoundHit] = {}
    for m in materials:
        c, c0 = m.constants, m.initial
        for k in m.free:
            lab = f"{m.name}.{k}"
            v = float(getattr(c, k))
            hit = None
            if k == "nu12":
                if v >= nu_max * (1 - tol):
                    hit = ("upper", nu_max, f"nu12 >= {nu_max:g}")
                elif v <= -nu_max * (1 - tol):
                    hit = ("lower", -nu_max, f"nu12 <= {-nu_max:g}")
            else:
                v0 = float(getattr(c0, k))
                lo, hi = v0 / bound_factor, v0 * bound_factor
                if k in ("E2", "G12", "G13", "G23") and v <= 2 * r * c.E1:
                    hit = ("lower", r * c.E1, f"{k} <= {r:g} E1 ({_gpa(r * c.E1)})")
                elif k == "E2" and v >= c.E1 * (1 - tol):
                    hit = ("upper", c.E1, f"E2 >= E1 ({_gpa(c.E1)})")
                # the factor limits bind every modulus of the 'constants' parametrisation but
                # only E1 of the alphas (the others can pass them): at the limit, not beyond
                elif abs(v - lo) <= tol * lo:
                    hit = ("lower", lo, f"{k} <= initial / {bound_factor:g} ({_gpa(lo)})")
                elif abs(v - hi) <= tol * hi:
                    hit = ("upper", hi, f"{k} >= {bound_factor:g} x initial ({_gpa(hi)})")
            if hit is not None:
                side, limit, stmt = hit
                out[lab] = BoundHit(lab, side, float(limit),
                                    f"at its bound — not identified: {stmt}")
    return out


def free_labels(materials) -> tuple[str, ...]:
    return tuple(f"{m.name}.{k}" for m in materials for k in CONSTANT_NAMES if k in m.free)


def linearized_uncertainty(obs, materials, *, scaling: str = "larger",
                           max_rel_interval: float = WEAK, confidence: float = 0.95,
                           sigma_source: str = "", notes=(), nu_max: float = 0.95,
                           bound_factor: float = 5.0) -> Uncertainty:
    """Covariance, intervals, correlation, condition and verdicts (module docstring).

    obs : sequence of :class:`Observations` (one per plate, columns = ``free_labels``)
    materials : sequence of :class:`MaterialState`
    nu_max, bound_factor : the search limits of the identification (IdentifyOptions), for the
        nu12 interval's clipping and :func:`bounds_reached`
    """
    from laminid_cli.quantiles import chi2_ppf

    if scaling not in SCALINGS:
        raise FitInputError(f"covariance scaling '{scaling}' unknown: choose {', '.join(SCALINGS)}")
    if not max_rel_interval > 0:
        raise FitInputError(f"the interval threshold must be positive, got {max_rel_interval:g}")
    if not 0 < confidence < 1:
        raise FitInputError(f"confidence must be in (0, 1), got {confidence:g}")
    labels = free_labels(materials)
    fixed = tuple(f"{m.name}.{k}" for m in materials for k in CONSTANT_NAMES if k not in m.free)
    p = len(labels)
    mat_of = {m.name: m for m in materials}
    value = np.array([getattr(mat_of[lab.rsplit(".", 1)[0]].constants, lab.rsplit(".", 1)[1])
                      for lab in labels], float)
    is_nu = np.array([lab.endswith(".nu12") for lab in labels], bool)
    hits = bounds_reached(materials, nu_max, bound_factor)
    at_bound = np.array([lab in hits for lab in labels], bool)
    inner = ~at_bound                      # constants at a bound are held there (module doc)
    # column scale: relative constants (moduli per ln P, nu12 per max(|nu12|, NU_SCALE))
    D = np.where(is_nu, np.maximum(np.abs(value), NU_SCALE), np.abs(value))
    rows, tau, resid = [], [], []
    rel_sd = []
    for o in obs:
        ok = (np.asarray(o.weight) > 0) & np.isfinite(o.freq_hz)
        f = o.freq_hz[ok]
        lam_m = (2 * np.pi * f) ** 2
        sw = np.sqrt(o.weight[ok])
        rows.append(-(sw / lam_m)[:, None] * o.dlam_dP[ok] * D[None, :])
        tau.append(sw * 2 * o.sigma_hz[ok] / f)
        resid.append(sw * (lam_m - o.lam[ok]) / lam_m)
        rel_sd.append(2 * o.sigma_hz[ok] / f)
    G_data = np.vstack(rows) if rows else np.zeros((0, p))
    tau_data = np.concatenate(tau)
    sigma_unit = float(np.sqrt(np.mean(np.concatenate(rel_sd) ** 2)))
    # prior rows (Eq. 15)
    prior_rows, prior_tau, prior_res = [], [], []
    for j, lab in enumerate(labels):
        mname, cname = lab.rsplit(".", 1)
        m = mat_of[mname]
        wp = float(m.prior.get(cname, 0.0))
        if wp <= 0:
            continue
        P0 = getattr(m.initial, cname)
        ref = P0 if P0 != 0 else 1.0
        row = np.zeros(p)
        row[j] = np.sqrt(wp) / ref * D[j]
        prior_rows.append(row)
        prior_tau.append(np.sqrt(wp) * sigma_unit)
        prior_res.append(np.sqrt(wp) * (value[j] - P0) / ref)
    G = np.vstack([G_data] + ([np.array(prior_rows)] if prior_rows else []))
    t = np.concatenate([tau_data, np.array(prior_tau)])
    r = np.concatenate(resid + [np.array(prior_res)])
    n_rows = G.shape[0]
    idx = np.flatnonzero(inner)
    p_in = idx.size
    # sandwich covariance in scaled variables, through the SVD of G (rank-safe), over the
    # constants not at a bound
    Gi = G[:, idx]
    U, S, Vt = np.linalg.svd(Gi, full_matrices=False)
    null = S <= NULL_TOL * (S[0] if S.size else 1.0)
    S_inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, S))
    Ginv = (Vt.T * S_inv) @ U.T                                      # pseudo-inverse (p_in, n)
    cov_s = np.full((p, p), np.nan)
    cov_s[np.ix_(idx, idx)] = Ginv @ np.diag(t**2) @ Ginv.T
    in_null = np.zeros(p, bool)
    if null.any():
        in_null[idx] = np.any(np.abs(Vt[null]) > 1e-6, axis=0)
    cov_stated = cov_s * np.outer(D, D)
    chi2 = float(np.sum((r / t) ** 2))
    dof = int(n_rows - p_in)
    s2 = chi2 / dof if dof > 0 else float("nan")
    chi2_limit = chi2_ppf(0.99, dof) if dof > 0 else float("nan")
    notes = list(notes)
    if at_bound.any():
        notes.append("at a bound, not identified: " + ", ".join(
            lab for lab in labels if lab in hits) + "; the intervals of the other constants "
            "hold them there")
    used, factor, q, note = interval_scale(scaling, dof, s2, confidence,
                                           f"{n_rows} data rows for {p_in} constants")
    notes += [note] if note else []
    if dof > 0 and chi2 > chi2_limit:
        notes.append(f"the fit misses the data by more than the stated frequency noise explains "
                     f"(chi2 {chi2:.3g} for {dof} degrees of freedom, 99 % limit "
                     f"{chi2_limit:.3g}): model error, differences between plates "
                     "(joint) or sigma too small"
                     + ("; intervals widened by s = sqrt(s2)" if used == "residuals" else ""))
    cov = cov_stated * factor
    with np.errstate(invalid="ignore"):
        std_stated = np.sqrt(np.clip(np.diag(cov_stated), 0, None))
        std = np.sqrt(np.clip(np.diag(cov), 0, None))
    std_stated[in_null] = np.inf
    std[in_null] = np.inf
    half = q * std
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rel = np.where(value != 0, half / np.abs(value), np.inf)
        corr = cov / np.outer(std, std)
        # moduli on ln P (asymmetric, > 0); nu12 linear within [-nu_max, nu_max]
        s_ln = np.where(is_nu, np.nan, std / np.abs(value))
        lower = np.where(is_nu, np.clip(value - half, -nu_max, nu_max),
                         value * np.exp(-q * s_ln))
        upper = np.where(is_nu, np.clip(value + half, -nu_max, nu_max),
                         value * np.exp(q * s_ln))
    rel[at_bound] = np.inf
    lower[at_bound] = np.nan
    upper[at_bound] = np.nan
    corr[~np.isfinite(corr)] = np.nan
    np.fill_diagonal(corr, 1.0)
    # identifiability: condition of the noise-whitened data Jacobian (relative constants)
    Gw = G_data[:, idx] / tau_data[:, None]
    Sw = np.linalg.svd(Gw, compute_uv=False) if Gw.size else np.zeros(0)
    condition = float(Sw[0] / Sw[-1]) if Sw.size and Sw[-1] > 0 else float("inf")
    weakest: tuple = ()
    if Gw.size:
        v = np.linalg.svd(Gw, full_matrices=False)[2][-1]
        v = v * np.sign(v[np.argmax(np.abs(v))])
        order = np.argsort(-np.abs(v))
        weakest = tuple((labels[idx[k]], float(v[k])) for k in order if abs(v[k]) >= 0.1)
    info_data = np.sum((G_data / tau_data[:, None]) ** 2, axis=0)
    info_prior = np.zeros(p)
    for row, tp in zip(prior_rows, prior_tau):
        info_prior += (row / tp) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        prior_share = np.where(info_data + info_prior > 0,
                               info_prior / (info_data + info_prior), 0.0)
    verdict, flagged = [], []
    for k, lab in enumerate(labels):
        v_ = verdict_of(rel[k], at_bound[k])
        if prior_share[k] > 0.5 and not at_bound[k]:
            v_ += " (held by the prior)"
        verdict.append(v_)
        if not rel[k] <= max_rel_interval:
            flagged.append(lab)
    return Uncertainty(
        labels=labels, value=value, std=std, std_stated=std_stated, half_width=half,
        lower=lower, upper=upper, rel_half_width=rel, covariance=cov,
        correlation=corr, verdict=tuple(verdict), flagged=tuple(flagged), fixed=fixed,
        confidence=confidence, quantile=q, scaling=scaling, scale_used=used,
        variance_factor=float(factor), s2=float(s2), chi2=chi2, dof=dof, n_rows=n_rows,
        condition=condition, weakest=weakest, information_from_prior=prior_share,
        sigma_source=sigma_source,
        thresholds={"well_determined": WELL_DETERMINED, "weak": WEAK,
                    "max_rel_interval": float(max_rel_interval)},
        notes=tuple(notes), scale=tuple("linear" if n else "log" for n in is_nu),
        at_bound=at_bound, bound_text=tuple(hits[lab].text if lab in hits else ""
                                            for lab in labels),
        chi2_limit=chi2_limit)


def _parts(result, fms):
    """(fm, per-plate Identification) pairs of a single or joint result."""
    fms = [fms] if not isinstance(fms, (list, tuple)) else list(fms)
    plates = list(getattr(result, "specimens", ())) or [result]
    if len(plates) != len(fms):
        raise ValueError(f"{len(fms)} forward models for {len(plates)} plates")
    return list(zip(fms, plates))


def uncertainty_of(result, fms, sigmas, **kwargs) -> Uncertainty:
    """:func:`linearized_uncertainty` of an Identification (``fms`` one ForwardModel, ``sigmas``
    one FrequencySigma) or a JointIdentification (sequences, one per plate)."""
    sigmas = [sigmas] if isinstance(sigmas, FrequencySigma) else list(sigmas)
    materials = material_states(result)
    labels = free_labels(materials)
    parts = _parts(result, fms)
    obs = [observations(fm, plate, s, labels) for (fm, plate), s in zip(parts, sigmas)]
    notes = list(kwargs.pop("notes", ()))
    if not result.converged:
        notes.append("the identification did not converge: the intervals describe the last "
                     "point, not an optimum")
    for plate in (getattr(result, "specimens", ()) or [result]):
        if plate.bounds_hit:
            notes.append("the optimum is on a bound (" + "; ".join(plate.bounds_hit) + "): the "
                         "linearised intervals assume an interior optimum")
            break
    source = "; ".join(dict.fromkeys(s.summary for s in sigmas))
    opts = result.options
    return linearized_uncertainty(obs, materials, sigma_source=source, notes=notes,
                                  nu_max=opts.nu_max, bound_factor=opts.bound_factor, **kwargs)


def sensitivity_table(result) -> dict:
    """Which mode determines which constant: d ln f_i / d ln P_j per plate (all constants).

    Returns {plate name: {"labels": [...], "dlnf_dlnP": (n_modes, n_constants),
    "dominant_mode": {label: 1-based mode with the largest |sensitivity| among weighted modes}}}.
    """
    out = {}
    plates = list(getattr(result, "specimens", ())) or [result]
    from laminid_cli.joint import unique_names

    for name, plate in zip(unique_names([p.specimen.name for p in plates]), plates):
        S = np.asarray(plate.sensitivity)
        ok = np.asarray(plate.weight) > 0
        masked = np.where(ok[:, None], np.abs(S), -1.0)
        dom = {lab: int(np.argmax(masked[:, j])) + 1
               for j, lab in enumerate(plate.sensitivity_labels)}
        out[name] = {"labels": list(plate.sensitivity_labels), "dlnf_dlnP": S,
                     "weight": np.asarray(plate.weight), "dominant_mode": dom}
    return out


# ----------------------------------------------------------------------------------------------
# Monte Carlo


@dataclass(frozen=True)
class MonteCarlo:
    """Empirical spread of re-identifications from perturbed frequencies.

    samples : (n_converged, p) identified free constants (SI) over ``labels``
    std, mean, lower, upper : (p,) empirical; lower/upper the (1-confidence)/2 quantiles
    linearized_std : (p,) the linearised standard errors they are compared with
    ratio : std / linearized_std
    sigma_factor : the frequencies were perturbed by sigma_f * sigma_factor (sqrt of the
        variance factor used for the linearised intervals, so both describe the same noise)
    """

    labels: tuple[str, ...]
    n_trials: int
    n_converged: int
    samples: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    linearized_std: np.ndarray
    ratio: np.ndarray
    sigma_factor: float
    seed: int
    jobs: int
    time_s: float
    failures: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        per = {}
        for k, lab in enumerate(self.labels):
            mat, const = lab.rsplit(".", 1)
            per.setdefault(mat, {})[const] = {
                "mean": float(self.mean[k]), "std": float(self.std[k]),
                "lower": float(self.lower[k]), "upper": float(self.upper[k]),
                "linearized_std": float(self.linearized_std[k]), "ratio": float(self.ratio[k])}
        return {"trials": self.n_trials, "converged": self.n_converged, "constants": per,
                "sigma_factor": self.sigma_factor, "seed": self.seed, "jobs": self.jobs,
                "time_s": self.time_s, "failures": list(self.failures)}


_WORKER: dict = {}


def _init_worker(specimens, mesh, boundaries, options, start, start_pairing, joint,
                 basis_vectors=None):
    from laminid_cli.forward import build_forward_model
    from laminid_cli.reduced import ReducedBasis

    _WORKER.clear()
    fms = [build_forward_model(s, mesh, boundary=b) for s, b in zip(specimens, boundaries)]
    # the optimum's reduced basis, rebuilt once per process: each trial starts from a copy
    bases = (None if basis_vectors is None else
             [ReducedBasis.from_vectors(fm, V) for fm, V in zip(fms, basis_vectors)])
    _WORKER.update(fms=fms, options=options, start=start, start_pairing=start_pairing,
                   joint=joint, bases=bases)


def _run_trial(args):
    """One re-identification from perturbed frequencies; (index, values or None, message)."""
    from laminid_cli.errors import LaminidError
    from laminid_cli.identify import identify
    from laminid_cli.joint import identify_joint

    index, freqs, labels = args
    fms = []
    for fm, f in zip(_WORKER["fms"], freqs):
        meas = dataclasses.replace(fm.specimen.measured, freq=f)
        fms.append(dataclasses.replace(fm, specimen=dataclasses.replace(fm.specimen,
                                                                        measured=meas)))
    bases = _WORKER["bases"]
    if bases is not None:                  # the bases hold the plate, not its frequencies
        bases = [b.copy() for b in bases]
    try:
        if _WORKER["joint"]:
            r = identify_joint(fms, _WORKER["options"], start=_WORKER["start"],
                               start_pairing=_WORKER["start_pairing"], basis=bases)
        else:
            r = identify(fms[0], _WORKER["options"], start=_WORKER["start"],
                         start_pairing=_WORKER["start_pairing"][0],
                         basis=None if bases is None else bases[0])
    except LaminidError as exc:
        return index, None, str(exc)
    if not r.converged:
        return index, None, r.status
    consts = {n: c for n, c in zip(r.material_names, r.constants)}
    vals = [getattr(consts[lab.rsplit(".", 1)[0]], lab.rsplit(".", 1)[1]) for lab in labels]
    return index, np.array(vals), ""


def _basis_vectors(result):
    """The reduced basis vectors of each plate of ``result`` (None with the full solver)."""
    basis = getattr(result, "basis", None)
    if basis is None:
        return None
    bases = basis if isinstance(basis, list) else [basis]
    if any(b is None for b in bases):
        return None
    plates = result.specimens if hasattr(result, "specimens") else [result]
    out = []
    for b, plate in zip(bases, plates):
        # with the first-order mode changes at the optimum, the trials (which move the poorly
        # determined constants far) need few enrichments: one factorisation here for all
        b = b.copy()
        b.add_sensitivities(b.fm.plate.coefficients(plate.constants), plate.modes.phi)
        out.append(b.V)
    return out


def monte_carlo(result, fms, sigmas, uncertainty: Uncertainty, n_trials: int, *,
                jobs: int | None = None, seed: int = 0, progress=None) -> MonteCarlo:
    """Re-identify ``n_trials`` times from frequencies perturbed by their uncertainties.

    Each trial draws f_i + sigma_f,i * sigma_factor * N(0, 1) for every measured mode of every
    plate (sigma_factor = sqrt(uncertainty.variance_factor)), starts at the optimum of
    ``result`` with its mode pairing, and keeps the free constants of converged runs. Trials run
    in ``jobs`` processes (default: the number of cores); ``progress(done, total)`` after each.
    The perturbations come from ``numpy.random.default_rng(seed)`` in the calling process, so a
    result does not depend on ``jobs``.
    """
    from concurrent.futures import ProcessPoolExecutor, as_completed

    if n_trials < 2:
        raise FitInputError(f"Monte Carlo needs at least 2 trials, got {n_trials}")
    t0 = time.perf_counter()
    joint = hasattr(result, "specimens")
    parts = _parts(result, fms)
    sigmas = [sigmas] if isinstance(sigmas, FrequencySigma) else list(sigmas)
    factor = float(np.sqrt(uncertainty.variance_factor))
    rng = np.random.default_rng(seed)
    base = [np.asarray(plate.measured_hz, float) for _, plate in parts]
    trials = []
    for i in range(n_trials):
        freqs = []
        for f, s in zip(base, sigmas):
            noise = rng.standard_normal(f.size) * np.nan_to_num(s.sigma_hz) * factor
            freqs.append(np.where(np.isfinite(f), f + noise, np.nan))
        trials.append((i, freqs, uncertainty.labels))
    init = ([plate.specimen for _, plate in parts], parts[0][0].mesh_size,
            [fm.plate.boundary for fm, _ in parts], result.options, tuple(result.constants),
            [np.asarray(plate.pairing) for _, plate in parts], joint, _basis_vectors(result))
    jobs = max(1, min(int(jobs or os.cpu_count() or 1), n_trials))
    out: list = [None] * n_trials
    failures = []
    done = 0

    def collect(res):
        nonlocal done
        i, vals, msg = res
        out[i] = vals
        if vals is None:
            failures.append(f"trial {i + 1}: {msg}")
        done += 1
        if progress is not None:
            progress(done, n_trials)

    if jobs == 1:
        saved = dict(_WORKER)
        try:
            _init_worker(*init)
            for t in trials:
                collect(_run_trial(t))
        finally:
            _WORKER.clear()
            _WORKER.update(saved)
    else:
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker,
                                 initargs=init) as pool:
            futures = [pool.submit(_run_trial, t) for t in trials]
            try:
                for fut in as_completed(futures):
                    collect(fut.result())
            except BaseException:
                for fut in futures:
                    fut.cancel()
                raise
    ok = [v for v in out if v is not None]
    p = len(uncertainty.labels)
    samples = np.array(ok) if ok else np.zeros((0, p))
    conf = uncertainty.confidence
    if samples.shape[0] >= 2:
        mean, std = samples.mean(axis=0), samples.std(axis=0, ddof=1)
        lower, upper = np.quantile(samples, [(1 - conf) / 2, (1 + conf) / 2], axis=0)
    else:
        mean = std = lower = upper = np.full(p, np.nan)
    lin = uncertainty.std
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = std / lin
    if failures:
        log.info("Monte Carlo: %d of %d trials failed (%s)", len(failures), n_trials, failures[0])
    return MonteCarlo(labels=uncertainty.labels, n_trials=n_trials, n_converged=len(ok),
                      samples=samples, mean=mean, std=std, lower=lower, upper=upper,
                      linearized_std=lin, ratio=ratio, sigma_factor=factor, seed=seed, jobs=jobs,
                      time_s=time.perf_counter() - t0, failures=tuple(failures[:10]))


# ----------------------------------------------------------------------------------------------
# the whole assessment


@dataclass(frozen=True)
class UncertaintyOptions:
    """Settings of :func:`assess`.

    sigma_rel : relative frequency standard deviation where the file gives none
    scaling : 'stated', 'residuals' or 'larger' (module docstring)
    max_rel_interval : a constant whose 95 % half-width exceeds this fraction of its value is
        flagged; fix_undetermined : fix flagged constants at their initial values and re-run
    monte_carlo : number of Monte Carlo trials (0: none); jobs : processes (None: cores);
    seed : of the perturbations
    """

    sigma_rel: float = DEFAULT_SIGMA_REL
    scaling: str = "larger"
    max_rel_interval: float = WEAK
    confidence: float = 0.95
    fix_undetermined: bool = False
    monte_carlo: int = 0
    jobs: int | None = None
    seed: int = 0


@dataclass(frozen=True)
class Assessment:
    """An identification with its uncertainty (and what :func:`assess` did on the way).

    result : Identification or JointIdentification (the final run)
    sigmas : one FrequencySigma per plate
    fixed_undetermined : labels fixed by ``fix_undetermined`` (in the order they were fixed)
    before_fixing : the uncertainty of the first run when constants were fixed, else None
    """

    result: object
    uncertainty: Uncertainty
    sigmas: tuple[FrequencySigma, ...]
    fixed_undetermined: tuple[str, ...] = ()
    before_fixing: Uncertainty | None = None
    monte_carlo: MonteCarlo | None = None
    runs: int = 1
    earlier_results: tuple = field(default=(), repr=False)


def assess(fms, options, uopts: UncertaintyOptions = UncertaintyOptions(), *,
           joint: bool = False, progress=None, mc_progress=None) -> Assessment:
    """Identify (one plate, or several jointly), then compute the uncertainty; optionally fix
    the flagged constants and identify again (until nothing new is flagged), and run the
    Monte Carlo check on the final result.

    ``fms``: a ForwardModel, or a sequence of them with ``joint=True``. ``progress`` is passed to
    the identification, ``mc_progress(done, total)`` to :func:`monte_carlo`.
    """
    from laminid_cli.identify import identify
    from laminid_cli.joint import identify_joint

    check_sigma_rel(uopts.sigma_rel)
    if uopts.monte_carlo < 0:
        raise FitInputError(f"the number of Monte Carlo trials must be >= 0, got {uopts.monte_carlo}")
    fm_list = list(fms) if isinstance(fms, (list, tuple)) else [fms]
    sigmas = tuple(frequency_sigma(fm.specimen.measured, uopts.sigma_rel,
                                   where=str(fm.specimen.path)) for fm in fm_list)
    kw = dict(scaling=uopts.scaling, max_rel_interval=uopts.max_rel_interval,
              confidence=uopts.confidence)

    def run(opts, basis=None):
        if joint:
            return identify_joint(fm_list, opts, progress,
                                  basis=None if basis is None else [b.copy() for b in basis])
        return identify(fm_list[0], opts, progress,
                        basis=None if basis is None else basis.copy())

    result = run(options)
    unc = uncertainty_of(result, fm_list if joint else fm_list[0], sigmas if joint else sigmas[0],
                         **kw)
    first = unc
    fixed: list[str] = []
    earlier = []
    runs = 1
    while uopts.fix_undetermined and unc.flagged:
        new = [lab for lab in unc.flagged if lab not in fixed]
        if not new:
            break
        if len(new) == len(unc.labels):
            raise FitInputError(
                "every free constant is undetermined by these modes ("
                + ", ".join(new) + "); nothing left to identify: measure more modes or a "
                "thicker plate, or raise --max-rel-interval")
        fixed += new
        log.info("fixing undetermined constants at their initial values: %s", ", ".join(new))
        options = dataclasses.replace(options, fix=tuple(options.fix) + tuple(new))
        earlier.append(result)
        result = run(options, result.basis)          # the basis spans the path already walked
        runs += 1
        unc = uncertainty_of(result, fm_list if joint else fm_list[0],
                             sigmas if joint else sigmas[0], **kw)
    mc = None
    if uopts.monte_carlo:
        mc = monte_carlo(result, fm_list if joint else fm_list[0], sigmas if joint else sigmas[0],
                         unc, uopts.monte_carlo, jobs=uopts.jobs, seed=uopts.seed,
                         progress=mc_progress)
    return Assessment(result=result, uncertainty=unc, sigmas=sigmas,
                      fixed_undetermined=tuple(fixed), before_fixing=first if fixed else None,
                      monte_carlo=mc, runs=runs, earlier_results=tuple(earlier))
