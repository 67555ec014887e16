"""Joint identification: several plates that share a material, one set of constants.

The paper identifies each of its four IM7/977-2 plates (Example 1) on its own and gets four
different nu12. Different stacking sequences make the frequencies sensitive to different
constants, so fitting all plates at once with one set of constants per material is sharper.

Objective: the sum over the plates of paper Eq. 17, each with its own weights, plus the prior
(Eq. 15) counted once per material::

    Phi(x) = sum_k sum_i w_ki ((lt_ki - l_ki(x)) / lt_ki)^2 + sum_j wp_j ((P_j - P_j0) / P_j0)^2

Materials are shared by *name*: a material of the same name in two files is one set of design
variables. Each plate keeps its own geometry, mass (so its own mass-derived density), layup,
boundary, measured frequencies and mode tracking. A shared material must have the same initial
constants, prior and written ``density``/``density_ratio`` in every file (checked by
:func:`check_shared_materials`); its ``fixed`` lists are merged. Densities derived from each
plate's measured mass are per plate by design.

Each plate's part of the problem is a :class:`laminid_cli.identify.Problem`; the optimiser
(:func:`laminid_cli.identify.run_optimizer`) sees a :class:`JointProblem` with the same
interface.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from laminid_cli.errors import FitInputError
from laminid_cli.forward import residuals_percent, weighted_rms
from laminid_cli.identify import (Evaluation, HistoryRow, Identification, IdentifyOptions,
                                  Problem, history_arrays,
                                  VariableSet, refused_evaluation,
                                  _result, run_optimizer, work_since)
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants
from laminid_cli.modal import WORK


@dataclass(frozen=True)
class JointIdentification:
    """Result of :func:`identify_joint`: shared constants and one Identification per plate.

    ``material_names`` lists every material once (first appearance order); ``specimens[k]`` is
    the k-th plate's result in the usual form (its materials in its own order; its
    ``objective`` is its own part of the joint objective, its ``evaluations`` the joint count).
    """

    material_names: tuple[str, ...]
    initial: tuple[ElasticConstants, ...]
    constants: tuple[ElasticConstants, ...]
    free: dict
    parametrization: dict
    variable_labels: tuple[str, ...]
    x: np.ndarray
    objective: float
    evaluations: int
    converged: bool
    status: str
    time_s: float
    rms_residual_percent: float
    initial_rms_residual_percent: float
    specimens: tuple[Identification, ...]
    history: dict
    swaps: tuple[str, ...]
    warnings: tuple[str, ...]
    merged_fixed: dict                       # material -> constants fixed in only some files
    options: IdentifyOptions = field(default_factory=IdentifyOptions)
    work: dict = field(default_factory=dict)   # as Identification.work
    basis: object = field(default=None, repr=False, compare=False)   # one per plate

    @property
    def specimen_names(self) -> tuple[str, ...]:
        return unique_names([r.specimen.name for r in self.specimens])


def unique_names(names) -> tuple[str, ...]:
    """Specimen names made unique with a suffix (two files may carry the same name)."""
    seen: dict[str, int] = {}
    out = []
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f"{n}#{seen[n]}")
    return tuple(out)


def check_shared_materials(specimens) -> dict:
    """Refuse shared materials that differ between files; return the merged ``fixed`` lists.

    Raises FitInputError naming both files, the material and the first difference. Returns
    {material: tuple of constants fixed in at least one file}.
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
            for attr, label in (("density", "density"), ("density_ratio", "density_ratio")):
                va, vb = getattr(mat0, attr), getattr(mat, attr)
                if (va is None) != (vb is None) or (va is not None and not np.isclose(va, vb)):
                    raise FitInputError(
                        f"{where}: {label} {_plain(va)} vs {_plain(vb)}; a shared material needs "
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


class JointProblem(VariableSet):
    """Objective, gradient and constraints over several plates with shared materials.

    Same interface as :class:`laminid_cli.identify.Problem` (what ``run_optimizer`` and the
    Gauss-Newton scaling use): variables of every distinct material once, stacked eigenvalues,
    weights and ``dlam_dx`` over the plates' measured modes.
    """

    def __init__(self, fms, options: IdentifyOptions, *, start=None, start_pairing=None,
                 basis=None):
        fms = tuple(fms)
        if len(fms) < 2:
            raise FitInputError("joint identification needs two or more specimens")
        self.fms = fms
        self.options = options
        specimens = [fm.specimen for fm in fms]
        merged = check_shared_materials(specimens)
        counts: dict[str, int] = {}
        for spec in specimens:
            for name in spec.materials:
                counts[name] = counts.get(name, 0) + 1
        if not any(c > 1 for c in counts.values()):
            raise FitInputError("joint identification: the specimens share no material (names: "
                                + ", ".join(counts) + "); identify them separately")
        self.merged_fixed = {n: tuple(k for k in merged[n]
                                      if not all(k in s.materials[n].fixed
                                                 for s in specimens if n in s.materials))
                             for n in merged}
        fix = tuple(options.fix) + tuple(f"{n}.{k}" for n, ks in merged.items() for k in ks)
        sub_options = dataclasses.replace(options, fix=fix)
        self.material_names = tuple(merged)
        self.start = None if start is None else dict(zip(self.material_names, start))
        pairings = [None] * len(fms) if start_pairing is None else list(start_pairing)
        self.subs = []
        for fm, pairing in zip(fms, pairings):
            sub_start = (None if self.start is None
                         else [self.start[n] for n in fm.material_names])
            sub = Problem(fm, sub_options, start=sub_start, start_pairing=pairing,
                          check_count=False)
            sub.prior = [{} for _ in sub.params]      # counted once, at the joint level
            self.subs.append(sub)
        # one parameter object per material (identical in every plate: same inputs)
        owner = {}
        for sub in self.subs:
            for p in sub.params:
                owner.setdefault(p.name, p)
        self.params = [owner[n] for n in self.material_names]
        self.sizes = [len(p.x0()) for p in self.params]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)]).astype(int)
        self.n_vars = int(self.offsets[-1])
        self.labels = tuple(f"{p.name}.{lab}" for p in self.params for lab in p.labels)
        first_mat = {}
        for spec in specimens:
            for name, mat in spec.materials.items():
                first_mat.setdefault(name, mat)
        self.prior = [{k: float(w) for k, w in first_mat[p.name].prior.items()}
                      for p in self.params]
        # global variable index of each plate's variables
        self.index = []
        for sub in self.subs:
            idx = [np.arange(self.offsets[self.material_names.index(p.name)],
                             self.offsets[self.material_names.index(p.name) + 1])
                   for p in sub.params]
            self.index.append(np.concatenate(idx).astype(int))
        self.weight = np.concatenate([s.weight for s in self.subs])
        self.freq = np.concatenate([s.freq for s in self.subs])
        self.lam_meas = np.concatenate([s.lam_meas for s in self.subs])
        self.n_meas = self.freq.size
        n_active = int((self.weight > 0).sum())
        if n_active < self.n_vars and not any(self.prior):
            raise FitInputError(f"joint identification: {n_active} weighted frequencies for "
                                f"{self.n_vars} free constants; measure more modes or fix "
                                "constants (--fix nu12,G13,G23)")
        self.given_basis = None if basis is None else list(basis)
        self._new_run()

    # --- variables (as Problem) ---------------------------------------------------------------
    def x0(self) -> np.ndarray:
        from laminid_cli.identify import variables_of

        if self.start is None:
            return np.concatenate([p.x0() for p in self.params])
        return np.concatenate([variables_of(p, self.start[p.name]) for p in self.params])

    # --- pairing state, for run_optimizer's re-anchoring (as Problem) -----------------------
    def sorted_pairing(self) -> np.ndarray:
        return np.concatenate([sub.sorted_pairing() for sub in self.subs])

    def reanchor(self) -> None:
        for sub in self.subs:
            sub.reanchor()
        self.best, self.cache = None, None

    def adopt(self, ev) -> None:
        for sub, part in zip(self.subs, ev.parts):
            sub.adopt(part)
        self.best, self.cache = ev, (ev.x.tobytes(), ev)

    # --- reduced-order model: one basis per plate (as Problem) ---------------------------------
    @property
    def reduced(self) -> bool:
        return self.subs[0].reduced

    def start_reduced(self, ev, basis=None) -> None:
        parts = ev.parts if ev is not None else [None] * len(self.subs)
        for k, (sub, part) in enumerate(zip(self.subs, parts)):
            sub.start_reduced(part, None if basis is None else basis[k])
        self.cache = None

    @property
    def last_basis(self):
        return [sub.last_basis for sub in self.subs]

    def enrich(self, ev, rounds: int = 2, target: float = 0.0) -> float:
        change = max(sub.enrich(part, rounds, target) for sub, part in zip(self.subs, ev.parts))
        self.n_enrich += 1
        self.cache = None
        bounds = [sub.final_bound for sub in self.subs]
        self.final_bound = (ev.x.tobytes(), np.concatenate([b[1] for b in bounds]),
                            max(b[2] for b in bounds))
        return change

    def bound_at(self, x):
        return Problem.bound_at(self, x)

    def use_full(self) -> None:
        for sub in self.subs:
            sub.use_full()
        self.cache = None

    @property
    def basis(self):
        return [sub.basis for sub in self.subs]

    def describe(self) -> str:
        return "joint identification of " + ", ".join(str(fm.specimen.path) for fm in self.fms)

    def check_start(self, ev) -> list[str]:
        out = []
        for fm, sub in zip(self.fms, self.subs):
            out += [f"{fm.specimen.name}: {w}" for w in sub.check_start(sub.cache[1])]
        return out

    # --- evaluation ------------------------------------------------------------------------------
    def evaluate(self, x) -> Evaluation:
        x = np.asarray(x, float)
        key = x.tobytes()
        if self.cache is not None and self.cache[0] == key:
            return self.cache[1]
        evs = [sub.evaluate(x[idx]) for sub, idx in zip(self.subs, self.index)]
        if any(e.refused for e in evs):
            return refused_evaluation(self, x, ["not positive definite"])
        return self._combine(x, evs)

    def final_check(self, ev):
        """As Problem.final_check, plate by plate."""
        parts = [sub.final_check(part) for sub, part in zip(self.subs, ev.parts)]
        self.cache = None
        out = self._combine(np.asarray(ev.x, float), parts)
        bounds = [sub.final_bound for sub in self.subs]
        self.final_bound = (out.x.tobytes(), np.concatenate([b[1] for b in bounds]),
                            max(b[2] for b in bounds))
        return out

    def _combine(self, x, evs):
        """The joint evaluation from the plates' evaluations at ``x``."""
        key = x.tobytes()
        objective = sum(ev.objective for ev in evs)
        gradient = np.zeros(self.n_vars)
        dlam_dx = np.zeros((self.n_meas, self.n_vars))
        row = 0
        for ev, idx in zip(evs, self.index):
            np.add.at(gradient, idx, ev.gradient)
            dlam_dx[row:row + ev.eigenvalues.size, idx] = ev.dlam_dx
            row += ev.eigenvalues.size
        pv, pg = Problem._prior(self, x)
        lam = np.concatenate([ev.eigenvalues for ev in evs])
        ev = Evaluation(x=x.copy(), objective=objective + pv, gradient=gradient + pg,
                        eigenvalues=lam, pairing=np.concatenate([e.pairing for e in evs]),
                        dlam_dx=dlam_dx, phi=None, modes=None, parts=evs)
        if self.best is None or ev.objective < self.best.objective:
            self.best = ev
        self.cache = (key, ev)
        self.n_eval += 1
        f_model = np.sqrt(lam) / (2 * np.pi)
        rms = weighted_rms(residuals_percent(self.freq, f_model), self.weight)
        self.history.append(HistoryRow(self.n_eval, ev.objective, rms, x.copy(),
                                       np.concatenate([c.as_array() for c in self.constants(x)])))
        return ev


