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
modes that swap order keep their identity. Swaps are recorded. A tracked pairing that ends out
of sorted order is re-anchored in sorted order there (run_optimizer), and such a run is also
fitted with the plain sorted pairing from the start, the better answer kept
(:func:`_sorted_from_start`). ``pairing="sorted"`` keeps the paper's plain sorted order.

Structure: the objective itself is pure (:class:`laminid_cli.objective.Objective`, over a list
of plates); :class:`Problem` is one optimisation run over it (the plates' eigen models and a
:class:`laminid_cli.objective.RunLog`); a single plate is the problem of one plate, the joint
identification (laminid_cli.joint) the same over several.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from laminid_cli.errors import FitInputError, LaminidError
from laminid_cli.forward import (FAR_FROM_MODEL, ForwardModel, coarse_mesh, far_cause,
                                 residuals_percent, weighted_rms)
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants, alphas_from_constants
from laminid_cli.modal import WORK, Modes
from laminid_cli.objective import (ErrorBound, Evaluation, HistoryRow, MeasuredData,  # noqa: F401
                                   Objective, PlateTerm, RunLog, VariableSet,
                                   check_shared_materials, history_arrays, max_assignment,
                                   residual_rows)
from laminid_cli.parametrization import (InitialValueError, coefficients_and_jacobian,
                                         make_parameters)
from laminid_cli.specimen import constant_line, field_line

log = logging.getLogger(__name__)


def _plural(n: int, one: str, many: str | None = None) -> str:
    """``1 weighted frequency``, ``3 weighted frequencies``."""
    return f"{n} {one if n == 1 else (many or one + 's')}"

OPTIMIZERS = ("slsqp", "mma")
PAIRINGS = ("track", "sorted")
SOLVERS = ("reduced", "full")
#: a reduced-model result is taken as the full model's when the relative eigenvalue error bound
#: of every mode up to two beyond the highest paired one is below this (the modes written are
#: cut there); else the optimum is solved again with the full model
FINAL_BOUND = 1e-9
#: block solves tried at the optimum (with one factorisation) to reach FINAL_BOUND, by the
#: final check's local refinement (ReducedBasis.check) and, if that falls short, by an
#: enrichment of the basis there
FINAL_ROUNDS = 12
#: damping of the Gauss-Newton scaling, relative to its largest diagonal term
DAMPING = 1e-2
#: default cap on an identification's model evaluations in all (full and reduced; the paper
#: plates take 37-269 at 12x12, hybrid CM 1164-1197 along its flat valley (CHOLMOD / banded
#: Cholesky); each re-run of --fix-undetermined and each Monte Carlo trial has its own)
MAX_EVALUATIONS = 3000


@dataclass(frozen=True)
class IdentifyOptions:
    """Settings of an identification run.

    fix : constants held at their initial values, as "nu12" (every material) or
        "glass.nu12" (one material); added to each material's ``fixed`` list in the specimen
    optimizer : 'slsqp' (nlopt LD_SLSQP, default) or 'mma' (nlopt LD_MMA)
    parametrization : 'auto' (paper Eq. 14 alphas where all constants are free), 'alpha', 'constants'
    xtol_rel : step tolerance on the Gauss-Newton-scaled variables (a step of 1 changes the
        objective by about its initial value), ftol_rel : relative objective tolerance,
        max_evaluations : most model evaluations of the whole identification (every stage,
        reduced ones included, and a sorted-pairing second pass)
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
    alpha_region : (material, floor) pairs: materials whose constants, where some are held,
        are searched in the region of the alphas (laminid_cli.parametrization.
        ConstantParameters, region 'alpha', with that floor of the shear moduli) instead of
        the box [P0 / f, P0 f]: the refits of a profile (laminid_cli.uncertainty.refit_held)
        of an identification that searched them with the alphas
    """

    fix: tuple[str, ...] = ()
    optimizer: str = "slsqp"
    parametrization: str = "auto"
    xtol_rel: float = 1e-6
    ftol_rel: float = 1e-8
    max_evaluations: int = MAX_EVALUATIONS
    pairing: str = "track"
    extra_modes: int = 4
    nu_max: float = 0.95
    bound_factor: float = 5.0
    far_limit: float = FAR_FROM_MODEL
    solver: str = "reduced"
    reduced_tol: float = 1e-7
    alpha_region: tuple[tuple[str, float], ...] = ()



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
    #: the factorisation of K - sigma M used: 'cholmod' or 'banded' (modal.make_factorizer)
    factorization: str = ""
    #: the plate's equations the model had: 'all', or 'bending' for a symmetric laminate's
    #: bending equations alone (forward.bending_model)
    equations: str = "all"



