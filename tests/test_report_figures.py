"""`laminid report`: what the pages' words, keys and legends say is what the page draws
(figure review: a note, key or legend entry for a mark the page does not have misleads)."""

import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.report import report_pages
from tests.figs import ax, cells, result_page

S21 = "specimens/example2/S2.1.yaml"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def texts(fig) -> str:
    return " ".join(t.get_text() for a in fig.axes for t in a.texts).replace("\n", " ")


@pytest.fixture(scope="module")
def s21_fixed_at_limit(s21_8x8_fix_undetermined):
    """S2.1 (8x8) with --fix-undetermined (conftest.py): G13, on its lower search limit in the
    first run, fixed ("fixed: it was at a search limit"), G23 fixed because undetermined; no
    constant of the answer is on a search limit. Read only."""
    return s21_8x8_fix_undetermined[1]


@pytest.fixture(scope="module")
def s21_fixed_pages(s21_fixed_at_limit):
    """The pages of its report that the tests read (summary, intervals, history), by name,
    built once for the tests that only read them (none draws them: see test_report.py's
    checked_pages), each alone (tests.figs.result_page): not the mode shapes and
    sensitivities, which none reads."""
    return {name: result_page(s21_fixed_at_limit, name)
            for name in ("summary", "intervals", "history")}


def test_no_search_limit_note_where_no_constant_is_on_one(s21_fixed_pages):
    """The summary page's note on "none — on a search limit" belongs to a constant whose
    interval cell says so; a constant fixed because it was on a limit says "fixed: it was at
    a search limit" and has the note on fixed values (the limit note read as if a constant of
    this answer had stopped on its limit)."""
    fig = s21_fixed_pages["summary"]
    table = cells(ax(fig, "constants"))[1:]
    assert any(row[3] == "fixed: it was at a search limit" for row in table)
    assert not any(row[2].startswith("none — on") for row in table)
    notes = texts(fig)
    assert "none — on a search limit" not in notes
    assert "fixed: held at its initial value, not identified" in notes


def _frequency_figure(measured, weight):
    """The measured-vs-model block of page 1 for a plate of four modes (no identification)."""
    from types import SimpleNamespace

    import numpy as np

    from laminid_cli.report import _figure, frequency_block

    model = np.array([100.0, 200.0, 300.0, 400.0])
    measured = np.asarray(measured, float)
    res = (measured - model) / measured * 100
    fr = SimpleNamespace(model=model, measured=measured, model_mode=np.arange(1, 5),
                         weight=np.asarray(weight, float), residual_percent=res,
                         rms_residual_percent=0.5)
    fig = _figure()
    frequency_block(fig, fig.add_gridspec(1, 1)[0, 0], SimpleNamespace(frequencies=fr))
    return ax(fig, "residuals")


@pytest.mark.parametrize("measured, weight, key", [
    ([100.5, 199.0, 301.0, 398.0], [1, 1, 1, 1], False),          # every mode fitted
    ([100.5, float("nan"), 301.0, 398.0], [1, 0, 1, 1], False),   # not measured: no bar
    ([100.5, 199.0, 301.0, 398.0], [1, 0, 1, 1], True)])          # measured, weight 0
def test_residual_bars_key_hatched_only_where_a_bar_is(measured, weight, key):
    """'hatched: weight 0' under the residual bars where one is hatched (every page 1 said
    it, also with every weight 1 or a weight-0 mode that was not measured and has no bar)."""
    a = _frequency_figure(measured, weight)
    assert a.get_xlabel().startswith("(measured − model)/measured (%)")
    assert ("hatched: weight 0" in a.get_xlabel()) is key
    hatches = [b.get_hatch() for b in a.patches if b.get_hatch()]
    assert bool(hatches) is (0 in weight)


def _damping_data(notes: str) -> dict:
    """The /damping data of a result as read_damping gives it: 12 modes, one material, eta13
    and eta23 not determined by the damping; ``notes`` as the file's attribute."""
    import numpy as np

    n, labels = 12, [f"M.eta{t}" for t in ("11", "22", "12", "13", "23")]
    shares = np.tile([0.6, 0.2, 0.15, 0.03, 0.02], (n, 1))
    value = np.array([0.002, 0.011, 0.016, 0.012, 0.007])
    eta = shares @ value
    return {"measured_loss_factor": eta, "measured_sigma": 0.02 * eta, "model_loss_factor": eta,
            "used": np.ones(n, bool), "energy_shares": shares,
            "share_labels": [f"M.{t}" for t in ("11", "22", "12", "13", "23")],
            "labels": labels, "value": value, "lower": 0.8 * value, "upper": 1.2 * value,
            "at_bound": np.zeros(5, bool),
            "verdict": ["weak"] * 3 + ["not determined by the measured damping"] * 2,
            "confidence": 0.95, "s2": 1.0, "dof": 7, "sigma_source": "the specimen file's "
            "measured.damping_sigma", "monte_carlo": {}, "verdict_from_monte_carlo": [],
            "fixed": "", "notes": notes, "specimen": "P"}


NOTE = ("M.eta13, M.eta23, M.eta11, M.eta22: the loss factors' intervals take the elastic "
        "constants as identified, and M.G13, M.G23, M.nu12 are not determined by the modes (or "
        "fixed because of it): these loss factors are known less well than the interval says")


@pytest.mark.parametrize("notes", ["", NOTE])
def test_damping_page_gives_the_results_note_on_the_loss_factors(notes):
    """The damping page says what the result file's /damping notes say (the terminal's note:
    loss factors leaning on elastic constants the modes do not determine are known less well
    than their intervals say; the page showed those intervals as plain 'weak'), above the
    table, clear of it and of the table's title, inside the page."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report_damping import NOT_DETERMINED_ADVICE, damping_pages

    fig = damping_pages(_damping_data(notes))[0]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw_without_rendering()
    a = ax(fig, "loss-factors")
    note = next(t for t in a.texts if t.get_gid() == "loss-factor-note")
    said = " ".join(note.get_text().split())
    assert said.startswith(NOT_DETERMINED_ADVICE)
    assert ("note: " + NOTE in said) is bool(notes)
    box = note.get_window_extent(renderer)
    table = a.tables[0].get_window_extent(renderer)
    # the title's words: its lines above the empty ones that keep the note's room
    title = a.title.get_window_extent(renderer)
    lines = a.title.get_text().split("\n")
    words_y0 = title.y1 - title.height * len([x for x in lines if x]) / len(lines)
    assert table.y1 <= box.y0 and box.y1 <= words_y0 + 1           # between table and title
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width


def test_damping_page_wraps_a_long_damping_sigma_source_inside_the_page():
    """The loss-factor table's title gives the damping sigma's source on one line; the source
    an frf_file's fit states ("the RFP fit of the specimen's measured.frf_file plate.frf.h5
    (spread over the stable orders, at least 2 % of the fitted ratio)", about 230 characters
    with the rest of the title) ran off both edges of the page, the rule cut on either side.
    Now wrapped: every character of it is on the page, within its width."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report_damping import damping_pages

    d = _damping_data("")
    d["sigma_source"] = ("the RFP fit of the specimen's measured.frf_file plate.frf.h5 (fitted "
                         "ratio's spread over the stable orders, at least 2 % of the ratio; "
                         "dominated by: rfp spread 1, floor 12 (modes); the floor is an assumed "
                         "2 %, not a spread the FRFs showed)")
    fig = damping_pages(d)[0]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw_without_rendering()
    a = ax(fig, "loss-factors")
    said = " ".join(a.title.get_text().split())
    assert d["sigma_source"] in said
    box = a.title.get_window_extent(renderer)
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width, (box.x0, box.x1, fig.bbox.width)
    assert len([x for x in a.title.get_text().split("\n") if x]) >= 2


def _legend_title(fig) -> str:
    return next(a.get_legend().get_title().get_text() for a in fig.axes
                if a.get_legend() is not None)


@pytest.mark.parametrize("kind", ["long", "wide", "old wide"])
def test_constants_across_specimens_legend_speaks_of_bars_only_where_drawn(tmp_path, kind):
    """The legend of the constants across specimens names the interval bars (and their
    arrows) where the summary has intervals (the long summary.csv, a --wide one with its
    interval columns); a --wide summary.csv written before those columns, alone, has none,
    and its page said 'bars: confidence interval of the summary (arrow: runs off the panel)'
    over panels without a bar or an arrow."""
    from laminid_cli.batch import write_summary_csv
    from tests.test_report import _summary_rows, old_wide

    path = tmp_path / "summary.csv"
    write_summary_csv(path, _summary_rows(), wide=kind != "long")
    if kind == "old wide":
        path = old_wide(path, tmp_path / "old.csv")
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    bars = [ln for a in fig.axes for ln in a.get_lines() if ln.get_gid() == "interval"]
    drawn = kind != "old wide"
    assert bool(bars) is drawn
    title = _legend_title(fig)
    assert title.startswith("colour: material")
    assert ("bars: confidence interval" in title) is drawn
    assert ("arrow" in title) is drawn


def test_history_rms_panel_tells_predictions_from_checked_evaluations(s21_fixed_at_limit,
                                                                     s21_fixed_pages):
    """The RMS residual panel marks the reduced model's predictions (error not bounded) as
    the objective's panel does, with a legend: drawn alike, a prediction below the result (S1.1
    + S1.2 joint: 0.2 % at evaluations 37-39, result 0.33 %) read as a better point the fit
    left."""
    import numpy as np

    from laminid_cli.report import revisits
    from laminid_cli.resultfile import read_result

    res = read_result(s21_fixed_at_limit)
    h = res.history
    pred = ~np.isfinite(h.error_bound) & ~revisits(h.constants)
    assert pred.any() and not pred.all()
    fig = s21_fixed_pages["history"]
    a = ax(fig, "rms")
    line = next(ln for ln in a.get_lines() if ln.get_gid() == "rms-predicted")
    assert np.array_equal(line.get_xdata(), h.evaluation[pred])
    assert np.array_equal(line.get_ydata(), h.rms_residual_percent[pred])
    legend = [t.get_text() for t in a.get_legend().get_texts()]
    assert legend == ["RMS residual", "reduced-model prediction (error not bounded)",
                      "checked (error bounded)"]
    objective = [t.get_text() for t in ax(fig, "objective").get_legend().get_texts()]
    assert "reduced-model prediction (trial point, error not bounded)" in objective


def test_history_rms_panels_checked_evaluations_are_drawn_and_keyed(s21_fixed_at_limit,
                                                                    s21_fixed_pages):
    """The RMS panel's checked evaluations (error bounded) were the line's own small dots,
    not in its legend beside the keyed predictions; they are now marked as on the objective's
    panel (dark edge) and keyed, the legend's mark the drawn one. The history page's
    "evaluation" axis label was at matplotlib's 10 pt, the panels' y labels at 8 pt: all 8."""
    import numpy as np

    from laminid_cli.report import revisits
    from laminid_cli.resultfile import read_result

    h = read_result(s21_fixed_at_limit).history
    chk = np.isfinite(h.error_bound) & ~revisits(h.constants)
    assert chk.any()
    fig = s21_fixed_pages["history"]
    a = ax(fig, "rms")
    line = next(ln for ln in a.get_lines() if ln.get_gid() == "rms-checked")
    assert np.array_equal(line.get_xdata(), h.evaluation[chk])
    assert np.array_equal(line.get_ydata(), h.rms_residual_percent[chk])
    leg = a.get_legend()
    i = [t.get_text() for t in leg.get_texts()].index("checked (error bounded)")
    key = leg.legend_handles[i]
    assert (key.get_marker(), key.get_markersize(), key.get_markeredgecolor(),
            key.get_markerfacecolor()) == (line.get_marker(), line.get_markersize(),
                                           line.get_markeredgecolor(),
                                           line.get_markerfacecolor())
    sizes = {a_.get_gid(): (a_.xaxis.label.get_fontsize(), a_.yaxis.label.get_fontsize())
             for a_ in fig.axes if a_.get_gid() in ("objective", "rms", "moduli", "nu12")}
    assert ax(fig, "nu12").get_xlabel() == "evaluation"
    assert {s[1] for s in sizes.values()} == {sizes["nu12"][0]} == {8}


@pytest.mark.parametrize("gid", ["objective", "rms"])
def test_history_log_panels_have_a_labelled_tick_under_their_lowest_value(s21_fixed_pages,
                                                                         gid):
    """The objective's and the RMS residual's log panels reach down to a labelled tick, so
    that the value the fit ended on is read against a number (S1.3's RMS residual panel
    labelled 1 and 10 only, with the result at 0.244 %; S2.1's 0.5 ... 10, result 0.246 %)."""
    import numpy as np

    fig = s21_fixed_pages["history"]
    a = ax(fig, gid)
    lo, hi = a.get_ylim()
    ticks = [t for t in a.yaxis.get_majorticklocs() if lo * (1 - 1e-9) <= t <= hi]
    lowest = min(np.nanmin(ln.get_ydata()) for ln in a.get_lines() if len(ln.get_ydata()))
    assert min(ticks) <= lowest
    assert len(ticks) >= 2


