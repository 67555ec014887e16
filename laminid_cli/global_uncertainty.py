"""Doubt on the laminate's global properties (paper Appendix A: Ex, Ey, Gxy, Gxz, Gyz, nu_xy,
nu_yx), propagated from the identified constants.

A global property g(P) is a smooth function of the ply constants P. Its linearised variance is
J C J^T, with J = dg/dP by central differences (relative step :data:`REL_STEP`) over the free
constants and C their covariance (:class:`laminid_cli.uncertainty.Uncertainty`, the same
scaling and quantile as the constants' intervals). Moduli get intervals on ln g, as the
constants do (``g exp(-/+ q std / g)``), Poisson ratios linear ones; the verdict follows the
same bands (5 % / 30 % half-width).

A property that depends (``|dg / dP| s / |g| >`` :data:`DEPENDS`, with s the constant's value, at
least a tenth of E2 for a modulus) on a constant at a limit of the search is not identified: it
gets no interval and says on which. One fixed because the modes did not determine it
(``--fix-undetermined``) counts the spread it had in the run before it was fixed, with its
covariance with the free constants (``spread_covariance``, ``spread_cross`` of
:func:`laminid_cli.uncertainty.counting_fixed_spread`; so Gxz of a plate whose G13 was fixed
is as undetermined as G13 was); without that spread (it was at a limit of the search), the
property is not identified either. One that depends on a constant fixed by
the user (``--fix`` or the file's ``fixed``) keeps its interval, "given" that value (the
interval does not count the fixed value's own doubt); one that depends on fixed constants only
is not identified ("from the fixed G13, G23"): it is an assumption. For an orthotropic ply
rotated about z the in-plane and the transverse-shear blocks of Q do not mix, so Ex, Ey, Gxy
and the Poisson ratios never depend on G13 or G23, and Gxz, Gyz only on them.

With the constants' Monte Carlo, each property is also computed at every converged trial's
constants (:func:`trial_properties`, one array computation) and summarised as the constants
are (:class:`MonteCarloRange`): its range, the range for sure, the ends set by trials on a
search limit, and the verdict by the constants' rule (a worse band of the range for sure than
of the interval: "(Monte Carlo)").

No click, no h5py: library code.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from laminid_cli.intervals import VERDICT_NOT
from laminid_cli.intervals import verdict as verdict_of
from laminid_cli.material import CONSTANT_NAMES

#: words of a global property's verdict (in the result file) that the report's laminate line
#: looks for: a constant it depends on that the Monte Carlo found less determined than the
#: linearised interval; fixed constants it is given; constants held by their prior
MC_NARROW_WORDS = "the Monte Carlo found"
GIVEN_WORDS = "given the fixed"
PRIOR_WORDS = "leans on the prior of"

#: the properties, in the order they are shown
KEYS = ("Ex", "Ey", "Gxy", "Gxz", "Gyz", "nu_xy", "nu_yx")
#: relative step of the central differences (a Poisson ratio: of max(|nu|, 0.1))
REL_STEP = 1e-6
#: |d ln g / d ln P| above which a property depends on a constant
DEPENDS = 1e-3
NOT_IDENTIFIED = "not identified"
#: the advice after a constant's "not determined by these modes", which a property does not take
_ADVICE = " — " + VERDICT_NOT.split(" — ", 1)[1]


@dataclass(frozen=True)
class GlobalInterval:
    """One property: value (Pa or 1), std, 95 % interval, relative half-width, verdict; the
    constants it depends on that are at a bound / fixed because undetermined (then no
    interval: NaN) / fixed by the user (the interval is given their values)."""

    key: str
    value: float
    std: float
    lower: float
    upper: float
    rel_half_width: float
    verdict: str
    at_bound: tuple[str, ...] = ()
    undetermined_fixed: tuple[str, ...] = ()
    given_fixed: tuple[str, ...] = ()
    #: constants fixed because undetermined whose spread before fixing the interval counts
    spread_counted: tuple[str, ...] = ()
    #: with a Monte Carlo: its range of this property (:class:`MonteCarloRange`; None where
    #: the trials do not move it: it depends on fixed values only, or on one fixed because
    #: undetermined that the trials held), and whether it set the verdict
    monte_carlo: "MonteCarloRange | None" = None
    monte_carlo_ran: bool = False
    verdict_from_monte_carlo: bool = False

    @property
    def identified(self) -> bool:
        return not (self.at_bound or self.undetermined_fixed)

    def as_dict(self) -> dict:
        out = {"value": self.value, "std": self.std, "lower": self.lower, "upper": self.upper,
               "rel_half_width": self.rel_half_width, "verdict": self.verdict,
               "depends_on_at_bound": list(self.at_bound),
               "depends_on_undetermined_fixed": list(self.undetermined_fixed),
               "given_fixed": list(self.given_fixed),
               "spread_counted": list(self.spread_counted)}
        if self.monte_carlo_ran:
            # the constants' keys (uncertainty.constants.<m>.<k>, uncertainty.monte_carlo)
            m = self.monte_carlo
            out["verdict_from"] = ("monte_carlo" if self.verdict_from_monte_carlo
                                   else "linearised")
            out["monte_carlo"] = None if m is None else m.as_dict()
            rel, sure = (np.nan, np.nan) if m is None else m.rel(self.value)
            out["monte_carlo_rel_half_width"] = float(rel)
            out["monte_carlo_rel_half_width_lower"] = float(sure)
        return out


@dataclass(frozen=True)
class MonteCarloRange:
    """A laminate property over the converged Monte Carlo trials, each at its own constants
    (:func:`trial_properties`), summarised as the constants' ranges are
    (laminid_cli.uncertainty: ``sample_spread``, ``inner_range_of``, and the flags of an end
    set by trials on a limit of the search, ``sorted_ends_at_bound``, a trial counting as on
    one where a constant the property depends on is)."""

    mean: float
    std: float
    lower: float
    upper: float
    inner_lower: float
    inner_upper: float
    linearized_std: float
    ratio: float
    trials_at_bound: int
    lower_at_bound: bool
    upper_at_bound: bool

    def rel(self, value: float) -> tuple[float, float]:
        """(half-width of the range, of the range for sure) over ``|value|``."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return (0.5 * (self.upper - self.lower) / abs(value),
                    0.5 * (self.inner_upper - self.inner_lower) / abs(value))

    def as_dict(self) -> dict:
        return {f.name: (bool(v) if isinstance(v, (bool, np.bool_)) else
                         int(v) if isinstance(v, (int, np.integer)) else float(v))
                for f in dataclasses.fields(self) for v in (getattr(self, f.name),)}


