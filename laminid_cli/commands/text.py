"""Plain-text tables for the terminal (formatting only; every number comes from the library)."""

from __future__ import annotations

import math
import re

from laminid_cli.intervals import (VERDICT_FIXED, VERDICT_NOT, flag_words, spread_sentence, t_std,
                                    width_text)
from laminid_cli.units import constant_text, number_text, significant_text

#: the advice that ends the verdict "not determined by these modes — fix it or ..." (shown
#: once in the constants' table, not again for the laminate's properties)
VERDICT_ADVICE = " — " + VERDICT_NOT.split(" — ", 1)[1]

MODULI = ("E1", "E2", "G12", "G13", "G23")
GLOBAL_ORDER = (("Ex", "GPa"), ("Ey", "GPa"), ("Gxy", "GPa"), ("Gxz", "GPa"), ("Gyz", "GPa"),
                ("nu_xy", ""), ("nu_yx", ""))


def _plies(n: int) -> str:
    """'1 ply', '24 plies'."""
    return f"{n} ply" if n == 1 else f"{n} plies"


def fmt(value, spec: str, missing: str = "-") -> str:
    """``value`` in ``spec``; ``missing`` (None, NaN, inf) right-aligned to the spec's width,
    so a mode that was not measured keeps its table's columns; a value that rounds to zero
    without a minus (:func:`~laminid_cli.units.number_text`: a residual "0.00", not "-0.00")."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        width = re.match(r"\d*", spec.lstrip("<>^=+- ")).group()
        return missing.rjust(int(width)) if width else missing
    return number_text(value, spec)


def _sig3(value, missing: str = "-") -> str:
    """Three significant digits with their trailing zeros, as units.significant_text: s2 and
    chi2 "2.00", not "2" (``g`` dropped them, and "chi2 2" beside "s2 0.286" read as exact)."""
    if value is None or not math.isfinite(value):
        return missing
    text = number_text(value, "#.3g")
    return text[:-1] if text.endswith(".") else text


def format_constant(name: str, value) -> str:
    """'117.2 GPa' for moduli, '0.350' for Poisson ratios."""
    if value is None or not math.isfinite(value):
        return "-"
    if name.startswith("nu"):
        return number_text(value, ".3f")
    return f"{_num(name, value)} GPa"          # a modulus below 1 GPa: 0.0031, not 0.00


def format_header(s: dict) -> list[str]:
    sp = s["specimen"]
    lines = [f"{sp['name']}" + (f" — {sp['description']}" if sp.get("description") else "")]
    mass = f", mass {sp['mass']:.4g} kg (model {sp['model_mass']:.4g} kg)" if sp.get("mass") else ""
    lines.append(f"plate {sp['a'] * 1e3:.4g} x {sp['b'] * 1e3:.4g} x {sp['h'] * 1e3:.4g} mm, "
                 f"{_plies(sp['n_plies'])}{mass}, boundary {sp['boundary']}")
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


def _finite(x) -> bool:
    return x is not None and math.isfinite(x)


def format_global(props: dict, unc: dict | None = None) -> list[str]:
    """The laminate's global properties (Appendix A); with ``unc`` (the JSON block
    "global_uncertainty") a table with their intervals and verdicts."""
    if unc:
        # with a Monte Carlo, each property's range over the trials, each at its own constants
        # (laminid_cli.global_uncertainty.MonteCarloRange), as the constants' table gives it
        mc = any("monte_carlo" in u for u in unc.values())
        lines = ["global laminate properties (Appendix A; 95 % intervals from the constants' "
                 "covariance" + ("; Monte Carlo: the property at each trial's constants"
                                 if mc else "") + ")"]
        if mc:
            lines.append(f"  {'property':<10} {'value':>8}  {'95 % interval':>17} "
                         f"{'±':>8}  {'Monte Carlo 95 % range':>24}  verdict")
        marked = False
        for key, unit in GLOBAL_ORDER:
            u = unc.get(key)
            v = props.get(key)
            if u is None or v is None:
                continue
            gpa = unit == "GPa"
            name = key if gpa else "nu12"         # _num: a modulus in GPa, or a ratio
            span = (f"{_num(name, u['lower'])} .. {_num(name, u['upper'])}"
                    if _finite(u["lower"]) else "none")
            rel = _pct(u["rel_half_width"]) if _finite(u["rel_half_width"]) else "—"
            cell = ""
            if mc:
                r = u.get("monte_carlo")
                cell = "none"
                if r and _finite(r.get("lower")):
                    # the digits of the constants' Monte Carlo table; "*": an end set by
                    # trials on a limit of the search
                    cell = (significant_text(name, r["lower"], 4)
                            + ("*" if r.get("lower_at_bound") else "") + " .. "
                            + significant_text(name, r["upper"], 4)
                            + ("*" if r.get("upper_at_bound") else ""))
                    marked |= bool(r.get("lower_at_bound") or r.get("upper_at_bound"))
                cell = f"{cell:>24}  "
            lines.append(f"  {key + (' [GPa]' if gpa else ''):<10} {_num(name, v):>8}  {span:>17} "
                         f"{rel:>8}  {cell}{u['verdict'].replace(VERDICT_ADVICE, '')}")
        if marked:
            lines.append("  * that end of the Monte Carlo range is set by trials with a constant "
                         "the property depends on on a limit of the search: the search's "
                         "limit, not the data's")
        return lines
    parts = []
    for key, unit in GLOBAL_ORDER:
        v = props.get(key)
        parts.append(f"{key} {format_constant(key, v)}")
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


def _plate_header(sp: dict) -> list[str]:
    return [f"{sp['name']}" + (f" — {sp['description']}" if sp.get("description") else ""),
            f"plate {sp['a'] * 1e3:.4g} x {sp['b'] * 1e3:.4g} x {sp['h'] * 1e3:.4g} mm, "
            f"{_plies(sp['n_plies'])}, boundary {sp['boundary']}"]


def _run_line(s: dict) -> str:
    opt = s["optimizer_status"]
    state = opt if s["converged"] else f"NOT CONVERGED — {opt}"
    how = ", ".join(x for x in (f"{s['solver']} solver" if s.get("solver") else "",
                                {"cholmod": "CHOLMOD", "banded": "banded Cholesky"}.get(
                                    s.get("factorization", ""), ""),
                                f"{s['equations']} equations"
                                if s.get("equations", "all") != "all" else "") if x)
    return (f"{s['optimizer']}: {state}; {s['evaluations']} evaluations, {s['time_s']:.2f} s"
            + (f" ({how})" if how else ""))


def format_status(s: dict) -> list[str]:
    """'status: ok' or 'status: CHECK' and one line per reason (laminid_cli.status)."""
    if "status" not in s:
        return []
    reasons = s.get("reasons") or []
    if not reasons:
        return ["status: ok"]
    lines = [f"status: CHECK — {len(reasons)} reason{'s' if len(reasons) > 1 else ''}"]
    lines += [f"  {r['code']}: {r['text']}" for r in reasons]
    return lines


def _paired_frequency_table(fr: dict, sigma: dict | None = None) -> list[str]:
    """Frequency table with a 'model #' column when the pairing is not in sorted order, and a
    '+/- Hz' column with each measured frequency's standard deviation where the run had them
    (``sigma``: the plate's entry of the JSON's uncertainty.frequency_sigma), as the damping
    table gives the measured loss factors': the residuals are read against them."""
    extra = {}
    sig = (sigma or {}).get("sigma_hz")
    if sig is not None and len(sig) == len(fr["measured"]):
        extra["+/- Hz"] = [fmt(x, ".2f") for x in sig]
    if any(m != i + 1 for i, m in enumerate(fr["model_mode"])):
        extra["model #"] = [str(m) for m in fr["model_mode"]]
    return format_frequency_table(fr, extra)


