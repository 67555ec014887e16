"""Typed reader of identification result files (``laminid identify``, ``laminid batch``).

:func:`read_result` opens a "laminid-result" or "laminid-joint-result" file (layout: the
docstring of :mod:`laminid_cli.results`), checks its ``format`` and ``schema_version`` and
returns a frozen :class:`ResultFile`. Version 1 files (material groups keyed by the name with a
look-alike slash, no result status) are read as far as they go: ``status`` is None then, and a
report says "status not recorded". The optional groups ``/status``, ``/uncertainty`` and
``/damping`` are None when absent.

Everything is in SI (Pa, Hz, m, kg; nu12 and loss factors: 1), as stored.
"""

from __future__ import annotations

import contextlib
import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from laminid_cli.errors import LaminidError, about_file, escaped, non_printable, non_printable_in
from laminid_cli.intervals import PROFILE_FLAT, PROFILE_NONE
from laminid_cli.status import Reason, ResultStatus

CONSTANTS = ("E1", "E2", "G12", "G13", "G23", "nu12")
RESULT_FORMATS = ("laminid-result", "laminid-joint-result")
READABLE_VERSIONS = (1, 2)
MAKES_A_RESULT = ("laminid identify SPEC.yaml (or laminid identify A.yaml B.yaml --joint, "
                  "laminid batch FOLDER)")


def not_a_result_but_frf(path) -> str:
    """The message for an FRF file given where a result is expected (``laminid report``,
    ``laminid show``): what draws it (``fit-frf --plot``) and what makes a result of it
    (``identify``)."""
    import shlex

    q = shlex.quote(str(path))
    plot = shlex.quote(f"{Path(path).name.split('.')[0] or 'frf'}.fit.pdf")
    return (f"{path}: an FRF file, not an identification result: laminid fit-frf {q} --plot "
            f"{plot} draws its FRFs and their fit; a result is made from it by laminid fit-frf {q} "
            "--into SPEC.yaml, then laminid identify SPEC.yaml")


def is_frf_text_file(path) -> bool:
    """A Universal File (.uff/.unv) or a CSV FRF file (.csv/.txt: first column the frequency,
    named so, "f [Hz]", "Frequency (kHz)", "omega [rad/s]", or a number; or a '# laminid FRF'
    comment), given to ``report`` or ``show`` instead of a result or summary. Another tool's
    CSV whose frequency was named "f [Hz]" was "not a laminid batch summary"."""
    from laminid_cli.frf.io import csv_frequency_first, decode_head

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".uff", ".unv"):
        return True
    if suffix not in (".csv", ".txt"):
        return False
    try:
        with open(p, "rb") as fh:
            raw = fh.read(65536)
    except OSError:
        return False
    text = decode_head(raw)
    if text is None:
        return False
    rows = text.splitlines()[:-1] if len(raw) == 65536 else text.splitlines()
    if any(ln.lstrip().startswith("# laminid FRF") for ln in rows[:5]):
        return True
    return csv_frequency_first(p, rows)


def _plain_frf_file(f, path) -> bool:
    """Whether the open HDF5 file ``f`` without a laminid format holds FRFs as
    ``fit-frf`` reads another tool's file (:mod:`laminid_cli.frf.generic_h5`): one
    frequency/FRF dataset pair, or several to choose from."""
    from laminid_cli.errors import FrfError
    from laminid_cli.frf.generic_h5 import _choose, _datasets

    try:
        _choose(Path(path), f, _datasets(f), None, None)
    except FrfError as exc:
        return "several frequency/FRF dataset pairs fit" in str(exc)
    except Exception:     # noqa: BLE001 - h5py on an odd dataset: not FRFs, say what it is not
        return False
    return True


class ResultFileError(LaminidError):
    """Not a readable identification result (exit code 2)."""


#: the result's status ("ok" | "check") and its reasons, as :mod:`laminid_cli.status` makes it
Status = ResultStatus


def profile_kind(bound, text) -> str:
    """:attr:`Interval.profile_kind` of a profile's bound (SI, NaN or None: none) and
    statement."""
    if bound is not None and np.isfinite(bound):
        return "bound"
    text = text or ""
    return ("flat" if text.startswith(PROFILE_FLAT) else
            "none" if text.startswith(PROFILE_NONE) else "")


@dataclass(frozen=True)
class Interval:
    """The confidence interval of one free constant (SI; nu12: 1)."""

    label: str                 # "material.constant"
    material: str
    constant: str
    value: float
    lower: float
    upper: float
    verdict: str
    rel_half_width: float = np.nan
    scale: str = "linear"      # "log" (moduli, schema 2) | "linear"
    at_bound: bool = False
    bound_text: str = ""
    #: of a constant at its bound: "lower" (the data push it below ``bound_limit``) | "upper";
    #: "" when not at a bound. Files written before these datasets: read from ``bound_text``
    bound_side: str = ""
    bound_limit: float = np.nan              # SI (Pa; nu12: 1)
    #: not determined: relative half-width above the run's --max-rel-interval (the file's
    #: /uncertainty attribute ``flagged``)
    flagged: bool = False
    #: the verdict is the Monte Carlo range's (worse than the linearised interval's; the
    #: /uncertainty attribute ``verdict_from_monte_carlo``)
    verdict_from_monte_carlo: bool = False
    #: of a constant at its bound: the profile's bound (where the fit rejects it, SI; NaN:
    #: none within the search) and its statement (/uncertainty/profile_*; files before stop
    #: 30 have none: "")
    profile_bound: float = np.nan
    profile_text: str = ""
    #: the other end of the profile's scan (SI; NaN: no profile, or one that could not be
    #: made: profile_kind "none", whose scan reached nowhere; files before that fix stored
    #: the planned end there, read as NaN)
    profile_far: float = np.nan

    @property
    def profile_kind(self) -> str:
        """What the profile of a constant at its bound says, in a word: "bound" (the fit
        rejects it beyond ``profile_bound``), "flat" (nowhere within the search: the modes do
        not determine it), "none" (no profile could be made: ``profile_text`` says why), ""
        (not at a bound, or a file without profiles)."""
        return profile_kind(self.profile_bound, self.profile_text)