def _two_band_fit():
    """A fit of two bands as fit_figure draws it (no RFP): each band's FRF a single pole, its
    stabilisation chart with a pole of each kind."""
    from types import SimpleNamespace

    import numpy as np

    def band(lo, hi, f0):
        def synthesise(f):
            return np.atleast_2d(1.0 / (f0 ** 2 - f ** 2 + 0.02j * f0 * f))
        chart = SimpleNamespace(freq_hz=np.array([0.9 * f0, f0, f0]),
                                order=np.array([2.0, 3.0, 4.0]), stable=np.array([0, 1, 2]),
                                damping_ratio=np.full(3, 0.01), track=np.array([0, 1, 1]),
                                band_hz=(lo, hi))
        return SimpleNamespace(band_hz=(lo, hi), synthesise=synthesise, chart=chart)

    from laminid_cli.frf.rfp import PoleCriteria

    bands = [band(50.0, 150.0, 100.0), band(150.0, 300.0, 220.0)]
    return SimpleNamespace(bands=bands, modes=[SimpleNamespace(freq_hz=100.0),
                                               SimpleNamespace(freq_hz=220.0)],
                           freq_hz=np.array([100.0, 220.0]), criteria=PoleCriteria())


@pytest.mark.parametrize("n_bands", [1, 2])
def test_stabilisation_legend_keys_the_x_of_every_band(n_bands):
    """fit-frf --plot: the x of a pole stable in frequency and damping is in its band's
    colour; with more than one band the legend says so and keys it in a neutral colour (it
    keyed the first band's blue x alone, the orange and green ones of the other bands had no
    entry). With one band: its colour, as drawn."""
    import numpy as np
    from matplotlib.colors import to_rgba

    from laminid_cli.frf.plot import fit_figure

    fit = _two_band_fit()
    fit.bands = fit.bands[:n_bands]
    fit.modes = fit.modes[:n_bands]
    fit.freq_hz = fit.freq_hz[:n_bands]
    freq = np.arange(50.0, 300.0, 0.5)
    frf = np.atleast_2d(1.0 / (100.0 ** 2 - freq ** 2 + 2j * freq))
    fig = fit_figure(freq, frf, fit)
    s = ax(fig, "stabilisation")
    leg = s.get_legend()
    labels = [t.get_text() for t in leg.get_texts()]
    x = labels.index(next(t for t in labels if t.startswith("stable in f and damping")))
    handle = leg.legend_handles[x]
    drawn = {to_rgba(ln.get_color()) for ln in s.get_lines() if ln.get_marker() == "x"}
    assert len(drawn) == n_bands
    if n_bands > 1:
        assert labels[x] == "stable in f and damping (colour: its band)"
        assert to_rgba(handle.get_color()) not in drawn
    else:
        assert labels[x] == "stable in f and damping"
        assert {to_rgba(handle.get_color())} == drawn


def test_history_rms_panel_goes_down_to_the_tick_under_its_lowest_point_only(
        s21_fixed_at_limit):
    """The labelled tick under the lowest point, not the one under the panel's margin below
    it: an RMS residual from 200 % down to 0.14 % (hybrid CM) went down to 0.01 %, a decade
    of empty panel, when its margin reached under 0.1."""
    import dataclasses

    import numpy as np

    from laminid_cli.report import history_page
    from laminid_cli.resultfile import read_result

    res = read_result(s21_fixed_at_limit)
    h = res.history
    n = h.evaluation.size
    rms = np.geomspace(200.0, 0.14, n)
    res = dataclasses.replace(res, history=dataclasses.replace(h, rms_residual_percent=rms))
    a = ax(history_page(res), "rms")
    lo, hi = a.get_ylim()
    ticks = [t for t in a.yaxis.get_majorticklocs() if lo * (1 - 1e-9) <= t <= hi]
    assert [t for t in ticks if t <= 0.14] == [pytest.approx(0.1)]
    assert lo > 0.05                          # not a decade of empty panel under 0.1


@pytest.mark.parametrize("all_check", [False, True])
def test_residuals_across_specimens_legend_keys_the_bars_drawn(tmp_path, all_check):
    """The RMS residual page of a batch summary keys the kinds of bar it draws: a batch none
    of whose specimens is ok (the eight shipped specimens: all 'check') had a 'status ok'
    entry for a dark bar the page did not have."""
    from tests.test_report import _summary_rows, _write_summary

    rows = _summary_rows()
    if all_check:
        rows[1] = rows[1] | {"status": "check", "reasons": [{"code": "poor_fit", "text": "."}],
                             "reason": "poor_fit"}
    path = tmp_path / "summary.json"
    _write_summary(path, rows)
    fig = {p.name: p.figure for p in report_pages(path)}["residuals"]
    a = ax(fig, "rms")
    drawn = {b.get_facecolor() for b in a.patches}
    keyed = [t.get_text() for t in a.get_legend().get_texts()]
    assert keyed == (["status not ok (reason codes above the bar)"] if all_check else
                     ["status ok", "status not ok (reason codes above the bar)"])
    assert len(drawn) == len(keyed)


@pytest.fixture(scope="module")
def s21(s21_8x8):
    """S2.1 (8x8, conftest.py): G13 on its lower search limit, G23's interval off its panel
    (to 11 GPa)."""
    return s21_8x8[1]


