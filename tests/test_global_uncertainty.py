"""Doubt on the laminate's global properties (laminid_cli.global_uncertainty): against closed
forms (a unidirectional laminate's properties are its ply's constants), against sampling (the
linearised spread of a quasi-isotropic laminate's properties vs 20000 draws of the constants),
the dependence rules, and the same numbers in --json, the HDF5 file, the terminal and the
report's text."""

import json
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.global_uncertainty import KEYS, global_intervals
from laminid_cli.laminate import Laminate
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants

C0 = ElasticConstants(E1=150e9, E2=9e9, G12=5e9, G13=4.5e9, G23=3e9, nu12=0.3)
LABELS = tuple(f"m.{k}" for k in CONSTANT_NAMES)


def laminate(angles_deg):
    n = len(angles_deg)
    h = 2e-3
    return Laminate(z=np.linspace(-h / 2, h / 2, n + 1), angle=np.radians(angles_deg),
                    material_index=np.zeros(n, int), material_names=("m",),
                    density=np.full(n, 1500.0), constants=(C0,))


def fake_u(cov, at_bound=None, labels=LABELS, q=1.959963984540054):
    return SimpleNamespace(labels=labels, covariance=np.asarray(cov, float), quantile=q,
                           at_bound=None if at_bound is None else np.asarray(at_bound, bool))


def rel_std():
    """5 % on every modulus, 0.03 on nu12, E1-E2 correlated 0.5."""
    v = np.array([getattr(C0, k) for k in CONSTANT_NAMES])
    sd = np.where(np.array(CONSTANT_NAMES) == "nu12", 0.03, 0.05 * v)
    corr = np.eye(6)
    corr[0, 1] = corr[1, 0] = 0.5
    return sd, corr * np.outer(sd, sd)


def test_a_unidirectional_laminate_has_its_plys_constants_and_their_doubt():
    """[0]4: Ex = E1, Ey = E2, Gxy = G12, Gxz = G13, Gyz = G23, nu_xy = nu12, so their standard
    deviations are the constants' own (1e-6, the central differences' error)."""
    sd, cov = rel_std()
    out = global_intervals(laminate([0, 0, 0, 0]), {"m": C0}, fake_u(cov))
    pairs = {"Ex": 0, "Ey": 1, "Gxy": 2, "Gxz": 3, "Gyz": 4, "nu_xy": 5}
    for key, j in pairs.items():
        assert out[key].std == pytest.approx(sd[j], rel=1e-6), key
        assert out[key].verdict == "weak"          # 1.96 x 5 % (moduli), 1.96 x 0.03 / 0.3
    # nu_yx = nu12 E2 / E1: d = nu12/E1 dE2 - nu12 E2/E1^2 dE1 + E2/E1 dnu12 (closed form)
    g = np.array([-C0.nu12 * C0.E2 / C0.E1 ** 2, C0.nu12 / C0.E1, 0, 0, 0, C0.E2 / C0.E1])
    assert out["nu_yx"].std == pytest.approx(np.sqrt(g @ cov @ g), rel=1e-6)
    # moduli: intervals on ln g, as the constants'
    q = 1.959963984540054
    assert out["Ex"].lower == pytest.approx(C0.E1 * np.exp(-q * sd[0] / C0.E1), rel=1e-9)


def test_linearised_spread_against_sampling_for_a_quasi_isotropic_laminate():
    """[0/45/-45/90]s with 1 % moduli and 0.005 on nu12: the linearised standard deviation of
    every property within 3 % of the spread of 8000 draws of the constants (the sample
    standard deviation's own error is 0.8 %)."""
    lam = laminate([0, 45, -45, 90, 90, -45, 45, 0])
    v = np.array([getattr(C0, k) for k in CONSTANT_NAMES])
    sd = np.where(np.array(CONSTANT_NAMES) == "nu12", 0.005, 0.01 * v)
    cov = np.diag(sd ** 2)
    out = global_intervals(lam, {"m": C0}, fake_u(cov))
    rng = np.random.default_rng(7)
    draws = rng.multivariate_normal(v, cov, size=8000)
    props = (lam.with_constants([ElasticConstants(*row)]).global_properties().as_dict()
             for row in draws)
    gp = np.array([[d[k] for k in KEYS] for d in props])
    for i, key in enumerate(KEYS):
        assert out[key].std == pytest.approx(gp[:, i].std(), rel=0.03), key