@dataclass(frozen=True)
class Uncertainty:
    confidence: float
    s2: float
    dof: float
    condition_number: float
    sigma_source: str
    well_determined: float     # relative half-width limits of the verdicts (e.g. 0.05, 0.30)
    weak: float
    intervals: tuple[Interval, ...]
    notes: str = ""
    monte_carlo: dict | None = None      # {"lower", "upper", "mean", "std", ...} arrays
    #: labels ("material.constant") held at their initial value: by ``--fix`` or by
    #: ``--fix-undetermined`` (attribute ``fixed``; () in files that did not write it)
    fixed: tuple[str, ...] = ()
    #: the labels ``--fix-undetermined`` fixed because the first run left them undetermined
    #: (attribute ``fixed_undetermined``), with that run's assessment of every constant in
    #: ``before_fixing`` ({label: (relative half-width, verdict)}; /uncertainty/before_fixing)
    fixed_undetermined: tuple[str, ...] = ()
    before_fixing: dict = field(default_factory=dict)
    #: {label: (relative half-width, verdict, run)} in the run that had it fixed
    #: (/uncertainty/fixed_undetermined; {} in files before stop 29)
    fixed_widths: dict = field(default_factory=dict)
    #: the fixed values whose spread before fixing the intervals count (attribute
    #: ``spread_counted``), and {label: relative half-width given the fixed values alone}
    #: (/uncertainty/rel_half_width_given_fixed); () and {} in files before stop 30, whose
    #: intervals were given the fixed values
    spread_counted: tuple[str, ...] = ()
    given_fixed: dict = field(default_factory=dict)
    #: {label: statement} of the constants fixed on a limit of the search, checked across it
    #: (/uncertainty/fixed_ranges; {} in older files)
    fixed_ranges: dict = field(default_factory=dict)
    #: whether the modes reject the values --fix-undetermined fixed, taken together: the
    #: statement (/uncertainty/fixed_check attr text; "" in older files) and its verdict
    fixed_check: str = ""
    fixed_rejected: bool = False
    #: how the intervals were made (attrs scale_used, variance_factor, quantile): "stated"
    #: (the stated frequency sigma, normal quantile) or "residuals" (covariance scaled by
    #: variance_factor = s2, Student t ``quantile``); "" and NaN in files without them
    scale_used: str = ""
    variance_factor: float = np.nan
    quantile: float = np.nan

    def get(self, material: str, constant: str) -> Interval | None:
        return next((iv for iv in self.intervals
                     if iv.material == material and iv.constant == constant), None)


@dataclass(frozen=True)
class Damping:
    """``/damping`` (the ply loss factors, results.py), as stored: the group's attributes,
    its datasets (string datasets as tuples of str) and each dataset's attributes."""

    attrs: dict
    data: dict
    dataset_attrs: dict = field(default_factory=dict)    # {dataset: {attribute: value}}
    #: /damping/monte_carlo: its datasets (arrays) and attributes in one dict; None in files
    #: without (no --monte-carlo, or written before the loss factors' Monte Carlo)
    monte_carlo: dict | None = None


@dataclass(frozen=True)
class Frequencies:
    measured: np.ndarray       # Hz, NaN = not measured
    model: np.ndarray          # Hz, the model mode paired with each measured one
    residual_percent: np.ndarray
    weight: np.ndarray
    model_mode: np.ndarray     # 1-based index of the sorted model mode paired with each
    rms_residual_percent: float
    initial_rms_residual_percent: float
    #: Hz, the standard deviation of each measured frequency the fit and its intervals used
    #: (/uncertainty/frequency_sigma; NaN: not measured); None in files without it
    sigma_hz: np.ndarray | None = None


@dataclass(frozen=True)
class History:
    evaluation: np.ndarray
    objective: np.ndarray
    rms_residual_percent: np.ndarray
    constants: np.ndarray      # (n_evaluations, n_materials*6), SI
    labels: tuple[str, ...]    # "material.constant" of the columns of ``constants``
    #: relative eigenvalue error bound per evaluation (0: full model, NaN: a reduced-model
    #: prediction); all zeros in files written before it was recorded (full-model runs)
    error_bound: np.ndarray | None = None


@dataclass(frozen=True)
class Plate:
    """One plate's part of a result (the whole file for a single identification)."""

    name: str
    path: str
    yaml: str
    a: float
    b: float
    h: float
    boundary: str
    nodes: np.ndarray          # (n_nodes, 2) m
    elements: np.ndarray       # (n_el, 8)
    mesh: tuple[int, int]
    materials: dict            # {material: {constant: value}} (with "density" when stored)
    frequencies: Frequencies
    w: np.ndarray              # (n_nodes, n_modes) transverse displacement of paired modes
    sensitivity: np.ndarray | None
    sensitivity_labels: tuple[str, ...]
    global_properties: dict
    history: History | None
    swaps: tuple[str, ...]
    warnings: tuple[str, ...]
    reference: dict            # {material: {constant: (low, high) SI}} from the specimen's
                               # YAML (low == high: one value; else the range written)
    reference_source: str = ""
    reference_global: dict = field(default_factory=dict)   # {Ex...: (low, high) SI}
    #: {Ex...: {"value", "std", "lower", "upper", "rel_half_width", "verdict"}} (SI; NaN
    #: interval: not identified) from the plate's global_properties_uncertainty; {} when not
    #: stored
    global_uncertainty: dict = field(default_factory=dict)
    #: the specimen file's folder, absolute ("" in files before it was stored): ``path`` is as
    #: the command was given it, relative to the folder it ran in
    folder: str = ""


@dataclass(frozen=True)
class ResultFile:
    path: Path
    format: str
    schema_version: int
    joint: bool
    converged: bool
    optimizer: str
    optimizer_status: str      # the nlopt outcome
    objective: float
    evaluations: int
    time_s: float
    materials: dict            # {material: {constant: value SI}} identified
    initial: dict
    free: dict                 # {material: (constant, ...)}
    history: History | None
    rms_residual_percent: float
    plates: tuple[Plate, ...]
    status: Status | None = None
    uncertainty: Uncertainty | None = None
    damping: Damping | None = None
    warnings: tuple[str, ...] = field(default_factory=tuple)
    #: /mesh_check of ``identify --mesh-check`` as plain data (MeshCheck.as_dict's keys:
    #: mesh, fine_mesh, modes, constants, labels, limit, too_coarse, text, time_s); None when
    #: the file has none (without the flag, or written before it existed)
    mesh_check: dict | None = None

    @property
    def confidence(self) -> float | None:
        return None if self.uncertainty is None else self.uncertainty.confidence

    @property
    def reference(self) -> dict:
        """{material: {constant: (low, high)}}: the plates' reference values, low == high for
        one value; where the plates of a joint result give different ones, the range from the
        lowest to the highest (:func:`combined_reference`, :attr:`reference_notes` says so)."""
        return combined_reference((p.name, p.reference) for p in self.plates)[0]

    @property
    def reference_notes(self) -> list[str]:
        """Where the plates' reference values of a constant differ, one line naming each
        plate's (empty for one plate, or plates that agree)."""
        return combined_reference((p.name, p.reference) for p in self.plates)[1]

    @property
    def reference_source(self) -> str:
        """The plates' reference sources, each once, in plate order ("; " between them)."""
        return "; ".join(dict.fromkeys(p.reference_source for p in self.plates
                                       if p.reference_source))


