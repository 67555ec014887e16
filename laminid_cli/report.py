"""Report figures of an identification result or of a batch summary (matplotlib, Agg).

Pages of a result file (``laminid identify`` / ``laminid batch``), each a matplotlib Figure:

1. frequencies: measured vs model frequency of every paired mode, the residuals
   (measured - model)/measured*100 as bars with the weighted RMS, the constants table
   (identified, initial, reference);
2. mode shapes: transverse displacement w0 of each paired model mode (``/modes/w`` on
   ``/mesh/nodes``, interpolated inside each element with its serendipity shape functions),
   filled contours of w/max|w| with the nodal lines (w = 0) in black, titled with the model and
   measured frequencies; twelve modes per page;
3. optimisation history: objective, RMS residual and each free constant relative to its initial
   value against the evaluation number;
4. sensitivities: heat map of d ln f_i / d ln P_j at the optimum;
5. confidence intervals, when the file has an ``/uncertainty`` group;
6. FRFs with their RFP fit, when the specimen took its frequencies from an FRF file
   (``measured.frf_file``) or one is given;
7. damping (laminid_cli.report_damping), when the file has a ``/damping`` group.

Every number drawn is read from the files. A batch summary (summary.csv/.json) gives one page
of the constants across specimens (with intervals when the result files have them) and one of
the RMS residuals.

matplotlib is imported inside the functions (Agg backend forced), so importing this module is
cheap; no numerical module imports it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laminid_cli.atomic import atomic_path
from laminid_cli.errors import LaminidError

log = logging.getLogger(__name__)

CONSTANTS = ("E1", "E2", "G12", "G13", "G23", "nu12")
REPORT_SUFFIXES = (".pdf", ".png")
MODES_PER_PAGE = 12
A4_LANDSCAPE = (11.69, 8.27)


class ReportError(LaminidError):
    """A report cannot be made: unreadable input, unsupported output type (exit code 2)."""


@dataclass
class Page:
    """One report page: a short name ("frequencies", "modes-1", ...) and its Figure."""

    name: str
    figure: object


def _figure(size=A4_LANDSCAPE):
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    return Figure(figsize=size, layout="constrained")


def _s(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _gpa(key: str, value: float) -> float:
    return value if key == "nu12" else value / 1e9


def _unit(key: str) -> str:
    return "" if key == "nu12" else " (GPa)"


# ----------------------------------------------------------------------------------------------
# reading


def read_result(path) -> dict:
    """A laminid result file as nested dicts (:func:`laminid_cli.results.read_h5`)."""
    from laminid_cli.results import read_h5

    path = Path(path)
    try:
        h = read_h5(path)
    except FileNotFoundError as exc:
        raise ReportError(f"{path}: file not found") from exc
    except OSError as exc:
        raise ReportError(f"{path}: not a readable HDF5 file ({exc})") from exc
    fmt = h["@attrs"].get("format")
    if fmt != "laminid-result":
        raise ReportError(f"{path}: not a laminid identification result (format {fmt!r}, "
                          "expected 'laminid-result')")
    h["_dataset_attrs"] = dataset_attrs(path)
    return h


def dataset_attrs(path) -> dict[str, dict]:
    """{"group/dataset": {attribute: value}} of every dataset (read_h5 keeps group attributes
    only; the labels of /history/constants and /sensitivities/dlnf_dlnP are dataset ones)."""
    import h5py

    out: dict[str, dict] = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            out[name] = {k: _s(v) if isinstance(v, bytes) else v for k, v in obj.attrs.items()}

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return out


def materials_of(h: dict, group: str = "materials") -> dict[str, dict]:
    """{material name: {constant: value SI}} of a result's /materials (or /initial)."""
    out = {}
    for key, g in h.get(group, {}).items():
        if key.startswith("@"):
            continue
        name = g["@attrs"].get("name", key.replace("\u2215", "/"))
        out[name] = {k: float(g[k]) for k in CONSTANTS if k in g}
    return out