@pytest.fixture(scope="module")
def s14(tmp_path_factory):
    """S1.4 (8x8): G13 and G23 on linear panels (within a decade), G23's interval off its
    panel (to 5.5 GPa)."""
    out = tmp_path_factory.mktemp("s14") / "S1.4.result.h5"
    r = run("identify", "specimens/example1/S1.4.yaml", "--mesh", "8x8", "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.mark.parametrize("case, arrow", [("s14", True), ("s21_fixed_at_limit", False)])
def test_interval_legend_speaks_of_arrows_only_where_drawn(case, arrow, request):
    """The interval page's legend explains the arrow of an interval (or range) that runs off
    its panel where one does (S1.4: G23 'to 5.52'; S2.1's G23 'to 11.00' was one until G23
    went on G13's log scale, SAME_SCALE); with every interval in view (S2.1 with G13 and G23
    fixed) it had the words for an arrow the page did not have."""
    fig = (request.getfixturevalue("s21_fixed_pages")["intervals"]
           if case == "s21_fixed_at_limit" else result_page(request.getfixturevalue(case),
                                                               "intervals"))
    words = [t.get_text() for a in fig.axes if a.get_gid() and a.get_gid().startswith(
        "interval-") for t in a.texts if t.get_text().startswith(("to\n", "from\n"))]
    assert bool(words) is arrow
    title = _legend_title(fig)
    assert title.startswith("moduli: interval on ln P")
    assert ("arrow: the interval or range runs off the panel to the value written"
            in title) is arrow


def _one_material_rows():
    """Two carbon specimens of a batch summary (SI): Q well determined, R with G13 on its
    lower search limit (flat profile to 5 GPa), G23 not determined, E1 with a Monte Carlo
    range: six legend entries, as the shipped S1.x specimens with a reference."""
    from tests.test_report import _summary_rows

    q = _summary_rows()[1]
    r = q | {"name": "R", "specimen": "R", "result": "R.result.h5", "status": "check",
             "reason": "at_bound, undetermined"}
    iv = {k: dict(e) for k, e in q["intervals"]["carbon"].items()}
    iv["G13"] = {"lower": None, "upper": None, "verdict": "at bound — not identified",
                 "at_bound": True, "bound_side": "lower", "bound_limit": 3.8e5,
                 "flagged": False, "profile": "flat", "profile_far": 5e9}
    iv["G23"] = iv["G23"] | {"lower": 0.3e9, "upper": 14e9, "flagged": True,
                             "verdict": "not determined by these modes"}
    iv["E1"] = iv["E1"] | {"mc_lower": 85e9, "mc_upper": 89e9}
    r["intervals"] = {"carbon": iv}
    r["materials"] = {"carbon": dict(q["materials"]["carbon"], G13=3.8e5)}
    return [q, r]


def test_constants_across_specimens_legend_inside_the_page(tmp_path):
    """The legend under the panels stays inside the page: with five or six entries it was
    set in four columns, wider than the page (the shipped S1.x specimens with the synthetic
    one: the material's marker cut at the left edge, 'reference value' at the right, the
    panels squeezed to the middle)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tests.test_report import _write_summary

    path = tmp_path / "summary.json"
    _write_summary(path, _one_material_rows())
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw_without_rendering()
    legend = next(a.get_legend() for a in fig.axes if a.get_legend() is not None)
    texts = [t.get_text() for t in legend.get_texts()]
    assert len(texts) >= 5 and "values the fit does not reject (profile of a constant on a " \
        "search limit);\narrow head: the end of its scan, not tried beyond" in texts
    box = legend.get_window_extent(renderer)
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width
    panels = [a.get_window_extent(renderer) for a in fig.axes
              if (a.get_gid() or "").startswith("across-")]
    # the panels keep the page's width (not squeezed to make room for the legend's width)
    assert max(b.x1 for b in panels) - min(b.x0 for b in panels) > 0.85 * fig.bbox.width


def test_damping_page_loss_factor_marks_not_in_the_colours_of_the_energy_terms():
    """On the damping page the measured and model modal loss factors are in colours none of
    the strain-energy terms beside them has: blue measured and red model read as '11
    (fibre)' and '13 (transverse shear)' of the shares' legend."""
    from matplotlib.colors import to_rgb

    from laminid_cli.report_damping import damping_pages

    fig = damping_pages(_damping_data(""))[0]
    a = ax(fig, "modal-loss-factors")
    marks = {ln.get_gid(): to_rgb(ln.get_color()) for ln in a.get_lines()
             if ln.get_gid() in ("measured", "model")}
    assert set(marks) == {"measured", "model"} and marks["measured"] != marks["model"]
    terms = {to_rgb(b.get_facecolor()) for b in ax(fig, "energy-shares").patches}
    assert len(terms) == 5
    assert not set(marks.values()) & terms


# ---------------------------------------------------------------------------------------------
# panels whose values span decades: log axes; page 1 says a Monte Carlo was run

S11 = "specimens/example1/S1.1.yaml"


@pytest.fixture(scope="module")
def s21_mc(tmp_path_factory):
    """S2.1 (8x8) with a Monte Carlo of 20 trials: G13 on its lower search limit (flat profile
    to 18.5 GPa), its range from the limit (0.0029 GPa) to a few GPa; G23's to 0.003*."""
    out = tmp_path_factory.mktemp("s21mc") / "S2.1.result.h5"
    r = run("identify", S21, "--mesh", "8x8", "--monte-carlo", 20, "-j", 1, "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.fixture(scope="module")
def s11(tmp_path_factory):
    """S1.1 (8x8): E1, E2, G12 within a few % to tens of %, nu12 linear; G23's interval
    0.2 .. 6 GPa (30 x)."""
    out = tmp_path_factory.mktemp("s11") / "S1.1.result.h5"
    r = run("identify", S11, "--mesh", "8x8", "-o", out)
    assert r.exit_code == 0, r.output
    return out


def test_interval_panel_spanning_decades_is_log_and_nothing_on_its_foot(s21_mc):
    """S2.1's G13 stopped on its lower search limit (0.0029 GPa), the values the fit does not
    reject up to 18.5 GPa, its Monte Carlo range up to a few GPa: on a linear panel (0 ..
    0.0035 GPa, or 0 .. 4 with a reference) everything but the limit ran off with arrows, or
    the limit sat on 0. On a log panel, said in its title, the limit, the reference, the range
    and the profile's end are all in view, apart, and the panel is not much wider than them."""
    import dataclasses

    import numpy as np

    from laminid_cli.report import interval_page, monte_carlo_range
    from laminid_cli.resultfile import read_result

    res = read_result(s21_mc)
    m = next(iter(res.materials))
    iv = res.uncertainty.get(m, "G13")
    assert iv.at_bound and iv.bound_side == "lower"
    ref = 3.7                               # GPa: the specimen gives none for G13
    plate = res.plates[0]
    plate = dataclasses.replace(plate, reference=plate.reference | {
        m: plate.reference.get(m, {}) | {"G13": (ref * 1e9, ref * 1e9)}})
    res = dataclasses.replace(res, plates=(plate,))
    fig = interval_page(res)
    fig.draw_without_rendering()
    a = ax(fig, f"interval-{m}.G13")
    assert a.get_yscale() == "log" and a.get_title() == "G13 (GPa, log scale)"
    rng = monte_carlo_range(res.uncertainty, iv)
    v = res.materials[m]["G13"] / 1e9
    data = [v, ref, rng.lower / 1e9, rng.upper / 1e9, iv.profile_far / 1e9]
    assert np.all(np.isfinite(data)) and max(data) / min(data) > 1e3
    lo, hi = a.get_ylim()
    assert lo <= min(data) and max(data) <= hi                      # all in view: no arrows
    assert not [t for t in a.texts if t.get_text().startswith(("to\n", "from\n"))]
    assert np.log10(hi / lo) <= 1.3 * np.log10(max(data) / min(data))
    marks = {ln.get_gid(): ln.get_ydata()[0] for ln in a.get_lines()
             if ln.get_gid() in ("at-bound", "reference")}
    assert marks == {"at-bound": v, "reference": ref}
    box = a.get_window_extent()

    def y(val):                                                     # pixels above the foot
        return a.transData.transform((0, val))[1] - box.y0

    assert y(v) >= 0.05 * box.height                                # not on the panel's foot
    assert y(ref) - y(v) >= 0.5 * box.height                        # limit and reference apart
    assert y(rng.upper / 1e9) - y(v) >= 0.3 * box.height
    assert box.height - y(iv.profile_far / 1e9) >= 0.02 * box.height


def test_interval_panels_within_a_decade_stay_linear(s11):
    """S1.1's E1, E2, G12 (and nu12, always) keep their linear panels; a modulus goes log
    only where its value, interval and reference span more than a decade (G23 0.2 .. 6 GPa),
    and G13 with it (SAME_SCALE: test_transverse_shear_moduli_on_one_scale)."""
    from laminid_cli.resultfile import CONSTANTS, read_result

    res = read_result(s11)
    fig = result_page(s11, "intervals")
    m = next(iter(res.materials))
    log, own = {}, {}
    for k in CONSTANTS:
        a = ax(fig, f"interval-{m}.{k}")
        iv = res.uncertainty.get(m, k)
        pts = [res.materials[m][k], iv.lower, iv.upper, *res.reference.get(m, {}).get(k, ())]
        log[k] = a.get_yscale() == "log"
        own[k] = k != "nu12" and max(pts) / min(pts) > 10
        assert ("log scale" in a.get_title()) is log[k]
    for k in ("E1", "E2", "G12", "nu12"):
        assert log[k] is own[k] is False
    assert own["G23"] and log["G23"] and log["G13"]


def test_transverse_shear_moduli_on_one_scale(s11, s14):
    """S1.1 (8x8) drew G13 [1.17, 10.4] GPa (8.9x: linear by its own numbers, its top off
    the panel under an arrow "to 10.40") beside G23 [0.199, 5.96] GPa (30x) whole on a log
    panel: the narrower interval (±109 % against ±170 %) looked the worse. G13 and G23 now
    share one log scale, each panel over the same decades, so that a bar's length is the
    same ratio on both: G13's bar is shorter than G23's by their ratios' logs, nothing runs
    off, and the legend says why a panel within a decade is on a log scale. S1.4 (8x8), both
    within a decade, keeps both linear."""
    import numpy as np

    from laminid_cli.report import LOG_PANEL_RATIO, wants_log_axis
    from laminid_cli.resultfile import read_result

    res = read_result(s11)
    m = next(iter(res.materials))
    fig = result_page(s11, "intervals")
    fig.draw_without_rendering()
    ivs = {k: res.uncertainty.get(m, k) for k in ("G13", "G23")}
    ratio = {k: iv.upper / iv.lower for k, iv in ivs.items()}
    assert 8 < ratio["G13"] < LOG_PANEL_RATIO < 25 < ratio["G23"]
    assert not wants_log_axis("G13", [res.materials[m]["G13"] / 1e9],
                              [ivs["G13"].lower / 1e9, ivs["G13"].upper / 1e9])
    span, bar = {}, {}
    for k, iv in ivs.items():
        a = ax(fig, f"interval-{m}.{k}")
        assert a.get_yscale() == "log" and a.get_title() == f"{k} (GPa, log scale)"
        lo, hi = a.get_ylim()
        span[k] = np.log10(hi / lo)
        assert lo < iv.lower / 1e9 and iv.upper / 1e9 < hi                   # whole in view
        assert not [t for t in a.texts if t.get_text().startswith(("to\n", "from\n"))]
        line = next(ln for ln in a.get_lines() if ln.get_gid() == "interval")
        y = a.transData.transform(np.c_[[0, 0], line.get_ydata()])[:, 1]
        bar[k] = abs(y[1] - y[0])
    assert abs(span["G13"] - span["G23"]) <= 1e-9 * span["G23"]
    # pixels per decade alike: the bars' lengths in the ratio of their decades (0.95, 1.48)
    assert np.isclose(bar["G13"] / bar["G23"], np.log10(ratio["G13"]) / np.log10(ratio["G23"]),
                      rtol=1e-6)
    title = _legend_title(fig)
    assert ("G13 and G23 on one log scale, as one of them spans more than a decade: each panel "
            "over the same decades, a bar's length the same ratio on each") in title
    # both within a decade: both linear, no word of it
    fig = result_page(s14, "intervals")
    m = next(iter(read_result(s14).materials))
    assert [ax(fig, f"interval-{m}.{k}").get_yscale() for k in ("G13", "G23")] == ["linear"] * 2
    assert "one log scale" not in _legend_title(fig)


def test_constants_across_specimens_log_where_values_span_decades(tmp_path):
    """Across specimens, R's G13 on its lower limit (0.00038 GPa) and Q's 3.8 GPa: a linear
    panel put R's on 0; a log one (its title says so) keeps both in view and apart. E1 (87 GPa
    both) stays linear."""
    from tests.test_report import _write_summary

    path = tmp_path / "summary.json"
    _write_summary(path, _one_material_rows())
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    fig.draw_without_rendering()
    a = ax(fig, "across-G13")
    assert a.get_yscale() == "log" and a.get_title() == "G13 (GPa, log scale)"
    box = a.get_window_extent()
    ys = {ln.get_gid(): a.transData.transform((0, ln.get_ydata()[0]))[1] - box.y0
          for ln in a.get_lines() if ln.get_gid() in ("value-Q-carbon", "at-bound-R-carbon")}
    assert len(ys) == 2 and all(0.03 * box.height <= y <= 0.97 * box.height
                                for y in ys.values())
    assert ys["value-Q-carbon"] - ys["at-bound-R-carbon"] >= 0.5 * box.height
    for k in ("E1", "nu12"):
        assert ax(fig, f"across-{k}").get_yscale() == "linear"
        assert "log" not in ax(fig, f"across-{k}").get_title()


def test_constants_across_specimens_do_not_magnify_values_a_hair_apart(tmp_path):
    """One plate identified twice (two starts, the same optimum), its G13 and nu12 not
    determined: their intervals run off the panel, whose span came from the two values alone,
    6.01761 and 6.01778 GPa: ticks 0.00060-0.00080 under an offset '+6.017', as if the two
    were far apart. The panel spans at least the "well determined" band's width (10 % of the
    value), labelled in plain GPa."""
    from tests.test_report import _write_summary

    q = _one_material_rows()[0]
    nd = "not determined by these modes — fix it or measure a thicker plate / more modes"
    rows = []
    for name, g13, nu in (("A", 6.01761e9, 0.22605), ("B", 6.01778e9, 0.22611)):
        iv = {k: dict(e) for k, e in q["intervals"]["carbon"].items()}
        iv["G13"] = iv["G13"] | {"lower": 1.28e9, "upper": 28.4e9, "flagged": True,
                                 "verdict": nd}
        iv["nu12"] = iv["nu12"] | {"lower": 0.068, "upper": 0.384, "flagged": True,
                                   "verdict": nd}
        rows.append(q | {"name": name, "specimen": name, "result": None,
                         "intervals": {"carbon": iv},
                         "materials": {"carbon": dict(q["materials"]["carbon"], G13=g13,
                                                      nu12=nu)}})
    path = tmp_path / "summary.json"
    _write_summary(path, rows)
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    fig.draw_without_rendering()
    for k, v in (("G13", 6.01778), ("nu12", 0.22611)):
        a = ax(fig, f"across-{k}")
        lo, hi = a.get_ylim()
        assert a.get_yscale() == "linear" and hi - lo >= 0.1 * v * (1 - 1e-9), (k, lo, hi)
        assert lo < v < hi
        assert a.yaxis.get_offset_text().get_text() == "", k


def test_residuals_across_specimens_labels_do_not_run_into_each_other(tmp_path):
    """Eleven specimens of a batch --mesh-check, most of them 'check', one failed: each bar's
    label (residual, mesh shift, status and reason codes) ran into its neighbours'
    ("0.265 %mesh shift 0.10 hw"), the failed one's reason across the next bar's label. The
    labels are as narrow as the bars leave room for, none overlaps the next, the reason codes
    stay whole, and the tallest is inside the axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tests.test_report import _write_summary

    q = _one_material_rows()[0]
    rows = [{"name": "broken/S1.3-broken", "specimen": "", "path": "", "status": "error",
             "reasons": [], "reason": "camp/broken/S1.3-broken.yaml:22, field "
             "'materials.IM7/977-2.G21': unknown key 'G21'; did you mean 'G23'? (valid keys: "
             "E1, E2, G12, G13, G23, nu12, density, density_ratio, fixed, prior)",
             "materials": {}, "intervals": {}, "rms_residual_percent": None, "result": None,
             "damping": {}, "mesh_check": None}]
    for i in range(10):
        rows.append(q | {"name": f"plates/S{i}", "specimen": f"S{i}", "result": None,
                         "status": "check" if i % 3 else "ok",
                         "reason": "fixed_rejected, coarse_mesh" if i % 3 else "",
                         "rms_residual_percent": (0.88 if i == 5 else 0.1 + 0.03 * i),
                         "mesh_check": {"max_shift_half_width": 0.1 + 0.02 * i,
                                        "max_change_sigma": 0.7, "coarse_mesh": False}})
    path = tmp_path / "summary.json"
    _write_summary(path, rows)
    fig = {p.name: p.figure for p in report_pages(path)}["residuals"]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    a = ax(fig, "rms")
    labels = sorted((t for t in a.texts if t.get_text().startswith(("no result", "0."))),
                    key=lambda t: t.xy[0])
    assert len(labels) == 11
    boxes = [t.get_window_extent(renderer) for t in labels]
    for (p, t), (q_, u) in zip(zip(boxes, labels), zip(boxes[1:], labels[1:])):
        assert not (p.x1 > q_.x0 and p.y1 > q_.y0 and q_.y1 > p.y0), \
            (t.get_text(), u.get_text())
    assert all("fixed_rejected," in t.get_text().split("\n") for t in labels[1:]
               if "check" in t.get_text())
    assert max(b.y1 for b in boxes) <= a.get_window_extent(renderer).y1


@pytest.mark.parametrize("name", ["summary.csv", "summary.json"])
def test_constants_across_specimens_name_the_specimens_without_a_result(tmp_path, name):
    """A campaign of three specimens, one of them failed (a broken file): the constants'
    page drew two and said nothing of the third (only the residuals' page, after it, did),
    so a reader of page 1 took the campaign for two plates. Its notes name it, with its
    status; a summary where every specimen has a result says nothing of the kind."""
    from tests.test_report import _write_summary

    q, r = _one_material_rows()
    broken = {"name": "broken/S1.3", "specimen": "", "path": "", "status": "error",
              "reasons": [], "reason": "S1.3.yaml:22, field 'materials.IM7/977-2.G21': unknown "
              "key 'G21'", "converged": None, "optimizer_status": "", "cached": False,
              "materials": {}, "intervals": {}, "rms_residual_percent": None,
              "evaluations": None, "time_s": 0.0, "result": None, "damping": {},
              "mesh_check": None, "stale_result": None}
    path = tmp_path / name
    _write_summary(path, [q, broken, r])
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    words = " ".join(" ".join(t.get_text() for t in fig.texts).split())
    assert "no result, not drawn (page 2 says why): broken/S1.3 (error)" in words
    assert [t.get_text() for t in ax(fig, "across-E1").get_xticklabels()] == ["Q", "R"]
    _write_summary(path, [q, r])
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    assert "not drawn" not in " ".join(t.get_text() for t in fig.texts)


@pytest.mark.parametrize("wide", [False, True])
def test_constants_across_specimens_mark_a_value_held_by_its_prior(tmp_path, wide):
    """A value held by its prior (its file's prior gives more than half of what is known of
    it) was drawn as an identified one: S1.2's nu12 with prior {nu12: 1.0}, a filled dot with
    a narrow interval on the reference's line, read as the modes confirming the reference. It
    gets a '~' beside it, as the terminal table's mark, and the legend says what it means; a
    --wide summary alone (its column 'flagged') too."""
    from laminid_cli.batch import write_summary_csv
    from tests.test_report import _write_summary

    q, r = _one_material_rows()
    iv = {k: dict(e) for k, e in q["intervals"]["carbon"].items()}
    iv["nu12"] = iv["nu12"] | {"verdict": "well determined (held by the prior)"}
    q = q | {"intervals": {"carbon": iv}, "result": None}
    r = r | {"result": None}
    path = tmp_path / ("summary.csv" if wide else "summary.json")
    if wide:
        write_summary_csv(path, [q, r], wide=True)
    else:
        _write_summary(path, [q, r])
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    marks = [(a.get_gid(), t.get_gid()) for a in fig.axes for t in a.texts
             if t.get_text() == "~"]
    assert marks == [("across-nu12", "prior-Q-carbon")]
    legend = next(a.get_legend() for a in fig.axes if a.get_legend() is not None)
    assert "~: held by its prior (mostly the file's prior value, not the modes')" in [
        t.get_text() for t in legend.get_texts()]


def test_interval_end_at_or_below_zero_on_a_log_panel_is_clipped_and_said(s21):
    """A linear interval (older files) whose lower end is <= 0, on a panel a decade and more
    wide: an arrow onto the log panel's foot with the end written, and the legend says that
    such an end is below any log scale."""
    import dataclasses

    from laminid_cli.report import interval_page
    from laminid_cli.resultfile import read_result

    res = read_result(s21)
    m = next(iter(res.materials))
    u = res.uncertainty
    v = res.materials[m]["G23"]
    ivs = tuple(dataclasses.replace(iv, lower=-5e9, upper=50 * v, scale="linear")
                if iv.constant == "G23" else iv for iv in u.intervals)
    fig = interval_page(dataclasses.replace(res, uncertainty=dataclasses.replace(
        u, intervals=ivs)))
    a = ax(fig, f"interval-{m}.G23")
    assert a.get_yscale() == "log"
    lo, hi = a.get_ylim()
    end = next(t for t in a.texts if t.get_gid() == "interval-end-below-log")
    assert end.get_text() == "from\n-5.00"
    bar = next(ln for ln in a.get_lines() if ln.get_gid() == "interval")
    assert list(bar.get_ydata()) == [lo, 50 * v / 1e9]               # clipped at the foot
    assert "(an end ≤ 0 is below any log scale)" in _legend_title(fig)
    assert "below any log scale" not in _legend_title(
        result_page(s21, "intervals"))


def _notes(fig) -> str:
    return next(t.get_text() for a in fig.axes for t in a.texts
                if t.get_gid() == "notes").replace("\n", " ")


def test_summary_page_says_a_monte_carlo_was_run(s21_mc, s21):
    """Page 1 says, where it describes the intervals, that a Monte Carlo was run: its trial
    counts from the file, in the words identify's terminal (and `show`) used, and where its
    ranges are; a result without one has no such line."""
    import h5py

    with h5py.File(s21_mc) as f:
        mc = f["uncertainty/monte_carlo"].attrs
        trials, converged = int(mc["trials"]), int(mc["converged"])
        factor = float(mc["sigma_factor"])
    assert trials == 20
    said = f"Monte Carlo check: {converged} of {trials} re-identifications converged"
    shown = run("show", s21_mc)
    assert shown.exit_code == 0 and said in shown.output
    notes = _notes(result_page(s21_mc, "summary"))
    assert (f"{said} (frequencies perturbed by σ × {factor:.3g}); their 95% ranges: grey bars "
            "on the intervals page") in notes
    # after the intervals' own line, before the table's words
    assert notes.index("uncertainty: 95% intervals") < notes.index(said)
    assert "Monte Carlo" not in _notes(result_page(s21, "summary"))


def test_monte_carlo_note_words():
    """199 of 200 converged, a range that set a verdict: the table is named too; a group
    without the counts (a hand-made file) says so; no group, no line."""
    from types import SimpleNamespace

    from laminid_cli.report import monte_carlo_note

    ivs = (SimpleNamespace(verdict_from_monte_carlo=True),)
    u = SimpleNamespace(confidence=0.95, intervals=ivs, monte_carlo={
        "trials": 200, "converged": 199, "sigma_factor": 1.2240, "lower": 0, "upper": 0})
    assert monte_carlo_note(u) == (
        "Monte Carlo check: 199 of 200 re-identifications converged (frequencies perturbed by "
        "σ × 1.22); their 95% ranges: grey bars on the intervals page and in the table, where "
        "a range set the verdict")
    u.monte_carlo = {"lower": 0, "upper": 0}
    assert monte_carlo_note(u).startswith("Monte Carlo check (its trial counts not in this "
                                          "file); their 95% ranges")
    u.monte_carlo = None
    assert monte_carlo_note(u) is None


def test_a_bounded_profiles_words_stay_inside_their_panel(s21_8x8):
    """Hybrid CM's glass G13 (on its lower limit, 0.0056 GPa; the fit rejects it above
    10.1 GPa, the top of its log panel): "profile\\n< 10.10" was centred on the cap and its
    first line ran out of the panel, over the top frame. S2.1's G13 (8x8) with such a bound
    (3450 times its value) stands in for it."""
    import dataclasses as dc

    import matplotlib.pyplot as plt
    import numpy as np

    from laminid_cli.report import interval_panel
    from laminid_cli.resultfile import read_result

    r = read_result(s21_8x8[1])
    m = "E-glass/R368"
    iv = r.uncertainty.get(m, "G13")
    assert iv.at_bound and iv.bound_side == "lower"
    bound = dc.replace(iv, profile_bound=3450 * iv.value, profile_far=np.nan,
                       profile_text="the fit rejects G13 above 10.1 GPa")
    assert bound.profile_kind == "bound"
    u = dc.replace(r.uncertainty, intervals=tuple(bound if x is iv else x
                                                  for x in r.uncertainty.intervals))
    # a panel 1.4 inch tall, as on hybrid CM's page of two materials (one row each)
    fig, a = plt.subplots(figsize=(1.6, 1.8))
    interval_panel(a, dc.replace(r, uncertainty=u), m, "G13")
    a.set_xlim(-0.75, 0.75)                        # as the intervals page (interval_page)
    fig.draw_without_rendering()
    label = next(t for t in a.texts if t.get_gid() == "profile-label")
    assert label.get_text().startswith("profile\n< ")
    box, panel = label.get_window_extent(), a.get_window_extent()
    assert panel.y0 <= box.y0 and box.y1 <= panel.y1, (box, panel)
    plt.close(fig)


def test_frequency_table_headers_fit_their_cells(s21_8x8):
    """The measured-vs-model table of page 1: its bold headers 'measured (Hz)', 'model mode'
    and 'weight' ran over their cells' borders (into the next header) on the A4 page."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = result_page(s21_8x8[1], "summary")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    table = ax(fig, "frequency-table").tables[0]
    for (i, j), cell in table.get_celld().items():
        if i:
            continue
        text, box = cell.get_text(), cell.get_window_extent(renderer)
        inner = text.get_window_extent(renderer)
        assert box.x0 < inner.x0 and inner.x1 < box.x1, (text.get_text(), inner, box)


def test_an_undetermined_value_is_not_compared_with_its_reference(s11):
    """S1.1's nu12, "not determined by these modes", showed its reference as "0.350 (-35 %)",
    a difference a reader may act on: the cell gives the reference and "(not compared)", inside
    its cell, and the notes say why; a determined constant keeps its difference."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.resultfile import read_result

    fig = result_page(s11, "summary")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    rows = {row[0].split(" ")[0]: row for row in cells(ax(fig, "constants"))[1:]}
    assert rows["nu12"][3] == "not determined"
    assert rows["nu12"][5] == "0.350\n(not compared)"
    e1 = read_result(s11).materials["IM7/977-2"]["E1"]
    assert rows["E1"][3] != "not determined"
    assert rows["E1"][5] == f"170.00 ({round((e1 / 170e9 - 1) * 100):+d} %)"
    assert ("reference (not compared): the value is not determined by these modes or is on a "
            "search limit, so its difference from the reference would mean nothing") \
        in " ".join(_notes(fig).split())
    table = ax(fig, "constants").tables[0]
    row = 1 + [k for k, r in enumerate(cells(ax(fig, "constants"))[1:])
               if r[0].startswith("nu12")][0]
    cell = table.get_celld()[row, 5]
    box, inner = cell.get_window_extent(renderer), cell.get_text().get_window_extent(renderer)
    assert box.x0 < inner.x0 and inner.x1 < box.x1 and box.y0 < inner.y0 and inner.y1 < box.y1


@pytest.fixture(scope="module")
def s12_prior(tmp_path_factory):
    """S1.2 (6x6) with ``prior: {nu12: 1.0}`` in its file: nu12 "well determined (held by the
    prior)" at its initial 0.350, the reference's value."""
    from pathlib import Path

    tmp = tmp_path_factory.mktemp("s12_prior")
    spec = tmp / "S1.2-prior.yaml"
    spec.write_text(Path("specimens/example1/S1.2.yaml").read_text().replace(
        "    nu12: 0.35\n", "    nu12: 0.35\n    prior: {nu12: 1.0}\n", 1))
    out = tmp / "S1.2-prior.result.h5"
    r = run("identify", spec, "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    return out


def test_a_value_held_by_its_prior_is_said_inside_its_cell_and_not_compared(s12_prior):
    """S1.2 with a prior on nu12: its verdict 'well determined (held by the prior)' ran over
    the verdict cell's borders on both sides, and its reference cell said '0.350 (+0 %)': the
    prior's value (the initial one) against a reference equal to it, an agreement the modes
    did not make. The words on two lines inside the cell, the reference '(not compared)' and
    the note says why."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = result_page(s12_prior, "summary")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    rows = cells(ax(fig, "constants"))[1:]
    k = next(i for i, row in enumerate(rows) if row[0].startswith("nu12"))
    assert rows[k][3] == "well determined\n(held by the prior)"
    assert rows[k][5] == "0.350\n(not compared)"
    assert "is held by its prior (the file's prior gives more than half of what is known of " \
        "it, paper Eq. 15)" in " ".join(_notes(fig).split())
    e1 = next(row for row in rows if row[0].startswith("E1"))
    assert e1[5].startswith("170.00 (") and "%" in e1[5]            # still compared
    table = ax(fig, "constants").tables[0]
    for col in (3, 5):
        cell = table.get_celld()[k + 1, col]
        box, inner = cell.get_window_extent(renderer), \
            cell.get_text().get_window_extent(renderer)
        assert box.x0 < inner.x0 and inner.x1 < box.x1 and box.y0 < inner.y0 \
            and inner.y1 < box.y1, (col, inner, box)


def _labelled_ticks(a, renderer):
    """(value, label, window extent) of the y axis' labelled major ticks in view."""
    lo, hi = a.get_ylim()
    out = []
    for tick in a.yaxis.get_major_ticks():
        v, label = tick.get_loc(), tick.label1
        if lo * (1 - 1e-9) <= v <= hi * (1 + 1e-9) and label.get_visible() and label.get_text():
            out.append((v, label.get_text(), label.get_window_extent(renderer)))
    return out


def test_history_modulus_panel_labels_the_range_it_shows(s21):
    """S2.1's "modulus / initial value" (0.0008 to 1.9 at 8x8, 4 at 12x12, on a log axis) labelled only its decades,
    none above 1, so that values 1 to 4 could not be read: its labels are at most 0.4 decade
    apart and from the panel's ends, plain text (no mathtext), not overlapping."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = result_page(s21, "history")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    a = ax(fig, "moduli")
    assert a.get_yscale() == "log"
    lo, hi = a.get_ylim()
    ys = np.concatenate([ln.get_ydata() for ln in a.get_lines()
                         if (ln.get_gid() or "").startswith("history-")])
    assert ys.max() > 1.5 and ys.min() < 0.01       # the case: values above 1, decades below
    ticks = _labelled_ticks(a, renderer)
    values = [v for v, _, _ in ticks]
    assert any(v > 1 for v in values), [t for _, t, _ in ticks]
    gaps = np.diff(np.log10([lo] + values + [hi]))
    assert gaps.max() <= 0.41, [t for _, t, _ in ticks]
    labels = [t for _, t, _ in ticks]
    assert "1" in labels and "2" in labels and not [t for t in labels if "$" in t]
    boxes = [b for _, _, b in ticks]
    assert all(b1.y1 < b0.y0 or b0.y1 < b1.y0 for b0, b1 in zip(boxes, boxes[1:]))


def test_a_squeezed_log_axis_labels_a_wide_partial_decade_at_its_end():
    """A log axis too short for 2 and 5 in each decade labels the decades, and a 2, 3 or 5
    x 10^k in a partial decade at an end when it has room (1 to 4.5: "3"), in plain text
    ("2×10⁻⁹", not "2e-09")."""
    from laminid_cli.report import _figure, log_axis_ticks, plain_number

    def labels(height, lim):
        fig = _figure((6, height + 0.5))
        a = fig.add_axes([0.1, 0.25 / (height + 0.5), 0.8, height / (height + 0.5)])
        a.set_yscale("log")
        a.set_ylim(*lim)
        log_axis_ticks(a, plain=False)
        locs = a.yaxis.get_majorticklocs()
        text = a.yaxis.get_major_formatter().format_ticks(locs)      # as the axis draws them
        return [t for v, t in zip(locs, text) if lim[0] <= v <= lim[1]]

    # (one form on the axis: test_a_log_axis_labels_its_ticks_in_one_form)
    assert labels(1.2, (1e-3, 4.5)) == ["0.001", "0.01", "0.1", "1", "3"]
    assert labels(2.4, (1e-3, 4.5)) == ["0.001", "0.002", "0.005", "0.01", "0.02", "0.05",
                                        "0.1", "0.2", "0.5", "1", "2"]
    # nine decades, every other one ticked: from 10⁻⁸ with matplotlib 3.11 (2×10⁻⁹ labels the
    # partial stretch below it), from 10⁻⁹ with 3.10 (0.5 labels the one above 10⁻¹)
    nine = labels(1.6, (1e-9, 1.0))
    assert nine in (["2×10⁻⁹", "10⁻⁸", "10⁻⁶", "10⁻⁴", "10⁻²", "10⁰"],
                    ["10⁻⁹", "10⁻⁷", "10⁻⁵", "10⁻³", "10⁻¹", "5×10⁻¹"]), nine
    assert labels(0.8, (0.3, 40)) == ["0.5", "1", "2", "5", "10", "20"]
    assert [plain_number(v) for v in (2e-5, 1e-5, 0.0002, 3.0, 2e5, 1.5e-7)] == [
        "2×10⁻⁵", "10⁻⁵", "0.0002", "3", "2×10⁵", "1.5e-07"]


@pytest.fixture(scope="module")
def example_frf_fit(tmp_path_factory):
    """scripts/example_frf.py's synthetic impact test of S1.1 (make example-frf) and its RFP
    fit: 13 modes; two poles stable in frequency and damping that are none of them, near
    the third band's edges (1112 Hz at order 14; 1405-1406 Hz at orders 13-14, the band
    ending at 1410 Hz)."""
    import importlib.util

    from laminid_cli.frf.io import read_frf
    from laminid_cli.frf.rfp import find_modes

    out = tmp_path_factory.mktemp("exfrf")
    spec = importlib.util.spec_from_file_location("example_frf", "scripts/example_frf.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--out", str(out)]) == 0
    fs = read_frf(out / "plate.frf.h5")
    return out / "plate.frf.h5", fs, find_modes(fs.freq, fs.frf)


def test_the_frf_figure_says_what_its_zoom_on_the_bands_leaves_out(example_frf_fit):
    """fit-frf --plot and the report's FRF page zoom on the fitted bands (59.4-1438 Hz of the
    example's 0.5-1424 Hz): a peak outside them (a mode the bands missed, one an exponential
    window damped past the rule) was out of sight without a word. A note in the magnitude
    panel names the measured frequencies not shown."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.frf.plot import HIDDEN_LINES, fit_figure, hidden_note

    axis = np.arange(0.0, 1424.5, 0.5)
    assert hidden_note(axis, (59.4, 1438.2)) == (
        "not shown: 0.5–59.4 Hz of the measured FRFs (no band fitted there)")
    assert hidden_note(axis, (59.4, 1200.0)) == (
        "not shown: 0.5–59.4 Hz and 1200–1424 Hz of the measured FRFs (no band fitted there)")
    # a few lines past a view's end are no part of the data left out
    assert hidden_note(axis, (0.5 * (HIDDEN_LINES + 1), 1500.0)) == ""
    _, fs, fit = example_frf_fit
    fig = fit_figure(fs.freq, fs.frf, fit, units=fs.units)
    renderer = FigureCanvasAgg(fig).get_renderer()
    notes = [t for a in fig.axes for t in a.texts if t.get_gid() == "view-note"]
    assert len(notes) == 1
    lo = min(b.band_hz[0] for b in fit.bands) * 0.95
    assert notes[0].get_text() == (f"not shown: {fs.freq[fs.freq > 0].min():.3g}–{lo:.3g} Hz "
                                   "of the measured FRFs (no band fitted there)")
    box, panel = notes[0].get_window_extent(renderer), notes[0].axes.get_window_extent(renderer)
    assert panel.x0 <= box.x0 and box.x1 <= panel.x1 and panel.y0 <= box.y0 <= box.y1 <= panel.y1