def combined_reference(plates) -> tuple[dict, list[str]]:
    """({material: {constant: (low, high)}}, notes) of the shared constants of plates fitted
    together, from ``plates`` = (name, {material: {constant: value}}) with a value a number or
    (low, high). A constant whose reference is the same in every plate that gives one keeps
    it; where the plates give different ones, the reference is the range from the lowest to
    the highest, and a note names each plate's value (a joint result compared with one plate's
    reference alone hid the others')."""
    seen: dict = {}
    for name, ref in plates:
        for m, consts in (ref or {}).items():
            for k, v in consts.items():
                low, high = (v, v) if np.isscalar(v) else v
                seen.setdefault(m, {}).setdefault(k, []).append((name, float(low), float(high)))
    out: dict = {}
    notes = []
    for m, consts in seen.items():
        for k, vals in consts.items():
            pairs = {(lo, hi) for _, lo, hi in vals}
            out.setdefault(m, {})[k] = (min(lo for lo, _ in pairs), max(hi for _, hi in pairs))
            if len(pairs) > 1:
                scale, unit = (1.0, "") if k == "nu12" else (1e-9, " GPa")
                each = ", ".join(f"{n} {lo * scale:g}" + (f"–{hi * scale:g}" if hi != lo else "")
                                 for n, lo, hi in vals)
                label = f"{m}.{k}" if len(seen) > 1 else k
                notes.append(f"reference {label} differs between the plates ({each}{unit}): "
                             "the range from the lowest to the highest is shown")
    return out, notes


# ----------------------------------------------------------------------------------------------
# the most a result file's datasets hold, from what laminid writes: checked on the declared
# shapes before anything is read (a tampered /history of 10**9 rows, chunked and unwritten: a
# 200 kB file, was read whole, 44.7 GiB, a MemoryError traceback)

def _mesh_limits() -> tuple[int, int]:
    """(nodes, elements) of the finest mesh laminid builds (fe.mesh.MAX_ELEMENTS_PER_SIDE a
    side, 8-node elements: 120801 nodes, 40000 elements)."""
    from laminid_cli.fe.mesh import MAX_ELEMENTS_PER_SIDE as n

    return (2 * n + 1) ** 2 - n * n, n * n


#: rows of /history (and of swaps, warnings: a note per evaluation at most), in the largest
#: --max-evaluations (commands._common.MAX_EVALUATIONS, which caps a run's evaluations in
#: all): twice, the factor a margin, not a count
HISTORY_ROWS_PER_EVALUATION = 2
#: values along any other axis (modes, constants, labels): each is an entry of the specimen's
#: YAML, which holds at most specimen.MAX_YAML_NODES (100000)
MAX_AXIS_VALUES = 100_000


def _row_limit(name: str) -> tuple[int, str]:
    """(most rows, what bounds them) of the dataset named ``name`` (its HDF5 path)."""
    from laminid_cli.commands._common import MAX_EVALUATIONS, TrialCount

    nodes, elements = _mesh_limits()
    parts = name.strip("/").split("/")
    last, parent = parts[-1], (parts[-2] if len(parts) > 1 else "")
    if (parent, last) in (("mesh", "nodes"), ("modes", "w")):
        return nodes, f"the nodes of the finest mesh laminid builds ({nodes})"
    if (parent, last) == ("mesh", "elements"):
        return elements, f"the elements of the finest mesh laminid builds ({elements})"
    if (parent, last) in (("modes", "phi"), ("modes", "dofs")):
        return 9 * nodes, f"the equations of the finest mesh laminid builds ({9 * nodes})"
    if parent == "history" or last in ("swaps", "warnings"):
        rows = HISTORY_ROWS_PER_EVALUATION * MAX_EVALUATIONS
        return rows, f"the evaluations laminid records ({rows})"
    if parent == "monte_carlo" and last in ("samples", "fixed_samples"):
        return TrialCount.MAX_TRIALS, f"the Monte Carlo trials ({TrialCount.MAX_TRIALS})"
    return MAX_AXIS_VALUES, f"the modes or constants a specimen holds ({MAX_AXIS_VALUES})"


def check_declared_sizes(f, path, error: type[Exception] | None = None,
                         what: str = "the result file") -> None:
    """``error`` (ResultFileError by default) naming the file and the dataset where a
    dataset of the open result (or modes) file ``f`` declares more values than laminid
    writes there (:func:`_row_limit` along its first axis, :data:`MAX_AXIS_VALUES` along
    the others) or more bytes than this process may use; only the shapes are looked at."""
    import h5py

    from laminid_cli.memory import available_memory_bytes

    def visit(name, obj):       # (a value returned stops the visit)
        if isinstance(obj, h5py.Dataset) and obj.shape:
            return _size_problem(obj, available_memory_bytes)
        return None

    found = f.visititems(visit)
    if found is not None:
        name, shape, reason = found
        raise (error or ResultFileError)(
            f"{path}: dataset '/{name.strip('/')}' declares {' x '.join(map(str, shape))} "
            f"values, {reason}; {what} is damaged or was edited")


def _size_problem(ds, available) -> tuple | None:
    from laminid_cli.memory import format_bytes

    shape = ds.shape
    rows, bound = _row_limit(ds.name)
    if shape[0] > rows:
        return ds.name, shape, f"more rows than {bound}"
    other = max(shape[1:], default=1)
    if other > MAX_AXIS_VALUES:
        return ds.name, shape, (f"more than {MAX_AXIS_VALUES} along an axis (the modes or "
                                "constants a specimen holds)")
    need = float(np.prod(shape, dtype=float)) * max(ds.dtype.itemsize, 8)
    room = available()
    if room is not None and need > room / 2:
        return ds.name, shape, (f"{format_bytes(need)} to read, more than half the memory "
                                f"available ({format_bytes(room)})")
    return None


# ----------------------------------------------------------------------------------------------


def decode(v):
    """An HDF5 attribute or dataset element as a plain Python value: bytes and 0-d string
    arrays as ``str`` (UTF-8), NumPy scalars as Python numbers, anything else unchanged."""
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray) and v.shape == ():
        return decode(v[()])
    if isinstance(v, np.generic):
        return v.item()
    return v


def _s(v) -> str:
    return str(decode(v))


def _strings(ds) -> tuple[str, ...]:
    return tuple(_s(x) for x in np.ravel(ds[()]))


def _name(key: str, group) -> str:
    """A group's real name: its ``name`` attribute; version 1 keys had a look-alike slash."""
    return _s(group.attrs["name"]) if "name" in group.attrs else key.replace("\u2215", "/")


