"""``laminid identify``: elastic constants from measured natural frequencies."""

from __future__ import annotations

from pathlib import Path

import click

from laminid_cli.commands._common import (OUTPUT_FILE, InputFile, echo_json, fit_options,
                                          force_option, json_option, pass_run_options, quiet,
                                          result_output, stderr_is_terminal,
                                          uncertainty_options)
from laminid_cli.commands.text import (format_damping, format_identify_report,
                                       format_joint_report)


def default_output(spec: str) -> Path:
    p = Path(spec)
    return p.with_name(p.stem + ".result.h5")


def default_joint_output(specs) -> Path:
    """First specimen's folder, ``<stem1>+<stem2>+....joint.result.h5``."""
    first = Path(specs[0])
    return first.with_name("+".join(Path(s).stem for s in specs) + ".joint.result.h5")


def logged_specimen_warnings(forward_models, joint: bool) -> set[str]:
    """The specimen reader's warnings (logged as it read each file) as the result's warnings
    hold them: a joint result's prefixed with the plate's name
    (laminid_cli.identify.Problem.check_start)."""
    return {f"{fm.specimen.name}: {w}" if joint else w
            for fm in forward_models for w in fm.specimen.warnings}


def batch_hint(folder: Path) -> str:
    """What identify says of a folder given as SPEC: batch is the command for a folder of
    specimen files (searched as batch does, in its subfolders too); of one without any, that
    it holds none, and the result or FRF files it holds with the command that takes them (it
    named batch, which then found no specimen file)."""
    import shlex

    from laminid_cli.commands._common import FRF_PATTERNS, files_hint
    from laminid_cli.commands.show import results_hint

    if any(p.is_file() and not any(part.startswith(".") for part in p.relative_to(folder).parts)
           for pattern in ("*.yaml", "*.yml") for p in folder.rglob(pattern)):
        return (f"; 'laminid batch {shlex.quote(str(folder))}' identifies every specimen in a "
                "folder")
    held = [h.removeprefix("; it holds ") for h in
            (results_hint(folder), files_hint("fit-frf", FRF_PATTERNS, "FRF file")(folder)) if h]
    return "; it holds no specimen file (*.yaml, *.yml)" + (
        " but " + "; and ".join(held) if held else "")


@click.command(short_help="Identify ply elastic constants from measured frequencies.")
@click.argument("specs", nargs=-1, required=True, type=InputFile(folder_hint=batch_hint),
                metavar="SPEC...")
@fit_options
@click.option("--joint", is_flag=True,
              help="Identify several SPECs together: one set of constants for each material "
                   "they share (same name, same initial constants), each plate with its own "
                   "geometry, mass and frequencies.")
@uncertainty_options
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Processes for the Monte Carlo trials (--monte-carlo) and for the "
                   "profiles of the constants that stop on a search limit (one constant "
                   "each; on Linux, elsewhere they run one after the other); the results do "
                   "not depend on it [default: the number of cores].")
@json_option
@click.option("-o", "--output", type=OUTPUT_FILE, default=None,
              help="HDF5 result file, never overwritten without --force [default: SPEC's "
                   "folder, <name>.result.h5; with --joint the first SPEC's folder, "
                   "<name1>+<name2>+....joint.result.h5; a derived file, replaced by each "
                   "run].")
@click.option("--no-output", is_flag=True, help="Do not write a result file.")
@click.option("--mesh-check", is_flag=True,
              help="After the identification, solve the model on a mesh twice as fine (12x12: "
                   "24x24; about 1 s more for S1.1) at the identified constants and report per "
                   "mode the frequency change (percent, and in units of the mode's frequency "
                   "sigma) and the constants' first-order shift there (percent, and in units "
                   "of their 95 % half-width); a shift beyond 0.3 half-width makes the status "
                   "'check' (coarse_mesh). One plate only (not with --joint).")
