"""How far the fit lets a constant on a limit of the search go (laminid_cli.uncertainty.Profile):
the bisection against closed forms, a thick plate whose G13 the search stops above its truth
(the bound checked by identifying the others again at it), and S2.1's flat G13 in --json, the
HDF5 file, the terminal and the report."""

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.identify import IdentifyOptions, identify
from laminid_cli.uncertainty import (PROFILE_SAME, PROFILE_TOL, UncertaintyOptions, assess,
                                     frequency_sigma, profile_bound, uncertainty_of)
from tests.clihelp import without_comments
from tests.figs import result_page
from tests.test_identify import CARBON, OFF_THICK, THICK, synthetic

Q2 = 1.959963984540054 ** 2


def test_bisection_against_closed_forms():
    """A chi2 rise quadratic in ln G (standard error 0.3 in ln G): the bound is
    L exp(0.3 q), within the bisection's 2 % in ln G and never below it (the returned end
    is rejected); a rise quadratic in nu12 (0.1) from 0.95 down: 0.95 - 0.196 within 0.02; a
    rise that stays below q^2 up to the far end and in the middle: no bound, and the statement
    says so; a rise above q^2 in the middle but not at the far end (a second valley), or a
    fit better than on the limit (a rise below zero): no profile, and why."""
    L, far = 3e9, 30e9
    calls = []

    def quad(v):
        calls.append(v)
        return (np.log(v / L) / 0.3) ** 2

    p = profile_bound("m.G13", "lower", L, far, quad, Q2)
    exact = L * np.exp(0.3 * np.sqrt(Q2))
    assert 0 <= np.log(p.bound / exact) <= PROFILE_TOL
    assert p.runs == len(calls) <= 9 and p.text.startswith("the fit rejects G13 above 5.4")
    p = profile_bound("m.nu12", "upper", 0.95, 0.0, lambda v: ((0.95 - v) / 0.1) ** 2, Q2)
    assert p.bound == pytest.approx(0.95 - 0.1 * np.sqrt(Q2), abs=0.02)
    assert p.bound <= 0.95 - 0.1 * np.sqrt(Q2) and f"below {p.bound:.3g}" in p.text
    p = profile_bound("m.G13", "lower", L, far, lambda v: 0.1 * np.log(v / L), Q2)
    assert np.isnan(p.bound) and p.runs == 2               # the far end and the middle
    assert p.delta_far == pytest.approx(0.1 * np.log(10)) and "up to 30 GPa" in p.text
    assert "the modes do not determine G13" in p.text
    # a second valley (rejected in the middle, not at the far end) is no profile
    p = profile_bound("m.G13", "lower", L, far,
                      lambda v: 10 * np.sin(np.pi * np.log(v / L) / np.log(far / L)) ** 2, Q2)
    assert np.isnan(p.bound) and p.error and "second valley" in p.text
    # a fit better than on the limit: the search stopped short of it
    p = profile_bound("m.G13", "lower", L, far, lambda v: -1.0 if v > 2 * L else 0.0, Q2)
    assert np.isnan(p.bound) and "the fit is better with G13 = 30 GPa" in p.text


def test_a_cliff_the_fits_do_not_narrow_is_stated_as_a_bracket():
    """A rise flat (0.3) up to a cliff just below the far end and 700 beyond it, as hybrid
    CM's glass G12 on 12x12 (0.30 at 16.7 GPa, 326 at 18.0, limit 0.0056, far end 18.5):
    every fit but the far end's is below q^2, each halves the bracket's log width (8.1), and
    its PROFILE_RUNS + 1 fits end before 2 %. The bound is the far side of the last bracket
    (rejected there: true) and the statement gives its near side, not rejected, and says the
    crossing between them was not narrowed further; a smooth rise there, which the secant
    narrows, says neither."""
    L, far, cliff = 0.0056e9, 18.5e9, 17.5e9

    def step(v):
        return 700.0 if v >= cliff else 0.3

    p = profile_bound("glass.G12", "lower", L, far, step, Q2)
    assert p.bound == pytest.approx(far, rel=1e-12) and p.runs == 9
    near = float(re.search(r"not rejected at ([\d.]+) GPa", p.text).group(1)) * 1e9
    assert near < cliff <= p.bound and np.log(far / near) > PROFILE_TOL
    assert p.text.startswith("the fit rejects G12 above 18.5 GPa") and \
        "the crossing between the two not narrowed further in 9 fits" in p.text
    # a steep but smooth rise over the same scan (0.3, then quadratic in ln G, standard error
    # 0.02, from 17.5 GPa):
    # the secant narrows it to 2 %, and the words give no bracket
    p = profile_bound("glass.G12", "lower", L, far,
                      lambda v: 0.3 + (max(np.log(v / 17.5e9), 0.0) / 0.02) ** 2, Q2)
    assert 0 <= np.log(p.bound / (17.5e9 * np.exp(0.02 * np.sqrt(Q2 - 0.3)))) <= PROFILE_TOL
    assert "not narrowed" not in p.text


def test_a_thick_plate_whose_g13_stops_above_its_truth():
    """a/h = 10 cross-ply, 8 modes with 0.2 % noise, true G13 3.1 GPa, initial 5.58 GPa and
    a search factor of 1.5 (lower limit 3.72 GPa): G13 stops on that limit. Its profile bound
    is where identifying the others again with G13 held there raises chi2 (scaled as the
    intervals) to q^2: checked here by two such identifications, at the bound (rise >= q^2)
    and 2.1 % below it in ln G (rise <= q^2)."""
    off = {k: 1.0 for k in OFF_THICK} | {"G13": 1.8, "E2": 0.7}
    fm, _ = synthetic(THICK, {"cf": CARBON}, 8, off, noise=0.002, seed=4)
    opts = IdentifyOptions(parametrization="constants", bound_factor=1.5, fix=("nu12",))
    a = assess(fm, opts, UncertaintyOptions())
    u = a.uncertainty
    assert [lab for lab, b in zip(u.labels, u.at_bound) if b] == ["cf.G13"]
    p = u.profiles["cf.G13"]
    assert p.limit == pytest.approx(5.58e9 / 1.5, rel=1e-9)
    assert 1.05 * p.limit < p.bound < 1.5 * p.limit, p
    sigma = frequency_sigma(fm.specimen.measured, 0.002)

    def rise(g13):
        mat = fm.specimen.materials["cf"]
        spec = dataclasses.replace(fm.specimen, materials={"cf": dataclasses.replace(
            mat, constants=dataclasses.replace(mat.constants, G13=g13))})
        fm_g = dataclasses.replace(fm, specimen=spec)
        r = identify(fm_g, dataclasses.replace(opts, fix=("nu12", "G13")))
        assert r.converged
        return (uncertainty_of(r, fm_g, sigma).chi2 - u.chi2) / u.variance_factor

    q2 = u.quantile ** 2
    assert rise(p.bound) >= 0.999 * q2
    assert rise(p.bound * np.exp(-1.05 * PROFILE_TOL)) <= q2
    assert "the fit rejects G13 above" in p.text