def identify_joint(fms, options: IdentifyOptions = IdentifyOptions(), progress=None, *,
                   start=None, start_pairing=None, basis=None) -> JointIdentification:
    """Identify one set of constants per material from several plates at once.

    ``fms``: ForwardModels of the plates (same mesh advised). ``progress(evaluation, objective,
    rms_percent)`` after each evaluation. ``start``: constants per distinct material (in
    first-appearance order) to start from; ``start_pairing``: one pairing array per plate.
    Raises FitInputError for inconsistent shared materials (see
    :func:`check_shared_materials`).
    """
    t0 = time.perf_counter()
    work0 = dict(WORK)
    prob = JointProblem(fms, options, start=start, start_pairing=start_pairing, basis=basis)
    ev, converged, status, warnings, initial_rms = run_optimizer(prob, progress)
    work = work_since(work0, prob)
    dt = time.perf_counter() - t0
    per_plate = []
    for sub, idx in zip(prob.subs, prob.index):
        sub_ev = sub.evaluate(ev.x[idx])                  # cached: the last joint evaluation
        per_plate.append(_result(sub, sub_ev, converged, status, [], sub.history[0].rms_residual_percent, dt))
    swaps = tuple(f"{r.specimen.name}: {s}" for r in per_plate for s in r.swaps)
    bounds = [f"{r.specimen.name}: {w}" for r in per_plate for w in r.warnings]
    notes = [f"material '{n}': {', '.join(ks)} fixed in some of the files, so fixed in all"
             for n, ks in prob.merged_fixed.items() if ks]
    f_model = np.sqrt(ev.eigenvalues) / (2 * np.pi)
    hist = prob.history
    return JointIdentification(
        material_names=prob.material_names,
        initial=tuple(p.initial for p in prob.params),
        constants=prob.constants(ev.x),
        free={p.name: tuple(p.free) for p in prob.params},
        parametrization={p.name: p.kind for p in prob.params},
        variable_labels=prob.labels, x=ev.x, objective=ev.objective, evaluations=prob.n_eval,
        converged=bool(converged), status=status, time_s=dt,
        rms_residual_percent=weighted_rms(residuals_percent(prob.freq, f_model), prob.weight),
        initial_rms_residual_percent=initial_rms, specimens=tuple(per_plate),
        history=history_arrays(hist),
        swaps=swaps, warnings=tuple(list(warnings) + notes + bounds),
        merged_fixed=dict(prob.merged_fixed), options=options, work=work,
        basis=prob.last_basis if prob.options.solver == "reduced" else None)
