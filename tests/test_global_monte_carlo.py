"""The laminate's global properties over the Monte Carlo trials
(laminid_cli.global_uncertainty.MonteCarloRange): each trial's properties at its own constants
(free from the trial, drawn fixed values from the trial, the others the result's), their range
as the constants' (quantiles, the range for sure, ends set by trials on a search limit), the
verdict by the constants' rule, and the range in --json, the HDF5 file, the terminal and the
report's laminate line."""

import json
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from laminid_cli.global_uncertainty import KEYS, global_intervals
from laminid_cli.material import ElasticConstants
from laminid_cli.uncertainty import MonteCarlo, range_ends_at_bound, sorted_ends_at_bound
from tests.mcfix import sure_width

from tests.test_global_uncertainty import C0, LABELS, laminate


def fake_u(labels, rel=0.01):
    """An uncertainty over ``labels``: ``rel`` relative sd on moduli, 0.01 on nu12."""
    v = np.array([getattr(C0, lab.rsplit(".", 1)[1]) for lab in labels])
    sd = np.where([lab.endswith("nu12") for lab in labels], 0.01, rel * v)
    return SimpleNamespace(labels=tuple(labels), covariance=np.diag(sd ** 2), std=sd,
                           quantile=1.959963984540054, at_bound=None, value=v)


def fake_mc(labels, samples, fixed_labels=(), fixed_samples=None, trial_at_bound=None):
    """A MonteCarlo of ``samples`` (n, p) over ``labels``, as monte_carlo returns it."""
    n, p = samples.shape
    z = np.zeros(p, int)
    return MonteCarlo(labels=tuple(labels), n_trials=n, n_converged=n, samples=samples,
                      mean=samples.mean(0), std=samples.std(0, ddof=1),
                      lower=np.quantile(samples, 0.025, 0), upper=np.quantile(samples, 0.975, 0),
                      linearized_std=np.ones(p), ratio=np.ones(p), sigma_factor=1.0, seed=0,
                      jobs=1, time_s=0.0, at_lower_bound=z, at_upper_bound=z,
                      fixed_labels=tuple(fixed_labels), fixed_samples=fixed_samples,
                      trial_at_bound=trial_at_bound)


def draws(labels, n, rel, seed=3):
    rng = np.random.default_rng(seed)
    v = np.array([getattr(C0, lab.rsplit(".", 1)[1]) for lab in labels])
    return v * (1 + rel * rng.standard_normal((n, v.size)))


def test_each_trial_at_its_own_constants_free_drawn_and_the_results():
    """[0/45/-45/90]s with E1, E2, G12, nu12 free, G13 fixed because undetermined and drawn by
    each trial, G23 fixed by the user: each property's range is the 2.5/97.5 % quantiles of
    the properties the test computes itself, trial by trial, through Laminate.with_constants
    (free values from the trial, G13 from its draw, G23 the result's), to 1e-12; the range for
    sure is the binomial order statistics' (tests/mcfix.sure_width)."""
    lam = laminate([0, 45, -45, 90, 90, -45, 45, 0])
    free = ("m.E1", "m.E2", "m.G12", "m.nu12")
    n = 200
    x = draws(free, n, 0.03)
    g13 = draws(("m.G13",), n, 0.2, seed=5)
    u = SimpleNamespace(**vars(fake_u(free)), spread_counted=("m.G13",),
                        spread_covariance=np.array([[(0.2 * C0.G13) ** 2]]),
                        spread_cross=np.zeros((4, 1)))
    mc = fake_mc(free, x, ("m.G13",), g13)
    out = global_intervals(lam, {"m": C0}, u, fixed_undetermined=("m.G13",), mc=mc)
    ref = np.array([list(lam.with_constants([ElasticConstants(
        E1=r[0], E2=r[1], G12=r[2], G13=g[0], G23=C0.G23, nu12=r[3])]).global_properties()
        .as_dict().values()) for r, g in zip(x, g13)])
    for i, key in enumerate(("Ex", "Ey", "Gxy", "Gxz", "Gyz", "nu_xy", "nu_yx")):   # (order)
        m = out[key].monte_carlo
        lo, hi = np.quantile(ref[:, i], [0.025, 0.975])
        assert m.lower == pytest.approx(lo, rel=1e-12, abs=0), key
        assert m.upper == pytest.approx(hi, rel=1e-12, abs=0), key
        assert m.std == pytest.approx(ref[:, i].std(ddof=1), rel=1e-10), key
        assert m.rel(out[key].value)[1] == pytest.approx(
            sure_width(ref[:, i], out[key].value), rel=1e-10), key
    # Gxz of this laminate moves with G13's draw (G23 is held): 0.2 spread on G13
    assert out["Gxz"].monte_carlo.rel(out["Gxz"].value)[0] > 0.1
    d = out["Ex"].as_dict()
    assert d["verdict_from"] == "linearised" and d["monte_carlo"]["lower"] == \
        out["Ex"].monte_carlo.lower


