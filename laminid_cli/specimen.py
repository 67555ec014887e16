"""Specimen files: YAML -> validated, frozen :class:`Specimen` (SI units inside).

A specimen file describes one plate: geometry, mass, ply materials (initial constants for the
identification), layup, boundary condition, measured natural frequencies and optional reference
values from other tests. The full format is documented in ``specimens/README.md``; in short::

    name: S1.1
    description: IM7/977-2 carbon/epoxy plate, Araujo et al. 2000, Example 1
    geometry: {a: 210.5 mm, b: 311 mm, h: 3.06 mm}   # a along x, b along y, h total thickness
    mass: 0.3225 kg                    # gives the density m/(a b h) of a single material
    materials:
      IM7/977-2: {E1: 117.2 GPa, E2: 8.8 GPa, G12: 3.1 GPa, G13: 3.1 GPa, G23: 3.1 GPa,
                  nu12: 0.35}          # optional: density, density_ratio, fixed, prior
      # an isotropic material: {E: 70 GPa, nu: 0.3} (G optional, default E / (2 (1 + nu)))
    layup: "[45_3/0_3/-45_3/90_3]s"    # stacking code, bottom ply first (or `plies:` list)
    boundary: free                     # free | simply-supported | clamped
    measured:
      frequencies: [125.05, 203.50, null, 446.65]   # Hz; null = not detected
      weights: [1, 1, 0, 1]            # optional, in [0, 1]; forced to 0 where null
      sigma: [0.1, 0.1, null, 0.2]     # optional standard deviations, Hz
      damping: [0.0021, 0.0046, null, 0.5 %]   # optional viscous damping ratios zeta
      damping_sigma: [0.0002, 0.0003, null, 0.0004]   # optional, their standard deviations
    reference:
      source: strain gauge
      materials: {IM7/977-2: {E1: 170 GPa, E2: [9 GPa, 11 GPa]}}   # [low, high]: a range
      global: {Ex: 77 GPa, nu_xy: [0.15, 0.17]}

Stacking codes (:func:`expand_layup`): plies bottom first separated by ``/`` (or ``,``);
``45_3`` three plies; ``(0/90)_2`` a repeated group; ``[...]s`` symmetric, ``[...]2s`` or
``[...]_2s`` repeated twice then mirrored, ``[...]_3`` repeated; ``±45`` (also ``+-45``) is
``45/-45`` and ``∓45`` (``-+45``) is ``-45/45``, so ``±45_2`` is ``45/-45/45/-45``; an optional
``°`` or ``deg`` after an angle (``rad`` is refused). A material tag follows a ply or a group,
after its repeat count: ``0:carbon``, ``90_2:glass``, ``(0/90):glass``; after a single ply angle
the colon may be left out when the tag is letters only, as the paper writes it:
``[0c/90g/0c/90_2g/0c/90g]s``. A tag
is a material name or an unambiguous beginning of one (``c`` for ``carbon``). A tag on a group
applies to the plies inside that have none.

Errors are :class:`~laminid_cli.errors.SpecimenError` with ``file:line, field 'x.y': problem``.
Positions in lists are counted from 1 (``plies[1]`` is the bottom ply, ``frequencies[3]`` the
third mode).
"""

from __future__ import annotations

import dataclasses
import difflib
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from laminid_cli.errors import LaminidError, SpecimenError, non_printable
from laminid_cli.filekinds import binary_kind
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants, infeasibility_reasons
from laminid_cli.units import Where, normalize_text, parse_fraction, parse_quantity

log = logging.getLogger(__name__)

#: boundary conditions understood by the plate model
BOUNDARIES = ("free", "simply-supported", "clamped")
#: laminate (global) properties of Appendix A that a reference may give
GLOBAL_NAMES = ("Ex", "Ey", "Gxy", "Gxz", "Gyz", "nu_xy", "nu_yx")
#: ply thicknesses must add up to h within this fraction of h (unless scale_thickness: true)
THICKNESS_TOLERANCE = 0.005
#: with scale_thickness, nominal ply thicknesses may be scaled to h by at most this factor (or
#: its inverse): more is a wrong unit or a wrong h, not a nominal-vs-measured difference
MAX_THICKNESS_SCALE = 1.5
#: a stacking code may not expand to more plies than this
MAX_PLIES = 2000
#: a plate whose mean density (model mass / (a b h), kg/m^3) is below this is warned about as
#: a likely unit slip (it is still computed: units.PLAUSIBLE refuses only below 1 kg/m^3).
#: Solid plates weigh 900 (polypropylene) to 19300 (tungsten) kg/m^3, composite laminates 1400-
#: 2100; a mass 1000 times too small (grams as kg) makes them 0.9-19 kg/m^3, a side in inches
#: for mm (25.4 times too large) 55-83 kg/m^3 for a carbon or glass laminate. A sandwich panel
#: modelled as one plate is lighter than a laminate but seldom below 100 (2 x 0.5 mm CFRP skins
#: on 10 mm of 48 kg/m^3 honeycomb: 184 kg/m^3); only a thick foam-cored one with very thin
#: skins gets there (0.25 mm skins on 25 mm of 32 kg/m^3 foam: 63 kg/m^3). A plate of several
#: materials is warned about only when its densest material is below SOLID_DENSITY as well: a
#: sandwich given as skins and core has skins of a solid's density, while each slip above
#: makes every material as light (skins of 1.6 kg/m^3 for grams as kg, 63 for inches)
LIGHT_PLATE_DENSITY = 100.0
#: the lightest solid a plate's skins or plies are made of (kg/m^3: polypropylene 900, wood
#: veneers from ~500)
SOLID_DENSITY = 500.0
#: a ply material of a plate of several materials lighter than this (kg/m^3) is warned about:
#: the lightest structural cores are 24 (Nomex honeycomb) and 32 (PMI foam) kg/m^3, while a ply
#: density 1000 times too small (g/cm^3 written as kg/m^3) is 0.9-19 kg/m^3
LIGHT_MATERIAL_DENSITY = 20.0

_TOP_KEYS = ("name", "description", "geometry", "mass", "materials", "layup", "plies",
             "ply_thickness", "scale_thickness", "scale_density_to_mass", "boundary", "measured",
             "reference")
_MATERIAL_KEYS = CONSTANT_NAMES + ("density", "density_ratio", "fixed", "prior")
#: an isotropic material's keys instead of the six constants (G optional: E / (2 (1 + nu)))
_ISOTROPIC_KEYS = ("E", "nu", "G") + _MATERIAL_KEYS[len(CONSTANT_NAMES):]

#: keys a user puts in the wrong block, and where they belong (said by the "unknown key"
#: message: a top-level ``density:`` was answered with the top level's valid keys alone)
_MATERIAL_PLACE = "to a ply material, under materials.<material name> (materials: {CF: {..., %s: ...}})"
_TOP_ELSEWHERE = {
    **{k: _MATERIAL_PLACE % k for k in _MATERIAL_KEYS + ("E", "nu", "G")},
    "density": (_MATERIAL_PLACE % "density") + ", or give the plate's mass here (mass: "
               "0.3225 kg), from which the density is m/(a b h)",
    **{k: f"under measured: (measured: {{{k}: [...]}})"
       for k in ("frequencies", "weights", "sigma", "damping", "damping_sigma", "frf_file")},
    **{k: f"under geometry: (geometry: {{a: ..., b: ..., h: ...}})" for k in ("a", "b", "h")},
}
_MATERIAL_ELSEWHERE = {
    "mass": "to the plate, at the top level of the file (mass: 0.3225 kg), not to a material",
    **{k: "to the plate, under geometry: (geometry: {a: ..., b: ..., h: ...})"
       for k in ("a", "b", "h", "thickness")},
}
_MODULI = ("E1", "E2", "G12", "G13", "G23")


# ----------------------------------------------------------------------------------------------
# the dataclasses


@dataclass(frozen=True)
class Material:
    """One ply material: initial (or current) constants and options for the identification.

    ``density`` is the value written in the file (kg/m^3, None when not given; the resolved
    density is in :attr:`Specimen.densities`). ``fixed`` names constants that ``identify`` holds
    at their initial value; ``prior`` maps constant names to relative confidences (paper Eq. 15).
    """

    name: str
    constants: ElasticConstants
    density: float | None
    fixed: tuple[str, ...] = ()
    prior: dict = field(default_factory=dict)
    density_ratio: float | None = None


@dataclass(frozen=True)
class Ply:
    """One ply: material name, angle in degrees (x towards y), thickness in m."""

    material: str
    angle_deg: float
    thickness: float


@dataclass(frozen=True)
class Measured:
    """Measured natural frequencies of the first n modes.

    freq : (n,) Hz, NaN where a mode was not detected
    weight : (n,) in [0, 1], 0 where ``freq`` is NaN (paper Eq. 17)
    sigma : (n,) Hz standard deviations, NaN where unknown; None when the file gives none
    damping : (n,) viscous damping ratios zeta (modal loss factor eta = 2 zeta), NaN where not
        measured; None when the file gives none (laminid_cli.damping)
    damping_sigma : (n,) their standard deviations, NaN where unknown; None when none given
    sigma_source : how the sigmas were made (``measured.sigma_source``, written by
        ``fit-frf --into``; for ``frf_file`` the fit's rule), "" when not said
    damping_sigma_source : how the damping sigmas were made (``measured.damping_sigma_source``,
        written by ``fit-frf --into``: how many are the RFP fit's assumed 2 % floor; for
        ``frf_file`` the fit's), "" when not said
    frf_file : the FRF file (``measured.frf_file``, as written) whose RFP fit gave the
        frequencies, sigmas and damping; "" when the specimen file lists them itself
    """

    freq: np.ndarray
    weight: np.ndarray
    sigma: np.ndarray | None = None
    damping: np.ndarray | None = None
    damping_sigma: np.ndarray | None = None
    sigma_source: str = ""
    frf_file: str = ""
    damping_sigma_source: str = ""

    @property
    def n_modes(self) -> int:
        return int(self.freq.shape[0])


@dataclass(frozen=True)
class Specimen:
    """A plate specimen read from a YAML file; SI units (angles in degrees).

    ``source_text`` is the YAML verbatim (stored in result files). ``reference`` always has the
    keys ``source`` (str), ``materials`` ({material: {constant: value}}) and ``global``
    ({property: value}); a value is a float, or a ``(low, high)`` tuple where the file gives
    a range (``E1: [120 GPa, 150 GPa]``): the range as written, never its midpoint, which
    nobody measured (SI; a range with low == high is the one value).
    """

    name: str
    path: str
    source_text: str
    a: float
    b: float
    h: float
    mass: float | None
    materials: dict[str, Material]
    plies: tuple[Ply, ...]
    densities: dict[str, float]
    measured: Measured | None
    reference: dict
    boundary: str = "free"
    description: str = ""
    #: the reader's warnings on the file (ply angles that look like radians, a mass that
    #: density x volume contradicts, a plate too light to be solid), each naming the file,
    #: line and field; logged when read, and in the --json 'warnings' of the commands that
    #: read the specimen
    warnings: tuple[str, ...] = ()

    @property
    def n_plies(self) -> int:
        return len(self.plies)

    @property
    def model_mass(self) -> float:
        """Mass of the plate model, a b sum(rho_k t_k), kg."""
        return self.a * self.b * sum(self.densities[p.material] * p.thickness for p in self.plies)

    def with_constants(self, constants: dict[str, ElasticConstants]) -> "Specimen":
        """Copy with new constants for some or all materials (``source_text`` is unchanged)."""
        unknown = [name for name in constants if name not in self.materials]
        if unknown:
            raise KeyError(f"no material {unknown[0]!r} in specimen {self.name!r} "
                           f"(materials: {', '.join(self.materials)})")
        materials = {name: dataclasses.replace(m, constants=constants[name])
                     if name in constants else m for name, m in self.materials.items()}
        return dataclasses.replace(self, materials=materials)


# ----------------------------------------------------------------------------------------------
# YAML with line numbers


@dataclass
class _Y:
    """A YAML value with its line (1-based) and dotted field name.

    ``value`` is a Python scalar, a dict of ``_Y`` (mapping, file order) or a list of ``_Y``.
    """

    value: Any
    line: int
    field: str