def _materials(f, group: str = "materials") -> dict:
    out = {}
    if group not in f:
        return out
    for key, g in f[group].items():
        out[_name(key, g)] = {k: _num(g[k]) for k in (*CONSTANTS, "density") if k in g}
    return out


def _arr(ds, dtype=float) -> np.ndarray:
    """The values of dataset ``ds`` as an array of ``dtype``: ResultFileError naming the file
    and the dataset where they are no numbers (text, a compound) or no finite float is an
    int (a result edited by hand or damaged: 'could not convert string to float' was a
    ValueError traceback in show and report)."""
    value = ds[()]
    try:
        out = np.asarray(value, dtype)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ResultFileError(f"{ds.file.filename}: dataset '{ds.name}' holds "
                              f"{_shown(value)}, not numbers; the result file is damaged "
                              "or was edited") from exc
    if np.asarray(value).dtype.kind not in "biuf":
        raise ResultFileError(f"{ds.file.filename}: dataset '{ds.name}' holds "
                              f"{_shown(value)}, not numbers; the result file is damaged or "
                              "was edited")
    return out


def _num(ds) -> float:
    """A scalar dataset's value as a float (:func:`_arr`'s check), ResultFileError naming it
    where it holds more than one value."""
    out = _arr(ds, float)
    if out.size != 1:
        raise ResultFileError(f"{ds.file.filename}: dataset '{ds.name}' holds {out.size} "
                              "values, where one number is expected; the result file is "
                              "damaged or was edited")
    return float(out.reshape(-1)[0])


def _shown(value) -> str:
    text = repr(decode(value) if not isinstance(value, np.ndarray) or value.shape == ()
                else value.tolist())
    return text if len(text) <= 40 else text[:37] + "..."


def _labels(ds) -> tuple[str, ...]:
    return tuple(x for x in _s(ds.attrs.get("labels", "")).split(",") if x)


def _history(f) -> History | None:
    if "history" not in f:
        return None
    h = f["history"]
    bound = _arr(h["error_bound"], float) if "error_bound" in h else None
    return History(np.asarray(h["evaluation"][()]), _arr(h["objective"], float),
                   _arr(h["rms_residual_percent"], float),
                   _arr(h["constants"], float), _labels(h["constants"]), bound)


def _reference_pair(v, kind: str) -> tuple[float, float]:
    """(low, high) SI of a reference value as the YAML writes it: one value (low == high), a
    range [low, high] or a value and its half-width, "170 ± 1 GPa" (specimen.plus_minus, as
    the specimen reader reads it: the report left such a reference out); ValueError (or a
    units error) when it cannot be read."""
    from laminid_cli.specimen import _PLUS_MINUS, plus_minus
    from laminid_cli.units import parse_quantity

    if isinstance(v, dict) or (isinstance(v, list) and len(v) != 2):
        raise ValueError(f"not a reference value: {v!r}")
    if isinstance(v, str) and _PLUS_MINUS.search(v):
        value, half = plus_minus(v, kind)       # (ValueError for a negative half-width)
        return value - half, value + half
    low, high = (float(parse_quantity(x, kind)) for x in (v if isinstance(v, list) else [v, v]))
    if not low <= high:
        raise ValueError(f"range [{low:g}, {high:g}] has low > high")
    return low, high


def parse_reference(text: str) -> tuple[dict, str]:
    """({material: {constant: (low, high) SI}}, source) of a specimen YAML's ``reference``
    block: low == high for one value, a range as written (``E1: [120 GPa, 150 GPa]``);
    values that cannot be read (typos) are left out."""
    import yaml

    try:
        doc = yaml.safe_load(text)
        ref = doc["reference"]
        mats = ref.get("materials") or {}
    except (KeyError, TypeError, AttributeError, yaml.YAMLError):
        return {}, ""
    out: dict[str, dict] = {}
    for m, consts in mats.items() if isinstance(mats, dict) else ():
        for k, v in (consts or {}).items() if isinstance(consts, dict) else ():
            if k not in CONSTANTS:
                continue
            try:
                out.setdefault(str(m), {})[k] = _reference_pair(
                    v, "dimensionless" if k == "nu12" else "modulus")
            except Exception:  # noqa: BLE001 - a reference we cannot read is not shown
                continue
    return out, str(ref.get("source", "") or "")


def parse_global_reference(text: str) -> dict:
    """{property: (low, high)} (SI; low == high for one value) of the YAML's
    ``reference.global`` block (laminate properties of Appendix A: Ex, nu_xy...)."""
    import yaml

    try:
        glob = yaml.safe_load(text)["reference"]["global"] or {}
    except (KeyError, TypeError, AttributeError, yaml.YAMLError):
        return {}
    out = {}
    for k, v in glob.items() if isinstance(glob, dict) else ():
        try:
            out[str(k)] = _reference_pair(
                v, "dimensionless" if str(k).startswith("nu") else "modulus")
        except Exception:  # noqa: BLE001 - a reference we cannot read is not shown
            continue
    return out


def restate_reference_ranges(ref: dict, yaml_text: str) -> None:
    """Put the specimen's reference ranges into a stored summary's ``reference`` block (in
    place): files written before laminid kept ranges stored a range's midpoint there, a
    value nobody wrote; the specimen YAML in the file has the range. Single values and
    summaries that have the range already are left as they are."""
    if not isinstance(ref, dict):
        return
    mats, _ = parse_reference(yaml_text)
    blocks = [(ref.get("materials"), m, consts) for m, consts in mats.items()]
    blocks.append((ref, "global", parse_global_reference(yaml_text)))
    for parent, key, pairs in blocks:
        stored = parent.get(key) if isinstance(parent, dict) else None
        if not isinstance(stored, dict):
            continue
        for k, (low, high) in pairs.items():
            if low != high and isinstance(stored.get(k), (int, float)):
                stored[k] = [low, high]


