"""Quantities written with units in specimen files: ``"210.5 mm"``, ``"117.2 GPa"``, ``"45 deg"``.

Everything inside laminid is SI (m, Pa, kg, kg/m^3, Hz); units are converted here, at the edge.
A bare number is taken in the base unit of its kind:

============  ==========  ======================================================
kind          base unit   accepted units
============  ==========  ======================================================
length        m           m, cm, mm, um (µm), in
modulus       Pa          Pa, kPa, MPa, GPa, N/mm^2 (= MPa), kN/mm^2 (= GPa), MN/m^2
                          (= MPa), psi, ksi, Msi (1 Msi = 6.894757 GPa); also N/m^2,
                          kN/m^2, GN/m^2, and "2" or "²" for "^2"   (alias: pressure, stress)
mass          kg          kg, g, lb
density       kg/m^3      kg/m^3 (kg/m3, kg/m³), g/cm^3 (g/cm3, g/cm³)
frequency     Hz          Hz, kHz
angle         deg         deg (°), rad
dimensionless 1           none
============  ==========  ======================================================

Angles are the one exception to "bare numbers are SI": ply angles are written in degrees in
laminid files and stacking codes (as in the paper), so a bare angle is in degrees and
:func:`parse_quantity` returns degrees for ``kind="angle"``.

Unit names are matched exactly first, then ignoring case when that is unambiguous within the
kind (``"gpa"`` is GPa, ``"kpa"`` is kPa); ``mPa`` (millipascal) and ``MPa`` differ only in case,
so ``"mpa"`` is refused as ambiguous, and ``mPa`` is read as what it says (and then refused by the
plausibility check of a modulus). The text is first normalised to Unicode NFKC, so full-width
and compatibility characters read as what they look like (``"２１０ ｍｍ"`` is 210 mm, ``"㎐"`` is
Hz), and a minus sign or dash (U+2212, U+2013) as ``-``; a number must be written with ASCII
digits after that.

Plausible ranges (:data:`PLAUSIBLE`): a positive length, modulus, mass, density or frequency
outside its range is refused with the value shown in a sensible unit, since it is far more
likely a wrong unit than a real plate (a modulus in mPa, a thickness in m written as mm).
"""

from __future__ import annotations

import math
import re
import unicodedata
from dataclasses import dataclass

from laminid_cli.errors import SpecimenError

_PSI = 6894.757293168361  # Pa, exact from the international pound and inch
# (1 lbf = 0.45359237 kg x 9.80665 m/s^2, 1 in = 0.0254 m: NIST SP 811, Appendix B.8;
# 1 Msi = 6.894757 GPa, the unit US labs quote moduli in)
#: stress units written as force per area (SI, exact: 1 N/mm^2 = 1 MPa, 1 kN/mm^2 = 1 GPa,
#: 1 MN/m^2 = 1 MPa, 1 GN/m^2 = 1 GPa, 1 N/m^2 = 1 Pa; BIPM SI Brochure, 9th ed., Table 4),
#: each also with "2" for "^2" (NFKC makes "²" a "2": "N/mm²" reads as "N/mm2")
_FORCE_PER_AREA = {f"{force}/{area}{power}": factor
                   for force, area, factor in (("N", "mm", 1e6), ("kN", "mm", 1e9),
                                               ("N", "m", 1.0), ("kN", "m", 1e3),
                                               ("MN", "m", 1e6), ("GN", "m", 1e9))
                   for power in ("^2", "2")}

