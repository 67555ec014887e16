"""Report figures of an identification result or of a batch summary (matplotlib, Agg).

The result file is read once by the typed reader :func:`laminid_cli.resultfile.read_result`;
every number drawn comes from it. Pages of a single-plate result, each a matplotlib Figure:

1. summary: the result's status and reasons; the constants with their interval (confidence
   level from the file), verdict, initial and reference value; a table of measured vs model
   frequency per mode; the residuals (measured - model)/measured*100 as bars with the RMS;
   notes, with the Monte Carlo's trial counts after the intervals' line where it has one;
2. intervals (when the file has ``/uncertainty``): one panel per constant in its own unit
   (GPa, 1) and on its own scale, with the verdict bands (well determined / weak, the file's
   thresholds), the reference value, and arrows where an interval runs off the panel; a
   modulus whose numbers span more than a decade on a log axis (:func:`wants_log_axis`),
   G13 and G23 on one scale (:func:`panel_scales`), log ones over the same decades;
3. mode shapes: w0 of each paired model mode (filled contours of w/max|w|, nodal lines), the
   same size on every page, with the MAC against the *initial* model's mode the measurement
   was first paired with (the result holds no measured shapes: frequencies only);
4. optimisation history: objective, RMS residual and free constants / initial value, on log
   scales, constants at a bound marked;
5. sensitivities: heat map of d ln f_i / d ln P_j at the optimum;
6. pages of :data:`EXTRA_PAGES` (hook for other page makers, e.g. damping);
7. FRFs with their RFP fit and coherence, when the specimen took its frequencies from an FRF
   file (``measured.frf_file``) or one is given.

A joint result ("laminid-joint-result") gives the shared constants first (summary without the
frequency table, intervals, history), then per plate its frequencies, mode shapes and
sensitivities. A batch summary (summary.csv/.json) gives the constants across specimens, the
materials of one specimen side by side, and the RMS residuals.

matplotlib is imported inside the functions (Agg backend forced), so importing this module is
cheap; no numerical module imports it.
"""

from __future__ import annotations

import functools
import logging
import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laminid_cli.atomic import atomic_path
from laminid_cli.errors import LaminidError
from laminid_cli.intervals import (HELD_BY_PRIOR, VERDICT_AT_BOUND, VERDICT_FIXED,
                                   VERDICT_NOT, WEAK, WELL_DETERMINED, spread_sentence)
from laminid_cli.resultfile import (CONSTANTS, ResultFile, bound_statement, profile_kind,
                                   read_result)
from laminid_cli.units import constant_text, gpa_text, number_text, significant_text

log = logging.getLogger(__name__)

REPORT_SUFFIXES = (".pdf", ".png")
MODES_PER_PAGE = 12
A4_LANDSCAPE = (11.69, 8.27)
UNDETERMINED = "not determined"
BAND_COLORS = ("#b9dfb9", "#f3e0a6")      # well determined, weak
#: the key of a reference drawn as a point: one value, which the specimen file gave without
#: an uncertainty (a range [low, high] is drawn as a bar); a bare point read as exact
REFERENCE_POINT_WORDS = "reference (no uncertainty given)"
REFERENCE_POINT_NOTE = ("reference without a range: the specimen file's reference block gives "
                        "one value and no uncertainty (words in its source aside); a [low, "
                        "high] there would be drawn as a range")


class ReportError(LaminidError):
    """A report cannot be made: unreadable input, unsupported output type (exit code 2)."""


@dataclass
class Page:
    """One report page: a short name ("summary", "modes-1", ...) and its Figure."""

    name: str
    figure: object


def _figure(size=A4_LANDSCAPE):
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    return Figure(figsize=size, layout="constrained")


def _gpa(key: str, value: float) -> float:
    return value if key == "nu12" else value / 1e9


def _unit(key: str) -> str:
    """Display unit: GPa for moduli, "–" for the dimensionless nu12."""
    return "–" if key == "nu12" else "GPa"


def fmt_value(key: str, value) -> str:
    """A constant in its display unit (GPa for moduli, plain nu12) in the terminal's digits
    (:func:`laminid_cli.units.constant_text`: "162.92", "0.00595", "0.177", "2.01e+54"), so a
    number reads the same on the page as in ``laminid identify``/``show``; "∞", or "—" for
    NaN/None."""
    if value is None or np.isnan(value):
        return "—"
    if np.isinf(value):
        return "∞" if value > 0 else "−∞"
    return constant_text(key, value)


def fmt_reference(key: str, ref) -> str:
    """A reference ``(low, high)`` (SI, as :attr:`ResultFile.reference` holds it) in the
    display unit: one value when low == high, else the range "120.0–150.0"."""
    low, high = ref
    if low == high:
        return fmt_value(key, low)
    return f"{fmt_value(key, low)}–{fmt_value(key, high)}"


def reference_diff(value: float, ref) -> float | None:
    """(value − reference) / |reference| of an identified value against a reference ``(low,
    high)``: for a range, 0 inside it and else against its nearer end (how far the value is
    from what the other test allows); None where that end is 0 (no relative difference)."""
    low, high = ref
    if low < high and low <= value <= high:
        return 0.0
    end = low if value < low else high
    return (value - end) / abs(end) if end else None


def short_verdict(text: str) -> str:
    """The verdict in a few words ("not determined by these modes — fix it ..." -> "not
    determined"; "at bound — not identified" -> "at bound, not identified")."""
    if text.startswith("at bound"):
        return "at bound, not identified"
    if text.startswith("not determined"):
        # VERDICT_NOT "<phrase> — <advice>", with " (Monte Carlo)" after the phrase and
        # " (held by the prior)" after the advice where they apply; a loss factor's verdict
        # (damping.VERDICT_NOT_DAMPING) has its own phrase and advice
        from laminid_cli.damping import VERDICT_NOT_DAMPING

        phrase, _, advice = VERDICT_NOT.partition(" — ")
        head, _, tail = text.partition(" — ")
        if not head.startswith(phrase):
            phrase = VERDICT_NOT_DAMPING.partition(" — ")[0]
        return (UNDETERMINED + head[len(phrase):]
                + (tail[len(advice):] if tail.startswith(advice) else ""))
    return text


#: an interval whose ends differ by more than this factor carries no information (a modulus
#: interval on ln P with a huge standard deviation: "[1e-30, 5e+30] GPa")
UNINFORMATIVE_RATIO = 1e3


def bound_words(iv) -> str:
    """Where a constant at its bound stopped: "none — on lower search limit" (from the file's
    bound_side; an older file's statement when the side is not stored). A constant at a bound
    has no interval: the value shown beside it is the limit, not a confidence bound."""
    side = iv.bound_side or bound_statement(iv.bound_text)[0]
    words = f"none — on {side} search limit" if side else "none — on a search limit"
    pb = getattr(iv, "profile_bound", np.nan)
    if np.isfinite(pb):
        sign = "<" if pb > iv.bound_limit or side == "lower" else ">"
        words += f"\nprofile: {sign} {fmt_value(iv.constant, pb)}"
    elif iv.profile_kind == "flat":
        words += "\nprofile: flat" + _flat_to(iv)
    return words


def _flat_to(iv) -> str:
    """Where a flat profile ended, the end of its scan, in the display unit
    (" to 18.50"); empty for a file that does not record it."""
    far = getattr(iv, "profile_far", np.nan)
    return f" to {fmt_value(iv.constant, far)}" if np.isfinite(far) else ""


def is_uninformative(k: str, lo: float, hi: float) -> bool:
    return k != "nu12" and lo > 0 and np.isfinite(hi) and hi / lo > UNINFORMATIVE_RATIO


def interval_text(k: str, iv) -> str:
    """The interval of a constant as a table cell: "[lo, hi]" in its display unit; "none — on
    lower search limit" for a constant at its bound; an interval whose ends are more than
    UNINFORMATIVE_RATIO apart (log-space modulus intervals only) gets a second line saying
    that it carries no information."""
    if iv is None:
        return "—"
    if iv.at_bound:
        return bound_words(iv)
    lo, hi = iv.lower, iv.upper
    text = f"[{fmt_value(k, lo)}, {fmt_value(k, hi)}]"
    if is_uninformative(k, lo, hi):
        text += "\nno information"
    return text


def fixed_words(r: ResultFile, m: str, k: str, width: int = 0) -> str | None:
    """Why constant ``k`` of material ``m`` was not identified, or None when it is free:
    "fixed because undetermined (half-width was ±109 %)" (``--fix-undetermined``, with the
    first run's relative half-width) or "fixed at its initial value (not identified)"."""
    lab = f"{m}.{k}"
    u = r.uncertainty
    fixed = (u is not None and lab in u.fixed) or k not in r.free.get(m, CONSTANTS)
    if not fixed or (u is not None and u.get(m, k) is not None):
        return None
    if u is not None and lab in u.fixed_undetermined:
        width = getattr(u, "fixed_widths", {}).get(lab)
        if width is not None:                                 # the run that had it fixed
            run = f" in run {width[2]}" if width[2] > 1 else ""
            if width[1].startswith("at bound"):
                return "fixed: it was at a search limit" + (f" ({run.strip()})" if run else "")
            if np.isfinite(width[0]):
                return f"fixed because undetermined (half-width was {_pct(width[0])}{run})"
        # older files: the first run's half-width is the one that had it fixed only where
        # that run left it undetermined; a constant fixed in a later round was undetermined there
        rel, verdict = u.before_fixing.get(lab, (np.nan, ""))
        if not np.isfinite(rel):
            return "fixed because undetermined"
        if verdict.startswith("not"):
            return f"fixed because undetermined (half-width was {_pct(rel)})"
        return f"fixed because undetermined in a later run (first run {_pct(rel)})"
    return "fixed at its initial value (not identified)"


def _pct(rel: float) -> str:
    """A relative half-width as the terminal writes it: "±11 %", "±41x" beyond 10."""
    if not np.isfinite(rel):
        return "±?"
    return f"±{rel:.0f}x" if rel >= 10 else f"±{100 * rel:.0f} %"


@dataclass
class MonteCarloRange:
    """The Monte Carlo range of one constant (SI): its ends, the width for sure (NaN where the
    file has none), and whether trials on a limit of the search set an end."""

    lower: float
    upper: float
    inner_lower: float = np.nan
    inner_upper: float = np.nan
    lower_at_limit: bool = False
    upper_at_limit: bool = False

    def rel(self, value: float) -> tuple[float, float]:
        """(relative half-width of the range, of the width for sure) about ``value``."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return (0.5 * (self.upper - self.lower) / abs(value),
                    0.5 * (self.inner_upper - self.inner_lower) / abs(value))


def monte_carlo_range(u, iv) -> MonteCarloRange | None:
    """The Monte Carlo range of a free constant from /uncertainty/monte_carlo, or None."""
    mc = (u.monte_carlo or {}) if u is not None else {}
    if iv is None or "lower" not in mc or "upper" not in mc:
        return None
    j = [x.label for x in u.intervals].index(iv.label)
    lo, hi = np.ravel(mc["lower"]), np.ravel(mc["upper"])
    if j >= lo.size or j >= hi.size:
        return None

    def at(key, default=np.nan):
        a = np.ravel(mc.get(key, ()))
        return a[j] if j < a.size else default
    return MonteCarloRange(float(lo[j]), float(hi[j]), float(at("inner_lower")),
                           float(at("inner_upper")), bool(at("lower_at_bound", 0)),
                           bool(at("upper_at_bound", 0)))


def mc_end_text(k: str, value: float) -> str:
    """An end of a Monte Carlo range in the display unit, in the digits of the terminal's
    Monte Carlo table (4 significant: "8.685", "0.01025"; units.significant_text)."""
    return fmt_value(k, value) if not np.isfinite(value) else significant_text(k, value, 4)


def monte_carlo_text(k: str, rng: MonteCarloRange, value: float) -> tuple[str, str]:
    """("0.01025*–4.894", "±50 %, ±11 % for sure") of a Monte Carlo range about ``value``
    (display unit; "*": an end set by trials on a search limit)."""
    ends = (f"{mc_end_text(k, rng.lower)}{'*' if rng.lower_at_limit else ''}–"
            f"{mc_end_text(k, rng.upper)}{'*' if rng.upper_at_limit else ''}")
    rel, sure = rng.rel(value)
    widths = _pct(rel) + (f", {_pct(sure)} for sure" if np.isfinite(sure) else "")
    return ends, widths


#: the colour of a CHECK status and of other warnings drawn on a page
CHECK_COLOR = "#b35900"


def status_line(r: ResultFile) -> tuple[str, str]:
    """(headline, colour) of the result's status; files without one say so."""
    if r.status is None:
        return (f"status not recorded (schema version {r.schema_version} file); optimizer: "
                f"{r.optimizer_status}", "0.35")
    if r.status.status == "ok":
        return "status: OK", "#1a7f37"
    if not r.status.reasons:
        return "status: CHECK — no reason given", CHECK_COLOR
    lines = [f"[{x.code}] {x.text}" for x in r.status.reasons]
    return "status: CHECK — " + "\n".join(lines), CHECK_COLOR


def _title(r: ResultFile, plate=None, what: str = "") -> str:
    state = "converged" if r.converged else "NOT CONVERGED"
    name = plate.name if plate is not None else " + ".join(p.name for p in r.plates)
    rms = plate.frequencies.rms_residual_percent if plate is not None else r.rms_residual_percent
    mesh = (plate or r.plates[0]).mesh
    head = f"{name}{': ' + what if what else ''}"
    return (f"{head}\n{r.optimizer} {state}, RMS residual {rms:.3f} %, {r.evaluations} "
            f"evaluations, mesh {mesh[0]}x{mesh[1]}")


def _wrap_width(fig, fontsize: float, bold: bool = False) -> int:
    """Characters of a line of text across the page (average glyph width 0.55 em, bold
    0.62 em, with a margin)."""
    return int(fig.get_figwidth() * 72 * 0.97 / ((0.62 if bold else 0.55) * fontsize))


def _footer(fig, text: str, *, color="k", weight="normal", fontsize=8.5, gid=None) -> None:
    """Lines of text under the page (paragraphs separated by newlines, each wrapped to the
    page width), with room kept free by the layout."""
    width = _wrap_width(fig, fontsize, weight == "bold")
    lines = [ln for para in text.split("\n")
             for ln in textwrap.wrap(para, width, break_on_hyphens=False,
                                     subsequent_indent="    ")]
    h = (0.006 + 0.021 * len(lines)) * fontsize / 8.5
    engine = fig.get_layout_engine()
    _, bottom, _, height = engine.get()["rect"]
    engine.set(rect=(0, h, 1, bottom + height - h))      # the top as set (_title_under)
    fig.text(0.01, 0.004, "\n".join(lines), fontsize=fontsize, color=color, ha="left",
             va="bottom", weight=weight, gid=gid)


def _status_banner(fig, r: ResultFile) -> None:
    text, color = status_line(r)
    _footer(fig, text, color=color, weight="bold", gid="status")


def status_corner(fig, r: ResultFile) -> None:
    """The status in one short line at the page's top right, for a page without the status
    text (its codes; the words are on page 1). Where the page's title would reach under it,
    the title moves down a line (:func:`_title_under`)."""
    if any(t.get_gid() == "status" for t in [*fig.texts, *(t for a in fig.axes
                                                           for t in a.texts)]):
        return
    text, color = status_line(r)                     # the words and colour of page 1's
    if r.status is None:
        text = "status not recorded"
    elif r.status.status != "ok":
        codes = ", ".join(x.code for x in r.status.reasons) or "no reason given"
        text = f"status: CHECK ({codes}; see page 1)"
    # wider than the page (a narrow figure, never A4 with every code): lines of codes
    text = "\n".join(textwrap.wrap(text, _wrap_width(fig, 8, bold=True),
                                   break_on_hyphens=False))
    status = fig.text(0.995, 0.995, text, ha="right", va="top", fontsize=8, color=color,
                      weight="bold", gid="status")
    _title_under(fig, status)


def _title_under(fig, status) -> None:
    """Give ``status`` (a text at the page's top right) a band of its own where the page's
    title would reach under it: the title is set under it, and the layout under the title.

    The status keeps its corner on every page (a reader finds it in the same place whether or
    not the title is long) and a title that leaves room for it stays where it was. The title
    (suptitle, centred on the page) is measured with the renderer: constrained layout sets its
    height only, so its width, and whether it comes within 1 em of the status, is known
    before the page is laid out. A suptitle given a height is no longer in constrained
    layout's margins, hence the layout's top edge set under it. A page without a suptitle
    keeps the band in every case (its axes titles are placed by the layout)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    renderer = canvas.get_renderer()
    box = status.get_window_extent(renderer)
    gap = renderer.points_to_pixels(status.get_fontsize())
    title = fig._suptitle              # matplotlib's only handle on the suptitle's Text
    if title is not None and title.get_text():
        t = title.get_window_extent(renderer)
        if t.x1 + gap <= box.x0 or box.x1 + gap <= t.x0:
            return
    engine = fig.get_layout_engine()
    pad = engine.get()["h_pad"] / fig.get_figheight()           # inches -> figure fraction
    top = status.get_position()[1] - box.height / fig.bbox.height - pad
    if title is not None and title.get_text():
        fig.suptitle(title.get_text(), y=top, fontsize=title.get_fontsize(),
                     fontweight=title.get_fontweight(), color=title.get_color())
        top -= t.height / fig.bbox.height + pad
    left, bottom, width, height = engine.get()["rect"]
    engine.set(rect=(left, bottom, width, min(bottom + height, top) - bottom))


# ----------------------------------------------------------------------------------------------
# page 1: constants, frequency table, residuals


def constants_rows(r: ResultFile) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the constants table (strings as drawn). A fixed constant says why
    (and gets no "% against the reference": its value is the initial one, not a result), as
    one not determined or on a search limit says "not compared"; a verdict set by the Monte
    Carlo gives the range and its widths."""
    conf = r.confidence
    head = ["constant", "value",
            f"{conf:.0%} interval" if conf is not None else "interval", "verdict", "initial",
            "reference (diff.)"]
    rows = []
    multi = len(r.materials) > 1
    names, _ = material_labels(r)
    ref = r.reference
    u = r.uncertainty
    for m, c in r.materials.items():
        for k in CONSTANTS:
            iv = u.get(m, k) if u is not None else None
            fixed = fixed_words(r, m, k)
            interval = interval_text(k, iv)
            if fixed is not None:
                interval = "none — not identified"
                verdict = fixed.replace(" (", "\n(", 1)
            elif iv is None:
                verdict = "no interval in file"
            elif iv.at_bound:
                verdict = "at bound, not identified"
            elif iv.verdict_from_monte_carlo or iv.verdict.startswith(("weak (Monte Carlo",
                                                                          "not determined (Mo")):
                # the range that set the verdict, on a second line of both cells
                verdict = short_verdict(iv.verdict).replace(" (Monte Carlo)", "")
                rng = monte_carlo_range(u, iv)
                if rng is not None:
                    ends, widths = monte_carlo_text(k, rng, c[k])
                    interval += f"\nMonte Carlo {ends}"
                    verdict += f" (Monte Carlo\n{widths})"
                else:
                    verdict += "\n(Monte Carlo)"
            else:
                verdict = short_verdict(iv.verdict)
            # held by the prior: on a line of its own ("well determined (held by the prior)"
            # ran over the cell's borders on both sides)
            held = iv is not None and fixed is None and iv.verdict.endswith(HELD_BY_PRIOR)
            if held:
                verdict = verdict.replace(HELD_BY_PRIOR, "") + "\n" + HELD_BY_PRIOR.strip()
            rv = ref.get(m, {}).get(k)
            diff = None if rv is None else reference_diff(c[k], rv)
            # a value the modes do not determine is no measurement of the constant: its
            # difference from the reference (S1.1's nu12 "0.350 (-35 %)") means nothing; nor
            # does that of a value held by its prior, mostly the prior's (S1.2 with prior
            # {nu12: 1.0}: "0.350 (+0 %)", its initial value against a reference equal to it)
            undetermined = verdict.startswith("not determined")
            if rv is None:
                rtext = ""
            elif (fixed is not None or (iv is not None and iv.at_bound) or undetermined
                  or held or diff is None):
                rtext = fmt_reference(k, rv) + (
                    "\n(fixed: not\ncompared)" if fixed is not None else
                    "\n(not compared)" if rv != (0.0, 0.0) else "")
            elif rv[0] == rv[1]:
                rtext = f"{fmt_reference(k, rv)} ({round(diff * 100) + 0:+d} %)"
            else:        # a range: inside it, or the distance to its nearer end
                rtext = fmt_reference(k, rv) + ("\n(inside)" if diff == 0 else
                                                f"\n({round(diff * 100) + 0:+d} % "
                                                f"{'above' if diff > 0 else 'below'})")
            # a material name too long for the line of its constant ("G12 (GPa)") above it
            rows.append([(f"{names[m]}{' ' if len(names[m]) <= 10 else chr(10)}{k} "
                          f"({_unit(k)})") if multi else f"{k} ({_unit(k)})",
                         fmt_value(k, c[k]), interval, verdict,
                         fmt_value(k, r.initial.get(m, {}).get(k)), rtext])
    return head, rows


FIXED_COLOR = "0.55"        # the marker of a fixed constant (hollow): not a result


