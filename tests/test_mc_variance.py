"""The Monte Carlo trials draw their variance factor where the intervals are Student t
(laminid_cli.uncertainty.variance_draws): independent reference scipy.stats.t."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import stats

from laminid_cli.cli import cli
from laminid_cli.uncertainty import t_std, variance_draws


@pytest.mark.parametrize("nu", [3, 6, 9, 30])
def test_normal_noise_times_the_drawn_factor_is_student_t(nu):
    """z g, z ~ N(0, 1) and g = sqrt(nu / X), X ~ chi-square(nu): its 2.5 / 97.5 % quantiles
    are Student t's (scipy) within 2 % over 200000 draws (the quantiles' relative standard
    error is below 0.5 % there), and its std is t_std(nu) = sqrt(nu / (nu - 2)) within 3 %
    (nu = 3 has no fourth moment: the sample std converges slowly, so the 3 % is for
    nu >= 6; nu = 3 is checked on the quantiles and its mean absolute value)."""
    n = 200_000
    u = SimpleNamespace(scale_used="residuals", dof=nu)
    g, got_nu = variance_draws(u, n, seed=0)
    assert got_nu == nu and g.shape == (n,) and np.all(g > 0)
    x = np.random.default_rng(123).standard_normal(n) * g
    lo, hi = np.quantile(x, [0.025, 0.975])
    t = stats.t.ppf(0.975, nu)
    assert hi == pytest.approx(t, rel=0.02) and lo == pytest.approx(-t, rel=0.02)
    if nu >= 6:
        assert np.std(x) == pytest.approx(t_std(nu), rel=0.03)
    else:
        assert np.mean(np.abs(x)) == pytest.approx(stats.t(nu).expect(np.abs), rel=0.02)


def test_stated_sigma_draws_nothing():
    for u in (SimpleNamespace(scale_used="stated", dof=9),
              SimpleNamespace(scale_used="residuals", dof=0)):
        g, nu = variance_draws(u, 5, seed=0)
        assert nu == 0 and np.array_equal(g, np.ones(5))
    assert t_std(0) == 1.0 and np.isnan(t_std(2)) and t_std(4) == pytest.approx(np.sqrt(2))


def test_the_draws_are_a_stream_of_their_own():
    """The same seed gives the same factors, another seed others; the stream is not the
    frequencies' (default_rng(seed)), whose first normal draws it leaves as they were."""
    u = SimpleNamespace(scale_used="residuals", dof=7)
    a, _ = variance_draws(u, 50, seed=4)
    b, _ = variance_draws(u, 50, seed=4)
    c, _ = variance_draws(u, 50, seed=5)
    assert np.array_equal(a, b) and not np.allclose(a, c)
    plain = np.random.default_rng(4).chisquare(7, 50)
    assert not np.allclose(a, np.sqrt(7 / plain))


def test_cli_shows_the_drawn_variance_and_the_ratio_scale():
    """S2.1 (s2 = 1.5 > 1: intervals on s2, Student t with 7 degrees of freedom at 8x8): the
    JSON has variance_dof 7, the terminal says how the trials drew it and what the ratio
    column is over (1.18 = sqrt(7 / 5)); S1.1 (stated sigma) draws none."""
    spec = "specimens/example2/S2.1.yaml"
    res = CliRunner().invoke(cli, ["identify", spec, "--mesh", "8x8", "--monte-carlo", "6",
                                   "-j", "1", "--json", "--no-output"])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)["uncertainty"]
    assert d["scaling"]["used"] == "residuals" and d["a_posteriori"]["dof"] == 7
    assert d["monte_carlo"]["variance_dof"] == 7
    t = CliRunner().invoke(cli, ["identify", spec, "--mesh", "8x8", "--monte-carlo", "6",
                                 "-j", "1", "--no-output"])
    assert ("each trial's variance factor drawn as s2 x 7 / chi-square(7): Student t, as the "
            "intervals") in t.output
    assert ("ratio: Monte Carlo std over the linearised std times 1.18, the std of Student t "
            "with 7 degrees of freedom") in t.output
    s = CliRunner().invoke(cli, ["identify", "specimens/example1/S1.1.yaml", "--mesh", "8x8",
                                 "--monte-carlo", "4", "-j", "1", "--json", "--no-output"])
    assert json.loads(s.output)["uncertainty"]["monte_carlo"]["variance_dof"] == 0
