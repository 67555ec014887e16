"""The numbers ``laminid identify S1.1 --no-output`` PRINTS, read back from the terminal text and
recomputed from other printed numbers by definitions and closed forms written here (not by
laminid's code), each within the rounding of the printed digits (interval arithmetic: a value
printed with d decimals is anywhere within half a unit of its last digit):

- residual % = (measured - model) / measured x 100, the RMS of the 12 weighted residuals, the
  '+/- Hz' column = 0.2 % (--sigma-rel default) of the measured frequency;
- chi2 = sum ((measured - model) / sigma)^2 and s2 = chi2 / (12 - 6);
- the 95 % intervals and their '± of value' column: moduli P exp(-/+ w), w = ln(upper / P) =
  ln(P / lower); nu12 P -/+ w |P|;
- the normalised sensitivities: the frequencies of a linear-elastic plate are homogeneous of
  degree 1/2 in its five moduli (K scales with them, M does not), so d ln f / d ln E1 + ... +
  d ln f / d ln G23 = 1/2 for every mode (Euler's theorem), and the 'most sensitive mode' is
  the printed column's largest magnitude;
- the global laminate properties of the quasi-isotropic [45_3/0_3/-45_3/90_3]s from the
  printed identified constants by classical lamination theory (Tsai-Pagano invariants:
  Ex = Ey = U1 - U4^2/U1, Gxy = U5, nu_xy = nu_yx = U4/U1; Gxz = Gyz = (G13 + G23)/2).

One identification on the default 12x12 mesh (~0.3 s)."""

import math
import re

import numpy as np
import pytest

from tests.clihelp import run

NUM = r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?"


def half_ulp(text: str) -> float:
    """Half a unit of the last printed digit of ``text`` (fixed-point)."""
    return 0.5 * 10.0 ** -len(text.split(".")[1]) if "." in text else 0.5


@pytest.fixture(scope="module")
def printed():
    r = run("identify", "specimens/example1/S1.1.yaml", "--no-output")
    assert r.exit_code == 0, r.output
    return r.output


def _modes(out):
    rows = re.findall(rf"^\s+(\d+)\s+({NUM})\s+({NUM})\s+({NUM})\s+1\s+({NUM})$", out, re.M)
    assert [int(r[0]) for r in rows] == list(range(1, 13)), out
    return rows


def test_residuals_rms_and_sigma_column_from_the_printed_frequencies(printed):
    rows = _modes(printed)
    model = np.array([float(r[1]) for r in rows])
    meas = np.array([float(r[2]) for r in rows])           # the file's values, exact
    du = np.array([half_ulp(r[1]) for r in rows])          # 0.005 Hz
    lo = (meas - model - du) / meas * 100
    hi = (meas - model + du) / meas * 100
    for r, a, b in zip(rows, lo, hi):
        res, u = float(r[3]), half_ulp(r[3])
        assert a - u - 1e-12 <= res <= b + u + 1e-12, r
        assert float(r[4]) == pytest.approx(0.002 * float(r[2]), abs=half_ulp(r[4]) + 1e-12), r
    rms = re.search(rf"RMS residual ({NUM}) %", printed).group(1)
    sq_lo = np.where(lo * hi > 0, np.minimum(lo ** 2, hi ** 2), 0.0)
    sq_hi = np.maximum(lo ** 2, hi ** 2)
    assert (math.sqrt(sq_lo.mean()) - half_ulp(rms) <= float(rms)
            <= math.sqrt(sq_hi.mean()) + half_ulp(rms)), (rms, sq_lo.mean(), sq_hi.mean())


