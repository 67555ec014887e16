"""Identification (laminid_cli.identify): gradient, synthetic round trips, options, bad input.

The synthetic specimens are YAML text built here; their "measured" frequencies are computed by
the forward model for known constants on the same (coarse) mesh, so a perfect identification
gives them back exactly. The initial guesses are 30 % off the truth with mixed signs, chosen
so that the model's mode order at the guess is the true order (checked by MAC in each test):
the identification pairs measured and model modes in sorted order at the start (paper
section 4), so a guess whose first modes come in another order cannot converge to the truth
(see test_crossing_modes_*).
"""

import numpy as np
import pytest

from laminid_cli.errors import FitError
from laminid_cli.forward import build_forward_model
from laminid_cli.identify import IdentifyOptions, Problem, identify
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants, infeasibility_reasons
from laminid_cli.modal import mac
from laminid_cli.specimen import load_specimen_text, read_specimen

GPa = 1e9
MESH = (6, 6)

#: carbon/epoxy constants close to the paper's Table 2
CARBON = dict(E1=161 * GPa, E2=9.3 * GPa, G12=6.8 * GPa, G13=3.1 * GPa, G23=3.2 * GPa, nu12=0.3)
#: a second carbon and an E-glass for the hybrid
CARBON_H = dict(E1=135 * GPa, E2=9 * GPa, G12=5 * GPa, G13=5 * GPa, G23=3.2 * GPa, nu12=0.3)
GLASS_H = dict(E1=42 * GPa, E2=12 * GPa, G12=4.2 * GPa, G13=4.2 * GPa, G23=3.5 * GPa, nu12=0.28)

#: the S1.1 plate: a = 210.5 mm, b = 311 mm, h = 3.06 mm (a/h = 69), 24 plies, 0.3225 kg
THIN = dict(a=0.2105, b=0.311, h=3.06e-3, mass=0.3225, layup="[45_3/0_3/-45_3/90_3]s")
#: a thick cross-ply, a/h = 10: transverse shear (G13, G23) matters, in-plane modes appear
THICK = dict(a=0.10, b=0.15, h=0.010, mass=1570 * 0.10 * 0.15 * 0.010, layup="[0/90]2s")
#: carbon 0-degree and glass 90-degree plies, a/h = 15
HYBRID = dict(a=0.15, b=0.10, h=0.010, mass=1750 * 0.15 * 0.10 * 0.010,
              layup="[0c/90g/0c/90g]s")

#: relative offsets of the initial guesses (mixed signs, 30 %)
OFF_THIN = dict(E1=1.3, E2=0.7, G12=1.3, G13=0.7, G23=1.3, nu12=0.7)
OFF_THICK = dict(E1=1.3, E2=0.7, G12=1.3, G13=1.3, G23=1.3, nu12=0.7)


# --- helpers ---------------------------------------------------------------------------------

def material_yaml(name, c, extra=""):
    lines = [f"  {name}:"] + [f"    {k}: {c[k]!r}" for k in CONSTANT_NAMES]
    return "\n".join(lines) + "\n" + extra


def specimen_text(plate, materials, freq=None, weights=None, extra_materials=None):
    """YAML text of a specimen; ``materials`` maps names to constant dicts (SI)."""
    extra_materials = extra_materials or {}
    text = (f"name: synthetic\ngeometry:\n  a: {plate['a']!r}\n  b: {plate['b']!r}\n"
            f"  h: {plate['h']!r}\nmass: {plate['mass']!r}\nmaterials:\n")
    text += "".join(material_yaml(n, c, extra_materials.get(n, "")) for n, c in materials.items())
    text += f"layup: \"{plate['layup']}\"\n"
    if freq is not None:
        text += "measured:\n  frequencies: [" + ", ".join(repr(float(f)) for f in freq) + "]\n"
        if weights is not None:
            text += "  weights: [" + ", ".join(repr(float(w)) for w in weights) + "]\n"
    return text