def test_s21_g13_is_flat_in_json_hdf5_terminal_and_report(s21_8x8, s21_8x8_terminal):
    """S2.1 (8x8): G13 stops on its lower limit, and the fit is as good up to the search's
    other end, 5 x 3.7 = 18.5 GPa (chi2 rises by 3.9 where 5.59 would reject it; 0.4 at
    12x12, the identify default): the
    same statement in --json, the HDF5 reader, the terminal and the report's cell."""
    from laminid_cli.report import interval_text
    from laminid_cli.resultfile import read_result

    doc, out = s21_8x8                   # conftest.py: identify S2.1 --mesh 8x8 --json -o
    g13 = doc["uncertainty"]["constants"]["E-glass/R368"]["G13"]
    prof = g13["profile"]
    assert g13["at_bound"] and prof["bound"] is None and prof["far"] == pytest.approx(18.5e9)
    assert prof["delta_chi2_far"] == pytest.approx(3.9, abs=0.4)      # of 5.59: flat
    assert prof["text"].startswith("the fit is as good with G13 anywhere above the limit up "
                                   "to 18.5 GPa, the end of the scan: 5 x the initial value "
                                   "(chi2 rises by")
    assert "not tried beyond): the modes do not determine G13 there" in prof["text"]
    iv = read_result(out).uncertainty.get("E-glass/R368", "G13")
    assert iv.profile_text == prof["text"] and np.isnan(iv.profile_bound)
    assert iv.profile_far == pytest.approx(18.5e9)
    assert interval_text("G13", iv).endswith("profile: flat to 18.50")       # as the terminal
    fig = result_page(out, "intervals")
    a = next(x for x in fig.axes if x.get_gid() == "interval-E-glass/R368.G13")
    stmt = next(t for t in a.texts if t.get_gid() == "bound-statement").get_text()
    assert stmt.replace("\n", " ") == "stopped on the lower search limit: no interval", stmt
    # the values the fit does not reject: dotted from the limit up to 18.5 GPa, 6300 x the
    # limit, on a log panel (on a linear one, 0 .. 0.0035 GPa, it ran off the top), an arrow
    # head there (the end of the scan, not tried beyond: no cap, which says the fit rejects
    # what lies beyond) with the far end's value beside it
    assert a.get_yscale() == "log"
    line = next(x for x in a.lines if x.get_gid() == "profile")
    (x0, x1), (y0, y1) = line.get_data()
    ymin, ymax = a.get_ylim()
    assert y0 == pytest.approx(prof_limit := iv.value / 1e9, rel=1e-9)
    assert y1 == pytest.approx(18.5, rel=1e-9)
    cap = next(x for x in a.lines if x.get_gid() == "profile-cap")
    assert cap.get_marker() == "^" and cap.get_ydata()[0] == y1
    label = next(t for t in a.texts if t.get_gid() == "profile-label").get_text()
    assert label == "profile:\nflat to\n18.50" and ymin < prof_limit and 18.5 < ymax < 40
    text = s21_8x8_terminal              # conftest.py: identify S2.1 --mesh 8x8 --no-output
    assert "none: flat to 18.50" in text and "profile: the fit is as good" in text


def test_a_bounded_profile_in_status_json_hdf5_and_report(tmp_path):
    """The thick plate through the command line (G13's initial value 24.8 GPa, limit 4.96 GPa
    = initial / 5 with --parametrization constants): G13 stops on its limit and the fit
    rejects it above a value; the status, --json, the HDF5 reader and the report's panel (a
    dotted line from the limit to that value, in GPa) agree."""
    from laminid_cli.resultfile import read_result

    spec = thick_yaml(tmp_path)
    out = tmp_path / "thick.h5"
    res = CliRunner().invoke(cli, ["identify", str(spec), "--mesh", "6x6", "--parametrization",
                                   "constants", "--fix", "nu12", "--json", "-o", str(out)])
    assert res.exit_code == 0, res.output
    d = json.loads(res.output)
    g13 = d["uncertainty"]["constants"]["cf"]["G13"]
    assert g13["at_bound"] and g13["bound_limit"] == pytest.approx(4.96e9, rel=1e-9)
    bound = g13["profile"]["bound"]
    assert 4.96e9 * 1.01 < bound < 24.8e9
    at = next(r["text"] for r in d["reasons"] if r["code"] == "at_bound")
    assert f"the fit rejects G13 above {bound / 1e9:.3g} GPa" in at
    iv = read_result(out).uncertainty.get("cf", "G13")
    assert iv.profile_bound == pytest.approx(bound, rel=1e-12)
    fig = result_page(out, "intervals")
    panel = next(a for a in fig.axes if a.get_gid() == "interval-cf.G13")
    line = next(ln for ln in panel.get_lines() if ln.get_gid() == "profile")
    np.testing.assert_allclose(line.get_ydata(), [4.96, bound / 1e9], rtol=1e-6)
    assert panel.get_ylim()[1] > bound / 1e9


def test_e2_on_its_lower_limit_gets_a_profile_below_e1():
    """E2 on its lower factor limit where the scan's far end (10 x the limit here, or the
    factor limit bound_factor x initial E2) lies above the initial E1: holding E2 there made
    every identification of the profile refuse its specimen ("initial E2 > E1; direction 1
    must be the fibre direction") and the constant got no profile. The scan now ends at the
    initial E1 (E2 <= E1), and the profile is made."""
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import read_specimen

    spec = read_specimen("specimens/example2/S2.1.yaml")
    (name, m), = spec.materials.items()
    m = dataclasses.replace(m, constants=dataclasses.replace(m.constants, E1=30e9, E2=12e9,
                                                             G12=2.8e9))
    fm = build_forward_model(dataclasses.replace(spec, materials={name: m}), (8, 8))
    a = assess(fm, IdentifyOptions(bound_factor=1.3, fix=("G13", "G23")), UncertaintyOptions())
    u = a.uncertainty
    lab = f"{name}.E2"
    assert [x for x, b in zip(u.labels, u.at_bound) if b] == [lab]
    p = u.profiles[lab]
    assert not p.error, p.text
    assert p.limit < p.far <= 30e9
    assert np.isfinite(p.bound) or p.text.startswith("the fit is as good")


def _fail_fits_holding_g13(monkeypatch):
    """Every identification with G13 held (a profile's) fails in the eigen solver: identify()'s
    and the reduced model's from the optimum (uncertainty.refit_reduced)."""
    import laminid_cli.identify as ident
    import laminid_cli.uncertainty as unc
    from laminid_cli.errors import SolverError

    real = ident.identify
    real_reduced = unc.refit_reduced

    def failing(fm, options, *args, **kw):
        if any(str(f).endswith("G13") for f in options.fix):
            raise SolverError("the stiffness matrix is not positive definite")
        return real(fm, options, *args, **kw)

    def failing_reduced(model, result, fms, sigmas, kw, held, *args, **k):
        if any(lab.endswith("G13") for lab in held):
            raise SolverError("the stiffness matrix is not positive definite")
        return real_reduced(model, result, fms, sigmas, kw, held, *args, **k)

    monkeypatch.setattr(ident, "identify", failing)
    monkeypatch.setattr(unc, "refit_reduced", failing_reduced)


def test_a_profile_whose_identification_fails_in_the_solver_does_not_end_the_run(monkeypatch):
    """An identification of the profile that fails in the model or the eigen solver (a
    SolverError, not a FitError) gave a traceback and lost the result already made; now that
    constant gets 'no profile' with the reason, like a profile whose fit did not converge."""
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import read_specimen

    _fail_fits_holding_g13(monkeypatch)
    fm = build_forward_model(read_specimen("specimens/example2/S2.1.yaml"), (8, 8))
    u = assess(fm, IdentifyOptions(), UncertaintyOptions()).uncertainty
    p = u.profiles["E-glass/R368.G13"]
    assert np.isnan(p.bound) and "not positive definite" in p.error
    assert p.text.startswith("no profile:")


def test_the_rise_is_zero_at_the_limit_with_a_prior_on_the_held_constant(tmp_path,
                                                                         monkeypatch):
    """chi2 (paper Eq. 17 + Eq. 15) counts a prior row of each free constant. Holding a
    constant with a prior dropped its row from the profile's fits, so the rise left out the
    prior's part: at the limit itself it was minus that part instead of 0 (S2.1 6x6, prior on
    G13 at its lower factor limit: -40000 before scaling), and the fit looked better than the
    optimum wherever the constant was held. The held value's prior row is counted now."""
    import laminid_cli.uncertainty as unc
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import read_specimen

    text = Path("specimens/example2/S2.1.yaml").read_text().replace(
        "    nu12: 0.28\n", "    nu12: 0.28\n    prior: {G13: 0.000001}\n")
    path = tmp_path / "S2.1-prior.yaml"
    path.write_text(text)
    seen = {}
    real = unc.profile_bound

    def spy(label, side, limit, far, delta, threshold, confidence=0.95, **kw):
        seen[label] = (limit, delta)
        return real(label, side, limit, far, delta, threshold, confidence, **kw)

    monkeypatch.setattr(unc, "profile_bound", spy)
    fm = build_forward_model(read_specimen(path), (6, 6))
    # one process: the spy sees the profiles made here (jobs > 1 forks them)
    u = assess(fm, IdentifyOptions(), UncertaintyOptions(jobs=1)).uncertainty
    lab = "E-glass/R368.G13"
    assert u.at_bound[u.labels.index(lab)]
    limit, delta = seen[lab]
    assert abs(delta(limit)) < 0.05 * u.profiles[lab].threshold