def trial_properties(laminate, constants: dict, mc) -> np.ndarray:
    """(n_converged, 7) the properties of :data:`KEYS` at each converged trial of ``mc`` (a
    laminid_cli.uncertainty.MonteCarlo): its free constants from the trial (``samples``), the
    fixed ones it drew from their spread before fixing from ``fixed_samples``, the others
    the result's ``constants`` ({material: ElasticConstants}). One vectorised evaluation
    (:meth:`laminid_cli.laminate.Laminate.global_properties_of`)."""
    names = laminate.material_names
    where = {name: m for m, name in enumerate(names)}
    samples = np.asarray(mc.samples, float)
    n = samples.shape[0]
    values = np.repeat(np.array([constants[name].as_array() for name in names])[None], n, 0)
    drawn = (() if mc.fixed_samples is None else
             zip(mc.fixed_labels, np.asarray(mc.fixed_samples, float).reshape(n, -1).T))
    for lab, column in [*zip(mc.labels, samples.T), *drawn]:
        name, k = lab.rsplit(".", 1)
        if name in where:                     # (a joint fit's other plates' materials)
            values[:, where[name], CONSTANT_NAMES.index(k)] = column
    return laminate.global_properties_of(values) if n else np.zeros((0, len(KEYS)))


def _monte_carlo_ranges(laminate, constants: dict, mc, deps: dict, held, g0, std
                        ) -> dict[str, "MonteCarloRange | None"]:
    """Per key, the :class:`MonteCarloRange` of the property over ``mc``'s trials, or None
    where the trials do not move it: no constant it depends on (``deps[key]``) is free or
    drawn by them, or one is fixed because undetermined and held by them (``held``)."""
    from laminid_cli.intervals import t_std
    from laminid_cli.uncertainty import (MC_EVIDENCE, inner_range_of, sample_spread,
                                         sorted_ends_at_bound)

    G = trial_properties(laminate, constants, mc)
    conf = float(mc.confidence)
    mean, sd, lower, upper = sample_spread(G, len(KEYS), conf)
    in_lo, in_hi = inner_range_of(G, len(KEYS), conf, MC_EVIDENCE)
    moved = set(mc.labels) | set(mc.fixed_labels)
    flags = (np.zeros((G.shape[0], len(mc.labels)), np.int8) if mc.trial_at_bound is None
             else np.asarray(mc.trial_at_bound).reshape(G.shape[0], len(mc.labels)))
    col = {lab: j for j, lab in enumerate(mc.labels)}
    out = {}
    for i, key in enumerate(KEYS):
        d = deps[key]
        if G.shape[0] < 2 or not moved.intersection(d) or set(d) & set(held):
            out[key] = None
            continue
        on_limit = np.zeros(G.shape[0], bool)
        for lab in d:
            if lab in col:
                on_limit |= flags[:, col[lab]] != 0
        lo_b, up_b = sorted_ends_at_bound(G[:, i], on_limit, conf)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = sd[i] / (std[i] * t_std(mc.variance_dof))
        out[key] = MonteCarloRange(float(mean[i]), float(sd[i]), float(lower[i]),
                                   float(upper[i]), float(in_lo[i]), float(in_hi[i]),
                                   float(std[i]), float(ratio), int(on_limit.sum()), lo_b, up_b)
    return out


