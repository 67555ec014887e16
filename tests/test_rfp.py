"""The RFP estimator against seeded synthetic FRFs with known modal parameters (tests/frf_synth.py).

Scenario (``plate_case``): 5 points, 1601 lines at 1 Hz (or 801 at 2 Hz), ten modes 125-1388 Hz
with 0.2-1.5 % damping and modal constants of both signs, one mode above the axis (2200 Hz), a
rigid-body mass line. Noise is circular complex Gaussian, std = 3 % of |H| line by line
("proportional") or 3 % of the FRF's RMS ("rms", additive).

Measured on this code (seeds 0-9 for 3 % noise): noise-free max frequency error 4e-5 %, damping
2e-3 %; 3 % proportional noise max 0.012 % (1 Hz) and 0.016 % (2 Hz), damping 1.9 % / 2.7 %;
3 % rms noise 0.008 %; no spurious or missed mode. Close pair (351.2 / 352.25 Hz, 0.3 % apart,
0.2 % damping): both found, 0.011 % at 3 % noise. Mode 50 times weaker (446.65 Hz): found
noise-free (2e-5 %), at 1 % noise (max 0.028 %) and at 3 % noise (max 0.085 %, seeds 0-11),
by the gap search that follows the band fits.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.frf_synth import plate_case, synth_frf
from laminid_cli.errors import FrfError
from laminid_cli.frf import rfp

# named tolerances (issue 4)
FREQ_TOL_CLEAN = 1e-4       # 0.01 %
DAMP_TOL_CLEAN = 0.02       # 2 % of the damping ratio
FREQ_TOL_NOISY = 1e-3       # 0.1 %
DAMP_TOL_NOISY = 0.15       # 15 % (not specified by the issue; measured worst 4.4 %)
MATCH = 2e-3                # a found mode within 0.2 % of a true one "is" that mode


def _match(found, truth):
    """(index of the found mode per true mode or -1, indices of unmatched found modes)."""
    found = np.asarray(found, dtype=float)
    idx = []
    for f in truth:
        i = int(np.argmin(np.abs(found - f))) if found.size else -1
        idx.append(i if i >= 0 and abs(found[i] / f - 1) < MATCH else -1)
    spurious = [i for i in range(found.size) if i not in idx]
    return np.array(idx), spurious


def _check(case, fit, ftol, ztol):
    idx, spurious = _match(fit.freq_hz, case.freq_hz)
    assert np.all(idx >= 0), f"missed {case.freq_hz[idx < 0]} Hz; found {fit.freq_hz}"
    assert not spurious, f"spurious modes at {fit.freq_hz[spurious]} Hz"
    ferr = np.abs(fit.freq_hz[idx] / case.freq_hz - 1)
    zerr = np.abs(fit.damping_ratio[idx] / case.damping_ratio - 1)
    assert ferr.max() < ftol, ferr
    assert zerr.max() < ztol, zerr
    return ferr, zerr


# --------------------------------------------------------------------------- building blocks
def test_forsythe_polynomials_are_orthonormal_and_obey_their_recurrence():
    x = np.linspace(0.05, 1.0, 700)
    phi, gamma = rfp.forsythe_basis(x, 40)
    for parity in (0, 1):
        g = phi[parity::2] @ phi[parity::2].T
        assert np.allclose(g, np.eye(g.shape[0]), atol=1e-9)
    k = 7
    assert np.allclose(x * phi[k], gamma[k + 1] * phi[k + 1] + gamma[k] * phi[k - 1])


def test_comrade_matrix_gives_the_roots_of_a_polynomial_in_the_orthogonal_basis():
    x = np.linspace(0.1, 1.0, 300)
    phi, gamma = rfp.forsythe_basis(x, 7)
    roots = np.array([-0.01 + 0.3j, -0.01 - 0.3j, -0.02 + 0.7j, -0.02 - 0.7j, -0.5 + 0.2j,
                      -0.5 - 0.2j])
    s = 1j * x
    D = np.prod(s[:, None] - roots[None, :], axis=1)
    theta = (1j ** np.arange(7))[:, None] * phi
    coef = np.linalg.lstsq(theta.T, D, rcond=None)[0]
    assert np.allclose(coef.imag, 0, atol=1e-9)   # real coefficients in the theta basis
    got = np.sort_complex(rfp.comrade_roots(coef.real, gamma))
    assert np.allclose(got, np.sort_complex(roots), atol=1e-8)


def test_fit_rfp_single_mode_is_exact():
    f = np.arange(50.0, 150.0, 0.5)
    H = synth_frf(f, [(100.0, 0.01)], [[1.0], [-0.4]])
    fit = rfp.fit_rfp(f, H, 1, n_extra=0)
    assert fit.freq_hz.size == 1
    assert fit.freq_hz[0] == pytest.approx(100.0, rel=1e-10)
    assert fit.damping_ratio[0] == pytest.approx(0.01, rel=1e-8)


def test_modal_constants_recover_the_residues():
    f = np.arange(50.0, 400.0, 1.0)
    C = np.array([[1.0, -2.0], [0.5, 0.3]]) * 1e4
    H = synth_frf(f, [(120.0, 0.01), (300.0, 0.02)], C)
    poles = rfp._pole([120.0, 300.0], [0.01, 0.02])
    A, _res, synth = rfp.modal_constants(f, H, poles)
    # receptance C/(wr^2 - w^2 + 2j z wr w) = A/(s - lam) + conj; A = C / (2 j wd)
    wd = poles.imag
    assert np.allclose(A, C / (2j * wd[None, :]), rtol=1e-7)
    assert np.allclose(synth, H, rtol=1e-8, atol=1e-12 * np.abs(H).max())


# --------------------------------------------------------------------------- accuracy
@pytest.mark.parametrize("resolution, n_lines, kind", [(1.0, 1601, "receptance"),
                                                       (2.0, 801, "receptance"),
                                                       (1.0, 1601, "accelerance")])
def test_noise_free_frequencies_within_001_percent_damping_within_2_percent(resolution, n_lines,
                                                                            kind):
    case = plate_case(resolution_hz=resolution, n_lines=n_lines, kind=kind)
    fit = rfp.find_modes(case.freq, case.frf)
    _check(case, fit, FREQ_TOL_CLEAN, DAMP_TOL_CLEAN)
    for m in fit.modes:
        assert m.modal_constants.shape == (5,)
        assert m.orders_stable >= fit.criteria.min_stable


def test_noise_free_modal_constants_are_the_true_residues():
    case = plate_case()
    fit = rfp.find_modes(case.freq, case.frf)
    idx, _ = _match(fit.freq_hz, case.freq_hz)
    wd = 2 * np.pi * case.freq_hz * np.sqrt(1 - case.damping_ratio ** 2)
    true_A = case.constants / (2j * wd[None, :])
    got = np.array([fit.modes[i].modal_constants for i in idx]).T
    assert np.allclose(got, true_A, rtol=1e-3, atol=1e-3 * np.abs(true_A).max())
    # signs of the modal constants (real modes: A = C / 2 j wd)
    assert np.array_equal(np.sign((got * 2j).real), np.sign(case.constants))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_3_percent_noise_frequencies_within_01_percent_and_no_spurious_mode(seed):
    case = plate_case(noise=0.03, seed=seed)
    fit = rfp.find_modes(case.freq, case.frf)
    ferr, _ = _check(case, fit, FREQ_TOL_NOISY, DAMP_TOL_NOISY)
    # the reported spread is an uncertainty of the right order (not 0, not huge)
    assert np.all(fit.freq_std_hz > 0)
    assert np.all(fit.freq_std_hz < 2e-3 * fit.freq_hz)


@pytest.mark.parametrize("noise_kind, resolution, n_lines", [("rms", 1.0, 1601),
                                                             ("proportional", 2.0, 801)])
def test_3_percent_noise_other_noise_model_and_resolution(noise_kind, resolution, n_lines):
    case = plate_case(noise=0.03, noise_kind=noise_kind, resolution_hz=resolution,
                      n_lines=n_lines, seed=5)
    fit = rfp.find_modes(case.freq, case.frf)
    _check(case, fit, FREQ_TOL_NOISY, DAMP_TOL_NOISY)


@pytest.mark.parametrize("noise", [0.0, 0.03])
def test_two_modes_03_percent_apart_are_both_found(noise):
    close = 351.2 * 1.003          # 1.05 Hz from 351.2 Hz (0.2 % damping), 1 Hz lines
    case = plate_case(extra_modes=[(close, 0.002, 1.0)], noise=noise, seed=3)
    fit = rfp.find_modes(case.freq, case.frf)
    ftol = FREQ_TOL_CLEAN if noise == 0 else FREQ_TOL_NOISY
    ztol = DAMP_TOL_CLEAN if noise == 0 else DAMP_TOL_NOISY
    ferr, _ = _check(case, fit, ftol, ztol)
    assert len(fit.modes) == 11


def test_mode_50_times_weaker_than_its_neighbours_is_found():
    case = plate_case(weak=1 / 50)
    fit = rfp.find_modes(case.freq, case.frf)
    _check(case, fit, FREQ_TOL_CLEAN, DAMP_TOL_CLEAN)


@pytest.mark.parametrize("seed", [0, 4])
def test_weak_mode_with_3_percent_noise_is_found_by_the_gap_search(seed):
    """Seeds 0-11 measured: weak mode error -0.028..+0.085 %, nothing spurious. Without the
    gap search (criteria.gap_search=False) it is missed on every seed."""
    case = plate_case(weak=1 / 50, noise=0.03, seed=seed)
    fit = rfp.find_modes(case.freq, case.frf)
    _check(case, fit, FREQ_TOL_NOISY, DAMP_TOL_NOISY)


def test_weak_mode_with_1_percent_noise_in_a_band_around_it():
    case = plate_case(weak=1 / 50, noise=0.01, seed=1)
    fit = rfp.find_modes(case.freq, case.frf, bands=[(380, 520)])
    assert len(fit.modes) == 1
    assert fit.modes[0].freq_hz == pytest.approx(446.65, rel=FREQ_TOL_NOISY)


def test_user_bands_and_n_modes():
    case = plate_case()
    fit = rfp.find_modes(case.freq, case.frf, bands=[(100, 300), (300, 500)], n_modes=4)
    assert np.allclose(fit.freq_hz, case.freq_hz[:4], rtol=FREQ_TOL_CLEAN)
    # a single wide band is split internally and still finds everything
    fit = rfp.find_modes(case.freq, case.frf, bands=[(60, 1600)])
    _check(case, fit, FREQ_TOL_CLEAN, DAMP_TOL_CLEAN)


# --------------------------------------------------------------------------- continuity
def _start(freq_hz, zeta):
    return [rfp._Candidate(freq_hz=float(f), damping_ratio=float(z), freq_std_hz=0.0,
                           damping_std=0.0, orders_stable=5, top_order=10)
            for f, z in zip(freq_hz, zeta)]


@pytest.mark.parametrize("case_kw, band, own, near, applied", [
    # 1130.7, 1388.2 Hz, the neighbours 351-902 Hz fixed (as find_modes)
    (dict(noise=0.03, seed=1), (973, 1600), slice(8, None), slice(3, 8), 1e-6),
    # 125-446.65 Hz with a mode 50 times weaker (446.65 Hz), the neighbours 580-902 Hz fixed
    (dict(weak=1 / 50, noise=0.03, seed=2), (68, 511), slice(0, 5), slice(5, 8), 1e-7)],
    ids=["strong", "weak"])
def test_refined_poles_do_not_depend_on_where_the_refinement_starts(case_kw, band, own, near,
                                                                     applied):
    """The output-error optimum is one point: started 0.2 half-power bandwidths and 20 % of
    the damping away from the true poles (the size of the jumps of the stabilised RFP
    median), the refinement ends at the same poles to 1e-10 (measured 8e-12, damping 9e-10; it
    was 9e-4 Hz at 1130 Hz, 8e-7, before the projection was computed stably: the optimiser
    stopped where its start decided).

    A mode 50 times weaker than its neighbours (446.65 Hz, 3 % noise) is weakly determined:
    the trust region stopped where the fall of the cost reached its rounding, at a place its
    start decided: started 0.2 bandwidths away it ended 2.5e-8 (relative, 1.1e-5 Hz) from
    where it ended from the true poles, 2e-6 in damping. The Gauss-Newton polish ends at the
    stationary point: within 1e-10 and 1e-8 whatever the start (measured 1.2e-11, 8e-10)."""
    case = plate_case(**case_kw)
    sel = (case.freq >= band[0]) & (case.freq <= band[1])
    f, H = case.freq[sel], case.frf[:, sel]
    f_true, z_true = case.freq_hz[own], case.damping_ratio[own]
    fixed = rfp._pole(case.freq_hz[near], case.damping_ratio[near])

    def refined(shift):
        out = rfp.refine_poles(f, H, _start(f_true * (1 + shift * z_true), z_true * (1 - shift)),
                               fixed, w_ref=2 * np.pi * f[-1])
        return np.array([c.freq_hz for c in out]), np.array([c.damping_ratio for c in out])

    f0, z0 = refined(0.0)
    assert np.all(np.abs(f0 / f_true - 1) > applied)         # the refinement was applied
    assert np.allclose(f0, f_true, rtol=FREQ_TOL_NOISY)
    for shift in (-0.2, 0.2):
        f1, z1 = refined(shift)
        np.testing.assert_allclose(f1, f0, rtol=1e-10, atol=0)
        np.testing.assert_allclose(z1, z0, rtol=1e-8, atol=0)


def test_frequencies_are_continuous_in_the_frf_data():
    """FRFs changed by 1e-10 (relative, random) give frequencies within 1e-9 and damping
    ratios within 1e-8 (relative) of the unchanged ones. A continuous estimator changes by
    about the condition number times 1e-10: measured 3.5e-13 and 6.8e-11 here (at most 7e-12
    and 8e-10 over 14 synthetic cases, the mode 50 times weaker included). A refinement
    that stopped short of its optimum, where the stabilised RFP poles it started from
    decided, moved them by up to 5.3e-7 (6e-4 Hz at 1130 Hz, this case) and 8e-5."""
    case = plate_case(noise=0.03, seed=1)
    a = rfp.find_modes(case.freq, case.frf)
    noise = np.random.default_rng(0).standard_normal(case.frf.shape)
    b = rfp.find_modes(case.freq, case.frf * (1 + 1e-10 * noise))
    assert len(a.modes) == len(b.modes) == 10
    np.testing.assert_allclose(b.freq_hz, a.freq_hz, rtol=1e-9, atol=0)
    np.testing.assert_allclose(b.damping_ratio, a.damping_ratio, rtol=1e-8, atol=0)


def test_frequencies_do_not_follow_the_stabilised_poles_they_start_from(monkeypatch):
    """The stabilised RFP estimate of a pole (a median over the stable orders) jumps where a
    pole's stability flag flips. Every one moved by 0.1 half-power bandwidths (and its damping
    by 10 %), the frequencies reported stay within 1e-9 (relative) and the damping ratios
    within 1e-7 of those without the move (measured 1.2e-11 and 3.8e-9): each band's
    refinement ends at its optimum whatever its start, and the poles of the neighbouring bands
    it holds fixed are theirs after their own refinement. With the neighbours fixed at their
    RFP values they moved by up to 4.1e-7 (3.7e-4 Hz at 902 Hz) and 1.7e-5."""
    from dataclasses import replace

    case = plate_case(noise=0.03, seed=1)
    a = rfp.find_modes(case.freq, case.frf)
    select = rfp.select_poles

    def moved(chart, **kw):
        out = select(chart, **kw)
        sign = (-1.0) ** np.arange(len(out))
        return [replace(c, freq_hz=c.freq_hz * (1 + 0.1 * s * c.damping_ratio),
                        damping_ratio=c.damping_ratio * (1 - 0.1 * s))
                for c, s in zip(out, sign)]

    monkeypatch.setattr(rfp, "select_poles", moved)
    b = rfp.find_modes(case.freq, case.frf)
    assert len(a.modes) == len(b.modes) == 10
    np.testing.assert_allclose(b.freq_hz, a.freq_hz, rtol=1e-9, atol=0)
    np.testing.assert_allclose(b.damping_ratio, a.damping_ratio, rtol=1e-7, atol=0)


def test_stabilisation_chart_marks_physical_poles_stable():
    case = plate_case()
    chart = rfp.stabilisation(case.freq, case.frf, (100, 300), range(1, 11))
    assert set(np.unique(chart.order)) <= set(range(1, 11))
    for f in case.freq_hz[:3]:
        near = np.abs(chart.freq_hz / f - 1) < 1e-4
        assert (chart.stable[near] == 2).sum() >= 5
    cands = rfp.select_poles(chart)
    assert np.allclose([c.freq_hz for c in cands], case.freq_hz[:3], rtol=1e-5)


# --------------------------------------------------------------------------- bad input
def test_bad_axes_and_values_raise_frf_error():
    case = plate_case(n_lines=401)
    f = case.freq.copy()
    f[10] = f[9]
    with pytest.raises(FrfError, match="not strictly increasing"):
        rfp.find_modes(f, case.frf)
    with pytest.raises(FrfError, match="shape"):
        rfp.find_modes(case.freq[:-1], case.frf)
    H = case.frf.copy()
    H[2, 7] = np.nan
    with pytest.raises(FrfError, match="point 3 has NaN/inf"):
        rfp.find_modes(case.freq, H)


def test_bad_bands_and_too_many_modes_raise_frf_error():
    case = plate_case(n_lines=401)
    with pytest.raises(FrfError, match="empty"):
        rfp.find_modes(case.freq, case.frf, bands=[(300, 200)])
    with pytest.raises(FrfError, match="holds 4 frequency lines"):
        rfp.find_modes(case.freq, case.frf, bands=[(120, 123)])
    with pytest.raises(FrfError, match="outside the FRF axis"):
        rfp.find_modes(case.freq, case.frf, bands=[(1000, 1200)])
    with pytest.raises(FrfError, match="asked for 5 modes but the band"):
        rfp.find_modes(case.freq, case.frf, bands=[(100, 300)], n_modes=5)
    with pytest.raises(FrfError, match="too few to fit 40 modes"):
        rfp.find_modes(case.freq, case.frf, bands=[(110, 140)], n_modes=40)


def test_no_peak_raises_a_clear_error():
    f = np.arange(1.0, 200.0)
    with pytest.raises(FrfError, match="no resonance peak"):
        rfp.find_modes(f, np.ones((2, f.size), dtype=complex))


# --------------------------------------------------------------------------- independent estimator
def test_against_sdypy_ema_lscf():
    """sdypy-EMA's LSCF (optional dependency) on the same 3 % noise data.

    sdypy is told the true frequencies to pick its poles (select_closest_poles), laminid picks
    its own. Measured: sdypy max error 0.018 %, laminid 0.0064 % (accelerance, seed 0).
    """
    EMA = pytest.importorskip("sdypy.EMA")
    import warnings

    case = plate_case(kind="accelerance", f_start=0.0, noise=0.03, seed=0)
    model = EMA.Model(frf=case.frf, freq=case.freq, lower=50, upper=1600, pol_order_high=60,
                      frf_form="accelerance")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.get_poles(method="lscf", show_progress=False)
        model.select_closest_poles(case.freq_hz, f_window=20)
    sdypy_err = np.abs(np.asarray(model.nat_freq) / case.freq_hz - 1)
    fit = rfp.find_modes(case.freq, case.frf)
    idx, spurious = _match(fit.freq_hz, case.freq_hz)
    assert np.all(idx >= 0) and not spurious
    ours = np.abs(fit.freq_hz[idx] / case.freq_hz - 1)
    assert sdypy_err.max() < FREQ_TOL_NOISY
    assert ours.max() < FREQ_TOL_NOISY
    assert np.allclose(fit.freq_hz[idx], model.nat_freq, rtol=FREQ_TOL_NOISY)


def test_weak_mode_with_3_percent_noise_needs_sanathanan_koerner_iterations():
    """At 3 % noise the plain linearised fit does not stabilise the weak mode; per-order SK
    iterations in a band around it do (measured 446.48-446.82 Hz over seeds 0-4)."""
    case = plate_case(weak=1 / 50, noise=0.03, seed=2)
    crit = rfp.PoleCriteria(sk_iter=2, reweight=False)
    fit = rfp.find_modes(case.freq, case.frf, bands=[(380, 520)], criteria=crit)
    assert len(fit.modes) == 1
    assert fit.modes[0].freq_hz == pytest.approx(446.65, rel=FREQ_TOL_NOISY)


def test_relative_weighting_is_exact_on_clean_data():
    case = plate_case(n_lines=601)
    crit = rfp.PoleCriteria(weighting="relative")
    fit = rfp.find_modes(case.freq, case.frf, bands=[(60, 600)], criteria=crit)
    assert np.allclose(fit.freq_hz, case.freq_hz[:6], rtol=FREQ_TOL_CLEAN)
    with pytest.raises(FrfError, match="weighting 'x'"):
        rfp.find_modes(case.freq, case.frf, criteria=rfp.PoleCriteria(weighting="x"))


def test_an_automatic_band_too_narrow_for_a_sweep_joins_its_neighbour():
    """The peaks of noisy FRFs (an acquire file of coherence 0.7) made an automatic band of 9
    lines at the axis' end, 1582-1598 Hz, and find_modes stopped: 'band 1582:1598 Hz holds 9
    lines, too narrow for a stabilisation sweep over 6 orders; widen it', to a user who gave
    no band. It joins its neighbour (the lower one; the first band the next one)."""
    from laminid_cli.frf.rfp import PoleCriteria, _merge_narrow

    freq = np.arange(0.0, 1601.0, 2.0)
    c = PoleCriteria()
    plan = [((2.0, 12.0), 1), ((10.0, 500.0), 4), ((480.0, 1584.0), 4), ((1582.0, 1598.0), 1)]
    assert _merge_narrow(plan, freq, 3, c) == [((2.0, 500.0), 5), ((480.0, 1598.0), 5)]
    wide = [((10.0, 500.0), 4), ((480.0, 1584.0), 4)]
    assert _merge_narrow(wide, freq, 3, c) == wide
    assert _merge_narrow([((1582.0, 1598.0), 1)], freq, 3, c) == [((1582.0, 1598.0), 1)]


def test_a_strong_peak_without_a_mode_is_named_and_a_clean_fit_has_none():
    """rfp.missed_peak_notes: a peak of the summed |H| at least MISSED_PEAK_DB (20 dB)
    prominent, inside the bands fitted, with no mode within 2 % of it, is named with the band
    to fit alone. The emulated plate at --noise 0.2 hid its 212.4 Hz mode (a 21.9 dB peak)
    from the fit without a word, and --into would have written every mode above it one place
    too low. A clean plate's fit (ten modes, 0.1 % noise) has no such note; with its first
    mode taken out of the fit, the note names that mode's peak."""
    import dataclasses

    case = plate_case(noise=1e-3)
    fit = rfp.find_modes(case.freq, case.frf)
    assert len(fit.modes) == len(case.freq_hz)
    assert rfp.missed_peak_notes(fit, case.freq, case.frf) == []
    missing = dataclasses.replace(fit, modes=fit.modes[1:])
    notes = rfp.missed_peak_notes(missing, case.freq, case.frf)
    assert len(notes) == 1, notes
    assert notes[0].startswith("the summed |H| peaks at 125.0 Hz (")
    assert "no mode was found within 2 % of it" in notes[0]
    assert "(--band 100:150)" in notes[0]
    # a peak outside the bands fitted (--band elsewhere) is not the fit's to find
    elsewhere = dataclasses.replace(missing, bands=tuple(
        b for b in fit.bands if b.band_hz[0] > 200))
    assert rfp.missed_peak_notes(elsewhere, case.freq, case.frf) == []