def _verdict_color(verdict: str) -> str:
    if verdict.startswith("well"):
        return "#e3f3e3"
    if verdict.startswith("weak"):
        return "#fbf0cf"
    if verdict.startswith(("not", "at bound")):
        return "#f8d7d0"
    if verdict.startswith("fixed"):
        return "0.9"
    return "w"


TABLE_ROWS = 22          # rows (header included) a full-height table holds


def table_fraction(n_rows: int) -> float:
    """Height (fraction of its axes) of a table of n_rows + a header, from the top."""
    return min(1.0, (n_rows + 1) / TABLE_ROWS)


def _table(ax, head, rows, *, fontsize=8, col_widths=None, colors=None, head_fontsize=None):
    """A table of ``rows`` under bold ``head`` cells filling ``ax`` (``head_fontsize``: the
    header's, where its words are wider than the columns' values)."""
    ax.axis("off")
    if not rows:
        return None
    t = ax.table(cellText=rows, colLabels=head, loc="upper center", cellLoc="center",
                 colWidths=col_widths, bbox=[0, 0, 1, 1], cellColours=colors)
    t.auto_set_font_size(False)
    t.set_fontsize(fontsize)
    for (i, _), cell in t.get_celld().items():
        cell.set_linewidth(0.3)
        if i == 0:
            cell.set_text_props(weight="bold", fontsize=head_fontsize or fontsize)
            cell.set_facecolor("0.92")
    return t


#: a table row's height per extra line of text, in rows (a two-line cell needs 1.7 rows)
EXTRA_LINE = 0.7


def row_lines(row) -> int:
    """The lines of a table row's tallest cell."""
    return max(str(c).count("\n") + 1 for c in row)


def row_heights(head, rows) -> list[float]:
    """The heights of a table's rows (header first) in single-line rows, its two-line rows
    (an interval with "no information", a profile, a Monte Carlo range) counted taller
    (:data:`EXTRA_LINE`); their sum is the table's height."""
    return [1 + EXTRA_LINE * (row_lines(x) - 1) for x in [head, *rows]]


def constants_table(ax, r: ResultFile, table=None) -> None:
    """The constants' table of page 1 (``table``: :func:`constants_rows` of ``r``, when the
    caller has it)."""
    head, rows = table if table is not None else constants_rows(r)
    colors = [["w", "w", "w", _verdict_color(row[3]), "w", "w"] for row in rows]
    t = _table(ax, head, rows, fontsize=7.5, col_widths=[0.16, 0.09, 0.26, 0.25, 0.08, 0.16],
               colors=colors)
    if t is not None:
        # rows as tall as their lines (all the same height, two-line cells ran over their
        # borders); the table's bbox scales them together
        heights = row_heights(head, rows)
        for (i, _), cell in t.get_celld().items():
            cell.set_height(heights[i] / sum(heights))
    ax.set_gid("constants")
    # one material: its name, which no row gives (S1.1's page 1 named IM7/977-2 only in the
    # status words, and not at all where the status is ok)
    ax.set_title("identified constants" + (f" of {next(iter(r.materials))}"
                                           if len(r.materials) == 1 else ""),
                 fontsize=9, loc="left")


def frequency_rows(plate) -> tuple[list[str], list[list[str]]]:
    fr = plate.frequencies
    head = ["mode", "model\nmode", "measured\n(Hz)", "model\n(Hz)", "residual\n(%)", "weight"]
    rows = []
    for k in range(fr.model.size):
        meas = fr.measured[k]
        rows.append([str(k + 1), str(fr.model_mode[k]),
                     f"{meas:.2f}" if np.isfinite(meas) else "not\nmeasured",
                     f"{fr.model[k]:.2f}",
                     number_text(fr.residual_percent[k], "+.2f")
                     if np.isfinite(fr.residual_percent[k])
                     else "—", f"{fr.weight[k]:g}"])
    return head, rows


#: the shade of a measured frequency's ± 1 sd behind its residual bar
SIGMA_COLOR = "#cfe3f3"


