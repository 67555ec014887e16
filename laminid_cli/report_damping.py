"""Report page of the ply loss factors (the ``/damping`` group of a result file).

One page (A4 landscape), and a second where the table does not fit under the panels (two
materials with Monte Carlo ranges under a long status: :func:`damping_pages`):

- measured modal loss factor eta_i = 2 zeta_i of each mode (%) with +-1 standard deviation
  error bars, beside the model's sum of energy share x ply loss factor; modes left out of the
  fit (frequency weight 0) hollow;
- the strain-energy shares U_mik / U_i of each mode (%) as stacked bars, one colour per
  material term (11, 22, 12, 13, 23);
- the identified loss factors with their intervals and verdicts, fixed ones marked; with
  --monte-carlo, each free one's Monte Carlo range under its interval (each trial refitted
  the loss factors at its own constants) and, where that range set the verdict, its widths.

Every number drawn is read from the result file by the typed reader. ``laminid_cli.report`` adds the page when the
file has ``/damping`` (one-line hook); matplotlib is imported inside the functions.
"""

from __future__ import annotations

import numpy as np

A4_LANDSCAPE = (11.69, 8.27)
#: the measured and model modal loss factors: colours none of the energy terms has (C0-C4)
MEASURED_COLOR, MODEL_COLOR = "k", "0.5"
#: measured and model drawn this far (in modes) left and right of their mode, apart
MODE_OFFSET = 0.2
#: marker sizes (points) of the measured dot and the model's hollow square, and the half
#: width of the error bars' caps: wider than the dot so the bar's ends show
MEASURED_MS, MODEL_MS, ERROR_CAP_PT = 5.0, 7.0, 4.5
TERM_NAMES = {"11": "11 (fibre)", "22": "22 (transverse)", "12": "12 (in-plane shear)",
              "13": "13 (transverse shear)", "23": "23 (transverse shear)"}


def read_damping(result) -> dict | None:
    """The /damping group of a result (a path or a read :class:`ResultFile`) as the plain
    data the page draws, or None when it has none. Read by the typed reader
    (:func:`laminid_cli.resultfile.read_result`), like every other page."""
    from laminid_cli.resultfile import ResultFile, read_result

    r = result if isinstance(result, ResultFile) else read_result(result)
    if r.damping is None:
        return None
    g = r.damping
    d = {k: str(v) if isinstance(v, str) else v for k, v in g.attrs.items()}
    for key in ("value", "std", "lower", "upper", "measured_loss_factor", "measured_sigma",
                "model_loss_factor", "energy_shares", "at_bound", "used"):
        d[key] = g.data[key]
    d["labels"] = list(g.data["labels"])
    d["verdict"] = list(g.data["verdict"])
    d["share_labels"] = str(g.dataset_attrs["energy_shares"]["labels"]).split(",")
    d["specimen"] = r.plates[0].name if r.plates else ""
    # the loss factors' Monte Carlo (files before it have none)
    d["monte_carlo"] = g.monte_carlo
    d["verdict_from_monte_carlo"] = [x for x in str(g.attrs.get("verdict_from_monte_carlo",
                                                                "")).split(",") if x]
    return d


def damping_figures(result) -> list[tuple[str, object]]:
    """[("damping", Figure)] for a result (path or ResultFile) with /damping, else []; with
    ("damping-2", Figure) ... where the loss-factor table continues (:func:`damping_pages`).
    Each page ends with the result's status line, as every other page of the report."""
    from laminid_cli.report import _status_banner
    from laminid_cli.resultfile import ResultFile, read_result

    r = result if isinstance(result, ResultFile) else read_result(result)
    d = read_damping(r)
    if d is None:
        return []
    figs = damping_pages(d, banner=lambda fig: _status_banner(fig, r))
    return [("damping" if k == 0 else f"damping-{k + 1}", fig) for k, fig in enumerate(figs)]


#: the interval cell of a loss factor held at 0 by eta >= 0 (as "none — fixed" of a fixed one)
HELD_INTERVAL = "none — held at 0"


def loss_factor_rows(d: dict) -> list[list[str]]:
    """Rows of the loss-factor table (strings as drawn, %): label, value, interval, verdict
    in a few words (the advice is under the table). A loss factor held at 0 by eta >= 0 has
    no interval (:data:`HELD_INTERVAL`; a file written before kept 0 .. a one-sided upper,
    1e+06 % where the damping does not determine it: not shown either), nor has a fixed
    one."""
    from laminid_cli.intervals import width_text
    from laminid_cli.report import short_verdict
    from laminid_cli.units import number_text

    def pct(x) -> str:
        return number_text(100 * float(x), ".3f")

    rows = []
    mc = d.get("monte_carlo") or {}
    from_mc = set(d.get("verdict_from_monte_carlo") or ())
    for k, lab in enumerate(d["labels"]):
        # the ends in the value's digits (.3f), as the terminal's and the constants' tables
        interval = (HELD_INTERVAL if d["at_bound"][k]
                    else f"[{pct(d['lower'][k])}, {pct(d['upper'][k])}]")
        verdict = ("held at 0 by η ≥ 0: not identified" if d["at_bound"][k]
                   else short_verdict(d["verdict"][k]))
        if "lower" in mc and d["at_bound"][k]:
            # held at 0: its trials' range (0 up to 1e+06 % where the damping does not
            # determine it) is no more a range than its interval is; how often they held it
            # too is what they tell
            z = np.ravel(mc.get("trials_at_zero", []))
            if z.size > k and "refits" in mc:
                interval += f"\nMonte Carlo: held in {int(z[k])} of {int(mc['refits'])}"
        elif "lower" in mc:
            # the range of the loss factor refitted in each trial at its own constants
            mlo, mhi = np.ravel(mc["lower"])[k], np.ravel(mc["upper"])[k]
            zero = "*" if bool(np.ravel(mc.get("lower_at_zero", [0] * (k + 1)))[k]) else ""
            interval += f"\nMonte Carlo {pct(mlo)}{zero}–{pct(mhi)}"
            if lab in from_mc:
                value = d["value"][k]
                rel = 0.5 * (mhi - mlo) / value
                sure = 0.5 * (np.ravel(mc["inner_upper"])[k]
                              - np.ravel(mc["inner_lower"])[k]) / value
                # (the widths as the status and the terminal write them: 273x, not 27339 %)
                verdict = verdict.replace(" (Monte Carlo)", "") + (
                    f" (Monte Carlo\n±{width_text(rel)}, ±{width_text(sure)} for sure)")
        rows.append([lab, f"{100 * d['value'][k]:.3f}", interval, verdict])
    for item in filter(None, str(d.get("fixed", "")).split(",")):
        lab, value = item.rsplit("=", 1)
        rows.append([lab, f"{100 * float(value):.3f}", "none — fixed",
                     "fixed at the value given (not identified)"])
    return rows