#: unit -> factor to the base unit, per kind; the first unit of each kind is the base unit
UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6,
               "in": 0.0254},
    "modulus": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9, **_FORCE_PER_AREA,
                "psi": _PSI, "ksi": 1e3 * _PSI, "Msi": 1e6 * _PSI, "mPa": 1e-3,
                # millinewton spellings, so that "mn/m^2" is ambiguous (as "mpa") rather than
                # read as MN/m^2; refused afterwards as implausible, as mPa
                "mN/m^2": 1e-3, "mN/m2": 1e-3},
    "mass": {"kg": 1.0, "g": 1e-3, "lb": 0.45359237},
    "density": {"kg/m^3": 1.0, "kg/m3": 1.0, "kg/m³": 1.0, "g/cm^3": 1e3, "g/cm3": 1e3,
                "g/cm³": 1e3},
    "frequency": {"Hz": 1.0, "kHz": 1e3, "mHz": 1e-3, "MHz": 1e6},
    "angle": {"deg": 1.0, "°": 1.0, "rad": 180.0 / math.pi},
    "dimensionless": {},
}
_ALIASES = {"pressure": "modulus", "stress": "modulus", "ratio": "dimensionless"}
#: unit used to show a quantity of each kind to a user
DISPLAY_UNITS = {"length": "mm", "modulus": "GPa", "mass": "kg", "density": "kg/m^3",
                 "frequency": "Hz", "angle": "deg", "dimensionless": ""}
# units that are spellings of another one, left out of "accepted units" lists
_SPELLINGS = {"µm", "μm", "kg/m3", "kg/m³", "g/cm3", "g/cm³", "°", "mPa", "mHz", "MHz",
              "mN/m^2", "mN/m2", "N/m^2", "N/m2", "kN/m^2", "kN/m2", "GN/m^2", "GN/m2",
              *(u for u in _FORCE_PER_AREA if u.endswith("/mm2") or u.endswith("/m2"))}

#: (low, high) in the base unit: a positive value of these kinds outside the range is refused
#: (plates of polymers to diamond, 10 um to 100 m, 1 mg to 10 t, aerogel to osmium, 1 uHz (a sigma) to 10 MHz)
PLAUSIBLE = {"length": (1e-5, 100.0), "modulus": (1e5, 2e12), "mass": (1e-6, 1e4),
             "density": (1.0, 25000.0), "frequency": (1e-6, 1e7)}

_NUMBER = re.compile(r"\s*([+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?)\s*(.*?)\s*\Z",
                     re.S)


#: the minus sign (U+2212) and the dashes a word processor or a PDF puts for a minus, which
#: NFKC leaves as they are
_MINUS = str.maketrans({"\u2212": "-", "\u2012": "-", "\u2013": "-", "\ufe63": "-"})


def normalize_text(text: str) -> str:
    """``text`` as read: Unicode NFKC (full-width digits, ``㎐``), minus signs as ``-``.

    >>> normalize_text("\u221245 deg")
    '-45 deg'
    """
    return unicodedata.normalize("NFKC", text).translate(_MINUS)


@dataclass(frozen=True)
class Where:
    """Where a value was read: file, dotted field name and 1-based line (for error messages)."""

    path: str | None = None
    field: str | None = None
    line: int | None = None

    def error(self, message: str) -> SpecimenError:
        return SpecimenError(message, path=self.path, field=self.field, line=self.line)


def canonical_kind(kind: str) -> str:
    """``kind`` with aliases resolved (``pressure`` -> ``modulus``); ValueError if unknown."""
    kind = _ALIASES.get(kind, kind)
    if kind not in UNITS:
        raise ValueError(f"unknown quantity kind {kind!r}; expected one of "
                         f"{', '.join(list(UNITS) + list(_ALIASES))}")
    return kind


def accepted_units(kind: str) -> str:
    """Human-readable list of the units accepted for ``kind``."""
    kind = canonical_kind(kind)
    names = [u for u in UNITS[kind] if u not in _SPELLINGS]
    if not names:
        return "a plain number (no unit)"
    base = names[0]
    return ", ".join(names) + f" (a bare number is {base})"


def _lookup_unit(unit: str, kind: str) -> float | None:
    table = UNITS[kind]
    if unit in table:
        return table[unit]
    folded = [u for u in table if u.lower() == unit.lower()]
    if len({table[u] for u in folded}) == 1:
        return table[folded[0]]
    return None