# --------------------------------------------------------------------------- credible poles
@pytest.fixture(scope="module")
def noisy_emulated_plate():
    """The emulated analyser's plate (tests/instrument/emulator.py) at noise 0.2: five points,
    five hits each, 1-1600 Hz at 1 Hz; its seven modes (Hz, damping ratio)."""
    from tests.instrument.emulator import PLATE_MODES, PlateSimulator

    freq = np.arange(1, 1601) * 1.0
    sim = PlateSimulator(noise=0.2)
    H = np.array([sim.average(freq, p, 5, 0.0, p)[0] for p in range(1, 6)])
    return freq, H, np.array(PLATE_MODES)


def _once(fit, modes):
    """Each mode of ``fit`` matched to the true mode nearest it, within FREQ_TOL_NOISY in
    frequency and DAMP_TOL_NOISY in damping, and no true mode matched twice; the true
    frequencies matched."""
    true_f, true_z = modes[:, 0], modes[:, 1]
    k = np.argmin(np.abs(fit.freq_hz[:, None] - true_f[None, :]), axis=1)
    np.testing.assert_allclose(fit.freq_hz, true_f[k], rtol=FREQ_TOL_NOISY, atol=0)
    np.testing.assert_allclose(fit.damping_ratio, true_z[k], rtol=DAMP_TOL_NOISY, atol=0)
    assert np.unique(k).size == k.size, f"a mode listed twice: {fit.freq_hz}"
    return true_f[k]