class Problem(VariableSet):
    """One optimisation run over a list of plates: the pure :class:`Objective`, the eigen model
    of each plate (full, or a reduced basis that follows the optimiser) and the run's
    :class:`RunLog` (cache, tracking reference, swaps, counters, history).

    A single plate (``identify``) is the problem of one plate; ``identify --joint`` the same
    over several plates sharing materials by name (laminid_cli.joint)."""

    def __init__(self, fms, options: IdentifyOptions, *, start=None, start_pairing=None,
                 basis=None, check_count: bool = True, prior_shift: dict | None = None):
        """``fms``: a ForwardModel (one plate) or a sequence of them. ``start``: constants (one
        ElasticConstants per distinct material, first-appearance order) to start from instead
        of the files' initial values, which stay the reference of the design variables, the
        prior and the fixed constants (a Monte Carlo re-identification starts from the
        optimum). ``start_pairing``: model mode (0-based) paired with each measured mode at
        the start instead of sorted order (one array; with several plates a list of them, or
        None entries). ``basis``: a ReducedBasis (a list of them with several plates) to start
        the reduced solver from. ``check_count=False`` accepts fewer weighted frequencies than
        free constants. ``prior_shift``: a Monte Carlo trial's draw of the prior's
        pseudo-measurements (:attr:`laminid_cli.objective.VariableSet.prior_shift`)."""
        self.single = isinstance(fms, ForwardModel)
        fms = (fms,) if self.single else tuple(fms)
        if not self.single:
            start_pairing = None if start_pairing is None else list(start_pairing)
            basis = None if basis is None else list(basis)
        else:
            start_pairing = None if start_pairing is None else [start_pairing]
            basis = None if basis is None else [basis]
        self.fms = fms
        self.options = options
        if options.optimizer not in OPTIMIZERS:
            raise FitInputError(f"optimizer '{options.optimizer}' unknown: choose {', '.join(OPTIMIZERS)}")
        if options.solver not in SOLVERS:
            raise FitInputError(f"solver '{options.solver}' unknown: choose {', '.join(SOLVERS)}")
        if options.pairing not in PAIRINGS:
            raise FitInputError(f"pairing '{options.pairing}' unknown: choose {', '.join(PAIRINGS)}")
        specimens = [fm.specimen for fm in fms]
        data = [MeasuredData.of(spec) for spec in specimens]
        for d in data:
            if not (d.weight > 0).any():
                raise FitInputError(f"{d.source}: every measured frequency has weight 0; "
                                    "nothing to fit")
        merged = check_shared_materials(specimens)   # material -> fixed in some file
        self.material_names = tuple(merged)
        self.merged_fixed = {n: tuple(k for k in merged[n]
                                      if not all(k in s.materials[n].fixed
                                                 for s in specimens if n in s.materials))
                             for n in merged}
        first_mat, first_spec = {}, {}
        for spec in specimens:
            for name, mat in spec.materials.items():
                first_mat.setdefault(name, mat)
                first_spec.setdefault(name, spec)
        fixed_opt = _parse_fix(options.fix, self.material_names, self.describe())
        alpha_region = dict(options.alpha_region)
        params = []
        for name in self.material_names:
            mat = first_mat[name]
            fixed = tuple(dict.fromkeys(merged[name] + fixed_opt.get(name, ())))
            try:
                params.append(make_parameters(
                    name, mat.constants, fixed, kind=options.parametrization,
                    prior=bool(mat.prior), nu_max=options.nu_max,
                    bound_factor=options.bound_factor,
                    region="alpha" if name in alpha_region else "box",
                    floor=alpha_region.get(name, 1.0)))
            except InitialValueError as exc:  # an initial value the search cannot start from
                spec = first_spec[name]
                line = constant_line(spec, name, exc.constant)
                raise FitInputError(f"{spec.path}{f':{line}' if line else ''}, field "
                                    f"'materials.{name}.{exc.constant}': {exc.words}") from None
            except FitInputError as exc:
                raise FitInputError(f"{first_spec[name].path}: {exc}") from None
        self._set_params(params)
        prior = [{k: float(w) for k, w in first_mat[p.name].prior.items()} for p in params]
        by_name = {p.name: (k, p) for k, p in enumerate(params)}
        plates = []
        for fm, d in zip(fms, data):
            mine = [by_name[n] for n in fm.material_names]
            index = np.concatenate([np.arange(self.offsets[k], self.offsets[k + 1])
                                    for k, _ in mine]).astype(int)
            plates.append(PlateTerm(fm, d, [p for _, p in mine], index,
                                    d.n + options.extra_modes))
        self.solver_note = ""
        small = [(fm.plate.n_dofs, pt.n_model) for fm, pt in zip(fms, plates)
                 if fm.plate.n_dofs < REDUCED_MIN_EQUATIONS_PER_MODE * pt.n_model]
        if options.solver == "reduced" and small:
            n, k = small[0]
            options = self.options = dataclasses.replace(options, solver="full")
            self.solver_note = (
                f"full solver: the model has {n} equations for {k} modes, fewer than "
                f"{REDUCED_MIN_EQUATIONS_PER_MODE} per mode, too few for a reduced model (a "
                "mesh this coarse is itself suspect)")
        self.objective = Objective(plates, params, prior, pairing=options.pairing)
        obj = self.objective
        if prior_shift:
            obj.prior_shift = self.prior_shift = dict(prior_shift)
        self.plates, self.prior = obj.plates, obj.prior
        self.freq, self.weight, self.lam_meas, self.n_meas = (obj.freq, obj.weight,
                                                              obj.lam_meas, obj.n_meas)
        n_active = int((self.weight > 0).sum())
        if self.n_vars == 0:
            raise FitInputError(f"{self.describe()}: every constant is fixed; nothing to identify")
        if check_count and n_active < self.n_vars and not any(self.prior):
            raise FitInputError(self._too_few_frequencies(n_active))
        self.start = None if start is None else tuple(start)
        if self.start is not None and len(self.start) != len(params):
            raise FitInputError(f"{self.describe()}: {len(self.start)} start constants for "
                                f"{len(params)} materials")
        self.start_pairing = (None if start_pairing is None else
                              [None if s is None else np.asarray(s, int) for s in start_pairing])
        self.models = None               # per plate: ReducedBasis while the reduced model is used
        self.given_basis = basis         # bases to start from (reduced solver)
        self._last_basis = None
        self.log = RunLog(n_plates=len(plates))

    # --- the plates and the run log ------------------------------------------------------------
    @property
    def fm(self):
        """The forward model (one plate)."""
        return self.fms[0]

    @property
    def n_model(self) -> int:
        """Model modes computed (one plate)."""
        return self.plates[0].n_model

    @property
    def history(self) -> list:
        return self.log.history

    @property
    def n_eval(self) -> int:
        return self.log.n_eval

    @property
    def n_refused(self) -> int:
        return self.log.n_refused

    @property
    def n_enrich(self) -> int:
        return self.log.n_enrich

    @property
    def swaps(self) -> list:
        return self.log.swaps

    @property
    def best(self):
        return self.log.best

    # --- variables ---------------------------------------------------------------------------
    def x0(self) -> np.ndarray:
        """Start point: the initial values, or the ``start`` constants when given."""
        if self.start is None:
            return np.concatenate([p.x0() for p in self.params])
        return np.concatenate([variables_of(p, c) for p, c in zip(self.params, self.start)])

    def describe(self) -> str:
        """Where the data come from, for error messages."""
        if self.single:
            return str(self.fms[0].specimen.path)
        return "joint identification of " + ", ".join(str(fm.specimen.path) for fm in self.fms)

    def _too_few_frequencies(self, n_active: int) -> str:
        """Why fewer weighted frequencies than free constants cannot be fitted: the file, its
        field (measured.frequencies, measured.weights where some of them have weight 0, or
        measured.frf_file) and what to do."""
        need = self.n_vars - n_active
        todo = (f"measure more modes, or fix {need} or more of the constants (--fix, e.g. --fix "
                "nu12,G13,G23, which a thin plate's modes determine worst, or the material's "
                "'fixed:' list)")
        count = (f"{_plural(n_active, 'weighted frequency', 'weighted frequencies')} for "
                 f"{_plural(self.n_vars, 'free constant')}")
        needs = "the fit needs at least one per constant"
        if not self.single:
            each = ", ".join(f"{fm.specimen.path}: {int((pt.data.weight > 0).sum())}"
                             for fm, pt in zip(self.fms, self.plates))
            return f"{self.describe()}: {count} ({each}; {needs}): {todo}"
        spec = self.fms[0].specimen
        data = self.plates[0].data
        n_given = int(np.isfinite(data.freq).sum())
        if spec.measured is not None and spec.measured.frf_file:
            key, given = "frf_file", f"the fit of {spec.measured.frf_file} gave {n_given}; "
        elif n_given > n_active:
            key = "weights"
            given = f"{n_given - n_active} of the {n_given} measured have weight 0; "
            todo = "give more of them a weight above 0, " + todo
        else:
            key, given = "frequencies", ""
        if field_line(spec, "measured", key) is None:
            key = "frequencies"
        line = field_line(spec, "measured", key)
        where = f"{spec.path}{f':{line}' if line else ''}, field 'measured.{key}'"
        return f"{where}: {count} ({given}{needs}): {todo}"

    def check_start(self, ev: Evaluation) -> list[str]:
        """Refuse hopeless starts; return warnings for doubtful ones."""
        out = []
        for plate, part in zip(self.plates, ev.parts):
            warn = check_start(plate, part, self.options.far_limit)
            out += warn if self.single else [f"{plate.name}: {w}" for w in warn]
        return out

    # --- evaluation --------------------------------------------------------------------------
    def evaluate(self, x) -> Evaluation:
        """The objective at ``x`` on the current models, tracked against the best point so far;
        recorded in the run log (cached: the same ``x`` twice is one evaluation)."""
        x = np.asarray(x, float)
        ev = self.log.cached(x)
        if ev is not None:
            return ev
        ref = self.log.best
        ev = self.objective.evaluate(x, self.models, ref,
                                     self.start_pairing if ref is None else None)
        if ev.refused:
            return self._refused(ev)
        self.log.record(ev, self.objective)
        return ev

    def _refused(self, ev: Evaluation) -> Evaluation:
        """Stand-in for a point whose constitutive matrix is not positive definite (paper Eq.
        22), counted once: the objective is ten times the worst one met so far, the gradient
        zero, so the optimiser's line search or conservative update steps back inside."""
        self.log.n_refused += 1
        # (info: the optimiser steps back inside by itself; the result's warnings count these
        # points, run_optimizer; a Monte Carlo's trials would print one line per point)
        log.info("point outside the feasible region not evaluated (%s)", "; ".join(ev.reasons))
        worst = max((h.objective for h in self.log.history), default=1.0)
        ref = self.log.best
        ev.objective = 10.0 * worst + 1.0
        if ref is not None:
            ev.pairing, ev.phi, ev.modes, ev.parts = ref.pairing, ref.phi, ref.modes, ref.parts
        return ev

    # --- reduced-order model (laminid_cli.reduced): one basis per plate ------------------------
    @property
    def reduced(self) -> bool:
        return self.models is not None

    @property
    def basis(self):
        """The basis in use (one plate; a list with several), None with the full model."""
        if self.models is None:
            return None
        return self.models[0] if self.single else list(self.models)

    def run_state(self) -> tuple:
        """What a second pass from the start replaces, for :meth:`restore_run_state`: the
        objective (its pairing), the bases and the final check's record."""
        return (self.objective, self.models, self._last_basis, self.log.checked,
                self.log.final_bound)

    def restore_run_state(self, state: tuple) -> None:
        """Put back what :meth:`run_state` saved (the counters and history go on)."""
        (self.objective, self.models, self._last_basis, self.log.checked,
         self.log.final_bound) = state

    def start_reduced(self, ev: Evaluation | None, basis=None) -> None:
        """Use the reduced model from now on, with bases made of ``ev``'s modes (a full
        evaluation) or the given ``basis`` list (kept from an earlier run)."""
        from laminid_cli.reduced import ReducedBasis

        models = []
        for k, plate in enumerate(self.plates):
            b = None if basis is None else basis[k]
            if b is None:
                part = ev.parts[k]
                b = ReducedBasis(plate.fm)
                b.add(part.modes.phi)
                if SENSITIVITY_START:
                    b.add_sensitivities(plate.coefficients(part.x)[0], part.modes.phi)
            models.append(b)
        self.models = models
        self._last_basis = list(models)
        self.log.cache = None

    def enrich(self, ev: Evaluation, rounds: int = 2, target: float = 0.0,
               reuse: float = 0.0, checked: bool = False) -> float:
        """Enrich every plate's basis at ``ev.x``; returns the largest relative change of the
        weighted paired eigenvalues and records the relative error bound of the paired modes
        there (see ReducedBasis.enrich for ``rounds`` and ``target``)."""
        changes, paired, worst = [], [], 0.0
        for plate, part, model in zip(self.plates, ev.parts, self.models):
            coef, _ = plate.coefficients(part.x)
            k = checked_modes(plate, part) if checked else plate.n_model
            _, after, bound = model.enrich(coef, k, rounds, target, reuse, keep=plate.n_model)
            rel = bound / after
            paired.append(rel[part.pairing])
            worst = max(worst, float(np.max(rel[:checked_modes(plate, part)])))
            changes.append(weighted_change(plate.data.weight, after[part.pairing],
                                           part.eigenvalues))
        self.log.n_enrich += 1
        self.log.cache = None
        self.log.final_bound = ErrorBound(ev.x.tobytes(), np.concatenate(paired), worst)
        return max(changes)

    def final_check(self, ev: Evaluation, target: float = 0.0, rounds: int = 1) -> Evaluation:
        """``ev`` (reduced model) checked against the full model: eigenvalues the full model's
        Rayleigh quotients of its Ritz vectors, sensitivities from their full strain energies,
        and the relative error bound of each checked mode (ReducedBasis.check, which refines
        the vectors up to ``rounds - 1`` times while a bound is above ``target``)."""
        parts, paired, worst = [], [], 0.0
        for k, (plate, part, model) in enumerate(zip(self.plates, ev.parts, self.models)):
            n = checked_modes(plate, part)
            coef, jacs = plate.coefficients(part.x)
            theta, U, bound = model.check(coef, part.modes.phi, reuse=REUSE_FACTOR,
                                          target=target, rounds=rounds, n=n)
            m = part.modes
            modes = Modes(eigenvalues=theta, phi=U, n_rigid=m.n_rigid,
                          rigid_eigenvalues=m.rigid_eigenvalues)
            parts.append(self.objective.plate_evaluation(k, part.x, modes, part.pairing, jacs))
            rel = bound / theta
            paired.append(rel[part.pairing])
            worst = max(worst, float(rel.max()))
        out = self.objective.combine(ev.x, parts)
        self.log.final_bound = ErrorBound(out.x.tobytes(), np.concatenate(paired), worst)
        self.log.record(out, self.objective)         # its history row carries that bound
        return out

    def bound_at(self, x) -> ErrorBound | None:
        """Relative error bounds at ``x`` if the last enrichment or check was there."""
        b = self.log.final_bound
        if b is not None and b.key == np.asarray(x, float).tobytes():
            return b
        return None

    def use_full(self) -> None:
        self.models = None
        self.log.cache = None

    @property
    def last_basis(self):
        """The bases in use, or the ones given / built before a final full solve (one plate:
        the basis itself)."""
        b = self.models if self.models is not None else self._last_basis
        if b is None:
            return None
        return b[0] if self.single else list(b)

    # --- pairing state, for run_optimizer's re-anchoring -----------------------------------------
    def sorted_pairing(self) -> np.ndarray:
        return np.concatenate([np.arange(p.data.n) for p in self.plates])

    def reanchor(self) -> None:
        """Forget the tracked identities: the next evaluation pairs in sorted order."""
        self.log.best, self.log.cache, self.start_pairing = None, None, None

    def adopt(self, ev: Evaluation) -> None:
        """Make ``ev`` the tracking reference and the cached evaluation again."""
        self.log.best, self.log.cache = ev, (ev.x.tobytes(), ev)