def _kind_of_unit(unit: str) -> str | None:
    for kind in UNITS:
        if _lookup_unit(unit, kind) is not None:
            return kind
    return None


def parse_quantity(value, kind: str, *, where: Where | None = None,
                   expected: str | None = None) -> float:
    """Convert a number or a ``"<number> <unit>"`` string to the base unit of ``kind``.

    Parameters
    ----------
    value : int, float or str
        ``3.06e-3``, ``"3.06 mm"``, ``"3.06mm"``, ``"117.2 GPa"``. Booleans, None and
        non-finite numbers are refused.
    kind : str
        ``length``, ``modulus`` (or ``pressure``), ``mass``, ``density``, ``frequency``,
        ``angle`` (returns degrees) or ``dimensionless``.
    where : Where, optional
        File, field and line quoted in the error message.
    expected : str, optional
        What an error message says was expected (default: the kind and its units).

    Returns
    -------
    float
        The value in SI (degrees for angles).

    Raises
    ------
    SpecimenError
        Wrong or unknown unit, not a number; the message lists the accepted units.

    Examples
    --------
    >>> parse_quantity("210.5 mm", "length")
    0.2105
    >>> parse_quantity("1570 kg/m^3", "density")
    1570.0
    >>> parse_quantity(0.35, "dimensionless")
    0.35
    """
    kind = canonical_kind(kind)
    where = where or Where()
    if expected is None:
        expected = ("expected a plain number (no unit)" if kind == "dimensionless"
                    else f"expected {_a(kind)} in {accepted_units(kind)}")
    if isinstance(value, bool) or value is None:
        what = "nothing" if value is None else f"the boolean {value}"
        raise where.error(f"got {what}; {expected}")
    if isinstance(value, (int, float)):
        try:
            number, unit = float(value), ""
        except OverflowError:
            raise where.error(f"{_show(value)} is too large a number; {expected}") from None
    elif isinstance(value, str):
        match = _NUMBER.match(normalize_text(value))
        if match is None:
            raise where.error(f"cannot read {_show(value)} as a number with a unit; {expected}")
        number, unit = float(match.group(1)), match.group(2)
    else:
        raise where.error(f"got {type(value).__name__} {_show(value)}; {expected}")
    if not math.isfinite(number):
        raise where.error(f"got {_show(value)}, which is not a finite number; {expected}")
    factor = 1.0
    if unit:
        factor = _lookup_unit(unit, kind)
        if factor is None:
            other = _kind_of_unit(unit)
            if other is not None:
                noun = "plain number" if kind == "dimensionless" else kind
                raise where.error(f"{_show(value)} is {_a(other)}, not {_a(noun)}; {expected}")
            if any(u.lower() == unit.lower() for u in UNITS[kind]):
                raise where.error(f"unit {unit!r} in {_show(value)} is ambiguous (its case "
                                  f"decides the prefix); {expected}")
            comma = re.match(r",([0-9]+)((?:\s*[^,0-9\s].*)?)\Z", unit)
            if comma is not None and "." in match.group(1):
                # '1.250,3': a point and a comma; the comma as a point gives '1.250.3', no
                # number. Where the point groups thousands (three digits after it, as a
                # European spreadsheet writes 1.250,3) that is 1250.3; else it cannot be told
                grouped = re.fullmatch(r"([+-]?[0-9]{1,3})\.([0-9]{3})", match.group(1))
                hint = (f" ({grouped.group(1)}{grouped.group(2)}.{comma.group(1)}"
                        f"{comma.group(2)} if the point groups thousands)" if grouped else "")
                raise where.error(f"{_show(value)} has both a point and a comma; write the "
                                  f"number with one decimal point and no thousands separator"
                                  f"{hint}")
            if comma is not None:
                point = f"{match.group(1)}.{comma.group(1)}{comma.group(2)}"
                raise where.error(f"{_show(value)} has a decimal comma; write a decimal point, "
                                  f"{point!r}")
            raise where.error(f"unknown unit {unit!r} in {_show(value)}; {expected}")
    si = number * factor
    if not math.isfinite(si):
        raise where.error(f"{_show(value)} is too large a number; {expected}")
    check_plausible(si, kind, where=where, text=value)
    return si


