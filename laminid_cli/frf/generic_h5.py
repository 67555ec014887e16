"""FRFs from a plain HDF5 file written by another tool (issue 12, interchange).

Other modal tools store FRFs in HDF5 without laminid's layout: one frequency dataset and one
complex FRF dataset, units as attributes, names and orientation their own. This reader finds
them:

- **frequency**: a 1-D real dataset (or n x 1, 1 x n as MATLAB writes a vector), at least 2
  values, finite, strictly increasing, >= 0; its ``units`` (or ``unit``, any case: ``Unit``)
  attribute, if any, must be a frequency unit (Hz, kHz, 1/s or rad/s; converted to Hz);
  without one, a kHz or rad/s in its name ("f_kHz", "omega_rad_s") is its unit, a name
  that reads as an angular frequency without a unit ("omega", "w") is refused, any other
  is Hz with a warning (``meta["warnings"]``: the file, the dataset, the range read and the
  attribute that states the unit), refused where its values end below
  :data:`~laminid_cli.frf.store.UNSTATED_FREQ_MIN_SPAN_HZ` (very likely kHz). A name such as
  ``freq``, ``frequency``, ``f_hz`` ranks first. Or an attribute of the FRF dataset, its
  group or the root named so (``/frf@frequency``; its unit in an attribute
  ``frequency_units`` beside it or in its name, else Hz with the warning), ranked after
  such a dataset.
- **FRF**: a complex dataset (HDF5 compound ``r``/``i`` as h5py and most tools write it, or
  ``real``/``imag`` as MATLAB v7.3 does, or ``re``/``im``), or two real datasets of one shape
  named as its parts (``frf_real`` + ``frf_imag``, ``H_re`` + ``H_im``: named ``frf``, ``H``),
  1-D of the frequency's length, or 2-D with one axis of that length: ``(n_points, n_freq)``
  or ``(n_freq, n_points)`` (either orientation), or more axes of length 1 beside those
  (``(n_points, 1, n_freq)``, one reference of a MIMO layout; more references are refused
  by name). Its ``units`` attribute becomes the FRF
  units (without one: not stated, None, with a note).
- **coherence** (optional): a real dataset whose name contains ``coh``, of the FRF's shape.
- **units variables** (optional): a top-level text (MATLAB char, HDF5 string) named
  ``freq_unit`` (the frequency's, where its dataset has no units attribute), ``frf_unit``
  (the FRFs'), ``units``/``unit`` (either, or both "Hz, g/N"): :func:`said_units`. A MAT-file
  of version 4 or 5 (no HDF5) is read by :func:`read_mat_frf` into an HDF5 file in memory.
- **point labels** (optional): a top-level variable ``labels`` (or ``points``,
  ``point_labels``, ...: :data:`POINT_LABEL_VARIABLES`, any case) of one text per point, a
  MATLAB cell array of char (v7.3: references into '#refs#'; v5), an HDF5 string array or a
  char matrix of a label a row; without one the points are numbered 1, 2, ...

When several frequency/FRF pairs fit, the error lists them and the options to choose
(``--freq-dataset``, ``--frf-dataset`` of ``fit-frf``); a named path that is missing or does
not fit says why. :func:`read_any_frf_h5` reads laminid's own file with
:func:`~laminid_cli.frf.store.read_frf_h5` and every other HDF5 file with this reader.

h5py is imported inside the functions so importing this module stays cheap.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laminid_cli.errors import FrfError
from laminid_cli.frf.store import (FORMAT, MAX_FREQ_LINES, MAX_FRF_VALUES, FrfSet,
                                   check_frf_size,
                                   nonfinite_dc_lines, nonfinite_dc_warning,
                                   probe_hdf5_file, read_frf_h5, read_hdf5,
                                   unit_not_stated_note, unstated_freq_warning,
                                   validate_frf_arrays)

#: frequency units accepted in a ``units`` attribute -> factor to Hz
FREQ_UNITS = {"hz": 1.0, "hertz": 1.0, "1/s": 1.0, "s^-1": 1.0, "khz": 1e3,
              "rad/s": 1.0 / (2.0 * math.pi), "rad/sec": 1.0 / (2.0 * math.pi)}
#: other spellings of those units (spaces and case already ignored): "1/sec", "rad s^-1"
_FREQ_SPELLINGS = {"1/sec": "1/s", "sec^-1": "s^-1", "s-1": "s^-1", "rads^-1": "rad/s",
                   "rad*s^-1": "rad/s", "rad.s^-1": "rad/s", "rads-1": "rad/s"}
_FREQ_NAME = re.compile(r"(^|[^a-z])(f|freq|frequency|frequencies|f_?hz|freq_?hz|hz)"
                        r"([^a-z]|$)", re.I)


@dataclass(frozen=True)
class _Dataset:
    path: str
    shape: tuple[int, ...]
    kind: str          # numpy dtype kind: "f", "i", "u", "c"
    units: str | None
    #: a complex FRF stored as two real datasets: (real part's path, imaginary part's path)
    parts: tuple[str, str] | None = None

    @property
    def name(self) -> str:
        return self.path.rsplit("@", 1)[-1] if self.is_attribute else self.path.rsplit("/", 1)[-1]

    @property
    def is_attribute(self) -> bool:
        """A frequency vector stored as an attribute ("/frf@frequency": attribute
        ``frequency`` of ``/frf``), as some tools keep the axis with its FRF."""
        return "@" in self.path

    def describe(self) -> str:
        shape = " x ".join(str(n) for n in self.shape)
        units = f", units {self.units!r}" if self.units else ""
        where = f"'{self.parts[0]}' + '{self.parts[1]}'" if self.parts else f"'{self.path}'"
        return f"{where} ({shape}{units})"

    @property
    def length(self) -> int | None:
        """The length of a vector: a 1-D dataset's, or a 2-D one's with a single row or column
        (MATLAB writes every vector as n x 1 or 1 x n); None for a matrix."""
        if len(self.shape) == 1:
            return self.shape[0]
        if len(self.shape) == 2 and 1 in self.shape:
            return max(self.shape)
        return None


def _text(v) -> str:
    if isinstance(v, bytes):
        return v.decode(errors="replace")
    if isinstance(v, np.ndarray) and v.size == 1:
        return _text(v.reshape(-1)[0])
    return str(v)


def _units(ds) -> str | None:
    """The ``units`` (or ``unit``) attribute of ``ds``, in any case: ``Unit``, as some tools
    write it, was not read (its frequency read as unstated Hz with a warning, its FRF unit
    "not stated")."""
    keys = {str(k).lower(): k for k in ds.attrs.keys()}
    for key in ("units", "unit"):
        if key in keys:
            return _text(ds.attrs[keys[key]]).strip()
    return None


#: field names of a compound dataset holding complex numbers
_COMPLEX_FIELDS = (("r", "i"), ("real", "imag"), ("re", "im"))


def _complex_fields(dtype):
    names = tuple(n.lower() for n in (dtype.names or ()))
    for pair in _COMPLEX_FIELDS:
        if names == pair:
            return dtype.names
    return None


def _read(ds) -> np.ndarray:
    """A dataset's values; a compound (real, imag) pair as complex."""
    value = ds[()]
    fields = _complex_fields(ds.dtype)
    if fields:
        return value[fields[0]].astype(float) + 1j * value[fields[1]].astype(float)
    return value


