"""Interval scale and verdicts shared by the stiffness and damping fits (laminid_cli.intervals),
against scipy.stats quantiles."""

import math

import pytest
from scipy import stats

from laminid_cli.intervals import (VERDICT_AT_BOUND, VERDICT_NOT, VERDICT_WEAK, VERDICT_WELL,
                                   interval_scale, verdict)

Z95 = stats.norm.ppf(0.975)


def test_stated_scaling_uses_the_normal_quantile_and_no_factor():
    used, factor, q, note = interval_scale("stated", 5, 9.0, 0.95, "-")
    assert (used, factor, note) == ("stated", 1.0, None)
    assert q == pytest.approx(Z95, rel=1e-12)


@pytest.mark.parametrize("scaling", ["residuals", "larger"])
def test_residual_scaling_uses_student_t_and_s2_when_the_residuals_are_larger(scaling):
    used, factor, q, note = interval_scale(scaling, 4, 9.0, 0.95, "-")
    assert (used, factor, note) == ("residuals", 9.0, None)
    assert q == pytest.approx(stats.t.ppf(0.975, 4), rel=1e-10)


def test_larger_keeps_the_stated_sigma_when_the_residuals_are_smaller():
    # t(0.975, 4) sqrt(0.01) = 0.28 < 1.96
    assert interval_scale("larger", 4, 0.01, 0.95, "-")[:2] == ("stated", 1.0)
    assert interval_scale("residuals", 4, 0.01, 0.95, "-")[:2] == ("residuals", 0.01)


@pytest.mark.parametrize("scaling", ["residuals", "larger"])
def test_no_degree_of_freedom_falls_back_to_the_stated_sigma_with_a_note(scaling):
    used, factor, q, note = interval_scale(scaling, 0, math.nan, 0.95, "5 modes for 5 loss factors")
    assert (used, factor) == ("stated", 1.0) and q == pytest.approx(Z95, rel=1e-12)
    assert note == ("no degrees of freedom left (5 modes for 5 loss factors): the a-posteriori "
                    "variance cannot be estimated; stated sigma used")


@pytest.mark.parametrize("rel, at_bound, expected", [
    (0.049, False, VERDICT_WELL), (0.05, False, VERDICT_WEAK), (0.299, False, VERDICT_WEAK),
    (0.30, False, VERDICT_NOT), (math.inf, False, VERDICT_NOT), (math.nan, False, VERDICT_NOT),
    (0.01, True, VERDICT_AT_BOUND),
])
def test_verdict_thresholds(rel, at_bound, expected):
    assert verdict(rel, at_bound) == expected


def test_residuals_smaller_than_the_stated_sigma_implies_are_said_with_the_quantile():
    """chi2 below its 1 % quantile: the stated sigma is likely too large (the synthetic impact
    test's elastic fit, chi2 8e-5 for 7 degrees of freedom, said "residuals consistent with
    it"); at or above the quantile, or without a degree of freedom, nothing."""
    from laminid_cli.intervals import small_chi2_note

    q01 = stats.chi2.ppf(0.01, 7)                                   # 1.239
    note = small_chi2_note(8e-5, 7, "frequency sigma")
    assert note == ("the residuals are smaller than the stated frequency sigma implies (chi2 "
                    f"8e-05 for 7 degrees of freedom, below its 1 % quantile {q01:.3g}): the "
                    "frequency sigma is likely too large, and the intervals from it too wide "
                    "(--covariance-scale residuals takes them from the residuals' own scatter)")
    assert small_chi2_note(q01 * (1 - 1e-9), 7) is not None
    assert small_chi2_note(q01 * (1 + 1e-9), 7) is None
    assert small_chi2_note(0.0, 0) is None and small_chi2_note(float("nan"), 7) is None