def test_stabilisation_chart_says_why_a_stable_pole_is_not_a_mode(example_frf_fit):
    """fit-frf --plot: stable poles (x) near a band's edge that are not in the mode list were
    drawn as the modes' x, with no word why. They are boxed, the legend keys the box, and a
    note under the chart gives each one's frequencies, orders and the rule that left it out
    (here: stable at too few orders, a computational pole near the band edge), inside the
    figure."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.frf.plot import fit_figure
    from laminid_cli.frf.rfp import unlisted_stable_poles

    _, fs, fit = example_frf_fit
    unlisted = unlisted_stable_poles(fit, fs.freq)
    assert [(round(u.freq_hz[0]), round(u.freq_hz[1]), u.orders, u.reason, u.edge_hz)
            for u in unlisted] == [(1112, 1112, (14, 14), "few", 1105.5),
                                   (1405, 1406, (13, 14), "few", 1410.0)]
    listed = fit.freq_hz
    for u in unlisted:
        assert np.min(np.abs(listed - u.freq_hz[0])) > 20
    fig = fit_figure(fs.freq, fs.frf, fit, units=fs.units)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    s = ax(fig, "stabilisation")
    boxed = [ln for ln in s.get_lines() if ln.get_gid() == "unlisted"]
    assert len(boxed) == 1 and sorted(np.round(boxed[0].get_xdata())) == [1112, 1405, 1406]
    labels = [t.get_text() for t in s.get_legend().get_texts()]
    assert "boxed: stable, not a mode (why: below)" in labels
    note = next(t for t in s.texts if t.get_gid() == "unlisted-note")
    words = " ".join(note.get_text().split())
    assert words == (
        "boxed, stable but not a mode: 1112 Hz (order 14): stable at 1 order, fewer than the 5 "
        "a mode needs: a computational pole, near the band edge 1105.5 Hz, where the fit places "
        "poles for the modes beyond it; 1405–1406 Hz (orders 13–14): stable at 2 orders, fewer "
        "than the 5 a mode needs: a computational pole, near the band edge 1410 Hz, where the "
        "fit places poles for the modes beyond it")
    _assert_under_chart_in_page(note, s, fig, renderer)


def test_unlisted_pole_words_for_each_rule():
    """The note's words for the other rules: at the band's edge, damping out of range, below
    the noise; no band edge named far from one."""
    import numpy as np

    from laminid_cli.frf.plot import unlisted_note
    from laminid_cli.frf.rfp import PoleCriteria, UnlistedPoles

    def u(reason, edge=None, n=6):
        return UnlistedPoles(band=0, rows=np.array([0]), freq_hz=(1589.6, 1590.2),
                             orders=(8, 16), n_stable=n, reason=reason, edge_hz=edge)

    c = PoleCriteria()
    assert " ".join(unlisted_note([u("edge", 1590.5)], c).split()) == (
        "boxed, stable but not a mode: 1590 Hz (orders 8–16): within 2 lines of the band edge "
        "1590.5 Hz: not taken from that band (a pole there stands for the modes beyond it)")
    assert unlisted_note([u("damping")], c).endswith("damping outside 0–10%: not a physical "
                                                     "mode")
    assert " ".join(unlisted_note([u("noise")], c).split()).endswith(
        "its contribution does not rise above the fit's residual (5 x): dropped as noise")
    assert unlisted_note([u("few", n=3)], c).endswith(
        "stable at 3 orders, fewer than the 5 a mode needs: a computational pole")


def test_many_unlisted_pole_groups_are_counted_by_rule_inside_the_page(example_frf_fit,
                                                                       monkeypatch):
    """Noisy FRFs (an acquire file of coherence 0.7 at its resonances) left 100 groups of
    stable poles that are none of the modes: the note named each, 12 lines run off the page's
    foot, and matplotlib's layout gave up ('constrained_layout not applied', on stderr). More
    than MAX_NOTE_GROUPS groups are counted by rule, in at most three lines under the chart."""
    import warnings

    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.frf import rfp
    from laminid_cli.frf.plot import MAX_NOTE_GROUPS, fit_figure

    _, fs, fit = example_frf_fit
    reasons = ["few"] * 30 + ["edge"] * 6 + ["damping"] * 4 + ["noise"] * 2
    many = [rfp.UnlistedPoles(band=0, rows=np.array([0]), freq_hz=(70.0 + 30 * i, 71.0 + 30 * i),
                              orders=(6, 7), n_stable=2, reason=r,
                              edge_hz=62.5 if r == "few" and i < 10 else None)
            for i, r in enumerate(reasons)]
    assert len(many) > MAX_NOTE_GROUPS
    monkeypatch.setattr(rfp, "unlisted_stable_poles", lambda fit, freq: many)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                    # no layout warning
        fig = fit_figure(fs.freq, fs.frf, fit, units=fs.units)
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
    s = ax(fig, "stabilisation")
    note = next(t for t in s.texts if t.get_gid() == "unlisted-note")
    assert len(note.get_text().splitlines()) <= 3
    assert " ".join(note.get_text().split()) == (
        "boxed, stable but not a mode: 42 groups of poles, 70–1301 Hz: 30 stable at fewer "
        "orders than the 5 a mode needs (computational poles, 10 near a band edge); 6 within 2 "
        "lines of a band edge (not taken from that band); 4 damping outside 0–10% (not "
        "physical modes); 2 not above the fit's residual (5 x; dropped as noise). So many: noisy "
        "FRFs (see the coherence) or too wide bands; try --band LO:HI")
    _assert_under_chart_in_page(note, s, fig, renderer)
    # the panels keep their height: the chart no lower than with the two groups of the example
    assert s.get_window_extent(renderer).height > 0.2 * fig.bbox.height


def _assert_under_chart_in_page(note, chart, fig, renderer):
    """The stabilisation chart's note lies inside the page, under the chart and clear of it."""
    box, page = note.get_window_extent(renderer), fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0
    assert box.y1 < chart.get_window_extent(renderer).y0