def _join(parent: str, key: str) -> str:
    return f"{parent}.{key}" if parent else key


#: bounds on a specimen file (a real one is a few kB, 3-4 levels deep, with no or few aliases):
#: the YAML is checked against them, event by event, before anything is built from it
MAX_SPECIMEN_CHARS = 1_000_000
MAX_YAML_DEPTH = 32
MAX_YAML_ALIASES = 100
MAX_YAML_NODES = 100_000

# characters YAML 1.1 does not allow in a stream (tab, LF, CR, NEL are allowed)
_NON_PRINTABLE = re.compile("[^\x09\x0A\x0D\x20-\x7E\x85\xA0-\uD7FF\uE000-\uFFFD"
                            "\U00010000-\U0010FFFF]")


def check_yaml_text(text: str, path: str = "<string>") -> None:
    """Refuse YAML that laminid will not load, before any object is built from it.

    Checked on the raw text and on the parser's event stream (which needs neither recursion
    nor alias expansion, so the check is linear in the size of the text): the size
    (:data:`MAX_SPECIMEN_CHARS`), non-printable characters, nesting depth
    (:data:`MAX_YAML_DEPTH`), the number of aliases (:data:`MAX_YAML_ALIASES`) and the number
    of nodes once the aliases are expanded (:data:`MAX_YAML_NODES`, which stops "billion
    laughs" alias bombs), explicit tags (``!!int``, ``!foo``) and merge keys (``<<``).

    Raises
    ------
    SpecimenError
        ``path:line: problem`` (exit code 2).
    """
    if len(text) > MAX_SPECIMEN_CHARS:
        raise SpecimenError(f"the file has {len(text)} characters, more than a specimen file "
                            f"can have ({MAX_SPECIMEN_CHARS}); is it the right file?", path=path)
    bad = _NON_PRINTABLE.search(text)
    if bad is not None:
        line = text.count("\n", 0, bad.start()) + 1
        raise SpecimenError(f"non-printable character U+{ord(bad.group()):04X} in the text; "
                            "remove it (YAML allows no control characters)", path=path, line=line)
    depth = 0
    n_aliases = 0
    total = 0
    sizes: dict[str, int] = {}          # anchor -> nodes it stands for once expanded
    open_nodes: list[list] = []          # [anchor, nodes so far] of the open collections
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            line = event.start_mark.line + 1 if event.start_mark else None
            if isinstance(event, yaml.AliasEvent):
                n_aliases += 1
                if n_aliases > MAX_YAML_ALIASES:
                    raise SpecimenError(f"more than {MAX_YAML_ALIASES} YAML aliases (*name); "
                                        "write the values out", path=path, line=line)
                count = sizes.get(event.anchor, 1)
            elif isinstance(event, (yaml.ScalarEvent, yaml.SequenceStartEvent,
                                    yaml.MappingStartEvent)):
                tag = event.tag
                implicit = event.implicit[0] if isinstance(event, yaml.ScalarEvent) \
                    else event.implicit
                if tag is not None and not implicit and tag != "!":
                    tag = tag.replace("tag:yaml.org,2002:", "!!")
                    raise SpecimenError(f"YAML tag {tag!r} is not allowed in a specimen file; "
                                        "remove it (quote a value to make it text)",
                                        path=path, line=line)
                if isinstance(event, yaml.ScalarEvent) and event.value == "<<" \
                        and event.style is None:
                    raise SpecimenError("YAML merge keys (<<) are not allowed in a specimen "
                                        "file; write the keys out", path=path, line=line)
                if not isinstance(event, yaml.ScalarEvent):
                    depth += 1
                    if depth > MAX_YAML_DEPTH:
                        raise SpecimenError(f"nesting deeper than {MAX_YAML_DEPTH} levels",
                                            path=path, line=line)
                    open_nodes.append([event.anchor, 1])
                    continue
                count = 1
                if event.anchor is not None:
                    sizes[event.anchor] = 1
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                depth -= 1
                anchor, count = open_nodes.pop()
                if anchor is not None:
                    sizes[anchor] = count
            else:
                continue
            if open_nodes:
                open_nodes[-1][1] += count
            else:
                total += count
            if total + sum(n for _, n in open_nodes) > MAX_YAML_NODES:
                raise SpecimenError(f"the YAML expands to more than {MAX_YAML_NODES} values "
                                    "(aliases of aliases?); write the values out",
                                    path=path, line=line)
    except yaml.MarkedYAMLError:
        return   # a syntax error: reported with its context by _compose
    except yaml.YAMLError as exc:
        raise SpecimenError(f"not valid YAML: {' '.join(str(exc).split())}", path=path) from exc


def _compose(text: str, path: str) -> _Y:
    check_yaml_text(text, path)
    loader = yaml.SafeLoader(text)
    try:
        try:
            node = loader.get_single_node()
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            line = mark.line + 1 if mark else None
            problem = " ".join(str(p) for p in (exc.context, exc.problem) if p)
            hint = ""
            bad_line = text.splitlines()[line - 1] if line and line <= len(text.splitlines()) \
                else ""
            if re.search(r":\s*\[[^\]]*\][^\s#,\]]", bad_line):
                hint = " (quote a stacking code that starts with '[', e.g. layup: \"[0/90]s\")"
            elif "'\\t'" in problem and "\t" in bad_line:
                # PyYAML: "found character '\t' that cannot start any token"
                where = ("is indented with a tab" if bad_line[:1].isspace() and "\t" in
                         bad_line[:len(bad_line) - len(bad_line.lstrip())] else "has a tab")
                problem = (f"line {line} {where}; YAML indents and separates with spaces "
                           "only: replace the tab by spaces")
            raise SpecimenError(f"not valid YAML: {problem}{hint}", path=path, line=line) \
                from exc
        except yaml.YAMLError as exc:
            raise SpecimenError(f"not valid YAML: {' '.join(str(exc).split())}",
                                path=path) from exc
        if node is None:
            comments = sum(1 for ln in text.splitlines() if ln.lstrip().startswith("#"))
            # (a file of comments alone was 'the file is empty', which the lab saw it is not)
            what = (f"holds only comments ({comments} '#' line{'s' if comments > 1 else ''}), "
                    "no data" if comments else "the file is empty")
            raise SpecimenError(f"{what}; expected a mapping with geometry, materials, "
                                "layup, ...", path=path)
        return _convert(node, loader, "", path, set())
    finally:
        loader.dispose()


def _convert(node, loader, name: str, path: str, active: set) -> _Y:
    line = node.start_mark.line + 1
    if id(node) in active:
        raise SpecimenError("recursive YAML alias", path=path, field=name or None, line=line)
    if isinstance(node, yaml.ScalarNode):
        try:
            value = loader.construct_object(node, deep=True)
        except yaml.YAMLError as exc:
            problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
            raise SpecimenError(f"cannot read the value: {problem}", path=path,
                                field=name or None, line=line) from exc
        except (ValueError, OverflowError) as exc:
            # PyYAML's constructors of implicit types raise these: a date that is not one
            # (2024-13-45: "month must be in 1..12"), read as a date because it looks like one
            raise SpecimenError(f"cannot read the value '{node.value}': {exc} (YAML reads it "
                                "as a date or time; quote it to keep it as text)", path=path,
                                field=name or None, line=line) from exc
        return _Y(value, line, name)
    active = active | {id(node)}
    if isinstance(node, yaml.SequenceNode):
        return _Y([_convert(item, loader, f"{name}[{k + 1}]", path, active)
                   for k, item in enumerate(node.value)], line, name)
    out: dict[str, _Y] = {}
    for key_node, value_node in node.value:
        key_line = key_node.start_mark.line + 1
        if not isinstance(key_node, yaml.ScalarNode):
            raise SpecimenError("a key must be a plain name, not a list or mapping", path=path,
                                field=name or None, line=key_line)
        try:
            key = loader.construct_object(key_node, deep=True)
        except (yaml.YAMLError, ValueError, OverflowError) as exc:
            raise SpecimenError(f"cannot read the key '{key_node.value}': "
                                f"{getattr(exc, 'problem', None) or exc}", path=path,
                                field=name or None, line=key_line) from exc
        key = "null" if key is None else str(key)
        if key in out:
            raise SpecimenError(f"key '{key}' appears twice (first on line {out[key].line})",
                                path=path, field=_join(name, key), line=key_line)
        child = _convert(value_node, loader, _join(name, key), path, active)
        # report errors in a value on the line of its key (a block value starts below it)
        child.line = key_line
        out[key] = child
    return _Y(out, line, name)


def _closest(key: str, valid) -> str | None:
    valid = list(valid)
    for v in valid:
        if v.lower() == key.lower():
            return v
    # a shear modulus with its indices the other way round is the same modulus (G31 = G13):
    # spelling alone guessed G23 for G31 and for G21
    swapped = re.fullmatch(r"[Gg](\d)(\d)", str(key))
    if swapped and f"G{swapped[2]}{swapped[1]}" in valid:
        return f"G{swapped[2]}{swapped[1]}"
    found = difflib.get_close_matches(key, valid, n=1, cutoff=0.6)
    return found[0] if found else None


class _Reader:
    """Typed access to ``_Y`` values, raising SpecimenError with file, field and line."""

    def __init__(self, path: str, log_warnings: bool = True):
        self.path = path
        self.log_warnings = log_warnings
        self.warnings: list[str] = []

    def warn(self, message: str) -> None:
        """A warning on the file (``message`` names the file, line and field): logged now
        (unless the reader was made with ``log_warnings=False``), kept for
        :attr:`Specimen.warnings`."""
        if self.log_warnings:
            log.warning("%s", message)
        self.warnings.append(message)

    def where(self, y: _Y, field_name: str | None = None) -> Where:
        return Where(self.path, field_name or y.field or None, y.line)

    def error(self, y: _Y, message: str, field_name: str | None = None) -> SpecimenError:
        return self.where(y, field_name).error(message)

    def mapping(self, y: _Y, required=(), optional=(), what: str = "a mapping",
                any_key: bool = False, elsewhere: dict | None = None) -> dict:
        """``elsewhere``: keys that belong to another block of the file, with where they go
        (a plate's ``density:`` at the top level: a material's key), said instead of a guess
        among this block's keys."""
        if not isinstance(y.value, dict):
            raise self.error(y, f"expected {what} (key: value lines), got {_describe(y.value)}")
        valid = list(required) + list(optional)
        for key, child in y.value.items():
            if not any_key and key not in valid:
                place = (elsewhere or {}).get(key)
                guess = None if place else _closest(key, valid)
                hint = f"; did you mean '{guess}'?" if guess else ""
                if place:
                    hint = f": it belongs {place}"
                raise self.error(child, f"unknown key '{key}'{hint} (valid keys: "
                                        f"{', '.join(valid)})")
        for key in required:
            if key not in y.value:
                raise self.error(y, f"missing required key '{key}'", _join(y.field, key))
        return y.value

    def sequence(self, y: _Y, what: str = "a list") -> list:
        if not isinstance(y.value, list):
            raise self.error(y, f"expected {what} ([a, b, ...]), got {_describe(y.value)}")
        return y.value

    def quantity(self, y: _Y, kind: str) -> float:
        if isinstance(y.value, (dict, list)):
            raise self.error(y, f"expected a single {kind} value, got {_describe(y.value)}")
        return parse_quantity(y.value, kind, where=self.where(y))

    def positive(self, y: _Y, kind: str) -> float:
        value = self.quantity(y, kind)
        if value <= 0:
            raise self.error(y, f"must be positive, got {y.value!r}")
        return value

    def string(self, y: _Y) -> str:
        """A text: a control character, bidirectional override or invisible character in it
        (errors.NON_PRINTABLE, as a quoted escape "\\u202e" or "\\e[31m" makes one, which the
        check of the raw text cannot see) refused naming the field."""
        if isinstance(y.value, bool) or isinstance(y.value, (dict, list)) or y.value is None:
            raise self.error(y, f"expected text, got {_describe(y.value)}")
        text = str(y.value)
        bad = non_printable(text)
        if bad is not None:
            raise self.error(y, f"{bad} in {text!r}; remove it")
        return text

    def boolean(self, y: _Y) -> bool:
        if not isinstance(y.value, bool):
            raise self.error(y, f"expected true or false, got {_describe(y.value)}")
        return y.value


