"""`laminid report`: every page rendered, and the numbers drawn are those of the result file."""

import dataclasses
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.commands.text import fmt
from laminid_cli.forward import build_forward_model
from laminid_cli.frf.store import write_frf_h5
from laminid_cli.report import (Page, fmt_reference, fmt_value, interval_text, mac,
                                mc_end_text,
                                reference_diff, report_pages, short_verdict, write_pages)
from laminid_cli.resultfile import read_result
from laminid_cli.specimen import read_specimen
from laminid_cli.units import gpa_text
from tests.clihelp import write_s14_with_ranges
from tests.figs import ax, cells, page_signature, result_page
from tests.frf_synth import synth_frf
from tests.resultfix import drop_bound_data, make_version_1, mark_at_bound

S11 = "specimens/example1/S1.1.yaml"
S12 = "specimens/example1/S1.2.yaml"
S13 = "specimens/example1/S1.3.yaml"
S14 = "specimens/example1/S1.4.yaml"
S21 = "specimens/example2/S2.1.yaml"
MAT = "IM7/977-2"
MEASURED_BLOCK = ("  frequencies: [72.78, 121.00, 191.38, 286.78, 315.12, 340.40, 400.12, 433.84, "
                  "634.81, 653.56, 712.43, 789.97]   # Hz, Table 5")
PNG = b"\x89PNG\r\n\x1a\n"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def batch_dir(tmp_path_factory):
    """A batch over S1.4 and S2.1 (6x6): two result files and the summary."""
    tmp = tmp_path_factory.mktemp("rep")
    for src in (S14, S21):
        shutil.copy(src, tmp / src.rsplit("/", 1)[1])
    r = run("batch", tmp, "--mesh", "6x6", "--out", tmp / "out")
    assert r.exit_code == 0, r.output
    return tmp / "out"


@pytest.fixture(scope="module")
def checked(batch_dir, tmp_path_factory):
    """S1.4's result as written (status "check", log-space moduli intervals, reference values)
    with G23 marked at its bound as the writer marks one (resultfix.mark_at_bound)."""
    path = tmp_path_factory.mktemp("chk") / "S1.4.result.h5"
    shutil.copy(batch_dir / "S1.4.result.h5", path)
    # (the text as uncertainty.bounds_reached writes it; until stop 27 this fixture had the
    # older "(0.0160 GPa)", and the summary table's pattern did not follow the writer)
    mark_at_bound(path, {f"{MAT}.G23": ("at its bound — not identified: G23 <= 0.0001 E1 "
                                        "(0.0160 GPa at the optimum)", "lower", 0.0160e9)},
                  reasons=[("at_bound", "G23 at its bound (0.0001 E1)"),
                           ("undetermined", "G13 not determined by these modes")])
    return path


