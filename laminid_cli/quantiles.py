"""Quantiles of the normal, Student t and chi-square distributions from ``scipy.special``.

``scipy.stats`` costs about a second of start-up for three numbers; ``scipy.special`` has the
inverse distribution functions themselves (tests/test_identify_reduced.py checks them against
scipy.stats).
"""

from __future__ import annotations

from scipy import special


def norm_ppf(q: float) -> float:
    """Standard normal quantile (scipy.stats.norm.ppf)."""
    return float(special.ndtri(q))


def t_ppf(q: float, dof: float) -> float:
    """Student t quantile with ``dof`` degrees of freedom (scipy.stats.t.ppf)."""
    return float(special.stdtrit(dof, q))


def chi2_ppf(q: float, dof: float) -> float:
    """Chi-square quantile with ``dof`` degrees of freedom (scipy.stats.chi2.ppf)."""
    return float(special.chdtri(dof, 1.0 - q))