#: under a loss-factor table with a loss factor the damping does not determine
NOT_DETERMINED_ADVICE = ("not determined: the measured damping does not pin this loss factor "
                         "down — fix it (--fix eta13=0.01 ...) or measure more modes / a thicker "
                         "plate")


def loss_factor_table(ax, head, rows, col_widths, fill: bool = False):
    """Draw the loss-factor table (rows of :func:`loss_factor_rows`, possibly with columns in
    front; the verdict is the last column, coloured as in the other report tables) on ``ax``:
    from its top, rows at the height of their lines, or with ``fill`` filling ``ax`` (its
    rows as tall as their lines, laminid_cli.report.row_heights, in their share of it).
    Returns :data:`NOT_DETERMINED_ADVICE` when a loss factor is not determined, else "": the
    caller puts it where the table cannot run over it (a long table overflows its axes)."""
    from laminid_cli.report import _verdict_color, row_heights, row_lines

    ax.axis("off")
    ax.set_gid("loss-factors")
    table = ax.table(cellText=rows, colLabels=head, loc="upper center", cellLoc="center",
                     colLoc="center", colWidths=col_widths,
                     bbox=[0, 0, 1, 1] if fill else None)
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    last = len(head) - 1
    # a row with a second line (the Monte Carlo range under an interval) is that much taller
    lines = [1] + [row_lines(row) for row in rows]
    heights = row_heights(head, rows)
    for (i, j), cell in table.get_celld().items():    # the look of the other report tables
        # filling the axes: each row its share of it (the rows of a table sized to them
        # by damping_pages come out at TABLE_ROW_IN a line); else a row of n lines n rows tall
        cell.set_height(heights[i] / sum(heights) if fill else cell.get_height() * lines[i])
        cell.set_linewidth(0.3)
        if i == 0:
            cell.set_text_props(weight="bold")
            cell.set_facecolor("0.92")
        elif j == last:
            cell.set_facecolor(_verdict_color(rows[i - 1][last].replace("held at 0",
                                                                         "at bound")))
    return _advice(head, rows)


#: the table's width on its page (in): the damping page's and the summary's tables span the
#: page but its margins (A4 landscape)
TABLE_WIDTH_IN = 0.93 * 11.69


def fit_cells(rows, col_widths, *, fontsize: float = 8.0, table_in: float = TABLE_WIDTH_IN):
    """``rows`` with each cell's lines wrapped at spaces to its column's width (``col_widths``:
    fractions of the table's width; an average glyph 0.55 em). A loss factor's label of a long
    material ("Hexcel IM7/977-2 unidirectional prepreg tape 0.135 mm.eta11"), a long specimen
    name, ran under the next cell, which hid the end that says which loss factor the row is
    (".eta1"); wrapped, the row is as tall as its lines (laminid_cli.report.row_heights)."""
    import textwrap

    chars = [max(8, int(w * table_in * 72 / (0.55 * fontsize)) - 2) for w in col_widths]
    return [[c if len(c) <= n and "\n" not in c else "\n".join(
                piece for line in c.split("\n") for piece in (
                    textwrap.wrap(line, n, break_on_hyphens=False) or [""]))
             for c, n in zip(map(str, row), chars)] for row in rows]


def _advice(head, rows) -> str:
    """:data:`NOT_DETERMINED_ADVICE` when a row's verdict (the last column) says a loss
    factor is not determined, else ""."""
    return (NOT_DETERMINED_ADVICE if any(row[len(head) - 1].startswith("not determined")
                                         for row in rows) else "")


#: height of a one-line row of the damping page's loss-factor table (in): 8-point text with
#: the air of the other report tables (a two-line row is row_heights' 1.7 of it)
TABLE_ROW_IN = 0.17
#: how much taller than their lines the rows of a page of the loss-factor table alone may
#: be to fill the page down to the status (the rows under the panels are as tall as their
#: lines)
TABLE_PAGE_STRETCH = 2.0
#: how much taller than its y-label a panel of the damping page is at the least (in): the
#: label ("share of the mode's strain energy (%)", 2.65 in at 10 points) stays within the
#: panel's height. Rows of the table that would leave the panels less continue on the next
#: page (hybrid-CM's two materials with Monte Carlo ranges under a status of 14 lines: their
#: rows, squeezed to 0.55 of their text's height, ran over each other, and the label of a
#: 1.1 in panel ran 0.3 in off the top of the page)
PANEL_AIR_IN = 0.2