def _datasets(f) -> list[_Dataset]:
    import h5py

    found = []

    def visit(name, obj):
        if not isinstance(obj, h5py.Dataset) or _is_matlab_char(obj):
            return              # (a MATLAB text, uint16 codes: no frequency, no FRF)
        # (n_points, 1, n_freq) of one reference, as MIMO layouts store it: its 2-D squeeze
        shape = tuple(obj.shape) if obj.ndim <= 2 else tuple(n for n in obj.shape if n != 1)
        if len(shape) not in (1, 2):
            return
        kind = "c" if _complex_fields(obj.dtype) else obj.dtype.kind
        if kind in "fiuc":
            found.append(_Dataset("/" + name, shape, kind, _units(obj)))

    f.visititems(visit)
    return found + _real_imag_pairs(found) + _attribute_axes(f)


def _is_matlab_char(ds) -> bool:
    """Whether ``ds`` is a MATLAB char array as save -v7.3 writes one: UTF-16 code units
    (uint16) with the attribute MATLAB_class 'char' (MathWorks, "MAT-File Versions": v7.3
    is HDF5; the class attribute as MATLAB writes it)."""
    return _text(ds.attrs.get("MATLAB_class", b"")).strip() == "char"


def _variable_text(ds) -> str | None:
    """The text of a dataset that holds one: a MATLAB char array (its rows joined by ', '),
    an HDF5 string (or a 1-element array of one); None for any other dataset."""
    if _is_matlab_char(ds):
        if "MATLAB_empty" in ds.attrs:
            return ""
        codes = np.atleast_2d(np.asarray(ds[()])).T     # MATLAB's rows x columns
        rows = ["".join(chr(int(c)) for c in row) for row in codes.astype(np.uint16)]
        return ", ".join(r.strip() for r in rows)
    if ds.dtype.kind in "SOU" and ds.size == 1:
        return _text(ds[()]).strip()
    return None


#: the names (any case) of a text variable that gives the frequency's unit, the FRFs', or
#: either (or both: "Hz, g/N"), at the top of a MAT-file or plain HDF5 file: MATLAB cannot
#: write an attribute, so a lab saves ``units = 'kHz'`` beside ``f`` and ``H``; it was not
#: read, a kHz or rad/s axis read as Hz (with no more than the unstated-unit warning)
FREQ_UNIT_VARIABLES = ("freq_unit", "freq_units", "frequency_unit", "frequency_units",
                       "f_unit", "f_units", "funit", "frequnit")
FRF_UNIT_VARIABLES = ("frf_unit", "frf_units", "h_unit", "h_units")
ANY_UNIT_VARIABLES = ("units", "unit")


def _is_frf_unit(text: str) -> bool:
    """A text that reads as an FRF's unit: a response over a force ("g/N", "m s^-2 N^-1")."""
    return "/" in text or "-1" in text