def sigma_percent(fr) -> np.ndarray:
    """Each measured frequency's standard deviation in % of it (NaN: not measured, or a file
    without /uncertainty/frequency_sigma)."""
    sigma = getattr(fr, "sigma_hz", None)
    if sigma is None or np.size(sigma) != np.size(fr.measured):
        return np.full(np.size(fr.measured), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        return 100 * np.asarray(sigma, float) / np.asarray(fr.measured, float)


def frequency_block(fig, spec, plate):
    """Measured-vs-model table (left) and the residual bars aligned with its rows (right); the
    SubplotSpec of the room under them."""
    head, rows = frequency_rows(plate)
    f = table_fraction(len(rows))
    sub = spec.subgridspec(2, 2, width_ratios=[1.5, 1], height_ratios=[f, 1.001 - f],
                           wspace=0.0)
    ax_t = fig.add_subplot(sub[0, 0])
    ax_r = fig.add_subplot(sub[0, 1])
    # the bold two-line headers smaller than the values: at 7.5 pt 'measured', 'model' of
    # 'model mode' and 'weight' ran over their cells' borders on the A4 page
    _table(ax_t, head, rows, fontsize=7.5, head_fontsize=6.5,
           col_widths=[0.11, 0.13, 0.21, 0.2, 0.2, 0.15])
    ax_t.set_gid("frequency-table")
    ax_t.set_title("measured vs model frequencies", fontsize=9, loc="left")
    fr = plate.frequencies
    n = fr.model.size
    res = fr.residual_percent
    y = np.arange(n)
    bars = ax_r.barh(y, np.nan_to_num(res), 0.6, color="0.45")
    for k in np.flatnonzero(fr.weight == 0):
        bars[k].set_facecolor("0.85")
        bars[k].set_hatch("//")
    # the key only where a hatched bar is drawn (a mode not measured has no bar)
    hatched = bool((np.isfinite(res) & (np.asarray(fr.weight) == 0)).any())
    ax_r.set_gid("residuals")
    ax_r.axvline(0, color="k", lw=0.6)
    rms = fr.rms_residual_percent
    if np.isfinite(rms):
        for s in (1, -1):
            ax_r.axvline(s * rms, color="C0", ls="--", lw=0.9)
    # each mode's stated frequency sigma, in % of it, behind its bar: whether a residual is
    # within the noise the fit and its intervals assume (the page showed residuals without it:
    # S1.2's -0.5 to -0.9 % in the joint fit of S1.1-S1.4 against its 0.2 % read as small)
    sig = sigma_percent(fr)
    if np.isfinite(sig).any():
        from matplotlib.collections import PolyCollection

        boxes = [[(-s, k - 0.4), (s, k - 0.4), (s, k + 0.4), (-s, k + 0.4)]
                 for k, s in enumerate(sig) if np.isfinite(s)]
        ax_r.add_collection(PolyCollection(boxes, facecolors=SIGMA_COLOR, edgecolors="none",
                                           zorder=0.5, gid="frequency-sigma"))
    lim = np.nanmax(np.abs(res)) if np.isfinite(res).any() else 1.0
    lim = max(lim, rms if np.isfinite(rms) else 0, 1e-3,
              np.nanmax(sig) if np.isfinite(sig).any() else 0)
    ax_r.set_xlim(-1.2 * lim, 1.2 * lim)
    ax_r.set_ylim(n - 0.5, -1.5)               # row k of the table is y = k, the header y = -1
    ax_r.set_yticks([])
    ax_r.tick_params(labelsize=7)
    # few ticks, so that small residuals' labels (-0.0010, -0.0005...) do not run together
    from matplotlib.ticker import MaxNLocator

    ax_r.xaxis.set_major_locator(MaxNLocator(nbins=4, symmetric=True))
    ax_r.set_xlabel("(measured − model)/measured (%)"
                    + ("\nshaded: ± 1 sd of the\nmeasured frequency" if np.isfinite(sig).any()
                       else "")
                    + ("\nhatched: weight 0 (not fitted)" if hatched else ""), fontsize=7)
    ax_r.set_title("residuals" + (f"\n(dashed: ± weighted\nRMS {rms:.3f} %)"
                                  if np.isfinite(rms) else ""), fontsize=8)
    for side in ("top", "right", "left"):
        ax_r.spines[side].set_visible(False)
    return sub[1, :]


def _laminate_text(plate) -> str:
    from laminid_cli.global_uncertainty import GIVEN_WORDS, MC_NARROW_WORDS, PRIOR_WORDS

    gp = plate.global_properties
    if not gp:
        return ""
    ref = plate.reference_global

    unc = getattr(plate, "global_uncertainty", None) or {}
    starred = [False]

    def one(k, v):
        nu = k.startswith("nu")
        # the terminal's digits (below 1 GPa 3 significant: 0.0031 GPa, not 0.00 GPa)
        text = f"{k} {v:.3f}" if nu else f"{k} {gpa_text(v)} GPa"
        u = unc.get(k)
        if u is not None:                 # its doubt, from the constants' covariance
            rel = u["rel_half_width"]
            if not np.isfinite(rel):
                text += " (not identified)"
            else:
                pct = rel * 100
                text += (f" ±{pct:.2g} %" if pct < 9.95 else f" ±{pct:.0f} %" if rel < 1
                         else f" (±{pct:.0f} %)")
                if rel >= WEAK:           # as a constant is (intervals.WEAK)
                    text += " not determined"
                if MC_NARROW_WORDS in u.get("verdict", ""):
                    # the terminal's "— linearised; the Monte Carlo found ESL.G13 less
                    # determined than that: this interval is too narrow" (hybrid-ESL 8x8,
                    # 20 trials: Gxz ±27 % beside G13 "not determined (Monte Carlo)")
                    text += " (too narrow: the Monte Carlo found it less determined)"
                if GIVEN_WORDS in u.get("verdict", ""):
                    text += " (given fixed values)"     # their own doubt is not in the ±
                if PRIOR_WORDS in u.get("verdict", ""):
                    text += " (leans on a prior)"       # as the constant's "held by the prior"
            m = u.get("monte_carlo")
            if m:
                # its Monte Carlo range (the property at each trial's constants), in the
                # words of the constants' table: the ends ("*": set by trials on a search
                # limit) and, where it set the verdict, its widths and band
                rng = MonteCarloRange(m["lower"], m["upper"], m.get("inner_lower", np.nan),
                                      m.get("inner_upper", np.nan),
                                      bool(m.get("lower_at_bound")),
                                      bool(m.get("upper_at_bound")))
                ends, widths = monte_carlo_text("nu12" if nu else k, rng, v)
                text += f" (Monte Carlo {ends}" + ("" if nu else " GPa")
                if u.get("verdict_from") == "monte_carlo":
                    text += (f", {widths}: " + ("not determined" if u["verdict"].startswith(
                        "not determined") else "weak"))
                text += ")"
                starred[0] |= rng.lower_at_limit or rng.upper_at_limit
        if k in ref:
            lo, hi = ref[k]
            r = (f"{lo:.3g}" if nu else f"{lo / 1e9:.3g} GPa") if lo == hi else \
                (f"{lo:.3g}–{hi:.3g}" if nu else f"{lo / 1e9:.3g}–{hi / 1e9:.3g} GPa")
            text += f" (reference {r})"
        return text

    text = "laminate (Appendix A): " + ", ".join(one(k, v) for k, v in gp.items())
    return text + ("; *: an end of a Monte Carlo range set by trials on a search limit (the "
                   "search's end, not the data's)" if starred[0] else "")


def table_notes(r: ResultFile) -> list[str]:
    """What the constants table's words mean, for the words it uses."""
    _, rows = constants_rows(r)
    cells = [c for row in rows for c in row[2:4]]
    notes = []
    if any("no information" in c for c in cells):
        notes.append(f"no information: the interval's upper end is more than "
                     f"{UNINFORMATIVE_RATIO:.0f} times its lower end (the frequencies do not "
                     "constrain this constant)")
    # (the interval cell of a constant on a limit, not the verdict of one fixed because it was
    # on one: "fixed: it was at a search limit" has its own note)
    if any(c.startswith("none — on") for c in cells):
        notes.append("none — on a search limit: the fit stopped on a limit of the search (its "
                     "value is that limit): not identified, no interval")
    if any("profile:" in c for c in cells):
        notes.append("profile: < x: the fit rejects values beyond x at the intervals' level "
                     "(the other constants identified again with it held there); flat: it "
                     "rejects none up to the end of its scan (the modes do not determine "
                     "it there; nothing beyond was tried)")
    if any("Monte Carlo" in c for c in cells):
        notes.append("(Monte Carlo): the verdict is set by the Monte Carlo range (the constant "
                     "re-identified from perturbed frequencies), wider than the linearised "
                     "interval; its half-width over the value, and the half-width the range "
                     "has for sure" + ("; *: an end set by trials that stopped on a search "
                                      "limit (the search's end, not the data's)"
                                      if any("*" in c for c in cells) else ""))
    if any("–" in row[5] for row in rows):
        notes.append("reference low–high: a range given by the specimen file"
                     + (" or the plates' different values" if r.reference_notes else "")
                     + "; (inside): the value is within it, else the difference from its "
                     "nearer end")
    if any(c.startswith("fixed") for c in cells):
        notes.append("fixed: held at its initial value, not identified (its value is an "
                     "assumption, not a result; no comparison with the reference)")
    if any("(not compared)" in row[5] for row in rows):
        held = any("(not compared)" in row[5] and HELD_BY_PRIOR.strip() in row[3]
                   for row in rows)
        notes.append("reference (not compared): the value is not determined by these modes"
                     + (", is held by its prior (the file's prior gives more than half of what "
                        "is known of it, paper Eq. 15)," if held else "")
                     + " or is on a search limit, so its difference from the reference would "
                     "mean nothing")
    _, shortened = material_labels(r)
    if shortened:
        notes.append(shortened)
    u = r.uncertainty
    for lab, text in (getattr(u, "fixed_ranges", None) or {}).items():
        notes.append(f"{lab} (fixed on a search limit): {text}")
    if u is not None and getattr(u, "spread_counted", ()):
        names = [lab.rsplit(".", 1)[1] if len(r.materials) == 1 else lab
                 for lab in u.spread_counted]
        given = [(iv.constant if len(r.materials) == 1 else iv.label,
                  u.given_fixed.get(iv.label, np.nan)) for iv in u.intervals]
        notes.append(spread_sentence(names, [(n, w) for n, w in given if np.isfinite(w)]))
    if u is not None and u.fixed_check and not u.fixed_rejected:
        # a rejection is in the status, at the top of the page
        notes.append(u.fixed_check[0].upper() + u.fixed_check[1:])
    return notes


def mesh_check_note(mc: dict) -> str:
    """One line of ``identify --mesh-check`` (ResultFile.mesh_check) for the summary page."""
    m, f = mc["mesh"], mc["fine_mesh"]
    md = mc["modes"]
    sig = np.abs(np.asarray(md["change_sigma"], float))
    i = int(np.nanargmax(sig))
    hw = np.abs([c["shift_half_width"] for per in mc["constants"].values()
                 for c in per.values()], dtype=float)
    k = int(np.nanargmax(hw))
    lab = mc["labels"][k]
    lab = lab.rsplit(".", 1)[1] if len(mc["constants"]) == 1 else lab
    head = (f"mesh check, {m['nx']}x{m['ny']} against {f['nx']}x{f['ny']}: largest frequency "
            f"change {md['change_percent'][i]:+.3f} % ({sig[i]:.2f} σ, mode "
            f"{int(md['measured_mode'][i])}); the constants move by at most {hw[k]:.2f} of "
            f"their 95 % half-width ({lab})")
    return head + (f": too coarse — identify with --mesh {f['nx']}x{f['ny']}"
                   if mc["too_coarse"] else ": fine enough for these modes")


def widening(u) -> float:
    """How many times wider the intervals of ``u`` are than the stated frequency sigma alone
    gives (normal quantile): sqrt(s2) times the Student t quantile over the normal one where
    the covariance was scaled by the residuals; NaN where the file does not say."""
    from laminid_cli.quantiles import norm_ppf

    if u.scale_used != "residuals" or not (np.isfinite(u.variance_factor)
                                            and np.isfinite(u.quantile)):
        return np.nan
    z = norm_ppf(0.5 + u.confidence / 2)
    return float(np.sqrt(u.variance_factor) * u.quantile / z)


def interval_basis(u) -> str:
    """What the intervals of ``u`` come from, in the terminal's words ("intervals from:
    covariance scaled by s2 = 8.53 (Student t quantile)"), with how much wider that made them:
    "from the residuals (covariance scaled by s² = 8.53, Student t): 3.0 × as wide as the
    stated σ gives", or "from the stated frequency σ (normal quantile)"; "" for a file that
    does not record it. Page 1 said "95% intervals, s² = 8.53" either way, so that intervals
    widened three times by a poor fit read as the stated noise's."""
    if u.scale_used == "stated":
        return "from the stated frequency σ (normal quantile)"
    if u.scale_used == "residuals":
        w = widening(u)
        return ("from the residuals (covariance scaled by s² = "
                f"{u.variance_factor:.3g}, Student t)"
                + (f": {w:.1f} × as wide as the stated σ gives" if np.isfinite(w) else ""))
    return ""


def monte_carlo_note(u) -> str | None:
    """The summary page's line on the Monte Carlo check of ``u`` (/uncertainty/monte_carlo),
    in the words of identify's terminal ("Monte Carlo check: 199 of 200 re-identifications
    converged (frequencies perturbed by sigma x 1.22)") and where its ranges are drawn; None
    without one. A file whose group lacks the counts (attrs trials, converged) says so
    without them."""
    mc = u.monte_carlo if u is not None else None
    if not mc:
        return None
    if "trials" in mc and "converged" in mc:
        head = (f"Monte Carlo check: {int(mc['converged'])} of {int(mc['trials'])} "
                "re-identifications converged")
        factor = float(mc.get("sigma_factor", np.nan))
        if np.isfinite(factor):
            head += f" (frequencies perturbed by σ × {factor:.3g})"
    else:
        head = "Monte Carlo check (its trial counts not in this file)"
    if "lower" in mc and "upper" in mc:
        return head + (f"; their {u.confidence:.0%} ranges: grey bars on the intervals page"
                       + (" and in the table, where a range set the verdict"
                          if any(iv.verdict_from_monte_carlo for iv in u.intervals) else ""))
    return head + "; no ranges in this file"


def plate_chi2(plate) -> tuple[float | None, int]:
    """(chi2, n) of one plate of a fit: n its fitted modes (measured, weight > 0), chi2 the
    sum over them of ((f² − f_model²) / (2 f σ))², the uncertainty's eigenvalue residual over
    its σ (/uncertainty/frequency_sigma; the weight cancels), so that the plates' add up to
    the result's chi2 = s2 · dof (prior terms aside); chi2 None in files without σ."""
    fr = plate.frequencies
    ok = np.isfinite(fr.measured) & (np.asarray(fr.weight) > 0)
    n = int(ok.sum())
    if fr.sigma_hz is None or np.size(fr.sigma_hz) != np.size(fr.measured):
        return None, n
    f, fm, sd = fr.measured[ok], fr.model[ok], np.asarray(fr.sigma_hz, float)[ok]
    return float(np.sum(((f**2 - fm**2) / (2 * f * sd)) ** 2)), n


def prior_chi2(r: ResultFile) -> dict[str, float]:
    """{label: term} of each free constant's prior in the fit's chi2 (paper Eq. 15, as
    :func:`laminid_cli.uncertainty.design_rows` counts it): wp ((P − P0) / P0)² / σ_u², its
    term of Eq. 15 over the rows' noise σ_u², P0 the initial value, wp its weight, σ_u the RMS
    of 2 σ/f over every plate's fitted modes (σ the intervals'). With the plates'
    :func:`plate_chi2` these add up to the result's chi2 = s2 · dof. {} without a prior, or in
    a file without σ."""
    import yaml

    rel = []
    for p in r.plates:
        fr = p.frequencies
        if fr.sigma_hz is None or np.size(fr.sigma_hz) != np.size(fr.measured):
            return {}
        ok = np.isfinite(fr.measured) & (np.asarray(fr.weight) > 0)
        rel.append(2 * np.asarray(fr.sigma_hz, float)[ok] / fr.measured[ok])
    try:
        # a joint fit's plates have the same priors (identify refuses others): the first's
        mats = yaml.safe_load(r.plates[0].yaml)["materials"]
    except (IndexError, KeyError, TypeError, yaml.YAMLError):
        return {}
    sigma_unit = float(np.sqrt(np.mean(np.concatenate(rel) ** 2))) if rel else np.nan
    fixed = set(r.uncertainty.fixed) if r.uncertainty is not None else set()
    terms = {}
    for m, consts in r.materials.items():
        prior = ((mats or {}).get(m) or {}).get("prior") or {}
        for k in CONSTANTS:
            wp = prior.get(k, 0) if isinstance(prior, dict) else 0
            if (not isinstance(wp, (int, float)) or wp <= 0 or k not in r.free.get(m, ())
                    or f"{m}.{k}" in fixed):
                continue
            p0 = r.initial[m][k]
            terms[f"{m}.{k}"] = float(wp * ((consts[k] - p0) / (p0 or 1.0) / sigma_unit) ** 2)
    return terms


def summary_page(r: ResultFile, plate=None, what: str = ""):
    """Page 1: status, constants table, and (single plate, or ``plate`` given) the
    frequencies. A joint result without ``plate`` gets the RMS of each plate instead."""
    fig = _figure()
    fig.suptitle(_title(r, plate if plate is not None else (r.plates[0] if not r.joint
                                                             else None), what), fontsize=11)
    # the status first, under the title: what a lab reads before any number (the intervals
    # and damping pages repeat it at their foot, the others with its codes at their top right)
    text, color = status_line(r)
    width = _wrap_width(fig, 9, bold=True)
    lines = [ln for para in text.split("\n")
             for ln in textwrap.wrap(para, width, break_on_hyphens=False, subsequent_indent="    ")]
    # a 9-point bold line is ~0.15 in, 1.8 % of the A4 page's height (0.025 left a gap)
    h = min(0.35, 0.0195 * len(lines) + 0.015)
    outer = fig.add_gridspec(2, 1, height_ratios=[h, 1 - h])
    ax_s = fig.add_subplot(outer[0, 0])
    ax_s.axis("off")
    ax_s.text(0, 1, "\n".join(lines), transform=ax_s.transAxes, ha="left", va="top",
              fontsize=9, weight="bold", color=color, gid="status")
    gs = outer[1, 0].subgridspec(1, 2, width_ratios=[1.5, 1])
    table = constants_rows(r)
    f = min(1.0, sum(row_heights(*table)) / TABLE_ROWS)
    left = gs[0, 0].subgridspec(2, 1, height_ratios=[f, 1.001 - f])
    ax_c = fig.add_subplot(left[0, 0])
    constants_table(ax_c, r, table)
    plate = plate if plate is not None else (None if r.joint else r.plates[0])
    if plate is not None:
        frequency_block(fig, gs[0, 1], plate)
    else:
        right = gs[0, 1].subgridspec(2, 1, height_ratios=[table_fraction(len(r.plates)),
                                                           1.001 - table_fraction(len(r.plates))])
        ax = fig.add_subplot(right[0, 0])
        # each plate's share of the misfit beside its RMS: which plate disagrees with the
        # others (S1.1-S1.4's joint s² = 8.53 did not say; S1.3 is 191 of chi2 358)
        shares = [plate_chi2(p) for p in r.plates]
        head = ["plate", "RMS residual (%)", "chi2 (n)", "modes measured", "mesh"]
        rows = [[p.name, f"{p.frequencies.rms_residual_percent:.3f}",
                 f"{c:.3g} ({n})" if c is not None else "–",
                 str(int(np.isfinite(p.frequencies.measured).sum())),
                 f"{p.mesh[0]}x{p.mesh[1]}"] for p, (c, n) in zip(r.plates, shares)]
        # (a 7-point header: "modes measured" in 8-point bold ran over its cell)
        _table(ax, head, rows, fontsize=8, col_widths=[0.13, 0.25, 0.21, 0.24, 0.17],
               head_fontsize=7)
        ax.set_gid("plates")
        ax.set_title(f"{len(r.plates)} plates fitted together (their pages follow)", fontsize=9,
                     loc="left")
        if all(c is not None for c, _ in shares):
            total = sum(c for c, _ in shares)
            chi2 = r.uncertainty.s2 * r.uncertainty.dof if r.uncertainty is not None else total
            priors = prior_chi2(r)
            note = (f"chi2 (n): the plate's share of the fit's chi2 {chi2:.3g}, "
                    "Σ\u00a0((f²\u00a0−\u00a0f_model²)\u00a0/\u00a0(2\u00a0f\u00a0σ))² over its n fitted modes (σ the intervals'); "
                    "about n each when the plates agree, one far above its n disagrees with "
                    "the others")
            if priors:
                # the plates' chi2 alone fall short of the fit's by the priors' terms (a
                # joint S1.1 + S1.2 with prior {nu12: 1.0}: 71.4996 + 0.00694 = 71.5065)
                # one count of decimals for the three, the smallest term to 3 digits, so
                # that the sum reads by eye
                small = min([t for t in priors.values() if t > 0] or [1.0])
                d = int(min(8, max(1, 2 - np.floor(np.log10(small)))))
                one = len(r.materials) == 1
                terms = " + ".join(f"on {lab.rsplit('.', 1)[1] if one else lab} {t:.{d}f}"
                                   for lab, t in priors.items())
                note += (f"; the fit's chi2 {chi2:.{d}f} = the plates' {total:.{d}f} + the "
                         f"prior's {terms} (wp\u00a0((P\u00a0−\u00a0P0)\u00a0/\u00a0P0)²\u00a0/\u00a0σ_u², "
                         "paper Eq. 15, σ_u the RMS of 2\u00a0σ/f)")
            if not np.isclose(total + sum(priors.values()), chi2, rtol=1e-6):
                note += (f"; the result's chi2 {chi2:.4g} is not the plates' {total:.4g}"
                         + (" and the priors'" if priors else ""))
            ax_p = fig.add_subplot(right[1, 0])
            ax_p.axis("off")
            ax_p.text(0, 0.97, "\n".join(textwrap.wrap(note, 80)), fontsize=7.5, va="top",
                      ha="left", transform=ax_p.transAxes, gid="plates-note")
    ax_n = fig.add_subplot(left[1, 0])
    ax_n.axis("off")
    notes = [t for t in (_laminate_text(plate) if plate is not None else "",) if t]
    src = r.reference_source
    notes.append(textwrap.shorten("reference: " + src, 200) if src else
                 "no reference values in the specimen file")
    if any(lo == hi for consts in r.reference.values() for lo, hi in consts.values()):
        # (the source's words may state a scatter, "170 ± 1 GPa", that the values do not carry)
        notes.append(REFERENCE_POINT_NOTE)
    notes += r.reference_notes
    if r.uncertainty is not None:
        u = r.uncertainty
        basis = interval_basis(u)
        # (s² once: in the basis where the covariance was scaled by it)
        notes.append(f"uncertainty: {u.confidence:.0%} intervals"
                     + (f" {basis}; " if u.scale_used == "residuals" else
                        f" {basis}, s² = {u.s2:.3g}, " if basis else f", s² = {u.s2:.3g}, ")
                     + f"condition number {u.condition_number:.3g}, σ from {u.sigma_source}")
        mc = monte_carlo_note(u)
        if mc:
            notes.append(mc)
        from laminid_cli.intervals import small_chi2_note

        small = small_chi2_note(u.s2 * u.dof, u.dof, "frequency sigma")
        if small:
            notes.append(small)
        notes += table_notes(r)
    if r.mesh_check:
        notes.append(mesh_check_note(r.mesh_check))
    # the notes in the room left under the table: smaller type, wrapped wider, where there are
    # many (a two-material result with profiles and a Monte Carlo ran off the page)
    room = fig.get_figheight() * (1 - h) * (1.001 - f) * 0.9           # inches
    size, spacing = 7.5, 1.5
    while True:
        text = "\n".join("\n".join(textwrap.wrap(t, int(110 * 7.5 / size),
                                                 break_on_hyphens=False)) for t in notes)
        n = text.count("\n") + 1
        if n * size * spacing / 72 <= room or (size <= 6 and spacing < 1.5):
            break
        if size > 6:
            size -= 0.5
        else:
            spacing = 1.3
    ax_n.text(0, 0.97, text, fontsize=size, va="top", ha="left", transform=ax_n.transAxes,
              linespacing=spacing, gid="notes")
    return fig


# ----------------------------------------------------------------------------------------------
# intervals

#: a modulus' panel whose positive values (value, reference, interval, Monte Carlo range,
#: profile) span more than this ratio is drawn on a log axis: on a linear one a constant near
#: its search limit sat on 0 under an arrow (S2.1's G13 0.0029 GPa, flat to 18.5 GPa; across
#: specimens S2.1's and S2.2's G13 under S1.x's 2-6 GPa)
LOG_PANEL_RATIO = 10.0
#: on a log panel of one constant, the ends (interval, Monte Carlo range, profile) within this
#: factor of the value are drawn whole; one further (or <= 0) runs off with an arrow
LOG_PANEL_REACH = 1e4


def wants_log_axis(k: str, marks, ends=()) -> bool:
    """Whether the panel of constant ``k`` is drawn on a log axis: a modulus whose positive
    ``marks`` (values, reference ends: display unit, all > 0) and finite positive ``ends``
    (interval, range and profile ends; ends <= 0 run off the panel) span more than
    :data:`LOG_PANEL_RATIO`. nu12 stays linear (its intervals are linear, its values may be
    <= 0), as does a panel with a mark <= 0."""
    marks = np.asarray([x for x in marks if np.isfinite(x)], float)
    if k == "nu12" or marks.size == 0 or (marks <= 0).any():
        return False
    pts = np.concatenate([marks, [e for e in ends if np.isfinite(e) and e > 0]])
    # (a mark near 0, e.g. a loss factor's interval end of 1e-310, overflows the ratio to
    # inf, which is the answer; numpy's "overflow encountered" warning reached the terminal)
    with np.errstate(over="ignore"):
        return bool(pts.max() / pts.min() > LOG_PANEL_RATIO)


def _log_limits(core, extra, *, pad=(0.06, 0.06)):
    """(ymin, ymax) of a log panel: the positive values ``core`` always in view, ``extra``
    where positive, and margins ``pad`` (below, above) as fractions of the decades spanned."""
    pts = [x for x in (*core, *extra) if np.isfinite(x) and x > 0]
    lo, hi = min(pts), max(pts)
    decades = max(np.log10(hi / lo), 0.3)
    return lo / 10 ** (pad[0] * decades), hi * 10 ** (pad[1] * decades)


def _inward(ax, edge: float, frac: float, ymin: float, ymax: float, up: bool) -> float:
    """The y ``frac`` of the panel's height inside its edge ``edge`` (the top where ``up``),
    on a linear or a log axis: where an arrow onto that edge starts."""
    sign = -1 if up else 1
    if ax.get_yscale() == "log":
        return edge * (ymax / ymin) ** (sign * frac)
    return edge + sign * frac * (ymax - ymin)


def _between(ax, a: float, b: float) -> float:
    """Half way from ``a`` to ``b`` as drawn: the geometric mean on a log axis."""
    return float(np.sqrt(a * b)) if ax.get_yscale() == "log" else (a + b) / 2


#: a log axis over more than 2.5 decades labels 2 and 5 x 10^k too where a decade is at least
#: this tall (inches): 7-pt labels 0.3 decade apart (1 to 2) stay clear of each other
LOG_125_DECADE_INCHES = 0.5
#: the least gap (inches) between a decade's label and the 2, 3 or 5 x 10^k labelled in a
#: partial decade at an end of a log axis that labels only decades
LOG_LABEL_GAP_INCHES = 0.12


def log_axis_ticks(axis, *, plain: bool = True) -> None:
    """Ticks of a log y axis from its limits (:class:`_LogTicks`): 1, 2, 5 x 10^k (or more)
    over up to 2.5 decades or where a decade is tall enough to label them, else the decades
    and a 2, 3 or 5 x 10^k in a partial decade at an end (the history's "modulus / initial value" up
    to 4.5 labelled nothing above 1); ``plain`` numbers (0.001, 10) or decades as 10^k; no
    labels on the minor ticks. One form on an axis (:func:`log_tick_labels`)."""
    from matplotlib.ticker import Formatter, NullFormatter

    ticks = _LogTicks()

    class OneForm(Formatter):
        """The labels of the ticks in view, all in one form (:func:`log_tick_labels`)."""

        locs: list = []

        def set_locs(self, locs):
            lo, hi = sorted(axis.yaxis.get_view_interval())
            self.locs = [v for v in locs if lo * (1 - 1e-9) <= v <= hi * (1 + 1e-9)]

        def __call__(self, v, pos=None):
            # called alone (no set_locs: a figure not drawn), a decade as 10^k unless plain
            locs = self.locs or [v]
            return log_tick_labels(list(locs) + [v], plain=plain or ticks.labels_between())[-1]

    axis.yaxis.set_major_locator(ticks)
    axis.yaxis.set_major_formatter(OneForm())
    axis.yaxis.set_minor_formatter(NullFormatter())


def log_tick_labels(values, *, plain: bool) -> list[str]:
    """Labels of a log axis' ticks ``values``, all in one form: plain numbers ("0.001", "1",
    "3") where ``plain`` or some value is no power of ten, and every value is between 1e-4 and
    1e5; else powers of ten ("10⁻³", "10⁰", "3×10⁰"). An axis mixed them: "200" over "10²"
    (the history's RMS residual of the hybrid plate), "5" over "10⁰", "10000" under "10⁶"
    (an interval panel of 8 decades)."""
    values = [float(v) for v in values]
    if not values:
        return []
    inside = all(v == 0 or 1e-4 <= abs(v) * (1 + 1e-12) < 1e5 for v in values)
    if inside and (plain or not all(_decade(v) for v in values)):
        return [f"{v:g}" for v in values]
    return [power_text(v) for v in values]


def power_text(v: float) -> str:
    """``v`` as a power of ten in plain text, "10⁻³" or "3×10⁰" ("1.5×10⁻⁷" where its
    mantissa is not whole; f"{v:g}" for 0 and non-finite values)."""
    if not (np.isfinite(v) and v != 0):
        return f"{v:g}"
    k = int(np.floor(np.log10(abs(v)) + 1e-9))
    m = v / 10.0 ** k
    sup = "10" + str(k).translate(_SUPERSCRIPT)
    if abs(m - round(m)) < 1e-6:
        m = int(round(m))
        return sup if m == 1 else ("-" + sup if m == -1 else f"{m}×{sup}")
    return f"{m:.3g}×{sup}"


def _log_ticks_class():
    from matplotlib.ticker import LogLocator

    class LogTicks(LogLocator):
        """Major ticks of a log axis, chosen at draw time from its view and its height: 1, 1.5,
        2, 3, 5, 7 x 10^k within a decade; 1, 2, 5 x 10^k over up to 2.5 decades or where a
        decade is at least :data:`LOG_125_DECADE_INCHES` tall; else the decades (at most 8),
        with a 2, 3 or 5 x 10^k in a partial decade at either end, clear of the decade's label
        (:data:`LOG_LABEL_GAP_INCHES`), so that values at the ends are read against a
        number."""

        def __init__(self):
            super().__init__(base=10, numticks=8)

        def _decade_inches(self, lo: float, hi: float) -> float:
            if self.axis is None or self.axis.axes is None:
                return np.inf
            a = self.axis.axes
            return a.get_position().height * a.figure.get_figheight() / np.log10(hi / lo)

        def _subs_for(self, lo: float, hi: float) -> tuple:
            decades = np.log10(hi / lo)
            if decades <= 1:
                return (1.0, 1.5, 2.0, 3.0, 5.0, 7.0)
            if decades <= 2.5 or self._decade_inches(lo, hi) >= LOG_125_DECADE_INCHES:
                return (1.0, 2.0, 5.0)
            return (1.0,)

        def labels_between(self) -> bool:
            """Whether the axis now labels values between its decades (then in plain numbers
            throughout: "0.002, 0.005, 0.01", not "0.002, 0.005, 10⁻²")."""
            if self.axis is None:
                return False
            lo, hi = sorted(self.axis.get_view_interval())
            return lo > 0 and self._subs_for(lo, hi) != (1.0,)

        def tick_values(self, vmin, vmax):
            lo, hi = sorted((float(vmin), float(vmax)))
            if not (lo > 0 and np.isfinite(hi) and hi > lo):
                return super().tick_values(vmin, vmax)
            subs = self._subs_for(lo, hi)
            self.set_params(subs=subs)
            ticks = np.asarray(super().tick_values(lo, hi), float)
            if subs != (1.0,):
                return ticks
            inside = ticks[(ticks >= lo * (1 - 1e-9)) & (ticks <= hi * (1 + 1e-9))]
            if inside.size == 0:
                return ticks
            per_decade = self._decade_inches(lo, hi)
            extra = []
            top, bottom = inside.max(), inside.min()
            # the highest 5, 3 or 2 x 10^k above the top decade, the lowest below the bottom
            up = [c * top for c in (5.0, 3.0, 2.0) if c * top <= hi * (1 + 1e-9)
                  and np.log10(c) * per_decade >= LOG_LABEL_GAP_INCHES]
            down = [c * bottom / 10 for c in (2.0, 3.0, 5.0) if c * bottom / 10 >= lo * (1 - 1e-9)
                    and np.log10(10 / c) * per_decade >= LOG_LABEL_GAP_INCHES]
            extra += up[:1] + down[:1]
            return np.sort(np.concatenate([ticks, extra]))

    return LogTicks


def _decade(v: float) -> bool:
    """Whether ``v`` is a power of ten."""
    return v > 0 and abs(np.log10(v) - round(np.log10(v))) < 1e-9


def _LogTicks():
    """A :class:`LogTicks` locator (its class built on first use: matplotlib is imported by
    the report's pages only)."""
    global _LOG_TICKS
    if _LOG_TICKS is None:
        _LOG_TICKS = _log_ticks_class()
    return _LOG_TICKS()


_LOG_TICKS = None


def plain_number(v: float) -> str:
    """A log axis' tick label as a plain number ("0.002", "5", "20") between 1e-4 and 1e5,
    else in powers of ten ("10⁻⁵", "2×10⁻⁵") rather than "2e-05"."""
    a = abs(v)
    if a == 0 or 1e-4 <= a * (1 + 1e-12) < 1e5:
        return f"{v:g}"
    k = int(np.floor(np.log10(a) + 1e-9))
    m = v / 10.0 ** k
    if abs(m - round(m)) < 1e-6:
        sup = "10" + str(k).translate(_SUPERSCRIPT)
        return sup if round(m) == 1 else f"{int(round(m))}×{sup}"
    return f"{v:g}"


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def power_of_ten(v: float) -> str:
    """A log axis' tick label: "10⁻³" for a power of ten, in plain text (matplotlib's default
    writes it in mathtext, whose parser took ~0.8 s of the history page's 3.2 s under cProfile),
    else the number ("2e-05")."""
    if v > 0:
        k = np.log10(v)
        if abs(k - round(k)) < 1e-9:
            return "10" + str(int(round(k))).translate(_SUPERSCRIPT)
    return f"{v:g}"


def _panel_limits(v, lo, hi, refs, weak, nu: bool):
    """(ymin, ymax) of a constant's panel: its value with the weak band and the reference
    (``refs``: its ends, both of a range) in view; an interval end only when it stays within
    a value's width (else it gets an arrow)."""
    a = abs(v) if v else max(abs(lo), abs(hi), 1e-12)
    need = [1.35 * weak * a]
    for ref in refs:
        if np.isfinite(ref):
            need.append(1.15 * abs(ref - v))
    for e in (lo, hi):
        if np.isfinite(e) and abs(e - v) <= 1.0 * a:
            need.append(1.1 * abs(e - v))
    half = max(need)
    ymin, ymax = v - half, v + half
    if not nu and ymin < 0 <= v:
        ymin = 0.0
    return ymin, ymax


def _bound_limits(v, side: str, refs, nu: bool, profile=np.nan):
    """(ymin, ymax) of the panel of a constant at its bound: room on the side the data push
    it to (where the one-sided statement points), the reference (``refs``: its ends) and the
    profile's bound (where the fit rejects it, display unit) in view."""
    half = max(0.6 * abs(v), 0.1 if nu else 1e-12)
    ymin, ymax = (v - half, v + 0.35 * half) if side == "lower" else (v - 0.35 * half, v + half)
    for other in (*refs, profile):
        if other is not None and np.isfinite(other):
            pad = 0.1 * max(abs(other - v), half)
            ymin, ymax = min(ymin, other - pad), max(ymax, other + pad)
    if not nu and (ymin < 0 or side == "lower"):   # a modulus below its limit: 0 .. limit
        ymin = 0.0
    return ymin, ymax


INTERVAL_COLOR = "C0"


def _bound_panel(ax, k, v, iv, x, ymin, ymax):
    """A constant at its bound: no interval, a dashed arrow from the value towards the side
    the fit pushes it to, and words from the file's bound_side (never a statement that reads
    like a confidence bound)."""
    side = iv.bound_side or bound_statement(iv.bound_text)[0]
    if not side:
        return
    edge = ymin if side == "lower" else ymax
    ax.annotate("", (x, edge), xytext=(x, v), gid="one-sided",
                arrowprops=dict(arrowstyle="-|>", color=INTERVAL_COLOR, lw=2.5, ls="--"))
    words = f"stopped on the {side} search limit: no interval"
    pb = getattr(iv, "profile_bound", np.nan)
    if np.isfinite(pb):
        # the values the fit does not reject: from the limit to the profile's bound (in view)
        # (its words from the cap towards the limit, as the flat profile's: centred on a cap
        # at the panel's edge, the first line ran out of the panel)
        y = _gpa(k, pb)
        _profile_line(ax, x, v, y, ymin, ymax, f"profile\n{'<' if y > v else '>'} "
                      f"{fmt_value(k, pb)}", xytext=(6, -1 if y > v else 1),
                      va="top" if y > v else "bottom", ha="left")
    elif iv.profile_kind == "flat":
        far = getattr(iv, "profile_far", np.nan)
        if not np.isfinite(far):
            words += "; profile: flat to the end of its scan"
        else:
            # the values the fit does not reject: from the limit to the end of the scan,
            # off the panel when that end is out of view
            # (its words right of the line, as the bounded profile's: the left holds the
            # Monte Carlo bar's end words)
            y = _gpa(k, far)
            _profile_line(ax, x, v, y, ymin, ymax, f"profile:\nflat to\n{fmt_value(k, far)}",
                          open_end=True, xytext=(6, -3 if y > v else 3),
                          va="top" if y > v else "bottom", ha="left")
    # from the arrow's middle into the panel (centred there, the words of a limit at the
    # panel's edge ran out of it, over the value written under the panel)
    ax.annotate("\n".join(textwrap.wrap(words, 12)), (x, _between(ax, v, edge)), xytext=(5, 0),
                textcoords="offset points", fontsize=6.5, ha="left",
                va="bottom" if side == "lower" else "top", color=INTERVAL_COLOR,
                gid="bound-statement")


def _profile_line(ax, x, v, y, ymin, ymax, label, *, open_end=False, **label_kw):
    """A profile's values the fit does not reject, dotted from the limit ``v`` to ``y``
    (display unit) with a cap there, or to the panel's edge with an arrow head where ``y`` is
    out of view; ``label`` at that end (``label_kw``: its placement). ``open_end``: ``y`` is
    the end of a flat profile's scan, which the fit does not reject either (nothing beyond
    was tried): an arrow head there too, never a cap (a cap, as a bounded profile's, said the
    fit rejects what lies beyond: hybrid CM's glass E2 'flat to 0.9' and G12 '< 18.50' were
    drawn alike)."""
    up = y > v
    end = min(y, ymax) if up else max(y, ymin)
    ax.plot([x, x], [v, end], ls=(0, (1, 1.5)), color=INTERVAL_COLOR, lw=2.5, gid="profile")
    if end == y and not open_end:
        ax.plot([x], [y], "_", ms=14, mew=2.5, color=INTERVAL_COLOR, gid="profile-cap")
    else:
        ax.plot([x], [end], "^" if up else "v", ms=6, color=INTERVAL_COLOR, clip_on=False,
                gid="profile-cap")
    ax.annotate(label, (x, end), textcoords="offset points", fontsize=6.5,
                color=INTERVAL_COLOR, gid="profile-label", **label_kw)


def _mc_end_label(ax, k, x, y, end_si, up, at_limit, gid, sure_si=None):
    """The words at an end of the Monte Carlo bar (left of it): its value where the bar runs
    off the panel, and the end of the width for sure where that runs off too ("(for
    sure\n6.708)"); "search limit" where trials on a limit of the search set it."""
    text = f"{'to' if up else 'from'}\n{mc_end_text(k, end_si)}" if end_si is not None else ""
    if sure_si is not None and (end_si is None
                                or mc_end_text(k, sure_si) != mc_end_text(k, end_si)):
        # (an end for sure that reads as the range's own is not written twice)
        text += f"\n(for sure\n{mc_end_text(k, sure_si)})"
    if at_limit:
        text += ("\n" if text else "") + "search\nlimit"
    ax.annotate(text, (x, y), xytext=(-4, -3 if up else 3), textcoords="offset points",
                fontsize=6.5, va="top" if up else "bottom", ha="right", color="0.35", gid=gid)


#: the grey of the Monte Carlo range's bar and arrows
MC_COLOR = "0.45"
#: two ends of a Monte Carlo range on search limits nearer than this fraction of the panel's
#: height get one "search limit" label (two labels of two lines each need ~0.12 of a panel)
MC_LIMIT_LABELS_APART = 0.12


def _limit_ends_together(ax, rng: MonteCarloRange, lo, hi, ymin, ymax) -> bool:
    """Whether both ends of the Monte Carlo range are on search limits, inside the panel, and
    nearer than :data:`MC_LIMIT_LABELS_APART` of its height (on its scale)."""
    if not (rng.lower_at_limit and rng.upper_at_limit and ymin <= lo <= hi <= ymax):
        return False
    if ax.get_yscale() == "log":
        if min(lo, ymin) <= 0:
            return False
        lo, hi, ymin, ymax = np.log10([lo, hi, ymin, ymax])
    return (hi - lo) < MC_LIMIT_LABELS_APART * (ymax - ymin)


def _monte_carlo_bar(ax, k, rng: MonteCarloRange, x, ymin, ymax) -> None:
    """The Monte Carlo range at ``x``, its width for sure over it; an end off the panel
    stops at an arrow onto the panel's edge (its head inside the frame, as the interval's),
    with the end's value, and the width for sure's where that is off too, written beside."""
    g = (lambda z: _gpa(k, z))
    lo, hi = g(rng.lower), g(rng.upper)
    # where a bar running off the panel stops: the foot of the arrow onto that edge
    stop = {True: _inward(ax, ymax, 0.08, ymin, ymax, True),
            False: _inward(ax, ymin, 0.08, ymin, ymax, False)}

    def clipped(a, b):
        return [stop[False] if a < ymin else min(max(a, ymin), ymax),
                stop[True] if b > ymax else max(min(b, ymax), ymin)]
    ax.plot([x] * 2, clipped(lo, hi), "-", color=MC_COLOR, lw=2, solid_capstyle="butt",
            gid="monte-carlo")
    # the width the trials show for sure, which the verdicts use (files since stop 28)
    sure = np.isfinite(rng.inner_lower) and np.isfinite(rng.inner_upper)
    if sure:
        ax.plot([x] * 2, clipped(g(rng.inner_lower), g(rng.inner_upper)), "-",
                color="0.2", lw=4.5, solid_capstyle="butt", gid="monte-carlo-sure")
    both = _limit_ends_together(ax, rng, lo, hi, ymin, ymax)
    if both:
        # both ends on search limits, too near for two labels (S2.1 8x8: all ten trials on
        # G13's lower limit 1e-4 E1, 0.002879 .. 0.003000 GPa, two "search limit" labels
        # over each other): one, beside the bar's middle
        mid = np.sqrt(lo * hi) if ax.get_yscale() == "log" else 0.5 * (lo + hi)
        ax.annotate("search\nlimit\n(both\nends)", (x, mid), xytext=(-4, 0),
                    textcoords="offset points", fontsize=6.5, va="center", ha="right",
                    color="0.35", gid="monte-carlo-both-limit")
    for side, end, end_si, inner_si, at_limit in (
            ("upper", hi, rng.upper, rng.inner_upper, rng.upper_at_limit and not both),
            ("lower", lo, rng.lower, rng.inner_lower, rng.lower_at_limit and not both)):
        up = side == "upper"
        off = (end > ymax) if up else (end < ymin)
        if off:                     # an arrow onto the edge and the end's value beside it
            edge = ymax if up else ymin
            ax.annotate("", (x, edge), xytext=(x, stop[up]), gid=f"monte-carlo-{side}-arrow",
                        arrowprops=dict(arrowstyle="-|>", color=MC_COLOR, lw=1.5))
            inner_off = sure and ((g(inner_si) > ymax) if up else (g(inner_si) < ymin))
            _mc_end_label(ax, k, x, edge, end_si, up, at_limit, f"monte-carlo-{side}-end",
                          inner_si if inner_off else None)
        elif at_limit:
            # an end set by trials on a limit of the search is the search's, not the data's
            _mc_end_label(ax, k, x, end, None, up, True, f"monte-carlo-{side}-limit")


#: constants whose panels on one intervals page share one scale: log for all where any of
#: them wants it (:func:`panel_scales`). S1.1 (8x8) drew G13 [1.17, 10.4] GPa (8.9x) on a
#: linear panel, its top off under an arrow, beside G23 [0.199, 5.96] GPa (30x) whole on a
#: log one: the narrower interval (±109 % against ±170 %) looked the worse
SAME_SCALE = ("G13", "G23")


def _panel_marks(r: ResultFile, m: str, k: str) -> tuple[tuple, list]:
    """(marks, ends) of the panel of constant ``k`` of material ``m`` in the display unit, as
    :func:`wants_log_axis` takes them: the value and the reference's ends; the interval's,
    the Monte Carlo range's and, for a constant at a bound, its profile's (where the fit
    rejects it, or the end of a flat one's scan)."""
    u = r.uncertainty
    iv = u.get(m, k) if u is not None else None
    ref = r.reference.get(m, {}).get(k)
    g = (lambda z: _gpa(k, z))
    lo, hi = (iv.lower, iv.upper) if iv is not None else (np.nan, np.nan)
    rng = monte_carlo_range(u, iv)
    ends = [g(lo), g(hi)] + ([g(rng.lower), g(rng.upper)] if rng is not None else [])
    if iv is not None and iv.at_bound:
        ends += [g(getattr(iv, "profile_bound", np.nan))] + (
            [g(getattr(iv, "profile_far", np.nan))] if iv.profile_kind == "flat" else [])
    return (g(r.materials[m][k]), *(() if ref is None else (g(e) for e in ref))), ends


def panel_scales(r: ResultFile) -> dict[tuple[str, str], bool]:
    """{(material, constant): log} of the intervals page's panels: each by
    :func:`wants_log_axis`, except that the constants of :data:`SAME_SCALE` (the transverse
    shear moduli, of every material) are all log where any of them is, so that panels a
    reader compares side by side are on one scale (a log one can hold the narrow with the
    wide; a linear one cannot)."""
    log = {(m, k): wants_log_axis(k, *_panel_marks(r, m, k))
           for m in r.materials for k in CONSTANTS}
    if any(log[m, k] for m in r.materials for k in SAME_SCALE):
        for m in r.materials:
            for k in SAME_SCALE:
                marks, _ = _panel_marks(r, m, k)
                # (a mark <= 0 has no place on a log axis: such a panel stays linear)
                log[m, k] = all(x > 0 for x in marks if np.isfinite(x))
    return log


def _log_panel_limits(r: ResultFile, m: str, k: str, marks, ends) -> tuple[float, float]:
    """(ymin, ymax) of the panel of constant ``k`` of material ``m`` on a log scale, from its
    :func:`_panel_marks` (``marks``, ``ends``), before the decades its page may ask for: the
    value and the reference in view, the ends within :data:`LOG_PANEL_REACH` of the value,
    and the weak band; at a bound, room on the side the fit pushes it (the dashed arrow's).
    The panel's own, and the page's measure of the decades each such panel needs."""
    iv = r.uncertainty.get(m, k) if r.uncertainty is not None else None
    v = marks[0]
    reach = [e for e in ends if v / LOG_PANEL_REACH <= e <= v * LOG_PANEL_REACH]
    if iv is not None and iv.at_bound:
        down = (iv.bound_side or bound_statement(iv.bound_text)[0]) != "upper"
        return _log_limits(marks, reach, pad=(0.15, 0.06) if down else (0.06, 0.15))
    weak = r.uncertainty.weak
    return _log_limits((*marks, v * (1 - 1.2 * weak), v * (1 + 1.35 * weak)), reach)


def interval_panel(ax, r: ResultFile, m: str, k: str, *, x: float = 0.0,
                   log: bool | None = None, decades: float | None = None):
    """Value, interval, verdict bands and reference of constant ``k`` of material ``m``;
    ``log``: its scale (None: :func:`wants_log_axis` of its own numbers; the page gives
    :func:`panel_scales`'), ``decades``: on a log scale, the fewest decades its height spans
    (the page gives the widest of the :data:`SAME_SCALE` panels')."""
    u = r.uncertainty
    v = r.materials[m][k]
    iv = u.get(m, k) if u is not None else None
    fixed = fixed_words(r, m, k) is not None
    ref = r.reference.get(m, {}).get(k)
    lo, hi = (iv.lower, iv.upper) if iv is not None else (np.nan, np.nan)
    g = (lambda z: _gpa(k, z))
    nu = k == "nu12"
    # the reference's ends in the display unit: one value twice, or a range's low and high
    gref = () if ref is None else tuple(g(e) for e in ref)
    rng = monte_carlo_range(u, iv)
    at_bound = iv is not None and iv.at_bound
    # the ends drawn (display unit): interval, Monte Carlo range, a constant at a bound's
    # profile (where the fit rejects it, or the end of a flat one's scan)
    marks, ends = _panel_marks(r, m, k)
    if log is None:
        log = wants_log_axis(k, marks, ends)
    if log:
        # a decade and more: on a linear axis the value sat on 0 under the others
        ax.set_yscale("log")
        ymin, ymax = _log_panel_limits(r, m, k, marks, ends)
        d = np.log10(ymax / ymin)
        if decades is not None and d < decades:
            # as many decades as the panels it is compared with, about its own middle: a
            # length on it is the same ratio as on theirs
            ymin, ymax = ymin / 10 ** ((decades - d) / 2), ymax * 10 ** ((decades - d) / 2)
    elif at_bound:
        ymin, ymax = _bound_limits(g(v), iv.bound_side, gref, nu,
                                   g(getattr(iv, "profile_bound", np.nan)))
        far = g(getattr(iv, "profile_far", np.nan))
        if iv.profile_kind == "flat" and np.isfinite(far) and abs(far - g(v)) <= 2 * abs(g(v)):
            # a flat profile's other end in view where it is of the value's size (E2 55.5 ->
            # 0.9 GPa, nu12 0.95 -> 0); far beyond (G13 0.003 -> 18.5 GPa) it runs off
            ymin, ymax = _bound_limits(g(v), iv.bound_side, gref, nu, far)
    else:
        ymin, ymax = _panel_limits(g(v), g(lo), g(hi), gref, u.weak, nu)
    # verdict bands about an identified value only (none at a bound, none for a fixed value)
    if iv is not None and not iv.at_bound:
        a = abs(g(v))
        for frac, color in ((u.weak, BAND_COLORS[1]), (u.well_determined, BAND_COLORS[0])):
            ax.axhspan(g(v) - frac * a, g(v) + frac * a, color=color, lw=0, zorder=0)
    if iv is not None and iv.at_bound:
        _bound_panel(ax, k, g(v), iv, x, ymin, ymax)
    elif iv is not None:
        clo, chi = max(g(lo), ymin), min(g(hi), ymax)
        if not (np.isnan(clo) or np.isnan(chi)):
            ax.plot([x, x], [clo, chi], "-", color=INTERVAL_COLOR, lw=3,
                    solid_capstyle="butt", gid="interval")
            caps = [e for e, inside in ((clo, g(lo) >= ymin), (chi, g(hi) <= ymax)) if inside]
            ax.plot([x] * len(caps), caps, "_", ms=14, mew=2.5, color=INTERVAL_COLOR,
                    gid="interval-caps")
        for end, edge, up in ((hi, ymax, True), (lo, ymin, False)):
            if not np.isnan(end) and ((up and g(end) > ymax) or (not up and g(end) < ymin)):
                tail = _inward(ax, edge, 0.08, ymin, ymax, up)
                ax.annotate("", (x, edge), xytext=(x, tail),
                            arrowprops=dict(arrowstyle="-|>", color=INTERVAL_COLOR, lw=1.5))
                # (an end <= 0, of a linear interval, is off a log panel's foot: said so in
                # the legend)
                off_log = ax.get_yscale() == "log" and g(end) <= 0
                # (from the edge into the panel: centred on the arrow's foot, 8 % of a short
                # panel inside, the end's two lines ran over its frame, hybrid CM's glass
                # E1 "from 0.00272" over the panel's foot)
                ax.annotate(f"{'to' if up else 'from'}\n{fmt_value(k, end)}", (x, edge),
                            xytext=(5, -1 if up else 1), textcoords="offset points",
                            fontsize=7, va="top" if up else "bottom", ha="left",
                            color=INTERVAL_COLOR,
                            gid="interval-end-below-log" if off_log else "interval-end")
    if rng is not None:
        _monte_carlo_bar(ax, k, rng, x - 0.25, ymin, ymax)
    if fixed:                       # not a result: a hollow grey square, no band, no interval
        ax.plot([x], [g(v)], "s", ms=7, color=FIXED_COLOR, mfc="w", mew=1.5, zorder=5,
                gid="fixed")
    elif iv is not None and iv.at_bound:   # the limit it stopped on, pointing the fit's way
        side = iv.bound_side or bound_statement(iv.bound_text)[0]
        ax.plot([x], [g(v)], "^" if side == "upper" else "v", ms=8, color="k", mfc="w",
                zorder=5, gid="at-bound")
    else:
        hollow = iv is not None and iv.verdict.startswith("not")
        ax.plot([x], [g(v)], "o", ms=7, color="k", mfc="w" if hollow else "k", zorder=5,
                gid="value")
        if iv is not None and iv.verdict.endswith(HELD_BY_PRIOR):
            # mostly the file's prior, not the modes': a filled dot with a narrow interval
            # and a green band read as a constant the modes determine (S1.2 with prior
            # {nu12: 1.0}, 0.350 [0.347, 0.353] on its reference); the "~" of the page
            # across specimens and of the terminal's table
            ax.annotate(PRIOR_MARK, (x, g(v)), xytext=(6, 4), textcoords="offset points",
                        fontsize=12, weight="bold", color="k", gid="prior")
    if ref is not None and gref[0] == gref[1]:
        ax.plot([x + 0.25], [gref[0]], "D", ms=6, color="C3", zorder=5, gid="reference")
    elif ref is not None:
        # a range from low to high, not a point: what the other test allows
        ax.plot([x + 0.25] * 2, [max(gref[0], ymin), min(gref[1], ymax)], "-", color="C3",
                lw=4, solid_capstyle="butt", zorder=4, gid="reference-range")
    if ref is not None and not ymin <= gref[0] <= gref[1] <= ymax:
        ax.annotate(f"reference {fmt_reference(k, ref)} off scale", (0.5, 0.02),
                    xycoords="axes fraction", ha="center", fontsize=6.5, color="C3")
    ax.set_ylim(ymin, ymax)
    return iv


def _interval_legend(r: ResultFile) -> tuple[list, list[str]]:
    """Handles and labels of the interval page's legend (what is drawn on any panel)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    u = r.uncertainty
    items = [(Patch(color=BAND_COLORS[0], lw=0),
              f"interval within ±{u.well_determined:.0%} of the value: well determined"),
             (Patch(color=BAND_COLORS[1], lw=0), f"within ±{u.weak:.0%}: weak"),
             (Line2D([], [], color=INTERVAL_COLOR, lw=3, marker="_", ms=10, mew=2.5),
              f"{u.confidence:.0%} interval"),
             (Line2D([], [], ls="none", marker="o", ms=7, color="k"), "identified")]
    ivs = u.intervals
    hollow = [iv for iv in ivs if not iv.at_bound and iv.verdict.startswith("not")]
    if hollow:
        # a Monte Carlo verdict's interval may be narrow: its range is what is too wide
        items.append((Line2D([], [], ls="none", marker="o", ms=7, color="k", mfc="w"),
                      "not determined (interval" + (
                          " or Monte Carlo range" if any(iv.verdict_from_monte_carlo
                                                         for iv in hollow) else "")
                      + " too wide)"))
    if any(iv.at_bound for iv in ivs):
        items.append(((Line2D([], [], ls="none", marker="v", ms=7, color="k", mfc="w"),
                       Line2D([], [], ls="none", marker="^", ms=7, color="k", mfc="w")),
                      "stopped on a search limit: not identified"))
    bounded = any(np.isfinite(getattr(iv, "profile_bound", np.nan)) for iv in ivs)
    flat = any(iv.at_bound and iv.profile_kind == "flat" for iv in ivs)
    if bounded or flat:
        # dotted, without the end's cap (the cap hid the dots at a legend handle's length);
        # what its ends say where both kinds are drawn (a flat one's end has an arrow head)
        items.append((Line2D([], [], color=INTERVAL_COLOR, lw=2.5, ls=(0, (1, 1.5))),
                      "values the fit does not reject (profile)" + (
                          ";\ncap: it rejects beyond; arrow head: the end\nof its scan, "
                          "not tried beyond" if bounded and flat else
                          ";\narrow head: the end of its scan, not tried beyond" if flat
                          else "")))
    why = {fixed_words(r, m, k) for m in r.materials for k in CONSTANTS} - {None}
    if why:
        only = next(iter(why)) if len(why) == 1 else ""
        label = (only if only and "half-width" not in only else
                 "fixed because undetermined (not identified)" if all(
                     w.startswith("fixed because") for w in why) else
                 "fixed (not identified; why: below the panel)")
        items.append((Line2D([], [], ls="none", marker="s", ms=7, color=FIXED_COLOR, mfc="w",
                             mew=1.5), label))
    if any(not iv.at_bound and iv.verdict.endswith(HELD_BY_PRIOR) for iv in ivs):
        items.append((Line2D([], [], ls="none", marker=r"$\sim$", ms=8, color="k"),
                      f"{PRIOR_MARK}: held by its prior (mostly the file's prior value, "
                      "not the modes')"))
    refs = [r.reference.get(m, {}).get(k) for m in r.materials for k in CONSTANTS]
    if any(ref is not None and ref[0] == ref[1] for ref in refs):
        # a bare point reads as an exact value: say that the file gave it no uncertainty
        items.append((Line2D([], [], ls="none", marker="D", ms=6, color="C3"),
                      REFERENCE_POINT_WORDS))
    if any(ref is not None and ref[0] < ref[1] for ref in refs):
        items.append((Line2D([], [], color="C3", lw=4, solid_capstyle="butt"),
                      "reference range"))
    if u.monte_carlo and "lower" in u.monte_carlo:
        items.append((Line2D([], [], color="0.45", lw=2),
                      f"Monte Carlo range ({u.confidence:.0%} of the trials)"))
        if "inner_lower" in u.monte_carlo:
            sure = 100 * (2 * float(u.monte_carlo.get("evidence_level", 0.95)) - 1)
            items.append((Line2D([], [], color="0.2", lw=4.5),
                          f"Monte Carlo range for sure ({sure:.0f} %)"))
    return [h for h, _ in items], [t for _, t in items]


def panel_words(r: ResultFile, m: str, k: str, iv) -> str:
    """The words under a constant's panel: value, interval (or why there is none), verdict
    (with the Monte Carlo range's width where it set the verdict)."""
    v = r.materials[m][k]
    fixed = fixed_words(r, m, k)
    if fixed is not None:
        return f"{fmt_value(k, v)}\n" + "\n".join(
            ln for para in fixed.replace(" (", "\n(", 1).split("\n")
            for ln in textwrap.wrap(para, 26))
    if iv is None:
        return f"{fmt_value(k, v)}\nno interval"
    if iv.at_bound:
        words = bound_words(iv).replace("none — ", "")
        words += "" if "\n" in words else ":"        # "on lower search limit:" alone
        return f"{fmt_value(k, v)}\n{words}\nnot identified"
    text = f"{fmt_value(k, v)} " + interval_text(k, iv)
    verdict = short_verdict(iv.verdict)
    rng = monte_carlo_range(r.uncertainty, iv)
    if " (Monte Carlo)" in verdict and rng is not None:
        widths = monte_carlo_text(k, rng, v)[1]
        verdict = verdict.replace(" (Monte Carlo)", f" (Monte Carlo {widths})")
    return text + "\n" + "\n".join(textwrap.wrap(verdict, 24))


def interval_page(r: ResultFile):
    """One panel per constant (rows: materials), each in its unit and on its own scale."""
    u = r.uncertainty
    mats = list(r.materials)
    names, shortened = material_labels(r)
    fig = _figure()
    fig.suptitle(_title(r, None if r.joint else r.plates[0],
                        f"{u.confidence:.0%} confidence intervals"), fontsize=11)
    gs = fig.add_gridspec(len(mats) + 1, 6, height_ratios=[1] * len(mats) + [0.1])
    axes = np.array([[fig.add_subplot(gs[i, j]) for j in range(6)] for i in range(len(mats))])
    log_of = panel_scales(r)
    # the SAME_SCALE panels on log scales span as many decades each, the most any of them
    # needs (each panel's own log limits): S1.1 (8x8) drew G13 [1.17, 10.4] GPa over
    # 1.1 decades beside G23 [0.199, 5.96] over 1.6, two bars of one length for 8.9x and 30x
    spans = [np.log10(abs(np.divide(*_log_panel_limits(r, m, k, *_panel_marks(r, m, k))[::-1])))
             for m in mats for k in SAME_SCALE if log_of[m, k]]
    decades = max(spans) if spans else None
    for i, m in enumerate(mats):
        for j, k in enumerate(CONSTANTS):
            ax = axes[i, j]
            ax.set_gid(f"interval-{m}.{k}")
            iv = interval_panel(ax, r, m, k, log=log_of[m, k],
                                decades=decades if k in SAME_SCALE else None)
            ax.set_xlim(-0.75, 0.75)
            ax.set_xticks([])
            ax.tick_params(labelsize=7)
            unit = _unit(k)
            if ax.get_yscale() == "log":
                log_axis_ticks(ax)
                unit += ", log scale"
            name = f"{names[m]}\n{k} ({unit})" if len(mats) > 1 else f"{k} ({unit})"
            ax.set_title(name, fontsize=9)
            ax.set_xlabel(panel_words(r, m, k, iv), fontsize=7)
    scales = {iv.scale for iv in u.intervals}
    how = ("moduli: interval on ln P (asymmetric, > 0); nu12: linear" if "log" in scales
           else "linear intervals value ± half-width (as stored in this file)")
    handles, labels = _interval_legend(r)
    ax_leg = fig.add_subplot(gs[-1, :])
    ax_leg.axis("off")
    from matplotlib.legend_handler import HandlerTuple

    # the arrows of an interval or a Monte Carlo range off its panel: their words "to"/"from"
    arrow = any(t.get_text().startswith(("to\n", "from\n")) for a in axes.flat for t in a.texts)
    below = any(t.get_gid() == "interval-end-below-log" for a in axes.flat for t in a.texts)
    title = how
    if arrow:
        title += "; arrow: the interval or range runs off the panel to the value written"
    if below:
        title += " (an end ≤ 0 is below any log scale)"
    if decades is not None and sum(log_of[m, k] for m in mats for k in SAME_SCALE) > 1:
        # (a panel on a log scale that its own numbers, within a decade, would not need)
        forced = any(log_of[m, k] and not wants_log_axis(k, *_panel_marks(r, m, k))
                     for m in mats for k in SAME_SCALE)
        title += (f";\n{' and '.join(SAME_SCALE)} on one log scale"
                  + (", as one of them spans more than a decade" if forced else "")
                  + ": each panel over the same decades, a bar's length the same ratio on each")
    if any(iv.at_bound for iv in u.intervals):
        title += (";\ndashed arrow: the way the fit pushes a constant stopped on a search limit "
                  "(the value drawn is that limit)")
    if u.scale_used == "residuals":
        # the residuals' scatter, not the stated noise, set these widths (page 1 says so too)
        title += ";\nintervals " + interval_basis(u)
    if getattr(u, "spread_counted", ()):
        title += (";\nthe intervals count the spread the fixed "
                  + ", ".join(lab.rsplit(".", 1)[1] if len(r.materials) == 1 else lab
                              for lab in u.spread_counted)
                  + " had before fixing (see page 1 for the widths given them)"
                  + _mc_fixed_legend(u))
    if shortened:
        title += ";\n" + "\n".join(textwrap.wrap(shortened, _wrap_width(fig, 8) - 10))
    # as many columns as the page's width takes (up to four): hybrid CM with a Monte Carlo
    # (nine entries) ran its four columns off both edges of the page, and the constrained
    # layout squeezed the panels to half the page's width, their titles over each other
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    renderer = canvas.get_renderer()
    for ncol in range(min(len(handles), 4), 0, -1):
        legend = ax_leg.legend(handles, labels, loc="center", ncol=ncol, fontsize=8,
                               handler_map={tuple: HandlerTuple(ndivide=None)}, title=title,
                               title_fontsize=8)
        if legend.get_window_extent(renderer).width <= 0.97 * fig.bbox.width:
            break
    _status_banner(fig, r)
    _clear_bound_statements(fig, axes.flat)
    _shorten_crowded_mc_end_words(fig, axes.flat)
    _tidy_mc_limit_words(fig, axes.flat)
    return fig


def _tidy_mc_limit_words(fig, axes) -> None:
    """One "search limit (both ends)" where the words "search limit" of the two ends of a
    Monte Carlo bar run into each other: :func:`_limit_ends_together` joins them where the
    ends are near in the panel's height, but on a short panel words of ends farther apart
    meet as well (hybrid CM with measured damping and a Monte Carlo, 8x8: glass E2's range
    30-58 GPa, two "search limit" written over each other, the upper one over the frame).
    Then every word of a Monte Carlo bar that runs over the top or the foot of its panel is
    moved inside it: the joined words of near ends are centred on the bar's middle, which
    near the panel's foot put them over the frame and the value written under the panel
    (the same hybrid's glass G12, 0.0054-0.0060 GPa)."""
    axes = list(axes)
    pairs, words = [], []
    for ax in axes:
        up = [t for t in ax.texts if t.get_gid() == "monte-carlo-upper-limit"]
        low = [t for t in ax.texts if t.get_gid() == "monte-carlo-lower-limit"]
        if up and low:
            pairs.append((up[0], low[0]))
        words += [(ax, t) for t in ax.texts
                  if (t.get_gid() or "").startswith("monte-carlo") and t.get_text()]
    if not words:
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.get_layout_engine().execute(fig)     # the panels' final size, drawing nothing
    for up, low in pairs:
        if up.get_window_extent(renderer).overlaps(low.get_window_extent(renderer)):
            # the upper end's, hanging from it (as the joined words of near ends say)
            up.set_text("search\nlimit\n(both\nends)")
            low.remove()
    for ax, t in words:
        if t not in ax.texts:
            continue
        e, b = t.get_window_extent(renderer), ax.get_window_extent(renderer)
        if e.height >= b.height:
            continue
        dy = b.y0 - e.y0 if e.y0 < b.y0 else b.y1 - e.y1 if e.y1 > b.y1 else 0.0
        if dy:
            dx, dy0 = t.xyann
            t.xyann = (dx, dy0 + dy * 72.0 / fig.dpi)      # pixels to the offset's points


#: the gids of the words at the two ends of a Monte Carlo bar (:func:`_mc_end_label`)
MC_END_GIDS = {"upper": ("monte-carlo-upper-end", "monte-carlo-upper-limit"),
               "lower": ("monte-carlo-lower-end", "monte-carlo-lower-limit")}


def _shorten_crowded_mc_end_words(fig, axes) -> None:
    """Leave the "(for sure ...)" lines out of the words at both ends of a Monte Carlo bar
    where the two ends' words run into each other: on the short panels of hybrid CM with a
    Monte Carlo, glass nu12's "to 0.8603 (for sure 0.1822)" over its "from -0.6637 (for sure
    -0.4006) search limit", neither readable. The range's ends and "search limit" stay; the
    thick bar still shows the width for sure, and a verdict it set is under the panel."""
    import re

    pairs = []
    for ax in axes:
        ends = {side: [t for t in ax.texts if t.get_gid() in gids]
                for side, gids in MC_END_GIDS.items()}
        if ends["upper"] and ends["lower"] and any(
                "(for sure" in t.get_text() for t in ends["upper"] + ends["lower"]):
            pairs.append((ends["upper"][0], ends["lower"][0]))
    if not pairs:
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)                       # the constrained layout: the panels' final size
    for up, low in pairs:
        if up.get_window_extent(renderer).overlaps(low.get_window_extent(renderer)):
            for t in (up, low):
                t.set_text(re.sub(r"\n\(for sure\n[^)]*\)", "", t.get_text()))


def _clear_bound_statements(fig, axes) -> None:
    """Remove the words "stopped on the ... search limit: no interval" of a panel where they
    run into its profile's words: on panels made short by a long status (hybrid CM with its
    materials' long names, 14 lines of it) the two were written over each other, neither
    readable. The panel's triangle, its key in the legend and the words under the panel ("on
    upper search limit") say the same."""
    pairs = []
    for ax in axes:
        said = {t.get_gid(): t for t in ax.texts if t.get_gid() in ("bound-statement",
                                                                      "profile-label")}
        if len(said) == 2:
            pairs.append((ax, said["bound-statement"], said["profile-label"]))
    if not pairs:
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)                       # the constrained layout: the panels' final size
    for ax, statement, profile in pairs:
        if statement.get_window_extent(renderer).overlaps(profile.get_window_extent(renderer)):
            statement.remove()