def _plate(g, name: str | None = None) -> Plate:
    sp = g["specimen"]
    fr = g["frequencies"]
    measured = _arr(fr["measured"], float)
    yaml_text = _s(sp["yaml"][()]) if "yaml" in sp else ""
    ref, source = parse_reference(yaml_text)
    mesh = g["mesh"]
    sens = g.get("sensitivities")
    hist = _history(g)
    order = list(dict.fromkeys(lab.rsplit(".", 1)[0] for lab in
                               (hist.labels if hist is not None else ())))
    mats = _materials(g)
    mats = dict(sorted(mats.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order
                       else len(order)))
    return _checked_plate(g, Plate(
        name=name if name is not None else _s(sp.attrs.get("name", "")),
        path=_s(sp.attrs.get("path", "")), folder=_s(sp.attrs.get("folder", "")),
        yaml=yaml_text,
        a=_num(sp["a"]), b=_num(sp["b"]), h=_num(sp["h"]),
        boundary=_s(sp.attrs.get("boundary", "free")),
        nodes=_arr(mesh["nodes"], float), elements=_arr(mesh["elements"], int),
        mesh=(int(mesh.attrs.get("nx", 0)), int(mesh.attrs.get("ny", 0))),
        materials=mats, frequencies=Frequencies(
            measured=measured, model=_arr(fr["model"], float),
            residual_percent=_arr(fr["residual_percent"], float),
            weight=_arr(fr["weight"], float),
            model_mode=_arr(fr["model_mode"], int) if "model_mode" in fr
            else np.arange(1, measured.size + 1),
            rms_residual_percent=float(fr.attrs.get("rms_residual_percent", np.nan)),
            initial_rms_residual_percent=float(fr.attrs.get("initial_rms_residual_percent",
                                                            np.nan))),
        w=_arr(g["modes"]["w"], float),
        sensitivity=None if sens is None else _arr(sens["dlnf_dlnP"], float),
        sensitivity_labels=() if sens is None else _labels(sens["dlnf_dlnP"]),
        global_properties={k: _num(v) for k, v in g["global_properties"].items()}
        if "global_properties" in g else {},
        history=hist,
        swaps=_strings(g["swaps"]) if "swaps" in g else (),
        warnings=_strings(g["warnings"]) if "warnings" in g else (),
        reference=ref, reference_source=source,
        reference_global=parse_global_reference(yaml_text),
        global_uncertainty=_global_uncertainty(g)))


def _checked_plate(g, p: Plate) -> Plate:
    """``p`` as read from group ``g``, ResultFileError naming the file and the dataset where
    a stored value cannot be what identify wrote (a hand edit, a damaged file): a side or
    thickness not a finite positive length, an identified constant not finite, a mesh with
    no node, a non-finite coordinate or an element naming a node it does not have, mode
    shapes of another node count or not finite, frequency columns of different lengths.
    report died of each with a traceback ('Axis limits cannot be NaN or Inf', 'index
    1000000000 is out of bounds', 'shapes (5,) and (133,) not aligned')."""
    at = g.name.rstrip("/")
    texts = {"specimen@name": p.name, "specimen@description": _s(
        g["specimen"].attrs.get("description", ""))}
    texts |= {f"materials/{key}@name": name for key, name in
              ((k, _name(k, mg)) for k, mg in g["materials"].items())}
    for where, text in texts.items():
        bad = non_printable(text)
        if bad is not None:
            dataset, attribute = where.split("@")
            raise ResultFileError(f"{g.file.filename}: attribute '{attribute}' of "
                                  f"'{at}/{escaped(dataset)}' ({text!r}): {bad} in it; the "
                                  "result file is damaged or was edited")

    def bad(dataset: str, what: str):
        return ResultFileError(f"{g.file.filename}: dataset '{at}/{dataset}' {what}; the "
                               "result file is damaged or was edited")

    for key in ("a", "b", "h"):
        value = getattr(p, key)
        if not (np.isfinite(value) and 0 < value < 1e3):
            raise bad(f"specimen/{key}", f"is {value!r}, not a plate's length in m")
    for group_key, mg in g["materials"].items():
        for key, value in p.materials.get(_name(group_key, mg), {}).items():
            if key != "density" and not np.isfinite(value):
                raise bad(f"materials/{group_key}/{key}", f"is {value!r}, not a finite number")
    nodes, elements = p.nodes, p.elements
    if nodes.ndim != 2 or nodes.shape[0] == 0 or nodes.shape[1] != 2 \
            or not np.all(np.isfinite(nodes)):
        raise bad("mesh/nodes", f"holds {' x '.join(map(str, nodes.shape))} values, not the "
                                "finite x, y of at least one node")
    if elements.ndim != 2 or elements.size == 0 or elements.min() < 0 \
            or elements.max() >= nodes.shape[0]:
        raise bad("mesh/elements", f"names nodes outside 0 .. {nodes.shape[0] - 1} (the "
                                   "nodes of mesh/nodes)")
    if p.w.ndim != 2 or p.w.shape[0] != nodes.shape[0] or not np.all(np.isfinite(p.w)):
        raise bad("modes/w", f"holds {' x '.join(map(str, p.w.shape))} values, not finite "
                             f"mode shapes at the {nodes.shape[0]} nodes")
    fr = p.frequencies
    n = fr.measured.size
    for key in ("model", "residual_percent", "weight", "model_mode"):
        if getattr(fr, key).size != n:
            raise bad(f"frequencies/{key}", f"holds {getattr(fr, key).size} values, "
                                            f"frequencies/measured {n}")
    return p


def _frequency_sigmas(f) -> dict:
    """{plate name: sigma (Hz per measured mode)} from /uncertainty/frequency_sigma (each
    dataset's attr name: the specimen's), the only one under None too for a single plate; {}
    in files without it."""
    if "uncertainty" not in f or "frequency_sigma" not in f["uncertainty"]:
        return {}
    g = f["uncertainty"]["frequency_sigma"]
    out = {_s(d.attrs.get("name", key)): _arr(d, float).ravel()
           for key, d in g.items()}
    if len(out) == 1:
        out[None] = next(iter(out.values()))
    return out


def _global_uncertainty(g) -> dict:
    """The plate group's global_properties_uncertainty ({} in files before stop 29)."""
    if "global_properties_uncertainty" not in g:
        return {}
    h = g["global_properties_uncertainty"]
    keys = _strings(h["keys"])
    cols = {k: _arr(h[k], float) for k in ("value", "std", "lower", "upper",
                                                       "rel_half_width")}
    verdict = _strings(h["verdict"])
    out = {key: {**{k: float(v[i]) for k, v in cols.items()}, "verdict": verdict[i]}
           for i, key in enumerate(keys)}
    if "monte_carlo" in h:
        # each property's Monte Carlo range (files before it have none: no key)
        m = h["monte_carlo"]
        from_mc = set(filter(None, str(h.attrs.get("verdict_from_monte_carlo", ""))
                             .split(",")))
        for i, key in enumerate(keys):
            rng = {k: np.ravel(m[k][()])[i].item() for k in m}
            lo_b, up_b = (bool(rng.get(f"{side}_at_bound", 0)) for side in ("lower", "upper"))
            out[key]["monte_carlo"] = (None if not np.isfinite(rng.get("lower", np.nan)) else
                                       {**rng, "lower_at_bound": lo_b, "upper_at_bound": up_b})
            out[key]["verdict_from"] = "monte_carlo" if key in from_mc else "linearised"
    return out


