"""``laminid identify``: elastic constants from measured natural frequencies."""

from __future__ import annotations

from pathlib import Path

import click

from laminid_cli.commands._common import (echo_json, fit_options, force_option, json_option,
                                          result_output, uncertainty_options)
from laminid_cli.commands.text import (format_damping, format_identify_report,
                                       format_joint_report)


def default_output(spec: str) -> Path:
    p = Path(spec)
    return p.with_name(p.stem + ".result.h5")


def default_joint_output(specs) -> Path:
    """First specimen's folder, ``<stem1>+<stem2>+....joint.result.h5``."""
    first = Path(specs[0])
    return first.with_name("+".join(Path(s).stem for s in specs) + ".joint.result.h5")


@click.command(short_help="Identify ply elastic constants from measured frequencies.")
@click.argument("specs", nargs=-1, required=True, type=click.Path(dir_okay=False),
                metavar="SPEC...")
@fit_options
@click.option("--joint", is_flag=True,
              help="Identify several SPECs together: one set of constants for each material "
                   "they share (same name, same initial constants), each plate with its own "
                   "geometry, mass and frequencies.")
@uncertainty_options
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Processes for the Monte Carlo trials [default: the number of cores].")
@json_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="HDF5 result file, never overwritten without --force [default: SPEC's "
                   "folder, <name>.result.h5; with --joint the first SPEC's folder, "
                   "<name1>+<name2>+....joint.result.h5; a derived file, replaced by each "
                   "run].")
@click.option("--no-output", is_flag=True, help="Do not write a result file.")
@force_option
def identify(specs, mesh, fix, optimizer, parametrization, xtol, ftol, max_evaluations, pairing,
             solver, joint, sigma_rel, covariance_scale, max_rel_interval, fix_undetermined, monte_carlo,
             seed, jobs, as_json, output, no_output, force):
    """Identify E1, E2, G12, G13, G23 and nu12 of every ply material of the plate in SPEC by
    fitting the free-plate finite-element model to the measured frequencies (paper Eq. 17,
    weights from the file), with analytic sensitivities and constrained optimisation. With
    --joint, several plates sharing a material are fitted together.

    The report gives the identified constants beside the initial and reference values with
    their 95 % confidence intervals and a verdict (well determined / weak / not determined),
    measured vs model frequencies with residuals (measured - model)/measured*100, the global
    laminate properties, the correlation of the constants and the normalised sensitivities
    d ln f / d ln P of each mode. Frequency uncertainties come from the file's measured.sigma,
    else --sigma-rel. Every result has a status: ok, or check with the reasons (a constant at
    its bound or undetermined, a fit worse than the stated noise, implausible values, modes
    swapped). Exit code 0 when converged (also with status check), 1 when not, 2 for bad
    input.

    Run it again after editing SPEC: the default result file beside SPEC is derived from it
    and is replaced (the output says so); a file named with -o is kept unless --force.

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
      laminid identify S1.1.yaml S1.2.yaml S1.3.yaml S1.4.yaml --joint
    """
    import sys

    from laminid_cli.errors import FitInputError
    from laminid_cli.fe.mesh import parse_mesh
    from laminid_cli.forward import build_forward_model
    from laminid_cli.identify import IdentifyOptions
    from laminid_cli.results import (identification_summary, joint_identification_summary,
                                     status_of, uncertainty_summary, write_identification_file,
                                     write_joint_identification_file)
    from laminid_cli.specimen import read_specimen
    from laminid_cli.uncertainty import UncertaintyOptions, assess, check_sigma_rel

    from laminid_cli.damping import check_loss_fix, damping_of, split_fix

    if len(specs) > 1 and not joint:
        raise FitInputError(f"{len(specs)} specimens given: add --joint to identify them "
                            "together (one set of constants per shared material)")
    if joint and len(specs) < 2:
        raise FitInputError("--joint needs two or more specimen files")
    check_sigma_rel(sigma_rel)
    if not max_rel_interval > 0:
        raise FitInputError(f"--max-rel-interval must be positive (0.3 = 30 %), got "
                            f"{max_rel_interval:g}")
    default = default_joint_output(specs) if joint else default_output(specs[0])
    out, replacing = (None, False) if no_output else result_output(output, default, force)
    specimens = [read_specimen(s) for s in specs]
    fix_elastic, fix_loss = split_fix(fix.split(","))
    options = IdentifyOptions(
        fix=fix_elastic, optimizer=optimizer,
        parametrization=parametrization, xtol_rel=xtol, ftol_rel=ftol,
        max_evaluations=max_evaluations, pairing=pairing, solver=solver)
    uopts = UncertaintyOptions(sigma_rel=sigma_rel, scaling=covariance_scale,
                               max_rel_interval=max_rel_interval,
                               fix_undetermined=fix_undetermined, monte_carlo=monte_carlo,
                               jobs=jobs, seed=seed)
    nxny = parse_mesh(mesh)
    fms = [build_forward_model(sp, nxny) for sp in specimens]
    check_loss_fix(fix_loss, fms, joint)
    show_progress = not as_json and sys.stderr.isatty()

    def progress(n, objective, rms):
        if show_progress:
            click.echo(f"\r  evaluation {n:>4}: objective {objective:10.4g}, RMS residual "
                       f"{rms:8.4f} %", err=True, nl=False)

    bar = None

    def mc_progress(done, total):
        nonlocal bar
        if not show_progress:
            return
        if bar is None:
            click.echo("", err=True)
            bar = click.progressbar(length=total, label="Monte Carlo", file=sys.stderr)
            bar.__enter__()
        bar.update(1)

    try:
        a = assess(fms if joint else fms[0], options, uopts, joint=joint, progress=progress,
                   mc_progress=mc_progress)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    result = a.result
    if show_progress:
        click.echo("", err=True)
    if joint:
        summary = joint_identification_summary(result)
    else:
        summary = identification_summary(result)
    summary["mesh"] = {"nx": fms[0].mesh_size[0], "ny": fms[0].mesh_size[1]}
    summary["uncertainty"] = uncertainty_summary(a)
    damping = None if joint else damping_of(fms[0], a, fix=fix_loss)
    if joint and any(sp.measured is not None and sp.measured.damping is not None
                     for sp in specimens):
        click.echo("laminid: note: the measured damping is not used with --joint (identify "
                   "each plate alone for its loss factors)", err=True)
    if damping is not None:
        summary["damping"] = damping.as_dict()
    summary.update(status_of(result, a).as_dict())
    if out is not None:
        if joint:
            write_joint_identification_file(out, fms, result, summary, assessment=a)
        else:
            write_identification_file(out, fms[0], result, summary, assessment=a,
                                      damping=damping)
        summary["output"] = str(out)
        summary["output_replaced"] = replacing
    if as_json:
        echo_json(summary)
    else:
        click.echo(format_joint_report(summary) if joint else format_identify_report(summary))
        if damping is not None:
            click.echo("\n" + "\n".join(format_damping(summary["damping"])))
        if out is not None:
            click.echo(f"\nwritten: {out}" + (" (replaced the previous result of this "
                                              "specimen: a derived file)" if replacing else ""))
    if not result.converged:
        click.echo(f"laminid: identification did not converge: {result.status}", err=True)
        sys.exit(1)