def test_a_property_the_trials_do_not_move_gets_no_range():
    """A cross-ply's Gxz, Gyz depend on G13 and G23 only: both fixed by the user, they are an
    assumption and get no Monte Carlo range (JSON "monte_carlo": null, NaN widths); G23 fixed
    because undetermined and held by the trials (not drawn): none either. Ex keeps one."""
    lam = laminate([0, 90, 90, 0])
    free = ("m.E1", "m.E2", "m.G12", "m.nu12")
    mc = fake_mc(free, draws(free, 40, 0.02))
    out = global_intervals(lam, {"m": C0}, fake_u(free), mc=mc)
    for key in ("Gxz", "Gyz"):
        assert out[key].monte_carlo is None, key
        d = out[key].as_dict()
        assert d["monte_carlo"] is None and np.isnan(d["monte_carlo_rel_half_width"])
    assert out["Ex"].monte_carlo is not None
    free = ("m.E1", "m.E2", "m.G12", "m.G13", "m.nu12")
    mc = fake_mc(free, draws(free, 40, 0.02))
    u = fake_u(free)
    out = global_intervals(lam, {"m": C0}, u, fixed_undetermined=("m.G23",), mc=mc)
    assert out["Gxz"].monte_carlo is None and not out["Gxz"].identified
    # without a Monte Carlo: no such keys at all (files and JSON as before)
    assert "monte_carlo" not in global_intervals(lam, {"m": C0}, u)["Ex"].as_dict()


def test_the_verdict_follows_the_constants_rule_on_its_own_range():
    """[0]4 (Ex = E1): interval ±2 % (well determined), trials spread 10 % (for sure about
    ±17 %): "weak (Monte Carlo)", as a constant's would be; the words that the Monte Carlo
    found a constant less determined are not added beside the property's own range. Trials
    within the interval leave the verdict alone."""
    lam = laminate([0, 0, 0, 0])
    u = SimpleNamespace(**vars(fake_u(LABELS)), verdict_from_monte_carlo=("m.E1",))
    out = global_intervals(lam, {"m": C0}, u, mc=fake_mc(LABELS, draws(LABELS, 200, 0.1)))
    assert out["Ex"].rel_half_width == pytest.approx(0.0196, rel=1e-3)
    assert out["Ex"].verdict == "weak (Monte Carlo)"
    assert out["Ex"].as_dict()["verdict_from"] == "monte_carlo"
    out = global_intervals(lam, {"m": C0}, u, mc=fake_mc(LABELS, draws(LABELS, 200, 0.005)))
    assert out["Ex"].verdict == "well determined" and not out["Ex"].verdict_from_monte_carlo


