"""Identification of ply elastic constants from natural frequencies (paper section 4).

Minimise (paper Eqs 15-17)::

    Phi(x) = sum_i w_i ((lt_i - l_i(x)) / lt_i)^2  +  sum_j wp_j ((P_j(x) - P_j0) / P_j0)^2

with lt_i the measured eigenvalues (2 pi f_i)^2, l_i the model's, w_i the weights of the
specimen file and wp_j the optional prior weights (Eq. 15 with the reliability of the initial
values, per engineering constant). Design variables x per material: laminid_cli.parametrization.

Gradient (Eqs 24-27): ``d l_i / d x = sum_j E[m, j, i] d coef[m, j] / d x`` where
``E[m, j, i] = phi_i^T K_basis[m, j] phi_i`` are the basis strain energies of the
mass-normalised modes (PlateModel.basis_energies): one factorisation and one Lanczos run per
step plus cheap products; no finite differences.

Mode pairing: measured mode i is paired with the i-th model mode at the initial point (sorted
order, as in the paper); from then on each paired mode is followed from one evaluation to the
next by the modal assurance criterion (MAC, mass-weighted) with an optimal assignment, so two
modes that swap order keep their identity. Swaps are recorded. ``pairing="sorted"`` keeps the
paper's plain sorted order.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from laminid_cli.errors import FitInputError, LaminidError
from laminid_cli.forward import ForwardModel, residuals_percent, weighted_rms
from laminid_cli.material import (CONSTANT_NAMES, ElasticConstants, alphas_from_constants,
                                  infeasibility_reasons)
from laminid_cli.modal import WORK, Modes, mac
from laminid_cli.parametrization import coefficients_and_jacobian, make_parameters

log = logging.getLogger(__name__)

OPTIMIZERS = ("slsqp", "mma")
PAIRINGS = ("track", "sorted")
SOLVERS = ("reduced", "full")
#: a reduced-model result is taken as the full model's when the relative eigenvalue error bound
#: of every mode up to two beyond the highest paired one is below this (the modes written are
#: cut there); else the optimum is solved again with the full model
FINAL_BOUND = 1e-9
#: block solves tried at the optimum (with one factorisation) to reach FINAL_BOUND
FINAL_ROUNDS = 8
#: damping of the Gauss-Newton scaling, relative to its largest diagonal term
DAMPING = 1e-2


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of an identification run.

    fix : constants held at their initial values, as "nu12" (every material) or
        "glass.nu12" (one material); added to each material's ``fixed`` list in the specimen
    optimizer : 'slsqp' (nlopt LD_SLSQP, default) or 'mma' (nlopt LD_MMA)
    parametrization : 'auto' (paper Eq. 14 alphas where all constants are free), 'alpha', 'constants'
    xtol_rel : step tolerance on the Gauss-Newton-scaled variables (a step of 1 changes the
        objective by about its initial value), ftol_rel : relative objective tolerance,
        max_evaluations : nlopt stopping criteria
    pairing : 'track' (sorted at the start, then MAC tracking) or 'sorted'
    extra_modes : model modes computed beyond the measured ones (room for swaps)
    nu_max : |nu12| bound (< 1 keeps the constitutive matrix positive definite)
    bound_factor : moduli stay within [P0 / f, P0 * f]
    far_limit : a measured frequency more than this fraction away from its model mode at the
        initial guess is refused (wrong units, density, or mode numbering)
    solver : 'reduced' (default: the optimiser runs on a reduced-order model enriched where it
        goes, laminid_cli.reduced) or 'full' (one full eigen solution per evaluation, the
        reference)
    reduced_tol : the reduced solver stops when an enrichment changes the paired eigenvalues by
        less than this (relative)
    """

    fix: tuple[str, ...] = ()
    optimizer: str = "slsqp"
    parametrization: str = "auto"
    xtol_rel: float = 1e-6
    ftol_rel: float = 1e-8
    max_evaluations: int = 300
    pairing: str = "track"
    extra_modes: int = 4
    nu_max: float = 0.95
    bound_factor: float = 5.0
    far_limit: float = 0.5
    solver: str = "reduced"
    reduced_tol: float = 1e-7


class HistoryRow(NamedTuple):
    """One model evaluation of a run, as kept in the run's history (and written to the result
    file's /history by :func:`history_arrays`)."""

    evaluation: int                  # 1-based count within the run
    objective: float
    rms_residual_percent: float
    x: np.ndarray                    # design variables
    constants: np.ndarray            # every material's six constants, CONSTANT_NAMES order


def history_arrays(rows) -> dict:
    """The history rows as arrays, one per field (the result's ``history``)."""
    return {name: np.array([getattr(h, name) for h in rows]) for name in HistoryRow._fields}