#: how far under a panel's bottom edge its legend starts (points): under the tick labels and
#: the axis label ("mode") at the default 10-point type
LEGEND_DROP_PT = 34


def _below_xlabel(fig, ax):
    """The transform of a legend anchored :data:`LEGEND_DROP_PT` under ``ax``'s bottom edge.

    Why: anchored at -0.1 of the panel's height, a legend ran into the axis label "mode" of a
    shorter panel (S2.1 with Monte Carlo ranges in its table: 3 px over it), and the layout's
    margins changed with the panels' height."""
    from matplotlib.transforms import ScaledTranslation

    return ax.transAxes + ScaledTranslation(0, -LEGEND_DROP_PT / 72, fig.dpi_scale_trans)


class _Sheet:
    """A damping page laid out once before its table is drawn: its two grid rows' axes
    (``first`` over ``second``; the table's axes is one of them, or None on a page of panels
    alone) and ``room``, the height (in) the table's row can take.

    Why laid out first: the table is as tall as its rows (:data:`TABLE_ROW_IN` a line) and
    the page's margins (titles, labels, the legends under the panels, the notes over the
    table, the status at the foot) are only known once the page is laid out; constrained
    layout then keeps the ratio of the rows' axes heights exactly and their sum (the
    margins do not depend on the ratio: the legends hang a fixed distance under the panels,
    :func:`_below_xlabel`). So the page is laid out (0.15 s), measured, and the rows given
    the ratio that makes the table's axes as tall as its rows (:meth:`fit`). Before, the
    table's row had a fixed 1.25 of 4.25 of the height (a single material's 5 rows left a
    white band of 0.09 of the page), then at most 0.6 of it with its rows squeezed beyond."""

    def __init__(self, fig, gs, first, second, table_ax, panels=()):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        self.fig, self.gs, self.first, self.second = fig, gs, first, second
        self.table_ax = table_ax
        #: a page of the table alone (its axes the first row, an empty one under it)
        self.alone = table_ax is first
        if table_ax is None:
            self.room = 0.0
            return
        if not isinstance(fig.canvas, FigureCanvasAgg):
            FigureCanvasAgg(fig)
        fig.draw_without_rendering()                  # lays the page out
        self.both = first.get_position().height + second.get_position().height
        # the panels at least as tall as their y-labels (the longest), with some air
        renderer = fig.canvas.get_renderer()
        least = max((a.yaxis.label.get_window_extent(renderer).height / fig.dpi + PANEL_AIR_IN
                     for a in panels), default=0.0)
        self.room = self.both * fig.get_figheight() - least

    def fill(self) -> None:
        """Give the table's axes both rows (a page of the table alone, ``table_ax`` over an
        empty row): down to the status at the page's foot."""
        self.table_ax.set_subplotspec(self.gs[:, :])
        self.fig.delaxes(self.second)

    def fit(self, table_in: float) -> None:
        """Give the table's row ``table_in`` inches, the other row the rest."""
        want = table_in / self.fig.get_figheight()
        ratios = [self.both - want, want]
        self.gs.set_height_ratios(ratios if self.table_ax is self.second else ratios[::-1])


def _table_words(fig, ax_t, title: str, words):
    """The title of the loss-factor table on ``ax_t`` and, over the table, ``words`` (the
    advice and the result's notes on the loss factors), wrapped to the page's width: their
    text, or None without words."""
    import textwrap

    from laminid_cli.report import _wrap_width

    # the title wrapped to the page too: a long damping sigma source (fit-frf's rule, an
    # frf_file's fit) ran off both edges of the page on one line
    title = "\n".join(ln for para in title.split("\n")
                      for ln in textwrap.wrap(para, _wrap_width(fig, 9),
                                              break_on_hyphens=False) or [""])
    ax_t.set_title(title, fontsize=9)
    if not words:
        return None
    # above the table: under it, a table of two materials ran over the words
    lines = [ln for w in words for ln in textwrap.wrap(w, _wrap_width(fig, 8),
                                                        break_on_hyphens=False)]
    # 2 points over the table, which fills its axes up to their top
    note = ax_t.annotate("\n".join(lines), (0.5, 1.0), xycoords="axes fraction",
                         xytext=(0, 2), textcoords="offset points", ha="center",
                         va="bottom", fontsize=8, gid="loss-factor-note")
    ax_t.set_title(title + "\n" * len(lines), fontsize=9)
    return note