def test_sensitivity_rows_of_modes_the_fit_did_not_use_say_so():
    """A mode not measured, or measured with weight 0, determines no constant: its row on the
    sensitivity page says why and is faded, as the terminal's table says "(weight 0)" (the
    page drew it as a measured mode's: S1.2's mode 5 in the joint fit of S1.1-S1.4)."""
    from types import SimpleNamespace

    import numpy as np

    from laminid_cli.report import UNUSED_COLOR, sensitivity_page

    S = np.array([[0.4, 0.1], [0.3, 0.05], [0.2, 0.02], [0.35, -0.0002]])
    fr = SimpleNamespace(model=np.array([100.0, 200.0, 300.0, 400.0]),
                         measured=np.array([100.2, np.nan, 299.0, 401.0]),
                         weight=np.array([1.0, 0.0, 0.0, 1.0]))
    plate = SimpleNamespace(name="P", sensitivity=S, sensitivity_labels=("M.E1", "M.E2"),
                            frequencies=fr)
    fig = sensitivity_page(SimpleNamespace(materials={"M": {}}), plate)
    a = ax(fig, "sensitivity")
    labels = [t.get_text() for t in a.get_yticklabels()]
    assert labels == ["mode 1: 100.0 Hz", "mode 2: 200.0 Hz\n(not measured)",
                      "mode 3: 300.0 Hz\n(weight 0, not fitted)", "mode 4: 400.0 Hz"]
    assert [t.get_color() == UNUSED_COLOR for t in a.get_yticklabels()] == [
        False, True, True, False]
    faded = sorted(p.get_gid() for p in a.patches if (p.get_gid() or "").startswith("unused"))
    assert faded == ["unused-2", "unused-3"]
    greyed = {(round(t.get_position()[1]), t.get_text()) for t in a.texts
              if t.get_color() == UNUSED_COLOR}
    assert greyed == {(1, "0.300"), (1, "0.050"), (2, "0.200"), (2, "0.020")}


def test_sensitivity_columns_of_constants_on_a_search_limit_are_marked():
    """A constant that stopped on a search limit (``at_bound`` of its interval) is not
    identified: its sensitivity column says "(on limit)" in its header, is hatched, and a key
    under the map names it (hybrid CM's glass G12, G13, G23, E2 and carbon nu12 were drawn as
    identified constants' columns)."""
    from types import SimpleNamespace

    import numpy as np

    from laminid_cli.report import LIMIT_COLOR, sensitivity_page

    S = np.array([[0.4, 0.0, 0.1], [0.3, 0.001, 0.05]])
    fr = SimpleNamespace(model=np.array([100.0, 200.0]), measured=np.array([100.2, 199.0]),
                         weight=np.array([1.0, 1.0]))
    plate = SimpleNamespace(name="P", sensitivity=S, frequencies=fr, warnings=(),
                            sensitivity_labels=("glass.E1", "glass.G12", "carbon.E1"))
    ivs = [SimpleNamespace(label="glass.E1", at_bound=False),
           SimpleNamespace(label="glass.G12", at_bound=True),
           SimpleNamespace(label="carbon.E1", at_bound=False)]
    r = SimpleNamespace(materials={"glass": {}, "carbon": {}}, warnings=(), plates=(plate,),
                        uncertainty=SimpleNamespace(intervals=ivs))
    fig = sensitivity_page(r, plate)
    a = ax(fig, "sensitivity")
    assert [t.get_text() for t in a.get_xticklabels()] == [
        "glass.E1", "glass.G12\n(on limit)", "carbon.E1"]
    assert [t.get_color() == LIMIT_COLOR for t in a.get_xticklabels()] == [False, True, False]
    hatched = [p for p in a.patches if (p.get_gid() or "").startswith("on-limit")]
    assert [p.get_gid() for p in hatched] == ["on-limit-glass.G12"]
    assert hatched[0].get_hatch() and hatched[0].get_x() == 0.5 and hatched[0].get_width() == 1
    key = next(t for t in fig.texts if t.get_gid() == "on-limit-key").get_text()
    assert "glass.G12 stopped on a search limit" in key.replace("\n", " ")
    # none on a limit: no mark, no key
    r0 = SimpleNamespace(materials=r.materials, warnings=(), plates=(plate,),
                         uncertainty=SimpleNamespace(intervals=ivs[:1]))
    fig0 = sensitivity_page(r0, plate)
    assert "(on limit)" not in " ".join(t.get_text() for t in
                                        ax(fig0, "sensitivity").get_xticklabels())
    assert not [t for t in fig0.texts if t.get_gid() == "on-limit-key"]