def test_a_constant_fixed_on_a_limit_is_checked_across_the_search(tmp_path,
                                                                  s21_8x8_fix_undetermined):
    """S2.1 (8x8) --fix-undetermined fixes G13, which was on its lower limit (its doubt is not
    known, so the intervals cannot count it): the others are identified again with G13 at
    the search's two ends, 0.0001 E1 and 5 x 3.7 = 18.5 GPa; G12 moves most, 0.6 of its
    half-width, so the status is not made worse by it. Checked by identifying a copy of the
    file with G13 = 18.5 GPa and G13, G23 fixed: G12's move over its half-width is at most
    the reported ratio (the larger of the two ends). The thick plate with E2 and G13 fixed
    on their limits: E1 moves by about three half-widths, an 'undetermined' reason."""
    from laminid_cli.resultfile import read_result

    d, out = s21_8x8_fix_undetermined       # identify S2.1 --mesh 8x8 --fix-undetermined
    fr = d["uncertainty"]["fixed_ranges"]["E-glass/R368.G13"]
    assert read_result(out).uncertainty.fixed_ranges == {"E-glass/R368.G13": fr["text"]}
    assert fr["high"] == pytest.approx(18.5e9) and 2e6 < fr["low"] < 4e6
    assert not fr["moves"] and fr["worst"] == "E-glass/R368.G12"
    assert fr["ratio_to_half_width"] == pytest.approx(0.6, abs=0.1)
    assert not any("moves by" in r["text"] for r in d["reasons"])
    g12 = d["uncertainty"]["constants"]["E-glass/R368"]["G12"]
    text = Path("specimens/example2/S2.1.yaml").read_text()
    assert "    G13: 3.7 GPa\n" in text
    spec = tmp_path / "S2.1-G13.yaml"
    spec.write_text(text.replace("    G13: 3.7 GPa\n", "    G13: 18.5 GPa\n"))
    r = json.loads(CliRunner().invoke(cli, ["identify", str(spec), "--mesh", "8x8", "--fix",
                                            "G13,G23", "--json", "--no-output"]).output)
    move = abs(r["materials"]["E-glass/R368"]["G12"] - g12["value"]) / g12["half_width"]
    assert 0.1 < move <= fr["ratio_to_half_width"] * (1 + 1e-6)

    thick = thick_yaml(tmp_path)
    res = CliRunner().invoke(cli, ["identify", str(thick), "--mesh", "6x6", "--parametrization",
                                   "constants", "--fix", "nu12", "--fix-undetermined", "--json",
                                   "--no-output"])
    d = json.loads(res.output)
    fr = d["uncertainty"]["fixed_ranges"]["cf.G13"]
    assert fr["moves"] and fr["worst"] == "cf.E1" and fr["ratio_to_half_width"] > 2
    und = next(r["text"] for r in d["reasons"] if r["code"] == "undetermined")
    assert "cf.G13: cf.E1 moves by" in und and "its value is not known" in und


def thick_yaml(tmp_path):
    """The thick plate's specimen file (8 modes of the truth with 0.2 % noise) with G13's
    initial value 24.8 GPa: with --parametrization constants its lower limit, initial / 5 =
    4.96 GPa, is above the truth 3.1 GPa."""
    from tests.test_identify import scaled, specimen_text

    off = {k: 1.0 for k in OFF_THICK} | {"G13": 1.8, "E2": 0.7}
    fm, _ = synthetic(THICK, {"cf": CARBON}, 8, off, noise=0.002, seed=4)
    guess = scaled({"cf": CARBON}, off)
    guess["cf"]["G13"] = 24.8e9
    spec = tmp_path / "thick.yaml"
    spec.write_text(specimen_text(THICK, guess, fm.specimen.measured.freq))
    return spec


def _capped_profile_runs(monkeypatch, held: str, max_evaluations: int):
    """identify() of the profile's fits (``held`` among the fixed constants) stopped after
    ``max_evaluations``: as a fit on a flat valley that the profile's 300 do not finish. The
    fits from the optimum on the profile's reduced model (uncertainty.refit_reduced, which
    finish) are refused here, so that identify() makes every fit, as where the reduced fit
    gives no answer."""
    import laminid_cli.identify as ident
    import laminid_cli.uncertainty as unc

    monkeypatch.setattr(unc, "refit_reduced", lambda *args, **kw: None)
    real = ident.identify

    def capped(fm, options, *args, **kw):
        if any(str(f).endswith(held) for f in options.fix):
            options = dataclasses.replace(options, max_evaluations=max_evaluations)
        return real(fm, options, *args, **kw)

    monkeypatch.setattr(ident, "identify", capped)


def test_an_unfinished_fit_below_the_threshold_still_says_not_rejected(monkeypatch):
    """A profile's fit that stops on its evaluation limit has a chi2 at least the fit's: its
    rise bounds the true one from above. Below q^2 that is enough to say the fit does not
    reject the value (hybrid CM's glass E2 had 'no profile: ... did not converge' where it is
    flat); the statement says how many fits were unfinished. Checked here against finished
    fits at the same values: S2.1 (8x8), G13 flat, its fits stopped after 4 evaluations."""
    import laminid_cli.uncertainty as unc
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import read_specimen

    fm = build_forward_model(read_specimen("specimens/example2/S2.1.yaml"), (8, 8))
    lab = "E-glass/R368.G13"
    full = assess(fm, IdentifyOptions(), UncertaintyOptions())
    p_full = full.uncertainty.profiles[lab]
    seen = []
    real_refit = unc.refit_held

    def spy(*args, **kw):
        r, uc = real_refit(*args, **kw)
        seen.append((args[-1], r.converged, uc.chi2))
        return r, uc

    monkeypatch.setattr(unc, "refit_held", spy)
    _capped_profile_runs(monkeypatch, "G13", 4)
    a = assess(fm, IdentifyOptions(), UncertaintyOptions())
    u = a.uncertainty
    p = u.profiles[lab]
    assert not p.error and np.isnan(p.bound) and p.far == pytest.approx(18.5e9)
    unfinished = [(v, chi2) for v, ok, chi2 in seen if not ok]
    # the far end and the middle, each fitted once (from the optimum: a rise below the
    # threshold needs no second start, a local minimum only raises chi2)
    assert len(unfinished) == 2 and len({v for v, _ in unfinished}) == 2
    assert p.text.startswith("the fit is as good with G13 anywhere above the limit up to "
                             "18.5 GPa")
    assert p.text.endswith("2 of its 2 identifications stopped at 4 evaluations: their rise "
                           "is an upper bound, enough to say the fit does not reject those "
                           "values)"), p.text
    # the upper-bound property itself: each unfinished chi2 >= the finished fit's
    monkeypatch.undo()
    for v, chi2 in unfinished:
        uo = UncertaintyOptions()
        kw = dict(scaling=uo.scaling, max_rel_interval=uo.max_rel_interval,
                  confidence=uo.confidence)
        _, uc = unc.refit_held(a.result, [fm], list(a.sigmas), kw, False, lab, v)
        assert uc.chi2 <= chi2 * (1 + 1e-9)
    assert p.delta_far >= p_full.delta_far - 1e-9 * abs(p_full.delta_far)


def test_an_unfinished_fit_above_the_threshold_gives_no_profile(monkeypatch):
    """Above q^2 an unfinished fit says nothing (the finished one may rise less): no profile,
    with the rise it had when it stopped. The thick plate's G13 (rejected above ~5.8 GPa when
    its fits finish), its fits stopped after 2 evaluations."""
    off = {k: 1.0 for k in OFF_THICK} | {"G13": 1.8, "E2": 0.7}
    fm, _ = synthetic(THICK, {"cf": CARBON}, 8, off, noise=0.002, seed=4)
    opts = IdentifyOptions(parametrization="constants", bound_factor=1.5, fix=("nu12",))
    _capped_profile_runs(monkeypatch, "G13", 2)
    p = assess(fm, opts, UncertaintyOptions()).uncertainty.profiles["cf.G13"]
    assert p.text.startswith("no profile: the identification with G13 = ") and np.isnan(p.bound)
    assert "held did not converge in 2 evaluations (chi2 had risen by " in p.text
    assert f"scaled; {p.threshold:.3g} rejects)" in p.text and p.threshold > 3.84  # Student t