def written_unit(value, kind: str) -> tuple[str, float] | None:
    """The unit a quantity was written in and its factor to the base unit: ``("MPa", 1e6)``
    for ``"117 MPa"``, ``("", 1.0)`` for a bare number; None when ``value`` does not read as a
    ``kind`` (:func:`parse_quantity` says why). Tells a value written in another unit than its
    neighbours (E1 in MPa among moduli in GPa).

    >>> written_unit("117.2 gpa", "modulus")
    ('gpa', 1000000000.0)
    """
    kind = canonical_kind(kind)
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        return None
    if not isinstance(value, str):
        return "", 1.0
    match = _NUMBER.match(normalize_text(value))
    if match is None:
        return None
    unit = match.group(2)
    if not unit:
        return "", 1.0
    factor = _lookup_unit(unit, kind)
    return None if factor is None else (unit, factor)


def parse_fraction(value, *, where: Where | None = None) -> float:
    """A dimensionless ratio written as a plain number or as a percentage: the ratio.

    The one reader of the specimen file's damping ratios and of loss factors given on the
    command line (``--fix eta13=1%``); range checks are the caller's (a damping ratio and a
    loss factor have different ones). Errors as :func:`parse_quantity` (SpecimenError naming
    ``where``).

    >>> parse_fraction("0.4 %")
    0.004
    >>> parse_fraction(0.004)
    0.004
    """
    expected = "expected a plain number or a percentage (0.004 or '0.4 %')"
    if isinstance(value, str) and value.strip().endswith("%"):
        return parse_quantity(value.strip()[:-1].strip(), "dimensionless", where=where,
                              expected=expected) / 100
    return parse_quantity(value, "dimensionless", where=where, expected=expected)


def check_plausible(value: float, kind: str, *, where: Where | None = None, text=None) -> None:
    """Refuse a positive ``value`` (base unit of ``kind``) outside :data:`PLAUSIBLE`.

    Zero and negative values are left to the caller (which knows whether they are allowed).
    """
    kind = canonical_kind(kind)
    if kind not in PLAUSIBLE or not value > 0:
        return
    low, high = PLAUSIBLE[kind]
    if low <= value <= high:
        return
    where = where or Where()
    shown = _show(text) if text is not None else format_quantity(value, kind)
    raise where.error(f"{shown} = {format_quantity(value, kind)} is not a plausible {kind} "
                      f"(expected {format_quantity(low, kind)} to {format_quantity(high, kind)}); "
                      "check the number and its unit")


def _a(noun: str) -> str:
    """``noun`` with its indefinite article: 'a length', 'an angle'."""
    return f"{'an' if noun[:1] in 'aeiou' else 'a'} {noun}"