def _describe(value) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    return f"{value!r}"


# ----------------------------------------------------------------------------------------------
# stacking codes


class LayupSyntaxError(ValueError):
    """A stacking code cannot be read; ``position`` is the 0-based index in the code."""

    def __init__(self, code: str, position: int, problem: str):
        self.code, self.position, self.problem = code, position, problem
        found = repr(code[position]) if position < len(code) else "the end"
        super().__init__(f"cannot read the stacking code {code!r}: {problem} at character "
                         f"{position + 1}, found {found} (…{code[max(0, position - 8):position]}"
                         f"⟨here⟩{code[position:position + 8]}…)")


_TAG_COLON = re.compile(r"[A-Za-z][A-Za-z0-9_.\-]*")
_TAG_LETTERS = re.compile(r"[A-Za-z]+")
_ANGLE = re.compile(r"\d+(?:\.\d*)?|\.\d+")
#: a unit written after an angle in a stacking code (not the beginning of a material tag)
_ANGLE_UNIT = re.compile(r"(deg|rad)(?![A-Za-z])")
_SIGNS = (("±", (1, -1)), ("∓", (-1, 1)), ("+-", (1, -1)), ("-+", (-1, 1)), ("+", (1,)),
          ("-", (-1,)))


class _LayupParser:
    """Recursive-descent reader of stacking codes (grammar in the module docstring)."""

    def __init__(self, code: str):
        self.code = code
        self.i = 0

    def fail(self, problem: str, position: int | None = None):
        raise LayupSyntaxError(self.code, self.i if position is None else position, problem)

    def peek(self, n: int = 1) -> str:
        return self.code[self.i:self.i + n]

    def skip_space(self):
        while self.i < len(self.code) and self.code[self.i].isspace():
            self.i += 1

    def parse(self) -> list[tuple[float, str | None]]:
        self.skip_space()
        if not self.code.strip():
            self.fail("the code is empty; expected plies like [0/90]s")
        if self.peek() == "[":
            self.i += 1
            plies = self.sequence()
            self.skip_space()
            if self.peek() != "]":
                self.fail("expected '/' or the closing ']'")
            self.i += 1
            plies = self.suffix(plies, symmetric_allowed=True)
        else:
            plies = self.sequence()
        self.skip_space()
        if self.i < len(self.code):
            # '[0/90]s2', '[0/90]S_2': the count after the s, where the code reads it before
            after_s = re.fullmatch(r"(\[.*\])\s*([sS])\s*_?(\d+)\s*", self.code.strip())
            if after_s is not None:
                body, s, n = after_s.groups()
                self.fail(f"a repeat count after the s is not read: write it before the s, "
                          f"{body}{n}{s} (the plies {n} times, then mirrored), or repeat the "
                          f"mirrored group, [({body[1:-1]}){s}]{n}")
            self.fail("unexpected text after the end of the code")
        return plies

    def sequence(self) -> list:
        plies = self.item()
        while True:
            self.skip_space()
            if self.peek() in ("/", ",") and self.peek():
                self.i += 1
                plies = plies + self.item()
            else:
                return plies

    def item(self) -> list:
        self.skip_space()
        if self.peek() == "(":
            self.i += 1
            plies = self.sequence()
            self.skip_space()
            if self.peek() != ")":
                self.fail("expected '/' or the closing ')'")
            self.i += 1
            return self.suffix(plies, symmetric_allowed=True)
        return self.angle_item()

    def angle_item(self) -> list:
        start = self.i
        signs = (1,)
        for text, value in _SIGNS:
            if self.code.startswith(text, self.i):
                signs = value
                self.i += len(text)
                break
        match = _ANGLE.match(self.code, self.i)
        if match is None:
            self.fail("expected a ply angle in degrees (like 45, -45, ±45) or a group '(...)'")
        angle = float(match.group())
        self.i = match.end()
        if self.peek() == "°":
            self.i += 1
        unit = _ANGLE_UNIT.match(self.code, self.i)
        if unit is not None and unit.group() == "deg":
            self.i = unit.end()
        elif unit is not None:
            self.fail(f"ply angles in a stacking code are degrees, not radians ({angle:g} rad "
                      f"= {angle * 180 / math.pi:.4g} deg)")
        if angle > 360:
            self.fail(f"ply angle {angle:g} is outside -360..360 degrees", start)
        plies = [(s * angle + 0.0, None) for s in signs]
        return self.suffix(plies, symmetric_allowed=False)

    def count(self) -> int | None:
        match = re.compile(r"\d+").match(self.code, self.i)
        if match is None:
            return None
        n = int(match.group())
        if n < 1:
            self.fail("a repeat count must be at least 1")
        self.count_start = self.i
        self.i = match.end()
        return n

    def suffix(self, plies: list, symmetric_allowed: bool) -> list:
        """Optional ``_n`` or ``n`` repeat, ``s`` mirror (groups only) and material tag."""
        underscore = self.peek() == "_"
        if underscore:
            self.i += 1
        n = self.count()
        if n is not None:
            if len(plies) * n > MAX_PLIES:
                self.fail(f"the code expands to more than {MAX_PLIES} plies", self.count_start)
            plies = plies * n
        symmetric = False
        if symmetric_allowed and self.peek() in ("s", "S") and \
                not self.code[self.i + 1:self.i + 2].isalnum():
            self.i += 1
            symmetric = True
            plies = plies + plies[::-1]
        if underscore and n is None and not symmetric:
            self.fail("expected a repeat count (like _3) or s after '_'")
        if len(plies) > MAX_PLIES:
            self.fail(f"the code expands to more than {MAX_PLIES} plies")
        tag = None
        if self.peek() == ":":
            self.i += 1
            match = _TAG_COLON.match(self.code, self.i)
            if match is None:
                self.fail("expected a material name after ':'")
            tag = match.group()
            self.i = match.end()
        elif not symmetric_allowed:
            match = _TAG_LETTERS.match(self.code, self.i)
            if match is not None:
                tag = match.group()
                self.i = match.end()
        if tag is not None:
            plies = [(angle, own if own is not None else tag) for angle, own in plies]
        return plies


def expand_layup(code: str) -> list[tuple[float, str | None]]:
    """Expand a stacking code into ``(angle_deg, material_tag or None)`` per ply, bottom first.

    >>> [a for a, _ in expand_layup("[±45/0]s")]
    [45.0, -45.0, 0.0, 0.0, -45.0, 45.0]
    >>> expand_layup("[0c/90_2g]")
    [(0.0, 'c'), (90.0, 'g'), (90.0, 'g')]

    Raises
    ------
    LayupSyntaxError
        With the position of the problem in the code.
    """
    return _LayupParser(code).parse()


def _resolve_tag(tag: str, names) -> str | None:
    """Material named by a layup tag: exact name, else unique beginning, else unique ignoring case."""
    names = list(names)
    if tag in names:
        return tag
    for candidates in ([n for n in names if n.startswith(tag)],
                       [n for n in names if n.lower() == tag.lower()],
                       [n for n in names if n.lower().startswith(tag.lower())]):
        if len(candidates) == 1:
            return candidates[0]
        if len(candidates) > 1:
            return None
    return None


# ----------------------------------------------------------------------------------------------
# sections


#: longest specimen or material name
MAX_NAME_CHARS = 200


def _check_name(r: _Reader, y: _Y, name: str, what: str) -> None:
    """A name used in result files and tables: some visible text, not '.' or '..'."""
    if not name.strip() or name.strip() in (".", "..") or len(name) > MAX_NAME_CHARS:
        raise r.error(y, f"{what} {name!r} is not usable: give 1 to {MAX_NAME_CHARS} "
                         "characters of text other than '.' and '..'")
    bad = non_printable(name)          # (a material's name is a key, not read by r.string)
    if bad is not None:
        raise r.error(y, f"{bad} in the {what} {name!r}; remove it")


def _check_file_name(path: str, name: str) -> None:
    """The specimen name taken from the file's name (no ``name:`` in it) held to the rule of
    :func:`_check_name` (errors.NON_PRINTABLE: a right-to-left override or an ESC in the
    file's name went into the tables, result files and reports unchecked)."""
    bad = non_printable(name)
    if bad is not None or not name.strip() or len(name) > MAX_NAME_CHARS:
        what = (f"{bad} in it" if bad is not None else
                f"not usable: give 1 to {MAX_NAME_CHARS} characters of text")
        raise SpecimenError(f"the specimen name {name!r}, taken from the file's name (the "
                            f"file has no 'name:'): {what}; give the specimen a 'name:' line, "
                            "or rename the file", path=path)


def _read_geometry(r: _Reader, y: _Y) -> tuple[float, float, float]:
    g = r.mapping(y, required=("a", "b", "h"))
    a, b, h = (r.positive(g[k], "length") for k in ("a", "b", "h"))
    if h >= min(a, b):
        raise r.error(g["h"], f"the thickness h = {h * 1e3:g} mm must be smaller than the sides "
                              f"a = {a * 1e3:g} mm and b = {b * 1e3:g} mm")
    return a, b, h


def _isotropic_values(r: _Reader, name: str, y: _Y) -> dict:
    """The six constants of an isotropic material written as ``{E: .., nu: ..}`` (``G``
    optional, default E / (2 (1 + nu))): E1 = E2 = E, G12 = G13 = G23 = G, nu12 = nu."""
    m = y.value
    orthotropic = [k for k in CONSTANT_NAMES if k in m]
    if orthotropic:
        raise r.error(m[orthotropic[0]], f"material '{name}' gives both the isotropic E, nu and "
                                         f"the ply constant {orthotropic[0]}: write E and nu "
                                         "(and G) for an isotropic material, or the six "
                                         f"{', '.join(CONSTANT_NAMES)}",
                      _join(y.field, orthotropic[0]))
    m = r.mapping(y, required=_ISOTROPIC_KEYS[:2], optional=_ISOTROPIC_KEYS[2:],
                  what=f"a mapping of the constants of material '{name}'",
                  elsewhere=_MATERIAL_ELSEWHERE)
    E = r.quantity(m["E"], "modulus")
    nu = r.quantity(m["nu"], "dimensionless")
    if not -1.0 < nu < 0.5:
        raise r.error(m["nu"], f"an isotropic material's Poisson ratio must lie between -1 and "
                               f"0.5, got {nu:g}")
    G = r.quantity(m["G"], "modulus") if "G" in m else E / (2 * (1 + nu))
    return {"E1": E, "E2": E, "G12": G, "G13": G, "G23": G, "nu12": nu}


def _odd_unit(m: dict) -> tuple[str, str, str] | None:
    """The one modulus of a material written in another unit than the four others, which
    share theirs (by its factor: GPa and kN/mm^2 are one unit): (key, its unit as written,
    the others' unit); None when there is no such one."""
    from laminid_cli.units import written_unit

    units = {k: written_unit(m[k].value, "modulus") for k in _MODULI}
    if any(u is None for u in units.values()):
        return None
    for key in _MODULI:
        others = {units[k][1] for k in _MODULI if k != key}
        if len(others) == 1 and units[key][1] not in others:
            other = next(units[k][0] for k in _MODULI if k != key)
            return key, units[key][0], other or "Pa (bare numbers)"
    return None


