"""Helpers of the report tests: an axes of a page by its gid, the text of a drawn table."""

from __future__ import annotations


def ax(fig, gid):
    """The axes of ``fig`` whose gid is ``gid`` (the report names its panels)."""
    return next(a for a in fig.axes if a.get_gid() == gid)


def cells(axis) -> list[list[str]]:
    """Text of a table drawn on ``axis``: header row first."""
    d = axis.tables[0].get_celld()
    n_r = 1 + max(i for i, _ in d)
    n_c = 1 + max(j for _, j in d)
    return [[d[i, j].get_text().get_text() for j in range(n_c)] for i in range(n_r)]



def result_page(path, name: str):
    """The figure of page ``name`` of the report of one result file (``path`` to it, or the
    ResultFile read from it): summary, intervals, modes-<k>, history, sensitivities or damping
    (or another page of report.EXTRA_PAGES) of a single plate; shared, intervals or history of
    a joint result. Built alone as
    laminid_cli.report.result_pages (joint_pages) builds that page (its builder, then the
    status corner), for tests that read one page: report_pages builds every page (the mode
    shapes rebuild the initial model; an FRF page fits the FRF file again), 0.5-1 s a result
    against ~0.1 s. test_report.py::test_a_page_built_alone_is_the_reports_page holds it to
    report_pages' own."""
    from laminid_cli import report
    from laminid_cli.resultfile import ResultFile, read_result

    r = path if isinstance(path, ResultFile) else read_result(path)
    if r.joint:
        build = {"shared": lambda r: report.summary_page(
                     r, what=f"joint identification of {len(r.plates)} plates, shared constants"),
                 "intervals": report.interval_page, "history": report.history_page}[name]
    elif name.startswith("modes-"):
        def build(r):
            return report.mode_shape_pages(r, r.plates[0])[int(name.split("-")[1]) - 1]
    elif name in ("summary", "intervals", "history", "sensitivities"):
        build = {"summary": report.summary_page, "intervals": report.interval_page,
                 "history": report.history_page,
                 "sensitivities": lambda r: report.sensitivity_page(r, r.plates[0])}[name]
    else:
        def build(r):
            return next(p.figure for fn in report.EXTRA_PAGES for p in fn(r) if p.name == name)
    fig = build(r)
    report.status_corner(fig, r)
    return fig


def page_signature(fig) -> list:
    """What a page holds, to compare two builds of it: its texts and legends, and each axes'
    gid, title, labels, texts, lines (gid and data), patches, images, legend and tables."""
    import numpy as np

    def data(x):
        return repr(np.asarray(x).tolist())

    def legend(leg):
        return None if leg is None else [leg.get_title().get_text()] + [
            t.get_text() for t in leg.get_texts()]

    return [[t.get_text() for t in fig.texts], [legend(g) for g in fig.legends]] + [
        [a.get_gid(), a.get_title(), a.get_xlabel(), a.get_ylabel(), a.get_xlim(), a.get_ylim(),
         [(t.get_gid(), t.get_text()) for t in a.texts],
         [(ln.get_gid(), data(ln.get_xdata()), data(ln.get_ydata())) for ln in a.get_lines()],
         [(type(b).__name__, data(b.get_verts())) for b in a.patches],
         [data(im.get_array()) for im in a.get_images()], legend(a.get_legend()),
         [sorted((k, c.get_text().get_text()) for k, c in tb.get_celld().items())
          for tb in a.tables]]
        for a in fig.axes]
