"""The identification objective, pure, and the run log that an optimisation keeps beside it.

:class:`Objective` is paper Eqs 15-17 summed over a list of plates (one plate for ``identify``,
several sharing materials for ``identify --joint``)::

    Phi(x) = sum_k sum_i w_ki ((lt_ki - l_ki(x)) / lt_ki)^2 + sum_j wp_j ((P_j - P_j0) / P_j0)^2

``Objective.evaluate(x, models, reference, start_pairing)`` depends only on its arguments and on
what the objective was built from -- each plate's forward model, its measured data
(:class:`MeasuredData`, given, not read from the specimen), the parametrisation and the prior.
It changes nothing and counts nothing: the same arguments give the same :class:`Evaluation`.
``models[k]`` is the eigen model of plate k at this evaluation (a
:class:`laminid_cli.reduced.ReducedBasis`, or None for the full FE model); ``reference`` the
evaluation whose paired modes are tracked (MAC), None for sorted order or ``start_pairing``.

Everything that belongs to one optimisation run -- the tracking reference (best point so far),
the evaluation cache, the swaps, the counters, the typed history rows, the refused points, the
enrichments and the last error bound -- lives in a :class:`RunLog`
(laminid_cli.identify.Problem holds one and records each evaluation in it).
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from laminid_cli.errors import FitInputError
from laminid_cli.forward import residuals_percent, weighted_rms
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants, infeasibility_reasons
from laminid_cli.modal import Modes, mac

log = logging.getLogger(__name__)


# --- measured data ---------------------------------------------------------------------------

@dataclass(frozen=True)
class MeasuredData:
    """Measured frequencies of one plate, as the objective uses them.

    freq : (n,) Hz, NaN where a mode was not measured; weight : (n,) zero where not measured;
    source : where they come from (the specimen file), for messages."""

    freq: np.ndarray
    weight: np.ndarray
    source: str = ""

    @classmethod
    def of(cls, specimen) -> "MeasuredData":
        """The measured frequencies and weights of a specimen; FitInputError if it has none."""
        m = specimen.measured
        if m is None or m.freq.size == 0:
            raise FitInputError(f"{specimen.path}: no measured frequencies (field "
                                "'measured.frequencies')")
        freq = m.freq.astype(float)
        return cls(freq=freq, weight=np.where(np.isfinite(freq), m.weight, 0.0),
                   source=str(specimen.path))

    @property
    def n(self) -> int:
        return int(self.freq.size)

    @property
    def lam(self) -> np.ndarray:
        """Measured eigenvalues (2 pi f)^2, rad^2/s^2 (1 where not measured: weight 0)."""
        return (2 * np.pi * np.nan_to_num(self.freq, nan=1.0)) ** 2


# --- variables ---------------------------------------------------------------------------------

class VariableSet:
    """Design variables of a list of material parametrisations (``self.params``, ``self.offsets``,
    ``self.n_vars``): splitting, constants, bounds and the linear feasibility constraints."""

    def _set_params(self, params) -> None:
        self.params = list(params)
        self.sizes = [len(p.x0()) for p in self.params]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)]).astype(int)
        self.n_vars = int(self.offsets[-1])
        self.labels = tuple(f"{p.name}.{lab}" for p in self.params for lab in p.labels)

    def split(self, x):
        return [x[self.offsets[k]:self.offsets[k + 1]] for k in range(len(self.params))]

    def constants(self, x) -> tuple[ElasticConstants, ...]:
        return tuple(p.constants(xk) for p, xk in zip(self.params, self.split(x)))

    def coefficients(self, x):
        """Stiffness coefficients (n_materials, 6) at ``x`` and their Jacobians per material."""
        coefs, jacs = zip(*(p.coef_jacobian(xk) for p, xk in zip(self.params, self.split(x))))
        return np.array(coefs), jacs

    def bounds(self):
        lo, hi = zip(*(p.bounds() for p in self.params))
        return np.concatenate(lo), np.concatenate(hi)

    def linear_constraints(self):
        rows, rhs = [], []
        for k, p in enumerate(self.params):
            A, b = p.linear_constraints()
            full = np.zeros((A.shape[0], self.n_vars))
            full[:, self.offsets[k]:self.offsets[k + 1]] = A
            rows.append(full)
            rhs.append(b)
        return np.vstack(rows), np.concatenate(rhs)

    def feasible(self, x, tol: float = 1e-9) -> bool:
        lo, hi = self.bounds()
        A, b = self.linear_constraints()
        return bool(np.all(x >= lo - tol) and np.all(x <= hi + tol) and np.all(A @ x <= b + tol))

    def refusal(self, x) -> tuple[str, ...]:
        """Why ``x`` is not to be evaluated ("material: reason" each): outside the limits
        beyond round-off (1e-7: MMA's inner iterations and SLSQP step outside the safety
        margins) with a constitutive matrix that is not positive definite, whose stiffness is
        no stiffness; () where it may be evaluated (:meth:`Objective.evaluate`, the Monte
        Carlo trials' SLSQP)."""
        if self.feasible(x, tol=1e-7):
            return ()
        return tuple(f"{p.name}: {r}" for p, c in zip(self.params, self.constants(x))
                     for r in infeasibility_reasons(c))

    def eigenvalue_jacobian(self, E, jacs) -> np.ndarray:
        """``d lambda / d x`` (n_modes, n_vars) from the basis energies ``E`` (n_materials, 6,
        n_modes) = d lambda / d coef of some modes and each material's coefficient Jacobian
        (:meth:`coefficients`)."""
        return np.hstack([E[m].T @ J for m, J in enumerate(jacs)])

    #: a Monte Carlo trial's draw of the prior's pseudo-measurements: {material: {constant:
    #: delta}}, each row becoming ``sqrt(wp) ((P - P0) / P0 - delta)`` (none: delta = 0)
    prior_shift: dict = {}

    def prior_rows(self, x):
        """Eq. 15's second term as residual rows ``sqrt(wp) (P - P0) / P0`` (nu12: over 1 when
        P0 is 0) of the free constants given a prior weight (``self.prior``: per material,
        {constant: wp}), less ``sqrt(wp) delta`` of :attr:`prior_shift`, and their derivatives
        (n_rows, n_vars): each row is linear in one design variable (P = x * P0, nu12 = x).
        The term is ``rows . rows``."""
        vals, rows = [], []
        for k, (p, xk) in enumerate(zip(self.params, self.split(x))):
            if not self.prior[k]:
                continue
            P = p.constants(xk).as_array()
            P0 = p.initial.as_array()
            shift = self.prior_shift.get(p.name, {})
            for name, wp in self.prior[k].items():
                if name not in p.free:
                    continue
                i = CONSTANT_NAMES.index(name)
                ref = P0[i] if P0[i] != 0 else 1.0
                scale = 1.0 if name == "nu12" else P0[i]
                row = np.zeros(self.n_vars)
                row[self.offsets[k] + p.free.index(name)] = np.sqrt(wp) * scale / ref
                vals.append(np.sqrt(wp) * ((P[i] - P0[i]) / ref - shift.get(name, 0.0)))
                rows.append(row)
        return np.array(vals), np.array(rows).reshape(len(rows), self.n_vars)


class PlateTerm(VariableSet):
    """One plate of an objective: its forward model, measured data, its materials'
    parametrisations (``fm.material_names`` order, shared objects with the other plates) and
    where its variables sit in the objective's (``index``)."""

    def __init__(self, fm, data: MeasuredData, params, index: np.ndarray, n_model: int):
        self.fm = fm
        self.data = data
        self._set_params(params)
        self.index = np.asarray(index, int)
        self.n_model = int(n_model)

    @property
    def name(self) -> str:
        return self.fm.specimen.name


# --- evaluations and the run log ---------------------------------------------------------------

class _Shapes:
    """Descriptor of :attr:`Evaluation.phi`: an array, None, or a function that forms the array
    when it is first asked for (a reduced model's Ritz vectors ``V y_i``: most evaluations of
    an optimisation never need them at full size)."""

    def __set_name__(self, owner, name):
        self.key = "_" + name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return None                          # the dataclass default
        value = obj.__dict__.get(self.key)
        if callable(value):
            value = obj.__dict__[self.key] = value()
        return value

    def __set__(self, obj, value):
        obj.__dict__[self.key] = value

    @staticmethod
    def source(obj):
        """What ``obj.phi`` holds, without forming it."""
        return obj.__dict__.get("_phi")


@dataclass
class Evaluation:
    """One evaluation of the objective (or, in ``parts``, of one plate's term)."""

    x: np.ndarray
    objective: float
    gradient: np.ndarray
    eigenvalues: np.ndarray          # (n_measured,) paired model eigenvalues, rad^2/s^2
    pairing: np.ndarray              # (n_measured,) index of the model mode paired with each
    dlam_dx: np.ndarray              # (n_measured, n_vars)
    #: (n_dofs, n_measured) paired mode shapes (one plate), formed when first asked for
    phi: np.ndarray | None = _Shapes()
    modes: object = None             # Modes (all computed; one plate)
    parts: list | None = None        # per-plate evaluations (their own variables, no prior)
    refused: bool = False            # not positive definite: the model was not evaluated
    #: measured modes whose model mode changed against the reference: (i, before, after)
    changes: tuple = ()
    reasons: tuple = ()              # why a refused point was refused
    #: reduced model: (basis lineage, basis size, reduced eigenvectors of the paired modes)
    ritz: tuple | None = None


class HistoryRow(NamedTuple):
    """One model evaluation of a run, as kept in the run log (and written to the result
    file's /history by :func:`history_arrays`)."""

    evaluation: int                  # 1-based count within the run
    objective: float
    rms_residual_percent: float
    x: np.ndarray                    # design variables
    constants: np.ndarray            # every material's six constants, CONSTANT_NAMES order
    #: relative eigenvalue error bound of the evaluation against the full FE model: 0 for a
    #: full-model evaluation, the enrichment's bound where the reduced basis was just enriched
    #: (or checked) at this point, NaN for a reduced-model prediction whose error is unknown
    error_bound: float = float("nan")


def history_arrays(rows) -> dict:
    """History rows as arrays, one per field (a result's ``history``)."""
    return {name: np.array([getattr(h, name) for h in rows]) for name in HistoryRow._fields}


class ErrorBound(NamedTuple):
    """Relative eigenvalue error bounds of the reduced model where it was last enriched."""

    key: bytes                       # x.tobytes() of that point
    paired: np.ndarray               # per paired measured mode (every plate, stacked)
    worst: float                     # largest over the checked modes


@dataclass
class RunLog:
    """State of one optimisation run (laminid_cli.identify.Problem keeps one)."""

    n_plates: int = 1
    best: Evaluation | None = None           # tracking reference: lowest objective so far
    cache: tuple | None = None               # (x bytes, Evaluation) of the last evaluation
    swaps: list = field(default_factory=list)
    plate_swaps: list = field(default_factory=list)
    history: list = field(default_factory=list)          # HistoryRow of the objective
    plate_history: list = field(default_factory=list)    # per plate: its own HistoryRow
    n_eval: int = 0
    n_refused: int = 0
    n_enrich: int = 0
    final_bound: ErrorBound | None = None
    checked: Evaluation | None = None        # the optimum checked against the full model
    last_step: float = 0.0                   # scaled step of the last optimiser stage

    def __post_init__(self):
        self.plate_swaps = [[] for _ in range(self.n_plates)]
        self.plate_history = [[] for _ in range(self.n_plates)]

    def cached(self, x: np.ndarray):
        if self.cache is not None and self.cache[0] == x.tobytes():
            return self.cache[1]
        return None

    def bound_of(self, ev: Evaluation) -> float:
        """The ``error_bound`` of a history row (see HistoryRow)."""
        b = self.final_bound
        if b is not None and b.key == ev.x.tobytes():
            return float(b.worst)        # enriched or checked against the full matrices here
        if all(p.ritz is None for p in (ev.parts or [ev])):
            return 0.0                   # every plate solved with the full model
        return float("nan")

    def record(self, ev: Evaluation, objective: "Objective") -> None:
        """Count ``ev`` (a new evaluation), make it the cache, the best when it is, and append
        its history rows."""
        self.n_eval += 1
        n = self.n_eval
        if self.best is None or ev.objective < self.best.objective:
            self.best = ev
            for k, part in enumerate(ev.parts):
                if part.changes:         # reported only where the optimiser moves to
                    msg = (f"evaluation {n}: modes swapped order ("
                           + "; ".join(f"measured mode {i + 1}: model mode {a + 1} -> {b + 1}"
                                       for i, a, b in part.changes) + ")")
                    self.plate_swaps[k].append(msg)
                    name = objective.plates[k].name
                    self.swaps.append(msg if self.n_plates == 1 else f"{name}: {msg}")
                    log.info(msg)
        self.cache = (ev.x.tobytes(), ev)
        rms = objective.rms(ev.eigenvalues)
        bound = self.bound_of(ev)
        self.history.append(HistoryRow(n, ev.objective, rms, ev.x.copy(),
                                       _stacked(objective.constants(ev.x)), bound))
        if self.n_plates > 1:
            for k, (plate, part) in enumerate(zip(objective.plates, ev.parts)):
                self.plate_history[k].append(HistoryRow(
                    n, part.objective, objective.plate_rms(k, part.eigenvalues), part.x.copy(),
                    _stacked(plate.constants(part.x)), bound))
        else:
            self.plate_history[0] = self.history
        log.info("evaluation %d: objective %.6g, RMS residual %.4f %%", n, ev.objective, rms)


def _stacked(constants) -> np.ndarray:
    return np.concatenate([c.as_array() for c in constants])


# --- the objective -----------------------------------------------------------------------------

class Objective(VariableSet):
    """Paper Eqs 15-17 over a list of plates (see module docstring)."""

    def __init__(self, plates, params, prior, pairing: str = "track"):
        """``plates``: PlateTerm list; ``params``: one parametrisation per distinct material
        (the variables, in this order); ``prior``: per material {constant: weight} (Eq. 15);
        ``pairing``: 'track' (MAC tracking against the reference) or 'sorted'."""
        self.plates = tuple(plates)
        self._set_params(params)
        self.prior = [dict(p) for p in prior]
        self.pairing_mode = pairing
        self.freq = np.concatenate([p.data.freq for p in self.plates])
        self.weight = np.concatenate([p.data.weight for p in self.plates])
        self.lam_meas = np.concatenate([p.data.lam for p in self.plates])
        self.n_meas = int(self.freq.size)
        self.rows = np.concatenate([[0], np.cumsum([p.data.n for p in self.plates])]).astype(int)

    def with_pairing(self, pairing: str) -> "Objective":
        """The same objective with another pairing mode ('track' or 'sorted')."""
        out = copy.copy(self)
        out.pairing_mode = pairing
        return out

    # --- evaluation -------------------------------------------------------------------------
    def evaluate(self, x, models=None, reference: Evaluation | None = None,
                 start_pairing=None) -> Evaluation:
        """The objective, its gradient and the paired modes at ``x`` (see module docstring).

        A point outside the linear feasibility constraints (beyond round-off) whose
        constitutive matrices are not positive definite is not evaluated: the Evaluation is
        ``refused`` (objective NaN, ``reasons`` say why)."""
        x = np.asarray(x, float)
        reasons = self.refusal(x)
        if reasons:
            n = self.n_meas
            return Evaluation(x=x.copy(), objective=float("nan"),
                              gradient=np.zeros(self.n_vars), eigenvalues=np.full(n, np.nan),
                              pairing=np.arange(n), dlam_dx=np.zeros((n, self.n_vars)),
                              phi=None, modes=None, refused=True, reasons=reasons)
        models = [None] * len(self.plates) if models is None else list(models)
        refs = [None] * len(self.plates) if reference is None else reference.parts
        starts = [None] * len(self.plates) if start_pairing is None else list(start_pairing)
        parts = [self._evaluate_plate(k, x[plate.index], models[k], refs[k], starts[k])
                 for k, plate in enumerate(self.plates)]
        return self.combine(x, parts)

    def _evaluate_plate(self, k, xk, model, ref, start_pairing) -> Evaluation:
        plate = self.plates[k]
        coef, jacs = plate.coefficients(xk)
        if model is not None:                                       # reduced model
            modes, E_all, Y = model.solve(coef, plate.n_model)
            pairing, changes = self._pair(plate, modes, ref, start_pairing, model, Y)
            ev = self.plate_evaluation(k, xk, modes, pairing, jacs, E_all[:, :, pairing],
                                       changes)
            ev.ritz = (model.lineage, model.size, Y[:, pairing])
            return ev
        ref_ok = ref is not None and ref.modes is not None
        modes = plate.fm.solve(n_modes=plate.n_model, coef=coef,
                               v0=ref.phi.sum(axis=1) if ref_ok else None,
                               lambda1=float(ref.modes.eigenvalues[0]) if ref_ok else None)
        pairing, changes = self._pair(plate, modes, ref, start_pairing)
        return self.plate_evaluation(k, xk, modes, pairing, jacs, None, changes)

    def plate_evaluation(self, k, xk, modes: Modes, pairing, jacs=None, E=None,
                         changes=()) -> Evaluation:
        """Plate k's term from its model modes and their pairing (``E``: basis energies of
        the paired modes, computed from their shapes when None)."""
        plate = self.plates[k]
        if jacs is None:
            _, jacs = plate.coefficients(xk)
        pairing = np.asarray(pairing)
        lam = modes.eigenvalues[pairing]
        if E is None:
            E = plate.fm.plate.basis_energies(modes.columns(pairing))  # (n_mat, 6, n_meas)
        dlam_dx = plate.eigenvalue_jacobian(E, jacs)
        eq17 = residual_rows(plate.data.lam, plate.data.weight, lam, dlam_dx)
        return Evaluation(x=np.array(xk, float), objective=eq17.value, gradient=eq17.gradient,
                          eigenvalues=lam, pairing=pairing,
                          dlam_dx=dlam_dx, phi=lambda: modes.columns(pairing), modes=modes,
                          changes=tuple(changes))

    def combine(self, x, parts) -> Evaluation:
        """The objective's evaluation at ``x`` from its plates' evaluations there."""
        x = np.asarray(x, float)
        gradient = np.zeros(self.n_vars)
        dlam_dx = np.zeros((self.n_meas, self.n_vars))
        for k, (plate, ev) in enumerate(zip(self.plates, parts)):
            np.add.at(gradient, plate.index, ev.gradient)
            dlam_dx[self.rows[k]:self.rows[k + 1], plate.index] = ev.dlam_dx
        pv, pg = self.prior_term(x)
        one = parts[0] if len(parts) == 1 else None
        return Evaluation(x=x.copy(), objective=sum(ev.objective for ev in parts) + pv,
                          gradient=gradient + pg,
                          eigenvalues=np.concatenate([ev.eigenvalues for ev in parts]),
                          pairing=np.concatenate([ev.pairing for ev in parts]),
                          dlam_dx=dlam_dx, phi=None if one is None else _Shapes.source(one),
                          modes=None if one is None else one.modes, parts=list(parts))

    def _pair(self, plate, modes, ref, start_pairing, model=None, Y=None):
        """Model mode paired with each measured one, and the changes against the reference.

        Sorted order (or ``start_pairing``) without a reference, then MAC tracking against
        the reference (the best evaluation so far: line-search trial points can be far off)."""
        n = plate.data.n
        if ref is None and start_pairing is not None:
            return np.asarray(start_pairing, int).copy(), ()
        if self.pairing_mode == "sorted" or ref is None or ref.modes is None:
            return np.arange(n), ()
        if Y is not None:                                            # reduced model
            M = model.mac(lambda: ref.phi, Y, ref.ritz)        # (n_meas, n_model)
        else:
            M = mac(ref.phi, modes.phi, plate.fm.plate.mass)            # (n_meas, n_model)
        pairing = max_assignment(M)
        weak = M[np.arange(n), pairing] < 0.5
        if weak.any():
            log.debug("mode tracking uncertain for measured mode(s) %s (MAC < 0.5)",
                      ", ".join(str(i + 1) for i in np.flatnonzero(weak)))
        prev = ref.pairing
        if np.array_equal(pairing, prev) or weak.any():
            return pairing, ()
        return pairing, tuple((i, int(prev[i]), int(pairing[i])) for i in range(n)
                              if pairing[i] != prev[i])

    def prior_term(self, x):
        """Eq. 15 second term on relative engineering constants, and its gradient."""
        vals, rows = self.prior_rows(x)
        return float(vals @ vals), 2 * vals @ rows

    # --- residuals ------------------------------------------------------------------------------
    def rms(self, eigenvalues) -> float:
        """Weighted RMS residual (%) of stacked paired eigenvalues."""
        return weighted_rms(residuals_percent(self.freq, np.sqrt(eigenvalues) / (2 * np.pi)),
                            self.weight)

    def plate_rms(self, k, eigenvalues) -> float:
        d = self.plates[k].data
        return weighted_rms(residuals_percent(d.freq, np.sqrt(eigenvalues) / (2 * np.pi)),
                            d.weight)


class Eq17(NamedTuple):
    """Paper Eq. 17 of one plate at some paired model eigenvalues (:func:`residual_rows`)."""

    rows: np.ndarray                 # (n,) r_i = sqrt(w_i) (lt_i - l_i) / lt_i
    jacobian: np.ndarray             # (n, n_vars) d r_i / d x = -sqrt(w_i) / lt_i d l_i / d x
    value: float                     # sum_i w_i ((lt_i - l_i) / lt_i)^2 = r . r
    gradient: np.ndarray             # (n_vars,) paper Eq. 24 = 2 J^T r


def residual_rows(lam_meas, weight, lam, dlam_dx) -> Eq17:
    """Paper Eq. 17 from the measured eigenvalues ``lam_meas``, the weights, the paired model
    eigenvalues and their Jacobian ``dlam_dx``: as residual rows with their Jacobian (the Monte
    Carlo trials' Gauss-Newton steps) and as value and gradient (the objective), in one
    place. Value and gradient are computed as ``sum w rel^2`` and ``-2 (w rel / lt) . dl/dx``
    (the same numbers as ``r . r`` and ``2 J^T r`` up to round-off, and the same round-off as
    the optimiser has always seen)."""
    w = np.asarray(weight, float)
    lam_meas = np.asarray(lam_meas, float)
    s = np.sqrt(w)
    rel = (lam_meas - lam) / lam_meas
    return Eq17(rows=s * rel, jacobian=-(s / lam_meas)[:, None] * dlam_dx,
                value=float(np.sum(w * rel**2)), gradient=-2 * (w * rel / lam_meas) @ dlam_dx)


def max_assignment(M: np.ndarray) -> np.ndarray:
    """Column matched to each row of ``M`` (n_rows <= n_cols, entries in [0, 1], e.g. MAC
    values) so that the sum of the matched entries is largest, one column per row.

    ``min_weight_full_bipartite_matching`` on ``2 - M`` (every edge present, weights > 0): the
    assignment of ``scipy.optimize.linear_sum_assignment(-M)`` without importing
    scipy.optimize (checked in tests/test_identify_reduced.py). When every row's largest entry
    is in a column of its own, that is the assignment (no other can exceed the sum of the row
    maxima) and no matching is run."""
    M = np.asarray(M, float)
    best = np.argmax(M, axis=1)
    if np.unique(best).size == best.size:
        return best
    import scipy.sparse as sp
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching

    rows, cols = min_weight_full_bipartite_matching(sp.csr_matrix(2.0 - M))
    return cols[np.argsort(rows)]


# --- shared materials of several plates ------------------------------------------------------

def check_shared_materials(specimens) -> dict:
    """Refuse shared materials that differ between files; return the merged ``fixed`` lists.

    Raises FitInputError naming both files, the material and the first difference. Returns
    {material: tuple of constants fixed in at least one file}, materials in first-appearance
    order.
    """
    first: dict[str, tuple] = {}
    fixed: dict[str, tuple] = {}
    for spec in specimens:
        for name, mat in spec.materials.items():
            if name not in first:
                first[name] = (spec, mat)
                fixed[name] = tuple(mat.fixed)
                continue
            spec0, mat0 = first[name]
            where = (f"joint identification: material '{name}' differs between {spec0.path} and "
                     f"{spec.path}")
            a, b = mat0.constants.as_array(), mat.constants.as_array()
            for k, key in enumerate(CONSTANT_NAMES):
                if not np.isclose(a[k], b[k], rtol=1e-9, atol=0.0):
                    raise FitInputError(
                        f"{where}: initial {key} {_show(key, a[k])} vs {_show(key, b[k])}; a "
                        "shared material needs the same initial constants in every file (or "
                        "give the materials different names to identify them separately)")
            for attr in ("density", "density_ratio"):
                va, vb = getattr(mat0, attr), getattr(mat, attr)
                if (va is None) != (vb is None) or (va is not None and not np.isclose(va, vb)):
                    raise FitInputError(
                        f"{where}: {attr} {_plain(va)} vs {_plain(vb)}; a shared material needs "
                        "the same density in every file (leave it out to derive each plate's "
                        "density from its own mass)")
            if dict(mat0.prior) != dict(mat.prior):
                raise FitInputError(f"{where}: prior {dict(mat0.prior)} vs {dict(mat.prior)}; "
                                    "give the same prior in every file")
            fixed[name] = tuple(dict.fromkeys(fixed[name] + tuple(mat.fixed)))
    return fixed


def _show(key, v):
    return f"{v:g}" if key == "nu12" else f"{v / 1e9:g} GPa"


def _plain(v):
    return "not given" if v is None else f"{v:g}"
