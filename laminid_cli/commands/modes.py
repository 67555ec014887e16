"""``laminid modes``: natural frequencies of a specimen's plate model beside the measured ones."""

from __future__ import annotations

import time

import click

from laminid_cli.commands._common import (OUTPUT_FILE, InputFile, check_boundary_text,
                                          check_hdf5_name, check_mesh_text, check_output_path,
                                          echo_json, files_hint, force_option, json_option,
                                          quiet, stderr_is_terminal)
from laminid_cli.commands.text import format_modes_report


@click.command(short_help="Natural frequencies of the plate model vs the measured ones.")
@click.argument("spec", type=InputFile(folder_hint=files_hint("modes", ("*.yaml", "*.yml"),
                                                               "specimen file")))
@click.option("--mesh", default="12x12", show_default=True, metavar="NXxNY",
              callback=check_mesh_text, help="Elements along x (side a) and y (side b).")
@click.option("--modes", "n_modes", type=click.IntRange(1, 200), default=None,
              help="Elastic modes to compute [default: as many as measured, else 12].")
@click.option("--boundary", default=None, metavar="BC", callback=check_boundary_text,
              help="Override the specimen's boundary: free, simply-supported, clamped, or a "
                   "code of F/S/C for the edges x=0, y=0, x=a, y=b (e.g. SFSF).")
@json_option
@click.option("-o", "--output", type=OUTPUT_FILE, default=None,
              help="Write frequencies and mode shapes to this HDF5 file.")
@force_option
def modes(spec, mesh, n_modes, boundary, as_json, output, force):
    """Compute the natural frequencies of the plate described by SPEC (a specimen YAML file)
    with its initial material constants, and compare them with the measured frequencies.

    Residuals r = (measured - model) / measured * 100 (paper Eq. 28). The plate model is the
    third-order shear-deformation finite-element model (8-node elements, nine variables per
    node); a free plate's six rigid-body modes are dropped.

    \b
    Examples:
      laminid modes specimens/example1/S1.1.yaml
      laminid modes plate.yaml --mesh 16x24 --modes 20 --json
      laminid modes plate.yaml -o plate-modes.h5
    """
    from laminid_cli.fe.mesh import parse_mesh
    import numpy as np

    from laminid_cli.fe.assembly import boundary_code
    from laminid_cli.forward import (build_forward_model, coarse_mesh, far_from_model,
                                     modes_summary)
    from laminid_cli.errors import escaped
    from laminid_cli.specimen import read_specimen

    out = check_output_path(output, force, inputs=[spec])
    check_hdf5_name(output, "modes writes the modes", csv="--json prints the frequencies as "
                    "JSON, laminid export writes the mode shapes as a Universal File (.uff)")
    specimen = read_specimen(spec)
    # a terminal is told what runs, on a line erased when done (a convergence check on 40x40
    # with 40 modes took 10 s, busy machine, with nothing on it; 12x12 0.4 s)
    show_progress = not as_json and stderr_is_terminal() and not quiet()

    def step(text):
        if show_progress:
            click.echo(text, err=True, nl=False)

    def done(text):
        step("\r" + " " * len(text) + "\r")

    if n_modes is None:
        n_modes = specimen.measured.freq.size if specimen.measured is not None else 12
    t0 = time.perf_counter()
    building = f"  building the model on a {mesh} mesh"
    step(building)
    try:
        fm = build_forward_model(specimen, parse_mesh(mesh), boundary=boundary)
    finally:
        done(building)
    # the specimen reader's warnings are on stderr already (logged as it read the file)
    warnings = list(specimen.warnings)
    coarse = coarse_mesh(fm, n_modes)
    if coarse is not None:
        # escaped: a folder's 'bd\u202e' reversed the line (--json keeps the path as read)
        click.echo(escaped(f"warning: {spec}: {coarse}"), err=True)
        warnings.append(f"{spec}: {coarse}")
    solving = f"  solving {n_modes} modes of {fm.plate.n_dofs} equations"
    step(solving)
    try:
        result = fm.solve(n_modes=n_modes)
    finally:
        done(solving)
    summary = modes_summary(fm, result)
    summary["time_s"] = time.perf_counter() - t0
    fr = summary["frequencies"]
    far = far_from_model(np.asarray(fr["measured"], float), np.asarray(fr["model"], float),
                         np.asarray(fr["weight"], float))
    if far is not None and fm.plate.boundary == boundary_code(specimen.boundary):
        # (measured on the specimen's boundary: another --boundary is expected to be far off)
        click.echo(escaped(f"warning: {spec}: {far}"), err=True)
        warnings.append(f"{spec}: {far}")
    if out is not None:
        from laminid_cli.results import write_modes_file

        write_modes_file(out, fm, result, summary)
        summary["output"] = str(out)
    if as_json:
        from laminid_cli.units import json_units

        echo_json({**summary, "warnings": warnings, "units": json_units(summary)})
    else:
        click.echo(format_modes_report(summary))
        if out is not None:
            click.echo(escaped(f"\nwritten: {out}"))