def scaled(true, off):
    """``true`` times ``off``: constant -> factor for every material, or material -> that."""
    out = {}
    for m, c in true.items():
        f = off[m] if m in off else off
        out[m] = {k: v * f.get(k, 1.0) for k, v in c.items()}
    return out


def synthetic(plate, true, n_modes, off, mesh=MESH, extra_materials=None, noise=0.0, seed=0):
    """Forward model of a specimen whose measured frequencies are the model's for ``true``.

    Returns (fm, freq_true): fm's file holds the initial guess ``true * off`` and the
    frequencies of ``true`` (times 1 + noise N(0, 1), seeded).
    """
    spec = load_specimen_text(specimen_text(plate, true, extra_materials=extra_materials))
    fm = build_forward_model(spec, mesh)
    modes = fm.solve([ElasticConstants(**true[m]) for m in fm.material_names], n_modes)
    freq = modes.freq * (1 + noise * np.random.default_rng(seed).standard_normal(n_modes))
    guess = scaled(true, off)
    spec2 = load_specimen_text(specimen_text(plate, guess, freq, extra_materials=extra_materials))
    fm2 = build_forward_model(spec2, mesh)
    # precondition (see the module docstring): same mode order at the guess as at the truth
    start = fm2.solve(n_modes=n_modes + 4)
    order = mac(modes.phi, start.phi, fm2.plate.M).argmax(axis=1)
    assert np.array_equal(order, np.arange(n_modes)), f"mode order at the guess: {order}"
    return fm2, modes.freq


def relative_errors(result, true):
    return {f"{m}.{k}": getattr(c, k) / true[m][k] - 1
            for m, c in zip(result.material_names, result.constants) for k in CONSTANT_NAMES}


def linearised_std(result, noise):
    """Standard deviation of ln P of the free constants for a relative frequency noise
    ``noise`` (Gauss-Newton covariance from the normalised sensitivities d ln f / d ln P)."""
    cols = [result.sensitivity_labels.index(f"{m}.{k}") for m, free in result.free.items()
            for k in free]
    S = result.sensitivity[:, cols]
    std = noise * np.sqrt(np.diag(np.linalg.inv(S.T @ S)))
    return dict(zip((result.sensitivity_labels[j] for j in cols), std))


def fd_std(fm, true, n_modes, noise, h=1e-4):
    """The linearised standard deviations of ln P of the six constants of the single material
    ``true`` for relative frequency noise ``noise``, from central differences of the forward
    model's frequencies at ``true`` (steps of h in ln P): a reference independent of the
    identification's own sensitivities."""
    (m, c), = true.items()
    cols = []
    for k in CONSTANT_NAMES:
        f = []
        for sign in (1, -1):
            cc = dict(c)
            cc[k] = c[k] * np.exp(sign * h)
            f.append(fm.solve([ElasticConstants(**cc)], n_modes).freq)
        cols.append((np.log(f[0]) - np.log(f[1])) / (2 * h))
    S = np.column_stack(cols)
    std = noise * np.sqrt(np.diag(np.linalg.inv(S.T @ S)))
    return {f"{m}.{k}": float(v) for k, v in zip(CONSTANT_NAMES, std)}


