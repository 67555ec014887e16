"""``laminid show``: print a result file as ``laminid identify`` printed it."""

from __future__ import annotations

import click

from laminid_cli.commands._common import InputFile, echo_json, json_option


def results_hint(folder) -> str:
    """What show says of a folder given as RESULT: the result files it holds (a batch's --out:
    <folder>/<name>.result.h5, one level down), one to show, and its summary to report; it
    was "is a folder, not a file" alone."""
    import shlex

    found = sorted(folder.glob("*.result.h5")) + sorted(folder.glob("*/*.result.h5"))
    if not found:
        return ""
    hint = (f"; it holds {len(found)} result file{'s' if len(found) > 1 else ''}: 'laminid "
            f"show {shlex.quote(str(found[0]))}' prints {'one' if len(found) > 1 else 'it'}")
    summary = folder / "summary.csv"
    if summary.is_file():
        hint += f", 'laminid report {shlex.quote(str(summary))}' draws the batch"
    return hint


@click.command(short_help="Print a result file as identify printed it (or --json).")
@click.argument("result", type=InputFile(must_exist=True, folder_hint=results_hint))
@json_option
def show(result, as_json):
    """Print RESULT, a result file of 'laminid identify' (single or --joint) or 'laminid
    batch', as 'laminid identify' printed it when the file was written: the status and its
    reasons, the constants with their intervals and verdicts, the measured and model
    frequencies, the uncertainty assessment (Monte Carlo, fixed constants, profiles) and the
    ply loss factors, after a line naming when, by which command and on which mesh it was
    written. Nothing is computed again; with --json, what 'identify --json' printed,
    plus "file" and "written" (when, by which laminid and command). A reference range that an
    earlier laminid stored as its midpoint is given as the range of the specimen in the file.

    A file written by an earlier laminid (no /summary_json) is refused with a pointer to
    'laminid report', which draws any readable result.

    \b
    Examples:
      laminid show specimens/example1/S1.1.result.h5
      laminid show results/example2/S2.1.result.h5 --json | jq .status
    """
    from pathlib import Path

    from laminid_cli.commands.text import (format_damping, format_identify_report,
                                           format_joint_report)
    from laminid_cli.resultfile import (ResultFileError, is_frf_text_file, not_a_result_but_frf,
                                        read_stored_summary)

    if is_frf_text_file(result):
        # a CSV of FRFs was called a batch summary, a UFF not an HDF5 result
        raise ResultFileError(not_a_result_but_frf(result))
    if Path(result).suffix.lower() in (".csv", ".json"):
        # summary.csv / summary.json of a batch: text already, and report draws them
        raise ResultFileError(f"{result}: a batch summary is text already (a spreadsheet, "
                              f"jq); 'laminid report {result}' draws it, 'laminid show' "
                              "prints a result file (*.result.h5)")
    summary, written = read_stored_summary(result)
    if as_json:
        from laminid_cli.units import json_units

        # (a file written before identify --json had "units" gets them: the same SI numbers)
        units = summary.get("units") or json_units(summary)
        echo_json({**summary, "units": units, "file": str(result), "written": written})
        return
    # the mesh, which identify's own output leaves to the command line that gave it: a
    # batch's result (or one made by somebody else) did not say whether it was 12x12 or 6x6
    mesh = summary.get("mesh") or {}
    from laminid_cli.errors import escaped

    # escaped: a folder's 'bd\u202e' reversed the line (--json keeps the path as read)
    click.echo(escaped(f"{result}: written {written['created'] or '(date not recorded)'} by "
                       f"laminid {written['laminid_version'] or '?'}")
               + (f" ({written['command']})" if written["command"] else "")
               + (f", mesh {mesh['nx']}x{mesh['ny']}" if mesh.get("nx") and mesh.get("ny")
                  else "") + "\n")
    joint = written["format"] == "laminid-joint-result"
    click.echo(format_joint_report(summary) if joint else format_identify_report(summary))
    if "damping" in summary:
        click.echo("\n" + "\n".join(format_damping(summary["damping"])))
    for note in summary.get("notes") or ():
        click.echo(f"note: {note}")
