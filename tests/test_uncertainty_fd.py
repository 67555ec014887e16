"""The identification's printed linearised numbers against a reference built here from central
finite differences of full FE solves (no analytic sensitivity, no design row of
laminid_cli.uncertainty): the normalised sensitivities d ln f / d ln P, the condition number and
weakest combination, the standard deviations, correlations and 95 % intervals (Gauss-Newton
sandwich covariance of the unit-weight least squares of the relative frequency residuals with
their standard deviations, quantiles from scipy.stats), chi2,
s2, its 99 % limit and the RMS residual. S1.1 with its measured frequencies on a 6x6 mesh
with frequency standard deviations of 0.1-0.4 % that differ from mode to mode (so that the
whitening matters; chi2 25 for 6 degrees of freedom: the coarse mesh's error, so the 'larger'
scaling widens the intervals).

The reference is in frequencies, laminid's rows in eigenvalues relative to the measured one:
row i differs by the factor f_i / f_meas,i (residuals < 0.5 %), which moves every variance by
less than 1 % (the weighted normal matrix changes within (1 -/+ 2 max|r|) in Loewner order)."""

import dataclasses

import numpy as np
import pytest
from scipy import stats

from laminid_cli.forward import build_forward_model
from laminid_cli.identify import IdentifyOptions
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants
from laminid_cli.specimen import read_specimen
from laminid_cli.uncertainty import UncertaintyOptions, assess, sensitivity_table
from tests.data.paper import S11

#: relative frequency standard deviation of each of the 12 modes
SIGMA_REL = np.array([2, 1, 4, 3, 1.5, 2.5, 1, 3.5, 2, 1.2, 4, 2.8]) * 1e-3
IS_NU = np.array([k == "nu12" for k in CONSTANT_NAMES])


@pytest.fixture(scope="module")
def s11_fd():
    """(forward model, stated assessment, 'larger' assessment, reference dict)."""
    spec = read_specimen(S11)
    spec = dataclasses.replace(spec, measured=dataclasses.replace(
        spec.measured, sigma=SIGMA_REL * spec.measured.freq))
    fm = build_forward_model(spec, (6, 6))
    stated = assess(fm, IdentifyOptions(), UncertaintyOptions(scaling="stated"))
    larger = assess(fm, IdentifyOptions(), UncertaintyOptions())
    r = stated.result
    P = r.constants[0].as_array()
    n_modes = int(r.pairing.max()) + 3
    f0 = fm.solve([r.constants[0]], n_modes).freq[r.pairing]
    h = 1e-4                                               # step in ln P
    dlnf = np.zeros((r.pairing.size, 6))
    for j in range(6):
        up, dn = P.copy(), P.copy()
        up[j] *= np.exp(h)
        dn[j] *= np.exp(-h)
        f_up = fm.solve([ElasticConstants.from_array(up)], n_modes).freq[r.pairing]
        f_dn = fm.solve([ElasticConstants.from_array(dn)], n_modes).freq[r.pairing]
        dlnf[:, j] = (np.log(f_up) - np.log(f_dn)) / (2 * h)
    f_meas = r.measured_hz
    sigma = SIGMA_REL * f_meas
    # relative constants: moduli per ln P, nu12 per max(|nu12|, 0.1) (the documented scale)
    scale = np.where(IS_NU, np.maximum(np.abs(P), 0.1), P)
    dP_scale = np.where(IS_NU, scale / P, 1.0)             # d/d(P/scale) = d/d ln P * scale/P
    A = dlnf * dP_scale[None, :]                           # d ln f / d relative constant
    Jw = A * (f0 / sigma)[:, None]                          # noise-whitened
    # the fit weighs every mode by its weight in the file (1), not by 1/sigma^2: the
    # covariance of that estimator is the sandwich (A'A)^-1 A' S A (A'A)^-1, S = diag(sigma/f)^2
    B = np.linalg.inv(A.T @ A) @ A.T
    cov = B @ np.diag((sigma / f_meas) ** 2) @ B.T * np.outer(scale, scale)
    chi2 = float(np.sum(((f_meas - f0) / sigma) ** 2))
    ref = dict(P=P, f0=f0, dlnf=dlnf, Jw=Jw, cov=cov, std=np.sqrt(np.diag(cov)), chi2=chi2,
               dof=f_meas.size - 6)
    return fm, stated, larger, ref