def test_intervals_from_the_stated_sigma_say_so(s11):
    """S1.1 (8x8) fits within its stated noise (s2 ~ 0.5): its intervals are from the stated
    frequency sigma (normal quantile), which page 1 now says beside s² (it gave s² alone, as
    for intervals widened by it); the intervals page, whose legend speaks of a widening only
    where there is one, says nothing of it."""
    from laminid_cli.resultfile import read_result

    u = read_result(s11).uncertainty
    assert u.scale_used == "stated" and u.s2 < 1
    notes = next(t.get_text() for a in result_page(s11, "summary").axes for t in a.texts
                 if t.get_gid() == "notes").replace("\n", " ")
    assert (f"95% intervals from the stated frequency σ (normal quantile), s² = {u.s2:.3g}, "
            "condition number") in notes
    legend = next(a.get_legend() for a in result_page(s11, "intervals").axes
                  if a.get_legend())
    assert "residuals" not in legend.get_title().get_text()


def test_residual_bars_drawn_over_each_frequencys_stated_sigma(s11):
    """The residual bars of page 1 stand over each measured frequency's ± 1 sd (the file's
    /uncertainty/frequency_sigma, in % of the frequency), said under the panel, inside the
    page: the page showed residuals without the noise the fit assumes (S1.2's -0.5 to -0.9 %
    in the joint fit of S1.1-S1.4 against its 0.2 % read as small). A file or a plate without
    those sigmas draws no shade and says none."""
    import h5py
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    with h5py.File(s11) as f:
        (d,) = f["uncertainty/frequency_sigma"].values()
        sigma = d[()]
        measured = f["frequencies/measured"][()]
    fig = result_page(s11, "summary")
    a = ax(fig, "residuals")
    (shade,) = [c for c in a.collections if c.get_gid() == "frequency-sigma"]
    boxes = [p.vertices for p in shade.get_paths()]
    assert len(boxes) == np.isfinite(measured).sum() == 12
    half = np.array([b[:, 0].max() for b in boxes])
    assert np.allclose(half, 100 * sigma / measured, rtol=1e-12)
    assert np.allclose([b[:, 0].min() for b in boxes], -half)
    assert np.allclose([(b[:, 1].min() + b[:, 1].max()) / 2 for b in boxes], np.arange(12))
    lo, hi = a.get_xlim()
    assert lo <= -half.max() and hi >= half.max()
    assert "shaded: ± 1 sd of the measured frequency" in a.get_xlabel().replace("\n", " ")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box = a.xaxis.label.get_window_extent(renderer)
    page = fig.bbox
    assert page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0
    # no sigmas (an older file): no shade, no words
    b = _frequency_figure([100.5, 199.0, 301.0, 398.0], [1, 1, 1, 1])
    assert "shaded" not in b.get_xlabel() and not b.collections


@pytest.mark.parametrize("height, lim, plain, drawn", [
    # decades and a partial decade's 3 (the history's modulus / initial value up to 4.5):
    # "10⁻³ ... 10⁰" beside a plain "3" before
    (1.2, (1e-3, 4.5), False, ["0.001", "0.01", "0.1", "1", "3"]),
    # the hybrid plate's RMS residual, 0.1 to 250 %: "200" over "10²"
    (1.5, (0.09, 250.0), False, ["0.1", "1", "10", "100", "200"]),
    # the hybrid plate's glass E1 interval, 0.0087 to 3.9e5 GPa: "10000" under "10⁶"
    (2.2, (0.005, 2e6), True, ["10⁻²", "10⁰", "10²", "10⁴", "10⁶"]),
    # decades beyond 1e-4 with a partial one's 5 below 1: powers throughout
    (1.6, (1e-7, 0.8), False, None),
])
def test_a_log_axis_labels_its_ticks_in_one_form(height, lim, plain, drawn):
    """The labels a log axis draws are all plain numbers or all powers of ten (an axis mixed
    them: the hybrid plate's history had "200" over "10²", "5" over "10⁰" in the joint fit's,
    an interval panel "10000" under "10⁶"): plain where every label is between 1e-4 and 1e5
    and the axis is plain or labels more than decades, else powers throughout ("3×10⁰")."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report import _figure, log_axis_ticks

    fig = _figure((6, height + 0.5))
    fig.set_layout_engine("none")             # the axes placed by hand, as the page's height
    a = fig.add_axes([0.1, 0.25 / (height + 0.5), 0.8, height / (height + 0.5)])
    a.set_yscale("log")
    a.set_ylim(*lim)
    log_axis_ticks(a, plain=plain)
    FigureCanvasAgg(fig).draw()
    labels = [t.get_text() for t in a.get_yticklabels()
              if lim[0] <= t.get_position()[1] <= lim[1] and t.get_text()]
    powers = ["10" in t and any(c in t for c in "⁰¹²³⁴⁵⁶⁷⁸⁹") for t in labels]
    assert all(powers) or not any(powers), labels
    if drawn is not None:
        assert labels == drawn
    else:
        assert all(powers) and any("×" in t for t in labels), labels


def test_sensitivity_cells_in_the_terminals_digits():
    """Each cell of the sensitivity page in the terminal table's 3 decimals: a value that
    rounds to zero is "0.000", without a minus (the page wrote "0", read as exactly none beside
    0.001; the terminal "0.000" or "-0.000")."""
    from types import SimpleNamespace

    import numpy as np

    from laminid_cli.report import sensitivity_page

    S = np.array([[0.41234, -0.0004], [0.0004999, -0.0042], [0.0, -0.0005001]])
    fr = SimpleNamespace(model=np.array([100.0, 200.0, 300.0]),
                         measured=np.array([100.0, 200.0, 300.0]), weight=np.ones(3))
    plate = SimpleNamespace(name="P", sensitivity=S, sensitivity_labels=("M.E1", "M.E2"),
                            frequencies=fr)
    a = ax(sensitivity_page(SimpleNamespace(materials={"M": {}}), plate), "sensitivity")
    cell = {(round(t.get_position()[1]), round(t.get_position()[0])): t.get_text()
            for t in a.texts}
    assert cell == {(0, 0): "0.412", (0, 1): "0.000", (1, 0): "0.000", (1, 1): "-0.004",
                    (2, 0): "0.000", (2, 1): "-0.001"}


def test_long_specimen_names_are_shortened_under_the_panels_and_given_whole(tmp_path):
    """A lab's specimen names ("S1.1 panel B-07 (autoclave batch 2026-11, ...)") as they were
    under the panels across specimens, rotated: they took the page's height from the panels
    (squeezed to strips of a few pixels) and ran off its left edge. Each is shortened in the
    middle under the panels, the panels keep their height, every tick label is inside the
    page, and the note under the panels gives each name whole."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from tests.test_report import _write_summary

    q, r = _one_material_rows()
    long_q = "S1.1 panel B-07 (autoclave batch 2026-11, edges trimmed, re-tested after drop)"
    long_r = "S1.2 panel B-08 (autoclave batch 2026-11, edges trimmed)"
    rows = [q | {"name": "B-07", "specimen": long_q}, r | {"name": "B-08", "specimen": long_r}]
    path = tmp_path / "summary.json"
    _write_summary(path, rows)
    pages = {p.name: p.figure for p in report_pages(path)}
    for name, gid in (("constants", "across-E1"), ("residuals", "rms")):
        fig = pages[name]
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
        a = ax(fig, gid)
        ticks = [t for t in a.get_xticklabels() if t.get_text()]
        assert len(ticks) == 2 and all(len(t.get_text()) <= 24 for t in ticks)
        for t in ticks:
            box = t.get_window_extent(renderer)
            assert box.x0 >= 0 and box.y0 >= 0, (name, t.get_text(), box)
        # the panels are not squeezed by their ticks
        assert a.get_window_extent(renderer).height > 0.2 * fig.bbox.height, name
        words = " ".join(t.get_text() for t in fig.texts).replace("\n", " ")
        words = " ".join(words.split())
        assert long_q in words and long_r in words, name


def test_loss_factor_labels_of_a_long_material_name_stay_inside_their_cells():
    """A loss factor of a material with a long name ("Hexcel IM7/977-2 unidirectional prepreg
    tape 0.135 mm.eta11") ran under the next cell of the damping page's table, which hid the
    end that says which loss factor the row is (".eta1" of every row read alike). The label is
    wrapped to its column: each cell's text inside the cell, the loss factor's term whole."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report_damping import damping_pages

    mat = "Hexcel IM7/977-2 unidirectional prepreg tape 0.135 mm"
    d = _damping_data("")
    d["labels"] = [lab.replace("M.", f"{mat}.") for lab in d["labels"]]
    fig = damping_pages(d)[0]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    table = ax(fig, "loss-factors").tables[0]
    labels = []
    for (i, j), cell in table.get_celld().items():
        box, text = cell.get_window_extent(renderer), cell.get_text()
        t = text.get_window_extent(renderer)
        assert box.x0 - 0.5 <= t.x0 and t.x1 <= box.x1 + 0.5, text.get_text()
        if i > 0 and j == 0:
            labels.append(" ".join(text.get_text().split()))
    assert sorted(labels) == sorted(d["labels"])


GLASS = "E-glass 7781 woven fabric / Hexcel 913 epoxy (batch 2026-11)"
CARBON = "Toray T300 carbon / R367 epoxy UD prepreg tape (Structil CTE235)"


@pytest.fixture(scope="module")
def long_materials(tmp_path_factory):
    """A two-material plate (S1.1's, its plies tagged) whose materials have a lab's long
    names, identified at 4x4 with G13, G23, nu12 fixed (under a second). Read only."""
    folder = tmp_path_factory.mktemp("long-materials")
    spec = folder / "two.yaml"
    spec.write_text(
        "name: two\ngeometry: {a: 210.5 mm, b: 311 mm, h: 3.06 mm}\nmass: 0.3225 kg\n"
        "materials:\n"
        f'  "{GLASS}": {{E1: 40 GPa, E2: 10 GPa, G12: 4 GPa, G13: 3.5 GPa, G23: 3.5 GPa, '
        "nu12: 0.28, density_ratio: 1.3, fixed: [G13, G23, nu12]}\n"
        f'  "{CARBON}": {{E1: 117.2 GPa, E2: 8.8 GPa, G12: 3.1 GPa, G13: 3.1 GPa, '
        "G23: 3.1 GPa, nu12: 0.35, density_ratio: 1.0, fixed: [G13, G23, nu12]}\n"
        'layup: "[45_3:E/0_3:T/-45_3:E/90_3:T]s"\n'
        "measured:\n  frequencies: [125.05, 203.50, 331.30, 446.65, 493.55, 603.80, 650.75, "
        "818.70, 951.35, 990.65]\n")
    out = folder / "two.result.h5"
    res = run("identify", spec, "--mesh", "4x4", "-o", out)
    assert res.exit_code == 0, res.output
    return out


def test_long_material_names_are_shortened_in_the_labels_and_given_whole(long_materials):
    """A lab's material names ("E-glass 7781 woven fabric / Hexcel 913 epoxy (batch
    2026-11)") were written whole in the labels: the constants table's first column ran under
    the next cell, which hid the constant of each row ("...fabric / Hexcel 913 epoxy (" for
    E1 to G23 alike), the interval panels' titles ran into each other, the history's legend
    took two thirds of its page's width. Each name is shortened in the middle in the labels
    (the constant whole, under it in the table), every table cell's text is inside its cell,
    the titles do not overlap, and the notes give each name whole."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Text

    def drawn(name):
        fig = result_page(long_materials, name)
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
        words = " ".join(" ".join(t.get_text() for t in fig.findobj(Text)).split())
        return fig, renderer, words

    fig, renderer, words = drawn("summary")
    table = ax(fig, "constants").tables[0]
    firsts = []
    for (i, j), cell in table.get_celld().items():
        box, t = cell.get_window_extent(renderer), cell.get_text().get_window_extent(renderer)
        assert box.x0 - 0.5 <= t.x0 and t.x1 <= box.x1 + 0.5, cell.get_text().get_text()
        if i > 0 and j == 0:
            firsts.append(cell.get_text().get_text().split("\n")[-1])
    assert sorted(firsts) == sorted(f"{k} ({'–' if k == 'nu12' else 'GPa'})"
                                    for k in ("E1", "E2", "G12", "G13", "G23", "nu12")
                                    for _ in range(2))
    assert GLASS in words and CARBON in words
    fig, renderer, words = drawn("intervals")
    titles = [a.title for a in fig.axes if (a.get_gid() or "").startswith("interval-")]
    boxes = sorted((t.get_window_extent(renderer) for t in titles), key=lambda b: (b.y0, b.x0))
    for p, q in zip(boxes, boxes[1:]):
        assert not (p.x1 > q.x0 + 0.5 and abs(p.y0 - q.y0) < 1), (p, q)
    assert GLASS in words and CARBON in words
    fig, renderer, words = drawn("history")
    assert ax(fig, "moduli").get_window_extent(renderer).width > 0.5 * fig.bbox.width
    assert GLASS in words and CARBON in words


def test_a_bound_statement_running_into_its_profiles_words_is_left_out():
    """On interval panels made short by a long status (hybrid CM: carbon nu12 at 12x12, every
    glass panel on a search limit with the materials' long names), "stopped on the upper
    search limit: no interval" and "profile: flat to 0.000" were written over each other.
    Where they overlap the statement is left out (the triangle, the legend and the words
    under the panel say it); where they do not, both stay."""
    from laminid_cli.report import _clear_bound_statements, _figure

    fig = _figure()
    short, tall = fig.subplots(1, 2)
    for a, (y_statement, y_profile) in ((short, (0.6, 0.5)), (tall, (0.95, 0.05))):
        a.annotate("stopped on\nthe upper\nsearch\nlimit: no\ninterval", (0, y_statement),
                   fontsize=6.5, va="top", gid="bound-statement")
        a.annotate("profile:\nflat to\n0.000", (0, y_profile), fontsize=6.5, va="bottom",
                   gid="profile-label")
    _clear_bound_statements(fig, [short, tall])
    assert [t.get_gid() for t in short.texts] == ["profile-label"]
    assert [t.get_gid() for t in tall.texts] == ["bound-statement", "profile-label"]