def said_units(f, path) -> tuple[tuple[str, str, float] | None, str | None]:
    """The units the top-level text variables of ``f`` give (:data:`FREQ_UNIT_VARIABLES`,
    :data:`FRF_UNIT_VARIABLES`, :data:`ANY_UNIT_VARIABLES`): ((variable, unit, factor to
    Hz) of the frequency or None, the FRFs' unit or None). FrfError naming the variable for
    a frequency unit laminid does not read ("mm", "cycles"), and for a ``units`` that is
    neither a frequency's nor an FRF's: a frequency in an unknown unit is not read as Hz."""
    import h5py

    texts = {}
    for name, obj in f.items():
        if isinstance(obj, h5py.Dataset):
            text = _variable_text(obj)
            if text is not None:
                texts.setdefault(name.lower(), (name, text))
    freq = frf = None
    for key in FREQ_UNIT_VARIABLES:
        if key in texts:
            name, text = texts[key]
            freq = (name, text, _unit_variable_factor(path, name, text))
            break
    for key in FRF_UNIT_VARIABLES:
        if key in texts:
            frf = texts[key][1] or None
            break
    for key in ANY_UNIT_VARIABLES:
        if key not in texts:
            continue
        name, text = texts[key]
        items = [v.strip() for v in re.split(r"[,;]", text)]
        if len(items) == 2 and freq_unit_factor(items[0]) is not None \
                and _is_frf_unit(items[1]):                # "Hz, g/N"
            freq = freq or (name, items[0], freq_unit_factor(items[0]))
            frf = frf or items[1]
        elif len(items) == 1 and freq_unit_factor(text) is not None:
            freq = freq or (name, text, freq_unit_factor(text))
        elif len(items) == 1 and _is_frf_unit(text):
            frf = frf or text
        elif text:
            raise FrfError(f"{path}: variable {name!r} is {text!r}: neither a frequency unit "
                           "laminid reads (Hz, kHz, rad/s, 1/s) nor an FRF's (a response "
                           "over a force, 'g/N'); name the frequency's 'freq_unit' and the "
                           "FRFs' 'frf_unit'")
        break
    return freq, frf


def _unit_variable_factor(path, name: str, text: str) -> float:
    factor = freq_unit_factor(text) if text else None
    if factor is None:
        raise FrfError(f"{path}: variable {name!r} is {text!r}, not a frequency unit laminid "
                       "reads (Hz, kHz, rad/s, 1/s); the frequencies would be read in the "
                       "wrong unit")
    return factor


def _attribute_axes(f) -> list[_Dataset]:
    """Frequency vectors stored as attributes of a dataset or group (``/frf@frequency``):
    numeric, 1-D (or n x 1), at least 2 values, named as a frequency (``freq``,
    ``frequency``, ``f_Hz``, ``freq_kHz``, ``omega_rad_s``); their unit from an attribute
    ``<name>_units`` (or ``_unit``, any case) beside them, else from the name. Such a file
    was refused: "no frequency axis matches an FRF dataset; frequency candidates: none"."""
    import h5py

    objects = [("", f)]
    f.visititems(lambda name, obj: objects.append(("/" + name, obj)))
    found = []
    for path, obj in objects:
        if not isinstance(obj, (h5py.Dataset, h5py.Group)):
            continue
        keys = {str(k).lower(): k for k in obj.attrs.keys()}
        for key in obj.attrs.keys():
            name = str(key)
            if not (_FREQ_NAME.search(name) or _ANGULAR_NAME.search(name)
                    or re.search(r"(?i)(?<![a-z])(khz|rad[/_ ]?s)(?![a-z])", name)):
                continue
            try:
                value = np.asarray(obj.attrs[key])
            except (OSError, TypeError, ValueError):   # an attribute h5py cannot read
                continue
            if value.dtype.kind not in "fiu" or value.ndim not in (1, 2) or value.size < 2 \
                    or (value.ndim == 2 and 1 not in value.shape):
                continue
            unit = next((obj.attrs[keys[k]] for k in (f"{name.lower()}_units",
                                                      f"{name.lower()}_unit") if k in keys),
                        None)
            found.append(_Dataset(f"{path or ''}@{name}", tuple(value.shape), value.dtype.kind,
                                  None if unit is None else _text(unit).strip()))
    return found


def _values(f, path: str) -> np.ndarray:
    """The values of dataset ``path``, or of the attribute ``path`` names (``/frf@frequency``,
    ``@freq`` of the root)."""
    if "@" in path:
        where, name = path.rsplit("@", 1)
        return np.asarray(f[where or "/"].attrs[name])
    return f[path][()]


#: name endings of the real and imaginary parts of a complex FRF stored as two real datasets
#: (``frf_real`` + ``frf_imag``, ``H_re`` + ``H_im``, a group's ``real`` + ``imag``)
_PART_SUFFIXES = (("_real", "_imag"), ("_re", "_im"), (".re", ".im"), ("real", "imag"))