def test_chi2_and_s2_from_the_printed_frequencies_and_the_stated_sigma(printed):
    """Measured: chi2 within [2.20, 2.24] by the printed frequencies (printed 2.21), s2 0.369."""
    rows = _modes(printed)
    model = np.array([float(r[1]) for r in rows])
    meas = np.array([float(r[2]) for r in rows])
    sigma = 0.002 * meas                                    # --sigma-rel 0.2 % of each
    d_lo, d_hi = meas - model - 0.005, meas - model + 0.005
    t_lo = np.where(d_lo * d_hi > 0, np.minimum(d_lo ** 2, d_hi ** 2), 0.0) / sigma ** 2
    t_hi = np.maximum(d_lo ** 2, d_hi ** 2) / sigma ** 2
    m = re.search(rf"s2 = chi2/\(n-p\) = ({NUM}) \(chi2 ({NUM}), (\d+) degrees of freedom\)",
                  printed)
    assert m, printed
    s2, chi2, dof = m.group(1), m.group(2), int(m.group(3))
    assert dof == 12 - 6
    assert t_lo.sum() - half_ulp(chi2) <= float(chi2) <= t_hi.sum() + half_ulp(chi2)
    assert (t_lo.sum() / 6 - half_ulp(s2) <= float(s2) <= t_hi.sum() / 6 + half_ulp(s2))
    assert float(s2) == pytest.approx(float(chi2) / 6, abs=half_ulp(s2) + half_ulp(chi2) / 6)


def _constants(out):
    rows = re.findall(rf"^\s+(E1|E2|G12|G13|G23|nu12)(?: \[GPa\])?\s+({NUM})\s+({NUM})"
                      rf"(?:\s+{NUM})?\s+({NUM}) \.\. ({NUM})\s+({NUM}) %", out, re.M)
    assert [r[0] for r in rows] == ["E1", "E2", "G12", "G13", "G23", "nu12"], out
    return {r[0]: r[2:] for r in rows}


def test_intervals_and_their_share_of_the_value(printed):
    """Moduli: the printed interval is P exp(-/+ w) with w the printed '± of value'; nu12:
    P -/+ w |P|; within the printed digits of P, the ends and w."""
    for name, (p, lo, hi, pct) in _constants(printed).items():
        P, L, U, w = float(p), float(lo), float(hi), float(pct) / 100
        uw = half_ulp(pct) / 100
        if name == "nu12":
            tol = (half_ulp(lo) + half_ulp(hi)) / 2 / abs(P) + w * half_ulp(p) / abs(P) + uw
            assert (U - L) / 2 / abs(P) == pytest.approx(w, abs=tol), name
            assert (U + L) / 2 == pytest.approx(P, abs=half_ulp(lo) + half_ulp(hi) + half_ulp(p))
        else:
            uP = half_ulp(p) / P
            assert math.log(U / P) == pytest.approx(w, abs=uP + half_ulp(hi) / U + uw), name
            assert math.log(P / L) == pytest.approx(w, abs=uP + half_ulp(lo) / L + uw), name


def test_sensitivities_of_the_five_moduli_sum_to_one_half(printed):
    """Euler: f(c E1, ..., c G23) = sqrt(c) f, so each printed row's five moduli sum to 0.5
    within 5 x 0.0005 (measured: 0.499-0.500); the most sensitive mode is the column's largest
    magnitude."""
    block = printed.split("normalised sensitivities d ln f / d ln P")[1]
    head = block.splitlines()[1].split()
    assert head == ["mode", "E1", "E2", "G12", "G13", "G23", "nu12"]
    rows = re.findall(rf"^\s+(\d+)((?:\s+{NUM}){{6}})$", block, re.M)
    assert [int(r[0]) for r in rows] == list(range(1, 13))
    table = np.array([[float(x) for x in r[1].split()] for r in rows])
    np.testing.assert_allclose(table[:, :5].sum(axis=1), 0.5, rtol=0, atol=5 * 0.0005 + 1e-12)
    most = re.search(r"most sensitive mode: (.*)$", block, re.M).group(1)
    printed_most = {k: int(v) for k, v in re.findall(r"(\w+) (\d+)", most)}
    for j, k in enumerate(head[1:]):
        col = np.abs(table[:, j])
        # ties within the printed digits may go either way
        assert col[printed_most[k] - 1] >= col.max() - 0.001, k


