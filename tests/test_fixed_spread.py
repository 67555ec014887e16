"""The doubt of the values --fix-undetermined fixed, counted in the other constants' intervals
(laminid_cli.uncertainty.counting_fixed_spread, a "consider" covariance): against the exact
identity of a linear model (the covariance before fixing), the first-order regression against
re-identifying S1.1 with the fixed values moved, and the same numbers in --json, the HDF5 file,
the terminal and the report's text."""

import dataclasses
import json

import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.forward import build_forward_model
from laminid_cli.identify import IdentifyOptions, identify
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants
from laminid_cli.specimen import read_specimen
from laminid_cli.uncertainty import (MaterialState, Observations, counting_fixed_spread,
                                     fixed_value_regression, frequency_sigma,
                                     linearized_uncertainty, observations, uncertainty_of)
from tests.figs import result_page

S11 = "specimens/example1/S1.1.yaml"
C = ElasticConstants(E1=150e9, E2=9e9, G12=5e9, G13=4.5e9, G23=3e9, nu12=0.3)


def _linear_problem(seed=3, n=12):
    """Twelve modes whose eigenvalues are linear in the six constants (d lambda / d P fixed),
    at the optimum (model = measured), with a prior on E2 so that the prior rows count too.
    Its weight 1 keeps every row's weight proportional to its noise (0.2 % on each frequency),
    so that the least squares is the efficient estimate and the identity below exact (with
    other weights the all-free covariance is a sandwich that the count of an independent
    assumed value does not reproduce)."""
    rng = np.random.default_rng(seed)
    f = np.linspace(100.0, 1300.0, n)
    lam = (2 * np.pi * f) ** 2
    v = np.array([getattr(C, k) for k in CONSTANT_NAMES])
    # d ln lambda / d ln P: E1 dominant, G13/G23/nu12 weak, as on a thin plate
    share = np.column_stack([rng.uniform(0.5, 0.9, n), rng.uniform(0.05, 0.3, n),
                             rng.uniform(0.05, 0.3, n), rng.uniform(0.002, 0.03, n),
                             rng.uniform(0.002, 0.03, n), rng.uniform(-0.02, 0.02, n)])
    dlam = lam[:, None] * share / v[None, :]
    obs = Observations("toy", f, np.ones(n), 0.002 * f, lam, dlam)

    def state(free):
        return MaterialState("m", C, C, tuple(free), {"E2": 1.0})

    return obs, state


def test_a_linear_model_gets_back_the_covariance_before_fixing():
    """Fixing G13, G23 and nu12 at the optimum and counting their spread before fixing gives
    exactly (1e-9) the free constants' covariance, intervals and cross-covariance of the run
    with all six free; the widths given the fixed values alone are the fixed run's own."""
    obs, state = _linear_problem()
    before = linearized_uncertainty([obs], [state(CONSTANT_NAMES)], scaling="stated")
    free = ("E1", "E2", "G12")
    after = linearized_uncertainty([dataclasses.replace(obs, dlam_dP=obs.dlam_dP[:, :3])],
                                   [state(free)], scaling="stated")
    assert after.fixed == ("m.G13", "m.G23", "m.nu12")
    total = counting_fixed_spread(after, before, [obs], [state(free)])
    assert total.spread_counted == ("m.G13", "m.G23", "m.nu12")
    np.testing.assert_allclose(total.covariance, before.covariance[:3, :3], rtol=1e-9)
    np.testing.assert_allclose(total.spread_cross, before.covariance[:3, 3:], rtol=1e-9,
                               atol=1e-9 * np.abs(before.covariance[:3, 3:]).max())
    np.testing.assert_allclose(total.spread_covariance, before.covariance[3:, 3:], rtol=1e-9)
    np.testing.assert_allclose(total.rel_half_width, before.rel_half_width[:3], rtol=1e-9)
    np.testing.assert_allclose(total.lower, before.lower[:3], rtol=1e-9)
    np.testing.assert_allclose(total.rel_half_width_given_fixed, after.rel_half_width)
    # fixing does narrow the conditional widths here (E1 leans on the shear moduli)
    assert np.all(after.rel_half_width < before.rel_half_width[:3])
    # a fixed constant with no spread before (at a limit there) is not counted, and said so
    at_limit = dataclasses.replace(before, at_bound=np.array([0, 0, 0, 1, 0, 0], bool),
                                   std=np.where(np.arange(6) == 3, np.nan, before.std))
    part = counting_fixed_spread(after, at_limit, [obs], [state(free)])
    assert part.spread_counted == ("m.G23", "m.nu12") and part.spread_not_counted == ("m.G13",)
    assert any("given the fixed value of m.G13" in n for n in part.notes)
    assert np.all(part.rel_half_width < total.rel_half_width)