def _band_poles_are_modes(fit):
    """Every pole of every band's LSFD (its own and its neighbours') is a listed mode (to 1e-7:
    the neighbours are at the previous pass's values; 6.5e-9 apart in the case below)."""
    listed = fit.freq_hz
    for band in fit.bands:
        for f in np.abs(band.poles) / (2 * np.pi):
            assert np.min(np.abs(listed - f)) < 1e-7 * f, (band.band_hz, f, listed)


def test_a_pole_dropped_as_noise_is_no_neighbour_in_another_bands_fit(caplog):
    """A pole the significance test drops (here 1088.32 Hz, peak/residual 1.34 < 5, in the band
    375-1089 Hz; 10 % rms noise) was still held fixed, at its refined value, in the next
    pass's refinement and LSFD of the band 976-1558 Hz (its neighbour), where it moved 901.91
    and 1130.69 Hz by 1e-2 and 6e-3 Hz, and was a candidate of its own band again (dropped
    twice). Now the poles of every band's fit are the modes listed, and it is dropped once."""
    import logging

    case = plate_case(noise=0.1, noise_kind="rms", seed=6)
    with caplog.at_level(logging.INFO, logger="laminid_cli.frf.rfp"):
        fit = rfp.find_modes(case.freq, case.frf)
    _once(fit, np.column_stack([case.freq_hz, case.damping_ratio]))
    _band_poles_are_modes(fit)
    drops = [r.getMessage() for r in caplog.records if "1088.3" in r.getMessage()]
    assert len(drops) == 1 and "peak/residual 1.34 < 5.00" in drops[0], drops