def test_a_flat_profile_of_the_values_size_is_drawn_to_its_end(s21_8x8):
    """A flat profile whose far end is of the value's size (hybrid CM's glass E2: 55.5 GPa on
    its upper limit, flat down to 0.9 GPa; carbon nu12 0.95 down to 0) is drawn to that end,
    with an arrow head (the end of the scan: the fit does not reject what lies beyond, it was
    not tried; a cap, as a bounded profile has, said it was rejected) and its value, the
    panel widened to show it, on a linear axis (within a decade
    of the value); a far end a decade and more away is drawn on a log panel (the S2.1 test
    above). S2.1's G13 (8x8) with its far end moved to 2.9 x the limit stands in for it."""
    import dataclasses as dc

    import matplotlib.pyplot as plt

    from laminid_cli.report import interval_panel
    from laminid_cli.resultfile import read_result

    r = read_result(s21_8x8[1])
    m = "E-glass/R368"
    iv = r.uncertainty.get(m, "G13")
    assert iv.at_bound and iv.bound_side == "lower"
    far = 2.9 * iv.value                                   # within 2 x the value above it
    flat = dc.replace(iv, profile_bound=np.nan, profile_far=far,
                      profile_text="the fit is as good with G13 anywhere above the limit")
    u = dc.replace(r.uncertainty, intervals=tuple(flat if x is iv else x
                                                  for x in r.uncertainty.intervals))
    fig, ax = plt.subplots()
    interval_panel(ax, dc.replace(r, uncertainty=u), m, "G13")
    ymin, ymax = ax.get_ylim()
    line = next(x for x in ax.lines if x.get_gid() == "profile")
    assert line.get_ydata()[0] == pytest.approx(iv.value / 1e9)
    assert line.get_ydata()[1] == pytest.approx(far / 1e9) and far / 1e9 < ymax
    assert ax.get_yscale() == "linear"
    cap = next(x for x in ax.lines if x.get_gid() == "profile-cap")
    assert cap.get_marker() == "^" and cap.get_ydata()[0] == pytest.approx(far / 1e9)
    label = next(t for t in ax.texts if t.get_gid() == "profile-label").get_text()
    assert label.split("\n")[:2] == ["profile:", "flat to"]
    plt.close(fig)
    # the same end where the fit rejects beyond it (a bounded profile): a cap
    bounded = dc.replace(flat, profile_bound=far, profile_far=np.nan,
                         profile_text="the fit rejects G13 above")
    ub = dc.replace(r.uncertainty, intervals=tuple(bounded if x is iv else x
                                                   for x in r.uncertainty.intervals))
    fig, ax = plt.subplots()
    interval_panel(ax, dc.replace(r, uncertainty=ub), m, "G13")
    cap = next(x for x in ax.lines if x.get_gid() == "profile-cap")
    assert cap.get_marker() == "_" and cap.get_ydata()[0] == pytest.approx(far / 1e9)
    plt.close(fig)
    # the legend says which end is which where a page has both, and the arrow head alone
    # where it has flat profiles only
    from laminid_cli.report import _interval_legend

    both = dc.replace(u, intervals=u.intervals + (bounded,))
    words = [t for _, t in zip(*_interval_legend(dc.replace(r, uncertainty=both)))
             if t.startswith("values the fit does not reject")]
    assert words == ["values the fit does not reject (profile);\ncap: it rejects beyond; "
                     "arrow head: the end\nof its scan, not tried beyond"]
    words = [t for _, t in zip(*_interval_legend(dc.replace(r, uncertainty=u)))
             if t.startswith("values the fit does not reject")]
    assert words == ["values the fit does not reject (profile);\narrow head: the end of its "
                     "scan, not tried beyond"]


def test_the_check_between_the_limit_and_a_flat_far_end_uses_the_quick_fit():
    """Where the far end is not rejected, one fit in between checks for a second valley; only
    its rise below q^2 is needed, which a fit cut at PROFILE_MID_EVALUATIONS proves as well
    (an upper bound), so profile_bound calls ``quick`` there and ``delta`` everywhere else."""
    from laminid_cli.uncertainty import PROFILE_MID_EVALUATIONS

    assert PROFILE_MID_EVALUATIONS < 300
    calls = {"delta": [], "quick": [], "lenient": []}

    def make(name, rise):
        def f(v):
            calls[name].append(v)
            return rise(v)
        return f

    flat = lambda v: 0.1 * abs(np.log(v / 1e9))            # noqa: E731 - well below Q2
    p = profile_bound("m.G13", "lower", 1e9, 20e9, make("delta", flat), Q2,
                      quick=make("quick", flat), lenient=make("lenient", flat))
    assert np.isnan(p.bound) and not p.error and not calls["delta"]
    assert calls["lenient"] == [20e9] and calls["quick"] == [pytest.approx(np.sqrt(20) * 1e9)]
    # the bisection's fits are the strict ones (an unfinished fit there ends the profile)
    calls = {"delta": [], "quick": [], "lenient": []}
    steep = lambda v: 4 * np.log(v / 1e9) ** 2              # noqa: E731 - rejects above e^0.98
    p = profile_bound("m.G13", "lower", 1e9, 20e9, make("delta", steep), Q2,
                      quick=make("quick", steep), lenient=make("lenient", steep))
    assert np.isfinite(p.bound) and not calls["quick"] and calls["lenient"] == [20e9]
    assert len(calls["delta"]) >= 2


def test_a_flat_profile_and_a_monte_carlo_range_off_the_panel_keep_their_words_apart(s21_8x8):
    """S2.1's G13 (8x8) on its lower limit with a Monte Carlo range from the limit (trials on
    it) and a flat profile that both run off the top of the panel: the 100-trial run at 12x12
    gave 11.66 GPa and 18.5 GPa, off a linear panel, in view on the log panel it has now
    (within LOG_PANEL_REACH of the limit); here moved beyond that. The range's words ("to
    ...") sit left of its bar, the profile's ("profile: flat to ...") right of its line; they
    overlapped when both were on the left (drawn figure, display coordinates)."""
    import dataclasses as dc

    import matplotlib.pyplot as plt

    from laminid_cli.report import LOG_PANEL_REACH, fmt_value, interval_panel
    from laminid_cli.resultfile import read_result

    r = read_result(s21_8x8[1])
    m = "E-glass/R368"
    u = r.uncertainty
    labels = [x.label for x in u.intervals]
    j = labels.index(f"{m}.G13")
    iv = u.intervals[j]
    assert iv.at_bound and iv.profile_kind == "flat" and iv.profile_far == pytest.approx(18.5e9)
    top, far = 2 * LOG_PANEL_REACH * iv.value, 3 * LOG_PANEL_REACH * iv.value
    iv = dc.replace(iv, profile_far=far)
    u = dc.replace(u, intervals=u.intervals[:j] + (iv,) + u.intervals[j + 1:])
    values = np.array([x.value for x in u.intervals])
    lower, upper = values * 0.97, values * 1.03
    lower[j], upper[j] = iv.value, top
    at_lower = np.zeros(len(labels), np.int8)
    at_lower[j] = 1
    mc = {"lower": lower, "upper": upper, "inner_lower": lower, "inner_upper": upper,
          "lower_at_bound": at_lower}
    fig, ax = plt.subplots(figsize=(1.6, 5))
    interval_panel(ax, dc.replace(r, uncertainty=dc.replace(u, monte_carlo=mc)), m, "G13")
    ax.set_xlim(-0.75, 0.75)                       # as the intervals page (interval_page)
    fig.draw_without_rendering()
    texts = {t.get_gid(): t for t in ax.texts}
    prof, end = texts["profile-label"], texts["monte-carlo-upper-end"]
    # (its end for sure is the range's own here: written once)
    assert end.get_text() == f"to\n{fmt_value('G13', top)}"
    assert prof.get_text() == f"profile:\nflat to\n{fmt_value('G13', far)}"
    a, b = prof.get_window_extent(), end.get_window_extent()
    assert a.x0 >= b.x1 or a.x1 <= b.x0 or a.y0 >= b.y1 or a.y1 <= b.y0, (a, b)
    plt.close(fig)


