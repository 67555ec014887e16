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

    A prior (Eq. 15) adds a row ``sqrt(wp) (P_j - P_j0) / P_j0`` per constant. Its weight says
    how well P_j0 is known against the measured modes (the specimen file's "relative
    confidence"): the row's noise is ``sigma_unit``, the RMS relative eigenvalue standard
    deviation 2 sigma_f / f of the measured modes, i.e. that of a measured mode of weight 1,
    so that the prior value's own relative standard deviation is ``sigma_unit / sqrt(wp)``
    (wp = 1: as well as one mode's eigenvalue; 0.01: ten times worse). With unit weights on
    the modes this is the minimum of Eq. 15 read as a Gaussian posterior, and the prior's
    term of chi^2 is its term of Eq. 15 over sigma_unit^2. (Before stop 43 the noise was
    ``sqrt(wp) sigma_unit``: the weight cancelled, and every prior counted as known to
    sigma_unit whatever its weight; a prior of 0.001 held its constant as firmly as one of 1.)
    A constant whose information comes mostly from its prior is marked "(held by the prior)".

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
    :data:`VERDICT_AT_BOUND` and a statement in ``bound_text`` ("at its bound — not
    identified: stopped on the search's lower limit, G13 = 0.0001 E1 (0.0154 GPa at the
    optimum)"; files before stop 29 wrote "G13 <= 0.0001 E1 (...)", which read like a
    confidence bound: it is not one), with its side and limit as data in
    ``bound_side`` ("lower": the data push it below ``bound_limit``) and ``bound_limit`` (SI).
    The covariance of the other constants is computed with the constants at a bound held
    there (an active constraint), so one constant on its limit does not blow up every
    interval.

Constants fixed because undetermined
    ``--fix-undetermined`` (:func:`assess`) fixes a flagged constant at its initial value: an
    assumption, known no better than the modes left it. The final intervals count that
    (:func:`counting_fixed_spread`): to first order ``C + S C_f S^T`` with
    ``S = -G_P^+ G_f`` the free constants' change per change of the fixed ones and C_f their
    covariance before fixing; as identify counts it, by secants: the others identified again
    with the fixed values one standard deviation along each principal axis of C_f either way
    (:func:`fixed_spread_moves`; a step kept within the search's factor range), since an
    undetermined constant's spread is wide enough for the constants' response to bend.
    ``rel_half_width_given_fixed`` keeps the widths given the fixed values alone. The
    flags that decide what to fix are judged given the fixed values (counting their spread
    would otherwise fix more and more). The Monte Carlo shown counts the spread as well: its
    trials draw the fixed values from it (:class:`FixedDraw`, :func:`fixed_draw_of`), after
    a Monte Carlo holding them, whose flags the fixing judges
    (``Assessment.monte_carlo_given_fixed``).

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
    empirical spread beside the linearised one. A single-plate result of the reduced solver
    runs its trials on a :class:`TrialModel` built once at the optimum and enriched where the
    first trials need it (no full solve; at most one factorisation per trial, none where a kept
    factorisation is near enough); each trial's
    paired eigenvalues are checked against the full FE model by a residual bound, accepted
    where it is at most :data:`TRIAL_SHARE` (1 %) of the smallest relative eigenvalue
    standard deviation 2 sigma_f / f (4e-5 at the default 0.2 %; at most
    :data:`TRIAL_BOUND`), or where the bounds of all the paired modes together move no
    constant by more than TRIAL_SHARE sqrt(m) of its standard error to first order (m
    weighted modes; 3.5 % for 12; :meth:`TrialModel.accepts`; the first rule's own
    guarantee), far below the sampling error of the quantiles (about 20 % of a standard
    error for the 2.5 % quantile of 200 trials). The largest bound and shift are reported
    (``trial_eigenvalue_bound``, ``trial_shift_bound``).
    Joint results and the full solver's go through identify() for every trial. With values
    fixed because undetermined, each trial also draws them (``fixed_draw``): the trial model
    moves them per trial (:meth:`TrialModel.hold`), identify() holds them in the trial's
    specimen (:func:`_holding`).

No click, no h5py here: pure library code (README, "Development": only commands/ prints
or exits).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import os
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla

from laminid_cli.errors import FitError, FitInputError, ModelError, SolverError
# thresholds, scalings and verdicts shared with the damping fit (re-exported here)
from laminid_cli.intervals import (HELD_BY_PRIOR, PROFILE_FLAT, PROFILE_NONE,  # noqa: F401
                                   SCALINGS, VERDICT_AT_BOUND, VERDICT_FIXED, VERDICT_NOT,
                                   VERDICT_WEAK, VERDICT_WELL, WEAK, WELL_DETERMINED,
                                   interval_scale, t_std, variance_dof, verdict as verdict_of)
from laminid_cli.material import CONSTANT_NAMES
from laminid_cli.objective import VariableSet, max_assignment, residual_rows
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
    source : per mode, "file" (the specimen's ``measured.sigma``, or the fit of its
        ``measured.frf_file``), "relative" (sigma_rel * f) or ""
    sigma_rel : the relative default used where the file gives none
    note : how the file's sigmas were made (``measured.sigma_source``, e.g. by fit-frf)
    origin : where the "file" sigmas come from: "specimen" (``measured.sigma`` written in the
        specimen file), "frf_file" (an RFP fit of ``measured.frf_file`` when the specimen is
        read) or "given" (``sigma_hz`` of :func:`frequency_sigma`)
    frf_file : the FRF file of origin "frf_file", as the specimen names it
    """

    sigma_hz: np.ndarray
    source: tuple[str, ...]
    sigma_rel: float
    note: str = ""
    origin: str = "specimen"
    frf_file: str = ""

    @property
    def summary(self) -> str:
        """One line, read after "σ from": where the sigmas come from (the report's page 1, the
        identify output, ``uncertainty.sigma_source``)."""
        n_file = self.source.count("file")
        n_rel = self.source.count("relative")
        rel = f"{self.sigma_rel * 100:.3g} % of each frequency (--sigma-rel)"
        if self.origin == "frf_file":
            file = (f"the RFP fit of the specimen's measured.frf_file {self.frf_file}"
                    + (f" ({self.note})" if self.note else ""))
        elif self.origin == "given":
            file = "the standard deviations given (sigma_hz)"
        else:
            file = "the specimen file's measured.sigma" + (
                f" (made by: {self.note})" if self.note else " (how they were made: not stated)")
        if n_file and not n_rel:
            return file
        if n_rel and not n_file:
            return rel
        return f"{file} for {n_file} modes, {rel} for {n_rel}"


#: the smallest relative standard deviation of a frequency taken (--sigma-rel, a specimen's
#: sigma over its frequency): the model's own frequencies are exact to about this (the
#: solvers' eigenvalues to ~1e-9 relative), so a smaller one would weigh round-off; no impact
#: test comes near it (an analyser's line spacing is ~1e-4 of a mode's frequency). 1e-200
#: made chi2 overflow to inf, with numpy's RuntimeWarnings on the terminal
SIGMA_REL_MIN = 1e-9


def check_sigma_rel(sigma_rel: float) -> float:
    """A relative standard deviation must be a finite number in [SIGMA_REL_MIN, 0.5)
    (FitInputError otherwise)."""
    try:
        value = float(sigma_rel)
    except (TypeError, ValueError):
        raise FitInputError(f"relative frequency uncertainty {sigma_rel!r} is not a number") from None
    if not np.isfinite(value) or value <= 0:
        raise FitInputError(f"relative frequency uncertainty must be positive (e.g. 0.002 for "
                            f"0.2 %), got {sigma_rel:g}")
    if value < SIGMA_REL_MIN:
        raise FitInputError(f"relative frequency uncertainty {value:g} is below {SIGMA_REL_MIN:g} "
                            "of each frequency, finer than the model's own frequencies are exact "
                            "(and than any impact test resolves); give a fraction (0.002 = 0.2 %)")
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
        with np.errstate(divide="ignore", invalid="ignore"):
            tiny = np.flatnonzero(np.isfinite(given) & np.isfinite(freq)
                                  & (given < SIGMA_REL_MIN * np.abs(freq)))
        if tiny.size:
            i = int(tiny[0])
            raise FitInputError(f"{where}: standard deviation of mode {i + 1} is {given[i]:g} Hz, "
                                f"below {SIGMA_REL_MIN:g} of its {freq[i]:g} Hz, finer than the "
                                "model's own frequencies are exact: give it in Hz (0.2 for "
                                "0.2 Hz; null where unknown)")
    for i in range(n):
        if not np.isfinite(freq[i]):
            continue
        if given is not None and np.isfinite(given[i]):
            out[i], source[i] = given[i], "file"
        else:
            out[i], source[i] = sigma_rel * freq[i], "relative"
    note = getattr(measured, "sigma_source", "") if sigma_hz is None else ""
    frf_file = getattr(measured, "frf_file", "") if sigma_hz is None else ""
    origin = "given" if sigma_hz is not None else ("frf_file" if frf_file else "specimen")
    return FrequencySigma(sigma_hz=out, source=tuple(source), sigma_rel=sigma_rel, note=note,
                          origin=origin, frf_file=frf_file)


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


# HELD_BY_PRIOR, the note on a verdict whose constant gets most of its information from the
# prior: laminid_cli.intervals (the report and the batch summaries read it too)


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
    bound_text: tuple[str, ...] = ()        # per label: "" or the statement at the limit
    #: per label, of a constant at its bound: the side the data push it to ("lower" | "upper";
    #: "" when not at a bound) and the limit of the search there (SI; NaN when not at a bound)
    bound_side: tuple[str, ...] = ()
    bound_limit: np.ndarray | None = None
    chi2_limit: float = float("nan")        # 99 % quantile of chi2 with dof degrees of freedom
    #: RMS relative eigenvalue standard deviation 2 sigma_f / f of the weighted modes: the
    #: noise of a prior row (module docstring)
    sigma_unit: float = float("nan")
    #: (p,) the Monte Carlo range's half-width / |value| (:func:`with_monte_carlo`; None
    #: without a Monte Carlo), and the labels whose verdict it set
    mc_rel_half_width: np.ndarray | None = None
    verdict_from_monte_carlo: tuple[str, ...] = ()
    #: (p,) the width the Monte Carlo verdicts use: that of MonteCarlo.inner_range, the range's
    #: half-width / |value| that the trials show with probability >= 90 % (NaN: too few)
    mc_rel_half_width_lower: np.ndarray | None = None
    #: with constants fixed because undetermined (:func:`counting_fixed_spread`): the labels
    #: whose spread before fixing the intervals count, (p,) the relative half-widths given
    #: the fixed values alone, the covariance of the free constants with the counted ones
    #: (p, k) and among those (k, k) (SI), and the fixed labels not counted (no finite spread)
    spread_counted: tuple[str, ...] = ()
    rel_half_width_given_fixed: np.ndarray | None = None
    spread_cross: np.ndarray | None = None
    spread_covariance: np.ndarray | None = None
    spread_not_counted: tuple[str, ...] = ()
    #: with the spread counted: what it added to the free constants' covariance (p, p; SI),
    #: the degrees of freedom it is known with (the run before fixing's variance factor:
    #: infinite on the stated sigma), and per label the effective degrees of freedom of the
    #: total variance and the quantile its interval uses (Welch-Satterthwaite:
    #: :func:`laminid_cli.intervals.effective_dof`); None without a spread counted
    spread_free: np.ndarray | None = None
    spread_dof: float = float("inf")
    effective_dof: np.ndarray | None = None
    quantile_per_label: np.ndarray | None = None
    #: {label: Profile} of the constants at a limit of the search (:func:`with_profiles`)
    profiles: dict = field(default_factory=dict)
    #: {label: FixedRange} of the constants fixed on a limit of the search
    #: (:func:`with_fixed_ranges`)
    fixed_ranges: dict = field(default_factory=dict)
    #: with constants fixed by --fix-undetermined: do the modes reject those values together?
    #: (:func:`with_fixed_check`)
    fixed_check: "FixedCheck | None" = None

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
                "bound_text": self.bound_text[k] if self.bound_text else "",
                "bound_side": self.bound_side[k] if self.bound_side else "",
                "bound_limit": (float(self.bound_limit[k]) if self.bound_limit is not None
                                else float("nan")),
                "verdict_from": ("monte_carlo" if lab in self.verdict_from_monte_carlo
                                 else "linearised")}
            if self.mc_rel_half_width is not None:
                per[mat][const]["monte_carlo_rel_half_width"] = float(self.mc_rel_half_width[k])
            if self.mc_rel_half_width_lower is not None:
                per[mat][const]["monte_carlo_rel_half_width_lower"] = float(
                    self.mc_rel_half_width_lower[k])
            if lab in self.profiles:
                per[mat][const]["profile"] = self.profiles[lab].as_dict()
            if self.rel_half_width_given_fixed is not None:
                per[mat][const]["rel_half_width_given_fixed"] = float(
                    self.rel_half_width_given_fixed[k])
            if self.quantile_per_label is not None:
                per[mat][const]["quantile"] = float(self.quantile_per_label[k])
                per[mat][const]["effective_dof"] = float(self.effective_dof[k])
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
            "verdict_from_monte_carlo": list(self.verdict_from_monte_carlo),
            "fixed": list(self.fixed),
            "spread_counted": list(self.spread_counted),
            "spread_covariance": self.spread_covariance,
            "spread_cross_covariance": self.spread_cross,
            "spread_not_counted": list(self.spread_not_counted),
            "spread_dof": self.spread_dof,
            "fixed_ranges": {lab: r.as_dict() for lab, r in self.fixed_ranges.items()},
            "fixed_check": None if self.fixed_check is None else self.fixed_check.as_dict(),
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
#: how a constant's statement at a limit of the search begins (BoundHit.text)
BOUND_PREFIX = "at its bound — not identified: "


@dataclass(frozen=True)
class BoundHit:
    """A free constant on a limit of the search: side "lower" | "upper", the limit (SI) and the
    statement (:data:`BOUND_PREFIX` ...)."""

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

    Returns {label: BoundHit}. At a lower limit the fit would take the constant lower, but
    that is no confidence bound (a Monte Carlo of such a result has trials far above the
    limit): the statement names the limit, "stopped on the search's lower limit, G13 = 0.0001
    E1 (0.0154 GPa at the optimum)", and gives no interval.
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
                    hit = ("upper", nu_max, f"nu12 = {nu_max:g}")
                elif v <= -nu_max * (1 - tol):
                    hit = ("lower", -nu_max, f"nu12 = {-nu_max:g}")
            else:
                v0 = float(getattr(c0, k))
                lo, hi = v0 / bound_factor, v0 * bound_factor
                if k in ("E2", "G12", "G13", "G23") and v <= 2 * r * c.E1:
                    # the limit on the alphas lies slightly above r * E1 in the constants: the
                    # one-sided statement is the value where the search stopped, never below it
                    lim = max(v, r * c.E1)
                    hit = ("lower", lim, f"{k} = {r:g} E1 ({_gpa(lim)} at the optimum)")
                elif k == "E2" and v >= c.E1 * (1 - tol):
                    hit = ("upper", c.E1, f"E2 = E1 ({_gpa(c.E1)})")
                # the factor limits bind every modulus of the 'constants' parametrisation but
                # only E1 of the alphas (the others can pass them): at the limit, not beyond
                elif abs(v - lo) <= tol * lo:
                    hit = ("lower", lo, f"{k} = initial / {bound_factor:g} ({_gpa(lo)})")
                elif abs(v - hi) <= tol * hi:
                    hit = ("upper", hi, f"{k} = {bound_factor:g} x initial ({_gpa(hi)})")
            if hit is not None:
                side, limit, stmt = hit
                out[lab] = BoundHit(lab, side, float(limit), f"{BOUND_PREFIX}stopped on the "
                                    f"search's {side} limit, {stmt}")
    return out


def free_labels(materials) -> tuple[str, ...]:
    return tuple(f"{m.name}.{k}" for m in materials for k in CONSTANT_NAMES if k in m.free)


def _label_values(materials, labels, which: str = "constants") -> np.ndarray:
    """(len(labels),) the ``which`` ("constants" or "initial") value of each label
    "material.constant" of the :class:`MaterialState` s ``materials`` (SI)."""
    mat_of = {m.name: m for m in materials}
    return np.array([float(getattr(getattr(mat_of[lab.rsplit(".", 1)[0]], which),
                                   lab.rsplit(".", 1)[1])) for lab in labels])


@dataclass(frozen=True)
class DesignRows:
    """The rows of the linearised estimate (module docstring), over the free constants scaled
    to relative ones (moduli per ln P, nu12 per max(|nu12|, NU_SCALE)): data rows of every
    plate's weighted measured modes, then one row per prior.

    G : (n_rows, p) d r / d scaled constant; tau : (n_rows,) each row's noise standard
    deviation; resid : (n_rows,) the rows r at the optimum; scale : (p,) the column scale
    (SI: a constant's change is ``scale`` times its scaled one); G_data, tau_data : the data
    rows alone; used : per plate, (n,) bool, the measured modes that make its data rows (in
    order); sigma_unit : RMS relative eigenvalue standard deviation; prior_rows, prior_tau :
    the prior rows and their noise.
    """

    G: np.ndarray
    tau: np.ndarray
    resid: np.ndarray
    scale: np.ndarray
    G_data: np.ndarray
    tau_data: np.ndarray
    used: tuple
    sigma_unit: float
    prior_rows: list
    prior_tau: list


def design_rows(obs, materials, labels) -> DesignRows:
    """The rows of :func:`linearized_uncertainty` (paper Eq. 17 + Eq. 15 linearised at the
    optimum): ``obs`` sequence of :class:`Observations`, ``materials`` of
    :class:`MaterialState`, ``labels`` the free constants (:func:`free_labels`)."""
    p = len(labels)
    mat_of = {m.name: m for m in materials}
    value = _label_values(materials, labels)
    is_nu = np.array([lab.endswith(".nu12") for lab in labels], bool)
    # column scale: relative constants (moduli per ln P, nu12 per max(|nu12|, NU_SCALE))
    D = np.where(is_nu, np.maximum(np.abs(value), NU_SCALE), np.abs(value))
    rows, tau, resid, used = [], [], [], []
    rel_sd = []
    for o in obs:
        ok = (np.asarray(o.weight) > 0) & np.isfinite(o.freq_hz)
        used.append(ok)
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
        prior_tau.append(sigma_unit)                  # (module docstring: sigma_unit / sqrt(wp)
        #                                               on P0 / P0, times sqrt(wp) on the row)
        prior_res.append(np.sqrt(wp) * (value[j] - P0) / ref)
    G = np.vstack([G_data] + ([np.array(prior_rows)] if prior_rows else []))
    t = np.concatenate([tau_data, np.array(prior_tau)])
    r = np.concatenate(resid + [np.array(prior_res)])
    return DesignRows(G=G, tau=t, resid=r, scale=D, G_data=G_data, tau_data=tau_data,
                      used=tuple(used), sigma_unit=sigma_unit, prior_rows=prior_rows,
                      prior_tau=prior_tau)


def _pseudo_inverse(Gi: np.ndarray):
    """Rank-safe pseudo-inverse of the rows ``Gi`` (n, p) through its SVD: (p, n), the null
    singular values (bool (k,)) and V^T (k, p)."""
    U, S, Vt = np.linalg.svd(Gi, full_matrices=False)
    null = S <= NULL_TOL * (S[0] if S.size else 1.0)
    S_inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, S))
    return (Vt.T * S_inv) @ U.T, null, Vt


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
    if not 0 < max_rel_interval <= WEAK:
        raise FitInputError(f"the interval threshold must be in (0, {WEAK:g}] (above it a "
                            f"verdict is 'not determined', always flagged), got "
                            f"{max_rel_interval:g}")
    if not 0 < confidence < 1:
        raise FitInputError(f"confidence must be in (0, 1), got {confidence:g}")
    labels = free_labels(materials)
    fixed = tuple(f"{m.name}.{k}" for m in materials for k in CONSTANT_NAMES if k not in m.free)
    p = len(labels)
    value = _label_values(materials, labels)
    is_nu = np.array([lab.endswith(".nu12") for lab in labels], bool)
    hits = bounds_reached(materials, nu_max, bound_factor)
    at_bound = np.array([lab in hits for lab in labels], bool)
    inner = ~at_bound                      # constants at a bound are held there (module doc)
    rows = design_rows(obs, materials, labels)
    D, G, G_data, tau_data = rows.scale, rows.G, rows.G_data, rows.tau_data
    t, r, sigma_unit = rows.tau, rows.resid, rows.sigma_unit
    prior_rows, prior_tau = rows.prior_rows, rows.prior_tau
    n_rows = G.shape[0]
    idx = np.flatnonzero(inner)
    p_in = idx.size
    # sandwich covariance in scaled variables, through the SVD of G (rank-safe), over the
    # constants not at a bound
    Gi = G[:, idx]
    Ginv, null, Vt = _pseudo_inverse(Gi)                              # (p_in, n)
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
            v_ += HELD_BY_PRIOR
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
        bound_side=tuple(hits[lab].side if lab in hits else "" for lab in labels),
        bound_limit=np.array([hits[lab].limit if lab in hits else np.nan for lab in labels]),
        chi2_limit=chi2_limit, sigma_unit=sigma_unit)


def model_change_shift(obs, materials, rel_change, *, nu_max: float = 0.95,
                       bound_factor: float = 5.0) -> np.ndarray:
    """First-order change of the free constants (SI, (p,) over :func:`free_labels`) when the
    model's eigenvalues change, at the same constants, by the relative amounts ``rel_change``
    (one (n,) array per plate of ``obs``, over its measured modes; e.g. a finer mesh's).

    The estimate minimises the rows r_i = sqrt(w_i) (lt_i - l_i(P)) / lt_i (module docstring);
    a model whose eigenvalues become l_i (1 + e_i) changes them by -sqrt(w_i) e_i l_i / lt_i,
    so the constants move by the least-squares step ``G^+ (sqrt(w) e l / lt)`` on the same
    rows (:func:`design_rows`, priors unchanged) and the same pseudo-inverse as the
    covariance. A model too stiff by e_i is thus read as a measured eigenvalue too low by e_i.
    Constants at a bound are held there (NaN).
    """
    labels = free_labels(materials)
    rows = design_rows(obs, materials, labels)
    hits = bounds_reached(materials, nu_max, bound_factor)
    idx = np.array([k for k, lab in enumerate(labels) if lab not in hits], int)
    dr = []
    for o, e, ok in zip(obs, rel_change, rows.used):
        e = np.asarray(e, float)[ok]
        lam_m = (2 * np.pi * o.freq_hz[ok]) ** 2
        dr.append(np.sqrt(o.weight[ok]) * e * o.lam[ok] / lam_m)
    dr = np.concatenate(dr + [np.zeros(len(rows.prior_rows))])
    shift = np.full(len(labels), np.nan)
    if idx.size:
        Ginv = _pseudo_inverse(rows.G[:, idx])[0]
        shift[idx] = rows.scale[idx] * (Ginv @ dr)
    return shift


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
# Monte Carlo trials on a reduced model of the optimum


#: a trial is accepted when the relative eigenvalue error bound (against the full FE model) of
#: its paired modes is below TRIAL_SHARE times the smallest relative eigenvalue standard
#: deviation 2 sigma_f / f of the weighted modes (to first order a constant then moves by at
#: most about TRIAL_SHARE of its standard error; module docstring), and never above TRIAL_BOUND
TRIAL_SHARE = 0.01
TRIAL_BOUND = 1e-4
#: the trial optimiser's step tolerance, in linearised standard errors of the constants at the
#: optimum (a trial's constants then move by about 1e-3 of their spread; smaller steps are at
#: the reduced objective's round-off floor)
TRIAL_XTOL = 1e-3
#: the trial basis is enriched at this many standard errors from the optimum along at most
#: CLOUD_DIRECTIONS directions whose stiffness coefficients change there by more than
#: CLOUD_CHANGE (relative), with CLOUD_ROUNDS block solves each
CLOUD_RADIUS = 2.5
CLOUD_DIRECTIONS = 1
CLOUD_CHANGE = 0.05
CLOUD_ROUNDS = 1
#: Levenberg-Marquardt iterations of a trial before SLSQP takes over
TRIAL_GN_ITERATIONS = 30
#: the same for a profile's fit (:func:`refit_reduced`), whose held value goes far from the
#: optimum: hybrid CM (6x6) with glass E2 held at 0.9 GPa, 52 iterations, 0.32 s; with 30,
#: 30 iterations and 168 evaluations of SLSQP to the same answer, 1.2 s (at 12 GPa, SLSQP's
#: 200 evaluations ended unfinished)
PROFILE_GN_ITERATIONS = 100
#: steps over which a Levenberg-Marquardt fit's decrease is measured against its ``ftol``
#: (TrialModel)
GN_STALL = 5
#: a profile's Levenberg-Marquardt fit hands over to SLSQP (from where it is) where its last
#: GN_STALL steps lowered chi2 (scaled: about objective / tau2) by at most this share of the
#: threshold in all: a flat, curved valley, which its short steps follow slowly (hybrid CM,
#: 12x12, carbon nu12 held at 0: such steps stopped there left chi2 0.26 above the valley's
#: end, which SLSQP reached, 0.035)
PROFILE_FTOL = 1e-3
#: active-set iterations of a profile fit's constrained step (the trials' 50 did not finish
#: hybrid CM's first step with carbon nu12 held at 0 from its 0.95, five constraints active
#: at the start, which took ~100: SLSQP took over, 159 evaluations instead of ~50)
PROFILE_STEP_ITERATIONS = 200
#: SLSQP runs of a trial, each restarted from the last answer, and evaluations of each (a
#: trial that reaches them fails; a profile's fit goes on from its best point)
TRIAL_RESTARTS = 4
TRIAL_MAXEVAL = 200
#: a trial's first answer is checked with a kept factorisation (the optimum's or the cloud's)
#: only when its constitutive matrices are at least this fraction of that point's (the bound
#: grows as 1 / mu)
TRIAL_MU = 0.5
#: a trial whose first bound (with a kept factorisation) is above TRIAL_FAR times the accepted
#: one is factorised at its answer at once, instead of first enriched with the kept
#: factorisation: in 200 trials of S1.1 every trial above 6e-3 (150x the 4e-5 bound) needed
#: that factorisation anyway, one round later; every one below 3.1e-3 did without (11 far
#: trials 210 -> ~155 ms each, ~0.6 s of the 200 trials)
TRIAL_FAR = 100.0
#: the shared trial basis is enriched where the first TRIAL_PILOT trials need it
#: (TrialModel.prepare) before the trials run
TRIAL_PILOT = 8
#: enrich-and-optimise-again rounds of a trial before it is re-identified with identify()
TRIAL_ROUNDS = 3


#: Ritz vectors (per model mode) of the identification's basis that start the trial basis
TRIAL_RITZ = 2


class TrialModes(NamedTuple):
    """The trial model at one point: the paired Ritz values ``lam`` (rad^2/s^2), the pairing
    (model mode of each measured one), the reduced eigenvectors ``Y`` (all computed modes),
    ``dlam_dx``, d lambda / d x of the paired modes, and ``energies``, the basis strain
    energies ``phi_i^T K_basis[m, j] phi_i`` (n_materials, 6, n_measured) of the paired modes
    that ``dlam_dx`` is made of: ``y^T Kr_mj y`` with ``Kr_mj = V^T K_mj V``, the same
    quadratic form as with the full-size Ritz vector ``V y``, so no full-size product. The ply
    loss factors' Monte Carlo refits take a trial's strain-energy shares from them
    (laminid_cli.damping.shares_of_energies): kept, they cost the trial nothing."""

    lam: np.ndarray
    pairing: np.ndarray
    Y: np.ndarray
    dlam_dx: np.ndarray
    energies: np.ndarray | None = None


class TrialModel(VariableSet):
    """One plate's reduced model for the Monte Carlo trials (single plate, reduced solver).

    Basis (mass-orthonormal, built once in the calling process, inherited by forked worker
    processes): the optimum's final basis, its checked Ritz vectors ``phi_i``, their
    first-order changes with every basis stiffness ``A0^-1 K_b phi_i`` (``A0 = K(c*) - sigma0
    M``), and the preconditioned Ritz residuals at ``x* +- CLOUD_RADIUS`` standard errors
    along the directions where the trials change the stiffness most (:meth:`_enrich_cloud`),
    then, before the trials run, the preconditioned residuals where the first TRIAL_PILOT
    trials miss the accepted bound (:meth:`prepare`). The factorisations of the optimum and of
    those points are kept. The trials' eigenproblems on this shared basis are solved in
    standard form (``Mr = C C^T`` once).

    A trial minimises paper Eq. 17 (+ Eq. 15) with its perturbed frequencies on this model from
    the optimum: Levenberg-Marquardt on the residual rows of
    :func:`laminid_cli.objective.residual_rows` (the objective's own), each step restricted
    to the search's bounds and linear constraints (:func:`_constrained_step`; SLSQP only when
    that does not converge), modes paired by MAC against the optimum's. At its answer the
    paired Ritz vectors (and the next one) are checked with the full matrices: Rayleigh
    quotients and the residual bound of :func:`laminid_cli.reduced.residual_bounds` with a
    kept factorisation ``A_ref = U^T U`` in place of A (``r^T A_ref^-1 r = |U^-T r|^2``, one
    triangular solve per vector: ``energy`` of :class:`laminid_cli.modal.CholmodFactor` or
    :class:`laminid_cli.modal.BandFactor`): when the
    constitutive matrices satisfy ``Q(c) >= mu Q(c_ref)`` (mu the smallest generalised
    eigenvalue of the 5x5 pair of each material, the same for every ply angle since Q(theta) =
    T^T Q(0) T), then ``K(c) >= mu K(c_ref)`` and ``A(c) >= min(mu, 1) A_ref``, so ``r^T
    A(c)^-1 r <= r^T A_ref^-1 r / min(mu, 1)``: a valid bound with no factorisation at the
    trial point. Above the accepted bound, the preconditioned residuals (with that kept
    factorisation) are added to a copy of the basis and the trial optimised again from there;
    where no kept factorisation is near enough, or the next answer still misses the bound with
    it, ``A`` is factorised at the trial's answer (its one factorisation) for the check and the
    further enrichment.
    """

    #: ``step_progress(text)`` before each optimisation of :meth:`solve` (a profile's fit,
    #: :func:`with_profiles`: its reduced fits make up to 5 of 0.2 to 0.75 s); None: nothing
    step_progress = None

    def __init__(self, fm, result, tau2: float, bound: float = TRIAL_BOUND, moved=(),
                 rel_sd=None, profiled: str = "", iterations: int = TRIAL_GN_ITERATIONS,
                 ftol: float = 0.0, step_iterations: int = 50):
        from laminid_cli.identify import variables_of
        from laminid_cli.parametrization import alpha_floor, make_parameters
        from laminid_cli.reduced import ReducedBasis

        plate = fm.plate
        opts = result.options
        spec = fm.specimen
        self.fm = fm
        self.pilot: dict = {}                    # trials finished by prepare(), by position
        self.names = tuple(result.material_names)
        #: the free constant of the result that this model holds, a profile's (:func:`
        #: refit_reduced`): not free here, moved like :attr:`moved`, its material searched
        #: as :func:`refit_held` searches it (the constants parametrisation, in the alphas'
        #: region where the result searched it with the alphas); "" for the trials
        self.profiled = profiled
        held_name, _, held_k = profiled.rpartition(".")
        #: labels of fixed constants that the trials move (:meth:`hold`; a Monte Carlo that
        #: draws the values --fix-undetermined fixed, :class:`FixedDraw`; a profile's)
        self.moved = ((profiled,) if profiled else ()) + tuple(moved)
        self._held: dict = {}
        self.n_evaluations = 0                   # reduced eigenproblems solved (:meth:`modes`)
        #: a profile's reduced fits so far, (value held, design variables of the answer)
        #: (:func:`refit_reduced`, :func:`_nearer_answer`)
        self.answers: list = []
        #: Levenberg-Marquardt iterations of a fit before SLSQP takes over (:meth:`solve`)
        self.iterations = int(iterations)
        #: a Levenberg-Marquardt fit also ends where its last GN_STALL steps lowered the
        #: objective by at most ``ftol`` in all (0: never; :meth:`_gauss_newton`)
        self.ftol = float(ftol)
        #: active-set iterations of each constrained step (:func:`_constrained_step`)
        self.step_iterations = int(step_iterations)
        params = []
        for m, (name, c0) in enumerate(zip(self.names, fm.initial_constants)):
            free = result.free[name]
            fixed = tuple(k for k in CONSTANT_NAMES if k not in free)
            kind, region, floor = result.parametrization[name], "box", 1.0
            if name == held_name:
                fixed += (held_k,)
                if kind == "alpha":
                    region, floor = "alpha", alpha_floor(result.constants[m])
                kind = "constants"
            p = make_parameters(name, c0, fixed, kind=kind,
                                prior=bool(spec.materials[name].prior), nu_max=opts.nu_max,
                                bound_factor=opts.bound_factor, region=region, floor=floor)
            if name == held_name:
                # held at the optimum's value until :meth:`hold` says otherwise (as hold()
                # does it: glass E2 = E1 on hybrid CM's optimum is above its initial E1,
                # which make_parameters refuses of an initial E2)
                p = dataclasses.replace(p, initial=dataclasses.replace(
                    p.initial, **{held_k: getattr(result.constants[m], held_k)}))
            params.append(p)
        self._set_params(params)
        self._params0 = list(self.params)
        #: the profiled constant's value at the optimum (its limit; NaN for the trials)
        self.held_optimum = (float(getattr(result.constants[self.names.index(held_name)],
                                           held_k)) if profiled else np.nan)
        self._log_shear_variables()
        self.prior = [{k: float(w) for k, w in spec.materials[p.name].prior.items()
                       if k in p.free} for p in self.params]
        if profiled:
            self.x_opt = np.concatenate([variables_of(p, c)
                                         for p, c in zip(self.params, result.constants)])
        else:
            self.x_opt = np.asarray(result.x, float)
        self.pairing = np.asarray(result.pairing, int)
        self.n_model = int(result.modes.n_modes)
        self.n_check = int(min(self.n_model, np.max(self.pairing) + 3))
        self.coef_opt = self.coefficients(self.x_opt)[0]
        self.tau2 = float(tau2)
        self.bound = float(bound)            # accepted relative eigenvalue error bound
        # each measured mode's relative eigenvalue standard deviation (2 sigma_f / f, as the
        # intervals count it), for the first-order shift of a trial's constants that its
        # eigenvalue bounds allow (:meth:`shift_of`); None: the bound alone decides
        self.rel_sd = None
        self.shift_limit = 0.0
        if rel_sd is not None:
            rel_sd = np.asarray(rel_sd, float)
            fit = (np.asarray(result.weight, float) > 0) & (rel_sd > 0)
            self.rel_sd = np.where(fit, rel_sd, np.inf)
            self.shift_limit = TRIAL_SHARE * float(np.sqrt(np.count_nonzero(fit)))
        # the basis, with the one factorisation at the optimum
        phi = np.asarray(result.modes.phi, float)
        K0 = plate.stiffness(coef=self.coef_opt)
        lam1 = float(result.modes.eigenvalues[0])
        self.sigma = -0.5 * lam1
        self._solve = fm.factorizer.factor(K0.data - self.sigma * plate.M_on_K)
        basis = ReducedBasis(fm, split=True)
        if getattr(result, "basis", None) is not None:
            # the identification's basis holds every direction its optimiser went through
            # (~200 vectors): its lowest Ritz vectors at the optimum carry what the trials
            # near it need, at a fraction of the size of every trial's eigenproblems
            b = result.basis
            _, Y = b.eig(self.coef_opt, min(b.size, TRIAL_RITZ * self.n_model))
            basis.add(b.V @ Y)
        basis.add(phi)
        basis.add(self._solve(self._free_products(phi)))
        self.basis = basis
        # Gauss-Newton scaling at the optimum: y = L^T (x - x*) in linearised standard errors
        w = np.asarray(result.weight, float)
        lam_meas = (2 * np.pi * np.nan_to_num(np.asarray(result.measured_hz, float), nan=1.0))**2
        lam = (2 * np.pi * np.asarray(result.model_hz, float)) ** 2
        if profiled:
            # the result's d lambda / d x is over its own design variables
            dlam_dx = self.eigenvalue_jacobian(plate.basis_energies(result.phi_paired),
                                               self.coefficients(self.x_opt)[1])
        else:
            dlam_dx = np.asarray(result.dlam_dx, float)
        Jr = residual_rows(lam_meas, w, lam, dlam_dx).jacobian
        Jp = self.prior_rows(self.x_opt)[1]
        H = Jr.T @ Jr + Jp.T @ Jp
        d = np.diag(H).copy()
        H += np.diag(1e-10 * max(d.max(), 1e-300) + 1e-12 * d)
        self.L = np.linalg.cholesky(H / self.tau2)
        self.T = np.linalg.inv(self.L.T)
        self._set_limits()
        self.refs = [(self.coef_opt, self.sigma, self._solve)]     # factorisations kept
        self._enrich_cloud()
        theta, Y = self.basis.eig(self.coef_opt, self.n_model)
        self.Y_ref = Y[:, self.pairing]
        self._shared_basis_changed()

    def _set_limits(self):
        """The search's bounds and linear constraints at the current parametrisation (they
        depend on a fixed E1 or E2's value: :meth:`hold`)."""
        self.lo, self.hi = self.bounds()
        self.A, self.b = self.linear_constraints()
        self._A_all = np.vstack([self.A, np.eye(self.n_vars), -np.eye(self.n_vars)])
        self._b_all = np.concatenate([self.b, self.hi, -self.lo])
        self._exact_rows = self._exact_log_rows()

    def hold(self, values=None) -> None:
        """Hold the fixed constants of ``values`` ({label: SI}, labels of :attr:`moved`) there
        instead of at the result's values (None or {}: the result's), for the trials that
        follow (as :attr:`prior_shift`, a per-trial setting: :meth:`trial` sets both). The
        design variables stay those of the free constants (scaled by their own initial
        values), so ``x_opt`` is the optimum's free constants with the moved fixed ones."""
        values = dict(values or {})
        if values == self._held:
            return
        by = _by_material(values)
        params = [dataclasses.replace(p, initial=dataclasses.replace(p.initial, **by[p.name]))
                  if p.name in by else p for p in self._params0]
        self._set_params(params)
        self._set_limits()
        self._held = values

    def _moved_jacobian(self) -> np.ndarray:
        """d coef / d (moved fixed constant) (n_b, n_moved) at the optimum, one column per
        label of :attr:`moved` (moduli per relative change, nu12 per unit)."""
        from laminid_cli.parametrization import coefficients_and_jacobian

        n_b = 6 * len(self.params)
        out = np.zeros((n_b, len(self.moved)))
        consts = self.constants(self.x_opt)
        for j, lab in enumerate(self.moved):
            name, k = lab.rsplit(".", 1)
            m = self.names.index(name)
            _, Jc = coefficients_and_jacobian(consts[m])
            i = CONSTANT_NAMES.index(k)
            scale = 1.0 if k == "nu12" else float(getattr(consts[m], k))
            out[6 * m:6 * m + 6, j] = Jc[:, i] * scale
        return out

    def _log_shear_variables(self):
        """Where the trials' Levenberg-Marquardt steps take the transverse shear moduli in
        logarithm (:meth:`trial_variables`): paper Eq. 14's (alpha8, alpha9) pairs, whose sum
        and difference are G13 / s and G23 / s, and the free G13, G23 of the constants'
        parametrisation. Thin plates' frequencies barely see G13 and G23, so the trials range
        over decades of them (S1.1: 0.016 to 3 GPa for G23); on their logarithms the valleys
        the trials follow are straighter (S1.1, 12x12, 100 trials: 8.2 instead of 11.3 reduced
        eigenproblems per trial, every constant within 1.1e-3 standard errors of before)."""
        pairs, single = [], []
        for p, off in zip(self.params, self.offsets[:-1]):
            if p.kind == "alpha":
                pairs.append((off + 4, off + 5))
            else:
                single += [off + p.free.index(k) for k in ("G13", "G23") if k in p.free]
        self._log_pairs = np.array(pairs, int).reshape(-1, 2)
        self._log_single = np.array(single, int)

    def _exact_log_rows(self):
        """Rows of the constraints ``A_all x <= b_all`` that are linear in the trial variables
        y: ``alpha8 -+ alpha9 >= c`` (G23, G13 at their minimum) is ``log(alpha8 -+ alpha9)
        >= log c``, and a bound on a free G13 or G23 one on its logarithm. Returns (row,
        index of y, sign, log of the limit): ``sign * y[index] <= sign * limit``. A trial's
        step meets these exactly, so a trial that the data push to such a limit ends on it
        (linearised in y they would stop it short: exp is convex)."""
        A, b = self._A_all, self._b_all
        out = []
        for row, (a, lim) in enumerate(zip(A, b)):
            nz = np.flatnonzero(a)
            for i, j in self._log_pairs:
                if set(nz) == {i, j} and a[i] < 0 and lim < 0:
                    # -s (a8 -+ a9) <= lim: (a8 -+ a9) >= -lim / s
                    if a[j] == -a[i]:
                        out.append((row, j, -1.0, np.log(-lim / -a[i])))
                    elif a[j] == a[i]:
                        out.append((row, i, -1.0, np.log(-lim / -a[i])))
            for k in self._log_single:
                if list(nz) == [k] and lim / a[k] > 0:
                    sign = 1.0 if a[k] > 0 else -1.0
                    out.append((row, k, sign, np.log(lim / a[k])))
        return out

    def _step_constraints(self, x, y, D):
        """(G, s): the constraints on a trial step dy at (x, y), ``G dy <= s``: linearised in y
        (``A_all dx/dy dy <= b_all - A_all x``), except the rows linear in y
        (:meth:`_exact_log_rows`), which are exact."""
        G = self._A_all @ D
        s = self._b_all - self._A_all @ x
        for row, k, sign, lim in self._exact_rows:
            G[row] = 0.0
            G[row, k] = sign
            s[row] = sign * (lim - y[k])
        return G, s

    def trial_variables(self, x) -> np.ndarray:
        """The trials' step variables y of design variables x (:meth:`_log_shear_variables`):
        x itself except log(alpha8 + alpha9), log(alpha8 - alpha9) in the place of (alpha8,
        alpha9), and log x of a free G13 or G23 (x = G / G_0)."""
        y = np.array(x, float)
        i, j = self._log_pairs.T
        y[i], y[j] = np.log(x[i] + x[j]), np.log(x[i] - x[j])
        y[self._log_single] = np.log(x[self._log_single])
        return y

    def design_variables(self, y) -> tuple[np.ndarray, np.ndarray]:
        """(x, dx/dy) of trial variables y (the inverse of :meth:`trial_variables`)."""
        x = np.array(y, float)
        D = np.eye(x.size)
        i, j = self._log_pairs.T
        u, v = np.exp(y[i]), np.exp(y[j])
        x[i], x[j] = 0.5 * (u + v), 0.5 * (u - v)
        D[i, i], D[i, j], D[j, i], D[j, j] = 0.5 * u, 0.5 * v, 0.5 * u, -0.5 * v
        k = self._log_single
        x[k] = np.exp(y[k])
        D[k, k] = x[k]
        return x, D

    def coefficient_jacobian(self, x) -> tuple[np.ndarray, np.ndarray]:
        """The stiffness coefficients of every material at ``x``, in one vector (n_b,), and
        their derivatives with respect to all design variables (n_b, n_vars): block diagonal,
        each material's coefficients depending on its own variables only."""
        coefs, jacs = self.coefficients(x)
        J = np.zeros((coefs.size, self.n_vars))
        for m, Jm in enumerate(jacs):
            J[6 * m:6 * m + 6, self.offsets[m]:self.offsets[m + 1]] = Jm
        return coefs.reshape(-1), J

    def _free_products(self, phi):
        """``dK/dx_v phi`` for every design variable v at the optimum, side by side (n, n_vars
        * k; columns ``v * k ... (v + 1) * k - 1``): the stiffness' first-order changes that
        the trials can make. With every constant free they span what the basis matrices'
        products ``K_b phi`` span, and those are returned as they are (n_b * k columns). With
        some fixed there are fewer (n_vars < n_b). Where the coefficients stay in an affine
        set of dimension n_vars (any of G13, G23, nu12 fixed, the others free: with nu12 fixed
        the coefficients are affine in E1^2/8D, E1 E2/8D and G12), these directions span
        ``K(x) phi - K(x*) phi`` exactly at every x; otherwise to first order, and the trials'
        check adds what is missing. With G13, G23 and nu12 fixed on S1.1 (12x12) the shared
        basis has 104 instead of 137 vectors and 200 trials take 1.26 instead of 1.85 s
        (-j 1), each trial's constants the same to 3e-8 relative. Fixed constants that the
        trials move (:attr:`moved`: a Monte Carlo drawing the values --fix-undetermined fixed)
        add their own directions ``dK/df phi``: with G13, G23, nu12 moved on S1.1, all six
        basis products again."""
        plate = self.fm.plate
        P = plate.basis_products(phi)
        n_b = P.shape[1] // phi.shape[1]
        if self.n_vars + len(self.moved) >= n_b:
            return P
        Jc = self.coefficient_jacobian(self.x_opt)[1]
        if self.moved:
            # the fixed constants the trials move change the stiffness too
            Jc = np.hstack([Jc, self._moved_jacobian()])
        k = phi.shape[1]
        Jc /= np.maximum(np.abs(Jc).max(axis=0), 1e-300)
        W = np.einsum("nbk,bv->nvk", P.reshape(P.shape[0], n_b, k), Jc)
        return W.reshape(P.shape[0], Jc.shape[1] * k)

    def _shared_basis_changed(self):
        """After a change of the shared basis: the optimum's reduced vectors extended by zeros
        (columns were appended) and the model at the optimum, where every trial starts (the
        basis keeps its reduced eigenproblem in standard form itself, ReducedBasis.eig)."""
        extra = self.basis.size - self.Y_ref.shape[0]
        self.Y_ref = np.vstack([self.Y_ref, np.zeros((extra, self.Y_ref.shape[1]))])
        held = self._held
        self.hold(None)                          # the optimum's own fixed values
        self.model_opt = self.modes(self.basis, self.x_opt, self.Y_ref)
        self.hold(held)

    def _start(self):
        """(x, model) where a trial starts: the optimum, at the fixed values held now
        (:meth:`hold`; the model there computed again when they are not the result's);
        None when the optimum's free constants are outside the search's limits there (a
        fixed E2 drawn above the optimum's E1)."""
        if not self._held:
            return self.x_opt, self.model_opt
        if not self.feasible(self.x_opt):
            return None
        return self.x_opt, self.modes(self.basis, self.x_opt, self.Y_ref)

    def prepare(self, freqs, weight, prior_shifts=None, held=None) -> int:
        """Enrich the shared basis where the first trials (``freqs``: their frequencies, in
        order; ``prior_shifts``: their draws of the prior, ``held``: their fixed values,
        :meth:`trial`) need it, before the
        trials run: each is optimised on the shared basis and
        checked (:meth:`trial`'s first round); where the check misses the accepted bound, A
        is factorised at its answer (kept for the later checks) and, if still missed, the
        preconditioned residuals there are added to the shared basis. Deterministic (the
        same trials in the same order, whatever the number of processes); returns the
        directions added.

        A trial that reaches the accepted bound here is done: what :meth:`trial` would do
        with it (its first round on the shared basis as it is then, checked with the kept
        factorisation nearest to its answer or one at its answer) is already done, and its
        (constants, bound, rounds, energies) is kept in ``self.pilot`` (by position in ``freqs``)
        instead of running it again (with :attr:`TrialModes.energies` at its answer, as
        :meth:`trial` returns it)."""
        added = 0
        self.pilot = {}
        for i, f in enumerate(freqs):
            self.prior_shift = prior_shifts[i] if prior_shifts else {}
            self.hold(held[i] if held else None)
            lam_meas = (2 * np.pi * np.nan_to_num(f, nan=1.0)) ** 2
            w = np.where(np.isfinite(f), weight, 0.0)
            self.basis.reset_class_counts()  # (as trial() starts)
            start = self._start()
            gn = None if start is None else self._gauss_newton(
                self.basis, start[0], lam_meas, w, self.Y_ref, start[1])
            if gn is None:
                continue
            x, model, _ = gn
            pairing, Y = model.pairing, model.Y
            mu, near = self.nearest_ref(x)
            bound, shift = (self.check(self.basis, x, Y, pairing, near, mu)[1::2]
                            if mu >= TRIAL_MU else (np.inf, np.inf))
            done = bound <= self.bound
            if not done:
                coef = self.coefficients(x)[0]
                try:
                    ref = self.factor_at(x, self.basis.eig(coef, 1)[0][0])
                except _TrialFailed:
                    continue                     # (trial() makes it again, then identify())
                self.refs.append(ref)
                _, bound, S, shift = self.check(self.basis, x, Y, pairing, ref)
                done = bound <= self.bound
                if not done:
                    # the shared basis is enriched where the stricter bound is missed (the
                    # trials after these find it so); a pilot accepted by its shift
                    # (:meth:`accepts`) is done
                    done = self.accepts(bound, shift)
                    k = self.basis.add(S())
                    added += k
                    if k:
                        self._shared_basis_changed()
            if done:
                self.pilot[i] = (self.constants(x), bound, shift, 1, model.energies)
        self.hold(None)
        return added

    def _enrich_cloud(self):
        """Enrich the basis where the trials go far: at ``x* +- CLOUD_RADIUS`` standard errors
        along the directions of the largest relative change of the stiffness coefficients per
        standard error (where that change exceeds CLOUD_CHANGE), shrunk into the feasible
        set; one factorisation and CLOUD_ROUNDS block solves of the Ritz residuals each."""
        c, J = self.coefficient_jacobian(self.x_opt)
        # a coefficient that is 0 at the optimum (alpha2 = 0: hybrid CM's glass E2 = E1)
        # makes the relative changes infinite, and the SVD's directions NaN: no point of
        # the cloud is then feasible, and none is added (as before its profiles' models
        # made this warning visible)
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            rel = (J @ self.T) / np.maximum(np.abs(c), 1e-300)[:, None]
            _, sv, Wt = np.linalg.svd(rel, full_matrices=False)
        for k in range(min(CLOUD_DIRECTIONS, sv.size)):
            if sv[k] * CLOUD_RADIUS < CLOUD_CHANGE:
                break
            for sign in (1.0, -1.0):
                y = sign * CLOUD_RADIUS * Wt[k]
                x = self.x_opt + self.T @ y
                for _ in range(20):
                    if (np.all(x >= self.lo) and np.all(x <= self.hi)
                            and np.all(self.A @ x <= self.b)):
                        break
                    y = 0.8 * y
                    x = self.x_opt + self.T @ y
                else:
                    continue
                coef = self.coefficients(x)[0]
                theta, Y = self.basis.eig(coef, self.n_model)
                try:
                    ref = self.factor_at(x, theta[0])
                except _TrialFailed:
                    continue                     # (a point inside the limits: not seen)
                self.refs.append(ref)
                solve = ref[2]
                for _ in range(CLOUD_ROUNDS):
                    added = self.basis.add(self.basis.residuals(coef, theta, Y, solve)[1])
                    theta, Y = self.basis.eig(coef, self.n_model)
                    if not added:
                        break

    def __getstate__(self):                  # pickled (spawned workers): A0 is factorised
        state = dict(self.__dict__)          # again there, the cloud's are not kept
        state["_solve"] = None
        state["refs"] = None
        return state

    def nearest_ref(self, x):
        """(mu, (coefficients, sigma, solve)) of the kept factorisation whose constitutive
        matrices are closest below those at ``x`` (largest mu)."""
        if not self.refs:
            self.refs = [(self.coef_opt, self.sigma, self.factor0())]
        mus = self.mus(x, [ref[0] for ref in self.refs])
        k = int(np.argmax(mus))
        return float(mus[k]), self.refs[k]

    def factor0(self):
        """The factorisation of ``A0`` (once per process)."""
        if self._solve is None:
            plate = self.fm.plate
            K0 = plate.stiffness(coef=self.coef_opt)
            self._solve = self.fm.factorizer.factor(K0.data - self.sigma * plate.M_on_K)
        return self._solve

    def modes(self, basis, x, Y_ref) -> "TrialModes":
        """The model at ``x`` (:class:`TrialModes`), its modes paired by MAC against ``Y_ref``
        (the optimum's)."""
        coef, jacs = self.coefficients(x)
        theta, Y = basis.eig(coef, self.n_model)
        self.n_evaluations += 1
        pairing = max_assignment((Y_ref.T @ (basis.Mr @ Y)) ** 2)
        E = basis.energies(Y[:, pairing])
        return TrialModes(theta[pairing], pairing, Y, self.eigenvalue_jacobian(E, jacs), E)

    def rows(self, x, model, lam_meas, w):
        """Residual rows of paper Eq. 17 (+ Eq. 15) at ``x`` from its ``model`` (:meth:`modes`)
        and their Jacobian: (rows, Jacobian); the objective is ``rows . rows``."""
        r, J = residual_rows(lam_meas, w, model.lam, model.dlam_dx)[:2]
        pv, pr = self.prior_rows(x)
        return np.concatenate([r, pv]), np.vstack([J, pr])

    def evaluate(self, basis, x, lam_meas, w, Y_ref):
        """Objective, gradient, residual rows and their Jacobian, and the model at ``x``."""
        model = self.modes(basis, x, Y_ref)
        res, J = self.rows(x, model, lam_meas, w)
        return float(res @ res), 2 * res @ J, res, J, model

    def shift_of(self, rel_paired) -> float:
        """The first-order bound on the shift of any constant, in its standard errors, that
        relative eigenvalue errors up to ``rel_paired`` (the paired modes' bounds, by measured
        mode) allow: sqrt(sum_i (rel_i / rel_sd_i)^2) over the modes the fit weighs (inf
        without :attr:`rel_sd`).

        Why: to first order a constant moves by a_k . d (d the eigenvalues' relative errors;
        a_k its row of the fit's linear map), and its standard error is |a_k * rel_sd| (the
        same map applied to the modes' independent errors; sandwich form, so whatever the
        weights, a prior adding rows that do not move); by Cauchy-Schwarz
        |a_k . d| <= |a_k * rel_sd| |d / rel_sd|."""
        if self.rel_sd is None:
            return np.inf
        e = np.asarray(rel_paired, float) / self.rel_sd
        return float(np.sqrt(np.sum(e * e)))

    def accepts(self, bound: float, shift: float) -> bool:
        """A trial's answer is accepted when its paired modes' largest relative eigenvalue
        bound is within :attr:`bound` (TRIAL_SHARE of the smallest relative eigenvalue
        standard deviation), or, short of that, within TRIAL_BOUND with the first-order shift
        of every constant (:meth:`shift_of`) within :attr:`shift_limit` = TRIAL_SHARE
        sqrt(m) standard errors (m the modes the fit weighs). The first implies the second
        (each term of the sum is then at most TRIAL_SHARE): both give the same guarantee, a
        constant within TRIAL_SHARE sqrt(m) of its standard error of the full model's
        answer to first order (3.5 % for S1.1's 12 modes). The second also accepts an
        answer whose bounds are above the first's on some modes only (mostly the highest),
        which the first sent to an enrichment: 26 of the 54 such trials of 200 of S1.1
        (12x12), whose enriched answers were within 0.0175 standard errors of them."""
        return bound <= self.bound or (bound <= TRIAL_BOUND and shift <= self.shift_limit)

    def check(self, basis, x, Y, pairing, ref=None, mu=None):
        """Full-matrix Ritz values of the checked Ritz vectors at ``x`` and the largest relative
        error bound of the paired ones, with the factorisation ``ref`` = (coefficients, sigma,
        a factor of :func:`laminid_cli.modal.make_factorizer`) of another point (default: the
        optimum's; class docstring; ``mu``: :meth:`mu` against it, when known). Returns
        (theta, bound, directions, shift): ``directions()`` gives the preconditioned
        residuals (for an enrichment); bound inf when not computable; shift the first-order
        shift of the constants that the paired modes' bounds allow (:meth:`shift_of`; inf
        when not computable).

        The vectors checked are the paired modes and the next one (whose bound enters theirs,
        :func:`laminid_cli.reduced.residual_bounds`); ``r^T A_ref^-1 r`` is ``|L^-1 P r|^2``
        with ``P A_ref P^T = L L^T`` (one triangular solve per vector; banded: ``|U^-T r|^2``)."""
        plate = self.fm.plate
        coef = self.coefficients(x)[0]
        if ref is None:
            ref = (self.coef_opt, self.sigma, self.factor0())
        coef_ref, sigma, solve = ref
        if mu is None:
            mu = self.mu(x, coef_ref)
        if not mu > 0:
            return None, np.inf, None, np.inf
        n = min(int(np.max(pairing)) + 2, Y.shape[1])
        Yn = Y[:, :n]
        U = basis.V @ Yn
        MU = basis.M @ U                     # (KroneckerMass: 0.16 against 0.27 ms by MV Yn)
        scale = 1.0 / np.sqrt(np.einsum("ij,ij->j", U, MU))
        U *= scale
        MU *= scale
        from laminid_cli.reduced import TARGET_MARGIN, checked_ritz

        theta, R, bound = checked_ritz(U, plate.stiffness_products(coef, U), MU, solve, sigma,
                                       1.0 / min(mu, 1.0))
        rel = bound / theta

        # an enrichment adds the residuals of the modes above TARGET_MARGIN of the accepted
        # bound (the rule of ReducedBasis.enrich with a target: the others' are mostly round-off)
        active = rel > TARGET_MARGIN * self.bound
        return (theta, float(np.max(rel[pairing])), lambda: solve(R[:, active]),
                self.shift_of(rel[pairing]))

    def mu(self, x, coef_ref):
        """Smallest generalised eigenvalue of the constitutive matrices at ``x`` against those
        of ``coef_ref`` over the materials: ``K(x) >= mu K(ref)`` (class docstring)."""
        return float(self.mus(x, [coef_ref])[0])

    def mus(self, x, coef_refs) -> np.ndarray:
        """:meth:`mu` against each of ``coef_refs`` (reduced.stiffness_ratios)."""
        from laminid_cli.reduced import stiffness_ratios

        return stiffness_ratios(self.coefficients(x)[0], coef_refs)

    def factor_at(self, x, theta1):
        """(coefficients, sigma, solve) of A = K - sigma M factorised at ``x``; a factorisation
        that fails (A not positive definite: a trial's answer where the reduced model's lowest
        eigenvalue ``theta1`` is not positive) is the trial model's refusal (_TrialFailed: the
        trial is identified again with identify(), as any the model refuses)."""
        plate = self.fm.plate
        coef = self.coefficients(x)[0]
        sigma = -0.5 * float(theta1)
        try:
            solve = self.fm.factorizer.factor(plate.stiffness(coef=coef).data
                                              - sigma * plate.M_on_K)
        except SolverError as exc:
            raise _TrialFailed(f"no factorisation at its answer ({exc})") from None
        return coef, sigma, solve

    def _gauss_newton(self, basis, x0, lam_meas, w, Y_ref, model0=None):
        """Levenberg-Marquardt on the reduced model from ``x0`` (``model0``: the model there,
        when known), in the trial variables y (:meth:`trial_variables`: the transverse shear
        moduli in logarithm), each step the damped Gauss-Newton step restricted to the
        search's bounds and linear constraints (:meth:`_step_constraints`: exact where they
        are linear in y, else linearised at y and the step halved while the point it gives is
        outside them; :func:`_constrained_step`), lengthened by Aitken's factor 1 / (1 - q)
        where the last steps shrink by a steady ratio q; returns (x, model there) when the
        step taken, or the next one computed there (not evaluated: one evaluation fewer per
        trial, 200 trials of S1.1 10.9 -> 10.1 s, answers within 1e-3 standard errors), is
        below TRIAL_XTOL standard errors, None when it does not get there; (x, model,
        finished): finished False where its last GN_STALL steps lowered the objective by at
        most :attr:`ftol` in all (a flat, curved valley that its steps follow slowly), and,
        with an ftol, where it does not get there (:meth:`_unfinished`): SLSQP goes on from
        x (:meth:`solve`)."""
        x = np.asarray(x0, float)
        y = self.trial_variables(x)
        D = self.design_variables(y)[1]
        model = self.modes(basis, x, Y_ref) if model0 is None else model0
        res, J = self.rows(x, model, lam_meas, w)
        J = J @ D
        f = float(res @ res)
        A, b = self._A_all, self._b_all
        slack = 1e-12 * np.maximum(np.abs(b), 1.0)
        # Marquardt's scaling, Nielsen's damping update from the gain ratio (a rejected step
        # raises the damping to at least 1e-2 at once: the first steps of far trials overshoot)
        damp, nu = 1e-6, 4.0
        prev = None                             # the last step taken
        taken = [f]                             # the objective after each step taken
        for _ in range(self.iterations):
            H = J.T @ J
            d = np.diag(H)
            g = J.T @ res
            dy = _constrained_step(H + damp * np.diag(d) + 1e-14 * d.max() * np.eye(d.size), g,
                                   *self._step_constraints(x, y, D),
                                   max_iter=self.step_iterations)
            if dy is None:
                return self._unfinished(x, model)
            if prev is not None:
                # linear convergence (GN on non-zero residuals): when this step is the last
                # one shortened by a ratio q, the steps to come sum to dy / (1 - q) (Aitken)
                q = float(dy @ prev) / float(prev @ prev)
                if abs(q) < 0.8 and np.linalg.norm(dy - q * prev) <= 0.1 * np.linalg.norm(dy):
                    if float(np.max(np.abs(self.L.T @ (D @ dy)))) <= TRIAL_XTOL \
                            and damp <= 0.1:
                        return x, model, True
                    dy = dy / (1.0 - q)
            for _ in range(30):
                with np.errstate(over="ignore", invalid="ignore"):  # exp of a far step
                    x_new, D_new = self.design_variables(y + dy)
                    if np.all(np.isfinite(x_new)) and np.all(A @ x_new <= b + slack):
                        break
                dy = 0.5 * dy                  # (the constraints are linear in x, not in y)
            else:
                return self._unfinished(x, model)
            step = float(np.max(np.abs(self.L.T @ (x_new - x))))
            if step <= TRIAL_XTOL and damp <= 0.1:
                return x, model, True           # the next step is within the tolerance
            model_n = self.modes(basis, x_new, Y_ref)
            res_n, J_n = self.rows(x_new, model_n, lam_meas, w)
            f_new = float(res_n @ res_n)
            if f_new <= f:
                predicted = -(2 * g @ dy + dy @ H @ dy)
                rho = (f - f_new) / predicted if predicted > 0 else 0.0
                x, y, D, f, res, J, model = x_new, y + dy, D_new, f_new, res_n, J_n @ D_new, \
                    model_n
                prev = dy
                if step <= TRIAL_XTOL and damp <= 0.1:     # (not a step cut by damping)
                    return x, model, True
                taken.append(f)
                if self.ftol > 0 and len(taken) > GN_STALL \
                        and taken[-GN_STALL - 1] - f <= self.ftol:
                    return x, model, False      # a flat valley: SLSQP goes on (solve())
                damp = max(damp * max(1 / 3, 1 - (2 * rho - 1) ** 3), 1e-9)
                nu = 4.0
            elif step <= 10 * TRIAL_XTOL:
                # a step this small gives no decrease: the reduced objective's round-off floor
                # (about 1e-9 relative) is reached
                return x, model, True
            else:
                damp, nu = max(damp * nu, 1e-2), 2 * nu
                prev = None
                if damp > 1e3:
                    return self._unfinished(x, model)
        return self._unfinished(x, model)

    def _unfinished(self, x, model):
        """What :meth:`_gauss_newton` returns where it does not get to its end at ``x``: None
        (SLSQP starts again where it started: the trials), or, with an :attr:`ftol` (a
        profile's fits), (x, model, False) as after a stall: SLSQP goes on from there."""
        return (x, model, False) if self.ftol > 0 else None

    def _minimise(self, basis, x0, lam_meas, w, Y_ref):
        """One SLSQP run on the reduced model from ``x0`` (variables y = L^T (x - x0), in
        linearised standard errors); returns (best x, the model there (:meth:`modes`))."""
        import nlopt

        from laminid_cli.identify import nlopt_failures

        # scaled by the Gauss-Newton Hessian at x0 (far from the optimum the valley turns)
        J = self.evaluate(basis, x0, lam_meas, w, Y_ref)[3]
        H = J.T @ J / self.tau2
        d = np.diag(H).copy()
        H += np.diag(1e-9 * max(d.max(), 1e-300) + 1e-9 * d)
        L = np.linalg.cholesky(H)
        T = np.linalg.inv(L.T)
        A_all = np.vstack([self.A, np.eye(self.n_vars), -np.eye(self.n_vars)])
        b_all = np.concatenate([self.b, self.hi, -self.lo])
        Ay = A_all @ T
        by = b_all - A_all @ x0
        span = np.abs(L.T) @ np.maximum(self.hi - x0, x0 - self.lo)
        scale = 2 * self.tau2
        best = [np.inf, None, None]
        worst = [0.0]

        def objective(y, grad):
            x = x0 + T @ y
            if self.refusal(x):
                # as identify() does (identify.Problem._refused): not evaluated, ten times the
                # worst objective met, no gradient, so SLSQP steps back inside. Evaluated, the
                # reduced model gave such points an objective, and one below the feasible
                # ones' (the emulator's plate, seed 14: G12 = -2.7 MPa, its reduced lowest
                # eigenvalue negative) was the trial's answer, whose factorisation then failed
                if grad.size:
                    grad[:] = 0.0
                return (10.0 * worst[0] + 1.0) / scale
            f, g, _, _, model = self.evaluate(basis, x, lam_meas, w, Y_ref)
            if grad.size:
                grad[:] = T.T @ g / scale
            worst[0] = max(worst[0], f)
            if f < best[0]:
                best[:] = f, x, model
            return f / scale

        def cons(result, y, grad):
            if grad.size:
                grad[:] = Ay
            result[:] = Ay @ y - by

        opt = nlopt.opt(nlopt.LD_SLSQP, self.n_vars)
        opt.set_lower_bounds(-span)
        opt.set_upper_bounds(span)
        opt.add_inequality_mconstraint(cons, np.full(Ay.shape[0], 1e-12))
        opt.set_min_objective(objective)
        opt.set_xtol_abs(np.full(self.n_vars, TRIAL_XTOL))
        opt.set_ftol_rel(1e-12)
        opt.set_maxeval(TRIAL_MAXEVAL)
        try:
            opt.optimize(np.zeros(self.n_vars))
            code = opt.last_optimize_result()
            if code == nlopt.MAXEVAL_REACHED and self.ftol <= 0:
                # a trial gives up (identify() makes it); a profile's fit (an ftol) goes on
                # from its best point, restarted as after any run (:meth:`solve`), and its
                # answer is checked as any: hybrid CM's glass G13 held at 18.5 GPa and G12 at
                # 6.8 GPa went to identify() after 300-500 reduced evaluations (G12: 298 more,
                # unfinished at a rise of 262, the initial values' fit then taken, 0.11; its
                # reduced fit now ends at 0.094, and G12's later fits from the optimum too)
                raise _TrialFailed(f"{TRIAL_MAXEVAL} evaluations of the trial model reached")
            if code < 0:
                raise _TrialFailed(f"optimiser stopped ({code})")
        except nlopt.RoundoffLimited:
            pass                             # at the round-off floor: the best point is kept
        except nlopt_failures(nlopt) as exc:
            # (nlopt 2.11's own runtime_error subclasses no RuntimeError: it went past this as
            # a traceback with -j 1, and from a worker as "cannot pickle 'SwigPyObject'")
            raise _TrialFailed(f"optimiser failure ({exc})") from None
        if best[1] is None:
            raise _TrialFailed("the trial model was not evaluated")
        return best[1], best[2]

    def trial(self, freq_hz, weight, prior_shift=None, held=None):
        """Identify from ``freq_hz`` (and the prior's pseudo-measurements drawn as
        ``prior_shift``, :attr:`laminid_cli.objective.VariableSet.prior_shift`; the fixed
        constants of ``held`` at those values, :meth:`hold`): (constants,
        relative eigenvalue bound, first-order shift bound of the constants in standard errors
        (:meth:`shift_of`), rounds, :attr:`TrialModes.energies` of the model at the answer),
        accepted by :meth:`accepts`, or raises _TrialFailed (:meth:`solve`)."""
        a = self.solve(freq_hz, weight, prior_shift, held)
        return self.constants(a.x), a.bound, a.shift, a.rounds, a.model.energies

    def solve(self, freq_hz, weight, prior_shift=None, held=None, start=None) -> "TrialAnswer":
        """:meth:`trial`'s fit, its answer whole (:class:`TrialAnswer`): from ``start`` (x,
        model there; default :meth:`_start`, the optimum at the values held)."""
        self.prior_shift = prior_shift or {}
        self.hold(held)
        lam_meas = (2 * np.pi * np.nan_to_num(freq_hz, nan=1.0)) ** 2
        w = np.where(np.isfinite(freq_hz), weight, 0.0)
        self.basis.reset_class_counts()      # (the same trial in any process: -j 1 = -j 2)
        start = self._start() if start is None else start
        if start is None:
            raise _TrialFailed("the optimum is outside the search's limits at the drawn "
                               "fixed values")
        basis, Y_ref, L = self.basis, self.Y_ref, self.L
        x0, model0 = start
        ref = None
        steps = [0]

        def stepping():
            steps[0] += 1
            if self.step_progress is not None:
                self.step_progress(f"reduced model, step {steps[0]}")

        for rounds in range(1, TRIAL_ROUNDS + 1):
            stepping()
            gn = self._gauss_newton(basis, x0, lam_meas, w, Y_ref,
                                    model0 if rounds == 1 else None)
            if gn is not None and not gn[2]:
                x0, gn = gn[0], None             # stalled: SLSQP from where it stopped
            # else SLSQP, restarted from its answer while that moves (its quasi-Newton model
            # starts from the Gauss-Newton scaling again: flat valleys are followed to the end)
            for _ in range(0 if gn is not None else TRIAL_RESTARTS):
                stepping()
                x, model = self._minimise(basis, x0, lam_meas, w, Y_ref)
                step = float(np.max(np.abs(L.T @ (x - x0))))
                x0 = x
                if step <= 10 * TRIAL_XTOL:
                    break
            if gn is not None:
                x, model, _ = gn
            pairing, Y = model.pairing, model.Y
            if ref is None:
                # the kept factorisation nearest to the answer, if near enough
                mu, near = self.nearest_ref(x)
                bound, S, shift = np.inf, None, np.inf
                if mu >= TRIAL_MU:
                    theta, bound, S, shift = self.check(basis, x, Y, pairing, near, mu)
                if not self.accepts(bound, shift) and (S is None or rounds > 1
                                                       or bound > TRIAL_FAR * self.bound):
                    # one factorisation at the trial's answer, for the check and the
                    # enrichments; in the first round a kept one near enough gives the
                    # enrichment's directions instead (the enriched basis mostly reaches the
                    # bound with it: 19 instead of 43 factorisations in 200 trials of S1.1),
                    # unless the answer is far from every kept one (TRIAL_FAR)
                    ref = self.factor_at(x, basis.eig(self.coefficients(x)[0], 1)[0][0])
                    theta, bound, S, shift = self.check(basis, x, Y, pairing, ref)
            else:
                theta, bound, S, shift = self.check(basis, x, Y, pairing, ref)
            log.debug("trial round %d bound %.2e shift %.2e", rounds, bound, shift)
            if self.accepts(bound, shift):
                return TrialAnswer(x, model, basis, Y_ref, ref, bound, shift, rounds)
            if rounds == TRIAL_ROUNDS or S is None:
                break
            basis = basis.copy()
            if basis.add(S()) == 0:
                break
            # the basis only grows (new columns appended): old reduced vectors extend by zeros
            Y_ref = np.vstack([Y_ref, np.zeros((basis.size - Y_ref.shape[0], Y_ref.shape[1]))])
            x0 = x
        raise _TrialFailed(f"reduced trial model: eigenvalue bound {bound:.1e} above "
                           f"{self.bound:.0e}"
                           + (f" (first-order shift {shift:.2g} standard errors, above "
                              f"{self.shift_limit:.2g})" if self.rel_sd is not None else ""))


class TrialAnswer(NamedTuple):
    """A fit of the trial model accepted by :meth:`TrialModel.accepts`: its design variables
    ``x``, the model there (:class:`TrialModes`) on ``basis`` (the shared one, or a copy
    enriched for it) with the optimum's reduced vectors ``Y_ref`` on that basis, the
    factorisation made at the answer (None when a kept one did), the largest relative
    eigenvalue bound of its paired modes, the first-order shift bound of its constants
    (:meth:`TrialModel.shift_of`) and its rounds."""

    x: np.ndarray
    model: TrialModes
    basis: object
    Y_ref: np.ndarray
    ref: tuple | None
    bound: float
    shift: float
    rounds: int


class _TrialFailed(Exception):
    pass


def _constrained_step(H, g, A, s, max_iter: int = 50):
    """The step d minimising ``g . d + d . H d / 2`` (H positive definite) subject to
    ``A d <= s`` (``s >= 0``: d = 0 is feasible, up to round-off): primal active-set method
    (Nocedal & Wright, Algorithm 16.3) from d = 0; None if it does not finish."""
    n = g.size
    d = np.zeros(n)
    s = np.maximum(s, 0.0)
    p = np.linalg.solve(H, -g)
    if np.all(A @ p <= s):
        return p                             # the unconstrained step (the usual case)
    tiny = 1e-12 * np.abs(p).max()
    work: list[int] = []
    for _ in range(max_iter):
        grad = H @ d + g
        m = len(work)
        if m:
            # H p + Aw^T lambda = -grad, Aw p = 0 (lambda >= 0 at the answer)
            Aw = A[work]
            K = np.block([[H, Aw.T], [Aw, np.zeros((m, m))]])
            sol = np.linalg.lstsq(K, np.concatenate([-grad, np.zeros(m)]), rcond=None)[0]
            p, mult = sol[:n], sol[n:]
        else:
            p, mult = np.linalg.solve(H, -grad), np.zeros(0)
        if np.abs(p).max() <= tiny:
            if m == 0 or mult.min() >= 0:
                return d
            work.pop(int(np.argmin(mult)))
            continue
        Ap = A @ p
        slack = s - A @ d
        grow = Ap > 1e-15 * np.abs(A).sum(axis=1) * np.abs(p).max()
        grow[work] = False
        alpha, block = 1.0, -1
        if grow.any():
            ratios = np.where(grow, np.maximum(slack, 0.0) / np.where(grow, Ap, 1.0), np.inf)
            k = int(np.argmin(ratios))
            if ratios[k] < 1.0:
                alpha, block = float(ratios[k]), k
        d = d + alpha * p
        if block >= 0:
            work.append(block)
    return None


# ----------------------------------------------------------------------------------------------
# Monte Carlo

#: probability with which each end of MonteCarlo.inner_range lies inside the Monte Carlo
#: range's quantile: what the verdicts take from the trials (:func:`with_monte_carlo`)
MC_EVIDENCE = 0.95


@dataclass(frozen=True)
class MonteCarlo:
    """Empirical spread of re-identifications from perturbed frequencies.

    samples : (n_converged, p) identified free constants (SI) over ``labels``
    std, mean, lower, upper : (p,) empirical; lower/upper the (1-confidence)/2 quantiles
    linearized_std : (p,) the linearised standard errors they are compared with
    ratio : std / (linearized_std * t_std), t_std = sqrt(nu / (nu - 2)) the standard
        deviation of Student's t with nu = ``variance_dof`` (1 when 0; NaN for nu <= 2, whose
        t has no variance): 1 for a linear model
    sigma_factor : the frequencies were perturbed by sigma_f * sigma_factor (sqrt of the
        variance factor used for the linearised intervals, so both describe the same noise;
        with ``variance_dof`` > 0, times each trial's draw of :func:`variance_draws`)
    method : how the trials ran: "reduced" (the optimum's TrialModel) or "identify"
    trial_bound : largest relative eigenvalue error bound, against the full FE model, of the
        converged trials' paired modes (and two beyond) where the trials computed it (NaN
        where not: trials of the full solver)
    n_reidentified : reduced trials whose model missed its bound, re-run through identify()
    trial_bound_limit : the bound that accepts a reduced trial by itself (TRIAL_SHARE of the
        smallest relative eigenvalue standard deviation, at most TRIAL_BOUND)
    trial_shift, trial_shift_limit : the largest first-order bound, over the reduced trials,
        on how far a constant is from the full model's answer, in its standard errors
        (:meth:`TrialModel.shift_of`), and the limit a reduced trial had to meet
        (TRIAL_SHARE sqrt(m), m the modes the fit weighs; :meth:`TrialModel.accepts`)
    at_lower_bound, at_upper_bound : (p,) converged trials whose answer has the constant on a
        lower / upper limit of the search (:func:`bounds_reached`, as for the identification)
    confidence : of the range ``lower`` .. ``upper``
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
    method: str = "identify"
    trial_bound: float = float("nan")
    n_reidentified: int = 0
    trial_bound_limit: float = float("nan")
    trial_shift: float = float("nan")
    trial_shift_limit: float = float("nan")
    at_lower_bound: np.ndarray | None = None
    at_upper_bound: np.ndarray | None = None
    confidence: float = 0.95
    #: the prior rows' noise with which each trial drew the prior's values (paper Eq. 15: P0
    #: of a constant given a prior weight wp drawn with relative sd prior_sigma / sqrt(wp)),
    #: 0 without a prior
    prior_sigma: float = 0.0
    #: (n_converged,) the trial (0-based, in the order drawn) of each row of ``samples``
    trials: np.ndarray | None = None
    #: (n_converged, n_measured, n_materials * 5) strain-energy shares of each converged
    #: trial's paired modes at its constants (laminid_cli.damping.energy_shares), for a single
    #: plate with measured damping (None otherwise): the loss factors' refits
    #: (laminid_cli.damping.monte_carlo_loss_factors)
    energy_shares: np.ndarray | None = None
    #: with constants fixed because undetermined (:class:`FixedDraw`): the labels of those
    #: each trial drew from their spread before fixing, the values drawn (n_converged, k; SI,
    #: rows as ``samples``), the converged trials whose draw was shortened to the search's
    #: range (:meth:`FixedDraw.draw`), and the labels of those held (fixed on a limit of the
    #: search: doubt unknown)
    fixed_labels: tuple[str, ...] = ()
    fixed_samples: np.ndarray | None = None
    fixed_clipped: int = 0
    fixed_held: tuple[str, ...] = ()
    #: degrees of freedom of the variance factor each trial drew (the linearised intervals
    #: scaled by s2, Student t: :func:`variance_draws`); 0 when the stated sigma was used
    variance_dof: int = 0
    #: (n_converged, p) int8, rows as ``samples``: -1 where the trial's answer has the
    #: constant on a lower limit of the search, +1 on an upper one, 0 elsewhere
    #: (:func:`trial_bound_flags`; ``at_lower_bound``/``at_upper_bound`` count them); None
    #: where not kept (no trial then counts as on a limit)
    trial_at_bound: np.ndarray | None = None

    def bound_counts(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) trials at a limit of the search per constant (p,), zeros where not
        counted."""
        p = len(self.labels)
        return tuple(np.zeros(p, int) if c is None else np.asarray(c, int)
                     for c in (self.at_lower_bound, self.at_upper_bound))

    def inner_range(self, level: float = MC_EVIDENCE) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (p,): order statistics of the samples that lie inside the range's
        two quantiles, each with probability >= ``level`` whatever the samples' distribution
        (:func:`laminid_cli.quantiles.order_statistic_below`): the range ``lower`` ..
        ``upper`` that the trials' distribution has is at least this wide with probability
        >= 2 level - 1. With 40 trials (95 % range, level 0.95) the 4th smallest and the 4th
        largest sample; with 200 the 10th; with 5 the 2nd. NaN where the trials bound no width
        (a single trial)."""
        return inner_range_of(self.samples, len(self.labels), self.confidence, level)

    def ends_at_bound(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) flags (p,): the end of the range is set by trials at a limit of the
        search (:func:`range_ends_at_bound`), so it is the search's end, not the data's."""
        return range_ends_at_bound(*self.bound_counts(), self.n_converged, self.confidence)

    def as_dict(self) -> dict:
        per = {}
        lo_n, up_n = self.bound_counts()
        lo_b, up_b = self.ends_at_bound()
        in_lo, in_hi = self.inner_range()
        for k, lab in enumerate(self.labels):
            mat, const = lab.rsplit(".", 1)
            per.setdefault(mat, {})[const] = {
                "mean": float(self.mean[k]), "std": float(self.std[k]),
                "lower": float(self.lower[k]), "upper": float(self.upper[k]),
                "inner_lower": float(in_lo[k]), "inner_upper": float(in_hi[k]),
                "linearized_std": float(self.linearized_std[k]), "ratio": float(self.ratio[k]),
                "trials_at_lower_bound": int(lo_n[k]), "trials_at_upper_bound": int(up_n[k]),
                "lower_at_bound": bool(lo_b[k]), "upper_at_bound": bool(up_b[k])}
        return {"trials": self.n_trials, "converged": self.n_converged, "constants": per,
                "sigma_factor": self.sigma_factor, "seed": self.seed, "jobs": self.jobs,
                "time_s": self.time_s, "failures": list(self.failures),
                "method": self.method, "trial_eigenvalue_bound": self.trial_bound,
                "trial_eigenvalue_bound_limit": self.trial_bound_limit,
                "trial_shift_bound": self.trial_shift, "trial_shift_limit": self.trial_shift_limit,
                "reidentified": self.n_reidentified, "prior_sigma": self.prior_sigma,
                "evidence_level": MC_EVIDENCE, "fixed_drawn": list(self.fixed_labels),
                "fixed_clipped": self.fixed_clipped, "fixed_held": list(self.fixed_held),
                "variance_dof": self.variance_dof}


#: the stream of the trials' variance factors: ``numpy.random.default_rng([seed, 19])``, of
#: its own, so that the frequencies (stream ``seed``), the priors' ([seed, 15]), the measured
#: damping's ([seed, 16]) and the fixed values' ([seed, 17]) draws are those of a Monte Carlo
#: on the stated sigma
VARIANCE_STREAM = 19


def variance_draws(uncertainty, n_trials: int, seed) -> tuple[np.ndarray, int]:
    """(g (n_trials,), nu): each trial's noise multiplier, and the degrees of freedom drawn.

    Intervals scaled by the a-posteriori variance factor s2 (``scale_used`` "residuals") use
    Student's t with nu = dof degrees of freedom, because s2 is itself an estimate. A Monte
    Carlo that perturbed every trial by sigma s would give the normal quantile's range,
    narrower by t/z (dof 9: 2.26 / 1.96, dof 6: 2.45 / 1.96), and its verdicts would miss what
    the intervals see. So each trial draws its variance as the data leave it,
    sigma_t^2 = s2 nu / X with X ~ chi-square(nu), and its noise is the stated one times
    s g with g = sqrt(nu / X): for a linear model the trials' constants are then Student t
    about the optimum (a normal over a chi-square's root), and their 2.5-97.5 % range is the
    t interval. On the stated sigma (nu = 0), g = 1."""
    nu = variance_dof(uncertainty)
    if not np.isfinite(nu):
        return np.ones(n_trials), 0
    nu = int(nu)
    rng = np.random.default_rng(None if seed is None else [int(seed), VARIANCE_STREAM])
    return np.sqrt(nu / rng.chisquare(nu, n_trials)), nu


def sample_spread(samples, p: int, confidence: float):
    """(mean, std, lower, upper) (p,) of Monte Carlo ``samples`` (n, p): the empirical std
    (n - 1) and the (1 -+ confidence) / 2 quantiles; NaN with fewer than two samples (also the
    loss factors' Monte Carlo, laminid_cli.damping)."""
    if samples.shape[0] >= 2:
        mean, std = samples.mean(axis=0), samples.std(axis=0, ddof=1)
        lower, upper = np.quantile(samples, [(1 - confidence) / 2, (1 + confidence) / 2],
                                   axis=0)
        return mean, std, lower, upper
    nan = np.full(p, np.nan)
    return nan, nan.copy(), nan.copy(), nan.copy()


def inner_range_of(samples, p: int, confidence: float, level: float = MC_EVIDENCE
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`MonteCarlo.inner_range` of ``samples`` (n, p) with a ``confidence`` range (also
    the loss factors' Monte Carlo, laminid_cli.damping)."""
    from laminid_cli.quantiles import order_statistic_below

    n = int(samples.shape[0]) if samples is not None else 0
    k = order_statistic_below(n, 0.5 + confidence / 2, level) if n else 0
    m = n + 1 - k                       # the lower quantile's bound, by symmetry
    if k < 1 or m >= k:
        return np.full(p, np.nan), np.full(p, np.nan)
    x = np.sort(np.asarray(samples, float), axis=0)
    return x[m - 1].copy(), x[k - 1].copy()


def range_ends_at_bound(at_lower, at_upper, n: int, confidence: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) flags: the (1 - confidence) / 2 quantile of ``n`` samples (linear
    interpolation between order statistics, position q (n - 1) from 0) takes at least half its
    weight from samples at the lower limit of the search, so that end is the search's and not
    the data's; likewise the upper one. ``at_lower``/``at_upper``: samples at each limit, per
    constant. With 40 trials and 95 %, the quantile is 0.025 x the smallest + 0.975 x the
    second smallest: one trial at the limit moves it by 2.5 % of their distance only (not
    flagged), two make it the limit.

    Where nearly every trial ends on one limit, the other end of the range is set by them as
    well (S2.1 at 8x8, 10 trials, all ten on G13's lower limit 1e-4 E1: the range 0.002879 ..
    0.003000 GPa is the spread of that limit with E1, its upper end no bound the data put on
    G13, whose profile is flat to 18.5 GPa): that end is flagged too, by the same rule, the
    samples on the far limit counted from its side."""
    at_lower = np.asarray(at_lower, int)
    at_upper = np.asarray(at_upper, int)
    pos = (1 - confidence) / 2 * max(n - 1, 0)
    i = int(np.floor(pos))
    frac = pos - i
    need = i + 1 if frac <= 0.5 else i + 2          # samples at the limit for weight >= 1/2
    # the quantile from the other side lies in the trials on the far limit where fewer than
    # ``need`` others are left on its side (the order statistics of a sorted sample)
    return ((at_lower >= need) | ((at_upper > 0) & (n - at_upper < need)),
            (at_upper >= need) | ((at_lower > 0) & (n - at_lower < need)))


def sorted_ends_at_bound(values, on_limit, confidence: float) -> tuple[bool, bool]:
    """(lower, upper): the rule of :func:`range_ends_at_bound` for a quantity computed from
    the constants (a laminate property, laminid_cli.global_uncertainty), whose trials on a
    limit of the search need not be its smallest or largest: an end is flagged where the
    order statistic that carries at least half the weight of its quantile (linear
    interpolation, position q (n - 1) from 0; the outer one at a tie) is a trial on a limit
    (``on_limit``, (n,) bool). For samples whose trials on a limit are the smallest (a
    constant on its lower limit) this is :func:`range_ends_at_bound`, far end included."""
    x = np.asarray(values, float)
    n = x.size
    if n < 2:
        return False, False
    pos = (1 - confidence) / 2 * (n - 1)
    i = int(np.floor(pos))
    k = i + 1 if pos - i > 0.5 else i
    lim = np.asarray(on_limit, bool)[np.argsort(x, kind="stable")]
    return bool(lim[k]), bool(lim[n - 1 - k])


def trial_bound_flags(result, labels, samples) -> np.ndarray:
    """(n, p) int8 over the trials (rows of ``samples``, over ``labels``): -1 where the
    trial's answer has the constant on a lower limit of the search, +1 on an upper one, 0
    elsewhere: :func:`bounds_reached` on each trial's constants (the fixed ones are the
    result's)."""
    states = material_states(result)
    opts = result.options
    index = {lab: k for k, lab in enumerate(labels)}
    samples = np.asarray(samples, float).reshape(-1, len(labels))
    flags = np.zeros(samples.shape, np.int8)
    for t, row in enumerate(samples):
        trial = [dataclasses.replace(m, constants=dataclasses.replace(
            m.constants, **{k: float(row[index[f"{m.name}.{k}"]]) for k in m.free
                            if f"{m.name}.{k}" in index})) for m in states]
        for lab, hit in bounds_reached(trial, opts.nu_max, opts.bound_factor).items():
            if lab in index:
                flags[t, index[lab]] = -1 if hit.side == "lower" else 1
    return flags


_WORKER: dict = {}


def _processes(jobs, n_tasks: int) -> int:
    """Worker processes for ``n_tasks`` tasks: ``jobs`` (None or 0: the cores), at most one
    per task, at least one."""
    return max(1, min(int(jobs or os.cpu_count() or 1), n_tasks))


def _trial_pool_context():
    """The start method of the trials' worker processes: fork on Linux, where the workers
    inherit the model and its basis without pickling them (what every test and benchmark has
    run; Python 3.14 makes forkserver the default there), the platform's default elsewhere
    (spawn on macOS and Windows)."""
    import multiprocessing
    import sys

    if sys.platform.startswith("linux"):
        return multiprocessing.get_context("fork")
    return None


def _stops_with_parent() -> None:
    """Pool worker set-up (the Monte Carlo trials', the profiles'): SIGTERM ends the worker at
    once, and so does the death of the process that started it (atomic.stop_with_parent):
    an identify or batch -j 1 killed with SIGKILL during hybrid CM's profiles left both
    workers waiting for work, for ever."""
    import signal

    from laminid_cli.atomic import stop_with_parent

    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    stop_with_parent(functools.partial(os._exit, 143))


def _init_worker(*init) -> None:
    """Pool worker set-up of the trials: the process's (:func:`_stops_with_parent`), then the
    trials' state (:func:`_set_worker`)."""
    _stops_with_parent()
    _set_worker(*init)


def _set_worker(fms, options, start, start_pairing, joint, basis_vectors=None, model=None,
                damping=False, names=()):
    """The trials' state, per process: the plates' forward models, the identify() route's bases
    (rebuilt here from their vectors, copied per trial) or the reduced trial model (shared by
    the trials: an enrichment copies it; its factorisation is redone once per process);
    ``damping``: the trials return their modes' energy shares (:func:`_run_trial`); ``names``:
    the materials of ``start`` (the result's material_names). The trials run in the calling
    process (the pilot's, all of them with one job) set this alone: the worker's process
    set-up there reset the caller's SIGTERM handler, made it die with its own parent and left
    a thread watching that parent, one more each run (a later HDF5 probe then started a new
    interpreter instead of forking: frf.store._fork_is_safe)."""
    from laminid_cli.reduced import ReducedBasis

    bases = (None if basis_vectors is None else
             [ReducedBasis.from_vectors(fm, V) for fm, V in zip(fms, basis_vectors)])
    _WORKER.clear()
    _WORKER.update(fms=list(fms), options=options, start=start, start_pairing=start_pairing,
                   joint=joint, bases=bases, model=model, damping=bool(damping),
                   names=tuple(names))


def _trial_fms(freqs):
    fms = []
    for fm, f in zip(_WORKER["fms"], freqs):
        meas = dataclasses.replace(fm.specimen.measured, freq=f)
        fms.append(dataclasses.replace(fm, specimen=dataclasses.replace(fm.specimen,
                                                                        measured=meas)))
    return fms


def _identify_trial(freqs, bases, prior_shift=None, held=None):
    """A trial through identify() / identify_joint() from the optimum with its basis (and the
    trial's draw of the prior, ``prior_shift``; its fixed constants at ``held``, {label: SI},
    instead of their values in the specimen file, as :func:`refit_held` holds them)."""
    from laminid_cli.identify import identify
    from laminid_cli.joint import identify_joint

    fms = _trial_fms(freqs)
    start = _WORKER["start"]
    if held:
        fms = [_holding(fm, held) for fm in fms]
        by = _by_material(held)
        start = [dataclasses.replace(c, **by[name]) if name in by else c
                 for name, c in zip(_WORKER["names"], start)]
    if bases is not None:                  # the bases hold the plate, not its frequencies
        bases = [b.copy() for b in bases]
    if _WORKER["joint"]:
        return identify_joint(fms, _WORKER["options"], start=start,
                              start_pairing=_WORKER["start_pairing"], basis=bases,
                              prior_shift=prior_shift)
    return identify(fms[0], _WORKER["options"], start=start,
                    start_pairing=_WORKER["start_pairing"][0],
                    basis=None if bases is None else bases[0], prior_shift=prior_shift)


def _by_material(values) -> dict[str, dict[str, float]]:
    """{label "material.constant": SI} -> {material: {constant: SI}}: the updates of each
    material's constants (the trial model's, a start's, a specimen's)."""
    out: dict[str, dict[str, float]] = {}
    for lab, v in values.items():
        name, k = lab.rsplit(".", 1)
        out.setdefault(name, {})[k] = float(v)
    return out


def _holding(fm, held: dict):
    """``fm`` whose specimen has the constants of ``held`` ({label: SI}) as their values (a
    fixed constant is held at the specimen's value)."""
    spec = fm.specimen
    mats = {name: dataclasses.replace(mat, constants=dataclasses.replace(mat.constants, **upd))
            for name, upd in _by_material(held).items()
            if (mat := spec.materials.get(name)) is not None}
    if mats:
        spec = dataclasses.replace(spec, materials={**spec.materials, **mats})
    return dataclasses.replace(fm, specimen=spec)


def _run_trial(args):
    """One re-identification from perturbed frequencies: (index, values or None, message,
    relative eigenvalue bound of the trial's model or NaN, the first-order shift of its
    constants that the bound allows in standard errors (:meth:`TrialModel.shift_of`) or NaN,
    route, energy shares or None).

    The energy shares (n_measured, n_materials * 5; laminid_cli.damping.energy_shares) of
    the trial's paired modes at its constants are returned when the worker was told to
    (``damping``: a single plate with measured damping, whose loss factors each trial
    refits): from the trial model's basis energies of its accepted Ritz vectors
    (:attr:`TrialModes.energies`), or, for a trial re-identified with identify(), from its
    result's paired modes."""
    from laminid_cli.errors import LaminidError

    index, freqs, labels, shift, held = args
    model = _WORKER.get("model")
    route, bound, moved = "identify", float("nan"), float("nan")
    consts, energies = None, None
    try:
        if model is not None:
            try:
                done = model.pilot.get(index)
                c, bound, moved, _, energies = done if done is not None else model.trial(
                    np.asarray(freqs[0], float),
                    np.asarray(model.fm.specimen.measured.weight, float), shift, held)
                consts = dict(zip(model.names, c))
                route = "reduced"
            except _TrialFailed as exc:
                log.info("trial %d: %s; identified again with identify()", index + 1, exc)
        if consts is None:
            bases = _WORKER["bases"]
            if bases is None and model is not None:
                bases = [model.basis]          # it holds the first-order mode changes
            r = _identify_trial(freqs, bases, shift, held)
            if not r.converged:
                return index, None, r.status, bound, moved, route, None
            consts = {n: c for n, c in zip(r.material_names, r.constants)}
            eb = getattr(r, "error_bound", None)
            bound = float(np.max(eb)) if eb is not None and np.size(eb) else float("nan")
            moved = float("nan")
            if _WORKER.get("damping"):
                energies = _WORKER["fms"][0].plate.basis_energies(r.phi_paired)
    except LaminidError as exc:
        return index, None, str(exc), bound, moved, route, None
    vals = [getattr(consts[lab.rsplit(".", 1)[0]], lab.rsplit(".", 1)[1]) for lab in labels]
    shares = None
    if _WORKER.get("damping") and energies is not None:
        from laminid_cli.damping import shares_of_energies

        names = _WORKER["fms"][0].material_names
        shares = shares_of_energies(energies, [consts[n] for n in names])
    return index, np.array(vals), "", bound, moved, route, shares


def _run_chunk(chunk):
    return [_run_trial(t) for t in chunk]


#: the largest chunk of trials sent to a worker at once
CHUNK_MAX = 16


def trial_chunks(trials: list, jobs: int) -> list:
    """``trials`` in chunks for ``jobs`` worker processes, in order, shrinking as they go
    (guided self-scheduling): each chunk a third of an equal share of what is left,
    ``len(left) // (3 jobs)``, between 1 and CHUNK_MAX. Large chunks first keep the traffic
    between the processes low; single trials at the end let the workers finish together.

    (Chunks of one size, min(16, n // (4 jobs)), left one worker idle at the end while the
    other finished its last chunk: 200 trials of S1.1, -j 2, one worker done at 3.33 s, the
    other at 3.50 s; one slow trial, ~70 ms with an enrichment, ends the run with this.)"""
    chunks = []
    k = 0
    while k < len(trials):
        size = max(1, min(CHUNK_MAX, (len(trials) - k) // (3 * max(1, jobs))))
        chunks.append(trials[k:k + size])
        k += size
    return chunks


def _basis_vectors(result):
    """The reduced basis vectors of each plate of ``result`` with the first-order mode changes
    at the optimum (None with the full solver): one factorisation per plate here for all
    trials, which then move the poorly determined constants far with few enrichments."""
    basis = getattr(result, "basis", None)
    if basis is None:
        return None
    bases = basis if isinstance(basis, list) else [basis]
    if any(b is None for b in bases):
        return None
    plates = result.specimens if hasattr(result, "specimens") else [result]
    out = []
    for b, plate in zip(bases, plates):
        b = b.copy()
        b.add_sensitivities(b.fm.plate.coefficients(plate.constants), plate.modes.phi)
        out.append(b.V)
    return out


def _trial_scale(plate, sigma: FrequencySigma, factor: float) -> tuple[float, float, np.ndarray]:
    """(tau2, bound, rel_sd) of a :class:`TrialModel` of ``plate`` (an Identification of one
    plate) with frequency sigmas ``sigma`` scaled by ``factor``: the mean squared weighted
    relative eigenvalue standard deviation (its Gauss-Newton scaling), the accepted relative
    eigenvalue bound (TRIAL_SHARE of the smallest, at most TRIAL_BOUND) and each mode's
    relative eigenvalue standard deviation 2 sigma_f / f."""
    w = np.asarray(plate.weight, float)
    f = np.asarray(plate.measured_hz, float)
    rel = 2 * np.nan_to_num(sigma.sigma_hz) * factor / np.nan_to_num(f, nan=1.0)
    tau2 = w * rel**2
    bound = min(TRIAL_BOUND, TRIAL_SHARE * float(np.min(rel[w > 0])))
    return float(np.mean(tau2[w > 0])), bound, rel


def _prior_draw(z: float, row_sd: float, wp: float) -> float:
    """A trial's draw of a prior value's relative shift: ``z`` standard normal, the prior's
    row noise ``row_sd`` (sigma_unit, times the trial's variance factor), weight ``wp``: the
    value's relative standard deviation is row_sd / sqrt(wp) (module docstring); 0 for a
    weight of 0 (no row)."""
    wp = float(wp)
    return float(z * row_sd / np.sqrt(wp)) if wp > 0 else 0.0


def monte_carlo(result, fms, sigmas, uncertainty: Uncertainty, n_trials: int, *,
                jobs: int | None = None, seed: int = 0, progress=None,
                method: str = "auto", fixed_draw: FixedDraw | None = None) -> MonteCarlo:
    """Re-identify ``n_trials`` times from frequencies perturbed by their uncertainties.

    Each trial draws f_i + sigma_f,i * sigma_factor * N(0, 1) for every measured mode of every
    plate (sigma_factor = sqrt(uncertainty.variance_factor)), starts at the optimum of
    ``result`` with its mode pairing, and keeps the free constants of converged runs (and,
    for a single plate with measured damping, the strain-energy shares of its paired modes
    at its constants: :attr:`MonteCarlo.energy_shares`). Trials run
    in ``jobs`` processes (default: the number of cores), in chunks; ``progress(done, total)``
    after each chunk. The perturbations come from ``numpy.random.default_rng(seed)`` in the
    calling process, so a result does not depend on ``jobs``.

    ``method``: "reduced" runs each trial on the optimum's :class:`TrialModel` (one plate,
    reduced solver; no factorisation per trial), "identify" through identify() /
    identify_joint() from the optimum with its basis, "auto" (default) the first where it
    applies. A reduced trial whose model does not reach its bound is run through
    identify().

    ``fixed_draw`` (:func:`fixed_draw_of`, with constants fixed because undetermined): each
    trial also draws those fixed values from the spread they had before fixing (row t of
    :meth:`FixedDraw.draw`, a random stream of its own, so the frequencies drawn are those
    of a Monte Carlo without it) and identifies the free constants at them
    (:attr:`MonteCarlo.fixed_samples`).
    """
    from concurrent.futures import ProcessPoolExecutor, as_completed

    if n_trials < 2:
        raise FitInputError(f"Monte Carlo needs at least 2 trials, got {n_trials}")
    if method not in ("auto", "reduced", "identify"):
        raise FitInputError(f"Monte Carlo method '{method}' unknown: auto, reduced, identify")
    t0 = time.perf_counter()
    joint = hasattr(result, "specimens")
    parts = _parts(result, fms)
    sigmas = [sigmas] if isinstance(sigmas, FrequencySigma) else list(sigmas)
    factor = float(np.sqrt(uncertainty.variance_factor))
    rng = np.random.default_rng(seed)
    base = [np.asarray(plate.measured_hz, float) for _, plate in parts]
    # the prior's pseudo-measurements are drawn as the linearised covariance counts them
    # (noise sigma_unit on each row: module docstring), from a stream of their own
    # (a specimen without a prior draws the same frequencies as before)
    shift_sd = float(uncertainty.sigma_unit) * factor
    priors = [m for m in material_states(result) if m.prior] if shift_sd > 0 else []
    prng = np.random.default_rng(None if seed is None else [int(seed), 15])
    # with intervals on s2 (Student t), each trial also draws its variance factor
    g, nu = variance_draws(uncertainty, n_trials, seed)
    trials = []
    for i in range(n_trials):
        freqs = []
        for f, s in zip(base, sigmas):
            noise = rng.standard_normal(f.size) * np.nan_to_num(s.sigma_hz) * (factor * g[i])
            freqs.append(np.where(np.isfinite(f), f + noise, np.nan))
        # each prior value drawn with its own relative sd, shift_sd / sqrt(wp) (its row's
        # noise shift_sd: module docstring; a weight of 0 has no row, its draw no effect)
        shift = {m.name: {c: _prior_draw(prng.standard_normal(), shift_sd * g[i], wp)
                          for c, wp in m.prior.items() if c in m.free} for m in priors}
        trials.append((i, freqs, uncertainty.labels, shift, None))
    drawn, clipped = None, None
    if fixed_draw is not None and fixed_draw.labels:
        drawn, clipped = fixed_draw.draw(n_trials, seed)
        trials = [t[:4] + (dict(zip(fixed_draw.labels, map(float, drawn[t[0]]))),)
                  for t in trials]
    reducible = not joint and getattr(result, "basis", None) is not None
    if method == "reduced" and not reducible:
        raise FitInputError("the reduced Monte Carlo trials need a single-plate result of the "
                            "reduced solver")
    model = None
    if reducible and method != "identify":
        fm, plate = parts[0]
        tau2, limit, rel = _trial_scale(plate, sigmas[0], factor)
        model = TrialModel(fm, result, tau2, limit,
                           moved=() if drawn is None else fixed_draw.labels, rel_sd=rel)
        model.prepare([np.asarray(t[1][0], float) for t in trials[:TRIAL_PILOT]],
                      np.asarray(fm.specimen.measured.weight, float),
                      [t[3] for t in trials[:TRIAL_PILOT]],
                      [t[4] for t in trials[:TRIAL_PILOT]])
    # a single plate with measured damping: each trial returns its modes' energy shares, for
    # the loss factors' refits (laminid_cli.damping.monte_carlo_loss_factors)
    damped = (not joint and getattr(parts[0][0].specimen.measured, "damping", None)
              is not None)
    init = ([fm for fm, _ in parts], result.options, tuple(result.constants),
            [np.asarray(plate.pairing) for _, plate in parts], joint,
            None if model is not None else _basis_vectors(result), model, damped,
            tuple(result.material_names))
    jobs = _processes(jobs, n_trials)
    # the trials that the model's preparation finished (TrialModel.prepare) are collected
    # here, the others in the processes (all here with one job)
    pilot = model.pilot if model is not None else {}
    local = [t for t in trials if t[0] in pilot]
    trials = [t for t in trials if t[0] not in pilot]
    if jobs == 1:
        local, trials = local + trials, []
    out: list = [None] * n_trials
    failures = []
    bounds = np.full(n_trials, np.nan)
    shifts = np.full(n_trials, np.nan)
    routes: list = [""] * n_trials
    shares: list = [None] * n_trials
    done = 0

    def collect(results):
        nonlocal done
        for i, vals, msg, bound, moved, route, sh in results:
            out[i] = vals
            bounds[i], shifts[i], routes[i], shares[i] = bound, moved, route, sh
            if vals is None:
                failures.append(f"trial {i + 1}: {msg}")
            done += 1
        if progress is not None:
            progress(done, n_trials)

    if local:
        saved = dict(_WORKER)
        try:
            _set_worker(*init)
            for t in local:
                collect([_run_trial(t)])
        finally:
            _WORKER.clear()
            _WORKER.update(saved)
    if trials:
        chunks = trial_chunks(trials, jobs)
        with ProcessPoolExecutor(max_workers=jobs, initializer=_init_worker, initargs=init,
                                 mp_context=_trial_pool_context()) as pool:
            futures = [pool.submit(_run_chunk, c) for c in chunks]
            try:
                for fut in as_completed(futures):
                    collect(fut.result())
            except BaseException:
                for fut in futures:
                    fut.cancel()
                raise
    ok = [v for v in out if v is not None]
    converged = np.array([i for i, v in enumerate(out) if v is not None], int)
    trial_shares = (np.array([shares[i] for i in converged]) if damped and converged.size
                    and all(shares[i] is not None for i in converged) else None)
    p = len(uncertainty.labels)
    samples = np.array(ok) if ok else np.zeros((0, p))
    conf = uncertainty.confidence
    mean, std, lower, upper = sample_spread(samples, p, conf)
    lin = uncertainty.std
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = std / (lin * t_std(nu))
    if failures:
        log.info("Monte Carlo: %d of %d trials failed (%s)", len(failures), n_trials, failures[0])
    conv = np.array([v is not None for v in out])
    finite = bounds[conv & np.isfinite(bounds)]
    moved = shifts[conv & np.isfinite(shifts)]
    on_limit = trial_bound_flags(result, uncertainty.labels, samples)
    at_lower, at_upper = (on_limit < 0).sum(axis=0), (on_limit > 0).sum(axis=0)
    return MonteCarlo(labels=uncertainty.labels, n_trials=n_trials, n_converged=len(ok),
                      samples=samples, mean=mean, std=std, lower=lower, upper=upper,
                      linearized_std=lin, ratio=ratio, sigma_factor=factor, seed=seed, jobs=jobs,
                      time_s=time.perf_counter() - t0, failures=tuple(failures[:10]),
                      method="reduced" if model is not None else "identify",
                      trial_bound=float(finite.max()) if finite.size else float("nan"),
                      n_reidentified=sum(r == "identify" for r in routes) if model is not None
                      else 0,
                      trial_bound_limit=model.bound if model is not None else float("nan"),
                      trial_shift=float(moved.max()) if moved.size else float("nan"),
                      trial_shift_limit=model.shift_limit if model is not None
                      else float("nan"),
                      prior_sigma=shift_sd if priors else 0.0,
                      at_lower_bound=at_lower, at_upper_bound=at_upper, confidence=conf,
                      trial_at_bound=on_limit,
                      trials=converged, energy_shares=trial_shares, variance_dof=nu,
                      fixed_labels=() if drawn is None else fixed_draw.labels,
                      fixed_samples=None if drawn is None else drawn[converged],
                      fixed_clipped=0 if drawn is None else int(np.sum(clipped[converged])),
                      fixed_held=() if fixed_draw is None else fixed_draw.held)


#: the verdict of a constant whose Monte Carlo range is worse than its linearised interval
MC_MARK = " (Monte Carlo)"


def _verdict_rank(rel: float) -> int:
    """0 well determined, 1 weak, 2 not determined (NaN too): the band of
    :func:`laminid_cli.intervals.verdict`."""
    return (VERDICT_WELL, VERDICT_WEAK, VERDICT_NOT).index(verdict_of(rel, False))


def monte_carlo_verdict(rel_sure: float, rel_interval: float, not_words: str = "") -> str:
    """The verdict that the Monte Carlo range's width for sure ``rel_sure`` sets when it falls
    in a worse band than the interval's ``rel_interval`` ("" when it does not): that band's
    words marked :data:`MC_MARK` ("weak (Monte Carlo)", "not determined by these modes (Monte
    Carlo) — fix it ..."). ``not_words`` replaces :data:`VERDICT_NOT`'s head (the loss
    factors' own words). The rule of :func:`with_monte_carlo` and
    :func:`laminid_cli.damping.with_monte_carlo_damping`."""
    if not np.isfinite(rel_sure) or _verdict_rank(rel_sure) <= _verdict_rank(rel_interval):
        return ""
    words = verdict_of(rel_sure, False)
    if not_words:
        words = words.replace(VERDICT_NOT, not_words)
    head, _, tail = words.partition(" — ")
    return head + MC_MARK + (" — " + tail if tail else "")


def with_monte_carlo(u: Uncertainty, mc: MonteCarlo) -> Uncertainty:
    """``u`` with the verdicts the Monte Carlo makes worse. The linearised interval assumes
    the frequencies are linear in the constants over it; where the trials show a wider spread
    (a curved or flat valley, a second minimum, a limit of the search within reach), the narrow
    interval is not what a lab should act on.

    The evidence is the Monte Carlo range's relative half-width ``(upper - lower) / 2 /
    |value|``, taken at what the trials show for sure: the range between the order statistics
    that lie inside its two quantiles with probability >= :data:`MC_EVIDENCE` each
    (:meth:`MonteCarlo.inner_range`; the range is at least that wide with probability >= 90
    %). Where that width falls in a worse band (:data:`WELL_DETERMINED`, :data:`WEAK`) than
    the linearised interval, the constant gets that band's verdict marked "(Monte Carlo)",
    and it is flagged where that width is above ``max_rel_interval``. So a range that is wider
    only by the sampling noise of a few trials in its tails does not change a verdict (S1.4's
    nu12, 8x8, 40 trials: ±32 % with seed 0 and ±24-26 % with seeds 1-5 about a linearised
    ±29 %); 40 trials move a verdict only where the range is about 1.5 times the band's
    limit, 200 where it is about 1.15 times.

    The Monte Carlo never improves a verdict: its range is cut by the search's limits, where
    the linearised interval is not. Constants at a bound keep theirs. The intervals stay the
    linearised ones (the Monte Carlo range is reported beside them). Sets
    ``mc_rel_half_width`` (the range's own width) and ``mc_rel_half_width_lower`` (the width
    the verdicts use) per label."""
    index = {lab: k for k, lab in enumerate(mc.labels)}
    p = len(u.labels)
    rel_mc, rel_lo = np.full(p, np.nan), np.full(p, np.nan)
    inner_lo, inner_hi = mc.inner_range()
    for k, lab in enumerate(u.labels):
        j = index.get(lab)
        if j is not None and mc.n_converged >= 2:
            with np.errstate(divide="ignore", invalid="ignore"):
                rel_mc[k] = 0.5 * (mc.upper[j] - mc.lower[j]) / abs(u.value[k])
                rel_lo[k] = 0.5 * (inner_hi[j] - inner_lo[j]) / abs(u.value[k])
    at_bound = (np.zeros(p, bool) if u.at_bound is None else np.asarray(u.at_bound, bool))
    verdict, flagged, changed = list(u.verdict), list(u.flagged), []
    limit = u.thresholds["max_rel_interval"]
    for k, lab in enumerate(u.labels):
        if at_bound[k] or not np.isfinite(rel_lo[k]):
            continue
        worse = monte_carlo_verdict(rel_lo[k], u.rel_half_width[k])
        if worse:
            prior = HELD_BY_PRIOR if verdict[k].endswith(HELD_BY_PRIOR) else ""
            verdict[k] = worse + prior
            changed.append(lab)
        if rel_lo[k] > limit and lab not in flagged:
            flagged.append(lab)
    flagged = [lab for lab in u.labels if lab in flagged]
    return dataclasses.replace(u, verdict=tuple(verdict), flagged=tuple(flagged),
                               mc_rel_half_width=rel_mc, mc_rel_half_width_lower=rel_lo,
                               verdict_from_monte_carlo=tuple(changed))


# ----------------------------------------------------------------------------------------------
# the doubt of the constants --fix-undetermined fixed


def counting_fixed_spread(u: Uncertainty, before: Uncertainty, obs, materials,
                          nu_max: float = 0.95, moves=None) -> Uncertainty:
    """``u`` (the uncertainty of a run with constants fixed because undetermined) with the
    doubt of those fixed values counted (a "consider" covariance).

    ``obs``: the run's :class:`Observations` over ``u.labels + u.fixed`` (free, then fixed
    columns); ``materials``: its :class:`MaterialState` (values, priors); ``before``: the
    uncertainty of the run before fixing (all of the fixed-because-undetermined constants
    free there).

    The free constants' estimate depends on the fixed values f: to first order
    ``dP = S df`` (:func:`fixed_value_regression`); with ``moves`` = (DP, DF) from
    :func:`fixed_spread_moves` (what :func:`assess` uses) the count is made of secants
    instead, ``C + DP DP^T``, cross-covariance ``DP DF^T``, C_f ``DF DF^T``. A fixed value is
    as uncertain as the modes left it before it was fixed: its covariance C_f is ``before``'s, relative for moduli (their
    intervals are on ln P: the relative spread is kept at the fixed value), absolute for
    nu12. The free constants' covariance becomes ``C + S C_f S^T``; they share ``S C_f`` with
    the fixed ones (``spread_cross``, which the laminate properties use). For a linear model
    whose row weights follow the frequencies' noise (the default) this is exactly the
    covariance of the run before fixing: fixing an undetermined constant
    at an assumed value gives a stable point, not a better-known one. The intervals given the
    fixed values alone stay in ``rel_half_width_given_fixed``.

    A fixed constant with no finite spread before (at a limit of the search, or in a direction
    the modes do not see) is not counted (``spread_not_counted``; a note says the intervals are
    given its value). Constants fixed by the user are not counted either: their values are
    the user's statement.
    """
    if not any(lab in before.labels for lab in u.fixed):
        return u
    counted, missing, _, Cf = _fixed_spread(u, before, materials)
    notes = u.notes + ((_not_counted_note(missing),) if missing else ())
    if not counted:
        return dataclasses.replace(u, spread_not_counted=missing, notes=notes)
    labels = tuple(u.labels)
    p = len(labels)
    value = np.asarray(u.value, float)
    is_nu = np.array([lab.endswith(".nu12") for lab in labels], bool)
    inner = ~(np.zeros(p, bool) if u.at_bound is None else np.asarray(u.at_bound, bool))
    if moves is None:
        dP_df = fixed_value_regression(obs, materials, labels,
                                       [p + list(u.fixed).index(lab) for lab in counted], inner)
        cross = dP_df @ Cf                                 # Cov(P, f), SI
        add = cross @ dP_df.T
        add_stated = dP_df @ (Cf / (float(before.variance_factor)
                                    if before.variance_factor > 0 else 1.0)) @ dP_df.T
    else:
        # the moves along the fixed values' principal axes (fixed_spread_moves): secants of
        # identifications, not a tangent
        DP, DF = (np.asarray(x, float) for x in moves)
        cross, add, Cf = DP @ DF.T, DP @ DP.T, DF @ DF.T
        add_stated = add / (float(before.variance_factor) if before.variance_factor > 0
                            else 1.0)
    added = np.where(np.outer(inner, inner), add, 0.0)
    cov = np.asarray(u.covariance, float) + added
    std_u = np.asarray(u.std, float)
    with np.errstate(invalid="ignore"):
        std = np.where(np.isfinite(std_u), np.sqrt(np.clip(np.diag(cov), 0, None)), std_u)
    # the same from the stated frequency sigma alone (each run's covariance without its own
    # variance factor), as std_stated is without the spread
    f_u = float(u.variance_factor) if u.variance_factor > 0 else 1.0
    var_stated = np.diag(np.asarray(u.covariance, float)) / f_u + np.where(
        inner, np.diag(add_stated), 0.0)
    st_u = np.asarray(u.std_stated, float)
    with np.errstate(invalid="ignore"):
        std_stated = np.where(np.isfinite(st_u), np.sqrt(np.clip(var_stated, 0, None)), st_u)
    # the two parts are known with different degrees of freedom: the final run's noise with
    # its own (Student t where scaled by its s2), the spread with the run before fixing's;
    # each constant's quantile is Student t with their Welch-Satterthwaite combination
    from laminid_cli.intervals import effective_dof, quantiles_of

    nu_s = variance_dof(before)
    nu_eff = effective_dof(np.diag(np.asarray(u.covariance, float)), variance_dof(u),
                           np.diag(added), nu_s)
    q = quantiles_of(u.confidence, nu_eff)
    half = q * std
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rel = np.where(value != 0, half / np.abs(value), np.inf)
        s_ln = np.where(is_nu, np.nan, std / np.abs(value))
        lower = np.where(is_nu, np.clip(value - half, -nu_max, nu_max), value * np.exp(-q * s_ln))
        upper = np.where(is_nu, np.clip(value + half, -nu_max, nu_max), value * np.exp(q * s_ln))
        corr = cov / np.outer(std, std)
    rel[~inner] = np.inf
    lower[~inner], upper[~inner] = np.nan, np.nan
    corr[~np.isfinite(corr)] = np.nan
    np.fill_diagonal(corr, 1.0)
    verdict, flagged = list(u.verdict), set(u.flagged)
    for j, lab in enumerate(labels):
        if inner[j]:
            verdict[j] = verdict_of(rel[j], False) + (
                HELD_BY_PRIOR if u.verdict[j].endswith(HELD_BY_PRIOR) else "")
            if not rel[j] <= u.thresholds["max_rel_interval"]:
                flagged.add(lab)
    return dataclasses.replace(
        u, std=std, std_stated=std_stated, half_width=half, lower=lower, upper=upper,
        rel_half_width=rel, covariance=cov, correlation=corr, verdict=tuple(verdict),
        flagged=tuple(lab for lab in labels if lab in flagged), notes=notes,
        rel_half_width_given_fixed=np.asarray(u.rel_half_width, float),
        spread_counted=tuple(counted), spread_cross=cross, spread_covariance=Cf,
        spread_not_counted=missing, spread_free=added, spread_dof=nu_s,
        effective_dof=np.asarray(nu_eff, float), quantile_per_label=q)


def _fixed_spread(u: Uncertainty, before: Uncertainty, materials):
    """(counted, not counted, values, C_f) of the constants fixed because undetermined
    (:func:`counting_fixed_spread`): the labels whose spread before fixing is finite and their
    covariance then (SI; moduli's relative spread kept at the fixed value, nu12's absolute),
    the labels without one (at a limit of the search, or unseen), the fixed values (SI)."""
    bi = {lab: k for k, lab in enumerate(before.labels)}
    fixed = [lab for lab in u.fixed if lab in bi]
    b_at = (np.zeros(len(before.labels), bool) if before.at_bound is None
            else np.asarray(before.at_bound, bool))
    b_std = np.asarray(before.std, float)
    counted = [lab for lab in fixed if not b_at[bi[lab]] and np.isfinite(b_std[bi[lab]])]
    missing = tuple(lab for lab in fixed if lab not in counted)
    fval = _label_values(materials, counted)
    kb = [bi[lab] for lab in counted]
    ratio = np.where([lab.endswith(".nu12") for lab in counted], 1.0,
                     np.abs(fval / np.asarray(before.value, float)[kb])) if kb else np.zeros(0)
    Cf = (np.nan_to_num(np.asarray(before.covariance, float)[np.ix_(kb, kb)])
          * np.outer(ratio, ratio))
    return counted, missing, fval, Cf


#: the random stream of the fixed values' draws in a Monte Carlo (:meth:`FixedDraw.draw`):
#: ``numpy.random.default_rng([seed, FIXED_STREAM])``, of its own, so that the frequencies
#: (stream ``seed``), the priors' (``[seed, 15]``) and the measured damping's (``[seed, 16]``)
#: draws are what they are without it
FIXED_STREAM = 17


@dataclass(frozen=True)
class FixedDraw:
    """How the Monte Carlo trials draw the values --fix-undetermined fixed (:func:`fixed_draw_of`).

    labels : the fixed constants drawn (``spread_counted`` of :func:`counting_fixed_spread`)
    value : (k,) their fixed values, SI
    covariance : (k, k) their covariance before fixing (C_f of :func:`_fixed_spread`, SI:
        moduli's relative spread kept at the fixed value, nu12's absolute)
    lower, upper : (k,) the search's range, SI (initial / bound_factor .. x bound_factor for a
        modulus, +-nu_max for nu12): a draw beyond it is shortened to it (:meth:`draw`)
    held : the constants fixed because undetermined that are not drawn (fixed on a limit of
        the search: their doubt is not known)
    """

    labels: tuple[str, ...]
    value: np.ndarray
    covariance: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    held: tuple[str, ...] = ()

    def draw(self, n: int, seed) -> tuple[np.ndarray, np.ndarray]:
        """(values (n, k) SI, clipped (n,) bool): ``n`` draws of the fixed values in the
        variables the secant count uses (:func:`fixed_spread_moves`): z = ln P for a modulus,
        nu12 itself, z ~ N(z0, C_z) with C_z = C_f over the values (correlations included;
        its square root from the eigen-decomposition, so a singular C_f draws along its
        range). A draw z0 + dz that would leave the search's range is shortened to its edge
        along dz, as the secant count shortens its steps (``clipped``: the row was); clipping
        each value on its own would move a draw off its direction (it keeps the correlation
        no worse). On S1.1 (12x12) ln G13 and ln G23 have standard deviations 0.79 and 1.42
        before fixing, correlation -0.94, and the range is +-ln 5 = 1.61: a quarter of the
        draws leave it, and the correlation of the draws is -0.91 shortened or clipped one
        by one; E1's share of their spread (E1 linear in the draws, the tangent) is 1.66 GPa
        shortened, 1.44 GPa clipped one by one (2.05 GPa unbounded; the secant count: 1.82
        GPa), E2's 0.24 and 0.31 GPa (0.25 unbounded).
        Row t depends on the seed and t only (stream ``[seed, FIXED_STREAM]``)."""
        z0, lo, hi, lam, V = self.z_space()
        root = V * np.sqrt(np.clip(lam, 0.0, None))
        rng = np.random.default_rng(None if seed is None else [int(seed), FIXED_STREAM])
        dz = rng.standard_normal((int(n), z0.size)) @ root.T
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(dz > 0, (hi - z0) / dz, np.where(dz < 0, (lo - z0) / dz, np.inf))
        alpha = np.clip(np.min(room, axis=1, initial=np.inf), 0.0, 1.0)
        z = np.clip(z0 + alpha[:, None] * dz, lo, hi)        # (the clip: round-off only)
        return self.values(z), alpha < 1

    @property
    def nu(self) -> np.ndarray:
        """(k,) True for a Poisson ratio (linear), False for a modulus (ln P)."""
        return np.array([lab.endswith(".nu12") for lab in self.labels], bool)

    def z_space(self):
        """(z0, lo, hi, lam, V): the fixed values, the search's range and the eigen-
        decomposition C_z = V diag(lam) V^T of their covariance in the variables z of the
        draws and of the secant count (:func:`fixed_spread_moves`): ln P for a modulus (C_f
        over the values), nu12 itself."""
        nu, v = self.nu, np.asarray(self.value, float)
        sc = np.where(nu, 1.0, np.abs(v))                  # SI per unit of z at the value
        Cz = np.asarray(self.covariance, float) / np.outer(sc, sc)
        lam, V = np.linalg.eigh((Cz + Cz.T) / 2)
        z0 = np.where(nu, v, np.log(np.abs(v)))
        lo = np.where(nu, self.lower, np.log(np.abs(self.lower)))
        hi = np.where(nu, self.upper, np.log(np.abs(self.upper)))
        return z0, lo, hi, lam, V

    def values(self, z) -> np.ndarray:
        """The fixed values (SI) at ``z`` (:meth:`z_space`'s variables; rows or one point)."""
        return np.where(self.nu, z, np.sign(self.value) * np.exp(z))


def fixed_draw_of(u: Uncertainty, before: Uncertainty, result) -> FixedDraw | None:
    """The :class:`FixedDraw` of the constants --fix-undetermined fixed in ``result`` (``u``
    its uncertainty given the fixed values, ``before`` the run's before fixing), with the
    C_f and the range of the secant count (:func:`_fixed_spread`,
    :func:`fixed_spread_moves`); None when no fixed value has a spread to draw."""
    materials = material_states(result)
    counted, missing, fval, Cf = _fixed_spread(u, before, materials)
    if not counted:
        return None
    options = result.options
    nu = np.array([lab.endswith(".nu12") for lab in counted], bool)
    init = np.abs(_label_values(materials, counted, "initial"))
    bf = options.bound_factor
    lower = np.where(nu, -options.nu_max, init / bf)
    upper = np.where(nu, options.nu_max, init * bf)
    return FixedDraw(tuple(counted), np.asarray(fval, float), Cf, lower, upper, tuple(missing))


#: the fixed values' principal axes shorter than this share of the longest are not moved along
SPREAD_AXIS_MIN = 1e-6


def fixed_spread_moves(u: Uncertainty, before: Uncertainty, result, fms, sigmas, kw: dict,
                       joint: bool, progress=None):
    """(DP, DF): the moves of the free constants (p, a) and of the fixed values (k, a), SI,
    along each principal axis of the fixed values' spread before fixing (C_f of
    :func:`_fixed_spread`, on ln P for moduli): the others identified again with the fixed
    values at +- one standard deviation along the axis, the secant's half. A step that would
    leave the search's factor range (initial / bound_factor .. initial x bound_factor for a
    modulus, +-nu_max for nu12) is shortened to stay in it: an undetermined constant's
    spread (S1.3's G13: +-60 times in ln G) counts only as far as the search would go. The
    secants, not the tangent of :func:`fixed_value_regression`: over such spreads the
    constants' response bends (E1 does not fall without end as G13 grows). None where an
    identification fails (the first-order count is used then). ``progress(done, total)``
    before each identification (S1.1 at 16x16: six, 1.1 s)."""
    draw = fixed_draw_of(u, before, result)
    if draw is None:
        return None
    z0, lo, hi, lam, V = draw.z_space()
    DP, DF = [], []
    axes = np.flatnonzero(lam > SPREAD_AXIS_MIN * max(lam.max(), 0.0))
    for n, i in enumerate(axes):
        d = np.sqrt(lam[i]) * V[:, i]
        # the step is taken either way: each component needs room on both of its sides
        nz = d != 0
        alpha = min(1.0, float(np.min(np.minimum(hi - z0, z0 - lo)[nz] / np.abs(d[nz]))))
        if not alpha > 0:
            continue
        ends = []
        for sign in (1.0, -1.0):
            f = draw.values(z0 + sign * alpha * d)
            if progress is not None:
                progress(2 * n + (sign < 0), 2 * len(axes))
            try:
                r, _ = refit_held(result, fms, sigmas, kw, joint,
                                  {lab: float(v) for lab, v in zip(draw.labels, f)})
            except (FitError, FitInputError, ModelError, SolverError):
                return None
            ends.append((_label_values(material_states(r), u.labels), f))
        DP.append((ends[0][0] - ends[1][0]) / 2)
        DF.append((ends[0][1] - ends[1][1]) / 2)
    if not DP:
        return None
    return np.column_stack(DP), np.column_stack(DF)


def fixed_value_regression(obs, materials, labels, fixed_cols, inner=None) -> np.ndarray:
    """(p, k) d P / d f (SI): how the free constants ``labels`` (the first p columns of the
    :class:`Observations` ``obs``) of an optimum move, to first order, when the constants of
    the columns ``fixed_cols`` are fixed at other values: the least-squares regression
    ``-G_P^+ G_f`` of the objective's rows (paper Eq. 17; the prior rows of Eq. 15 are on
    free constants, zero in the fixed columns) on the fixed columns. Gauss-Newton: the
    residuals' curvature is left out, as in the covariance (S1.1 with G13, G23, nu12 fixed:
    within 4 % of re-identifying with G13, G23 moved, 20-37 % with nu12 moved).
    ``inner`` (p,) bool: the constants not at a bound (held there: rows of zeros)."""
    labels = tuple(labels)
    p = len(labels)
    inner = np.ones(p, bool) if inner is None else np.asarray(inner, bool)
    cols = list(range(p)) + list(fixed_cols)
    rows = []
    for o in obs:
        ok = (np.asarray(o.weight) > 0) & np.isfinite(o.freq_hz)
        lam_m = (2 * np.pi * o.freq_hz[ok]) ** 2
        rows.append((np.sqrt(o.weight[ok]) / lam_m)[:, None] * o.dlam_dP[ok][:, cols])
    A = np.vstack(rows)
    mat_of = {m.name: m for m in materials}
    value = _label_values(materials, labels)
    for j, lab in enumerate(labels):
        name, const = lab.rsplit(".", 1)
        wp = float(mat_of[name].prior.get(const, 0.0))
        if wp > 0:
            P0 = float(getattr(mat_of[name].initial, const))
            row = np.zeros((1, A.shape[1]))
            row[0, j] = np.sqrt(wp) / (P0 if P0 != 0 else 1.0)
            A = np.vstack([A, row])
    # columns scaled as in linearized_uncertainty, for the pseudo-inverse's rank decision
    D = np.where([lab.endswith(".nu12") for lab in labels],
                 np.maximum(np.abs(value), NU_SCALE), np.abs(value))
    idx = np.flatnonzero(inner)
    out = np.zeros((p, len(cols) - p))
    if idx.size:
        out[idx] = -(np.linalg.pinv(A[:, idx] * D[idx], rcond=NULL_TOL) @ A[:, p:]) \
            * D[idx][:, None]
    return out


def drawn_fixed_note(mc: MonteCarlo, fixed, draw: FixedDraw, options) -> str:
    """The note of a Monte Carlo whose trials drew the values --fix-undetermined fixed
    (:class:`FixedDraw`): what was drawn, how, what was clipped, what stayed held."""
    one = len({x.rsplit(".", 1)[0] for x in fixed}) == 1

    def names(labels):
        return ", ".join(lab.rsplit(".", 1)[1] if one else lab for lab in labels)

    they = "they" if len(draw.labels) > 1 else "it"
    text = (f"each Monte Carlo trial drew the fixed {names(draw.labels)} from the spread {they} "
            "had before fixing (ln G for the moduli, linear for nu12, correlations included) and "
            "identified the others again at them: its ranges count that spread, as the "
            f"intervals do; a draw beyond the search's range (initial / "
            f"{options.bound_factor:g} .. x {options.bound_factor:g}, |nu12| <= "
            f"{options.nu_max:g}) was shortened to its edge, as the secant count's steps are "
            f"({mc.fixed_clipped} of {mc.n_converged} trials)")
    held = [lab for lab in fixed if lab not in draw.labels]
    if draw.held:
        text += ("; " + names(draw.held) + " (fixed on a limit of the search, or in a "
                 "direction the modes do not see: doubt not known) stayed held")
    user = [lab for lab in held if lab not in draw.held]
    if user:
        text += "; " + names(user) + " (fixed with --fix) stayed held"
    return text


def _not_counted_note(missing) -> str:
    return ("the intervals are given the fixed value of " + ", ".join(missing) + ": it was at "
            "a limit of the search (or in a direction the modes do not see) before it was "
            "fixed, so its doubt is not known and not counted")


# ----------------------------------------------------------------------------------------------
# constants on a limit of the search: how far the fit lets them go (profile of the fit)


#: the profile's bisection stops when its bracket is this narrow: in ln P for a modulus
#: (2 %), in nu12 itself for nu12
PROFILE_TOL = 0.02
#: at most this many identifications per bisection (after the one at the far end)
PROFILE_RUNS = 8
#: the most model evaluations of one identification of a profile (it starts at the optimum;
#: an unfinished one counts only where its rise, an upper bound, is below the threshold)
PROFILE_EVALUATIONS = 300
#: the same for the one fit between the limit and a far end the fit does not reject (the
#: check for a second valley): only a rise below the threshold is needed there, which an
#: unfinished fit proves as well (hybrid CM's glass E2: 283 evaluations, ~6 s, otherwise)
PROFILE_MID_EVALUATIONS = 100
#: the most evaluations of a profile's fit from the initial values (:func:`with_profiles`:
#: where the fit from the optimum rejects the value, and first where it gave the lower chi2
#: before): its rise, finished or an upper bound, mostly only needs to fall below the threshold
PROFILE_INITIAL_EVALUATIONS = 100
#: two fits of a profile's value from its two starts end in one valley when their rises agree
#: to this share of the threshold (finished both): its later rejections are not checked again
PROFILE_SAME = 1e-3
#: a profile's fit whose chi2 is below the limit's by more than this share of the threshold
#: (scaled) shows that the search stopped short of a better fit: no profile
PROFILE_BETTER = 0.05


class ProfileError(Exception):
    """Why a profile cannot be drawn (its statement, after "no profile: ")."""


#: where the optimum is no start (constants on other limits), a profile's identifications
#: start these fractions of the way to the initial values
PROFILE_STEPS = (0.0, 1e-3, 1e-2, 0.1, 1.0)


@dataclass(frozen=True)
class Profile:
    """How far a constant that stopped on a limit of the search can go before the fit rejects
    it: the other constants are identified again with it held at each value tried, and the
    chi2 of the fit (scaled as the intervals are: divided by their variance factor) is
    compared with the one at the limit. ``bound``: the value where the increase reaches
    ``threshold`` = q^2 (q the intervals' quantile: the same level as their ends), SI; NaN
    when it stays below that up to ``far``, the other end of the search (the modes do not
    determine the constant there). ``delta_far``: the increase at ``far``. ``text``: the
    statement. ``error``: why the profile could not be made ("" when it was); ``far`` and
    ``delta_far`` are NaN then: a profile that was not made reached no end (hybrid CM's
    glass G13 had ``far`` 18.5 GPa, the scan's planned end, where its bisection's fit
    failed at 0.00865 GPa)."""

    label: str
    side: str
    limit: float
    bound: float
    far: float
    delta_far: float
    threshold: float
    runs: int
    text: str
    error: str = ""

    def as_dict(self) -> dict:
        return {"bound": self.bound, "far": self.far, "delta_chi2_far": self.delta_far,
                "threshold": self.threshold, "runs": self.runs, "text": self.text,
                "error": self.error}


def _no_profile(label: str, side: str, limit: float, threshold: float, runs: int,
                error: str) -> Profile:
    """The :class:`Profile` of a constant whose profile could not be made (``error`` why): no
    bound and no far end (NaN: its scan reached nowhere that can be stated)."""
    return Profile(label, side, limit, np.nan, np.nan, np.nan, threshold, runs,
                   f"{PROFILE_NONE} {error}", error)


def _between(c, c0, step: float):
    """ElasticConstants ``step`` of the way from ``c`` to ``c0``."""
    if step == 0:
        return c
    return dataclasses.replace(c, **{k: (1 - step) * getattr(c, k) + step * getattr(c0, k)
                                     for k in CONSTANT_NAMES})


def _show(k: str, v: float) -> str:
    return f"{v:.3g}" if k == "nu12" else _gpa(v)


def _profile_far(k: str, side: str, limit: float, options, initial_c) -> float:
    """The other end of the profile's scan: for a modulus on its lower limit the search's
    upper factor limit (at least 10 times the limit), on an upper one its lower factor limit
    (limits of the search in the 'constants' parametrisation; the alphas bound only E1 so, and
    the others may go beyond: :func:`_profile_far_words`);
    for nu12 zero (a Poisson ratio beyond that is not a composite's). ``options``: the
    identification's (bound_factor); ``initial_c``: the material's initial ElasticConstants.
    E2 <= E1 (paper Eq. 22): a held E2 goes no higher than the initial E1, a held E1 no lower
    than the initial E2 (the identifications of the profile start from a specimen with the
    held value, which must keep E2 <= E1)."""
    if k == "nu12":
        return 0.0
    initial = abs(float(getattr(initial_c, k)))
    if side == "lower":
        far = max(initial * options.bound_factor, 10 * abs(limit))
        return min(far, float(initial_c.E1)) if k == "E2" else far
    far = min(initial / options.bound_factor, 0.1 * abs(limit))
    return max(far, float(initial_c.E2)) if k == "E1" else far


def _profile_far_words(k: str, side: str, limit: float, far: float, options,
                       initial_c) -> str:
    """Why the profile's scan of ``k`` ends at ``far`` (:func:`_profile_far`), for its
    statement: the scan is no search limit (the alphas bound only E1 by the factor: the
    others, and a Monte Carlo trial, may go further)."""
    if k == "nu12":
        return "a negative nu12 is no fibre ply's"
    initial = abs(float(getattr(initial_c, k)))
    f = options.bound_factor
    if k == "E2" and side == "lower" and far == float(initial_c.E1) and far < initial * f:
        return "the initial E1: E2 <= E1"
    if k == "E1" and side == "upper" and far == float(initial_c.E2) and far > initial / f:
        return "the initial E2: E2 <= E1"
    if side == "lower":
        return (f"{f:g} x the initial value" if far == initial * f else "10 x the limit")
    return f"the initial value / {f:g}" if far == initial / f else "the limit / 10"


def _limit(u: Uncertainty, j: int) -> tuple[str, float]:
    """(side, limit) of the search that constant ``j`` of ``u`` ended on (its value where the
    uncertainty does not store the limit)."""
    side = u.bound_side[j] if u.bound_side else ""
    return side, float(u.bound_limit[j]) if u.bound_limit is not None else float(u.value[j])


def profile_bound(label: str, side: str, limit: float, far: float, delta, threshold: float,
                  confidence: float = 0.95, quick=None, lenient=None,
                  far_words: str = "") -> Profile:
    """The :class:`Profile` of ``label`` from ``delta(value)``: the scaled increase of chi2
    with the constant held at ``value`` (one identification of the others per call). First
    the far end: below ``threshold`` there, the fit does not bound the constant within the
    search (``quick`` checks one point in between). Otherwise a bracketing search between the
    limit (increase 0) and the far end, on ln P for a modulus and nu12 itself, to
    :data:`PROFILE_TOL`: the secant of the increase's logarithm, safeguarded by bisection.
    ``lenient`` (the far end) and ``quick`` (the point in between) may accept a fit that
    stopped unfinished below the threshold (an upper bound of the rise); both default to
    ``delta``, which the bracketing search uses. ``far_words``: why the
    scan ends at ``far`` (:func:`_profile_far_words`), in a flat profile's statement: nothing
    beyond it was tried."""
    quick = delta if quick is None else quick
    lenient = delta if lenient is None else lenient
    k = label.rsplit(".", 1)[1]
    nu = k == "nu12"
    show = functools.partial(_show, k)
    to = (lambda t: limit + t * (far - limit)) if nu else (
        lambda t: limit * np.exp(t * np.log(far / limit)))
    direction = "above" if far > limit else "below"
    runs = 0

    def rise(v, delta=delta):
        # a fit better than the one on the limit: the search stopped short of it, and the
        # limit is no place to measure a rise from
        nonlocal runs
        d = float(delta(v))
        runs += 1
        if d < -PROFILE_BETTER * threshold:
            raise ProfileError(
                f"the fit is better with {k} = {show(v)} than on the limit (chi2 lower by "
                f"{-d:.3g}, scaled): the search stopped short of it; identify again from "
                "other initial values")
        return d

    try:
        d_far = rise(far, lenient)
        if not d_far >= threshold:
            # one fit in between too: a rise that is not monotonic (a second valley) is no
            # profile
            d_mid = rise(to(0.5), quick)
            if d_mid >= threshold:
                raise ProfileError(
                    f"chi2 rises by {d_mid:.3g} at {k} = {show(to(0.5))} but by {d_far:.3g} at "
                    f"{show(far)} (scaled; {threshold:.3g} rejects): the fit has a second "
                    "valley there")
            why = f": {far_words}" if far_words else ""
            text = (f"{PROFILE_FLAT} with {k} anywhere {direction} the limit "
                    f"{'up' if far > limit else 'down'} to {show(far)}, the end of the "
                    f"scan{why} (chi2 rises by {max(d_far, d_mid):.2g}; {threshold:.3g} would "
                    f"reject it at {confidence * 100:.0f} %; not tried beyond): the modes do "
                    f"not determine {k} there")
            return Profile(label, side, limit, np.nan, far, d_far, threshold, runs, text)
    except ProfileError as exc:
        return _no_profile(label, side, limit, threshold, runs, str(exc))
    # the bracket [a, b] in t (0: the limit, rise 0; 1: the far end), ``ra``/``rb`` the rises
    # there. The rise is steep and convex in t where a constant held across decades barely
    # matters over most of them (rise ~ c (P / L - 1), exponential in t): regula falsi on the
    # rise itself crept from the flat end by its 5 % floor (its 8 fits ended 10.8 % above the
    # crossing with c = 0.1, and at the far end itself for hybrid CM's glass G12). The secant
    # of the rise's logarithm is near linear there and for a quadratic rise alike (ln of
    # (t / s)^2); a bisection where one end has no positive rise (the limit) or where the
    # bracket did not halve in two steps
    a, ra, b, rb = 0.0, 0.0, 1.0, d_far
    span = 1.0 if nu else abs(np.log(far / limit))
    widths = [np.inf, np.inf]                 # the bracket's width before each step
    log_q = np.log(threshold)
    while runs < PROFILE_RUNS + 1 and (b - a) * span > PROFILE_TOL:
        w = b - a
        if w > 0.5 * widths[-2] or not ra > 0:
            t = 0.5 * (a + b)
        else:
            t = a + w * (log_q - np.log(ra)) / (np.log(rb) - np.log(ra))
            t = min(max(t, a + 0.05 * w), b - 0.05 * w)
        widths.append(w)
        try:
            r = rise(to(t))
        except ProfileError as exc:
            return _no_profile(label, side, limit, threshold, runs, str(exc))
        if r >= threshold:
            b, rb = t, r
        else:
            a, ra = t, r
    bound = float(to(b))
    text = (f"the fit rejects {k} {direction} {show(bound)} ({confidence * 100:.0f} %, profile: "
            f"the other constants identified again, within the search, with {k} held there)")
    if (b - a) * span > PROFILE_TOL:
        # its fits spent before the bracket narrowed to PROFILE_TOL: the bound is the bracket's
        # far side, true but not tight (hybrid CM's glass G12, 12x12: a rise of 0.30 at 16.7
        # GPa and 326 at 18.0, flat and then a cliff, each fit halving the bracket's log
        # width from 8.1: 18.5 GPa, the far end, after 8 fits); the near side is said too
        text += (f"; not rejected at {show(float(to(a)))}, the crossing between the two not "
                 f"narrowed further in {runs} fits")
    return Profile(label, side, limit, bound, far, d_far, threshold, runs, text)


def _identify_again(result, fms, opts, start, joint: bool, progress=None):
    """The plate(s) of ``fms`` identified with ``opts`` from ``start``, on a copy of
    ``result``'s reduced basis (one per plate when ``joint``): the refits of the profiles
    (:func:`refit_held`) and of the fixed values' check (:func:`_refit_releasing`).
    ``progress``: identify()'s, after each evaluation."""
    from laminid_cli.identify import identify
    from laminid_cli.joint import identify_joint

    bases = result.basis
    if joint:
        return identify_joint(list(fms), opts, progress, start=start,
                              basis=None if bases is None else [b.copy() for b in bases])
    return identify(fms[0], opts, progress, start=start,
                    basis=None if bases is None else bases.copy())


def _held_options(result, held: dict, max_evaluations: int):
    """The IdentifyOptions of ``result``'s refits with the constants of ``held`` held: fixed,
    at most ``max_evaluations``, a material that the result searched with the alphas searched
    in their region again (held constants make it the constants parametrisation, whose box
    would exclude an optimum with a shear modulus at 1e-4 E1: every refit of hybrid CM's
    profiles started from the initial values, 300 evaluations, in a region where its glass
    shear moduli could not go below 0.74 GPa)."""
    from laminid_cli.parametrization import alpha_floor

    options = result.options
    alpha = tuple((n, alpha_floor(c)) for n, c in zip(result.material_names, result.constants)
                  if result.parametrization.get(n) == "alpha")
    return dataclasses.replace(options, fix=tuple(options.fix) + tuple(held),
                               max_evaluations=min(options.max_evaluations, max_evaluations),
                               alpha_region=tuple(options.alpha_region) + alpha)


def refit_held(result, fms, sigmas, kw: dict, joint: bool, label, value=None,
               max_evaluations: int = PROFILE_EVALUATIONS, unconverged: bool = False,
               from_initial: bool = False, model=None, progress=None):
    """(result, uncertainty) of the others identified again with the constant ``label`` held
    at ``value`` (SI; or ``label`` a {label: value} of several): from ``result``'s optimum (a
    short walk; where other constants sit on a limit a run may not start from, E2 = E1
    exactly, a little towards the initial values), its basis, at most ``max_evaluations``, in
    ``result``'s search region (``alpha_region``); from the initial values (with ``value``)
    when ``from_initial``. FitError when that fit does not converge, unless ``unconverged``:
    then its best point is returned (``result.converged`` False), whose chi2 is an upper
    bound of the fit's. ``model``: the profile's reduced model (:func:`profile_model`), which
    a fit from the optimum tries first (:func:`refit_reduced`); identify() where it gives no
    answer, ``progress`` its own (after each evaluation)."""
    held = dict(label) if isinstance(label, dict) else {label: value}
    if model is not None and not from_initial:
        out = refit_reduced(model, result, fms, sigmas, kw, held, max_evaluations)
        if out is not None:
            return out
    names = tuple(result.material_names)
    fms_v = [_holding(fm, held) for fm in fms]
    opts = _held_options(result, held, max_evaluations)
    from laminid_cli.identify import FarStartError

    for step in (1.0,) if from_initial else PROFILE_STEPS:
        start = [_between(c, c0, step) for c, c0 in zip(result.constants, result.initial)]
        for lab, v in held.items():
            name, k = lab.rsplit(".", 1)
            m = names.index(name)
            start[m] = dataclasses.replace(start[m], **{k: v})
        try:
            r = _identify_again(result, fms_v, opts, start, joint, progress)
            break
        except FitInputError as exc:
            if step != PROFILE_STEPS[-1]:
                continue
            if isinstance(exc, FarStartError):
                # not the user's initial guess: the fit's own starts, with the value held
                where = ", ".join(f"{lab.rsplit('.', 1)[1]} = "
                                  f"{_show(lab.rsplit('.', 1)[1], v)}" for lab, v in held.items())
                raise exc.where(
                    f"with {where} held, at the initial values" if from_initial else
                    f"with {where} held, at every start tried from the optimum to the initial "
                    "values", f"the modes are too far from {where} for a fit to start there"
                ) from None
            raise
    if not r.converged and not unconverged:
        raise FitError(_not_converged(held, opts.max_evaluations))
    uc = uncertainty_of(r, fms_v if joint else fms_v[0], sigmas if joint else sigmas[0], **kw)
    return r, uc


def profile_model(result, fms, sigmas, u: Uncertainty, label: str):
    """The reduced model of the refits of ``label``'s profile from the optimum (a
    :class:`TrialModel` holding ``label``, ``profiled``), built as the Monte Carlo trials'
    (the same accepted eigenvalue bound and shift, from the frequency sigmas scaled by the
    variance factor of ``u``); None where there is none: a joint result or the full solver's
    (no reduced basis), or a model that cannot be made there (the refits then all go through
    identify())."""
    if hasattr(result, "specimens") or getattr(result, "basis", None) is None:
        return None
    fm, sigma = fms[0], sigmas[0]
    factor = float(u.variance_factor) if u.variance_factor > 0 else 1.0   # (as the profile)
    tau2, bound, rel = _trial_scale(result, sigma, float(np.sqrt(factor)))
    try:
        return TrialModel(fm, result, tau2, bound, rel_sd=rel, profiled=label,
                          iterations=PROFILE_GN_ITERATIONS,
                          ftol=PROFILE_FTOL * float(u.quantile) ** 2 * tau2,
                          step_iterations=PROFILE_STEP_ITERATIONS)
    except (FitError, ModelError, SolverError, np.linalg.LinAlgError) as exc:
        log.info("profile of %s: no reduced model (%s); its fits go through identify()",
                 label, exc)
        return None


def refit_reduced(model, result, fms, sigmas, kw: dict, held: dict,
                  max_evaluations: int = PROFILE_EVALUATIONS):
    """:func:`refit_held` from the optimum on the profile's reduced model (:func:`
    profile_model`; ``held`` its one constant, {label: SI}), started at the answer of its
    nearest value held before between the limit and this one where there is one (:func:`
    _nearer_answer`: hybrid CM's glass G23 held at 8.13 GPa after 7.68, 14 reduced
    evaluations instead of 136, the rise the same to 1e-3): Levenberg-Marquardt on the
    objective's residual rows (:meth:`TrialModel.solve`, as a Monte Carlo trial, the held
    value in place of the perturbed frequencies), accepted only where the full model's
    eigenvalue bound at its answer passes :meth:`TrialModel.accepts` (the basis enriched
    where it does not, and kept enriched for the profile's later values). Returns (result,
    uncertainty) as refit_held does, the result converged (its ``evaluations`` the reduced
    eigenproblems, ``error_bound`` the largest bound of its paired modes), the uncertainty
    from :func:`uncertainty_of` (its chi2 the profile's); or None where the fit gives no
    answer, for refit_held's identify() to take over: the optimum outside the search's limits
    with the value held, a measured mode more than the start's limit (``far_limit``) from
    the model there (identify() refuses such a start and says so), or a fit that does not
    converge or that the check does not accept. The result holds what the profile and
    uncertainty_of read: no modes, sensitivities, history or global properties (None, empty)."""
    from laminid_cli.forward import far_from_model, residuals_percent, weighted_rms

    t0 = time.perf_counter()
    (label, value), = held.items()
    fm = _holding(fms[0], held)
    freq = np.asarray(result.measured_hz, float)
    weight = np.where(np.isfinite(freq), np.asarray(result.weight, float), 0.0)
    opts = _held_options(result, held, max_evaluations)
    n0 = model.n_evaluations
    try:
        model.hold(held)
        start = model._start()
        if start is None:
            log.info("profile of %s at %.6g: the optimum is outside the search's limits there",
                     label, value)
            return None
        near = _nearer_answer(model, label, value)
        if near is not None and model.feasible(near):
            # the profile followed from the optimum: the answer at the nearest value held
            # between the limit and this one
            start = (near, model.modes(model.basis, near, model.Y_ref))
        if far_from_model(freq, np.sqrt(start[1].lam) / (2 * np.pi), weight,
                          opts.far_limit) is not None:
            return None
        a = model.solve(freq, weight, None, held, start)
    except (_TrialFailed, np.linalg.LinAlgError) as exc:
        log.info("profile of %s at %.6g: %s; identified again with identify()", label, value,
                 exc)
        return None
    n = model.n_evaluations - n0
    x, tm = a.x, a.model
    model.answers.append((value, np.array(x)))
    lam_meas = (2 * np.pi * np.nan_to_num(freq, nan=1.0)) ** 2
    res = model.rows(x, tm, lam_meas, weight)[0]
    U = a.basis.V @ tm.Y[:, tm.pairing]
    U /= np.sqrt(np.einsum("ij,ij->j", U, a.basis.M @ U))
    # the enriched basis and the factorisation made are kept: the profile's next values
    # are near this one
    if a.basis is not model.basis:
        model.basis = a.basis
        model._shared_basis_changed()
    if a.ref is not None and model.refs is not None:
        model.refs.append(a.ref)
    f_model = np.sqrt(tm.lam) / (2 * np.pi)
    residual = residuals_percent(freq, f_model)
    r = dataclasses.replace(
        result, specimen=fm.specimen, initial=fm.initial_constants,
        constants=model.constants(x), free={p.name: tuple(p.free) for p in model.params},
        parametrization={p.name: p.kind for p in model.params},
        variable_labels=model.labels, x=x, objective=float(res @ res), evaluations=n,
        converged=True, status=f"converged on the reduced model (eigenvalue bound "
        f"{a.bound:.1e}, {a.rounds} round{'s' if a.rounds > 1 else ''})",
        time_s=time.perf_counter() - t0, model_hz=f_model, pairing=tm.pairing,
        residual_percent=residual, rms_residual_percent=weighted_rms(residual, weight),
        modes=None, phi_paired=U, dlam_dx=tm.dlam_dx, sensitivity=None, history={},
        swaps=(), bounds_hit=(), warnings=(), global_properties={}, options=opts,
        error_bound=np.full(freq.size, a.bound), work={"reduced_evaluations": n}, basis=None)
    return r, uncertainty_of(r, fm, sigmas[0], **kw)


def _nearer_answer(model, label: str, value: float):
    """The design variables of the profile's reduced fit (:attr:`TrialModel.answers`) whose
    held value is the nearest to ``value`` strictly between the limit (the held constant's
    value at the optimum, where the first fits start) and ``value`` (in ln P for a modulus,
    nu12 itself), or None where none is: the next fit follows the profile out from the
    optimum, its start near its answer."""
    k = label.rsplit(".", 1)[1]
    f = (lambda v: v) if k == "nu12" else (lambda v: np.log(abs(v)))
    lo, hi = sorted((f(model.held_optimum), f(value)))
    near = [(abs(f(v) - f(value)), i) for i, (v, _) in enumerate(model.answers)
            if lo < f(v) < hi]
    return model.answers[min(near)[1]][1] if near else None


def _not_converged(held: dict, max_evaluations: int) -> str:
    where = ", ".join(f"{lab.rsplit('.', 1)[1]} = {_show(lab.rsplit('.', 1)[1], v)}"
                      for lab, v in held.items())
    return (f"the identification with {where} held did not converge in {max_evaluations} "
            "evaluations")


#: the profile of one constant, run in a forked worker (:func:`with_profiles`)
_PROFILE_JOB: dict = {}


def _profile_job(j: int):
    return _PROFILE_JOB["run"](j)


def with_profiles(u: Uncertainty, result, fms, sigmas, kw: dict, joint: bool, jobs=1,
                  progress=None, fit_progress=None) -> Uncertainty:
    """``u`` with a :class:`Profile` of each constant that stopped on a limit of the search
    (``profiles``; {} when none did). ``fms``/``sigmas``: the plates' forward models and
    frequency sigmas (lists); ``kw``: the interval settings of :func:`uncertainty_of`.
    ``jobs``: processes (None: the cores), one constant's profile each at a time (forked
    where the trials fork, :func:`_trial_pool_context`; else one after the other): hybrid
    CM's five, 0.9 to 9.5 s of CPU each (stop 44), 24 s one after the other. ``progress(done, total, label)``
    after each profile (and ``progress(0, total, None)`` before the first);
    ``fit_progress(label, n, text)`` before each fit of a profile, its n-th ("G12 = 7.68 GPa",
    "... from the initial values"), told from the workers through a pipe (hybrid CM's
    profiles make 5 to 12 fits of 0.2 to 0.5 s each). A single plate
    of the reduced solver makes each profile's fits from the optimum on a reduced model of its
    own (:func:`profile_model`, :func:`refit_reduced`: Levenberg-Marquardt, its answers checked
    against the full model), identify() where that gives no answer; the fits from the initial
    values go through identify()."""
    if u.at_bound is None or not np.any(u.at_bound):
        return u
    if not result.converged:
        # the rise would be measured from a point that is no optimum
        return dataclasses.replace(u, profiles={
            lab: Profile(lab, *_limit(u, j), np.nan, np.nan, np.nan, float(u.quantile) ** 2,
                         0, f"{PROFILE_NONE} the identification did not converge",
                         "not converged")
            for j, lab in enumerate(u.labels) if u.at_bound[j]})
    options = result.options
    threshold = float(u.quantile) ** 2
    factor = float(u.variance_factor) if u.variance_factor > 0 else 1.0
    names = tuple(result.material_names)
    prior = {ms.name: dict(ms.prior) for ms in material_states(result)}

    def profile_of(j: int) -> Profile:
        lab = u.labels[j]
        name, k = lab.rsplit(".", 1)
        m = names.index(name)
        initial = float(getattr(result.initial[m], k))

        unfinished = []
        fits = [0]
        # the reduced model of the fits from the optimum (:func:`refit_reduced`), made at the
        # first of them; [None] where none can be made
        reduced = []
        # which start goes first: the optimum, until the initial values' start gives the
        # lower chi2 at some value (hybrid CM's glass G12 from 6.8 GPa up: 300 unfinished
        # evaluations at chi2 79-490 from the optimum, 97 at 9.6-9.8 from the initial values)
        order = [False, True]
        # whether a rejection is checked from the other start: until both starts, finished,
        # end at the same chi2 (one valley: S2.1's G13 at every value; hybrid CM's glass
        # constants never)
        check = [True]

        def delta(v, name=name, k=k, lab=lab, initial=initial, unfinished=unfinished,
                  max_evaluations=PROFILE_EVALUATIONS, order=order, check=check,
                  reduced=reduced):
            def fit(from_initial):
                cap = min(max_evaluations, PROFILE_INITIAL_EVALUATIONS) if from_initial \
                    else max_evaluations
                fits[0] += 1
                text = f"{k} = {_show(k, v)}" + (" from the initial values" if from_initial
                                                  else "")
                tell(lab, fits[0], text)
                said = [time.perf_counter()]

                def evaluations(n, objective, rms, n_fit=fits[0], text=text):
                    # a fit of a few seconds (hybrid CM's glass G13 at 18.5 GPa: 4.8 s): its
                    # evaluations, four times a second at most
                    if time.perf_counter() - said[0] >= 0.25:
                        said[0] = time.perf_counter()
                        tell(lab, n_fit, f"{text}, evaluation {n}")
                if not from_initial and not reduced:
                    tell(lab, fits[0], f"{text}, building its reduced model")
                    reduced.append(profile_model(result, fms, sigmas, u, lab))
                model = reduced[0] if reduced and not from_initial else None
                if model is not None and fit_progress is not None:
                    model.step_progress = functools.partial(
                        lambda n_fit, text, t: tell(lab, n_fit, f"{text}, {t}"), fits[0], text)
                try:
                    r, uc = refit_held(result, fms, sigmas, kw, joint, lab, v,
                                       unconverged=True, max_evaluations=cap,
                                       from_initial=from_initial, model=model,
                                       progress=evaluations if fit_progress is not None
                                       else None)
                finally:
                    if model is not None:
                        model.step_progress = None
                chi2 = uc.chi2
                wp = prior.get(name, {}).get(k, 0.0)
                if wp > 0:
                    # held, the constant has no prior row in that fit; u.chi2 counted it
                    # (free): its row as linearized_uncertainty counts one, sqrt(wp) (v -
                    # P0) / P0 over sigma_unit (design_rows)
                    ref = initial if initial != 0 else 1.0
                    chi2 += wp * ((v - initial) / ref / uc.sigma_unit) ** 2
                return r, (chi2 - u.chi2) / factor

            first, second = order
            r, d = fit(first)
            if d >= threshold and check[0]:
                # a rejection may be a local minimum of the fit (a fit that does not reject
                # cannot be wrong that way): hybrid CM's glass E2 held at 0.9 GPa ended at a
                # rise of 14.6 from the optimum ("rejected"), below 0.9 from the initial values
                # (not rejected). A fit from the other start too; the lower chi2 is kept
                try:
                    r2, d2 = fit(second)
                    if r.converged and r2.converged and abs(d2 - d) <= PROFILE_SAME * threshold:
                        check[0] = False
                    elif d2 < d:
                        r, d = r2, d2
                        order.reverse()
                except FitInputError:
                    pass
            if not r.converged:
                # its best point's chi2 bounds the fit's from above: a rise below the
                # threshold says "not rejected" for sure (a better fit too); only a rise
                # above it needs the fit's end
                if d >= threshold:
                    raise FitError(_not_converged({lab: v}, r.options.max_evaluations)
                                   + f" (chi2 had risen by {d:.3g} when it stopped, scaled; "
                                   f"{threshold:.3g} rejects)")
                unfinished.append(r.options.max_evaluations)
            return d

        side, limit = _limit(u, j)
        far = _profile_far(k, side, limit, options, result.initial[m])
        try:
            # an unfinished fit tells a value is not rejected (its rise, an upper bound, below
            # the threshold) and nothing else; the point in between the limit and a far end
            # not rejected is checked with fewer evaluations (only "not rejected" is needed)
            p = profile_bound(lab, side, limit, far, delta, threshold, u.confidence,
                              far_words=_profile_far_words(k, side, limit, far, options,
                                                           result.initial[m]),
                              quick=functools.partial(
                                  delta, max_evaluations=PROFILE_MID_EVALUATIONS))
        except (FitError, ModelError, SolverError) as exc:
            p = _no_profile(lab, side, limit, threshold, 0, str(exc))
        if unfinished and not p.error:
            n = len(unfinished)
            caps = " and ".join(str(c) for c in dict.fromkeys(unfinished))
            p = dataclasses.replace(p, text=p.text + (
                f" ({n} of its {p.runs} identifications stopped at {caps} "
                f"evaluations: {'its' if n == 1 else 'their'} rise is an upper bound, enough "
                f"to say the fit does not reject {'that value' if n == 1 else 'those values'})"))
        return p

    todo = [j for j, b in enumerate(u.at_bound) if b]
    out = {}
    jobs = _processes(jobs, len(todo))
    context = _trial_pool_context() if jobs > 1 else None
    # the fits' progress: told at once in this process, through a pipe from forked workers
    # (drained between their results below)
    pipe = context.SimpleQueue() if context is not None and fit_progress is not None else None

    def tell(label, n, text):
        if pipe is not None:
            pipe.put((label, n, text))
        elif fit_progress is not None:
            fit_progress(label, n, text)

    def drain():
        while pipe is not None and not pipe.empty():
            fit_progress(*pipe.get())

    def done(j, p):
        out[u.labels[j]] = p
        if progress is not None:
            progress(len(out), len(todo), u.labels[j])

    if progress is not None and todo:
        progress(0, len(todo), None)
    if context is None:
        for j in todo:
            done(j, profile_of(j))
    else:
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

        # forked workers inherit the result, models and this closure (no pickling)
        _PROFILE_JOB["run"] = profile_of
        try:
            with ProcessPoolExecutor(max_workers=jobs, mp_context=context,
                                     initializer=_stops_with_parent) as pool:
                futures = {pool.submit(_profile_job, j): j for j in todo}
                pending = set(futures)
                while pending:
                    # (a quarter second at most between the fits' words and the terminal)
                    finished, pending = wait(pending, timeout=None if pipe is None else 0.25,
                                             return_when=FIRST_COMPLETED)
                    drain()
                    for fut in finished:
                        done(futures[fut], fut.result())
        finally:
            _PROFILE_JOB.clear()
            if pipe is not None:
                pipe.close()
    # in the constants' order, whichever finished first
    return dataclasses.replace(u, profiles={u.labels[j]: out[u.labels[j]] for j in todo})


@dataclass(frozen=True)
class FixedRange:
    """What a constant fixed by ``--fix-undetermined`` while it was on a limit of the search
    (its doubt unknown: not counted in the intervals) does to the others: they are identified
    again with it held at each end of the search (``low``, ``high``, SI), and the largest move
    of a free constant is compared with its half-width. ``moves``: some constant moves by more
    than its half-width (``worst``, ``ratio`` = move / half-width): its interval is given the
    fixed value, which is not known. ``error``: why the check could not be made."""

    label: str
    low: float
    high: float
    moves: bool
    worst: str
    ratio: float
    text: str
    error: str = ""

    def as_dict(self) -> dict:
        return {"low": self.low, "high": self.high, "moves": self.moves, "worst": self.worst,
                "ratio_to_half_width": self.ratio, "text": self.text, "error": self.error}


def with_fixed_ranges(u: Uncertainty, before: Uncertainty, result, fms, sigmas, kw: dict,
                      joint: bool) -> Uncertainty:
    """``u`` with a :class:`FixedRange` of each constant fixed at a limit of the search
    (``u.spread_not_counted``: its doubt is not known, so :func:`counting_fixed_spread` could
    not count it): the others identified again with it at the two ends of its profile's scan
    (the limit it was on before fixing, and :func:`_profile_far`)."""
    if not u.spread_not_counted:
        return u
    options = result.options
    names = tuple(result.material_names)
    half = np.asarray(u.half_width, float)
    value = np.asarray(u.value, float)
    out = {}
    for lab in u.spread_not_counted:
        name, k = lab.rsplit(".", 1)
        m = names.index(name)
        side, limit = _limit(before, list(before.labels).index(lab))
        far = _profile_far(k, side, limit, options, result.initial[m])
        low, high = sorted((limit, far))
        span = f"anywhere from {_show(k, low)} to {_show(k, high)}"
        try:
            moved = []
            for end in (low, high):
                r, _ = refit_held(result, fms, sigmas, kw, joint, lab, end)
                moved.append(np.abs(_label_values(material_states(r), u.labels) - value))
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(half > 0, np.maximum(*moved) / half, np.nan)
            ok = np.isfinite(ratio)
            if not ok.any():
                out[lab] = FixedRange(lab, low, high, False, "", np.nan,
                                      "not checked: no free constant has an interval")
                continue
            w = int(np.nanargmax(np.where(ok, ratio, -1.0)))
            worst, r_w = u.labels[w], float(ratio[w])
            rel = float(np.maximum(*moved)[w] / abs(value[w])) if value[w] else np.nan
            if r_w > 1:
                text = (f"{worst} moves by {rel * 100:.3g} % ({r_w:.1f} times its half-width) "
                        f"with {k} {span}: {k} was fixed on a limit of the search, its value "
                        f"is not known, and the intervals are given it")
            else:
                text = (f"with {k} {span} the others stay within their intervals ({worst} "
                        f"moves most: {r_w:.2g} of its half-width)")
            out[lab] = FixedRange(lab, low, high, r_w > 1, worst, r_w, text)
        except (FitError, FitInputError, ModelError, SolverError) as exc:
            out[lab] = FixedRange(lab, low, high, False, "", np.nan,
                                  f"not checked: {exc}", str(exc))
    return dataclasses.replace(u, fixed_ranges=out)


@dataclass(frozen=True)
class FixedCheck:
    """Do the modes reject the values ``--fix-undetermined`` fixed, taken together?

    Each fixed value is undetermined on its own, but together they may still be rejected: on
    S1.1, G13 = G23 = 3.10 GPa and nu12 = 0.35 raise chi2 from 2.21 to 18.2, where G13 and G23
    alone give 3.08 (nu12, free with them, goes to 0.17). The test is that of nested fits: the
    rise of chi2 from the run before fixing (``chi2_before``) to the final one (``chi2``), with
    k = the number of values fixed, against the chi-square quantile of k degrees of freedom
    (``test`` "chi2", the intervals of the run before fixing on the stated sigma) or k times
    the F quantile of (k, dof before) in units of that run's variance factor ("F", its s2
    estimated from the residuals, as Student's t replaces the normal quantile in its
    intervals), at the intervals' confidence. ``statistic`` is the rise in those units and
    ``limit`` the quantile; ``rejected``: statistic > limit.

    ``worst``/``moved``: the free constant that moved most between the two runs, in units of
    its half-width before fixing (above 1: out of that interval). ``release``: when rejected
    and k > 1, the fixed value whose release alone lowers chi2 most (the others identified
    again with it free), ``release_chi2`` that fit's chi2 and ``release_ok`` whether the
    others are then within their own limit (k - 1 values).
    """

    labels: tuple[str, ...]
    values: tuple[float, ...]
    chi2_before: float
    chi2: float
    test: str
    scale: float
    statistic: float
    limit: float
    confidence: float
    rejected: bool
    worst: str = ""
    moved: float = float("nan")
    release: str = ""
    release_chi2: float = float("nan")
    release_ok: bool = False

    @property
    def k(self) -> int:
        return len(self.labels)

    @property
    def text(self) -> str:
        return fixed_check_text(self)

    def as_dict(self) -> dict:
        return {"labels": list(self.labels), "values": list(self.values), "k": self.k,
                "chi2_before": self.chi2_before, "chi2": self.chi2, "test": self.test,
                "variance_factor_before": self.scale, "statistic": self.statistic,
                "limit": self.limit, "confidence": self.confidence,
                "rejected": self.rejected, "worst": self.worst,
                "moved_in_half_widths": self.moved, "release": self.release,
                "release_chi2": self.release_chi2, "release_ok": self.release_ok,
                "text": self.text}


def _rise_test(before: Uncertainty, k: int) -> tuple[str, float, float]:
    """(test, scale, limit) of a rise of chi2 over ``k`` values fixed (:class:`FixedCheck`)."""
    from laminid_cli.quantiles import chi2_ppf, f_ppf

    conf = float(before.confidence)
    nu = variance_dof(before)
    if np.isfinite(nu):
        return "F", float(before.variance_factor), k * f_ppf(conf, k, nu)
    return "chi2", 1.0, chi2_ppf(conf, k)


def with_fixed_check(u: Uncertainty, before: Uncertainty, fixed, result, fms, sigmas,
                     kw: dict, joint: bool) -> Uncertainty:
    """``u`` (the final run of ``--fix-undetermined``) with its :class:`FixedCheck`: do the
    modes reject the ``fixed`` values together? ``before``: the uncertainty of the run before
    fixing. ``fms``/``sigmas``/``kw``/``joint`` as :func:`with_profiles` (for the releases)."""
    fixed = tuple(fixed)
    k = len(fixed)
    if not k or not (np.isfinite(u.chi2) and np.isfinite(before.chi2)):
        return u
    names = tuple(result.material_names)
    values = tuple(float(getattr(result.constants[names.index(lab.rsplit(".", 1)[0])],
                                 lab.rsplit(".", 1)[1])) for lab in fixed)
    test, scale, limit = _rise_test(before, k)
    stat = (float(u.chi2) - float(before.chi2)) / scale
    rejected = bool(stat > limit)
    # how far the free constants moved, in their half-widths before fixing
    worst, moved = "", float("nan")
    for j, lab in enumerate(u.labels):
        if lab not in before.labels:
            continue
        i = list(before.labels).index(lab)
        h = float(before.half_width[i])
        if not (np.isfinite(h) and h > 0):
            continue
        m = abs(float(u.value[j]) - float(before.value[i])) / h
        if not m <= moved:
            worst, moved = lab, m
    release, release_chi2, release_ok = "", float("nan"), False
    if rejected and k > 1:
        for lab in fixed:
            try:
                r = _refit_releasing(result, fms, lab, joint)
            except (FitError, FitInputError, ModelError, SolverError):
                continue
            if not r.converged:
                continue
            c = float(uncertainty_of(r, fms if joint else fms[0],
                                     sigmas if joint else sigmas[0], **kw).chi2)
            if not c >= release_chi2:
                release, release_chi2 = lab, c
        if release:
            _, s1, l1 = _rise_test(before, k - 1)
            release_ok = bool((release_chi2 - float(before.chi2)) / s1 <= l1)
    return dataclasses.replace(u, fixed_check=FixedCheck(
        fixed, values, float(before.chi2), float(u.chi2), test, scale, stat, limit,
        float(before.confidence), rejected, worst, moved, release, release_chi2, release_ok))


def _refit_releasing(result, fms, label: str, joint: bool):
    """``result`` identified again with its fixed constant ``label`` free (from its optimum
    and basis; at most :data:`PROFILE_EVALUATIONS` evaluations)."""
    options = result.options
    opts = dataclasses.replace(options, fix=tuple(x for x in options.fix if x != label),
                               max_evaluations=min(options.max_evaluations,
                                                   PROFILE_EVALUATIONS))
    return _identify_again(result, fms, opts, list(result.constants), joint)


def fixed_check_text(c: FixedCheck) -> str:
    """The words of a :class:`FixedCheck` (the terminal, the status, the report)."""
    def short(lab):
        return lab.rsplit(".", 1)[1]

    vals = ", ".join(f"{short(lab)} = {_show(short(lab), v)}"
                     for lab, v in zip(c.labels, c.values))
    units = ("" if c.test == "chi2" else
             f" ({c.statistic:.3g} times s2 = {c.scale:.3g} of the run before fixing)")
    law = (f"chi-square, {c.k} degree{'s' if c.k > 1 else ''} of freedom" if c.test == "chi2"
           else f"{c.k} times the F quantile of {c.k} and the run's degrees of freedom")
    what = ("the values --fix-undetermined fixed, taken together" if c.k > 1 else
            "the value --fix-undetermined fixed")
    head = f"the modes {'reject' if c.rejected else 'do not reject'} {what}"
    text = (f"{head} ({vals}): fixing {'them' if c.k > 1 else 'it'} raised chi2 from "
            f"{c.chi2_before:.3g} to "
            f"{c.chi2:.3g}{units}; the {c.confidence * 100:.0f} % limit is {c.limit:.3g} "
            f"({law})")
    if c.worst:
        text += (f"; {short(c.worst)} moved {'out of' if c.moved > 1 else 'within'} its "
                 f"interval before fixing ({c.moved:.2g} of its half-width)")
    if c.rejected:
        if c.release:
            text += (f"; with {short(c.release)} free again chi2 is {c.release_chi2:.3g}"
                     + (" and the others are not rejected" if c.release_ok else ""))
        text += ": put values you know in the specimen file and --fix them"
        if c.release and c.release_ok:
            others = ",".join(lab for lab in c.labels if lab != c.release)
            text += (f", or identify with --fix {others} in place of --fix-undetermined "
                     f"({short(c.release)} free)")
    return text


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
    #: per label fixed by ``fix_undetermined``: (relative half-width, verdict, run) in the run
    #: that flagged it (the Monte Carlo's "for sure" width where that flagged it)
    fixed_widths: dict = field(default_factory=dict)
    #: per label flagged but not fixed by ``fix_undetermined``: why (fixing it at its initial
    #: value would move the others beyond their spread, :func:`_initial_rejected`)
    kept_free: dict = field(default_factory=dict)
    #: with constants fixed because undetermined whose spread is counted: the Monte Carlo
    #: whose trials held them (its flags decided what to fix, judged given the fixed values
    #: as the linearised flags are); ``monte_carlo`` is then the one whose trials drew them
    #: (:class:`FixedDraw`), with the same frequency draws. Its widths are in the summary
    #: (``monte_carlo.given_fixed``: --json and /summary_json), not in the typed datasets.
    monte_carlo_given_fixed: MonteCarlo | None = None


def assess(fms, options, uopts: UncertaintyOptions = UncertaintyOptions(), *,
           joint: bool = False, progress=None, mc_progress=None, accept=None,
           profile_progress=None, stage_progress=None) -> Assessment:
    """Identify (one plate, or several jointly), then compute the uncertainty; optionally fix
    the flagged constants and identify again (until nothing new is flagged), and run the
    Monte Carlo check on the final result (with ``fix_undetermined``, the constants its range
    flags (:func:`with_monte_carlo`) are fixed as well, and the assessment goes on from there).

    ``fms``: a ForwardModel, or a sequence of them with ``joint=True``. ``progress`` is passed to
    the identification, ``mc_progress(done, total)`` to :func:`monte_carlo`,
    ``profile_progress(done, total, label)`` to :func:`with_profiles`;
    ``stage_progress(text)`` before each step that says nothing of its own (the linearised
    intervals, an identification again by --fix-undetermined, the fixed values' checks) and
    at each fit of a profile ("profile of glass.G12 (1 of 5 done): fit 3, G12 = 7.68 GPa":
    hybrid CM's profiles take 1.4 to 3.4 s each, the fixed values' checks of S1.1 at 16x16
    1.1 s, with nothing said). ``accept(result)``
    is asked about the final result, before the Monte Carlo: False returns the assessment
    without it (``monte_carlo`` None), for a caller that will identify again (the pipeline,
    when the bending equations alone no longer describe the plate at the answer).
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

    def stage(text):
        if stage_progress is not None:
            stage_progress(text)

    fms_arg = fm_list if joint else fm_list[0]
    sig_arg = sigmas if joint else sigmas[0]
    result = run(options)
    stage("linearised intervals")
    unc = uncertainty_of(result, fms_arg, sig_arg, **kw)
    first = unc
    fixed: list[str] = []
    fixed_widths: dict = {}
    kept_free: dict = {}
    kept_run: dict = {}                   # the run whose values judged each of kept_free
    earlier = []
    runs = 1
    def to_fix(unc):
        """The flagged constants to fix now: not fixed yet, and not ones whose initial value
        would bias the others beyond their own spread (S1.2: G12 5.99 GPa +-32 %, initial
        3.10 GPa moved E1 by 6 %; :func:`_initial_rejected`, judged on the constants that
        stay determined). Those stay free (and undetermined), with why in ``kept_free``."""
        out = []
        for lab in unc.flagged:
            if lab in fixed or lab in kept_free:
                continue
            why = _initial_rejected(result, unc, lab, fixing=set(unc.flagged) | set(fixed))
            if why:
                kept_free[lab] = why
                kept_run[lab] = runs
            else:
                out.append(lab)
        return out

    mc = mc_given = None
    accepted = True
    while True:
        fixed_before = len(fixed)
        while uopts.fix_undetermined and (new := to_fix(unc)):
            if len(new) == len(unc.labels):

                done = "; ".join(f"run {w[2]}: {lab}" for lab, w in fixed_widths.items())
                raise FitError(
                    ("every free constant is undetermined by these modes" if not fixed else
                     f"after {runs} runs of --fix-undetermined, every constant left is "
                     "undetermined") + " (" + ", ".join(new) + (f" in run {runs}" if fixed
                                                                else "")
                    + "); nothing left to identify"
                    + (f" (fixed before: {done})" if done else "")
                    + ": measure more modes or a thicker plate, fix constants you know (--fix), "
                    "or raise --max-rel-interval")
            for lab in new:
                fixed_widths[lab] = _flagging_width(unc, lab, runs)
            fixed += new
            log.info("fixing undetermined constants at their initial values: %s", ", ".join(new))
            options = dataclasses.replace(options, fix=tuple(options.fix) + tuple(new))
            earlier.append(result)
            stage(_run_words(runs + 1, fixed))
            result = run(options, result.basis)      # the basis spans the path already walked
            runs += 1
            stage("linearised intervals")
            unc = uncertainty_of(result, fms_arg, sig_arg, **kw)
        if mc is not None and len(fixed) == fixed_before:
            break             # the Monte Carlo's flags fixed nothing: it stands for this result
        mc = None
        accepted = accept is None or accept(result)
        if not (uopts.monte_carlo and accepted):
            break
        mc = monte_carlo(result, fms_arg, sig_arg, unc, uopts.monte_carlo, jobs=uopts.jobs,
                         seed=uopts.seed, progress=mc_progress)
        linearised = unc
        unc = with_monte_carlo(unc, mc)
        # with --fix-undetermined, the constants the Monte Carlo range flags are fixed too and
        # the whole assessment runs again (its Monte Carlo included)
        if not uopts.fix_undetermined:
            break
    if fixed:
        # the fixed values are as uncertain as the modes left them: the final intervals count
        # that (the flags above were judged given the fixed values, so counting it does not
        # fix more constants); so does the Monte Carlo shown
        u0 = unc if mc is None else linearised
        obs = [observations(fm, plate, s, u0.labels + u0.fixed)
               for (fm, plate), s in zip(_parts(result, fms_arg), sigmas)]
        moves = fixed_spread_moves(
            u0, first, result, fm_list, sigmas, kw, joint,
            progress=lambda done, total: stage(
                f"the fixed values' spread: the others identified with them moved, {done} of "
                f"{total} done"))
        unc = counting_fixed_spread(u0, first, obs, material_states(result),
                                    result.options.nu_max, moves)
        if moves is None and unc.spread_counted:
            unc = dataclasses.replace(unc, notes=unc.notes + (
                "the fixed values' spread is counted to first order (a tangent): an "
                "identification with them moved along it failed; over a wide spread the "
                "tangent overstates it",))
        if mc is not None:
            draw = fixed_draw_of(u0, first, result) if unc.spread_counted else None
            if draw is not None:
                # the trials above held the fixed values (their flags decide what to fix,
                # judged given them as the intervals' are); the Monte Carlo shown draws
                # them from their spread before fixing (the same frequency draws), so that
                # its ranges count that spread as the intervals do
                mc_given = mc
                stage("Monte Carlo again, the fixed values drawn from their spread")
                mc = monte_carlo(result, fms_arg, sig_arg, unc, uopts.monte_carlo,
                                 jobs=uopts.jobs, seed=uopts.seed, progress=mc_progress,
                                 fixed_draw=draw)
            unc = with_monte_carlo(unc, mc)
            if draw is not None:
                unc = dataclasses.replace(unc, notes=unc.notes + (
                    drawn_fixed_note(mc, u0.fixed, draw, result.options),))
    if accepted:
        # how far the fit lets a constant on a search limit go (identifications of the
        # others with it held): only for the result that stands
        count = [0, 0]

        def profile_done(done, total, label):
            count[:] = [done, total]
            if profile_progress is not None:
                profile_progress(done, total, label)

        def profile_fit(label, n, text):
            stage(f"profile of {label} ({count[0]} of {count[1]} done): fit {n}, {text}")

        unc = with_profiles(unc, result, fm_list, sigmas, kw, joint, jobs=uopts.jobs,
                            progress=profile_done,
                            fit_progress=None if stage_progress is None else profile_fit)
        if fixed:
            if unc.spread_not_counted:
                stage("the fixed values on a search limit: the others identified with each "
                      "at its ends")
            unc = with_fixed_ranges(unc, first, result, fm_list, sigmas, kw, joint)
            if result.converged and (earlier[0].converged if earlier else True):
                # an unfinished fit's chi2 is only an upper bound of its minimum
                stage("do the modes reject the fixed values? the others identified with them "
                      "released")
                unc = with_fixed_check(unc, first, fixed, result, fm_list, sigmas, kw, joint)
    # a constant judged in an earlier run was judged on that run's values, not the ones shown
    kept_free = {lab: why if kept_run[lab] == runs else _judged_in_run(why, kept_run[lab])
                 for lab, why in kept_free.items()}
    return Assessment(result=result, uncertainty=unc, sigmas=sigmas,
                      fixed_undetermined=tuple(fixed), before_fixing=first if fixed else None,
                      monte_carlo=mc, runs=runs, earlier_results=tuple(earlier),
                      fixed_widths=fixed_widths, kept_free=kept_free,
                      monte_carlo_given_fixed=mc_given)


def _run_words(run: int, fixed) -> str:
    """The progress words of --fix-undetermined's identification ``run`` with the constants
    ``fixed`` (labels) held: "run 2, G13, G23 fixed as undetermined" (short names; the
    evaluation lines follow it)."""
    names = list(dict.fromkeys(lab.rsplit(".", 1)[1] for lab in fixed))
    shown = ", ".join(names[:4]) + (f" and {len(names) - 4} more" if len(names) > 4 else "")
    return f"run {run}, {shown} fixed as undetermined"


def _initial_rejected(result, u: Uncertainty, label: str, fixing=()) -> str:
    """Why ``label`` must not be fixed at its initial value by --fix-undetermined ("" when it
    may): fixing it there moves another free constant out of its own 95 % interval. To first
    order (the posterior's regression) the move of constant j is rho_jp s_j (p0 - p) / s_p, so
    the test is max |rho_jp| |p0 - p| / s_p > q (the intervals' quantile, 1.96 or Student's)
    over the constants that stay free (not ``fixing``). An undetermined constant with little
    correlation (nu12 of a thin plate) may be fixed even where its interval excludes p0; one
    the others lean on (S1.2's G12, 5.99 GPa +-32 %, p0 3.10 GPa: E1 moved by 6 %) may not. A
    constant at a limit of the search (no interval) may be fixed."""
    k = u.labels.index(label)
    sd = np.sqrt(np.maximum(np.diag(np.asarray(u.covariance, float)), 0.0))
    if not (np.isfinite(sd[k]) and sd[k] > 0) or (u.at_bound is not None and u.at_bound[k]):
        return ""
    name, const = label.rsplit(".", 1)
    c0 = float(getattr(result.initial[list(result.material_names).index(name)], const))
    z = abs(c0 - float(u.value[k])) / sd[k]
    corr = np.asarray(u.correlation, float)[k]
    others = [j for j, lab in enumerate(u.labels)
              if j != k and lab not in fixing and np.isfinite(corr[j])
              and not (u.at_bound is not None and u.at_bound[j])]
    if not others:
        return ""
    j = max(others, key=lambda j: abs(corr[j]))
    shift = abs(corr[j]) * z
    if shift <= float(u.quantile):       # within that constant's own 95 % interval
        return ""

    def show(v):
        return f"{v:.3g}" if const == "nu12" else _gpa(v)

    return (f"not fixed: its initial value {show(c0)} is {z:.1f} standard deviations from the "
            f"identified {show(float(u.value[k]))}, and fixing it there would move "
            f"{u.labels[j]} by {shift:.1f} of its own standard deviations, out of its "
            f"{u.confidence * 100:.0f} % interval: put a value you know in the specimen file "
            "and --fix it")


def _judged_in_run(why: str, run: int) -> str:
    """:func:`_initial_rejected`'s words for a judgement made in an earlier ``run`` than the
    result shown: its value and standard deviations are that run's ("not fixed in run 1: ...
    from the 5.99 GPa identified in that run")."""
    head, sep, rest = why.partition(" standard deviations from the identified ")
    if not sep:
        return why
    value, sep2, tail = rest.partition(", ")
    return (head.replace("not fixed:", f"not fixed in run {run}:", 1)
            + f" standard deviations from the {value} identified in that run" + sep2 + tail)


def _flagging_width(u: Uncertainty, label: str, run: int) -> tuple[float, str, int]:
    """(relative half-width, verdict, run) that flagged ``label`` in ``u``: the linearised
    half-width, or the Monte Carlo's "for sure" one where only that was above the limit."""
    k = u.labels.index(label)
    rel = float(u.rel_half_width[k])
    limit = u.thresholds["max_rel_interval"]
    if not rel > limit and u.mc_rel_half_width_lower is not None:
        sure = float(u.mc_rel_half_width_lower[k])
        if sure > limit:
            rel = sure
    return rel, u.verdict[k], run
