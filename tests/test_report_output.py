"""Where `laminid report` writes: its default report beside the result is replaced on a re-run
(the edit -> identify -> report loop), a file named with -o is kept unless --force, and a file
at the default name that laminid did not write is never replaced."""

from pathlib import Path

import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli

S11 = "specimens/example1/S1.1.yaml"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture
def one_page(monkeypatch):
    """The report of the result's first page only: these tests check where the report is
    written and what is protected, not its pages (drawn and checked in test_report.py); the
    PDF is still written by write_pages, with its Creator, as the command writes it. The page
    is built alone (tests.figs.result_page, held to report_pages' own in test_report.py), not
    the whole report cut to its first page: ~0.1 s a run instead of ~1 s."""
    import laminid_cli.report as rep
    from tests.figs import result_page

    def first_page(source, frf_path=None):
        assert frf_path is None
        return [rep.Page("summary", result_page(source, "summary"))]

    monkeypatch.setattr(rep, "report_pages", first_page)


@pytest.fixture(scope="module")
def result(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("rep") / "S1.1.result.h5"
    r = run("identify", S11, "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    return out


def test_the_default_report_is_replaced_on_a_rerun(result, one_page):
    pdf = result.with_name("S1.1.report.pdf")
    pdf.unlink(missing_ok=True)
    r = run("report", result)
    assert r.exit_code == 0, r.output
    assert "replaced" not in r.output and pdf.read_bytes()[:5] == b"%PDF-"
    first = pdf.stat().st_mtime_ns
    r = run("report", result)
    assert r.exit_code == 0, r.output
    assert "(replaced the previous report of this result)" in r.output
    assert pdf.stat().st_mtime_ns >= first and pdf.read_bytes()[:5] == b"%PDF-"


def test_a_foreign_file_at_the_default_name_is_kept(result):
    pdf = result.with_name("S1.1.report.pdf")
    pdf.write_bytes(b"%PDF-1.4 a lab's own notes\n")
    r = run("report", result)
    assert r.exit_code == 2
    assert "exists and is not a laminid report; move it or name the report with -o" in r.output
    assert pdf.read_bytes() == b"%PDF-1.4 a lab's own notes\n"
    pdf.unlink()


def test_an_explicit_output_is_protected(result, tmp_path, one_page):
    out = tmp_path / "mine.pdf"
    assert run("report", result, "-o", out).exit_code == 0
    r = run("report", result, "-o", out)
    assert r.exit_code == 2 and "file exists; use --force" in r.output
    assert run("report", result, "-o", out, "--force").exit_code == 0


def test_every_page_says_the_status(result):
    """Page 1 has the status with its reasons; every other page (mode shapes, history,
    sensitivities...) at least the status and its codes."""
    from laminid_cli.report import report_pages
    from laminid_cli.resultfile import read_result

    res = read_result(result)
    codes = ", ".join(x.code for x in res.status.reasons)
    pages = report_pages(result)
    assert len(pages) >= 4
    for page in pages:
        fig = page.figure
        texts = [t.get_text() for t in [*fig.texts, *(t for a in fig.axes for t in a.texts)]
                 if t.get_gid() == "status"]
        assert len(texts) == 1, page.name
        if res.status.status == "check":
            assert texts[0].startswith("status: CHECK")
            assert codes in texts[0] or all(c in texts[0] for c in codes.split(", ")), page.name


def test_an_earlier_point_evaluated_again_is_drawn_off_the_history_line():
    """revisits(): evaluation i is at the point of an evaluation before i - 1 (the reduced
    solver re-evaluates its trust region's centre after enriching the basis), not a step; a
    repeat of the previous point is not one."""
    import numpy as np

    from laminid_cli.report import revisits

    a, b, c, d = ([1.0, 2.0], [1.5, 2.0], [1.6, 2.1], [1.7, 2.2])
    C = np.array([a, b, c, a, d, d, c])
    assert revisits(C).tolist() == [False, False, False, True, False, False, True]


def test_page_one_fits_two_line_cells_and_many_notes(s21_6x6, monkeypatch):
    """Page 1's constants table gave every row one line's height, so two-line cells (S2.1's
    G13: "none — on lower search limit" / "profile: < 1.47") ran over their borders; and a
    result with many notes (hybrid CM with profiles and a Monte Carlo) ran off the page. Rows
    now take the height of their lines, and the notes shrink to the room left."""
    import laminid_cli.report as rep
    from laminid_cli.resultfile import read_result

    r, _, out = s21_6x6                    # identify S2.1 --mesh 6x6 -o (conftest.py)
    assert r.exit_code == 0, r.output
    res = read_result(out)
    real = rep.table_notes
    monkeypatch.setattr(rep, "table_notes", lambda rr: real(rr) + [
        f"note {k}: " + "a long explanation of what a mark in the table means " * 3
        for k in range(14)])
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = rep.summary_page(res)
    canvas = FigureCanvasAgg(fig)
    fig.draw_without_rendering()                    # lays out and places every text
    renderer = canvas.get_renderer()
    ax = next(a for a in fig.axes if a.get_gid() == "constants")
    table = ax.tables[0]
    two_line = 0
    for cell in table.get_celld().values():
        text = cell.get_text()
        if not text.get_text():
            continue
        t, c = text.get_window_extent(renderer), cell.get_window_extent(renderer)
        assert t.height <= c.height + 0.5, text.get_text()
        two_line += "\n" in text.get_text()
    assert two_line >= 1                     # the case the fix is for is on the page
    notes = next(t for a in fig.axes for t in a.texts if t.get_gid() == "notes")
    box = notes.get_window_extent(renderer)
    assert box.y0 >= 0 and notes.get_fontsize() < 7.5      # shrunk, and still on the page


@pytest.mark.parametrize("fmt", ["pdf", "png"])
def test_a_page_laid_out_once_is_the_page_savefig_lays_out(fmt, tmp_path):
    """write_pages lays each page out once (report.lay_out_once) and removes its layout engine,
    so that savefig draws it once instead of twice: the layout must be the one savefig's own
    first draw makes, with the renderer of the format (a PDF's text metrics at 72 dpi differ
    from Agg's: laid out with Agg, S1.1's pages moved by up to 5 pt)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    from laminid_cli.report import lay_out_once

    def page():
        fig = Figure(figsize=(6.0, 4.0), layout="constrained")
        fig.suptitle("a title of some length", fontsize=13)
        for k, ax in enumerate(fig.subplots(1, 2)):
            ax.plot([0.0, 1.0], [0.0, 10.0 ** (4 * k)])
            ax.set_ylabel("a label\non two lines" if k else "w", fontsize=11)
            ax.set_title(f"panel {k}: 0.123456 Hz")
        return fig

    saved = page()
    saved.savefig(tmp_path / f"a.{fmt}", dpi=110)        # laid out by savefig's first draw
    once = page()
    lay_out_once(once, fmt, 110)
    assert once.get_layout_engine() is None and once.dpi == saved.dpi
    for a, b in zip(saved.axes, once.axes):
        assert a.get_position().bounds == pytest.approx(b.get_position().bounds, abs=1e-9)
    assert saved._suptitle.get_position() == pytest.approx(once._suptitle.get_position(),
                                                           abs=1e-9)


def test_a_page_of_words_only_is_written_without_a_layout_warning(tmp_path):
    """A page without axes is not laid out by savefig (Figure.draw lays out only a figure with
    axes); lay_out_once does the same, where constrained layout warns 'There are no gridspecs
    with layoutgrids'."""
    import warnings

    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    from laminid_cli.report import Page, write_pages

    fig = Figure(figsize=(4.0, 3.0), layout="constrained")
    fig.text(0.5, 0.5, "words only", ha="center")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert write_pages([Page("words", fig)], tmp_path / "w.pdf") == [tmp_path / "w.pdf"]
    assert fig.get_layout_engine() is None

def test_a_terminal_is_told_which_page_is_drawn(result, tmp_path, monkeypatch):
    """report drew a result's pages for 5 s (hybrid CM: 15 s) with nothing on a terminal;
    it now says it is reading the result, then each page as it is drawn, and ends the line
    before its own. Not on a pipe or a log, nor under -q. (Three blank pages stand for the
    result's: what is said, not what is drawn.)"""
    import laminid_cli.commands.report as cmd
    import laminid_cli.report as rep

    def pages(source, frf_path=None):
        return [rep.Page(name, rep._figure(size=(2, 2))) for name in ("a", "b", "c")]

    monkeypatch.setattr(rep, "report_pages", pages)
    monkeypatch.setattr(cmd, "stderr_is_terminal", lambda: True)
    r = CliRunner().invoke(cli, ["report", str(result), "-o", str(tmp_path / "r.pdf")])
    assert r.exit_code == 0, r.output
    head = f"  reading {result} and laying out its pages"
    assert r.stderr.split("\r") == [head] + [
        f"  drawing page {k} of 3 ({n})".ljust(len(head)) for k, n in ((1, "a"), (2, "b"))] + [
        "  drawing page 3 of 3 (c)".ljust(len(head)) + "\n"]
    assert r.stdout == f"3 pages (a, b, c) written to {tmp_path / 'r.pdf'}\n"
    r = CliRunner().invoke(cli, ["-q", "report", str(result), "-o", str(tmp_path / "q.pdf")])
    assert r.exit_code == 0 and r.stderr == ""


def test_an_existing_first_png_page_is_refused_before_the_pages_are_drawn(result, tmp_path,
                                                                          monkeypatch):
    """report -o r.png where r-1.png exists laid out every page (5 s for S1.1, 15 s for
    hybrid CM), then refused r-1.png; it is refused first, nothing drawn, the file kept."""
    import laminid_cli.report as rep

    def no_pages(source, frf_path=None):
        raise AssertionError("the pages were laid out before the output was refused")

    monkeypatch.setattr(rep, "report_pages", no_pages)
    (tmp_path / "r-1.png").write_bytes(b"page one of an earlier report")
    r = run("report", result, "-o", tmp_path / "r.png")
    assert r.exit_code == 2, r.output
    assert r.output == (f"laminid: error: {tmp_path / 'r-1.png'}: file exists; use --force to "
                        "overwrite it or choose another name with -o\n")
    assert (tmp_path / "r-1.png").read_bytes() == b"page one of an earlier report"


def test_the_frf_file_is_found_beside_the_result_from_another_folder(tmp_path, monkeypatch):
    """identify plate.yaml (measured.frf_file: plate.frf.h5) stores the specimen's path as
    given; the report of its result made from another folder looked for plate.frf.h5 there,
    and drew no FRF page. The result's own folder (identify's default result lies beside its
    specimen) is looked in too; an absolute specimen path keeps its own folder."""
    from types import SimpleNamespace

    from laminid_cli.report import frf_source

    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "plate.frf.h5").write_bytes(b"")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    plate = SimpleNamespace(yaml="measured: {frf_file: plate.frf.h5}\n", path="plate.yaml")
    found = frf_source(plate, None, lab / "plate.result.h5")
    assert found is not None and found[0] == lab / "plate.frf.h5" and found[3] is True
    assert frf_source(plate, None, None) is None              # the cwd alone: not there
    other = SimpleNamespace(yaml=plate.yaml, path=str(tmp_path / "x" / "plate.yaml"))
    assert frf_source(other, None, lab / "plate.result.h5") is None


def test_the_specimens_folder_is_stored_and_finds_its_frf_file(tmp_path, monkeypatch):
    """A batch's result lies in --out, not beside its specimen, and stores the specimen's path
    as the batch was given it: a report made from another folder drew no FRF page. The
    result stores the specimen's folder (absolute), where the FRF file is looked for."""
    from types import SimpleNamespace

    import h5py

    from laminid_cli.report import frf_source
    from laminid_cli.resultfile import read_result

    lab = tmp_path / "lab"
    lab.mkdir()
    spec = lab / "S1.1.yaml"
    spec.write_text(Path(S11).read_text())
    monkeypatch.chdir(lab)
    out = tmp_path / "out" / "S1.1.result.h5"
    out.parent.mkdir()
    assert run("identify", "S1.1.yaml", "--mesh", "4x4", "-o", out).exit_code == 0
    with h5py.File(out) as f:
        assert f["specimen"].attrs["path"] == "S1.1.yaml"
        assert f["specimen"].attrs["folder"] == str(lab.resolve())
    assert read_result(out).plates[0].folder == str(lab.resolve())
    (lab / "plate.frf.h5").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    plate = SimpleNamespace(yaml="measured: {frf_file: plate.frf.h5}\n", path="S1.1.yaml",
                            folder=str(lab.resolve()))
    found = frf_source(plate, None, out)
    assert found is not None and found[0] == lab.resolve() / "plate.frf.h5"
