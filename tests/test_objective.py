"""The pure objective (laminid_cli.objective.Objective) on a fixed model, without any optimiser:
value against a direct full solve, gradient against central differences, the reduced model on
a basis holding the exact modes, purity (same arguments -> same answer, nothing counted), the
measured data an argument and not the specimen's."""

import dataclasses

import numpy as np
import pytest

from laminid_cli.forward import build_forward_model
from laminid_cli.identify import IdentifyOptions, Problem
from laminid_cli.objective import MeasuredData, Objective, PlateTerm, RunLog
from laminid_cli.parametrization import make_parameters
from laminid_cli.reduced import ReducedBasis
from laminid_cli.specimen import read_specimen
from tests.data.paper import S11

N_EXTRA = 4


@pytest.fixture(scope="module")
def fm():
    return build_forward_model(read_specimen(S11), (6, 6))


def objective_of(fm, data: MeasuredData, prior=None, kind="constants"):
    """An Objective of one plate built by hand from its parts (no Problem, no run)."""
    spec = fm.specimen
    params = [make_parameters(n, c, tuple(spec.materials[n].fixed), kind=kind,
                              prior=bool(prior), nu_max=0.95, bound_factor=5.0)
              for n, c in zip(fm.material_names, fm.initial_constants)]
    n_vars = sum(len(p.x0()) for p in params)
    plate = PlateTerm(fm, data, params, np.arange(n_vars), data.n + N_EXTRA)
    return Objective([plate], params, [prior or {} for _ in params], pairing="track")


def test_value_is_eq17_of_a_direct_full_solve(fm):
    data = MeasuredData.of(fm.specimen)
    obj = objective_of(fm, data)
    x = np.concatenate([p.x0() for p in obj.params]) * np.array([1.1, 0.95, 1.2, 1.0, 0.9, 1.05])
    ev = obj.evaluate(x)                          # no reference: sorted pairing
    modes = fm.solve(obj.constants(x), n_modes=data.n + N_EXTRA)
    lam = modes.eigenvalues[:data.n]
    lt = (2 * np.pi * data.freq) ** 2
    w = data.weight
    expected = float(np.sum(w * ((lt - lam) / lt) ** 2))
    assert ev.objective == pytest.approx(expected, rel=1e-10)
    np.testing.assert_allclose(ev.eigenvalues, lam, rtol=1e-10)
    np.testing.assert_array_equal(ev.pairing, np.arange(data.n))
    assert len(ev.parts) == 1 and ev.parts[0].objective == ev.objective