def test_the_flat_profiles_words_say_why_its_scan_ends_there():
    """A flat profile's scan end is no limit of the search (the alphas bound only E1 by the
    factor; a new user saw Monte Carlo trials of G13 at 76 GPa beside "flat up to the search's
    other limit", 25 GPa): its statement names the scan's end, for each rule of _profile_far."""
    from types import SimpleNamespace

    from laminid_cli.material import ElasticConstants
    from laminid_cli.uncertainty import _profile_far, _profile_far_words

    c0 = ElasticConstants(E1=40e9, E2=10e9, G12=4e9, G13=4e9, G23=3e9, nu12=0.3)
    opts = SimpleNamespace(bound_factor=5.0)

    def words(k, side, limit):
        far = _profile_far(k, side, limit, opts, c0)
        return far, _profile_far_words(k, side, limit, far, opts, c0)

    assert words("G13", "lower", 4e6) == (20e9, "5 x the initial value")
    assert words("G13", "lower", 3e9) == (30e9, "10 x the limit")
    assert words("E2", "lower", 1e9) == (40e9, "the initial E1: E2 <= E1")     # not 50 GPa
    assert words("G12", "upper", 20e9) == pytest.approx((0.8e9, "the initial value / 5"))
    assert words("G12", "upper", 5e9) == (0.5e9, "the limit / 10")
    assert words("E1", "upper", 200e9) == (10e9, "the initial E2: E2 <= E1")   # not 8 GPa
    assert words("nu12", "upper", 0.95) == (0.0, "a negative nu12 is no fibre ply's")


def test_no_profile_names_no_far_end(tmp_path, monkeypatch):
    """A constant on its limit whose profile could not be made has no far end: hybrid CM's
    glass G13 gave profile_far 18.5 GPa (the scan's planned end) in --json, HDF5 and the
    summaries although its fit failed at 0.00865 GPa, which a program reads as 'flat to
    18.5 GPa'. S2.1 (8x8) with every identification holding G13 failing in the solver
    stands in: its far end is null in --json, NaN in the HDF5 file (whose description says
    why), empty in summary.csv, null in summary.json; the report says nothing of a 'flat'
    profile; an older file or summary that stored the planned end is read as none."""
    import csv
    import shutil

    import h5py

    from laminid_cli.report import doubt_of_row, interval_text
    from laminid_cli.resultfile import read_result

    _fail_fits_holding_g13(monkeypatch)
    m, lab = "E-glass/R368", "E-glass/R368.G13"
    out = tmp_path / "r.h5"
    res = CliRunner().invoke(cli, ["identify", "specimens/example2/S2.1.yaml", "--mesh", "8x8",
                                   "--json", "-o", str(out)])
    assert res.exit_code == 0, res.output
    g13 = json.loads(res.output)["uncertainty"]["constants"][m]["G13"]
    prof = g13["profile"]
    assert g13["at_bound"] and prof["text"].startswith("no profile: the stiffness matrix")
    assert prof["far"] is None and prof["delta_chi2_far"] is None and prof["bound"] is None
    with h5py.File(out, "r") as f:
        u = f["uncertainty"]
        j = [x.decode() if isinstance(x, bytes) else x for x in u["labels"][()]].index(lab)
        assert np.isnan(u["profile_far"][j]) and np.isnan(u["profile_delta_chi2_far"][j])
        assert "no profile could be made" in u["profile_far"].attrs["description"]
    iv = read_result(out).uncertainty.get(m, "G13")
    assert iv.profile_kind == "none" and np.isnan(iv.profile_far)
    assert interval_text("G13", iv) == "none — on lower search limit"
    # the batch's summaries
    folder = tmp_path / "in"
    folder.mkdir()
    shutil.copy("specimens/example2/S2.1.yaml", folder)
    res = CliRunner().invoke(cli, ["batch", str(folder), "--out", str(tmp_path / "out"),
                                   "--mesh", "8x8"])
    assert res.exit_code == 0, res.output
    with open(tmp_path / "out" / "summary.csv", newline="") as fh:
        row = next(r for r in csv.DictReader(without_comments(fh)) if r["constant"] == "G13")
    assert row["profile"] == "none" and row["profile_far"] == "" and row["bound_limit"]
    doc = json.loads((tmp_path / "out" / "summary.json").read_text())
    entry = doc["specimens"][0]["intervals"][m]["G13"]
    assert entry["profile"] == "none" and entry["profile_far"] is None
    # older files and summaries stored the planned end: read as none
    with h5py.File(out, "r+") as f:
        f["uncertainty"]["profile_far"][j] = 18.5e9
    assert np.isnan(read_result(out).uncertainty.get(m, "G13").profile_far)
    old = {"intervals": {m: {"G13": dict(entry, profile_far=18.5e9)}}}
    d = doubt_of_row(old, m, "G13")
    assert d.profile == "none" and np.isnan(d.profile_far)


def test_a_rise_flat_over_most_of_the_scan_is_bisected_to_its_end():
    """A rise linear in the held modulus over a scan of three decades (a shear modulus from
    1e-4 E1 up: flat in ln G over most of the scan, steep at its end): the crossing is
    L (1 + q^2 / c). Regula falsi alone crept from the flat end by its 5 % floor: with c = 0.1
    it stopped after its 8 fits 10.8 % above the crossing (with the hybrid CM's glass G12,
    at the far end itself: "rejects G12 above 18.5 GPa"). The secant of the rise's logarithm
    (near linear here) ends within PROFILE_TOL in ln G, the returned end rejected, in at most
    8 fits after the far end's."""
    L, far = 5.58e6, 18.5e9
    for c in (1e-2, 0.1, 1.0, 10.0):
        p = profile_bound("glass.G12", "lower", L, far, lambda v, c=c: c * (v / L - 1), Q2)
        exact = L * (1 + Q2 / c)
        assert 0 <= np.log(p.bound / exact) <= PROFILE_TOL, (c, p.bound, exact)
        assert p.runs <= 9


@pytest.fixture(scope="module")
def hybrid_cm_6x6():
    """Hybrid CM (glass and carbon plies) on 6x6, identified with the alphas: glass G12 stops
    on its floor, G12 = 1e-4 E1 (the alphas' floor ``8 r s``), E2 = E1... (~2.5 s)."""
    from laminid_cli.forward import bending_model, build_forward_model
    from laminid_cli.specimen import read_specimen

    fm = bending_model(build_forward_model(read_specimen("specimens/example3/hybrid-cm.yaml"),
                                           (6, 6)))
    r = identify(fm)
    sigma = frequency_sigma(fm.specimen.measured)
    return fm, r, sigma, uncertainty_of(r, fm, sigma)


def test_a_profile_refit_searches_the_alphas_region_from_the_optimum(hybrid_cm_6x6):
    """Holding a constant of a material identified with the alphas makes its refit use the
    constants parametrisation; its box (each modulus within [P0 / 5, 5 P0]) excluded the
    optimum's glass G12 of 1e-4 E1 (6.1 MPa, the box's floor 0.92 GPa): every refit of the
    profiles walked from the initial values in another region (the refit with G12 held at
    its own value did not converge in 300 evaluations). In the alphas' region it starts at
    the optimum and stays there: the same chi2 to 1e-6 in a few evaluations; with 1.5 times
    the value held, it ends beside the optimum within the profiles' 300 evaluations, its chi2
    no lower than the optimum's (the held value is off the search's best)."""
    from laminid_cli.uncertainty import refit_held

    fm, r, sigma, u = hybrid_cm_6x6
    assert r.parametrization == {"glass": "alpha", "carbon": "alpha"}
    assert "glass: G12 at its minimum (0.0001 E1)" in r.bounds_hit
    g12 = r.constants[0].G12
    assert g12 == pytest.approx(1e-4 * r.constants[0].E1, rel=0.05)
    r0, u0 = refit_held(r, [fm], [sigma], {}, False, "glass.G12", g12)
    assert r0.converged and r0.evaluations <= 20
    assert r0.parametrization["glass"] == "constants"
    assert u0.chi2 == pytest.approx(u.chi2, rel=1e-6)
    for c0, c in zip(r0.constants, r.constants):
        # it stays at the optimum (carbon's G13, G23, barely determined, within 1.1e-4)
        np.testing.assert_allclose(c0.as_array(), c.as_array(), rtol=1e-3)
    r1, u1 = refit_held(r, [fm], [sigma], {}, False, "glass.G12", 1.5 * g12)
    assert r1.converged and u1.chi2 >= u.chi2 * (1 - 1e-9)
    # it ends beside the optimum too: 8 evaluations with numpy 2.4; 273 with numpy 2.5
    # (Python 3.13), along the flat valley of carbon's barely determined G13, G23, to the
    # same point (chi2 within 1e-5; the constants within 2e-2: carbon G13 moves by 1.0 %)
    assert u1.chi2 == pytest.approx(u.chi2, rel=1e-4)
    for c1, c in zip(r1.constants, r.constants):
        a1, a = c1.as_array(), c.as_array()
        keep = np.arange(6) != (2 if c1 is r1.constants[0] else -1)   # glass G12 is held
        np.testing.assert_allclose(a1[keep], a[keep], rtol=2e-2)


