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

A joint problem is the single-plate problem over a list of plates
(:class:`laminid_cli.identify.Problem`, objective :class:`laminid_cli.objective.Objective`): one
code path, one run log, one optimiser (:func:`laminid_cli.identify.run_optimizer`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from laminid_cli.errors import FitInputError
from laminid_cli.forward import residuals_percent, weighted_rms
from laminid_cli.identify import (Identification, IdentifyOptions, Problem, _result,
                                  history_arrays, run_optimizer, work_since)
from laminid_cli.material import ElasticConstants
from laminid_cli.modal import WORK
from laminid_cli.objective import check_shared_materials  # noqa: F401  (re-exported)


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
    def factorization(self) -> str:
        """How K - sigma M was factorised (as Identification.factorization)."""
        return self.specimens[0].factorization if self.specimens else ""

    @property
    def equations(self) -> str:
        """The plates' equations (as Identification.equations): 'all', 'bending', or e.g.
        'bending, all' where the plates differ (in their order of first appearance)."""
        seen = []
        for r in self.specimens:
            if r.equations not in seen:
                seen.append(r.equations)
        return ", ".join(seen)

    @property
    def specimen_names(self) -> tuple[str, ...]:
        return unique_names([r.specimen.name for r in self.specimens])


def same_plate_data(a, b) -> bool:
    """True when specimens ``a`` and ``b`` (laminid_cli.specimen.Specimen) hold the data of
    one plate: the same measured frequencies, bit for bit (NaN for the same missing modes), and
    the same geometry a, b, h, mass, boundary and plies (material, angle, thickness).

    Names, descriptions, comments, weights, sigmas, damping and initial constants are not
    compared: a copy of a file with those edited is still the same measurement. Two different
    plates, even cut from one panel with one layup, do not give the same measured frequencies
    to every recorded digit (thickness, density and fibre content scatter shift them far more
    than the last digit), so equal frequencies with equal geometry and layup mean one plate's
    data given twice. A specimen without measured frequencies is never taken for a copy.
    """
    ma, mb = a.measured, b.measured
    if ma is None or mb is None or ma.freq.shape != mb.freq.shape:
        return False
    return (bool(np.array_equal(ma.freq, mb.freq, equal_nan=True))
            and (a.a, a.b, a.h, a.mass, a.boundary) == (b.a, b.b, b.h, b.mass, b.boundary)
            and tuple(a.plies) == tuple(b.plies))


def check_distinct_plates(specimens) -> None:
    """Refuse one plate's data given twice to a joint identification (two files that are
    copies, :func:`same_plate_data`): counted twice, its modes would weigh double and narrow
    every interval by sqrt(2). FitInputError naming both files."""
    specimens = list(specimens)
    for j, b in enumerate(specimens):
        for a in specimens[:j]:
            if same_plate_data(a, b):
                raise FitInputError(
                    f"{b.path}: the same plate data as {a.path} (the same measured frequencies, "
                    "geometry, mass and layup; a copy under another name?): a plate measured "
                    "once counts once in a joint identification (twice would narrow the "
                    "intervals by sqrt(2)); give each plate's file once")


def unique_names(names) -> tuple[str, ...]:
    """Specimen names made unique with a suffix (two files may carry the same name)."""
    seen: dict[str, int] = {}
    out = []
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f"{n}#{seen[n]}")
    return tuple(out)


class JointProblem(Problem):
    """The :class:`laminid_cli.identify.Problem` of two or more plates that share a material
    (the same code path as one plate): variables of every distinct material once, stacked
    eigenvalues, weights and ``dlam_dx`` over the plates' measured modes."""

    def __init__(self, fms, options: IdentifyOptions, *, start=None, start_pairing=None,
                 basis=None, prior_shift=None):
        fms = tuple(fms)
        if len(fms) < 2:
            raise FitInputError("joint identification needs two or more specimens")
        specimens = [fm.specimen for fm in fms]
        check_shared_materials(specimens)
        counts: dict[str, int] = {}
        for spec in specimens:
            for name in spec.materials:
                counts[name] = counts.get(name, 0) + 1
        if not any(c > 1 for c in counts.values()):
            raise FitInputError("joint identification: the specimens share no material (names: "
                                + ", ".join(counts) + "); identify them separately")
        super().__init__(fms, options, start=start, start_pairing=start_pairing, basis=basis,
                         prior_shift=prior_shift)


def identify_joint(fms, options: IdentifyOptions = IdentifyOptions(), progress=None, *,
                   start=None, start_pairing=None, basis=None,
                   prior_shift=None) -> JointIdentification:
    """Identify one set of constants per material from several plates at once.

    ``fms``: ForwardModels of the plates (same mesh advised). ``progress(evaluation, objective,
    rms_percent)`` after each evaluation. ``start``: constants per distinct material (in
    first-appearance order) to start from; ``start_pairing``: one pairing array per plate.
    Raises FitInputError for inconsistent shared materials (see
    :func:`check_shared_materials`).
    """
    t0 = time.perf_counter()
    work0 = dict(WORK)
    prob = JointProblem(fms, options, start=start, start_pairing=start_pairing, basis=basis,
                        prior_shift=prior_shift)
    ev, converged, status, warnings, initial_rms = run_optimizer(prob, progress)
    work = work_since(work0, prob)
    dt = time.perf_counter() - t0
    per_plate = [_result(prob, k, ev, converged, status, [],
                         prob.log.plate_history[k][0].rms_residual_percent, dt)
                 for k in range(len(prob.plates))]
    swaps = tuple(prob.log.swaps)
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
        merged_fixed=dict(prob.merged_fixed), options=prob.options, work=work,
        basis=prob.last_basis if prob.options.solver == "reduced" else None)