def _real_imag_pairs(found) -> list[_Dataset]:
    """One complex candidate per pair of real datasets of one shape named as the real and
    imaginary parts of one thing; its path is the common stem (``/frf`` of ``/frf_real`` and
    ``/frf_imag``, the group of ``real`` and ``imag``), unless a dataset has that path."""
    by_path = {d.path.lower(): d for d in found}
    pairs = []
    for d in found:
        if d.kind not in "fiu":
            continue
        for re_end, im_end in _PART_SUFFIXES:
            if not d.path.lower().endswith(re_end):
                continue
            stem = d.path[:-len(re_end)]
            im = by_path.get((stem + im_end).lower())
            path = stem.rstrip("/") or "/"
            if im is not None and im.kind in "fiu" and im.shape == d.shape \
                    and path.lower() not in by_path:
                pairs.append(_Dataset(path, d.shape, "c", d.units, parts=(d.path, im.path)))
            break
    return pairs


#: a frequency's name that reads as an angular frequency (omega, w, "angular"): without a
#: unit, Hz or rad/s cannot be told, and rad/s read as Hz puts every mode 2 pi too high
_ANGULAR_NAME = re.compile(r"(?<![a-z])(omega|w|angular|ang_?freq)(?![a-z])", re.I)


def name_freq_unit(name: str, where: str) -> str | None:
    """The frequency unit a name states (:data:`FREQ_UNITS` key: "khz" in "f_kHz", "rad/s" in
    "omega_rad_s", "hz" in "freq_Hz"); None where it states none ("f", "freq"). FrfError
    (``where`` names the dataset or column, and how to give the unit) for a name that reads as
    an angular frequency without saying which unit ("omega", "w": read as Hz, a rad/s axis
    put every natural frequency 2 pi = 6.28 times too high, with exit 0)."""
    low = name.lower()
    if re.search(r"(?<![a-z])khz(?![a-z])", low):
        return "khz"
    if re.search(r"(?<![a-z])rad[/_ ]?(s|sec)(?![a-z])", low):
        return "rad/s"
    if re.search(r"(?<![a-z])hz(?![a-z])", low):
        return "hz"
    if _ANGULAR_NAME.search(low):
        raise FrfError(f"{where}: the frequency {name!r} reads as an angular frequency but "
                       "says no unit: Hz or rad/s cannot be told (rad/s read as Hz puts every "
                       "mode 2 pi = 6.28 times too high)")
    return None


def freq_unit_factor(unit: str) -> float | None:
    """Factor to Hz of a frequency unit as written ("Hz", "rad/s", "k Hz", "[Hz]", "rad s^-1";
    spaces, case and one pair of enclosing brackets ignored), None when it is not one of
    :data:`FREQ_UNITS`. A units attribute '[Hz]' made its dataset no axis, and the file was
    refused with "frequency candidates: none"."""
    key = unbracketed(unit.replace(" ", "").lower())
    return FREQ_UNITS.get(_FREQ_SPELLINGS.get(key, key))


def unbracketed(text: str) -> str:
    """``text`` without one pair of enclosing brackets, as a unit is written in a header or
    a comment line ("[Hz]", "(g/N)"; a text of two characters or fewer as it is)."""
    if len(text) > 2 and text[0] + text[-1] in ("[]", "()"):
        return text[1:-1]
    return text


def _freq_factor(units: str | None) -> float | None:
    """Factor to Hz, 1 when no units attribute, None when the units are not a frequency."""
    if units is None or units == "":
        return 1.0
    return freq_unit_factor(units)


def _is_axis(f, d: _Dataset) -> bool:
    if d.length is None or d.length < 2 or d.kind == "c" or _freq_factor(d.units) is None \
            or d.length > MAX_FREQ_LINES:       # (not read: 10**9 lines were 7.5 GiB)
        return False
    x = np.asarray(_values(f, d.path), dtype=float).reshape(-1)
    return bool(np.all(np.isfinite(x)) and x[0] >= 0 and np.all(np.diff(x) > 0))


def _fits(frf: _Dataset, n: int) -> bool:
    return (len(frf.shape) == 1 and frf.shape[0] == n) or \
        (len(frf.shape) == 2 and n in frf.shape)


def _rank(d: _Dataset) -> int:
    """0 for a dataset named or labelled as a frequency, 1 for a frequency attribute, 2
    otherwise."""
    if d.is_attribute:
        return 1
    return 0 if _FREQ_NAME.search(d.name) or d.units else 2


def _listing(datasets, limit: int = 12) -> str:
    shown = ", ".join(d.describe() for d in datasets[:limit]) or "none"
    more = len(datasets) - limit
    return shown + (f" and {more} more" if more > 0 else "")