def test_profiles_in_forked_workers_are_the_ones_made_in_turn(hybrid_cm_6x6):
    """Hybrid CM (6x6) has three constants on a limit (glass E2 = E1, glass G12 = 1e-4 E1,
    carbon nu12 = 0.95; glass G12's profile is slow, carbon G12 stands in for it): with two
    processes (one profile each at a time, forked) the profiles are those made one after
    the other, field for field, in the constants' order;
    progress is told before the first and once per profile, with its label, the count
    running from 0 to three."""
    from laminid_cli.uncertainty import with_profiles

    fm, r, sigma, u = hybrid_cm_6x6
    labels = [lab for lab, b in zip(u.labels, u.at_bound) if b]
    assert labels == ["glass.E2", "glass.G12", "carbon.nu12"]
    # glass G12's fits far from its limit take 300 evaluations each: the other two, with a
    # third that is quick (carbon G12 as if on a lower limit at its value: its scan's far
    # end, 49 GPa, is refused at the start, 199 % from the first mode: "no profile")
    labels = ["glass.E2", "carbon.G12", "carbon.nu12"]
    j = u.labels.index("carbon.G12")
    limit = np.array(u.bound_limit, float)
    limit[j] = u.value[j]
    u = dataclasses.replace(u, at_bound=np.array([x in labels for x in u.labels]),
                            bound_side=tuple("lower" if x == "carbon.G12" else s
                                             for x, s in zip(u.labels, u.bound_side)),
                            bound_limit=limit)
    seen = {1: [], 2: []}
    fits = {1: [], 2: []}
    made = {j: with_profiles(u, r, [fm], [sigma], {}, False, jobs=j,
                             progress=lambda d, n, lab, j=j: seen[j].append((d, n, lab)),
                             fit_progress=lambda lab, n, text, j=j: fits[j].append(
                                 (lab, n, text)))
            for j in (1, 2)}
    assert list(made[2].profiles) == labels
    for lab in labels:                       # (NaN where no bound: equal to NaN here)
        np.testing.assert_equal(dataclasses.astuple(made[2].profiles[lab]),
                                dataclasses.astuple(made[1].profiles[lab]))
    assert made[1].profiles["glass.E2"].text.startswith("the fit is as good with E2 anywhere")
    for j in (1, 2):
        assert [d for d, _, _ in seen[j]] == [0, 1, 2, 3] and {n for _, n, _ in seen[j]} == {3}
        assert seen[j][0][2] is None
        assert sorted(lab for _, _, lab in seen[j][1:]) == sorted(labels)
    # each fit of each profile is told, numbered from 1, with the value held: from the forked
    # workers (through a pipe) as in turn (the lines of evaluations, told by the clock, aside)
    told = {j: sorted(f for f in fits[j] if ", evaluation" not in f[2]) for j in (1, 2)}
    assert told[2] == told[1]
    # within a fit on the profile's reduced model: its making (once a profile), its steps
    for lab in labels:
        assert sum(x == lab and t.endswith(", building its reduced model")
                   for x, _, t in told[1]) <= 1
    assert any(t.endswith(", reduced model, step 2") for _, _, t in told[1])
    told = {j: [f for f in told[j] if ", " not in f[2]] for j in (1, 2)}      # each fit once
    assert {lab for lab, _, _ in told[1]} == set(labels)
    for lab in labels:
        ns = [n for x, n, _ in told[1] if x == lab]
        assert ns == list(range(1, len(ns) + 1)) and len(ns) >= made[1].profiles[lab].runs
    assert ("glass.E2", 1, "E2 = 0.9 GPa") in told[1]


def _identify_on_a_terminal(*args) -> tuple[list[str], str]:
    """``laminid identify ARGS --no-output`` with stderr a pseudo-terminal and stdout a pipe
    (the tables): (stderr's lines as drawn, each ``\\r`` starting one, stripped; stdout)."""
    import os
    import pty
    import select
    import subprocess
    import sys

    master, slave = pty.openpty()
    p = subprocess.Popen([sys.executable, "-m", "laminid_cli", "identify", *args,
                          "--no-output"], stdout=subprocess.PIPE, stderr=slave)
    os.close(slave)
    err = b""
    while True:                    # read while it runs: a full pty buffer would block it
        ready, _, _ = select.select([master], [], [], 60)
        if not ready:
            break
        try:
            chunk = os.read(master, 65536)
        except OSError:            # EIO: the child closed its end
            break
        if not chunk:
            break
        err += chunk
    out = p.communicate(timeout=120)[0].decode()
    os.close(master)
    assert p.returncode == 0, err.decode(errors="replace")
    lines = err.decode().replace("\r\n", "\n").replace("\n", "\r").split("\r")
    return [ln.strip() for ln in lines if ln.strip()], out


def test_a_terminal_is_told_the_profiles_progress():
    """On a terminal, identify shows where the profiles are (they take a few to 10 s each,
    after the identification's last evaluation line): '0 of 1 done' when they start, then
    each one done with its label. S2.1 (6x6) has one, G13 on its lower limit (1e-4 E1); its
    stderr is a pseudo-terminal here, its stdout a pipe (the tables)."""
    lines, out = _identify_on_a_terminal("specimens/example2/S2.1.yaml", "--mesh", "6x6")
    said = [ln for ln in lines if "profiles of the constants" in ln]
    assert said == ["profiles of the constants on a search limit: 0 of 1 done",
                    "profiles of the constants on a search limit: 1 of 1 done "
                    "(E-glass/R368.G13)"]
    assert "profile: the fit rejects G13 above" in out


#: S2.1 (6x6) with --fix-undetermined, on a terminal: each step after the identification's
#: evaluations, in its order (a profile's fits after their first, with its evaluations if
#: slow, are left out: their number depends on the clock)
FIX_UNDETERMINED_STEPS = [
    "linearised intervals",
    "run 2, G13 fixed as undetermined",
    "run 2, G13 fixed as undetermined: evaluation    1, RMS 14.8616 %",
    "linearised intervals",
    "run 3, G13, nu12 fixed as undetermined",
    "run 3, G13, nu12 fixed as undetermined: evaluation    1, RMS 14.8616 %",
    "linearised intervals",
    "the fixed values' spread: the others identified with them moved, 0 of 2 done",
    "the fixed values' spread: the others identified with them moved, 1 of 2 done",
    "profiles of the constants on a search limit: 0 of 1 done",
    "profile of E-glass/R368.G23 (0 of 1 done): fit 1, G23 = 18.5 GPa",
    "profiles of the constants on a search limit: 1 of 1 done (E-glass/R368.G23)",
    "the fixed values on a search limit: the others identified with each at its ends",
    "do the modes reject the fixed values? the others identified with them released"]


def test_a_terminal_is_told_each_step_of_the_uncertainty():
    """After the identification's last evaluation line, a terminal was told nothing but the
    profiles' count until the tables (S1.1 at 16x16 with --fix-undetermined: 2.7 s, its
    fixed values' checks 1.1 s; hybrid CM's first profile 2.4 s at "0 of 5 done"): now each
    step (linearised intervals, each run of --fix-undetermined on its evaluation lines, the
    fixed values' checks) and each fit of a profile with the value held. S2.1 (6x6)."""
    lines, out = _identify_on_a_terminal("specimens/example2/S2.1.yaml", "--mesh", "6x6",
                                         "--fix-undetermined")
    first = lines.index("linearised intervals")
    steps = [ln for ln in lines[first:]
             if not (ln.startswith("run ") and ": evaluation" in ln
                     and not ln.split(": evaluation")[1].strip().startswith("1,"))
             and not (ln.startswith("profile of ") and not ln.endswith("fit 1, G23 = 18.5 GPa"))]
    assert steps == FIX_UNDETERMINED_STEPS
    # the first fit on the profile's reduced model: its making, then its steps
    assert ("profile of E-glass/R368.G23 (0 of 1 done): fit 1, G23 = 18.5 GPa, building its "
            "reduced model") in lines
    assert ("profile of E-glass/R368.G23 (0 of 1 done): fit 1, G23 = 18.5 GPa, reduced model, "
            "step 1") in lines
    fits = [ln for ln in lines if ln.startswith("profile of E-glass/R368.G23 (0 of 1 done)")
            and ", " not in ln.split("done): fit ")[1].split(", ", 1)[1]]
    assert len(fits) >= 3 and fits[1] == ("profile of E-glass/R368.G23 (0 of 1 done): fit 2, "
                                          "G23 = 18.5 GPa from the initial values")
    assert "G23" in out