def _props(laminate, constants: dict) -> np.ndarray:
    gp = laminate.with_constants(constants).global_properties().as_dict()
    return np.array([gp[k] for k in KEYS])


def _step(name: str, value: float) -> float:
    return REL_STEP * (max(abs(value), 0.1) if name == "nu12" else abs(value))


def _dependence_scale(constants: dict, label: str) -> float:
    """The change of a constant that its dependence is judged on: its value, at least a tenth
    of its material's E2 for a modulus (a shear modulus at its floor, a few MPa, would
    otherwise hide a property's dependence on it: its real value is not known) and 0.1 for
    nu12."""
    name, k = label.rsplit(".", 1)
    c = constants[name]
    v = abs(float(getattr(c, k)))
    return max(v, 0.1) if k == "nu12" else max(v, 0.1 * abs(float(c.E2)))


def sensitivities(laminate, constants: dict) -> tuple[np.ndarray, tuple[str, ...], np.ndarray]:
    """(J, labels, g0): J (7, p) = d g / d P of :data:`KEYS` over every constant of every
    material ("material.E1", ...), by central differences; g0 the properties."""
    g0 = _props(laminate, constants)
    labels, cols = [], []
    for name, c in constants.items():
        for k in CONSTANT_NAMES:
            v = float(getattr(c, k))
            h = _step(k, v)
            up = dict(constants, **{name: dataclasses.replace(c, **{k: v + h})})
            dn = dict(constants, **{name: dataclasses.replace(c, **{k: v - h})})
            cols.append((_props(laminate, up) - _props(laminate, dn)) / (2 * h))
            labels.append(f"{name}.{k}")
    return np.column_stack(cols), tuple(labels), g0