def _choose(path: Path, f, datasets, freq_path, frf_path):
    by_path = {d.path: d for d in datasets}

    def named(p, what):
        key = p.strip() if p.strip().startswith("@") else "/" + p.strip("/")
        if key not in by_path:
            raise FrfError(f"{path}: no numeric 1-D/2-D dataset {key!r} for the {what}; "
                           f"datasets: {_listing(datasets)}")
        return by_path[key]

    axes = [d for d in datasets if _is_axis(f, d)]
    frfs = [d for d in datasets if d.kind == "c"]
    if freq_path is not None:
        d = named(freq_path, "frequency")
        if not _is_axis(f, d):
            raise FrfError(f"{path}: dataset {d.describe()} is not a frequency axis (1-D, "
                           "finite, strictly increasing, >= 0, units Hz/kHz/1/s/rad/s)")
        axes = [d]
    if frf_path is not None:
        d = named(frf_path, "FRF")
        if d.kind != "c":
            raise FrfError(f"{path}: dataset {d.describe()} is not complex; the FRF must be "
                           "a complex dataset (HDF5 compound of r and i)")
        frfs = [d]
    if not frfs:
        more = _many_axes(f)
        raise FrfError(f"{path}: not a laminid FRF file and no complex dataset (FRF) in it; "
                       f"datasets: {_listing(datasets)}" + (
                           f"; complex datasets of more than 2 axes: {more} (laminid reads "
                           "one reference's FRFs, points x lines: store each reference's as "
                           "a 2-D dataset, H[:, 0, :])" if more else ""))
    pairs = [(a, h) for a in axes for h in frfs if _fits(h, a.length)]
    if not pairs:
        # a frequency set aside for its units attribute is named with it: the message said
        # only "frequency candidates: none" beside a '/freq' of the FRF's length
        aside = [d for d in datasets if d.units and d.kind != "c" and d.length
                 and _freq_factor(d.units) is None and _FREQ_NAME.search(d.name)]
        why = _not_an_axis(f, [d for d in datasets if d not in aside and d not in axes
                               and not d.is_attribute and _FREQ_NAME.search(d.name)])
        raise FrfError(
            f"{path}: no frequency axis matches an FRF dataset; frequency candidates: "
            f"{_listing(axes)}; FRF candidates: {_listing(frfs)} (an FRF axis must have the "
            "frequency's length)" + (
                f"; set aside for a units attribute that is no frequency unit laminid reads "
                f"({', '.join(FREQ_UNITS)}): {_listing(aside)}" if aside else "") + why)
    if len(pairs) > 1:
        best = min(_rank(a) for a, _ in pairs)
        pairs = [(a, h) for a, h in pairs if _rank(a) == best]
    if len(pairs) > 1:
        listing = "; ".join(f"frequency {a.describe()} + FRF {h.describe()}" for a, h in pairs)
        raise FrfError(f"{path}: several frequency/FRF dataset pairs fit: {listing}; choose "
                       "one with --freq-dataset PATH and --frf-dataset PATH")
    return pairs[0]


def _not_an_axis(f, named) -> str:
    """Why datasets named as a frequency ('/freq') are no axis, for the message that finds
    none ('frequency candidates: none' beside a '/freq' of negative or NaN values left the
    lab to guess): "; '/freq' is no axis: it starts below 0 Hz (-2000)"."""
    import h5py

    said = []
    for d in named[:3]:
        obj = f.get(d.path)
        if not isinstance(obj, h5py.Dataset):
            continue
        if d.length is None or d.kind == "c" or d.units:
            continue                # a matrix, an FRF ('freq_response'), units said above
        if d.length > MAX_FREQ_LINES:
            said.append(f"'{d.path}' is no axis: {d.length} lines, more than laminid reads "
                        f"({MAX_FREQ_LINES})")
            continue
        x = np.asarray(obj[()], dtype=float).reshape(-1)
        if x.size < 2:
            reason = f"{x.size} value(s), fewer than 2"
        elif not np.all(np.isfinite(x)):
            reason = f"NaN or inf at index {int(np.argmin(np.isfinite(x)))}"
        elif x[0] < 0:
            reason = f"it starts below 0 Hz ({x[0]:g})"
        else:
            k = int(np.argmin(np.diff(x) > 0))
            reason = f"not increasing at index {k + 1} ({x[k]:g}, then {x[k + 1]:g})"
        said.append(f"'{d.path}' is no axis: {reason}")
    return "".join(f"; {s}" for s in said)


def _many_axes(f) -> str:
    """The complex datasets of more than 2 axes other than 1 (``'/H' (4 x 2 x 2848)``, a
    MIMO test's outputs x references x lines), for the message that finds no FRF."""
    import h5py

    found = []

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and obj.ndim > 2 and (
                _complex_fields(obj.dtype) or obj.dtype.kind == "c"):
            found.append(f"'/{name}' ({' x '.join(str(n) for n in obj.shape)})")

    f.visititems(visit)
    return ", ".join(found)


def _orient(values: np.ndarray, n_freq: int) -> np.ndarray:
    """(n_points, n_freq) from a 1-D or 2-D array with one axis of length n_freq."""
    values = np.atleast_2d(values)
    if values.shape[1] == n_freq:
        return values
    return values.T


def read_generic_frf_h5(path, freq_dataset: str | None = None,
                        frf_dataset: str | None = None) -> FrfSet:
    """Read FRFs from a plain HDF5 file (see the module docstring). Raises :class:`FrfError`."""
    path = Path(path)
    return read_hdf5(path, lambda f: _read_generic(f, path, freq_dataset, frf_dataset),
                     "HDF5 FRF file")


