"""Report page of the ply loss factors (the ``/damping`` group of a result file).

One page (A4 landscape):

- measured modal loss factor eta_i = 2 zeta_i of each mode (%) with +-1 standard deviation
  error bars, beside the model's sum of energy share x ply loss factor; modes left out of the
  fit (frequency weight 0) hollow;
- the strain-energy shares U_mik / U_i of each mode (%) as stacked bars, one colour per
  material term (11, 22, 12, 13, 23);
- the identified loss factors with their intervals and verdicts, fixed ones marked.

Every number drawn is read from the result file by the typed reader. ``laminid_cli.report`` adds the page when the
file has ``/damping`` (one-line hook); matplotlib is imported inside the functions.
"""

from __future__ import annotations

import numpy as np

A4_LANDSCAPE = (11.69, 8.27)
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
    return d


def damping_figures(result) -> list[tuple[str, object]]:
    """[("damping", Figure)] for a result (path or ResultFile) with /damping, else []; the
    page ends with the result's status line, as every other page of the report."""
    from laminid_cli.report import _status_banner
    from laminid_cli.resultfile import ResultFile, read_result

    r = result if isinstance(result, ResultFile) else read_result(result)
    d = read_damping(r)
    if d is None:
        return []
    fig = damping_page(d)
    _status_banner(fig, r)
    return [("damping", fig)]


def loss_factor_rows(d: dict) -> list[list[str]]:
    """Rows of the loss-factor table (strings as drawn, %): label, value, interval, verdict
    in a few words (the advice is under the table). A loss factor held at 0 by eta >= 0
    keeps its one-sided interval 0 .. upper; a fixed one has none."""
    from laminid_cli.report import short_verdict

    rows = []
    for k, lab in enumerate(d["labels"]):
        lo = 0.0 if d["at_bound"][k] else 100 * d["lower"][k]
        interval = f"[{lo:.3g}, {100 * d['upper'][k]:.3g}]"
        verdict = ("held at 0 by η ≥ 0: not identified" if d["at_bound"][k]
                   else short_verdict(d["verdict"][k]))
        rows.append([lab, f"{100 * d['value'][k]:.3f}", interval, verdict])
    for item in filter(None, str(d.get("fixed", "")).split(",")):
        lab, value = item.rsplit("=", 1)
        rows.append([lab, f"{100 * float(value):.3f}", "none — fixed",
                     "fixed at the value given (not identified)"])
    return rows


def damping_page(d: dict):
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    fig = Figure(figsize=A4_LANDSCAPE, layout="constrained")
    gs = fig.add_gridspec(2, 2, height_ratios=[3, 1.25])
    ax_m = fig.add_subplot(gs[0, 0])
    ax_s = fig.add_subplot(gs[0, 1])
    ax_t = fig.add_subplot(gs[1, :])
    ax_m.set_gid("modal-loss-factors")
    ax_s.set_gid("energy-shares")
    meas = np.asarray(d["measured_loss_factor"], float) * 100
    sig = np.asarray(d["measured_sigma"], float) * 100
    model = np.asarray(d["model_loss_factor"], float) * 100
    used = np.asarray(d["used"], bool)
    n = meas.size
    modes = np.arange(1, n + 1)
    ok = np.isfinite(meas)
    # measured (filled where fitted, hollow where left out), error bars +-1 sd, model beside
    ax_m.plot(modes[ok], meas[ok], "o", color="C0", label="measured 2\u03b6 \u00b1 1 sd",
              zorder=3, gid="measured")
    ax_m.errorbar(modes[ok], meas[ok], yerr=sig[ok], fmt="none", ecolor="C0", capsize=4,
                  zorder=2)
    out = ok & ~used
    if out.any():
        ax_m.plot(modes[out], meas[out], "o", mfc="white", color="C0", zorder=4,
                  label="measured, not fitted (weight 0)")
    ax_m.plot(modes, model, "s", color="C3", mfc="none", ms=8, mew=1.5,
              label="model \u03a3 share \u00d7 ply \u03b7", zorder=5, gid="model")
    ax_m.set_xlabel("mode")
    ax_m.set_ylabel("modal loss factor \u03b7 (%)")
    ax_m.set_xticks(modes)
    top = np.nanmax(np.concatenate([meas + np.nan_to_num(sig), model]))
    ax_m.set_ylim(0, 1.25 * top if np.isfinite(top) and top > 0 else 1)
    ax_m.grid(alpha=0.3)
    ax_m.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8,
                frameon=False)                   # below the panel: clear of the points
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
    ax_s.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8,
                frameon=False)

    # table of loss factors
    ax_t.axis("off")
    conf = float(d.get("confidence", 0.95)) * 100
    rows = loss_factor_rows(d)
    table = ax_t.table(cellText=rows, colLabels=["loss factor", "value (%)",
                                                 f"{conf:.0f} % interval (%)", "verdict"],
                       loc="upper center", cellLoc="center", colLoc="center",
                       colWidths=[0.28, 0.14, 0.22, 0.36])
    ax_t.set_gid("loss-factors")
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    from laminid_cli.report import _verdict_color

    for (i, j), cell in table.get_celld().items():    # the look of the other report tables
        cell.set_linewidth(0.3)
        if i == 0:
            cell.set_text_props(weight="bold")
            cell.set_facecolor("0.92")
        elif j == 3:
            cell.set_facecolor(_verdict_color(rows[i - 1][3].replace("held at 0", "at bound")))
    if any(row[3].startswith("not determined") for row in rows):
        ax_t.text(0.5, 0.0, "not determined: the measured damping does not pin this loss factor "
                  "down — fix it (--fix eta13=0.01 ...) or measure more modes / a thicker plate",
                  transform=ax_t.transAxes, ha="center", va="bottom", fontsize=8,
                  gid="loss-factor-note")
    s2 = float(d.get("s2", np.nan))
    ax_t.set_title(f"ply loss factors, modal strain energy method (s\u00b2 = {s2:.3g}, "
                   f"{int(d.get('dof', 0))} degrees of freedom; damping sigma: "
                   f"{d.get('sigma_source', '') or '-'})", fontsize=9)
    name = d.get("specimen", "")
    fig.suptitle(f"{name}: damping (modal strain energy)" if name else "damping", fontsize=11)
    return fig