def test_normalised_sensitivities_are_central_differences_of_ln_f_in_ln_p(s11_fd):
    """d ln f_i / d ln P_j (the table 'normalised sensitivities') within 1e-6 (absolute; the
    largest is 0.43; the differences' own error is ~1e-8), and the 'most sensitive mode' the
    largest |d ln f / d ln P| of the differences."""
    _, a, _, ref = s11_fd
    r = a.result
    assert r.sensitivity_labels == tuple(f"IM7/977-2.{k}" for k in CONSTANT_NAMES)
    np.testing.assert_allclose(r.sensitivity, ref["dlnf"], rtol=0, atol=1e-6)
    dom = sensitivity_table(r)[r.specimen.name]["dominant_mode"]
    for j, k in enumerate(CONSTANT_NAMES):
        assert dom[f"IM7/977-2.{k}"] == int(np.argmax(np.abs(ref["dlnf"][:, j]))) + 1, k


def test_condition_number_and_weakest_combination_from_the_svd_of_the_fd_jacobian(s11_fd):
    """Condition number of the noise-whitened Jacobian over relative constants within 1 %
    (503 here), the weakest combination (right singular vector of its smallest singular value,
    sign: largest entry positive) within 0.01 per coefficient."""
    _, a, _, ref = s11_fd
    u = a.uncertainty
    s = np.linalg.svd(ref["Jw"], compute_uv=False)
    assert u.condition == pytest.approx(s[0] / s[-1], rel=0.01)
    v = np.linalg.svd(ref["Jw"])[2][-1]
    v *= np.sign(v[np.argmax(np.abs(v))])
    printed = dict(u.weakest)
    expected = {f"IM7/977-2.{k}": v[j] for j, k in enumerate(CONSTANT_NAMES) if abs(v[j]) >= 0.1}
    assert set(printed) == set(expected)
    for lab, c in expected.items():
        assert printed[lab] == pytest.approx(c, abs=0.01), lab


def test_std_correlation_and_intervals_are_the_sandwich_covariance_of_the_fd_jacobian(s11_fd):
    """Stated scaling: std within 1 % of the sandwich covariance built on the FD Jacobian
    (measured: 0.4 %; (J'J)^-1 of the whitened Jacobian, the 1/sigma^2-weighted fit's, would
    be 5-25 % off here), correlations within 0.005, the 95 % intervals with scipy's normal
    quantile: moduli P exp(-/+ z std / P), nu12 P -/+ z std, within 1 %."""
    _, a, _, ref = s11_fd
    u = a.uncertainty
    np.testing.assert_allclose(u.std, ref["std"], rtol=0.01)
    corr = ref["cov"] / np.outer(ref["std"], ref["std"])
    np.testing.assert_allclose(u.correlation, corr, rtol=0, atol=0.005)
    z = stats.norm.ppf(0.975)
    P, sd = ref["P"], ref["std"]
    lower = np.where(IS_NU, P - z * sd, P * np.exp(-z * sd / P))
    upper = np.where(IS_NU, P + z * sd, P * np.exp(z * sd / P))
    np.testing.assert_allclose(u.lower, lower, rtol=0.01)
    np.testing.assert_allclose(u.upper, upper, rtol=0.01)
    np.testing.assert_allclose(u.rel_half_width, z * sd / np.abs(P), rtol=0.01)


def test_chi2_s2_limit_and_the_residual_scaled_intervals(s11_fd):
    """chi2 = sum ((f_meas - f) / sigma)^2 within 1 % (the eigenvalue form differs by the
    residuals' size), s2 = chi2 / (12 - 6), the 99 % limit scipy's chi2.ppf(0.99, 6) = 16.81;
    chi2 above dof, so '--covariance-scale larger' widens the intervals: half-width
    t(0.975, 6) sqrt(s2) std within 1 %."""
    _, a, b, ref = s11_fd
    u = a.uncertainty
    assert u.dof == ref["dof"] == 6
    assert u.chi2 == pytest.approx(ref["chi2"], rel=0.01)
    assert u.s2 == pytest.approx(ref["chi2"] / 6, rel=0.01)
    assert u.chi2_limit == pytest.approx(stats.chi2.ppf(0.99, 6), rel=1e-12)
    ub = b.uncertainty
    assert ub.scale_used == "residuals" and ref["chi2"] > 6
    t = stats.t.ppf(0.975, 6)
    np.testing.assert_allclose(ub.half_width, t * np.sqrt(ref["chi2"] / 6) * ref["std"],
                               rtol=0.01)


def test_residuals_and_rms_from_a_full_solve(s11_fd):
    """Model frequencies = a full solve at the identified constants (1e-9), residual % =
    (measured - model) / measured * 100, RMS over the 12 weighted modes."""
    _, a, _, ref = s11_fd
    r = a.result
    np.testing.assert_allclose(r.model_hz, ref["f0"], rtol=1e-9)
    res = (r.measured_hz - ref["f0"]) / r.measured_hz * 100
    np.testing.assert_allclose(r.residual_percent, res, rtol=1e-6, atol=1e-9)
    assert r.rms_residual_percent == pytest.approx(np.sqrt(np.mean(res ** 2)), rel=1e-6)