def _mc_fixed_legend(u) -> str:
    """The interval page's words on what the Monte Carlo trials did with the values
    --fix-undetermined fixed: drew them from their spread before fixing (attr fixed_drawn of
    /uncertainty/monte_carlo), or, in older files, held them."""
    mc = u.monte_carlo
    if not mc or "lower" not in mc:
        return ""
    if str(mc.get("fixed_drawn", "") or ""):
        return (";\nthe Monte Carlo trials drew them from that spread too (shortened to the "
                "search's range): their range counts it")
    return ";\nthe Monte Carlo trials hold them fixed: their range is the width given them"


# ----------------------------------------------------------------------------------------------
# mode shapes


def mode_shape_grid(plate, k: int, n_sub: int = 6):
    """w0 of paired mode ``k`` on a fine triangulation: (x m, y m, triangles, w).

    Each element is sampled on an n_sub x n_sub grid of natural coordinates and w is
    interpolated with its eight serendipity shape functions, so the picture is the FE field
    and not a linear interpolation of the nodal values.
    """
    from laminid_cli.fe.element import shape_functions

    nodes, elements = plate.nodes, plate.elements
    w = plate.w[:, k]
    s = np.linspace(-1, 1, n_sub + 1)
    XI, ETA = np.meshgrid(s, s)
    N, _ = shape_functions(np.column_stack([XI.ravel(), ETA.ravel()]))     # (p, 8)
    xy = np.einsum("pa,eai->epi", N, nodes[elements])                      # (n_el, p, 2)
    ww = np.einsum("pa,ea->ep", N, w[elements])                             # (n_el, p)
    m = n_sub + 1
    i, j = np.meshgrid(np.arange(n_sub), np.arange(n_sub))
    p0 = (j * m + i).ravel()
    local = np.vstack([np.column_stack([p0, p0 + 1, p0 + m + 1]),
                       np.column_stack([p0, p0 + m + 1, p0 + m])])
    n_pts = m * m
    tris = (local[None, :, :] + (np.arange(elements.shape[0]) * n_pts)[:, None, None]).reshape(-1, 3)
    return xy[..., 0].ravel(), xy[..., 1].ravel(), tris, ww.ravel()