def _invariants(E1, E2, G12, nu12):
    nu21 = nu12 * E2 / E1
    d = 1.0 - nu12 * nu21
    Q11, Q22, Q12, Q66 = E1 / d, E2 / d, nu12 * E2 / d, G12
    U1 = (3 * Q11 + 3 * Q22 + 2 * Q12 + 4 * Q66) / 8
    U4 = (Q11 + Q22 + 6 * Q12 - 4 * Q66) / 8
    U5 = (Q11 + Q22 - 2 * Q12 + 4 * Q66) / 8
    return U1, U4, U5


def test_global_properties_by_lamination_theory_of_the_printed_constants(printed):
    """Quasi-isotropic laminate: the printed Ex..nu_yx from the printed E1, E2, G12, G13, G23,
    nu12 by the invariants; bounds: the extremes over the 16 corners of the printed constants'
    rounding boxes (E1, E2, G12, nu12), plus the property's own last digit."""
    c = {k: v[0] for k, v in _constants(printed).items()}
    g = dict(re.findall(rf"^\s+(Ex|Ey|Gxy|Gxz|Gyz|nu_xy|nu_yx)(?: \[GPa\])?\s+({NUM})\s",
                        printed, re.M))
    assert set(g) == {"Ex", "Ey", "Gxy", "Gxz", "Gyz", "nu_xy", "nu_yx"}, printed
    vals = {k: float(v) for k, v in c.items()}
    corners = []
    for s in np.array(np.meshgrid(*[[-1, 1]] * 4)).reshape(4, -1).T:
        E1, E2, G12, nu = (vals[k] + si * half_ulp(c[k])
                           for k, si in zip(("E1", "E2", "G12", "nu12"), s))
        U1, U4, U5 = _invariants(E1, E2, G12, nu)
        corners.append((U1 - U4 ** 2 / U1, U5, U4 / U1))
    corners = np.array(corners)
    for key, j in (("Ex", 0), ("Ey", 0), ("Gxy", 1), ("nu_xy", 2), ("nu_yx", 2)):
        u = half_ulp(g[key])
        assert corners[:, j].min() - u <= float(g[key]) <= corners[:, j].max() + u, key
    gxz = (vals["G13"] + vals["G23"]) / 2
    tol = (half_ulp(c["G13"]) + half_ulp(c["G23"])) / 2
    for key in ("Gxz", "Gyz"):
        assert float(g[key]) == pytest.approx(gxz, abs=tol + half_ulp(g[key])), key


def test_modes_prints_the_density_from_the_mass_and_the_dimensions():
    """S1.1: 0.3225 kg / (210.5 x 311 x 3.06 mm) = 1609.87 kg/m^3 (printed 1609.9), by hand."""
    r = run("modes", "specimens/example1/S1.1.yaml", "--mesh", "6x6")
    assert r.exit_code == 0, r.output
    rho = float(re.search(rf"density ({NUM}) kg/m\^3", r.output).group(1))
    assert rho == pytest.approx(0.3225 / (0.2105 * 0.311 * 0.00306), abs=0.05)
    assert "mass 0.3225 kg (model 0.3225 kg)" in r.output