def read_intervals(h: dict) -> dict[str, dict[str, tuple[float, float]]]:
    """Confidence intervals {material: {constant: (low, high)}} (SI) from ``/uncertainty``.

    Accepted layouts (the group is optional; an empty dict when absent or not understood):
    per-material groups ``/uncertainty/<material>`` holding, per constant, a dataset of two
    values (low, high) or a group/attributes with ``low``/``high`` (or ``lower``/``upper``,
    ``ci_low``/``ci_high``); or arrays over the labels ``"<material>.<constant>"`` (attribute
    ``labels`` or dataset ``labels``) named ``lower``/``upper`` (``low``/``high``,
    ``ci_low``/``ci_high``) or ``interval`` (n, 2); or ``value`` and ``half_width``/
    ``std`` (then the interval is value +/- 1.96 std).
    """
    u = h.get("uncertainty")
    if not isinstance(u, dict):
        return {}
    out: dict[str, dict] = {}
    mats = materials_of(h)

    def low_high(node):
        if isinstance(node, dict):
            src = {**node.get("@attrs", {}), **{k: v for k, v in node.items() if k != "@attrs"}}
        else:
            arr = np.asarray(node, dtype=float).ravel()
            return (float(arr[0]), float(arr[1])) if arr.size == 2 else None
        for lo, hi in (("low", "high"), ("lower", "upper"), ("ci_low", "ci_high")):
            if lo in src and hi in src:
                return float(np.ravel(src[lo])[0]), float(np.ravel(src[hi])[0])
        if "interval" in src:
            return low_high(src["interval"])
        return None

    # per-material groups
    for key, g in u.items():
        if key.startswith("@") or not isinstance(g, dict):
            continue
        name = g.get("@attrs", {}).get("name", key.replace("\u2215", "/"))
        if name not in mats:
            continue
        for k in CONSTANTS:
            if k in g:
                iv = low_high(g[k])
                if iv is not None:
                    out.setdefault(name, {})[k] = iv
    if out:
        return out
    # flat arrays over labels
    ds_attrs = h.get("_dataset_attrs", {})
    groups = [("uncertainty", u)] + [(f"uncertainty/{k}", g) for k, g in u.items()
                                     if not k.startswith("@") and isinstance(g, dict)]
    for where, g in groups:
        labels = g.get("labels", g.get("@attrs", {}).get("labels"))
        if labels is None:                      # a labels attribute on one of the datasets
            labels = next((a["labels"] for name, a in ds_attrs.items()
                           if name.rsplit("/", 1)[0] == where and "labels" in a), None)
        if labels is None:
            continue
        if isinstance(labels, (str, bytes)):
            labels = _s(labels).split(",")
        labels = [_s(x) for x in np.ravel(labels)]
        lows = highs = None
        for lo, hi in (("lower", "upper"), ("low", "high"), ("ci_low", "ci_high")):
            if lo in g and hi in g:
                lows, highs = np.ravel(g[lo]), np.ravel(g[hi])
                break
        if lows is None and "interval" in g:
            arr = np.asarray(g["interval"], float).reshape(len(labels), 2)
            lows, highs = arr[:, 0], arr[:, 1]
        if lows is None and "value" in g and ("half_width" in g or "std" in g):
            v = np.ravel(g["value"])
            hw = np.ravel(g["half_width"]) if "half_width" in g else 1.96 * np.ravel(g["std"])
            lows, highs = v - hw, v + hw
        if lows is None or len(lows) != len(labels):
            continue
        for lab, lo, hi in zip(labels, lows, highs):
            if "." not in lab:
                continue
            m, k = lab.rsplit(".", 1)
            if m in mats and k in CONSTANTS and np.isfinite(lo) and np.isfinite(hi):
                out.setdefault(m, {})[k] = (float(lo), float(hi))
        if out:
            return out
    return out


def frf_source(h: dict, frf_path=None):
    """(path, bands, n_modes) of the FRF file the result's specimen was fitted from, or None.

    ``frf_path`` overrides; otherwise ``measured.frf_file`` of the stored specimen YAML,
    relative to the specimen's folder (``/specimen`` attribute ``path``).
    """
    import yaml

    try:
        doc = yaml.safe_load(h["specimen"]["yaml"])
        m = doc.get("measured", {}) if isinstance(doc, dict) else {}
    except (KeyError, yaml.YAMLError, AttributeError):
        m = {}
    bands = None
    if isinstance(m, dict) and m.get("bands"):
        try:
            bands = [tuple(float(v) for v in str(b).split(":")) for b in m["bands"]]
        except ValueError:
            bands = None
    n_modes = int(m["modes"]) if isinstance(m, dict) and m.get("modes") else None
    if frf_path is not None:
        return Path(frf_path), bands, n_modes
    if not isinstance(m, dict) or not m.get("frf_file"):
        return None
    spec_path = Path(h["specimen"]["@attrs"].get("path", "."))
    p = spec_path.parent / str(m["frf_file"])
    if not p.exists():
        log.warning("FRF file %s of the specimen not found: no FRF page", p)
        return None
    return p, bands, n_modes