def weighted_change(weight: np.ndarray, lam: np.ndarray, ref: np.ndarray) -> float:
    """Largest relative change ``|lam - ref| / ref`` over the modes of positive weight (0
    when there is none): how far a basis change or a check moved the paired eigenvalues."""
    ok = weight > 0
    return float(np.max(np.abs(lam - ref)[ok] / ref[ok])) if ok.any() else 0.0


def checked_modes(plate: PlateTerm, part: Evaluation) -> int:
    """Modes held to FINAL_BOUND at the optimum: up to two beyond the highest paired one."""
    return int(min(plate.n_model, np.max(part.pairing) + 3))


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
        key = item.split("=", 1)[0].strip()
        if "=" in item and key.rsplit(".", 1)[-1] in CONSTANT_NAMES:
            raise FitInputError(
                f"--fix {item}: an elastic constant is fixed at its initial value in {path}; "
                f"write '--fix {key}' and set that value in the specimen's materials (only loss "
                "factors take a value here: eta13=0.01)")
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
                           f"{', '.join(CONSTANT_NAMES)}{_fix_case_hint(item)}")
        for t in targets:
            out[t] = out.get(t, ()) + (const,)
    return out


def _fix_case_hint(item: str) -> str:
    """"; did you mean 'G13'?" for ``--fix g13`` (or 'carbon.G13' for carbon.g13): the
    constants' names are case-sensitive (nu12 and NU12 alike would pass, G12 and g12 not)."""
    by_case = {c.lower(): c for c in CONSTANT_NAMES}
    mat, _, const = item.rpartition(".")
    if const.lower() in by_case:
        return f"; did you mean '{mat + '.' if mat else ''}{by_case[const.lower()]}'?"
    return ""