def _plate_sigma(s: dict, name: str) -> dict | None:
    """The plate's frequency sigmas of an identify/joint JSON (None without uncertainty)."""
    fs = (s.get("uncertainty") or {}).get("frequency_sigma") or {}
    return fs.get(name)


def _closing_lines(s: dict) -> list[str]:
    """Uncertainty tables, then notes (mode swaps) and warnings."""
    lines = []
    if s.get("uncertainty"):
        lines.append("")
        lines += format_uncertainty(s["uncertainty"])
    from laminid_cli.errors import escaped

    lines += [f"note: {msg}" for msg in s.get("swaps", [])]
    # escaped: identify's coarse-mesh warning names the file ('bd\u202e/S1.1.yaml')
    lines += [escaped(f"warning: {msg}") for msg in s.get("warnings", [])]
    return lines


def format_identify_report(s: dict) -> str:
    """Terminal report of an identification, in the shape of the paper's Tables 1-3.

    With an ``uncertainty`` block (laminid_cli.results.uncertainty_summary) each constant gets
    its 95 % interval and verdict, followed by the uncertainty, correlation, sensitivity and
    Monte Carlo tables.
    """
    lines = _plate_header(s["specimen"]) + [_run_line(s)] + format_status(s)
    lines += _material_tables(s, s.get("reference") or {})
    lines.append("")
    lines += _paired_frequency_table(s["frequencies"], _plate_sigma(s, s["specimen"]["name"]))
    lines.append(f"RMS residual {s['rms_residual_percent']:.3f} % "
                 f"(initial guess {s['initial_rms_residual_percent']:.2f} %), objective "
                 f"{s['objective']:.4g}")
    if s.get("mesh_check"):
        lines.append("")
        lines += format_mesh_check(s["mesh_check"])
    lines.append("")
    lines += format_global(s["global_properties"], s.get("global_uncertainty"))
    ref = s.get("reference") or {}
    gref = ref.get("global") or {}
    if gref:
        lines.append("    reference: " + ", ".join(
            f"{k} {_ref('nu12', v)}" if k.startswith("nu") else f"{k} {_ref('Ex', v)} GPa"
            for k, v in gref.items()))
    lines += _closing_lines(s)
    return "\n".join(lines)