def _read_generic(f, path: Path, freq_dataset, frf_dataset) -> FrfSet:
    datasets = _datasets(f)
    axis, frf_d = _choose(path, f, datasets, freq_dataset, frf_dataset)
    if axis.is_attribute:
        owner = axis.path.rsplit("@", 1)[0] or "/"
        what = f"attribute {axis.name!r} of '{owner}' (no {axis.name}_units attribute beside it)"
        target = f"['{owner}'].attrs['{axis.name}_units']"      # where its unit would go
    else:
        what = f"dataset '{axis.path}' (no units attribute)"
        target = f"['{axis.path}'].attrs['units']"
    how = f"h5py.File('{path}', 'r+'){target} = 'kHz' (or 'rad/s')"
    if path.suffix.lower() == ".mat":
        how = (f"save a text variable freq_unit = 'kHz' (or 'rad/s') beside '{axis.name}' "
               "in the MAT-file")
        target = ""
    said_freq, said_frf = said_units(f, path)
    if said_freq is not None:
        _check_said_unit(path, axis, said_freq)
    if axis.units:
        factor, stated = _freq_factor(axis.units), True
    elif said_freq is not None:
        factor, stated = said_freq[2], True
    else:
        unit = name_freq_unit(
            axis.name, f"{path}: {what.removesuffix(')')}; give it one, 'Hz' or 'rad/s': "
                       + (f"h5py.File(file, 'r+'){target} = 'rad/s')" if target else
                          "a text variable freq_unit = 'rad/s' beside it)"))
        factor, stated = (1.0 if unit is None else FREQ_UNITS[unit]), unit is not None
    n_points = math.prod(frf_d.shape) // axis.length
    check_frf_size(n_points, axis.length, f"{path}: '{frf_d.path}'")   # before reading it
    freq = np.asarray(_values(f, axis.path), dtype=float).reshape(-1) * factor
    if frf_d.parts:
        values = np.asarray(f[frf_d.parts[0]][()], dtype=float) \
            + 1j * np.asarray(f[frf_d.parts[1]][()], dtype=float)
    else:
        values = np.asarray(_read(f[frf_d.path]), dtype=complex)
    frf = _orient(values.reshape(frf_d.shape), freq.size)
    coherence = None
    for d in datasets:
        if "coh" in d.name.lower() and d.kind in "fiu" and d.shape == frf_d.shape:
            coherence = _orient(np.asarray(f[d.path][()], dtype=float).reshape(d.shape),
                                freq.size)
            break
    units = frf_d.units or said_frf or None
    warnings = []
    dc = nonfinite_dc_lines(freq, frf.T) if np.ndim(frf) == 2 else 0  # (points, lines)
    if dc:
        warnings.append(nonfinite_dc_warning(path, dc))
        freq, frf = freq[dc:], frf[:, dc:]
        coherence = None if coherence is None else coherence[..., dc:]
    validate_frf_arrays(freq, frf, coherence, source=str(path))
    labels = point_labels(f, path, frf.shape[0], frf_d) \
        or tuple(str(i + 1) for i in range(frf.shape[0]))
    meta = {"frequency_dataset": axis.path, "frf_dataset": frf_d.path}
    if not stated:
        # neither a units attribute nor a unit in the name ("f", "freq"): Hz, said, and
        # refused where it ends below 100 (kHz read as Hz: every mode 1000 times too low)
        warnings.append(unstated_freq_warning(
            f"{path}: {what}", freq, f"give it one: {how}",
            f"a {axis.name}_units attribute 'Hz'" if axis.is_attribute
            else "a units attribute 'Hz'" if target else "a variable freq_unit = 'Hz'"))
    if warnings:
        meta["warnings"] = warnings
    if units is None:
        where = frf_d.parts[0] if frf_d.parts else frf_d.path
        meta["notes"] = [unit_not_stated_note(path, f"no 'units' attribute on '{where}'"
                                              + ("" if target else " nor a variable frf_unit"))]
    return FrfSet(freq=freq, frf=frf, coherence=coherence, labels=labels, units=units,
                  source=str(path), meta=meta)


def _check_said_unit(path, axis: _Dataset, said: tuple[str, str, float]) -> None:
    """FrfError where a units variable contradicts the unit the axis states itself (its
    units attribute, or its name: "f_kHz" beside units = 'Hz')."""
    name, text, factor = said
    own = axis.units if axis.units else None
    if own is None:
        try:
            own = name_freq_unit(axis.name, "")
        except FrfError:            # "omega": the variable says which
            own = None
    if own is None or _freq_factor(own) is None:
        return
    if not math.isclose(_freq_factor(own), factor, rel_tol=1e-12):
        source = "its units attribute" if axis.units else "its name"
        raise FrfError(f"{path}: variable {name!r} gives the frequency in {text!r}, "
                       f"{source} in {own!r} ('{axis.path}'): which is meant cannot be told")


#: the names (any case) of a top-level variable of texts, one per point, that gives the
#: points' labels ("1+Z", "tip"); without one the points are numbered 1, 2, ...
POINT_LABEL_VARIABLES = ("labels", "label", "point_labels", "point_label", "point_names",
                         "points")
#: longest point label read from a MAT-file or plain HDF5 file (a longer text: refused)
MAX_LABEL_CHARS = 200