def _hz(f: float) -> str:
    """A frequency with two decimals, and below 1 Hz with 3 significant digits: kHz written as
    a bare number, 0.12505 (Hz), showed as 0.13 Hz."""
    return f"{f:.2f}" if abs(f) >= 1 else f"{f:.3g}"


class FarStartError(FitInputError):
    """A measured mode too far from the model where a fit starts (:func:`check_start`). Its
    parts are kept, so that a fit that starts elsewhere than at the specimen's initial values
    says where (:meth:`where`: a profile's fit with a constant held,
    :func:`laminid_cli.uncertainty.refit_held`)."""

    def __init__(self, source, mode: int, measured: float, model: float, ratio: float,
                 limit: float, cause: str, at: str = "at the initial guess"):
        self.parts = (source, mode, measured, model, ratio, limit, cause)
        super().__init__(f"{source}: measured mode {mode + 1} ({_hz(measured)} Hz) is "
                         f"{ratio * 100:.0f} % away from the model ({_hz(model)} Hz) {at} "
                         f"(limit {limit * 100:.0f} %): {cause}")

    def where(self, at: str, cause: str | None = None) -> "FarStartError":
        """The same refusal, saying ``at`` what start instead of "at the initial guess" (and
        ``cause`` instead of the likely input mistakes, where given)."""
        parts = self.parts if cause is None else self.parts[:-1] + (cause,)
        return FarStartError(*parts, at=at)