def test_a_pole_whose_refinement_leaves_its_bounds_is_no_mode(noisy_emulated_plate, caplog):
    """A pole whose output-error optimum lies beyond the refinement's bounds (two half-power
    half-widths from its stabilised value, or its damping e^1.5 times) kept that stabilised
    value: at noise 0.2 a second pole of the 497.3 Hz mode's band (497.339 Hz, damping driven
    to its lower bound) sat on the mode the other found, and the mode was listed twice
    (497.430, 497.431 Hz: every later mode's index shifted); a pole at 1263.30 Hz with damping
    9e-5, whose optimum lay beyond both bounds, was listed as a mode. Both are dropped now, and
    are no other band's neighbours: the five modes the automatic bands see are listed once,
    within 0.1 % and 15 % (measured 2.9e-4, 2.9 %; 212.4 and 841.2 Hz hide in the noise, which
    rfp.missed_peak_notes names), and every band's poles are those five."""
    import logging

    freq, H, modes = noisy_emulated_plate
    with caplog.at_level(logging.INFO, logger="laminid_cli.frf.rfp"):
        fit = rfp.find_modes(freq, H)
    assert list(_once(fit, modes)) == [318.9, 497.3, 633.8, 1120.6, 1388.2]
    _band_poles_are_modes(fit)
    out = [r.getMessage() for r in caplog.records if "not a credible mode" in r.getMessage()]
    assert [m.split(":")[0] for m in out] == ["dropping pole at 497.339 Hz",
                                              "dropping pole at 1263.303 Hz"], out
    # --plot's chart note says why the 1263 Hz poles are none of the modes (it said: below
    # the fit's residual, dropped as noise)
    from laminid_cli.frf.plot import unlisted_note

    group = [u for u in rfp.unlisted_stable_poles(fit, freq) if u.reason == "reach"]
    assert len(group) == 1 and fit.bands[group[0].band].band_hz == (1261.0, 1497.0)
    assert group[0].freq_hz[0] < 1263.3 < group[0].freq_hz[1]
    assert unlisted_note(group, fit.criteria, width=1000).endswith(
        "its output-error fit would move it more than 2 f·ζ (at least 0.5 line), or its damping "
        "4.5 times: not a credible mode")