def mac(a, b) -> float:
    """Modal assurance criterion of two real shapes: (a.b)^2 / (a.a b.b)."""
    a, b = np.ravel(a), np.ravel(b)
    return float(np.dot(a, b) ** 2 / (np.dot(a, a) * np.dot(b, b)))


def initial_mac(plate) -> tuple[np.ndarray | None, str]:
    """MAC of each paired mode (w0 at the nodes) with the *initial* model's mode i, the mode
    measured mode i was paired with at the start (sorted order). The model is rebuilt from
    the specimen YAML stored in the result (its constants are the initial ones) on the same
    mesh. (None, reason) when it cannot be rebuilt."""
    n = plate.w.shape[1]
    try:
        nodes, w0 = _initial_shapes(plate.yaml, plate.path or "<result>", plate.mesh,
                                    plate.boundary, n)
    except Exception as exc:  # noqa: BLE001 - any failure: the page says MAC is not available
        return None, f"the initial model could not be rebuilt ({exc})"
    if nodes.shape != plate.nodes.shape or not np.allclose(nodes, plate.nodes, rtol=0,
                                                           atol=1e-9):
        return None, "the stored mesh differs from the rebuilt one"
    return np.array([mac(plate.w[:, k], w0[:, k]) for k in range(n)]), ""


@functools.lru_cache(maxsize=8)
def _initial_shapes(yaml_text: str, path: str, mesh: tuple, boundary: str, n: int):
    """(mesh nodes, w0 of the n lowest modes) of the specimen's model at its own constants."""
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import load_specimen_text

    # the result's stored specimen: its reader's warnings are the result's, on the report's
    # pages (they were logged on stderr as 'laminid report' drew the modes page)
    spec = load_specimen_text(yaml_text, path, log_warnings=False)
    fm = build_forward_model(spec, mesh, boundary=boundary)
    modes = fm.solve(None, n)
    return fm.plate.mesh.nodes, fm.plate.w_shape(modes.phi)