# ----------------------------------------------------------------------------------------------
# pages of a result


def result_pages(path, *, frf_path=None) -> list[Page]:
    """All pages of the report of one result file."""
    h = read_result(path)
    pages = [Page("frequencies", frequency_page(h))]
    pages += [Page(f"modes-{k + 1}", fig) for k, fig in enumerate(mode_shape_pages(h))]
    pages.append(Page("history", history_page(h)))
    pages.append(Page("sensitivities", sensitivity_page(h)))
    intervals = read_intervals(h)
    if intervals:
        pages.append(Page("intervals", interval_page(h, intervals)))
    src = frf_source(h, frf_path)
    if src is not None:
        pages.append(Page("frf", frf_page(h, *src)))
    from laminid_cli.report_damping import damping_figures
    pages += [Page(name, fig) for name, fig in damping_figures(path)]
    return pages


def _title(h: dict) -> str:
    a = h["@attrs"]
    spec = h["specimen"]["@attrs"].get("name", "")
    state = "converged" if a.get("converged") else "NOT CONVERGED"
    rms = h["frequencies"]["@attrs"].get("rms_residual_percent", np.nan)
    mesh = h["mesh"]["@attrs"]
    return (f"{spec}: {a.get('optimizer', '')} {state}, RMS residual {rms:.3f} %, "
            f"{a.get('evaluations', '?')} evaluations, mesh {mesh.get('nx')}x{mesh.get('ny')}")


def frequency_page(h: dict):
    """Measured vs model frequencies, residual bars, constants table."""
    fr = h["frequencies"]
    measured, model = np.asarray(fr["measured"], float), np.asarray(fr["model"], float)
    residual, weight = np.asarray(fr["residual_percent"], float), np.asarray(fr["weight"], float)
    rms = float(fr["@attrs"].get("rms_residual_percent", np.nan))
    n = measured.size
    mode = np.arange(1, n + 1)
    fig = _figure()
    fig.suptitle(_title(h), fontsize=11)
    gs = fig.add_gridspec(2, 2, width_ratios=[1.5, 1], height_ratios=[1, 1])
    ax_f = fig.add_subplot(gs[0, 0])
    ax_r = fig.add_subplot(gs[1, 0], sharex=ax_f)
    ax_t = fig.add_subplot(gs[:, 1])
    ax_f.set_gid("frequencies")
    ax_r.set_gid("residuals")
    width = 0.38
    ax_f.bar(mode - width / 2, np.nan_to_num(measured), width, color="0.55", label="measured")
    ax_f.bar(mode + width / 2, model, width, color="C0", label="model")
    for k in np.flatnonzero(~np.isfinite(measured)):
        ax_f.annotate("not measured", (mode[k] - width / 2, 0.5 * model[k]), ha="center",
                      va="center", fontsize=7, rotation=90)
    ax_f.set_ylabel("natural frequency (Hz)")
    ax_f.legend(loc="upper left", fontsize=8)
    ax_f.set_title("measured and model frequencies", fontsize=10)
    colors = ["C3" if r < 0 else "C2" for r in np.nan_to_num(residual)]
    bars = ax_r.bar(mode, np.nan_to_num(residual), 0.6, color=colors)
    for k in np.flatnonzero(weight == 0):
        bars[k].set_hatch("//")
        bars[k].set_alpha(0.4)
        if not np.isfinite(residual[k]):
            ax_r.annotate("n/m", (mode[k], 0), ha="center", va="bottom", fontsize=7)
    ax_r.axhline(0, color="k", lw=0.6)
    if np.isfinite(rms):
        for s in (1, -1):
            ax_r.axhline(s * rms, color="k", ls="--", lw=0.8,
                         label=f"weighted RMS {rms:.3f} %" if s == 1 else None)
        ax_r.legend(loc="upper right", fontsize=8)
    ax_r.set_ylabel("residual (measured - model)/measured (%)")
    ax_r.set_xlabel("mode")
    ax_r.set_xticks(mode)
    ax_r.set_title("residuals (hatched: weight 0)", fontsize=10)
    lim = np.nanmax(np.abs(residual)) if np.isfinite(residual).any() else 1.0
    ax_r.set_ylim(-1.25 * lim, 1.25 * lim)
    _constants_table(ax_t, h)
    return fig