#: the statement of a constant at a bound: files before stop 29 wrote it as an inequality
#: ("G13 <= 0.0001 E1 (0.0154 GPa)", "nu12 >= 0.95"), later ones name the limit ("stopped on
#: the search's lower limit, G13 = 0.0001 E1 (0.0154 GPa at the optimum)")
_BOUND_OLD = re.compile(r"(nu12|E1|E2|G12|G13|G23)\s*(<=|>=)\s*(.*)$")
_BOUND_NEW = re.compile(r"stopped on the search's (lower|upper) limit, "
                        r"(nu12|E1|E2|G12|G13|G23)\s*=\s*(.*)$")


def _bound_parts(text: str) -> tuple[str, str, str]:
    """(side, constant, the limit as written) of a ``bound_text``, ("", "", "") when it says
    neither form."""
    tail = text.rsplit(": ", 1)[-1] if text else ""
    m = _BOUND_NEW.search(tail)
    if m is not None:
        return m.group(1), m.group(2), m.group(3).strip()
    m = _BOUND_OLD.search(tail)
    if m is not None:
        k, op, rest = m.groups()
        return ("lower" if op == "<=" else "upper"), k, rest.strip()
    return "", "", ""


def bound_statement(text: str) -> tuple[str, str]:
    """(side, limit) of a ``bound_text``: side "lower" when the data push the constant below
    the search's limit, "upper" above it, "" when the text says neither; the limit as the
    text writes it, without the constant or an inequality sign. Both forms:
    "at its bound — not identified: G13 <= 0.0001 E1 (0.00286 GPa)" (files before stop 29)
    and "... stopped on the search's lower limit, G13 = 0.0001 E1 (0.00286 GPa at the
    optimum)" both give ("lower", "0.0001 E1 (0.00286 GPa...)")."""
    side, _, limit = _bound_parts(text)
    return side, limit


def bound_from_text(text: str) -> tuple[str, float]:
    """(side, limit SI) of a constant at its bound from its statement (either form of
    :func:`bound_statement`), for files written before /uncertainty held them as data
    (bound_side, bound_limit): "... G13 <= 0.0001 E1 (0.0154 GPa)" -> ("lower", 1.54e7);
    "nu12 >= 0.95" -> ("upper", 0.95); ("", NaN) when the text says neither."""
    side, k, rest = _bound_parts(text)
    if not side:
        return "", np.nan
    if k == "nu12":
        num = re.match(r"[-+0-9.eE]+", rest)
        return side, float(num.group()) if num else np.nan
    gpa = re.search(r"\(([-+0-9.eE]+) GPa[^)]*\)", rest)
    return side, float(gpa.group(1)) * 1e9 if gpa else np.nan


def _uncertainty(f) -> Uncertainty | None:
    if "uncertainty" not in f:
        return None
    u = f["uncertainty"]
    a = {k: decode(v) for k, v in u.attrs.items()}
    labels = _strings(u["labels"]) if "labels" in u else ()
    n = len(labels)

    def arr(key, default=np.nan):
        return np.ravel(u[key][()]) if key in u else np.full(n, default)

    def strs(key, default=""):
        return _strings(u[key]) if key in u else (default,) * n

    value, lower, upper = arr("value"), arr("lower"), arr("upper")
    rel, verdict, scale = arr("rel_half_width"), strs("verdict"), strs("scale", "linear")
    at_bound = arr("at_bound", False).astype(bool) if "at_bound" in u else np.zeros(n, bool)
    bound_text = strs("bound_text")
    if "bound_side" in u:
        bound_side, bound_limit = strs("bound_side"), arr("bound_limit")
    else:                                   # written before the limits were data
        parsed = [bound_from_text(t) if b else ("", np.nan)
                  for t, b in zip(bound_text, at_bound)]
        bound_side = tuple(s for s, _ in parsed)
        bound_limit = np.array([v for _, v in parsed], float)
    profile_bound, profile_text = arr("profile_bound"), strs("profile_text")
    # a profile that could not be made reached no end: files written before the fix stored
    # the scan's planned end there (hybrid CM's glass G13: 18.5 GPa), read as none
    profile_far = np.array([np.nan if profile_kind(b, t) == "none" else f for b, t, f in
                            zip(profile_bound, profile_text, arr("profile_far"))], float)
    flagged = set(filter(None, str(a.get("flagged", "")).split(",")))
    from_mc = set(filter(None, str(a.get("verdict_from_monte_carlo", "")).split(",")))
    intervals = []
    for j, lab in enumerate(labels):
        m, k = lab.rsplit(".", 1) if "." in lab else ("", lab)
        intervals.append(Interval(lab, m, k, float(value[j]), float(lower[j]), float(upper[j]),
                                  verdict[j], float(rel[j]), scale[j], bool(at_bound[j]),
                                  bound_text[j], bound_side[j], float(bound_limit[j]),
                                  lab in flagged, lab in from_mc, float(profile_bound[j]),
                                  profile_text[j], float(profile_far[j])))
    mc = None
    if "monte_carlo" in u:
        g = u["monte_carlo"]
        mc = {k: np.asarray(v[()]) for k, v in g.items()} | {
            k: decode(v) for k, v in g.attrs.items()}
    fc = u["fixed_check"].attrs if "fixed_check" in u else {}    # older files: none
    return Uncertainty(
        confidence=float(a.get("confidence", 0.95)), s2=float(a.get("s2", np.nan)),
        dof=float(a.get("dof", np.nan)), condition_number=float(a.get("condition_number", np.nan)),
        sigma_source=str(a.get("sigma_source", "")),
        well_determined=float(a.get("well_determined", 0.05)), weak=float(a.get("weak", 0.30)),
        intervals=tuple(intervals), notes=str(a.get("notes", "")), monte_carlo=mc,
        fixed=_label_list(a.get("fixed")), fixed_undetermined=_label_list(
            a.get("fixed_undetermined")), before_fixing=_before_fixing(u),
        fixed_widths=_fixed_widths(u), spread_counted=_label_list(a.get("spread_counted")),
        fixed_ranges=({lab: text for lab, text in zip(_strings(u["fixed_ranges"]["labels"]),
                                                      _strings(u["fixed_ranges"]["text"]))}
                      if "fixed_ranges" in u else {}),
        fixed_check=decode(fc.get("text", "")), fixed_rejected=bool(fc.get("rejected", False)),
        scale_used=decode(a.get("scale_used", "")),
        variance_factor=float(a.get("variance_factor", np.nan)),
        quantile=float(a.get("quantile", np.nan)),
        given_fixed=({lab: float(w) for lab, w in zip(
            labels, np.ravel(u["rel_half_width_given_fixed"][()]))}
            if "rel_half_width_given_fixed" in u else {}))


def _label_list(text) -> tuple[str, ...]:
    return tuple(x for x in str(text or "").split(",") if x)