def _panels(fig, ax_m, ax_s, d) -> None:
    """The two panels of the damping page: measured vs model modal loss factor of each mode
    on ``ax_m``, the strain-energy shares on ``ax_s``."""
    from matplotlib.legend_handler import HandlerTuple

    ax_m.set_gid("modal-loss-factors")
    ax_s.set_gid("energy-shares")
    meas = np.asarray(d["measured_loss_factor"], float) * 100
    sig = np.asarray(d["measured_sigma"], float) * 100
    model = np.asarray(d["model_loss_factor"], float) * 100
    used = np.asarray(d["used"], bool)
    n = meas.size
    modes = np.arange(1, n + 1)
    ok = np.isfinite(meas)
    # measured (filled where fitted, hollow where left out), error bars +-1 sd, model beside;
    # in black and grey: the colours of the shares' panel beside are the energy terms' (blue
    # measured and red model read as "11 (fibre)" and "13 (transverse shear)"). The two
    # series sit MODE_OFFSET either side of the mode (the model's squares covered the
    # measured dots, a model that fits drawn right over them) and the error bars over the
    # dots, their caps wider than a dot (a 2 % sd is about a dot's size: under the dot it
    # did not show)
    xm, xs = modes - MODE_OFFSET, modes + MODE_OFFSET
    dot = ax_m.plot(xm[ok], meas[ok], "o", color=MEASURED_COLOR, ms=MEASURED_MS,
                    label="measured 2\u03b6 \u00b1 1 sd", zorder=3, gid="measured")[0]
    bars = ax_m.errorbar(xm[ok], meas[ok], yerr=sig[ok], fmt="none", ecolor=MEASURED_COLOR,
                         elinewidth=1.2, capsize=ERROR_CAP_PT, capthick=1.2, zorder=4)
    bars.lines[2][0].set_gid("measured-sd")
    out = ok & ~used
    if out.any():
        ax_m.plot(xm[out], meas[out], "o", mfc="white", color=MEASURED_COLOR, ms=MEASURED_MS,
                  zorder=3.5, label="measured, not fitted (weight 0)", gid="measured-unused")
    ax_m.plot(xs, model, "s", color=MODEL_COLOR, mfc="none", ms=MODEL_MS, mew=1.5,
              label="model \u03a3 share \u00d7 ply \u03b7", zorder=5, gid="model")
    if not ok.all():   # null in the specimen (fit-frf: not above the window's): said, not blank
        ax_m.plot(modes[~ok], np.zeros((~ok).sum()), "x", color=MEASURED_COLOR, ms=8, mew=1.5,
                  clip_on=False, zorder=6, gid="not-measured",
                  label="no measured damping (null)")
    ax_m.set_xlabel("mode")
    ax_m.set_ylabel("modal loss factor \u03b7 (%)")
    ax_m.set_xticks(modes)
    top = np.nanmax(np.concatenate([meas + np.nan_to_num(sig), model]))
    ax_m.set_ylim(0, 1.25 * top if np.isfinite(top) and top > 0 else 1)
    ax_m.grid(alpha=0.3)
    # the measured entry as drawn: the dot with its error bar
    handles, labels = ax_m.get_legend_handles_labels()
    handles = [(dot, bars) if h is dot else h for h in handles]
    ax_m.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0), ncol=3,
                fontsize=8, frameon=False, handler_map={tuple: HandlerTuple(ndivide=1)},
                bbox_transform=_below_xlabel(fig, ax_m))  # below, clear of the points
    ax_m.set_title("measured vs model modal loss factor")

    # stacked energy shares
    shares = np.asarray(d["energy_shares"], float) * 100
    labels = d["share_labels"]
    many = len({lab.rsplit(".", 1)[0] for lab in labels}) > 1
    bottom = np.zeros(n)
    hatches = ["", "//", "..", "xx", "\\\\"]
    for j, lab in enumerate(labels):
        mat, k = lab.rsplit(".", 1)
        name = (f"{mat} " if many else "") + TERM_NAMES.get(k, k)
        m_index = [x.rsplit(".", 1)[0] for x in labels].index(mat) // 5
        ax_s.bar(modes, shares[:, j], bottom=bottom, color=f"C{j % 5}",
                 hatch=hatches[m_index % len(hatches)], edgecolor="white", lw=0.5, label=name)
        bottom = bottom + shares[:, j]
    ax_s.set_xlabel("mode")
    ax_s.set_ylabel("share of the mode's strain energy (%)")
    ax_s.set_xticks(modes)
    ax_s.set_ylim(0, 100)
    ax_s.set_title("strain-energy shares U\u2098\u1d62\u2096 / U\u1d62 (material axes)")
    ax_s.legend(loc="upper center", bbox_to_anchor=(0.5, 0), ncol=3, fontsize=8,
                frameon=False, bbox_transform=_below_xlabel(fig, ax_s))


def _page_title(d: dict, more: str = "") -> str:
    name = d.get("specimen", "")
    return (f"{name}: damping (modal strain energy)" if name else "damping") + more