def test_a_property_not_determined_gets_no_constants_advice():
    """A property wider than 30 % was "not determined by these modes — fix it or measure a
    thicker plate / more modes" in --json and the file (the terminal printed the words
    without the advice): no laminate property can be --fix'ed. The words are now the
    terminal's in every form (S1.1 joint --fix-undetermined: Gxz ±35 %)."""
    lam = laminate([0, 90, 90, 0])
    v = np.array([getattr(C0, k) for k in CONSTANT_NAMES])
    sd = np.where(np.array(CONSTANT_NAMES) == "nu12", 0.03, np.array([.02, .02, .02, .4, .4, 0]) * v)
    out = global_intervals(lam, {"m": C0}, fake_u(np.diag(sd ** 2)))
    assert out["Gxz"].rel_half_width > 0.3
    assert out["Gxz"].verdict == "not determined by these modes"
    assert out["Ex"].verdict == "well determined"


def test_dependence_on_constants_at_a_bound_fixed_or_fixed_because_undetermined():
    """Gxz and Gyz of a cross-ply depend on G13 and G23 only, Ex, Ey, Gxy, nu_xy never on
    them: G13 at its bound leaves Gxz, Gyz not identified; G23 fixed because undetermined adds
    the spread it had before fixing; nu12 fixed by the user gives 'given the fixed'."""
    lam = laminate([0, 90, 90, 0])
    sd, cov = rel_std()
    out = global_intervals(lam, {"m": C0}, fake_u(cov, at_bound=[0, 0, 0, 1, 0, 0]))
    assert not out["Gxz"].identified and out["Gxz"].at_bound == ("m.G13",)
    assert np.isnan(out["Gyz"].lower) and "depends on m.G13 (at its bound)" in out["Gyz"].verdict
    for key in ("Ex", "Ey", "Gxy", "nu_xy", "nu_yx"):
        assert out[key].identified and np.isfinite(out[key].lower), key
    # G23 and nu12 fixed (not among the labels); G23 because undetermined, with its earlier std
    free = ("m.E1", "m.E2", "m.G12", "m.G13")
    # its spread as uncertainty.counting_fixed_spread counts it: its own variance and its
    # covariance with the free G13 (the free constants' covariance already counts it)
    cross = np.zeros((4, 1))
    cross[3, 0] = -0.4 * sd[3] * 0.8e9
    u = SimpleNamespace(**vars(fake_u(cov[:4, :4], labels=free)), spread_counted=("m.G23",),
                        spread_covariance=np.array([[0.8e9 ** 2]]), spread_cross=cross)
    out = global_intervals(lam, {"m": C0}, u, fixed_undetermined=("m.G23",))
    assert out["Gxz"].spread_counted == ("m.G23",)
    assert "counts the spread m.G23 had before it was fixed" in out["Gxz"].verdict
    assert out["Ex"].given_fixed == ("m.nu12",) and out["Ex"].verdict.endswith(
        "given the fixed m.nu12")
    # G13 and G23 of a cross-ply enter Gxz as t-weighted sums: exact variance by hand
    t0 = t90 = 0.5
    dGxz = np.array([t0, t90])                       # d Gxz / d (G13, G23), Voigt average
    var = dGxz @ np.array([[sd[3] ** 2, cross[3, 0]], [cross[3, 0], 0.8e9 ** 2]]) @ dGxz
    assert out["Gxz"].std == pytest.approx(np.sqrt(var), rel=1e-5)
    # without its spread counted: not identified
    u = fake_u(cov[:4, :4], labels=free)
    out = global_intervals(lam, {"m": C0}, u, fixed_undetermined=("m.G23",))
    assert not out["Gxz"].identified and "fixed because undetermined" in out["Gxz"].verdict
    # fixed because it was at a search limit in the run before: said so, not "undetermined"
    at_limit = SimpleNamespace(labels=LABELS, std=np.array([1, 1, 1, 1, np.nan, 1]),
                               at_bound=np.array([0, 0, 0, 0, 1, 0], bool))
    out = global_intervals(lam, {"m": C0}, u, fixed_undetermined=("m.G23",), before=at_limit)
    assert "depends on m.G23 (fixed: it was at a search limit)" in out["Gxz"].verdict