def _fixed_widths(u) -> dict:
    """{label: (relative half-width, verdict, run)} of /uncertainty/fixed_undetermined."""
    if "fixed_undetermined" not in u:
        return {}
    g = u["fixed_undetermined"]
    labels = _strings(g["labels"])
    rel = np.ravel(g["rel_half_width"][()])
    verdict = _strings(g["verdict"])
    run = np.ravel(g["run"][()])
    return {lab: (float(rel[k]), verdict[k], int(run[k])) for k, lab in enumerate(labels)}


def _before_fixing(u) -> dict:
    """{label: (relative half-width, verdict)} of /uncertainty/before_fixing, {} without it."""
    if "before_fixing" not in u:
        return {}
    b = u["before_fixing"]
    labels = _strings(b["labels"]) if "labels" in b else ()
    rel = np.ravel(b["rel_half_width"][()]) if "rel_half_width" in b else np.full(len(labels),
                                                                                   np.nan)
    verdict = _strings(b["verdict"]) if "verdict" in b else ("",) * len(labels)
    return {lab: (float(rel[k]), verdict[k]) for k, lab in enumerate(labels)}


def _status(f) -> tuple[Status | None, str]:
    """(Status or None for a file that did not record one, the optimizer's outcome)."""
    a = f.attrs
    if "optimizer_status" not in a:               # schema 1: "status" is nlopt's outcome
        return None, _s(a.get("status", ""))
    reasons = ()
    if "status" in f and isinstance(f["status"], _group_type()):
        g = f["status"]
        codes = _strings(g["codes"]) if "codes" in g else ()
        texts = _strings(g["texts"]) if "texts" in g else ()
        reasons = tuple(Reason(c, t) for c, t in zip(codes, texts))
    return Status(_s(a.get("status", "")), reasons), _s(a["optimizer_status"])


def _group_type():
    import h5py

    return h5py.Group


def _damping(f) -> Damping | None:
    if "damping" not in f:
        return None
    g = f["damping"]
    data, ds_attrs = {}, {}
    for k, v in g.items():
        if isinstance(v, _group_type()):
            continue
        x = v[()]
        data[k] = _strings(v) if v.dtype.kind in "OSU" else np.asarray(x)
        ds_attrs[k] = {a: decode(y) for a, y in v.attrs.items()}
    mc = None
    if "monte_carlo" in g:
        m = g["monte_carlo"]
        mc = {k: np.asarray(v[()]) for k, v in m.items()} | {
            k: decode(v) for k, v in m.attrs.items()}
    return Damping({k: decode(v) for k, v in g.attrs.items()}, data, ds_attrs, mc)


def _mesh_check(f) -> dict | None:
    """/mesh_check as MeshCheck.as_dict's plain data (the warning and the constants beyond the
    limit derived from the stored shifts, as when written); None when the file has none."""
    if "mesh_check" not in f:
        return None
    from laminid_cli.meshcheck import MeshCheck

    g = f["mesh_check"]
    a = g.attrs
    arrays = {key: np.asarray(g[key][()]) for key in (
        "measured_mode", "model_mode", "fine_mode", "mac", "freq_hz", "fine_hz",
        "change_percent", "change_sigma", "shift", "shift_percent", "shift_half_width")}
    return MeshCheck(mesh=(int(a["nx"]), int(a["ny"])),
                     fine_mesh=(int(a["fine_nx"]), int(a["fine_ny"])),
                     labels=tuple(_strings(g["labels"])), limit=float(a["limit"]),
                     time_s=float(a.get("time_s", np.nan)), **arrays).as_dict()


def read_result(path) -> ResultFile:
    """Read an identification result (single or joint) into a :class:`ResultFile`.

    Raises
    ------
    ResultFileError
        The file is missing, not HDF5, not an identification result (the message names the
        command that makes one), of a newer schema version, or lacks a required group.
    """
    path = Path(path)
    with about_file(path, ResultFileError), _open_result(path) as (f, fmt, version):
        return _read_complete(f, path, fmt, version)


def _read_complete(f, path, fmt, version) -> ResultFile:
    """:func:`_read`, a missing group or attribute a ResultFileError naming it."""
    try:
        return _read(f, path, fmt, version)
    except KeyError as exc:
        raise ResultFileError(f"{path}: incomplete result file ({exc})") from exc
    except (ValueError, TypeError, IndexError, AttributeError, OverflowError) as exc:
        # what _arr/_num do not name: an attribute of the wrong type, a dataset where a
        # group is expected; a traceback before (UnicodeDecodeError is a ValueError)
        reason = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise ResultFileError(f"{path}: damaged or malformed result file "
                              f"({type(exc).__name__}: {reason})") from exc


@contextlib.contextmanager
def _open_result(path: Path):
    """(open file, format, schema version) of a result file whose format and version this
    laminid reads; ResultFileError otherwise (:func:`read_result`'s messages)."""
    from laminid_cli.h5open import format_of, open_h5

    if Path(path).suffix.lower() in (".yaml", ".yml") and Path(path).is_file():
        # a newcomer's slip: the specimen given where its result is meant ("not an HDF5 file
        # ... make one with laminid identify SPEC.yaml" left the lab to see it was the SPEC)
        raise ResultFileError(f"{path}: a specimen file, not an identification result; "
                              f"laminid identify {path} makes its result "
                              f"({Path(path).with_suffix('.result.h5')})")
    from laminid_cli.filekinds import HDF5_MAGIC

    try:
        with open(path, "rb") as fh:
            head = fh.read(len(HDF5_MAGIC))
    except OSError:                         # (missing, unreadable: open_h5 says which)
        head = b""
    if not head and Path(path).is_file() and Path(path).stat().st_size == 0:
        # (it was "not an HDF5 file, so not a laminid identification result", as of a file of
        # another kind: a 0-byte file is a copy or a transfer that did not finish)
        raise ResultFileError(f"{path}: the file is empty (0 bytes), a copy that did not "
                              "finish?; copy it again, or make it again with "
                              + MAKES_A_RESULT)
    if head == HDF5_MAGIC:
        # an HDF5 file h5py cannot open is damaged or cut short (a copy that did not finish),
        # not "not an HDF5 file ... make one with laminid identify", which sent the lab to
        # look for a wrong file rather than a broken one
        not_hdf5 = ("an HDF5 file that cannot be read ({exc}): damaged or incomplete (a copy "
                    "cut short?); copy it again, or make it again with " + MAKES_A_RESULT)
    else:
        not_hdf5 = ("not an HDF5 file, so not a laminid identification result; make one with "
                    + MAKES_A_RESULT)
    f = open_h5(path, ResultFileError, not_hdf5)
    with f:
        fmt = format_of(f)
        if fmt == "laminid-frf":             # laminid acquire's (or example_frf.py's) file
            raise ResultFileError(not_a_result_but_frf(path))
        if fmt == "laminid-modes":          # laminid modes -o: the model's modes only
            raise ResultFileError(
                f"{path}: a file of 'laminid modes' (the model's modes at the specimen's "
                "constants), not an identification result: 'laminid modes SPEC.yaml' prints "
                f"its table again, 'laminid export {path} -o modes.unv' writes its mode shapes; "
                f"a result is made with {MAKES_A_RESULT}")
        if not fmt and _plain_frf_file(f, path):
            # another tool's FRFs (a frequency and a complex FRF dataset, as fit-frf reads
            # them) were "not a laminid identification result (no 'format' attribute ...)"
            raise ResultFileError(not_a_result_but_frf(path))
        if fmt not in RESULT_FORMATS:
            what = f"a {fmt!r} file" if fmt else "no 'format' attribute"
            raise ResultFileError(f"{path}: not a laminid identification result ({what}; "
                                  f"expected format 'laminid-result'); make one with "
                                  f"{MAKES_A_RESULT}")
        try:
            version = int(f.attrs.get("schema_version", 1))
        except (TypeError, ValueError) as exc:
            raise ResultFileError(f"{path}: attribute schema_version "
                                  f"{f.attrs.get('schema_version')!r} is not a number") from exc
        if version not in READABLE_VERSIONS:
            raise ResultFileError(f"{path}: schema_version {version} is not readable by this "
                                  f"laminid (reads {', '.join(map(str, READABLE_VERSIONS))}); "
                                  "update laminid")
        check_declared_sizes(f, path)       # before any dataset is read
        yield f, fmt, version


