"""Figure of an RFP fit: FRF magnitude and phase with the fitted curves, and stabilisation charts.

matplotlib (Agg backend) is imported inside :func:`plot_fit` only, so the numerical modules
never load it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from laminid_cli.errors import FrfError

PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def plot_fit(path, freq, frf, fit, *, title: str = "") -> Path:
    """Write a figure of a :class:`~laminid_cli.frf.rfp.ModalFit` to ``path`` (PNG/PDF/SVG).

    Top: magnitude (dB re 1 FRF unit) of every measured FRF (thin grey) and the fitted curves
    (coloured) per band, identified natural frequencies as dashed lines. Middle: phase (deg).
    Bottom: stabilisation chart of every band (model order N vs pole frequency; o new, + stable
    in frequency, x stable in frequency and damping) over the summed FRF magnitude.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    path = Path(path)
    if path.suffix.lower() not in PLOT_SUFFIXES:
        raise FrfError(f"{path}: plot file type {path.suffix!r} not supported; use one of "
                       f"{', '.join(PLOT_SUFFIXES)}")
    freq = np.asarray(freq, dtype=float)
    frf = np.atleast_2d(np.asarray(frf))
    fig = Figure(figsize=(10, 10), layout="constrained")
    ax_m, ax_p, ax_s = fig.subplots(3, 1, sharex=True, height_ratios=[3, 2, 3])
    with np.errstate(divide="ignore", invalid="ignore"):
        for H in frf:
            ax_m.plot(freq, 20 * np.log10(np.abs(H)), color="0.7", lw=0.6)
            ax_p.plot(freq, np.degrees(np.angle(H)), color="0.7", lw=0.6)
        for k, band in enumerate(fit.bands):
            lo, hi = band.band_hz
            sel = (freq >= lo) & (freq <= hi) & (freq > 0)
            Hs = band.synthesise(freq[sel])
            color = f"C{k % 10}"
            for H in Hs:
                ax_m.plot(freq[sel], 20 * np.log10(np.abs(H)), color=color, lw=0.9)
                ax_p.plot(freq[sel], np.degrees(np.angle(H)), color=color, lw=0.9)
            ch = band.chart
            for code, marker, label in ((0, "o", "new"), (1, "+", "stable f"),
                                        (2, "x", "stable f, zeta")):
                s = ch.stable == code
                ax_s.plot(ch.freq_hz[s], ch.order[s], marker, ms=3 if code == 0 else 5,
                          mfc="none", color=color if code == 2 else "0.5",
                          label=label if k == 0 else None, ls="none")
        summed = 20 * np.log10(np.abs(frf).sum(axis=0))
    for m in fit.modes:
        for ax in (ax_m, ax_p, ax_s):
            ax.axvline(m.freq_hz, color="k", ls="--", lw=0.6)
        ax_m.annotate(f"{m.freq_hz:.2f}", (m.freq_hz, 1), xycoords=("data", "axes fraction"),
                      rotation=90, va="top", ha="right", fontsize=7)
    ax_s2 = ax_s.twinx()
    finite = np.isfinite(summed)
    ax_s2.plot(freq[finite], summed[finite], color="0.8", lw=0.8, zorder=0)
    ax_s2.set_yticks([])
    ax_s.set_zorder(ax_s2.get_zorder() + 1)
    ax_s.patch.set_visible(False)
    ax_m.set_ylabel("|H| (dB)")
    ax_p.set_ylabel("phase (deg)")
    ax_p.set_ylim(-185, 185)
    ax_s.set_ylabel("model order N (modes)")
    ax_s.set_xlabel("frequency (Hz)")
    ax_s.legend(loc="upper left", fontsize=7)
    if fit.bands:
        ax_s.set_xlim(min(b.band_hz[0] for b in fit.bands) * 0.95,
                      max(b.band_hz[1] for b in fit.bands) * 1.02)
    ax_m.set_title(title or f"RFP fit: {len(fit.modes)} modes")
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise FrfError(f"{path}: cannot write the plot ({exc})") from exc
    return path