def check_start(plate: PlateTerm, ev: Evaluation, far_limit: float) -> list[str]:
    """Refuse a hopeless start of one plate (its evaluation ``ev``); return warnings for
    doubtful ones."""
    d = plate.data
    f_model = np.sqrt(ev.eigenvalues) / (2 * np.pi)
    ok = d.weight > 0
    ratio = np.abs(d.freq - f_model) / d.freq
    far = ok & (ratio > far_limit)
    if far.any():
        i = int(np.flatnonzero(far)[0])
        raise FarStartError(d.source, i, float(d.freq[i]), float(f_model[i]), float(ratio[i]),
                            far_limit, far_cause(d.freq, f_model, d.weight))
    # the specimen reader's own warnings first (ply angles that look like radians, a mass
    # that density x volume contradicts): the result, its report and --json keep them
    warnings = list(plate.fm.specimen.warnings)
    warnings += [f"measured mode {i + 1} is {ratio[i] * 100:.0f} % from the model at the start"
                 for i in np.flatnonzero(ok & (ratio > 0.25))]
    # a mesh too coarse for the measured modes, as modes warns of it (identify said nothing:
    # S1.1 at 3x3 ended 'poor_fit', naming 'a mesh too coarse' among five causes); the
    # thresholds are the whole plate's equations (those of a bending model are fewer)
    whole = plate.fm.whole if getattr(plate.fm, "whole", None) is not None else plate.fm
    coarse = coarse_mesh(whole, int(d.freq.size))
    if coarse is not None:
        warnings.append(f"{d.source}: {coarse}")
    spec = plate.fm.specimen
    slender = min(spec.a, spec.b) / spec.h
    if slender < THICK_PLATE:
        warnings.append(f"{d.source}: min(a, b)/h = {slender:.2g}: a plate theory (here third-"
                        "order shear deformation) describes a plate, not a block; below about "
                        f"{THICK_PLATE:g} its frequencies depart from 3-D elasticity, which "
                        "the constants then absorb")
    return warnings


#: side-to-thickness ratio below which check_start warns that the plate is a thick block
THICK_PLATE = 5.0


def identify(fm: ForwardModel, options: IdentifyOptions = IdentifyOptions(),
             progress=None, *, start=None, start_pairing=None, basis=None,
             prior_shift: dict | None = None) -> Identification:
    """Identify the constants of every material of ``fm.specimen`` (see module docstring).

    ``progress(evaluation, objective, rms_percent)`` is called after each model evaluation.
    Raises FitError for hopeless input; a run that stops before convergence returns with
    ``converged = False`` and a status message. ``start``/``start_pairing``: see
    :class:`Problem`. ``basis``: a ReducedBasis of ``fm`` to start the reduced solver from
    (e.g. ``earlier_result.basis.copy()``: no full solve at the start). ``prior_shift``: see
    :class:`Problem` (Monte Carlo trials).
    """
    t0 = time.perf_counter()
    work0 = dict(WORK)
    prob = Problem(fm, options, start=start, start_pairing=start_pairing, basis=basis,
                   prior_shift=prior_shift)
    ev, converged, status, warnings, initial_rms = run_optimizer(prob, progress)
    return _result(prob, 0, ev, converged, status, warnings, initial_rms,
                   time.perf_counter() - t0, work=work_since(work0, prob))


def work_since(work0: dict, prob) -> dict:
    """Factorisations, solve pairs and Lanczos runs since ``work0``, and the enrichments."""
    out = {k: WORK[k] - work0.get(k, 0) for k in WORK}
    out["enrichments"] = int(prob.n_enrich)
    return out


#: the reduced solver needs a model of at least this many equations per mode computed: its basis
#: grows to ~6-11 vectors per mode, most of a smaller model, and its Gram matrix comes near
#: singular. Seen on S1.1 at 2x2 (105 bending equations, 16 modes: 6.6 per mode): an error
#: ("lost its M-orthogonality") with one BLAS build (numpy 2.4), with another (numpy 2.5) an
#: optimum 29 % above the full solver's; at 3x3 (200 equations, 12.5 per mode, a basis of
#: 119-144 vectors) S1.1, S1.2, S1.3, S2.1 and S2.2 agree with the full solver's objective to
#: 3e-10 on both builds
REDUCED_MIN_EQUATIONS_PER_MODE = 10

#: a tracked pairing that ends out of sorted order is re-anchored at most this many times
MAX_REANCHOR = 2


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
                       f"{options.nu_max}, positive moduli, and with the paper's alphas E2 and "
                       "the shear moduli at least 1e-4 E1)")
    if options.solver == "reduced" and prob.given_basis is not None:
        prob.start_reduced(None, prob.given_basis)
    ev0 = prob.evaluate(x0)
    warnings = prob.check_start(ev0)
    if getattr(prob, "solver_note", ""):
        warnings = [prob.solver_note, *warnings]
    initial_rms = prob.history[0].rms_residual_percent
    if options.solver == "reduced" and not prob.reduced:
        prob.start_reduced(ev0)
        prob.adopt(ev0)
    ev, converged, status = _stage(prob, ev0, progress)
    # Re-anchoring: measured mode i pairs with the model's i-th mode at the start; if tracking
    # ends with another order, that start pairing was wrong (the initial guess had its modes in
    # another order than the plate). Re-pair in sorted order there and optimise again; keep
    # the better fit. Found on the paper's S2.2 and hybrid ESL (RMS 1.12 / 4.35 % -> 0.22 / 0.14 %).
    reanchored = False
    for _ in range(MAX_REANCHOR):
        if prob.options.pairing != "track" or np.array_equal(ev.pairing, prob.sorted_pairing()):
            break
        reanchored = True
        prob.reanchor()
        ev_r = prob.evaluate(ev.x)
        ev2, converged2, status2 = _stage(prob, ev_r, progress)
        log.info("re-anchored the mode pairing: objective %.6g -> %.6g", ev.objective,
                 ev2.objective)
        if ev2.objective < ev.objective:
            prob.log.swaps.append(f"evaluation {prob.n_eval}: mode pairing re-anchored in sorted "
                              "order at the optimum (the initial guess had the modes in another "
                              "order)")
            ev, converged, status = ev2, converged2, status2
        else:
            prob.adopt(ev)
            break
    if reanchored:
        ev, converged, status = _sorted_from_start(prob, x0, ev, converged, status, progress)
    if prob.options.pairing == "track" and not np.array_equal(ev.pairing, prob.sorted_pairing()):
        warnings = list(warnings) + [
            "at the optimum the measured modes are not paired with the model modes in sorted "
            "order (model modes " + ", ".join(str(int(k) + 1) for k in ev.pairing) + "): a mode "
            "may be missing from the measured list (give it as null) or the modes are too close "
            "to order reliably"]
    if prob.n_refused:
        # the optimiser's own points (not Monte Carlo trials); a constant the search ends on
        # a limit of is flagged by the status, not here
        n = prob.n_refused
        warnings = list(warnings) + [
            f"the optimiser proposed {n} point{'' if n == 1 else 's'} outside the feasible "
            f"region of Eq. 22 (E2 <= E1, |nu12| < {prob.options.nu_max:g}, positive moduli); "
            f"{'it was' if n == 1 else 'each was'} refused without evaluating the model and "
            "the search went on inside the region"]
    if prob.reduced:
        ev = _finish_reduced(prob, ev)
    return ev, converged, status, warnings, initial_rms