def _constants_table(ax, h: dict) -> None:
    ax.axis("off")
    ident, init = materials_of(h), materials_of(h, "initial")
    ref = _reference(h)
    rows, cells = [], []
    for m, c in ident.items():
        for k in CONSTANTS:
            rows.append(f"{m} {k}{_unit(k)}" if len(ident) > 1 else f"{k}{_unit(k)}")
            fmt = "{:.3f}" if k == "nu12" else "{:.2f}"
            r = ref.get(m, {}).get(k)
            cells.append([fmt.format(_gpa(k, c[k])),
                          fmt.format(_gpa(k, init[m][k])) if k in init.get(m, {}) else "",
                          fmt.format(_gpa(k, r)) if r is not None else ""])
    title = "identified constants" + (f" ({next(iter(ident))})" if len(ident) == 1 else "")
    ax.set_title(title, fontsize=10)
    if rows:
        t = ax.table(cellText=cells, rowLabels=rows, colLabels=["identified", "initial",
                                                                 "reference"], loc="upper center")
        t.auto_set_font_size(False)
        t.set_fontsize(8)
        t.scale(1, 1.3)
    gp = {k: float(v) for k, v in h.get("global_properties", {}).items() if not k.startswith("@")}
    if gp:
        lines = ["laminate (Appendix A):"] + [
            f"{k} = {v / 1e9:.2f} GPa" if not k.startswith("nu") else f"{k} = {v:.3f}"
            for k, v in gp.items()]
        ax.text(0.02, 0.45, "\n".join(lines), transform=ax.transAxes, fontsize=8, va="top",
                family="monospace")


def _reference(h: dict) -> dict:
    import yaml

    from laminid_cli.units import parse_quantity

    try:
        doc = yaml.safe_load(h["specimen"]["yaml"])
        mats = doc["reference"]["materials"]
    except (KeyError, TypeError, yaml.YAMLError):
        return {}
    out: dict[str, dict] = {}
    for m, consts in (mats or {}).items():
        for k, v in (consts or {}).items():
            if isinstance(v, list) and len(v) == 2:
                v = None
            try:
                out.setdefault(m, {})[k] = float(parse_quantity(v, "dimensionless" if k == "nu12"
                                                                 else "modulus"))
            except Exception:  # noqa: BLE001 - a reference value we cannot read is not drawn
                continue
    return out


def mode_shape_grid(h: dict, k: int, n_sub: int = 6):
    """w0 of paired mode ``k`` on a fine triangulation: (x m, y m, triangles, w).

    Each element is sampled on an n_sub x n_sub grid of natural coordinates and w is
    interpolated with its eight serendipity shape functions, so the picture is the FE field
    and not a linear interpolation of the nodal values.
    """
    from laminid_cli.fe.element import shape_functions

    nodes = np.asarray(h["mesh"]["nodes"], float)
    elements = np.asarray(h["mesh"]["elements"], int)
    w = np.asarray(h["modes"]["w"], float)[:, k]
    s = np.linspace(-1, 1, n_sub + 1)
    XI, ETA = np.meshgrid(s, s)
    N, _ = shape_functions(np.column_stack([XI.ravel(), ETA.ravel()]))     # (p, 8)
    xy = np.einsum("pa,eai->epi", N, nodes[elements])                      # (n_el, p, 2)
    ww = np.einsum("pa,ea->ep", N, w[elements])                             # (n_el, p)
    # two triangles per sub-cell, local point index j*(n_sub+1)+i
    m = n_sub + 1
    i, j = np.meshgrid(np.arange(n_sub), np.arange(n_sub))
    p0 = (j * m + i).ravel()
    local = np.vstack([np.column_stack([p0, p0 + 1, p0 + m + 1]),
                       np.column_stack([p0, p0 + m + 1, p0 + m])])
    n_pts = m * m
    tris = (local[None, :, :] + (np.arange(elements.shape[0]) * n_pts)[:, None, None]).reshape(-1, 3)
    return xy[..., 0].ravel(), xy[..., 1].ravel(), tris, ww.ravel()