def point_labels(f, path, n_points: int, frf_d: _Dataset) -> tuple[str, ...] | None:
    """The point labels of the top-level variable named as such (:data:`POINT_LABEL_VARIABLES`)
    when it holds texts: a MATLAB cell array of char (save -v7.3: a dataset of HDF5 object
    references to char arrays in the group '#refs#', its attribute MATLAB_class 'cell'; a
    v5 MAT-file's cell as :func:`_put_variable` stores it), an HDF5 string array, or a
    MATLAB char matrix of one label a row. None without such a variable, or one of numbers
    (point numbers) or a single text beside several points (a title): the points are then
    numbered 1, 2, ... FrfError naming the variable where it is a cell of anything but
    texts, holds an empty text, or another count of texts than the FRF has points (a cell of
    labels was not read: the FRFs were numbered whatever it said)."""
    import h5py

    named = [(name, obj) for name, obj in f.items() if isinstance(obj, h5py.Dataset)
             and name.lower() in POINT_LABEL_VARIABLES]
    if not named:
        return None
    name, ds = named[0]
    where = f"{path}: variable {name!r}"
    cell = h5py.check_ref_dtype(ds.dtype) is not None or "laminid_cell" in ds.attrs
    if "laminid_cell" in ds.attrs and ds.attrs["laminid_cell"]:     # a v5 cell of others
        raise FrfError(f"{where} is a cell array whose {_text(ds.attrs['laminid_cell'])}; "
                       "laminid reads a cell array of texts, one per point, as the point "
                       "labels")
    # (a MATLAB char matrix of r rows, c columns: HDF5 dimensions (c, r))
    count = ds.size if ds.dtype.kind in "SOU" or cell else \
        ds.shape[-1] if _is_matlab_char(ds) and ds.ndim == 2 else 0
    if not cell and (count <= 1 < n_points or not count
                     or not (ds.dtype.kind in "SOU" or _is_matlab_char(ds))
                     or "MATLAB_empty" in ds.attrs):
        return None                      # numbers, or one text beside several points
    if count != n_points:
        what = f"a cell array of {count} entries" if cell else f"a list of {count} texts"
        raise FrfError(f"{where} is {what}, the FRF {frf_d.describe()} has "
                       f"{n_points} points: which label goes with which point cannot be "
                       "told; give one text per point")
    if h5py.check_ref_dtype(ds.dtype) is not None:
        # MATLAB's column-major order is h5py's C order of the reversed dimensions
        labels = []
        for k, ref in enumerate(np.asarray(ds[()]).reshape(-1), start=1):
            try:
                target = f[ref] if ref else None
            except (ValueError, KeyError, OSError):     # a reference to nothing readable
                target = None
            if not isinstance(target, h5py.Dataset) or not _is_matlab_char(target):
                raise FrfError(f"{where} is a cell array whose entry {k} is no text; laminid "
                               "reads a cell array of texts, one per point, as the point "
                               "labels")
            if target.size > MAX_LABEL_CHARS:
                raise FrfError(f"{where}: entry {k} holds {target.size} characters, more "
                               f"than a point label laminid reads ({MAX_LABEL_CHARS})")
            labels.append(_variable_text(target))
    elif ds.dtype.kind in "SOU":
        if ds.dtype.itemsize > 4 * MAX_LABEL_CHARS:          # fixed-length texts, not read
            raise FrfError(f"{where}: texts of {ds.dtype.itemsize} bytes, more than a point "
                           f"label laminid reads ({MAX_LABEL_CHARS} characters)")
        labels = [_text(x).strip() for x in np.asarray(ds[()]).reshape(-1)]
    else:                                           # a char matrix, one label a row
        if ds.size > MAX_LABEL_CHARS * n_points:
            raise FrfError(f"{where}: {ds.size} characters, more than {n_points} point "
                           f"labels of {MAX_LABEL_CHARS} hold")
        codes = np.atleast_2d(np.asarray(ds[()])).T                 # MATLAB's rows x columns
        labels = ["".join(map(chr, row)).strip() for row in codes.astype(np.uint16)]
    empty = next((k for k, t in enumerate(labels, start=1) if not t), None)
    if empty is not None:
        raise FrfError(f"{where}{' is a cell array whose' if cell else ':'} entry {empty} is "
                       "an empty text, where a point label is expected")
    return tuple(labels)