def _read_material(r: _Reader, name: str, y: _Y) -> Material:
    if isinstance(y.value, dict) and ("E" in y.value or "nu" in y.value):
        values = _isotropic_values(r, name, y)
        m = y.value
    else:
        m = r.mapping(y, required=CONSTANT_NAMES, optional=_MATERIAL_KEYS[len(CONSTANT_NAMES):],
                      what=f"a mapping of the constants of material '{name}'",
                      elsewhere=_MATERIAL_ELSEWHERE)
        values = {k: r.quantity(m[k], "modulus") for k in _MODULI}
        values["nu12"] = r.quantity(m["nu12"], "dimensionless")
    constants = ElasticConstants(**values)
    reasons = infeasibility_reasons(constants)
    if reasons:
        odd = None if "E" in m or "nu" in m else _odd_unit(m)
        if odd is not None:
            # E1: 117 MPa among moduli in GPa: the line of the value in the odd unit, and why
            key, unit, others = odd
            raise r.error(m[key], f"'{m[key].value}' is in {unit or 'Pa (a bare number)'} where "
                                  f"the material's other moduli are in {others}: a unit slip? "
                                  "With it the constants are not physically admissible (paper "
                                  "Eq. 22): " + "; ".join(reasons))
        raise r.error(y, "constants not physically admissible (paper Eq. 22): "
                         + "; ".join(reasons))
    density = r.positive(m["density"], "density") if "density" in m else None
    ratio = r.positive(m["density_ratio"], "dimensionless") if "density_ratio" in m else None
    if density is not None and ratio is not None:
        raise r.error(m["density_ratio"], "give either density or density_ratio, not both")
    fixed: tuple[str, ...] = ()
    if "fixed" in m:
        items = m["fixed"].value if isinstance(m["fixed"].value, list) else [m["fixed"]]
        names = []
        for item in items:
            text = r.string(item)
            if text not in CONSTANT_NAMES:
                guess = _closest(text, CONSTANT_NAMES)
                hint = f"; did you mean '{guess}'?" if guess else ""
                raise r.error(item, f"'{text}' is not a constant{hint} (constants: "
                                    f"{', '.join(CONSTANT_NAMES)})")
            if text not in names:
                names.append(text)
        fixed = tuple(names)
    prior: dict[str, float] = {}
    if "prior" in m:
        entries = r.mapping(m["prior"], optional=CONSTANT_NAMES)
        for key, item in entries.items():
            value = r.quantity(item, "dimensionless")
            if value < 0:
                raise r.error(item, f"a prior weight must not be negative, got {value:g}")
            prior[key] = value
    return Material(name=name, constants=constants, density=density, fixed=fixed, prior=prior,
                    density_ratio=ratio)


def _read_plies(r: _Reader, top: dict, root: _Y, h: float,
                materials: dict[str, Material]) -> tuple[Ply, ...]:
    names = list(materials)
    if ("layup" in top) == ("plies" in top):
        which = "both" if "layup" in top else "neither"
        raise r.error(root, f"give exactly one of 'layup' (a stacking code) and 'plies' (a list "
                            f"of plies); the file has {which}", "layup")
    own_thickness: list[float | None] = []
    raw: list[tuple[float, str | None, _Y]] = []   # angle, tag, where
    bare: list[bool] = []        # each angle written without a unit
    angle_at: list[_Y] = []      # where each angle is written
    if "layup" in top:
        y = top["layup"]
        if isinstance(y.value, list):   # layup: [0, 90, 90, 0] or an unquoted [0/90]
            code = "[" + "/".join(r.string(item) for item in y.value) + "]"
        else:
            code = r.string(y)
        code = normalize_text(code)   # full-width digits, slashes, brackets; '−45' (U+2212)
        try:
            expanded = expand_layup(code)
        except LayupSyntaxError as exc:
            raise r.error(y, str(exc)) from exc
        raw = [(angle, tag, y) for angle, tag in expanded]
        own_thickness = [None] * len(raw)
        # a code that marks any angle in degrees ("45deg", "45°") states the unit
        bare = [not re.search(r"deg|°", code)] * len(raw)
        angle_at = [y] * len(raw)
    else:
        y = top["plies"]
        items = r.sequence(y, "a list of plies ({angle: 45, material: ..., thickness: ...})")
        if not items:
            raise r.error(y, "the list of plies is empty")
        if len(items) > MAX_PLIES:
            raise r.error(y, f"more than {MAX_PLIES} plies")
        for item in items:
            p = r.mapping(item, required=("angle",), optional=("material", "thickness"),
                          what="a ply mapping {angle: ..., material: ..., thickness: ...}")
            angle = r.quantity(p["angle"], "angle")
            if abs(angle) > 360:
                raise r.error(p["angle"], f"ply angle {angle:g} deg is outside -360..360")
            written = p["angle"].value
            bare.append(not isinstance(written, str) or not re.search(r"[A-Za-z°]", written))
            angle_at.append(p["angle"])
            tag = r.string(p["material"]) if "material" in p else None
            raw.append((angle, tag, p.get("material", item)))
            own_thickness.append(r.positive(p["thickness"], "length") if "thickness" in p
                                 else None)

    _check_radian_angles(r, top, [angle for angle, _, _ in raw], angle_at, bare)

    # materials of the plies
    ply_materials = []
    for k, (angle, tag, y) in enumerate(raw):
        if tag is None:
            if len(names) > 1:
                raise r.error(y, f"ply {k + 1} ({angle:g} deg) has no material and the specimen "
                                 f"has several ({', '.join(names)}); tag it, e.g. "
                                 f"{angle:g}:{names[0]}")
            ply_materials.append(names[0])
            continue
        found = _resolve_tag(tag, names)
        if found is None:
            guess = _closest(tag, names)
            hint = f"; did you mean '{guess}'?" if guess else ""
            raise r.error(y, f"ply {k + 1} uses material '{tag}', which is not one (or not an "
                             f"unambiguous beginning of one) of the materials "
                             f"({', '.join(names)}){hint}")
        ply_materials.append(found)
    unused = [n for n in names if n not in ply_materials]
    if unused:
        raise r.error(top["materials"].value[unused[0]],
                      f"material '{unused[0]}' is defined but no ply uses it")

    thickness = _ply_thicknesses(r, top, root, h, ply_materials, own_thickness, names)
    return tuple(Ply(material=m, angle_deg=float(angle), thickness=float(t))
                 for (angle, _, _), m, t in zip(raw, ply_materials, thickness))


#: words of a specimen's name, description or comments that say its laminate is unsymmetric
#: on purpose (no warning of a forgotten 's' then): unsymmetric, asymmetric, non-symmetric,
#: antisymmetric, (bending-extension) coupled / coupling
UNSYMMETRIC_WORDS = re.compile(r"un-?sym|asym|non-?sym|anti-?sym|coupl", re.IGNORECASE)


def _comments(text: str) -> list[str]:
    """The YAML comments of ``text`` (a '#' at a line's start or after a blank, to its end;
    one inside a quoted string is taken too: these are only searched for words)."""
    return re.findall(r"(?:^|\s)#(.*)$", text, re.MULTILINE)


def _mirrored(a: Ply, b: Ply) -> bool:
    """Whether plies ``a`` and ``b`` are each other's mirror about the mid-plane: the same
    material and thickness, angles equal modulo 180 degrees."""
    turn = (a.angle_deg - b.angle_deg) % 180.0
    return (a.material == b.material and min(turn, 180.0 - turn) < 1e-9
            and abs(a.thickness - b.thickness) <= 1e-9 * max(a.thickness, b.thickness))