def test_a_mode_left_out_by_modes_n_is_said_so_not_noise(example_frf_fit):
    """fit-frf --band 100:700 --modes 6 of the example: the 7th mode, 651 Hz, the band's
    tallest peak, was found and cut by --modes 6, but the chart boxed it as "its contribution
    does not rise above the fit's residual (5 x): dropped as noise" and the terminal asked "a
    mode missed in noise?". It is now boxed as a mode above the lowest --modes asks for, not
    listed, and no missed peak is said."""
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.frf.plot import fit_figure
    from laminid_cli.frf.rfp import find_modes, missed_peak_notes, unlisted_stable_poles

    _, fs, _ = example_frf_fit
    fit = find_modes(fs.freq, fs.frf, bands=[(100.0, 700.0)], n_modes=6)
    assert len(fit.modes) == 6 and [round(m.freq_hz) for m in fit.beyond] == [651]
    beyond = [u for u in unlisted_stable_poles(fit, fs.freq) if u.reason == "beyond"]
    assert [round(u.freq_hz[0]) for u in beyond] == [651]
    assert not any(round(u.freq_hz[0]) == 651 for u in unlisted_stable_poles(fit, fs.freq)
                   if u.reason != "beyond")
    assert not [n for n in missed_peak_notes(fit, fs.freq, fs.frf) if "651" in n]
    fig = fit_figure(fs.freq, fs.frf, fit, units=fs.units)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    s = ax(fig, "stabilisation")
    note = " ".join(next(t for t in s.texts if t.get_gid() == "unlisted-note")
                    .get_text().split())
    assert note.startswith("boxed, stable but not listed: 651 Hz")
    assert "a mode, above the lowest that --modes asks for: not listed" in note
    assert "dropped as noise" not in note
    assert "boxed: stable, not listed (why: below)" in [
        t.get_text() for t in s.get_legend().get_texts()]
    assert np.isfinite(fit.freq_hz).all()


def test_the_constants_table_of_one_material_names_it(s11):
    """S1.1's page 1: the table's rows say "E1 (GPa)" ..., and the material (IM7/977-2) was
    named nowhere on the page but in the status's words (none where the status is ok). The
    table's title names it."""
    fig = result_page(s11, "summary")
    assert ax(fig, "constants").get_title(loc="left") == "identified constants of IM7/977-2"


def test_interval_legend_of_many_long_entries_stays_on_the_page(s21_mc, monkeypatch):
    """The interval page's legend takes as many columns as the page's width holds: hybrid CM
    with a Monte Carlo (the nine entries below, its legend as drawn) ran four columns off
    both edges of the page, and the constrained layout squeezed the panels into half its
    width, their titles over each other."""
    from laminid_cli import report
    from laminid_cli.resultfile import read_result

    res = read_result(s21_mc)
    handles, labels = report._interval_legend(res)
    long = ["interval within ±5% of the value: well determined", "within ±30%: weak",
            "95% interval", "identified",
            "not determined (interval or Monte Carlo range too wide)",
            "stopped on a search limit: not identified",
            "values the fit does not reject (profile);\ncap: it rejects beyond; arrow head: "
            "the end\nof its scan, not tried beyond",
            "Monte Carlo range (95% of the trials)", "Monte Carlo range for sure (90 %)"]
    many = (handles + handles)[:len(long)]
    monkeypatch.setattr(report, "_interval_legend", lambda r: (many, long))
    fig = report.interval_page(res)
    fig.draw_without_rendering()
    page = fig.bbox
    legend = next(a.get_legend() for a in fig.axes if a.get_legend() is not None)
    box = legend.get_window_extent()
    assert page.x0 <= box.x0 and box.x1 <= page.x1, (box, page)
    assert [t.get_text() for t in legend.get_texts()] == long
    panels = [a for a in fig.axes if (a.get_gid() or "").startswith("interval-")]
    assert len(panels) == 6
    # six panels across the page: each at least a tenth of its width (squeezed: 0.04)
    assert min(a.get_window_extent().width for a in panels) >= 0.1 * page.width


def test_monte_carlo_end_words_running_into_each_other_leave_out_the_widths_for_sure():
    """On the short panels of hybrid CM with a Monte Carlo, glass nu12's range ran off both
    ends: "to 0.8603 (for sure 0.1822) search limit" was written over "from -0.6637 (for
    sure -0.4006)". Where the two ends' words overlap, the "(for sure ...)" lines are left
    out of both (the range's ends and "search limit" stay); where they do not, all stay."""
    from laminid_cli.report import _figure, _shorten_crowded_mc_end_words

    fig = _figure()
    short, tall = fig.subplots(1, 2)
    up_words, low_words = "to\n0.8603\n(for sure\n0.1822)\nsearch\nlimit", \
        "from\n-0.6637\n(for sure\n-0.4006)"
    for a, (y_up, y_low) in ((short, (0.52, 0.48)), (tall, (0.98, 0.02))):
        a.annotate(up_words, (0, y_up), fontsize=6.5, va="top",
                   gid="monte-carlo-upper-end")
        a.annotate(low_words, (0, y_low), fontsize=6.5, va="bottom",
                   gid="monte-carlo-lower-end")
    _shorten_crowded_mc_end_words(fig, [short, tall])
    assert [t.get_text() for t in short.texts] == ["to\n0.8603\nsearch\nlimit",
                                                   "from\n-0.6637"]
    assert [t.get_text() for t in tall.texts] == [up_words, low_words]


def test_interval_end_words_stay_inside_a_short_panel(s21):
    """The words of an interval's end off the panel ("to ...", "from ...") hang from the
    panel's edge into it: centred on the arrow's foot (8 % of the panel inside its edge),
    their two lines ran over the frame of a short panel (hybrid CM's glass E1 with a Monte
    Carlo: "from 0.00272" over the panel's foot)."""
    import dataclasses

    import matplotlib.pyplot as plt

    from laminid_cli.report import interval_panel
    from laminid_cli.resultfile import read_result

    res = read_result(s21)
    m = next(iter(res.materials))
    u = res.uncertainty
    v = res.materials[m]["G23"]
    ivs = tuple(dataclasses.replace(iv, lower=v / 1e5, upper=v * 1e5)
                if iv.constant == "G23" else iv for iv in u.intervals)
    fig, a = plt.subplots(figsize=(1.6, 1.1))
    interval_panel(a, dataclasses.replace(res, uncertainty=dataclasses.replace(
        u, intervals=ivs)), m, "G23", log=True)
    a.set_xlim(-0.75, 0.75)                             # as the intervals page
    fig.draw_without_rendering()
    ends = {t.get_text().split("\n")[0]: t.get_window_extent() for t in a.texts
            if t.get_gid() == "interval-end"}
    assert set(ends) == {"to", "from"}
    box = a.get_window_extent()
    for word, e in ends.items():
        assert box.y0 <= e.y0 and e.y1 <= box.y1, (word, e, box)
    plt.close(fig)


def test_a_value_held_by_its_prior_is_marked_on_its_interval_panel(s12_prior, s11):
    """S1.2 with a prior on nu12: its panel drew a filled dot, a narrow interval and the
    green band on its reference, as a constant the modes determine (only the words under the
    panel said "held by the prior"). It has the "~" of the page across specimens beside the
    value, and the legend keys it; a page without such a value has neither."""
    from laminid_cli.resultfile import read_result

    res = read_result(s12_prior)
    m = next(iter(res.materials))
    fig = result_page(s12_prior, "intervals")
    a = ax(fig, f"interval-{m}.nu12")
    mark = next(t for t in a.texts if t.get_gid() == "prior")
    assert mark.get_text() == "~" and mark.xy[1] == pytest.approx(res.materials[m]["nu12"])
    legend = next(x.get_legend() for x in fig.axes if x.get_legend() is not None)
    assert ("~: held by its prior (mostly the file's prior value, not the modes')"
            in [t.get_text() for t in legend.get_texts()])
    # only that constant's panel, and no key on a page without a prior
    assert [x.get_gid() for x in fig.axes if any(t.get_gid() == "prior" for t in x.texts)] \
        == [f"interval-{m}.nu12"]
    other = result_page(s11, "intervals")
    assert not [t for x in other.axes for t in x.texts if t.get_gid() == "prior"]
    legend = next(x.get_legend() for x in other.axes if x.get_legend() is not None)
    assert not [t for t in legend.get_texts() if "held by its prior" in t.get_text()]


def test_two_search_limit_words_running_into_each_other_are_said_once():
    """Hybrid CM with measured damping and a Monte Carlo (8x8): glass E2's range 30-58 GPa,
    both ends set by trials on search limits, too far apart in the panel to be joined
    beforehand (_limit_ends_together) but near enough on its short panel for the two
    "search limit" to be written over each other. Where they overlap, one "search limit
    (both ends)" hangs from the upper end; where they do not, both stay."""
    from laminid_cli.report import _figure, _tidy_mc_limit_words

    fig = _figure()
    short, tall = fig.subplots(1, 2)
    for a, (y_up, y_low) in ((short, (0.52, 0.48)), (tall, (0.98, 0.02))):
        a.annotate("search\nlimit", (0, y_up), fontsize=6.5, va="top",
                   gid="monte-carlo-upper-limit")
        a.annotate("search\nlimit", (0, y_low), fontsize=6.5, va="bottom",
                   gid="monte-carlo-lower-limit")
    _tidy_mc_limit_words(fig, [short, tall])
    assert [(t.get_gid(), t.get_text(), t.xy[1]) for t in short.texts] == [
        ("monte-carlo-upper-limit", "search\nlimit\n(both\nends)", 0.52)]
    assert [(t.get_gid(), t.get_text()) for t in tall.texts] == [
        ("monte-carlo-upper-limit", "search\nlimit"), ("monte-carlo-lower-limit", "search\nlimit")]


def test_monte_carlo_words_over_a_panels_foot_are_moved_inside_it():
    """The joined "search limit (both ends)" is centred on the bar's middle: on a short
    panel with the bar near its foot (hybrid CM with measured damping and a Monte Carlo,
    8x8: glass G12's range 0.0054-0.0060 GPa) its words ran 11 pixels below the frame, over
    the value written under the panel. Words of a Monte Carlo bar over the panel's foot or
    top are moved inside it; words inside stay where they are."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from laminid_cli.report import _figure, _tidy_mc_limit_words

    fig = _figure()
    a = fig.subplots(3, 1)[0]                                       # a short panel
    low = a.annotate("search\nlimit\n(both\nends)", (0, 0.02), xytext=(-4, 0),
                     textcoords="offset points", fontsize=6.5, va="center",
                     gid="monte-carlo-both-limit")
    top = a.annotate("search\nlimit", (0, 0.99), xytext=(-4, 3), textcoords="offset points",
                     fontsize=6.5, va="bottom", gid="monte-carlo-upper-limit")
    mid = a.annotate("search\nlimit", (0, 0.5), xytext=(-4, 3), textcoords="offset points",
                     fontsize=6.5, va="bottom", gid="monte-carlo-lower-limit")
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    box = a.get_window_extent(renderer)
    assert low.get_window_extent(renderer).y0 < box.y0 - 5            # as drawn before
    assert top.get_window_extent(renderer).y1 > box.y1 + 5
    _tidy_mc_limit_words(fig, [a])
    fig.draw(renderer)
    box = a.get_window_extent(renderer)
    for t in (low, top):
        e = t.get_window_extent(renderer)
        assert box.y0 - 0.5 <= e.y0 and e.y1 <= box.y1 + 0.5, (t.get_text(), e, box)
    assert mid.xyann == (-4, 3)


def test_constants_across_specimens_mark_the_values_of_a_fit_that_did_not_converge(tmp_path):
    """A specimen whose fit did not converge (S1.1 stopped by --max-evaluations 8) had its
    values drawn as identified ones, a filled dot with its interval beside the others; only
    the status line under the panels said 'not_converged'. Each of its values has "nc"
    beside it, keyed in the legend; a converged specimen's have none."""
    from laminid_cli.batch import write_summary_csv
    from tests.test_report import _summary_rows

    h, q = _summary_rows()
    q = q | {"status": "check", "converged": False, "reason": "not_converged",
             "reasons": [{"code": "not_converged", "text": "..."}]}
    path = tmp_path / "summary.csv"
    write_summary_csv(path, [h, q])
    fig = {p.name: p.figure for p in report_pages(path)}["constants"]
    marks = [(a.get_gid(), t.get_gid(), t.get_text(), t.xy[1]) for a in fig.axes
             for t in a.texts if (t.get_gid() or "").startswith("not-converged")]
    k_of = {f"across-{k}": k for k in q["materials"]["carbon"]}
    assert sorted(m[0] for m in marks) == sorted(k_of)                # Q's six, none of H's
    for gid, tag, text, y in marks:
        k = k_of[gid]
        assert tag == "not-converged-Q-carbon" and text == "nc"
        assert y == pytest.approx(q["materials"]["carbon"][k] / (1 if k == "nu12" else 1e9))
    legend = next(a.get_legend() for a in fig.axes if a.get_legend() is not None)
    assert ("nc: not converged (the optimiser's last point, not an identification)"
            in [t.get_text() for t in legend.get_texts()])