def _page_frame(d, banner, more: str, nrows: int, ncols: int, height_ratios=None):
    """A damping page's figure (A4 landscape, constrained layout) with its title
    (:func:`_page_title` + ``more``) and the result's status at its foot (``banner(fig)``),
    and the grid (``nrows`` x ``ncols``) its axes go in: (figure, gridspec)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    fig = Figure(figsize=A4_LANDSCAPE, layout="constrained")
    gs = fig.add_gridspec(nrows, ncols, height_ratios=height_ratios)
    fig.suptitle(_page_title(d, more), fontsize=11)
    if banner is not None:
        banner(fig)
    return fig, gs


def _table_axes(fig, spec):
    """The loss-factor table's axes in ``spec`` of the grid: no axis lines, gid
    "loss-factors"."""
    ax_t = fig.add_subplot(spec)
    ax_t.axis("off")
    ax_t.set_gid("loss-factors")
    return ax_t


def _panels_sheet(d, banner, table_title=None, words=()) -> _Sheet:
    """The damping page's panels over the loss-factor table's axes (titled ``table_title``,
    with ``words`` over it), laid out; without ``table_title`` the panels alone, the table
    on the next page."""
    if table_title is None:
        fig, gs = _page_frame(d, banner, "; the ply loss factors on the next page", 1, 2)
    else:
        fig, gs = _page_frame(d, banner, "", 2, 2, height_ratios=[3, 1.25])
    ax_m, ax_s = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[0, 1])    # fig.axes[:2]
    ax_t = None if table_title is None else _table_axes(fig, gs[1, :])
    _panels(fig, ax_m, ax_s, d)
    if ax_t is not None:
        _table_words(fig, ax_t, table_title, words)
    return _Sheet(fig, gs, ax_m, ax_t, ax_t, panels=(ax_m, ax_s))


#: the left and right margins of the table on a page of the table alone (fraction of the
#: page's width): about those of the table under the panels (0.037 and 0.06 on hybrid-CM's)
TABLE_PAGE_INSET = 0.04


def _table_sheet(d, banner, table_title: str, words=()) -> _Sheet:
    """A page of the loss-factor table alone (the rows the damping page has no room for):
    the table's axes at the top (titled ``table_title``, ``words`` over it), an empty row
    under it, laid out."""
    fig, gs = _page_frame(d, banner, ", continued", 2, 1, height_ratios=[1, 1])
    ax_t = _table_axes(fig, gs[0])
    rest = fig.add_subplot(gs[1], xticks=[], yticks=[])
    rest.axis("off")
    rest.set_gid("under-the-table")
    note = _table_words(fig, ax_t, table_title, words)
    if note is not None:    # as wide as the page: the layout narrowed the table to it
        note.set_in_layout(False)        # (the title's empty lines keep its height)
    # the table inset from the page's edges as under the panels (an axes without its axis
    # lines gets no margin: the table ran from edge to edge)
    engine = fig.get_layout_engine()
    _, bottom, _, height = engine.get()["rect"]
    engine.set(rect=(TABLE_PAGE_INSET, bottom, 1 - 2 * TABLE_PAGE_INSET, height))
    return _Sheet(fig, gs, ax_t, rest, ax_t)


def _material_ends(rows) -> list[int]:
    """The numbers of rows after which the material of the rows' labels changes, and the
    last: where the table may continue on the next page without splitting a material."""
    mats = [row[0].rsplit(".", 1)[0] for row in rows]
    return [k for k in range(1, len(rows) + 1) if k == len(rows) or mats[k] != mats[k - 1]]


def damping_pages(d: dict, banner=None) -> list:
    """The damping page of :func:`read_damping`'s ``d`` and, when its loss-factor table does
    not fit under the panels with its rows as tall as their lines (:data:`TABLE_ROW_IN`) and
    the panels as tall as their y-labels (:data:`PANEL_AIR_IN`), the table on the next page,
    whole where it fits on a page of its own (the first page the panels alone); else the
    pages it continues on ("ply loss factors (continued)", the header repeated; a page takes
    whole materials where it can, and the page of the table's end the advice and notes over
    the table; when not one material fits under the panels, the table starts on the next
    page). On a page of the table alone its rows take the room down to the status, up to
    :data:`TABLE_PAGE_STRETCH` times their lines' height. ``banner(fig)`` puts the result's
    status at the foot of each (laminid_cli.report._status_banner) before its rows are sized
    to the room that leaves."""
    from laminid_cli.report import row_heights

    conf = float(d.get("confidence", 0.95)) * 100
    head = ["loss factor", "value (%)", f"{conf:.0f} % interval (%)", "verdict"]
    widths = [0.28, 0.14, 0.22, 0.36]
    rows = fit_cells(loss_factor_rows(d), widths)
    s2 = float(d.get("s2", np.nan))
    mc = d.get("monte_carlo") or {}
    key = (f"\nMonte Carlo: {int(mc['refits'])} trials refitted the loss factors at their own "
           f"constants ({conf:.0f} % of them in the range; * an end at the bound 0)"
           if "refits" in mc else "")
    title = (f"ply loss factors, modal strain energy method (s\u00b2 = {s2:.3g}, "
             f"{int(d.get('dof', 0))} degrees of freedom; damping sigma: "
             f"{d.get('sigma_source', '') or '-'})" + key)
    # the result's notes on the loss factors (a free one leaning on an elastic constant the
    # modes do not determine is known less well than its interval says: the terminal's note)
    notes = str(d.get("notes", "") or "").strip()
    words = [w for w in (_advice(head, rows), f"note: {notes}" if notes else "") if w]

    def height(part):
        return TABLE_ROW_IN * sum(row_heights(head, part))

    def draw(sheet, part):
        loss_factor_table(sheet.table_ax, head, part, widths, fill=True)
        # on a page of the table alone its rows take the room down to the status, up to
        # TABLE_PAGE_STRETCH times their lines' height (at that height they left 0.22 of the
        # page blank under hybrid-CM's 14-line status)
        if not sheet.alone:                            # under the panels
            sheet.fit(height(part))
        elif TABLE_PAGE_STRETCH * height(part) < sheet.room:
            sheet.fit(TABLE_PAGE_STRETCH * height(part))
        else:
            sheet.fill()
        return sheet.fig

    # pages of the table alone laid out and measured but not drawn on (the table did not fit
    # there), by (title, words): the next page of the same title and words is that one, not
    # laid out again (the first page of a table that starts on the next page is the whole
    # table's page measured below; each page after the first continuation is the one the
    # page before was measured on)
    measured: dict = {}

    def table_sheet(top, words=()):
        return measured.pop((top, tuple(words)), None) or _table_sheet(d, banner, top, words)

    def spare(sheet, top, words=()):
        measured[(top, tuple(words))] = sheet

    sheet = _panels_sheet(d, banner, title, words)
    if height(rows) <= sheet.room:                   # the page as it always was
        return [draw(sheet, rows)]
    # too long for the room under the panels: whole on a page of its own where it fits there,
    # the panels alone on the first page (split there, hybrid-CM's carbon rows left 0.54 of
    # their page blank even at TABLE_PAGE_STRETCH; a table is one table to read)
    alone = table_sheet(title, words)
    if height(rows) <= alone.room:
        return [_panels_sheet(d, banner).fig, draw(alone, rows)]
    spare(alone, title, words)
    nxt = "\ncontinued on the next page" + (", with the notes on the loss factors" if words
                                             else "")
    sheet = _panels_sheet(d, banner, title + nxt)
    k = max((e for e in _material_ends(rows)[:-1] if height(rows[:e]) <= sheet.room),
            default=0)
    if k == 0:
        figs = [_panels_sheet(d, banner).fig]
    else:
        figs = [draw(sheet, rows[:k])]
    rest = rows[k:]
    while rest:
        top = title if k == 0 and len(figs) == 1 else "ply loss factors (continued)" + key
        sheet = table_sheet(top, words)
        if height(rest) <= sheet.room:
            figs.append(draw(sheet, rest))
            break
        spare(sheet, top, words)
        sheet = table_sheet(top + nxt)
        ends = [e for e in _material_ends(rest)[:-1] if height(rest[:e]) <= sheet.room] or \
            [e for e in range(1, len(rest)) if height(rest[:e]) <= sheet.room] or [1]
        figs.append(draw(sheet, rest[:max(ends)]))
        rest = rest[max(ends):]
    return figs


# ----------------------------------------------------------------------------------------------
# batch summary: the loss factors across specimens

#: rows of the loss-factor table of a batch summary on one page
SUMMARY_TABLE_ROWS = 26


def summary_loss_factors(row) -> dict | None:
    """The loss factors of one batch-summary row (its ``damping``, SI, as
    :func:`laminid_cli.batch.damping_of_file` writes it and ``read_summary`` reads it back) as
    the dict :func:`loss_factor_rows` draws; None when the row has none."""
    from laminid_cli.damping import LOSS_NAMES

    per = row.get("damping") or {}
    d: dict = {"labels": [], "value": [], "lower": [], "upper": [], "at_bound": [],
               "verdict": []}
    fixed = []
    for mat, terms in per.items():
        for name in LOSS_NAMES:
            e = terms.get(name)
            if e is None:
                continue
            verdict = str(e.get("verdict") or "")
            if verdict == "fixed":
                fixed.append(f"{mat}.{name}={float(e['value'])!r}")
                continue
            d["labels"].append(f"{mat}.{name}")
            d["verdict"].append(verdict)
            # (a long summary.csv written before the bound columns: the verdict says it)
            d["at_bound"].append(bool(e.get("at_bound")) or verdict.startswith("at bound"))
            for key in ("value", "lower", "upper"):
                d[key].append(np.nan if e.get(key) is None else float(e[key]))
    if not d["labels"] and not fixed:
        return None
    for key in ("value", "lower", "upper"):
        d[key] = np.asarray(d[key], float)
    d["at_bound"] = np.asarray(d["at_bound"], bool)
    d["fixed"] = ",".join(fixed)
    return d


def _confidence_words(confidence) -> str:
    return f"{100 * confidence:.0f} % " if confidence else ""


def loss_factors_across_page(rows, title: str, confidence: float | None = None):
    """One panel per loss factor (eta11 ... eta23, %): each specimen of the summary on the x
    axis, the materials of one specimen side by side, each with the doubt the summary gives
    it, in the marks of the constants' page: interval bar, hollow "?" when not determined by
    the damping, a hollow triangle at 0 without a bar when held at 0 by eta >= 0 (no
    interval: :func:`loss_factor_rows`), a grey square when fixed (--fix); with a Monte Carlo
    (each trial refitted the loss factors at its own constants) its range beside the
    interval, a pale bar of the material's colour."""
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.lines import Line2D

    from laminid_cli.damping import LEANS_WORDS, TERMS, leans_on
    from laminid_cli.report import (FIXED_COLOR, NOT_CONVERGED_MARK, _clipped_bar, _figure,
                                    _footer, _row_check, axis_names, mc_tint, specimen_labels,
                                    style_across_panel)

    rows = [row for row in rows if row.get("damping")]
    names = specimen_labels(rows)
    ticks, shortened = axis_names(names)
    materials: list[str] = []
    for row in rows:
        materials += [m for m in row["damping"] if m not in materials]
    fig = _figure()
    fig.suptitle(f"{title}: ply loss factors across specimens (modal strain energy method)",
                 fontsize=11)
    gs = fig.add_gridspec(2, 3)
    axes = [fig.add_subplot(gs[i, j]) for i, j in ((0, 0), (0, 1), (0, 2), (1, 0), (1, 1))]
    nm = len(materials)
    width = min(0.22, 0.7 / max(nm, 1))
    offsets = {m: (c - (nm - 1) / 2) * width for c, m in enumerate(materials)}
    kinds: set[str] = set()
    #: {(specimen, the constants it leans on): [its loss factors whose interval is too narrow]}
    leaning: dict[tuple[str, str], list[str]] = {}
    has_mc = has_mc_limit = has_nc = False
    on_top = dict(zorder=6, clip_on=False)
    for ax, k in zip(axes, TERMS):
        name = f"eta{k}"
        ax.set_gid(f"across-{name}")
        vals, loose, bars = [], [], []
        for c, m in enumerate(materials):
            color = f"C{c % 10}"
            for i, (label, row) in enumerate(zip(names, rows)):
                e = row["damping"].get(m, {}).get(name)
                if e is None:
                    continue
                xi = i + offsets[m]
                v = 100 * float(e["value"])
                verdict = str(e.get("verdict") or "")
                lo = np.nan if e.get("lower") is None else 100 * float(e["lower"])
                hi = np.nan if e.get("upper") is None else 100 * float(e["upper"])
                tag = f"{label}-{m}"
                mlo, mhi = (100 * float(e[key]) if e.get(key) is not None else np.nan
                            for key in ("mc_lower", "mc_upper"))
                if verdict != "fixed" and np.isfinite(mlo) and np.isfinite(mhi):
                    has_mc = True
                    # "*" on an end set by refits held at 0, as the terminal and the result's
                    # damping page mark it (the bound's end, not the data's)
                    limits = (bool(e.get("mc_lower_at_limit")), bool(e.get("mc_upper_at_limit")))
                    has_mc_limit = has_mc_limit or any(limits)
                    bars.append((xi + 0.55 * width, mlo, mhi, color, f"monte-carlo-{tag}",
                                 limits, "-"))
                    loose.append(mhi)
                at_bound = bool(e.get("at_bound")) or verdict.startswith("at bound")
                if "not_converged" in _row_check(row, None):
                    # refitted at the optimiser's last point, not at identified constants: as
                    # on the constants' page (S1.1 and S1.4 stopped by --max-evaluations 8,
                    # their loss factors drawn as any others)
                    has_nc = True
                    ax.annotate(NOT_CONVERGED_MARK, (xi, 0.0 if at_bound else v),
                                xytext=(4, -10 if v > 0 and not at_bound else 3),
                                textcoords="offset points", fontsize=7, color=color,
                                weight="bold", annotation_clip=False,
                                gid=f"not-converged-{tag}")
                if verdict == "fixed":
                    ax.plot([xi], [v], "s", ms=6, color=FIXED_COLOR, mfc="w", mew=1.3,
                            gid=f"fixed-{tag}", **on_top)
                    kinds.add("fixed")
                    vals.append(v)
                    continue
                if at_bound:
                    ax.plot([xi], [0.0], "v", ms=7, color=color, mfc="w", mew=1.3,
                            gid=f"at-bound-{tag}", **on_top)
                    kinds.add("at bound")
                    continue
                undetermined = verdict.startswith("not")
                # an interval too narrow (damping.VERDICT_LEANS): its energy share rests on a
                # constant the modes did not determine, taken as exact; a half-filled dot and a
                # dashed bar, where a plain dot read as identified to its interval
                leans = not undetermined and LEANS_WORDS in verdict
                if leans:
                    ax.plot([xi], [v], "o", ms=6, color=color, fillstyle="left", mfc=color,
                            markerfacecoloralt="w", gid=f"leans-{tag}", **on_top)
                    kinds.add("leans")
                    on = leans_on(verdict)
                    leaning.setdefault((label, on), []).append(f"{m}.{name}")
                else:
                    ax.plot([xi], [v], "o", ms=6, color=color,
                            mfc="w" if undetermined else color, gid=f"value-{tag}", **on_top)
                vals.append(v)
                if leans:
                    vals += [lo, hi, mlo, mhi]
                elif undetermined:
                    ax.annotate("?", (xi, v), xytext=(4, 2), textcoords="offset points",
                                fontsize=9, color=color, weight="bold")
                    kinds.add("undetermined")
                    loose.append(hi)
                else:
                    kinds.add("identified")
                    vals += [lo, hi, mlo, mhi]           # (the Monte Carlo's NaN: none)
                if np.isfinite(lo) or np.isfinite(hi):
                    bars.append((xi, lo, hi, color, f"interval-{tag}", (False, False),
                                 "--" if leans else "-"))
        # the panel spans the identified values and their intervals; an interval of a loss
        # factor not determined runs off it with an arrow rather than squash
        # the others (as on the constants' page); from 0: a loss factor is >= 0
        finite = [t for t in vals if np.isfinite(t)]
        top = max(finite) if finite and max(finite) > 0 else \
            max([t for t in loose if np.isfinite(t)], default=1.0)
        ymax = 1.15 * top if top > 0 else 1.0
        ax.set_ylim(0.0, ymax)
        for xi, lo, hi, color, gid, limits, ls in bars:
            _clipped_bar(ax, name, xi, lo, hi, 0.0, ymax, color,
                         lw=2.2 if gid.startswith("monte-carlo") else 1.2, gid=gid,
                         marks=limits, ls=ls, pale=gid.startswith("monte-carlo"))
        style_across_panel(ax, f"\u03b7{k} (%)", ticks)
        ax.set_ylabel("loss factor (%)", fontsize=8)
    handles = {m: Line2D([], [], ls="none", marker="o", ms=6, color=f"C{c % 10}")
               for c, m in enumerate(materials)}
    grey = "0.3"
    marks = {
        "identified": (Line2D([], [], ls="-", marker="o", ms=6, color=grey, lw=1.2),
                       "identified (well determined / weak), with its interval"),
        "undetermined": (Line2D([], [], ls="-", marker="o", ms=6, color=grey, mfc="w", lw=1.2),
                         "?: not determined by the damping (interval too wide)"),
        "leans": (Line2D([], [], ls="--", marker="o", ms=6, color=grey, fillstyle="left",
                         markerfacecoloralt="w", lw=1.2),
                  "interval too narrow: its energy share leans on\na constant the modes do not "
                  "determine (named below)"),
        "at bound": (Line2D([], [], ls="none", marker="v", ms=7, color=grey, mfc="w"),
                     "held at 0 by \u03b7 \u2265 0: not identified, no interval"),
        "fixed": (Line2D([], [], ls="none", marker="s", ms=6, color=FIXED_COLOR, mfc="w"),
                  "fixed at the value given (--fix): not identified")}
    for kind in ("identified", "leans", "undetermined", "at bound", "fixed"):
        if kind in kinds:
            h, text = marks[kind]
            handles[text] = h
    if has_mc:
        # (the pale bar of each material's colour, as drawn)
        handles["Monte Carlo range (each trial refits\nthe loss factors at its own constants):"
                "\npale bar of the material's colour, right of its value"
                + ("\n*: end set by refits held at 0 (\u03b7 \u2265 0),\nnot by the data"
                   if has_mc_limit else "")] = tuple(
                       Line2D([], [], color=mc_tint(f"C{c % 10}"), lw=2.2)
                       for c in range(len(materials)))
    if has_nc:
        handles[f"{NOT_CONVERGED_MARK}: not converged (refitted at the optimiser's\nlast "
                "point, not at identified constants)"] = Line2D(
                    [], [], ls="none", ms=10, color=grey,
                    marker=rf"$\mathrm{{{NOT_CONVERGED_MARK}}}$")
    ax_leg = fig.add_subplot(gs[1, 2])             # the sixth cell: clear of the panels
    ax_leg.axis("off")
    ax_leg.set_gid("legend")
    ax_leg.legend(list(handles.values()), list(handles), loc="center", fontsize=8,
                  handler_map={tuple: HandlerTuple(ndivide=None)},
                  title=f"colour: material; bars: {_confidence_words(confidence)}confidence "
                        "interval\nof the summary (arrow: runs off the panel)",
                  title_fontsize=8, frameon=False)
    _footer(fig, "The intervals count the noise of the measured modal damping; the strain-"
            "energy shares are computed with the identified elastic constants, taken as exact"
            + (" (the Monte Carlo ranges count the free constants' doubt too)" if has_mc
               else "") + ". Measured vs model damping of each mode and the energy shares: the damping page of "
            "each result's report (laminid report <result>.h5)."
            + "".join(f"\n{spec}: {', '.join(etas)} {'leans' if len(etas) == 1 else 'lean'} on "
                      f"{on}, not determined by the modes: interval too narrow"
                      for (spec, on), etas in leaning.items())
            + (f"\n{shortened}" if shortened else ""), color="0.25")
    return fig


