"""``laminid identify``: elastic constants from measured natural frequencies."""

from __future__ import annotations

from pathlib import Path

import click

from laminid_cli.commands._common import check_output_path, echo_json, force_option, json_option
from laminid_cli.commands.text import format_identify_report


def default_output(spec: str) -> Path:
    p = Path(spec)
    return p.with_name(p.stem + ".result.h5")


@click.command(short_help="Identify ply elastic constants from measured frequencies.")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("--mesh", default="12x12", show_default=True, metavar="NXxNY",
              help="Elements along x (side a) and y (side b); the paper uses 12x12.")
@click.option("--fix", "fix", default="", metavar="LIST",
              help="Constants held at their initial values, comma-separated: nu12,G13,G23 (all "
                   "materials) or glass.nu12 (one material). Adds to 'fixed' in the file.")
@click.option("--optimizer", type=click.Choice(["slsqp", "mma"]), default="slsqp",
              show_default=True, help="nlopt algorithm: LD_SLSQP or LD_MMA.")
@click.option("--parametrization", type=click.Choice(["auto", "alpha", "constants"]),
              default="auto", show_default=True,
              help="Design variables: alpha = paper Eq. 14 (E1/E1_0, a2, a3, a4, a8, a9); "
                   "constants = free constants / initial values; auto = alpha where all six "
                   "constants of a material are free and it has no prior.")
@click.option("--xtol", type=click.FloatRange(min=0, min_open=True), default=1e-6,
              show_default=True, help="Step tolerance on the scaled design variables.")
@click.option("--ftol", type=click.FloatRange(min=0, min_open=True), default=1e-8,
              show_default=True, help="Relative tolerance on the objective.")
@click.option("--max-evaluations", type=click.IntRange(2, 100000), default=300,
              show_default=True, help="Most model evaluations before giving up.")
@click.option("--pairing", type=click.Choice(["track", "sorted"]), default="track",
              show_default=True, help="Mode pairing: sorted order at the start then MAC "
                                      "tracking (track), or sorted order throughout (paper).")
@json_option
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="HDF5 result file [default: SPEC's folder, <name>.result.h5].")
@click.option("--no-output", is_flag=True, help="Do not write a result file.")
@force_option
def identify(spec, mesh, fix, optimizer, parametrization, xtol, ftol, max_evaluations, pairing,
             as_json, output, no_output, force):
    """Identify E1, E2, G12, G13, G23 and nu12 of every ply material of the plate in SPEC by
    fitting the free-plate finite-element model to the measured frequencies (paper Eq. 17,
    weights from the file), with analytic sensitivities and constrained optimisation.

    The report gives the identified constants beside the initial and reference values,
    measured vs model frequencies with residuals (measured - model)/measured*100, and the
    global laminate properties. Exit code 0 when converged, 1 when not, 2 for bad input.

    \b
    Examples:
      laminid identify specimens/example1/S1.1.yaml
      laminid identify plate.yaml --fix nu12,G13,G23 --json
      laminid identify plate.yaml --optimizer mma -o plate-result.h5 --force
    """
    import sys

    from laminid_cli.fe.mesh import parse_mesh
    from laminid_cli.forward import build_forward_model
    from laminid_cli.identify import IdentifyOptions, identify as run_identify
    from laminid_cli.results import identification_summary, write_identification_file
    from laminid_cli.specimen import read_specimen

    out = None if no_output else check_output_path(output or default_output(spec), force)
    specimen = read_specimen(spec)
    options = IdentifyOptions(
        fix=tuple(x.strip() for x in fix.split(",") if x.strip()), optimizer=optimizer,
        parametrization=parametrization, xtol_rel=xtol, ftol_rel=ftol,
        max_evaluations=max_evaluations, pairing=pairing)
    fm = build_forward_model(specimen, parse_mesh(mesh))
    show_progress = not as_json and sys.stderr.isatty()

    def progress(n, objective, rms):
        if show_progress:
            click.echo(f"\r  evaluation {n:>4}: objective {objective:10.4g}, RMS residual "
                       f"{rms:8.4f} %", err=True, nl=False)

    result = run_identify(fm, options, progress=progress)
    if show_progress:
        click.echo("", err=True)
    summary = identification_summary(result)
    summary["mesh"] = {"nx": fm.mesh_size[0], "ny": fm.mesh_size[1]}
    if out is not None:
        write_identification_file(out, fm, result, summary)
        summary["output"] = str(out)
    if as_json:
        echo_json(summary)
    else:
        click.echo(format_identify_report(summary))
        if out is not None:
            click.echo(f"\nwritten: {out}")
    if not result.converged:
        click.echo(f"laminid: identification did not converge: {result.status}", err=True)
        sys.exit(1)