def test_global_doubt_in_json_hdf5_terminal_and_report(s21_8x8, s21_8x8_terminal):
    """S2.1 (8x8): G13 ends at its bound, so Gxz and Gyz are not identified everywhere; Ex
    keeps an interval, the same in --json, HDF5 and the terminal."""
    from laminid_cli.report import _laminate_text
    from laminid_cli.resultfile import read_result

    doc, out = s21_8x8                   # conftest.py: identify S2.1 --mesh 8x8 --json -o
    gu = doc["global_uncertainty"]
    assert gu["Gxz"]["lower"] is None and "not identified" in gu["Gxz"]["verdict"]
    assert gu["Ex"]["rel_half_width"] < 0.05 and gu["Ex"]["verdict"] == "well determined"
    with h5py.File(out) as f:
        h = f["global_properties_uncertainty"]
        keys = [k.decode() for k in h["keys"][()]]
        assert keys == list(KEYS)
        assert h["lower"][keys.index("Ex")] == gu["Ex"]["lower"]
        assert np.isnan(h["lower"][keys.index("Gyz")])
    plate = read_result(out).plates[0]
    assert plate.global_uncertainty["Ex"]["upper"] == gu["Ex"]["upper"]
    text = _laminate_text(plate)
    assert "Gxz 2.21 GPa (not identified)" in text
    assert f"Ex {gu['Ex']['value'] / 1e9:.2f} GPa ±{gu['Ex']['rel_half_width'] * 100:.2g} %" \
        in text
    row = next(ln for ln in s21_8x8_terminal.splitlines() if ln.startswith("  Gxz [GPa]"))
    assert "none" in row and "not identified: depends on E-glass/R368.G13 (at its bound)" in row


def test_joint_result_gives_each_plate_its_laminate_doubt(tmp_path):
    """--joint: each plate's block has its laminate's properties with intervals from the shared
    constants' covariance (S1.1 and S1.2 are both quasi-isotropic: Ex = Ey to 1e-9), in --json,
    in each plate's group of the HDF5 file and on each plate's report page."""
    from laminid_cli.report import _laminate_text
    from laminid_cli.resultfile import read_result

    out = tmp_path / "j.h5"
    r = CliRunner().invoke(cli, ["identify", "specimens/example1/S1.1.yaml",
                                 "specimens/example1/S1.2.yaml", "--joint", "--mesh", "8x8",
                                 "--json", "-o", str(out)])
    assert r.exit_code == 0, r.output
    plates = json.loads(r.output)["specimens"]
    assert len(plates) == 2
    res = read_result(out)
    for plate, (name, p) in zip(res.plates, plates.items()):
        gu = p["global_uncertainty"]
        assert gu["Ex"]["value"] == pytest.approx(p["global_properties"]["Ex"], rel=1e-12)
        assert gu["Ex"]["value"] == pytest.approx(gu["Ey"]["value"], rel=1e-9)
        assert 0 < gu["Ex"]["rel_half_width"] < 0.05
        assert plate.global_uncertainty["Gxz"]["upper"] == gu["Gxz"]["upper"]
        rel = gu["Ex"]["rel_half_width"]
        assert f"Ex {gu['Ex']['value'] / 1e9:.2f} GPa ±{rel * 100:.2g} %" in _laminate_text(plate)