@pytest.fixture(scope="module")
def s11_fixed():
    spec = read_specimen(S11)
    opts = IdentifyOptions(fix=("G13", "G23", "nu12"))
    r = identify(build_forward_model(spec), opts)
    return spec, opts, r


def _identify_with(spec, opts, **values):
    (name, m), = spec.materials.items()
    m2 = dataclasses.replace(m, constants=dataclasses.replace(m.constants, **values))
    sp = dataclasses.replace(spec, materials={name: m2})
    return identify(build_forward_model(sp), opts).constants[0].as_array()[:3]


def test_first_order_regression_against_re_identifying_s11(s11_fixed):
    """d(E1, E2, G12) / d(G13, G23, nu12) at S1.1's optimum with those three fixed at 3.10,
    3.10 GPa and 0.35, against central differences of whole identifications (step 1e-3
    relative; 1e-2 gives the same to 1e-4): G13 and G23 within 5 %; nu12 within 40 % (the
    Gauss-Newton regression leaves out the residuals' curvature, which the weak nu12 columns
    feel: measured 1.21-1.37 times)."""
    spec, opts, r = s11_fixed
    labels = tuple(f"IM7/977-2.{k}" for k in ("E1", "E2", "G12"))
    fixed = tuple(f"IM7/977-2.{k}" for k in ("G13", "G23", "nu12"))
    obs = [observations(build_forward_model(spec), r, frequency_sigma(spec.measured, 0.002),
                        labels + fixed)]
    from laminid_cli.uncertainty import material_states

    S = fixed_value_regression(obs, material_states(r), labels, [3, 4, 5])
    c0 = spec.materials["IM7/977-2"].constants
    for j, (k, tol) in enumerate((("G13", 0.05), ("G23", 0.05), ("nu12", 0.4))):
        v = getattr(c0, k)
        h = 1e-3 * abs(v)
        fd = (_identify_with(spec, opts, **{k: v + h})
              - _identify_with(spec, opts, **{k: v - h})) / (2 * h)
        np.testing.assert_allclose(S[:, j], fd, rtol=tol, err_msg=k)
    # E1 leans on the shear moduli one for one (Pa per Pa): the reason their doubt matters
    assert S[0, 0] == pytest.approx(-1.02, abs=0.02) and S[0, 1] == pytest.approx(-1.02, abs=0.02)


def test_spread_counted_like_re_identifying_one_spread_away(s11_fixed):
    """The tangent (fixed_value_regression) times one standard deviation of G13 or G23's
    spread before fixing (in ln G: 0.79 and 1.42) against re-identifying S1.1 with them there
    (secant over +-1 sd): E1's move within 10 % (measured 1.56 vs 1.56 %, 2.80 vs 2.83 %).
    And the count itself, by secants along the fixed values' principal axes
    (fixed_spread_moves, what identify uses) against the first-order count: within 15 % on
    E1, E2, G12 (S1.1's spreads are moderate: the two agree), both wider than the intervals
    given the fixed values."""
    from laminid_cli.uncertainty import fixed_spread_moves, material_states

    spec, opts, r = s11_fixed
    a = _assess_s11()
    before = a.before_fixing
    fm = build_forward_model(spec)
    sigma = frequency_sigma(spec.measured, 0.002)
    cond = uncertainty_of(a.result, fm, sigma)
    labels = tuple(f"IM7/977-2.{k}" for k in ("E1", "E2", "G12"))
    assert cond.labels == labels
    obs = [observations(fm, a.result, sigma, cond.labels + cond.fixed)]
    mats = material_states(a.result)
    S = fixed_value_regression(obs, mats, labels, [3, 4])
    base = a.result.constants[0].as_array()[0]
    for j, k in enumerate(("G13", "G23")):
        lab = f"IM7/977-2.{k}"
        s_ln = before.std[before.labels.index(lab)] / before.value[before.labels.index(lab)]
        g0 = getattr(spec.materials["IM7/977-2"].constants, k)
        tangent = abs(S[0, j] * g0 * s_ln) / base
        hi = _identify_with(spec, opts, **{k: g0 * np.exp(s_ln)})[0]
        lo = _identify_with(spec, opts, **{k: g0 * np.exp(-s_ln)})[0]
        secant = abs(hi - lo) / 2 / base
        assert tangent == pytest.approx(secant, rel=0.10), k
        assert secant > 0.01                      # a change a lab would see
    first = counting_fixed_spread(cond, before, obs, mats)
    moves = fixed_spread_moves(cond, before, a.result, [fm], [sigma],
                               {"scaling": "larger"}, False)
    secants = counting_fixed_spread(cond, before, obs, mats, moves=moves)
    np.testing.assert_allclose(secants.rel_half_width, first.rel_half_width, rtol=0.15)
    assert np.all(secants.rel_half_width > cond.rel_half_width)