def format_mesh_check(mc: dict) -> list[str]:
    """``--mesh-check`` (laminid_cli.meshcheck.MeshCheck.as_dict): per paired mode this mesh's
    and the finer mesh's frequency at the identified constants, the change in percent and in
    units of the mode's frequency sigma; per free constant its first-order shift on the finer
    mesh, in percent and in units of its 95 % half-width; then the verdict."""
    m, f = mc["mesh"], mc["fine_mesh"]
    this, fine = f"{m['nx']}x{m['ny']}", f"{f['nx']}x{f['ny']}"
    md = mc["modes"]
    lines = [f"mesh check: {this} against {fine} (both at the identified constants, modes "
             f"paired by MAC of w0, lowest {min(md['mac']):.4f}; {mc['time_s']:.1f} s)",
             f"{'mode':>4}  {this + ' Hz':>12}  {fine + ' Hz':>12}  {'change %':>8}  "
             f"{'change/sigma':>12}"]
    for i in range(len(md["measured_mode"])):
        lines.append(f"{int(md['measured_mode'][i]):>4}  {fmt(md['freq_hz'][i], '12.2f')}  "
                     f"{fmt(md['fine_hz'][i], '12.2f')}  {fmt(md['change_percent'][i], '+8.3f')}"
                     f"  {fmt(md['change_sigma'][i], '+12.2f')}")
    labels = mc["labels"]
    one = len({lab.rsplit(".", 1)[0] for lab in labels}) == 1
    names = [lab.rsplit(".", 1)[1] if one else lab for lab in labels]
    w = max([8] + [len(n) for n in names])
    lines.append(f"constants on {fine} (first order: the weighted least-squares step of the "
                 "frequency changes)")
    lines.append(f"  {'constant':<{w}}  {'shift %':>8}  {'/half-width':>11}")
    for lab, name in zip(labels, names):
        mat, const = lab.rsplit(".", 1)
        c = mc["constants"][mat][const]
        lines.append(f"  {name:<{w}}  {fmt(c['shift_percent'], '+8.3f', 'at bound')}  "
                     f"{fmt(c['shift_half_width'], '+11.3f')}")
    if mc["text"]:
        lines.append(f"warning: {mc['text']}")
    else:
        lines.append(f"the mesh is fine enough for these modes: no constant moves by more "
                     f"than {mc['limit']:g} of its 95 % half-width on {fine}")
    return lines


def format_joint_report(s: dict) -> str:
    """Terminal report of a joint identification: shared constants, then each plate."""
    names = s["specimen_names"]
    lines = [f"joint identification of {len(names)} plates: {', '.join(names)}", _run_line(s)]
    lines += format_status(s)
    lines += _material_tables(s, _joint_reference(s))
    for name, p in s["specimens"].items():
        lines.append("")
        lines += _plate_header({**p["specimen"], "name": name})
        lines += _paired_frequency_table(p["frequencies"], _plate_sigma(s, name))
        lines.append(f"RMS residual {p['rms_residual_percent']:.3f} % (initial guess "
                     f"{p['initial_rms_residual_percent']:.2f} %)")
        lines += format_global(p["global_properties"], p.get("global_uncertainty"))
    lines.append("")
    lines.append(f"RMS residual over all plates {s['rms_residual_percent']:.3f} % (initial guess "
                 f"{s['initial_rms_residual_percent']:.2f} %), objective {s['objective']:.4g}")
    lines += _closing_lines(s)
    return "\n".join(lines)


