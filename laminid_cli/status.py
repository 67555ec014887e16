"""Status of an identification result: ``ok`` or ``check``, with the reasons in codes and words.

:func:`result_status` is a pure function of the identification (single or joint) and its
uncertainty assessment. A result is ``ok`` when no reason applies, ``check`` otherwise; the
reasons (stable lowercase codes, one entry per code, the words name the constants):

``not_converged``
    the optimiser stopped without converging (``laminid identify`` exits 1 for this one).
``at_bound``
    a free constant ended on a limit of the search (laminid_cli.uncertainty.bounds_reached),
    or the optimum sits on a feasibility constraint: that constant is not identified. A free
    ply loss factor held at 0 (the measured damping asks for less than none) counts too.
``undetermined``
    a free constant's 95 % half-width exceeds ``--max-rel-interval`` of its value (flagged by
    the uncertainty assessment): the modes do not determine it. With a Monte Carlo, the half-
    width its 95 % range has for sure (90 % confidence from the trials' order statistics)
    counts too (:func:`laminid_cli.uncertainty.with_monte_carlo`). So does a free ply loss
    factor whose 95 % half-width exceeds the same fraction of its value.
``fixed_rejected``
    the modes reject the values ``--fix-undetermined`` fixed, taken together (each was
    undetermined on its own): fixing them raised chi2 beyond the test of nested fits
    (:class:`laminid_cli.uncertainty.FixedCheck`). The constants left free are identified
    under an assumption the data contradict; the words name the value whose release lowers
    chi2 most.
``poor_fit``
    chi2 of the residuals is above its 99 % quantile for the degrees of freedom (s2 beyond
    its 99 % limit): the model misses the data by more than the stated frequency noise —
    plates that disagree (joint), model error, or frequency sigmas that are too small. The
    same test on the loss factors' fit to the measured modal damping counts too.
``implausible``
    a combination a mechanics reader would reject, judged on the identified values of free
    constants that are not at a bound:

    - **G23 > E2.** A transversely isotropic ply has G23 = E2 / (2 (1 + nu23)); with
      nu23 >= 0 (every fibre composite) G23 <= E2 / 2, and G23 > E2 needs nu23 < -1/2.
    - **G13 > 2 G12 or G23 > 2 G12.** Transverse isotropy gives G13 = G12, and
      G23 = E2 / (2 (1 + nu23)) stays below G12 for carbon and glass plies; for an
      equivalent single layer the transverse shear moduli are thickness averages of the plies'
      G13, G23, themselves <= the ply G12 <= the laminate's in-plane Gxy. A factor 2 leaves
      room for real scatter.
    - **nu12 < 0.** A fibre/matrix ply has nu12 = Vf nu_f + (1 - Vf) nu_m > 0 (rule of
      mixtures; fibres and matrices have positive Poisson ratios). A laminate of such plies
      cannot produce a negative in-plane nu_xy either: A12 = sum t_k Q12(theta_k) with
      Q12(theta) = Q12 (c^4 + s^4) + (Q11 + Q22 - 4 Q66) s^2 c^2 > 0 whenever Q12 > 0 and
      Q11 + Q22 > 4 Q66 (fibre plies), so nu_xy = A12 / A22 > 0.
``coarse_mesh``
    ``identify --mesh-check`` only: on a mesh twice as fine, some constant would move by more
    than 0.3 of its 95 % half-width (laminid_cli.meshcheck): the discretisation error biases
    the constants beyond what the frequency noise allows; the words name the constants and the
    finer mesh.
``modes_swapped``
    the final pairing of measured and model modes is not in sorted order (MAC tracking
    re-ordered them): check the mode identification against the mode shapes.

No click, no h5py: library code. Texts use GPa for moduli; the numbers in files are SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

OK = "ok"
CHECK = "check"
#: reason codes, in the order they are listed
CODES = ("not_converged", "at_bound", "undetermined", "fixed_rejected", "poor_fit",
         "coarse_mesh", "implausible", "modes_swapped")
#: a transverse shear modulus above this multiple of G12 is implausible (module docstring)
SHEAR_RATIO_LIMIT = 2.0


@dataclass(frozen=True)
class Reason:
    code: str
    text: str


@dataclass(frozen=True)
class ResultStatus:
    """``status`` "ok" | "check" and the reasons (empty when ok), in :data:`CODES` order."""

    status: str
    reasons: tuple[Reason, ...] = ()

    @property
    def codes(self) -> tuple[str, ...]:
        return tuple(r.code for r in self.reasons)

    @property
    def texts(self) -> tuple[str, ...]:
        return tuple(r.text for r in self.reasons)

    def as_dict(self) -> dict:
        """JSON keys ``status`` and ``reasons`` (results.py, schema version 2)."""
        return {"status": self.status,
                "reasons": [{"code": r.code, "text": r.text} for r in self.reasons]}

    def line(self) -> str:
        """One line for tables: "ok" or "check: at_bound, poor_fit"."""
        return self.status if not self.reasons else f"{self.status}: {', '.join(self.codes)}"


def _gpa(v: float) -> str:
    return f"{v / 1e9:.3g} GPa"


def _plates(result) -> list:
    return list(getattr(result, "specimens", ())) or [result]


def implausible_combinations(result, uncertainty=None) -> list[str]:
    """The implausible combinations of the module docstring, as sentences (empty: none).

    Only constants that are free (in at least one of the pair) and not at a bound count."""
    at_bound = set()
    if uncertainty is not None and uncertainty.at_bound is not None:
        at_bound = {lab for lab, b in zip(uncertainty.labels, uncertainty.at_bound) if b}
    out = []
    for name, c in zip(result.material_names, result.constants):
        free = set(result.free.get(name, ()))
        prefix = f"{name}: " if len(result.material_names) > 1 else ""

        def usable(*keys):
            return any(k in free for k in keys) and not any(f"{name}.{k}" in at_bound
                                                            for k in keys)

        if usable("G23", "E2") and c.G23 > c.E2:
            out.append(f"{prefix}G23 = {_gpa(c.G23)} is above E2 = {_gpa(c.E2)} (a transversely "
                       "isotropic ply has G23 = E2/(2(1+nu23)) <= E2/2)")
        why = {"G13": "G13 = G12 for a transversely isotropic ply",
               "G23": "G23 = E2/(2(1+nu23)) stays below G12 for carbon and glass plies"}
        for k in ("G13", "G23"):
            v = getattr(c, k)
            if usable(k, "G12") and v > SHEAR_RATIO_LIMIT * c.G12:
                out.append(f"{prefix}{k} = {_gpa(v)} is more than {SHEAR_RATIO_LIMIT:g} x G12 = "
                           f"{_gpa(c.G12)} ({why[k]})")
        if usable("nu12") and c.nu12 < 0:
            out.append(f"{prefix}nu12 = {c.nu12:.3f} is negative (fibre plies, and laminates "
                       "of them, have a positive in-plane Poisson ratio)")
    return out


def swapped_modes(result) -> list[str]:
    """Per plate, the measured modes paired out of sorted order (empty: none)."""
    out = []
    plates = _plates(result)
    for p in plates:
        pairing = np.asarray(p.pairing)
        used = np.asarray(p.weight) > 0
        bad = [i for i in range(pairing.size) if used[i] and pairing[i] != i]
        if bad:
            pairs = ", ".join(f"{i + 1}->{int(pairing[i]) + 1}" for i in bad)
            who = f"{p.specimen.name}: " if len(plates) > 1 else ""
            out.append(f"{who}measured -> model mode {pairs}")
    return out


def result_status(result, uncertainty=None, damping=None, mesh_check=None) -> ResultStatus:
    """Status and reasons of an Identification or JointIdentification (module docstring).

    ``uncertainty``: its :class:`laminid_cli.uncertainty.Uncertainty` (None: the reasons that
    need it — at_bound per constant, undetermined, poor_fit — are judged without it: only the
    optimiser's bound hits count). ``damping``: the ply loss factors'
    :class:`laminid_cli.damping.DampingFit`, when the specimen has measured damping.
    ``mesh_check``: the :class:`laminid_cli.meshcheck.MeshCheck` of ``identify --mesh-check``.
    """
    found: dict[str, list[str]] = {}

    def add(code, text):
        found.setdefault(code, []).append(text)

    if not result.converged:
        add("not_converged", f"the optimiser did not converge ({result.status})")
    u = uncertainty
    covered = set()
    if u is not None and u.at_bound is not None:
        for lab, hit, text in zip(u.labels, u.at_bound, u.bound_text):
            if hit:
                prof = getattr(u, "profiles", {}).get(lab)
                add("at_bound", f"{lab}: {text}" + (f"; {prof.text}" if prof is not None
                                                    and not prof.error else ""))
                covered.add(lab.rsplit(".", 1)[1])
    hits = []
    for p in _plates(result):
        for h in p.bounds_hit:
            if h not in hits:
                hits.append(h)
    if hits and not covered:
        # the optimiser's own bound hits (on design variables) when no constant explains them
        add("at_bound", "the optimum is on a limit of the search: " + "; ".join(hits))
    if u is not None:
        bound = set(lab for lab, b in zip(u.labels, u.at_bound) if b) \
            if u.at_bound is not None else set()
        und = [lab for lab in u.flagged if lab not in bound]
        if und:
            rel = dict(zip(u.labels, u.rel_half_width))
            mc = dict(zip(u.labels, u.mc_rel_half_width)) if u.mc_rel_half_width is not None \
                else {}
            sure = (dict(zip(u.labels, u.mc_rel_half_width_lower))
                    if u.mc_rel_half_width_lower is not None else {})
            limit = u.thresholds["max_rel_interval"]
            words = ", ".join(
                f"{lab} ({_width(rel[lab], mc.get(lab), sure.get(lab), limit, 'linearised')})"
                for lab in und)
            from laminid_cli.intervals import flag_words

            add("undetermined", f"{flag_words(limit)} ({u.confidence * 100:.0f} % "
                                f"half-width above {u.thresholds['max_rel_interval'] * 100:.0f} %"
                                f" of the value): {words}")
        for fr in getattr(u, "fixed_ranges", {}).values():
            if fr.moves or fr.error:
                # moved beyond a half-width, or could not be checked: the intervals are given
                # a value that is not known
                add("undetermined", f"{fr.label}: {fr.text}" + (
                    f" ({fr.label.rsplit('.', 1)[1]} was fixed on a limit of the search: the "
                    "intervals are given its value, which is not known)" if fr.error else ""))
        fc = getattr(u, "fixed_check", None)
        if fc is not None and fc.rejected:
            add("fixed_rejected", fc.text)
        if u.dof > 0 and np.isfinite(u.chi2_limit) and u.chi2 > u.chi2_limit:
            joint = len(_plates(result)) > 1
            add("poor_fit", f"the fit misses the data by more than the stated frequency noise: "
                            f"s2 = {u.s2:.3g} (chi2 {u.chi2:.3g} for {u.dof} degrees of freedom, "
                            f"99 % limit {u.chi2_limit:.3g}): "
                            + ("plates that disagree, " if joint else "")
                            + "model error (a mesh too coarse, a wrong layup, thickness or mass, "
                            "a mode paired with the wrong one), a local minimum of the fit "
                            "(identify again from other initial values), or frequency sigmas "
                            "too small")
    if damping is not None:
        limit = (u.thresholds["max_rel_interval"] if u is not None else None)
        for code, text in damping_reasons(damping, limit):
            add(code, text)
    if mesh_check is not None and mesh_check.too_coarse:
        add("coarse_mesh", mesh_check.text)
    for text in implausible_combinations(result, u):
        add("implausible", text)
    sw = swapped_modes(result)
    if sw:
        add("modes_swapped", "modes paired out of sorted order (check the mode shapes): "
                             + "; ".join(sw))
    reasons = tuple(Reason(code, "; ".join(found[code])) for code in CODES if code in found)
    return ResultStatus(CHECK if reasons else OK, reasons)


def damping_reasons(damping, max_rel_interval: float | None = None) -> list[tuple[str, str]]:
    """(code, text) of the ply loss factors' fit (module docstring): free loss factors held at
    0 (``at_bound``), with a 95 % half-width above ``max_rel_interval`` of their value
    (default :data:`laminid_cli.intervals.WEAK`; ``undetermined``; or whose Monte Carlo range
    shows that much for sure), and a fit whose chi2 is
    above its 99 % quantile (``poor_fit``)."""
    from laminid_cli.intervals import WEAK
    from laminid_cli.quantiles import chi2_ppf

    limit = WEAK if max_rel_interval is None else max_rel_interval
    conf = f"{damping.confidence * 100:.0f} %"
    out = []
    at = [lab for lab, b in zip(damping.labels, damping.at_bound) if b]
    if at:
        out.append(("at_bound", "loss factors held at their lower limit 0 (the measured damping "
                                "asks for less than none in these terms): " + ", ".join(at)))
    sure = getattr(damping, "mc_rel_half_width_lower", None)
    sure = np.full(len(damping.labels), np.nan) if sure is None else np.asarray(sure, float)
    mc = getattr(damping, "mc_rel_half_width", None)

    # flagged by the Monte Carlo range too (each trial refitted the loss factors at its own
    # constants)
    und = [(lab, _width(rel, None if mc is None else mc[k], sure[k], limit, "interval"))
           for k, (lab, rel, b) in enumerate(zip(
               damping.labels, damping.rel_half_width, damping.at_bound))
           if not b and (not rel <= limit or sure[k] > limit)]
    if und:
        words = ", ".join(f"{lab} ({w})" for lab, w in und)
        out.append(("undetermined", f"loss factors not determined by the measured damping "
                                    f"({conf} half-width above {limit * 100:.0f} % of the "
                                    f"value): {words}"))
    limit99 = chi2_ppf(0.99, damping.dof) if damping.dof > 0 else np.inf
    if damping.chi2 > limit99:
        out.append(("poor_fit", f"the loss factors' model misses the measured modal damping by "
                                f"more than its stated noise: chi2 {damping.chi2:.3g} for "
                                f"{damping.dof} degrees of freedom (99 % limit "
                                f"{limit99:.3g}): damping that is not the "
                                "ply materials' (air, supports), or damping sigmas too small"))
    return out


def _width(rel, mc, sure, limit, interval: str) -> str:
    """How wide a flagged constant (or loss factor) is: "±34 %", or, where the Monte Carlo's
    width for sure flagged it and the ``interval`` (its word: "linearised", "interval") did
    not (narrower, or none), "Monte Carlo ±59 %, at least ±52 %; linearised ±22 %"."""
    if not rel > limit and sure is not None and sure > limit:
        return f"Monte Carlo ±{_pct(mc)}, at least ±{_pct(sure)}; {interval} ±{_pct(rel)}"
    return f"±{_pct(rel)}"


def _pct(rel) -> str:
    if rel is None or not np.isfinite(rel):
        return "inf"
    return f"{rel * 100:.0f} %" if rel < 10 else f"{rel:.0f}x"
