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