def central_differences(prob, x, h):
    """Richardson-extrapolated central differences (steps h and h/2, error O(h^4)) of the
    objective (n_vars,) and of the paired eigenvalues (n_measured, n_vars)."""
    g = np.zeros(x.size)
    dlam = np.zeros((prob.n_meas, x.size))
    ev = prob.evaluate(x)
    lam, phi = ev.eigenvalues.copy(), ev.phi.copy()
    for j in range(x.size):
        est = []
        for step in (h[j], h[j] / 2):
            xp, xm = x.copy(), x.copy()
            xp[j] += step
            xm[j] -= step
            assert prob.feasible(xp) and prob.feasible(xm)
            ep, em = prob.evaluate(xp), prob.evaluate(xm)
            # sorted pairing: the paired modes must be the same modes at +-step
            for e in (ep, em):
                assert np.diag(mac(phi, e.phi, prob.fm.plate.M)).min() > 0.9, "modes crossed"
            est.append(((ep.objective - em.objective) / (2 * step),
                        (ep.eigenvalues - em.eigenvalues) / (2 * step)))
        g[j] = (4 * est[1][0] - est[0][0]) / 3
        dlam[:, j] = (4 * est[1][1] - est[0][1]) / 3
    prob.evaluate(x)
    assert np.allclose(prob.evaluate(x).eigenvalues, lam)
    return g, dlam


# --- 1. analytic gradient (paper Eqs 24-27) vs central differences ---------------------------

PRIOR_SPECIMEN = specimen_text(
    dict(THIN, layup="[0/90/45/-45]s"),
    {"cf": dict(CARBON)}, freq=[115, 180, 300, 400, 450, 560, 600, 760],
    extra_materials={"cf": "    prior: {nu12: 1.0}\n"})

GRADIENT_CASES = {
    "S1.1-alpha": (lambda: read_specimen("specimens/example1/S1.1.yaml"), (), "alpha", 6),
    "S2.1-alpha": (lambda: read_specimen("specimens/example2/S2.1.yaml"), (), "alpha", 6),
    "hybrid-cm-12": (lambda: read_specimen("specimens/example3/hybrid-cm.yaml"), (), "alpha", 12),
    "S1.1-fixed": (lambda: read_specimen("specimens/example1/S1.1.yaml"), ("nu12", "G13"),
                   "constants", 4),
    "prior": (lambda: load_specimen_text(PRIOR_SPECIMEN), (), "constants", 6),
}


@pytest.mark.parametrize("case", list(GRADIENT_CASES))
def test_gradient_matches_central_differences(case):
    """Every component within 1e-5 relative, at the initial guess and a perturbed point.

    The steps are 1e-3 max(1, |x_j|) with Richardson extrapolation: the eigenvalues carry a
    relative noise of about 1e-12 (Lanczos tolerance), so plain central differences with tiny
    steps cannot resolve the small components (alpha9's is 3e-4 of the largest for S2.1).
    The rows of d lambda / d x are checked within 1e-6 of their largest entry.
    """
    load, fix, kind, n_vars = GRADIENT_CASES[case]
    fm = build_forward_model(load(), MESH)
    prob = Problem(fm, IdentifyOptions(fix=fix, pairing="sorted"))
    assert prob.n_vars == n_vars
    assert {p.kind for p in prob.params} == {kind}
    x0 = prob.x0()
    rng = np.random.default_rng(3)
    x1 = x0 + 0.05 * np.abs(x0).clip(0.1) * rng.standard_normal(x0.size)
    assert prob.feasible(x1)
    for x in (x0, x1):
        ev = prob.evaluate(x)
        grad, dlam_dx = ev.gradient.copy(), ev.dlam_dx.copy()
        g_fd, _ = central_differences(prob, x, 1e-3 * np.maximum(1.0, np.abs(x)))
        rel = np.abs(grad - g_fd) / np.abs(g_fd)
        assert rel.max() < 1e-5, (case, rel)
        # each row of d lambda / d x relative to its largest entry; smaller steps, since a
        # close pair of modes (the hybrid's 14th and 15th) curves its eigenvalues strongly
        _, dlam_fd = central_differences(prob, x, 1e-4 * np.maximum(1.0, np.abs(x)))
        row = np.abs(dlam_dx - dlam_fd).max(axis=1) / np.abs(dlam_fd).max(axis=1)
        assert row.max() < 1e-6, (case, row)