def test_two_poles_the_refinement_brings_to_one_place_are_one_mode(noisy_emulated_plate,
                                                                   monkeypatch, caplog):
    """Two poles that the refinement brings within a tenth of a half-power bandwidth of each
    other are one mode: their LSFD columns are collinear (rfp.pole_overlap at least
    1/sqrt(1.01)), their modal constants large and of opposite sign (|A| ~ 175-300 where the
    mode's are ~1), so the significance test kept both. Here the refinement is made to keep a
    pole at its bound where it was (as before poles out of reach were dropped), which put two
    poles on the 497.3 Hz mode (497.430, 497.431 Hz) in every pass: listed once now, with a
    log line, within 0.1 % and 15 % of the true mode. The tests' close pair (351.2 and 352.25
    Hz, 0.2 % damping: 0.75 bandwidths apart) overlaps 0.80 and stays two
    (test_two_modes_03_percent_apart_are_both_found). The significance test
    (rfp.pole_false_alarm) is switched off here (FALSE_ALARM 1): it drops the pole at its
    bound first (its constants lower the residual by chi-squared 9.5 on 10 degrees of freedom),
    before the refinement brings it onto the mode."""
    import logging

    refine = rfp._refine
    monkeypatch.setattr(rfp, "FALSE_ALARM", 1.0)

    def keep_at_bound(*args, **kwargs):
        poles, off = refine(*args, **kwargs)
        return poles, np.zeros_like(off)

    monkeypatch.setattr(rfp, "_refine", keep_at_bound)
    freq, H, modes = noisy_emulated_plate
    with caplog.at_level(logging.INFO, logger="laminid_cli.frf.rfp"):
        fit = rfp.find_modes(freq, H)
    near = [m for m in fit.modes if abs(m.freq_hz - 497.3) < 5]
    assert len(near) == 1, fit.freq_hz
    assert near[0].freq_hz == pytest.approx(497.3, rel=FREQ_TOL_NOISY)
    assert near[0].damping_ratio == pytest.approx(0.007, rel=DAMP_TOL_NOISY)
    assert any(r.getMessage().startswith("poles at 497.43") and "are one mode" in r.getMessage()
               for r in caplog.records), [r.getMessage() for r in caplog.records]
    lam = rfp._pole([351.2, 351.2 * 1.003], [0.002, 0.002])
    assert rfp.pole_overlap(lam[0], lam[1]) == pytest.approx(0.80, abs=0.01)
    sigma = -lam[0].real                                 # 0.1 half-power bandwidths (2 sigma)
    assert rfp.pole_overlap(lam[0], lam[0] + 0.2j * sigma) == pytest.approx(1 / np.sqrt(1.01),
                                                                             rel=1e-12)