def _grid(n: int, aspect: float, width: float = 10.5, height: float = 6.6) -> tuple[int, int]:
    """(n_rows, n_cols) that draws n plates of height/width ``aspect`` largest on the page
    (each cell also needs room for a two-line title and tick labels: +0.9 in, +0.5 in)."""
    best, best_scale = (1, n), 0.0
    for ncol in range(1, n + 1):
        nrow = -(-n // ncol)
        scale = min(width / ncol - 0.5, (height / nrow - 0.9) / aspect)
        if scale > best_scale:
            best, best_scale = (nrow, ncol), scale
    return best


def mode_shape_pages(h: dict) -> list:
    """Pages of mode shapes, at most MODES_PER_PAGE per page, split evenly."""
    w = np.asarray(h["modes"]["w"], float)
    n = w.shape[1]
    fr = h["frequencies"]
    model, measured = np.asarray(fr["model"], float), np.asarray(fr["measured"], float)
    model_mode = np.asarray(fr.get("model_mode", np.arange(1, n + 1)), int)
    a, b = float(h["specimen"]["a"]), float(h["specimen"]["b"])
    n_pages = -(-n // MODES_PER_PAGE)
    per_page = -(-n // n_pages)
    spec = h["specimen"]["@attrs"].get("name", "")
    figs = []
    for start in range(0, n, per_page):
        idx = list(range(start, min(n, start + per_page)))
        nrow, ncol = _grid(len(idx), b / a)
        fig = _figure()
        page = f" ({len(figs) + 1}/{n_pages})" if n_pages > 1 else ""
        fig.suptitle(f"{spec}: mode shapes w0 of the model at the identified constants{page}; "
                     "colour w / max|w|, black lines: nodal lines (w = 0)", fontsize=11)
        axes = fig.subplots(nrow, ncol, squeeze=False, sharex=True, sharey=True).ravel()
        cs = None
        for ax, k in zip(axes, idx):
            x, y, tris, ww = mode_shape_grid(h, k)
            scale = np.max(np.abs(ww)) or 1.0
            ww = ww / scale
            cs = ax.tricontourf(x * 1e3, y * 1e3, tris, ww, levels=np.linspace(-1, 1, 17),
                                cmap="RdBu_r")
            if ww.min() < 0 < ww.max():
                ax.tricontour(x * 1e3, y * 1e3, tris, ww, levels=[0.0], colors="k",
                              linewidths=1.4)
            ax.set_aspect("equal")
            ax.set_gid(f"mode-{k + 1}")
            paired = f" (model mode {model_mode[k]})" if model_mode[k] != k + 1 else ""
            meas = f"measured {measured[k]:.1f} Hz" if np.isfinite(measured[k]) else \
                "not measured"
            ax.set_title(f"mode {k + 1}{paired}: {model[k]:.1f} Hz\n{meas}", fontsize=8)
            ax.tick_params(labelsize=6)
        for i, ax in enumerate(axes[:len(idx)]):
            if i + ncol >= len(idx):                   # nothing drawn below: label x
                ax.set_xlabel("x (mm)", fontsize=7)
                ax.tick_params(labelbottom=True)
            if i % ncol == 0:
                ax.set_ylabel("y (mm)", fontsize=7)
        for ax in axes[len(idx):]:
            ax.axis("off")
        if cs is not None:
            cb = fig.colorbar(cs, ax=axes[:len(idx)].tolist(), shrink=0.6, ticks=[-1, 0, 1])
            cb.set_label("w / max|w|")
        figs.append(fig)
    return figs


def history_page(h: dict):
    """Objective, RMS residual and the free constants / initial value per evaluation."""
    hist = h["history"]
    ev = np.asarray(hist["evaluation"])
    fig = _figure()
    fig.suptitle(_title(h) + ": optimisation history", fontsize=11)
    ax_o, ax_r, ax_c = fig.subplots(3, 1, sharex=True)
    ax_o.set_gid("objective")
    obj = np.asarray(hist["objective"], float)
    ax_o.semilogy(ev, obj, "o-", ms=3, color="C0")
    best = int(np.argmin(obj))
    ax_o.semilogy(ev[best], obj[best], "*", ms=12, color="C3", label=f"best {obj[best]:.3g}")
    ax_o.legend(fontsize=8)
    ax_o.set_ylabel("objective (Eq. 17)")
    ax_r.plot(ev, np.asarray(hist["rms_residual_percent"], float), "o-", ms=3, color="C1")
    ax_r.set_ylabel("RMS residual (%)")
    const = np.asarray(hist["constants"], float)
    labels = _short(h, _labels(h, "history", "constants")
                    or [f"P{j + 1}" for j in range(const.shape[1])])
    shown = 0
    for j, lab in enumerate(labels):
        col = const[:, j]
        if col[0] == 0 or np.allclose(col, col[0], rtol=1e-12):
            continue                                          # fixed constant: flat line
        ax_c.plot(ev, col / col[0], "-", lw=1.2, label=lab)
        shown += 1
    ax_c.axhline(1, color="k", lw=0.5)
    ax_c.set_ylabel("constant / initial value")
    ax_c.set_xlabel("evaluation")
    if shown:
        ax_c.legend(fontsize=7, ncol=min(6, shown), loc="best")
    return fig


def _labels(h: dict, group: str, name: str) -> list[str]:
    """The comma-separated ``labels`` attribute of a dataset, as a list ([] when absent)."""
    text = h.get("_dataset_attrs", {}).get(f"{group}/{name}", {}).get("labels", "")
    return [x for x in _s(text).split(",") if x] if text is not None else []


def _short(h: dict, labels: list[str]) -> list[str]:
    """Labels "<material>.<constant>" without the material when there is only one."""
    mats = materials_of(h)
    if len(mats) != 1:
        return labels
    prefix = next(iter(mats)) + "."
    return [lab[len(prefix):] if lab.startswith(prefix) else lab for lab in labels]


def sensitivity_page(h: dict):
    """Heat map of the normalised sensitivities d ln f_i / d ln P_j at the optimum."""
    S = np.asarray(h["sensitivities"]["dlnf_dlnP"], float)
    labels = _short(h, _labels(h, "sensitivities", "dlnf_dlnP")
                    or [f"P{j + 1}" for j in range(S.shape[1])])
    fr = h["frequencies"]
    model = np.asarray(fr["model"], float)
    fig = _figure()
    fig.suptitle(_title(h) + ": sensitivities", fontsize=11)
    ax = fig.subplots()
    ax.set_gid("sensitivity")
    vmax = float(np.nanmax(np.abs(S))) or 1.0
    im = ax.imshow(S, cmap="RdBu_r", vmin=-vmax, vmax=vmax, aspect="auto")
    ax.set_xticks(range(S.shape[1]), labels, rotation=30 if S.shape[1] > 6 else 0,
                  ha="right" if S.shape[1] > 6 else "center", fontsize=8)
    ax.set_yticks(range(S.shape[0]), [f"mode {i + 1}: {f:.1f} Hz" for i, f in enumerate(model)],
                  fontsize=8)
    fs = 8 if S.size <= 150 else 6
    for i in range(S.shape[0]):
        for j in range(S.shape[1]):
            v = S[i, j]
            ax.text(j, i, f"{v + 0.0:.3f}" if abs(v) >= 5e-4 else "0", ha="center", va="center", fontsize=fs,
                    color="w" if abs(v) > 0.6 * vmax else "k")
    ax.set_xlabel("ply constant $P_j$" + (f" ({next(iter(materials_of(h)))})"
                                         if len(materials_of(h)) == 1 else ""))
    ax.set_ylabel("measured mode $i$ (model frequency)")
    ax.set_title(r"normalised sensitivity $\partial \ln f_i / \partial \ln P_j$ at the optimum "
                 "(a column near 0: the frequencies do not determine that constant)", fontsize=9)
    cb = fig.colorbar(im, ax=ax, shrink=0.8)
    cb.set_label(r"$\partial \ln f_i / \partial \ln P_j$")
    return fig


def interval_page(h: dict, intervals: dict):
    """Identified constants with their confidence intervals (relative to the value, %)."""
    ident = materials_of(h)
    fig = _figure()
    fig.suptitle(_title(h) + ": confidence intervals", fontsize=11)
    ax = fig.subplots()
    ax.set_gid("intervals")
    labels, lo, hi, vals = [], [], [], []
    for m, iv in intervals.items():
        for k in CONSTANTS:
            if k not in iv or k not in ident.get(m, {}):
                continue
            v = ident[m][k]
            labels.append(f"{m} {k}" if len(intervals) > 1 else k)
            vals.append(v)
            lo.append((iv[k][0] - v) / abs(v) * 100)
            hi.append((iv[k][1] - v) / abs(v) * 100)
    y = np.arange(len(labels))
    ax.hlines(y, lo, hi, color="C0", lw=6, alpha=0.6)
    ax.plot(np.zeros_like(y), y, "k|", ms=14)
    for yi, v, l_, h_, lab in zip(y, vals, lo, hi, labels):
        k = lab.rsplit(" ", 1)[-1]
        txt = (f"{_gpa(k, v):.3f} [{_gpa(k, v * (1 + l_ / 100)):.3f}, "
               f"{_gpa(k, v * (1 + h_ / 100)):.3f}]{_unit(k)}")
        ax.annotate(txt, (max(h_, 0), yi), xytext=(6, 0), textcoords="offset points",
                    va="center", fontsize=8)
    ax.set_yticks(y, labels)
    ax.invert_yaxis()
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("interval relative to the identified value (%)")
    span = max([abs(v) for v in lo + hi] + [1.0])
    ax.set_xlim(-1.1 * span, 1.7 * span)
    return fig


def frf_page(h: dict, frf_path, bands=None, n_modes=None):
    """FRF magnitudes with the RFP fit, the RFP natural frequencies and the model ones."""
    from laminid_cli.frf import rfp
    from laminid_cli.frf.io import read_frf

    fs = read_frf(frf_path)
    fit = rfp.find_modes(fs.freq, fs.frf, bands=bands, n_modes=n_modes)
    fig = _figure()
    fig.suptitle(f"{h['specimen']['@attrs'].get('name', '')}: FRFs of {Path(frf_path).name} "
                 f"with the RFP fit", fontsize=11)
    ax_m, ax_p = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1.4])
    ax_m.set_gid("frf")
    with np.errstate(divide="ignore", invalid="ignore"):
        for H in fs.frf:
            ax_m.plot(fs.freq, 20 * np.log10(np.abs(H)), color="0.7", lw=0.6)
            ax_p.plot(fs.freq, np.degrees(np.angle(H)), color="0.7", lw=0.6)
        for k, band in enumerate(fit.bands):
            lo, hi = band.band_hz
            sel = (fs.freq >= lo) & (fs.freq <= hi) & (fs.freq > 0)
            Hs = band.synthesise(fs.freq[sel])
            for p, H in enumerate(Hs):
                ax_m.plot(fs.freq[sel], 20 * np.log10(np.abs(H)), color=f"C{k % 10}", lw=0.9,
                          label="RFP fit" if k == 0 and p == 0 else None)
                ax_p.plot(fs.freq[sel], np.degrees(np.angle(H)), color=f"C{k % 10}", lw=0.9)
    for i, m in enumerate(fit.modes):
        for ax in (ax_m, ax_p):
            ax.axvline(m.freq_hz, color="k", ls="--", lw=0.6,
                       label="RFP natural frequency" if ax is ax_m and i == 0 else None)
        ax_m.annotate(f"{m.freq_hz:.1f}", (m.freq_hz, 1), xycoords=("data", "axes fraction"),
                      rotation=90, va="top", ha="right", fontsize=7)
    model = np.asarray(h["frequencies"]["model"], float)
    for i, f in enumerate(model):
        ax_m.axvline(f, color="C3", ls=":", lw=1.0, label="model (identified)" if i == 0 else None)
    ax_m.set_ylabel(f"|H| (dB re 1 {fs.units})")
    ax_m.legend(loc="lower right", fontsize=8)
    ax_p.set_ylabel("phase (deg)")
    ax_p.set_ylim(-185, 185)
    ax_p.set_xlabel("frequency (Hz)")
    if fit.bands:
        ax_p.set_xlim(min(b.band_hz[0] for b in fit.bands) * 0.95,
                      max(b.band_hz[1] for b in fit.bands) * 1.02)
    return fig


# ----------------------------------------------------------------------------------------------
# batch summary


def summary_pages(path) -> list[Page]:
    """Pages of the report of a batch summary (summary.csv or summary.json)."""
    from laminid_cli.batch import read_summary

    rows = read_summary(path)
    done = []
    for r in rows:
        res = r.get("result")
        mats, iv = r["materials"], {}
        if res and Path(res).exists():
            try:
                h = read_result(res)
                mats, iv = materials_of(h), read_intervals(h)
            except ReportError as exc:
                log.warning("%s: %s; using the summary's numbers", r["name"], exc)
        if mats:
            done.append((r, mats, iv))
    if not done:
        raise ReportError(f"{path}: no identified specimen in the summary")
    return [Page("constants", constants_across_page(done, Path(path).name)),
            Page("residuals", residuals_across_page(rows, Path(path).name))]


def constants_across_page(done, title: str):
    """One panel per constant: value of each specimen (and material) with its interval."""
    materials: list[str] = []
    for _, mats, _ in done:
        materials += [m for m in mats if m not in materials]
    fig = _figure()
    fig.suptitle(f"{title}: identified constants across specimens (bars: confidence "
                 "intervals where the results have them; hollow: not converged)", fontsize=11)
    axes = fig.subplots(2, 3).ravel()
    names = [r["specimen"] if r.get("specimen") else r["name"] for r, _, _ in done]
    if len(set(names)) != len(names):
        names = [r["name"] for r, _, _ in done]
    x = np.arange(len(done))
    for ax, k in zip(axes, CONSTANTS):
        ax.set_gid(f"across-{k}")
        values, ends = [], []
        for c, m in enumerate(materials):
            xs, ys, err, hollow = [], [], [[], []], []
            for i, (r, mats, iv) in enumerate(done):
                if m not in mats or k not in mats[m]:
                    continue
                v = _gpa(k, mats[m][k])
                lo, hi = iv.get(m, {}).get(k, (mats[m][k], mats[m][k]))
                lo, hi = _gpa(k, lo), _gpa(k, hi)
                xs.append(i)
                ys.append(v)
                err[0].append(max(v - lo, 0))
                err[1].append(max(hi - v, 0))
                hollow.append(r["status"] != "ok")
                values.append(v)
                if hi - lo < abs(v):                  # a meaningful interval sets the scale
                    ends += [lo, hi]
            if not xs:
                continue
            color = f"C{c % 10}"
            ax.errorbar(xs, ys, yerr=err, fmt="none", capsize=3, color=color, lw=1)
            xs, ys, hollow = np.array(xs), np.array(ys), np.array(hollow)
            ax.plot(xs[~hollow], ys[~hollow], "o", ms=5, color=color, label=m)
            if hollow.any():
                ax.plot(xs[hollow], ys[hollow], "o", ms=6, mfc="none", color=color,
                        label=f"{m} (not converged)")
        if values:
            lo, hi = min(values + ends), max(values + ends)
            pad = 0.12 * (hi - lo) if hi > lo else 0.1 * abs(hi) or 1.0
            ax.set_ylim(lo - pad, hi + pad)         # wider intervals run off the panel
        ax.set_title(k, fontsize=10)
        ax.set_ylabel(k + _unit(k), fontsize=8)
        ax.set_xticks(x, names, rotation=45, ha="right", fontsize=7)
        ax.grid(axis="y", lw=0.3)
    handles = {}
    for ax in axes:
        for hd, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, hd)
    fig.legend(list(handles.values()), list(handles), loc="outside lower center",
               ncol=min(len(handles), 7), fontsize=8)
    return fig