def test_prior_term_value_and_gradient():
    """Eq. 15 second term: wp ((nu12 - nu12_0) / nu12_0)^2 is in the objective."""
    fm = build_forward_model(load_specimen_text(PRIOR_SPECIMEN), MESH)
    prob = Problem(fm, IdentifyOptions(pairing="sorted"))
    x = prob.x0()
    j = prob.labels.index("cf.nu12")
    assert prob.prior == [{"nu12": 1.0}] and prob.evaluate(x).gradient[j] != 0
    x2 = x.copy()
    x2[j] *= 1.1                                      # nu12 10 % up: prior adds 1.0 * 0.1^2
    ev2 = prob.evaluate(x2)
    rel = (prob.lam_meas - ev2.eigenvalues) / prob.lam_meas
    assert ev2.objective - np.sum(prob.weight * rel**2) == pytest.approx(0.01, rel=1e-9)


# --- 2. synthetic round trips ----------------------------------------------------------------

def test_round_trip_thin_plate_all_six_constants():
    """S1.1-like plate, 12 modes, noise-free: all six constants within 1e-4.

    nu12, G13 and G23 change the frequencies by at most 1-3 % of their relative change here
    (normalised sensitivities 0.001-0.01), but noise-free data determine them: the
    sensitivity matrix has full rank (checked), and the optimum is reached within 1e-4.
    """
    true = {"cf": CARBON}
    fm, _ = synthetic(THIN, true, 12, OFF_THIN)
    r = identify(fm, IdentifyOptions())
    assert r.converged, r.status
    assert r.parametrization == {"cf": "alpha"}
    assert np.linalg.svd(r.sensitivity, compute_uv=False).min() > 1e-3
    err = relative_errors(r, true)
    assert max(abs(e) for e in err.values()) < 1e-4, err
    assert r.rms_residual_percent < 1e-4
    assert r.initial_rms_residual_percent > 5


def test_round_trip_thick_plate_all_six_constants():
    """a/h = 10 cross-ply, 16 modes (two of them in-plane), noise-free: all six within 1e-4."""
    true = {"cf": CARBON}
    fm, _ = synthetic(THICK, true, 16, OFF_THICK)
    r = identify(fm, IdentifyOptions())
    assert r.converged, r.status
    err = relative_errors(r, true)
    assert max(abs(e) for e in err.values()) < 1e-4, err
    # transverse shear matters here: G13 and G23 sensitivities of several percent
    s = np.abs(r.sensitivity).max(axis=0)
    assert s[CONSTANT_NAMES.index("G13")] > 0.03 and s[CONSTANT_NAMES.index("G23")] > 0.1


HYBRID_DENSITY = {"carbon": "    density: 1550 kg/m^3\n", "glass": "    density: 1950 kg/m^3\n"}
#: free E1, E2, G12 of both materials off by 30 %; the rest at the truth (fixed)
OFF_HYBRID = {"carbon": dict(E1=0.7, E2=0.7, G12=1.3), "glass": dict(E1=1.3, E2=1.3, G12=0.7)}


def test_round_trip_two_material_hybrid():
    """Carbon 0 and glass 90 plies, 15 modes, E1, E2, G12 of each free: within 1e-4.

    Bending alone cannot separate a carbon 0-degree ply's E1 from a glass 90-degree ply's E2
    (both enter D11); the through-thickness distribution (third-order terms) and the in-plane
    modes of this thick plate do, weakly: the smallest singular value of the normalised
    sensitivities is about 0.004.
    """
    true = {"carbon": CARBON_H, "glass": GLASS_H}
    fm, _ = synthetic(HYBRID, true, 15, OFF_HYBRID, extra_materials=HYBRID_DENSITY)
    r = identify(fm, IdentifyOptions(fix=("G13", "G23", "nu12")))
    assert r.converged, r.status
    assert r.free == {"carbon": ("E1", "E2", "G12"), "glass": ("E1", "E2", "G12")}
    err = relative_errors(r, true)
    for m in ("carbon", "glass"):
        for k in ("E1", "E2", "G12"):
            assert abs(err[f"{m}.{k}"]) < 1e-4, err
        for k in ("G13", "G23", "nu12"):                     # held exactly
            assert getattr(r.constants[r.material_names.index(m)], k) == true[m][k]