def _assess_s11():
    from laminid_cli.uncertainty import UncertaintyOptions, assess

    return assess(build_forward_model(read_specimen(S11)), IdentifyOptions(),
                  UncertaintyOptions(fix_undetermined=True))


@pytest.fixture(scope="module")
def s11_monte_carlo(tmp_path_factory):
    """``identify S1.1 --fix-undetermined --monte-carlo 8 -j 1 -o``: (its terminal output,
    the result file), run once for the two tests that read one or the other (the output is
    that of --no-output but for its last line, "written: ...")."""
    out = tmp_path_factory.mktemp("mc") / "mc.h5"
    res = CliRunner().invoke(cli, ["identify", S11, "--fix-undetermined", "--monte-carlo", "8",
                                   "-j", "1", "-o", str(out)])
    assert res.exit_code == 0, res.output
    return res.output, out


def test_fixed_spread_in_json_hdf5_terminal_and_report(s11_fix_undetermined, s11_monte_carlo):
    """S1.1 --fix-undetermined: E1 +-2.5 % counting the fixed values' spread, +-1.3 % given
    them (tolerances: the factorizers' round-off is far below); the same numbers in --json,
    the reader of the HDF5 file, the terminal line and the report's note. Each interval's
    quantile is Student t with the Welch-Satterthwaite degrees of freedom of its two parts,
    recomputed here from the JSON's std and given-fixed width (the noise's 9 degrees of
    freedom, the spread's infinitely many: the run before fixing used the stated sigma):
    E1 t(197) = 1.97 where the final run's t(9) = 2.26 gave +-2.9 %; Gxz, all spread, the
    normal quantile."""
    from scipy import stats
    from laminid_cli.report import table_notes
    from laminid_cli.resultfile import read_result

    doc, out = s11_fix_undetermined          # identify S1.1 --fix-undetermined --json -o
    u = doc["uncertainty"]
    assert u["spread_counted"] == [f"IM7/977-2.{k}" for k in ("G13", "G23", "nu12")]
    c = u["constants"]["IM7/977-2"]
    assert c["E1"]["rel_half_width"] == pytest.approx(0.0251, abs=0.0015)
    assert c["E1"]["rel_half_width_given_fixed"] == pytest.approx(0.0133, abs=0.0005)
    nu_n = u["a_posteriori"]["dof"]
    assert u["scaling"]["used"] == "residuals" and nu_n == 9 and u["spread_dof"] is None  # inf
    for k in ("E1", "E2", "G12"):
        v = c[k]
        assert v["rel_half_width"] > v["rel_half_width_given_fixed"], k
        # Welch-Satterthwaite from the parts: the noise's variance from the width given the
        # fixed values (its quantile the final run's t(9)), the spread's the rest
        v_tot = v["std"] ** 2
        v_n = (v["rel_half_width_given_fixed"] * abs(v["value"]) / u["quantile"]) ** 2
        nu = v_tot ** 2 / (v_n ** 2 / nu_n)
        assert v["effective_dof"] == pytest.approx(nu, rel=1e-6), k
        assert v["quantile"] == pytest.approx(stats.t.ppf(0.975, nu), rel=1e-10), k
        assert v["rel_half_width"] == pytest.approx(
            v["quantile"] * v["std"] / abs(v["value"]), rel=1e-10), k
    assert c["E1"]["effective_dof"] == pytest.approx(197, abs=15)
    g = doc["global_uncertainty"]["Gxz"]
    # Gxz = (G13 + G23) / 2 here: the fixed values' moves are secants, G sinh(+-sd in ln G)
    # along their principal axes (0.83 with the tangent G sd, stop 30's first count); all of
    # it spread, known on the stated sigma: the normal quantile (t(9) gave 1.31)
    assert g["rel_half_width"] == pytest.approx(1.136, abs=0.05)
    assert g["rel_half_width"] == pytest.approx(
        stats.norm.ppf(0.975) * g["std"] / abs(g["value"]), rel=1e-9)
    r = read_result(out)
    assert r.uncertainty.spread_counted == tuple(u["spread_counted"])
    for k in ("E1", "E2", "G12"):
        assert r.uncertainty.given_fixed[f"IM7/977-2.{k}"] == pytest.approx(
            c[k]["rel_half_width_given_fixed"], rel=1e-12)
        assert r.uncertainty.get("IM7/977-2", k).rel_half_width == pytest.approx(
            c[k]["rel_half_width"], rel=1e-12)
    fig = result_page(out, "intervals")
    titles = [a.get_legend().get_title().get_text() for a in fig.axes if a.get_legend()]
    assert any("the intervals count the spread the fixed G13, G23, nu12 had before fixing" in t
               for t in titles), titles
    assert not any("Monte Carlo" in t for t in titles), titles
    # with a Monte Carlo, its trials draw the fixed values from that spread too, so its range
    # counts it as the intervals drawn beside it do: the legend says so
    _, out2 = s11_monte_carlo
    fig = result_page(out2, "intervals")
    titles = [a.get_legend().get_title().get_text() for a in fig.axes if a.get_legend()]
    assert any("had before fixing (see page 1 for the widths given them);\nthe Monte Carlo "
               "trials drew them from that spread too (shortened to the search's range): "
               "their range counts it" in t for t in titles), titles
    note = [n for n in table_notes(r) if n.startswith("the intervals count the spread")]
    # as the terminal writes them (one decimal: a width of 0.4 % is no "±0 %")
    assert note and "given the fixed values alone: E1 ±1.3 %, E2 ±10.6 %, G12 ±12.9 %" in note[0]
    text = CliRunner().invoke(cli, ["identify", S11, "--fix-undetermined", "--no-output"])
    assert ("count the spread G13, G23, nu12 had before they were fixed" in text.output
            and "given the fixed values alone: E1 ±1.3 %" in text.output), text.output


