"""Figure of an RFP fit: FRF magnitude, phase and coherence with the fitted curves, and the
stabilisation charts.

matplotlib (Agg backend) is imported inside the functions only, so the numerical modules never
load it. :func:`draw_frf` is shared with the FRF page of ``laminid report``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from laminid_cli.errors import FrfError

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
MEASURED_COLOR = "k"
#: the box around the stable poles of a stabilisation chart that are none of the modes
UNLISTED_COLOR = "k"


def has_coherence(coherence) -> bool:
    return coherence is not None and bool(np.isfinite(np.asarray(coherence, float)).any())


def _label_levels(freqs, lo: float, hi: float, min_gap: float = 0.018, levels: int = 3):
    """Vertical level (0, 1, 2...) of each frequency label so that labels closer than
    ``min_gap`` of the axis width sit at different heights."""
    out, last = [], {}
    span = max(hi - lo, 1e-12)
    for f in freqs:
        x = (f - lo) / span
        lev = next((k for k in range(levels) if x - last.get(k, -1.0) >= min_gap), levels - 1)
        last[lev] = x
        out.append(lev)
    return out


def _phase(freq, H):
    """(freq, phase deg wrapped to +/-180) with a NaN gap at each wrap, so that a wrapped line
    is not joined by a vertical stroke across the panel."""
    ph = np.degrees(np.angle(H))
    jumps = np.flatnonzero(np.abs(np.diff(ph)) > 180) + 1
    return np.insert(freq, jumps, np.nan), np.insert(ph, jumps, np.nan)


#: lines of the measured axis outside the fitted bands' view from which the FRF figure says
#: what it does not show
HIDDEN_LINES = 5


def hidden_note(freq, view) -> str:
    """What an FRF figure zoomed on the fitted bands (``view`` = (lo, hi) Hz) leaves out of
    the measured axis ``freq`` (Hz): "not shown: 0.875–59.3 Hz of the measured FRFs (no band
    fitted there)"; "" when at most :data:`HIDDEN_LINES` lines are out of view at either end."""
    def hz(v: float) -> str:
        return f"{v:.3g}" if abs(v) < 100 else f"{v:.0f}"

    measured = np.asarray(freq, float)
    measured = measured[measured > 0]
    parts = []
    below, above = measured[measured < view[0]], measured[measured > view[1]]
    if below.size > HIDDEN_LINES:
        parts.append(f"{hz(below.min())}–{hz(view[0])} Hz")
    if above.size > HIDDEN_LINES:
        parts.append(f"{hz(view[1])}–{hz(above.max())} Hz")
    if not parts:
        return ""
    return f"not shown: {' and '.join(parts)} of the measured FRFs (no band fitted there)"


def sigma_label(sigma_hz) -> str:
    """The legend words of the RFP natural frequencies with their standard deviations (the
    labels give the values alone): "RFP natural frequency (± 0.25–2.75 Hz, one standard
    deviation)"; without sigmas the plain words."""
    s = np.asarray([] if sigma_hz is None else sigma_hz, float)
    s = s[np.isfinite(s)]
    if not s.size:
        return "RFP natural frequency"
    lo, hi = (f"{v:.3g}" for v in (s.min(), s.max()))
    span = lo if lo == hi else f"{lo}–{hi}"
    return f"RFP natural frequency (± {span} Hz, one standard deviation)"