def test_noisy_unidirectional_plate_E1_E2_G12_within_1_percent():
    """0.2 % Gaussian frequency noise (seeded): E1, E2, G12 within 1 %.

    A unidirectional 0-degree plate, 300 x 150 x 3 mm, whose modes separate E1, E2 and G12
    well (linearised standard deviations below 0.4 % each at this noise; its modes are 1.5 %
    apart or more, so the noise keeps their order). nu12, G13 and G23 are fixed at the
    true values: with 12 modes of a thin plate their standard deviations would be 12-120 %
    and they would drag the others (E1 0.9 %).
    """
    true = {"cf": CARBON}
    plate = dict(a=0.3, b=0.15, h=0.003, mass=1570 * 0.3 * 0.15 * 0.003, layup="[0_8]")
    fm, _ = synthetic(plate, true, 12, dict(E1=1.3, E2=1.3, G12=0.7), noise=0.002, seed=0)
    r = identify(fm, IdentifyOptions(fix=("nu12", "G13", "G23")))
    assert r.converged, r.status
    err = relative_errors(r, true)
    std = linearised_std(r, 0.002)
    assert max(std.values()) < 0.004, std
    for k in ("E1", "E2", "G12"):
        assert abs(err[f"cf.{k}"]) < 0.01, err
    # the residuals are the noise: RMS near 0.2 %
    assert 0.05 < r.rms_residual_percent < 0.3


@pytest.mark.parametrize("plate,n_modes,off", [(THIN, 12, OFF_THIN), (THICK, 16, OFF_THICK)],
                         ids=["thin-S1.1-like", "thick-cross-ply"])
def test_noisy_round_trip_all_free_within_linearised_scatter(plate, n_modes, off):
    """0.2 % frequency noise, all six free: E1, E2, G12 within 3 standard deviations.

    The issue asked for E1, E2, G12 within 1 %; for these layups that is not attainable: the
    linearised standard deviations at 0.2 % noise are E1 0.8 %, E2 5.4 %, G12 5.8 % (thin) and
    E1 1.0 %, E2 8.7 %, G12 0.3 % (thick) -- even with nu12, G13, G23 fixed, E2's are 3.1 % and
    3.8 %. So they are checked against the scatter the data allow (itself asserted), and
    within 1 % where that is 3 standard deviations or more.
    """
    true = {"cf": CARBON}
    fm, _ = synthetic(plate, true, n_modes, off, noise=0.002, seed=0)
    r = identify(fm, IdentifyOptions())
    assert r.converged, r.status
    err = relative_errors(r, true)
    # the scatter the data allow, from finite differences at the true constants (independent
    # of the identification); the identification's own sensitivities at its optimum agree
    std = fd_std(fm, true, n_modes, 0.002)
    own = linearised_std(r, 0.002)
    for k in ("E1", "E2", "G12"):
        assert own[f"cf.{k}"] == pytest.approx(std[f"cf.{k}"], rel=0.15), (k, own, std)
    assert std["cf.E2"] > 0.03                          # why 1 % cannot be asked for E2
    for k in ("E1", "E2", "G12"):
        assert abs(err[f"cf.{k}"]) < 3 * std[f"cf.{k}"], (k, err, std)
        if std[f"cf.{k}"] < 0.01 / 3:
            assert abs(err[f"cf.{k}"]) < 0.01, (k, err)


# --- 4. optimiser options and behaviour ------------------------------------------------------

