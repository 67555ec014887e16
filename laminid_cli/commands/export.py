"""``laminid export``: FRFs (UFF 58) or identified mode shapes (UFF 15 + 55) for other tools."""

from __future__ import annotations

import click

from laminid_cli.commands._common import (OUTPUT_FILE, InputFile, check_output_path,
                                          echo_frf_warnings, echo_json, force_option,
                                          frf_json_option, writable_target)

#: the suffixes of the Universal Files export writes (those the FRF reader takes for UFF)
UFF_SUFFIXES = (".uff", ".unv")


def _shape_format(path) -> str | None:
    """The format of a laminid result/modes file (mode shapes), None for anything else
    (FRFs)."""
    from laminid_cli.export import SHAPE_FORMATS
    from laminid_cli.h5open import file_format

    try:
        fmt = file_format(path)
    except (OSError, ValueError):
        return None
    return fmt if fmt in SHAPE_FORMATS else None


def _span(freq) -> list:
    """[lowest, highest] of the frequencies written (Hz), for --json (``freq_range_hz``);
    [] when there are none."""
    import numpy as np

    f = np.asarray(freq, float)
    f = f[np.isfinite(f)]
    return [float(f.min()), float(f.max())] if f.size else []


@click.command("export")
@click.argument("input_file", type=InputFile())
@click.option("-o", "--output", required=True, type=OUTPUT_FILE,
              help="Universal File to write (.uff or .unv).")
@click.option("--ascii", "ascii_", is_flag=True,
              help="FRFs: write ASCII UFF 58 (12 significant digits, the frequencies 6) "
                   "instead of binary 58b (lossless doubles).")
@click.option("--format", "fmt", type=click.Choice(["hdf5", "uff", "csv"]), default=None,
              help="FRF input format (default: from the suffix).")
@click.option("--freq-dataset", default=None, metavar="PATH",
              help="Plain HDF5 FRF input: the frequency dataset.")
@click.option("--frf-dataset", default=None, metavar="PATH",
              help="Plain HDF5 FRF input: the complex FRF dataset.")
@click.option("--specimen", default=None, metavar="NAME",
              help="Joint result: the plate whose mode shapes to write.")