def residuals_across_page(rows, title: str):
    fig = _figure()
    fig.suptitle(f"{title}: weighted RMS frequency residual per specimen", fontsize=11)
    ax = fig.subplots()
    ax.set_gid("rms")
    names = [r["name"] for r in rows]
    rms = [r["rms_residual_percent"] if r["rms_residual_percent"] is not None else 0.0
           for r in rows]
    colors = ["C0" if r["status"] == "ok" else ("C1" if r["status"] == "not converged"
                                                else "0.7") for r in rows]
    ax.bar(np.arange(len(rows)), rms, color=colors)
    for i, r in enumerate(rows):
        if r["status"] != "ok":
            ax.annotate(r["status"], (i, rms[i]), xytext=(0, 3), textcoords="offset points",
                        ha="center", fontsize=7, rotation=90, va="bottom")
    ax.set_xticks(np.arange(len(rows)), names, rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("RMS residual (%)")
    ax.set_xlabel("specimen")
    return fig


# ----------------------------------------------------------------------------------------------
# output


def is_summary(path) -> bool:
    p = Path(path)
    return p.suffix.lower() in (".csv", ".json")


def report_pages(path, *, frf_path=None) -> list[Page]:
    """Pages of a result file or a batch summary (by the suffix: .csv/.json = summary)."""
    if is_summary(path):
        return summary_pages(path)
    pages = result_pages(path, frf_path=frf_path)
    return pages


def write_pages(pages, out, *, dpi: int = 110) -> list[Path]:
    """Write a multi-page PDF (one file) or PNGs (``out`` for one page, else ``<stem>-1.png``,
    ``<stem>-2.png``...). Each file goes to a temporary name first, then is renamed."""

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
                for p in pages:
                    pdf.savefig(p.figure)
        return [out]
    for k, p in enumerate(pages, start=1):
        target = out if len(pages) == 1 else out.with_name(f"{out.stem}-{k}{out.suffix}")
        with atomic_path(target) as tmp:
            p.figure.savefig(tmp, dpi=dpi, format="png")
        written.append(target)
    return written