def test_range_ends_set_by_trials_on_a_search_limit():
    """The rule of the constants' ends (uncertainty.range_ends_at_bound) read off the sorted
    trials gives the same flags where the trials on a limit are the smallest, the far end
    included; a property is flagged where its end's trial has a constant it depends on on a
    limit (a cross-ply's Gxz with the 8 lowest-G23 trials on G23's lower limit; Ex, which does
    not depend on G23, is not)."""
    for n in (5, 10, 40, 41, 200):
        x = np.arange(n, dtype=float)
        for k in range(n + 1):
            lim = np.arange(n) < k
            assert sorted_ends_at_bound(x, lim, 0.95) == tuple(
                bool(f) for f in range_ends_at_bound(k, 0, n, 0.95)), (n, k)
    lam = laminate([0, 90, 90, 0])
    x = draws(LABELS, 200, 0.05)
    flags = np.zeros(x.shape, np.int8)
    flags[np.argsort(x[:, 4])[:8], 4] = -1          # G23's lowest trials on its lower limit
    out = global_intervals(lam, {"m": C0}, fake_u(LABELS), mc=fake_mc(LABELS, x,
                                                                       trial_at_bound=flags))
    g = out["Gxz"].monte_carlo
    assert g.trials_at_bound == 8 and not g.upper_at_bound
    # whether Gxz's lower end is one of them is its own trials' order: the test's
    order = np.argsort(np.array([lam.with_constants([ElasticConstants(*r)])
                                 .global_properties().Gxz for r in x]))
    assert g.lower_at_bound == bool(flags[order[5], 4])   # 0.025 x 199 = 4.975: the 6th
    assert g.lower_at_bound
    assert out["Ex"].monte_carlo.trials_at_bound == 0 and not out["Ex"].monte_carlo.lower_at_bound


def test_monte_carlo_ranges_in_json_hdf5_terminal_and_report(tmp_path):
    """identify S1.1 --mesh 6x6 --monte-carlo 10: each property's Monte Carlo range in --json
    (global_uncertainty.<key>.monte_carlo), the HDF5 file
    (/global_properties_uncertainty/monte_carlo/lower...), the terminal's table and the
    report's laminate line; Ex's range is the quantiles of Ex computed here from the file's
    trials (/uncertainty/monte_carlo/samples) through the laminate, to 1e-12."""
    from laminid_cli.commands.text import format_global
    from laminid_cli.laminate import laminate_from_specimen
    from laminid_cli.report import _laminate_text
    from laminid_cli.resultfile import read_result
    from laminid_cli.specimen import read_specimen
    from tests.clihelp import run

    out = tmp_path / "s.h5"
    r = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "6x6", "--monte-carlo",
            "10", "--json", "-o", str(out))
    assert r.exit_code == 0, r.output
    gu = json.loads(r.output)["global_uncertainty"]
    with h5py.File(out) as f:
        mc = f["uncertainty/monte_carlo"]
        labels = [x.decode() for x in f["uncertainty/labels"][()]]
        samples = mc["samples"][()]
        h = f["global_properties_uncertainty"]
        keys = [k.decode() for k in h["keys"][()]]
        lower = h["monte_carlo/lower"][()]
        assert {"upper", "inner_lower", "inner_upper", "lower_at_bound", "upper_at_bound",
                "trials_at_bound", "std", "mean"} <= set(h["monte_carlo"])
        assert "monte_carlo_rel_half_width_lower" in h
        assert "verdict_from_monte_carlo" in h.attrs
    lam = laminate_from_specimen(read_specimen("specimens/example1/S1.1.yaml"))
    ex = [lam.with_constants([ElasticConstants(**dict(zip(
        [lab.rsplit(".", 1)[1] for lab in labels], row)))]).global_properties().Ex
        for row in samples]
    lo, hi = np.quantile(ex, [0.025, 0.975])
    assert gu["Ex"]["monte_carlo"]["lower"] == pytest.approx(lo, rel=1e-12, abs=0)
    assert gu["Ex"]["monte_carlo"]["upper"] == pytest.approx(hi, rel=1e-12, abs=0)
    assert lower[keys.index("Ex")] == gu["Ex"]["monte_carlo"]["lower"]
    plate = read_result(out).plates[0]
    assert plate.global_uncertainty["Ex"]["monte_carlo"]["upper"] == \
        gu["Ex"]["monte_carlo"]["upper"]
    line = _laminate_text(plate)
    assert f"(Monte Carlo {lo / 1e9:.2f}–{hi / 1e9:.2f} GPa)" in line
    table = format_global(json.loads(r.output)["global_properties"], gu)
    row = next(t for t in table if t.startswith("  Ex [GPa]"))
    assert f"{lo / 1e9:.2f} .. {hi / 1e9:.2f}" in row