def _joint_reference(s: dict) -> dict:
    """The reference block of a joint summary's shared constants: each constant's reference
    where the plates agree, the range lowest–highest where they differ (with ``notes`` naming
    each plate's value), the plates' sources each once."""
    from laminid_cli.resultfile import combined_reference

    refs = {name: p.get("reference") or {} for name, p in s["specimens"].items()}
    mats, notes = combined_reference((n, r.get("materials") or {}) for n, r in refs.items())
    return {"source": "; ".join(dict.fromkeys(str(r["source"]) for r in refs.values()
                                              if r.get("source"))),
            "materials": {m: {k: lo if lo == hi else [lo, hi] for k, (lo, hi) in c.items()}
                          for m, c in mats.items()},
            "notes": notes}


def _material_tables(s: dict, ref: dict) -> list[str]:
    """Per material: initial, identified, reference, 95 % interval and verdict per constant."""
    lines = []
    ref_mats = ref.get("materials") or {}
    unc = (s.get("uncertainty") or {}).get("constants", {})
    for name, ident in s["materials"].items():
        init = s["initial"][name]
        free = set(s["free"].get(name, ()))
        param = s["parametrization"].get(name, "")
        lines.append("")
        lines.append(f"material {name} (variables: "
                     + ("paper Eq. 14, E1/E1_0 and alphas" if param == "alpha"
                        else "free constants / initial values") + ")")
        rm = ref_mats.get(name, {})
        # as wide as a range "120.00 .. 150.00" needs
        rw = max([10, *(len(_ref(k, v)) for k, v in rm.items())])
        mu = unc.get(name, {})
        # a run that did not converge stopped at a point that is not an optimum: its values
        # and intervals are that point's
        done = s.get("converged", True) is not False
        lines.append(f"  {'constant':<10} {'initial':>12} "
                     f"{'identified' if done else 'last point':>12}  "
                     f"{'reference' if rm else '':>{rw}}"
                     + (f"  {'95 % interval':>17} {'± of value':>10}  verdict" if mu else ""))
        if not done:
            lines.append("  (NOT CONVERGED: the values, intervals and verdicts are those of the "
                         "last point, not of an optimum)")
        assumed = set((s.get("uncertainty") or {}).get("fixed_undetermined") or ())
        for k in (*MODULI, "nu12"):
            # a value --fix-undetermined held is the initial guess, assumed, not a known one
            note = "" if k in free else "  (assumed: fixed because undetermined)" \
                if f"{name}.{k}" in assumed else "  (fixed)"
            row = (f"  {k + (' [GPa]' if k != 'nu12' else ''):<10} "
                   f"{_num(k, init[k]):>12} {_num(k, ident[k]):>12}  "
                   f"{_ref(k, rm.get(k)) if k in rm else '':>{rw}}")
            u = mu.get(k)
            if u is not None and u.get("at_bound"):
                # no interval (a limit of the search is no confidence bound: a Monte Carlo has
                # trials far from it); the statement names the side and the limit
                prof = u.get("profile") or {}
                span = "none: at limit"
                if prof.get("bound") is not None and math.isfinite(prof["bound"]):
                    below = prof["bound"] > (u.get("bound_limit") or 0)
                    span = f"{'<' if below else '>'} {_num(k, prof['bound'])} (profile)"
                elif prof.get("text") and not prof.get("error"):
                    span = f"none: flat to {_num(k, prof['far'])}"
                row += (f"  {span:>17} {'—':>10}  "
                        f"{u.get('bound_text') or u['verdict']} [!]")
                lines.append(row)
                if prof.get("text"):
                    lines.append(f"{'':14}profile: {prof['text']}")
            elif u is not None and "half_width" in u and u.get("verdict") != VERDICT_FIXED:
                flag = " [!]" if u.get("flagged") else ""
                span = f"{_num(k, u['lower'])} .. {_num(k, u['upper'])}"
                row += (f"  {span:>17} {_pct(u['rel_half_width']):>10}  "
                        f"{u['verdict'].split(' — ')[0]}{flag}")
                lines.append(row)
            else:
                lines.append(row + note)
    if ref.get("source") and (ref_mats or ref.get("global")):
        lines.append(f"  reference: {' '.join(str(ref['source']).split())}")
    lines += [f"  note: {n}" for n in ref.get("notes", ())]
    return lines


def _pct(rel) -> str:
    if rel is None or not math.isfinite(rel):
        return "inf"
    return width_text(rel)


def _short(labels) -> list[str]:
    """Drop the material prefix when there is only one material."""
    mats = {lab.rsplit(".", 1)[0] for lab in labels}
    return [lab.rsplit(".", 1)[1] if len(mats) == 1 else lab for lab in labels]