@dataclass
class Evaluation:
    """One model evaluation during the optimisation."""

    x: np.ndarray
    objective: float
    gradient: np.ndarray
    eigenvalues: np.ndarray          # (n_measured,) paired model eigenvalues, rad^2/s^2
    pairing: np.ndarray              # (n_measured,) index of the model mode paired with each
    dlam_dx: np.ndarray              # (n_measured, n_vars)
    phi: np.ndarray                  # (n_dofs, n_measured) paired mode shapes
    modes: object                    # Modes (all computed)
    parts: list | None = None        # per-plate evaluations of a joint problem
    refused: bool = False            # not positive definite: the model was not evaluated


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify` (SI units, frequencies in Hz)."""

    specimen: object
    material_names: tuple[str, ...]
    initial: tuple[ElasticConstants, ...]
    constants: tuple[ElasticConstants, ...]
    free: dict                               # material -> tuple of free constants
    parametrization: dict                    # material -> 'alpha' | 'constants'
    variable_labels: tuple[str, ...]
    x: np.ndarray
    objective: float
    evaluations: int
    converged: bool
    status: str
    time_s: float
    measured_hz: np.ndarray
    weight: np.ndarray
    model_hz: np.ndarray                     # paired model frequencies
    pairing: np.ndarray                      # model mode index (0-based) of each measured mode
    residual_percent: np.ndarray
    rms_residual_percent: float
    initial_rms_residual_percent: float
    modes: object                            # Modes at the optimum (all computed, sorted)
    phi_paired: np.ndarray                   # (n_dofs, n_measured)
    dlam_dx: np.ndarray                      # (n_measured, n_vars) at the optimum
    sensitivity: np.ndarray                  # (n_measured, n_materials * 6) d ln f / d ln P
    sensitivity_labels: tuple[str, ...]
    history: dict                            # arrays over evaluations
    swaps: tuple[str, ...]
    bounds_hit: tuple[str, ...]
    warnings: tuple[str, ...]
    global_properties: dict
    options: IdentifyOptions = field(default_factory=IdentifyOptions)
    #: relative error bound of each paired eigenvalue against the full FE model (0 where the
    #: full model was solved at the optimum)
    error_bound: np.ndarray | None = None
    #: work of the run: factorisations, solve pairs, Lanczos runs, enrichments
    work: dict = field(default_factory=dict)
    #: the reduced basis at the end (laminid_cli.reduced.ReducedBasis; None with the full
    #: solver), for re-identifications of the same plate to start from
    basis: object = field(default=None, repr=False, compare=False)


class VariableSet:
    """Design variables of a list of material parametrisations (``self.params``, ``self.offsets``,
    ``self.n_vars``): splitting, constants, bounds and the linear feasibility constraints.
    Shared by :class:`Problem` and the joint problem."""

    def split(self, x):
        return [x[self.offsets[k]:self.offsets[k + 1]] for k in range(len(self.params))]

    def constants(self, x) -> tuple[ElasticConstants, ...]:
        return tuple(p.constants(xk) for p, xk in zip(self.params, self.split(x)))

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

    def _new_run(self) -> None:
        """Empty optimisation state: tracking reference, cache, history, counters."""
        self.best: Evaluation | None = None   # tracking reference: lowest objective so far
        self.cache: tuple[bytes, Evaluation] | None = None
        self.swaps: list[str] = []
        self.history: list[HistoryRow] = []
        self.n_eval = 0
        self.n_refused = 0
        self.n_enrich = 0
        self.final_bound = None          # (x bytes, relative bound per paired mode)


class Problem(VariableSet):
    """Objective, gradient and constraints of one identification, with evaluation cache."""

    def __init__(self, fm: ForwardModel, options: IdentifyOptions, *, start=None,
                 start_pairing=None, check_count: bool = True, basis=None):
        """``start``: constants (one ElasticConstants per material, ``fm.material_names`` order)
        to start from instead of the file's initial values, which stay the reference of the
        design variables, the prior and the fixed constants (a Monte Carlo re-identification
        starts from the optimum). ``start_pairing``: model mode (0-based) paired with each
        measured mode at the start, instead of sorted order. ``check_count=False`` accepts
        fewer weighted frequencies than free constants (one plate of a joint identification).
        """
        self.fm = fm
        self.options = options
        spec = fm.specimen
        if options.optimizer not in OPTIMIZERS:
            raise FitInputError(f"optimizer '{options.optimizer}' unknown: choose {', '.join(OPTIMIZERS)}")
        if options.solver not in SOLVERS:
            raise FitInputError(f"solver '{options.solver}' unknown: choose {', '.join(SOLVERS)}")
        if options.pairing not in PAIRINGS:
            raise FitInputError(f"pairing '{options.pairing}' unknown: choose {', '.join(PAIRINGS)}")
        if spec.measured is None or spec.measured.freq.size == 0:
            raise FitInputError(f"{spec.path}: no measured frequencies (field 'measured.frequencies')")
        self.freq = spec.measured.freq.astype(float)
        self.weight = np.where(np.isfinite(self.freq), spec.measured.weight, 0.0)
        self.lam_meas = (2 * np.pi * np.nan_to_num(self.freq, nan=1.0)) ** 2
        self.n_meas = self.freq.size
        fixed_all = _parse_fix(options.fix, fm.material_names, spec.path)
        self.params = []
        for name, c0 in zip(fm.material_names, fm.initial_constants):
            mat = spec.materials[name]
            fixed = tuple(dict.fromkeys(tuple(mat.fixed) + fixed_all.get(name, ())))
            self.params.append(make_parameters(
                name, c0, fixed, kind=options.parametrization, prior=bool(mat.prior),
                nu_max=options.nu_max, bound_factor=options.bound_factor))
        self.sizes = [len(p.x0()) for p in self.params]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)])
        self.n_vars = int(self.offsets[-1])
        self.labels = tuple(f"{p.name}.{lab}" for p in self.params for lab in p.labels)
        # prior (Eq. 15): relative deviation of engineering constants from their initial values
        self.prior = [{k: float(w) for k, w in spec.materials[p.name].prior.items()}
                      for p in self.params]
        n_active = int((self.weight > 0).sum())
        if n_active == 0:
            raise FitInputError(f"{spec.path}: every measured frequency has weight 0; nothing to fit")
        if self.n_vars == 0:
            raise FitInputError(f"{spec.path}: every constant is fixed; nothing to identify")
        if check_count and n_active < self.n_vars and not any(self.prior):
            raise FitInputError(f"{spec.path}: {n_active} weighted frequencies for {self.n_vars} free "
                           "constants; measure more modes or fix constants (--fix nu12,G13,G23)")
        self.n_model = self.n_meas + options.extra_modes
        self.start = None if start is None else tuple(start)
        if self.start is not None and len(self.start) != len(self.params):
            raise FitInputError(f"{spec.path}: {len(self.start)} start constants for "
                                f"{len(self.params)} materials")
        self.start_pairing = None if start_pairing is None else np.asarray(start_pairing, int)
        self.basis = None                # ReducedBasis while the reduced model is in use
        self.given_basis = basis         # a basis to start from (reduced solver)
        self._last_basis = None
        self._new_run()

    # --- variables ---------------------------------------------------------------------------
    def x0(self) -> np.ndarray:
        """Start point: the initial values, or the ``start`` constants when given."""
        if self.start is None:
            return np.concatenate([p.x0() for p in self.params])
        return np.concatenate([variables_of(p, c) for p, c in zip(self.params, self.start)])

    def describe(self) -> str:
        """Where the data come from, for error messages."""
        return str(self.fm.specimen.path)

    def check_start(self, ev: Evaluation) -> list[str]:
        return check_start(self, ev)

    # --- evaluation --------------------------------------------------------------------------
    def evaluate(self, x) -> Evaluation:
        x = np.asarray(x, float)
        key = x.tobytes()
        if self.cache is not None and self.cache[0] == key:
            return self.cache[1]
        if not self.feasible(x, tol=1e-7):
            # Outside the safety margins of the linear constraints (MMA's inner iterations and
            # round-off can step there). Evaluate only if the constitutive matrices are still
            # positive definite; otherwise refuse without touching the model.
            reasons = [f"{p.name}: {r}" for p, c in zip(self.params, self.constants(x))
                       for r in infeasibility_reasons(c)]
            if reasons:
                return refused_evaluation(self, x, reasons)
        coefs, jacs = zip(*(p.coef_jacobian(xk) for p, xk in zip(self.params, self.split(x))))
        coef = np.array(coefs)
        if self.basis is not None:
            modes, E_all, Y = self.basis.solve(coef, self.n_model)
            pairing, swap = self._pair(modes, Y)
            E = E_all[:, :, pairing]
        else:
            ref = self.best if self.best is not None and not self.best.refused else None
            v0 = None if ref is None else ref.phi.sum(axis=1)
            lambda1 = None if ref is None else float(ref.modes.eigenvalues[0])
            modes = self.fm.solve(n_modes=self.n_model, coef=coef, v0=v0, lambda1=lambda1)
            pairing, swap = self._pair(modes)
            E = None
        return self._record(x, jacs, modes, pairing, swap, E)

    def _record(self, x, jacs, modes, pairing, swap, E=None) -> Evaluation:
        """Objective and gradient from the paired modes; the run's bookkeeping. ``E``: basis
        energies of the paired modes (computed from their shapes when None)."""
        key = x.tobytes()
        phi = modes.phi[:, pairing]
        lam = modes.eigenvalues[pairing]
        if E is None:
            E = self.fm.plate.basis_energies(phi)                     # (n_mat, 6, n_meas)
        dlam_dx = np.zeros((self.n_meas, self.n_vars))
        for k, J in enumerate(jacs):
            dlam_dx[:, self.offsets[k]:self.offsets[k + 1]] = E[k].T @ J
        rel = (self.lam_meas - lam) / self.lam_meas
        w = self.weight
        phi_val = float(np.sum(w * rel**2))
        grad = -2 * (w * rel / self.lam_meas) @ dlam_dx                # paper Eq. 24
        pv, pg = self._prior(x)
        ev = Evaluation(x=x.copy(), objective=phi_val + pv, gradient=grad + pg, eigenvalues=lam,
                        pairing=pairing, dlam_dx=dlam_dx, phi=phi, modes=modes)
        if self.best is None or ev.objective < self.best.objective:
            self.best = ev
            if swap:                     # reported only where the optimiser moves to
                self.swaps.append(swap)
                log.info(swap)
        self.cache = (key, ev)
        self.n_eval += 1
        f_model = np.sqrt(lam) / (2 * np.pi)
        rms = weighted_rms(residuals_percent(self.freq, f_model), self.weight)
        self.history.append(HistoryRow(self.n_eval, ev.objective, rms, x.copy(),
                                       np.concatenate([c.as_array() for c in self.constants(x)])))
        log.info("evaluation %d: objective %.6g, RMS residual %.4f %%", self.n_eval,
                 ev.objective, rms)
        return ev

    def _pair(self, modes, Y=None) -> tuple[np.ndarray, str]:
        """Model mode paired with each measured one, and a swap message ('' if none).

        Sorted order at the start (or ``start_pairing``), then MAC tracking against the best
        evaluation so far (line-search trial points can be far off)."""
        sorted_pairing = np.arange(self.n_meas)
        if self.best is None and self.start_pairing is not None:
            return self.start_pairing.copy(), ""
        if self.options.pairing == "sorted" or self.best is None:
            return sorted_pairing, ""

        if Y is not None:                                            # reduced model
            M = self.basis.mac(self.best.phi, Y)
        else:
            M = mac(self.best.phi, modes.phi, self.fm.plate.M)       # (n_meas, n_model)
        pairing = max_assignment(M)
        weak = M[np.arange(self.n_meas), pairing] < 0.5
        if weak.any():
            log.debug("mode tracking uncertain for measured mode(s) %s (MAC < 0.5)",
                      ", ".join(str(i + 1) for i in np.flatnonzero(weak)))
        prev = self.best.pairing
        if np.array_equal(pairing, prev) or weak.any():
            return pairing, ""
        changed = [f"measured mode {i + 1}: model mode {prev[i] + 1} -> {pairing[i] + 1}"
                   for i in range(self.n_meas) if pairing[i] != prev[i]]
        return pairing, f"evaluation {self.n_eval + 1}: modes swapped order ({'; '.join(changed)})"

    # --- reduced-order model (laminid_cli.reduced) ---------------------------------------------
    @property
    def reduced(self) -> bool:
        return self.basis is not None

    def start_reduced(self, ev: Evaluation, basis=None) -> None:
        """Use the reduced model from now on, with a basis made of ``ev``'s modes (a full
        evaluation) or the given ``basis`` (kept from an earlier run)."""
        from laminid_cli.reduced import ReducedBasis

        if basis is None:
            basis = ReducedBasis(self.fm)
            basis.add(ev.modes.phi)
            if SENSITIVITY_START:
                coef = np.array([p.coef_jacobian(xk)[0]
                                 for p, xk in zip(self.params, self.split(ev.x))])
                basis.add_sensitivities(coef, ev.modes.phi)
        self.basis = self._last_basis = basis
        self.cache = None

    def enrich(self, ev: Evaluation, rounds: int = 2, target: float = 0.0) -> float:
        """Enrich the basis at ``ev.x``; returns the relative change of the paired eigenvalues
        and records the relative error bound of the paired modes there (see
        ReducedBasis.enrich for ``rounds`` and ``target``)."""
        coef = np.array([p.coef_jacobian(xk)[0] for p, xk in zip(self.params, self.split(ev.x))])
        before, after, bound = self.basis.enrich(coef, self.n_model, rounds, target)
        self.n_enrich += 1
        self.cache = None
        lam = ev.eigenvalues
        ok = self.weight > 0
        rel = bound / after
        n_keep = self.checked_modes(ev)
        self.final_bound = (ev.x.tobytes(), rel[ev.pairing], float(np.max(rel[:n_keep])))
        change = np.abs(after[ev.pairing] - lam) / lam
        return float(np.max(change[ok])) if ok.any() else 0.0

    def final_check(self, ev: Evaluation):
        """``ev`` (reduced model) checked against the full model: eigenvalues the full model's
        Rayleigh quotients of its Ritz vectors, sensitivities from their full strain energies,
        and the relative error bound of each checked mode (ReducedBasis.check)."""
        coefs, jacs = zip(*(p.coef_jacobian(xk) for p, xk in zip(self.params, self.split(ev.x))))
        n = self.checked_modes(ev)
        theta, U, bound = self.basis.check(np.array(coefs), ev.modes.phi[:, :n])
        m = ev.modes
        modes = Modes(eigenvalues=theta, phi=U, n_rigid=m.n_rigid,
                      rigid_eigenvalues=m.rigid_eigenvalues)
        self.cache = None
        out = self._record(np.asarray(ev.x, float), jacs, modes, ev.pairing, "")
        rel = bound / theta
        self.final_bound = (out.x.tobytes(), rel[ev.pairing], float(rel.max()))
        return out

    def checked_modes(self, ev: Evaluation) -> int:
        """Modes held to FINAL_BOUND at the optimum: up to two beyond the highest paired one."""
        return int(min(self.n_model, np.max(ev.pairing) + 3))

    def bound_at(self, x) -> np.ndarray | None:
        """Relative error bound of every computed mode at ``x`` if the last enrichment was there."""
        if self.final_bound is not None and self.final_bound[0] == np.asarray(x, float).tobytes():
            return self.final_bound
        return None

    def use_full(self) -> None:
        self.basis = None
        self.cache = None

    @property
    def last_basis(self):
        """The basis in use, or the one given / built before a final full solve."""
        return self.basis if self.basis is not None else self._last_basis

    # --- pairing state, for run_optimizer's re-anchoring -----------------------------------------
    def sorted_pairing(self) -> np.ndarray:
        return np.arange(self.n_meas)

    def reanchor(self) -> None:
        """Forget the tracked identities: the next evaluation pairs in sorted order."""
        self.best, self.cache, self.start_pairing = None, None, None

    def adopt(self, ev: Evaluation) -> None:
        """Make ``ev`` the tracking reference and the cached evaluation again."""
        self.best, self.cache = ev, (ev.x.tobytes(), ev)

    def _prior(self, x):
        """Eq. 15 second term on relative engineering constants, and its gradient."""
        value, grad = 0.0, np.zeros(self.n_vars)
        for k, (p, xk) in enumerate(zip(self.params, self.split(x))):
            if not self.prior[k]:
                continue
            scale = np.array([1.0 if n == "nu12" else p.initial.as_array()[i]
                              for i, n in enumerate(CONSTANT_NAMES)])
            P = p.constants(xk).as_array()
            P0 = p.initial.as_array()
            for name, wp in self.prior[k].items():
                if name not in p.free:
                    continue
                i = CONSTANT_NAMES.index(name)
                ref = P0[i] if P0[i] != 0 else 1.0
                dev = (P[i] - P0[i]) / ref
                value += wp * dev**2
                j = self.offsets[k] + p.free.index(name)
                grad[j] += 2 * wp * dev * scale[i] / ref
        return value, grad


def max_assignment(M: np.ndarray) -> np.ndarray:
    """Column matched to each row of ``M`` (n_rows <= n_cols, entries in [0, 1], e.g. MAC
    values) so that the sum of the matched entries is largest, one column per row.

    ``min_weight_full_bipartite_matching`` on ``2 - M`` (every edge present, weights > 0): the
    assignment of ``scipy.optimize.linear_sum_assignment(-M)`` without importing
    scipy.optimize (checked in tests/test_identify_reduced.py)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import min_weight_full_bipartite_matching

    rows, cols = min_weight_full_bipartite_matching(sp.csr_matrix(2.0 - np.asarray(M, float)))
    return cols[np.argsort(rows)]


def variables_of(params, constants: ElasticConstants) -> np.ndarray:
    """Design variables of one material (``make_parameters`` object) for given constants.

    The inverse of ``params.constants(x)`` on the free constants (the fixed ones keep their
    initial values whatever ``constants`` says).
    """
    if params.kind == "alpha":
        a = alphas_from_constants(constants)
        return np.array([constants.E1 / params.initial.E1, a[1], a[2], a[3], a[4], a[5]])
    P = constants.as_array()
    P0 = params.initial.as_array()
    idx = [CONSTANT_NAMES.index(k) for k in params.free]
    scale = np.where(np.array(CONSTANT_NAMES) == "nu12", 1.0, P0)
    return P[idx] / scale[idx]


def _parse_fix(fix, names, path) -> dict:
    out: dict[str, tuple] = {}
    for item in fix:
        item = item.strip()
        if not item:
            continue
        if "." in item and item.rsplit(".", 1)[1] in CONSTANT_NAMES:
            mat, const = item.rsplit(".", 1)
            targets = [mat]
            if mat not in names:
                raise FitInputError(f"--fix {item}: no material '{mat}' in {path} "
                               f"(materials: {', '.join(names)})")
        else:
            const, targets = item, list(names)
        if const not in CONSTANT_NAMES:
            raise FitInputError(f"--fix {item}: '{const}' is not a constant; choose from "
                           f"{', '.join(CONSTANT_NAMES)}")
        for t in targets:
            out[t] = out.get(t, ()) + (const,)
    return out


def check_start(problem: Problem, ev: Evaluation) -> list[str]:
    """Refuse hopeless starts; return warnings for doubtful ones."""
    f_model = np.sqrt(ev.eigenvalues) / (2 * np.pi)
    ok = problem.weight > 0
    ratio = np.abs(problem.freq - f_model) / problem.freq
    far = ok & (ratio > problem.options.far_limit)
    if far.any():
        i = int(np.flatnonzero(far)[0])
        raise FitInputError(
            f"{problem.fm.specimen.path}: measured mode {i + 1} ({problem.freq[i]:.2f} Hz) is "
            f"{ratio[i] * 100:.0f} % away from the model ({f_model[i]:.2f} Hz) at the initial "
            f"guess (limit {problem.options.far_limit * 100:.0f} %): check the units, the mass/"
            "density, the geometry and the initial constants")
    return [f"measured mode {i + 1} is {ratio[i] * 100:.0f} % from the model at the start"
            for i in np.flatnonzero(ok & (ratio > 0.25))]


def identify(fm: ForwardModel, options: IdentifyOptions = IdentifyOptions(),
             progress=None, *, start=None, start_pairing=None, basis=None) -> Identification:
    """Identify the constants of every material of ``fm.specimen`` (see module docstring).

    ``progress(evaluation, objective, rms_percent)`` is called after each model evaluation.
    Raises FitError for hopeless input; a run that stops before convergence returns with
    ``converged = False`` and a status message. ``start``/``start_pairing``: see
    :class:`Problem`. ``basis``: a ReducedBasis of ``fm`` to start the reduced solver from
    (e.g. ``earlier_result.basis.copy()``: no full solve at the start).
    """
    t0 = time.perf_counter()
    work0 = dict(WORK)
    prob = Problem(fm, options, start=start, start_pairing=start_pairing, basis=basis)
    ev, converged, status, warnings, initial_rms = run_optimizer(prob, progress)
    prob.work = work_since(work0, prob)
    return _result(prob, ev, converged, status, warnings, initial_rms, time.perf_counter() - t0)


def work_since(work0: dict, prob) -> dict:
    """Factorisations, solve pairs and Lanczos runs since ``work0``, and the enrichments."""
    out = {k: WORK[k] - work0.get(k, 0) for k in WORK}
    out["enrichments"] = int(prob.n_enrich)
    return out


#: a tracked pairing that ends out of sorted order is re-anchored at most this many times
MAX_REANCHOR = 2


def refused_evaluation(prob, x, reasons) -> Evaluation:
    """Stand-in for a point whose constitutive matrix is not positive definite (paper Eq. 22).

    The model is not evaluated: the objective is ten times the worst one met so far, the
    gradient zero, so the optimiser's line search or conservative update steps back inside.
    """
    prob.n_refused += 1
    log.warning("point outside the feasible region not evaluated (%s)", "; ".join(reasons))
    worst = max((h.objective for h in prob.history), default=1.0)
    ref = prob.best
    n = prob.n_meas
    return Evaluation(x=np.asarray(x, float).copy(), objective=10.0 * worst + 1.0,
                      gradient=np.zeros(prob.n_vars), eigenvalues=np.full(n, np.nan),
                      pairing=ref.pairing if ref is not None else np.arange(n),
                      dlam_dx=np.zeros((n, prob.n_vars)),
                      phi=ref.phi if ref is not None else None,
                      modes=ref.modes if ref is not None else None, refused=True)


def run_optimizer(prob, progress=None):
    """Minimise ``prob``'s objective from ``prob.x0()``.

    ``prob`` is a :class:`Problem` or anything with its interface (a joint problem over several
    plates). Returns (evaluation at the optimum, converged, status, warnings, initial RMS %).
    """
    options = prob.options
    x0 = prob.x0()
    if not prob.feasible(x0):
        raise FitInputError(f"{prob.describe()}: the initial constants (with the fixed ones) are "
                       "outside the feasible region of Eq. 22 (E2 <= E1, |nu12| < "
                       f"{options.nu_max}, positive moduli)")
    if options.solver == "reduced" and prob.given_basis is not None:
        prob.start_reduced(None, prob.given_basis)
    ev0 = prob.evaluate(x0)
    warnings = prob.check_start(ev0)
    initial_rms = prob.history[0].rms_residual_percent
    if options.solver == "reduced" and not prob.reduced:
        prob.start_reduced(ev0)
        prob.adopt(ev0)
    ev, converged, status = _stage(prob, ev0, progress)
    # Re-anchoring: measured mode i pairs with the model's i-th mode at the start; if tracking
    # ends with another order, that start pairing was wrong (the initial guess had its modes in
    # another order than the plate). Re-pair in sorted order there and optimise again; keep
    # the better fit. Found on the paper's S2.2 and hybrid ESL (RMS 1.12 / 4.35 % -> 0.22 / 0.14 %).
    for _ in range(MAX_REANCHOR):
        if prob.options.pairing != "track" or np.array_equal(ev.pairing, prob.sorted_pairing()):
            break
        prob.reanchor()
        ev_r = prob.evaluate(ev.x)
        ev2, converged2, status2 = _stage(prob, ev_r, progress)
        log.info("re-anchored the mode pairing: objective %.6g -> %.6g", ev.objective,
                 ev2.objective)
        if ev2.objective < ev.objective:
            prob.swaps.append(f"evaluation {prob.n_eval}: mode pairing re-anchored in sorted "
                              "order at the optimum (the initial guess had the modes in another "
                              "order)")
            ev, converged, status = ev2, converged2, status2
        else:
            prob.adopt(ev)
            break
    if prob.options.pairing == "track" and not np.array_equal(ev.pairing, prob.sorted_pairing()):
        warnings = list(warnings) + [
            "at the optimum the measured modes are not paired with the model modes in sorted "
            "order (model modes " + ", ".join(str(int(k) + 1) for k in ev.pairing) + "): a mode "
            "may be missing from the measured list (give it as null) or the modes are too close "
            "to order reliably"]
    if prob.n_refused:
        warnings = list(warnings) + [f"{prob.n_refused} trial point(s) outside the feasible "
                                     "region were refused without evaluating the model"]
    if prob.reduced:
        ev = _finish_reduced(prob, ev)
    return ev, converged, status, warnings, initial_rms


#: the start's basis also holds the first-order mode changes in every stiffness coefficient
#: (ReducedBasis.add_sensitivities). Off: it halves the evaluations and saves 2 factorisations
#: on S1.1, but its stiff directions raise the round-off floor of the projected eigenvalues to
#: ~1e-8 relative (seen in central differences); the Monte Carlo trials use it at the optimum
SENSITIVITY_START = False
#: most enrichments of one reduced-model stage
MAX_ENRICH = 40
#: initial trust radius (Gauss-Newton-scaled variables: a step of 1 changes the objective by
#: about its value) and its growth when the reduced model predicted the decrease well
RADIUS0 = 8.0
#: Gauss-Newton damping of the reduced stages: each restarts the optimiser (its quasi-Newton
#: memory is lost), so its scaling must be the Gauss-Newton Hessian itself for the first step
#: to reach along flat valleys; the trust region bounds the step instead
REDUCED_DAMPING = 1e-6
#: converged when, besides the eigenvalues, the step from a centre enriched there is below
#: this (Gauss-Newton-scaled: changes the objective by about STEP_TOL^2 of its value)
STEP_TOL = 1e-4
RADIUS_GROWTH = 4.0


def _stage(prob, ev0, progress=None):
    """One optimisation stage from ``ev0``: on the reduced model when it is in use."""
    if prob.reduced:
        return _optimize_reduced(prob, ev0, progress)
    return _optimize_from(prob, ev0, progress)


def _optimize_reduced(prob, ev_c, progress=None):
    """Trust-region loop on the reduced model (laminid_cli.reduced).

    From the centre ``ev_c`` the optimiser runs on the reduced model within a box of radius
    ``radius`` in the Gauss-Newton-scaled variables; at its answer x_t the basis is enriched
    and the objective evaluated again. The step is accepted when the enriched objective at x_t
    is below the enriched one at the centre; the radius doubles when the predicted decrease is
    confirmed (ratio rho >= 0.75) and the step reached the box, and shrinks to a quarter of the
    step when rho < 0.25. Stops when an enrichment changes the paired eigenvalues by less than
    ``reduced_tol`` (relative) and the step is within ``xtol``.
    """
    options = prob.options
    radius = RADIUS0
    converged, status = False, "not converged: reduced model did not settle"
    for _ in range(MAX_ENRICH):
        # each optimiser run on the reduced model has the evaluation budget of a full-model
        # run, less the start's evaluation and the final check's
        n_before = prob.n_eval
        budget = max(options.max_evaluations - 2, 1)
        ev_t, inner_conv, inner_status = _optimize_from(prob, ev_c, progress, radius=radius,
                                                        maxeval=budget,
                                                        damping=REDUCED_DAMPING)
        step = prob.last_step
        if prob.n_eval - n_before >= budget:
            converged, status = False, inner_status
            ev_c = ev_t if ev_t.objective <= ev_c.objective else ev_c
            break
        f_c_old, f_pred, lam_pred = ev_c.objective, ev_t.objective, ev_t.eigenvalues
        prob.enrich(ev_t)
        ev_t2 = prob.evaluate(ev_t.x)
        same = np.array_equal(ev_t.x, ev_c.x)
        ev_c2 = ev_t2 if same else prob.evaluate(ev_c.x)
        ok = prob.weight > 0
        change = (float(np.max(np.abs(ev_t2.eigenvalues - lam_pred)[ok] / lam_pred[ok]))
                  if not ev_t2.refused else np.inf)
        predicted = f_c_old - f_pred
        actual = ev_c2.objective - ev_t2.objective
        rho = actual / predicted if predicted > 0 else (1.0 if actual >= 0 else -1.0)
        if ev_t2.objective <= ev_c2.objective:
            ev_c = ev_t2
        else:
            ev_c = ev_c2
        prob.adopt(ev_c)
        if predicted <= 1e-12 * abs(f_c_old):
            pass                         # decrease at round-off level: rho means nothing
        elif rho >= 0.75 and step >= 0.9 * radius:
            radius *= RADIUS_GROWTH
        elif rho < 0.25:
            radius = max(0.25 * step, 1e-3 * options.xtol_rel)
        log.info("enrichment %d: basis change of the paired eigenvalues %.2e, step %.2e, "
                 "rho %.3f, radius %.3g", prob.n_enrich, change, step, rho, radius)
        # converged: the enrichment left the paired eigenvalues at the optimiser's answer
        # unchanged, and that answer is the optimiser's own (not cut by the trust region) or
        # the step is within the step tolerance
        if change <= options.reduced_tol and step <= STEP_TOL:
            converged, status = inner_conv, inner_status
            if ev_c is not ev_t2 and ev_t2.objective <= ev_c.objective * (1 + 1e-9):
                ev_c = ev_t2             # as good within a 1e-9 of the objective (a step of
                #                          < STEP_TOL), and enriched there: no new factorisation
                prob.adopt(ev_c)
            break
    return ev_c, converged, status


def _finish_reduced(prob, ev):
    """The evaluation reported at the optimum: the reduced one when its error bound shows it
    equal to the full model's (relative eigenvalue bound <= FINAL_BOUND for every checked
    mode), else the full model solved there.

    The bound of the enrichment is that of the Ritz vectors before its last block solve; the
    final check's (full-matrix Rayleigh quotients of the Ritz vectors) can land just above the
    limit (seen: 1.2e-9 on a Monte Carlo trial), so one more enrichment at the same point -- its
    factorisation is kept -- is tried before a full solve."""
    for _ in range(2):
        bounds = prob.bound_at(ev.x)
        if bounds is None or bounds[2] > FINAL_BOUND:
            prob.enrich(ev, rounds=FINAL_ROUNDS, target=FINAL_BOUND)
            prob.adopt(prob.evaluate(ev.x))
            ev = prob.best
        final = prob.final_check(ev)
        bounds = prob.bound_at(final.x)
        log.info("error bound at the optimum: %.2e relative (limit %.0e)", bounds[2],
                 FINAL_BOUND)
        if bounds[2] <= FINAL_BOUND:
            prob.adopt(final)
            return final
    prob.use_full()
    full = prob.evaluate(ev.x)
    prob.adopt(full)
    prob.final_bound = (full.x.tobytes(), np.zeros(full.eigenvalues.size), 0.0)
    return full


def _optimize_from(prob, ev0, progress=None, radius=None, ftol_rel=None, xtol=None,
                   damping=None, maxeval=None):
    """One nlopt run from ``ev0`` (Gauss-Newton-scaled variables); returns (ev, converged, status).

    ``radius``: the scaled step stays within this box (trust region of the reduced model);
    the step taken (max norm, scaled) is left in ``prob.last_step``."""
    import nlopt

    options = prob.options
    x0 = ev0.x
    first = len(prob.history) - 1            # this stage's evaluations start here
    # Variables scaled by the Gauss-Newton Hessian at the start, y = L^T (x - x0) with
    # L L^T = 2 J^T W J / Phi0 (+ damping): SLSQP's first quasi-Newton step is then close to a
    # Gauss-Newton step instead of a raw gradient step that jumps to the bounds. Bounds and
    # the feasibility constraints become linear constraints on y (still a polytope).
    scale = max(ev0.objective, 1e-300)
    L = _gauss_newton_factor(prob, ev0, scale, DAMPING if damping is None else damping)
    T = np.linalg.inv(L.T)                                            # x = x0 + T y
    lo, hi = prob.bounds()
    A, b = prob.linear_constraints()
    A_all = np.vstack([A, np.eye(prob.n_vars), -np.eye(prob.n_vars)])
    b_all = np.concatenate([b, hi, -lo])
    Ay = A_all @ T
    by = b_all - A_all @ x0
    span = np.abs(L.T) @ np.maximum(hi - x0, x0 - lo)                 # a finite box for MMA
    if radius is not None:
        span = np.minimum(span, radius)

    algo = nlopt.LD_SLSQP if options.optimizer == "slsqp" else nlopt.LD_MMA
    opt = nlopt.opt(algo, prob.n_vars)
    opt.set_lower_bounds(-span)
    opt.set_upper_bounds(span)

    def cons(result, y, grad):
        if grad.size:
            grad[:] = Ay
        result[:] = Ay @ y - by

    opt.add_inequality_mconstraint(cons, np.full(Ay.shape[0], 1e-12))

    def objective(y, grad):
        ev = prob.evaluate(x0 + T @ y)
        if grad.size:
            grad[:] = T.T @ ev.gradient / scale
        if progress is not None:
            progress(prob.n_eval, ev.objective, prob.history[-1].rms_residual_percent)
        return ev.objective / scale

    opt.set_min_objective(objective)
    opt.set_xtol_abs(np.full(prob.n_vars, options.xtol_rel if xtol is None else xtol))
    opt.set_ftol_rel(options.ftol_rel if ftol_rel is None else ftol_rel)
    opt.set_maxeval(options.max_evaluations if maxeval is None else maxeval)
    status = ""
    try:
        x_best = x0 + T @ opt.optimize(np.zeros(prob.n_vars))
        code = opt.last_optimize_result()
        converged = code in (nlopt.SUCCESS, nlopt.FTOL_REACHED, nlopt.XTOL_REACHED,
                             nlopt.STOPVAL_REACHED)
        status = {nlopt.SUCCESS: "converged", nlopt.FTOL_REACHED: "converged (objective "
                  "tolerance reached)", nlopt.XTOL_REACHED: "converged (variable tolerance "
                  "reached)", nlopt.MAXEVAL_REACHED: f"not converged: {options.max_evaluations} "
                  "evaluations reached (raise --max-evaluations or loosen --xtol/--ftol)",
                  nlopt.MAXTIME_REACHED: "not converged: time limit"}.get(code, f"stopped ({code})")
    except nlopt.RoundoffLimited:
        x_best = _best_x(prob, first)
        converged = _stalled(prob)
        status = ("converged (stopped by round-off: no further decrease is resolvable)"
                  if converged else "not converged: stopped by round-off errors")
    except LaminidError:
        raise
    except (RuntimeError, ValueError) as exc:
        x_best = _best_x(prob, first)
        converged = False
        status = f"not converged: optimiser failure ({exc})"
    # the optimiser's answer may not be the last evaluation: evaluate it (cached if it is)
    best = _best_x(prob, first)
    if prob.evaluate(best).objective < prob.evaluate(x_best).objective:
        x_best = best
    ev = prob.evaluate(x_best)
    prob.last_step = float(np.max(np.abs(L.T @ (ev.x - x0)))) if prob.n_vars else 0.0
    return ev, converged, status


def _gauss_newton_factor(prob: Problem, ev: Evaluation, scale: float,
                         damping: float = DAMPING) -> np.ndarray:
    """Lower Cholesky factor of the damped Gauss-Newton Hessian of Phi / scale at ``ev``."""
    Jr = -(np.sqrt(prob.weight) / prob.lam_meas)[:, None] * ev.dlam_dx
    H = 2 * Jr.T @ Jr / scale
    for k, p in enumerate(prob.params):                   # prior term, Eq. 15
        for name, wp in prob.prior[k].items():
            if name in p.free:
                j = prob.offsets[k] + p.free.index(name)
                ref = p.initial.as_array()[CONSTANT_NAMES.index(name)]
                sc = 1.0 if name == "nu12" else ref
                H[j, j] += 2 * wp * (sc / (ref if ref else 1.0)) ** 2 / scale
    d = np.diag(H).copy()
    H += np.diag(damping * max(d.max(), 1e-300) + 1e-3 * d)  # Levenberg-Marquardt-type damping
    return np.linalg.cholesky(H)


def _best_x(prob: Problem, first: int = 0) -> np.ndarray:
    """Variables of the lowest objective among the evaluations from index ``first`` on."""
    k = first + int(np.argmin([h.objective for h in prob.history[first:]]))
    return prob.history[k].x


def _stalled(prob: Problem) -> bool:
    """Round-off stop at an optimum: the best objective stopped changing."""
    obj = np.array([h.objective for h in prob.history])
    if obj.size < 4:
        return False
    best = np.minimum.accumulate(obj)
    return bool(abs(best[-4] - best[-1]) <= 1e-8 * max(best[-1], 1e-300) or best[-1] < 1e-20)


def _result(prob: Problem, ev: Evaluation, converged, status, warnings, initial_rms, dt):
    fm = prob.fm
    constants = prob.constants(ev.x)
    f_model = np.sqrt(ev.eigenvalues) / (2 * np.pi)
    residual = residuals_percent(prob.freq, f_model)
    # normalised sensitivities d ln f_i / d ln P_j for every constant of every material
    E = fm.plate.basis_energies(ev.phi)
    sens, labels = [], []
    for k, c in enumerate(constants):
        _, Jc = coefficients_and_jacobian(c)
        dlam_dP = E[k].T @ Jc                                        # (n_meas, 6)
        P = c.as_array()
        sens.append(dlam_dP * P[None, :] / (2 * ev.eigenvalues[:, None]))
        labels += [f"{fm.material_names[k]}.{n}" for n in CONSTANT_NAMES]
    lo, hi = prob.bounds()
    A, b = prob.linear_constraints()
    hit = [f"{prob.labels[i]} at its {'lower' if abs(ev.x[i] - lo[i]) < abs(ev.x[i] - hi[i]) else 'upper'} bound"
           for i in range(prob.n_vars)
           if min(abs(ev.x[i] - lo[i]), abs(ev.x[i] - hi[i])) <= 1e-6 * max(1.0, abs(ev.x[i]))]
    active = np.flatnonzero(A @ ev.x - b > -1e-7) if A.shape[0] else []
    held = [f"{p.name}: {lab}" for p in prob.params for lab in p.constraint_labels()]
    hit += [held[int(j)] for j in active]
    if hit:
        warnings = list(warnings) + [f"the optimum runs into a bound: {'; '.join(hit)}"]
    hist = prob.history
    lam = fm.laminate.with_constants(constants)
    return Identification(
        specimen=fm.specimen, material_names=fm.material_names, initial=fm.initial_constants,
        constants=constants, free={p.name: tuple(p.free) for p in prob.params},
        parametrization={p.name: p.kind for p in prob.params}, variable_labels=prob.labels,
        x=ev.x, objective=ev.objective, evaluations=prob.n_eval, converged=bool(converged),
        status=status, time_s=dt, measured_hz=prob.freq, weight=prob.weight, model_hz=f_model,
        pairing=ev.pairing, residual_percent=residual,
        rms_residual_percent=weighted_rms(residual, prob.weight),
        initial_rms_residual_percent=initial_rms, modes=ev.modes, phi_paired=ev.phi,
        dlam_dx=ev.dlam_dx, sensitivity=np.hstack(sens), sensitivity_labels=tuple(labels),
        history=history_arrays(hist),
        swaps=tuple(prob.swaps), bounds_hit=tuple(hit), warnings=tuple(warnings),
        global_properties=lam.global_properties().as_dict(), options=prob.options,
        error_bound=_error_bound(prob, ev), work=dict(getattr(prob, "work", {})),
        basis=prob.last_basis)


def _error_bound(prob, ev) -> np.ndarray:
    """Relative error bound of the paired eigenvalues at ``ev`` against the full model."""
    if prob.basis is None:
        return np.zeros(prob.n_meas)
    b = prob.bound_at(ev.x)
    return np.full(prob.n_meas, np.nan) if b is None else b[1]