def test_monte_carlo_bars_across_specimens_have_their_materials_colour(tmp_path):
    """The Monte Carlo bars of two materials of one specimen (hybrid CM's glass and carbon)
    stand side by side; grey, either could be pinned on either material (the glass bar, right
    of the glass dot, stands next to the carbon dot). Each is its material's colour, pale
    (mc_tint: half-way to white), on the constants' and the loss factors' pages, and the
    legend's key shows each material's pale bar."""
    from matplotlib.colors import to_rgb

    from laminid_cli.batch import write_summary_csv
    from laminid_cli.report import mc_tint
    from tests.test_report import _summary_rows

    h, q = _summary_rows()
    for m in ("glass", "carbon"):
        h["intervals"][m]["E1"] |= {"mc_lower": 0.9 * h["materials"][m]["E1"],
                                    "mc_upper": 1.1 * h["materials"][m]["E1"],
                                    "mc_lower_at_limit": False, "mc_upper_at_limit": False}
    h["damping"] = {m: {"eta11": {"value": e, "lower": 0.9 * e, "upper": 1.1 * e,
                                  "verdict": "well determined", "at_bound": False,
                                  "bound_side": "", "bound_limit": None, "mc_lower": 0.8 * e,
                                  "mc_upper": 1.2 * e, "mc_lower_at_limit": False,
                                  "mc_upper_at_limit": False}}
                    for m, e in (("glass", 0.002), ("carbon", 0.004))}
    path = tmp_path / "summary.csv"
    write_summary_csv(path, [h, q])
    pages = {p.name: p.figure for p in report_pages(path)}
    for page, panel in (("constants", "across-E1"), ("loss-factors", "across-eta11")):
        a = ax(pages[page], panel)
        for m in ("glass", "carbon"):
            dot = next(ln for ln in a.get_lines() if ln.get_gid() == f"value-H-{m}")
            bar = next(ln for ln in a.get_lines() if ln.get_gid() == f"monte-carlo-H-{m}")
            assert to_rgb(bar.get_color()) == pytest.approx(mc_tint(dot.get_color()), abs=1e-12)
            assert bar.get_xdata()[0] > dot.get_xdata()[0]          # right of its own value
        colours = {to_rgb(ln.get_color()) for ln in a.get_lines()
                   if (ln.get_gid() or "").startswith("monte-carlo")}
        assert len(colours) == 2 and to_rgb("0.62") not in colours  # none grey, two apart
        legend = next(x.get_legend() for x in pages[page].axes if x.get_legend() is not None)
        from matplotlib.lines import Line2D

        keys = {to_rgb(ln.get_color()) for ln in legend.findobj(Line2D)}
        assert colours <= keys                   # each material's pale bar in the key
        assert "pale bar of the material's colour" in next(
            t.get_text() for t in legend.get_texts() if t.get_text().startswith("Monte Carlo"))


def test_constants_across_specimens_tell_a_bounded_profile_from_a_flat_one():
    """A profile bounded where the fit rejects (hybrid CM's glass G12 on its lower limit,
    rejected above 18.5 GPa) and a flat one, not rejected up to the end of its scan (glass E2
    on its upper limit, flat down to 0.9 GPa; carbon nu12 0.95 flat to 0) were the same
    dotted bar ending bare. As on the intervals page: a cap at the bound, an arrow head at
    the end of the flat one's scan pointing away from the value, and the legend says which
    is which."""
    from laminid_cli.report import constants_across_page

    at = dict(verdict="at bound — not identified", at_bound=True)
    mats = {"glass": {"E1": 58e9, "E2": 55.5e9, "G12": 5.9e6, "G13": 3e9, "G23": 3e9,
                      "nu12": 0.3},
            "carbon": {"E1": 87e9, "E2": 8e9, "G12": 4.8e9, "G13": 3e9, "G23": 3e9,
                       "nu12": 0.95}}
    row = {"name": "H", "status": "check", "intervals": {
        "glass": {"E2": dict(at, bound_side="upper", bound_limit=55.5e9, profile="flat",
                             profile_bound=None, profile_far=0.9e9),
                  "G12": dict(at, bound_side="lower", bound_limit=5.9e6, profile="bound",
                              profile_bound=18.5e9, profile_far=None)},
        "carbon": {"nu12": dict(at, bound_side="upper", bound_limit=0.95, profile="flat",
                                profile_bound=None, profile_far=0.0)}}}
    fig = constants_across_page([(row, mats, None)], "t")
    for panel, tag, marker, y in (("across-G12", "profile-cap-H-glass", "_", 18.5),
                                  ("across-E2", "profile-end-H-glass", "v", 0.9),
                                  ("across-nu12", "profile-end-H-carbon", "v", 0.0)):
        a = ax(fig, panel)
        ends = [ln for ln in a.get_lines() if (ln.get_gid() or "").startswith("profile-")]
        assert [ln.get_gid() for ln in ends] == [tag]
        assert ends[0].get_marker() == marker
        assert ends[0].get_ydata()[0] == pytest.approx(y, rel=1e-12)
        lo, hi = a.get_ylim()
        assert lo <= y <= hi                                     # in view, not off the panel
        bar = next(ln for ln in a.get_lines() if ln.get_gid() == "profile")
        assert ends[0].get_color() == bar.get_color()            # its material's
    legend = next(a.get_legend() for a in fig.axes if a.get_legend() is not None)
    assert ("values the fit does not reject (profile of a constant on a search limit);\n"
            "cap: it rejects beyond; arrow head: the end of its scan, not tried beyond"
            in [t.get_text() for t in legend.get_texts()])
    # a page of flat profiles only: the arrow head alone in the legend, no cap drawn
    only = {"name": "H", "status": "check",
            "intervals": {"carbon": row["intervals"]["carbon"]}}
    fig = constants_across_page([(only, {"carbon": mats["carbon"]}, None)], "t")
    legend = next(a.get_legend() for a in fig.axes if a.get_legend() is not None)
    assert ("values the fit does not reject (profile of a constant on a search limit);\n"
            "arrow head: the end of its scan, not tried beyond"
            in [t.get_text() for t in legend.get_texts()])
    assert not [ln for a in fig.axes for ln in a.get_lines()
                if (ln.get_gid() or "").startswith("profile-cap")]


def test_loss_factors_across_specimens_mark_those_of_a_fit_that_did_not_converge(tmp_path):
    """The loss factors of a specimen whose fit did not converge (S1.1 and S1.4 stopped by
    --max-evaluations 8: refitted at the optimiser's last point) were drawn as any others.
    Each has "nc" beside it, as on the constants' page (one held at 0: at 0), keyed in the
    legend; a converged specimen's have none."""
    from laminid_cli.batch import write_summary_csv
    from tests.test_report import _summary_rows

    h, q = _summary_rows()
    free = {"at_bound": False, "bound_side": "", "bound_limit": None}
    lf = {"eta11": {"value": 0.002, "lower": 0.0018, "upper": 0.0022,
                    "verdict": "well determined"} | free,
          "eta22": {"value": 0.0, "lower": None, "upper": None,
                    "verdict": "at bound — not identified", "at_bound": True,
                    "bound_side": "lower", "bound_limit": 0.0}}
    h["damping"] = {"carbon": lf}
    q = q | {"status": "check", "converged": False, "reason": "not_converged",
             "reasons": [{"code": "not_converged", "text": "..."}],
             "damping": {"carbon": {"eta11": dict(lf["eta11"], value=0.003),
                                    "eta22": lf["eta22"]}}}
    path = tmp_path / "summary.csv"
    write_summary_csv(path, [h, q])
    fig = {p.name: p.figure for p in report_pages(path)}["loss-factors"]
    marks = {a.get_gid(): [(t.get_gid(), t.get_text(), t.xy[1]) for t in a.texts
                           if (t.get_gid() or "").startswith("not-converged")]
             for a in fig.axes}
    assert marks["across-eta11"] == [("not-converged-Q-carbon", "nc", pytest.approx(0.3))]
    assert marks["across-eta22"] == [("not-converged-Q-carbon", "nc", 0.0)]   # H's: none
    dot = next(ln for ln in ax(fig, "across-eta11").get_lines()
               if ln.get_gid() == "value-Q-carbon")
    mark = next(t for t in ax(fig, "across-eta11").texts
                if t.get_gid() == "not-converged-Q-carbon")
    assert mark.xy[0] == dot.get_xdata()[0] and mark.get_color() == dot.get_color()
    legend = [t.get_text() for t in ax(fig, "legend").get_legend().get_texts()]
    assert ("nc: not converged (refitted at the optimiser's\nlast point, not at identified "
            "constants)") in legend


def test_a_wide_summary_draws_the_profiles_of_its_result_files(tmp_path):
    """A --wide summary.csv written before its profile columns: hybrid CM's glass G12 (on
    its lower limit, rejected above 18.5 GPa) and E2 (on its upper limit, flat down to 0.9
    GPa) were bare triangles where the long summary draws their profiles dotted, to a cap and
    to an arrow head. Where the result file is found its profile is drawn, as from the long
    one; without it, none."""
    import csv
    import re
    from types import SimpleNamespace

    import numpy as np

    from laminid_cli.batch import read_summary, write_summary_csv
    from laminid_cli.report import constants_across_page
    from tests.test_report import _summary_rows

    h = _summary_rows()[0]
    h["materials"]["glass"]["E2"] = 55.5e9
    h["intervals"]["glass"]["E2"]["bound_limit"] = 55.5e9
    write_summary_csv(tmp_path / "new.csv", [h], wide=True)
    with open(tmp_path / "new.csv", newline="") as fh:             # without those columns
        recs = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    keep = [c for c in recs[0]
            if not re.search(r" (bound_limit|profile_bound|profile_far) \[.*\]$| profile$", c)]
    assert len(recs[0]) - len(keep) == 4 * 12
    with open(tmp_path / "wide.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(recs)
    (row,) = read_summary(tmp_path / "wide.csv")
    assert row["intervals"]["glass"]["G12"]["bound_limit"] is None     # as before
    assert "profile" not in row["intervals"]["glass"]["G12"]           # no such column
    ivs = {"G12": SimpleNamespace(profile_kind="bound", profile_bound=18.5e9,
                                  profile_far=np.nan),
           "E2": SimpleNamespace(profile_kind="flat", profile_bound=np.nan,
                                 profile_far=0.9e9)}
    r = SimpleNamespace(reference={}, status=None, uncertainty=SimpleNamespace(
        get=lambda m, k: ivs.get(k) if m == "glass" else None))
    fig = constants_across_page([(row, row["materials"], r)], "t")
    for k, gid, marker, far in (("G12", "profile-cap-H-glass", "_", 18.5),
                                ("E2", "profile-end-H-glass", "v", 0.9)):
        a = ax(fig, f"across-{k}")
        line = next(ln for ln in a.get_lines() if ln.get_gid() == "profile")
        v = row["materials"]["glass"][k] / 1e9
        assert sorted(line.get_ydata()) == pytest.approx(sorted([v, far]), rel=1e-12)
        end = next(ln for ln in a.get_lines() if ln.get_gid() == gid)
        assert end.get_marker() == marker and end.get_ydata()[0] == pytest.approx(far)
    fig = constants_across_page([(row, row["materials"], None)], "t")        # no result file
    assert not [ln for a in fig.axes for ln in a.get_lines()
                if (ln.get_gid() or "").startswith("profile")]


def test_a_monte_carlo_ends_star_across_specimens_is_in_its_materials_full_colour(tmp_path):
    """The "*" on a Monte Carlo end set by trials on a search limit took its bar's pale tint
    (hybrid CM's carbon nu12, 6x6, 10 trials: a light orange star hard to make out); it is in
    its material's own colour, the bar pale."""
    from matplotlib.colors import to_rgb

    from laminid_cli.batch import write_summary_csv
    from laminid_cli.report import mc_tint
    from tests.test_report import _summary_rows

    h, q = _summary_rows()
    free = {"at_bound": False, "bound_side": "", "bound_limit": None}
    h["damping"] = {"carbon": {"eta13": {"value": 0.0077, "lower": 0.0, "upper": 0.017,
                                         "verdict": "weak", "mc_lower": 0.0,
                                         "mc_upper": 0.0102, "mc_lower_at_limit": True,
                                         "mc_upper_at_limit": False} | free}}
    path = tmp_path / "summary.csv"
    write_summary_csv(path, [h, q])
    pages = {p.name: p.figure for p in report_pages(path)}
    for page, panel in (("constants", "across-G12"), ("loss-factors", "across-eta13")):
        a = ax(pages[page], panel)
        dot = next(ln for ln in a.get_lines() if ln.get_gid() == "value-H-carbon")
        bar = next(ln for ln in a.get_lines() if ln.get_gid() == "monte-carlo-H-carbon")
        (star,) = [t for t in a.texts if t.get_gid() == "monte-carlo-H-carbon-search-limit"]
        assert star.get_text() == "*"
        assert to_rgb(star.get_color()) == to_rgb(dot.get_color())
        assert to_rgb(bar.get_color()) == pytest.approx(mc_tint(dot.get_color()), abs=1e-12)