def _grid(n: int, aspect: float, width: float = 10.5, height: float = 6.4) -> tuple[int, int]:
    """(n_rows, n_cols) that draws n plates of height/width ``aspect`` largest on the page
    (each cell also needs room for a three-line title and tick labels: +0.95 in, +0.5 in)."""
    best, best_scale = (1, n), 0.0
    for ncol in range(1, n + 1):
        nrow = -(-n // ncol)
        scale = min(width / ncol - 0.5, (height / nrow - 0.95) / aspect)
        if scale > best_scale:
            best, best_scale = (nrow, ncol), scale
    return best


def mode_shape_pages(r: ResultFile, plate) -> list:
    """Pages of mode shapes: at most MODES_PER_PAGE per page, one grid (same plate size) on
    every page."""
    from matplotlib.ticker import MaxNLocator

    n = plate.w.shape[1]
    fr = plate.frequencies
    n_pages = -(-n // MODES_PER_PAGE)
    per_page = -(-n // n_pages)
    nrow, ncol = _grid(per_page, plate.b / plate.a)
    macs, why = initial_mac(plate)
    if macs is None:
        about = f"MAC not available: {why}"
    else:
        about = ("MAC: agreement of the fitted mode's w0 with the initial model's mode it was "
                 "first paired with (no measured shapes: frequencies only); near 1 = the same "
                 "mode family, low = the fit moved to another shape")
    figs = []
    for start in range(0, n, per_page):
        idx = list(range(start, min(n, start + per_page)))
        fig = _figure()
        page = f" ({len(figs) + 1}/{n_pages})" if n_pages > 1 else ""
        fig.suptitle(f"{plate.name}: mode shapes w0 of the model at the identified constants"
                     f"{page}\ncolour w / max|w|, black lines: nodal lines (w = 0); "
                     "axes x, y in mm",
                     fontsize=11)
        axes = fig.subplots(nrow, ncol, squeeze=False).ravel()
        cs = None
        for ax, k in zip(axes, idx):
            x, y, tris, ww = mode_shape_grid(plate, k)
            ww = ww / (np.max(np.abs(ww)) or 1.0)
            cs = ax.tricontourf(x * 1e3, y * 1e3, tris, ww, levels=np.linspace(-1, 1, 17),
                                cmap="RdBu_r")
            if ww.min() < 0 < ww.max():
                ax.tricontour(x * 1e3, y * 1e3, tris, ww, levels=[0.0], colors="k",
                              linewidths=1.3)
            ax.set_aspect("equal")
            ax.set_xlim(0, plate.a * 1e3)
            ax.set_ylim(0, plate.b * 1e3)
            ax.set_gid(f"mode-{k + 1}")
            # the model mode paired with it on a line of its own: "mode 1 (model mode 11):
            # 1124.8 Hz" ran into the next panel's title, the first off the page
            paired = f"\n(model mode {fr.model_mode[k]})" if fr.model_mode[k] != k + 1 else ""
            # the frequencies in page 1's digits (1 decimal put 125.05 measured beside 124.84
            # as "125.0" and "124.8", 203.50 beside 203.55 as the same "203.5")
            meas = (f"meas. {fr.measured[k]:.2f} Hz" if np.isfinite(fr.measured[k])
                    else "not measured")
            mac_t = f"\nMAC vs initial {macs[k]:.2f}" if macs is not None else ""
            ax.set_title(f"mode {k + 1}: {fr.model[k]:.2f} Hz{paired}\n{meas}{mac_t}",
                         fontsize=8)
            ax.xaxis.set_major_locator(MaxNLocator(3))
            ax.yaxis.set_major_locator(MaxNLocator(4))
            ax.tick_params(labelsize=7)
        for ax in axes[len(idx):]:
            ax.axis("off")
        if cs is not None:
            cb = fig.colorbar(cs, ax=axes.tolist(), shrink=0.6, ticks=[-1, 0, 1])
            cb.set_label("w / max|w|")
        _footer(fig, about, fontsize=7.5)
        figs.append(fig)
    return figs


# ----------------------------------------------------------------------------------------------
# history and sensitivities

_BOUND_WARNING = re.compile(r"(?:(\S+): )?(E1|E2|G12|G13|G23|nu12) (?:at its (?:minimum|maximum)"
                            r"|= [+-])")


def bound_hits(r: ResultFile) -> set[str]:
    """Labels "material.constant" that ended at a bound: ``at_bound`` of /uncertainty (schema
    2), else the optimiser's bound warning ("glass: G12 at its minimum ...")."""
    if r.uncertainty is not None and any(iv.at_bound for iv in r.uncertainty.intervals):
        return {iv.label for iv in r.uncertainty.intervals if iv.at_bound}
    hits = set()
    only = next(iter(r.materials)) if len(r.materials) == 1 else None
    for w in r.warnings + sum((p.warnings for p in r.plates), ()):
        if "bound" not in w:
            continue
        for m, k in _BOUND_WARNING.findall(w):
            if m or only:
                hits.add(f"{m or only}.{k}")
    return hits


def revisits(constants) -> np.ndarray:
    """(n,) bool: evaluation i is at the same point as an evaluation before i - 1 (not a step,
    a point evaluated again)."""
    C = np.asarray(constants, float)
    n = C.shape[0]
    if n < 3:
        return np.zeros(n, bool)
    _, first, inverse = np.unique(C, axis=0, return_index=True, return_inverse=True)
    same_as_previous = np.r_[False, np.all(C[1:] == C[:-1], axis=1)]
    return (first[np.ravel(inverse)] < np.arange(n) - 1) & ~same_as_previous


def marker_offsets(values, log: bool, step: float = 9.0) -> list[float]:
    """Horizontal offsets (points) for markers at ``values`` drawn at one abscissa, so that
    those that would cover each other (within 4 % on a log axis, 0.03 on a linear one) stand
    side by side, ``step`` apart and centred on it; 0 for a marker alone.

    >>> marker_offsets([0.0015, 0.0015, 12.0, 0.00151], log=True)
    [-9.0, 0.0, 0.0, 9.0]
    >>> marker_offsets([0.95, 0.5], log=False)
    [0.0, 0.0]
    """
    v = np.asarray(values, float)
    key = np.log(np.abs(v) + 1e-300) if log else v
    near = 0.04 if log else 0.03
    out = [0.0] * v.size
    order = sorted(range(v.size), key=lambda i: (key[i], i))
    group: list[int] = []
    for i in order + [None]:
        if i is not None and group and key[i] - key[group[-1]] <= near:
            group.append(i)
            continue
        for k, j in enumerate(sorted(group)):
            out[j] = (k - (len(group) - 1) / 2) * step
        group = [] if i is None else [i]
    return out


def history_page(r: ResultFile):
    """Objective, RMS residual and the free constants / initial value per evaluation."""
    hist = r.history
    ev = hist.evaluation
    fig = _figure()
    fig.suptitle(_title(r, None if r.joint else r.plates[0], "optimisation history"),
                 fontsize=11)
    ax_o, ax_r, ax_c, ax_n = fig.subplots(4, 1, sharex=True, height_ratios=[1, 1, 1.6, 0.8])
    ax_o.set_gid("objective")
    ax_c.set_gid("moduli")
    ax_n.set_gid("nu12")
    pts = "o-" if ev.size <= 200 else "-"             # points only while they stay apart
    # the reduced solver evaluates an earlier point again after enriching its basis (the
    # trust region's ratio): drawn apart, off the line (else it looks like a restart)
    again = revisits(hist.constants)
    on = ~again
    ax_o.semilogy(ev[on], hist.objective[on], pts, ms=2.5, lw=1, color="C0", label="objective")
    if again.any():
        ax_o.semilogy(ev[again], hist.objective[again], "o", ms=4.5, mfc="w", color="0.4",
                      mew=0.8, zorder=4, gid="revisit", linestyle="none",
                      label="an earlier point evaluated again\n(a check or a new pass, "
                            "not a step)")
    # reduced solver: trial points are predictions of the reduced model (error bound NaN);
    # only evaluations with a known error bound count as the lowest evaluated
    bound = hist.error_bound if hist.error_bound is not None else np.zeros(ev.size)
    known = np.isfinite(bound)
    if not known.all():
        # a light marker for a prediction and a dark one for a checked evaluation, both
        # over the line (a grey dot over the line's own marker read as one marker)
        ax_o.semilogy(ev[~known], hist.objective[~known], "o", ms=3.5, color="0.75",
                      mec="0.55", mew=0.5, zorder=3, gid="predicted",
                      label="reduced-model prediction (trial point, error not bounded)")
        ax_o.semilogy(ev[known], hist.objective[known], "o", ms=4.5, color="C0", mec="k",
                      mew=0.6, zorder=4, gid="checked",
                      label="checked: full model, or basis enriched there (error bounded)")
    pool = np.flatnonzero(known) if known.any() else np.arange(ev.size)
    best = int(pool[np.argmin(hist.objective[pool])])
    ax_o.semilogy(ev[best], hist.objective[best], "*", ms=10, color="C3", zorder=6,
                  label=f"lowest checked evaluation {hist.objective[best]:.3g}")
    if np.isfinite(r.objective) and r.objective > 0:
        ax_o.semilogy(ev[-1], r.objective, "D", ms=7, mfc="w", color="k", zorder=5,
                      gid="result", label=f"result {r.objective:.3g}")
    ax_o.set_ylabel("objective (Eq. 17)", fontsize=8)
    ax_o.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)
    ax_r.set_gid("rms")
    ax_r.semilogy(ev[on], hist.rms_residual_percent[on], pts, ms=2.5, lw=1, color="C1",
                  label="RMS residual")
    if not known.all():
        # the reduced model's predictions as on the objective's panel (a prediction below
        # the result read as a better point the fit had left)
        pred = on & ~known
        ax_r.semilogy(ev[pred], hist.rms_residual_percent[pred], "o", ms=3.5, color="0.75",
                      mec="0.55", mew=0.5, zorder=3, gid="rms-predicted", ls="none",
                      label="reduced-model prediction (error not bounded)")
        # and the checked evaluations as there (dark-edged), keyed: a small orange dot of
        # the line alone, unkeyed, left the reader to guess what the others were
        chk = on & known
        ax_r.semilogy(ev[chk], hist.rms_residual_percent[chk], "o", ms=4.5, color="C1",
                      mec="k", mew=0.6, zorder=4, gid="rms-checked", ls="none",
                      label="checked (error bounded)")
        ax_r.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)
    ax_r.set_ylabel("RMS residual (%)", fontsize=8)
    hits = bound_hits(r)
    multi = len(r.materials) > 1
    names, shortened = material_labels(r)
    shown_mod = shown_nu = 0
    fixed = {"mod": [], "nu": []}            # fixed constants: no line, named instead
    ends = []                                # (axes, last value, colour, label) at a bound
    for j, lab in enumerate(hist.labels):
        col = hist.constants[:, j]
        m, k = lab.rsplit(".", 1)
        short = f"{names.get(m, m)}.{k}"
        if m in r.materials and fixed_words(r, m, k) is not None:
            name = short if multi else k
            fixed["nu" if k == "nu12" else "mod"].append(
                f"{name} = {fmt_value(k, r.materials[m][k])}" if k == "nu12" else name)
            continue
        if col[0] == 0 or np.allclose(col, col[0], rtol=1e-12):
            continue                                          # never moved: flat line
        name = short if multi else k
        is_nu = lab.endswith(".nu12")
        ax = ax_n if is_nu else ax_c
        y = col if is_nu else col / col[0]
        style = "--" if (shown_nu if is_nu else shown_mod) >= 10 else "-"
        (line,) = ax.plot(ev[on], y[on], style, lw=1.2, label=name, gid=f"history-{lab}")
        if lab in hits:
            ends.append((ax, float(y[-1]), line.get_color(), lab))
        if is_nu:
            shown_nu += 1
        else:
            shown_mod += 1
    from matplotlib.transforms import offset_copy

    for ax in (ax_c, ax_n):
        mine = [e for e in ends if e[0] is ax]
        # the X of each constant at a bound, side by side where they fall on one another
        # (hybrid CM's glass G12, G13 and G23 all end at 1e-4 E1 from the same initial
        # value: one X showed, the others' colours hidden under it)
        shifts = marker_offsets([e[1] for e in mine], log=ax is ax_c)
        for (_, value, color, lab), dx in zip(mine, shifts):
            ax.plot(ev[-1], value, "X", ms=9, color=color, mec="k", zorder=5,
                    gid=f"bound-{lab}",
                    transform=offset_copy(ax.transData, fig=fig, x=dx, units="points"))
    ax_c.set_yscale("log")
    ax_c.axhline(1, color="k", lw=0.5)
    ax_c.set_ylabel("modulus / initial value", fontsize=8)
    ax_n.set_ylabel("nu12 (–)", fontsize=8)
    ax_n.set_xlabel("evaluation", fontsize=8)       # as the panels' y labels
    for ax, which in ((ax_c, "mod"), (ax_n, "nu")):
        title = ("fixed, not identified:\n" + "\n".join(textwrap.wrap(
            ", ".join(fixed[which]), 30))) if fixed[which] else None
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0,
                      ncol=1 if len(ax.get_lines()) < 14 else 2, title=title,
                      title_fontsize=7)
        elif title:                         # nothing identified here: say why it is empty
            ax.text(0.5, 0.5, title.replace(":\n", ": "), transform=ax.transAxes,
                    ha="center", va="center", fontsize=8, color=FIXED_COLOR, gid="fixed-note")
            ax.set_yticks([])
    from matplotlib.ticker import MaxNLocator

    for ax in (ax_o, ax_r, ax_c, ax_n):
        ax.tick_params(labelsize=7)
        ax.grid(lw=0.3, which="major")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        if ax.get_yscale() == "log":
            lo, hi = ax.get_ylim()
            log_axis_ticks(ax, plain=False)
            if ax in (ax_o, ax_r):
                # down to a labelled tick under the lowest point: the value the fit ended on
                # (the lowest, as a rule) is read against a number (S1.3's RMS 0.244 % had
                # none under 1 %); the tick under the point, not under the margin below it
                # (hybrid CM's 0.14 % went down to 0.01)
                ys = np.concatenate([np.asarray(ln.get_ydata(), float) for ln in ax.get_lines()])
                low = np.min(ys[np.isfinite(ys) & (ys > 0)], initial=hi)
                below = [t for t in ax.yaxis.get_major_locator().tick_values(lo / 10, hi)
                         if t <= low * (1 + 1e-9)]
                if below and max(below) < lo:
                    ax.set_ylim(max(below), hi)
    notes = []
    if hits:
        notes.append("X: constant that ended at a bound of the feasible set (not identified): "
                     + ", ".join(sorted(hits)))
    if shortened and multi:
        notes.append(shortened)
    if notes:
        _footer(fig, "\n".join(notes), color=CHECK_COLOR if hits else "k")
    return fig


#: the text of a mode the fit did not use, on the sensitivity page
UNUSED_COLOR = "0.5"
#: the header, hatching and key of a constant on a search limit, on the sensitivity page
LIMIT_COLOR = "#b35900"


def unused_modes(plate) -> dict[int, str]:
    """{row (0-based): why} of the modes of ``plate`` the fit did not use: "not measured" (no
    measured frequency) or "weight 0, not fitted"."""
    fr = plate.frequencies
    out = {}
    for i in range(np.size(fr.model)):
        if not np.isfinite(fr.measured[i]):
            out[i] = "not measured"
        elif fr.weight[i] == 0:
            out[i] = "weight 0, not fitted"
    return out


def sensitivity_page(r: ResultFile, plate):
    """Heat map of the normalised sensitivities d ln f_i / d ln P_j at the optimum."""
    S = plate.sensitivity
    full = list(plate.sensitivity_labels) or [f"P{j + 1}" for j in range(S.shape[1])]
    names, shortened = material_labels(r)
    labels = ([lab.rsplit(".", 1)[-1] for lab in full] if len(r.materials) == 1 else
              [f"{names.get(m, m)}.{k}" for m, k in (lab.rsplit(".", 1) for lab in full)])
    # a constant that stopped on a search limit is not identified: its column is the
    # sensitivity at the limit value, said in its header and hatched (drawn as an identified
    # one's, hybrid CM's glass G12, G13, G23 and E2 at their limits read as determined)
    hits = bound_hits(r) if hasattr(r, "warnings") else set()
    on_limit = [j for j, lab in enumerate(full) if lab in hits]
    labels = [lab + ("\n(on limit)" if j in on_limit else "") for j, lab in enumerate(labels)]
    model = plate.frequencies.model
    fig = _figure()
    fig.suptitle(f"{plate.name}: normalised sensitivity ∂ ln fᵢ / ∂ ln Pⱼ at the optimum\n"
                 "a column near 0: the frequencies do not determine that constant",
                 fontsize=11)
    ax = fig.subplots()
    ax.set_gid("sensitivity")
    vmax = float(np.nanmax(np.abs(S))) or 1.0
    im = ax.imshow(S, cmap="RdBu_r", vmin=-vmax, vmax=vmax, aspect="auto")
    rot = S.shape[1] > 6
    ax.set_xticks(range(S.shape[1]), labels, rotation=30 if rot else 0,
                  ha="right" if rot else "center", fontsize=8)
    # a mode the fit did not use (not measured, or weight 0) determines nothing: its row is
    # said and faded, as the terminal's table says "(weight 0)" (the page drew it as a
    # measured mode's: S1.2's mode 5, not measured, looked as if it pinned E1)
    unused = unused_modes(plate)
    ax.set_yticks(range(S.shape[0]), [f"mode {i + 1}: {f:.1f} Hz" + (f"\n({unused[i]})"
                                                                       if i in unused else "")
                                      for i, f in enumerate(model)], fontsize=8)
    for i, t in enumerate(ax.get_yticklabels()):
        if i in unused:
            t.set_color(UNUSED_COLOR)
    from matplotlib.patches import Rectangle

    for j in on_limit:
        ax.get_xticklabels()[j].set_color(LIMIT_COLOR)
        ax.add_patch(Rectangle((j - 0.5, -0.5), 1, S.shape[0], facecolor="w", alpha=0.55,
                               hatch="//", edgecolor=LIMIT_COLOR, lw=0,
                               gid=f"on-limit-{full[j]}"))
    fs = 8 if S.size <= 150 else 6
    for i in range(S.shape[0]):
        if i in unused:
            ax.axhspan(i - 0.5, i + 0.5, color="w", alpha=0.7, lw=0, gid=f"unused-{i + 1}")
        for j in range(S.shape[1]):
            v = S[i, j]
            # the terminal's 3 decimals, a value that rounds to 0 without its minus ("0" read
            # as exactly none beside 0.001)
            ax.text(j, i, f"{v if abs(v) >= 5e-4 else 0.0:.3f}", ha="center",
                    va="center", fontsize=fs, color=UNUSED_COLOR if i in unused else
                    "w" if abs(v) > 0.6 * vmax else "k")
    # (plain text, no mathtext: its parser is the one thing of this page a report built
    # nowhere else, ~0.3 s of every report command)
    ax.set_xlabel("ply constant Pⱼ" + (f" ({next(iter(r.materials))})"
                                         if len(r.materials) == 1 else ""))
    ax.set_ylabel("measured mode i (model frequency)")
    cb = fig.colorbar(im, ax=ax, shrink=0.8)
    cb.set_label("∂ ln fᵢ / ∂ ln Pⱼ")
    keys = []
    if on_limit:
        limited = ", ".join(labels[j].split("\n")[0] for j in on_limit)
        keys.append(f"hatched, \"(on limit)\": {limited} stopped on a search limit, not "
                    "identified; its column is the sensitivity at that limit value, not a "
                    "determined constant's (see the intervals page)")
    if shortened and len(r.materials) > 1:
        keys.append(shortened)
    if keys:
        # (a figure label: the constrained layout keeps room for it under the axes' label)
        fig.supxlabel("\n".join(ln for key in keys for ln in textwrap.wrap(
            key, _wrap_width(fig, 8))), fontsize=8,
            color=LIMIT_COLOR if on_limit else "k").set_gid(
            "on-limit-key" if on_limit else "names-key")
    return fig


# ----------------------------------------------------------------------------------------------
# FRF


def frf_source(plate, frf_path=None, result_path=None):
    """(path, bands, n_modes, own) of the FRF file the plate was fitted from, or None; ``own``
    False for ``frf_path``.

    ``frf_path`` overrides; otherwise ``measured.frf_file`` of the stored specimen YAML,
    relative to the specimen's folder: the stored path's (as identify was given it: relative
    to the folder it ran in), else, where both are relative, the specimen's folder as stored
    (``plate.folder``, absolute), else the folder of the result file ``result_path``
    (identify's default result lies beside its specimen). The report of
    ``identify plate.yaml`` made from another folder had no FRF page ("FRF file plate.frf.h5
    of the specimen not found"), though the FRF file lay beside the result.
    """
    import yaml

    try:
        doc = yaml.safe_load(plate.yaml)
        m = doc.get("measured", {}) if isinstance(doc, dict) else {}
    except (yaml.YAMLError, AttributeError):
        m = {}
    bands = None
    if isinstance(m, dict) and m.get("bands"):
        try:
            bands = [tuple(float(v) for v in str(b).split(":")) for b in m["bands"]]
        except ValueError:
            bands = None
    n_modes = int(m["modes"]) if isinstance(m, dict) and m.get("modes") else None
    if frf_path is not None:
        return Path(frf_path), bands, n_modes, False
    if not isinstance(m, dict) or not m.get("frf_file"):
        return None
    p = Path(plate.path or ".").parent / str(m["frf_file"])
    if not p.is_absolute():
        # where the command that made the result ran elsewhere: the specimen's folder as
        # stored (absolute; in result files written since it is), else the result's folder
        for folder in (getattr(plate, "folder", ""),
                       "" if result_path is None else str(Path(result_path).parent)):
            if not p.exists() and folder and (Path(folder) / str(m["frf_file"])).exists():
                p = Path(folder) / str(m["frf_file"])
    if not p.exists():
        log.warning("FRF file %s of the specimen not found: no FRF page", p)
        return None
    return p, bands, n_modes, True


#: relative difference of an RFP frequency from the one the identification used above which
#: the FRF file is not the one identified from: the same file fits the same to ~1e-15 on one
#: machine (another BLAS may differ in the last digits of an ill-conditioned fit: hence not
#: 1e-12), while a point added or a record replaced moves the frequencies by ~1e-5 and more
FRF_CHANGED_REL = 1e-6


def frf_fit_changed(fit_hz, measured_hz) -> str | None:
    """None when the RFP frequencies of an FRF file, fitted now, are those the identification
    used (``measured_hz``, the result's measured frequencies); else what differs, in words."""
    fit_hz = np.asarray(fit_hz, float)
    measured_hz = np.asarray(measured_hz, float)
    why = "not the FRFs identified from (the file changed since)"
    if fit_hz.shape != measured_hz.shape:
        return (f"its fit now gives {fit_hz.size} modes, the identification used "
                f"{measured_hz.size} frequencies: {why}")
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.abs(fit_hz - measured_hz) / np.abs(measured_hz)
    # a mode the fit no longer finds (NaN) where the identification had one: changed
    rel = np.where(np.isnan(measured_hz), 0.0, np.where(np.isnan(fit_hz), np.inf, rel))
    i = int(np.argmax(rel))
    if not rel[i] > FRF_CHANGED_REL:
        return None
    if np.isnan(fit_hz[i]):
        return (f"its fit now finds no mode {i + 1}, the identification used "
                f"{measured_hz[i]:.10g} Hz: {why}")
    return (f"its fit now gives mode {i + 1} at {fit_hz[i]:.10g} Hz, the identification used "
            f"{measured_hz[i]:.10g} Hz ({fit_hz[i] - measured_hz[i]:+.2g} Hz, "
            f"{rel[i] * 100:.2g} %): {why}")


def frf_page(r: ResultFile, plate, frf_path, bands=None, n_modes=None, own: bool = True):
    """Measured FRFs (over the RFP fit), phase, coherence, RFP and model frequencies. ``own``:
    the specimen's ``measured.frf_file``, whose fit gave the frequencies identified from (the
    page says when it no longer does); a file given with ``report --frf`` may have been
    fitted with other bands (``fit-frf --band ... --into``), and is drawn as it is."""
    from laminid_cli.frf import rfp
    from laminid_cli.frf.io import read_frf
    from laminid_cli.frf.plot import draw_frf, has_coherence

    fs = read_frf(frf_path)
    for warning in fs.meta.get("warnings") or ():   # each names the file
        log.warning("%s", warning)
    for note in fs.meta.get("notes") or ():     # the reader's (a CSV phase unit assumed)
        # (a note that names the file already, as the unit's, is not prefixed twice)
        named = note.startswith(f"{Path(frf_path)}: ")
        log.warning("%s", note if named else f"{frf_path}: {note}")
    fit = rfp.find_modes(fs.freq, fs.frf, bands=bands, n_modes=n_modes)
    fig = _figure()
    fig.suptitle(f"{plate.name}: FRFs of {Path(frf_path).name} with the RFP fit", fontsize=11)
    changed = frf_fit_changed(fit.freq_hz, plate.frequencies.measured) if own else None
    if changed:
        log.warning("%s: %s", frf_path, changed)
        _footer(fig, f"{Path(frf_path).name}: {changed}", color=CHECK_COLOR,
                weight="bold", gid="frf-changed")
    coh = has_coherence(fs.coherence)
    ratios = [3, 1.4] + ([0.9] if coh else [])
    axes = fig.subplots(len(ratios), 1, sharex=True, height_ratios=ratios)
    ax_m, ax_p = axes[0], axes[1]
    ax_m.set_gid("frf")
    # the RFP frequencies in page 1's digits (1 decimal labelled its 124.98 Hz "125.0")
    # (their sigmas as fit-frf and an frf_file's identify take them: the legend gives the span)
    sig = rfp.measurement_sigma(fit, fs.freq, exp_window_s=rfp.window_time_constant(fs))
    draw_frf(ax_m, ax_p, fs.freq, fs.frf, fit, units=fs.units, coherence=fs.coherence,
             ax_c=axes[2] if coh else None, decimals=2, sigma_hz=sig.sigma_hz)
    for i, f in enumerate(plate.frequencies.model):
        ax_m.axvline(f, color="C3", ls=":", lw=1.2, label="model (identified)" if i == 0
                     else None)
    ax_m.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4, fontsize=8,
                frameon=False)                  # above the panel: clear of the curves
    axes[-1].set_xlabel("frequency (Hz)")
    return fig


# ----------------------------------------------------------------------------------------------
# assembling the pages

#: Extra page makers, called as ``fn(result_file) -> list[Page]`` after the sensitivities of a
#: result (single or joint); e.g. a damping page appends itself here.
def _damping_pages(r: ResultFile) -> list[Page]:
    """The damping page (laminid_cli.report_damping) of a result with /damping."""
    if r.damping is None:
        return []
    from laminid_cli.report_damping import damping_figures

    return [Page(name, fig) for name, fig in damping_figures(r)]


EXTRA_PAGES: list = [_damping_pages]


def _read(path) -> ResultFile:
    from laminid_cli.resultfile import ResultFileError

    try:
        return read_result(path)
    except ResultFileError as exc:
        raise ReportError(str(exc)) from exc