def test_mma_reaches_the_slsqp_optimum():
    """LD_MMA and LD_SLSQP agree within 2e-5 relative (MMA needs ~90 evaluations, SLSQP ~13)."""
    true = {"cf": CARBON}
    fm, _ = synthetic(THIN, true, 12, dict(E1=1.3, E2=0.7, G12=1.3))
    opts = dict(fix=("nu12", "G13", "G23"))
    r_sl = identify(fm, IdentifyOptions(**opts))
    r_mma = identify(fm, IdentifyOptions(optimizer="mma", **opts))
    assert r_sl.converged and r_mma.converged, (r_sl.status, r_mma.status)
    a = np.array([r_sl.constants[0].as_array()])
    b = np.array([r_mma.constants[0].as_array()])
    assert np.abs(b / a - 1).max() < 2e-5
    assert np.abs(a / np.array([ElasticConstants(**CARBON).as_array()]) - 1).max() < 1e-6


def test_mma_with_all_constants_free():
    """MMA's inner iterations step outside the safety margins of the linear constraints (alpha
    parametrisation): such points are evaluated only while still positive definite, refused
    otherwise, and the run ends at a feasible point."""
    true = {"cf": CARBON}
    fm, _ = synthetic(THIN, true, 12, OFF_THIN)
    r = identify(fm, IdentifyOptions(optimizer="mma", max_evaluations=60))
    assert all(not infeasibility_reasons(c) for c in r.constants)
    assert r.rms_residual_percent < 0.1 * r.initial_rms_residual_percent


def test_fixed_constants_stay_at_their_initial_values_and_every_point_is_feasible():
    """fix=("nu12", "G13") on S1.1: the two never move (exactly), the others do; every
    evaluated point satisfies the bounds and linear constraints and gives a positive definite
    constitutive matrix."""
    spec = read_specimen("specimens/example1/S1.1.yaml")
    fm = build_forward_model(spec, MESH)
    opts = IdentifyOptions(fix=("nu12", "G13"))
    r = identify(fm, opts)
    c0 = fm.initial_constants[0]
    assert r.parametrization == {"IM7/977-2": "constants"}
    assert r.constants[0].nu12 == c0.nu12 and r.constants[0].G13 == c0.G13
    hist = r.history["constants"]
    assert np.all(hist[:, CONSTANT_NAMES.index("nu12")] == c0.nu12)
    assert np.all(hist[:, CONSTANT_NAMES.index("G13")] == c0.G13)
    assert abs(r.constants[0].E1 / c0.E1 - 1) > 0.2           # the free ones moved
    prob = Problem(fm, opts)
    lo, hi = prob.bounds()
    A, b = prob.linear_constraints()
    for x, P in zip(r.history["x"], hist):
        assert np.all(x >= lo - 1e-9) and np.all(x <= hi + 1e-9) and np.all(A @ x <= b + 1e-9)
        assert not infeasibility_reasons(ElasticConstants.from_array(P))


def test_every_evaluated_point_is_feasible_with_alpha_variables():
    """Paper Eq. 14 variables, S2.1 (glass): bounds and A x <= b at every evaluation."""
    fm = build_forward_model(read_specimen("specimens/example2/S2.1.yaml"), MESH)
    r = identify(fm, IdentifyOptions())
    prob = Problem(fm, IdentifyOptions())
    lo, hi = prob.bounds()
    A, b = prob.linear_constraints()
    X = r.history["x"]
    assert len(X) == r.evaluations > 5
    assert np.all(X >= lo - 1e-9) and np.all(X <= hi + 1e-9)
    assert np.all(X @ A.T <= b + 1e-9)
    for P in r.history["constants"]:
        assert not infeasibility_reasons(ElasticConstants.from_array(P))


#: a unidirectional plate whose 8th and 9th modes (a bending mode along the fibres and one
#: across them, a/b = 2.1 = 1.03 (E1/E2)^(1/4)) swap order when E1/E2 drops by a third
CROSSING = dict(a=0.1 * 2.04 * 1.03, b=0.1, h=0.003, mass=1570 * 0.2101 * 0.1 * 0.003,
                layup="[0_4]")
