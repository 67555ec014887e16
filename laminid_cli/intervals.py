"""Interval scale and verdicts shared by the stiffness and the damping fits.

Both :func:`laminid_cli.uncertainty.linearized_uncertainty` (elastic constants) and
:func:`laminid_cli.damping.fit_loss_factors` (ply loss factors) turn a least-squares covariance
into intervals the same way:

* the covariance ``scaling`` — "stated" (the stated noise), "residuals" (times the a-posteriori
  variance s2 = chi2 / dof, Student t quantile) or "larger" (whichever gives the wider interval);
  without degrees of freedom the stated noise is used and a note says so (:func:`interval_scale`);
* the verdict of a constant from its relative half-width (:func:`verdict`).
"""

from __future__ import annotations

import math

#: the start of a flat profile's statement (uncertainty.profile_bound: no value rejected
#: within the search); one that could not be made starts with PROFILE_NONE
#: (resultfile.profile_kind reads them back)
PROFILE_FLAT = "the fit is as good"
PROFILE_NONE = "no profile:"

#: relative 95 % half-width below which a constant is "well determined"
WELL_DETERMINED = 0.05
#: relative 95 % half-width below which a constant is "weak" (above: not determined)
WEAK = 0.30
#: covariance scaling choices (module docstring)
SCALINGS = ("stated", "residuals", "larger")
VERDICT_WELL = "well determined"
VERDICT_WEAK = "weak"
VERDICT_NOT = "not determined by these modes — fix it or measure a thicker plate / more modes"
VERDICT_FIXED = "fixed"
VERDICT_AT_BOUND = "at bound — not identified"
#: the note after a verdict whose constant gets most of its information from the prior
#: (uncertainty.linearized_uncertainty: more than half, paper Eq. 15)
HELD_BY_PRIOR = " (held by the prior)"


def interval_scale(scaling: str, dof: int, s2: float, confidence: float, counts: str
                   ) -> tuple[str, float, float, str | None]:
    """(scale used, variance factor, quantile, note or None) of a fit's intervals.

    scaling : one of :data:`SCALINGS`; dof, s2 : degrees of freedom and chi2 / dof of the fit;
    confidence : two-sided level (0.95); counts : what the data and unknowns were, for the note
    when no degree of freedom is left (e.g. "5 modes for 5 loss factors").
    """
    from laminid_cli.quantiles import norm_ppf, t_ppf

    z = norm_ppf(0.5 + confidence / 2)
    if scaling in ("residuals", "larger"):
        if dof <= 0:
            return "stated", 1.0, z, (f"no degrees of freedom left ({counts}): the a-posteriori "
                                      "variance cannot be estimated; stated sigma used")
        tq = t_ppf(0.5 + confidence / 2, dof)
        if scaling == "residuals" or tq * math.sqrt(s2) > z:
            return "residuals", s2, tq, None
    return "stated", 1.0, z, None


def small_chi2_note(chi2: float, dof: float, sigma: str = "sigma") -> str | None:
    """The words for a fit whose residuals are smaller than its stated ``sigma`` implies
    (chi2 below its 1 % quantile for ``dof``), else None: the sigmas are then likely too
    large and the intervals made from them too wide (``--covariance-scale larger`` keeps the
    stated sigma where the residuals' scale is smaller). A conservative interval is no error,
    but a lab reading "residuals consistent with it" would not know its intervals overstate
    the doubt (the synthetic impact test: chi2 8e-5 for 7 degrees of freedom)."""
    from laminid_cli.quantiles import chi2_ppf

    if not (dof > 0 and math.isfinite(chi2)):
        return None
    q01 = chi2_ppf(0.01, dof)
    if not chi2 < q01:
        return None
    return (f"the residuals are smaller than the stated {sigma} implies (chi2 {chi2:.3g} for "
            f"{dof:g} degrees of freedom, below its 1 % quantile {q01:.3g}): the {sigma} is "
            "likely too large, and the intervals from it too wide (--covariance-scale "
            "residuals takes them from the residuals' own scatter)")


