"""Plain-text tables for the terminal (formatting only; every number comes from the library)."""

from __future__ import annotations

import math

MODULI = ("E1", "E2", "G12", "G13", "G23")
GLOBAL_ORDER = (("Ex", "GPa"), ("Ey", "GPa"), ("Gxy", "GPa"), ("Gxz", "GPa"), ("Gyz", "GPa"),
                ("nu_xy", ""), ("nu_yx", ""))


def fmt(value, spec: str, missing: str = "-") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return missing
    return format(value, spec)


def format_constant(name: str, value) -> str:
    """'117.2 GPa' for moduli, '0.350' for Poisson ratios."""
    if value is None or not math.isfinite(value):
        return "-"
    if name.startswith("nu"):
        return f"{value:.3f}"
    return f"{value / 1e9:.2f} GPa"


def format_header(s: dict) -> list[str]:
    sp = s["specimen"]
    lines = [f"{sp['name']}" + (f" — {sp['description']}" if sp.get("description") else "")]
    mass = f", mass {sp['mass']:.4g} kg (model {sp['model_mass']:.4g} kg)" if sp.get("mass") else ""
    lines.append(f"plate {sp['a'] * 1e3:.4g} x {sp['b'] * 1e3:.4g} x {sp['h'] * 1e3:.4g} mm, "
                 f"{sp['n_plies']} plies{mass}, boundary {sp['boundary']}")
    m = s["mesh"]
    lines.append(f"mesh {m['nx']}x{m['ny']} ({m['nodes']} nodes, {m['dofs']} DOF)"
                 + (f", {m['rigid_modes_dropped']} rigid-body modes dropped"
                    if m.get("rigid_modes_dropped") else ""))
    return lines


def format_frequency_table(freqs: dict, extra: dict | None = None) -> list[str]:
    """Mode table: model, measured, residual, weight (+ optional extra columns)."""
    extra = extra or {}
    head = f"{'mode':>4}  {'model Hz':>10}  {'measured Hz':>11}  {'residual %':>10}  {'weight':>6}"
    for name in extra:
        head += f"  {name:>8}"
    lines = [head]
    for i, f_model in enumerate(freqs["model"]):
        row = (f"{i + 1:>4}  {fmt(f_model, '10.2f')}  {fmt(freqs['measured'][i], '11.2f')}  "
               f"{fmt(freqs['residual_percent'][i], '10.2f')}  {fmt(freqs['weight'][i], '6.2g')}")
        for values in extra.values():
            row += f"  {values[i]:>8}"
        lines.append(row)
    return lines


def format_global(props: dict) -> list[str]:
    parts = []
    for key, unit in GLOBAL_ORDER:
        v = props.get(key)
        parts.append(f"{key} {v / 1e9:.2f} GPa" if unit == "GPa" else f"{key} {v:.3f}")
    return ["global laminate properties (Appendix A): " + ", ".join(parts[:5]),
            "    " + ", ".join(parts[5:])]


def format_modes_report(s: dict) -> str:
    lines = format_header(s)
    for name, c in s["materials"].items():
        consts = ", ".join(f"{k} {format_constant(k, c[k])}" for k in (*MODULI, "nu12"))
        lines.append(f"material {name}: {consts}, density {c['density']:.1f} kg/m^3")
    lines.append("")
    lines += format_frequency_table(s["frequencies"])
    if math.isfinite(s.get("rms_residual_percent", float("nan"))):
        lines.append(f"RMS residual over the weighted modes: {s['rms_residual_percent']:.2f} %")
    lines.append("")
    lines += format_global(s["global_properties"])
    if "time_s" in s:
        lines.append(f"time {s['time_s']:.2f} s")
    return "\n".join(lines)


def format_identify_report(s: dict) -> str:
    """Terminal report of an identification, in the shape of the paper's Tables 1-3."""
    sp = s["specimen"]
    lines = [f"{sp['name']}" + (f" — {sp['description']}" if sp.get("description") else ""),
             f"plate {sp['a'] * 1e3:.4g} x {sp['b'] * 1e3:.4g} x {sp['h'] * 1e3:.4g} mm, "
             f"{sp['n_plies']} plies, boundary {sp['boundary']}"]
    state = s["status"] if s["converged"] else f"NOT CONVERGED — {s['status']}"
    lines.append(f"{s['optimizer']}: {state}; {s['evaluations']} evaluations, "
                 f"{s['time_s']:.2f} s")
    ref = s.get("reference") or {}
    ref_mats = ref.get("materials") or {}
    for name, ident in s["materials"].items():
        init = s["initial"][name]
        free = set(s["free"].get(name, ()))
        param = s["parametrization"].get(name, "")
        lines.append("")
        lines.append(f"material {name} (variables: "
                     + ("paper Eq. 14, E1/E1_0 and alphas" if param == "alpha"
                        else "free constants / initial values") + ")")
        rm = ref_mats.get(name, {})
        lines.append(f"  {'constant':<10} {'initial':>12} {'identified':>12}  "
                     f"{'reference' if rm else ''}")
        for k in (*MODULI, "nu12"):
            note = "" if k in free else "  (fixed)"
            lines.append(f"  {k + (' [GPa]' if k != 'nu12' else ''):<10} "
                         f"{_num(k, init[k]):>12} {_num(k, ident[k]):>12}  "
                         f"{_num(k, rm.get(k)) if k in rm else '':>10}{note}")
    if ref.get("source") and (ref_mats or ref.get("global")):
        lines.append(f"  reference: {' '.join(str(ref['source']).split())}")
    lines.append("")
    fr = s["frequencies"]
    extra = {}
    if any(m != i + 1 for i, m in enumerate(fr["model_mode"])):
        extra["model #"] = [str(m) for m in fr["model_mode"]]
    lines += format_frequency_table(fr, extra)
    lines.append(f"RMS residual {s['rms_residual_percent']:.3f} % "
                 f"(initial guess {s['initial_rms_residual_percent']:.2f} %), objective "
                 f"{s['objective']:.4g}")
    lines.append("")
    lines += format_global(s["global_properties"])
    gref = ref.get("global") or {}
    if gref:
        lines.append("    reference: " + ", ".join(
            f"{k} {v / 1e9:.2f} GPa" if not k.startswith("nu") else f"{k} {v:.3f}"
            for k, v in gref.items()))
    for msg in s.get("swaps", []):
        lines.append(f"note: {msg}")
    for msg in s.get("warnings", []):
        lines.append(f"warning: {msg}")
    return "\n".join(lines)


def _num(name: str, value) -> str:
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:.3f}" if name == "nu12" else f"{value / 1e9:.2f}"