def format_uncertainty(u: dict) -> list[str]:
    """Uncertainty, identifiability, correlation, sensitivity and Monte Carlo sections."""
    conf = u["confidence"] * 100
    sc = u["scaling"]
    ap = u["a_posteriori"]
    th = u["thresholds"]
    lines = [f"uncertainty ({conf:.0f} % intervals, linearised at the optimum; verdict: "
             f"half-width < {th['well_determined'] * 100:.0f} % of the value well determined, "
             f"< {th['weak'] * 100:.0f} % weak)"]
    lines.append(f"  frequency standard deviations: {u['sigma_source']}")
    s2 = ap["s2"]
    if s2 is not None and math.isfinite(s2):
        from laminid_cli.intervals import small_chi2_note

        small = small_chi2_note(ap["chi2"], ap["dof"], "frequency sigma")
        fit = (small if small else "residuals consistent with it" if s2 <= 2 else
               "the model misses the data by more than that (model error or sigma too small)")
        lines.append(f"  a-posteriori variance factor s2 = chi2/(n-p) = {_sig3(s2)} (chi2 "
                     f"{_sig3(ap['chi2'])}, {ap['dof']} degrees of freedom): {fit}")
    used = ("stated frequency sigma (normal quantile)" if sc["used"] == "stated" else
            f"covariance scaled by s2 = {_sig3(sc['variance_factor'])} (Student t quantile)")
    lines.append(f"  intervals from: {used}; --covariance-scale {sc['requested']}")
    cond = u["condition_number"]
    weakest = " ".join(f"{number_text(c, '+.2f')} {lab}" for lab, c in
                       zip(_short([w[0] for w in u["weakest_combination"]]),
                           [w[1] for w in u["weakest_combination"]]))
    lines.append(f"  condition number {fmt(cond, '.3g', 'inf')} (whitened Jacobian, relative "
                 f"constants); least determined combination: {weakest}")
    if u.get("fixed_undetermined"):
        lines.append("  fixed at their initial values because undetermined (--fix-undetermined): "
                     + ", ".join(u["fixed_undetermined"]))
        widths = u.get("fixed_undetermined_widths") or {}
        for lab in u["fixed_undetermined"]:
            w = widths.get(lab) or (u.get("before_fixing") or {}).get(lab)
            if w is not None:
                run = f" in run {w['run']}" if w.get("run", 1) > 1 else ""
                if str(w.get("verdict", "")).startswith("at bound"):
                    fr = (u.get("fixed_ranges") or {}).get(lab)
                    lines.append(f"    {lab}: was at a limit of the search (not identified){run}"
                                 + (f"; {fr['text']}" if fr else ""))
                else:
                    lines.append(f"    {lab}: {conf:.0f} % half-width was "
                                 f"{_pct(w['rel_half_width'])} of its value{run}")
        counted = u.get("spread_counted") or []
        if counted:
            given = [(f"{m}.{k}", v.get("rel_half_width_given_fixed"))
                     for m, per in (u.get("constants") or {}).items() for k, v in per.items()]
            given = [(lab, w) for lab, w in given if w is not None and math.isfinite(w)]
            names = _short(list(counted) + [lab for lab, _ in given])
            lines.append("  " + spread_sentence(
                names[:len(counted)], [(n, w) for n, (_, w) in zip(names[len(counted):], given)],
                f"the {conf:.0f} % intervals"))
        eff = [(f"{m}.{k}", v["effective_dof"], v["quantile"])
               for m, per in (u.get("constants") or {}).items() for k, v in per.items()
               if v.get("quantile") is not None and v.get("rel_half_width") is not None]
        if counted and eff:
            nu_n = ap["dof"] if sc["used"] == "residuals" else None
            nu_s = u.get("spread_dof")

            def dof(n):
                return "∞" if n is None or not math.isfinite(n) else f"{n:.0f}"
            lines.append(
                f"  their quantiles combine the noise's {dof(nu_n)} degrees of freedom and the "
                f"spread's {dof(nu_s)} (Welch-Satterthwaite): " + ", ".join(
                    f"{name} t({dof(n)}) {q:.3g}" for name, (_, n, q) in
                    zip(_short([e[0] for e in eff]), eff)))
        fc = u.get("fixed_check")
        if fc and fc.get("text") and not fc.get("rejected"):
            lines.append("  " + fc["text"])          # a rejection is in the status
    for lab, why in (u.get("kept_free") or {}).items():
        lines.append(f"  --fix-undetermined: {lab} {why}")
    at_bound = {f"{m}.{k}" for m, per in (u.get("constants") or {}).items()
                for k, v in per.items() if v.get("at_bound")}
    wide = [lab for lab in u["flagged"] if lab not in at_bound]
    if wide:
        mc_too = " of the interval or the Monte Carlo range" if u.get(
            "verdict_from_monte_carlo") else ""
        advice = ("fix them (--fix-undetermined) or measure a thicker plate / more modes")
        if u.get("fixed_undetermined"):
            # this run fixed what it could (its flags are judged given the fixed values): a
            # constant flagged now is so by the fixed values' spread, or was kept free
            given = {f"{m}.{k}": v.get("rel_half_width_given_fixed")
                     for m, per in (u.get("constants") or {}).items() for k, v in per.items()}
            by_spread = [f"{lab} within ±{_pct(given[lab])} given the fixed values alone"
                         for lab in wide if given.get(lab) is not None
                         and given[lab] <= th["max_rel_interval"]]
            advice = (("; ".join(by_spread) + ": their spread before fixing makes it so; "
                       if by_spread else "")
                      + "put values you know in the specimen file and --fix them, or measure "
                        "a thicker plate / more modes")
        limit = th["max_rel_interval"]
        lines.append(f"  flagged (half-width{mc_too} > {limit * 100:.0f} % of "
                     "the value):"
                     f" {', '.join(wide)} — {flag_words(limit)}; {advice}")
    bound = [lab for lab in u["flagged"] if lab in at_bound]
    if bound:
        lines.append(f"  flagged (at a limit of the search, no interval): {', '.join(bound)} — "
                     "not identified")
    for note in u.get("notes", []):
        lines.append(f"  note: {note}")
    labels = u["labels"]
    if len(labels) > 1:
        short = _short(labels)
        width = max(6, max(len(x) for x in short) + 1)
        lines.append("")
        lines.append("correlation of the identified constants")
        lines.append(" " * (width + 2) + "".join(f"{x:>{width}}" for x in short))
        for i, x in enumerate(short):
            lines.append(f"  {x:<{width}}" + "".join(
                f"{fmt(u['correlation'][i][j], f'{width}.2f', '-'):>{width}}"
                for j in range(len(short))))
    for plate, tab in (u.get("sensitivity") or {}).items():
        short = _short(tab["labels"])
        lines.append("")
        head = "normalised sensitivities d ln f / d ln P"
        lines.append(head + (f" — {plate}" if len(u["sensitivity"]) > 1 else "")
                     + " (which mode determines which constant)")
        width = max(7, max(len(x) for x in short) + 1)
        lines.append(f"  {'mode':>4}" + "".join(f"{x:>{width}}" for x in short))
        for i, row in enumerate(tab["dlnf_dlnP"]):
            skip = "" if tab["weight"][i] > 0 else "  (weight 0)"
            lines.append(f"  {i + 1:>4}" + "".join(f"{fmt(v, f'{width}.3f'):>{width}}"
                                                  for v in row) + skip)
        lines.append("  most sensitive mode: " + ", ".join(
            f"{x} {tab['dominant_mode'][lab]}" for x, lab in zip(short, tab["labels"])))
    mc = u.get("monte_carlo")
    if mc:
        lines.append("")
        procs = f"{mc['jobs']} process" + ("es" if mc["jobs"] != 1 else "")
        prior = (f"; the priors' values by {100 * mc['prior_sigma']:.2g} % over the square "
                 "root of their weight (as the intervals count them)"
                 if mc.get("prior_sigma") else "")
        drawn = mc.get("fixed_drawn") or []
        if drawn:
            prior += ("; the fixed " + ", ".join(_short(drawn)) + " drawn from "
                      + ("their" if len(drawn) > 1 else "its") + " spread before fixing")
        nu = mc.get("variance_dof") or 0
        drawn_var = (f", each trial's variance factor drawn as s2 x {nu} / chi-square({nu}): "
                     "Student t, as the intervals" if nu else "")
        lines.append(f"Monte Carlo check: {mc['converged']} of {mc['trials']} re-identifications "
                     f"converged (frequencies perturbed by sigma x {mc['sigma_factor']:.3g}"
                     f"{drawn_var}{prior}, {procs}, {mc['time_s']:.1f} s)")
        lines.append(f"  {'constant':<18} {'linearised std':>15} {'Monte Carlo std':>16} "
                     f"{'ratio':>6}  {'Monte Carlo ' + format(conf, '.0f') + ' % range':>26}")
        limits, marked = [], False
        for mat, consts in mc["constants"].items():
            for k, v in consts.items():
                lab = k if len(mc["constants"]) == 1 else f"{mat}.{k}"
                lo = _val(k, v['lower'], 4) + ("*" if v.get("lower_at_bound") else "")
                hi = _val(k, v['upper'], 4) + ("*" if v.get("upper_at_bound") else "")
                marked |= bool(v.get("lower_at_bound") or v.get("upper_at_bound"))
                # (the range's upper end is the line's last cell: not padded)
                lines.append(f"  {lab:<18} {_val(k, v['linearized_std']):>15} "
                             f"{_val(k, v['std']):>16} {fmt(v['ratio'], '6.2f'):>6}  "
                             f"{lo:>12} .. {hi}")
                at = [f"{v[f'trials_at_{side}_bound']} at its {side} limit"
                      for side in ("lower", "upper") if v.get(f"trials_at_{side}_bound")]
                if at:
                    limits.append(f"{lab} ({', '.join(at)})")
        if nu:
            lines.append(f"  ratio: Monte Carlo std over the linearised std times "
                         f"{fmt(t_std(nu), '.3g')}, "
                         f"the std of Student t with {nu} degrees of freedom (1 for a linear "
                         "model" + ("" if nu > 2 else "; none below 3 degrees of freedom")
                         + ")")
        given = mc.get("given_fixed")
        if drawn and given:
            # the trials drew the fixed values: the table counts their spread, as the
            # intervals do; the trials that held them (for the flags) give the narrower width
            widths = [f"{k if len(given['constants']) == 1 else f'{m}.{k}'} "
                      f"±{_pct(g['rel_half_width'])}"
                      for m, per in given["constants"].items() for k, g in per.items()]
            lines.append("  linearised std and ratio: counting the fixed values' spread, as the "
                         "intervals above; the trials holding the fixed values instead "
                         f"(what --fix-undetermined judges its flags on, {given['time_s']:.1f} "
                         "s): " + ", ".join(widths))
        elif u.get("spread_counted") and not drawn:
            # a file written before the trials drew the fixed values: they held them
            lines.append("  linearised std and ratio: given the fixed values (the trials hold "
                         "them); the intervals above count their spread")
        if limits:
            lines.append(f"  trials that ended on a limit of the search, of {mc['converged']}: "
                         + "; ".join(limits))
            if marked:
                lines.append("  * that end of the range is set by such trials: it is the "
                             "search's limit, not the data's (the constant is not determined "
                             "there)")
        from_mc = u.get("verdict_from_monte_carlo") or []
        sure = 100 * (2 * mc.get("evidence_level", 0.95) - 1)
        inner = [v.get("inner_lower") for c in mc["constants"].values() for v in c.values()]
        if inner and all(x is None or not math.isfinite(x) for x in inner) \
                and "evidence_level" in mc:
            lines.append(f"  {mc['converged']} converged trial(s) do not bound the range's width "
                         f"with {sure:.0f} % confidence: the verdicts stay the linearised ones; "
                         "run 40 or more trials for the Monte Carlo to set them")
        if from_mc:
            lines.append(f"  verdicts set by the Monte Carlo range (the width its trials show "
                         f"with {sure:.0f} % confidence), wider than the linearised "
                         "interval (the frequencies are not linear in the constant over it): "
                         + ", ".join(_short(from_mc) if len(mc["constants"]) == 1
                                     else from_mc))
    return lines


