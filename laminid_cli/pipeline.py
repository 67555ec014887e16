"""One identification, from specimen files to a result file: the pipeline of ``laminid
identify`` and of every specimen of ``laminid batch``.

    specimens -> forward models (mesh)
      -> identify / identify_joint with the uncertainty assessment
         (laminid_cli.uncertainty.assess: --fix-undetermined re-runs, Monte Carlo)
      -> status (laminid_cli.status)
      -> loss factors, for one plate with measured damping (laminid_cli.damping)
      -> summary (plain data, SI: what ``identify --json`` prints)
      -> result file, written atomically (laminid_cli.results)

:func:`run_identification` does everything up to the summary and returns an
:class:`IdentificationRun`; :func:`write_result` writes its file. Neither echoes nor exits:
``identify`` prints the summary, ``batch`` sends the file's bytes to its client.

The settings are one :class:`RunOptions`: the mesh, :class:`laminid_cli.identify.IdentifyOptions`,
:class:`laminid_cli.uncertainty.UncertaintyOptions` and the loss factors held by ``--fix``
(``batch`` uses them as they are: laminid_cli.batch.BatchOptions).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from laminid_cli.errors import FitInputError
from laminid_cli.identify import IdentifyOptions
from laminid_cli.uncertainty import UncertaintyOptions


@dataclass(frozen=True)
class RunOptions:
    """Settings of one identification run.

    mesh : "NXxNY" elements (laminid_cli.fe.mesh.parse_mesh)
    identify : the optimisation (its ``fix`` holds the elastic constants fixed by ``--fix``)
    uncertainty : intervals, --fix-undetermined, Monte Carlo
    fix_loss : loss factors held by ``--fix``, e.g. ("carbon.eta13=0.01",)
    mesh_check : after the identification, compare with a mesh twice as fine
        (laminid_cli.meshcheck; one plate only)
    """

    mesh: str = "12x12"
    identify: IdentifyOptions = IdentifyOptions()
    uncertainty: UncertaintyOptions = UncertaintyOptions()
    fix_loss: tuple[str, ...] = ()
    mesh_check: bool = False

    @classmethod
    def with_fix(cls, fix="", **kw) -> "RunOptions":
        """Options whose ``--fix`` list (a comma-separated string or items, elastic constants
        and loss factors mixed) is split between ``identify.fix`` and ``fix_loss``; ``kw`` as
        the fields (``identify`` without its fix)."""
        items = fix.split(",") if isinstance(fix, str) else list(fix)
        if any(item.strip() for item in items):
            from laminid_cli.damping import split_fix

            elastic, loss = split_fix(items)
        else:                              # nothing fixed: no need of the damping module
            elastic, loss = (), ()
        identify = kw.pop("identify", IdentifyOptions())
        return cls(identify=dataclasses.replace(identify, fix=elastic), fix_loss=loss, **kw)

    @property
    def fix(self) -> tuple[str, ...]:
        """All ``--fix`` items: the elastic constants, then the loss factors."""
        return tuple(self.identify.fix) + tuple(self.fix_loss)

    def check(self, copies: int = 1, plates: int = 1) -> tuple[int, int]:
        """Refuse bad settings before any work (a one-line LaminidError, exit code 2): the mesh
        (``copies`` models in memory at once, one per worker), --mesh-check with ``plates``
        identified jointly, the frequency sigma and the interval threshold. Returns the mesh
        (nx, ny)."""
        from laminid_cli.fe.mesh import monte_carlo_factors, parse_mesh
        from laminid_cli.intervals import WEAK
        from laminid_cli.uncertainty import check_sigma_rel

        u = self.uncertainty
        if u.monte_carlo > 0:       # its trial model keeps factorisations; its workers add theirs
            nxny = parse_mesh(self.mesh, copies=copies, factors=monte_carlo_factors(u.jobs),
                              what=" with the Monte Carlo trials")
        else:
            nxny = parse_mesh(self.mesh, copies=copies)
        if self.mesh_check and plates > 1:
            raise FitInputError("--mesh-check checks one plate's identification, not a joint "
                                "one: run laminid identify SPEC --mesh-check on each specimen, "
                                "then identify jointly on the mesh it asks for")
        if self.mesh_check:
            from laminid_cli.meshcheck import fine_mesh_size

            fx, fy = fine_mesh_size(nxny)
            parse_mesh(f"{fx}x{fy}", what=f" for --mesh-check (twice as fine as {self.mesh})")
        check_sigma_rel(u.sigma_rel)
        if not 0 < u.max_rel_interval <= WEAK:
            raise FitInputError(f"--max-rel-interval must be above 0 and at most {WEAK:g} "
                                f"(0.3 = 30 %: a wider interval's verdict is 'not determined', "
                                f"always flagged), got {u.max_rel_interval:g}")
        return nxny

    def check_fix(self, where: str = "the specimen file") -> None:
        """Refuse the --fix items that are wrong whatever the specimen (an unknown constant or
        loss factor, a bad value, one loss factor given two values) before any work: batch
        would otherwise fail every specimen on them, and identify would take a mistyped
        option for a failing specimen and set its earlier result aside. ``where`` names the
        specimen file(s) in the messages. A material named by an item is checked per
        specimen."""
        from laminid_cli.identify import _parse_fix

        def named(items):                 # the materials the items name ("carbon.G13")
            return {i.split("=", 1)[0].strip().rsplit(".", 1)[0]
                    for i in items if "." in i.split("=", 1)[0]}
        # the "<every material>" stands for a specimen's materials that no item names
        _parse_fix(self.identify.fix, tuple(named(self.identify.fix)) + ("<every material>",),
                   where)
        if self.fix_loss:                 # (no loss factor fixed: no need of the damping module)
            from laminid_cli.damping import parse_loss_fix

            parse_loss_fix(self.fix_loss, tuple(named(self.fix_loss)) + ("<every material>",))

    def as_dict(self) -> dict:
        """Every setting as JSON-safe plain data (lists for tuples): the batch's input hash and
        summary. A field added to IdentifyOptions or UncertaintyOptions is in it at once."""
        return json.loads(json.dumps({
            "mesh": self.mesh, "fix": list(self.fix),
            "identify": dataclasses.asdict(self.identify),
            "uncertainty": dataclasses.asdict(self.uncertainty),
            "fix_loss": list(self.fix_loss), "mesh_check": bool(self.mesh_check)},
            default=str))


@dataclass(frozen=True)
class IdentificationRun:
    """What :func:`run_identification` made.

    forward_models : one per plate; assessment : laminid_cli.uncertainty.Assessment (its
    ``result`` the final Identification or JointIdentification); status :
    laminid_cli.status.ResultStatus; damping : laminid_cli.damping.DampingFit or None;
    summary : plain data, SI (``identify --json``); notes : things the user should be told
    (one line each, e.g. measured damping not used by a joint fit); mesh_check :
    laminid_cli.meshcheck.MeshCheck with ``RunOptions.mesh_check``, else None
    """

    options: RunOptions
    forward_models: tuple
    assessment: object
    status: object
    damping: object | None
    summary: dict = field(repr=False)
    notes: tuple[str, ...] = ()
    mesh_check: object | None = None

    @property
    def joint(self) -> bool:
        return len(self.forward_models) > 1

    @property
    def result(self):
        return self.assessment.result

    @property
    def converged(self) -> bool:
        return bool(self.result.converged)


def run_identification(specimens, options: RunOptions = RunOptions(), *, progress=None,
                       mc_progress=None, profile_progress=None, stage_progress=None,
                       loss_fix_needs_damping: bool = True
                       ) -> IdentificationRun:
    """Identify the plate of one specimen, or the plates of several jointly (one set of
    constants per shared material), with the uncertainty assessment, the status and, for one
    plate with measured damping, the loss factors.

    Parameters
    ----------
    specimens : specimen files (or laminid_cli.specimen.Specimen objects); two or more make a
        joint identification
    options : RunOptions
    progress : ``progress(n, objective, rms_percent)`` after each model evaluation;
        mc_progress : ``mc_progress(done, total)`` after each Monte Carlo trial;
        profile_progress : ``profile_progress(done, total, label)`` after each profile of a
        constant on a search limit; stage_progress : ``stage_progress(text)`` before a
        step that reports no progress of its own (the mesh check's solve on the finer mesh,
        the linearised intervals, an identification again: evaluation lines follow) and at
        each fit of a profile (laminid_cli.uncertainty.assess)
    loss_fix_needs_damping : a loss factor in ``options.fix_loss`` for a specimen without
        measured damping is an error (``identify``); False ignores it there (``batch``, where
        one --fix serves specimens with and without damping). Bad names or values are always
        errors.

    Raises
    ------
    LaminidError
        Bad specimen, options or start (before the fit), solver failure. A run that does not
        converge is not an error: ``converged`` is False and the status says so.
    """
    from laminid_cli.forward import bending_model, build_forward_model
    from laminid_cli.results import (identification_summary, joint_identification_summary,
                                     status_of, uncertainty_summary)
    from laminid_cli.specimen import read_specimen
    from laminid_cli.uncertainty import assess

    specimens = list(specimens)
    if not specimens:
        raise FitInputError("no specimen to identify")
    joint = len(specimens) > 1
    nxny = options.check(plates=len(specimens))
    specimens = [read_specimen(s) if isinstance(s, (str, Path)) else s for s in specimens]
    if joint:
        from laminid_cli.joint import check_distinct_plates

        check_distinct_plates(specimens)    # a copy of one file under another name
    # a symmetric laminate is identified on its bending equations alone when its membrane
    # modes lie well above the measured ones (forward.bending_model; checked at the answer)
    fms = tuple(bending_model(build_forward_model(sp, nxny)) for sp in specimens)
    if options.fix_loss:
        from laminid_cli.damping import check_loss_fix, parse_loss_fix

        if loss_fix_needs_damping or joint:
            check_loss_fix(options.fix_loss, fms, joint)
        else:
            parse_loss_fix(options.fix_loss, fms[0].material_names)

    low: list[str] = []

    def bending_holds(result, fms=fms) -> bool:     # asked by assess of its final result
        low[:] = _membrane_in_band(fms, result)
        return not low

    def run(fms, accept=None):
        return assess(list(fms) if joint else fms[0], options.identify, options.uncertainty,
                      joint=joint, progress=progress, mc_progress=mc_progress, accept=accept,
                      profile_progress=profile_progress, stage_progress=stage_progress)

    a = run(fms, bending_holds)
    notes = []
    if low:
        # a membrane mode came below the model's highest mode at the answer: the bending
        # equations alone are not the plate any more; identified again on the whole plate
        fms = tuple(fm.whole if fm.whole is not None else fm for fm in fms)
        notes.append("; ".join(low) + ": identified on the whole plate's equations")
        if stage_progress is not None:
            stage_progress("again on the whole plate's equations")
        a = run(fms)
    result = a.result
    summary = joint_identification_summary(result) if joint else identification_summary(result)
    summary["mesh"] = {"nx": fms[0].mesh_size[0], "ny": fms[0].mesh_size[1]}
    summary["uncertainty"] = uncertainty_summary(a)
    from laminid_cli.global_uncertainty import global_intervals

    shared = dict(zip(result.material_names, result.constants))
    for k, fm in enumerate(fms):
        # the laminate's global properties with their doubt (one block per plate when joint)
        gu = {key: gi.as_dict() for key, gi in global_intervals(
            fm.laminate, {n: shared[n] for n in fm.material_names}, a.uncertainty,
            a.fixed_undetermined, a.before_fixing, a.monte_carlo).items()}
        if joint:
            list(summary["specimens"].values())[k]["global_uncertainty"] = gu
        else:
            summary["global_uncertainty"] = gu
    damping = None
    if not joint and _has_damping(specimens[0]):
        from laminid_cli.damping import damping_of

        damping = damping_of(fms[0], a, fix=options.fix_loss)
    elif joint and any(_has_damping(sp) for sp in specimens):
        notes.append("the measured damping is not used with --joint (identify each plate "
                     "alone for its loss factors)")
    if damping is not None:
        summary["damping"] = damping.as_dict()
    mesh_check = None
    if options.mesh_check:
        from laminid_cli.meshcheck import check_mesh, fine_mesh_size

        if stage_progress is not None:      # (S1.1 at 24x24: 11.6 s, with nothing said)
            fx, fy = fine_mesh_size(nxny)
            stage_progress(f"mesh check: the identified constants on {fx}x{fy}")
        mesh_check = check_mesh(fms[0], a)
    summary["mesh_check"] = None if mesh_check is None else mesh_check.as_dict()
    status = status_of(result, a, damping, mesh_check)
    summary.update(status.as_dict())
    if notes:
        summary["notes"] = list(notes)
    from laminid_cli.units import json_units

    summary["units"] = json_units(summary)
    return IdentificationRun(options=options, forward_models=fms, assessment=a, status=status,
                             damping=damping, summary=summary, notes=tuple(notes),
                             mesh_check=mesh_check)


def _membrane_in_band(fms, result) -> list[str]:
    """The plates identified on their bending equations alone (forward.bending_model) whose
    lowest membrane mode, at the identified constants, is not above the model's highest mode,
    or could not be computed (one line each; empty when none)."""
    from laminid_cli.errors import SolverError
    from laminid_cli.forward import membrane_floor_bound_hz, membrane_floor_hz

    plates = result.specimens if hasattr(result, "specimens") else [result]
    out = []
    for fm, plate in zip(fms, plates):
        if fm.whole is None:
            continue
        top = float(np.max(plate.modes.freq))
        if membrane_floor_bound_hz(fm, plate.constants) > top:
            continue                    # decided by the floor at the start (no solve)
        try:
            floor = membrane_floor_hz(fm, plate.constants)
        except SolverError as exc:
            out.append(f"{fm.specimen.name}: the membrane modes at the answer not computed "
                       f"({exc})")
            continue
        if not floor > top:
            out.append(f"{fm.specimen.name}: a membrane mode at {floor:.1f} Hz, below the "
                       f"model's mode at {top:.1f} Hz")
    return out


def _has_damping(specimen) -> bool:
    """Whether a specimen gives measured damping (the loss factors need it)."""
    return specimen.measured is not None and specimen.measured.damping is not None


def write_result(path, run: IdentificationRun, *, command: str | None = None,
                 attrs: dict | None = None) -> Path:
    """Write the result file of a run (format "laminid-result", or "laminid-joint-result" for a
    joint run; layout in laminid_cli.results), atomically: it appears at ``path`` complete or
    not at all.

    command : the root attribute ``command`` [default "laminid identify", "laminid identify
    --joint"]; attrs : extra root attributes (batch: its input hash, name and options); the
    run's notes, if any, go to the root attribute ``notes`` (one string, "; " between them)
    """
    from laminid_cli.results import write_identification_file, write_joint_identification_file

    path = Path(path)
    if run.notes:                            # e.g. identified again on the whole plate
        attrs = {**(attrs or {}), "notes": "; ".join(run.notes)}
    if run.joint:
        write_joint_identification_file(
            path, list(run.forward_models), run.result, run.summary, assessment=run.assessment,
            command=command or "laminid identify --joint", status=run.status, attrs=attrs)
    else:
        write_identification_file(
            path, run.forward_models[0], run.result, run.summary,
            command=command or "laminid identify", assessment=run.assessment,
            damping=run.damping, status=run.status, attrs=attrs, mesh_check=run.mesh_check)
    return path


def fix_list_hint(name: str) -> str:
    """What to add to "file not found" for a file named on the command line that reads as
    --fix items: ``--fix G13 G23`` or ``--fix G13, G23`` (the shell splits the list at the
    space, and the second part is taken for a specimen file; identify then asked for --joint).
    Empty for any other name.

    >>> fix_list_hint("G23").startswith("; it reads as a --fix item: --fix takes one comma-")
    True
    >>> fix_list_hint("plate.yaml")
    ''
    """
    from laminid_cli.damping import LOSS_NAMES
    from laminid_cli.material import CONSTANT_NAMES

    names = {n.lower() for n in CONSTANT_NAMES + LOSS_NAMES}
    items = [i.strip() for i in str(name).split(",") if i.strip()]
    if not items or not all(i.split("=", 1)[0].rsplit(".", 1)[-1].strip().lower() in names
                            for i in items):
        return ""
    return ("; it reads as a --fix item: --fix takes one comma-separated list without spaces "
            "(--fix G13,G23)")