def test_gradient_matches_central_differences(fm):
    obj = objective_of(fm, MeasuredData.of(fm.specimen))
    x = np.concatenate([p.x0() for p in obj.params]) * np.array([1.1, 0.95, 1.2, 1.0, 0.9, 1.05])
    ev = obj.evaluate(x)
    for j in range(obj.n_vars):
        # step 1e-5: truncation ~1e-10, and the full solves' round-off (eigenvalues to ~3e-15
        # relative) divided by the step stays ~1e-7 of the gradient (at 1e-6 up to 2e-5 on the
        # insensitive G13, G23: measured with both factorisations)
        h = 1e-5 * max(1.0, abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        # tracked against the evaluation at x: the same modes on both sides
        fd = (obj.evaluate(xp, reference=ev).objective
              - obj.evaluate(xm, reference=ev).objective) / (2 * h)
        assert ev.gradient[j] == pytest.approx(fd, rel=1e-5, abs=1e-9 * ev.objective), j


def test_prior_term_value_and_gradient(fm):
    prior = {"nu12": 2.0, "G12": 0.5}
    obj = objective_of(fm, MeasuredData.of(fm.specimen), prior=prior)
    plain = objective_of(fm, MeasuredData.of(fm.specimen))
    x = np.concatenate([p.x0() for p in obj.params]) * np.array([1.0, 1.0, 1.1, 1.0, 1.0, 1.2])
    ev, ev0 = obj.evaluate(x), plain.evaluate(x)
    P, P0 = obj.constants(x)[0], obj.params[0].initial
    expected = 2.0 * ((P.nu12 - P0.nu12) / P0.nu12) ** 2 + 0.5 * ((P.G12 - P0.G12) / P0.G12) ** 2
    assert ev.objective - ev0.objective == pytest.approx(expected, rel=1e-10)
    for j in range(obj.n_vars):
        h = 1e-6
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        fd = (obj.prior_term(xp)[0] - obj.prior_term(xm)[0]) / (2 * h)
        assert obj.prior_term(x)[1][j] == pytest.approx(fd, rel=1e-6, abs=1e-10), j


def test_evaluate_is_pure(fm):
    """The same arguments give the same evaluation; nothing is counted or remembered."""
    obj = objective_of(fm, MeasuredData.of(fm.specimen))
    x = np.concatenate([p.x0() for p in obj.params]) * 1.05
    a = obj.evaluate(x)
    state = dict(vars(obj))
    b = obj.evaluate(x)
    assert a is not b and a.objective == b.objective
    np.testing.assert_array_equal(a.gradient, b.gradient)
    assert vars(obj).keys() == state.keys() and all(vars(obj)[k] is state[k] for k in state)


def test_measured_data_are_an_argument_not_the_specimens(fm):
    """The objective uses the data it is given: the specimen's own measured list is not read
    (here the specimen has none at all)."""
    data = MeasuredData.of(fm.specimen)
    bare = dataclasses.replace(fm, specimen=dataclasses.replace(fm.specimen, measured=None))
    shifted = dataclasses.replace(data, freq=data.freq * 1.01)
    x = np.concatenate([p.x0() for p in objective_of(fm, data).params])
    same = objective_of(bare, data).evaluate(x).objective
    assert same == pytest.approx(objective_of(fm, data).evaluate(x).objective, rel=1e-12)
    assert objective_of(bare, shifted).evaluate(x).objective != pytest.approx(same, rel=1e-3)


def test_reduced_model_on_exact_modes_equals_the_full_model(fm):
    obj = objective_of(fm, MeasuredData.of(fm.specimen))
    x = np.concatenate([p.x0() for p in obj.params]) * np.array([1.1, 0.95, 1.2, 1.0, 0.9, 1.05])
    full = obj.evaluate(x)
    basis = ReducedBasis(fm)
    basis.add(full.modes.phi)
    red = obj.evaluate(x, models=[basis], reference=full)
    assert red.objective == pytest.approx(full.objective, rel=1e-8)
    np.testing.assert_allclose(red.eigenvalues, full.eigenvalues, rtol=1e-10)
    np.testing.assert_allclose(red.gradient, full.gradient, rtol=1e-6,
                               atol=1e-9 * np.abs(full.gradient).max())
    np.testing.assert_array_equal(red.pairing, full.pairing)


def test_refused_point_is_not_evaluated_and_counted_once_by_the_run(fm):
    obj = objective_of(fm, MeasuredData.of(fm.specimen))
    lo, hi = obj.bounds()
    bad = hi * 50
    ev = obj.evaluate(bad)
    assert ev.refused and np.isnan(ev.objective) and ev.reasons
    prob = Problem(fm, IdentifyOptions(solver="full"))
    first = prob.evaluate(prob.x0())
    out = prob.evaluate(hi * 50)
    assert out.refused and prob.n_refused == 1 and prob.n_eval == 1
    assert out.objective == pytest.approx(10 * first.objective + 1)


def test_run_log_records_typed_rows(fm):
    prob = Problem(fm, IdentifyOptions(solver="full"))
    assert isinstance(prob.log, RunLog) and prob.log.n_eval == 0
    x = prob.x0()
    ev = prob.evaluate(x)
    assert prob.evaluate(x) is ev                 # cached: one evaluation
    prob.evaluate(x * 1.01)
    rows = prob.log.history
    assert [r.evaluation for r in rows] == [1, 2] and prob.log.n_eval == 2
    assert rows[0].objective == ev.objective and rows[0].constants.shape == (6,)
    assert prob.log.best.objective == min(r.objective for r in rows)