# --------------------------------------------------------------------------- significance
def _pure_noise(n_points, seed, n_lines=400):
    rng = np.random.default_rng(seed)
    shape = (n_points, n_lines)
    return (np.arange(1.0, n_lines + 1),
            (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2))


@pytest.mark.parametrize("n_points, seed, pole_hz", [(2, 3, 69.2), (2, 7, 78.4), (1, 15, 233.7),
                                                     (1, 172, 113.45), (1, 273, 364.24)])
def test_pure_noise_gives_no_mode(n_points, seed, pole_hz):
    """FRFs of pure noise (complex Gaussian, 1-400 Hz, automatic bands) gave a stable pole that
    passed the peak/residual rule and was listed as a mode: its half-power bandwidth below the
    line spacing, its peak |A| / sigma between two lines high while at the lines it fitted one
    line's noise (seeds 3, 7 and 14 of 2 FRFs, 15 of 1: 4 of 120 fits of 1, 2 or 5 FRFs). Its
    modal constants lower the residual by what noise gives somewhere in the lines fitted with a
    probability near 1, far above rfp.FALSE_ALARM (1 %): no mode now, the pole reported as
    dropped by chance. The probability is over all the lines fitted, the places the pole could
    have been found: taken over each band's own lines (27-34 of ~19 automatic bands), one FRF
    of pure noise kept a mode in 3 of 200 fits (seeds 100-299: 113.45 Hz with seed 172, 0.0057
    in its band, 0.079 over the 399 lines fitted; 364.24 Hz with seed 273, 0.0025 and 0.034);
    none of 600 fits of 1, 2 or 5 FRFs now (46 before the test)."""
    freq, H = _pure_noise(n_points, seed)
    fit = rfp.find_modes(freq, H)
    assert fit.modes == ()
    chance = [d for d in fit.dropped if d.reason == "chance"]
    assert any(abs(d.freq_hz - pole_hz) < 0.1 for d in chance), fit.dropped
    assert all(d.false_alarm > rfp.FALSE_ALARM for d in chance)