def _show(value, limit: int = 40) -> str:
    """``repr`` of a value from a file, cut to ``limit`` characters (a 400-digit number...)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 5] + "…" + text[-4:]


def format_quantity(value: float, kind: str, digits: int = 4) -> str:
    """``value`` (SI; degrees for angles) written in the display unit of ``kind``.

    >>> format_quantity(117.2e9, "modulus")
    '117.2 GPa'
    """
    kind = canonical_kind(kind)
    unit = DISPLAY_UNITS[kind]
    number = value / UNITS[kind][unit] if unit else value
    return f"{number:.{digits}g} {unit}".rstrip()


#: the parts of a format spec (Python's mini-language) that decide how number_text writes a
#: zero without its minus: alignment, sign, width
_SPEC = re.compile(r"(?:.?([<>=^]))?([+\- ]?)z?#?0?(\d*)")
#: a minus before a number whose digits are all zeros ("-0.00", "-0.000e+00", "-0 %")
_NEGATIVE_ZERO = re.compile(r"-(?=[0.,_]*0[0.,_]*(?:[eE][+-]?\d+)?\s*%?\s*\Z)")


def number_text(value, spec: str) -> str:
    """``format(value, spec)`` as every table writes a number: a value that rounds to zero in
    ``spec`` without a minus ("0.00", not "-0.00" for a residual of -0.001 %, nor for IEEE's
    -0.0), "+0.000" where ``spec`` asks for a sign, in the spec's width. Python's "z" option
    does this from 3.11 only (laminid runs on 3.10).

    >>> number_text(-0.001, "6.2f"), number_text(-4e-4, "+.3f"), number_text(-0.02, ".2f")
    ('  0.00', '+0.000', '-0.02')
    """
    text = format(value, spec)
    m = _NEGATIVE_ZERO.search(text)
    if m is None:
        return text
    align, sign, width = _SPEC.match(spec).groups()
    head, tail = text[:m.start()], text[m.end():]
    if sign in ("+", " "):
        return head + sign + tail
    text = head + tail
    if width and len(text) < int(width):          # the column keeps its width
        text = text + " " if align == "<" else " " + text
    return text


def gpa_text(value: float) -> str:
    """A modulus (Pa) as the number of GPa every table shows: 2 decimals ('117.20'); 3
    significant digits below 1 GPa, so a modulus at its floor reads 0.00299, not 0.00, and one
    written in MPa by mistake 0.117 (E1 117.2 MPa), not 0.12; from 1e5 GPa (an undetermined
    constant's interval end) in exponent form, not 26 digits. The terminal's tables
    (commands/text.py) and the report's pages (through constant_text) write moduli by it.

    >>> gpa_text(117.2e9), gpa_text(2.99e6), gpa_text(3.1e20)
    ('117.20', '0.00299', '3.10e+11')
    """
    v = value / 1e9
    if abs(v) >= 1e5:
        return f"{v:.2e}"
    if 0 < abs(v) < 1:
        return f"{v:.3g}"
    return number_text(v, ".2f")


def constant_text(name: str, value: float) -> str:
    """A finite elastic constant as the terminal's tables and the report's pages both write
    it: a modulus (``name`` not ``nu12``; Pa) as :func:`gpa_text` writes its GPa, a Poisson
    ratio to 3 decimals, from 1e5 (an undetermined ratio's interval end) in exponent form.
    One number reads the same on the terminal and on the page ("0.00595", not "0.005950").

    >>> constant_text("G12", 5.95e6), constant_text("E2", 0.9e9), constant_text("nu12", 0.9)
    ('0.00595', '0.9', '0.900')
    """
    if name != "nu12":
        return gpa_text(value)
    if abs(value) >= 1e5:
        return f"{value:.2e}"
    return number_text(value, ".3f")


def significant_text(name: str, value: float, digits: int = 3) -> str:
    """A constant (``name``; SI, a modulus written in GPa) to ``digits`` significant digits,
    as the terminal's Monte Carlo table writes its stds (3) and its range ends (4: "8.685",
    "0.01025"), and the report its Monte Carlo range ends.

    Trailing zeros are kept, so that every number shows the digits it has: the range
    "156.0 GPa .. 163.7 GPa" and the std "0.500 GPa" beside "0.489 GPa" (``g`` wrote "156"
    and "0.5", which read as known to fewer digits than their neighbours).

    >>> significant_text("G13", 8.684992e9, 4), significant_text("nu12", 0.0552771, 4)
    ('8.685', '0.05528')
    >>> significant_text("E1", 156.0e9, 4), significant_text("E2", 0.5e9)
    ('156.0', '0.500')
    >>> significant_text("E1", 1234.4e9, 4), significant_text("nu12", 1e-5, 3)
    ('1234', '1.00e-05')
    """
    text = f"{(value if name == 'nu12' else value / 1e9):#.{digits}g}"
    return text[:-1] if text.endswith(".") else text


#: the unit of each numeric field of a ``--json`` document (modes, identify, show) by the
#: field's name, wherever it appears: SI throughout (frequencies Hz, moduli Pa, lengths m, mass
#: kg); a block's name (``frequencies``) gives the unit of its lists that have no entry of their
#: own; the fields of a constant's, a property's or a loss factor's block (``value``,
#: ``lower``, ...) are in the unit of that quantity. Counts, indices, flags and text have none.
JSON_UNITS: dict[str, str] = {
    "a": "m", "b": "m", "h": "m", "mass": "kg", "model_mass": "kg", "density": "kg/m^3",
    **{k: "Pa" for k in ("E1", "E2", "G12", "G13", "G23", "Ex", "Ey", "Gxy", "Gxz", "Gyz")},
    "nu12": "1", "nu_xy": "1", "nu_yx": "1",
    **{f"eta{k}": "1 (loss factor, eta = 2 zeta)" for k in ("11", "22", "12", "13", "23")},
    "frequencies": "Hz", "measured": "Hz", "model": "Hz", "sigma_hz": "Hz", "freq_hz": "Hz",
    "fine_hz": "Hz",
    "weight": "1", "residual_percent": "%", "rms_residual_percent": "%",
    "initial_rms_residual_percent": "%", "change_percent": "%", "shift_percent": "%",
    "change_sigma": "frequency sigma of the mode", "shift_half_width": "95 % half-width of the "
    "constant", "error_bound": "1 (relative eigenvalue error)", "time_s": "s",
    "trial_eigenvalue_bound": "1 (relative eigenvalue error)",
    "trial_eigenvalue_bound_limit": "1 (relative eigenvalue error)",
    "trial_shift_bound": "standard errors of a constant (first order)",
    "trial_shift_limit": "standard errors of a constant (first order)",
    **{k: "unit of the quantity it belongs to" for k in (
        "value", "std", "std_stated", "lower", "upper", "half_width", "bound_limit",
        "profile_bound", "profile_far", "mean", "inner_lower", "inner_upper", "linearized_std",
        "shift")},
    "rel_half_width": "1 (fraction of the value)", "sigma_rel": "1 (fraction of the frequency)",
    # the Monte Carlo's and the verdicts' relative widths, fractions as rel_half_width (0.0113
    # is +-1.13 %), not percent: they had no unit and sit beside *_percent fields
    "monte_carlo_rel_half_width": "1 (fraction of the value)",
    "monte_carlo_rel_half_width_lower": "1 (fraction of the value)",
    "well_determined": "1 (fraction of the value: rel_half_width below it)",
    "weak": "1 (fraction of the value: rel_half_width below it)",
    "max_rel_interval": "1 (fraction of the value: rel_half_width above it is flagged)",
    "information_from_prior": "1 (fraction of what is known of the constant)",
    "covariance": "product of the units of its row's and column's labels (Pa^2, Pa, 1)",
    "correlation": "1", "dlnf_dlnP": "1",
}


def json_units(document: dict) -> dict[str, str]:
    """The ``units`` object of a ``--json`` document: :data:`JSON_UNITS` for the field names
    that occur in ``document`` (at any depth), in the order of :data:`JSON_UNITS`.

    >>> json_units({"frequencies": {"model": [105.5]}, "specimen": {"a": 0.21}})
    {'a': 'm', 'frequencies': 'Hz', 'model': 'Hz'}
    """
    names: set[str] = set()
    stack = [document]
    while stack:
        obj = stack.pop()
        if isinstance(obj, dict):
            names.update(str(k) for k, v in obj.items() if k != "units")
            stack.extend(v for k, v in obj.items() if k != "units")
        elif isinstance(obj, (list, tuple)):
            stack.extend(v for v in obj if isinstance(v, (dict, list, tuple)))
    return {k: u for k, u in JSON_UNITS.items() if k in names}