def test_a_terminal_is_told_the_monte_carlo_trials_done():
    """The Monte Carlo's bar said its percentage only; it counts the trials ("6/6"), and
    the steps around it are told on their own lines. S2.1 (6x6), 6 trials."""
    lines, _ = _identify_on_a_terminal("specimens/example2/S2.1.yaml", "--mesh", "6x6",
                                       "--monte-carlo", "6", "-j", "1")
    bars = [ln for ln in lines if "Monte Carlo trials" in ln]
    assert bars[0].endswith("]  0/6") and bars[-1].endswith("]  6/6"), bars
    assert lines.index("linearised intervals") < lines.index(bars[0])


def test_no_step_is_told_on_a_pipe_or_with_json():
    """The steps' lines are a terminal's only: stderr on a pipe (a log) or --json gets none
    of them (nor the evaluations), as the profiles' count before."""
    from click.testing import CliRunner

    from laminid_cli.cli import cli

    for extra in ([], ["--json"]):
        r = CliRunner().invoke(cli, ["identify", "specimens/example2/S2.1.yaml", "--mesh",
                                      "6x6", "--fix-undetermined", "--no-output", *extra])
        assert r.exit_code == 0, r.output
        for words in ("linearised intervals", "fixed as undetermined", "evaluation",
                      "profile of", "the fixed values' spread", "do the modes reject"):
            assert words not in r.stderr, (extra, r.stderr)


def test_a_rejection_from_the_optimum_is_checked_from_the_initial_values(hybrid_cm_6x6,
                                                                         monkeypatch):
    """A profile's fit starts at the optimum; where that fit rejects the value (or stops
    unfinished), a second fit starts from the initial values and the lower chi2 is kept: a
    fit that rejects may have ended in a local minimum. Hybrid CM (6x6) with glass E2 held
    at 0.9 GPa (the far end of its scan): from the optimum identify()'s fit ends at chi2
    30.7, from the initial values at 24.8, both finished. At 80 % (q^2 = 1.64) the first
    alone rejected E2 there; with the second (at most 100 evaluations) the profile is flat.
    The profile's own fit from the optimum, on its reduced model (refit_reduced), ends in the
    initial values' valley, a little lower still (chi2 24.77 against 24.77 + 3e-4): flat at
    once, no second fit; the two starts are checked here with identify() making every fit."""
    import laminid_cli.uncertainty as unc
    from laminid_cli.uncertainty import refit_held, with_profiles

    fm, r, sigma, _ = hybrid_cm_6x6
    kw = dict(confidence=0.8)
    u = uncertainty_of(r, fm, sigma, **kw)
    lab = "glass.E2"
    a, ua = refit_held(r, [fm], [sigma], kw, False, lab, 0.9e9)
    b, ub = refit_held(r, [fm], [sigma], kw, False, lab, 0.9e9, from_initial=True)
    assert a.converged and b.converged
    if not ub.chi2 < ua.chi2 - 5:
        # the case needs the two starts in two valleys, the initial values' the lower: so with
        # numpy 2.4 (30.7 against 24.8); numpy 2.5 (Python 3.13) takes the initial values'
        # fit to a third, higher one (chi2 133), and the case is not there to test
        pytest.skip(f"this build's fits from the two starts end at chi2 {ua.chi2:.3g} (the "
                    f"optimum's) and {ub.chi2:.3g} (the initial values'): not the case")
    factor = max(u.variance_factor, 1e-300)
    threshold = u.quantile ** 2
    assert (ua.chi2 - u.chi2) / factor > threshold > (ub.chi2 - u.chi2) / factor
    only = dataclasses.replace(u, at_bound=np.array([x == lab for x in u.labels]))
    # the reduced model's fit from the optimum: the lower valley, not rejected, one fit
    p = with_profiles(only, r, [fm], [sigma], kw, False, jobs=1).profiles[lab]
    assert p.far == pytest.approx(0.9e9) and np.isnan(p.bound) and p.runs == 2
    assert p.delta_far <= (ub.chi2 - u.chi2) / factor + 1e-3 * threshold
    assert "stopped at" not in p.text
    monkeypatch.setattr(unc, "refit_reduced", lambda *args, **k: None)   # identify() only
    p = with_profiles(only, r, [fm], [sigma], kw, False, jobs=1).profiles[lab]
    assert p.far == pytest.approx(0.9e9) and np.isnan(p.bound)
    # the second fit stops at PROFILE_INITIAL_EVALUATIONS (100): its rise bounds the finished
    # one's from above, and is below the threshold
    assert (ub.chi2 - u.chi2) / factor <= p.delta_far < threshold
    assert p.text.startswith("the fit is as good with E2 anywhere below the limit down to 0.9")
    assert "stopped at 100 evaluations" in p.text


def test_a_profile_fit_refused_at_its_starts_says_where_it_started(hybrid_cm_6x6):
    """A profile's fit whose held value puts a measured mode beyond the start's limit (50 %)
    at every start says so with the value held and where the fit started, not "at the initial
    guess" and the input mistakes to check (the specimen's own start is fine): carbon E1
    held at 30 times its optimum, 2620 GPa, moves mode 4 from 392.70 Hz to 963 Hz."""
    from laminid_cli.identify import FarStartError
    from laminid_cli.uncertainty import refit_held

    fm, r, sigma, _ = hybrid_cm_6x6
    e1 = 30 * r.constants[1].E1
    for from_initial, at in ((False, "at every start tried from the optimum to the initial "
                                     "values"), (True, "at the initial values")):
        with pytest.raises(FarStartError) as exc:
            refit_held(r, [fm], [sigma], {}, False, "carbon.E1", e1, from_initial=from_initial)
        text = str(exc.value)
        # (145 % and 963 Hz with numpy 2.4; the optimum's carbon E1 differs by 5e-4 with
        # numpy 2.5: 154 %, 997 Hz, 2.62e+03 GPa held alike)
        assert re.match(r"specimens/example3/hybrid-cm\.yaml: measured mode 4 \(392\.70 Hz\) "
                        r"is 1[45]\d % away from the model \(9\d\d\.\d\d Hz\) with E1 = ", text), \
            text
        assert text.endswith(f"Hz) with E1 = 2.62e+03 GPa held, {at} (limit 50 %): the modes "
                             "are too far from E1 = 2.62e+03 GPa for a fit to start there")
        assert "initial guess" not in text and "units" not in text


@pytest.fixture(scope="module")
def s21_6x6():
    """S2.1 on 6x6 (the alphas, E-glass G13 stops on its floor 1e-4 E1): forward model,
    result, sigma and uncertainty (~0.3 s)."""
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import read_specimen

    fm = build_forward_model(read_specimen("specimens/example2/S2.1.yaml"), (6, 6))
    r = identify(fm)
    sigma = frequency_sigma(fm.specimen.measured)
    return fm, r, sigma, uncertainty_of(r, fm, sigma)


def test_a_reduced_refit_ends_where_a_converged_identify_refit_ends(s21_6x6, hybrid_cm_6x6):
    """A profile's fit from the optimum runs on the profile's reduced model (Levenberg-
    Marquardt, refit_reduced), its answer checked against the full model. S2.1 (6x6), G13
    (an alpha-parametrised shear modulus on its floor) held at 1.7, 5 and 18.5 GPa: chi2
    within PROFILE_SAME (1e-3) of the threshold (scaled) of identify()'s fit run to its end
    (3000 evaluations; 4.7e-4, 3.0e-4, 1.7e-3 against 5.6e-3), every other constant within
    0.01 of its standard error (6.4e-4 at most), in 8-10 reduced evaluations (identify():
    15-33). Hybrid CM (6x6), glass G12 on the alphas' floor held at 1.5 times it, the same
    (its material in the constants parametrisation, in the alphas' region)."""
    import laminid_cli.uncertainty as unc

    for (fm, r, sigma, u), lab, values in (
            (s21_6x6, "E-glass/R368.G13", (1.7e9, 5e9, 18.5e9)),
            (hybrid_cm_6x6, "glass.G12", (1.5 * hybrid_cm_6x6[1].constants[0].G12,))):
        model = unc.profile_model(r, [fm], [sigma], u, lab)
        threshold, factor = u.quantile ** 2, u.variance_factor
        name, k = lab.rsplit(".", 1)
        for v in values:
            rr, ur = unc.refit_held(r, [fm], [sigma], {}, False, lab, v, model=model)
            assert rr.converged and 0 < rr.work["reduced_evaluations"] <= 20, rr.status
            assert k not in rr.free[name] and rr.parametrization[name] == "constants"
            assert rr.constants[rr.material_names.index(name)].as_array()[
                ["E1", "E2", "G12", "G13", "G23", "nu12"].index(k)] == v
            ri, ui = unc.refit_held(r, [fm], [sigma], {}, False, lab, v, max_evaluations=3000)
            assert ri.converged and "reduced_evaluations" not in ri.work
            assert abs(ur.chi2 - ui.chi2) / factor <= PROFILE_SAME * threshold, (v, ur.chi2,
                                                                                 ui.chi2)
            assert ur.labels == ui.labels
            ok = np.isfinite(ui.std)
            np.testing.assert_array_less(np.abs(ur.value - ui.value)[ok] / ui.std[ok], 0.01)