def test_10_percent_noise_pole_beside_a_mode_is_not_kept():
    """At 10 % (proportional) noise a noise pole beside the 351.2 Hz mode (0.2 % damping) was
    listed as a second mode: 351.485 Hz, 0.21 half-power bandwidths from it, in the band
    63-426 Hz (the mode itself at 351.155 Hz); 350.685 Hz, 0.36 bandwidths, with the automatic
    bands. Its modal constants lower the weighted residual by chi-squared 21.4 (12.8) on 10
    degrees of freedom: what noise gives somewhere in the 364 lines fitted with a probability
    of 1. Dropped, with why; the four modes are found within 0.1 % and 15 %, the 351.2 Hz one
    closer without the noise pole beside it (351.188 Hz)."""
    case = plate_case(noise=0.1, seed=0)
    fit = rfp.find_modes(case.freq, case.frf, bands=[(63, 426)])
    np.testing.assert_allclose(fit.freq_hz, case.freq_hz[:4], rtol=FREQ_TOL_NOISY, atol=0)
    np.testing.assert_allclose(fit.damping_ratio, case.damping_ratio[:4], rtol=DAMP_TOL_NOISY)
    drop = [d for d in fit.dropped if abs(d.freq_hz - 351.5) < 0.5]
    assert len(drop) == 1 and drop[0].reason == "chance", fit.dropped
    assert drop[0].false_alarm > 0.5
    assert "what noise alone gives somewhere in the 364 lines fitted" in drop[0].why