#: the plain sorted pairing's answer replaces the tracked one only when its objective is lower
#: by more than this (relative): an equal answer (S2.2) keeps the tracked run's
SORTED_GAIN = 1e-9


def nlopt_failures(nlopt) -> tuple:
    """The exceptions of an nlopt run that failed (besides RoundoffLimited and ForcedStop):
    RuntimeError and ValueError up to nlopt 2.7; since (2.11 here) its own ``nlopt.exception``
    classes, ``nlopt.runtime_error`` for NLOPT_FAILURE, which subclass neither: such a run
    went past ``except RuntimeError`` as a traceback (the emulator's plate, -j 1), and through
    a worker process as "cannot pickle 'SwigPyObject'"."""
    extra = getattr(nlopt, "exception", None)
    return (RuntimeError, ValueError) + ((extra,) if isinstance(extra, type) else ())


def objective_change(before: float, after: float) -> str:
    """``'0.205571 -> 0.205569'``: two objectives with as many significant digits (6 to 12)
    as tell them apart, where 6 wrote a fit kept for being better as '0.205571 -> 0.205571'
    (SORTED_GAIN is 1e-9 relative); the relative change after them where 12 digits do not
    tell them apart."""
    for digits in range(6, 13):
        a, b = f"{before:.{digits}g}", f"{after:.{digits}g}"
        if a != b:
            return f"{a} -> {b}"
    return f"{a} -> {b}, {(after - before) / before:+.1e} relative" if before else f"{a} -> {b}"