def test_a_property_from_fixed_constants_only_is_not_identified():
    """S1.1 with nu12, G13, G23 fixed: Gxz and Gyz come from the fixed G13, G23 alone (an
    assumption: no interval, never '±0 % well determined'); Ex is given the fixed nu12."""
    r = CliRunner().invoke(cli, ["identify", "specimens/example1/S1.1.yaml", "--mesh", "8x8",
                                 "--fix", "nu12,G13,G23", "--json", "--no-output"])
    gu = json.loads(r.output)["global_uncertainty"]
    assert gu["Gxz"]["lower"] is None and gu["Gxz"]["rel_half_width"] is None
    assert gu["Gxz"]["verdict"] == ("not identified: from the fixed IM7/977-2.G13, "
                                    "IM7/977-2.G23")
    assert gu["Ex"]["verdict"].endswith("given the fixed IM7/977-2.nu12")
    assert 0 < gu["Ex"]["rel_half_width"] < 0.05
    from laminid_cli.report import _laminate_text

    plate = type("P", (), {"global_properties": {"Ex": gu["Ex"]["value"]},
                           "reference_global": {}, "global_uncertainty": {"Ex": gu["Ex"]}})()
    assert _laminate_text(plate).endswith("% (given fixed values)")


def test_report_laminate_line_says_an_interval_the_monte_carlo_found_too_narrow():
    """hybrid-ESL (8x8, --monte-carlo 20): G13 "not determined by these modes (Monte Carlo)",
    and Gxz (= G13 there) "weak — linearised; the Monte Carlo found ESL.G13 less determined
    than that: this interval is too narrow" in the terminal, --json and the file; the
    report's laminate line gave "Gxz 2.50 GPa ±27 %" alone, a plain interval. Now it says so;
    a property the Monte Carlo did not touch keeps its plain "±"."""
    from laminid_cli.report import _laminate_text

    gu = {"Gxz": {"rel_half_width": 0.272, "verdict": "weak — linearised; the Monte Carlo "
                  "found ESL.G13 less determined than that: this interval is too narrow"},
          "Ex": {"rel_half_width": 0.0071, "verdict": "well determined"}}
    plate = type("P", (), {"global_properties": {"Ex": 75.99e9, "Gxz": 2.50e9},
                           "reference_global": {}, "global_uncertainty": gu})()
    text = _laminate_text(plate)
    assert "Gxz 2.50 GPa ±27 % (too narrow: the Monte Carlo found it less determined)" in text
    assert "Ex 75.99 GPa ±0.71 %," in text