@pytest.fixture(scope="module")
def printed_damping(tmp_path_factory):
    """identify --mesh 6x6 of S1.1 with synthetic modal damping (tests/dampspec.py: ply loss
    factors 0.2, 1.2, 1.5, 1.0, 1.0 %, damping sigma 2 % of each zeta, 3 % noise, seed 1):
    (terminal text, the noisy zeta written in the file, its sigma)."""
    from tests.dampspec import damped_copy

    spec = tmp_path_factory.mktemp("damp") / "S1.1-damped.yaml"
    zeta = damped_copy("specimens/example1/S1.1.yaml", spec,
                       np.array([0.002, 0.012, 0.015, 0.01, 0.01]), sigma_rel=0.02, mesh="6x6",
                       noise=0.03, seed=1)
    noisy = zeta * (1 + 0.03 * np.random.default_rng(1).standard_normal(zeta.size))
    r = run("identify", spec, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 0, r.output
    return r.output, noisy, 0.02 * zeta


def test_modal_loss_factors_from_the_printed_shares_and_ply_loss_factors(printed_damping):
    """Modal strain energy: each mode's model eta = sum_k U_k eta_k (printed shares, %, and
    printed ply loss factors), within the printed digits; the shares sum to 100 within
    5 x 0.05; measured = 2 zeta and '+/-' = 2 sigma of the file's values; s2 =
    chi2 / (12 - 5) with chi2 from the file's damping and sigma and the printed model column
    (measured: s2 within [0.97, 1.20], printed 1.11)."""
    out, zeta, sigma = printed_damping
    eta = dict(re.findall(rf"^\s+(eta11|eta22|eta12|eta13|eta23)\s+({NUM})\s", out, re.M))
    assert list(eta) == ["eta11", "eta22", "eta12", "eta13", "eta23"], out
    e = np.array([float(v) for v in eta.values()])
    ue = np.array([half_ulp(v) for v in eta.values()])
    block = out.split("strain-energy shares (%) of each mode")[1]
    rows = re.findall(rf"^\s+(\d+)((?:\s+{NUM}){{8}})$", block, re.M)
    assert [int(r[0]) for r in rows] == list(range(1, 13)), block
    t = np.array([[float(x) for x in r[1].split()] for r in rows])
    meas, pm, model, U = t[:, 0], t[:, 1], t[:, 2], t[:, 3:]
    np.testing.assert_allclose(U.sum(axis=1), 100, rtol=0, atol=5 * 0.05 + 1e-9)
    bound = (0.05 * e + U * ue).sum(axis=1) / 100 + 0.0005 + 1e-12
    np.testing.assert_array_less(np.abs(model - U @ e / 100), bound)
    np.testing.assert_allclose(meas, 200 * zeta, rtol=0, atol=0.0005 + 1e-12)
    np.testing.assert_allclose(pm, 200 * sigma, rtol=0, atol=0.0005 + 1e-12)
    d_lo = np.abs(200 * zeta - model) - 0.0005             # the model column's rounding
    d_hi = np.abs(200 * zeta - model) + 0.0005
    chi2_lo = (np.clip(d_lo, 0, None) ** 2 / (200 * sigma) ** 2).sum()
    chi2_hi = (d_hi ** 2 / (200 * sigma) ** 2).sum()
    m = re.search(rf"intervals from: .*; s2 = ({NUM}) \((\d+) degrees of freedom\)", out)
    assert m and int(m.group(2)) == 12 - 5, out
    assert chi2_lo / 7 - half_ulp(m.group(1)) <= float(m.group(1)) <= chi2_hi / 7 + half_ulp(m.group(1))


def test_s2_and_chi2_keep_their_trailing_zeros(s11_fix_undetermined_6x6):
    """A chi2 of 12.0 and s2 of 2.0 were printed "chi2 12" and "s2 = 2" (format g): read as
    exact beside "s2 = 0.286". Three significant digits, as the Monte Carlo table's."""
    import copy

    from laminid_cli.commands.text import format_uncertainty

    u = copy.deepcopy(s11_fix_undetermined_6x6[0]["uncertainty"])
    u["a_posteriori"].update(chi2=12.0, s2=2.0)
    u["scaling"].update(used="residuals", variance_factor=2.0)
    text = "\n".join(format_uncertainty(u))
    assert "s2 = chi2/(n-p) = 2.00 (chi2 12.0, " in text
    assert "covariance scaled by s2 = 2.00 (Student t quantile)" in text