def effective_dof(v1, nu1: float, v2, nu2: float):
    """Welch-Satterthwaite's effective degrees of freedom of a variance v1 + v2 whose parts
    are known with nu1 and nu2 degrees of freedom (GUM, JCGM 100 G.4.1): (v1 + v2)^2 /
    (v1^2 / nu1 + v2^2 / nu2); an infinite nu (a stated sigma) adds nothing below; inf where
    both parts are exact. Arrays elementwise."""
    import numpy as np

    v1, v2 = np.asarray(v1, float), np.asarray(v2, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        den = (np.where(np.isfinite(nu1), v1 ** 2 / nu1, 0.0)
               + np.where(np.isfinite(nu2), v2 ** 2 / nu2, 0.0))
        return np.where(den > 0, (v1 + v2) ** 2 / den, np.inf)


def quantile_of(confidence: float, nu: float) -> float:
    """The two-sided ``confidence`` quantile of Student t with ``nu`` degrees of freedom, the
    normal's where nu is infinite (or NaN)."""
    from laminid_cli.quantiles import norm_ppf, t_ppf

    if not math.isfinite(nu):
        return norm_ppf(0.5 + confidence / 2)
    return t_ppf(0.5 + confidence / 2, float(nu))


def quantiles_of(confidence: float, nus):
    """:func:`quantile_of` for each of the degrees of freedom ``nus`` (per constant, per
    laminate property)."""
    import numpy as np

    return np.array([quantile_of(float(confidence), float(n)) for n in np.ravel(nus)])


def variance_dof(u) -> float:
    """The degrees of freedom of an uncertainty's variance factor: its residuals' where its
    intervals are scaled by s2 (Student t), infinite on the stated sigma."""
    return float(u.dof) if u.scale_used == "residuals" and u.dof > 0 else math.inf


def t_std(nu: float) -> float:
    """Standard deviation of Student's t with ``nu`` degrees of freedom (1 for nu = 0: the
    normal; NaN for nu <= 2, whose t has no variance)."""
    if nu == 0:
        return 1.0
    return math.sqrt(nu / (nu - 2)) if nu > 2 else math.nan


def verdict(rel: float, at_bound: bool) -> str:
    """Verdict of one constant from its relative half-width (:data:`WELL_DETERMINED`,
    :data:`WEAK`)."""
    if at_bound:
        return VERDICT_AT_BOUND
    if rel < WELL_DETERMINED:
        return VERDICT_WELL
    if rel < WEAK:
        return VERDICT_WEAK
    return VERDICT_NOT                    # also a NaN half-width


def flag_words(max_rel_interval: float) -> str:
    """What a constant flagged by ``--max-rel-interval`` is, in the status and the terminal's
    flag line: "not determined by these modes" at the verdicts' band (:data:`WEAK`); below it
    (a tighter threshold) the flagged constant may read "weak", so the words say what the lab
    asked for."""
    if max_rel_interval >= WEAK:
        return "not determined by these modes"
    return f"known less well than --max-rel-interval {max_rel_interval * 100:.0f} % asks"


def width_text(rel: float) -> str:
    """A relative half-width as the terminal and the report write it: "1.3 %" (one decimal,
    so that 0.4 % is not "0 %"), "60x" from ten times the value on."""
    return f"{rel * 100:.1f} %" if rel < 10 else f"{rel:.0f}x"


def spread_sentence(counted, given, what: str = "the intervals") -> str:
    """The statement that ``what`` count the spread the ``counted`` fixed values (names as
    shown) had before --fix-undetermined fixed them, with the widths ``given`` ((name, relative
    half-width) pairs, finite) they have given the fixed values alone."""
    return (f"{what} count the spread " + ", ".join(counted) + " had before "
            + ("it was" if len(counted) == 1 else "they were")
            + " fixed (a fixed value is not known better than that)"
            + ("; given the fixed values alone: " + ", ".join(
                f"{name} ±{width_text(w)}" for name, w in given) if given else ""))


#: the words of the summaries' ``flag`` (long summary.csv, summary.json, identify --json's
#: loss factors) and of the wide summary's ``flagged`` column for each mark of batch's
#: terminal table
FLAG_AT_BOUND, FLAG_UNDETERMINED, FLAG_FIXED, FLAG_PRIOR, FLAG_ASSUMED, FLAG_LEANS = \
    "at_bound", "undetermined", "fixed", "prior", "assumed", "leans"

#: what a loss factor's verdict says when its interval leans on elastic constants the modes do
#: not determine (laminid_cli.damping.VERDICT_LEANS is built on these words; its flag:
#: FLAG_LEANS)
LEANS_WORDS = "interval too narrow: its energy share leans on"


def flag_word(iv: dict) -> str:
    """What a summary's value is when it is no plain identified one, as a word a script can
    test (the verdict is words for a reader): "fixed" (held at its initial value: --fix, the
    file's ``fixed``), "assumed" (held at its initial guess by --fix-undetermined, because the
    modes did not determine it: an assumption, where "fixed" is a value the user gave as
    known), "at_bound" (stopped on a limit of the search: the
    value is that limit), "undetermined" (flagged: its interval wider than --max-rel-interval;
    a loss factor's verdict "not determined"), "prior" (held by the prior: the file's prior
    gives more than half of what is known of it, paper Eq. 15; its value is mostly the
    prior's), "leans" (a loss factor whose interval is too narrow: its energy share leans on
    elastic constants the modes do not determine, :data:`LEANS_WORDS`), else "" (identified,
    with its interval).
    ``iv``: an entry of a summary row's ``intervals`` (or a loss factor's of ``damping``)."""
    verdict = str(iv.get("verdict") or "")
    if verdict == VERDICT_FIXED:
        return FLAG_ASSUMED if iv.get("assumed") else FLAG_FIXED
    if iv.get("at_bound") or verdict == VERDICT_AT_BOUND:
        return FLAG_AT_BOUND
    if iv.get("flagged") or ("flagged" not in iv and verdict.startswith("not determined")):
        return FLAG_UNDETERMINED
    if verdict.endswith(HELD_BY_PRIOR):
        return FLAG_PRIOR
    if LEANS_WORDS in verdict:
        return FLAG_LEANS
    return ""