def test_a_property_leaning_on_a_constant_held_by_its_prior_says_so(tmp_path):
    """S1.2 (6x6) with prior {nu12: 1.0}: nu12 ends "well determined (held by the prior)",
    mostly the file's value; Ex, Ey, Gxy and the Poisson ratios, which depend on it, were
    "well determined" / "weak" with no word of it, as if the modes had given them. Now "—
    leans on the prior of IM7/977-2.nu12" (terminal, --json, the file) and "(leans on a prior)"
    on the report's laminate line; Gxz, Gyz (no nu12 in them) keep theirs."""
    from pathlib import Path

    from laminid_cli.report import _laminate_text

    text = Path("specimens/example1/S1.2.yaml").read_text()
    assert text.count("    nu12: 0.35\n") == 1
    spec = tmp_path / "pr.yaml"
    spec.write_text(text.replace("    nu12: 0.35\n", "    nu12: 0.35\n    prior: {nu12: 1.0}\n"))
    r = CliRunner().invoke(cli, ["identify", str(spec), "--mesh", "6x6", "--json",
                                 "--no-output"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["uncertainty"]["constants"]["IM7/977-2"]["nu12"]["verdict"].endswith(
        "(held by the prior)")
    gu = d["global_uncertainty"]
    for k in ("Ex", "Ey", "Gxy", "nu_xy", "nu_yx"):
        assert gu[k]["verdict"].endswith(" — leans on the prior of IM7/977-2.nu12"), k
    assert "prior" not in gu["Gxz"]["verdict"] and "prior" not in gu["Gyz"]["verdict"]
    as_file = {k: {f: np.nan if v is None else v for f, v in e.items()} for k, e in gu.items()}
    plate = type("P", (), {"global_properties": d["global_properties"],
                           "reference_global": {}, "global_uncertainty": as_file})()
    line = _laminate_text(plate)
    rel = gu["Ex"]["rel_half_width"] * 100
    assert f"Ex {gu['Ex']['value'] / 1e9:.2f} GPa ±{rel:.2g} % (leans on a prior)" in line


def _qi_ex_nu_gxy(P):
    """Ex, nu_xy, Gxy of a pi/4 quasi-isotropic laminate from the Tsai-Pagano invariants
    (classical lamination theory, written for complex P: complex-step derivatives)."""
    E1, E2, G12, _, _, nu12 = P
    d = 1 - nu12 ** 2 * E2 / E1
    Q11, Q22, Q12 = E1 / d, E2 / d, nu12 * E2 / d
    U1 = (3 * Q11 + 3 * Q22 + 2 * Q12 + 4 * G12) / 8
    U4 = (Q11 + Q22 + 6 * Q12 - 4 * G12) / 8
    U5 = (Q11 + Q22 - 2 * Q12 + 4 * G12) / 8
    return np.array([U1 - U4 ** 2 / U1, U4 / U1, U5])


def test_delta_method_against_complex_step_derivatives_of_the_invariants():
    """[0/45/-45/90]s with a full, correlated covariance: std of Ex, nu_xy, Gxy within 1e-6
    of sqrt(g' C g) with g the complex-step gradient (exact to rounding) of the closed-form
    invariants, and Gxz = Gyz = (G13 + G23) / 2, so var = (C33 + C44 + 2 C34) / 4; the
    intervals: moduli on ln g with scipy's normal quantile, nu_xy linear."""
    from scipy import stats

    lam = laminate([0, 45, -45, 90, 90, -45, 45, 0])
    v = np.array([getattr(C0, k) for k in CONSTANT_NAMES])
    rng = np.random.default_rng(11)
    sd = np.where(np.array(CONSTANT_NAMES) == "nu12", 0.02, rng.uniform(0.02, 0.1, 6) * v)
    L = rng.uniform(-1, 1, (6, 6))
    corr = np.corrcoef(L @ L.T + 6 * np.eye(6))
    cov = corr * np.outer(sd, sd)
    z = stats.norm.ppf(0.975)
    out = global_intervals(lam, {"m": C0}, fake_u(cov, q=z))
    grad = np.zeros((3, 6))
    for j in range(6):
        P = v.astype(complex)
        P[j] += 1j * 1e-20 * abs(v[j])
        grad[:, j] = _qi_ex_nu_gxy(P).imag / (1e-20 * abs(v[j]))
    value = _qi_ex_nu_gxy(v)
    for i, key in enumerate(("Ex", "nu_xy", "Gxy")):
        std = np.sqrt(grad[i] @ cov @ grad[i])
        assert out[key].value == pytest.approx(value[i], rel=1e-12), key
        assert out[key].std == pytest.approx(std, rel=1e-6), key
    assert out["Ex"].lower == pytest.approx(value[0] * np.exp(-z * out["Ex"].std / value[0]),
                                            rel=1e-12)
    assert out["nu_xy"].upper == pytest.approx(value[1] + z * out["nu_xy"].std, rel=1e-12)
    var_gxz = (cov[3, 3] + cov[4, 4] + 2 * cov[3, 4]) / 4
    for key in ("Gxz", "Gyz"):
        assert out[key].std == pytest.approx(np.sqrt(var_gxz), rel=1e-6), key
    assert out["Gxz"].rel_half_width == pytest.approx(
        z * np.sqrt(var_gxz) / (0.5 * (C0.G13 + C0.G23)), rel=1e-6)
