"""``laminid report``: figures of an identification result or of a batch summary."""

from __future__ import annotations

from pathlib import Path

import click

from laminid_cli.commands._common import (OUTPUT_FILE, InputFile, check_output_path,
                                          force_option, quiet, stderr_is_terminal,
                                          writable_target)

#: what write_pages puts in a PDF's information dictionary
_CREATOR = b"/Creator (laminid)"


def default_output(source: str) -> Path:
    p = Path(source)
    stem = p.name[: -len(".result.h5")] if p.name.endswith(".result.h5") else p.stem
    return p.with_name(stem + ".report.pdf")


def is_laminid_report(path: Path) -> bool:
    """A PDF that ``laminid report`` wrote (its Creator is laminid)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(64 << 20)
    except OSError:
        return False
    return data.startswith(b"%PDF") and _CREATOR in data


def derived_report(source: str) -> tuple[Path, bool]:
    """The default report beside SOURCE: (path, replacing an earlier laminid report). Re-running
    replaces the report laminid wrote there; any other file of that name is refused."""
    from laminid_cli.errors import OutputExistsError

    out = writable_target(default_output(source))
    if not out.exists():
        return out, False
    if not is_laminid_report(out):
        raise OutputExistsError(f"{out}: exists and is not a laminid report; move it or name "
                                "the report with -o")
    return out, True


def summary_hint(folder: Path) -> str:
    """What report says of a folder given as SOURCE: a batch's --out folder has its summary."""
    import shlex

    found = [folder / n for n in ("summary.csv", "summary.json") if (folder / n).is_file()]
    return (f"; 'laminid report {shlex.quote(str(found[0]))}' draws the batch summary it holds"
            if found else "")


@click.command(short_help="PDF/PNG report of a result file or a batch summary.")
@click.argument("source", type=InputFile(must_exist=True, folder_hint=summary_hint))
@click.option("-o", "--output", type=OUTPUT_FILE, default=None,
              help="report.pdf (all pages in one file) or report.png (one PNG per page: "
                   "report-1.png, report-2.png...), never overwritten without --force "
                   "[default: next to SOURCE, <name>.report.pdf, replaced on a re-run].")
@click.option("--frf", "frf_path", type=InputFile(must_exist=True), default=None,
              help="FRF file to draw with its RFP fit (default: the specimen's "
                   "measured.frf_file, when it has one).")
@click.option("--dpi", type=click.IntRange(50, 600), default=110, show_default=True,
              help="Resolution of PNG pages.")
@force_option
def report(source, output, frf_path, dpi, force):
    """Draw the report of SOURCE: a result file of 'laminid identify' (single or --joint)
    or 'laminid batch' (*.h5), or a batch summary (summary.csv or summary.json).

    \b
    A result gives the pages:
      summary        status and reasons; constants with interval (confidence level of the
                     file), verdict, initial and reference value; measured vs model
                     frequency table with the residuals
      intervals      one panel per constant in its unit, verdict bands, reference values
                     (when the file has /uncertainty)
      mode shapes    w0 of each paired mode, nodal lines, MAC vs the initial model's mode
      history        objective, RMS residual, constants / initial value (log scales),
                     constants that ended at a bound marked
      sensitivities  heat map of d ln f_i / d ln P_j at the optimum
      FRF            FRFs over their RFP fit, phase, coherence (specimens with
                     measured.frf_file, or --frf)
      damping        measured vs model modal loss factors, strain-energy shares, ply loss
                     factors (when the specimen has measured damping); a table too
                     long for the page continues on a second damping page
    A joint result gives the shared constants first (summary, intervals, history), then
    per plate its frequencies, mode shapes and sensitivities. A batch summary gives the
    constants across specimens (materials of a specimen side by side, intervals, reference
    values, undetermined values marked) and the RMS residuals; when it holds loss factors,
    also the ply loss factors across specimens (%, intervals, verdict marks) and their table
    in the words of the damping page.

    \b
    Examples:
      laminid report specimens/example1/S1.1.result.h5
      laminid report results/example2/S2.1.result.h5 -o S2.1.png
      laminid report results/summary.csv -o study.pdf
    """
    from laminid_cli.errors import escaped
    from laminid_cli.report import REPORT_SUFFIXES, ReportError, report_pages, write_pages

    if output:
        writable_target(output)            # a folder, a missing folder: said first
    out = Path(output) if output else default_output(source)
    if out.suffix.lower() not in REPORT_SUFFIXES:
        raise ReportError(f"{out}: report type {out.suffix!r} not supported; use .pdf or .png "
                          "(-o)")
    replacing = False
    if output:
        out = check_output_path(out, force)
        if out.suffix.lower() == ".png":
            # every report has two pages or more (a result's summary and mode shapes, a
            # summary's constants and residuals), so its first PNG is <stem>-1.png: one there
            # was refused only after the pages were laid out (5 s for S1.1, 15 s hybrid CM)
            check_output_path(out.with_name(f"{out.stem}-1{out.suffix}"), force)
    else:
        out, replacing = derived_report(source)
    # a terminal is told where the report is (S1.1: 5 s, hybrid CM: 15 s on a busy machine,
    # with nothing said before)
    show_progress = stderr_is_terminal() and not quiet()
    head = escaped(f"  reading {source} and laying out its pages")

    def progress(k, n, name):
        if show_progress:          # (as wide as the line before: none of it left over)
            click.echo("\r" + escaped(f"  drawing page {k} of {n} ({name})").ljust(len(head)),
                       err=True, nl=False)

    if show_progress:
        click.echo(head, err=True, nl=False)
    try:
        pages = report_pages(source, frf_path=frf_path)
        if out.suffix.lower() == ".png" and len(pages) > 1:
            for k in range(1, len(pages) + 1):
                check_output_path(out.with_name(f"{out.stem}-{k}{out.suffix}"), force)
        try:
            written = write_pages(pages, out, dpi=dpi, progress=progress)
        except OSError as exc:
            raise ReportError(f"{out}: cannot write the report ({exc})") from exc
    finally:
        if show_progress:               # the line ends before the result or an error
            click.echo("", err=True)
    names = ", ".join(p.name for p in pages)
    click.echo(escaped(f"{len(pages)} pages ({names}) written to "
                       + ", ".join(map(str, written)))
               + (" (replaced the previous report of this result)" if replacing else ""))