def draw_frf(ax_m, ax_p, freq, frf, fit, *, units: str = "", coherence=None, ax_c=None,
             decimals: int = 2, sigma_hz=None):
    """Draw measured FRFs (black, on top), the RFP fit per band (coloured, below), the RFP
    natural frequencies (dashed, labelled at the top) on magnitude ``ax_m`` (dB re 1 ``units``)
    and phase ``ax_p`` (wrapped to +/-180 deg), and the coherence on ``ax_c`` when given.
    ``sigma_hz``: the frequencies' standard deviations (fit-frf's +/-), their span given in
    the legend (the labels were the values alone, with no word of their doubt).
    Returns the x range of the fitted bands (or None)."""
    freq = np.asarray(freq, dtype=float)
    frf = np.atleast_2d(np.asarray(frf))
    n = frf.shape[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        for p, H in enumerate(frf):
            lab = (f"measured ({n} point{'s' if n > 1 else ''})" if p == 0 else None)
            ax_m.plot(freq, 20 * np.log10(np.abs(H)), color=MEASURED_COLOR, lw=0.7, alpha=0.8,
                      zorder=3, label=lab)
            ax_p.plot(freq, np.degrees(np.angle(H)), ".", color=MEASURED_COLOR, ms=1.0,
                      alpha=0.6, zorder=3)
        for k, band in enumerate(fit.bands):
            lo, hi = band.band_hz
            sel = (freq >= lo) & (freq <= hi) & (freq > 0)
            Hs = band.synthesise(freq[sel])
            color = f"C{k % 10}"
            for p, H in enumerate(Hs):
                ax_m.plot(freq[sel], 20 * np.log10(np.abs(H)), color=color, lw=2.2, alpha=0.55,
                          zorder=2, label="RFP fit (one colour per band)" if k == 0 and p == 0
                          else None)
                ax_p.plot(*_phase(freq[sel], H), color=color, lw=1.8, alpha=0.55, zorder=2)
    xr = None
    if fit.bands:
        xr = (min(b.band_hz[0] for b in fit.bands) * 0.95,
              max(b.band_hz[1] for b in fit.bands) * 1.02)
    lo, hi = xr if xr else (float(freq.min()), float(freq.max()))
    fm = [m.freq_hz for m in fit.modes]
    for i, (f, lev) in enumerate(zip(fm, _label_levels(fm, lo, hi))):
        for ax in [a for a in (ax_m, ax_p, ax_c) if a is not None]:
            ax.axvline(f, color="0.35", ls="--", lw=0.6, zorder=1,
                       label=sigma_label(sigma_hz) if ax is ax_m and i == 0 else None)
        ax_m.annotate(f"{f:.{decimals}f}", (f, 1 - 0.09 * lev), xycoords=("data", "axes fraction"),
                      rotation=90, va="top", ha="right", fontsize=7, color="0.25",
                      bbox=dict(fc="w", ec="none", pad=0.4, alpha=0.85), zorder=6)
    ax_m.set_ylabel(f"|H| (dB re 1 {units})" if units else "|H| (dB re 1 FRF unit)")
    ax_p.set_ylabel("phase (deg),\nwrapped to ±180")
    ax_p.set_ylim(-190, 190)
    ax_p.set_yticks([-180, -90, 0, 90, 180])
    ax_p.grid(axis="y", lw=0.3)
    if ax_c is not None:
        coh = np.atleast_2d(np.asarray(coherence, float))
        for p, c in enumerate(coh):
            ax_c.plot(freq, c, color=MEASURED_COLOR, lw=0.6, alpha=0.7, gid="coherence",
                      label="coherence" if p == 0 else None)
        ax_c.set_ylim(0, 1.05)
        ax_c.set_ylabel("coherence (–)")
        ax_c.grid(axis="y", lw=0.3)
    if xr:
        ax_m.set_xlim(*xr)
        note = hidden_note(freq, xr)
        if note:
            # the view is the bands': a peak outside them (a mode the bands missed: one the
            # exponential window damped below the rule, or below the first peak picked) would
            # be out of sight without a word
            ax_m.text(0.005, 0.02, note, transform=ax_m.transAxes, fontsize=6.5, color="0.3",
                      ha="left", va="bottom", gid="view-note", zorder=7,
                      bbox=dict(fc="w", ec="none", pad=0.5, alpha=0.85))
    sel = (freq >= lo) & (freq <= hi)
    with np.errstate(divide="ignore"):
        db = 20 * np.log10(np.abs(frf[:, sel]))
    db = db[np.isfinite(db)]
    if db.size:                         # magnitudes outside the shown band do not set the scale
        ax_m.set_ylim(db.min() - 5, db.max() + 12)
    return xr


def plot_fit(path, freq, frf, fit, *, title: str = "", units: str = "", coherence=None,
             sigma_hz=None) -> Path:
    """Write :func:`fit_figure` to ``path`` (PNG/PDF/SVG)."""
    path = Path(path)
    if path.suffix.lower() not in PLOT_SUFFIXES:
        raise FrfError(f"{path}: plot file type {path.suffix!r} not supported; use one of "
                       f"{', '.join(PLOT_SUFFIXES)}")
    fig = fit_figure(freq, frf, fit, title=title, units=units, coherence=coherence,
                     sigma_hz=sigma_hz)
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise FrfError(f"{path}: cannot write the plot ({exc})") from exc
    return path


#: most groups of unlisted stable poles the chart's note names one by one; above it the note
#: counts them by rule (noisy FRFs gave 60 groups: 12 lines of note clipped at the page's
#: foot, and the figure's other panels squeezed)
MAX_NOTE_GROUPS = 6


def unlisted_note(unlisted, criteria, width: int = 150) -> str:
    """Why each group of stable poles that is none of the modes was left out (the chart's
    note; :func:`~laminid_cli.frf.rfp.unlisted_stable_poles`), e.g. "1405-1406 Hz (orders
    13-14): stable at 2 orders, fewer than the 5 a mode needs: a computational pole, near the
    band edge 1410 Hz, where the fit places poles for the modes beyond it". More than
    :data:`MAX_NOTE_GROUPS` groups are counted by rule instead, in at most three lines."""
    import textwrap

    from laminid_cli.frf.rfp import EDGE_LINES, FALSE_ALARM, REFINE_LIMITS

    not_listed = ("not listed" if any(u.reason == "beyond" for u in unlisted)
                  else "not a mode")
    if len(unlisted) > MAX_NOTE_GROUPS:
        def count(reason):
            return sum(1 for u in unlisted if u.reason == reason)

        few = count("few")
        near = sum(1 for u in unlisted if u.reason == "few" and u.edge_hz is not None)
        rules = [
            (few, f"stable at fewer orders than the {criteria.min_stable} a mode needs "
                  "(computational poles" + (f", {near} near a band edge)" if near else ")")),
            (count("edge"), f"within {EDGE_LINES} lines of a band edge (not taken from that "
                            "band)"),
            (count("damping"), f"damping outside 0–{criteria.max_damping:.0%} (not physical "
                               "modes)"),
            (count("noise"), f"not above the fit's residual ({criteria.min_snr:g} x; dropped "
                             "as noise)"),
            (count("chance"), "lowering the residual no more than noise does somewhere in the "
                              f"lines fitted (false alarm above {FALSE_ALARM:g}; dropped)"),
            (count("reach"), "output-error fit beyond its bounds (not credible modes)"),
            (count("beyond"), "modes above the lowest that --modes asks for (not listed)")]
        lo = min(u.freq_hz[0] for u in unlisted)
        hi = max(u.freq_hz[1] for u in unlisted)
        text = (f"boxed, stable but {not_listed}: {len(unlisted)} groups of poles, "
                f"{lo:.0f}–{hi:.0f} Hz: " + "; ".join(f"{n} {why}" for n, why in rules if n)
                + ". So many: noisy FRFs (see the coherence) or too wide bands; try --band "
                  "LO:HI")
        return "\n".join(textwrap.wrap(text, width))
    parts = []
    for u in unlisted:
        lo, hi = u.freq_hz
        where = f"{lo:.0f} Hz" if round(lo) == round(hi) else f"{lo:.0f}–{hi:.0f} Hz"
        o_lo, o_hi = u.orders
        orders = f"order {o_lo}" if o_lo == o_hi else f"orders {o_lo}–{o_hi}"
        edge = f"{u.edge_hz:g} Hz" if u.edge_hz is not None else ""
        if u.reason == "few":
            why = (f"stable at {u.n_stable} order{'s' if u.n_stable != 1 else ''}, fewer than "
                   f"the {criteria.min_stable} a mode needs: a computational pole"
                   + (f", near the band edge {edge}, where the fit places poles for the modes "
                      "beyond it" if edge else ""))
        elif u.reason == "edge":
            why = (f"within {EDGE_LINES} lines of the band edge {edge}: not taken from that "
                   "band (a pole there stands for the modes beyond it)")
        elif u.reason == "damping":
            why = (f"damping outside 0–{criteria.max_damping:.0%}: not a physical mode")
        elif u.reason == "beyond":
            why = "a mode, above the lowest that --modes asks for: not listed"
        elif u.reason == "reach":
            why = (f"its output-error fit would move it more than {REFINE_LIMITS[0]:g} f·ζ (at "
                   f"least {REFINE_LIMITS[0] / 4:g} line), or "
                   f"its damping {np.exp(REFINE_LIMITS[1]):.1f} times: not a credible mode")
        elif u.reason == "chance":
            why = ("its modal constants lower the residual no more than noise alone does "
                   f"somewhere in the lines fitted (false-alarm probability above "
                   f"{FALSE_ALARM:g}): not a credible mode")
        else:
            why = (f"its contribution does not rise above the fit's residual ({criteria.min_snr:g}"
                   " x): dropped as noise")
        parts.append(f"{where} ({orders}): {why}")
    text = f"boxed, stable but {not_listed}: " + "; ".join(parts)
    return "\n".join(textwrap.wrap(text, width))


def fit_figure(freq, frf, fit, *, title: str = "", units: str = "", coherence=None,
               sigma_hz=None):
    """The figure of a :class:`~laminid_cli.frf.rfp.ModalFit` (``fit-frf --plot``).

    Magnitude (dB re 1 FRF unit) of every measured FRF (black, drawn over the fit) and the
    fitted curves (coloured, one colour per band), identified natural frequencies as dashed
    lines; phase (deg, wrapped to +/-180); coherence when the file has it; stabilisation chart
    of every band (model order N vs pole frequency; o new, + stable in frequency, x stable in
    frequency and damping) over the summed FRF magnitude.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    freq = np.asarray(freq, dtype=float)
    frf = np.atleast_2d(np.asarray(frf))
    coh = has_coherence(coherence)
    fig = Figure(figsize=(10, 11 if coh else 10), layout="constrained")
    ratios = [3, 1.6] + ([1.1] if coh else []) + [3]
    axes = fig.subplots(len(ratios), 1, sharex=True, height_ratios=ratios)
    ax_m, ax_p, ax_s = axes[0], axes[1], axes[-1]
    ax_m.set_gid("frf")
    ax_s.set_gid("stabilisation")
    ax_c = axes[2] if coh else None
    xr = draw_frf(ax_m, ax_p, freq, frf, fit, units=units, coherence=coherence, ax_c=ax_c,
                  sigma_hz=sigma_hz)
    ax_m.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, fontsize=8,
                frameon=False)                  # above the panel: clear of the curves
    from matplotlib.lines import Line2D

    from laminid_cli.frf.rfp import unlisted_stable_poles

    kinds = ((0, "o", "new pole"), (1, "+", "stable in f"),
             (2, "x", "stable in f and damping" + (" (colour: its band)"
                                                   if len(fit.bands) > 1 else "")))
    # stable poles that are none of the modes: drawn apart and said why below the chart (a
    # stable x at a band's edge, not in the list, was left for the reader to guess)
    unlisted = unlisted_stable_poles(fit, freq)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, band in enumerate(fit.bands):
            color = f"C{k % 10}"
            ch = band.chart
            apart = np.zeros(ch.order.size, bool)
            for u in unlisted:
                if u.band == k:
                    apart[u.rows] = True
            for code, marker, _ in kinds:
                s = ch.stable == code
                ax_s.plot(ch.freq_hz[s], ch.order[s], marker, ms=3 if code == 0 else 5,
                          mfc="none", color=color if code == 2 else "0.5", ls="none")
            if apart.any():     # boxed: a shape no band's colour can be mistaken for
                ax_s.plot(ch.freq_hz[apart], ch.order[apart], "s", ms=9, mfc="none",
                          mew=0.9, color=UNLISTED_COLOR, ls="none", gid="unlisted")
        summed = 20 * np.log10(np.abs(frf).sum(axis=0))
    # the legend's x in the first band's colour where there is one band, else neutral (the
    # first band's blue keyed the orange and green x of the others as something else)
    handles = [Line2D([], [], ls="none", marker=marker, ms=3 if code == 0 else 5, mfc="none",
                      color="0.5" if code < 2 else "C0" if len(fit.bands) <= 1 else "0.15")
               for code, marker, _ in kinds]
    labels = [label for _, _, label in kinds]
    if unlisted:
        handles.append(Line2D([], [], ls="none", marker="s", ms=9, mfc="none", mew=0.9,
                              color=UNLISTED_COLOR))
        labels.append("boxed: stable, not " + ("listed" if any(
            u.reason == "beyond" for u in unlisted) else "a mode") + " (why: below)")
    for m in fit.modes:
        ax_s.axvline(m.freq_hz, color="0.35", ls="--", lw=0.6)
    ax_s2 = ax_s.twinx()
    finite = np.isfinite(summed)
    ax_s2.plot(freq[finite], summed[finite], color="0.8", lw=0.8, zorder=0)
    ax_s2.set_yticks([])
    ax_s.set_zorder(ax_s2.get_zorder() + 1)
    ax_s.patch.set_visible(False)
    ax_s.set_ylabel("model order N (modes)")
    from matplotlib.ticker import MaxNLocator
    ax_s.yaxis.set_major_locator(MaxNLocator(integer=True))     # orders are whole numbers
    ax_s.set_xlabel("frequency (Hz)")
    ax_s.legend(handles, labels, loc="lower center",
                bbox_to_anchor=(0.5, 1.0), ncol=len(labels), fontsize=8, frameon=False,
                title="stabilisation chart (grey: summed |H|)", title_fontsize=9)
    if unlisted:
        note = unlisted_note(unlisted, fit.criteria)
        ax_s.annotate(note, (0, 0), xycoords="axes fraction", xytext=(0, -32),
                      textcoords="offset points", va="top", ha="left", fontsize=7.5,
                      color="0.2", gid="unlisted-note")
    if xr:
        ax_s.set_xlim(*xr)
    fig.suptitle(title or f"RFP fit: {len(fit.modes)} modes")
    return fig