OFF_CROSSING = dict(E1=0.8, E2=1.2)


def crossing_case():
    true = {"cf": CARBON}
    spec = load_specimen_text(specimen_text(CROSSING, true))
    fm = build_forward_model(spec, MESH)
    truth = fm.solve([ElasticConstants(**CARBON)], 10)
    guess = scaled(true, OFF_CROSSING)
    spec2 = load_specimen_text(specimen_text(CROSSING, guess, truth.freq))
    fm2 = build_forward_model(spec2, MESH)
    start = fm2.solve(n_modes=12)
    order = mac(truth.phi, start.phi, fm2.plate.M).argmax(axis=1)
    assert list(order) == [0, 1, 2, 3, 4, 5, 6, 8, 7, 9]       # modes 8 and 9 cross
    return fm2, true


def test_crossing_modes_are_reported_and_sorted_pairing_recovers_the_truth():
    fm, true = crossing_case()
    opts = dict(fix=("G13", "G23", "nu12"))
    tracked = identify(fm, IdentifyOptions(**opts))
    assert tracked.swaps and "measured mode 8: model mode 8 -> 9" in tracked.swaps[0]
    assert any("re-anchored" in s for s in tracked.swaps)       # ended mis-paired, re-anchored
    assert list(tracked.pairing) == list(range(10))
    plain = identify(fm, IdentifyOptions(pairing="sorted", **opts))
    err = relative_errors(plain, true)
    assert max(abs(e) for e in err.values()) < 1e-6, err


def test_crossing_modes_tracked_pairing_recovers_the_truth():
    """Tracking keeps the start's (wrong) pairing through the crossing; re-anchoring in sorted
    order at the optimum then recovers the truth (before the fix: RMS 0.79 %, E1 -1.3 %)."""
    fm, true = crossing_case()
    r = identify(fm, IdentifyOptions(fix=("G13", "G23", "nu12")))
    assert r.swaps
    err = relative_errors(r, true)
    assert max(abs(e) for e in err.values()) < 1e-4, err


def test_too_few_evaluations_is_not_converged_with_a_status():
    fm, _ = synthetic(THIN, {"cf": CARBON}, 12, OFF_THIN)
    r = identify(fm, IdentifyOptions(max_evaluations=5))
    assert not r.converged
    assert "not converged" in r.status and "--max-evaluations 5 evaluations ran out" in r.status
    assert r.evaluations <= 6
    # the few evaluations are spent on the fit (10.8 % -> 0.75 % RMS), not only on checks
    assert r.rms_residual_percent < 0.2 * r.initial_rms_residual_percent


# --- 5. bad input ----------------------------------------------------------------------------

FREQ_S11 = [125.05, 203.50, 331.30, 446.65, 493.55, 603.80, 650.75, 818.70]


def plain_specimen(freq=FREQ_S11, weights=None, materials=None):
    guess = {"cf": dict(E1=117.2 * GPa, E2=8.8 * GPa, G12=3.1 * GPa, G13=3.1 * GPa,
                        G23=3.1 * GPa, nu12=0.35)}
    return build_forward_model(load_specimen_text(
        specimen_text(THIN, materials or guess, freq, weights), path="plate.yaml"), (4, 4))


def test_fewer_weighted_frequencies_than_free_constants():
    """Names the file, the weights' line and field (8 measured, 3 with weight 0) and what to
    do (was "plate.yaml: 5 weighted frequencies for 6 free constants; measure more modes or
    fix constants (--fix nu12,G13,G23)")."""
    fm = plain_specimen(weights=[1, 1, 1, 0, 0, 1, 0, 1])
    line = fm.specimen.source_text.splitlines().index(
        "  weights: [1.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0]") + 1
    with pytest.raises(FitError) as info:
        Problem(fm, IdentifyOptions())
    assert str(info.value) == (
        f"plate.yaml:{line}, field 'measured.weights': 5 weighted frequencies for 6 free "
        "constants (3 of the 8 measured have weight 0; the fit needs at least one per "
        "constant): give more of them a weight above 0, measure more modes, or fix 1 or more of "
        "the constants (--fix, e.g. --fix nu12,G13,G23, which a thin plate's modes determine "
        "worst, or the material's 'fixed:' list)")
    assert info.value.exit_code == 2
    # fixing two of them makes it solvable
    assert Problem(fm, IdentifyOptions(fix=("G13", "G23"))).n_vars == 4