def global_intervals(laminate, constants: dict, u, fixed_undetermined=(), before=None,
                     mc=None) -> dict[str, GlobalInterval]:
    """The :class:`GlobalInterval` of each property of ``laminate`` (a
    :class:`laminid_cli.laminate.Laminate`) with the identified ``constants`` ({material:
    ElasticConstants}), from the constants' uncertainty ``u``. ``fixed_undetermined``: labels
    fixed because undetermined, whose spread counts where ``u`` counted it
    (``u.spread_counted``; a property depending on one not counted is not identified);
    ``before``: the uncertainty of the run before they were fixed (which of them were at a
    limit of the search there); ``mc``: the constants' Monte Carlo
    (laminid_cli.uncertainty.MonteCarlo), whose trials give each property its range
    (:class:`MonteCarloRange`) and, by the constants' rule
    (laminid_cli.uncertainty.monte_carlo_verdict: the range's width for sure in a worse band
    than the interval's), a worse verdict marked "(Monte Carlo)"."""
    from laminid_cli.uncertainty import monte_carlo_verdict

    J, labels, g0 = sensitivities(laminate, constants)
    index = {lab: j for j, lab in enumerate(labels)}
    free = list(u.labels)
    at_bound = ({lab for lab, b in zip(free, u.at_bound) if b} if u.at_bound is not None
                else set())
    # a constant with no finite standard deviation (a direction the modes do not see: the
    # covariance's pseudo-inverse gives it none) is as unknown as one at a limit
    std_u = np.asarray(getattr(u, "std", np.zeros(len(free))), float)
    unseen = {lab for lab, sd in zip(free, std_u) if not np.isfinite(sd)} - at_bound
    cov = np.nan_to_num(np.asarray(u.covariance, float))
    # the labels of this plate's materials only (a joint fit's other materials do not change
    # this laminate; the covariance's sub-matrix over these labels is exact)
    keep = [k for k, lab in enumerate(free)
            if lab in index and lab not in at_bound and lab not in unseen]
    Jf = J[:, [index[free[k]] for k in keep]] if keep else np.zeros((len(KEYS), 0))
    var = (np.einsum("ij,jk,ik->i", Jf, cov[np.ix_(keep, keep)], Jf) if keep
           else np.zeros(len(KEYS)))
    # a constant fixed because undetermined still has the spread it had before it was fixed,
    # and the free constants share part of it (uncertainty.counting_fixed_spread: the
    # covariance of the free constants already counts it; here the fixed ones' own block and
    # the cross terms are added)
    undetermined = set(fixed_undetermined)
    counted_all = tuple(getattr(u, "spread_counted", ()) or ())
    spread = [lab for lab in counted_all if lab in undetermined and lab in index]
    if spread:
        ks = [counted_all.index(lab) for lab in spread]
        Jc = J[:, [index[lab] for lab in spread]]
        Cf = np.asarray(u.spread_covariance, float)[np.ix_(ks, ks)]
        var = var + np.einsum("ij,jk,ik->i", Jc, Cf, Jc)
        if keep:
            X = np.asarray(u.spread_cross, float)[np.ix_(keep, ks)]
            var = var + 2 * np.einsum("ij,jk,ik->i", Jf, X, Jc)
    std = np.sqrt(np.maximum(var, 0.0))
    q = np.full(len(KEYS), float(u.quantile))
    spread_free = getattr(u, "spread_free", None)
    if spread and spread_free is not None:
        # the spread's part is known with the run before fixing's degrees of freedom, the
        # rest with the final run's: Welch-Satterthwaite per property, as for the constants
        from laminid_cli.intervals import effective_dof, quantiles_of, variance_dof

        noise = cov - np.nan_to_num(np.asarray(spread_free, float))
        v_n = (np.einsum("ij,jk,ik->i", Jf, noise[np.ix_(keep, keep)], Jf) if keep
               else np.zeros(len(KEYS)))
        nu = effective_dof(v_n, variance_dof(u), np.maximum(var - v_n, 0.0), u.spread_dof)
        q = quantiles_of(u.confidence, nu)
    # fixed because it was at a limit of the search in the run before (no spread to count)
    was_at_limit = set()
    if before is not None and getattr(before, "at_bound", None) is not None:
        was_at_limit = {lab for lab, b in zip(before.labels, before.at_bound) if b}
    scale = np.array([_dependence_scale(constants, lab) for lab in labels])
    by_monte_carlo = set(getattr(u, "verdict_from_monte_carlo", ()))
    # constants held by their prior (more than half of what is known of them is the file's
    # prior: their verdict says "(held by the prior)"); a property leaning on one says so
    share = getattr(u, "information_from_prior", None)
    by_prior = set() if share is None else {
        lab for lab, x in zip(u.labels, np.asarray(share, float)) if x > 0.5}
    depends = {key: [lab for lab, d in zip(labels, np.abs(J[i]) * scale
                                           / max(abs(float(g0[i])), 1e-300)) if d > DEPENDS]
               for i, key in enumerate(KEYS)}
    ranges = {}
    if mc is not None:
        # the trials hold a constant fixed because undetermined unless they drew it
        ranges = _monte_carlo_ranges(laminate, constants, mc, depends,
                                     undetermined - set(mc.fixed_labels), g0, std)
    ran = mc is not None
    out = {}
    for i, key in enumerate(KEYS):
        g = float(g0[i])
        deps = depends[key]
        rng = ranges.get(key)
        bound = tuple(lab for lab in deps if lab in at_bound or lab in unseen)
        und = tuple(lab for lab in deps if lab in undetermined)
        counted = tuple(lab for lab in und if lab in spread)
        und = tuple(lab for lab in und if lab not in spread)
        given = tuple(lab for lab in deps if lab not in free and lab not in undetermined)
        half = float(q[i]) * float(std[i])
        rel = half / abs(g) if g != 0 else np.inf
        from_free = [lab for lab in deps if lab in free]
        if given and not from_free and not counted:
            # only fixed values (e.g. Gxz of a plate with G13, G23 fixed): an assumption, not a
            # result; no interval (its doubt is the fixed values', which laminid does not know)
            out[key] = GlobalInterval(key, g, np.nan, np.nan, np.nan, np.nan,
                                      f"{NOT_IDENTIFIED}: from the fixed " + ", ".join(given),
                                      (), (), given, monte_carlo=rng, monte_carlo_ran=ran)
            continue
        if bound or und:
            why = ", ".join([f"{lab} (at its bound)" if lab in at_bound else
                             f"{lab} (not determined in any direction)" for lab in bound]
                            + [f"{lab} (fixed: it was at a search limit)" if lab in was_at_limit
                               else f"{lab} (fixed because undetermined)" for lab in und])
            out[key] = GlobalInterval(key, g, np.nan, np.nan, np.nan, np.nan,
                                      f"{NOT_IDENTIFIED}: depends on {why}", bound, und, given,
                                      monte_carlo=rng, monte_carlo_ran=ran)
            continue
        if key.startswith("nu"):
            lo, hi = g - half, g + half
        else:
            with np.errstate(over="ignore"):
                lo, hi = g * np.exp(-half / g), g * np.exp(half / g)
        # the constants' bands and words, without their advice ("fix it or measure a thicker
        # plate / more modes": no laminate property can be fixed; the terminal left it out,
        # --json and the file gave it)
        verdict = verdict_of(rel, False).replace(_ADVICE, "")
        sure = rng.rel(g)[1] if rng is not None else np.nan
        worse = monte_carlo_verdict(sure, rel) if np.isfinite(sure) else ""
        if worse:
            verdict = worse.replace(_ADVICE, "")
        narrow = [lab for lab in deps if lab in by_monte_carlo]
        if narrow and not np.isfinite(sure):
            # no range of its own to judge by: a constant it depends on says it
            verdict += (f" — linearised; {MC_NARROW_WORDS} " + ", ".join(narrow)
                        + " less determined than that: this interval is too narrow")
        if counted:
            verdict += (" — counts the spread " + ", ".join(counted) + " had before "
                        + ("it was" if len(counted) == 1 else "they were") + " fixed")
        if given:
            verdict += f" — {GIVEN_WORDS} " + ", ".join(given)
        prior = [lab for lab in deps if lab in by_prior]
        if prior:
            # (S1.2 with prior {nu12: 1.0}: Ex "well determined" beside nu12 "well
            # determined (held by the prior)", as if the modes had given both)
            verdict += f" — {PRIOR_WORDS} " + ", ".join(prior)
        out[key] = GlobalInterval(key, g, float(std[i]), float(lo), float(hi), float(rel),
                                  verdict, (), (), given, counted, monte_carlo=rng,
                                  monte_carlo_ran=ran, verdict_from_monte_carlo=bool(worse))
    return out