def result_pages(path, *, frf_path=None) -> list[Page]:
    """All pages of the report of one result file (single or joint): ``path`` to it, or the
    :class:`ResultFile` read from it."""
    r = path if isinstance(path, ResultFile) else _read(path)
    if r.joint:
        return joint_pages(r, frf_path=frf_path)
    plate = r.plates[0]
    pages = [Page("summary", summary_page(r))]
    if r.uncertainty is not None and r.uncertainty.intervals:
        pages.append(Page("intervals", interval_page(r)))
    pages += [Page(f"modes-{k + 1}", fig) for k, fig in enumerate(mode_shape_pages(r, plate))]
    if r.history is not None:
        pages.append(Page("history", history_page(r)))
    if plate.sensitivity is not None:
        pages.append(Page("sensitivities", sensitivity_page(r, plate)))
    for fn in EXTRA_PAGES:
        pages += fn(r)
    src = frf_source(plate, frf_path, r.path)
    if src is not None:
        pages.append(Page("frf", frf_page(r, plate, *src)))
    for page in pages:                   # every page says the result's status
        status_corner(page.figure, r)
    return pages


def joint_pages(r: ResultFile, *, frf_path=None) -> list[Page]:
    """Shared constants (summary, intervals, history), then per plate its frequencies, mode
    shapes and sensitivities (and FRF page when it has an FRF file)."""
    pages = [Page("shared", summary_page(r, what=f"joint identification of {len(r.plates)} "
                                                  "plates, shared constants"))]
    if r.uncertainty is not None and r.uncertainty.intervals:
        pages.append(Page("intervals", interval_page(r)))
    if r.history is not None:
        pages.append(Page("history", history_page(r)))
    for fn in EXTRA_PAGES:
        pages += fn(r)
    for plate in r.plates:
        tag = re.sub(r"[^A-Za-z0-9_.-]", "_", plate.name)
        pages.append(Page(f"{tag}-frequencies", plate_frequency_page(r, plate)))
        pages += [Page(f"{tag}-modes-{k + 1}", fig)
                  for k, fig in enumerate(mode_shape_pages(r, plate))]
        if plate.sensitivity is not None:
            pages.append(Page(f"{tag}-sensitivities", sensitivity_page(r, plate)))
        src = frf_source(plate, None, r.path)
        if src is not None:
            pages.append(Page(f"{tag}-frf", frf_page(r, plate, *src)))
    for page in pages:                   # every page says the result's status
        status_corner(page.figure, r)
    return pages


def plate_frequency_page(r: ResultFile, plate):
    """One plate of a joint result: frequency table and residuals, laminate properties."""
    fig = _figure()
    fig.suptitle(_title(r, plate, "measured vs model (joint fit)"), fontsize=11)
    # the laminate's properties under the table (they stood at the foot of the page, some
    # 3 inches of blank under a 12-mode table)
    below = frequency_block(fig, fig.add_gridspec(1, 1)[0, 0], plate)
    ax = fig.add_subplot(below)
    ax.axis("off")
    ax.text(0, 1, "\n".join(textwrap.wrap(_laminate_text(plate), 150)), fontsize=7.5,
            va="top", transform=ax.transAxes, gid="laminate")
    _status_banner(fig, r)
    return fig


# ----------------------------------------------------------------------------------------------
# batch summary


def summary_pages(path) -> list[Page]:
    """Pages of the report of a batch summary (summary.csv or summary.json). The doubt of
    every constant (interval, verdict, at a bound, fixed, Monte Carlo range) is the summary's
    own; the result files, where found, add the reference values (and the doubt for a wide
    CSV written before its interval columns, which has none)."""
    from laminid_cli.batch import NOT_FROM_BATCH, read_summary

    # a result file the batch found in its folder but did not make is no specimen of it
    rows = [r for r in read_summary(path) if r.get("status") != NOT_FROM_BATCH]
    done = []
    for row in rows:
        res = row.get("result")
        r = None
        if res and Path(res).exists():
            try:
                r = read_result(res)
            except LaminidError as exc:
                log.warning("%s: %s; using the summary's numbers", row["name"], exc)
        mats = row["materials"] or (r.materials if r is not None else {})
        if mats:
            done.append((row, mats, r))
    if not done:
        raise ReportError(f"{path}: no identified specimen in the summary")
    # the specimens of the summary without a result (failed, not run): named under the
    # constants, which cannot draw them (page 2 gives their reasons)
    drawn = {id(row) for row, _, _ in done}
    absent = [f"{row['name']} ({row.get('status') or 'no result'})" for row in rows
              if id(row) not in drawn]
    pages = [Page("constants", constants_across_page(done, Path(path).name, absent)),
             Page("residuals", residuals_across_page(rows, Path(path).name))]
    if any(row.get("damping") for row in rows):
        from laminid_cli.report_damping import summary_damping_pages

        # the summary holds no confidence level: the result files' (one level for all)
        levels = {float(r.damping.attrs["confidence"]) for _, _, r in done
                  if r is not None and r.damping is not None and "confidence" in r.damping.attrs}
        pages += [Page(name, fig) for name, fig in summary_damping_pages(
            rows, Path(path).name, levels.pop() if len(levels) == 1 else None)]
    return pages


@dataclass
class Doubt:
    """What is known of one constant of one specimen in a batch summary (SI): its interval
    (NaN where it has none), verdict, whether it stopped on a search limit (side, limit) or
    was fixed, and its Monte Carlo range (NaN without one); of a constant at its bound the
    profile's kind ("bound", "flat", "none", "": resultfile.profile_kind) and bound (SI)."""

    lower: float = np.nan
    upper: float = np.nan
    verdict: str = ""
    at_bound: bool = False
    bound_side: str = ""
    bound_limit: float = np.nan
    fixed: bool = False
    mc_lower: float = np.nan
    mc_upper: float = np.nan
    mc_lower_at_limit: bool = False
    mc_upper_at_limit: bool = False
    profile: str = ""
    profile_bound: float = np.nan
    profile_far: float = np.nan
    #: all that is known is a --wide summary.csv's ``flagged`` column (one written before its
    #: interval columns; its result file not found): at a bound (side not stated),
    #: undetermined, fixed, or none of them; no interval
    flag_only: bool = False

    @property
    def undetermined(self) -> bool:
        return not self.at_bound and not self.fixed and self.verdict.startswith("not")

    @property
    def held_by_prior(self) -> bool:
        """Determined, but mostly by the file's prior (its verdict "... (held by the prior)"),
        not by the modes."""
        return (not self.at_bound and not self.fixed and not self.undetermined
                and self.verdict.endswith(HELD_BY_PRIOR.strip()))


def _si(v) -> float:
    return np.nan if v is None else float(v)


def _doubt_of_flag(row, m: str, k: str) -> Doubt | None:
    """The :class:`Doubt` a --wide summary.csv's ``flagged`` column gives constant ``k`` of
    material ``m`` where the summary has no interval columns (written before them;
    ``flag_only``: no interval, no side of a bound); None for a row without the column (a wide
    summary written before it)."""
    flags = row.get("flagged")
    if not isinstance(flags, dict) or m not in (row.get("materials") or {}):
        return None
    word = flags.get(m, {}).get(k, "")
    if word in ("fixed", "assumed"):                   # assumed: fixed by --fix-undetermined
        return Doubt(verdict=VERDICT_FIXED, fixed=True, flag_only=True)
    if word == "at_bound":
        return Doubt(verdict=VERDICT_AT_BOUND, at_bound=True, flag_only=True)
    if word == "prior":
        return Doubt(verdict=HELD_BY_PRIOR.strip(), flag_only=True)
    return Doubt(verdict=VERDICT_NOT if word == "undetermined" else "", flag_only=True)


def doubt_of_row(row, m: str, k: str, r: ResultFile | None = None) -> Doubt | None:
    """The :class:`Doubt` of constant ``k`` of material ``m`` from the summary row's own
    columns (summary.json, long summary.csv, a wide one's interval and verdict columns, which
    do not say the side of a bound); from the result file ``r`` only when the row has none (a
    wide summary.csv written before those columns), and the profile of a constant at a bound
    where the row has none (a wide one written before its profile columns); None when neither
    says anything."""
    e = (row.get("intervals") or {}).get(m, {}).get(k)
    if e is not None and "profile" not in e and e.get("at_bound") and r is not None \
            and r.uncertainty is not None and r.uncertainty.get(m, k) is not None:
        # a wide summary.csv written before its profile columns (wide_bound_columns): its
        # result file's profile where found
        # (hybrid CM's glass G12, rejected above 18.5 GPa, and E2, flat to 0.9 GPa, were bare
        # triangles beside the long summary's dotted profiles)
        iv = r.uncertainty.get(m, k)
        e = dict(e, profile=iv.profile_kind,
                 profile_bound=iv.profile_bound if np.isfinite(iv.profile_bound) else None,
                 profile_far=iv.profile_far if np.isfinite(iv.profile_far) else None)
    if e is not None:
        verdict = str(e.get("verdict") or "")
        profile = profile_kind(e.get("profile_bound"), "") or str(e.get("profile") or "")
        return Doubt(
            lower=_si(e.get("lower")), upper=_si(e.get("upper")), verdict=verdict,
            at_bound=bool(e.get("at_bound")) or verdict.startswith("at bound"),
            bound_side=str(e.get("bound_side") or ""), bound_limit=_si(e.get("bound_limit")),
            fixed=verdict == "fixed", mc_lower=_si(e.get("mc_lower")),
            mc_upper=_si(e.get("mc_upper")),
            mc_lower_at_limit=bool(e.get("mc_lower_at_limit")),
            mc_upper_at_limit=bool(e.get("mc_upper_at_limit")),
            profile=profile,
            profile_bound=_si(e.get("profile_bound")),
            # no profile reached no end (summaries before that fix gave the planned one)
            profile_far=np.nan if profile == "none" else _si(e.get("profile_far")))
    if r is None or m not in r.materials:
        return _doubt_of_flag(row, m, k)
    if fixed_words(r, m, k) is not None:
        return Doubt(verdict="fixed", fixed=True)
    iv = r.uncertainty.get(m, k) if r.uncertainty is not None else None
    if iv is None:
        return None
    d = Doubt(iv.lower, iv.upper, iv.verdict, iv.at_bound, iv.bound_side, iv.bound_limit,
              profile=iv.profile_kind, profile_bound=iv.profile_bound,
              profile_far=iv.profile_far)
    rng = monte_carlo_range(r.uncertainty, iv)
    if rng is not None:
        d.mc_lower, d.mc_upper = rng.lower, rng.upper
        d.mc_lower_at_limit, d.mc_upper_at_limit = rng.lower_at_limit, rng.upper_at_limit
    return d


def _row_check(row, r) -> str:
    """"" when the specimen's result is ok, else its status with the reason codes ("check:
    at_bound, undetermined"; "failed: ..." for a specimen without a result): the summary's
    own status, the result file's only for a row without one."""
    if not row.get("status") and r is not None and r.status is not None:
        if r.status.status == "ok":
            return ""
        return f"{r.status.status}: {', '.join(x.code for x in r.status.reasons)}"
    if row.get("status") == "ok":
        return ""
    why = str(row.get("reason") or "")
    return f"{row.get('status', '')}: {why}" if why else str(row.get("status", ""))


def specimen_labels(rows) -> list[str]:
    """The label of each summary row: the specimen's name (as on the pages of its result),
    or the batch name (folder/stem) when two rows share a specimen name."""
    names = [str(row.get("specimen") or row["name"]) for row in rows]
    return [n if names.count(n) == 1 else str(row["name"]) for n, row in zip(names, rows)]


#: the most characters of a specimen's name under the panels across specimens: a lab's name
#: ("S1.1 panel B-07 (autoclave batch 2026-11, edges trimmed, re-tested after drop)"), rotated
#: there, took the page's height from the panels (squeezed to a strip) and ran off its left
#: edge; a longer name is shortened in the middle and given whole in the page's notes
AXIS_NAME_CHARS = 24


def axis_names(names, limit: int = AXIS_NAME_CHARS,
               said: str = "names shortened under the panels") -> tuple[list[str], str | None]:
    """The specimens' names as ticks under a panel (each at most ``limit`` characters: its
    start and end kept, "…" between), and the note naming each shortened one whole, ``said``
    first (None when none is). Two names shortened alike get their place in the row after
    them ("#2").

    >>> axis_names(["S1.1", "S1.1 panel B-07 (autoclave batch 2026-11)"])[0]
    ['S1.1', 'S1.1 panel B-07…2026-11)']
    """
    head = (limit - 1) * 2 // 3
    tail = limit - 1 - head
    short = [n if len(n) <= limit else n[:head].rstrip() + "\u2026" + n[-tail:].lstrip()
             for n in names]
    short = [s if short.count(s) == 1 or s == n else f"{s} #{i + 1}"
             for i, (s, n) in enumerate(zip(short, names))]
    pairs = [f"{s} = {n}" for s, n in zip(short, names) if s != n]
    return short, (f"{said}: " + "; ".join(pairs)) if pairs else None


#: the most characters of a material's name in the labels of a result's pages (the
#: constants table's first column, the interval panels' titles, the sensitivity columns, the
#: history's legend): a lab's name ("E-glass 7781 woven fabric / Hexcel 913 epoxy (batch
#: 2026-11)") hid the constant of each table row under the next cell, ran the panels' titles
#: into each other and squeezed the history's panels to a third of the page
MATERIAL_LABEL_CHARS = 18


def material_labels(r: ResultFile) -> tuple[dict[str, str], str | None]:
    """{material: its name in the pages' labels} (shortened in the middle beyond
    :data:`MATERIAL_LABEL_CHARS`, as :func:`axis_names`), and the note naming each shortened
    one whole (None when none is)."""
    mats = list(r.materials)
    short, note = axis_names(mats, MATERIAL_LABEL_CHARS, "materials shortened in the labels")
    return dict(zip(mats, short)), note


MC_COLOR = "0.62"


def mc_tint(color) -> tuple:
    """A Monte Carlo bar's colour on the pages across specimens: its material's ``color``
    half-way to white. Grey, the bars of two materials of one specimen side by side (hybrid
    CM's glass and carbon) could be pinned on either: the glass bar, right of the glass dot,
    stands next to the carbon dot."""
    from matplotlib.colors import to_rgb

    return tuple(0.5 * c + 0.5 for c in to_rgb(color))


#: the least span of a linear panel across specimens, as a fraction of its largest value: the
#: width of the verdicts' "well determined" band (a 95 % half-width of 5 %, either way), so
#: that differences well inside it are not drawn as if they were apart
ACROSS_MIN_SPAN = 2 * WELL_DETERMINED


def _either_limit():
    """The marker of a constant on a search limit whose side is not known: the lower limit's
    and the upper limit's triangles ("v", "^") drawn over each other."""
    from matplotlib.path import Path as MplPath

    up, down = [(0, 1), (-1, -1), (1, -1), (0, 1)], [(0, -1), (-1, 1), (1, 1), (0, -1)]
    codes = [MplPath.MOVETO, MplPath.LINETO, MplPath.LINETO, MplPath.CLOSEPOLY]
    return MplPath(up + down, codes * 2)


def _across_point(ax, k, xi, v, d: Doubt | None, color, tag):
    """One specimen's constant on a panel of the page across specimens; returns what it draws
    by kind ("identified", "undetermined", "undetermined (Monte Carlo)", "at bound", "fixed",
    "no interval")."""
    # markers above the bars and the reference ticks, and not clipped by the axes (a value at
    # a lower limit of a few MPa sits on the panel's edge)
    on_top = dict(zorder=6, clip_on=False)
    if d is not None and d.fixed:
        ax.plot([xi], [v], "s", ms=6, color=FIXED_COLOR, mfc="w", mew=1.3, gid=f"fixed-{tag}",
                **on_top)
        return "fixed"
    if d is not None and d.at_bound and d.bound_side not in ("lower", "upper"):
        # which limit the summary does not say (a --wide summary.csv): both triangles, so
        # that neither direction is claimed
        ax.plot([xi], [v], ls="none", marker=_either_limit(), ms=8, color=color, mfc="none",
                mew=1.1, gid=f"at-bound-{tag}", **on_top)
        return "at bound (side not stated)"
    if d is not None and d.at_bound:
        ax.plot([xi], [v], "^" if d.bound_side == "upper" else "v", ms=7, color=color, mfc="w",
                mew=1.3, gid=f"at-bound-{tag}", **on_top)
        return "at bound"
    if d is not None and d.flag_only:
        # a --wide summary's flag (one written before its interval columns): determined or
        # not, without the interval
        ax.plot([xi], [v], "o", ms=6, color=color, mfc="w" if d.undetermined else color,
                gid=f"value-{tag}", **on_top)
        if d.undetermined:
            ax.annotate("?", (xi, v), xytext=(4, 2), textcoords="offset points", fontsize=9,
                        color=color, weight="bold")
            return "undetermined"
        if d.held_by_prior:
            _prior_mark(ax, xi, v, color, tag)
            return "held by prior"
        return "not flagged"
    if d is None or (np.isnan(d.lower) and np.isnan(d.upper)):
        ax.plot([xi], [v], "d", ms=6, color=color, mfc="w", mew=1.0, gid=f"value-{tag}",
                **on_top)
        return "no interval"
    ax.plot([xi], [v], "o", ms=6, color=color, mfc="w" if d.undetermined else color,
            gid=f"value-{tag}", **on_top)
    if d.undetermined:
        ax.annotate("?", (xi, v), xytext=(4, 2), textcoords="offset points", fontsize=9,
                    color=color, weight="bold")
        return "undetermined (Monte Carlo)" if "(Monte Carlo)" in d.verdict else "undetermined"
    if d.held_by_prior:
        _prior_mark(ax, xi, v, color, tag)
        return "held by prior"
    return "identified"


#: the mark beside a value held by its prior on the page across specimens (the terminal
#: table's, batch.MARK_PRIOR)
PRIOR_MARK = "~"
#: the mark beside the values of a specimen whose fit did not converge on the page across
#: specimens
NOT_CONVERGED_MARK = "nc"


def _prior_mark(ax, xi, v, color, tag) -> None:
    """The "~" beside a value held by its prior (as the "?" of one not determined): a dot on
    a reference line, with a narrow interval, read as the modes confirming the reference when
    the value is mostly the prior's (S1.2 with prior {nu12: 1.0} at its initial 0.35)."""
    ax.annotate(PRIOR_MARK, (xi, v), xytext=(4, 2), textcoords="offset points", fontsize=10,
                color=color, weight="bold", gid=f"prior-{tag}")


def _clipped_bar(ax, k, xi, lo, hi, ymin, ymax, color, *, lw, gid, marks=(False, False),
                 arrow=True, ls="-", pale=False):
    """A vertical bar lo..hi (display unit) clipped to the panel, with an arrow where it runs
    off and a "*" at an end set on a search limit (``marks``: lower, upper). ``pale``: the bar
    and its arrows in :func:`mc_tint` of ``color`` (a Monte Carlo range), the "*" in
    ``color`` itself (pale, it was hard to make out)."""
    a, b = max(lo, ymin) if np.isfinite(lo) else ymin, min(hi, ymax) if np.isfinite(hi) else ymax
    if a > b:
        return
    bar = mc_tint(color) if pale else color
    ax.plot([xi, xi], [a, b], ls=ls, color=bar, lw=lw, alpha=0.85, gid=gid,
            solid_capstyle="butt")
    for end, edge, up in ((hi, ymax, True), (lo, ymin, False)):
        if arrow and (not np.isfinite(end) or (end > ymax if up else end < ymin)):
            ax.annotate("", (xi, edge), xytext=(xi, _inward(ax, edge, 0.07, ymin, ymax, up)),
                        arrowprops=dict(arrowstyle="-|>", color=bar, lw=1))
    for end, mark, up in ((lo, marks[0], False), (hi, marks[1], True)):
        if mark:
            y = min(max(end, ymin), ymax)
            ax.annotate("*", (xi, y), xytext=(2, -6 if up else 0), textcoords="offset points",
                        fontsize=9, color=color, weight="bold", gid=f"{gid}-search-limit")


def style_across_panel(ax, title: str, names) -> None:
    """Title, specimen ticks and grid of a panel across specimens (the constants' and the
    loss factors' pages)."""
    ax.set_title(title, fontsize=10)
    ax.set_xticks(np.arange(len(names)), names, rotation=45, ha="right", fontsize=7)
    ax.set_xlim(-0.6, len(names) - 0.4)
    ax.grid(axis="y", lw=0.3)
    ax.tick_params(axis="y", labelsize=7)