def _sorted_from_start(prob, x0, ev, converged, status, progress=None):
    """A second opinion for a tracked pairing that needed re-anchoring: the paper's plain
    sorted pairing, from the same start. Returns the better of the two answers.

    The tracking that ended out of sorted order went through near-coincident modes whose order
    along the way decides which minimum the re-anchorings reach. Each solver then takes its
    own path: on the hybrid ESL the reduced solver ended at 2.443e-4 (measured mode 20 paired
    with model mode 21) and the full solver at 3.894e-4. The sorted pairing from the start does
    not depend on that path: both solvers reach 1.5359e-4 with it, sorted, closer to the
    paper's Table 6. Where the tracked answer is as good (S2.2: both 2.3005e-4), it is kept.

    The pass is the ``pairing="sorted"`` identification itself: the reduced solver starts it
    afresh from a full solve at the start, as that run does (with the tracked run's basis it
    took another path, to 1.267e-3 on the hybrid ESL). The tracked run's bases and final
    check are kept for the case its answer stays."""
    saved = prob.run_state()
    prob.objective = prob.objective.with_pairing("sorted")
    prob.reanchor()
    prob.use_full()                      # the start afresh, as in run_optimizer
    ev0 = prob.evaluate(x0)
    if prob.options.solver == "reduced":
        prob.start_reduced(ev0)
        prob.adopt(ev0)
    ev_s, converged_s, status_s = _stage(prob, ev0, progress)
    log.info("plain sorted pairing from the start: objective %.6g (tracked: %.6g)",
             ev_s.objective, ev.objective)
    if ev_s.objective < ev.objective * (1 - SORTED_GAIN):
        prob.log.swaps.append(
            f"evaluation {prob.n_eval}: the plain sorted pairing from the start fits better than "
            f"the tracked one (objective {objective_change(ev.objective, ev_s.objective)}); "
            "its answer is kept")
        return ev_s, converged_s, status_s
    prob.restore_run_state(saved)
    prob.adopt(ev)
    return ev, converged, status


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
#: loosest step tolerance (Gauss-Newton-scaled) of a reduced-model stage; the stages after an
#: enrichment take the relative change of the paired eigenvalues it made, down to xtol_rel
INNER_XTOL_MAX = 1e-2
#: an enrichment (or the final check) at stiffness coefficients within this relative distance
#: of the last factorised ones preconditions with that factorisation (no new one); its error
#: bound holds with the factor 1 / min(mu, 1) of reduced.stiffness_ratio (mu ~ 0.99 here)
REUSE_FACTOR = 1e-2
#: block solves of an enrichment in the trust-region loop. One: the optimiser moves on after
#: it, and a second solve at the same point mostly refines what the next point's enrichment
#: replaces (S1.1 12x12: 0.86 -> 0.69 s; eight paper specimens 17.0 -> 11.3 s, with the
#: check's local refinement below); the accuracy at the optimum comes from the final check
LOOP_ROUNDS = 1
#: once an enrichment has changed the paired eigenvalues by at most CHECK_CHANGE (relative) and
#: the next stage's step is within CHECK_STEP (Gauss-Newton-scaled), its answer is checked
#: against the full model instead of enriched (:func:`_checked`): accepted when the checked
#: eigenvalues agree with the reduced ones within ``reduced_tol`` there (the enrichment's
#: criterion, measured at the answer itself). With the check's quadratic bound (one refinement
#: step) this saves the last enrichment: S1.1 12x12 6 -> 5 enrichments, 0.59 -> 0.53 s; the
#: eight paper specimens 11.1 -> 9.6 s, objectives within 1.3e-8 (hybrid CM) of before
CHECK_CHANGE = 1e-5
CHECK_STEP = 1e-3


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
    is below the enriched one at the centre; the radius grows fourfold (RADIUS_GROWTH) when the
    predicted decrease is confirmed (ratio rho >= 0.75) and the step reached the box, and
    shrinks to a quarter of the step when rho < 0.25. Stops when an enrichment changes the
    paired eigenvalues by less than ``reduced_tol`` (relative) and the step is within
    STEP_TOL; once an enrichment has changed them by at most CHECK_CHANGE, a stage whose step
    is within CHECK_STEP is checked against the full model at once (:func:`_checked`, no
    enrichment), and ends the loop when the checked eigenvalues agree with the reduced ones
    within ``reduced_tol`` (the same criterion, measured at the answer itself).
    """
    options = prob.options
    radius = RADIUS0
    converged, status = False, "not converged: reduced model did not settle"
    change = 0.0                         # the last enrichment's change of the eigenvalues
    for _ in range(MAX_ENRICH):
        # --max-evaluations caps the identification's evaluations in all (reduced-model ones
        # included): a stage gets what is left, less what an enrichment and the final check
        # take (RESERVE_EVALUATIONS)
        n_before = prob.n_eval
        reserve = min(RESERVE_EVALUATIONS, max(1, options.max_evaluations // 4))
        budget = options.max_evaluations - prob.n_eval - reserve
        if budget < 1:
            converged, status = False, maxeval_status(options)
            break
        # after an enrichment, the reduced model is only as good as that enrichment showed it:
        # solve it to a step tolerance of that order, not beyond (a tail of evaluations the
        # next enrichment would make moot); the first stage runs to xtol_rel
        xtol = max(options.xtol_rel, min(INNER_XTOL_MAX, change))
        ev_t, inner_conv, inner_status = _optimize_from(prob, ev_c, progress, radius=radius,
                                                        maxeval=budget, xtol=xtol,
                                                        damping=REDUCED_DAMPING)
        step = prob.log.last_step
        if prob.n_eval - n_before >= budget:
            converged, status = False, inner_status
            ev_c = ev_t if ev_t.objective <= ev_c.objective else ev_c
            break
        f_c_old, f_pred, lam_pred = ev_c.objective, ev_t.objective, ev_t.eigenvalues
        check_change = max(CHECK_CHANGE, options.reduced_tol)
        if prob.n_enrich and change <= check_change and step <= CHECK_STEP:
            # the last enrichment changed the eigenvalues little and the optimiser moved little
            # from its point: check the answer against the full model (refined to
            # FINAL_BOUND) instead of enriching; converged if the check agrees within
            # reduced_tol (else its factorisation serves the enrichment that follows)
            final = _checked(prob, ev_t, options.reduced_tol)
            if final is not None:
                return final, inner_conv, inner_status
        prob.enrich(ev_t, rounds=LOOP_ROUNDS, reuse=REUSE_FACTOR)
        ev_t2 = prob.evaluate(ev_t.x)
        same = np.array_equal(ev_t.x, ev_c.x)
        ev_c2 = ev_t2 if same else prob.evaluate(ev_c.x)
        change = (weighted_change(prob.weight, ev_t2.eigenvalues, lam_pred)
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
                 "rho %.3f (predicted decrease %.2e, actual %.2e relative), radius %.3g",
                 prob.n_enrich, change, step, rho, predicted / max(abs(f_c_old), 1e-300),
                 actual / max(abs(f_c_old), 1e-300), radius)
        # converged: the enrichment left the paired eigenvalues at the optimiser's answer
        # unchanged, and the step is within the step tolerance
        if change <= options.reduced_tol and step <= STEP_TOL:
            converged, status = inner_conv, inner_status
            if ev_c is not ev_t2 and ev_t2.objective <= ev_c.objective * (1 + 1e-9):
                ev_c = ev_t2             # as good within a 1e-9 of the objective (a step of
                #                          < STEP_TOL), and enriched there: no new factorisation
                prob.adopt(ev_c)
            break
    return ev_c, converged, status


def _checked(prob, ev, tol=None):
    """``ev`` checked against the full model (Problem.final_check, refined to FINAL_BOUND)
    when the check's bound is within FINAL_BOUND and, with ``tol``, its paired eigenvalues
    differ from ``ev``'s by at most ``tol`` (relative, weighted modes: the reduced model was
    already exact there); else None (the check's factorisation is kept for an enrichment that
    follows)."""
    final = prob.final_check(ev, target=FINAL_BOUND, rounds=FINAL_ROUNDS)
    bounds = prob.bound_at(final.x)
    change = weighted_change(prob.weight, final.eigenvalues, ev.eigenvalues)
    log.info("check at the optimum: error bound %.2e relative (limit %.0e), change of the "
             "paired eigenvalues %.2e", bounds.worst, FINAL_BOUND, change)
    if bounds.worst <= FINAL_BOUND and (tol is None or change <= tol):
        prob.adopt(final)
        prob.log.checked = final
        return final
    return None


#: evaluations the reduced loop keeps for an enrichment's two and the final check's (a quarter
#: of a smaller --max-evaluations, at least 1: a cap of 5 still runs 3)
RESERVE_EVALUATIONS = 5


def maxeval_status(options) -> str:
    return (f"not converged: the budget of --max-evaluations {options.max_evaluations} "
            "evaluations ran out (a few are kept for the final check; raise it or loosen "
            "--xtol/--ftol)")


def _finish_reduced(prob, ev):
    """The evaluation reported at the optimum: the reduced one checked against the full model
    (:func:`_checked`: relative eigenvalue bound <= FINAL_BOUND for every checked mode after
    refining the Ritz vectors, ReducedBasis.check), else the full model solved there. A check
    that falls short (near-coincident modes converge slowly on the check's local space) is
    tried once more after enriching the basis there (its factorisation is kept)."""
    if prob.log.checked is ev:
        return ev
    for attempt in range(2):
        final = _checked(prob, ev)
        if final is not None:
            return final
        if attempt == 0:
            prob.enrich(ev, rounds=FINAL_ROUNDS, target=FINAL_BOUND, reuse=REUSE_FACTOR,
                        checked=True)
            prob.adopt(prob.evaluate(ev.x))
            ev = prob.best
    prob.use_full()
    full = prob.evaluate(ev.x)
    prob.adopt(full)
    prob.log.final_bound = ErrorBound(full.x.tobytes(), np.zeros(full.eigenvalues.size), 0.0)
    return full


def _optimize_from(prob, ev0, progress=None, radius=None, ftol_rel=None, xtol=None,
                   damping=None, maxeval=None):
    """One nlopt run from ``ev0`` (Gauss-Newton-scaled variables); returns (ev, converged, status).

    ``radius``: the scaled step stays within this box (trust region of the reduced model);
    the step taken (max norm, scaled) is left in ``prob.log.last_step``."""
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
    left = options.max_evaluations - prob.n_eval                 # a cap on them in all
    if left < 1:                       # the budget is spent: a later stage runs no evaluation
        return ev0, False, maxeval_status(options)
    opt.set_maxeval(min(left, options.max_evaluations if maxeval is None else maxeval))
    status = ""
    try:
        x_best = x0 + T @ opt.optimize(np.zeros(prob.n_vars))
        code = opt.last_optimize_result()
        converged = code in (nlopt.SUCCESS, nlopt.FTOL_REACHED, nlopt.XTOL_REACHED,
                             nlopt.STOPVAL_REACHED)
        status = {nlopt.SUCCESS: "converged", nlopt.FTOL_REACHED: "converged (objective "
                  "tolerance reached)", nlopt.XTOL_REACHED: "converged (variable tolerance "
                  "reached)", nlopt.MAXEVAL_REACHED: maxeval_status(options),
                  nlopt.MAXTIME_REACHED: "not converged: time limit"}.get(code, f"stopped ({code})")
    except nlopt.RoundoffLimited:
        x_best = _best_x(prob, first)
        converged = _stalled(prob)
        status = ("converged (stopped by round-off: no further decrease is resolvable)"
                  if converged else "not converged: stopped by round-off errors")
    except LaminidError:
        raise
    except nlopt_failures(nlopt) as exc:
        x_best = _best_x(prob, first)
        converged = False
        status = f"not converged: optimiser failure ({exc})"
    # the optimiser's answer may not be the last evaluation: evaluate it (cached if it is)
    best = _best_x(prob, first)
    if prob.evaluate(best).objective < prob.evaluate(x_best).objective:
        x_best = best
    ev = prob.evaluate(x_best)
    prob.log.last_step = float(np.max(np.abs(L.T @ (ev.x - x0)))) if prob.n_vars else 0.0
    return ev, converged, status


def _gauss_newton_factor(prob: Problem, ev: Evaluation, scale: float,
                         damping: float = DAMPING) -> np.ndarray:
    """Lower Cholesky factor of the damped Gauss-Newton Hessian of Phi / scale at ``ev``."""
    Jr = residual_rows(prob.lam_meas, prob.weight, ev.eigenvalues, ev.dlam_dx).jacobian
    Jp = prob.prior_rows(ev.x)[1]                         # prior term, Eq. 15 (linear)
    H = 2 * (Jr.T @ Jr + Jp.T @ Jp) / scale
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


def _result(prob: Problem, k: int, ev: Evaluation, converged, status, warnings, initial_rms,
            dt, work=None):
    """The Identification of plate ``k`` at the optimum ``ev``: with one plate the run's
    result; with several, the plate's own part (its variables, its term of the objective
    without the prior, its history)."""
    plate = prob.plates[k]
    fm = plate.fm
    part = ev.parts[k]
    x = part.x
    constants = plate.constants(x)
    f_model = np.sqrt(part.eigenvalues) / (2 * np.pi)
    residual = residuals_percent(plate.data.freq, f_model)
    # normalised sensitivities d ln f_i / d ln P_j for every constant of every material
    E = fm.plate.basis_energies(part.phi)
    sens, labels = [], []
    for m, c in enumerate(constants):
        _, Jc = coefficients_and_jacobian(c)
        dlam_dP = E[m].T @ Jc                                        # (n_meas, 6)
        P = c.as_array()
        sens.append(dlam_dP * P[None, :] / (2 * part.eigenvalues[:, None]))
        labels += [f"{fm.material_names[m]}.{n}" for n in CONSTANT_NAMES]
    lo, hi = plate.bounds()
    A, b = plate.linear_constraints()
    hit = [f"{plate.labels[i]} at its {'lower' if abs(x[i] - lo[i]) < abs(x[i] - hi[i]) else 'upper'} bound"
           for i in range(plate.n_vars)
           if min(abs(x[i] - lo[i]), abs(x[i] - hi[i])) <= 1e-6 * max(1.0, abs(x[i]))]
    active = np.flatnonzero(A @ x - b > -1e-7) if A.shape[0] else []
    held = [f"{p.name}: {lab}" for p in plate.params for lab in p.constraint_labels()]
    hit += [held[int(j)] for j in active]
    if hit:
        warnings = list(warnings) + [f"the optimum runs into a bound: {'; '.join(hit)}"]
    lam = fm.laminate.with_constants(constants)
    bases = prob.last_basis if prob.single else (prob.last_basis or [None] * len(prob.plates))
    return Identification(
        specimen=fm.specimen, material_names=fm.material_names, initial=fm.initial_constants,
        constants=constants, free={p.name: tuple(p.free) for p in plate.params},
        parametrization={p.name: p.kind for p in plate.params}, variable_labels=plate.labels,
        x=x, objective=ev.objective if prob.single else part.objective,
        evaluations=prob.n_eval, converged=bool(converged),
        status=status, time_s=dt, measured_hz=plate.data.freq, weight=plate.data.weight,
        model_hz=f_model, pairing=part.pairing, residual_percent=residual,
        rms_residual_percent=weighted_rms(residual, plate.data.weight),
        initial_rms_residual_percent=initial_rms, modes=part.modes, phi_paired=part.phi,
        dlam_dx=part.dlam_dx, sensitivity=np.hstack(sens), sensitivity_labels=tuple(labels),
        history=history_arrays(prob.log.plate_history[k]),
        swaps=tuple(prob.log.swaps if prob.single else prob.log.plate_swaps[k]),
        bounds_hit=tuple(hit), warnings=tuple(warnings),
        global_properties=lam.global_properties().as_dict(), options=prob.options,
        error_bound=_error_bound(prob, k, ev), work=dict(work or {}),
        basis=bases if prob.single else bases[k],
        factorization=getattr(fm.factorizer, "name", ""), equations=fm.plate.family)


def _error_bound(prob, k, ev) -> np.ndarray:
    """Relative error bound of plate ``k``'s paired eigenvalues at ``ev`` against the full
    model (0 where the full model was solved there)."""
    n = prob.plates[k].data.n
    if not prob.reduced:
        return np.zeros(n)
    b = prob.bound_at(ev.x)
    return np.full(n, np.nan) if b is None else b.paired[prob.objective.rows[k]:
                                                           prob.objective.rows[k + 1]]