def read_mat_frf(path, freq_dataset: str | None = None,
                 frf_dataset: str | None = None, probe: bool = True) -> FrfSet:
    """FRFs from a MATLAB MAT-file of version 4 or 5 (MATLAB's save without '-v7.3',
    scipy.io.savemat; not HDF5), read with scipy.io.loadmat and then as a plain HDF5 file
    (:func:`_read_generic`, here an HDF5 file in memory): numeric variables (those of a
    struct as its group's), a char variable as text (units, :func:`said_units`), a cell
    array of texts as a string list (point labels, :func:`point_labels`); other cells are
    left out. FrfError naming the file for one scipy cannot read; with ``probe``
    the file is read first in a child process (:func:`~laminid_cli.frf.store.probe_hdf5_file`):
    scipy's reader crashed this process (SIGSEGV) on a damaged file, as libhdf5 can."""
    import io as _io
    import struct
    import zlib

    import h5py
    import scipy.io

    path = Path(path)
    if path.stat().st_size == 0:
        raise FrfError(f"{path}: the file is empty (0 bytes), not a MAT-file")
    if probe:
        probe_hdf5_file(path, reader="read_mat_frf", module="laminid_cli.frf.generic_h5",
                        library="scipy's MAT-file reader")
    try:
        # each variable's size from its header first (scipy.io.whosmat): one larger than
        # laminid reads (a compressed one of 10**8 zeros is 150 kB on disk) is left out,
        # not decompressed into memory; named where no FRF is found
        sizes = {name: math.prod(shape) for name, shape, _ in scipy.io.whosmat(path)}
        big = [f"'{n}' ({n_values} values)" for n, n_values in sizes.items()
               if n_values > MAX_FRF_VALUES]
        variables = scipy.io.loadmat(path, squeeze_me=False, chars_as_strings=True,
                                     variable_names=[n for n, n_values in sizes.items()
                                                     if n_values <= MAX_FRF_VALUES])
    except (scipy.io.matlab.MatReadError, ValueError, TypeError, OSError, EOFError,
            IndexError, KeyError, AttributeError, NotImplementedError, struct.error,
            zlib.error, ArithmeticError, MemoryError) as exc:
        reason = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
        raise FrfError(f"{path}: not a MATLAB MAT-file laminid can read ({reason}); save the "
                       "frequency and FRF variables again, or write them as a CSV") from exc
    with h5py.File(_io.BytesIO(), "w") as f:
        for name, value in variables.items():
            if not name.startswith("__"):
                _put_variable(f, name, value, depth=0)
        try:
            return _read_generic(f, path, freq_dataset, frf_dataset)
        except FrfError as exc:
            if not big:
                raise
            raise FrfError(f"{exc}; left out, larger than laminid reads ({MAX_FRF_VALUES} "
                           f"values): {', '.join(big)}") from exc


def _put_variable(group, name: str, value, depth: int) -> None:
    """A loadmat variable into an HDF5 group: numbers as a dataset, text as a string, a
    1 x 1 struct as a group of its fields (two levels), a top-level cell array as below;
    anything else left out."""
    import h5py

    arr = np.asarray(value)
    if arr.dtype.kind in "fiuc" and arr.ndim >= 1:
        group.create_dataset(name, data=arr)
    elif arr.dtype.kind == "U":
        group.create_dataset(name, data=", ".join(str(t).strip() for t in arr.reshape(-1)))
    elif arr.dtype.names and arr.size == 1 and depth < 2:
        sub = group.create_group(name)
        for field in arr.dtype.names:
            _put_variable(sub, field, arr[field].reshape(-1)[0], depth + 1)
    elif arr.dtype == object and depth == 0:
        # a cell array (loadmat: an object array of its entries, each an array): of texts,
        # a string dataset in MATLAB's order (point labels: point_labels); of anything
        # else, an empty one that says what, refused there if named as labels
        items = arr.reshape(-1, order="F")
        other = next((k for k, x in enumerate(items, start=1)
                      if np.asarray(x).dtype.kind != "U" or np.asarray(x).size > 1), None)
        if other is None:
            d = group.create_dataset(name, data=np.array(
                ["".join(np.asarray(x).reshape(-1).tolist()).strip() for x in items],
                dtype=object), dtype=h5py.string_dtype())
            d.attrs["laminid_cell"] = ""
        else:
            d = group.create_dataset(name, data=np.zeros(0))
            d.attrs["laminid_cell"] = f"entry {other} is no text"


def read_any_frf_h5(path, freq_dataset: str | None = None,
                    frf_dataset: str | None = None, probe: bool = True) -> FrfSet:
    """laminid's own FRF file (attribute format = "laminid-frf") with
    :func:`~laminid_cli.frf.store.read_frf_h5`, any other HDF5 file (or any file when dataset
    paths are given) with :func:`read_generic_frf_h5`. With ``probe`` the file is first read
    in a child process (:func:`~laminid_cli.frf.store.probe_hdf5_file`): a damaged file that
    crashes or hangs libhdf5 is refused instead of killing this process."""
    import h5py

    if probe and Path(path).is_file():
        probe_hdf5_file(path, reader="read_any_frf_h5", module="laminid_cli.frf.generic_h5")

    if freq_dataset is None and frf_dataset is None:
        from laminid_cli.h5open import format_of

        try:
            with h5py.File(path, "r") as f:
                fmt = format_of(f)
        except OSError:
            fmt = FORMAT    # let the laminid reader give its message (missing, unreadable)
        if fmt == FORMAT:
            return read_frf_h5(path, probe=False)
        if fmt.startswith("laminid-"):
            from laminid_cli.h5open import laminid_kind

            # what it is and what reads it, as identify and batch name it (a result: show,
            # report; a modes file: export), where the format is one laminid writes
            what, hint = laminid_kind(fmt, path) or (f"a {fmt} file (results of laminid)", "")
            raise FrfError(f"{path}: {what}, not FRFs{'; ' + hint if hint else ''}; give the "
                           "file written by laminid acquire or another tool's FRF file")
    return read_generic_frf_h5(path, freq_dataset, frf_dataset)