def test_std_stated_counts_the_spread_as_std_does():
    """std_stated is the standard error from the stated frequency sigma alone: with the
    stated scaling it is std. Counting the fixed values' spread replaced std and kept
    std_stated given the fixed values (the linear problem: E1 0.47 % of its value against
    0.83 %), so the file's std and std_stated disagreed on what they were of."""
    obs, state = _linear_problem()
    before = linearized_uncertainty([obs], [state(CONSTANT_NAMES)], scaling="stated")
    free = ("E1", "E2", "G12")
    after = linearized_uncertainty([dataclasses.replace(obs, dlam_dP=obs.dlam_dP[:, :3])],
                                   [state(free)], scaling="stated")
    total = counting_fixed_spread(after, before, [obs], [state(free)])
    np.testing.assert_allclose(total.std_stated, total.std, rtol=1e-12)
    np.testing.assert_allclose(total.std_stated, before.std_stated[:3], rtol=1e-9)
    # with the residuals' scaling, each part is divided by its own run's variance factor
    before_r = dataclasses.replace(before, covariance=before.covariance * 3.0,
                                   std=before.std * np.sqrt(3.0), variance_factor=3.0)
    after_r = dataclasses.replace(after, covariance=after.covariance * 2.0,
                                  std=after.std * np.sqrt(2.0), variance_factor=2.0)
    total_r = counting_fixed_spread(after_r, before_r, [obs], [state(free)])
    np.testing.assert_allclose(total_r.std_stated, total.std_stated, rtol=1e-9)


def test_a_huge_spread_counts_only_as_far_as_the_search_goes():
    """S1.3 --fix-undetermined fixes E2, G13, G23, nu12; G13's spread before fixing was +-60
    times (in ln G). The tangent count takes E1 to +-91 % (E1 leans on G13 one for one at
    3.1 GPa, times e^+-59); the secants along the fixed values' principal axes, each step kept
    within the search's factor range (3.1 / 5 .. 3.1 x 5 GPa), give +-6.3 % (the interval
    given the fixed values alone: +-2.2 %)."""
    from laminid_cli.uncertainty import UncertaintyOptions, assess, material_states

    spec = read_specimen("specimens/example1/S1.3.yaml")
    fm = build_forward_model(spec)
    a = assess(fm, IdentifyOptions(), UncertaintyOptions(fix_undetermined=True))
    u = a.uncertainty
    assert set(a.fixed_undetermined) == {f"IM7/977-2.{k}" for k in ("E2", "G13", "G23", "nu12")}
    k = u.labels.index("IM7/977-2.E1")
    assert u.rel_half_width[k] == pytest.approx(0.060, abs=0.01)
    assert u.rel_half_width_given_fixed[k] == pytest.approx(0.022, abs=0.003)
    sigma = frequency_sigma(spec.measured, 0.002)
    cond = uncertainty_of(a.result, fm, sigma)
    obs = [observations(fm, a.result, sigma, cond.labels + cond.fixed)]
    tangent = counting_fixed_spread(cond, a.before_fixing, obs, material_states(a.result))
    assert tangent.rel_half_width[k] > 0.5