def test_all_weights_zero():
    fm = plain_specimen(weights=[0] * 8)
    with pytest.raises(FitError, match="every measured frequency has weight 0"):
        identify(fm)


def test_frequencies_far_from_the_model_at_the_initial_guess():
    """Frequencies in the wrong unit or a wrong density: more than 50 % off is refused."""
    fm = plain_specimen(freq=[2.2 * f for f in FREQ_S11])
    with pytest.raises(FitError, match=r"measured mode 1 \(275\.11 Hz\) is \d+ % away from the "
                       r"model \(105\.\d\d Hz\) at the initial guess \(limit 50 %\)"):
        identify(fm)


def test_frequencies_in_khz_are_refused_with_the_khz_hint():
    """S1.1's frequencies written in kHz as bare numbers (bare is Hz): identify refused them
    with "check the units, the mass/density, the geometry and the initial constants" while
    modes said they look like kHz; both say it now (forward.far_cause)."""
    fm = plain_specimen(freq=[f / 1000 for f in FREQ_S11])
    with pytest.raises(FitError, match=r"measured mode 1 \(0\.125 Hz\) is 8\d{4} % away from "
                       r"the model \(105\.\d\d Hz\) at the initial guess \(limit 50 %\): the "
                       r"measured frequencies look like kHz: write them in Hz \(a bare number "
                       r"is Hz\) or with their unit, '0\.125 kHz'\Z"):
        identify(fm)
    # 2.2 times (a wrong density, not kHz): the things to check, no kHz
    with pytest.raises(FitError, match=r"\(limit 50 %\): check the units, the mass/density, "
                       r"the geometry and the initial constants\Z"):
        identify(plain_specimen(freq=[2.2 * f for f in FREQ_S11]))


@pytest.mark.parametrize("factor, cause", [
    (31.6, r"the model's frequencies are 1/\d\d of the measured ones, as with moduli 1000 times "
           r"too small \(frequency goes as sqrt\(modulus/density\)\): check the moduli's units "
           r"\(MPa written where GPa is meant\?\), then the mass/density\Z"),
    (1 / 31.6, r"the model's frequencies are \d\d times the measured ones, as with moduli 1000 "
               r"times too large or a density 1000 times too small"),
], ids=["moduli 1000 times too small", "moduli 1000 times too large"])
def test_frequencies_sqrt_1000_off_point_at_the_units_of_the_moduli(factor, cause):
    """Frequencies sqrt(1000) times the model's (moduli written in MPa where GPa is meant)
    or 1/sqrt(1000) of them: the refusal names that cause (forward.far_cause), not only the
    list of things to check."""
    with pytest.raises(FitError, match=r"at the initial guess \(limit 50 %\): " + cause):
        identify(plain_specimen(freq=[factor * f for f in FREQ_S11]))


def test_unknown_constant_in_fix():
    fm = plain_specimen()
    with pytest.raises(FitError, match=r"--fix E3: 'E3' is not a constant; choose from E1, E2"):
        Problem(fm, IdentifyOptions(fix=("G13", "E3")))


def test_unknown_material_in_fix():
    fm = plain_specimen()
    with pytest.raises(FitError, match=r"--fix steel.nu12: no material 'steel' in plate.yaml "
                       r"\(materials: cf\)"):
        Problem(fm, IdentifyOptions(fix=("steel.nu12",)))