@force_option
@pass_run_options(monte_carlo_jobs="jobs")
def identify(specs, options, joint, jobs, as_json, output, no_output, force, mesh_check):
    """Identify E1, E2, G12, G13, G23 and nu12 of every ply material of the plate in SPEC by
    fitting the free-plate finite-element model to the measured frequencies (paper Eq. 17,
    weights from the file), with analytic sensitivities and constrained optimisation. With
    --joint, several plates sharing a material are fitted together.

    The report gives the identified constants beside the initial and reference values with
    their 95 % confidence intervals and a verdict (well determined / weak / not determined),
    measured vs model frequencies with residuals (measured - model)/measured*100, the global
    laminate properties, the correlation of the constants and the normalised sensitivities
    d ln f / d ln P of each mode. Frequency uncertainties come from the file's measured.sigma,
    or the RFP fit of its measured.frf_file, else --sigma-rel. Every result has a status: ok, or check with the reasons (a constant at
    its bound or undetermined, a fit worse than the stated noise, implausible values, modes
    swapped). Exit code 0 when converged (also with status check), 1 when not, 2 for bad
    input.

    Run it again after editing SPEC: the default result file beside SPEC is derived from it
    and is replaced (the output says so); a file named with -o is kept unless --force. When
    SPEC now fails, its earlier default result is renamed <name>.result.stale.h5 (.stale1.h5,
    ... when that exists), out of the *.result.h5 pattern, as batch does.

    A symmetric laminate is fitted on its bending equations alone (its bending modes are the
    same), where its membrane modes lie well above the measured ones; the run line and the
    result ('equations') say so, and a membrane mode reaching the model's modes sends the fit
    back to the whole plate.

    When the specimen has measured damping (measured.damping, or an frf_file), the loss factors
    eta11, eta22, eta12, eta13, eta23 of each ply material follow from the modal loss factors
    2 zeta by the modal strain energy method, with intervals and verdicts; --fix holds them too
    (--fix eta13=0.01,eta23=0.01 or carbon.eta13=0.01).

    \b
    Examples:
      laminid identify specimens/example1/S1.1.yaml
      laminid identify plate.yaml --fix nu12,G13,G23 --json
      laminid identify plate.yaml --optimizer mma -o plate-result.h5 --force
      laminid identify plate.yaml --fix-undetermined --monte-carlo 200
      laminid identify plate.yaml --fix eta13=0.01,eta23=0.01
      laminid identify plate.yaml --mesh-check
      laminid identify S1.1.yaml S1.2.yaml S1.3.yaml S1.4.yaml --joint
    """
    import dataclasses
    import sys

    from laminid_cli.errors import (FitInputError, InputFileError, LaminidError, SpecimenError,
                                    escaped)
    from laminid_cli.pipeline import fix_list_hint, run_identification, write_result

    if no_output and output is not None:
        raise FitInputError("--no-output and -o contradict each other: give one of them")
    for sp in specs:
        # a file that is not there: said before the count of specimens, which would ask for
        # --joint where the second "specimen" is the rest of a --fix list split at a space
        if not Path(sp).exists() and (len(specs) > 1 or fix_list_hint(sp)):
            raise InputFileError(f"{sp}: file not found{fix_list_hint(sp)}", path=sp)
        # and before the output is looked at: /nope/x.yaml was "/nope/x.result.h5: folder
        # /nope does not exist", and a mistyped path set the earlier default result of that
        # name aside as another input's (a path is no specimen that now fails)
        if not Path(sp).exists():
            raise SpecimenError("file not found", path=sp)
    if len(specs) > 1 and not joint:
        raise FitInputError(f"{len(specs)} specimens given: add --joint to identify them "
                            "together (one set of constants per shared material)")
    if joint and len(specs) < 2:
        raise FitInputError("--joint needs two or more specimen files")
    options = dataclasses.replace(options, mesh_check=mesh_check)
    seen: dict = {}
    for sp in specs:
        key = Path(sp).resolve()
        if key in seen:
            raise FitInputError(f"{sp}: the same specimen file as {seen[key]}: a plate measured "
                                "once counts once (twice would narrow the intervals by "
                                "sqrt(2))")
        seen[key] = sp
    options.check(plates=len(specs))
    # a mistyped --fix is a usage error, refused before any work (and before the default
    # result of the specimen could be taken for an earlier input's and set aside below)
    options.check_fix(", ".join(str(sp) for sp in specs))
    default = default_joint_output(specs) if joint else default_output(specs[0])
    out, replacing = ((None, False) if no_output else
                      result_output(output, default, force, None if joint else specs[0],
                                    inputs=specs))
    show_progress = not as_json and stderr_is_terminal() and not quiet()

    # the step under way (laminid_cli.uncertainty.assess: "run 2, G13 fixed as undetermined"),
    # named on the evaluation lines of an identification again
    phase = [""]

    def progress(n, objective, rms):
        if show_progress and phase[0]:
            click.echo("\r" + f"  {phase[0]}: evaluation {n:>4}, RMS {rms:.4f} %".ljust(78),
                       err=True, nl=False)
        elif show_progress:
            click.echo(f"\r  evaluation {n:>4}: objective {objective:10.4g}, RMS residual "
                       f"{rms:8.4f} %".ljust(78), err=True, nl=False)

    bar = None
    last = [0]

    def mc_progress(done, total):
        nonlocal bar
        if not show_progress:
            return
        if bar is not None and done <= last[0]:
            # another Monte Carlo (--fix-undetermined: one holding the fixed values, whose
            # flags decide what to fix, then the one shown, drawing them): a bar of its own
            bar.__exit__(None, None, None)
            bar = None
        if bar is None:
            click.echo("", err=True)
            # trials k/N beside the percentage (the bar alone said 5 % steps of 20 trials)
            bar = click.progressbar(length=total, label="Monte Carlo trials", file=sys.stderr,
                                    show_pos=True)
            bar.__enter__()
            last[0] = 0
        bar.update(done - last[0])          # (a chunk of trials at a time)
        last[0] = done

    def profile_progress(done, total, label):
        # the profiles of constants on a search limit (a few to 10 s each): which finished
        if show_progress:
            line = (f"  profiles of the constants on a search limit: {done} of {total} done"
                    + (f" ({label})" if label else ""))
            click.echo("\r" + line.ljust(78), err=True, nl=False)

    def stage_progress(text):
        # a step with no progress of its own: the mesh check's finer mesh (S1.1 at 24x24:
        # 11.6 s under the last "evaluation" line, which looked stuck), the linearised
        # intervals, --fix-undetermined's runs and checks, each fit of a profile (hybrid CM's
        # first profile: 2.4 s at "0 of 5 done")
        nonlocal bar
        phase[0] = text
        if not show_progress:
            return
        if bar is not None:
            # the Monte Carlo's bar is finished: kept on its line, the step on the next
            bar.__exit__(None, None, None)
            bar = None
        click.echo("\r" + escaped(f"  {text}").ljust(78), err=True, nl=False)

    try:
        run = run_identification(specs, options, progress=progress, mc_progress=mc_progress,
                                 profile_progress=profile_progress,
                                 stage_progress=stage_progress)
    except LaminidError as exc:
        if replacing and not isinstance(exc, FitInputError):
            # this input fails, so the default result beside it is an earlier input's: set
            # aside out of the *.result.h5 pattern, as batch does (a file named with -o is the
            # user's, and left alone). Not for options that do not fit the specimen (--fix of
            # a material it does not have, every constant fixed, one plate given twice): a
            # mistyped command is not a new input, its earlier result stays
            from laminid_cli.batch import set_aside

            moved, why = set_aside(out)
            if show_progress:
                click.echo("", err=True)
            click.echo(escaped(f"laminid: {out}: the earlier result of another input " + (
                f"moved to {moved}" if moved is not None else f"left in place ({why})")),
                err=True)
        raise
    except KeyboardInterrupt:
        # (before "laminid: interrupted"): the result is written whole at the end, so a Ctrl-C
        # during the Monte Carlo or the profiles left no file and said nothing of it
        if show_progress:
            click.echo("", err=True)
        if out is not None:
            click.echo(escaped(f"laminid: nothing written to {out}: the result is written "
                               "when every step has finished"
                               + (" (an earlier result there is left as it was)"
                                  if out.exists() else "")), err=True)
        raise
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    if show_progress:
        click.echo("", err=True)
    for note in run.notes if not quiet() else ():     # -q: only errors on stderr
        click.echo(escaped(f"laminid: note: {note}"), err=True)
    summary = dict(run.summary)
    if out is not None:
        write_result(out, run)
        summary["output"] = str(out)
        summary["output_replaced"] = replacing
    if as_json:
        echo_json(summary)
    else:
        report = summary
        if not quiet():
            # the specimen reader's warnings are on stderr already, written as it read the
            # file (before a run that may take minutes, and also when the run then fails):
            # not again at the report's end. Under -q they were not, so the report keeps them
            logged = logged_specimen_warnings(run.forward_models, joint)
            report = {**summary, "warnings": [w for w in summary.get("warnings", ())
                                              if w not in logged]}
        click.echo(format_joint_report(report) if joint else format_identify_report(report))
        if "damping" in summary:
            click.echo("\n" + "\n".join(format_damping(summary["damping"])))
        if out is not None:
            click.echo(escaped(f"\nwritten: {out}") + (" (replaced the previous result of this "
                                              "specimen: a derived file)" if replacing else ""))
    if not run.converged:
        click.echo(f"laminid: identification did not converge: {run.result.status}", err=True)
        sys.exit(1)