def test_monte_carlo_table_counts_the_fixed_values_spread_as_the_intervals_do(s11_monte_carlo):
    """S1.1 --fix-undetermined --monte-carlo 8: the intervals count the fixed values' spread
    (E1 +-2.9 %, std 2.05 GPa), and so do the Monte Carlo trials, which draw the fixed G13,
    G23, nu12 from it: the table's "linearised std" is the one the intervals use (2.05 GPa,
    not 0.95 GPa given the fixed values), and a line under the table says so, with the range
    of the trials that held the fixed values instead (what --fix-undetermined judges its flags
    on). Until the trials drew them, they held them, and the table said its column was given
    the fixed values."""
    output, _ = s11_monte_carlo
    table = output[output.index("Monte Carlo check:"):]
    flat = " ".join(table.split())
    assert "the fixed G13, G23, nu12 drawn from their spread before fixing" in flat
    row = next(x for x in table.splitlines() if x.startswith("  E1 "))
    assert row.split()[1:3] == ["2.05", "GPa"], row
    assert ("linearised std and ratio: counting the fixed values' spread, as the intervals "
            "above; the trials holding the fixed values instead (what --fix-undetermined judges "
            "its flags on" in flat)
    assert "(the trials hold them)" not in flat
    plain = CliRunner().invoke(cli, ["identify", S11, "--monte-carlo", "8", "-j", "1",
                                     "--no-output"])
    assert plain.exit_code == 0 and "linearised std and ratio" not in plain.output


def test_a_constant_flagged_by_the_counted_spread_is_not_told_to_use_fix_undetermined():
    """S1.2 --fix-undetermined --max-rel-interval 0.25: G12 is within +-9.4 % given the fixed
    values alone and +-27.7 % counting their spread, so it is flagged; the flag line told the
    user to "fix them (--fix-undetermined)", the option this run was made with (which judges
    its flags given the fixed values, so it fixes nothing more). It now says the spread of
    the fixed values makes it so, and to --fix values the lab knows. (At the default 0.30 it
    was flagged at +-31 %, before its quantile was Welch-Satterthwaite's.)"""
    res = CliRunner().invoke(cli, ["identify", "specimens/example1/S1.2.yaml",
                                   "--fix-undetermined", "--max-rel-interval", "0.25",
                                   "--no-output"])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.output.splitlines() if x.startswith("  flagged (half-width"))
    assert "IM7/977-2.G12" in line and "(--fix-undetermined)" not in line
    assert ("IM7/977-2.G12 within ±9.4 % given the fixed values alone: their spread before "
            "fixing makes it so" in line), line
    assert "put values you know in the specimen file and --fix them" in line
    # without --fix-undetermined the advice stays
    plain = CliRunner().invoke(cli, ["identify", "specimens/example1/S1.2.yaml", "--no-output"])
    line = next(x for x in plain.output.splitlines() if x.startswith("  flagged (half-width"))
    assert "fix them (--fix-undetermined)" in line


def test_welch_satterthwaite_closed_forms():
    """effective_dof against its closed forms: two equal parts with nu each give 2 nu; a part
    of zero leaves the other's; an exact part (nu infinite) adds nothing below, so a variance
    that is 80 % exact has nu / 0.2^2 = 25 nu; both exact give infinity (the normal quantile,
    1.95996)."""
    from laminid_cli.intervals import effective_dof, quantile_of

    inf = float("inf")
    assert effective_dof(1.0, 9, 1.0, 9) == pytest.approx(18.0, rel=1e-14)
    assert effective_dof(2.0, 9, 0.0, 6) == pytest.approx(9.0, rel=1e-14)
    assert effective_dof(0.0, 9, 2.0, 6) == pytest.approx(6.0, rel=1e-14)
    assert effective_dof(0.2, 9, 0.8, inf) == pytest.approx(9 / 0.2 ** 2, rel=1e-12)
    assert effective_dof(1.0, inf, 1.0, inf) == inf
    np.testing.assert_allclose(effective_dof([1.0, 0.2], 9, [1.0, 0.8], inf),
                               [36.0, 225.0], rtol=1e-12)
    assert quantile_of(0.95, inf) == pytest.approx(1.959963984540054, rel=1e-14)
    assert quantile_of(0.95, 9) == pytest.approx(2.2621571627982036, rel=1e-12)