def constants_across_page(done, title: str, absent=()):
    """One panel per constant: each specimen on the x axis, the materials of one specimen side
    by side, each with the doubt the summary gives it: interval bar, hollow "?" when not
    determined, a triangle when it stopped on a search limit (no interval), a grey square when
    fixed, the Monte Carlo range beside the interval, a pale bar of the material's colour
    (:func:`mc_tint`); reference values from the result
    files where found. ``absent``: the summary's specimens without a result ("name (status)"),
    named in the notes."""
    from matplotlib.legend_handler import HandlerTuple
    from matplotlib.lines import Line2D

    materials: list[str] = []
    for _, mats, _ in done:
        materials += [m for m in mats if m not in materials]
    fig = _figure()
    fig.suptitle(f"{title}: identified constants across specimens", fontsize=11)
    gs = fig.add_gridspec(3, 3, height_ratios=[1, 1, 0.2])
    axes = np.array([fig.add_subplot(gs[i, j]) for i in range(2) for j in range(3)])
    names = specimen_labels([row for row, _, _ in done])
    ticks, shortened = axis_names(names)
    nm = len(materials)
    width = min(0.22, 0.7 / max(nm, 1))
    offsets = {m: (c - (nm - 1) / 2) * width for c, m in enumerate(materials)}
    kinds: set[str] = set()
    has_mc = has_mc_limit = has_ref = has_ref_range = has_profile = has_interval = False
    has_nc = has_flat = has_bounded = False
    for ax, k in zip(axes, CONSTANTS):
        ax.set_gid(f"across-{k}")
        vals, ends, bars, profile_ends = [], [], [], []
        for c, m in enumerate(materials):
            color = f"C{c % 10}"
            for i, (name, (row, mats, r)) in enumerate(zip(names, done)):
                if m not in mats or k not in mats[m]:
                    continue
                v = _gpa(k, mats[m][k])
                xi = i + offsets[m]
                d = doubt_of_row(row, m, k, r)
                kinds.add(_across_point(ax, k, xi, v, d, color, f"{name}-{m}"))
                if "not_converged" in _row_check(row, r):
                    # the optimiser's last point, not an identification: drawn as one it read
                    # as the specimen's constants (S1.1 stopped by --max-evaluations 8, its
                    # E1 a filled dot with an interval beside the others)
                    has_nc = True
                    ax.annotate(NOT_CONVERGED_MARK, (xi, v), xytext=(4, -10),
                                textcoords="offset points", fontsize=7, color=color,
                                weight="bold", gid=f"not-converged-{name}-{m}")
                vals.append(v)
                if d is not None and not d.fixed and not d.at_bound and np.isfinite(d.lower):
                    lo, hi = _gpa(k, d.lower), _gpa(k, d.upper)
                    if not d.undetermined and abs(hi - lo) < abs(v):
                        ends += [lo, hi]
                    bars.append((xi, lo, hi, color, 1.2, "interval", (False, False), "-"))
                    has_interval = True
                if d is not None and np.isfinite(d.mc_lower) and np.isfinite(d.mc_upper):
                    has_mc = True
                    marks = (d.mc_lower_at_limit, d.mc_upper_at_limit)
                    has_mc_limit |= any(marks)
                    bars.append((xi + 0.55 * width, _gpa(k, d.mc_lower), _gpa(k, d.mc_upper),
                                 color, 2.2, f"monte-carlo-{name}-{m}", marks, "-"))
                if d is not None and d.at_bound and d.profile in ("bound", "flat"):
                    # the values the fit does not reject: from the limit to the profile's
                    # bound, or (flat) to the other end of its scan (an arrow where that is
                    # off the panel; off it when a summary does not say where)
                    has_profile = True
                    far = d.profile_bound if d.profile == "bound" else d.profile_far
                    far = _gpa(k, far) if np.isfinite(far) else (
                        -np.inf if d.bound_side == "upper" else np.inf)
                    if d.profile == "bound" or (k == "nu12" and np.isfinite(far)):
                        ends.append(far)
                    bars.append((xi, min(v, far), max(v, far), color, 1.6, "profile",
                                 (False, False), (0, (1, 1.5))))
                    profile_ends.append((xi, v, far, d.profile, color, f"{name}-{m}"))
                ref = r.reference.get(m, {}).get(k) if r is not None else None
                if ref is not None and ref[0] == ref[1]:
                    has_ref = True
                    ax.plot([xi], [_gpa(k, ref[0])], "_", ms=14, mew=2.2, color="k",
                            gid=f"reference-{name}-{m}")
                    vals.append(_gpa(k, ref[0]))
                elif ref is not None:
                    # a range: a black bar from low to high, left of the interval (which is
                    # on the value, the Monte Carlo range on its right)
                    has_ref_range = True
                    ax.plot([xi - 0.55 * width] * 2, [_gpa(k, e) for e in ref], "_-", lw=1.5,
                            ms=8, mew=1.5, color="k", solid_capstyle="butt",
                            gid=f"reference-range-{name}-{m}")
                    vals += [_gpa(k, e) for e in ref]
        log = bool(vals) and wants_log_axis(k, vals, ends)
        if log:
            # values a decade and more apart (S2.1's G13 0.0029 GPa, S1.x's 2-6 GPa): on a
            # linear axis the small ones sat on 0; the bars as on a linear panel, in view
            # where the panel's limits come from them, else to the edge with an arrow
            ax.set_yscale("log")
            ymin, ymax = _log_limits(vals, ends, pad=(0.08, 0.08))
        elif vals:
            lo, hi = min(vals + ends), max(vals + ends)
            pad = 0.15 * (hi - lo) if hi > lo else 0.1 * abs(hi) or 1.0
            # at least ACROSS_MIN_SPAN of the values (nu12: of 0.1, as it may be near 0):
            # values a hair apart with no interval in view (one plate identified twice from
            # two starts, its G13 undetermined: 6.01761 and 6.01778 GPa) were magnified to
            # their last digits, ticks 0.00060-0.00080 under an offset '+6.017'
            least = ACROSS_MIN_SPAN * max(abs(lo), abs(hi), 0.1 if k == "nu12" else 0.0)
            pad = max(pad, (least - (hi - lo)) / 2)
            ymin, ymax = lo - pad, hi + pad
            if k != "nu12" and ymin < 0 <= lo:
                ymin = 0.0
        if vals:
            ax.set_ylim(ymin, ymax)
            for xi, blo, bhi, color, lw, gid, marks, ls in bars:
                _clipped_bar(ax, k, xi, blo, bhi, ymin, ymax, color, lw=lw, gid=gid,
                             marks=marks, ls=ls, pale=gid.startswith("monte-carlo"))
            for xi, v, far, kind, color, tag in profile_ends:
                # the profile's end in view as on the intervals page: a cap where the fit
                # rejects beyond (a bound), an arrow head at the end of a flat profile's scan
                # (not rejected there, not tried beyond); drawn alike, hybrid CM's glass E2
                # (flat to 0.9 GPa) read as bounded as its G12 (< 18.5 GPa). Off the panel:
                # the bar's arrow at the edge
                if not ymin <= far <= ymax:
                    continue
                if kind == "bound":
                    has_bounded = True
                    ax.plot([xi], [far], "_", ms=9, mew=1.6, color=color, zorder=5,
                            gid=f"profile-cap-{tag}")
                else:
                    has_flat = True
                    ax.plot([xi], [far], "^" if far > v else "v", ms=5, color=color,
                            zorder=5, clip_on=False, gid=f"profile-end-{tag}")
        style_across_panel(ax, f"{k} ({_unit(k)}{', log scale' if log else ''})", ticks)
        if log:
            log_axis_ticks(ax)
    handles = {m: Line2D([], [], ls="none", marker="o", ms=6, color=f"C{c % 10}")
               for c, m in enumerate(materials)}
    grey = "0.3"
    marks = {
        "identified": (Line2D([], [], ls="-", marker="o", ms=6, color=grey, lw=1.2),
                       "identified, with its confidence interval"),
        "undetermined": (Line2D([], [], ls="none", marker="o", ms=6, color=grey, mfc="w"),
                         "?: not determined (interval too wide)"),
        "at bound": ((Line2D([], [], ls="none", marker="v", ms=7, color=grey, mfc="w"),
                      Line2D([], [], ls="none", marker="^", ms=7, color=grey, mfc="w")),
                     "stopped on a lower / upper search limit: not identified, no interval"),
        "fixed": (Line2D([], [], ls="none", marker="s", ms=6, color=FIXED_COLOR, mfc="w"),
                  "fixed at its initial value: not identified"),
        "held by prior": (Line2D([], [], ls="none", marker=r"$\sim$", ms=8, color=grey),
                          "~: held by its prior (mostly the file's prior value, not the "
                          "modes')"),
        "no interval": (Line2D([], [], ls="none", marker="d", ms=6, color=grey, mfc="w"),
                        "no interval in this summary (wide CSV, result file not found)"),
        "not flagged": (Line2D([], [], ls="none", marker="o", ms=6, color=grey),
                        "identified, not flagged (--wide: no interval)"),
        "at bound (side not stated)": (
            Line2D([], [], ls="none", marker=_either_limit(), ms=8, color=grey, mfc="none"),
            "on a search limit, not identified (--wide: which one not said)")}
    if "held by prior" in kinds and has_interval:
        kinds.add("identified")           # its dot and interval bar are an identified one's
    if "undetermined (Monte Carlo)" in kinds:
        # a Monte Carlo verdict's interval may be narrow: its range is what is too wide
        kinds.add("undetermined")
        h, _ = marks["undetermined"]
        marks["undetermined"] = (h, "?: not determined (interval or Monte Carlo range too "
                                    "wide)")
    for kind in ("identified", "not flagged", "undetermined", "held by prior", "at bound",
                 "at bound (side not stated)", "fixed", "no interval"):
        if kind in kinds:
            h, text = marks[kind]
            handles[text] = h
    if has_mc:
        # (the pale bar of each material's colour, as drawn)
        handles["Monte Carlo range: pale bar of the material's colour, right of its value"
                + (" (*: end set by trials on a search limit)" if has_mc_limit else "")] = \
            tuple(Line2D([], [], color=mc_tint(f"C{c % 10}"), lw=2.2)
                  for c in range(len(materials)))
    if has_nc:
        handles[f"{NOT_CONVERGED_MARK}: not converged (the optimiser's last point, not an "
                "identification)"] = Line2D([], [], ls="none", ms=10, color=grey,
                                            marker=rf"$\mathrm{{{NOT_CONVERGED_MARK}}}$")
    if has_profile:
        # what its ends say, as on the intervals page (dotted alone: a cap or an arrow head
        # hid the dots at a handle's length)
        handles["values the fit does not reject (profile of a constant on a search limit)"
                + (";\ncap: it rejects beyond; arrow head: the end of its scan, not tried "
                   "beyond" if has_bounded and has_flat else
                   ";\narrow head: the end of its scan, not tried beyond" if has_flat else
                   ";\ncap: it rejects beyond" if has_bounded else "")] = \
            Line2D([], [], ls=(0, (1, 1.5)), color=grey, lw=1.6)
    if has_ref:
        handles["reference value " + REFERENCE_POINT_WORDS.removeprefix("reference ")] = \
            Line2D([], [], ls="none", marker="_", ms=14, mew=2.2, color="k")
    if has_ref_range:
        # a capped vertical bar, as drawn (a line would look like the reference value's tick)
        handles["reference range (left of the value)"] = Line2D(
            [], [], ls="none", marker=r"$\mathrm{I}$", ms=10, color="k")
    ax_leg = fig.add_subplot(gs[2, :])                 # a row of its own: clear of the panels
    ax_leg.axis("off")
    # as many columns as the page's width takes (four columns of five or six long entries
    # ran off both edges of the page and squeezed the panels)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    renderer = canvas.get_renderer()
    for ncol in range(min(len(handles), 3 if len(handles) > 6 else 4), 0, -1):
        legend = ax_leg.legend(list(handles.values()), list(handles), loc="center", ncol=ncol,
                               fontsize=8, handler_map={tuple: HandlerTuple(ndivide=None)})
        # (within the panels' width: the y tick labels' margin is outside the legend's row)
        if legend.get_window_extent(renderer).width <= 0.9 * fig.bbox.width:
            break
    ax_leg.legend(list(handles.values()), list(handles), loc="center", ncol=ncol, fontsize=8,
                  handler_map={tuple: HandlerTuple(ndivide=None)},
                  # (bars and arrows where there are intervals: a --wide summary written
                  # before its interval columns has none)
                  title="colour: material" + ("; bars: confidence interval of the summary "
                                              "(arrow: runs off the panel)" if has_interval
                                              else ""), title_fontsize=8)
    notes = []
    checks = [f"{name}: {w}" for name, (row, _, r) in zip(names, done)
              if (w := _row_check(row, r))]
    if checks:
        notes.append("status not ok — " + "; ".join(checks))
    if absent:
        notes.append(f"no result, not drawn (page 2 says why): {', '.join(absent)}")
    missing = [name for name, (row, _, r) in zip(names, done) if r is None]
    if missing:
        notes.append("result file not found (no reference values): " + ", ".join(missing))
    if "no interval" in kinds:
        notes.insert(0, "values without their doubt (hollow diamonds): a --wide summary.csv "
                        "written before its interval columns has no intervals, verdicts or "
                        "search limits, and their result files were not found: a value at a "
                        "search limit or not determined looks like any other here; use the "
                        "long summary.csv or summary.json, or run the batch again")
    elif any(d is not None and d.flag_only for row, mats, r in done for m in mats
             for k in mats[m] if (d := doubt_of_row(row, m, k, r)) is not None):
        notes.insert(0, "no intervals: a --wide summary.csv written before its interval "
                        "columns gives only which constants are at a search limit (not which "
                        "one), not determined or fixed (its column flagged), and their result "
                        "files were not found; the intervals are in the long summary.csv or "
                        "summary.json (a batch run again writes them in the wide one too)")
    if shortened:
        notes.append(shortened)
    if notes:
        _footer(fig, "\n".join(notes), color=CHECK_COLOR)
    return fig


def residuals_across_page(rows, title: str):
    """The weighted RMS residual of each specimen, its status and reason codes above."""
    from matplotlib.patches import Patch

    fig = _figure()
    fig.suptitle(f"{title}: weighted RMS frequency residual per specimen", fontsize=11)
    ax = fig.subplots()
    ax.set_gid("rms")
    names = specimen_labels(rows)
    rms = [r["rms_residual_percent"] if r["rms_residual_percent"] is not None else 0.0
           for r in rows]
    colors = ["0.45" if r["status"] == "ok" else "0.8" for r in rows]
    ax.bar(np.arange(len(rows)), rms, color=colors)
    meshes = [r.get("mesh_check") or {} for r in rows]
    labels = []
    for i, r in enumerate(rows):
        parts = [f"{rms[i]:.3f} %" if r["rms_residual_percent"] is not None else "no result"]
        if meshes[i].get("max_shift_half_width") is not None:
            # batch --mesh-check: how far the constants would move on the finer mesh
            parts.append(f"mesh shift {meshes[i]['max_shift_half_width']:.2f} hw")
        check = _row_check(r, None)
        if check:
            parts.append(check)
        labels.append(parts)
    # a failed specimen's reason may hold long file names and fields, broken anywhere; the
    # reason codes and numbers are not (a code cut in two, "fixe d_rejected", reads as two)
    breakable = [r["rms_residual_percent"] is None for r in rows]
    ax.set_ylim(0, 1.3 * max(max(rms), 1e-3))          # room for the labels above the bars
    ticks, shortened = axis_names(names)
    ax.set_xticks(np.arange(len(rows)), ticks, rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("RMS residual (%)")
    ax.set_xlabel("specimen")
    # the kinds of bar drawn (a batch of which none is ok keyed a dark bar it did not have)
    kinds = [(Patch(color=c), text) for c, text in (
        ("0.45", "status ok"), ("0.8", "status not ok (reason codes above the bar)"))
        if c in colors]
    ax.legend(handles=[h for h, _ in kinds], labels=[t for _, t in kinds],
              loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0, fontsize=8)
    notes = []
    checked_mesh = any(m.get("max_shift_half_width") is not None for m in meshes)
    if checked_mesh:
        from laminid_cli.meshcheck import SHIFT_LIMIT

        notes.append("mesh shift (hw: 95 % half-widths): the largest first-order shift of a "
                     "constant on a mesh twice as fine (batch --mesh-check), in units of its "
                     f"95 % half-width; beyond {SHIFT_LIMIT:g} the mesh is too coarse for the "
                     "modes (coarse_mesh)")
    if shortened:
        notes.append(shortened)
    if notes:
        _footer(fig, "\n".join(notes), gid="mesh-check-note" if checked_mesh else "names-note")
    _bar_labels(fig, ax, labels, rms, breakable)
    return fig


#: (characters per line, font size) of the labels above the residual bars, widest first: the
#: first whose neighbouring labels do not overlap is used
BAR_LABEL_FITS = ((18, 7.5), (14, 7.0), (11, 6.5), (9, 6.0), (7, 5.5))


def _bar_labels(fig, ax, labels, heights, breakable) -> None:
    """Each bar's label (``labels``: its parts, each wrapped on its own; words longer than a
    line broken only where ``breakable``) above it, as wide as the bars leave room for: eleven
    specimens with --mesh-check had each label run into its neighbours' ("0.265 %mesh shift
    0.10 hw", a failed specimen's reason across the next bar's). The axis is raised to hold
    the tallest label under its top."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)                       # the constrained layout: the axes' final width
    anns: list = []
    for width, size in BAR_LABEL_FITS:
        for a in anns:
            a.remove()
        anns = [ax.annotate("\n".join(line for part in parts for line in textwrap.wrap(
                    part, width, break_on_hyphens=False, break_long_words=brk)), (i, h),
                    xytext=(0, 3), textcoords="offset points", ha="center", va="bottom",
                    fontsize=size, gid=f"bar-label-{i}")
                for i, (parts, h, brk) in enumerate(zip(labels, heights, breakable))]
        boxes = [a.get_window_extent(renderer) for a in anns]
        if not any(p.x1 > q.x0 and p.y1 > q.y0 and q.y1 > p.y0
                   for p, q in zip(boxes, boxes[1:])):
            break
    # the tallest label's top inside the axes (it ran over the page's title)
    for _ in range(3):
        top = max(a.get_window_extent(renderer).y1 for a in anns)
        box = ax.get_window_extent(renderer)
        if top <= box.y1 - 4:
            break
        lo, hi = ax.get_ylim()
        # the labels keep their height in points: the data above the bars shrinks by the
        # ratio of the room needed to the room there is
        over = (top - box.y1 + 8) / box.height
        ax.set_ylim(lo, hi + over * (hi - lo) / max(1e-3, 1 - over))
        fig.draw(renderer)


# ----------------------------------------------------------------------------------------------
# output


def is_summary(path) -> bool:
    p = Path(path)
    return p.suffix.lower() in (".csv", ".json")


def report_pages(path, *, frf_path=None) -> list[Page]:
    """Pages of a result file or a batch summary (by the suffix: .csv/.json = summary)."""
    from laminid_cli.resultfile import ResultFileError, is_frf_text_file, not_a_result_but_frf

    if is_frf_text_file(path):
        raise ResultFileError(not_a_result_but_frf(path))
    if is_summary(path):
        return summary_pages(path)
    return result_pages(path, frf_path=frf_path)


def lay_out_once(fig, fmt: str, dpi: float) -> None:
    """Lay the page out once, as savefig would for ``fmt`` ("pdf", "png") at ``dpi``, and keep
    it: the layout engine is run with the renderer of that format and then removed, so that
    saving the page draws it once. matplotlib's savefig of a figure with a layout engine draws
    it twice, once (not rendered) to lay it out and once to write it: S1.1's five fresh pages
    took 2.00 s of CPU to write as a PDF that way, 1.62 s laid out once (median of 4, in one
    process, alternated). The page written is the same: the layout is the one that draw made,
    with the same renderer (for a PDF, 72 dpi and the PDF backend's text metrics, not Agg's)."""
    import matplotlib

    engine = fig.get_layout_engine()
    if engine is None:
        return
    own_canvas, own_dpi = fig.canvas, fig.dpi
    if fmt == "pdf":
        from matplotlib.backends.backend_pdf import FigureCanvasPdf

        FigureCanvasPdf(fig)        # the layout engine asks the figure's canvas for a renderer
    else:
        fig.set_dpi(dpi)
    try:
        if fig.axes:                # as Figure.draw: no layout of a page without axes
            engine.execute(fig)
    finally:
        fig.set_dpi(own_dpi)        # (the PDF canvas leaves it at 72)
        fig.set_canvas(own_canvas)
    # set_layout_engine(None) removes the engine unless the rc asks for one; "none" would
    # leave a placeholder, and savefig would still draw the page twice
    with matplotlib.rc_context({"figure.autolayout": False,
                                "figure.constrained_layout.use": False}):
        fig.set_layout_engine(None)


def write_pages(pages, out, *, dpi: int = 110, progress=None) -> list[Path]:
    """Write a multi-page PDF (one file) or PNGs (``out`` for one page, else ``<stem>-1.png``,
    ``<stem>-2.png``...). Each file goes to a temporary name first, then is renamed. Each
    page is laid out once and drawn once (:func:`lay_out_once`); its figure keeps that
    layout. ``progress(k, n, name)``, if given, is called before page k of n is drawn
    (drawing is most of a report's time: hybrid CM's six pages 12 of 18 s)."""

    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in REPORT_SUFFIXES:
        raise ReportError(f"{out}: report type {out.suffix!r} not supported; use .pdf or .png")
    written = []
    if suffix == ".pdf":
        from matplotlib.backends.backend_pdf import PdfPages

        with atomic_path(out) as tmp:
            with PdfPages(tmp, metadata={"Title": f"laminid report {out.stem}",
                                         "Creator": "laminid"}) as pdf:
                for k, p in enumerate(pages, start=1):
                    if progress is not None:
                        progress(k, len(pages), p.name)
                    lay_out_once(p.figure, "pdf", 72)
                    pdf.savefig(p.figure)
        return [out]
    for k, p in enumerate(pages, start=1):
        if progress is not None:
            progress(k, len(pages), p.name)
        target = out if len(pages) == 1 else out.with_name(f"{out.stem}-{k}{out.suffix}")
        lay_out_once(p.figure, "png", dpi)
        with atomic_path(target) as tmp:
            p.figure.savefig(tmp, dpi=dpi, format="png")
        written.append(target)
    return written