def loss_factor_table_pages(rows, title: str, confidence: float | None = None) -> list:
    """The loss factors of every specimen of a summary as the table of a result's damping
    page (:func:`loss_factor_rows`, verdicts in the same words and colours), a specimen
    column in front; :data:`SUMMARY_TABLE_ROWS` lines a page."""
    from laminid_cli.report import _figure, _footer, row_heights, specimen_labels

    rows = [row for row in rows if row.get("damping")]
    table = []
    for label, row in zip(specimen_labels(rows), rows):
        d = summary_loss_factors(row)
        if d is not None:
            table += [[label] + r for r in loss_factor_rows(d)]
    head = ["specimen", "loss factor", "value (%)",
            f"{_confidence_words(confidence)}interval (%)".capitalize()
            if not confidence else f"{100 * confidence:.0f} % interval (%)", "verdict"]
    widths = [0.14, 0.26, 0.1, 0.16, 0.34]
    table = fit_cells(table, widths)
    # SUMMARY_TABLE_ROWS one-line rows a page: a row wrapped to more lines counts as more
    # (row_heights)
    chunks: list[list] = [[]]
    filled = 0.0                             # the heights of the rows on the page so far
    for row, h in zip(table, row_heights(head, table)[1:]):
        if chunks[-1] and filled + h > SUMMARY_TABLE_ROWS:
            chunks.append([])
            filled = 0.0
        chunks[-1].append(row)
        filled += h
    figs = []
    for n, chunk in enumerate(chunks, start=1):
        fig = _figure()
        more = f" ({n}/{len(chunks)})" if len(chunks) > 1 else ""
        fig.suptitle(f"{title}: ply loss factors of each specimen{more}", fontsize=11)
        ax = fig.subplots()
        advice = loss_factor_table(ax, head, chunk, widths)
        if advice:
            _footer(fig, advice, gid="loss-factor-note")
        figs.append(fig)
    return figs


def summary_damping_pages(rows, title: str, confidence: float | None = None) -> list:
    """[(name, Figure)] of the loss factors of a batch summary: across specimens, then the
    table; [] when no row has loss factors."""
    if not any(row.get("damping") for row in rows):
        return []
    pages = [("loss-factors", loss_factors_across_page(rows, title, confidence))]
    figs = loss_factor_table_pages(rows, title, confidence)
    pages += [(f"loss-factor-table{'' if k == 0 else f'-{k + 1}'}", f)
              for k, f in enumerate(figs)]
    return pages