def _warn_unsymmetric(r: _Reader, top: dict, plies, words: str) -> None:
    """A warning (not an error: an unsymmetric laminate is a laminate, modelled whole, its
    bending and extension coupled) where the plies are not symmetric about the mid-plane and
    the specimen's name, description and comments (``words``) do not say so on purpose
    (:data:`UNSYMMETRIC_WORDS`): a code whose 's' was forgotten, "[45_3/0_3/-45_3/90_3]" for
    "[45_3/0_3/-45_3/90_3]s", gave 12 plies sharing h, twice as thick each, silently."""
    n = len(plies)
    if all(_mirrored(plies[k], plies[n - 1 - k]) for k in range(n // 2)) \
            or UNSYMMETRIC_WORDS.search(words):
        return
    key = "layup" if "layup" in top else "plies"
    t = sorted(p.thickness * 1e3 for p in plies)
    each = (f"{t[0]:.4f} mm" if t[-1] - t[0] <= 1e-9 * t[-1] else
            f"{t[0]:.4f} to {t[-1]:.4f} mm")
    fix = ("end the code with 's'" if key == "layup" else
           "list the plies of both halves")
    r.warn(f"{r.path}:{top[key].line}, field '{key}': {n} plies of {each}: unsymmetric; "
           f"bending-extension coupled; if a symmetric laminate was meant, {fix} "
           "('unsymmetric' in its description leaves this warning out)")


#: ply angles written without a unit that are all, to this (rad), non-zero multiples of pi/12
#: (15 deg) within +-pi/2 are radians, and refused: 0.785 is pi/4 to 4e-4 (3 decimals),
#: 1.57 pi/2 to 8e-4 (2 decimals). No laminate is laid up at 0.785 degrees, and no multiple
#: of pi/12 up to pi/2 is within 0.01 of a whole number, so a layup in degrees never meets it;
#: a looser match (0.79, 0.8) is only warned of
RADIAN_ANGLE_TOL = 1e-3


def _check_radian_angles(r: _Reader, top: dict, angles: list[float], where: list[_Y],
                         bare: list[bool]) -> None:
    """Refuse ply angles that are radians read as degrees (``[0/0.785/-0.785/1.571]``,
    which gave a plate of nearly parallel plies without complaint): every non-zero angle
    written without a unit, a non-zero multiple of pi/12 to :data:`RADIAN_ANGLE_TOL` within
    +-pi/2 (none then a whole degree). Warn (:meth:`_Reader.warn`) where every non-zero angle
    is a fraction within +-2 pi but not that plainly radians (0.8, 1.5, or a unit given)."""
    turned = [(a, y, b) for a, y, b in zip(angles, where, bare) if a != 0]
    if not turned or any(abs(a) > 2 * math.pi or a == round(a) for a, _, _ in turned):
        return
    key = "layup" if "layup" in top else "plies"
    values = list(dict.fromkeys(a for a, _, _ in turned))
    shown = ", ".join(f"{a:g}" for a in values)
    step = math.pi / 12
    k = {a: round(a / step) for a in values}
    if all(b for _, _, b in turned) and all(
            0 < abs(k[a]) <= 6 and abs(a - k[a] * step) <= RADIAN_ANGLE_TOL for a in values):
        y = turned[0][1]
        writes = ", ".join(f"{15 * k[a]} for {a:g} rad" for a in values)
        raise r.error(y, f"the ply angles {shown} are radians, not degrees (each a multiple of "
                         f"pi/12 = 15 deg to {RADIAN_ANGLE_TOL:g}, within +-pi/2, none a whole "
                         "degree): read as degrees they make a plate of nearly parallel plies; "
                         f"laminid reads ply angles in degrees: write {writes}",
                      key if key == "layup" else y.field)
    y = turned[0][1]
    r.warn(f"{r.path}:{y.line}, field '{key if key == 'layup' else y.field}': the ply angles "
           f"{shown} look like radians; laminid reads ply angles in degrees (write "
           + ", ".join(f"{a * 180 / math.pi:.4g}" for a in values) + ")")


def _h_node(top: dict) -> _Y:
    """Where the file writes h (geometry.h), for an error about h; the geometry block where
    it is not a mapping with h."""
    g = top["geometry"].value
    return g["h"] if isinstance(g, dict) and "h" in g else top["geometry"]


def _ply_thicknesses(r: _Reader, top: dict, root: _Y, h: float, ply_materials: list[str],
                     own: list[float | None], names: list[str]) -> np.ndarray:
    n = len(ply_materials)
    scale = r.boolean(top["scale_thickness"]) if "scale_thickness" in top else False
    nominal: dict[str, float] | None = None
    if "ply_thickness" in top:
        y = top["ply_thickness"]
        if isinstance(y.value, dict):
            entries = r.mapping(y, optional=names)
            nominal = {k: r.positive(v, "length") for k, v in entries.items()}
        else:
            value = r.positive(y, "length")
            nominal = {name: value for name in names}
    given = [t is not None for t in own]
    if all(given) or nominal is not None:
        t = []
        for k, (tk, m) in enumerate(zip(own, ply_materials)):
            if tk is None:
                if m not in nominal:
                    raise r.error(top["ply_thickness"], f"no thickness for material '{m}' "
                                  f"(ply {k + 1})", f"ply_thickness.{m}")
                tk = nominal[m]
            t.append(tk)
        t = np.array(t)
    elif any(given):
        raise r.error(top["plies"], "give a thickness for every ply or for none (then the plies "
                                    "share h equally, or use ply_thickness)")
    else:
        if scale:
            log.debug("scale_thickness without ply thicknesses: plies share h equally")
        return np.full(n, h / n)
    total = float(t.sum())
    if n > 1 and np.all(np.abs(t - h) <= THICKNESS_TOLERANCE * h):
        # every ply as thick as the plate: h is one ply's thickness, not the laminate's
        # (the advice to scale the plies to h, or to fix them, was the wrong way round)
        node = _h_node(top)
        given = "ply_thickness" if "ply_thickness" in top else "the plies' thickness"
        raise r.error(node, f"h = {h * 1e3:.4g} mm is one ply's thickness ({given} "
                            f"{t[0] * 1e3:.4g} mm): h is the whole laminate's, {n} plies of "
                            f"{t[0] * 1e3:.4g} mm are {total * 1e3:.4g} mm; give that h, or "
                            f"each ply's own thickness ({h / n * 1e3:.4g} mm for {n} plies "
                            f"sharing {h * 1e3:.4g} mm)", "geometry.h")
    if scale:
        if not 1 / MAX_THICKNESS_SCALE <= h / total <= MAX_THICKNESS_SCALE:
            where = top.get("ply_thickness", top.get("plies", root))
            raise r.error(where, f"the ply thicknesses add up to {total * 1e3:.4g} mm, which "
                                 f"contradicts h = {h * 1e3:.4g} mm: scale_thickness would "
                                 f"scale them by {h / total:.3g} (at most "
                                 f"{MAX_THICKNESS_SCALE:g} or 1/{MAX_THICKNESS_SCALE:g}); check "
                                 "the thicknesses, their unit and h")
        return t * (h / total)
    if abs(total - h) > THICKNESS_TOLERANCE * h:
        where = top.get("ply_thickness", top.get("plies", root))
        raise r.error(where, f"the ply thicknesses add up to {total * 1e3:.4g} mm but h = "
                             f"{h * 1e3:.4g} mm (tolerance {THICKNESS_TOLERANCE:.1%} of h); fix "
                             "them or set scale_thickness: true to scale them to h")
    return t * (h / total)   # remove the small rounding difference so the plies fill h


def _resolve_densities(r: _Reader, top: dict, root: _Y, a: float, b: float, h: float,
                       mass: float | None, materials: dict[str, Material],
                       plies: tuple[Ply, ...]) -> dict[str, float]:
    absolute = {n: m.density for n, m in materials.items() if m.density is not None}
    ratios = {n: m.density_ratio for n, m in materials.items() if m.density_ratio is not None}
    missing = [n for n in materials if n not in absolute and n not in ratios]
    if "scale_density_to_mass" in top:
        scale = r.boolean(top["scale_density_to_mass"])
    else:
        scale = len(absolute) < len(materials)
    if len(materials) == 1 and missing:
        if mass is None:
            raise r.error(root, "no density for the material and no mass to compute it from; "
                                "give mass (kg) or materials.<name>.density", "mass")
        (name,) = materials
        return {name: mass / (a * b * h)}
    nodes = top["materials"].value
    if missing:
        raise r.error(nodes[missing[0]], f"material '{missing[0]}' has no density: a specimen "
                      "with several materials needs a density or a density_ratio for each",
                      f"materials.{missing[0]}.density")
    if not scale:
        if ratios:
            name = next(iter(ratios))
            raise r.error(nodes[name].value["density_ratio"], "density_ratio gives relative "
                          "densities only; set scale_density_to_mass: true and give the mass, "
                          "or give densities")
        return dict(absolute)
    if mass is None:
        raise r.error(root, "scaling the densities to the mass needs the mass", "mass")
    relative = {n: absolute.get(n, ratios.get(n)) for n in materials}
    per_area = sum(relative[p.material] * p.thickness for p in plies)
    factor = mass / (a * b * per_area)
    if absolute and ratios:
        log.info("%s: densities and density ratios mixed; all are scaled as relative values",
                 r.path)
    return {n: relative[n] * factor for n in materials}


#: kg/m^3: the densities of fibre-reinforced plies (carbon/epoxy ~1550-1600, glass/epoxy
#: ~1900-2100, aramid ~1350) with room for the odd resin or core
PLY_DENSITY = (1000.0, 2600.0)


#: kg/m^3: no fibre-reinforced ply is denser than this. A ply cannot outweigh its fibre with
#: its lighter resin: the densest reinforcements are E-glass (2580), boron (2570) and basalt
#: (2700), so a glass/epoxy ply is at most ~2200; 2800 also clears the rare metal-matrix plies
#: whose shear modulus is as low as a fibre composite's (boron/aluminium, 2650)
FIBRE_PLY_DENSITY_MAX = 2800.0
#: a material whose G12 is at most this fraction of its larger Young's modulus is taken for a
#: fibre composite: carbon/epoxy 0.03, glass/epoxy 0.1, woven fabrics 0.07-0.2; a metal or any
#: isotropic solid is E/(2 (1 + nu)), 0.37-0.39 of E (and metal-matrix plies about 0.2-0.3)
FIBRE_SHEAR_RATIO = 0.2


def _fibre_composite(m: Material) -> bool:
    """Whether a material's constants are a fibre composite's (:data:`FIBRE_SHEAR_RATIO`)."""
    c = m.constants
    return c.G12 <= FIBRE_SHEAR_RATIO * max(c.E1, c.E2)


def _check_derived_densities(r: _Reader, top: dict, root: _Y, densities: dict,
                             materials: dict[str, Material], h: float | None = None,
                             n_plies: int = 0) -> None:
    """A density computed from the mass (not written in the file, where the unit check has
    seen it already) must be plausible too (units.PLAUSIBLE): a mass or a dimension in the
    wrong unit shows there. One n_plies times too high, a fibre ply's (PLY_DENSITY) once
    divided by them, is h written as one ply's thickness: said so, on h's line; so is one
    plausible for a solid but above :data:`FIBRE_PLY_DENSITY_MAX` for a material whose
    constants are a fibre composite's (4 carbon plies with h = 0.25 mm, one ply's: 6667
    kg/m^3, passed), unless a decimal slip explains it as well. Such a density that n_plies
    does not explain alone is warned of, with the slips that would."""
    from laminid_cli.units import PLAUSIBLE

    low, high = PLAUSIBLE["density"]

    def ply_like(value: float) -> bool:
        return PLY_DENSITY[0] <= value <= PLY_DENSITY[1]

    for name, rho in densities.items():
        if materials[name].density == rho:
            continue
        fibre_too_dense = _fibre_composite(materials[name]) and rho > FIBRE_PLY_DENSITY_MAX
        if low <= rho <= high and not fibre_too_dense:
            continue
        one_ply = h is not None and n_plies > 1 and ply_like(rho / n_plies)
        # a decimal slip (mass 10 times too large, h 10 times too small) explains a density
        # that is no solid's as well: then the data do not tell which, and only a density
        # beyond any solid's is refused (identify then refuses a start that far off, with
        # its cause); S2.1's 14 glass plies with 2.571 kg for 0.2571 kg: 16460 kg/m^3
        tenfold = n_plies != 10 and ply_like(rho / 10)
        if one_ply and (rho > high or not tenfold):
            raise r.error(_h_node(top), f"h = {h * 1e3:.4g} mm looks like one ply's "
                          f"thickness: h is the whole laminate's ({n_plies} plies of "
                          f"{h * 1e3:.4g} mm are {n_plies * h * 1e3:.4g} mm; with this h the "
                          f"mass gives '{name}' a density of {rho:.4g} kg/m^3)", "geometry.h")
        node = top.get("mass", root)
        if low <= rho <= high:
            c = materials[name].constants
            slips = []
            if tenfold:
                slips.append(f"a mass 10 times too large or h 10 times too small "
                             f"({rho / 10:.4g} kg/m^3)")
            if one_ply:
                slips.append(f"h one ply's thickness ({n_plies} plies of {h * 1e3:.4g} mm: "
                             f"{rho / n_plies:.4g} kg/m^3)")
            likely = f"; {' or '.join(slips)}?" if slips else ""
            r.warn(f"{r.path}:{node.line}, field 'mass': the mass gives material '{name}' a "
                   f"density of {rho:.4g} kg/m^3, denser than any fibre-reinforced ply (at "
                   f"most {FIBRE_PLY_DENSITY_MAX:g} kg/m^3; carbon/epoxy ~1550-1600, "
                   f"glass/epoxy ~1900-2100), which its constants are (G12 {c.G12 / 1e9:.3g} "
                   f"GPa, {c.G12 / max(c.E1, c.E2):.2g} of E1): check the mass, a, b and h "
                   f"(h is the whole laminate's thickness){likely}")
            continue
        raise r.error(node, f"the mass gives material '{name}' a density of {rho:.4g} kg/m^3, "
                            f"not a plausible one ({low:g} to {high:g} kg/m^3): check the units "
                            "of mass, a, b, h and the ply thicknesses", "mass")


#: the longest ``measured.sigma_source`` / ``damping_sigma_source`` (characters): fit-frf
#: --into writes a file name and a line of the rule (a few hundred); each is printed by
#: identify and show and set on the report's pages, where 10 kB collapsed the damping page's
#: table (matplotlib: "axes sizes collapsed to zero")
MAX_SOURCE_CHARS = 1000


def _source_text(r: _Reader, y: _Y) -> str:
    """A ``sigma_source`` or ``damping_sigma_source``: text on one line (line breaks of a
    YAML block or a quoted "\\n" read as spaces), refused where longer than
    :data:`MAX_SOURCE_CHARS` or holding a control character a quoted YAML escape can make
    ("\\e[31m", which the check of the raw text cannot see)."""
    text = " ".join(r.string(y).split())      # (r.string refuses a control character)
    if len(text) > MAX_SOURCE_CHARS:
        raise r.error(y, f"{len(text)} characters, more than {MAX_SOURCE_CHARS}: a line "
                         "saying how the standard deviations were made is expected")
    return text


def _read_measured(r: _Reader, y: _Y) -> Measured:
    m = r.mapping(y, optional=("frequencies", "weights", "sigma", "sigma_source", "frf_file",
                               "bands", "modes", "damping", "damping_sigma",
                               "damping_sigma_source"))
    if "frf_file" in m:
        if "frequencies" in m or "sigma" in m or "sigma_source" in m:
            raise r.error(m["frf_file"], "give either 'frequencies' (and 'sigma') or "
                                         "'frf_file', not both")
        for key in ("damping", "damping_sigma", "damping_sigma_source"):
            if key in m:
                raise r.error(m[key], f"'{key}' comes from the fit of 'frf_file'; give either "
                                      "the FRF file or the damping ratios, not both")
        return _measured_from_frf(r, m)
    if "damping_sigma" in m and "damping" not in m:
        raise r.error(m["damping_sigma"], "'damping_sigma' without 'damping' (the damping "
                                          "ratios it belongs to)")
    for key in ("bands", "modes"):
        if key in m:
            raise r.error(m[key], f"'{key}' applies only with 'frf_file'")
    if "frequencies" not in m:
        raise r.error(y, "missing key 'frequencies' (a list in Hz, null where not detected) "
                         "or 'frf_file' (an FRF file to fit)")
    items = r.sequence(m["frequencies"], "a list of frequencies in Hz (null where not detected)")
    if not items:
        raise r.error(m["frequencies"], "the list of frequencies is empty: give the measured "
                      "frequencies in Hz, or leave out measured: to compute the model alone "
                      "(laminid modes), before the plate is measured")
    freq = np.full(len(items), np.nan)
    previous = None
    for k, item in enumerate(items):
        if item.value is None:
            continue
        value = r.quantity(item, "frequency")
        if value <= 0:
            raise r.error(item, f"a natural frequency must be positive, got {item.value!r}")
        if previous is not None and value <= freq[previous]:
            raise r.error(item, f"frequencies must increase: mode {k + 1} ({value:g} Hz) is not "
                                f"above mode {previous + 1} ({freq[previous]:g} Hz)")
        freq[k] = value
        previous = k
    if previous is None:
        raise r.error(m["frequencies"], "every frequency is null; at least one is needed")
    n = len(items)
    weight = np.ones(n)
    if "weights" in m:
        w_items = r.sequence(m["weights"], "a list of weights in [0, 1]")
        if len(w_items) != n:
            raise r.error(m["weights"], f"{len(w_items)} weights for {n} frequencies; give one "
                                        "per frequency")
        for k, item in enumerate(w_items):
            value = r.quantity(item, "dimensionless")
            if not 0.0 <= value <= 1.0:
                raise r.error(item, f"a weight must be in [0, 1], got {value:g}")
            weight[k] = value
    weight[np.isnan(freq)] = 0.0
    sigma = None
    if "sigma" in m:
        # one relative sigma for every mode (the 0.2 % the README and the output speak of) is
        # the command line's, not the file's: said where it was written here (sigma: 0.2 %,
        # or a list of them, was "expected a list ...", "unknown unit '%'")
        relative = ("a relative sigma for every mode is identify's and batch's --sigma-rel "
                    "(0.002 or 0.2%), used where the file gives none")
        if not isinstance(m["sigma"].value, list):
            raise r.error(m["sigma"], "expected a list of standard deviations in Hz, one per "
                                      f"frequency ([a, b, ...]), got "
                                      f"{_describe(m['sigma'].value)}; {relative}")
        s_items = r.sequence(m["sigma"], "a list of standard deviations in Hz")
        if len(s_items) != n:
            raise r.error(m["sigma"], f"{len(s_items)} sigma values for {n} frequencies; give "
                                      "one per frequency (null where unknown)")
        sigma = np.full(n, np.nan)
        for k, item in enumerate(s_items):
            if item.value is None:
                continue
            if isinstance(item.value, str) and item.value.strip().endswith("%"):
                raise r.error(item, f"'{item.value}' is relative; measured.sigma is in Hz "
                                    f"(0.25 Hz); {relative}")
            value = r.quantity(item, "frequency")
            if value <= 0:
                raise r.error(item, f"a standard deviation must be positive, got {item.value!r}")
            sigma[k] = value
        sigma[np.isnan(freq)] = np.nan
    source = ""
    if "sigma_source" in m:
        if sigma is None:
            raise r.error(m["sigma_source"], "'sigma_source' describes 'sigma', which is missing")
        source = _source_text(r, m["sigma_source"])
    damping = _damping_list(r, m, "damping", n, "damping ratios") if "damping" in m else None
    damping_sigma = (_damping_list(r, m, "damping_sigma", n, "standard deviations of the damping "
                                   "ratios") if "damping_sigma" in m else None)
    damping_source = ""
    if "damping_sigma_source" in m:
        if damping_sigma is None:
            raise r.error(m["damping_sigma_source"], "'damping_sigma_source' describes "
                                                     "'damping_sigma', which is missing")
        damping_source = _source_text(r, m["damping_sigma_source"])
    if damping is not None:
        damping[np.isnan(freq)] = np.nan
        if damping_sigma is not None:
            damping_sigma[np.isnan(damping)] = np.nan
        if not np.isfinite(damping).any():
            raise r.error(m["damping"], "every damping ratio is null (or its frequency is)")
        if damping_sigma is not None:
            with np.errstate(invalid="ignore"):
                tiny = np.flatnonzero(damping_sigma < DAMPING_SIGMA_REL_MIN * damping)
            if tiny.size:
                # 1e-250 of each ratio was taken: the loss factors' chi2 overflowed to inf,
                # with numpy's RuntimeWarnings on the terminal
                i = int(tiny[0])
                raise r.error(m["damping_sigma"], f"mode {i + 1}'s {damping_sigma[i]:.3g} is "
                              f"below {DAMPING_SIGMA_REL_MIN:g} of its damping ratio "
                              f"{damping[i]:.3g}: no damping estimate is that exact (half-power "
                              "or RFP ratios are known to a few %); give the standard deviation "
                              f"of the ratio (5 % of it: {0.05 * damping[i]:.2g})")
            warn_loose_damping_sigma(r, f"measured.damping_sigma (line "
                                     f"{m['damping_sigma'].line})", freq, damping, damping_sigma)
        given = damping[np.isfinite(damping)]
        if given.size >= 2 and given.min() >= DAMPING_PERCENT_SUSPECT:
            # a free composite plate's modes damp at 0.1-2 %: 10 % and more on every mode is
            # the percentage written as a plain number
            r.warn(f"{r.path}: measured.damping (line {m['damping'].line}): every damping "
                   f"ratio is {100 * DAMPING_PERCENT_SUSPECT:.0f} % or more (zeta "
                   f"{given.min():g} ... {given.max():g}); a plain number is the ratio itself "
                   f"(0.004 = 0.4 %): if these are percent, write '{given.min():g} %'")
    for array in (freq, weight, sigma, damping, damping_sigma):
        if array is not None:
            array.flags.writeable = False
    return Measured(freq=freq, weight=weight, sigma=sigma, damping=damping,
                    damping_sigma=damping_sigma, sigma_source=source,
                    damping_sigma_source=damping_source)


#: damping ratios all at least this large are suspected of being percentages written as plain
#: numbers (a warning)
DAMPING_PERCENT_SUSPECT = 0.1


#: a damping ratio whose standard deviation exceeds this multiple of the ratio is warned of:
#: at sigma > zeta the +-1 sd range of zeta already reaches 0 (no damping), i.e. the measurement
#: does not tell the ratio from zero -- the ratio is not measured at all. The fit weighs the mode
#: by 1/sigma^2, so it hardly counts; far more often the sigma is a slip (a percentage written
#: as a plain number, 0.3 for 0.3 %, or the list shifted by a mode). An RFP fit's spread is at
#: least 2 % of the ratio and typically 5-30 %: 1 leaves honest measurements alone.
DAMPING_SIGMA_SUSPECT = 1.0


def warn_loose_damping_sigma(r: "_Reader", where: str, freq, zeta, sigma) -> list[int]:
    """Warn (through the reader ``r``: logged unless it was made not to, kept for
    :attr:`Specimen.warnings`; not an error) of the modes whose damping ratio's standard
    deviation is larger than :data:`DAMPING_SIGMA_SUSPECT` times the ratio; returns their
    0-based indices. ``where``: the field (and line) the sigmas came from."""
    zeta, sigma = np.asarray(zeta, float), np.asarray(sigma, float)
    with np.errstate(invalid="ignore"):
        loose = np.flatnonzero(np.isfinite(zeta) & np.isfinite(sigma)
                               & (sigma > DAMPING_SIGMA_SUSPECT * zeta))
    if loose.size:
        modes = "; ".join(f"mode {k + 1} ({freq[k]:g} Hz): sigma {sigma[k]:g} > zeta {zeta[k]:g}"
                          for k in loose)
        r.warn(f"{r.path}: {where}: the standard deviation of a damping ratio is larger than "
               f"the ratio itself ({modes}): such a ratio is not measured at all (its +-1 sd "
               "range reaches 0) and the fit gives it almost no weight; check the value (a "
               f"percentage written as a plain number? write '{sigma[loose[0]]:g} %')")
    return [int(k) for k in loose]


#: the smallest standard deviation of a damping ratio taken, relative to the ratio
#: (measured.damping_sigma): far below what any damping estimate resolves, above round-off
DAMPING_SIGMA_REL_MIN = 1e-6


def _damping_list(r: _Reader, m: dict, key: str, n: int, what: str) -> np.ndarray:
    """``measured.damping`` / ``damping_sigma``: one dimensionless ratio per frequency (a plain
    number or a percentage "0.4 %"), null where not measured; each in (0, 0.5)."""
    items = r.sequence(m[key], f"a list of {what} (plain numbers or '0.4 %', null where none)")
    if len(items) != n:
        raise r.error(m[key], f"{len(items)} {what} for {n} frequencies; give one per "
                              "frequency (null where not measured)")
    out = np.full(n, np.nan)
    for k, item in enumerate(items):
        if item.value is None:
            continue
        if isinstance(item.value, (dict, list)):
            r.quantity(item, "dimensionless")          # refused: "expected a single ..."
        value = parse_fraction(item.value, where=r.where(item))
        if not 0 < value < 0.5:
            what_one = ("a standard deviation of a damping ratio" if key == "damping_sigma"
                        else "a damping ratio (viscous, zeta = eta / 2)")
            raise r.error(item, f"{what_one} must be between 0 and 0.5, got {item.value!r}; "
                                "write 0.004 or '0.4 %'")
        out[k] = value
    return out


def _measured_from_frf(r: _Reader, m: dict) -> Measured:
    """``measured.frf_file``: natural frequencies and their sigmas from an RFP fit of the FRFs.

    The file path is relative to the specimen file's folder; optional ``bands`` (list of
    "LO:HI" in Hz) and ``modes`` (the n lowest) are passed to the fitter, ``weights`` apply
    to the fitted modes in order.
    """
    from laminid_cli.errors import FrfError
    from laminid_cli.frf.rfp import DEFAULT_SIGMA_REL, measured_from_frf_file

    name = r.string(m["frf_file"])
    base = Path(r.path).parent if r.path and not str(r.path).startswith("<") else Path.cwd()
    path = base / name
    if not path.exists():
        raise r.error(m["frf_file"], f"FRF file {path} not found")
    bands = None
    if "bands" in m:
        bands = []
        for item in r.sequence(m["bands"], 'a list of bands "LO:HI" in Hz'):
            text = str(item.value)
            try:
                lo, hi = (float(v) for v in text.split(":"))
            except ValueError:
                raise r.error(item, f"band {text!r} not understood; write LO:HI in Hz, e.g. "
                                    "100:1400") from None
            if not 0 <= lo < hi:
                raise r.error(item, f"band {text!r} is empty; need 0 <= LO < HI")
            bands.append((lo, hi))
    n_modes = None
    if "modes" in m:
        n_modes = int(r.quantity(m["modes"], "dimensionless"))
        if n_modes < 1:
            raise r.error(m["modes"], "the number of modes must be at least 1")
    found: list[str] = []
    rule: list[str] = []
    try:
        freq, sigma, damping, damping_sigma = measured_from_frf_file(
            path, bands=bands, n_modes=n_modes, with_damping_sigma=True, warnings=found,
            damping_sigma_rule=rule)
    except FrfError as exc:
        raise r.error(m["frf_file"], f"fitting {path}: {exc}") from exc
    for warning in found:          # the FRF file's own (a frequency unit not stated)
        r.warn(f"{r.path}:{m['frf_file'].line}, field 'measured.frf_file': {warning}")
    freq = np.asarray(freq, float)
    weight = np.ones(freq.size)
    if "weights" in m:
        w_items = r.sequence(m["weights"], "a list of weights in [0, 1]")
        if len(w_items) != freq.size:
            raise r.error(m["weights"], f"{len(w_items)} weights for the {freq.size} modes "
                                        f"fitted in {name}")
        for k, item in enumerate(w_items):
            value = r.quantity(item, "dimensionless")
            if not 0.0 <= value <= 1.0:
                raise r.error(item, f"a weight must be in [0, 1], got {value:g}")
            weight[k] = value
    sigma = np.asarray(sigma, float)
    damping = np.asarray(damping, float)
    damping_sigma = np.asarray(damping_sigma, float)
    warn_loose_damping_sigma(r, f"the damping of the fit of {name}", freq, damping,
                             damping_sigma)
    for array in (freq, weight, sigma, damping, damping_sigma):
        array.flags.writeable = False
    return Measured(freq=freq, weight=weight, sigma=sigma, damping=damping,
                    damping_sigma=damping_sigma, frf_file=name,
                    damping_sigma_source=rule[0] if rule else "",
                    sigma_source="sqrt(RFP spread^2 + resolution^2 + window^2), at least "
                                 f"{100 * DEFAULT_SIGMA_REL:g} % of f")


#: "value ± half-width" in a reference ("170 ± 1 GPa"; "+/-" and "+-" for keyboards without ±)
_PLUS_MINUS = re.compile(r"\s*(?:±|\+/-|\+-)\s*")
_LEADING_NUMBER = re.compile(r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def plus_minus(text: str, kind: str, where=None) -> tuple[float, float]:
    """``(value, half-width)`` in SI of a reference written "value ± half-width": the unit
    written once at the end applies to both ("170 ± 1 GPa", as tables print it), or written
    on both ("170 GPa ± 1 GPa"); a half-width in per cent of the value ("170 GPa ± 2 %").
    ValueError where it is not of that form; a SpecimenError (at ``where``, a units.Where)
    where a part cannot be read as a quantity of ``kind``. The
    specimen reader and the result files' reader (resultfile.parse_reference) both read it.

    >>> plus_minus("170 ± 1 GPa", "modulus"), plus_minus("0.3 +/- 10 %", "dimensionless")
    ((170000000000.0, 1000000000.0), (0.3, 0.03))
    """
    text = str(text)
    # a word processor's minus ('170 ± −1 GPa', U+2212) is a minus, as in every quantity: it
    # was "no half-width after ±" where the half-width is there, negative
    parts = _PLUS_MINUS.split(normalize_text(text))
    if len(parts) != 2 or not parts[0].strip() or not parts[1].strip():
        raise ValueError(f"'{text}': write a value and its half-width as '170 ± 1 GPa' "
                         "(or [low, high])")
    centre, half = (p.strip() for p in parts)
    if _LEADING_NUMBER.match(half) is None:
        word = half.split()[0]
        if word.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            # '170 ± nan GPa' (a spreadsheet's empty cell) was "no half-width after ±"
            raise ValueError(f"'{text}': the half-width '{word}' is not a finite number; write "
                             "a value and its half-width as '170 ± 1 GPa' (or [low, high])")
        # '170 ± GPa': the half-width left out (the unit alone was read as the centre's)
        raise ValueError(f"'{text}': no half-width after ±; write a value and its half-width "
                         "as '170 ± 1 GPa' (or [low, high])")
    if half.endswith("%"):
        value = parse_quantity(centre, kind, where=where)
        share = parse_quantity(half[:-1].strip(), "dimensionless", where=where)
        if share > 100:
            # '0.35 ± 200 %' was read as -0.35 .. 1.05 (a modulus' was refused as reaching
            # below 0, a Poisson's ratio's kept): more than the value itself is a typo
            raise ValueError(f"'{text}': a half-width of {share:g} % is more than the value "
                             "itself; write the range as [low, high] if that is meant")
        width = abs(value) * share / 100.0
    else:
        number = _LEADING_NUMBER.match(centre)
        if number is not None and number.end() == len(centre):
            # the centre's unit is the half-width's ('170 ± 1 GPa')
            lead = _LEADING_NUMBER.match(half)
            centre = centre + (half[lead.end():] if lead is not None else "")
        value = parse_quantity(centre, kind, where=where)
        width = parse_quantity(half, kind, where=where)
    if width < 0:
        raise ValueError(f"'{text}': the half-width after ± must not be negative")
    return value, width


def _plus_minus(r: _Reader, y: _Y, kind: str) -> tuple[float, float]:
    """:func:`plus_minus` of a reference's YAML node, its errors the reader's."""
    try:
        return plus_minus(str(y.value), kind, where=r.where(y))
    except ValueError as exc:                 # not "value ± half-width"
        raise r.error(y, str(exc)) from None


def _reference_value(r: _Reader, y: _Y, kind: str) -> float | tuple[float, float]:
    """A reference value, or ``(low, high)`` for a range ``[low, high]`` or "value ±
    half-width" (kept as a range: its midpoint is no value anyone measured; a half-width read
    as the range the source gives, whatever its confidence)."""
    if isinstance(y.value, str) and _PLUS_MINUS.search(y.value):
        value, half = _plus_minus(r, y, kind)
        low, high, one = value - half, value + half, half == 0
        below = (f"'{y.value}' reaches down to {low / 1e9:.4g} GPa: a reference modulus must "
                 "be positive")
    elif isinstance(y.value, list):
        if len(y.value) != 2:
            raise r.error(y, "a range is written [low, high]")
        low, high = (r.quantity(item, kind) for item in y.value)
        # the ends as written ('170 GPa'), not in Pa (1.7e+11)
        ends = [item.value for item in y.value]
        if low > high:
            raise r.error(y, f"range [{ends[0]}, {ends[1]}] has low > high: write [low, high]")
        one = low == high
        below = f"a reference modulus must be positive, got {ends[0]!r}"
    else:
        low = high = r.quantity(y, kind)
        one = True
        below = f"a reference modulus must be positive, got {y.value!r}"
    if kind == "modulus" and low <= 0:
        raise r.error(y, below)
    return low if one else (low, high)


def _read_reference(r: _Reader, y: _Y, materials: dict[str, Material]) -> dict:
    ref = {"source": "", "materials": {}, "global": {}}
    m = r.mapping(y, optional=("source", "materials", "global"))
    if "source" in m:
        ref["source"] = r.string(m["source"])
    if "materials" in m:
        for name, entry in r.mapping(m["materials"], optional=list(materials)).items():
            values = {}
            for key, item in r.mapping(entry, optional=CONSTANT_NAMES).items():
                kind = "dimensionless" if key == "nu12" else "modulus"
                values[key] = _reference_value(r, item, kind)
            ref["materials"][name] = values
    if "global" in m:
        for key, item in r.mapping(m["global"], optional=GLOBAL_NAMES).items():
            kind = "dimensionless" if key.startswith("nu") else "modulus"
            ref["global"][key] = _reference_value(r, item, kind)
    return ref


# ----------------------------------------------------------------------------------------------
# entry points


def load_specimen_text(text: str, path: str = "<string>", *,
                       log_warnings: bool = True) -> Specimen:
    """Read and validate a specimen from YAML text (``path`` is used in messages only).

    The reader's warnings (ply angles that look like radians, a mass that density x volume
    contradicts...) are in :attr:`Specimen.warnings`, and logged as they are found unless
    ``log_warnings`` is False: for a file read again that the user was told of already (one
    checked again after an edit, a result's stored specimen rebuilt).

    Raises
    ------
    SpecimenError
        ``path:line, field 'x.y': problem`` for anything invalid.
    """
    path = str(path)
    root = _compose(text, path)
    r = _Reader(path, log_warnings)
    top = r.mapping(root, required=("geometry", "materials"), optional=[
        k for k in _TOP_KEYS if k not in ("geometry", "materials")], elsewhere=_TOP_ELSEWHERE,
        what="a mapping with name, geometry, materials, layup, measured, ... at the top level")

    name = r.string(top["name"]) if "name" in top else Path(path).stem
    if "name" in top:
        _check_name(r, top["name"], name, "specimen name")
    else:
        _check_file_name(path, name)
    description = r.string(top["description"]) if "description" in top else ""
    a, b, h = _read_geometry(r, top["geometry"])
    mass = r.positive(top["mass"], "mass") if "mass" in top else None

    entries = r.mapping(top["materials"], what="a mapping of material names to constants",
                        any_key=True)
    if not entries:
        raise r.error(top["materials"], "no material defined")
    for name_, y in entries.items():
        _check_name(r, y, name_, "material name")
    materials = {name_: _read_material(r, name_, y) for name_, y in entries.items()}

    boundary = "free"
    if "boundary" in top:
        written = r.string(top["boundary"]).strip()
        boundary = written.lower()
        if len(boundary) == 4 and set(boundary) <= set("fsc"):
            # an edge code (CFFF, a cantilever) was "unknown boundary condition 'cfff'", though
            # modes --boundary takes it: say where it goes
            raise r.error(top["boundary"], f"'{written}' is an edge code, which only 'laminid "
                                           "modes --boundary' takes; a specimen's boundary is "
                                           f"one of {', '.join(BOUNDARIES)} (what identify and "
                                           "batch fit)")
        if boundary not in BOUNDARIES:
            guess = _closest(boundary, BOUNDARIES)
            hint = f"; did you mean '{guess}'?" if guess else ""
            raise r.error(top["boundary"], f"unknown boundary condition '{boundary}'{hint} "
                                           f"(valid: {', '.join(BOUNDARIES)})")

    plies = _read_plies(r, top, root, h, materials)
    _warn_unsymmetric(r, top, plies, " ".join((name, description, *_comments(text))))
    densities = _resolve_densities(r, top, root, a, b, h, mass, materials, plies)
    _check_derived_densities(r, top, root, densities, materials, h=h, n_plies=len(plies))
    measured = _read_measured(r, top["measured"]) if "measured" in top else None
    reference = (_read_reference(r, top["reference"], materials) if "reference" in top else
                 {"source": "", "materials": {}, "global": {}})

    specimen = Specimen(name=name, path=path, source_text=text, a=a, b=b, h=h, mass=mass,
                        materials=materials, plies=plies, densities=densities,
                        measured=measured, reference=reference, boundary=boundary,
                        description=description)
    if mass is not None:
        model = specimen.model_mass
        if abs(model - mass) > MASS_TOLERANCE * mass:
            r.warn(_mass_density_warning(specimen, top))
    for line, field_name, message in light_plate_warnings(specimen, top):
        r.warn(f"{path}:{line}, field '{field_name}': {message}")
    return dataclasses.replace(specimen, warnings=tuple(r.warnings))


#: the model mass (density x volume, the densities as given) may differ from the measured mass
#: by this fraction before it is warned of. A plate weighed to 0.1 g of 300 g, its sides to
#: 0.1 mm of 200 mm and its thickness to 0.01-0.02 mm of 3 mm gives m / (a b h) to about 1 %;
#: a datasheet's ply density is good to 1-2 % (fibre volume fraction, voids). More than 2 % is
#: one of them wrong, and it matters: laminid uses the density, and every identified modulus
#: scales with it (E ~ rho f^2), so the moduli carry the same percentage
MASS_TOLERANCE = 0.02


def _mass_density_warning(spec: Specimen, top: dict) -> str:
    """The warning on a plate whose mass and densities (used as given, not scaled to the
    mass) disagree by more than :data:`MASS_TOLERANCE`: both values, their ratio, which one
    laminid uses and how to use the other."""
    mass, model = spec.mass, spec.model_mass
    ratio = model / mass
    mats = top["materials"].value

    def line(name):
        node = mats.get(name)
        node = node.value.get("density") if node is not None and isinstance(
            node.value, dict) else None
        return f" (line {node.line})" if node is not None else ""

    sides = f"{spec.a * 1e3:.4g} x {spec.b * 1e3:.4g}"
    if len(spec.materials) == 1:
        (name,) = spec.materials
        given = (f"the density {spec.densities[name]:.4g} kg/m^3{line(name)} x the volume "
                 f"{sides} x {spec.h * 1e3:.4g} mm")
        other = (f"leave out density (then mass / (a b h) = "
                 f"{mass / (spec.a * spec.b * spec.h):.4g} kg/m^3) or ")
    else:
        given = ("the densities " + ", ".join(f"'{n}' {rho:.4g} kg/m^3{line(n)}"
                                              for n, rho in spec.densities.items())
                 + f" over their plies' thicknesses on {sides} mm")
        other = ""
    where = f"{spec.path}:{top['mass'].line}, field 'mass'" if "mass" in top else spec.path
    return (f"{where}: the model mass {model:.4g} kg differs from the measured mass "
            f"{mass:.4g} kg by {100 * (model - mass) / mass:.1f} %: {given} "
            f"give{'s' if len(spec.materials) == 1 else ''} {model:.4g} "
            f"kg, {ratio:.3g} times the mass (more than the {MASS_TOLERANCE * 100:g} % a weighed "
            "plate and its measured sides and thickness agree to); laminid uses the density, "
            "not the mass, and every identified modulus scales with it (E ~ rho f^2); if the "
            f"weighing is right, {other}set scale_density_to_mass: true (the "
            f"{'density' if len(spec.materials) == 1 else 'densities'} scaled by "
            f"{1 / ratio:.4g} to the mass)")


#: the isotropic keys a ply constant is read from ({E: .., nu: .., G: ..})
_ISOTROPIC_SOURCE = {"E1": ("E",), "E2": ("E",), "nu12": ("nu",), "G12": ("G", "E"),
                     "G13": ("G", "E"), "G23": ("G", "E")}


def field_line(spec: Specimen, *keys: str) -> int | None:
    """The line (1-based) of the field ``keys[0].keys[1]...`` in the specimen's YAML, for
    messages about a value judged after the file was read (an initial value or a count of
    frequencies the identification cannot start from); None when the text does not have it."""
    try:
        y = _compose(spec.source_text, spec.path)
    except SpecimenError:
        return None
    for key in keys:
        if not isinstance(y.value, dict) or key not in y.value:
            return None
        y = y.value[key]
    return y.line


def constant_line(spec: Specimen, material: str, constant: str) -> int | None:
    """The line of ``constant`` of ``material`` in the specimen's YAML (of ``nu``, ``E`` or
    ``G`` for an isotropic material: the key the constant was read from), else the material's
    line; None when the text does not have the material (:func:`field_line`)."""
    for key in (constant,) + _ISOTROPIC_SOURCE.get(constant, ()):
        line = field_line(spec, "materials", material, key)
        if line is not None:
            return line
    return field_line(spec, "materials", material)


def light_plate_warnings(spec: Specimen, top: dict | None = None) -> list[tuple]:
    """Densities too light for a solid plate (:data:`LIGHT_PLATE_DENSITY`,
    :data:`LIGHT_MATERIAL_DENSITY`): (line or None, field, words) per warning, with the density,
    the values it came from and the likely unit slip. ``top`` is the file's top-level mapping
    (for the lines); empty when every density is plausible."""
    top = top or {}
    dims = f"{spec.a * 1e3:.4g} x {spec.b * 1e3:.4g} x {spec.h * 1e3:.4g} mm"
    derived = [n for n, m in spec.materials.items() if m.density != spec.densities[n]]
    mean = spec.model_mass / (spec.a * spec.b * spec.h)
    out = []

    def material_line(name):
        y = top.get("materials")
        y = y.value.get(name) if y is not None and isinstance(y.value, dict) else None
        y = y.value.get("density") if y is not None and isinstance(y.value, dict) else None
        return y.line if y is not None else None

    if mean < LIGHT_PLATE_DENSITY and max(spec.densities.values()) < SOLID_DENSITY:
        limit = (f"lighter than any solid plate (below {LIGHT_PLATE_DENSITY:g} kg/m^3; only a "
                 "foam-cored sandwich with very thin skins comes near)")
        if derived:
            written = top["mass"].value if "mass" in top else None
            shown = (f"{written!r} = {spec.mass:.4g} kg" if isinstance(written, str)
                     else f"{spec.mass:.4g} kg")
            words = (f"the plate's density, mass / (a b h) = {shown} / ({dims}), is "
                     f"{mean:.4g} kg/m^3, {limit}: "
                     + _light_slip(mean, "a mass 1000 times too small (a value in kg written "
                                         "with the unit g, or grams as kg)", "a, b or h"))
            out.append((top["mass"].line if "mass" in top else None, "mass", words))
        else:
            name = min(spec.materials, key=lambda n: spec.densities[n])
            rho = spec.densities[name]
            plate = ("" if len(spec.materials) == 1 else
                     f" and the plate's mean density (model mass {spec.model_mass:.4g} kg over "
                     f"{dims}) {mean:.4g} kg/m^3")
            words = (f"material '{name}' has a density of {rho:.4g} kg/m^3{plate}, {limit}: "
                     + _light_slip(rho, _DENSITY_IN_G_CM3, None))
            out.append((material_line(name), f"materials.{name}.density", words))
        return out
    if len(spec.materials) > 1:
        for name, rho in spec.densities.items():
            if rho >= LIGHT_MATERIAL_DENSITY:
                continue
            words = (f"material '{name}' has a density of {rho:.4g} kg/m^3, lighter than any "
                     f"ply or core material (below {LIGHT_MATERIAL_DENSITY:g} kg/m^3): "
                     + _light_slip(rho, _DENSITY_IN_G_CM3 if name not in derived
                                   else "its density_ratio or density wrong", None))
            field_name = f"materials.{name}.density"
            out.append((material_line(name), field_name, words))
    return out


#: the likely slip behind a ply density 1000 times too small that the file gives itself
_DENSITY_IN_G_CM3 = ("a density in g/cm^3 written as a bare number or as kg/m^3 (a bare number "
                     "is kg/m^3)")


def _light_slip(rho: float, thousand: str, sides: str | None) -> str:
    """The likely slip behind a density ``rho`` (kg/m^3) too light for a plate: ``thousand``
    when 1000 times it is a solid's density, a side in inches for mm when 25.4 times it is
    (``sides``: what holds the lengths, None when the density is not computed from them)."""
    solid = (500.0, 25000.0)
    if solid[0] <= 1000 * rho <= solid[1]:
        also = (f", or {sides} 1000 times too large (m for mm)" if sides else "")
        return f"{thousand}{also}? 1000 times it is {1000 * rho:.4g} kg/m^3"
    if sides and solid[0] <= 25.4 * rho <= solid[1]:
        return f"{sides} in inches where it is mm? 25.4 times it is {25.4 * rho:.4g} kg/m^3"
    return "check the number and its unit"


#: what a specimen's reader says of each kind of binary file (laminid_cli.filekinds), beyond
#: its name: (words in parentheses after it, what takes it or what to do)
_NOT_A_SPECIMEN = {
    "hdf5": (" (an FRF or result file?)",
             ": FRFs go through 'laminid fit-frf FILE --into SPECIMEN.yaml' (or "
             "measured.frf_file in the specimen), a result through 'laminid report FILE'"),
    "zip": ("", "; write the specimen as YAML text (specimens/README.md)"),
    "gzip": ("", "; unpack it first"),
}


def not_a_specimen(head: bytes) -> str | None:
    """What a file whose first bytes are ``head`` is when those bytes say it can be no
    specimen file (HDF5, PDF, ZIP, PNG, gzip: :data:`laminid_cli.filekinds.SIGNATURES`), in
    words with what takes it ("an HDF5 file (an FRF or result file?), not a specimen file
    (YAML text): ..."); None otherwise.

    >>> not_a_specimen(b"%PDF-1.7")
    'a PDF document, not a specimen file (YAML text)'
    """
    kind = binary_kind(head)
    if kind is None:
        return None
    aside, then = _NOT_A_SPECIMEN.get(kind[0], ("", ""))
    return f"{kind[1]}{aside}, not a specimen file (YAML text){then}"


def hdf5_format(path, probe: bool = True) -> str:
    """The root attribute ``format`` of the HDF5 file ``path`` ("laminid-result",
    "laminid-frf", ...; "" when it has none). With ``probe`` the file is read in a child
    process first (:func:`laminid_cli.frf.store.probe_hdf5_file`): one that would crash or
    hang libhdf5 is an FrfError, as is one h5py cannot open."""
    from laminid_cli.errors import FrfError
    from laminid_cli.frf.store import H5_DAMAGE_ERRORS, probe_hdf5_file
    from laminid_cli.h5open import file_format

    if probe:
        probe_hdf5_file(path, reader="hdf5_format", module="laminid_cli.specimen")
    try:
        return file_format(path)
    except H5_DAMAGE_ERRORS as exc:
        raise FrfError(f"{path}: {exc}") from exc


def is_batch_summary(head: bytes) -> bool:
    """Whether ``head``, the first bytes of a file (a few hundred will do), are those of a
    summary.json or summary.csv of laminid batch: the JSON's leading ``"format":
    "laminid-batch-summary"``, the CSV's options title
    (:data:`laminid_cli.batch.CSV_OPTIONS_TITLE`) or, in one written before it, its header
    ``name,specimen,``."""
    text = head.lstrip().decode("utf-8", "replace")
    if text.startswith("{"):
        return bool(re.match(r'\{\s*"format"\s*:\s*"laminid-batch-summary"', text))
    first = text.split("\n", 1)[0]
    return ((first.startswith("# laminid ") and " batch summary; " in first)
            or first.startswith("name,specimen,"))


def non_specimen_text(path) -> str | None:
    """What ``path`` is, in words with what takes it, when it can be no specimen file: by its
    first bytes (:func:`not_a_specimen`: PDF, ZIP, ...) and an HDF5 file
    by its ``format`` (a laminid result, FRF or modes file, another tool's file). None for a
    file that may be one: its faults are its own, reported when it runs."""
    import shlex

    from laminid_cli.filekinds import HDF5_MAGIC
    from laminid_cli.h5open import laminid_kind

    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError:
        return None
    if is_batch_summary(head):
        # a YAML reader took summary.json for a specimen ("unknown key 'format'") and
        # summary.csv for one line of text, echoed whole in its message
        return ("a laminid batch summary, not a specimen file (YAML text); "
                f"'laminid report {shlex.quote(str(path))}' draws it")
    if not head.startswith(HDF5_MAGIC):
        return not_a_specimen(head)
    try:
        fmt = hdf5_format(path)
    except LaminidError as exc:
        reason = str(exc).removeprefix(f"{path}: ")
        return f"a damaged HDF5 file ({reason}), not a specimen file (YAML text)"
    kind = laminid_kind(fmt, path)
    if kind is not None:
        return f"{kind[0]}, not a specimen file (YAML text); {kind[1]}"
    which = f"format {fmt!r}" if fmt else "not a laminid file"
    return (f"an HDF5 file ({which}), not a specimen file (YAML text); FRFs of another tool go "
            f"through 'laminid fit-frf {shlex.quote(str(path))} --into SPEC.yaml'")


def read_specimen(path, *, log_warnings: bool = True) -> Specimen:
    """Read a specimen YAML file (UTF-8, or UTF-16 with its byte-order mark) and validate it;
    see :func:`load_specimen_text` (``log_warnings`` too)."""
    name = str(path)
    p = Path(path)
    try:
        if p.is_file():
            with open(p, "rb") as fh:
                head = fh.read(512)
            what = not_a_specimen(head)
            if what is not None or head.lstrip().startswith((b"{", b"# laminid ",
                                                              b"name,specimen,")):
                if what is not None or is_batch_summary(head):
                    # a laminid file named by its format, with what reads it (a result: show,
                    # report; an FRF file: fit-frf; a batch summary: report), as batch names
                    # them; a summary.json was "unknown key 'format'", a result "an FRF or
                    # result file?"
                    raise SpecimenError(f"is {non_specimen_text(p) or what}", path=name)
        size = p.stat().st_size if p.is_file() else 0
        if size > 4 * MAX_SPECIMEN_CHARS:   # refused before it is read into memory
            raise SpecimenError(f"the file has {size} bytes, more than a specimen file can have "
                                f"({MAX_SPECIMEN_CHARS} characters); is it the right file?",
                                path=name)
        data = p.read_bytes()
    except FileNotFoundError as exc:
        raise SpecimenError("file not found", path=name) from exc
    except IsADirectoryError as exc:
        raise SpecimenError("is a folder, not a specimen file", path=name) from exc
    except OSError as exc:
        raise SpecimenError(f"cannot read the file: {exc.strerror or exc}", path=name) from exc
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        # UTF-16 with its byte-order mark, as Windows Notepad's "Unicode" saves it; YAML
        # 1.1 reads it (yaml.org, YAML 1.1, 5.1 "Character Set": UTF-8, UTF-16 with a BOM);
        # it was "not UTF-8 text (byte 0xff at byte 1)"
        try:
            text = data.decode("utf-16")
        except UnicodeDecodeError as exc:
            raise SpecimenError(f"UTF-16 text (its byte-order mark) that cannot be read as "
                                f"such ({exc.reason} at byte {exc.start + 1}); save the file "
                                "as UTF-8", path=name) from exc
    else:
        try:
            text = data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            line = data[:exc.start].count(b"\n") + 1
            raise SpecimenError(f"not UTF-8 text (byte 0x{data[exc.start]:02x} at byte "
                                f"{exc.start + 1}); save the file as UTF-8", path=name,
                                line=line) from exc
    if not text.strip():
        raise SpecimenError("the file is empty; expected a mapping with geometry, materials, "
                            "layup, ...", path=name)
    return load_specimen_text(text, name, log_warnings=log_warnings)