@pytest.fixture(scope="module")
def joint(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("joint")
    out = tmp / "j.result.h5"
    r = run("identify", S11, S12, "--joint", "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    return out


# Pages built once per module for the tests that only read them (~1-2 s a build). A test that
# draws a figure (canvas.draw, write_pages) builds its own pages, so that no test reads a
# figure another test has laid out.
@pytest.fixture(scope="module")
def checked_pages(checked):
    return {p.name: p.figure for p in report_pages(checked)}


@pytest.fixture(scope="module")
def joint_pages(joint):
    return report_pages(joint)


def status_text(fig):
    """The one status text of a page (the page's own text, or in an axes of its own)."""
    found = [t for t in list(fig.texts) + [t for a in fig.axes for t in a.texts]
             if t.get_gid() == "status"]
    assert len(found) == 1
    return found[0]


def n_pdf_pages(path) -> int:
    return len(re.findall(rb"/Type\s*/Page\b(?!s)", path.read_bytes()))


def pages_the_command_builds(monkeypatch) -> list:
    """The list to which each report_pages call of the report command (report_pages kept as
    the command calls it) adds the pages it built: a test that runs the command reads the
    pages the command built and wrote, instead of building the report again (~0.5-1 s)."""
    import laminid_cli.report as rep

    built = []
    real = rep.report_pages

    def kept(*args, **kwargs):
        built.append(real(*args, **kwargs))
        return built[-1]

    monkeypatch.setattr(rep, "report_pages", kept)
    return built


def test_pdf_report_of_a_result(batch_dir, tmp_path):
    out = tmp_path / "r.pdf"
    r = run("report", batch_dir / "S1.4.result.h5", "-o", out)
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:5] == b"%PDF-" and out.stat().st_size > 50_000
    assert n_pdf_pages(out) == 5
    assert "5 pages (summary, intervals, modes-1, history, sensitivities)" in r.output
    r = run("report", batch_dir / "S1.4.result.h5", "-o", out)
    assert r.exit_code == 2 and "file exists" in r.output


def test_png_pages(batch_dir, tmp_path):
    src = tmp_path / "S2.1.result.h5"
    shutil.copy(batch_dir / "S2.1.result.h5", src)
    r = run("report", src, "-o", tmp_path / "rep.png", "--dpi", "60")
    assert r.exit_code == 0, r.output
    pngs = sorted(tmp_path.glob("rep-*.png"))
    assert [p.name for p in pngs] == [f"rep-{k}.png" for k in range(1, 6)]
    assert all(p.read_bytes()[:8] == PNG and p.stat().st_size > 10_000 for p in pngs)


@pytest.mark.slow
def test_default_name_beside_a_copied_result(batch_dir, tmp_path):
    """Without -o: <name>.report.pdf beside the result (S2.1 copied away from its batch). The
    default run checks the same on S1.1 in test_report_output.py (the default report, then
    replaced on a re-run); this variant renders a whole PDF again (~5 s)."""
    src = tmp_path / "S2.1.result.h5"
    shutil.copy(batch_dir / "S2.1.result.h5", src)
    r = run("report", src)
    assert r.exit_code == 0 and (tmp_path / "S2.1.report.pdf").stat().st_size > 0


def test_summary_page_tables_and_residuals_read_back(checked, checked_pages, tmp_path):
    res = read_result(checked)
    plate = res.plates[0]
    fr = plate.frequencies
    pages = checked_pages
    fig = pages["summary"]
    # measured vs model table: one row per mode, numbers of the file
    t = cells(ax(fig, "frequency-table"))
    assert t[0][2].startswith("measured") and len(t) == fr.model.size + 1
    for k, row in enumerate(t[1:]):
        assert row[0] == str(k + 1) and row[1] == str(fr.model_mode[k])
        assert float(row[2]) == pytest.approx(fr.measured[k], abs=0.005)
        assert float(row[3]) == pytest.approx(fr.model[k], abs=0.005)
        assert float(row[4]) == pytest.approx(fr.residual_percent[k], abs=0.005)
        # the terminal's digits (2 decimals; the page adds the sign of a signed column)
        assert row[4].lstrip("+") == fmt(fr.residual_percent[k], "10.2f").strip()
    # residual bars: exact values, one neutral colour (no sign coding)
    bars = ax(fig, "residuals").patches
    assert np.array_equal([b.get_width() for b in bars], fr.residual_percent)
    assert len({b.get_facecolor() for b in bars}) == 1
    # constants table: value, interval (confidence level from the file), verdict, reference
    c = cells(ax(fig, "constants"))
    assert c[0][2] == "95% interval"
    u = res.uncertainty
    rows = {row[0].split(" ")[0]: row for row in c[1:]}
    for k in ("E1", "E2", "G12", "G13", "nu12"):
        iv = u.get(MAT, k)
        scale = 1 if k == "nu12" else 1e9
        lo, hi = (float(x) for x in rows[k][2].strip("[]").split(", "))
        tol = dict(abs=5e-4) if k == "nu12" else dict(rel=1e-3)     # 3 decimals / 4 digits
        assert lo == pytest.approx(iv.lower / scale, **tol)
        assert hi == pytest.approx(iv.upper / scale, **tol)
        assert lo < float(rows[k][1]) < hi
        assert rows[k][3] == short_verdict(iv.verdict)
    assert u.get(MAT, "E1").scale == "log"             # asymmetric: exp(-/+ q std/v)
    # at its bound: no interval (the value column is the limit it stopped on)
    assert rows["G23"][3] == "at bound, not identified"
    assert rows["G23"][2] == "none — on lower search limit"
    assert rows["G23"][1] == fmt_value("G23", res.materials[MAT]["G23"])
    assert rows["E1"][5] == f"170.00 ({round((res.materials[MAT]['E1'] / 170e9 - 1) * 100):+d} %)"
    assert rows["G13"][5] == ""                         # no reference value for G13
    # status line with the reasons
    status = status_text(fig).get_text()
    assert status.startswith("status: CHECK") and "[at_bound]" in status \
        and "G13 not determined" in status.replace("\n", " ")
    write_pages([Page("summary", result_page(checked, "summary"))], tmp_path / "s.png")
    assert (tmp_path / "s.png").read_bytes()[:8] == PNG


def test_a_page_built_alone_is_the_reports_page(checked, checked_pages, damped, damped_pages,
                                                joint, joint_pages):
    """tests.figs.result_page, which the tests reading one page of a result use, builds the
    page report_pages builds: the same texts, lines, bars, images, legends and tables on
    each page it builds (S1.4 at a bound, S2.1 with damping and fixed constants, and the
    joint S1.1 + S1.2)."""
    joint_named = {p.name: p.figure for p in joint_pages}
    for path, pages, names in ((checked, checked_pages, ("summary", "intervals", "modes-1",
                                                         "history", "sensitivities")),
                               (damped, damped_pages, ("summary", "intervals", "modes-1",
                                                       "history", "sensitivities", "damping")),
                               (joint, joint_named, ("shared", "intervals", "history"))):
        for name in names:
            assert page_signature(result_page(path, name)) == page_signature(pages[name]), \
                (path.name, name)


def test_interval_panels_each_in_their_unit_with_reference_and_arrows(checked, checked_pages):
    res = read_result(checked)
    fig = checked_pages["intervals"]
    u = res.uncertainty
    for k in ("E1", "E2", "G12", "G13", "nu12"):
        a = ax(fig, f"interval-{MAT}.{k}")
        scale = 1 if k == "nu12" else 1e9
        iv = u.get(MAT, k)
        assert iv.scale == ("linear" if k == "nu12" else "log")
        value = next(ln for ln in a.get_lines() if ln.get_gid() == "value")
        assert value.get_ydata()[0] == res.materials[MAT][k] / scale
        line = next(ln for ln in a.get_lines() if ln.get_gid() == "interval")
        ymin, ymax = a.get_ylim()
        assert np.allclose(line.get_ydata(), [max(iv.lower / scale, ymin),
                                              min(iv.upper / scale, ymax)], rtol=1e-12)
        caps = next(ln for ln in a.get_lines() if ln.get_gid() == "interval-caps")
        inside = [e / scale for e in (iv.lower, iv.upper) if ymin <= e / scale <= ymax]
        assert np.allclose(caps.get_ydata(), inside, rtol=1e-12)
        # the value and the weak band are always in view; moduli panels never go below 0
        assert ymin <= iv.value / scale <= ymax
        assert k == "nu12" or ymin >= 0
        arrows = [t for t in a.texts if t.get_text().startswith(("to", "from"))]
        assert bool(arrows) == (iv.upper / scale > ymax or iv.lower / scale < ymin)
        ref = res.reference[MAT].get(k)               # (low, high): single values here
        refs = [ln for ln in a.get_lines() if ln.get_gid() == "reference"]
        assert (len(refs) == 1 and ref[0] == ref[1] and refs[0].get_ydata()[0] == ref[0] / scale
                ) if ref else not refs
        assert a.get_title() == f"{k} ({'–' if k == 'nu12' else 'GPa'})"
    # G23 at its bound: no interval, no verdict band, a dashed arrow from the value down to 0
    # (the way the fit pushes it), the limit drawn as a hollow triangle pointing down
    a = ax(fig, f"interval-{MAT}.G23")
    assert not [ln for ln in a.get_lines() if ln.get_gid() in ("interval", "interval-caps",
                                                               "value")]
    assert not a.patches                               # the verdict bands have zero height
    assert a.get_ylim()[0] == 0.0
    arrow = next(t for t in a.texts if t.get_gid() == "one-sided")
    g23 = res.materials[MAT]["G23"] / 1e9
    assert arrow.xyann == (0.0, g23) and arrow.xy == (0.0, 0.0)
    stmt = next(t for t in a.texts if t.get_gid() == "bound-statement").get_text()
    assert stmt.replace("\n", " ") == "stopped on the lower search limit: no interval"
    mark = next(ln for ln in a.get_lines() if ln.get_gid() == "at-bound")
    assert mark.get_marker() == "v" and mark.get_markerfacecolor() == "w"
    assert mark.get_ydata()[0] == g23
    assert a.get_xlabel() == (f"{gpa_text(res.materials[MAT]['G23'])}\non lower search limit:\n"
                              "not identified")
    # E1 (well determined) is not squashed by G23's (undetermined) interval: its panel spans
    # a few tens of % of its value, not the width of G23's interval
    lo, hi = ax(fig, f"interval-{MAT}.E1").get_ylim()
    assert (hi - lo) / (res.materials[MAT]["E1"] / 1e9) < 1.0


def test_at_bound_cell_from_the_limit_and_from_an_older_files_statement(checked, tmp_path):
    """The summary cell of a constant at its bound is its side and limit (the file's
    bound_side, bound_limit: 0.0160 GPa, shown with 4 digits); a file written before those
    datasets gives the same cell from its statement; an upper limit shows "≥"."""
    import dataclasses

    iv = read_result(checked).uncertainty.get(MAT, "G23")
    # no "≤ 0.01600": a constant at its bound has no interval, and the limit is no
    # confidence bound (a Monte Carlo of such a result has trials far above it)
    assert iv.bound_limit == 0.0160e9
    assert interval_text("G23", iv) == "none — on lower search limit"
    old = tmp_path / "old.result.h5"
    shutil.copy(checked, old)
    drop_bound_data(old)
    o = read_result(old).uncertainty.get(MAT, "G23")
    assert (o.bound_side, o.bound_limit) == ("lower", pytest.approx(0.0160e9, rel=1e-12))
    assert interval_text("G23", o) == "none — on lower search limit"
    up = dataclasses.replace(iv, constant="nu12", bound_side="upper", bound_limit=0.95,
                             bound_text="at its bound — not identified: nu12 >= 0.95")
    assert interval_text("nu12", up) == "none — on upper search limit"
    # the side comes from the data, not the words: a bound_text in the new form, or none
    new = dataclasses.replace(up, bound_side="", bound_text="at its bound — not identified: "
                              "stopped on the search's upper limit, nu12 = 0.95")
    assert interval_text("nu12", new) == "none — on upper search limit"
    assert interval_text("nu12", dataclasses.replace(up, bound_text="")) == \
        "none — on upper search limit"
    # neither side nor a readable statement (a hand-edited file): still no interval
    blank = dataclasses.replace(o, bound_side="", bound_text="", bound_limit=np.nan)
    assert interval_text("G23", blank) == "none — on a search limit"


def test_mode_shapes_with_mac_against_the_initial_model(batch_dir, tmp_path):
    path = tmp_path / "S1.4.result.h5"
    shutil.copy(batch_dir / "S1.4.result.h5", path)
    res = read_result(path)
    fr = res.plates[0].frequencies
    # replace the paired shapes by the initial model's modes, computed here independently:
    # the MAC against the initial model must then be 1
    fm = build_forward_model(read_specimen(S14), (6, 6))
    modes = fm.solve(None, fr.model.size)
    w0 = fm.plate.w_shape(modes.phi)
    with h5py.File(path, "r+") as f:
        f["modes"]["w"][...] = w0
    pages = {"modes-1": result_page(path, "modes-1")}
    for k in range(fr.model.size):
        t = ax(pages["modes-1"], f"mode-{k + 1}").get_title()
        # page 1's digits (1 decimal: 125.05 measured, 124.84 model read "125.0", "124.8")
        assert f": {fr.model[k]:.2f} Hz" in t and f"meas. {fr.measured[k]:.2f} Hz" in t
        assert "MAC vs initial 1.00" in t
    # a mode replaced by another one: MAC of two different mode shapes is small
    with h5py.File(path, "r+") as f:
        f["modes"]["w"][:, 0] = w0[:, 1]
    t = ax(result_page(path, "modes-1"), "mode-1").get_title()
    assert f"MAC vs initial {mac(w0[:, 1], w0[:, 0]):.2f}" in t
    assert mac(w0[:, 1], w0[:, 0]) < 0.1
    assert mac([1, 2, 3], [-2, -4, -6]) == pytest.approx(1.0, abs=1e-15)
    assert mac([1, 0], [0, 1]) == 0.0
    # every mode axes of a page has the same size
    sizes = {tuple(np.round(a.get_position().size, 4)) for a in pages["modes-1"].axes
             if (a.get_gid() or "").startswith("mode-")}
    assert len(sizes) == 1
    # the longest titles, every mode paired with another model mode at 4-digit frequencies,
    # clear of each other
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    with h5py.File(path, "r+") as f:
        g = f["frequencies"]
        g["model_mode"][...] = g["model_mode"][()] + 10
        g["model"][...] = g["model"][()] + 1000
        g["measured"][...] = g["measured"][()] + 1000
    fig = result_page(path, "modes-1")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    titles = [a.title for a in fig.axes if (a.get_gid() or "").startswith("mode-")]
    assert all("(model mode " in t.get_text() for t in titles)
    boxes = [t.get_window_extent(renderer) for t in titles]
    assert not [(i, j) for i, a in enumerate(boxes) for j, b in enumerate(boxes[:i])
                if a.overlaps(b)]
    assert all(fig.bbox.x0 <= b.x0 and b.x1 <= fig.bbox.x1 for b in boxes)


def test_no_page_of_a_result_needs_mathtext(checked, checked_pages):
    """Every text of a result's pages is plain (Unicode: Pⱼ, ∂ ln fᵢ, 10⁻³): matplotlib's
    mathtext parser, built on first use, was ~0.3 s of every report command for the
    sensitivity page's labels alone."""
    texts = []
    for fig in checked_pages.values():
        from matplotlib.text import Text

        texts += [t.get_text() for t in fig.findobj(Text)]
        for a in fig.axes:
            for axis in (a.xaxis, a.yaxis):
                texts += [axis.get_major_formatter()(v, 0) for v in axis.get_majorticklocs()]
    assert texts and not [t for t in texts if t.count("$") >= 2]
    sens = checked_pages["sensitivities"]
    assert sens.axes[0].get_xlabel().startswith("ply constant Pⱼ")
    assert sens.axes[1].get_ylabel() == "∂ ln fᵢ / ∂ ln Pⱼ"


def test_history_bound_marks_that_coincide_stand_side_by_side(checked):
    """Constants that end at one bound from one initial value (hybrid CM's glass G12, G13 and
    G23 at 1e-4 E1) end on the same point of the history's panel: one X showed, the others'
    colours hidden under it. They stand side by side now, 9 points apart, at the same height;
    a lone X stays at the last evaluation."""
    import dataclasses

    from laminid_cli.report import history_page, marker_offsets

    assert marker_offsets([0.0015, 0.0015, 12.0, 0.00151], log=True) == [-9.0, 0.0, 0.0, 9.0]
    assert marker_offsets([0.95, 0.5], log=False) == [0.0, 0.0]
    res = read_result(checked)
    h = res.history
    labels = list(h.labels)
    C = h.constants.copy()
    g13, g23 = labels.index(f"{MAT}.G13"), labels.index(f"{MAT}.G23")
    C[:, g13] = C[:, g23] / C[0, g23] * C[0, g13]         # the same ratio to its start
    u = res.uncertainty
    ivs = tuple(dataclasses.replace(iv, at_bound=True) if iv.label == f"{MAT}.G13" else iv
                for iv in u.intervals)
    res = dataclasses.replace(res, history=dataclasses.replace(h, constants=C),
                              uncertainty=dataclasses.replace(u, intervals=ivs))
    fig = history_page(res)
    fig.canvas.draw()
    marks = {ln.get_gid(): ln for a in fig.axes for ln in a.get_lines()
             if (ln.get_gid() or "").startswith("bound-")}
    assert sorted(marks) == [f"bound-{MAT}.G13", f"bound-{MAT}.G23"]
    (x13, y13), (x23, y23) = (marks[f"bound-{MAT}.{k}"].get_transform().transform(
        marks[f"bound-{MAT}.{k}"].get_xydata())[0] for k in ("G13", "G23"))
    assert abs(x23 - x13) == pytest.approx(9.0 * fig.dpi / 72.0, rel=1e-6)
    assert y13 == pytest.approx(y23, abs=1e-6)
    plain = history_page(read_result(checked))          # G23 alone: at the last evaluation
    plain.canvas.draw()
    mark = next(ln for a in plain.axes for ln in a.get_lines()
                if ln.get_gid() == f"bound-{MAT}.G23")
    a = mark.axes
    assert mark.get_transform().transform(mark.get_xydata())[0][0] == pytest.approx(
        a.transData.transform((res.history.evaluation[-1], 1.0))[0], abs=1e-6)


def test_history_on_log_scales_with_bound_hits(checked, checked_pages):
    from laminid_cli.report import power_of_ten

    res = read_result(checked)
    fig = checked_pages["history"]
    a = ax(fig, "objective")
    assert a.get_yscale() == "log"
    # its decades in plain text, not mathtext (whose parser was a quarter of the page's time)
    fmt = a.yaxis.get_major_formatter()
    assert [fmt(v, 0) for v in (1e-6, 1e-1, 1.0, 100.0)] == ["10⁻⁶", "10⁻¹", "10⁰", "10²"]
    assert power_of_ten(2e-5) == "2e-05" and power_of_ten(0.0) == "0"
    # the line: every evaluation but the earlier points evaluated again (drawn apart)
    from laminid_cli.report import revisits

    on = ~revisits(res.history.constants)
    assert np.array_equal(a.get_lines()[0].get_ydata(), res.history.objective[on])
    result = next(ln for ln in a.get_lines() if ln.get_gid() == "result")
    assert result.get_ydata()[0] == res.objective
    assert ax(fig, "rms").get_yscale() == "log"
    hits = [ln.get_gid() for a in fig.axes for ln in a.get_lines()
            if (ln.get_gid() or "").startswith("bound-")]
    assert hits == [f"bound-{MAT}.G23"]
    line = next(ln for a in fig.axes for ln in a.get_lines()
                if ln.get_gid() == f"history-{MAT}.E1")
    col = res.history.constants[:, list(res.history.labels).index(f"{MAT}.E1")]
    assert np.allclose(line.get_ydata(), (col / col[0])[on], rtol=1e-15)
    # reduced solver: predictions (error bound NaN) and checked evaluations marked apart,
    # together every evaluation once
    bound = res.history.error_bound
    pred = next(ln for ln in a.get_lines() if ln.get_gid() == "predicted")
    chk = next(ln for ln in a.get_lines() if ln.get_gid() == "checked")
    assert np.array_equal(pred.get_xdata(), res.history.evaluation[np.isnan(bound)])
    assert np.array_equal(chk.get_ydata(), res.history.objective[np.isfinite(bound)])
    assert pred.get_xdata().size + chk.get_xdata().size == res.history.evaluation.size
    assert 0 < chk.get_xdata().size < pred.get_xdata().size


def test_sensitivity_page(batch_dir):
    path = batch_dir / "S1.4.result.h5"
    res = read_result(path)
    fig = result_page(path, "sensitivities")
    a = ax(fig, "sensitivity")
    assert np.array_equal(a.get_images()[0].get_array(), res.plates[0].sensitivity)
    assert [t.get_text() for t in a.get_xticklabels()] == ["E1", "E2", "G12", "G13", "G23",
                                                          "nu12"]


def test_version_1_file_says_status_not_recorded(batch_dir, tmp_path):
    """A file as schema 1 wrote it (look-alike-slash keys, nlopt outcome in "status", no
    /status, symmetric linear intervals): every page drawn, the status said not recorded."""
    path = tmp_path / "v1.result.h5"
    shutil.copy(batch_dir / "S1.4.result.h5", path)
    make_version_1(path)
    with h5py.File(path) as f:
        assert list(f["materials"]) == ["IM7\u2215977-2"] and "status" not in f
    res = read_result(path)
    assert res.schema_version == 1 and res.status is None and list(res.materials) == [MAT]
    assert res.optimizer_status.startswith("converged")
    pages = {p.name: p.figure for p in report_pages(path)}
    assert list(pages) == ["summary", "intervals", "modes-1", "history", "sensitivities"]
    for name in ("summary", "intervals"):
        status = status_text(pages[name]).get_text()
        assert status.startswith("status not recorded (schema version 1 file); optimizer: "
                                  "converged")
    legend = ax(pages["intervals"], None).get_legend().get_title().get_text()
    assert legend.startswith("linear intervals value ± half-width")
    e1 = res.uncertainty.get(MAT, "E1")
    assert e1.scale == "linear"
    line = next(ln for ln in ax(pages["intervals"], f"interval-{MAT}.E1").get_lines()
                if ln.get_gid() == "interval")
    assert np.allclose(line.get_ydata(), [e1.lower / 1e9, e1.upper / 1e9], rtol=1e-12)


def test_joint_report_shared_constants_then_each_plate(joint, joint_pages, tmp_path):
    res = read_result(joint)
    pages = joint_pages
    names = [p.name for p in pages]
    assert names[:3] == ["shared", "intervals", "history"]
    assert names.index("S1.1-frequencies") < names.index("S1.2-frequencies")
    assert {"S1.1-modes-1", "S1.1-sensitivities", "S1.2-modes-1", "S1.2-sensitivities"} \
        <= set(names)
    figs = dict((p.name, p.figure) for p in pages)
    c = cells(ax(figs["shared"], "constants"))
    assert c[1][1] == fmt_value("E1", res.materials[MAT]["E1"])
    plates = cells(ax(figs["shared"], "plates"))
    assert [row[0] for row in plates[1:]] == ["S1.1", "S1.2"]
    for plate in res.plates:
        bars = ax(figs[f"{plate.name}-frequencies"], "residuals").patches
        assert np.array_equal([b.get_width() for b in bars],
                              np.nan_to_num(plate.frequencies.residual_percent))
        assert plate.name in figs[f"{plate.name}-frequencies"]._suptitle.get_text()
    # (the command's PNG files, one per page: test_png_pages; every joint page drawn:
    # test_status_clear_of_the_titles_on_every_page[joint-worst])


def test_joint_shared_page_gives_each_plates_chi2_summing_to_the_results(joint, joint_pages):
    """The "plates fitted together" table gives each plate's chi2 and fitted modes, "chi2
    (n)", so that a plate that disagrees with the others shows (the RMS alone did not: S1.1-S1.4
    joint, s² = 8.53, S1.3 191 of chi2 358): the plates' chi2, from the file's
    /uncertainty/frequency_sigma, add up to the result's stored chi2 within rtol 1e-9 (the
    uncertainty's residuals, not a near form of them), and a note under the table says the
    total and how to read it."""
    from laminid_cli.report import plate_chi2

    res = read_result(joint)
    with h5py.File(joint, "r") as f:
        stored = float(f["uncertainty"].attrs["chi2"])
    shares = [plate_chi2(p) for p in res.plates]
    fitted = [int((np.isfinite(p.frequencies.measured) & (p.frequencies.weight > 0)).sum())
              for p in res.plates]
    assert [n for _, n in shares] == fitted and all(n > 0 for n in fitted)
    assert all(c is not None and c > 0 for c, _ in shares)
    assert np.isclose(sum(c for c, _ in shares), stored, rtol=1e-9, atol=0)
    assert np.isclose(stored, res.uncertainty.s2 * res.uncertainty.dof, rtol=1e-12)
    shared = next(p.figure for p in joint_pages if p.name == "shared")
    table = cells(ax(shared, "plates"))
    col = table[0].index("chi2 (n)")
    assert [row[col] for row in table[1:]] == [f"{c:.3g} ({n})" for c, n in shares]
    note = next(t for a in shared.axes for t in a.texts if t.get_gid() == "plates-note")
    text = note.get_text().replace("\n", " ")
    assert f"chi2 {stored:.3g}" in text and "disagrees with the others" in text


@pytest.fixture(scope="module")
def joint_prior(tmp_path_factory):
    """S1.1 + S1.2 joint (6x6), both files with ``prior: {E2: 0.001, nu12: 1.0}``: a fit
    whose chi2 holds two prior terms beside the plates' (E2 moved 4.2 % off its initial 8.80
    GPa, weighed 0.001: a term of 0.11; nu12 near its 0.350: 0.046)."""
    tmp = tmp_path_factory.mktemp("joint_prior")
    specs = []
    for src in (S11, S12):
        spec = tmp / Path(src).name
        spec.write_text(Path(src).read_text().replace(
            "    nu12: 0.35\n", "    nu12: 0.35\n    prior: {E2: 0.001, nu12: 1.0}\n", 1))
        specs.append(spec)
    out = tmp / "jp.result.h5"
    r = run("identify", *specs, "--joint", "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    return out


def test_joint_shared_page_with_a_prior_adds_its_terms_to_the_plates_chi2(joint_prior):
    """With a prior (paper Eq. 15) the plates' chi2 fall short of the fit's: the note said
    only "the result's chi2 71.5 adds the prior terms" beside "the fit's chi2 71.5" (the
    plates' sum, S1.1 + S1.2 with prior {nu12: 1.0}: 71.4996 of 71.5065). It now gives each
    prior's term, wp ((P − P0)/P0)² / σ_u² (its term of Eq. 15 over the rows' noise, σ_u the
    RMS of 2σ/f over the fitted modes: uncertainty.design_rows), and the sum: plates' +
    priors' = the stored chi2 within rtol 1e-9, each number written with the same decimals.
    Prior {E2: 0.001, nu12: 1.0}: E2's term 0.001 times its unweighted 3.06."""
    from laminid_cli.report import plate_chi2, prior_chi2

    res = read_result(joint_prior)
    with h5py.File(joint_prior, "r") as f:
        stored = float(f["uncertainty"].attrs["chi2"])
    plates = sum(plate_chi2(p)[0] for p in res.plates)
    fitted = [np.isfinite(p.frequencies.measured) & (p.frequencies.weight > 0)
              for p in res.plates]
    rel = np.concatenate([(2 * p.frequencies.sigma_hz / p.frequencies.measured)[ok]
                          for p, ok in zip(res.plates, fitted)])
    sigma_u = np.sqrt(np.mean(rel**2))
    assert np.isclose(sigma_u, 0.004, rtol=1e-12)         # 2 × the default 0.2 %
    expect = {f"{MAT}.{k}": wp * ((res.materials[MAT][k] - res.initial[MAT][k])
                                  / res.initial[MAT][k] / sigma_u) ** 2
              for k, wp in (("E2", 0.001), ("nu12", 1.0))}
    terms = prior_chi2(res)
    assert terms.keys() == expect.keys()
    assert all(np.isclose(terms[k], expect[k], rtol=1e-12) for k in expect)
    # E2 4.2 % off its 8.80 GPa: 0.001 (0.042 / 0.004)^2 = 0.110; nu12 0.0009 off its 0.35
    assert 0.05 < terms[f"{MAT}.E2"] < 0.5 and 0.01 < terms[f"{MAT}.nu12"] < 0.1
    # without the priors' terms the plates' chi2 miss the stored one by far more than 1e-9
    assert not np.isclose(plates, stored, rtol=1e-6, atol=0)
    assert np.isclose(plates + sum(terms.values()), stored, rtol=1e-9, atol=0)
    shared = result_page(joint_prior, "shared")
    note = next(t for a in shared.axes for t in a.texts if t.get_gid() == "plates-note")
    text = " ".join(note.get_text().split()).replace("\u00a0", " ")
    d = int(2 - np.floor(np.log10(terms[f"{MAT}.nu12"])))
    assert (f"the fit's chi2 {stored:.{d}f} = the plates' {plates:.{d}f} + the prior's on E2 "
            f"{terms[f'{MAT}.E2']:.{d}f} + on nu12 {terms[f'{MAT}.nu12']:.{d}f}") in text
    assert "paper Eq. 15" in text and "is not the plates'" not in text
    # the numbers as written add up (to the last decimal written, rounding aside)
    nums = [float(x) for x in re.search(
        r"chi2 ([\d.]+) = the plates' ([\d.]+) \+ the prior's on E2 ([\d.]+) \+ on nu12 "
        r"([\d.]+)", text).groups()]
    assert abs(nums[0] - sum(nums[1:])) <= 1.5 * 10.0 ** -d


def test_joint_plates_table_header_within_its_cells(joint):
    """The plates table's header "modes measured" (8-point bold) ran over its cell into
    "mesh" ("modes measurec" on the PNG: 95 % of the cell's width by the font's metrics, the
    glyphs reach further) and "RMS residual (%)" touched its borders (92 %); every header's
    text now lies inside its cell with 5 % of its width to spare on each side."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    shared = result_page(joint, "shared")
    renderer = FigureCanvasAgg(shared).get_renderer()
    shared.draw(renderer)
    table = ax(shared, "plates").tables[0]
    heads = [(c, cell) for (i, c), cell in table.get_celld().items() if i == 0]
    assert sorted(cell.get_text().get_text() for _, cell in heads) == sorted(
        ["plate", "RMS residual (%)", "chi2 (n)", "modes measured", "mesh"])
    for _, cell in heads:
        box = cell.get_window_extent(renderer)
        inner = cell.get_text().get_window_extent(renderer)
        pad = 0.05 * box.width
        assert box.x0 + pad < inner.x0 and inner.x1 < box.x1 - pad, cell.get_text().get_text()


def _s21_modes(n_modes: int, n_points: int):
    """S2.1's first ``n_modes`` frequencies (6x6, initial constants) and modal constants of
    ``n_points`` points (seeded), to synthesise its FRFs; with the generator, for more draws."""
    fm = build_forward_model(read_specimen(S21), (6, 6))
    f_true = fm.solve([fm.initial_constants[0]], n_modes).freq
    rng = np.random.default_rng(3)
    shape = (n_points, n_modes)
    return f_true, rng.choice([-1, 1], size=shape) * rng.uniform(0.3, 1.0, size=shape), rng


def _identify_from_frf_file(folder, n_modes: int):
    """S2.1 identified (6x6, E1, E2, G12) from the lowest ``n_modes`` of ``folder``'s
    plate.frf.h5 (``measured.frf_file``); the result file's path."""
    text = Path(S21).read_text().replace(MEASURED_BLOCK,
                                    f"  frf_file: plate.frf.h5\n  modes: {n_modes}")
    (folder / "plate.yaml").write_text(text)
    res = folder / "plate.result.h5"
    r = run("identify", folder / "plate.yaml", "--mesh", "6x6", "--fix", "nu12,G13,G23",
            "-o", res)
    assert r.exit_code == 0, r.output
    return res


@pytest.fixture(scope="module")
def frf_case(tmp_path_factory):
    """S2.1 fitted from an FRF file of 8 modes, 3 points, with coherence (the report has an
    FRF page): (result file, the modes' frequencies, the FRFs, the coherence). Read by
    test_frf_page_for_a_specimen_fitted_from_an_frf_file and, as frf_result, by
    test_status_clear_of_the_titles_on_every_page, which each fitted and identified it (~2 s);
    neither changes the files."""
    tmp = tmp_path_factory.mktemp("frfres")
    f_true, constants, rng = _s21_modes(8, 3)
    freq = np.arange(0.5, 700.0, 0.5)
    frf = synth_frf(freq, np.column_stack([f_true, np.full(8, 0.008)]), constants,
                    kind="accelerance", noise=0.005, seed=4)
    coherence = np.clip(1 - 0.05 * rng.random(frf.shape), 0, 1)
    write_frf_h5(tmp / "plate.frf.h5", freq, frf, coherence, units="(m/s^2)/N")
    return _identify_from_frf_file(tmp, 8), f_true, frf, coherence


def test_frf_page_for_a_specimen_fitted_from_an_frf_file(frf_case, tmp_path, monkeypatch):
    res, f_true, frf, coherence = frf_case
    # the pages the command builds (its FRF fit included) and writes are the ones read here
    built = pages_the_command_builds(monkeypatch)
    r = run("report", res, "-o", tmp_path / "plate.png", "--dpi", "50")
    assert r.exit_code == 0, r.output
    # "N pages (summary, ..., frf, ...) written to plate-1.png, ...": the FRF page's own file
    names = r.output.split("(", 1)[1].split(")", 1)[0].split(", ")
    k = names.index("frf") + 1
    assert f"plate-{k}.png" in r.output
    assert (tmp_path / f"plate-{k}.png").read_bytes()[:8] == PNG
    (pages,) = built
    assert [p.name for p in pages] == names
    fig = {p.name: p.figure for p in pages}["frf"]
    a = ax(fig, "frf")
    dashed = [ln.get_xdata()[0] for ln in a.get_lines() if ln.get_linestyle() == "--"]
    assert np.allclose(sorted(dashed), f_true, rtol=1e-3)                # RFP modes
    # labelled in page 1's digits: the measured column of its table, fitted from this file
    from laminid_cli.report import frequency_rows

    tags = sorted((t.xy[0], t.get_text()) for t in a.texts if t.get_gid() != "view-note")
    page1 = [row[2] for row in frequency_rows(read_result(res).plates[0])[1]]
    assert [t for _, t in tags] == page1, (tags, page1)
    dotted = [ln.get_xdata()[0] for ln in a.get_lines() if ln.get_linestyle() == ":"]
    assert np.array_equal(dotted, read_result(res).plates[0].frequencies.model)
    measured = [ln for ln in a.get_lines() if ln.get_color() == "k"]
    fitted = [ln for ln in a.get_lines() if ln.get_linestyle() == "-" and ln.get_color() != "k"]
    assert len(measured) == 3 and fitted
    assert min(ln.get_zorder() for ln in measured) > max(ln.get_zorder() for ln in fitted)
    with np.errstate(divide="ignore"):
        assert np.array_equal(measured[0].get_ydata(), 20 * np.log10(np.abs(frf[0])))
    assert a.get_ylabel() == "|H| (dB re 1 (m/s^2)/N)"
    labels = a.get_legend().get_texts()
    assert [t.get_text() for t in labels][:2] == ["measured (3 points)",
                                                  "RFP fit (one colour per band)"]
    # the frequencies' doubt: the span of the sigmas identify took from this file's fit (the
    # labels were the values alone)
    with h5py.File(res) as f:
        sig = next(iter(f["uncertainty/frequency_sigma"].values()))[()]    # the one plate's
    assert labels[2].get_text() == (f"RFP natural frequency (± {sig.min():.3g}–{sig.max():.3g} "
                                    "Hz, one standard deviation)")
    coh = next(x for x in fig.axes if x.get_ylabel() == "coherence (–)")
    lines = [ln for ln in coh.get_lines() if ln.get_gid() == "coherence"]
    assert len(lines) == 3 and np.array_equal(lines[0].get_ydata(), coherence[0])
    assert not [t for t in fig.texts if t.get_gid() == "frf-changed"]   # the file identified


def test_frf_page_of_an_frf_file_changed_since_the_identification_says_so(tmp_path, caplog):
    """The FRF page draws the specimen's FRF file as it is when the report is made: where its
    fit no longer gives the frequencies the identification used (a record replaced, points
    added), the page and a warning say so, naming the mode that moved most."""
    import logging

    f_true, constants, _ = _s21_modes(6, 2)
    freq = np.arange(0.5, 560.0, 0.5)

    def write(shift):
        frf = synth_frf(freq, np.column_stack([f_true * shift, np.full(6, 0.008)]), constants,
                        kind="accelerance", noise=0.0, seed=4)
        path = tmp_path / "plate.frf.h5"
        path.unlink(missing_ok=True)
        write_frf_h5(path, freq, frf, units="(m/s^2)/N")

    write(np.ones(6))
    res = _identify_from_frf_file(tmp_path, 6)
    used = read_result(res).plates[0].frequencies.measured
    write(np.r_[1, 1, 1.003, 1, 1, 1])                 # mode 3 now 0.3 % higher
    with caplog.at_level(logging.WARNING, logger="laminid_cli.report"):
        fig = {p.name: p.figure for p in report_pages(res)}["frf"]
    note = [t.get_text() for t in fig.texts if t.get_gid() == "frf-changed"]
    assert len(note) == 1 and note[0].startswith("plate.frf.h5: its fit now gives mode 3 at ")
    now = float(note[0].split("mode 3 at ")[1].split(" Hz")[0])
    assert now == pytest.approx(used[2] * 1.003, rel=1e-5)
    words = " ".join(note[0].split())
    assert (f"the identification used {used[2]:.10g} Hz (+{now - used[2]:.2g} Hz, 0.3 %): not "
            "the FRFs identified from (the file changed since)") in words
    assert [m for m in caplog.messages if "its fit now gives mode 3" in m]
    # the same file given with --frf (which may have been fitted with other bands, fit-frf
    # --band ... --into): drawn as it is, without the claim
    fig = {p.name: p.figure for p in report_pages(res, frf_path=tmp_path / "plate.frf.h5")}
    assert not [t for t in fig["frf"].texts if t.get_gid() == "frf-changed"]


def test_frf_fit_changed_words():
    from laminid_cli.report import frf_fit_changed

    assert frf_fit_changed([100.0, 200.0], [100.0, 200.0 * (1 + 1e-7)]) is None
    assert frf_fit_changed([100.0, 201.0], [100.0, 200.0]) == (
        "its fit now gives mode 2 at 201 Hz, the identification used 200 Hz (+1 Hz, 0.5 %): "
        "not the FRFs identified from (the file changed since)")
    # digits enough to show the difference
    assert frf_fit_changed([23.45674, 101.2], [23.4567, 101.2]).startswith(
        "its fit now gives mode 1 at 23.45674 Hz, the identification used 23.4567 Hz (+4e-05 "
        "Hz, 0.00017 %)")
    assert frf_fit_changed([100.0, 200.0, 300.0], [100.0, 200.0]).startswith(
        "its fit now gives 3 modes, the identification used 2 frequencies")
    assert frf_fit_changed([np.nan, 250.0], [100.0, 250.0]).startswith(
        "its fit now finds no mode 1, the identification used 100 Hz")
    assert frf_fit_changed([100.0, 250.0], [np.nan, 250.0]) is None      # not measured


def test_report_of_a_batch_summary(batch_dir, tmp_path, monkeypatch):
    # the pages the command builds and writes for each summary are the ones read below
    written = pages_the_command_builds(monkeypatch)
    built = {}
    for src in ("summary.csv", "summary.json"):
        out = tmp_path / (src + ".png")
        r = run("report", batch_dir / src, "-o", out, "--dpi", "50")
        assert r.exit_code == 0, r.output
        assert len(list(tmp_path.glob(src + "-*.png"))) == 2
        built[src] = {p.name: p.figure for p in written[-1]}
        assert list(built[src]) == ["constants", "residuals"]
    pages = built["summary.csv"]
    a = ax(pages["constants"], "across-E1")
    res = read_result(batch_dir / "S1.4.result.h5")
    v = next(ln for ln in a.get_lines() if ln.get_gid() == f"value-S1.4-{MAT}")
    assert v.get_ydata()[0] == res.materials[MAT]["E1"] / 1e9
    ref = next(ln for ln in a.get_lines() if ln.get_gid() == f"reference-S1.4-{MAT}")
    assert ref.get_ydata()[0] == 170.0
    ticks = [t.get_text() for t in a.get_xticklabels()]
    assert ticks == ["S1.4", "S2.1"]
    assert [t.get_text() for t in ax(pages["residuals"], "rms").get_xticklabels()] == ticks
    # G13 of S1.4 is not determined: hollow marker and "?"
    g = ax(pages["constants"], "across-G13")
    m = next(ln for ln in g.get_lines() if ln.get_gid() == f"value-S1.4-{MAT}")
    assert m.get_markerfacecolor() == "w" and any(t.get_text() == "?" for t in g.texts)
    # G13 of S2.1 (6x6) stopped on its lower limit and its profile bounds it (< ~1.5 GPa):
    # the values the fit does not reject, dotted from the limit up to the profile's bound,
    # from both summaries alike, in the legend
    s21 = read_result(batch_dir / "S2.1.result.h5").uncertainty.get("E-glass/R368", "G13")
    assert s21.profile_kind == "bound" and 0.1e9 < s21.profile_bound < 18.5e9
    for src in ("summary.csv", "summary.json"):
        pages = built[src]
        g = ax(pages["constants"], "across-G13")
        prof = [ln for ln in g.get_lines() if ln.get_gid() == "profile"]
        assert len(prof) == 1 and prof[0].get_linestyle() != "-"          # dotted
        assert np.allclose(sorted(prof[0].get_ydata()),
                           [s21.bound_limit / 1e9, s21.profile_bound / 1e9], rtol=1e-12)
        legend = [t.get_text() for t in pages["constants"].legends[0].get_texts()] if \
            pages["constants"].legends else [t.get_text() for a in pages["constants"].axes
                                            if a.get_legend() for t in a.get_legend().get_texts()]
        assert "values the fit does not reject (profile of a constant on a search limit);" \
            "\ncap: it rejects beyond" in legend
        (cap,) = [ln for ln in g.get_lines() if ln.get_gid() == "profile-cap-S2.1-E-glass/R368"]
        assert cap.get_marker() == "_"                   # where the fit rejects beyond
        assert cap.get_ydata()[0] == pytest.approx(s21.profile_bound / 1e9, rel=1e-12)


def test_summary_puts_the_materials_of_one_specimen_side_by_side(tmp_path):
    from laminid_cli.report import constants_across_page

    row = {"name": "H1", "status": "ok"}
    mats = {"glass": {"E1": 45e9, "E2": 9e9, "G12": 3e9, "G13": 3e9, "G23": 3e9, "nu12": 0.3},
            "carbon": {"E1": 120e9, "E2": 8e9, "G12": 4e9, "G13": 4e9, "G23": 3e9,
                       "nu12": 0.3}}
    fig = constants_across_page([(row, mats, None), (dict(row, name="H2"), mats, None)], "t")
    a = ax(fig, "across-E1")
    xs = {ln.get_gid(): ln.get_xdata()[0] for ln in a.get_lines()}
    assert xs["value-H1-glass"] < 0 < xs["value-H1-carbon"] < 1
    assert xs["value-H2-glass"] < 1 < xs["value-H2-carbon"]
    write_pages([type("P", (), {"name": "x", "figure": fig})()], tmp_path / "x.png")


def test_summary_draws_a_flat_profile_to_the_other_end_of_its_scan():
    """A constant on a search limit whose profile is flat (the fit rejects no value up to the
    search's other end): dotted from the limit to that end (G13: 0.003 -> 18.5 GPa, off the
    panel, clipped at its top; nu12: 0.95 -> 0 within the panel), not a bound."""
    from laminid_cli.report import constants_across_page

    mats = {"glass": {"E1": 45e9, "E2": 9e9, "G12": 3e9, "G13": 3e6, "G23": 3e9, "nu12": 0.95}}
    flat = dict(verdict="at bound — not identified", at_bound=True, profile="flat",
                profile_bound=None)
    row = {"name": "H1", "status": "check", "intervals": {"glass": {
        "G13": dict(flat, bound_side="lower", bound_limit=3e6, profile_far=18.5e9),
        "nu12": dict(flat, bound_side="upper", bound_limit=0.95, profile_far=0.0)}}}
    fig = constants_across_page([(row, mats, None)], "t")
    g = ax(fig, "across-G13")
    (line,) = [ln for ln in g.get_lines() if ln.get_gid() == "profile"]
    lo, hi = sorted(line.get_ydata())
    assert lo == pytest.approx(0.003) and hi == pytest.approx(g.get_ylim()[1]) and hi < 18.5
    n = ax(fig, "across-nu12")
    (line,) = [ln for ln in n.get_lines() if ln.get_gid() == "profile"]
    assert sorted(line.get_ydata()) == pytest.approx([0.0, 0.95])
    assert n.get_ylim()[0] <= 0.0


@pytest.mark.parametrize("name", ["plate.frf.h5", "plate.csv", "plate.uff"])
def test_report_of_an_frf_file_suggests_fit_frf_plot_and_identify(tmp_path, name):
    """`report plate.frf.h5` said only 'make one with laminid identify SPEC.yaml'; a CSV FRF
    file was 'not a laminid batch summary', a UFF 'not an HDF5 file'. Each now says it is an
    FRF file, that fit-frf --plot draws it and how a result (for a report) is made."""
    from laminid_cli.frf import io
    from laminid_cli.frf.store import FrfSet

    freq = np.arange(1.0, 100.0, 0.25)
    frf = synth_frf(freq, np.array([[30.0, 0.01], [70.0, 0.01]]), np.array([[1.0, -0.5]]),
                    kind="accelerance", noise=0.001, seed=1)
    path = io.write_frf(tmp_path / name, FrfSet(freq=freq, frf=frf))
    r = run("report", path, "-o", tmp_path / "r.pdf")
    assert r.exit_code == 2, r.output
    assert " ".join(r.output.split()) == (
        f"laminid: error: {path}: an FRF file, not an identification result: laminid fit-frf "
        f"{path} --plot plate.fit.pdf draws its FRFs and their fit; a result is made from it "
        f"by laminid fit-frf {path} --into SPEC.yaml, then laminid identify SPEC.yaml")
    assert not (tmp_path / "r.pdf").exists()
    # show says the same (a CSV of FRFs was "a batch summary is text already", a UFF "not an
    # HDF5 file, so not a laminid identification result"; "a report needs" fits no show)
    r = run("show", path)
    assert r.exit_code == 2 and r.stdout == ""
    assert " ".join(r.stderr.split()) == (
        f"laminid: error: {path}: an FRF file, not an identification result: laminid fit-frf "
        f"{path} --plot plate.fit.pdf draws its FRFs and their fit; a result is made from it "
        f"by laminid fit-frf {path} --into SPEC.yaml, then laminid identify SPEC.yaml")
    # and the command it suggests draws the file
    r = run("fit-frf", path, "--plot", tmp_path / "plate.fit.pdf")
    assert r.exit_code == 0 and (tmp_path / "plate.fit.pdf").exists(), r.output


def test_report_and_show_of_a_specimen_file_name_it_and_the_command(tmp_path):
    """`report S1.1.yaml` / `show S1.1.yaml` (the specimen where its result is meant) said
    "not an HDF5 file, so not a laminid identification result; make one with laminid identify
    SPEC.yaml": it names the file a specimen and the identify command that makes its result."""
    spec = tmp_path / "S1.1.yaml"
    spec.write_text(Path("specimens/example1/S1.1.yaml").read_text())
    said = (f"laminid: error: {spec}: a specimen file, not an identification result; laminid "
            f"identify {spec} makes its result ({tmp_path / 'S1.1.result.h5'})")
    for command in ("report", "show"):
        r = run(command, spec)
        assert r.exit_code == 2 and r.stdout == "", r.output
        assert " ".join(r.stderr.split()) == said, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["S1.1.yaml"]


def test_report_errors(batch_dir, tmp_path):
    bad = tmp_path / "x.h5"
    with h5py.File(bad, "w") as f:
        f.attrs["format"] = "laminid-frf"
    r = run("report", bad, "-o", tmp_path / "x.pdf")
    assert r.exit_code == 2
    assert "an FRF file, not an identification result" in r.output
    r = run("report", batch_dir / "S1.4.result.h5", "-o", tmp_path / "x.svg")
    assert r.exit_code == 2 and "use .pdf or .png" in r.output
    (tmp_path / "s.csv").write_text("a,b\n1,2\n")
    r = run("report", tmp_path / "s.csv", "-o", tmp_path / "s.pdf")
    assert r.exit_code == 2 and "not a laminid batch summary" in r.output
    (tmp_path / "t.h5").write_text("not hdf5")
    r = run("report", tmp_path / "t.h5", "-o", tmp_path / "t.pdf")
    assert r.exit_code == 2 and "not an HDF5 file" in r.output and "laminid identify" in r.output
    assert not list(tmp_path.glob("*.pdf"))


def _with_monte_carlo(checked, tmp_path, lower_at_bound=None, inner=False, upper_at_bound=None):
    """A copy of the checked result with a Monte Carlo range of 0.97 .. 1.02 x each value (and
    ``lower_at_bound`` flags, with ``upper_at_bound`` or no upper end at a bound, when given;
    ``inner``: the width for sure 0.98 .. 1.01 x, as files since stop 28 have it)."""
    path = tmp_path / "mc.result.h5"
    shutil.copy(checked, path)
    with h5py.File(path, "r+") as f:
        v = f["uncertainty"]["value"][()]
        g = f["uncertainty"].create_group("monte_carlo")
        g.create_dataset("lower", data=0.97 * v)
        g.create_dataset("upper", data=1.02 * v)
        if inner:
            g.create_dataset("inner_lower", data=0.98 * v)
            g.create_dataset("inner_upper", data=1.01 * v)
            g.attrs["evidence_level"] = 0.95
        if lower_at_bound is not None:
            g.create_dataset("lower_at_bound", data=np.asarray(lower_at_bound, np.int8))
            g.create_dataset("upper_at_bound", data=np.zeros(v.size, np.int8)
                             if upper_at_bound is None else np.asarray(upper_at_bound, np.int8))
    return path


def test_monte_carlo_spread_drawn_beside_the_interval(checked, tmp_path):
    path = _with_monte_carlo(checked, tmp_path)
    res = read_result(path)
    fig = result_page(path, "intervals")
    a = ax(fig, f"interval-{MAT}.E1")
    line = next(ln for ln in a.get_lines() if ln.get_gid() == "monte-carlo")
    e1 = res.materials[MAT]["E1"] / 1e9
    assert np.allclose(line.get_ydata(), [0.97 * e1, 1.02 * e1], rtol=1e-12)
    assert not [t for t in a.texts if "limit" in (t.get_gid() or "")]
    assert not [ln for ln in a.get_lines() if ln.get_gid() == "monte-carlo-sure"]  # older file
    # the width the trials show for sure (what the verdicts use), over the spread, in the legend
    fig = result_page(_with_monte_carlo(checked, tmp_path, inner=True), "intervals")
    a = ax(fig, f"interval-{MAT}.E1")
    sure = next(ln for ln in a.get_lines() if ln.get_gid() == "monte-carlo-sure")
    assert np.allclose(sure.get_ydata(), [0.98 * e1, 1.01 * e1], rtol=1e-12)
    assert sure.get_xdata()[0] == line.get_xdata()[0]
    texts = [t.get_text() for a_ in fig.axes if a_.get_legend() is not None
             for t in a_.get_legend().get_texts()]
    assert "Monte Carlo range for sure (90 %)" in texts


def test_monte_carlo_range_with_both_ends_on_search_limits_close_together_has_one_label(
        checked, tmp_path):
    """Both ends of a Monte Carlo range set by trials on search limits (S2.1 8x8: all ten
    trials on G13's lower limit 1e-4 E1, which moves with E1: 0.002879 .. 0.003000 GPa) got a
    "search limit" label each, written over each other beside the short bar; one label now,
    beside its middle, saying both ends."""
    with h5py.File(checked) as f:
        flags = np.zeros(f["uncertainty"]["value"].size, np.int8)
    flags[1] = 1                                        # E2: 0.97 .. 1.02 x, both ends
    path = _with_monte_carlo(checked, tmp_path, lower_at_bound=flags, upper_at_bound=flags)
    e2 = read_result(path).materials[MAT]["E2"] / 1e9
    a = ax(result_page(path, "intervals"), f"interval-{MAT}.E2")
    labels = [t for t in a.texts if "limit" in (t.get_gid() or "")]
    assert [t.get_gid() for t in labels] == ["monte-carlo-both-limit"]
    assert labels[0].get_text() == "search\nlimit\n(both\nends)"
    lo, hi = a.get_ylim()
    assert labels[0].xy[1] == pytest.approx(0.5 * (0.97 + 1.02) * e2, rel=1e-12)
    assert (1.02 - 0.97) * e2 < 0.12 * (hi - lo)        # as near as the rule says


def test_monte_carlo_range_end_at_a_search_limit_is_labelled(checked, tmp_path):
    """A Monte Carlo range end set by trials on a limit of the search (the file's
    /uncertainty/monte_carlo/lower_at_bound) is labelled "search limit" at that end, on that
    constant's panel only."""
    with h5py.File(checked) as f:
        flags = np.zeros(f["uncertainty"]["value"].size, np.int8)
    flags[1] = 1                                        # E2's lower end
    path = _with_monte_carlo(checked, tmp_path, lower_at_bound=flags)
    res = read_result(path)
    fig = result_page(path, "intervals")
    a = ax(fig, f"interval-{MAT}.E2")
    label = next(t for t in a.texts if t.get_gid() == "monte-carlo-lower-limit")
    assert label.get_text() == "search\nlimit"
    assert label.xy[1] == pytest.approx(0.97 * res.materials[MAT]["E2"] / 1e9, rel=1e-12)
    assert not [t for t in ax(fig, f"interval-{MAT}.E1").texts
                if "limit" in (t.get_gid() or "")]


def test_laminate_reference_values_on_the_summary_page(batch_dir):
    path = batch_dir / "S2.1.result.h5"
    res = read_result(path)
    assert res.plates[0].reference_global == {"Ey": (22.5e9, 22.5e9)}    # S2.1.yaml
    fig = result_page(path, "summary")
    text = " ".join(t.get_text() for a in fig.axes for t in a.texts).replace("\n", " ")
    ey = res.plates[0].global_properties["Ey"] / 1e9
    rel = res.plates[0].global_uncertainty["Ey"]["rel_half_width"]       # its doubt, then the
    assert f"Ey {ey:.2f} GPa ±{rel * 100:.2g} % (reference 22.5 GPa)" in text   # reference


def test_laminate_moduli_below_a_gpa_keep_their_digits():
    """Page 1's laminate line: a modulus below 1 GPa with 3 digits, as the terminal's
    tables (Gxz of moduli written in MPa showed "0.00 GPa")."""
    from types import SimpleNamespace

    from laminid_cli.report import _laminate_text

    plate = SimpleNamespace(global_properties={"Ex": 0.0445e9, "Gxy": 0.1672e9, "Gxz": 3.1e6,
                                               "Ey": 62.43e9, "nu_xy": 0.333},
                            reference_global={}, global_uncertainty={})
    assert _laminate_text(plate) == ("laminate (Appendix A): Ex 0.0445 GPa, Gxy 0.167 GPa, "
                                     "Gxz 0.0031 GPa, Ey 62.43 GPa, nu_xy 0.333")


def test_reference_range_words_and_difference():
    """A range is written low–high and compared by its nearer end (0 inside it); one value
    is a range of no width, so its difference is the usual one."""
    assert fmt_reference("E1", (120e9, 150e9)) == "120.00–150.00"
    assert fmt_reference("E1", (170e9, 170e9)) == "170.00"
    assert fmt_reference("nu12", (0.3, 0.4)) == "0.300–0.400"
    assert reference_diff(130e9, (120e9, 150e9)) == 0.0
    assert reference_diff(150e9, (120e9, 150e9)) == 0.0
    assert reference_diff(165e9, (120e9, 150e9)) == pytest.approx(0.10, rel=1e-12)
    assert reference_diff(108e9, (120e9, 150e9)) == pytest.approx(-0.10, rel=1e-12)
    assert reference_diff(187e9, (170e9, 170e9)) == pytest.approx(0.10, rel=1e-12)
    assert reference_diff(-0.1, (0.0, 0.3)) is None        # no relative difference from 0


@pytest.fixture(scope="module")
def ranged_batch(tmp_path_factory):
    """A batch of S1.4 with E1's reference [120 GPa, 150 GPa] and nu_xy's [0.05, 0.07]
    (clihelp.S14_RANGES), 6x6: its output folder."""
    tmp = tmp_path_factory.mktemp("ranged")
    write_s14_with_ranges(tmp)
    r = run("batch", tmp, "--mesh", "6x6", "--out", tmp / "out")
    assert r.exit_code == 0, r.output
    return tmp / "out"


def test_a_reference_range_in_the_table_the_panels_and_across_specimens(ranged_batch):
    """E1's reference range: "120.0–150.0" and the difference from its nearer end in the
    table (once an empty cell), a red bar from 120 to 150 on its panel (a single value stays
    a diamond), a capped black bar across specimens; nu_xy's range beside the laminate."""
    path = ranged_batch / "S1.4r.result.h5"
    res = read_result(path)
    e1 = res.materials[MAT]["E1"]
    assert e1 > 150e9                         # the 6x6 S1.4 lands above the range (~162 GPa)
    pages = {name: result_page(path, name) for name in ("summary", "intervals")}
    rows = {row[0].split(" ")[0]: row for row in cells(ax(pages["summary"], "constants"))[1:]}
    assert rows["E1"][5] == f"120.00–150.00\n(+{round((e1 / 150e9 - 1) * 100)} % above)"
    g12 = res.materials[MAT]["G12"]
    assert rows["G12"][5] == f"5.80 ({round((g12 / 5.8e9 - 1) * 100):+d} %)"
    # (E2, not determined by S1.4's modes at 6x6: its reference not compared)
    assert rows["E2"][3] == "not determined" and rows["E2"][5] == "10.00\n(not compared)"
    text = " ".join(t.get_text() for a in pages["summary"].axes
                    for t in a.texts).replace("\n", " ")
    assert "nu_xy" in text and "(reference 0.05–0.07)" in text
    assert ("reference low–high: a range given by the specimen file; (inside): the value is "
            "within it, else the difference from its nearer end") in text
    fig = pages["intervals"]
    a = ax(fig, f"interval-{MAT}.E1")
    bar = next(ln for ln in a.get_lines() if ln.get_gid() == "reference-range")
    assert list(bar.get_xdata()) == [0.25, 0.25] and list(bar.get_ydata()) == [120.0, 150.0]
    assert not [ln for ln in a.get_lines() if ln.get_gid() == "reference"]
    assert a.get_ylim()[0] < 120.0 and 150.0 < a.get_ylim()[1]
    d = next(ln for ln in ax(fig, f"interval-{MAT}.E2").get_lines()
             if ln.get_gid() == "reference")
    assert d.get_marker() == "D" and list(d.get_ydata()) == [10.0]
    legend = [t.get_text() for t in ax(fig, None).get_legend().get_texts()]
    assert "reference (no uncertainty given)" in legend and "reference range" in legend
    across = {p.name: p.figure for p in report_pages(ranged_batch / "summary.json")}
    a = ax(across["constants"], "across-E1")
    bar = next(ln for ln in a.get_lines()
               if (ln.get_gid() or "").startswith("reference-range-"))
    assert list(bar.get_ydata()) == [120.0, 150.0] and bar.get_marker() == "_"
    assert not [ln for ln in a.get_lines()
                if (ln.get_gid() or "").startswith("reference-") and ln is not bar]
    legend = [t.get_text() for x in across["constants"].axes if x.get_legend() is not None
              for t in x.get_legend().get_texts()]
    assert "reference range (left of the value)" in legend
    # (the single values beside it: G12 5.8 GPa, nu12 0.35, E2 10 GPa)
    assert "reference value (no uncertainty given)" in legend


def test_a_reference_point_is_said_to_carry_no_uncertainty(batch_dir):
    """A reference the specimen file gives as one value was drawn as a bare point (a red
    diamond, keyed "reference"; a black tick "reference value" across specimens), which reads
    as an exact value: S1.4's strain-gauge E1 170, E2 10, G12 5.8 GPa, nu12 0.35, whose
    source's words give "170 ± 1 GPa". The keys now say "no uncertainty given" and page 1's
    notes say that the file's reference block gives none and that a [low, high] would be
    drawn as a range; S2.1, with no material reference (a laminate Ey only), gets neither."""
    from laminid_cli.report import REFERENCE_POINT_NOTE

    path = batch_dir / "S1.4.result.h5"
    res = read_result(path)
    assert {k: v for k, v in res.reference[MAT].items()} == {
        "E1": (170e9, 170e9), "E2": (10e9, 10e9), "G12": (5.8e9, 5.8e9), "nu12": (0.35, 0.35)}
    assert "170 ± 1 GPa" in res.reference_source
    fig = result_page(path, "intervals")
    for k, v in (("E1", 170.0), ("E2", 10.0), ("G12", 5.8), ("nu12", 0.35)):
        d = next(ln for ln in ax(fig, f"interval-{MAT}.{k}").get_lines()
                 if ln.get_gid() == "reference")
        assert d.get_marker() == "D" and np.isclose(d.get_ydata()[0], v, rtol=1e-12)
    legend = [t.get_text() for t in ax(fig, None).get_legend().get_texts()]
    assert "reference (no uncertainty given)" in legend and "reference" not in legend
    assert "reference range" not in legend
    notes = " ".join(t.get_text() for a in result_page(path, "summary").axes
                     for t in a.texts if t.get_gid() == "notes").replace("\n", " ")
    assert " ".join(REFERENCE_POINT_NOTE.split()) in " ".join(notes.split())
    assert REFERENCE_POINT_NOTE.startswith("reference without a range: the specimen file's "
                                           "reference block gives one value and no uncertainty")
    s21 = batch_dir / "S2.1.result.h5"
    assert read_result(s21).reference == {}
    notes = " ".join(t.get_text() for a in result_page(s21, "summary").axes
                     for t in a.texts if t.get_gid() == "notes")
    assert "no uncertainty" not in notes
    across = {p.name: p.figure for p in report_pages(batch_dir / "summary.csv")}
    legend = [t.get_text() for x in across["constants"].axes if x.get_legend() is not None
              for t in x.get_legend().get_texts()]
    assert "reference value (no uncertainty given)" in legend and "reference value" not in legend
    ticks = [ln for a in across["constants"].axes for ln in a.get_lines()
             if (ln.get_gid() or "").startswith("reference-S1.4-")]
    assert sorted(float(ln.get_ydata()[0]) for ln in ticks) == [0.35, 5.8, 10.0, 170.0]


def _no_overlap(fig, axis, legend, *, draw=True) -> bool:
    """The legend's box is outside the axes' box (laid-out figure, display coordinates);
    ``draw=False`` where the caller laid the figure out and changed nothing since."""
    if draw:
        fig.draw_without_rendering()
    a = axis.get_window_extent()
    b = legend.get_window_extent()
    return b.x0 >= a.x1 or b.x1 <= a.x0 or b.y0 >= a.y1 or b.y1 <= a.y0


@pytest.fixture(scope="module")
def damped(tmp_path_factory):
    """S2.1 (6x6) with measured damping ratios: a result with /damping."""
    tmp = tmp_path_factory.mktemp("damped")
    zeta = "[" + ", ".join(f"{0.002 + 0.0004 * k:.4f}" for k in range(12)) + "]"
    text = Path(S21).read_text().replace("  frequencies:", f"  damping: {zeta}\n  frequencies:", 1)
    (tmp / "d.yaml").write_text(text)
    out = tmp / "d.result.h5"
    r = run("identify", tmp / "d.yaml", "--mesh", "6x6", "--fix",
            "nu12,G13,G23,eta13=0.01,eta23=0.01", "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture(scope="module")
def damped_pages(damped):
    """The damped result's pages, for the tests that only read them (see checked_pages)."""
    return {p.name: p.figure for p in report_pages(damped)}


def test_damping_page_numbers_read_back(damped, damped_pages, tmp_path):
    res = read_result(damped)
    d = res.damping.data
    pages = damped_pages
    fig = pages["damping"]
    a = ax(fig, "modal-loss-factors")
    meas = next(ln for ln in a.get_lines() if ln.get_gid() == "measured")
    ok = np.isfinite(d["measured_loss_factor"])
    assert np.array_equal(meas.get_ydata(), 100 * d["measured_loss_factor"][ok])
    assert np.allclose(d["measured_loss_factor"], 2 * (0.002 + 0.0004 * np.arange(12)),
                       rtol=1e-12)                              # 2 zeta of the YAML
    model = next(ln for ln in a.get_lines() if ln.get_gid() == "model")
    assert np.array_equal(model.get_ydata(), 100 * d["model_loss_factor"])
    s = ax(fig, "energy-shares")
    heights = np.array([[b.get_height() for b in c] for c in s.containers]).T
    assert np.allclose(heights, 100 * d["energy_shares"], rtol=1e-12, atol=1e-12)
    t = cells(ax(fig, "loss-factors"))
    assert [row[0] for row in t[1:4]] == list(d["labels"])
    assert [float(row[1]) for row in t[1:4]] == pytest.approx(100 * d["value"], abs=5e-4)
    assert fig._suptitle.get_text() == f"{res.plates[0].name}: damping (modal strain energy)"
    write_pages([Page("damping", result_page(damped, "damping"))], tmp_path / "d.png")
    assert (tmp_path / "d.png").read_bytes()[:8] == PNG


def test_damping_page_measured_and_model_loss_factors_do_not_hide_each_other(damped_pages):
    """The measured dots, their +-1 sd bars and the model's hollow squares were drawn at the
    same x: the squares (ms 8) covered the dots and the bars (under the dots, a 2 % sd about
    a dot's size) did not show. The two series now sit either side of their mode, apart by
    more than a dot and a square (in points on the page), the bars over the dots with caps
    wider than a dot; the legend's marks are the drawn ones, the measured one with its bar."""
    from matplotlib.collections import LineCollection

    fig = damped_pages["damping"]
    a = ax(fig, "modal-loss-factors")
    lines = {ln.get_gid(): ln for ln in a.get_lines()}
    meas, model = lines["measured"], lines["model"]
    n = model.get_xdata().size
    modes = np.arange(1, n + 1)
    assert np.all(meas.get_xdata() < modes) and np.all(model.get_xdata() > modes)
    # centre to centre in points, against half a dot + half a square (and its edge)
    to_pt = 72 / fig.dpi
    xm = a.transData.transform(np.c_[meas.get_xdata(), meas.get_ydata()])[:, 0] * to_pt
    xs = a.transData.transform(np.c_[model.get_xdata(), model.get_ydata()])[:, 0] * to_pt
    assert np.all(xs - xm > meas.get_markersize() / 2 + model.get_markersize() / 2
                  + model.get_markeredgewidth())
    (bars,) = [c for c in a.collections if isinstance(c, LineCollection)]
    assert bars.get_gid() == "measured-sd" and bars.get_zorder() > meas.get_zorder()
    caps = [ln for ln in a.get_lines() if ln.get_marker() == "_"]
    assert caps and all(c.get_zorder() > meas.get_zorder()
                        and c.get_markersize() > meas.get_markersize() for c in caps)
    leg = a.get_legend()
    assert [t.get_text() for t in leg.get_texts()][:2] == ["measured 2\u03b6 \u00b1 1 sd",
                                                            "model \u03a3 share \u00d7 ply \u03b7"]
    marks = [(h.get_marker(), h.get_markersize()) for h in leg.legend_handles[:2]]
    assert marks == [("o", meas.get_markersize()), ("s", model.get_markersize())]
    assert leg.findobj(LineCollection)                  # the measured entry's error bar


def test_joint_interval_panels_read_back(joint, joint_pages):
    res = read_result(joint)
    fig = {p.name: p.figure for p in joint_pages}["intervals"]
    for iv in res.uncertainty.intervals:
        a = ax(fig, f"interval-{iv.label}")
        scale = 1 if iv.constant == "nu12" else 1e9
        v = next(ln for ln in a.get_lines() if ln.get_gid() == "value")
        assert v.get_ydata()[0] == res.materials[iv.material][iv.constant] / scale
        line = next(ln for ln in a.get_lines() if ln.get_gid() == "interval")
        lo, hi = a.get_ylim()
        assert np.allclose(line.get_ydata(), [max(iv.lower / scale, lo),
                                              min(iv.upper / scale, hi)], rtol=1e-12)
    assert fig._suptitle.get_text().startswith("S1.1 + S1.2: 95% confidence intervals")


def test_intervals_widened_by_the_residuals_say_so_and_by_how_much(joint, joint_pages):
    """S1.1 + S1.2 (joint, 6x6) fit worse than their stated noise (s2 ~ 6): the intervals are
    the covariance scaled by s2 with a Student t quantile, about 2.7 times as wide as the stated
    sigma gives. Page 1 said "95% intervals, s² = 6.15" as for any fit, and the intervals page
    nothing, so that they read as the stated noise's; both now say where they come from and
    the widening, that of the file's own std over std_stated."""
    from statistics import NormalDist

    res = read_result(joint)
    u = res.uncertainty
    assert u.scale_used == "residuals" and u.variance_factor > 2
    with h5py.File(joint) as f:
        g = f["uncertainty"]
        ratio = g["std"][()] / g["std_stated"][()]
    assert np.allclose(ratio, np.sqrt(u.variance_factor), rtol=1e-9)
    wider = np.sqrt(u.variance_factor) * u.quantile / NormalDist().inv_cdf(0.975)
    words = (f"95% intervals from the residuals (covariance scaled by s² = "
             f"{u.variance_factor:.3g}, Student t): {wider:.1f} × as wide as the stated σ gives")
    figs = {p.name: p.figure for p in joint_pages}
    notes = next(t.get_text() for a in figs["shared"].axes for t in a.texts
                 if t.get_gid() == "notes").replace("\n", " ")
    assert words in notes
    assert notes.count("s² =") == 1                 # once, in the basis
    legend = next(a.get_legend() for a in figs["intervals"].axes if a.get_legend())
    assert words.split("95% ", 1)[1] in legend.get_title().get_text().replace("\n", " ")


def test_joint_plate_page_has_its_laminate_under_its_table(joint):
    """A plate's page of a joint result gives the laminate's properties just under its
    frequency table, clear of the residual panel's words and inside the page; they stood at the
    foot of the page, under some 3 inches of blank."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report import plate_frequency_page

    res = read_result(joint)
    fig = plate_frequency_page(res, res.plates[1])
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    table = ax(fig, "frequency-table")
    (text,) = [t for a in fig.axes for t in a.texts if t.get_gid() == "laminate"]
    assert text.get_text().replace("\n", " ").startswith("laminate (Appendix A): Ex ")
    box = text.get_window_extent(renderer)
    bottom = table.get_window_extent(renderer).y0
    gap = (bottom - box.y1) / fig.dpi                                     # inches
    assert 0 <= gap < 1.0, gap          # the residual panel's words between (about 0.7 in)
    label = ax(fig, "residuals").xaxis.label.get_window_extent(renderer)
    assert not box.overlaps(label)
    assert fig.bbox.x0 <= box.x0 and box.x1 <= fig.bbox.x1


def test_residuals_page_reads_back_the_result_files(batch_dir):
    from laminid_cli.batch import read_summary

    rows = read_summary(batch_dir / "summary.json")
    fig = {p.name: p.figure for p in report_pages(batch_dir / "summary.json")}["residuals"]
    a = ax(fig, "rms")
    heights = [b.get_height() for b in a.patches]
    for h, row in zip(heights, rows):
        res = read_result(row["result"])
        assert h == pytest.approx(res.rms_residual_percent, rel=1e-12)
    assert [t.get_text() for t in a.get_xticklabels()] == [
        read_result(row["result"]).plates[0].name for row in rows]
    texts = [t.get_text() for t in a.texts]
    for t, row in zip(texts, rows):
        codes = ", ".join(x.code for x in read_result(row["result"]).status.reasons)
        assert t.replace("\n", " ").startswith(f"{row['rms_residual_percent']:.3f} %")
        assert (f"check: {codes}" in t.replace("\n", " ")) == bool(codes)
    assert _no_overlap(fig, a, a.get_legend())


def test_fit_frf_figure_reads_back_the_frf_file(tmp_path):
    from laminid_cli.frf import rfp
    from laminid_cli.frf.io import read_frf
    from laminid_cli.frf.plot import fit_figure

    freq = np.arange(1.0, 400.0, 0.5)
    poles = np.array([[80.0, 0.01], [150.0, 0.008], [260.0, 0.01]])
    frf = synth_frf(freq, poles, np.array([[1.0, -0.6, 0.8], [0.5, 0.9, -0.7]]),
                    kind="accelerance", noise=0.002, seed=1)
    coh = np.full(frf.shape, 0.97)
    write_frf_h5(tmp_path / "p.frf.h5", freq, frf, coh, units="(m/s^2)/N")
    fs = read_frf(tmp_path / "p.frf.h5")
    fit = rfp.find_modes(fs.freq, fs.frf, n_modes=3)
    fig = fit_figure(fs.freq, fs.frf, fit, units=fs.units, coherence=fs.coherence)
    a = ax(fig, "frf")
    measured = [ln for ln in a.get_lines() if ln.get_color() == "k"]
    assert len(measured) == 2
    with np.errstate(divide="ignore"):
        assert np.array_equal(measured[1].get_ydata(), 20 * np.log10(np.abs(fs.frf[1])))
    dashed = sorted(ln.get_xdata()[0] for ln in a.get_lines() if ln.get_linestyle() == "--")
    assert dashed == [m.freq_hz for m in fit.modes]
    assert np.allclose(dashed, poles[:, 0], rtol=2e-3)
    assert a.get_ylabel() == "|H| (dB re 1 (m/s^2)/N)"
    assert _no_overlap(fig, a, a.get_legend())                  # legend clear of the curves
    s = ax(fig, "stabilisation")
    assert _no_overlap(fig, s, s.get_legend(), draw=False)      # (laid out by the line above)
    for lim in ((0.5, 18.5), (0.1, 18.9), (0.2, 19.6)):   # orders 1-18 as in S1.1's example
        s.set_ylim(*lim)                                   # FRFs, whose ticks were 2.5, 7.5...
        fig.draw_without_rendering()                       # orders are whole numbers
        ticks = [t for t in s.get_yticks() if lim[0] <= t <= lim[1]]
        assert len(ticks) >= 3 and all(float(t).is_integer() for t in ticks), (lim, ticks)
    coh_ax = next(x for x in fig.axes if x.get_ylabel() == "coherence (–)")
    coh_lines = [ln for ln in coh_ax.get_lines() if ln.get_gid() == "coherence"]
    assert len(coh_lines) == 2
    assert np.array_equal(coh_lines[1].get_ydata(), fs.coherence[1])
    r = run("fit-frf", tmp_path / "p.frf.h5", "--modes", "3", "--plot", tmp_path / "p.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "p.png").read_bytes()[:8] == PNG


def test_legends_clear_of_the_lines(checked, batch_dir):
    """History legends right of their panels; the summary legend in a row of its own."""
    fig = result_page(checked, "history")
    fig.draw_without_rendering()            # laid out once: the checks below change nothing
    for gid in ("objective",):
        a = ax(fig, gid)
        assert _no_overlap(fig, a, a.get_legend(), draw=False)
    for a in fig.axes:
        if a.get_legend() is not None:
            assert _no_overlap(fig, a, a.get_legend(), draw=False)
    fig = {p.name: p.figure for p in report_pages(batch_dir / "summary.csv")}["constants"]
    fig.draw_without_rendering()
    leg = next(a for a in fig.axes if a.get_legend() is not None).get_legend()
    for a in fig.axes:
        if (a.get_gid() or "").startswith("across-"):
            assert _no_overlap(fig, a, leg, draw=False)


@pytest.fixture(scope="module")
def fixed_undetermined(s11_fix_undetermined_6x6):
    """S1.1 (6x6) with --fix-undetermined (conftest.py): G13, G23, nu12 undetermined in the
    first run and fixed, E2 fixed in a later round, G12 kept free; read only."""
    return s11_fix_undetermined_6x6[1]


def test_fixed_constants_are_not_drawn_as_identified(fixed_undetermined):
    """A constant fixed by --fix-undetermined says so and why (the first run's half-width),
    has no interval, no verdict band and no "% against the reference"; on the interval page
    a hollow grey square, never the black "identified" dot; the history names it instead of
    leaving an empty panel."""
    res = read_result(fixed_undetermined)
    u = res.uncertainty
    before = {lab.rsplit(".", 1)[1]: rel for lab, (rel, _) in u.before_fixing.items()}
    pages = {name: result_page(fixed_undetermined, name)
             for name in ("summary", "intervals", "history")}
    rows = {row[0].split(" ")[0]: row for row in cells(ax(pages["summary"], "constants"))[1:]}
    for k in ("G13", "G23", "nu12"):
        assert rows[k][1] == fmt_value(k, res.initial[MAT][k]) == rows[k][4]
        assert rows[k][2] == "none — not identified"
        assert rows[k][3] == ("fixed because undetermined\n(half-width was "
                              f"±{100 * before[k]:.0f} %)")
    assert before["G13"] > 0.3 and before["E2"] < 0.3          # E2: weak in the first run
    run, e2 = u.fixed_widths[f"{MAT}.E2"][2], u.fixed_widths[f"{MAT}.E2"][0]
    assert run == 2 and e2 > 0.3                                # undetermined in run 2
    assert rows["E2"][3] == (f"fixed because undetermined\n(half-width was ±{100 * e2:.0f} % "
                             "in run 2)")
    assert rows["nu12"][5] == "0.350\n(fixed: not\ncompared)"
    e1 = res.materials[MAT]["E1"]
    assert rows["E1"][5] == f"170.00 ({round((e1 / 170e9 - 1) * 100):+d} %)"
    assert rows["E1"][3] == short_verdict(u.get(MAT, "E1").verdict)
    notes = " ".join(t.get_text() for a in pages["summary"].axes for t in a.texts)
    assert "fixed: held at its initial value, not identified" in notes.replace("\n", " ")
    fig = pages["intervals"]
    assert u.get(MAT, "G12") is not None           # G12 kept free (its initial value rejected)
    for k in ("E2", "G13", "G23", "nu12"):
        a = ax(fig, f"interval-{MAT}.{k}")
        gids = [ln.get_gid() for ln in a.get_lines()]
        assert "value" not in gids and "interval" not in gids and not a.patches
        mark = next(ln for ln in a.get_lines() if ln.get_gid() == "fixed")
        assert mark.get_marker() == "s" and mark.get_markerfacecolor() == "w"
        assert mark.get_ydata()[0] == pytest.approx(_gpa_(k, res.materials[MAT][k]))
        assert "fixed because undetermined" in a.get_xlabel().replace("\n", " ")
    assert [ln.get_gid() for ln in ax(fig, f"interval-{MAT}.E1").get_lines()
            if ln.get_gid() == "value"] == ["value"]
    legend = [t.get_text() for a in fig.axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "fixed because undetermined (not identified)" in legend
    assert "not determined (interval too wide)" not in legend        # none is drawn
    hist = pages["history"]
    note = next(t for a in hist.axes for t in a.texts if t.get_gid() == "fixed-note")
    assert note.get_text() == "fixed, not identified: nu12 = 0.350"
    titles = [a.get_legend().get_title().get_text() for a in hist.axes
              if a.get_legend() is not None]
    assert "fixed, not identified:\nE2, G13, G23" in titles


def _gpa_(k, v):
    return v if k == "nu12" else v / 1e9


def test_constants_fixed_by_fix_say_so(damped, damped_pages):
    """--fix nu12,G13,G23: "fixed at its initial value (not identified)" in the table and in
    the interval page's legend."""
    pages = damped_pages
    mat = "E-glass/R368"
    rows = {row[0].split(" ")[0]: row for row in cells(ax(pages["summary"], "constants"))[1:]}
    for k in ("nu12", "G13", "G23"):
        assert rows[k][3] == "fixed at its initial value\n(not identified)"
        assert rows[k][2] == "none — not identified"
    legend = [t.get_text() for a in pages["intervals"].axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "fixed at its initial value (not identified)" in legend
    g13 = read_result(damped).materials[mat]["G13"]
    assert ax(pages["intervals"], f"interval-{mat}.G13").get_xlabel() == \
        f"{fmt_value('G13', g13)}\nfixed at its initial value\n(not identified)"


def test_monte_carlo_numbers_on_the_pages(checked, tmp_path):
    """A Monte Carlo end beyond the panel gets its value, like the linearised interval's; a
    verdict the Monte Carlo set gives the range (an end on a search limit starred) and its
    half-widths, whole and for sure, in the table and under the panel."""
    path = _with_monte_carlo(checked, tmp_path, inner=True)
    with h5py.File(path, "r+") as f:
        u = f["uncertainty"]
        labels = [x.decode() for x in u["labels"][()]]
        j13, j2 = labels.index(f"{MAT}.G13"), labels.index(f"{MAT}.E2")
        mc = u["monte_carlo"]
        v = u["value"][()]
        up, lo = mc["upper"][()], mc["lower"][()]
        # far above G13's panel: beyond what even a log panel draws (LOG_PANEL_REACH; a
        # range 30 x the value is drawn whole on a log axis)
        up[j13] = 1e5 * v[j13]
        lo[j2] = 0.2 * v[j2]                               # E2: trials down to a limit
        mc["upper"][...], mc["lower"][...] = up, lo
        flags = np.zeros(v.size, np.int8)
        flags[j2] = 1
        mc.create_dataset("lower_at_bound", data=flags)
        mc.create_dataset("upper_at_bound", data=np.zeros(v.size, np.int8))
        verdict = [x.decode() for x in u["verdict"][()]]
        verdict[j2] = "weak (Monte Carlo)"
        del u["verdict"]
        u.create_dataset("verdict", data=np.array(verdict, dtype=object),
                         dtype=h5py.string_dtype())
        u.attrs["verdict_from_monte_carlo"] = f"{MAT}.E2"
        # the widths as the report computes them from the file (0.2 .. 1.02 x the value, inner
        # 0.98 .. 1.01 x: 1.5 % rounds either way with the last bit of the value)
        whole = f"{100 * 0.5 * (up[j2] - lo[j2]) / abs(v[j2]):.0f}"
        sure = f"{100 * 0.5 * (mc['inner_upper'][j2] - mc['inner_lower'][j2]) / abs(v[j2]):.0f}"
    res = read_result(path)
    pages = {name: result_page(path, name) for name in ("summary", "intervals")}
    a = ax(pages["intervals"], f"interval-{MAT}.G13")
    g13 = res.materials[MAT]["G13"]
    end = next(t for t in a.texts if t.get_gid() == "monte-carlo-upper-end")
    assert end.get_text() == f"to\n{mc_end_text('G13', 1e5 * g13)}"
    assert end.xy[1] == a.get_ylim()[1]
    e2 = res.materials[MAT]["E2"]
    iv = res.uncertainty.get(MAT, "E2")
    rows = {row[0].split(" ")[0]: row for row in cells(ax(pages["summary"], "constants"))[1:]}
    assert rows["E2"][2] == (f"[{fmt_value('E2', iv.lower)}, {fmt_value('E2', iv.upper)}]\n"
                             f"Monte Carlo {mc_end_text('E2', 0.2 * e2)}*–"
                             f"{mc_end_text('E2', 1.02 * e2)}")
    assert rows["E2"][3] == f"weak (Monte Carlo\n±{whole} %, ±{sure} % for sure)"
    label = ax(pages["intervals"], f"interval-{MAT}.E2").get_xlabel().replace("\n", " ")
    assert label.endswith(f"weak (Monte Carlo ±{whole} %, ±{sure} % for sure)")
    notes = " ".join(t.get_text() for a in pages["summary"].axes for t in a.texts)
    assert "*: an end set by trials that stopped on a search limit" in notes.replace("\n", " ")


def test_a_monte_carlo_range_off_its_panel_keeps_its_arrow_inside_and_writes_its_ends(
        checked, tmp_path):
    """S1.1's G13 with a Monte Carlo (range to 8.685 GPa, 6.708 for sure, panel to 6): the
    grey arrow head was a marker centred on the panel's top edge, half over the frame, and
    the dark bar for sure ran to the edge under it with no value written. The arrow's head
    now ends inside the panel (as the interval's), the bars stop at its foot, and the words
    give both ends, in the terminal's Monte Carlo digits."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = _with_monte_carlo(checked, tmp_path, inner=True)
    with h5py.File(path, "r+") as f:
        u = f["uncertainty"]
        j13 = [x.decode() for x in u["labels"][()]].index(f"{MAT}.G13")
        v = u["value"][()]
        mc = u["monte_carlo"]
        for key, factor in (("upper", 1e5), ("inner_upper", 3e4)):
            a = mc[key][()]
            a[j13] = factor * v[j13]
            mc[key][...] = a
    g13 = read_result(path).materials[MAT]["G13"]
    fig = result_page(path, "intervals")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    a = ax(fig, f"interval-{MAT}.G13")
    top = a.get_ylim()[1]
    assert 3e4 * g13 / 1e9 > top                         # both ends off the panel
    end = next(t for t in a.texts if t.get_gid() == "monte-carlo-upper-end")
    assert end.get_text() == (f"to\n{mc_end_text('G13', 1e5 * g13)}\n"
                              f"(for sure\n{mc_end_text('G13', 3e4 * g13)})")
    arrow = next(t for t in a.texts if t.get_gid() == "monte-carlo-upper-arrow")
    head, panel = arrow.arrow_patch.get_window_extent(renderer), a.get_window_extent(renderer)
    assert head.y1 <= panel.y1 and head.y0 >= panel.y0, (head, panel)
    for gid in ("monte-carlo", "monte-carlo-sure"):     # stop at the arrow's foot
        line = next(ln for ln in a.get_lines() if ln.get_gid() == gid)
        assert max(line.get_ydata()) == pytest.approx(arrow.xyann[1]) and arrow.xyann[1] < top


def test_the_intervals_page_writes_numbers_in_the_terminals_digits(checked):
    """Hybrid CM's glass G12 (on its lower limit, 0.00595 GPa) read "0.005950" on the
    intervals page and "0.00595" in `laminid identify`/`show`; glass E2's flat profile
    "flat to 0.9000" against the terminal's "flat to 0.9". Every number of a panel's words
    is now the terminal's (commands/text.py's _num, laminid_cli.units.constant_text)."""
    from laminid_cli.commands.text import _num
    from laminid_cli.intervals import PROFILE_FLAT
    from laminid_cli.report import interval_page

    r = read_result(checked)
    iv = r.uncertainty.get(MAT, "G23")
    assert iv.at_bound
    flat = dataclasses.replace(iv, profile_bound=np.nan, profile_far=0.9e9,
                               profile_text=PROFILE_FLAT + " with G23 anywhere up to 0.9 GPa")
    assert flat.profile_kind == "flat"
    mats = {m: dict(c) for m, c in r.materials.items()}
    mats[MAT]["G23"] = 5.95e6
    r = dataclasses.replace(r, materials=mats, uncertainty=dataclasses.replace(
        r.uncertainty, intervals=tuple(flat if x is iv else x for x in r.uncertainty.intervals)))
    fig = interval_page(r)
    words = ax(fig, f"interval-{MAT}.G23").get_xlabel().split("\n")
    assert words[0] == _num("G23", 5.95e6) == "0.00595"
    assert "profile: flat to " + _num("G23", 0.9e9) in words and _num("G23", 0.9e9) == "0.9"
    label = next(t for t in ax(fig, f"interval-{MAT}.G23").texts
                 if t.get_text().startswith("profile:"))
    assert label.get_text() == "profile:\nflat to\n0.9"
    # an interval's ends and value: as the terminal's table ("162.92", "160.33 .. 165.55")
    e1 = r.uncertainty.get(MAT, "E1")
    assert ax(fig, f"interval-{MAT}.E1").get_xlabel().split("\n")[0] == (
        f"{_num('E1', r.materials[MAT]['E1'])} [{_num('E1', e1.lower)}, {_num('E1', e1.upper)}]")


def test_an_interval_without_information_shows_its_ends_in_words(checked):
    """A modulus interval whose ends are more than 1000 x apart shows both ends and says it
    carries no information (no "×5e+07" code), and the summary page says what that means."""
    import dataclasses

    iv = read_result(checked).uncertainty.get(MAT, "E2")
    wide = dataclasses.replace(iv, lower=1e7, upper=5e14)
    assert interval_text("E2", wide) == "[0.01, 5.00e+05]\nno information"
    assert interval_text("E2", dataclasses.replace(iv, lower=1e9, upper=9e11)) == \
        "[1.00, 900.00]"                                   # 900 x apart: an interval
    assert interval_text("nu12", dataclasses.replace(iv, lower=-0.95, upper=0.95)) == \
        "[-0.950, 0.950]"


def _write_summary(path, rows):
    """``rows`` (laminid batch's summary rows) as a summary.csv (long) or summary.json, by
    ``path``'s suffix."""
    import json

    from laminid_cli.batch import write_summary_csv

    if path.suffix == ".csv":
        write_summary_csv(path, rows)
    else:
        path.write_text(json.dumps({"format": "laminid-batch-summary", "specimens": rows}))


def _summary_rows():
    """Two specimens as `laminid batch` rows (SI): H (glass and carbon, as hybrid CM at 8x8
    with 40 trials: glass E2 and nu12 on upper limits, glass G12 on a lower one, glass G13
    fixed, glass G23 with an interval of no information, carbon G12 "weak (Monte Carlo)" with
    a range down to a search limit) and Q (carbon, all well determined)."""
    well = "well determined"
    nd = "not determined by these modes — fix it or measure a thicker plate / more modes"

    def iv(lo, hi, verdict=well, **kw):
        return {"lower": lo, "upper": hi, "verdict": verdict, "at_bound": False,
                "bound_side": "", "bound_limit": None, "flagged": verdict == nd} | kw

    def at(side, limit):
        return {"lower": None, "upper": None, "verdict": "at bound — not identified",
                "at_bound": True, "bound_side": side, "bound_limit": limit, "flagged": False}

    glass = {"E1": 58.0e9, "E2": 58.47e9, "G12": 5.949e6, "G13": 3.7e9, "G23": 3.0e9,
             "nu12": 0.95}
    carbon = {"E1": 87.0e9, "E2": 8.0e9, "G12": 4.864e9, "G13": 3.8e9, "G23": 3.0e9,
              "nu12": 0.3}
    h_iv = {"glass": {"E1": iv(55e9, 61e9), "E2": at("upper", 58.47e9),
                      "G12": at("lower", 5.949e6), "G13": {"verdict": "fixed"},
                      "G23": iv(1.4e-45, 1.7e63, nd), "nu12": at("upper", 0.95)},
            "carbon": {k: iv(0.99 * v, 1.01 * v) for k, v in carbon.items()}}
    h_iv["carbon"]["G12"] = iv(4.786e9, 4.943e9, "weak (Monte Carlo)", mc_lower=1.025e7,
                               mc_upper=4.894e9, mc_lower_at_limit=True,
                               mc_upper_at_limit=False)
    common = {"status": "check", "reasons": [{"code": "at_bound", "text": "..."}],
              "reason": "at_bound", "converged": True, "cached": False, "path": "",
              "rms_residual_percent": 0.14, "evaluations": 600, "time_s": 9.0,
              "result": "H.result.h5", "damping": {}}
    h = common | {"name": "H", "specimen": "H", "materials": {"glass": glass,
                                                               "carbon": carbon},
                  "intervals": h_iv}
    q = common | {"name": "Q", "specimen": "Q", "status": "ok", "reasons": [], "reason": "",
                  "materials": {"carbon": carbon}, "result": "Q.result.h5",
                  "intervals": {"carbon": {k: iv(0.98 * v, 1.02 * v)
                                           for k, v in carbon.items()}}}
    return [h, q]


def _line(axis, gid):
    return next(ln for ln in axis.get_lines() if ln.get_gid() == gid)


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_summary_pages_take_the_doubt_from_the_summary_itself(tmp_path, kind):
    """With no result file next to it, summary.csv (long) or summary.json still gives every
    constant its doubt: the interval, "?" for not determined, a triangle on the limit for a
    constant at a bound (never a data dot), a grey square for a fixed one, the Monte Carlo
    range with its search-limit end starred; the legend tells them apart."""
    import json

    from laminid_cli.report import FIXED_COLOR

    rows = _summary_rows()
    path = tmp_path / f"summary.{kind}"
    _write_summary(path, rows)
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    for k, marker, y in (("E2", "^", 58.47), ("G12", "v", 5.949e-3), ("nu12", "^", 0.95)):
        a = ax(fig, f"across-{k}")
        mark = _line(a, "at-bound-H-glass")
        assert mark.get_marker() == marker and mark.get_markerfacecolor() == "w"
        assert mark.get_ydata()[0] == pytest.approx(y, rel=1e-12)
        assert "value-H-glass" not in [ln.get_gid() for ln in a.get_lines()]
    a = ax(fig, "across-G13")
    mark = _line(a, "fixed-H-glass")
    assert mark.get_marker() == "s" and mark.get_color() == FIXED_COLOR
    assert "value-H-glass" not in [ln.get_gid() for ln in a.get_lines()]
    a = ax(fig, "across-G23")                               # no information: "?", both arrows
    assert _line(a, "value-H-glass").get_markerfacecolor() == "w"
    assert [t.get_text() for t in a.texts].count("?") == 1
    assert len([t for t in a.texts if t.arrow_patch is not None and not t.get_text()]) == 2
    a = ax(fig, "across-G12")                       # carbon: identified, Monte Carlo range
    v = _line(a, "value-H-carbon")
    assert v.get_markerfacecolor() == v.get_color()                        # filled
    lo, hi = a.get_ylim()
    mc = [ln for ln in a.get_lines() if (ln.get_gid() or "").startswith("monte-carlo")]
    assert [ln.get_gid() for ln in mc] == ["monte-carlo-H-carbon"]
    assert np.allclose(mc[0].get_ydata(), [max(0.01025, lo), 4.894], rtol=1e-12)
    star = next(t for t in a.texts if t.get_gid() == "monte-carlo-H-carbon-search-limit")
    assert star.get_text() == "*" and star.xy[1] == pytest.approx(max(0.01025, lo))
    legend = [t.get_text() for a in fig.axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    for text in ("?: not determined (interval too wide)",
                 "stopped on a lower / upper search limit: not identified, no interval",
                 "fixed at its initial value: not identified",
                 "Monte Carlo range: pale bar of the material's colour, right of its value "
                 "(*: end set by trials on a search limit)"):
        assert text in legend
    footer = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
    assert "result file not found (no reference values): H, Q" in footer
    assert "H: check: at_bound" in footer and "Q:" not in footer


def old_wide(path, to, flagged: bool = True):
    """The wide summary.csv ``path`` as written before its interval and verdict columns (and,
    ``flagged`` False, before its column 'flagged'), at ``to``."""
    import csv

    with open(path, newline="") as fh:
        recs = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    keep = [c for c in recs[0] if not re.search(r" (lower|upper) \[[^]]*\]$| verdict$", c)
            and (flagged or c != "flagged")
            # (nor the columns after 'flagged': sides of a bound, ranges, loss factors)
            and not re.search(r" (bound_side|mc_lower \[.*|mc_upper \[.*|mc_search_limit"
                              r"|bound_limit \[.*|profile_bound \[.*|profile|profile_far \[.*)$"
                              r"|^\S+ eta\d\d ", c)]
    assert len(keep) < len(recs[0])
    with open(to, "w", newline="") as fh:
        w = csv.DictWriter(fh, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(recs)
    return to


def test_a_wide_summary_alone_draws_its_flagged_column(tmp_path):
    """A --wide summary.csv written before its interval columns, without its result files:
    its column 'flagged' ("glass.E2 at_bound; glass.G12 at_bound; glass.G13 fixed; glass.G23
    undetermined; glass.nu12 at_bound") is drawn as the long summary draws them: the fixed one
    a grey square, the undetermined one hollow with "?", those at a bound a hollow triangle
    (both, "^" over "v": the column does not say which limit), the others filled (identified,
    not flagged). They were all hollow diamonds with "values without their doubt"."""
    from laminid_cli.batch import read_summary, write_summary_csv
    from laminid_cli.report import FIXED_COLOR

    path = tmp_path / "wide.csv"
    write_summary_csv(tmp_path / "new.csv", _summary_rows(), wide=True)
    old_wide(tmp_path / "new.csv", path)
    assert read_summary(path)[0]["flagged"] == {"glass": {
        "E2": "at_bound", "G12": "at_bound", "G13": "fixed", "G23": "undetermined",
        "nu12": "at_bound"}}
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    for k, y in (("E2", 58.47), ("G12", 5.949e-3), ("nu12", 0.95)):
        a = ax(fig, f"across-{k}")
        mark = _line(a, "at-bound-H-glass")
        verts = mark.get_marker().vertices
        assert {tuple(v) for v in verts} == {(0, 1), (-1, -1), (1, -1), (0, -1), (-1, 1),
                                             (1, 1)}
        assert mark.get_markerfacecolor() == "none"                        # hollow
        assert mark.get_ydata()[0] == pytest.approx(y, rel=1e-12)
        assert "value-H-glass" not in [ln.get_gid() for ln in a.get_lines()]
    a = ax(fig, "across-G13")
    mark = _line(a, "fixed-H-glass")
    assert mark.get_marker() == "s" and mark.get_color() == FIXED_COLOR
    a = ax(fig, "across-G23")
    v = _line(a, "value-H-glass")
    assert v.get_marker() == "o" and v.get_markerfacecolor() == "w"
    assert [t.get_text() for t in a.texts].count("?") == 1
    for k in ("E1", "G12"):                         # glass E1, carbon G12: not flagged
        a = ax(fig, f"across-{k}")
        for tag in (["H-glass"] if k == "E1" else []) + ["H-carbon", "Q-carbon"]:
            v = _line(a, f"value-{tag}")
            assert v.get_marker() == "o" and v.get_markerfacecolor() == v.get_color(), tag
        assert not [ln for ln in a.get_lines() if ln.get_gid() == "interval"]
    legend = [t.get_text() for a in fig.axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "identified, not flagged (--wide: no interval)" in legend
    assert "on a search limit, not identified (--wide: which one not said)" in legend
    assert "?: not determined (interval too wide)" in legend
    assert "fixed at its initial value: not identified" in legend
    assert "no interval in this summary (wide CSV, result file not found)" not in legend
    foot = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
    assert "values without their doubt" not in foot
    assert "no intervals: a --wide summary.csv written before its interval columns gives " \
           "only which constants" in foot


def test_a_wide_summary_alone_draws_the_long_summarys_bars(tmp_path):
    """A --wide summary.csv with its interval columns, without its result files, draws each
    identified constant's interval bar where the long summary.csv of the same rows draws it
    (the same ends, to 1e-9), with its legend; it drew hollow diamonds or dots without a bar,
    and the note that a wide CSV has no intervals."""
    from laminid_cli.batch import write_summary_csv

    (tmp_path / "long").mkdir()
    (tmp_path / "wide").mkdir()
    write_summary_csv(tmp_path / "long" / "summary.csv", _summary_rows())
    write_summary_csv(tmp_path / "wide" / "summary.csv", _summary_rows(), wide=True)
    figs = {kind: {p.name: p.figure for p in report_pages(tmp_path / kind / "summary.csv")}[
        "constants"] for kind in ("long", "wide")}

    def bars(fig):
        return {(a.get_gid(), tuple(ln.get_xdata())): tuple(ln.get_ydata())
                for a in fig.axes for ln in a.get_lines() if ln.get_gid() == "interval"}

    long, wide = bars(figs["long"]), bars(figs["wide"])
    # H's carbon (6 constants, G12 0.955 ... 1.016 of its value), H's glass E1 and G23, Q's 6
    assert len(long) == 14 and set(wide) == set(long)
    for key, ends in long.items():
        assert np.allclose(wide[key], ends, rtol=1e-9, atol=0), key
    g12 = ax(figs["wide"], "across-G12")
    assert _line(g12, "value-H-carbon").get_markerfacecolor() == \
        _line(g12, "value-H-carbon").get_color()                          # filled: identified
    legend = [t.get_text() for a in figs["wide"].axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "identified, with its confidence interval" in legend
    assert "identified, not flagged (--wide: no interval)" not in legend
    # the side of a bound is in the wide summary now (its bound_side columns): one triangle
    # on that side, as the long summary draws it (both triangles, "which one not said", before)
    assert "on a search limit, not identified (--wide: which one not said)" not in legend
    assert "stopped on a lower / upper search limit: not identified, no interval" in legend

    def at_bound(fig):
        return {(a.get_gid(), ln.get_gid()): (ln.get_marker(), tuple(ln.get_ydata()))
                for a in fig.axes for ln in a.get_lines()
                if (ln.get_gid() or "").startswith("at-bound")}

    assert at_bound(figs["wide"]) == at_bound(figs["long"]) and len(at_bound(figs["long"])) >= 3
    foot = " ".join(t.get_text() for t in figs["wide"].texts).replace("\n", " ")
    assert "no intervals" not in foot and "without their doubt" not in foot


def test_a_wide_summary_alone_has_the_long_summarys_bounds_and_profiles(tmp_path):
    """--wide had each constant's bound_side but not its bound_limit nor its profile, so the
    wide CSV alone could not tell a constant the data bound (glass G12 on its lower limit,
    rejected above 18.5 GPa) from one they do not determine (glass E2, flat down to 0.9 GPa),
    and its report drew no profile without the result files. Its columns "glass G12
    bound_limit [Pa]", "... profile_bound [Pa]", "... profile", "... profile_far [Pa]" (nu12's
    in [1]), after each bound_side, hold the long summary's cells (1e-12 relative), empty where
    the long ones are; read_summary gives the long reader's keys and values back; the report
    of the wide CSV alone draws the long one's profiles, caps and arrow heads."""
    import csv

    from laminid_cli.batch import CONSTANTS, BatchError, read_summary, write_summary_csv

    rows = _summary_rows()
    g = rows[0]["intervals"]["glass"]
    g["G12"].update(profile="bound", profile_bound=18.5e9, profile_far=0.4e9)
    g["E2"].update(profile="flat", profile_bound=None, profile_far=0.9e9)
    g["nu12"].update(profile="none", profile_bound=None, profile_far=None)
    (tmp_path / "long").mkdir()
    (tmp_path / "wide").mkdir()
    write_summary_csv(tmp_path / "long" / "summary.csv", rows)
    write_summary_csv(tmp_path / "wide" / "summary.csv", rows, wide=True)
    with open(tmp_path / "long" / "summary.csv", newline="") as fh:
        long = {(x["name"], x["material"], x["constant"]): x
                for x in csv.DictReader(ln for ln in fh if not ln.startswith("#"))}
    with open(tmp_path / "wide" / "summary.csv", newline="") as fh:
        reader = csv.DictReader(ln for ln in fh if not ln.startswith("#"))
        header, wide = reader.fieldnames, {x["name"]: x for x in reader}
    i = header.index("glass nu12 bound_side")
    assert header[i:i + 5] == ["glass nu12 bound_side", "glass nu12 bound_limit [1]",
                               "glass nu12 profile_bound [1]", "glass nu12 profile",
                               "glass nu12 profile_far [1]"]
    n = 0
    for (name, m, k), rec in long.items():
        unit = rec["unit"]
        for key, col in (("bound_limit", f"bound_limit [{unit}]"),
                         ("profile_bound", f"profile_bound [{unit}]"),
                         ("profile_far", f"profile_far [{unit}]")):
            cell = wide[name][f"{m} {k} {col}"]
            assert (cell == "") is (rec[key] == ""), (name, m, k, key)
            if cell:
                assert float(cell) == pytest.approx(float(rec[key]), rel=1e-12, abs=0.0)
                n += 1
        assert wide[name][f"{m} {k} profile"] == rec["profile"]
    assert n == 6                     # 3 limits, G12's bound, G12's and E2's far ends
    assert wide["H"]["glass G12 profile"] == "bound" and wide["H"]["glass E2 profile"] == "flat"
    assert wide["H"]["glass nu12 profile"] == "none" and wide["H"]["glass E1 profile"] == ""
    # read back: the long reader's keys and values
    back = {kind: read_summary(tmp_path / kind / "summary.csv")[0]["intervals"]["glass"]
            for kind in ("long", "wide")}
    keys = ("bound_side", "bound_limit", "profile_bound", "profile", "profile_far")
    for k in CONSTANTS:
        if k == "G13":                                   # fixed: no entry in either
            continue
        assert [back["wide"][k][x] for x in keys] == [back["long"][k][x] for x in keys], k
    assert back["wide"]["G12"]["profile_bound"] == pytest.approx(18.5e9, rel=1e-12)
    assert back["wide"]["E2"]["profile_far"] == pytest.approx(0.9e9, rel=1e-12)
    assert back["wide"]["E2"]["bound_limit"] == pytest.approx(58.47e9, rel=1e-12)
    # a cell edited to text: the file, its line and the column named, as the other cells
    text = (tmp_path / "wide" / "summary.csv").read_text()
    bad = tmp_path / "bad.csv"
    bad.write_text(text.replace(",18500000000.0,bound,", ",n/a,bound,", 1))
    assert bad.read_text() != text
    with pytest.raises(BatchError, match=r"bad\.csv:\d+, column 'glass G12 profile_bound "
                                         r"\[Pa\]': 'n/a' is not a number"):
        read_summary(bad)
    # the report of the wide CSV alone (no result file beside it) draws the long one's
    assert not list(tmp_path.rglob("*.result.h5"))
    figs = {kind: {p.name: p.figure for p in report_pages(tmp_path / kind / "summary.csv")}[
        "constants"] for kind in ("long", "wide")}

    def profiles(fig):
        return {(a.get_gid(), ln.get_gid()): (ln.get_marker(), tuple(ln.get_ydata()))
                for a in fig.axes for ln in a.get_lines()
                if (ln.get_gid() or "").startswith("profile")}

    drawn = profiles(figs["wide"])
    assert set(drawn) == set(profiles(figs["long"]))
    for key, (marker, ys) in profiles(figs["long"]).items():
        assert drawn[key][0] == marker and np.allclose(drawn[key][1], ys, rtol=1e-12), key
    assert drawn[("across-G12", "profile-cap-H-glass")][0] == "_"
    assert drawn[("across-G12", "profile-cap-H-glass")][1][0] == pytest.approx(18.5, rel=1e-12)
    assert sorted(drawn[("across-G12", "profile")][1]) == pytest.approx([5.949e-3, 18.5],
                                                                       rel=1e-12)
    assert drawn[("across-E2", "profile-end-H-glass")][0] == "v"
    assert sorted(drawn[("across-E2", "profile")][1]) == pytest.approx([0.9, 58.47], rel=1e-12)


def test_batch_summary_alone_keeps_its_verdicts(batch_dir, tmp_path):
    """The batch's own summary.csv copied away from its result files: S1.4's G13 is still
    drawn not determined (hollow, "?") with its interval; a wide CSV alone (no intervals in
    it, written before its columns 'flagged' and the intervals) draws its values as "no
    interval in this summary", and with its result files beside it takes their doubt."""
    from laminid_cli.batch import read_summary, write_summary_csv

    shutil.copy(batch_dir / "summary.csv", tmp_path / "summary.csv")
    fig = {p.name: p.figure for p in report_pages(tmp_path / "summary.csv")}["constants"]
    g = ax(fig, "across-G13")
    assert _line(g, "value-S1.4-IM7/977-2").get_markerfacecolor() == "w"
    assert any(t.get_text() == "?" for t in g.texts)
    assert any(ln.get_gid() == "interval" for ln in g.get_lines())
    wide = tmp_path / "wide.csv"
    write_summary_csv(wide, read_summary(batch_dir / "summary.json"), wide=True)
    fig = {p.name: p.figure for p in report_pages(wide)}["constants"]
    g = ax(fig, "across-G13")
    assert _line(g, "value-S1.4-IM7/977-2").get_marker() == "o"        # from the result file
    assert _line(g, "value-S1.4-IM7/977-2").get_markerfacecolor() == "w"
    (tmp_path / "x").mkdir()
    alone = tmp_path / "x" / "wide.csv"
    # a wide summary written before its columns 'flagged' and the intervals: the present note
    old_wide(wide, alone, flagged=False)
    fig = {p.name: p.figure for p in report_pages(alone)}["constants"]
    g = ax(fig, "across-E1")
    assert _line(g, "value-S1.4-IM7/977-2").get_marker() == "d"
    legend = [t.get_text() for a in fig.axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "no interval in this summary (wide CSV, result file not found)" in legend
    assert "identified, with its confidence interval" not in legend
    foot = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
    assert "values without their doubt (hollow diamonds): a --wide summary.csv written " \
           "before its interval columns has no intervals" in foot


def test_damping_page_fits_the_page_and_ends_with_the_status(damped, tmp_path):
    """The loss-factor table stays inside the page (short verdicts, the advice once under the
    table), fixed loss factors say they were given, one held at 0 has no interval (it showed
    the one-sided 0 .. upper a file written before keeps: hybrid-CM's "[0, 1e+06]"), and the
    page ends with the result's status like the others."""
    from laminid_cli.report import status_line
    from laminid_cli.report_damping import loss_factor_rows, read_damping

    res = read_result(damped)
    fig = result_page(damped, "damping")
    status = next(t for t in fig.texts if t.get_gid() == "status").get_text()
    head, _ = status_line(res)
    assert status.replace("\n    ", " ").replace("\n", " ") == head.replace("\n", " ")
    a = ax(fig, "loss-factors")
    t = cells(a)
    d = read_damping(res)
    assert [row[3] for row in t[1:4]] == [short_verdict(v) for v in d["verdict"]]
    assert t[4] == ["E-glass/R368.eta13", "1.000", "none — fixed",
                    "fixed at the value given (not identified)"]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw_without_rendering()            # lays out and places every text
    width = fig.bbox.width
    for cell in a.tables[0].get_celld().values():
        box = cell.get_window_extent(renderer)
        assert 0 <= box.x0 and box.x1 <= width
        text = cell.get_text().get_window_extent(renderer)
        assert box.x0 <= text.x0 and text.x1 <= box.x1 + 1          # no text past its cell
    held = dict(d, at_bound=np.array([True] + [False] * (len(d["labels"]) - 1)))
    row = loss_factor_rows(held)[0]
    assert row[2] == "none — held at 0"
    assert row[3] == "held at 0 by η ≥ 0: not identified"
    assert loss_factor_rows(held)[1][2] == f"[{100 * d['lower'][1]:.3f}, {100 * d['upper'][1]:.3f}]"
    # a Monte Carlo range hundreds of times the value: its widths as the note under the table
    # and the terminal write them (was "±27339 %", beside the note's "±273x")
    n = len(d["labels"])
    wide = dict(d, verdict_from_monte_carlo=[d["labels"][0]], monte_carlo={
        "lower": np.zeros(n), "upper": np.full(n, 546.8 * d["value"][0]),
        "inner_lower": np.zeros(n), "inner_upper": np.full(n, 0.8 * d["value"][0]),
        "lower_at_zero": np.ones(n, bool)})
    assert loss_factor_rows(wide)[0][3].endswith("(Monte Carlo\n±273x, ±40.0 % for sure)")
    # held at 0 with a Monte Carlo: how many refits held it too, not the refits' range (it
    # showed "Monte Carlo 0*–1.2e+06" under "none — held at 0" on hybrid CM)
    held_mc = dict(wide, at_bound=held["at_bound"],
                   monte_carlo=dict(wide["monte_carlo"], trials_at_zero=np.full(n, 13),
                                    refits=20))
    rows = loss_factor_rows(held_mc)
    assert rows[0][2] == "none — held at 0\nMonte Carlo: held in 13 of 20"
    assert rows[1][2].startswith(f"[{100 * d['lower'][1]:.3f}, ") and "Monte Carlo 0.000*–" in rows[1][2]
    write_pages([type("P", (), {"name": "d", "figure": fig})()], tmp_path / "d.png")


def test_status_on_top_of_the_first_page_at_the_foot_of_the_others(checked):
    """As the README says: the status and its reasons open the report (under the title of
    the first page, above the constants); every other page repeats it at its foot."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    names = ("summary", "intervals") + (("damping",) if read_result(checked).damping is not None
                                        else ())
    pages = {name: result_page(checked, name) for name in names}
    fig = pages["summary"]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw_without_rendering()            # lays out and places every text
    status = status_text(fig)
    assert status not in fig.texts                          # not a footer
    box = status.get_window_extent(renderer)
    table = ax(fig, "constants").get_window_extent(renderer)
    title = fig._suptitle.get_window_extent(renderer)
    assert table.y1 < box.y0 and box.y1 <= title.y0 + 1      # under the title, above the table
    assert status.get_text().startswith("status: CHECK — [at_bound]")
    for name in ("intervals", "damping") if "damping" in pages else ("intervals",):
        foot = status_text(pages[name])
        assert foot in pages[name].texts and foot.get_position()[1] < 0.05


@pytest.fixture(scope="module")
def s13(tmp_path_factory):
    """S1.3 as identified (its default mesh): status check with three reasons (undetermined,
    poor_fit, implausible), which ran the top-right status into the titles."""
    out = tmp_path_factory.mktemp("s13") / "S1.3.result.h5"
    r = run("identify", S13, "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture(scope="module")
def frf_result(frf_case):
    """S2.1 fitted from an FRF file (the report has an FRF page, with its coherence panel)."""
    return frf_case[0]


#: a long specimen name: 60 characters, so that a title carrying it (and "A + B" of a joint
#: result's two such names) still fits the page's width
LONG_NAME = "IM7/977-2 [0/90/+45/-45]s panel P-0042, plate 07 (recut 2nd)"


def worst_case(path):
    """The result at ``path`` read back with every reason code laminid_cli.status defines and
    long plate names (the two things that widen the status and the titles)."""
    from laminid_cli.status import CODES, Reason, ResultStatus

    res = read_result(path)
    status = ResultStatus("check", tuple(Reason(c, f"{c} (synthetic)") for c in CODES))
    many = len(res.plates) > 1
    names = [LONG_NAME[:28] + f" #{k + 1}" if many else LONG_NAME
             for k in range(len(res.plates))]
    return dataclasses.replace(res, status=status, plates=tuple(
        dataclasses.replace(p, name=n) for p, n in zip(res.plates, names)))


@pytest.mark.parametrize("case", ["s13", "s13-worst", "joint-worst", "damped-worst",
                                  "frf-worst"])
def test_status_clear_of_the_titles_on_every_page(case, request):
    """Wherever a page carries the status (under the first page's title, at the foot, at the
    top right), its drawn box meets neither the page's title nor an axes' title and stays
    inside the page: with S1.3's three reasons and with all reason codes and long names, on
    single, joint, damping and FRF pages."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report import result_pages

    fixture, _, worst = case.partition("-")
    path = request.getfixturevalue({"s13": "s13", "joint": "joint", "damped": "damped",
                                    "frf": "frf_result"}[fixture])
    pages = result_pages(worst_case(path) if worst else path)
    names = {p.name for p in pages}
    assert {"modes-1", "sensitivities", "history"} <= names or "shared" in names
    assert fixture != "damped" or "damping" in names
    assert fixture != "frf" or "frf" in names
    bad = []
    for page in pages:
        fig = page.figure
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw_without_rendering()        # lays out and places every text
        status = status_text(fig)
        if worst and status.get_text().startswith("status: CHECK ("):
            assert "modes_swapped; see page 1)" in status.get_text()
        box = status.get_window_extent(renderer)
        titles = [fig._suptitle] if fig._suptitle is not None else []
        titles += [t for a in fig.axes for t in (a.title, a._left_title, a._right_title)
                   if t.get_text()]
        for t in titles:
            if box.overlaps(t.get_window_extent(renderer)):
                bad.append(f"{page.name}: status over {t.get_text()[:40]!r}")
        if not fig.bbox.containsx(box.x0) or not fig.bbox.containsx(box.x1) \
                or not fig.bbox.containsy(box.y0) or not fig.bbox.containsy(box.y1):
            bad.append(f"{page.name}: status outside the page {box.bounds}")
    assert not bad


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_summary_loss_factor_page_draws_their_monte_carlo_range(tmp_path, kind):
    """With --monte-carlo each trial refits the loss factors at its own constants: the range
    goes into both summaries (mc_lower, mc_upper of the loss factor's row, as a constant's),
    reads back, and is drawn in grey beside the interval, named in the legend and the footer;
    a loss factor held at 0 keeps its side and limit through summary.csv. A range whose lower
    end refits held at 0 set (eta13 here; the terminal's "0*") keeps that flag through both
    summaries (summary.csv's mc_search_limit "lower") and gets its "*" on the page, with the
    legend saying what it means; it had none past the result file."""
    from laminid_cli.batch import read_summary
    from laminid_cli.damping import VERDICT_NOT_DAMPING
    from laminid_cli.report import mc_tint

    rows = _summary_rows()
    free = {"at_bound": False, "bound_side": "", "bound_limit": None}
    rows[0]["damping"] = {"glass": {
        "eta11": {"value": 0.002, "lower": 0.0017, "upper": 0.0023, "verdict": "weak",
                  "mc_lower": 0.0012, "mc_upper": 0.0031, "mc_lower_at_limit": False,
                  "mc_upper_at_limit": False} | free,
        "eta13": {"value": 0.0077, "lower": 0.0, "upper": 0.017,
                  "verdict": VERDICT_NOT_DAMPING.format(term="eta13"), "mc_lower": 0.0,
                  "mc_upper": 0.0102, "mc_lower_at_limit": True,
                  "mc_upper_at_limit": False} | free,
        "eta22": {"value": 0.0, "lower": 0.0, "upper": 0.03, "verdict":
                  "at bound — not identified", "at_bound": True, "bound_side": "lower",
                  "bound_limit": 0.0}}}
    path = tmp_path / f"summary.{kind}"
    _write_summary(path, rows)
    back = {r["name"]: r for r in read_summary(path)}["H"]["damping"]["glass"]
    assert back["eta11"]["mc_lower"] == 0.0012 and back["eta11"]["mc_upper"] == 0.0031
    assert back["eta22"]["bound_side"] == "lower" and back["eta22"]["bound_limit"] == 0.0
    assert "mc_lower" not in back["eta22"] or back["eta22"]["mc_lower"] is None
    assert (back["eta13"]["mc_lower_at_limit"], back["eta13"]["mc_upper_at_limit"]) \
        == (True, False)
    assert not back["eta11"]["mc_lower_at_limit"] and not back["eta11"]["mc_upper_at_limit"]
    fig = {p.name: p.figure for p in report_pages(path)}["loss-factors"]
    a = ax(fig, "across-eta11")
    mc = _line(a, "monte-carlo-H-glass")
    assert np.allclose(mc.get_ydata(), [0.12, 0.31], rtol=1e-12)
    assert mc.get_color() == mc_tint(_line(a, "value-H-glass").get_color())   # glass's, pale
    assert mc.get_xdata()[0] > _line(a, "interval-H-glass").get_xdata()[0]
    assert not [t for t in a.texts if t.get_gid() == "monte-carlo-H-glass-search-limit"]
    a = ax(fig, "across-eta13")
    assert _line(a, "monte-carlo-H-glass").get_ydata()[0] == 0.0      # (off the top: arrow)
    star = [t for t in a.texts if t.get_gid() == "monte-carlo-H-glass-search-limit"]
    assert [t.get_text() for t in star] == ["*"] and star[0].xy[1] == 0.0
    legend = [t.get_text() for t in ax(fig, "legend").get_legend().get_texts()]
    assert any(t.startswith("Monte Carlo range (each trial refits") for t in legend)
    assert any("*: end set by refits held at 0" in t for t in legend)
    assert any("the Monte Carlo ranges count the free constants' doubt too"
               in " ".join(t.get_text().split()) for t in fig.texts)


@pytest.mark.parametrize("kind", ["csv", "json", "wide"])
def test_summary_loss_factor_leaning_on_an_undetermined_constant_is_marked(tmp_path, kind):
    """A loss factor whose verdict says "interval too narrow: its energy share leans on
    glass.E2, not determined by the modes" (damping.VERDICT_LEANS; no Monte Carlo counted the
    constant's doubt) was drawn as a plain identified dot with a solid bar, the same as a weak
    one. Now a half-filled dot and a dashed bar, a legend entry, and a footer line naming the
    specimen, the loss factor and the constant; a plain weak one keeps its filled dot."""
    from laminid_cli.batch import write_summary_csv
    from laminid_cli.damping import VERDICT_LEANS

    rows = _summary_rows()
    free = {"at_bound": False, "bound_side": "", "bound_limit": None}
    rows[0]["damping"] = {"glass": {
        "eta11": {"value": 0.002, "lower": 0.0017, "upper": 0.0023, "verdict": "weak"} | free,
        "eta22": {"value": 0.012, "lower": 0.0097, "upper": 0.0143,
                  "verdict": "weak" + VERDICT_LEANS.format(labels="glass.E2")} | free}}
    path = tmp_path / f"summary.{'json' if kind == 'json' else 'csv'}"
    if kind == "wide":
        write_summary_csv(path, rows, wide=True)
    else:
        _write_summary(path, rows)
    fig = {p.name: p.figure for p in report_pages(path)}["loss-factors"]
    a = ax(fig, "across-eta22")
    dot = _line(a, "leans-H-glass")
    assert dot.get_fillstyle() == "left" and dot.get_markerfacecoloralt() == "w"
    assert dot.get_ydata()[0] == pytest.approx(1.2, rel=1e-12)
    assert "value-H-glass" not in [ln.get_gid() for ln in a.get_lines()]
    bar = _line(a, "interval-H-glass")
    assert bar.get_linestyle() == "--"
    assert np.allclose(bar.get_ydata(), [0.97, 1.43], rtol=1e-12)
    a = ax(fig, "across-eta11")
    v = _line(a, "value-H-glass")
    assert v.get_fillstyle() == "full" and v.get_markerfacecolor() == v.get_color()
    assert _line(a, "interval-H-glass").get_linestyle() == "-"
    legend = [" ".join(t.get_text().split())
              for t in ax(fig, "legend").get_legend().get_texts()]
    assert ("interval too narrow: its energy share leans on a constant the modes do not "
            "determine (named below)") in legend
    foot = " ".join(" ".join(t.get_text() for t in fig.texts).split())
    assert "H: glass.eta22 leans on glass.E2, not determined by the modes: interval too " \
           "narrow" in foot


def test_short_verdict_of_a_loss_factor_not_determined_by_the_damping():
    """The damping's verdict has its own phrase ("by the measured damping"); the table shows
    "not determined", not the phrase cut at the length of the modes' one."""
    from laminid_cli.damping import VERDICT_NOT_DAMPING
    from laminid_cli.intervals import VERDICT_NOT

    assert short_verdict(VERDICT_NOT_DAMPING.format(term="eta22")) == "not determined"
    assert short_verdict(VERDICT_NOT) == "not determined"


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_summary_with_loss_factors_has_a_loss_factor_page(tmp_path, kind, monkeypatch):
    """A batch summary holding loss factors had no page of them; now one panel per loss
    factor (%) in the marks of the constants' page -- interval bar, hollow "?" for not
    determined by the damping, a hollow triangle at 0 for one held at 0 by eta >= 0 (no
    interval: it had a one-sided bar 0 .. upper), a grey square for a fixed one -- and the
    table of a result's
    damping page, verdicts in the same words, a specimen column in front. A specimen without
    loss factors (Q) is in neither; a summary without any has no such pages."""
    from laminid_cli.damping import VERDICT_NOT_DAMPING
    from laminid_cli.report import FIXED_COLOR

    rows = _summary_rows()
    path = tmp_path / f"summary.{kind}"
    _write_summary(path, rows)
    assert [p.name for p in report_pages(path)] == ["constants", "residuals"]
    free = {"at_bound": False, "bound_side": "", "bound_limit": None}
    rows[0]["damping"] = {"glass": {
        "eta11": {"value": 0.002, "lower": 0.0017, "upper": 0.0023, "verdict": "weak"} | free,
        "eta22": {"value": 0.0, "lower": 0.0, "upper": 0.03, "verdict":
                  "at bound — not identified", "at_bound": True, "bound_side": "lower",
                  "bound_limit": 0.0},
        "eta13": {"value": 0.02, "lower": 0.0, "upper": 0.09,
                  "verdict": VERDICT_NOT_DAMPING.format(term="eta13")} | free,
        "eta23": {"value": 0.012, "lower": None, "upper": None, "verdict": "fixed"}}}
    _write_summary(path, rows)
    # the pages the command builds and writes are the ones read below
    built = pages_the_command_builds(monkeypatch)
    r = run("report", path, "-o", tmp_path / "s.png", "--dpi", "50")
    assert r.exit_code == 0, r.output
    assert "loss-factors, loss-factor-table" in r.output
    assert (tmp_path / "s-4.png").read_bytes()[:8] == PNG
    (written,) = built
    pages = {p.name: p.figure for p in written}
    assert list(pages) == ["constants", "residuals", "loss-factors", "loss-factor-table"]
    fig = pages["loss-factors"]
    a = ax(fig, "across-eta11")
    v = _line(a, "value-H-glass")
    assert v.get_ydata()[0] == pytest.approx(0.2) and v.get_markerfacecolor() == v.get_color()
    assert np.allclose(_line(a, "interval-H-glass").get_ydata(), [0.17, 0.23], rtol=1e-12)
    assert a.get_title() == "\u03b711 (%)" and a.get_ylim()[0] == 0
    a = ax(fig, "across-eta22")
    mark = _line(a, "at-bound-H-glass")
    assert mark.get_marker() == "v" and mark.get_markerfacecolor() == "w"
    assert mark.get_ydata()[0] == 0.0
    assert [ln.get_gid() for ln in a.get_lines()] == ["at-bound-H-glass"]     # no bar
    assert not a.texts                            # (nor the arrow of a bar off the panel)
    assert a.get_ylim() == (0.0, 1.15)            # nothing but the mark at 0 to show
    a = ax(fig, "across-eta13")
    assert _line(a, "value-H-glass").get_markerfacecolor() == "w"
    assert [t.get_text() for t in a.texts].count("?") == 1
    a = ax(fig, "across-eta23")
    mark = _line(a, "fixed-H-glass")
    assert mark.get_marker() == "s" and mark.get_color() == FIXED_COLOR
    assert mark.get_ydata()[0] == pytest.approx(1.2)
    assert not [ln for ln in a.get_lines() if "Q" in str(ln.get_gid())]
    legend = [t.get_text() for t in ax(fig, "legend").get_legend().get_texts()]
    assert "held at 0 by \u03b7 \u2265 0: not identified, no interval" in legend
    keys = dict(zip(legend, ax(fig, "legend").get_legend().legend_handles))
    assert keys["held at 0 by \u03b7 \u2265 0: not identified, no interval"].get_linestyle() \
        == "None"                                                 # its key: no bar either
    assert "?: not determined by the damping (interval too wide)" in legend
    assert any("taken as exact" in t.get_text() for t in fig.texts)
    # the table: the words of a result's damping page
    table = ax(pages["loss-factor-table"], "loss-factors").tables[0]
    cells = {(i, j): c.get_text().get_text() for (i, j), c in table.get_celld().items()}
    body = [[cells[i, j] for j in range(5)] for i in range(1, 5)]
    assert body == [["H", "glass.eta11", "0.200", "[0.170, 0.230]", "weak"],
                    ["H", "glass.eta22", "0.000", "none — held at 0",
                     "held at 0 by \u03b7 \u2265 0: not identified"],
                    ["H", "glass.eta13", "2.000", "[0.000, 9.000]", "not determined"],
                    ["H", "glass.eta23", "1.200", "none — fixed",
                     "fixed at the value given (not identified)"]]
    assert (5, 0) not in cells                                  # Q has no loss factors


def test_bound_statement_stays_inside_its_panel(checked, tmp_path):
    """The words "stopped on the lower search limit: no interval" beside a constant at its
    lower limit stay inside the panel: with a profile bound far above the limit (the panel
    from 0 to it), centred on the limit at the panel's foot, they ran below the axis over the
    value and the words under it (S1.2, 8x8: G13 at 0.0164 GPa, rejected above 5.36 GPa)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = tmp_path / "S1.4.result.h5"
    shutil.copy(checked, path)
    with h5py.File(path, "r+") as f:
        u = f["uncertainty"]
        j = [s.decode() for s in u["labels"][()]].index(f"{MAT}.G23")
        bound = np.full(len(u["labels"]), np.nan)
        bound[j] = 5.36e9
        u.create_dataset("profile_bound", data=bound).attrs["units"] = "Pa (nu12: 1)"
        f["materials/IM7_977-2/G23"][()] = 0.0160e9     # the limit it stopped on
    fig = result_page(path, "intervals")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw_without_rendering()            # lays out and places every text
    a = ax(fig, f"interval-{MAT}.G23")
    words = next(t for t in a.texts if t.get_gid() == "bound-statement")
    box, panel = words.get_window_extent(renderer), a.get_window_extent(renderer)
    assert panel.y0 <= box.y0 and box.y1 <= panel.y1, (box.bounds, panel.bounds)
    assert not box.overlaps(a.xaxis.label.get_window_extent(renderer))


@pytest.mark.parametrize("kind", ["csv", "json"])
def test_legend_of_a_monte_carlo_verdict_names_the_range(tmp_path, kind):
    """A constant "not determined (Monte Carlo)" may have a narrow interval (hybrid ESL's G13,
    8x8, 40 trials: ±27 %, range ±39 %): the hollow "?" of the page across specimens says the
    interval *or the Monte Carlo range* is too wide, where "interval too wide" contradicted the
    bar drawn; the result's interval page likewise."""
    rows = _summary_rows()
    q = rows[1]["intervals"]["carbon"]["G13"]
    q.update(verdict="not determined by these modes (Monte Carlo) — fix it or measure a "
                     "thicker plate / more modes", flagged=True, mc_lower=2.0e9, mc_upper=5.6e9)
    path = tmp_path / f"summary.{kind}"
    _write_summary(path, rows)
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    legend = [t.get_text() for a in fig.axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "?: not determined (interval or Monte Carlo range too wide)" in legend
    assert "?: not determined (interval too wide)" not in legend
    # without a Monte Carlo verdict the words stay those of the interval
    _write_summary(path, _summary_rows())
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    legend = [t.get_text() for a in fig.axes if a.get_legend() is not None
              for t in a.get_legend().get_texts()]
    assert "?: not determined (interval too wide)" in legend


def test_interval_legend_of_a_monte_carlo_verdict_names_the_range(checked, tmp_path):
    path = _with_monte_carlo(checked, tmp_path)
    with h5py.File(path, "r+") as f:
        f["uncertainty"].attrs["verdict_from_monte_carlo"] = f"{MAT}.G13"
    fig = result_page(path, "intervals")
    texts = [t.get_text() for a_ in fig.axes if a_.get_legend() is not None
             for t in a_.get_legend().get_texts()]
    assert "not determined (interval or Monte Carlo range too wide)" in texts


def test_joint_reference_that_differs_between_plates_is_their_range_and_said(joint, tmp_path):
    """Plates fitted together whose specimen files give different references for a shared
    constant (E1 170 GPa in S1.1, 160 GPa here for S1.2): the summary compares with the range
    160.0–170.0 and a note names each plate's value (the first plate's alone was shown); a
    constant they agree on (E2 10 GPa) stays one value, without a note."""
    from laminid_cli.resultfile import combined_reference

    res = read_result(joint)
    p1, p2 = res.plates
    ref2 = {MAT: {**p2.reference[MAT], "E1": (160e9, 160e9)}}
    res = dataclasses.replace(res, plates=(p1, dataclasses.replace(p2, reference=ref2)))
    assert res.reference[MAT]["E1"] == (160e9, 170e9)
    assert res.reference[MAT]["E2"] == (10e9, 10e9)
    assert res.reference_notes == [
        "reference E1 differs between the plates (S1.1 170, S1.2 160 GPa): the range from the "
        "lowest to the highest is shown"]
    pages = {"shared": result_page(res, "shared")}
    rows = {row[0].split(" ")[0]: row for row in cells(ax(pages["shared"], "constants"))[1:]}
    e1 = res.materials[MAT]["E1"]
    assert rows["E1"][5].startswith("160.00–170.00\n")
    assert rows["E1"][5] == "160.00–170.00\n" + (
        "(inside)" if 160e9 <= e1 <= 170e9 else
        f"({round((e1 / 160e9 - 1) * 100):+d} % below)" if e1 < 160e9 else
        f"(+{round((e1 / 170e9 - 1) * 100)} % above)")
    text = " ".join(t.get_text() for a in pages["shared"].axes for t in a.texts)
    assert "reference E1 differs between the plates (S1.1 170, S1.2 160 GPa)" \
        in text.replace("\n", " ")
    assert "reference low–high: a range given by the specimen file or the plates' different " \
        "values;" in text.replace("\n", " ")
    # a range in one plate, a value in the other; the materials named with two of them
    refs, notes = combined_reference([("A", {"glass": {"G12": (4e9, 5e9)}, "carbon": {}}),
                                      ("B", {"glass": {"G12": 6e9}}),
                                      ("C", {"glass": {"nu12": 0.3}})])
    assert refs == {"glass": {"G12": (4e9, 6e9), "nu12": (0.3, 0.3)}}
    assert notes == ["reference G12 differs between the plates (A 4–5, B 6 GPa): the range "
                     "from the lowest to the highest is shown"]


def test_joint_terminal_table_gives_the_plates_reference_range(tmp_path):
    """The terminal report of identify --joint: the shared constants' reference from every
    plate (the range where they differ, with the note), not the first plate's alone."""
    s12 = tmp_path / "S1.2.yaml"
    s12.write_text(Path(S12).read_text().replace("{E1: 170 GPa, E2: 10 GPa", "{E1: 160 GPa, "
                                            "E2: 10 GPa"))
    r = run("identify", S11, s12, "--joint", "--mesh", "4x4", "--no-output")
    assert r.exit_code == 0, r.output
    e1 = next(ln for ln in r.output.splitlines() if ln.startswith("  E1 [GPa]"))
    assert "160.00 .. 170.00" in e1
    assert ("  note: reference E1 differs between the plates (S1.1 170, S1.2 160 GPa): the "
            "range from the lowest to the highest is shown") in r.output.splitlines()
    same = run("identify", S11, S12, "--joint", "--mesh", "4x4", "--no-output")
    e1 = next(ln for ln in same.output.splitlines() if ln.startswith("  E1 [GPa]"))
    assert "170.00" in e1 and ".." not in e1.split("170.00")[0] and "note: reference" \
        not in same.output


def test_a_mode_without_measured_damping_is_marked_on_the_damping_page(damped):
    """A mode whose damping the specimen gives as null (fit-frf: not above the exponential
    window's) had only its model square on the page, and the legend's 'measured 2 zeta' left
    the reader to guess why the dot was missing; it is marked x on the axis and keyed."""
    from laminid_cli.report_damping import damping_pages, read_damping

    d = dict(read_damping(read_result(damped)))
    meas = np.array(d["measured_loss_factor"], float)
    meas[[0, 4]] = np.nan
    d["measured_loss_factor"] = meas
    d["measured_sigma"] = np.where(np.isnan(meas), np.nan, d["measured_sigma"])
    fig = damping_pages(d)[0]
    a = ax(fig, "modal-loss-factors")
    x = next(ln for ln in a.get_lines() if ln.get_gid() == "not-measured")
    assert list(x.get_xdata()) == [1, 5] and list(x.get_ydata()) == [0, 0]
    dots = next(ln for ln in a.get_lines() if ln.get_gid() == "measured")
    assert 1 not in dots.get_xdata() and 5 not in dots.get_xdata()
    assert "no measured damping (null)" in [t.get_text() for t in a.get_legend().get_texts()]
    fig = damping_pages(dict(read_damping(read_result(damped))))[0]        # all measured: no key
    a = ax(fig, "modal-loss-factors")
    assert not any(ln.get_gid() == "not-measured" for ln in a.get_lines())
    assert "no measured damping (null)" not in [t.get_text()
                                                for t in a.get_legend().get_texts()]


#: the largest band across the damping page that nothing is drawn in, as a fraction of the
#: page's height: two lines of 9-point text (a single material's table left 0.093 blank
#: between it and the status)
DAMPING_PAGE_MAX_BLANK = 0.04


def _drawn_bands(fig):
    """{what: (y0, y1)} of what the page draws, in fractions of its height, once laid out:
    each panel with its labels, legend and title, the loss-factor table, the texts above it
    (its title, the advice and notes), the page's title and the status at its foot."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = (fig.canvas if isinstance(fig.canvas, FigureCanvasAgg)
                else FigureCanvasAgg(fig)).get_renderer()
    fig.draw_without_rendering()
    height = fig.bbox.height
    boxes = {}
    for a in fig.axes:
        if a.axison:
            boxes[a.get_gid()] = a.get_tightbbox(renderer)
        for k, t in enumerate([*a.tables, a.title, *a.texts]):
            if not hasattr(t, "get_text") or t.get_text().strip():
                boxes[f"{a.get_gid()}-{t.get_gid() or k}"] = t.get_window_extent(renderer)
    for k, t in enumerate([*fig.texts, fig._suptitle]):
        if t is not None and t.get_text().strip():
            boxes[f"page-{t.get_gid() or k}"] = t.get_window_extent(renderer)
    return {key: (b.y0 / height, b.y1 / height) for key, b in boxes.items()}


def _largest_blank(bands) -> float:
    """The tallest band of the page (0 to 1) that none of ``bands`` covers."""
    edges, blank = 0.0, 0.0
    for y0, y1 in sorted(bands.values()):
        blank = max(blank, y0 - edges)
        edges = max(edges, y1)
    return max(blank, 1.0 - edges)


@pytest.mark.parametrize("monte_carlo", [False, True], ids=["plain", "monte-carlo"])
def test_the_damping_page_has_no_blank_band_and_its_table_fits_its_rows(damped, monte_carlo,
                                                                        monkeypatch):
    """The damping page's table got a fixed 1.25 of 4.25 of the panels' and table's height
    whatever its rows; a single material's 5 rows (S2.1) filled 0.11 of the page's height of
    the 0.18 given, and a white band of 0.093 of the page stayed between the table and the
    status. Now the table's row is sized to its rows: no band of the page is blank beyond
    DAMPING_PAGE_MAX_BLANK, nothing overlaps (panels, the table's title and notes, the table,
    the status; the legends under the panels and their axis label "mode", which met where the
    panels were shorter) and every row is as tall as its text, a Monte Carlo range's two
    lines too."""
    from laminid_cli import report_damping

    r = read_result(damped)
    if monte_carlo:   # each free loss factor's range under its interval: two-line rows
        d = dict(report_damping.read_damping(r))
        d["monte_carlo"] = {"lower": 0.8 * d["value"], "upper": 1.3 * d["value"],
                            "lower_at_zero": np.zeros(len(d["value"]), bool), "refits": 40}
        monkeypatch.setattr(report_damping, "read_damping", lambda _: d)
    [(_, fig)] = report_damping.damping_figures(r)
    bands = _drawn_bands(fig)
    assert _largest_blank(bands) < DAMPING_PAGE_MAX_BLANK, bands
    panels = min(bands["modal-loss-factors"][0], bands["energy-shares"][0])
    table = bands["loss-factors-0"]
    title = bands["loss-factors-1"]
    note = bands["loss-factors-loss-factor-note"]
    status = bands["page-status"]
    assert 0 < status[1] <= table[0] < table[1] <= note[0] < note[1] <= title[1] <= panels
    assert bands["page-2"][1] <= 1.0                                       # the title
    renderer = fig.canvas.get_renderer()
    for gid in ("modal-loss-factors", "energy-shares"):    # the legend under the axis label
        a = ax(fig, gid)
        assert a.get_legend().get_window_extent(renderer).y1 < \
            a.xaxis.label.get_window_extent(renderer).y0
    t = ax(fig, "loss-factors").tables[0]
    for cell in t.get_celld().values():
        box, text = cell.get_window_extent(renderer), cell.get_text().get_window_extent(renderer)
        assert box.y0 <= text.y0 and text.y1 <= box.y1, cell.get_text().get_text()
        assert 0 <= box.x0 and box.x1 <= fig.bbox.width
    intervals = [row[2] for row in cells(ax(fig, "loss-factors"))[1:]]
    assert sum(x.count("\n") for x in intervals) == (len(r.damping.data["labels"])
                                                     if monte_carlo else 0)


#: the status of hybrid-CM (6x6, --monte-carlo 20, synthetic damping): three constants at their
#: search limits, eight undetermined, loss factors held at 0 and not determined; 14 lines at the
#: foot of the page
HYBRID_STATUS = (
    ("at_bound", "glass.E2: at its bound — not identified: stopped on the search's upper "
     "limit, E2 = E1 (59.9 GPa); the fit is as good with E2 anywhere below the limit down to "
     "0.9 GPa, the end of the scan: the initial value / 5 (chi2 rises by 2.8; 4.84 would "
     "reject it at 95 %; not tried beyond): the modes do not determine E2 there (1 of its 2 "
     "identifications stopped at 100 evaluations: its rise is an upper bound, enough to say "
     "the fit does not reject that value); glass.G12: at its bound — not identified: stopped "
     "on the search's lower limit, G12 = 0.0001 E1 (0.00614 GPa at the optimum); carbon.nu12: "
     "at its bound — not identified: stopped on the search's upper limit, nu12 = 0.95; the fit "
     "is as good with nu12 anywhere below the limit down to 0, the end of the scan: a negative "
     "nu12 is no fibre ply's (chi2 rises by 0.02; 4.84 would reject it at 95 %; not tried "
     "beyond): the modes do not determine nu12 there; loss factors held at their lower limit "
     "0 (the measured damping asks for less than none in these terms): glass.eta12, "
     "glass.eta23, carbon.eta22, carbon.eta23"),
    ("undetermined", "not determined by these modes (95 % half-width above 30 % of the value): "
     "glass.E1 (±12x), glass.G13 (±21x), glass.G23 (±20x), glass.nu12 (±93x), carbon.E1 "
     "(±203 %), carbon.E2 (±242x), carbon.G13 (±369x), carbon.G23 (±104x); loss factors not "
     "determined by the measured damping (95 % half-width above 30 % of the value): "
     "glass.eta22 (±183 %), glass.eta13 (Monte Carlo ±273x, at least ±157x; interval ±19 %), "
     "carbon.eta11 (±138 %), carbon.eta12 (Monte Carlo ±54 %, at least ±53 %; interval "
     "±13 %), carbon.eta13 (Monte Carlo ±244 %, at least ±39 %; interval ±18 %)"))


def _hybrid_damping(n_modes: int = 20, mats=("glass", "carbon")) -> dict:
    """read_damping's dict of a two-material plate (hybrid-CM's glass and carbon, 20 modes)
    with a Monte Carlo of 20 trials: ten free loss factors, each row two lines (its range under
    its interval), three verdicts set by the range (two-line verdicts), the result's long
    note on the loss factors. More ``mats``: their rows those of glass and carbon again."""
    terms = ("11", "22", "12", "13", "23")
    labels = [f"{m}.eta{t}" for m in mats for t in terms]
    n = len(labels)
    value = np.resize([0.0063, 0.0155, 0.0, 0.105, 0.0, 0.0044, 0.0, 0.0048, 1.46, 0.0], n)
    at_bound = value == 0
    upper = np.resize([0.0072, 0.044, 1.0e4, 0.125, 2.5, 0.0104, 52.6, 0.0054, 1.73, 16.2], n)
    shares = np.random.default_rng(3).dirichlet(np.ones(n), n_modes)
    eta = np.linspace(0.006, 0.0136, n_modes)
    verdict = ["weak", "not determined by the measured damping", "at bound — not identified",
               "not determined by the measured damping (Monte Carlo)",
               "at bound — not identified", "not determined by the measured damping",
               "at bound — not identified",
               "not determined by the measured damping (Monte Carlo)",
               "not determined by the measured damping (Monte Carlo)",
               "at bound — not identified"] * (n // 10 + 1)
    verdict = verdict[:n]
    notes = ("glass.eta13, carbon.eta13: less than 1% of any fitted mode's strain energy is in "
             "these terms (transverse shear of a thin plate), so the modal damping cannot "
             "determine them; fix them (--fix eta13=0.01,eta23=0.01) to free the others; "
             + ", ".join(labels) + ": the loss factors' intervals take the elastic constants "
             "as identified, and carbon.E1, carbon.E2, carbon.G13, carbon.G23, carbon.nu12, "
             "glass.E1, glass.E2, glass.G12, glass.G13, glass.G23, glass.nu12 are not "
             "determined by the modes (or fixed because of it): these loss factors are known "
             "less well than the interval says; the Monte Carlo range counts the free "
             "constants' doubt (each trial refits the loss factors at its own constants)")
    return {"measured_loss_factor": eta, "measured_sigma": 0.05 * eta,
            "model_loss_factor": 1.02 * eta, "used": np.ones(n_modes, bool),
            "energy_shares": shares, "share_labels": [f"{m}.{t}" for m in mats for t in terms],
            "labels": labels, "value": value, "lower": 0.85 * value, "upper": upper,
            "at_bound": at_bound, "verdict": verdict, "confidence": 0.95, "s2": 0.917,
            "dof": 14, "sigma_source": "5% of each damping ratio (none given)",
            "monte_carlo": {"lower": 0.0 * value, "upper": 1.2 * upper,
                            "lower_at_zero": np.ones(n, bool), "refits": 20,
                            "trials_at_zero": np.full(n, 12),
                            "inner_lower": 0.0 * value, "inner_upper": 0.9 * upper},
            "verdict_from_monte_carlo": ["glass.eta13", "carbon.eta12", "carbon.eta13"],
            "fixed": "", "notes": notes, "specimen": "hybrid-CM"}


def _drawn_texts(fig):
    """The texts ``fig`` draws: visible, not empty, not the tick labels of an axes drawn
    without its axis (a table's)."""
    from matplotlib.axis import Axis
    from matplotlib.text import Text

    def walk(artist, axis_off):
        for child in artist.get_children():
            if not child.get_visible() or (axis_off and isinstance(child, Axis)):
                continue
            if isinstance(child, Text) and child.get_text().strip():
                yield child
            yield from walk(child, axis_off or not getattr(child, "axison", True))

    return list(walk(fig, False))


#: hybrid-CM's table under its 14-line status (two reasons), under one reason, and four
#: materials' under one reason (too long for a page of its own)
TABLE_CASES = {"hybrid-status": (2, ("glass", "carbon")), "one-reason": (1, ("glass", "carbon")),
               "four-materials": (1, ("glass", "carbon", "aramid", "basalt"))}


def _damping_pages_of(case, damped, monkeypatch):
    """The damping pages of :data:`TABLE_CASES`' ``case`` over the damped result."""
    from laminid_cli import report_damping
    from laminid_cli.status import Reason, ResultStatus

    reasons, mats = TABLE_CASES[case]
    d = _hybrid_damping(mats=mats)
    r = dataclasses.replace(read_result(damped), status=ResultStatus(
        "check", tuple(Reason(code, text) for code, text in HYBRID_STATUS[-reasons:])))
    monkeypatch.setattr(report_damping, "read_damping", lambda _: d)
    return d, report_damping.damping_figures(r)


@pytest.fixture(scope="module")
def damping_table_pages(damped):
    """``pages_of(case)``: (d, pages) of :func:`_damping_pages_of`, each case built once
    (0.4-0.8 s) and each call given its own copy (pickled): the two tests below lay the
    pages out and write them, so that neither reads a figure the other has laid out; a copy
    lays out as the build it is copied from (the same bands to the last digit)."""
    import pickle

    built = {}

    def pages_of(case):
        if case not in built:
            with pytest.MonkeyPatch.context() as mp:
                built[case] = pickle.dumps(_damping_pages_of(case, damped, mp))
        return pickle.loads(built[case])

    return pages_of


@pytest.mark.parametrize("case", list(TABLE_CASES))
def test_a_damping_table_too_long_for_its_page_continues_on_the_next(damping_table_pages, case,
                                                                     tmp_path):
    """hybrid-CM (two materials, 20 modes) with a Monte Carlo of 20 trials under its 14-line status
    (6x6): the table's ten two-line rows got at most 0.6 of the panels' and table's height and
    were squeezed (their text 1.82 times as tall as their rows: the Monte Carlo ranges ran over
    the next row's intervals), and the energy shares' panel, 1.08 in tall, had its 2.65 in
    y-label run 0.30 in off the top of the page (this copy of its table and status over S2.1's
    result: 1.64 times, a 1.20 in panel, 0.24 in). Now a table that does not fit at its rows'
    height under panels as tall as their y-labels is on the next page, whole where it fits there
    (page 1 the panels, its title saying where the table is): with that status and with one of
    its reasons (which split it, carbon's rows alone on a page 0.54 blank). Four materials' do
    not fit on a page: they continue, a material's rows together, glass's under the panels and
    the others' on the next page ("ply loss factors (continued)", the header and the key to the
    ranges' "*" repeated). On every page every row is as tall as its text, every text is inside
    the page, the table is between the titles and the status, each panel is as tall as its
    y-label, the legends are clear of the axis labels, the pages list every row once, in
    order, and the advice and notes on the loss factors are over the table's end."""
    from laminid_cli import report_damping

    d, pages = damping_table_pages(case)
    whole = case != "four-materials"
    assert [name for name, _ in pages] == ["damping", "damping-2"]
    drawn = []
    for name, fig in pages:
        bands = _drawn_bands(fig)                  # lays the page out
        renderer = fig.canvas.get_renderer()
        page = fig.bbox
        for t in _drawn_texts(fig):                # every word inside the page
            box = t.get_window_extent(renderer)
            assert page.x0 - 1 <= box.x0 and box.x1 <= page.x1 + 1 \
                and page.y0 - 1 <= box.y0 and box.y1 <= page.y1 + 1, (name, t.get_text())
        if whole and name == "damping":             # the panels alone
            assert not any(a.tables for a in fig.axes)
            continue
        table = bands["loss-factors-0"]
        title = bands["loss-factors-1"]
        assert bands["page-status"][1] <= table[0] < table[1] <= title[1] <= \
            min(bands["page-2"][0],                                        # the page's title
                bands.get("modal-loss-factors", (1, 1))[0],
                bands.get("energy-shares", (1, 1))[0])
        t = ax(fig, "loss-factors").tables[0]
        for cell in t.get_celld().values():       # each row as tall as its text
            box = cell.get_window_extent(renderer)
            text = cell.get_text().get_window_extent(renderer)
            assert box.y0 <= text.y0 and text.y1 <= box.y1, (name, cell.get_text().get_text())
            assert box.x0 >= 0 and box.x1 <= page.x1
        rows = cells(ax(fig, "loss-factors"))
        assert rows[0] == ["loss factor", "value (%)", "95 % interval (%)", "verdict"]
        drawn += rows[1:]
    assert drawn == report_damping.loss_factor_rows(d)        # every row once, in order
    first, second = (fig for _, fig in pages)
    renderer = first.canvas.get_renderer()
    for gid in ("modal-loss-factors", "energy-shares"):    # each panel as tall as its label
        a = ax(first, gid)
        label = a.yaxis.label.get_window_extent(renderer)
        panel = a.get_window_extent(renderer)
        assert panel.y0 <= label.y0 and label.y1 <= panel.y1
        assert a.get_legend().get_window_extent(renderer).y1 < \
            a.xaxis.label.get_window_extent(renderer).y0
    title = ax(second, "loss-factors").get_title()
    assert "Monte Carlo: 20 trials" in title         # the key to the rows' "*" with them
    if whole:
        assert first._suptitle.get_text().endswith("the ply loss factors on the next page")
        assert title.startswith("ply loss factors, modal strain energy method")
        assert len(drawn) == 10
    else:
        assert "continued on the next page, with the notes on the loss factors" in \
            ax(first, "loss-factors").get_title()
        assert title.startswith("ply loss factors (continued)")
        assert [row[0] for row in cells(ax(first, "loss-factors"))[1:]] == \
            [f"glass.eta{k}" for k in ("11", "22", "12", "13", "23")]
        assert [row[0].split(".")[0] for row in cells(ax(second, "loss-factors"))[1:]] == \
            ["carbon"] * 5 + ["aramid"] * 5 + ["basalt"] * 5
        assert not [x for x in ax(first, "loss-factors").texts
                    if x.get_gid() == "loss-factor-note"]
    note = next(x for x in ax(second, "loss-factors").texts if x.get_gid() == "loss-factor-note")
    assert " ".join(note.get_text().split()).startswith(report_damping.NOT_DETERMINED_ADVICE)
    assert status_text(first).get_text() == status_text(second).get_text()
    write_pages([Page(name, fig) for name, fig in pages], tmp_path / "d.png")


@pytest.mark.parametrize("case", list(TABLE_CASES))
def test_a_page_of_the_damping_table_alone_has_no_blank_band(damping_table_pages, case):
    """The page of the loss-factor table alone (damping-2) put the table at its rows' height
    at the top and left the rest blank down to the status at its foot: 0.216 of the page with
    hybrid-CM's 14-line status, 0.539 with one reason (carbon's five rows alone). Now its rows
    take the room down to the status, up to TABLE_PAGE_STRETCH times their lines' height, and
    the table is whole there where it fits: no band of the page is blank beyond
    DAMPING_PAGE_MAX_BLANK (the damping page's own), nothing overlaps (the table's title and
    notes, the table, the status), every row is as tall as its text and at most
    TABLE_PAGE_STRETCH times its lines, all rows stretched alike."""
    from laminid_cli.report import row_heights
    from laminid_cli.report_damping import TABLE_PAGE_STRETCH, TABLE_ROW_IN

    _, pages = damping_table_pages(case)
    name, fig = pages[-1]
    assert name == "damping-2" and not any(a.get_gid() == "energy-shares" for a in fig.axes)
    bands = _drawn_bands(fig)
    assert _largest_blank(bands) < DAMPING_PAGE_MAX_BLANK, bands
    status, table = bands["page-status"], bands["loss-factors-0"]
    note, title = bands["loss-factors-loss-factor-note"], bands["loss-factors-1"]
    assert 0 < status[1] <= table[0] < table[1] <= note[0] < note[1] <= title[1] \
        <= bands["page-2"][0]
    renderer = fig.canvas.get_renderer()
    t = ax(fig, "loss-factors").tables[0]
    rows = cells(ax(fig, "loss-factors"))
    lines = row_heights(rows[0], rows[1:])
    stretch = []
    for (i, _), cell in t.get_celld().items():
        box = cell.get_window_extent(renderer)
        text = cell.get_text().get_window_extent(renderer)
        assert box.y0 <= text.y0 and text.y1 <= box.y1, cell.get_text().get_text()
        stretch.append(box.height / fig.dpi / (TABLE_ROW_IN * lines[i]))
    assert 1 <= min(stretch) and max(stretch) <= TABLE_PAGE_STRETCH + 1e-6
    assert max(stretch) - min(stretch) < 1e-6                  # all rows alike


def test_a_log_panel_choice_with_a_mark_near_zero_warns_nothing():
    """report.wants_log_axis: marks 1e-310 and 1 (a loss factor's interval end near 0) span
    more than LOG_PANEL_RATIO: a log axis, without numpy's "RuntimeWarning: overflow
    encountered in scalar divide" that the hybrid-CM damping report printed."""
    import warnings

    from laminid_cli.report import wants_log_axis

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert wants_log_axis("E2", [1e-310, 1.0]) is True
        assert wants_log_axis("E2", [1.0, 2.0], ends=[5.0]) is False
        assert wants_log_axis("nu12", [1e-310, 1.0]) is False


def test_the_reports_frequency_table_writes_a_residual_that_rounds_to_zero_as_plus_zero():
    """The report's table wrote a residual of -0.0004 % as "-0.000": now "+0.00" (its column
    is signed; 2 decimals as the terminal's), through laminid_cli.units.number_text as the
    terminal's tables."""
    from types import SimpleNamespace

    from laminid_cli.report import frequency_rows

    fr = SimpleNamespace(model=np.array([105.0, 200.0]), measured=np.array([105.0, 201.0]),
                         residual_percent=np.array([-4e-4, 0.498]), weight=np.ones(2),
                         model_mode=np.array([1, 2]))
    _, rows = frequency_rows(SimpleNamespace(frequencies=fr))
    assert [row[4] for row in rows] == ["+0.00", "+0.50"]


def test_a_page_of_the_damping_table_is_laid_out_once(monkeypatch):
    """Ten materials' loss factors (fifty two-line rows): the table does not fit whole on a
    page of its own, nor does glass's under the panels: page 1 the panels, then three pages of
    the table. Each page of the table alone was laid out (0.15 s) once to learn that the rest
    does not fit there, then again when the table went on: the whole table's page (measured
    first) a second time as the table's first page, each "(continued)" page once more after
    the page before was measured on the same. Now a page measured and not drawn on is the next
    page of its title and words: four layouts for three pages (the whole table's only
    measured), not six; the pages are the same (test_a_damping_table_too_long_for_its_page...
    and test_a_page_of_the_damping_table_alone_has_no_blank_band hold their layout)."""
    from laminid_cli import report_damping

    mats = ("glass", "carbon", "aramid", "basalt", "flax", "hemp", "boron", "pbo", "uhmwpe",
            "steel")
    built = []
    table_sheet = report_damping._table_sheet

    def recorded(d, banner, title, words=()):
        built.append((title.split("\n")[0], "continued on the next page" in title, len(words)))
        return table_sheet(d, banner, title, words)

    monkeypatch.setattr(report_damping, "_table_sheet", recorded)
    d = _hybrid_damping(mats=mats)
    figs = report_damping.damping_pages(d)
    assert len(figs) == 4 and not any(a.tables for a in figs[0].axes)
    whole = ("ply loss factors, modal strain energy method (s\u00b2 = 0.917, 14 degrees of "
             "freedom; damping sigma: 5% of each damping ratio (none given))")
    assert built == [(whole, False, 2), (whole, True, 0),
                     ("ply loss factors (continued)", False, 2),
                     ("ply loss factors (continued)", True, 0)]
    drawn = [row for fig in figs[1:] for row in cells(ax(fig, "loss-factors"))[1:]]
    assert drawn == report_damping.loss_factor_rows(d)


@pytest.mark.parametrize("name", ["lab.csv", "lab.txt", "lab.h5"])
def test_report_of_another_tools_frf_file_names_it_an_frf_file(tmp_path, name):
    """Another tool's FRFs, which fit-frf reads, were not known by report: a CSV whose
    frequency column is "f [Hz]" (an export's title line above it) was "not a laminid batch
    summary", a plain HDF5 file "not a laminid identification result (no 'format'
    attribute ...)"."""
    freq = np.arange(1.0, 100.0, 0.25)
    frf = synth_frf(freq, np.array([[30.0, 0.01], [70.0, 0.01]]), np.array([[1.0, -0.5]]),
                    kind="accelerance", noise=0.001, seed=1)
    path = tmp_path / name
    if name.endswith(".h5"):
        with h5py.File(path, "w") as f:
            f["measurement/f"] = freq
            f["measurement/H"] = frf.T
    else:
        rows = [f"{x:.6f};{h.real:.9e};{h.imag:.9e}".replace(".", ",")
                for x, h in zip(freq, frf[0])]
        path.write_text("\n".join(["Title;plate", "f [Hz];H1_re;H1_im"] + rows) + "\n")
    said = (f"laminid: error: {path}: an FRF file, not an identification result: laminid "
            f"fit-frf {path} --plot lab.fit.pdf draws its FRFs and their fit; a result is made "
            f"from it by laminid fit-frf {path} --into SPEC.yaml, then laminid identify "
            "SPEC.yaml")
    for command in (["report", path, "-o", tmp_path / "r.pdf"], ["show", path]):
        r = run(*command)
        assert r.exit_code == 2, r.output
        assert " ".join(r.stderr.split()) == said
    assert not (tmp_path / "r.pdf").exists()


@pytest.mark.parametrize("first, frf", [("Fréquence (Hz)", True), ("X [Hz]", True),
                                        ("f / kHz", True), ("Hz", True), ("omega", True),
                                        ("125.5", True), ("Time [s]", False), ("name", False)])
def test_a_csv_is_an_frf_file_by_its_frequency_column(tmp_path, first, frf):
    from laminid_cli.resultfile import is_frf_text_file

    path = tmp_path / "x.csv"
    path.write_text(f"{first},H_re,H_im\n125.5,1,2\n126,1,2\n", encoding="utf-8")
    assert is_frf_text_file(path) is frf