def test_a_refit_the_reduced_model_refuses_is_made_by_identify(s21_6x6, monkeypatch):
    """Where the reduced model's answer fails its check against the full model (here: every
    answer, the accepted eigenvalue bound and shift set to 0), the fit falls back to
    identify() from the optimum (refit_held), and the profile is the same: S2.1 (6x6), G13
    rejected above 1.55 GPa either way (within PROFILE_TOL), each fit identify()'s."""
    import laminid_cli.uncertainty as unc

    fm, r, sigma, u = s21_6x6
    lab = "E-glass/R368.G13"
    only = dataclasses.replace(u, at_bound=np.array([x == lab for x in u.labels]))
    p = unc.with_profiles(only, r, [fm], [sigma], {}, False, jobs=1).profiles[lab]
    assert p.text.startswith("the fit rejects G13 above 1.5")
    real = unc.profile_model
    routes = []

    def strict(*args, **kw):
        model = real(*args, **kw)
        model.bound = model.shift_limit = 0.0        # no answer passes TrialModel.accepts
        return model

    def spy(*args, **kw):
        out = real_refit(*args, **kw)
        routes.append("reduced_evaluations" in out[0].work)
        return out

    real_refit = unc.refit_held
    monkeypatch.setattr(unc, "profile_model", strict)
    monkeypatch.setattr(unc, "refit_held", spy)
    q = unc.with_profiles(only, r, [fm], [sigma], {}, False, jobs=1).profiles[lab]
    assert routes and not any(routes)
    assert q.text.startswith("the fit rejects G13 above 1.5") and not q.error
    assert abs(np.log(q.bound / p.bound)) <= PROFILE_TOL
    # one such fit against identify()'s own
    model = strict(r, [fm], [sigma], u, lab)
    n0 = model.n_evaluations
    rr, ur = real_refit(r, [fm], [sigma], {}, False, lab, 1.7e9, model=model)
    ri, ui = real_refit(r, [fm], [sigma], {}, False, lab, 1.7e9)
    assert model.n_evaluations > n0 and "reduced_evaluations" not in rr.work
    assert rr.evaluations == ri.evaluations and ur.chi2 == pytest.approx(ui.chi2, rel=1e-12)


@pytest.mark.slow
def test_hybrid_cm_glass_g12_and_g23_get_the_bounds_of_finished_fits():
    """Hybrid CM as the command runs it (12x12, ~25 s): glass G12 and G23, on their lower
    limits, get profile bounds from the reduced refits where identify()'s fits, capped at 300
    and 100 evaluations, gave no profile (stop 42: "did not converge"). The reference: the same
    profiles with every fit made by identify() run to 3000 evaluations
    (``benchmarks/bench_profiles.py --budget 3000`` on stop 42's code): 18.5 and 8.11 GPa;
    the bounds within PROFILE_TOL (2 %) of them (seen: 18.5 and 8.13 GPa)."""
    from tests.clihelp import run

    j = json.loads(run("identify", "specimens/example3/hybrid-cm.yaml", "--json",
                       "--no-output").output)
    glass = j["uncertainty"]["constants"]["glass"]
    for k, reference in (("G12", 18.5e9), ("G23", 8.11e9)):
        p = glass[k]["profile"]
        assert p["error"] == "" and p["bound"] is not None, (k, p["text"])
        assert p["text"].startswith(f"the fit rejects {k} above"), p["text"]
        assert abs(np.log(p["bound"] / reference)) <= PROFILE_TOL, (k, p["bound"])


def test_a_profile_fit_goes_on_from_what_slsqp_reached_at_its_cap(s21_6x6, monkeypatch):
    """The reduced model's SLSQP run (TrialModel._minimise, after a Levenberg-Marquardt fit
    that stalled) has TRIAL_MAXEVAL evaluations: a Monte Carlo trial that reaches them fails
    (identify() makes it), a profile's fit (a model with an ftol) keeps the best point it
    reached and goes on from there (hybrid CM's glass G12 at 6.8 GPa and G13 at 18.5 GPa went
    to identify() after 300-500 reduced evaluations). S2.1 (6x6), G13 held at 5 GPa, SLSQP
    from the optimum capped at 3 evaluations: the profile's model returns a point below the
    start's objective; the same model as a trial's (no ftol) refuses."""
    import laminid_cli.uncertainty as unc

    fm, r, sigma, u = s21_6x6
    lab = "E-glass/R368.G13"
    model = unc.profile_model(r, [fm], [sigma], u, lab)
    assert model.ftol > 0
    model.hold({lab: 5e9})
    x0, _ = model._start()
    freq = np.asarray(r.measured_hz, float)
    w = np.where(np.isfinite(freq), np.asarray(r.weight, float), 0.0)
    lam = (2 * np.pi * np.nan_to_num(freq, nan=1.0)) ** 2
    f0 = model.evaluate(model.basis, x0, lam, w, model.Y_ref)[0]
    monkeypatch.setattr(unc, "TRIAL_MAXEVAL", 3)
    n0 = model.n_evaluations
    x, _ = model._minimise(model.basis, x0, lam, w, model.Y_ref)
    assert model.n_evaluations - n0 == 1 + 3             # its scaling at x0, its 3
    f = model.evaluate(model.basis, x, lam, w, model.Y_ref)[0]
    assert f < 0.5 * f0, (f, f0)                        # (0.23 f0)
    model.ftol = 0.0                                       # as the trials' model
    with pytest.raises(unc._TrialFailed, match="3 evaluations of the trial model reached"):
        model._minimise(model.basis, x0, lam, w, model.Y_ref)


def test_a_profile_fit_starts_at_the_answer_nearest_to_it_on_the_limits_side(s21_6x6):
    """A profile's reduced fit starts where the fit of the nearest value held before, between
    the limit and its own value, ended (the profile followed out from the optimum); with none
    there, at the optimum. S2.1 (6x6), G13 held at 18.5 GPa (the far end: not between the
    limit and the values after it) and 5 GPa, then at 5.2 GPa: it starts at 5 GPa's answer,
    in fewer reduced evaluations than from the optimum (3 against 11), chi2 the same within
    PROFILE_SAME of the threshold (scaled; 104.2431 against 104.2418)."""
    import laminid_cli.uncertainty as unc

    fm, r, sigma, u = s21_6x6
    lab = "E-glass/R368.G13"
    threshold, factor = u.quantile ** 2, u.variance_factor
    fresh = unc.profile_model(r, [fm], [sigma], u, lab)
    n0 = fresh.n_evaluations
    rf, uf = unc.refit_held(r, [fm], [sigma], {}, False, lab, 5.2e9, model=fresh)
    from_optimum = fresh.n_evaluations - n0
    model = unc.profile_model(r, [fm], [sigma], u, lab)
    for v in (18.5e9, 5e9):
        unc.refit_held(r, [fm], [sigma], {}, False, lab, v, model=model)
    assert [v for v, _ in model.answers] == [18.5e9, 5e9]
    assert unc._nearer_answer(model, lab, 5.2e9) is model.answers[1][1]
    assert unc._nearer_answer(model, lab, 4e9) is None        # nothing below 4 GPa
    n0 = model.n_evaluations
    rc, uc = unc.refit_held(r, [fm], [sigma], {}, False, lab, 5.2e9, model=model)
    followed = model.n_evaluations - n0
    assert rc.converged and "reduced_evaluations" in rc.work
    assert followed < from_optimum
    assert abs(uc.chi2 - uf.chi2) / factor <= PROFILE_SAME * threshold