@force_option
@frf_json_option
def export(input_file, output, ascii_, fmt, freq_dataset, frf_dataset, specimen, force,
           as_json):
    """Write FRFs or identified mode shapes as a Universal File for other modal software.

    \b
    INPUT_FILE is either
      - FRFs (laminid acquire file, plain HDF5, UFF 58 or CSV): written as the units record
        (UFF 164, SI) and one UFF 58 record per measurement point, response node = point
        number (label), direction +Z, reference node 1 +Z (a UFF label such as 12-Z, or
        5+Z:2+Z of a roving hammer: its nodes and directions), abscissa Hz, the file's units
        as the response's over the force's (Pa/N: ordinate Pa, pressure, over N, excitation
        force, with their units exponents; a unit not SI, g or kN, of unknown type), each
        followed by the point's coherence where the file has it (a UFF 58 record of function
        type 6);
      - a result of identify/batch/modes: the plate mesh as UFF 15 nodes (metres, UFF 164
        units SI) and each mode as a UFF 55 normal-mode record (0, 0, w0) at the nodes,
        w0 of the mass-normalised mode in m/sqrt(kg), with its natural frequency.
    UFF 15 and 55 store 6 significant digits (E13.5); binary UFF 58 is lossless.

    \b
    Examples:
      laminid export plate.frf.h5 -o plate.uff
      laminid export S1.1.result.h5 -o S1.1_modes.unv
    """
    from pathlib import Path

    from laminid_cli.errors import OutputExistsError
    from laminid_cli.export import ExportError

    writable_target(output)                # a folder...: said first
    out = check_output_path(output, force, inputs=[input_file])     # the input itself: next
    if Path(output).suffix.lower() not in UFF_SUFFIXES:
        raise OutputExistsError(f"{output}: export writes Universal Files; name the output "
                                f"{' or '.join(UFF_SUFFIXES)} (-o)")
    shape_format = _shape_format(input_file) if Path(input_file).is_file() else None
    if Path(input_file).suffix.lower() in (".yaml", ".yml") and Path(input_file).is_file():
        # a specimen given for its mode shapes, most likely: the FRF reader's message named
        # only 'fit-frf --into', which takes FRFs into it, not what export takes
        raise ExportError(f"{input_file}: a specimen file (YAML), neither FRFs nor a result; "
                          f"'laminid identify {input_file}' (or 'laminid modes {input_file} "
                          "-o NAME.modes.h5') makes a result whose mode shapes export writes; "
                          "FRFs are an acquire file, UFF 58 or CSV", path=input_file)
    # an option that does not apply to this input is a mistake, not something to ignore
    if shape_format is not None:
        for given, option in ((fmt, "--format"), (freq_dataset, "--freq-dataset"),
                              (frf_dataset, "--frf-dataset")):
            if given is not None:
                raise ExportError(f"{input_file}: holds mode shapes (a {shape_format} file); "
                                  f"{option} applies to FRF input only")
    elif specimen is not None:
        raise ExportError(f"{input_file}: holds FRFs; --specimen picks the plate of a joint "
                          "result (mode shapes)")
    if shape_format is not None:
        from laminid_cli.export import read_shapes, write_shapes_uff

        shapes = read_shapes(input_file, specimen)
        write_shapes_uff(out, shapes, overwrite=force)
        summary = {"input": str(input_file), "output": str(out), "kind": "mode shapes",
                   "datasets": {"164": 1, "15": 1, "55": int(shapes.w.shape[1])},
                   "specimen": shapes.specimen, "n_nodes": int(shapes.nodes.shape[0]),
                   "n_modes": int(shapes.w.shape[1]), "freq_hz": shapes.freq_hz.tolist(),
                   "freq_range_hz": _span(shapes.freq_hz)}
        if shapes.model_mode is not None:
            summary["model_mode"] = shapes.model_mode.tolist()
        text = (f"{out}: {summary['n_modes']} mode shapes of {shapes.specimen} (UFF 55) on "
                f"{summary['n_nodes']} nodes (UFF 15, metres; UFF 164 SI)")
    else:
        from laminid_cli.frf.io import (read_frf, uff_coherence_points, uff_direction,
                                        uff_point, uff_units, write_frf_uff)
        from laminid_cli.frf.store import units_text

        fs = read_frf(input_file, fmt, freq_dataset=freq_dataset, frf_dataset=frf_dataset)
        warnings = echo_frf_warnings(fs)                 # a frequency unit not stated
        write_frf_uff(out, fs, overwrite=force, binary=not ascii_)
        # as written: a Universal File is ASCII ("m/s²/N" is written "m/s^2/N")
        units = uff_units(fs.units, input_file)
        labels = list(fs.labels) or [str(i + 1) for i in range(fs.n_points)]
        dofs = [uff_point(lab, i) for i, lab in enumerate(labels)]    # as write_frf_uff
        nodes = [d[0] for d in dofs]
        coherent, notes = uff_coherence_points(fs)
        notes[:0] = fs.meta.get("notes") or ()    # the reader's (a CSV phase unit assumed)
        point_units = fs.meta.get("point_units")
        if point_units and len(set(point_units)) > 1:
            notes.append("the FRFs are in different units, each record written in its own: "
                         + "; ".join(f"{lab} {units_text(uff_units(u, input_file))}"
                                     for lab, u in zip(labels, point_units)))
        if "exp_window_s" in (fs.meta.get("settings") or {}):
            from laminid_cli.frf.rfp import window_time_constant

            tau = window_time_constant(fs)
            notes.append(
                (f"the FRFs carry the analyser's exponential window (tau = {tau:g} s), "
                 if tau is not None else
                 "the FRFs carry the analyser's exponential window (tau unknown, --keep-setup), ")
                + "written in each record's id3: laminid fit-frf of the Universal File removes "
                  "it as of the acquire file; another tool's damping ratios include it "
                  "(about 1/(tau*omega_n) added)")
        summary = {"input": str(input_file), "output": str(out), "kind": "FRF",
                   "datasets": {"164": 1, "58": fs.n_points + len(coherent)},
                   "binary": not ascii_,
                   "frf_unit": units,
                   "units": units,      # frf_unit's old name, kept for 0.2.x (--json help)
                   "n_lines": int(fs.freq.size),
                   "freq_range_hz": _span(fs.freq),
                   # label -> node, kept for 0.2.x: a label that two records share (a
                   # DOF measured twice, scalar records at node 0) keeps its last record
                   "points": dict(zip(labels, nodes)),
                   # every record, in file order: the map above cannot hold a repeat
                   "point_nodes": [{"label": lab, "node": n, "direction": uff_direction(d),
                                    "ref_node": r, "ref_direction": uff_direction(rd)}
                                   for lab, (n, d, r, rd) in zip(labels, dofs)],
                   "coherence_points": [labels[k] for k in coherent], "notes": notes,
                   "warnings": warnings}
        frfs = f"{fs.n_points} FRF{'' if fs.n_points == 1 else 's'}"     # (was "1 FRFs")
        text = (f"{out}: {frfs} (UFF 58{'' if ascii_ else 'b'}, {units_text(units)}, "
                f"{fs.freq.size} lines {fs.freq[0]:g}-{fs.freq[-1]:g} Hz)"
                + (f" and the coherence of {len(coherent)} (UFF 58 function type 6)"
                   if coherent else "")
                + ", point -> node: "
                + ", ".join(f"{lab}->{n}" for lab, n in zip(labels, nodes))
                + "".join(f"\nnote: {note}" for note in notes))
    if as_json:
        echo_json(summary)
    else:
        click.echo(text)