def test_false_alarm_probability_of_a_pole_in_noise_is_as_stated():
    """rfp.pole_false_alarm's per-place probability (its chi-squared tail; the false-alarm
    probability is it times the number of lines fitted) of a pole held at one place in noise
    is uniform on (0, 1): of 300 seeds (2 FRFs of 120 lines with a mode at 130 Hz, 1 %
    damping; additive noise, and noise proportional to the FRF), the share below 0.1 is 0.1
    within 0.06 (binomial std 0.021), for a pole far from the mode (157.3 Hz) and one 0.38
    half-power bandwidths from it (129.5 Hz; measured 0.06-0.12). The noise variance of each
    line is modelled from the residuals, a + b |H|^2, by reweighted least squares; fitted
    unweighted, the few large residuals of the proportional noise at the resonance set a: the
    noise far from the mode taken about twice too large, the share was 0.03 at 157.3 Hz."""
    from scipy.special import chdtrc

    freq = np.arange(100.0, 220.0)
    w_ref = 2 * np.pi * freq[-1]
    for kind in ("rms", "proportional"):
        for at in (157.3, 129.5):
            test_pole, mode = rfp._pole([at, 130.0], [0.004, 0.01])
            p = []
            for seed in range(200):
                H = synth_frf(freq, [(130.0, 0.01)], np.array([[1e4], [-6e3]]), noise=0.05,
                              noise_kind=kind, seed=seed)
                fa, stat, dof = rfp.pole_false_alarm(freq, H, [test_pole, mode], 1, w_ref=w_ref)
                assert dof == 4
                p.append(chdtrc(dof, stat[0]))
                assert fa[0] == pytest.approx(min(freq.size * p[-1], 1.0), rel=1e-12)
            share = np.mean(np.array(p) < 0.1)
            assert share == pytest.approx(0.1, abs=0.06), (kind, at, share)


def test_the_chart_note_says_a_pole_was_dropped_by_chance():
    """--plot's chart note named a pole the significance test dropped 'not above the fit's
    residual (5 x): dropped as noise', the peak/residual rule it had passed; it names the rule
    that dropped it."""
    from laminid_cli.frf.plot import unlisted_note

    freq, H = _pure_noise(2, 3)
    fit = rfp.find_modes(freq, H)
    # the pole's stable track at 68.77-68.86 Hz (refined to 69.23 Hz before it was dropped)
    group = [u for u in rfp.unlisted_stable_poles(fit, freq) if u.reason == "chance"]
    assert len(group) == 1 and 68.7 < group[0].freq_hz[0] <= group[0].freq_hz[1] < 68.9, group
    assert unlisted_note(group, fit.criteria, width=1000).endswith(
        "its modal constants lower the residual no more than noise alone does somewhere in the "
        "lines fitted (false-alarm probability above 0.01): not a credible mode")


def test_a_sub_band_of_a_given_band_too_narrow_for_a_sweep_joins_its_neighbour():
    """--band 100:300 on noisy FRFs (two FRFs of pure noise, seed 3) holds more than six peaks
    and is fitted as sub-bands; noise peaks made the last one 293:300 Hz, 8 lines, and the fit
    stopped: 'band 293:300 Hz holds 8 lines, too narrow for a stabilisation sweep ...; widen
    it', a band the user never gave (9 of 60 such fits of 1, 2 or 5 FRFs). It joins its
    neighbour, as an automatic band does: the sub-bands cover 100-300 Hz, each of 20 lines
    or more, and the noise gives no mode."""
    freq, H = _pure_noise(2, 3)
    fit = rfp.find_modes(freq, H, bands=[(100, 300)])
    bands = [b.band_hz for b in fit.bands]
    assert bands[0][0] == 100.0 and bands[-1] == (260.0, 300.0), bands
    assert all(hi - lo >= 20 for lo, hi in bands), bands
    assert fit.modes == ()