def _val(name: str, value, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "-"
    return significant_text(name, value, digits) + ("" if name == "nu12" else " GPa")


def _ref(name: str, value) -> str:
    """A reference value as _num writes it, or a range [low, high] as "low .. high" (the
    interval columns' form): the range the specimen gives, not its midpoint."""
    if isinstance(value, (list, tuple)):
        low, high = value
        return f"{_num(name, low)} .. {_num(name, high)}"
    return _num(name, value)


def _num(name: str, value) -> str:
    if value is None:
        return "-"
    if value == math.inf:
        return "inf"
    if not math.isfinite(value):
        return "-"
    return constant_text(name, value)    # (its digits: laminid_cli.units; the report's too)


def format_damping(d: dict) -> list[str]:
    """Ply loss factors with intervals and verdicts, and measured vs model modal loss factors
    (the JSON block "damping")."""
    conf = d["confidence"] * 100
    lines = [f"ply loss factors ({d['method']}, {conf:.0f} % intervals; eta = 2 zeta)"]
    mats = d["loss_factors"]
    many = len(mats) > 1
    lines.append(f"  {'loss factor':<{24 if many else 12}} {'value %':>9} "
                 f"{f'{conf:.0f} % interval %':>20}  verdict")
    for mat, per in mats.items():
        for name, v in per.items():
            lab = f"{mat}.{name}" if many else name
            if v["verdict"] == "fixed":
                cell = ""
            elif v.get("at_bound"):
                # held at 0 by eta >= 0: no interval, as a constant on a search limit (a file
                # written before kept 0 .. a one-sided upper: not shown either)
                cell = "none: held at 0"
            else:
                # the ends in the value's digits, as the constants' (_num): "0.178 .. 0.22"
                # beside a value of 0.199 read as a narrower doubt at the top
                cell = f"{fmt(100 * v['lower'], '.3f')} .. {fmt(100 * v['upper'], '.3f')}"
            lines.append(f"  {lab:<{24 if many else 12}} {fmt(100 * v['value'], '9.3f')} "
                         f"{cell:>20}  {v['verdict']}")
    s2 = d["s2"]
    used = ("stated damping sigma (normal quantile)" if d["scaling"]["used"] == "stated" else
            "scaled by s2 (Student t quantile)")
    lines.append(f"  damping standard deviations: {d['sigma_source'] or '-'}; intervals from: "
                 f"{used}; s2 = {_sig3(s2)} ({d['dof']} degrees of freedom)")
    for note in d.get("notes", []):
        lines.append(f"  note: {note}")
    lines += format_damping_monte_carlo(d)
    lines.append("")
    labels = d["energy_share_labels"]
    short = [lab.rsplit(".", 1)[1] if not many else lab for lab in labels]
    width = max(7, max(len(x) for x in short) + 1)
    lines.append("modal loss factors (%) and strain-energy shares (%) of each mode")
    lines.append(f"  {'mode':>4} {'measured':>9} {'+/-':>7} {'model':>7}"
                 + "".join(f"{'U' + x:>{width}}" for x in short))
    for i, meas in enumerate(d["measured_loss_factor"]):
        m = "-" if meas is None or not math.isfinite(meas) else f"{100 * meas:.3f}"
        sig = d["measured_sigma"][i]
        sig = "-" if sig is None or not math.isfinite(sig) else f"{100 * sig:.3f}"
        skip = "" if d["used"][i] or m == "-" else "  (not fitted: weight 0)"
        lines.append(f"  {i + 1:>4} {m:>9} {sig:>7} {fmt(100 * d['model_loss_factor'][i], '7.3f')}"
                     + "".join(f"{100 * x:>{width}.1f}" for x in d["energy_shares"][i]) + skip)
    return lines


def format_damping_monte_carlo(d: dict) -> list[str]:
    """The loss factors' Monte Carlo (the JSON block "damping" / "monte_carlo": each trial
    refitted them at its own constants, laminid_cli.damping.monte_carlo_loss_factors) beside
    their intervals; [] without one."""
    mc = d.get("monte_carlo")
    if not mc:
        return []
    conf = d["confidence"] * 100
    many = len(mc["loss_factors"]) > 1
    w = 24 if many else 12
    lines = ["", f"  Monte Carlo: {mc['refits']} of {mc['trials']} trials refitted the loss "
             "factors at their own constants (measured damping perturbed by sigma x "
             f"{mc['sigma_factor']:.3g}, {mc['time_s']:.2f} s)",
             f"  {'loss factor':<{w}} {'interval std %':>14} {'Monte Carlo std %':>17} "
             f"{'ratio':>6}  {'Monte Carlo ' + format(conf, '.0f') + ' % range %':>26}"]
    zero = []
    for mat, per in mc["loss_factors"].items():
        for name, v in per.items():
            lab = f"{mat}.{name}" if many else name
            lo = fmt(100 * v["lower"], ".3f") + ("*" if v.get("lower_at_zero") else "")
            hi = fmt(100 * v["upper"], ".3f")             # (the value's digits, as above)
            lines.append(f"  {lab:<{w}} {fmt(100 * v['linearized_std'], '14.3g'):>14} "
                         f"{fmt(100 * v['std'], '17.3g'):>17} {fmt(v['ratio'], '6.2f'):>6}  "
                         f"{lo:>12} .. {hi}")
            if v.get("trials_at_zero"):
                zero.append(f"{lab} {v['trials_at_zero']}")
    if zero:
        lines.append(f"  trials that held the loss factor at 0, of {mc['refits']}: "
                     + ", ".join(zero) + ("; * that end of the range is the bound eta >= 0, "
                                          "not the data's" if any(
                                              v.get("lower_at_zero") for per in
                                              mc["loss_factors"].values()
                                              for v in per.values()) else ""))
    sure = 100 * (2 * mc.get("evidence_level", 0.95) - 1)
    inner = [v.get("inner_lower") for per in mc["loss_factors"].values() for v in per.values()]
    if inner and all(x is None or not math.isfinite(x) for x in inner):
        lines.append(f"  {mc['refits']} refit(s) do not bound the range's width with "
                     f"{sure:.0f} % confidence: the verdicts stay the intervals'")
    return lines