def read_stored_summary(path) -> tuple[dict, dict]:
    """(summary, written) of a result file: the run's summary as ``identify --json`` printed
    it (/summary_json), and ``written`` = {created, laminid_version, command, format}.

    Raises
    ------
    ResultFileError
        As :func:`read_result` (the file read as it reads it, in the same opening); also a
        file written before results kept their summary, or whose /summary_json is not
        readable JSON.
    """
    import json

    path = Path(path)
    with about_file(path, ResultFileError), _open_result(path) as (f, fmt, version):
        _read_complete(f, path, fmt, version)     # a complete result, as read_result checks
        a = f.attrs
        written = {"created": _s(a.get("created", "")),
                   "laminid_version": _s(a.get("laminid_version", "")),
                   "command": _s(a.get("command", "")), "format": fmt}
        if "summary_json" not in f:
            raise ResultFileError(
                f"{path}: written by laminid {written['laminid_version'] or '(unknown)'} "
                "before result files kept what identify printed (no /summary_json); "
                f"'laminid report {path}' draws it, or identify the specimen again")
        try:
            summary = json.loads(decode(f["summary_json"][()]))
        except (ValueError, TypeError, OSError) as exc:
            raise ResultFileError(f"{path}: /summary_json is not readable JSON ({exc})") from exc
        if not isinstance(summary, dict):
            raise ResultFileError(f"{path}: /summary_json is not a summary (a JSON object)")
        # (not the paths laminid took from the file system, nor the warnings naming them: a
        # specimen in a folder 'bd\u202e' gave a result that show refused as damaged; show
        # prints them escaped, --json as read)
        found = non_printable_in(_without_paths(summary))
        if found is not None:
            where, text, bad = found
            raise ResultFileError(f"{path}: /summary_json, field '{escaped(where)}' "
                                  f"({text!r}): {bad} in it; the result file is damaged or "
                                  "was edited")
        # a reference range an earlier laminid stored as its midpoint: the range again
        if fmt == "laminid-joint-result":
            plates = summary.get("specimens")
            for key, g in f["specimens"].items():
                if isinstance(plates, dict) and isinstance(plates.get(_name(key, g)), dict) \
                        and "yaml" in g["specimen"]:
                    restate_reference_ranges(plates[_name(key, g)].get("reference"),
                                             _s(g["specimen"]["yaml"][()]))
        elif "yaml" in f["specimen"]:
            restate_reference_ranges(summary.get("reference"), _s(f["specimen"]["yaml"][()]))
    return summary, written


#: the keys of a stored summary (at any depth) whose text is a path from the file system or
#: names one (read_stored_summary): what laminid refuses in a name may be in a folder's name
_PATH_KEYS = ("path", "output", "warnings")


def _without_paths(value):
    """``value`` (a stored summary) without the items of :data:`_PATH_KEYS`."""
    if isinstance(value, dict):
        return {k: _without_paths(v) for k, v in value.items() if k not in _PATH_KEYS}
    if isinstance(value, list):
        return [_without_paths(v) for v in value]
    return value


def _read(f, path, fmt, version) -> ResultFile:
    joint = fmt == "laminid-joint-result"
    a = f.attrs
    if joint:
        plates = tuple(_plate(g, _name(key, g)) for key, g in f["specimens"].items())
        order = [x for x in _s(a.get("specimens", "")).split(",") if x]
        if sorted(order) == sorted(p.name for p in plates):          # the order of the run
            plates = tuple(sorted(plates, key=lambda p: order.index(p.name)))
        rms = float(a.get("rms_residual_percent", np.nan))
    else:
        plates = (_plate(f),)
        rms = plates[0].frequencies.rms_residual_percent
    sigmas = _frequency_sigmas(f)
    plates = tuple(dataclasses.replace(p, frequencies=dataclasses.replace(
        p.frequencies, sigma_hz=sigmas.get(p.name if joint else None))) for p in plates)
    status, opt_status = _status(f)
    free = {}
    for key, g in f["materials"].items():
        free[_name(key, g)] = tuple(x for x in _s(g.attrs.get("free", "")).split(",") if x)
    history = _history(f)
    # HDF5 lists groups alphabetically; the run's material order is that of the history labels
    order = list(dict.fromkeys(lab.rsplit(".", 1)[0] for lab in
                               (history.labels if history is not None else ())))

    def ordered(d):
        return dict(sorted(d.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order
                           else len(order)))
    return ResultFile(
        path=Path(path), format=fmt, schema_version=version, joint=joint,
        converged=bool(a.get("converged", False)), optimizer=_s(a.get("optimizer", "")),
        optimizer_status=opt_status, objective=float(a.get("objective", np.nan)),
        evaluations=int(a.get("evaluations", 0)), time_s=float(a.get("time_s", np.nan)),
        materials=ordered({m: {k: v for k, v in c.items() if k != "density"}
                           for m, c in _materials(f).items()}),
        initial=ordered(_materials(f, "initial")), free=ordered(free), history=history,
        rms_residual_percent=rms, plates=plates, status=status,
        uncertainty=_uncertainty(f), damping=_damping(f),
        warnings=_strings(f["warnings"]) if "warnings" in f else (),
        mesh_check=_mesh_check(f))
