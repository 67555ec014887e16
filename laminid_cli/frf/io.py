"""FRF file formats: laminid HDF5 (see :mod:`laminid_cli.frf.store`), UFF 58 and CSV.

Every reader returns a :class:`~laminid_cli.frf.store.FrfSet` (``frf`` complex
(n_points, n_freq) on one strictly increasing axis in Hz) validated by
:func:`~laminid_cli.frf.store.validate_frf_arrays`, and raises
:class:`~laminid_cli.errors.FrfError` with the file name for anything unusable.

Formats (:data:`FORMATS`, chosen by suffix unless given):

``hdf5`` (``.h5``, ``.hdf5``)
    laminid's own file, written by ``laminid acquire``, or a plain HDF5 file of another tool
    (frequency + complex FRF datasets, :mod:`laminid_cli.frf.generic_h5`).
``uff`` (``.uff``, ``.unv``)
    Universal File Format, dataset 58 (function at nodal DOF), ASCII or binary, read with
    pyuff. Every type-58 record of function type 4 (FRF) is one point (complex: a real FRF
    record is refused); records of function type 6 (coherence) with the same
    response/reference DOF give the coherence. All FRFs must
    share one abscissa, in the unit of its label (Hz, kHz, rad/s: converted to Hz; another
    unit refused); where no record has one (blank or "NONE", pyuff's default, whatever the
    specific data type), read as Hz with a warning, refused where it ends below
    :data:`UNSTATED_FREQ_MIN_SPAN_HZ`. An
    ordinate units label blank or "NONE" (pyuff's default) states no FRF unit (``units`` None),
    except in a file whose units record says SI, where a record typed (8, 11, 12 or 15 over
    13) without labels has its types' unit (:func:`_uff_typed_unit`, with a note).
    A units record (dataset 164) must be SI (length and force factors 1): another is refused
    (:func:`_check_uff_units_records`). laminid writes one, SI, at the head of its files.
``csv`` (``.csv``, ``.txt``)
    Text: first column frequency in Hz (kHz or rad/s when its header says so: "f [kHz]",
    "f (kHz)", "omega_rad_s"; another bracketed unit is refused, and so is a header that reads
    as an angular frequency without its unit, "omega"; a header that states no unit, "f", or
    none is read as Hz with a warning, and refused where the values end below
    :data:`UNSTATED_FREQ_MIN_SPAN_HZ`, Hz implausible for a plate), then per FRF, in one of
    three layouts:

    - real and imaginary part (``freq, re_1, im_1, re_2, im_2, ...``; what laminid writes);
    - one column of complex numbers (``freq, H_1, H_2, ...``), known by its cells: Python's
      and numpy's ``(1.2e-3+4.5e-4j)``, ``1.2e-3-4.5e-4j``, MATLAB's, Octave's and a
      spreadsheet's ``1.2e-3+4.5e-4i``, also with blanks around the sign (in a
      blank-separated file only a lone sign is joined: ``1.2 - 4.5i`` is one cell,
      ``1.2 -4.5i`` two). A plain number in such a file is a + 0j, but every FRF column must
      hold complex cells (a real/imaginary file with a stray one is refused); a frequency
      written complex (numpy: ``(125+0j)``) must have no imaginary part;
    - a magnitude and a phase column, by their header names only (case-insensitive whole
      words, :data:`CSV_MAGNITUDE_WORDS` or ``|H|``; :data:`CSV_PHASE_WORDS`), in either order
      within the pair: ``H1_mag, H1_phase``, ``|H|, phase``, ``Magnitude [dB], Phase [deg]``
      (without those words a dB unit makes a magnitude, a deg/rad unit a phase: ``H1 [dB]``).
      The magnitude is linear, or in dB when its name says so ("[dB]", "(dB)", "_dB"):
      |H| = 10^(dB/20), dB re 1 of the FRF's unit. The phase in degrees ("[deg]", "(°)",
      "degrees", "_deg") or radians ("[rad]", "(rad)"); without a unit in radians when no
      |phase| exceeds pi (a phase in degrees turns by 180 at each resonance), in degrees when
      it jumps by more than 180 between neighbouring lines (wrapped at +-180) or exceeds 180,
      and ``meta["notes"]`` says which was assumed and why (fit-frf and export print it);
      refused in between (a degree phase that never wraps and a radian one unwrapped over a
      few resonances look alike). The labels are the magnitude names without the magnitude word (``H1_mag`` H1).
      Without a header, columns are never taken for magnitude and phase.

    A first line at 0 Hz whose FRF values are NaN or inf (H = X/F, the force 0 at DC; also a
    spreadsheet's ``#DIV/0!``, :data:`CSV_SHEET_ERRORS`) is dropped with a warning
    (:func:`~laminid_cli.frf.store.nonfinite_dc_lines`; the UFF and plain HDF5 readers too);
    NaN or inf at any other line is refused.

    Text in UTF-8, UTF-16 with a BOM, or Windows-1252 (:func:`decode_text`, with a note).
    Separator ``;`` tab ``,`` (the first found in the first line) or blanks; with ``;`` or tab
    a decimal comma is read too (``125,05``, as a European spreadsheet writes), and '.' as its
    thousands separator (``1.000,5``) where the whole file says so (:func:`_csv_thousands`,
    with a note; refused where a decimal point shares the file; with ',' a quoted "1,000.5"
    reads as 1000.5 where the whole file says so, :func:`_csv_comma_thousands`); ``#`` comment
    lines (not one beginning with a spreadsheet's error value, ``#VALUE!,1.2,...``: a data
    line whose frequency cell is broken, refused by line and column; ``# ... units Pa/N``, ``# Units: g/N``, ``# Units: Hz, g/N`` give the FRF unit, and the
    last the frequency's: :func:`_csv_units_comment`; else a unit closing every FRF column's
    name, ``H1_re [g/N]``, ``Pt1 Magnitude (g/N)``: :func:`_csv_header_units`; without one the
    unit is not stated:
    ``units`` None and a note, never "1", which declares the FRFs dimensionless); an optional
    header line, known by its
    first cell not being a number (or, above a first line of data, the comment line just
    above it, numpy's ``savetxt(header=...)``, when it has as many cells as the data and its
    first is not a number: :func:`_commented_header`, with a note; lines above it that are
    neither, an export's title and date, skipped with a note: :func:`_csv_preamble`; or the
    names over a line of their units, :func:`_csv_two_line_header`) (its
    names give the point labels: of the real columns, of
    the complex columns, of the magnitude columns).
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from laminid_cli.atomic import atomic_path
from laminid_cli.errors import (NON_PRINTABLE, FrfError, LaminidError, OutputExistsError,
                                 about_file)
from laminid_cli.filekinds import binary_kind
from laminid_cli.frf.store import (UNSTATED_FREQ_MIN_SPAN_HZ, FrfSet, check_frf_arrays,
                                   check_frf_texts,
                                   check_frf_size, nonfinite_dc_lines, nonfinite_dc_warning,
                                   read_frf_h5, resonance_lines,
                                   unit_not_stated_note, unstated_freq_warning,
                                   validate_frf_arrays, write_frf_h5)

__all__ = ["FORMATS", "SUFFIXES", "UNSTATED_FREQ_MIN_SPAN_HZ", "check_frf_arrays",
           "check_frf_size", "frf_format", "read_frf", "read_frf_csv", "read_frf_uff",
           "validate_frf_arrays", "write_frf"]

FORMATS = ("hdf5", "uff", "csv")
SUFFIXES = {".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5", ".mat": "hdf5", ".uff": "uff",
            ".unv": "uff", ".csv": "csv", ".txt": "csv"}

#: UFF 58 function types (record 6, field 1: 4 frequency response function, 6 coherence), and
#: the abscissa's specific data type for frequency (Hz; record 8, field 1: 18). Source: the
#: dataset 58 definition of the I-DEAS Universal File format, as reproduced in the docstring
#: of pyuff's ``pyuff/datasets/dataset_58.py`` (pyuff 2.5.8, whose ``_write58`` writes function
#: types 0-4, 6 and 9); record 7, field 1 (ordinate data type): 4 real double, 6 complex double
UFF_FRF, UFF_COHERENCE = 4, 6
UFF_ABSCISSA_FREQUENCY = 18
#: UFF 58 specific data types (record 9/10 of the header) of the response units laminid
#: writes, and of the force: SI units only, as the units record (dataset 164,
#: :func:`uff_units_record`) at the head of the file says SI, and a reader takes a record's
#: values in the file's units by its type (the labels "take precedence" for display only: UFF
#: 58 record 8, field 6, note). Any other unit ("g", "mm/s", "kPa", "kN", "lbf") is written as
#: 0 (unknown), whose values no tool converts: "g" typed 12 (acceleration) in an SI file read
#: as m/s^2 elsewhere, 9.81 times too small
UFF_RESPONSE_TYPES = {"m": 8, "m/s": 11, "m/s^2": 12, "m/s2": 12, "Pa": 15}
UFF_FORCE_TYPES = {"N": 13}
#: the length, force and temperature units exponents (records 8-11, fields 2-4) of the specific
#: data types laminid writes, translational direction: Addendum A ("Table - Unit Exponents") of
#: the dataset 58 definition (UC-SDRL's copy of the I-DEAS Universal File format, 58.asc, as
#: reproduced in pyuff 2.5.8's ``pyuff/datasets/dataset_58.py``). Time has no exponent (the
#: second in every unit system): acceleration is length 1, as displacement and velocity
UFF_UNIT_EXPONENTS = {0: (0, 0, 0), 8: (1, 0, 0), 11: (1, 0, 0), 12: (1, 0, 0),
                      13: (0, 1, 0), 15: (-2, 1, 0), 18: (0, 0, 0)}
#: the units record (dataset 164) laminid writes at the head of every Universal File: units
#: code 1, SI (metre, newton), factors to SI 1 (UC-SDRL's 164.asc: "to convert from universal
#: file units to SI divide by the appropriate factor"); temperature relative, offset 273.15
UFF_SI_UNITS = dict(units_code=1, units_description="SI - Meter (newton)", temp_mode=2,
                    length=1.0, force=1.0, temp=1.0, temp_offset=273.15)
#: ``id2`` of every UFF 58 record laminid writes: the reader knows its own records by it
UFF_WRITER = "laminid"
#: ``id3`` of laminid's FRF records from a file that records the exponential window the
#: analyser applied to the response (``exp_window_s``, acquire): its time constant in seconds
#: (repr of the float, exact), or "unknown" (--keep-setup). UFF 58 has no field for it; without
#: it the window's 1/tau was lost and fit-frf of the UFF gave every damping ratio with
#: 1/(tau omega_n) added (2x the truth on the emulators' plate)
UFF_WINDOW_ID = "exponential window tau = {} s"
#: characters of a UFF 58 units label (records 8-11, field 6: A20); a longer one is cut
UFF_UNITS_CHARS = 20
#: a Universal File is ASCII in fixed columns: laminid's text written there in ASCII, these
#: characters by their ASCII spelling (pyuff 2.5.3 drops any other character silently, so
#: "m/s²" became "m/s", a velocity; pyuff 2.5.8 writes UTF-8, whose two-byte characters shift
#: the fixed columns for other readers)
UFF_ASCII = str.maketrans({"²": "^2", "³": "^3", "µ": "u", "μ": "u", "°": "deg", "·": "*",
                           "−": "-", "–": "-", "—": "-", "×": "x"})
#: a spreadsheet's error values for a division by zero and an undefined number: on a CSV's
#: 0 Hz line (H = X/F, F 0 at DC) they are NaN, and that line is dropped with a warning
#: (:func:`~laminid_cli.frf.store.nonfinite_dc_lines`); anywhere else still "not a number"
CSV_SHEET_ERRORS = ("#DIV/0!", "#NUM!")
#: a spreadsheet's error value as a line's first cell ("#DIV/0!,1.2,3.4", "#N/A;..."): the
#: line is data whose frequency cell is broken, not a '#' comment line (it was skipped as
#: one, a line of the file lost without a word; or taken for numpy's commented header); the
#: error values of Excel and LibreOffice Calc (Microsoft, "How to correct a #... error";
#: LibreOffice Help, "Error codes in LibreOffice Calc")
_SHEET_ERROR_FIRST = re.compile(r'\s*"?#(?:DIV/0!|VALUE!|N/A|NUM!|REF!|NAME\?|NULL!|SPILL!|'
                                r'CALC!|FIELD!|BLOCKED!|BUSY!|CONNECT!|UNKNOWN!|GETTING_DATA)'
                                r'"?\s*(?:[,;\t ]|\Z)', re.IGNORECASE)


def is_comment_line(line: str) -> bool:
    """Whether a CSV text line is a '#' comment: it begins with '#', and not with a
    spreadsheet's error value (:data:`_SHEET_ERROR_FIRST`)."""
    return line.lstrip().startswith("#") and not _SHEET_ERROR_FIRST.match(line)
#: text FRF files (UFF, CSV) larger than this are refused before they are read (1 GB: the
#: 50 million values of MAX_FRF_VALUES at ~20 characters each)
MAX_TEXT_FILE_BYTES = 1_000_000_000


def frf_format(path, fmt: str | None = None) -> str:
    """The format of ``path``: ``fmt`` if given, else from the suffix (:data:`SUFFIXES`)."""
    if fmt is not None:
        if fmt not in FORMATS:
            raise FrfError(f"FRF format {fmt!r}: expected one of {', '.join(FORMATS)}")
        return fmt
    suffix = Path(path).suffix.lower()
    if suffix in (".yaml", ".yml"):
        # a newcomer's slip: the specimen given where its FRFs are meant
        raise FrfError(f"{path}: a specimen file (YAML), not FRFs; give the FRF file (laminid "
                       "HDF5 .frf.h5, UFF 58 .uff/.unv, CSV): 'laminid fit-frf FRFS --into "
                       f"{path}' writes their frequencies into it")
    if suffix not in SUFFIXES:
        raise FrfError(f"{path}: unknown FRF file type {suffix!r}; expected one of "
                       f"{', '.join(sorted(SUFFIXES))} (laminid HDF5, UFF 58, CSV)")
    return SUFFIXES[suffix]


def read_frf(path, fmt: str | None = None, **h5_paths) -> FrfSet:
    """Read FRFs from a laminid HDF5, UFF 58 or CSV file (format from the suffix).

    ``h5_paths``: ``freq_dataset``, ``frf_dataset`` for a plain HDF5 file (see
    :func:`laminid_cli.frf.generic_h5.read_any_frf_h5`)."""
    path = Path(path)
    with about_file(path, FrfError):       # (its --json error document names the file)
        return _read_frf(path, fmt, h5_paths)


def _read_frf(path: Path, fmt: str | None, h5_paths: dict) -> FrfSet:
    from laminid_cli.frf.generic_h5 import read_any_frf_h5

    fmt = frf_format(path, fmt)
    if fmt != "hdf5" and any(v is not None for v in h5_paths.values()):
        raise FrfError(f"{path}: dataset paths apply to HDF5 files only (format {fmt})")
    if not path.exists():
        raise FrfError(f"{path}: file not found")
    if path.is_dir():
        raise FrfError(f"{path}: is a folder, not an FRF file")
    if fmt == "hdf5" and path.suffix.lower() == ".mat" and not _is_hdf5(path):
        from laminid_cli.frf.generic_h5 import read_mat_frf

        # version 4 or 5 (save's default, scipy.io.savemat): no HDF5
        return _some_points(path, read_mat_frf(path, **h5_paths))
    if fmt != "hdf5":
        size = path.stat().st_size
        if size > MAX_TEXT_FILE_BYTES:
            raise FrfError(f"{path}: {size / 1e9:.3g} GB, larger than an FRF text file laminid "
                           f"reads ({MAX_TEXT_FILE_BYTES / 1e9:g} GB)")
    fs = {"hdf5": lambda p: read_any_frf_h5(p, **h5_paths), "uff": read_frf_uff,
          "csv": read_frf_csv}[fmt](path)
    return _some_points(path, fs)


def _some_points(path: Path, fs: FrfSet) -> FrfSet:
    if fs.n_points == 0:
        raise FrfError(f"{path}: the file holds no FRF (0 measurement points)")
    return check_frf_texts(fs, path)


def _is_hdf5(path: Path) -> bool:
    """Whether ``path`` is HDF5 (a MAT-file saved with '-v7.3' is: read as a plain HDF5
    file); a file that cannot be opened counts as one, the HDF5 reader says why."""
    import h5py

    try:
        return bool(h5py.is_hdf5(str(path)))
    except OSError:
        return True


def write_frf(path, fs: FrfSet, fmt: str | None = None, *, overwrite: bool = False) -> Path:
    """Write an :class:`FrfSet` in any of :data:`FORMATS` (format from the suffix)."""
    fmt = frf_format(path, fmt)
    check_frf_arrays(fs.freq, fs.frf, fs.coherence, source=str(path))   # e.g. NaN: UFF writes 0
    if fmt == "hdf5":
        return write_frf_h5(path, fs.freq, fs.frf, fs.coherence, units=fs.units,
                            labels=fs.labels or None, overwrite=overwrite)
    return {"uff": write_frf_uff, "csv": write_frf_csv}[fmt](path, fs, overwrite=overwrite)


def _new_target(path, overwrite: bool) -> Path:
    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputExistsError(f"{path}: file exists (not overwritten)")
    return path


# --------------------------------------------------------------------------- CSV
#: the kinds of binary file (laminid_cli.filekinds) given as an FRF text file by mistake that
#: the reader has words for: (words after the kind's name, the --format that reads it, None
#: for no FRF format); the others are no FRF format either
_FRF_KINDS = {"hdf5": (" (laminid acquire's FRF file or another tool's)", "hdf5"),
              # a workbook (.xlsx, .ods) is a ZIP archive: its sheet saved as CSV is read
              "zip": ("; a spreadsheet is read once its sheet is saved as CSV (File > Save As "
                      "> CSV), the frequency in the first column", None)}


def describe_content(path) -> tuple[str, str | None]:
    """What ``path`` looks like from its first bytes, for a message that says the file is not
    in the format asked for: (``"an HDF5 file (...)"``, the :data:`FORMATS` entry that reads
    it, or None)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        return f"an unreadable file ({exc.strerror or exc})", None
    if not head:
        return "an empty file (0 bytes)", None
    kind = binary_kind(head)
    if kind is not None:
        aside, fmt = _FRF_KINDS.get(kind[0], ("", None))
        return kind[1] + aside, fmt
    text = decode_head(head)
    if text is None:
        return "binary data, not text", None
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if not first:
        return "text with blank lines only", None
    quoted = repr(first if len(first) <= 50 else first[:47] + "...")
    if first.startswith(("{", "[")):
        return f"JSON text (first line {quoted})", None
    data = [ln for ln in text.splitlines() if ln.strip() and not is_comment_line(ln)]
    if data and any(c in data[0] for c in ",;\t"):
        return f"text in columns, as a CSV FRF file is (first line {quoted})", "csv"
    return f"text whose first line is {quoted}", None


#: the byte-order marks of a UTF-16 text file (a spreadsheet's "Unicode text" export)
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")


def decode_head(head: bytes) -> str | None:
    """The text of a file's first block ``head`` (:func:`decode_text`; where it ends in the
    middle of a multi-byte character, without its last bytes), None for binary data."""
    text, _ = decode_text(head)
    if text is None:
        text, _ = decode_text(head[:-4])
    return text


def decode_text(raw: bytes) -> tuple[str | None, str | None]:
    """``(text, encoding)`` of a text file's bytes: UTF-8 (a BOM dropped), UTF-16 with its BOM
    (Excel's "Unicode Text" export, tab-separated), else Windows-1252 (Excel's "CSV" on
    Windows writes the '°' of "Phase [°]" as the byte 0xB0, which was refused as "binary
    data, not text") where no byte is a control character other than tab, CR, LF and form
    feed; ``(None, None)`` for anything else (binary data, and bytes that begin with a
    binary file's signature: :func:`laminid_cli.filekinds.binary_kind`).

    >>> decode_text("f;H [°]".encode("cp1252"))
    ('f;H [°]', 'cp1252')
    """
    if binary_kind(raw[:16]):
        # a binary file's signature, whatever follows: a ZIP archive's 'PK\x03\x04' is valid
        # UTF-8, and a workbook cut to its first bytes was read as a header without data
        return None, None
    if raw.startswith(_UTF16_BOMS):
        try:
            return raw.decode("utf-16"), "utf-16"
        except UnicodeDecodeError:
            return None, None
    try:
        return raw.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError:
        pass
    if re.search(rb"[\x00-\x08\x0b\x0e-\x1f\x7f]", raw):
        return None, None
    try:
        return raw.decode("cp1252"), "cp1252"
    except UnicodeDecodeError:   # 0x81, 0x8d, 0x8f, 0x90, 0x9d are not cp1252
        return None, None


def _not_the_format(path, fmt: str) -> str:
    """``path``: not a file of ``fmt``; what it looks like, and the --format that reads it."""
    what, other = describe_content(path)
    suffix = Path(path).suffix.lower()
    hint = ""
    if other and other != fmt:
        hint = f"; read it with --format {other}"
        if SUFFIXES.get(suffix) == other:
            hint += f" or without --format (its suffix {suffix} says {other})"
    return f"it looks like {what}{hint}"


def _real_part_label(name: str) -> str:
    """The point label of a real-part column name: without its unit ("[g/N]") and "_re",
    ".re", "_real", ".real", " Re", " real"."""
    name = _csv_unit_removed(name)
    for suffix in ("_real", ".real", "_re", ".re"):
        if name.endswith(suffix):
            return name[:-len(suffix)].strip()
    return re.sub(r"(?i)\s+(re|real)\Z", "", name.strip()).strip() or name.strip()


#: a unit closing a CSV column name: "H1 real [g/N]", "FRF 1 Re (m/s^2/N)" (a round bracket
#: after a blank or "_": "abs(H1)" is a magnitude of H1)
_CSV_UNIT = re.compile(r"\s*(?:\[\s*([^\]]*?)\s*\]|(?:(?<=[\s_])|^)\(\s*([^()]*?)\s*\))\s*\Z")
#: what such a bracket holds that is no FRF unit: a magnitude's dB, a phase's angle unit, a
#: frequency's, or "no unit"
_CSV_NOT_FRF_UNITS = {"", "-", "db", "deg", "degree", "degrees", "rad", "radian", "radians",
                      "°", "hz", "khz", "rad/s"}


def _csv_unit_removed(name: str) -> str:
    return _CSV_UNIT.sub("", name) if _csv_frf_unit(name) else name


def _csv_frf_unit(name: str) -> str | None:
    """The FRF unit that closes a column name ("H1 real [g/N]", "Magnitude (m/s^2/N)": g/N,
    m/s^2/N); None where it names none or a dB, phase or frequency unit."""
    m = _CSV_UNIT.search(name)
    if m is None:
        return None
    unit = (m.group(1) if m.group(1) is not None else m.group(2)).strip()
    if unit.lower() in _CSV_NOT_FRF_UNITS or unit.lower().startswith("db"):
        return None
    # an FRF's unit is a response over a force: "g/N", "m s^-2 N^-1"
    return unit if "/" in unit or "-1" in unit else None


def _csv_header_units(path, header: list[str], columns: list[list[int]]
                      ) -> tuple[str | None, list[str] | None]:
    """The FRF unit the header gives ("H1 real [g/N]"): ``(unit, None)`` where every point's
    columns (``columns``: per point, its column indices) state one and the same, ``(first,
    each point's)`` where points differ (an accelerance beside a mobility, as a UFF's
    records may), ``(None, None)`` where any point states none."""
    each = []
    for cols in columns:
        units = {_csv_frf_unit(header[j]) for j in cols}
        if len(units) != 1 or None in units:
            return None, None
        each.append(units.pop())
    if not each:
        return None, None
    return each[0], (each if len(set(each)) > 1 else None)


def _commented_header(text: str, first_data: int, sep: str | None, n: int
                      ) -> list[str] | None:
    """The column names of a CSV file whose header is a comment line, as numpy's ``savetxt``
    writes ``header=`` ("# f (kHz),H1_re,H1_im" above the data): the comment line just above
    the first data line (``first_data``, 1-based), when it splits into the data's ``n``
    cells and its first names no number; else None. Ignored, its unit was lost ("f (kHz)"
    read as Hz: every mode 1000 times too low)."""
    lines = text.splitlines()
    if first_data < 2:
        return None
    above = lines[first_data - 2].strip()
    if not is_comment_line(above):
        return None
    cells = _split(above.lstrip("#").strip(), sep)
    if len(cells) != n or not cells[0]:
        return None
    try:
        float(cells[0])
    except ValueError:
        return cells
    return None


#: characters refused in a CSV's column names (errors.NON_PRINTABLE)
_BAD_NAME_CHARS = NON_PRINTABLE


def _check_names(path, lineno: int, names, what: str = "") -> None:
    """FrfError naming the file, the line and the column of a column name holding a character
    of :data:`_BAD_NAME_CHARS` (``what``: the name of a single text checked, the FRF unit of a
    '# units' line)."""
    for j, name in enumerate(names):
        bad = _BAD_NAME_CHARS.search(name)
        if bad is not None:
            at = what or f"column {j + 1}"
            raise FrfError(f"{path}: line {lineno}, {at} ({_quoted(name)}): non-printable "
                           f"character U+{ord(bad.group()):04X} in "
                           f"{'it' if what else 'the column name'}; remove it")


def _split(line: str, sep: str | None) -> list[str]:
    """The cells of a CSV line: quoted cells unquoted (``"f [Hz]","0.5"``, as pandas with
    QUOTE_ALL, LabVIEW and many loggers write them; they were "'\"0.5\"' is not a number"),
    and the empty cells after the separators that end the line dropped (``0,5;1,2;``, as a
    spreadsheet writes a trailing empty column: "column 10: empty, where a number is
    expected"; ``0.5,1.2,,,`` of columns formatted but empty, and ``0.5\t1.2\t``, whose tab
    the test for a separator at the end stripped as a blank)."""
    if sep and '"' in line:
        cells = [t.strip() for t in next(csv.reader([line], delimiter=sep))]
    else:
        cells = [t.strip() for t in (line.split(sep) if sep else line.split())]
    if sep and line.rstrip(" \r\n").endswith(sep):
        while len(cells) > 1 and cells[-1] == "":
            cells.pop()
    if sep is None and ("+" in cells or "-" in cells):
        cells = _join_signs(cells)
    return cells


def _join_signs(cells: list[str]) -> list[str]:
    """Blank-separated cells with a complex number written with blanks around its sign
    ("1.2e-3 - 4.5e-4i", as MATLAB's and Octave's disp write it) joined back into one cell;
    only a lone sign is joined, and only where the three make a complex number ("1.2 -4.5i"
    stays two cells: a real and an imaginary column)."""
    out: list[str] = []
    i = 0
    while i < len(cells):
        if cells[i] in ("+", "-") and out and i + 1 < len(cells) \
                and _COMPLEX_CELL.fullmatch(out[-1] + cells[i] + cells[i + 1]):
            out[-1] += cells[i] + cells[i + 1]
            i += 2
        else:
            out.append(cells[i])
            i += 1
    return out


def _csv_column(header: list[str] | None, j: int) -> str:
    """Column ``j`` (0-based) of a CSV FRF file for a message: its number and header name."""
    name = header[j] if header and j < len(header) and header[j] else None
    return f"column {j + 1}" + (f" ({name!r})" if name else " (no header)"
                                if not header else "")


def _quoted(cell: str) -> str:
    return repr(cell if len(cell) <= 40 else cell[:37] + "...")


def _not_a_number(cell: str, complex_cells: bool = False) -> str:
    """What is wrong with a cell that is not a number: quoted, cut to 40 characters;
    ``complex_cells``: in a file of complex numbers (the forms it reads named)."""
    if not cell:
        return "empty, where a number is expected"
    if _SHEET_ERROR_FIRST.fullmatch(cell):
        return (f"{_quoted(cell)} is a spreadsheet's error value, not a number (the formula "
                "of that cell failed: correct it in the sheet and save the CSV again)")
    if complex_cells:
        return (f"{_quoted(cell)} is neither a number nor a complex number (a+bj, a+bi, "
                "(a+bj))")
    return f"{_quoted(cell)} is not a number"


#: a real number as Python, numpy and MATLAB write it (any case: "NaN", "Inf")
_NUMBER = r"(?:(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?|nan|inf(?:inity)?)"
#: a complex number in a cell: Python's and numpy's "(1.2e-3+4.5e-4j)", "1.2e-3-4.5e-4j",
#: "-2j"; MATLAB's, Octave's and a spreadsheet's "1.2e-3+4.5e-4i", "1.2 - 4.5i", "i";
#: "4.5*i"; old numpy's "+-" for a negative imaginary part
_COMPLEX_CELL = re.compile(
    rf"(?P<open>\()?\s*(?:(?P<re>[+-]?\s*{_NUMBER})\s*(?P<sign>[+-]\s*[+-]?)|(?P<sign1>[+-])?)"
    rf"\s*(?:(?P<im>{_NUMBER})\s*\*?)?\s*[ij]\s*(?(open)\))", re.IGNORECASE)


def parse_complex_cell(cell: str) -> complex:
    """The complex number written in ``cell`` (:data:`_COMPLEX_CELL`); ValueError for any
    other text, a real number too (``float`` reads those).

    >>> parse_complex_cell("(1.5-2e-3j)"), parse_complex_cell("1.5 + 2i"), parse_complex_cell("-i")
    ((1.5-0.002j), (1.5+2j), -1j)
    """
    m = _COMPLEX_CELL.fullmatch(cell.strip())
    if m is None:
        raise ValueError(f"not a complex number: {cell!r}")
    sign = m["sign"] if m["re"] is not None else (m["sign1"] or "+")
    im = float(m["im"]) if m["im"] else 1.0
    re_ = float(m["re"].replace(" ", "").replace("\t", "")) if m["re"] is not None else 0.0
    # complex(re, im), not re + im * 1j: inf * 1j is nan + inf j
    return complex(re_, -im if sign.count("-") % 2 else im)


#: whole words of a CSV column name (any case; "H1_mag", "Magnitude [dB]", "abs(H1)", "H1Mag")
#: that make it a magnitude column, and a phase column; "|H|" is a magnitude too. Without
#: any of them, a name with a dB unit is a magnitude, one with deg/rad a phase
CSV_MAGNITUDE_WORDS = ("mag", "magnitude", "abs", "amp", "amplitude", "modulus")
CSV_PHASE_WORDS = ("phase", "phi", "arg", "angle")
#: the words of a real or an imaginary part ("amp_re", "H1_imag"): never a magnitude or phase
_CSV_PART_WORDS = ("re", "real", "im", "imag", "imaginary")
_DEGREE_WORDS = ("deg", "degree", "degrees")
_RADIAN_WORDS = ("rad", "radian", "radians")
#: a phase without a unit in its header is in radians when no |phase| exceeds this: a phase in
#: degrees turns by 180 at each resonance, so one that stays within +-3.14 has none in its band
_PHASE_RADIANS_MAX = np.pi * (1 + 1e-6)
#: ... and in degrees when it jumps by more than this between neighbouring lines (a wrapped
#: phase in degrees jumps by 360 where it crosses +-180; one in radians by 2 pi at most) or
#: exceeds _PHASE_DEGREES_MAX (radians unwrapped that far would need 57 resonances); between
#: the two, without a jump, it is refused: a phase in degrees that never crosses +-180 (a
#: driving point's, 0 to 180) and one in radians unwrapped over a few resonances look alike
_PHASE_WRAP_JUMP = 180.0
_PHASE_DEGREES_MAX = 180.0 * (1 + 1e-6)


def _csv_words(name: str) -> list[str]:
    """The words of a column name, lower case: split at anything not a letter, at digits and
    at camel case ("H1Mag" h, mag; "Imag" imag, not mag); "dB" is one word."""
    return [w.lower() for w in re.findall(r"(?i:db)(?![A-Za-z])|[A-Z]+(?![a-z])|[A-Z]?[a-z]+",
                                          name)]


def _csv_part_kind(name: str) -> str | None:
    """"magnitude", "phase" (or "magnitude and phase") where the column name says so
    (:data:`CSV_MAGNITUDE_WORDS`, :data:`CSV_PHASE_WORDS`), else None."""
    words = set(_csv_words(name))
    if words & set(_CSV_PART_WORDS):
        return None
    mag = bool(words & set(CSV_MAGNITUDE_WORDS)) or re.search(r"\|[^|]+\|", name) is not None
    phase = bool(words & set(CSV_PHASE_WORDS))
    if not (mag or phase):         # "H1 [dB]", "H1 [deg]": the unit says which
        mag = "db" in words
        phase = bool(words & set(_DEGREE_WORDS + _RADIAN_WORDS)) or "°" in name
    if mag and phase:
        return "magnitude and phase"
    return "magnitude" if mag else "phase" if phase else None


def _csv_magnitude_in_db(path, header: list[str], j: int) -> bool:
    """Whether magnitude column ``j`` is in dB (its name says dB: "[dB]", "(dB)", "_dB")."""
    name = header[j]
    if "db" in _csv_words(name):
        return True
    other = re.search(r"(?i)(?<![a-z])db[a-z]+", name)
    if other:
        raise FrfError(f"{path}: {_csv_column(header, j)}: a magnitude in {other.group()!r}; "
                       "laminid reads dB re 1 of the FRF's unit ('... [dB]') or a linear "
                       "magnitude")
    return False


def _csv_phase_unit(path, header: list[str], j: int) -> str | None:
    """"deg" or "rad" as phase column ``j``'s name says ("[deg]", "(°)", "degrees", "_deg",
    "[rad]", "(rad)"); None where it says no unit."""
    name = header[j]
    words = set(_csv_words(name))
    deg = bool(words & set(_DEGREE_WORDS)) or "°" in name
    rad = bool(words & set(_RADIAN_WORDS))
    if deg and rad:
        raise FrfError(f"{path}: {_csv_column(header, j)}: a phase in degrees and radians")
    if deg or rad:
        return "deg" if deg else "rad"
    bracketed = re.search(r"\[\s*([^\]]*?)\s*\]", name)
    if bracketed and bracketed.group(1):
        raise FrfError(f"{path}: {_csv_column(header, j)}: phase unit {bracketed.group(1)!r} "
                       "is not one laminid reads (deg, °, rad)")
    return None


def _csv_point_label(name: str) -> str:
    """A point's label from its magnitude column's name: without the magnitude words, the dB
    and the unit ("H1_mag" H1, "|H2|" H2, "abs(H3)" H3, "Magnitude [dB]" "", "Pt1 Magnitude
    (g/N)" Pt1)."""
    s = re.sub(r"\[[^\]]*\]", " ", _csv_unit_removed(name))
    s = re.sub(r"(?i)\(\s*(?:db|deg|degrees?|rad|radians?|°)\s*\)", " ", s)
    drop = set(CSV_MAGNITUDE_WORDS) | {"db"}
    for m in reversed(list(re.finditer(r"(?i:db)(?![A-Za-z])|[A-Z]+(?![a-z])|[A-Z]?[a-z]+",
                                       s))):
        if m.group().lower() in drop:
            s = s[:m.start()] + " " + s[m.end():]
    s = re.sub(r"\s+", " ", s).strip(" _.-:|,")
    while s.startswith("(") and s.endswith(")") or s.startswith("|") and s.endswith("|"):
        s = s[1:-1].strip(" _.-:|,")
    return s


def _csv_mag_phase(path, header: list[str], data: np.ndarray, lines
                   ) -> tuple[np.ndarray, tuple[str, ...], list[str]]:
    """The complex FRFs (n_points, n_freq) of a CSV file of magnitude and phase columns
    (``data``: float (n_freq, n_columns), column 0 the frequency), their labels, and notes on
    what was assumed (a phase unit)."""
    n = data.shape[1]
    found = ", ".join(repr(h) for h in header)
    expected = ("expected the frequency then a magnitude and a phase column per FRF (magnitude: "
                f"{', '.join(CSV_MAGNITUDE_WORDS)} or |H| in its name, linear or [dB]; phase: "
                f"{', '.join(CSV_PHASE_WORDS)}, [deg] or [rad])")
    if len(header) != n:
        raise FrfError(f"{path}: the header names magnitude and phase columns but has "
                       f"{len(header)} names ({found}), the data lines {n} columns; {expected}")
    kinds = [None] + [_csv_part_kind(h) for h in header[1:]]
    other = {"magnitude": "phase", "phase": "magnitude"}
    pairs = []
    for j in range(1, n, 2):
        a, b = kinds[j], kinds[j + 1] if j + 1 < n else None
        col, problem = _csv_column(header, j), None
        if a is None:
            problem = f"{col} is neither a magnitude nor a phase"
        elif a not in other:
            problem = f"{col} names both a magnitude and a phase"
        elif j + 1 >= n:
            problem = f"{col}, a {a}, has no {other[a]} column after it"
        elif b is None or b not in other:
            problem = (f"{col}, a {a}, is followed by {_csv_column(header, j + 1)}, "
                       f"not its {other[a]}")
        elif b == a:
            problem = (f"{col}, a {a}, is followed by {_csv_column(header, j + 1)}, another "
                       f"{a}, not its {other[a]}")
        if problem:
            raise FrfError(f"{path}: header {found}: {problem}; {expected}")
        pairs.append((j, j + 1) if a == "magnitude" else (j + 1, j))
    units = {p: _csv_phase_unit(path, header, p) for _, p in pairs}
    unknown = [p for _, p in pairs if units[p] is None]
    notes = []
    if unknown:
        # one unit for all: one tool wrote them
        values = np.abs(data[:, unknown])
        values = values[np.isfinite(values)]
        peak = float(values.max()) if values.size else 0.0
        with np.errstate(invalid="ignore"):
            jumps = np.abs(np.diff(data[:, unknown], axis=0))
        jump = float(np.nanmax(jumps)) if jumps.size and np.any(np.isfinite(jumps)) else 0.0
        names = ", ".join(repr(header[p]) for p in unknown)
        what = f"phase column{'s' if len(unknown) > 1 else ''} {names} with no unit"
        give = (f"give the unit in the header ('{header[unknown[0]]} [deg]' or "
                f"'{header[unknown[0]]} [rad]')")
        if peak <= _PHASE_RADIANS_MAX:
            assumed = "rad"
            why = (f"read in radians: no |phase| exceeds pi (largest {peak:.6g}), as a phase "
                   "in degrees over a band with a resonance would (it turns by 180 deg there)")
        elif jump > _PHASE_WRAP_JUMP:
            assumed = "deg"
            why = (f"read in degrees: it jumps by {jump:.6g} between neighbouring lines, as a "
                   "phase in degrees wrapped at +-180 does")
        elif peak > _PHASE_DEGREES_MAX:
            assumed = "deg"
            why = (f"read in degrees: |phase| reaches {peak:.6g}, which in radians would take "
                   "more than 57 resonances")
        else:
            raise FrfError(f"{path}: {what}: |phase| reaches {peak:.6g} without wrapping, "
                           "which degrees (a phase that never crosses +-180, as a driving "
                           "point's) and radians (unwrapped over a few resonances) both give; "
                           f"{give}")
        notes.append(f"{what}: {why}; {give} to read it otherwise")
        units.update(dict.fromkeys(unknown, assumed))
    frf = np.empty((len(pairs), data.shape[0]), dtype=complex)
    for k, (m, p) in enumerate(pairs):
        mag = data[:, m]
        if _csv_magnitude_in_db(path, header, m):
            with np.errstate(over="ignore"):        # inf: refused as such by the caller
                mag = 10.0 ** (mag / 20.0)
        else:
            negative = np.flatnonzero(mag < 0)
            if negative.size:
                i = int(negative[0])
                raise FrfError(f"{path}: line {lines[i][0]}, {_csv_column(header, m)}: "
                               f"magnitude {mag[i]:g} is negative (a magnitude in dB says so "
                               f"in its header: '{header[m]} [dB]')")
        phase = np.deg2rad(data[:, p]) if units[p] == "deg" else data[:, p]
        frf[k] = mag * np.exp(1j * phase)
    labels = [_csv_point_label(header[m]) or str(k + 1) for k, (m, _) in enumerate(pairs)]
    if len(set(labels)) < len(labels):      # "|H|, phase, |H|, phase": numbered
        labels = [str(k + 1) for k in range(len(pairs))]
    return frf, tuple(labels), notes


def _csv_freq_factor(path, name: str) -> tuple[float, bool]:
    """The factor to Hz of a CSV's frequency column by its header ``name``, and whether the
    header states the unit: the unit in brackets ("Frequency [rad/s]", "f (kHz)"), else a kHz,
    rad/s or Hz in the name ("f_kHz", "omega_rad_s", "freq_Hz"); (1, False), Hz not stated,
    for any other name or none (:func:`_unstated_freq_warning` then judges the values).
    FrfError for a bracketed unit that is no frequency ("time [s]") and for a name that reads
    as an angular frequency without a unit ("omega":
    :func:`~laminid_cli.frf.generic_h5.name_freq_unit`)."""
    from laminid_cli.frf.generic_h5 import FREQ_UNITS, freq_unit_factor, name_freq_unit

    bracketed = re.search(r"[\[(]\s*([^\])]*?)\s*[\])]", name)
    if bracketed:
        unit = bracketed.group(1)
        factor = freq_unit_factor(unit)
        if factor is None:
            raise FrfError(f"{path}: column 1 ({name!r}): unit {unit!r} is not a frequency "
                           f"unit laminid reads ({', '.join(FREQ_UNITS)})")
        return factor, True
    where = (f"{path}: column 1 ({name!r}; give its unit in the header, '{name} [rad/s]' or "
             f"'{name} [Hz]')")
    unit = name_freq_unit(name, where)
    return (1.0 if unit is None else FREQ_UNITS[unit]), unit is not None


def _unstated_freq_warning(path, header: list[str] | None, sep: str | None,
                           freq: np.ndarray) -> str:
    """The warning on a CSV frequency column whose header states no unit, read as Hz
    (``freq``, Hz): the file, the column, the range read and how to state the unit (in a
    blank-separated file (``sep`` None) without a blank: "f_kHz"). FrfError, the same said,
    where the range ends below :data:`UNSTATED_FREQ_MIN_SPAN_HZ`
    (:func:`~laminid_cli.frf.store.unstated_freq_warning`)."""
    column = _csv_column(header, 0)
    name = header[0].strip() if header and header[0].strip() else "f"
    if sep is None:                # "f [kHz]" would be two cells
        khz, hz, rad, more = f"{name}_kHz", f"{name}_Hz", f"{name}_rad_s", ""
    else:
        khz, hz, rad = f"{name} [kHz]", f"{name} [Hz]", f"{name} [rad/s]"
        more = f" (also '{name} (kHz)' or '{name}_kHz')"
    if header:
        how = f"state it in the header: '{khz}', '{hz}' or '{rad}'{more}"
    else:
        how = (f"add a header line above the data, one name per column, the first stating the "
               f"unit: '{khz}', '{hz}' or '{rad}'")
    return unstated_freq_warning(f"{path}: {column}", freq, how, f"'{hz}'")


#: a number with '.' grouping thousands and ',' its decimal mark, as a spreadsheet with a
#: German, Dutch, Italian or Spanish locale writes it with "Use 1000 separator" ticked
#: ("1.000,5", "12.345.678", "-2.500,125E-03"): a first group of 1-3 digits not beginning with
#: 0 ("0.001" is a decimal point's), then groups of exactly 3
_CSV_GROUPED = re.compile(r"[+-]?[1-9]\d{0,2}(?:\.\d{3})+(?:,\d*)?(?:[eE][+-]?\d+)?")
#: a cell with a decimal point that groups no thousands ("1.5", "0.0012", "1.25e-3")
_CSV_DECIMAL_POINT = re.compile(r"[+-]?(?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?")


#: a number with ',' grouping thousands and '.' its decimal point ("1,000.5", "12,500"), as a
#: spreadsheet writes a cell formatted with a 1000 separator: quoted in a ','-separated file
_CSV_COMMA_GROUPED = re.compile(r"[+-]?[1-9]\d{0,2}(?:,\d{3})+(?:\.\d*)?(?:[eE][+-]?\d+)?")


def _csv_comma_thousands(lines) -> str | None:
    """Whether ',' groups thousands in the data ``lines`` of a ','-separated CSV file (a
    cell holding a ',' is quoted there): the first such cell, or None. Decided by the whole
    file: every cell with a ',' a number grouped in threes (:data:`_CSV_COMMA_GROUPED`), and
    a decimal point somewhere, so that '.' is the decimal mark ("1,000.0" in an Excel CSV of
    a column formatted 'Use 1000 separator' was refused as "not a number"); a "0,5" in
    the file (a decimal comma) leaves every cell as it was."""
    if not any('"' in ln for _, ln in lines):
        return None                 # (no quoted cell: no ',' within a number; not split)
    grouped = None
    point = False
    for lineno, ln in lines:
        for j, cell in enumerate(_split(ln, ",")):
            if "," in cell:
                if not _CSV_COMMA_GROUPED.fullmatch(cell):
                    return None
                grouped = grouped or (lineno, j, cell)
            point = point or "." in cell
    return grouped if point else None


def _csv_thousands(path, lines, sep: str | None, header: list[str] | None) -> str | None:
    """Whether '.' groups thousands in the data ``lines`` ((number, text)) of a CSV file: the
    note saying it is read so, or None where it is not. Decided by the whole file, never by
    one cell: separated by ';' or tab, a decimal comma somewhere ("0,5", or "1.000,5"
    itself), and every cell with a '.' a number grouped in threes (:data:`_CSV_GROUPED`);
    "1.000,5" was refused as "not a number" and, worse, "1.250" in such a file read as 1.25.
    FrfError naming both cells where a grouped cell and a decimal point ("1.5") share the
    file: "1.000" is then 1 or 1000, and nothing in the file says which. A file without a
    decimal comma keeps '.' the decimal point, as before ("1.250;0.002" is 1.25)."""
    if sep == ",":
        where = _csv_comma_thousands(lines)
        return None if where is None else (
            f"{path}: ',' read as a thousands separator (line {where[0]}, "
            f"{_csv_column(header, where[1])}: {_quoted(where[2])} is "
            f"{float(where[2].replace(',', ''))!r}): every ',' in the file's numbers is "
            "followed by groups of 3 digits, and its decimal mark is '.'")
    if sep not in (";", "\t"):
        return None
    body = "\n".join(ln for _, ln in lines)
    if "." not in body or "," not in body:
        return None
    grouped = point = comma = None
    for lineno, ln in lines:
        for j, cell in enumerate(_split(ln, sep)):
            if "." in cell:
                if _CSV_GROUPED.fullmatch(cell):
                    grouped = grouped or (lineno, j, cell)
                    if "," in cell:
                        comma = comma or (lineno, j, cell)
                elif _CSV_DECIMAL_POINT.fullmatch(cell):
                    point = point or (lineno, j, cell)
            elif "," in cell:
                comma = comma or (lineno, j, cell)
        if grouped and point and comma:
            break
    if grouped is None or comma is None:
        return None

    def at(where) -> str:
        return f"line {where[0]}, {_csv_column(header, where[1])}: {_quoted(where[2])}"

    if point is not None:
        raise FrfError(
            f"{path}: {at(grouped)} reads as a number with '.' grouping thousands, as the "
            f"file's decimal commas suggest ({at(comma)}), but {at(point)} has a decimal point: "
            "with both, which '.' groups thousands is not known (1.000 is 1 or 1000); save "
            "the file again without thousands separators (the cells' number format: untick "
            "'Use 1000 separator')")
    return (f"{path}: '.' read as a thousands separator and ',' as the decimal mark "
            f"({at(grouped)} is {_grouped_number(grouped[2])!r}): the file's decimal marks are "
            "commas, and every '.' in it is followed by groups of 3 digits")


def _grouped_number(cell: str) -> float:
    """The value of a cell of :data:`_CSV_GROUPED` ("1.000,5": 1000.5)."""
    return float(cell.replace(".", "").replace(",", "."))


#: a units comment line as a tool writes it: "# Units: g/N", "# FRF units = m/s^2/N", "# Unit:
#: Hz, g/N" (a unit per column, the frequency's first); laminid's "# ... units Pa/N" below
_CSV_UNITS_SAID = re.compile(r"\s*#.*?\bunits?\s*[:=]\s*(\S.*?)\s*\Z", re.IGNORECASE)
_CSV_UNITS_LAMINID = re.compile(r"\s*#.*?\bunits\s+(\S.*?)\s*\Z")


def _csv_units_comment(path, text: str) -> tuple[str | None, str | None, int | None]:
    """The FRF unit a CSV file's comment line states, the frequency unit it states (None
    where it states none) and the line's number: laminid's "# laminid FRF, units Pa/N" (the
    rest of the line: a unit may hold spaces, "m/s^2 / N"), or a tool's "# Units: g/N",
    "# FRF units = m/s^2/N", "# Units: Hz, g/N" (one unit per column or per kind, the
    frequency's first; an FRF unit is a ratio, "g/N", "m s^-2 N^-1": "# Units: SI" states
    none). "# Units: g/N" was not read (the FRFs 'unit not stated'), and
    "# units = g/N" read as the unit "= g/N". FrfError where the list names more than one
    FRF unit (which column each is not said)."""
    from laminid_cli.frf.generic_h5 import freq_unit_factor, unbracketed

    for lineno, ln in enumerate(text.splitlines(), start=1):
        said = _CSV_UNITS_SAID.match(ln)
        if said is None:
            hit = _CSV_UNITS_LAMINID.match(ln)
            if hit:
                return hit.group(1), None, lineno
            continue
        value = unbracketed(said.group(1)).strip()
        items = [v.strip() for v in re.split(r"[,;\t]", value)]
        freq_unit = items[0] if len(items) > 1 and freq_unit_factor(items[0]) else None
        frf_units = list(dict.fromkeys(
            v for v in items[1 if freq_unit else 0:]
            if v and v.lower() not in _CSV_NOT_FRF_UNITS and not v.lower().startswith("db")
            and ("/" in v or "-1" in v)))         # an FRF's unit: a response over a force
        if len(frf_units) > 1:
            raise FrfError(f"{path}: line {lineno}: {_quoted(ln.strip())} names more than one "
                           f"FRF unit ({', '.join(frf_units)}), not which column each is; "
                           "give one ('# units g/N') or each FRF column's in the header "
                           "('H1_re [g/N]')")
        if frf_units or freq_unit:
            return (frf_units[0] if frf_units else None), freq_unit, lineno
        # "# Units: SI": no unit of the FRFs or the frequency; a later line may give one
    return None, None, None


def _csv_separator(line: str) -> str | None:
    """The cell separator of a CSV line: ";" first, a European spreadsheet writes
    "125,05;0,0012" (';' between cells, ',' the decimal mark), which split at ',' was refused
    as "'5;0' is not a number"; then tab, ","; None for blanks."""
    return next((c for c in (";", "\t", ",") if c in line), None)


def _csv_number(cell: str, sep: str | None) -> bool:
    """Whether ``cell`` of a line separated by ``sep`` is a number (a decimal comma with ';'
    or tab)."""
    if sep in (";", "\t") and "," in cell and "." not in cell:
        cell = cell.replace(",", ".")
    if sep in (";", "\t") and _CSV_GROUPED.fullmatch(cell):
        return True                         # "1.000,5": _csv_thousands decides
    try:
        float(cell)
    except ValueError:
        try:
            parse_complex_cell(cell)
        except ValueError:
            return False
    return True


def _csv_preamble(lines) -> int:
    """How many of the non-comment ``lines`` ((number, text)) come before a CSV file's header:
    an analyser's or spreadsheet's export writes its title, date and settings above the
    column names ("Title: plate", "Date;07.12.2026"), and the first of them was taken for the
    header ("line 2, column 1 ('Title:'): 'Date:' is not a number"). They are the lines
    above the last one before the first data line (first cell a number), when that one
    is a header: no cell of it a number, as many cells as the data line, split alike; else
    0 (a header and a bad data line are named as before)."""
    for i, (_, ln) in enumerate(lines):
        sep = _csv_separator(ln)
        cells = _split(ln, sep)
        if cells and _csv_number(cells[0], sep):
            break
    else:
        return 0
    if i < 2:
        return 0
    header = lines[i - 1][1]
    if _csv_separator(header) != sep:
        return 0
    names = _split(header, sep)
    if len(names) != len(cells) or any(c and _csv_number(c, sep) for c in names):
        return 0
    return i - 1


def csv_frequency_first(path, rows) -> bool:
    """Whether the text lines ``rows`` of the CSV file ``path`` have the frequency in their
    first column, as a CSV FRF file has: the first cell of the first line below any comments
    and preamble (:func:`_csv_preamble`) a number (no header), or a name whose unit is a
    frequency's ("X [Hz]", "f / kHz") or that names one ("f", "Frequency (kHz)", "omega");
    False for no such line. For :func:`laminid_cli.resultfile.is_frf_text_file` (show and
    report given FRFs)."""
    from laminid_cli.frf.generic_h5 import _ANGULAR_NAME, _FREQ_NAME

    lines = [(i + 1, ln) for i, ln in enumerate(rows)
             if ln.strip() and not is_comment_line(ln)]
    if not lines:
        return False
    first = lines[_csv_preamble(lines)][1]
    sep = _csv_separator(first)
    cell = (_split(first, sep) or [""])[0]
    if _csv_number(cell, sep):
        return True                         # no header: the frequency first
    try:
        if _csv_freq_factor(path, cell)[1]:
            return True                     # its unit a frequency's: "X [Hz]", "f / kHz"
    except LaminidError:
        pass                                # "Time [s]"; "omega" (its name, below)
    name = re.sub(r"[\[(].*", "", cell).strip()    # "f [Hz]", "Frequency (kHz)": f, Frequency
    return bool(name and (_FREQ_NAME.fullmatch(name) or _ANGULAR_NAME.fullmatch(name)
                          or name.lower().startswith(("freq", "f_hz", "omega"))))


def _csv_two_line_header(names_line: str, units_line: str) -> list[str] | None:
    """The header of a CSV whose column names are over a line of their units, as loggers and
    spreadsheets write it ("Frequency,H1 Real,..." over "Hz,m/s^2/N,..."): each name with its
    unit in brackets ("Frequency [Hz]", "H1 Real [m/s^2/N]"; a name that has one keeps it, a
    blank unit adds none), which the header's readers then take the units from. The units'
    line was taken for the header and the names' line skipped as a title: the points were
    named "m/s^2/N" and the FRF unit lost. None unless both lines split alike into as many
    cells and the first unit is a frequency unit (Hz, kHz, rad/s)."""
    from laminid_cli.frf.generic_h5 import freq_unit_factor, unbracketed

    sep = _csv_separator(units_line)
    if sep != _csv_separator(names_line):
        return None
    names, units = _split(names_line, sep), _split(units_line, sep)
    if len(names) != len(units) or len(names) < 2 or not units[0] \
            or freq_unit_factor(units[0]) is None or _csv_number(names[0], sep):
        return None
    merged = []
    for name, unit in zip(names, units):
        unit = unbracketed(unit.strip()).strip()
        has_unit = re.search(r"[\[(][^\])]*[\])]\s*\Z", name) is not None
        merged.append(name if not unit or has_unit else f"{name} [{unit}]")
    return merged


def _check_csv_lines(path, freq, frf, lines, header, labels) -> None:
    """FrfError naming the file line of a CSV's frequency that is not finite or not above the
    one before, or of an FRF value that is not finite: check_frf_arrays (every reader's check)
    counts the axis' lines from 1, which in a CSV are not its lines: 'line 50: 50 Hz, line
    51: 50 Hz' for file lines 51 and 52 (the header above), further off after a preamble or
    dropped 0 Hz lines; and 'FRF of point 1 has NaN/inf at 1 Hz' said no line."""
    freq = np.asarray(freq)
    bad = np.flatnonzero(~np.isfinite(freq))
    if bad.size:
        raise FrfError(f"{path}: line {lines[bad[0]][0]}, {_csv_column(header, 0)}: the "
                       f"frequency {freq[bad[0]]:g} is not a finite number")
    down = np.flatnonzero(np.diff(freq) <= 0)
    if down.size:
        i = down[0]
        raise FrfError(f"{path}: the frequency is not strictly increasing: line "
                       f"{lines[i][0]}: {freq[i]:g} Hz, line {lines[i + 1][0]}: "
                       f"{freq[i + 1]:g} Hz")
    bad = np.argwhere(~np.isfinite(frf))
    if bad.size and np.shape(frf)[1] == len(lines):
        p, k = bad[0]
        raise FrfError(f"{path}: line {lines[k][0]}: the FRF of point {labels[p]} has "
                       f"NaN/inf at {freq[k]:g} Hz; only a 0 Hz line of them is dropped")


def read_frf_csv(path) -> FrfSet:
    """Read a CSV FRF file: ``freq, re_1, im_1, ...``, ``freq, H_1, H_2, ...`` of complex cells
    or magnitude and phase columns named in the header (see module docstring).

    A note on what was assumed (the unit of a phase column whose header gives none) is in
    the returned set's ``meta["notes"]``; a warning where the frequency's header states no
    unit (read as Hz; refused, FrfError, where it ends below
    :data:`UNSTATED_FREQ_MIN_SPAN_HZ`) in its ``meta["warnings"]``."""
    path = Path(path)
    try:
        text, encoding = decode_text(path.read_bytes())
    except OSError as exc:
        raise FrfError(f"{path}: cannot read the file ({exc.strerror or exc})") from exc
    if text is None:
        raise FrfError(f"{path}: not a text (CSV) file; {_not_the_format(path, 'csv')}")
    # not stated: not "1", which declares FRFs dimensionless
    units, comment_freq_unit, units_line = _csv_units_comment(path, text)
    if units is not None:
        _check_names(path, units_line, [units], "FRF unit")
    # a line of separators only (",,,,", a spreadsheet's formatted empty row) is blank
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines())
             if ln.strip(' \t,;"') and not is_comment_line(ln)]
    if len(lines) > 1:
        check_frf_size(1, len(lines) - 1, str(path))
    if not lines:
        comments = sum(1 for ln in text.splitlines() if is_comment_line(ln))
        # ('no data lines' said of a file of comments alone as of an empty one)
        what = (f"holds only comments ({comments} '#' line{'s' if comments > 1 else ''}), no "
                "data" if comments else "the file is empty (0 bytes)" if not text else
                "holds only blank lines, no data" if not text.strip() else "no data lines")
        raise FrfError(f"{path}: {what} (expected columns freq, re_1, im_1, ...)")
    notes: list[str] = []
    preamble = _csv_preamble(lines)
    two_line = _csv_two_line_header(lines[preamble - 1][1], lines[preamble][1]) \
        if preamble else None
    names_line = lines[preamble - 1][1] if two_line is not None else ""
    if two_line is not None:
        preamble -= 1               # the names' line is the header's first, no preamble
        notes.append(f"{path}: a header of two lines: the column names (line "
                     f"{lines[preamble][0]}) over their units (line {lines[preamble + 1][0]}), "
                     f"read as {', '.join(two_line)}")
    if preamble:
        shown = ", ".join(_quoted(ln.strip()) for _, ln in lines[:min(preamble, 3)])
        notes.append(f"{path}: lines {lines[0][0]}-{lines[preamble - 1][0]} above the header "
                     f"skipped ({shown}{', ...' if preamble > 3 else ''}): they are no "
                     "column names or data")
        lines = lines[preamble:]
    if two_line is not None:
        lines = lines[1:]           # the units' line next, read as the header, then replaced
    first = lines[0][1]
    sep = _csv_separator(first)
    header = None
    thousands = False               # '.' groups thousands: _csv_thousands

    def number(cell: str) -> float | complex:
        """A cell's value: a float, or a complex for a cell in complex syntax."""
        if thousands and "." in cell and _CSV_GROUPED.fullmatch(cell):
            return _grouped_number(cell)           # "1.000,5"
        if thousands and sep == "," and "," in cell and _CSV_COMMA_GROUPED.fullmatch(cell):
            return float(cell.replace(",", ""))    # "1,000.5", quoted
        if sep in (";", "\t") and "," in cell and "." not in cell:
            cell = cell.replace(",", ".")          # the decimal comma
        try:
            return float(cell)
        except ValueError:
            return parse_complex_cell(cell)

    cells = _split(first, sep)
    if not _csv_number(cells[0], sep) and not _SHEET_ERROR_FIRST.match(first):
        # the frequency's name: a first line whose first cell is a number is data, and a bad
        # cell in it is named as such (it was taken for the header, the line lost)
        header = cells if two_line is None else two_line
        _check_names(path, lines[0][0], cells)
        if two_line is not None:
            _check_names(path, lines[0][0] - 1, _split(names_line, sep))
        lines = lines[1:]
        if [c.strip().lower() for c in cells[:2]] == ["name", "specimen"]:
            # laminid batch's summary.csv (long or --wide): was "line 2, column 1 ('name'):
            # 'example1/S1.1' is not a number"
            raise FrfError(f"{path}: a laminid batch summary, not FRFs: 'laminid report {path}' "
                           "draws it; FRFs are what laminid acquire writes (.frf.h5), UFF 58 or "
                           "a CSV of frequency and FRF columns")
    else:
        header = _commented_header(text, lines[0][0], sep, len(cells))
        if header is not None:
            _check_names(path, lines[0][0] - 1, header)
            notes.append(f"column names read from the comment line just above the data (line "
                         f"{lines[0][0] - 1}, as numpy's savetxt writes a header): "
                         f"{', '.join(header)}")
    grouping = _csv_thousands(path, lines, sep, header)
    if grouping is not None:
        thousands = True
        notes.append(grouping)
    rows = []
    #: the first complex cell of each column that has one: (line, cell)
    complex_at: dict[int, tuple[int, str]] = {}
    sheet_error = None              # a CSV_SHEET_ERRORS cell read as NaN
    for lineno, ln in lines:
        cells = _split(ln, sep)
        row, bad = [], None
        for j, cell in enumerate(cells):
            try:
                v = number(cell)
            except ValueError:
                if not (j and row and row[0] == 0 and cell.upper() in CSV_SHEET_ERRORS):
                    bad = bad or (j, cell)
                    continue
                v = float("nan")    # a spreadsheet's X/F at 0 Hz: NaN, the line dropped below
                sheet_error = sheet_error or cell
            if isinstance(v, complex) and j not in complex_at:
                complex_at[j] = (lineno, cell)
            row.append(v)
        if bad is not None:
            j, cell = bad
            looks_complex = re.search(r"\d", cell) and re.search(r"[ij]", cell, re.I)
            raise FrfError(f"{path}: line {lineno}, {_csv_column(header, j)}: "
                           f"{_not_a_number(cell, bool(complex_at or looks_complex))}")
        rows.append(row)
    if not rows:
        raise FrfError(f"{path}: header but no data lines")
    for i, r in enumerate(rows):
        if len(r) != len(rows[0]):
            raise FrfError(f"{path}:{lines[i][0]}: {len(r)} columns, the first data line has "
                           f"{len(rows[0])}")
    data = np.array(rows)           # complex where any cell is
    n = data.shape[1]
    first = data[:, 0].real
    if (header and header[0].strip().lower() in ("", "index", "unnamed: 0") and n > 2
            and first.size > 2 and first[0] in (0, 1)
            and np.array_equal(first, first[0] + np.arange(first.size))):
        # pandas' to_csv writes its row index first, under an empty name: 0, 1, 2 ... read as
        # the frequency in Hz would put every mode at a line number
        raise FrfError(f"{path}: {_csv_column(header, 0)} holds {first[0]:g}, {first[1]:g}, "
                       f"{first[2]:g} ... (line numbers): a row index, as pandas' to_csv writes "
                       "one, not the frequency; write the file with index=False or delete that "
                       "column")
    if 0 in complex_at:             # numpy writes a complex array's frequency "(125+0j)"
        i = np.flatnonzero(data[:, 0].imag != 0)
        if i.size:
            raise FrfError(f"{path}: line {lines[i[0]][0]}, {_csv_column(header, 0)}: the "
                           f"frequency {data[i[0], 0]} has an imaginary part")
    warnings: list[str] = []
    dc = nonfinite_dc_lines(data[:, 0].real, data[:, 1:])
    if dc:
        # before the layouts are told apart: a NaN phase there would weigh in on its unit
        warnings.append(nonfinite_dc_warning(
            path, dc, "NaN/inf" if sheet_error is None else f"NaN/inf or {sheet_error}"))
        data, lines = data[dc:], lines[dc:]
    kinds = [_csv_part_kind(h) for h in header[1:]] if header else []
    complex_columns = sorted(j for j in complex_at if j > 0)
    expected = ("expected the frequency, then a real and an imaginary column per FRF, or one "
                "column of complex numbers per FRF (a+bj, a+bi), or a magnitude and a phase "
                "column per FRF named in the header")
    if complex_columns:
        k = complex_columns[0]
        at = f"{_csv_column(header, k)}, line {complex_at[k][0]}: {_quoted(complex_at[k][1])}"
        if any(kinds):
            raise FrfError(f"{path}: the header names magnitude and phase columns "
                           f"({', '.join(repr(h) for h in header)}) but the cells hold "
                           f"complex numbers ({at}); {expected}")
        plain = [j for j in range(1, n) if j not in complex_at]
        if plain:
            # a real and an imaginary column with a stray complex cell is no file of complex
            # columns: every FRF column of one holds complex numbers (a "0" in some lines)
            raise FrfError(f"{path}: {_csv_column(header, plain[0])} holds no complex number "
                           f"where {_csv_column(header, k)} does (line {complex_at[k][0]}: "
                           f"{_quoted(complex_at[k][1])}); {expected}, not both")
        check_frf_size(n - 1, data.shape[0], str(path))
        frf = data[:, 1:].T.astype(complex)
        labels = tuple(str(i + 1) for i in range(n - 1))
        unit_columns = [[j] for j in range(1, n)]
        if header and len(header) == n:
            labels = tuple(_csv_unit_removed(h) or str(i + 1)
                           for i, h in enumerate(header[1:]))
    elif any(kinds):
        check_frf_size(max((n - 1) // 2, 1), data.shape[0], str(path))
        frf, labels, more = _csv_mag_phase(path, header, data.real, lines)
        notes += more
        unit_columns = [[j] for j in range(1, n) if kinds[j - 1] == "magnitude"
                        and not _csv_magnitude_in_db(path, header, j)]
    else:
        data = data.real
        check_frf_size(max((n - 1) // 2, 1), data.shape[0], str(path))
        if n < 3 or (n - 1) % 2:
            raise FrfError(f"{path}: {n} columns; expected the frequency then a real and an "
                           "imaginary column per FRF (an odd number, at least 3), or one "
                           "column of complex numbers per FRF (a+bj, a+bi), or a magnitude "
                           "and a phase column per FRF named in the header")
        frf = np.empty((data.shape[0], (n - 1) // 2), dtype=complex)
        frf.real, frf.imag = data[:, 1::2], data[:, 2::2]   # no inf * 1j = nan: inf stays inf
        frf = frf.T
        labels = tuple(str(i + 1) for i in range(frf.shape[0]))
        unit_columns = [[j, j + 1] for j in range(1, n, 2)]
        if header and len(header) == n:
            labels = tuple(_real_part_label(h) or str(i + 1)
                           for i, h in enumerate(header[1::2]))
    if encoding == "cp1252":
        notes.append(f"{path}: not UTF-8; read as Windows-1252 text (a spreadsheet's 'CSV' "
                     "export on Windows: '°' is byte 0xB0)")
    factor, stated = _csv_freq_factor(path, header[0] if header else "")
    if comment_freq_unit is not None:
        from laminid_cli.frf.generic_h5 import freq_unit_factor

        said = freq_unit_factor(comment_freq_unit)
        if not stated:
            factor, stated = said, True
            notes.append(f"{path}: the frequency read in {comment_freq_unit}, as the comment "
                         f"line {units_line} says (its first unit)")
        elif not np.isclose(said, factor, rtol=1e-12):
            raise FrfError(f"{path}: {_csv_column(header, 0)} states a frequency unit the "
                           f"comment line {units_line} contradicts ({comment_freq_unit!r}, its "
                           "first unit); make them agree")
    _check_csv_lines(path, data[:, 0].real * factor, frf, lines, header, labels)
    freq, frf, _ = check_frf_arrays(data[:, 0].real * factor, frf, source=str(path))
    meta: dict = {}
    if not stated:
        warnings.append(_unstated_freq_warning(path, header, sep, freq))
    if warnings:
        meta["warnings"] = warnings
    if units is None and header and len(header) == n and len(unit_columns) == frf.shape[0]:
        # "H1 real [g/N]": the unit a spreadsheet's header gives was read as "not stated"
        units, point_units = _csv_header_units(path, header, unit_columns)
        if point_units:
            meta["point_units"] = point_units
    if units is None:
        notes.append(unit_not_stated_note(path, "a comment line '# units Pa/N' above the data "
                                                "or the FRF columns' headers, 'H1_re [g/N]', "
                                                "state it"))
    if notes:
        meta["notes"] = notes
    return FrfSet(freq=freq, frf=frf, labels=labels, units=units, source=str(path), meta=meta)


def write_frf_csv(path, fs: FrfSet, *, overwrite: bool = False) -> Path:
    """Write ``freq_Hz, <label>_re, <label>_im, ...`` with full double precision."""
    path = _new_target(path, overwrite)
    labels = fs.labels or tuple(str(i + 1) for i in range(fs.n_points))
    data = np.empty((fs.freq.size, 1 + 2 * fs.n_points))
    data[:, 0] = fs.freq
    data[:, 1::2] = fs.frf.real.T
    data[:, 2::2] = fs.frf.imag.T
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        # a unit not known is written as such: "units 1" would declare the FRFs dimensionless
        fh.write(f"# laminid FRF, units {fs.units}\n" if fs.units is not None else
                 "# laminid FRF, unit not stated in the source file\n")
        w = csv.writer(fh)
        w.writerow(["freq_Hz"] + [f"{lab}_{part}" for lab in labels for part in ("re", "im")])
        w.writerows([[repr(float(v)) for v in row] for row in data])
    return path


# --------------------------------------------------------------------------- UFF 58
def read_frf_uff(path) -> FrfSet:
    """Read the type-58 FRF records of a Universal File (see module docstring)."""
    import pyuff

    path = Path(path)
    try:
        uff = pyuff.UFF(str(path))
        types = np.asarray(uff.get_set_types(), dtype=int)
    except Exception as exc:  # pyuff raises bare Exception on unreadable files
        raise FrfError(f"{path}: not a readable Universal File ({exc})") from exc
    idx = [int(i) for i in np.flatnonzero(types == 58)]
    if not types.size:             # not one '    -1' delimited dataset: another kind of file
        raise FrfError(f"{path}: not a Universal File (no dataset between '    -1' lines, as "
                       f"UFF 58 FRF records are); {_not_the_format(path, 'uff')}")
    if not _uff_ends_closed(path):
        # pyuff drops a dataset its end tag never closes: a file cut short gave fewer points,
        # silently, and a fit of those (exit 0)
        raise FrfError(f"{path}: the file ends inside a dataset, after {types.size} complete "
                       f"ones (no '    -1' line closes the last): cut short, a copy or an "
                       "export that did not finish; copy or export it again")
    if not idx:
        found = ", ".join(str(t) for t in sorted(set(types.tolist()))) or "none"
        raise FrfError(f"{path}: no type-58 (function at nodal DOF) record; dataset types "
                       f"found: {found}")
    si = _check_uff_units_records(path, uff, [int(i) for i in np.flatnonzero(types == 164)])
    try:
        sets = uff.read_sets(idx)
    except Exception as exc:  # noqa: BLE001 - pyuff raises bare Exception, and others
        raise FrfError(f"{path}: cannot read the type-58 records ({exc})") from exc
    sets = [sets] if isinstance(sets, dict) else sets
    for k, d in enumerate(sets, start=1):
        _check_uff_record(path, k, d)
    _recover_uff_labels(path, sets)
    frfs = [d for d in sets if int(d.get("func_type", 0)) == UFF_FRF]
    if not frfs:
        kinds = sorted({int(d.get("func_type", 0)) for d in sets})
        raise FrfError(f"{path}: no FRF among the type-58 records (function types {kinds}; "
                       f"{UFF_FRF} = frequency response function)")
    real = [k for k, d in enumerate(frfs, start=1) if not np.iscomplexobj(d["data"])]
    if real:
        odt = int(frfs[real[0] - 1].get("ord_data_type", 0) or 0)
        raise FrfError(f"{path}: FRF record {real[0]} holds real values (ordinate data type "
                       f"{odt}; {len(real)} of {len(frfs)} FRF records are real): a magnitude "
                       "or one part only, from which no pole can be fitted; the fit needs the "
                       "complex FRF (ordinate data type 5 or 6)")
    absc = int(frfs[0].get("abscissa_spec_data_type", 0) or 0)
    if absc not in (0, UFF_ABSCISSA_FREQUENCY):
        raise FrfError(f"{path}: the abscissa of the FRF records is not frequency (specific data "
                       f"type {absc}, expected {UFF_ABSCISSA_FREQUENCY} = frequency in Hz)")
    freq = np.asarray(frfs[0]["x"], dtype=float) * _uff_abscissa_to_hz(path, 1, frfs[0])
    for k, d in enumerate(frfs[1:], start=2):
        x = np.asarray(d["x"], dtype=float) * _uff_abscissa_to_hz(path, k, d)
        if x.shape != freq.shape or not np.allclose(x, freq, rtol=1e-9, atol=1e-9):
            raise FrfError(f"{path}: FRF record {k} has a different frequency axis "
                           f"({x.size} lines, {x[0]:g}-{x[-1]:g} Hz) from record 1 "
                           f"({freq.size} lines, {freq[0]:g}-{freq[-1]:g} Hz)")
    check_frf_size(len(frfs), freq.size, str(path))
    frf = np.array([np.asarray(d["data"]).astype(complex) for d in frfs])

    def dof(d):
        return (int(d.get("rsp_node", 0)), int(d.get("rsp_dir", 0)),
                int(d.get("ref_node", 0)), int(d.get("ref_dir", 0)))

    # each DOF's coherence records in file order, the n-th to its n-th FRF: a DOF measured
    # twice (a repeat) gave both FRFs the second's coherence
    coh_by_dof: dict[tuple, list] = {}
    #: coherence records not used, each with why: they were dropped without a word, so that
    #: a file whose coherence was written on another axis read as one without coherence
    unused: list[tuple[int, str]] = []
    for k, d in enumerate(sets, start=1):
        if int(d.get("func_type", 0)) != UFF_COHERENCE:
            continue
        n = np.asarray(d["x"]).size
        if n == freq.size:
            coh_by_dof.setdefault(dof(d), []).append((k, np.asarray(d["data"]).real))
        else:
            unused.append((k, f"{n} lines where the FRFs have {freq.size}"))
    coherence = None
    if coh_by_dof:
        rows = []
        for d in frfs:
            queue = coh_by_dof.get(dof(d))
            rows.append(queue.pop(0)[1] if queue else np.full(freq.size, np.nan))
        coherence = np.array(rows)
        unused += [(k, "no FRF record of its DOF left to pair it with")
                   for queue in coh_by_dof.values() for k, _ in queue]
    # the response DOF, and the reference's where they differ (a roving hammer: "5+Z:2+Z")
    roving = len({dof(d)[2:] for d in frfs}) > 1
    labels = tuple(f"{d.get('rsp_node', k + 1)}{_dir(d.get('rsp_dir', 0))}"
                   + (f":{d.get('ref_node', 0)}{_dir(d.get('ref_dir', 0))}" if roving else "")
                   for k, d in enumerate(frfs))
    each = [_uff_units(d) for d in frfs]
    # no units labels, a type over a force's, in a file whose units record says SI: the unit
    # a tool generates from the types (the labels "take precedence" where given)
    typed = {k: _uff_typed_unit(d) for k, d in enumerate(frfs) if si and each[k] is None}
    typed = {k: unit for k, unit in typed.items() if unit is not None}
    for k, unit in typed.items():
        each[k] = unit
    units = each[0]
    warnings = []
    dc = nonfinite_dc_lines(freq, frf.T)
    if dc:
        warnings.append(nonfinite_dc_warning(path, dc))
        freq, frf = freq[dc:], frf[:, dc:]
        coherence = None if coherence is None else coherence[:, dc:]
    freq, frf, coherence = check_frf_arrays(freq, frf, coherence, source=str(path))
    meta = {"uff_ids": [str(d.get("id1", "")) for d in frfs]}
    stated = [_uff_abscissa_label(d) for d in frfs]
    if not any(stated):
        # type 18 says "frequency", not in which unit (a tool's rad/s or kHz axis written
        # with type 18 and no label reads as Hz): Hz, said, and refused where it ends below
        # 100 (kHz read as Hz: every mode 1000 times too low)
        label = str(frfs[0].get("abscissa_axis_units_lab", "") or "").strip()
        kind = "frequency" if absc == UFF_ABSCISSA_FREQUENCY else "unknown"
        warnings.append(unstated_freq_warning(
            f"{path}: the FRF records' abscissa (specific data type {absc}, {kind}; units "
            f"label {label!r})", freq,
            "state it in the records' abscissa units label (record 8, field 6): 'kHz' or "
            "'rad/s' (pyuff: abscissa_axis_units_lab='kHz')", "the label 'Hz'"))
    if warnings:
        meta["warnings"] = warnings
    if typed:
        k = min(typed)
        d = frfs[k]
        one = len(typed) == 1
        meta["notes"] = [
            f"{path}: FRF record{'' if one else 's'} "
            f"{', '.join(str(j + 1) for j in sorted(typed))} state{'s' if one else ''}"
            f" no units label: {typed[k]} from the specific data types "
            f"({int(d['ordinate_spec_data_type'])} over {int(d['orddenom_spec_data_type'])}) in "
            "the units record's SI"]
    if units is None and len(set(each)) == 1:
        d = frfs[0]
        meta["notes"] = [unit_not_stated_note(
            path, "FRF records' ordinate units label "
                  f"{str(d.get('ordinate_axis_units_lab', '') or '').strip()!r} over "
                  f"{str(d.get('orddenom_axis_units_lab', '') or '').strip()!r}")]
    records_of: dict[str, list[int]] = {}
    for k, label in enumerate(labels, start=1):
        records_of.setdefault(label, []).append(k)
    twice = {label: ks for label, ks in records_of.items() if len(ks) > 1}
    if twice:
        # a repeated measurement: nothing in the file tells the records apart but their order
        meta.setdefault("notes", []).append(
            f"{path}: the same DOF in more than one FRF record ("
            + "; ".join(f"{label}: records {', '.join(map(str, ks))}"
                        for label, ks in twice.items())
            + "): each fitted as a point of its own, its coherence the DOF's record of the "
              "same rank")
    if len(set(each)) > 1:
        # accelerances beside mobilities (another tool's file): one pole set, so the modes
        # are those of all; each FRF's modal constants are in its own unit (fit-frf says so)
        meta["point_units"] = each
    if unused:
        meta.setdefault("notes", []).append(
            f"{path}: coherence (function type {UFF_COHERENCE}) not used: "
            + "; ".join(f"type-58 record {k}: {why}" for k, why in sorted(unused)))
    tau = _uff_window(frfs)
    if tau is not None:
        meta["settings"] = {"exp_window_s": tau}
    return FrfSet(freq=freq, frf=frf, coherence=coherence, labels=labels, units=units,
                  source=str(path), meta=meta)


#: the SI unit of a type-58 record's ordinate of each specific data type laminid knows
#: (record 9, field 1: 8 displacement, 11 velocity, 12 acceleration, 15 pressure), over an
#: excitation force (record 10: 13) in N, as a tool labels a record that gives no label
UFF_SI_UNIT_OF_TYPE = {8: "m", 11: "m/s", 12: "m/s^2", 15: "Pa"}


def _uff_typed_unit(d) -> str | None:
    """The FRF unit of a type-58 record by its specific data types, in SI ("m/s^2/N" for 12
    over 13), where both its units labels are blank or "NONE"; None where a label is given
    or a type is another."""
    for key in ("ordinate_axis_units_lab", "orddenom_axis_units_lab"):
        if str(d.get(key, "") or "").strip().upper() not in ("", "NONE"):
            return None
    try:
        types = (int(d.get("ordinate_spec_data_type", 0)),
                 int(d.get("orddenom_spec_data_type", 0)))
    except (TypeError, ValueError):
        return None
    if types[1] != 13 or types[0] not in UFF_SI_UNIT_OF_TYPE:
        return None
    return f"{UFF_SI_UNIT_OF_TYPE[types[0]]}/N"


def _check_uff_units_records(path, uff, idx) -> bool:
    """The units records (dataset 164) of a Universal File: SI (length and force factors 1,
    whatever the units code says) is read as the file's FRFs are (True: the file has one);
    another unit system is refused. Its factors convert a record's values to SI by the powers
    of length and force of its specific data type (Addendum A of dataset 58; UC-SDRL's
    164.asc: "to convert from universal file units to SI divide by the appropriate factor"),
    while the units labels, which laminid takes the FRF unit from, are display text
    ("mm/s^2" over "N" in a file of mm and mN): which of the two the values follow is not
    said, and a guess is wrong by the factor (1000 for mm)."""
    if not idx:
        return False
    try:
        records = uff.read_sets(idx)
    except Exception as exc:  # noqa: BLE001 - pyuff raises bare Exception
        what = None
        for i in idx:
            what = what or _uff_164_problem(path, uff, i)
        raise FrfError(f"{path}: cannot read its units record (dataset 164"
                       + (f"): {what}" if what else f") ({exc})")
                       + "; export the file again, or delete that dataset where the file is in "
                         "SI (its FRF records are then read by their units labels)") from exc
    for d in [records] if isinstance(records, dict) else records:
        try:
            factors = float(d["length"]), float(d["force"])
        except (KeyError, TypeError, ValueError):
            raise FrfError(f"{path}: its units record (dataset 164) has no length and force "
                           "factors") from None
        if not np.allclose(factors, 1.0, rtol=1e-9, atol=0):
            name = str(d.get("units_description", "") or "").strip()
            raise FrfError(
                f"{path}: its units record (dataset 164) says units code "
                f"{d.get('units_code')} ({name!r}; length factor {factors[0]:.10g}, force "
                f"factor {factors[1]:.10g} to SI), not SI: laminid reads FRF records in SI "
                "units only (whether the values follow that record or their units labels is "
                "not said, a factor apart); export them from the tool in SI (units code 1, "
                "metre and newton)")
    return True


#: the numbers of a units record (dataset 164) after its record 1, each with its record:
#: record 2 FORMAT(3D25.17) the length, force and temperature factors, record 3 FORMAT(D25.17)
#: the temperature offset (the dataset 164 definition as reproduced in the docstring of pyuff
#: 2.5.8's ``pyuff/datasets/dataset_164.py``; pyuff reads them as 4 blank-separated numbers)
_UFF_164_NUMBERS = (("length factor", 2), ("force factor", 2), ("temperature factor", 2),
                    ("temperature offset", 3))


def _uff_164_problem(path, uff, i: int) -> str | None:
    """What is wrong with dataset ``i`` (0-based) of the Universal File ``path``, a units
    record (dataset 164) pyuff could not read: where it is (the dataset's number in the file,
    its line) and the field that is no number or is missing, by the lines of
    :data:`_UFF_164_NUMBERS`; None where none is found (pyuff's own words are given then)."""
    blocks = getattr(uff, "_block_ind", None)      # pyuff's byte offsets of each dataset
    try:
        start, end = (int(v) for v in blocks[i])
        raw = path.read_bytes()
    except (TypeError, IndexError, ValueError, OSError):
        return None
    first = raw.count(b"\n", 0, start) + 1         # the line of its opening '    -1'
    lines = raw[start:end + 1].decode("latin-1").splitlines()[2:]
    where = f"dataset {i + 1} of the file, line {first}"
    if not lines or not lines[0].strip():
        return f"{where}: record 1 (units code, description, temperature mode) is missing"
    rec1 = lines[0].ljust(40)
    for name, cell in (("units code", rec1[:10]), ("temperature mode", rec1[30:40])):
        try:
            int(cell.strip())
        except ValueError:
            return (f"{where}: record 1 (line {first + 2}), the {name} (I10): "
                    f"{_quoted(cell.strip())} is not a whole number")
    tokens = [(first + 3 + k, t) for k, ln in enumerate(lines[1:]) for t in ln.split()]
    for n, (name, record) in enumerate(_UFF_164_NUMBERS):
        if n >= len(tokens):
            return (f"{where}: it ends after {n} of its 4 numbers, the {name} (record "
                    f"{record}) missing")
        lineno, token = tokens[n]
        try:
            float(token.lower().replace("d", "e"))
        except ValueError:
            return (f"{where}: record {record} (line {lineno}), the {name}: {_quoted(token)} "
                    "is not a number")
    return None


#: the units labels of a type-58 record (records 8-10, field 6)
_UFF_LABELS = ("abscissa_axis_units_lab", "ordinate_axis_units_lab", "orddenom_axis_units_lab")


def _recover_uff_labels(path, sets) -> None:
    """Units labels that pyuff decoded with a replacement character (a byte not UTF-8: a
    Windows tool's "m/s²" in Windows-1252, "²" the byte 0xB2) read again from the file's
    bytes as Windows-1252. The unit was "m/s\ufffd/N", and another point's "m/s^2/N" a
    different unit."""
    raw = None
    for d in sets:
        for key in _UFF_LABELS:
            label = d.get(key)
            if not isinstance(label, str) or "\ufffd" not in label:
                continue
            if raw is None:
                raw = Path(path).read_bytes()
            pattern = rb"[\x80-\xff]".join(re.escape(part.encode("ascii", "replace"))
                                            for part in label.split("\ufffd"))
            m = re.search(pattern, raw)
            if m is not None:
                d[key] = m.group().decode("cp1252", errors="replace")


def _uff_ends_closed(path) -> bool:
    """Whether a Universal File ends with the ``    -1`` tag (I6, as pyuff finds the tags)
    that closes its last dataset: trailing blanks, line ends and a DOS end-of-file byte
    allowed, and no line end before it (pyuff writes it right after a binary record's data)."""
    with open(path, "rb") as fh:
        fh.seek(0, 2)
        fh.seek(max(0, fh.tell() - 256))
        tail = fh.read()
    return re.search(rb"    -1[ \t\r\n\x1a]*\Z", tail) is not None


def _uff_abscissa_to_hz(path, k: int, d) -> float:
    """The factor from the abscissa of FRF record ``k`` to Hz, by its units label (record 8,
    field 6): 1 for Hz or no label (:func:`read_frf_uff` warns where no record has one),
    1/(2 pi) for rad/s, 1000 for kHz (the specific data type
    18 says "frequency", not in which unit: a tool's rad/s axis read as Hz gave every natural
    frequency 2 pi times too high). FrfError for a label that is no frequency unit."""
    from laminid_cli.frf.generic_h5 import FREQ_UNITS, freq_unit_factor

    label = _uff_abscissa_label(d)
    if label is None:
        return 1.0
    factor = freq_unit_factor(label)
    if factor is None:
        raise FrfError(f"{path}: FRF record {k}: abscissa unit {label!r} is not a frequency "
                       f"unit laminid reads ({', '.join(FREQ_UNITS)})")
    return factor


def _uff_abscissa_label(d) -> str | None:
    """The abscissa units label of a type-58 record (record 8, field 6); None where blank or
    "NONE" (the format's "not used", pyuff's default)."""
    label = str(d.get("abscissa_axis_units_lab", "") or "").strip()
    return None if label.upper() in ("", "NONE") else label


def _uff_window(frfs) -> float | None:
    """The exponential window's time constant (s; NaN: unknown) that laminid wrote in the
    ``id3`` of every FRF record (:data:`UFF_WINDOW_ID`); None where any record is another
    tool's or does not say it."""
    import re

    pattern = re.escape(UFF_WINDOW_ID).replace(r"\{\}", r"(\S+)")
    values = set()
    for d in frfs:
        m = re.fullmatch(pattern, str(d.get("id3", "") or "").strip())
        if str(d.get("id2", "") or "").strip() != UFF_WRITER or m is None:
            return None
        values.add(m.group(1))
    if len(values) != 1:
        return None
    try:
        return float(values.pop())          # "unknown" -> ValueError
    except ValueError:
        return float("nan")


def _window_id(fs) -> str:
    """``id3`` of an FRF record of ``fs``: :data:`UFF_WINDOW_ID` where its settings record the
    exponential window (``exp_window_s``), else pyuff's default "NONE"."""
    settings = fs.meta.get("settings") or {}
    if "exp_window_s" not in settings:
        return "NONE"
    try:
        tau = float(settings["exp_window_s"])
    except (TypeError, ValueError):
        tau = float("nan")
    return UFF_WINDOW_ID.format(repr(tau) if np.isfinite(tau) and tau > 0 else "unknown")


def _uff_units(d) -> str | None:
    """The FRF unit of a type-58 record: its ordinate's unit label over its denominator's
    ("m/s^2" over "N": "m/s^2/N"); the ordinate's alone where the denominator has none
    ("NONE", pyuff's default); None where the ordinate has none (blank or "NONE": not stated,
    whatever the denominator says; a stated dimensionless ordinate is "1").

    A record laminid wrote (``id2`` "laminid") is joined exactly so: :func:`_uff_axes` split
    the unit at its last '/', so "N/N/N" is "N/N" over "N" and reads back "N/N/N" (laminid's
    files before that split wrote the whole unit over "NONE", also read right). Another tool's
    ordinate that already ends with its denominator ("m/s^2/N" over "N") is taken as the whole
    unit, not "m/s^2/N/N"; that guess is never applied to laminid's own records, where it
    turned "N/N/N" into "N/N"."""
    # in the ASCII spelling laminid writes ("m/s²" "m/s^2"): the same unit, one string
    ordinate = str(d.get("ordinate_axis_units_lab", "") or "").strip().translate(UFF_ASCII)
    if ordinate.upper() in ("", "NONE"):  # pyuff's default label: no unit given, as blank
        return None
    denominator = str(d.get("orddenom_axis_units_lab", "") or "").strip().translate(UFF_ASCII)
    if denominator.upper() in ("", "NONE"):
        return ordinate
    ours = str(d.get("id2", "") or "").strip() == UFF_WRITER
    if not ours and ordinate.endswith("/" + denominator):
        return ordinate
    return f"{ordinate}/{denominator}"


def _check_uff_record(path, k: int, d) -> None:
    """One type-58 record as pyuff returns it: a mapping with numeric ``x`` and ``data`` of
    the same length (``num_pts`` when given), integer DOF and type fields."""
    if not isinstance(d, dict) or "x" not in d or "data" not in d:
        raise FrfError(f"{path}: type-58 record {k} has no abscissa or data")
    for key in ("func_type", "abscissa_spec_data_type", "rsp_node", "rsp_dir", "ref_node",
                "ref_dir"):
        try:
            int(d.get(key, 0) or 0)
        except (TypeError, ValueError):
            raise FrfError(f"{path}: type-58 record {k}: field {key} is {d.get(key)!r}, "
                           "expected an integer") from None
    x, data = np.asarray(d["x"]), np.asarray(d["data"])
    for name, a in (("abscissa", x), ("data", data)):
        if a.dtype.kind not in "biufc" or a.ndim != 1:
            raise FrfError(f"{path}: type-58 record {k}: {name} is not a list of numbers")
    n = d.get("num_pts")
    if x.size != data.size or (n is not None and int(n) != data.size):
        raise FrfError(f"{path}: type-58 record {k} is truncated or inconsistent ({data.size} "
                       f"values, {x.size} abscissa values, header says {n})")


_DIRECTIONS = {1: "+X", 2: "+Y", 3: "+Z", -1: "-X", -2: "-Y", -3: "-Z"}


def _dir(code) -> str:
    code = int(code)
    return _DIRECTIONS.get(code, f"/{code}" if code else "")


def uff_direction(code) -> str | None:
    """A UFF direction code's name ("+Z" of 3, "-X" of -1); None for 0 (a scalar) or a code
    outside 1-3 either sign."""
    return _DIRECTIONS.get(int(code))


def negative_direction_points(labels) -> list[str]:
    """The labels of :func:`read_frf_uff` ("12-Z", "5+Z:2-Y") whose response or reference
    direction is negative: their FRF is the +direction's times -1, and so are its modal
    constants."""
    import re

    return [lab for lab in labels if re.search(r"\d-[XYZ]", str(lab))]


#: coherence at the resonances below which a point's FRF is called noisy when the file does
#: not record acquire's --coherence-min (its default)
DEFAULT_COHERENCE_MIN = 0.9


def coherence_at_resonances(freq, frf, coherence) -> np.ndarray:
    """Mean coherence of each FRF over its resonances (:func:`~laminid_cli.frf.store.
    resonance_lines`, as acquire's quality line takes them), the lines of unknown coherence
    left out; NaN where it is unknown at all of them.

    freq : (n_freq,) Hz; frf : complex (n_points, n_freq); coherence : (n_points, n_freq), 1
    """
    out = np.full(np.shape(frf)[0], np.nan)
    for p, (H, c) in enumerate(zip(np.atleast_2d(frf), np.atleast_2d(coherence))):
        top = resonance_lines(freq, H) & np.isfinite(c)
        if top.any():
            out[p] = float(np.mean(c[top]))
    return out


def point_quality_notes(fs) -> list[str]:
    """Notes on the FRFs a fit should not be trusted blindly with: points whose coherence at
    the resonances is below the file's ``coherence_min`` (acquire's --coherence-min, else
    :data:`DEFAULT_COHERENCE_MIN`) and points whose inputs went over range (``overloads`` of
    an acquire file). A file acquired with --no-prompt keeps such points as measured; its fit
    then misses modes or lists noise without a word. And an acquisition whose session stopped
    before its last point (``complete`` false): fitted as if it were the whole test."""
    notes = []
    labels = list(fs.labels) or [str(i + 1) for i in range(fs.n_points)]
    try:
        n_asked = int((fs.meta.get("settings") or {})["n_points"])
    except (KeyError, TypeError, ValueError):
        n_asked = None
    # not marked complete, and (where the file says how many were asked for) points missing:
    # a session that saved its last point and stopped before marking the file is whole
    if fs.meta.get("complete") is False and (n_asked is None or fs.n_points < n_asked):
        asked = "" if n_asked is None else f" of the {n_asked} asked for"
        notes.append(f"{fs.source}: an unfinished acquisition (its session stopped): "
                     f"{fs.n_points} point{'s' if fs.n_points != 1 else ''}{asked}, fitted "
                     "as saved (a mode with a nodal line through every point measured goes "
                     "unseen); laminid acquire ... --resume measures the rest")
    if fs.coherence is not None and np.isfinite(fs.coherence).any():
        settings = fs.meta.get("settings") or {}
        try:
            c_min = float(settings["coherence_min"])
        except (KeyError, TypeError, ValueError):
            c_min, said = DEFAULT_COHERENCE_MIN, f"{DEFAULT_COHERENCE_MIN:g}"
        else:
            said = f"{c_min:g}, the acquisition's --coherence-min"
        coh = coherence_at_resonances(fs.freq, fs.frf, fs.coherence)
        poor = [k for k in range(coh.size) if np.isfinite(coh[k]) and coh[k] < c_min]
        if poor:
            lo, hi = float(np.min(coh[poor])), float(np.max(coh[poor]))
            level = f"{lo:.2f}" if f"{lo:.2f}" == f"{hi:.2f}" else f"{lo:.2f}-{hi:.2f}"
            notes.append(
                f"{'point' if len(poor) == 1 else 'points'} "
                f"{', '.join(labels[k] for k in poor)} of {fs.n_points}: coherence at the "
                f"resonances {level}, below {said}: noisy FRFs, in which the fit misses modes "
                "or takes noise for them; measure them again")
    overloads = (fs.meta.get("points") or {}).get("overloads")
    if overloads is not None:
        over = [k for k, n in enumerate(list(overloads)[:len(labels)])
                if isinstance(n, (int, np.integer)) and n > 0]
        if over:
            notes.append(f"{'point' if len(over) == 1 else 'points'} "
                         f"{', '.join(labels[k] for k in over)}: an input went over range "
                         "while averaging (the hammer hit too hard, or the response's range too "
                         "small): the FRF is distorted; measure again")
    return notes


def uff_point(label: str, k: int, rsp_dir: int = 3, ref: tuple[int, int] = (1, 3)
              ) -> tuple[int, int, int, int]:
    """(response node, direction code, reference node, direction code) of the FRF labelled
    ``label``, the ``k``-th (0-based): a point number ("12") on ``rsp_dir``, a UFF label as
    :func:`read_frf_uff` makes it ("12+Z", "12-Z", with a roving reference "5+Z:2+Z") on its
    own DOFs, anything else node k + 1 on ``rsp_dir``; the reference ``ref`` where the label
    names none."""
    import re

    m = re.fullmatch(r"\s*(\d+)\s*([+-][XYZ])?\s*(?::\s*(\d+)\s*([+-][XYZ])\s*)?", label)
    if m is None:
        return k + 1, rsp_dir, *ref
    codes = {name: code for code, name in _DIRECTIONS.items()}
    node = int(m.group(1)), codes[m.group(2)] if m.group(2) else rsp_dir
    return (*node, int(m.group(3)), codes[m.group(4)]) if m.group(3) else (*node, *ref)


def uff_coherence_points(fs: FrfSet) -> tuple[list[int], list[str]]:
    """Which points' coherence :func:`write_frf_uff` writes: ``(indices, notes)``.

    A point gets a coherence record when its coherence is known (finite) at every line; one
    unknown (NaN) at every line has none, silently (nothing was recorded); one unknown at some
    lines has none either, and a note names it: UFF has no "unknown", and 0 would be read as a
    measured coherence of 0.
    """
    if fs.coherence is None:
        return [], []
    rows, notes = [], []
    for k in range(fs.n_points):
        known = np.isfinite(fs.coherence[k])
        if known.all():
            rows.append(k)
        elif known.any():
            label = fs.labels[k] if k < len(fs.labels) else str(k + 1)
            notes.append(f"point {label}: coherence unknown at {int((~known).sum())} of "
                         f"{known.size} lines; not written")
    return rows, notes


def write_frf_uff(path, fs: FrfSet, *, overwrite: bool = False, ref_node: int = 1,
                  rsp_dir: int = 3, ref_dir: int = 3, binary: bool = False) -> Path:
    """Write one type-58 FRF record per point (response node = point number), each followed by
    the point's coherence when known (function type 6, real double, same DOFs, unit "NONE";
    :func:`uff_coherence_points`); ASCII, or binary 58b (lossless doubles) with
    ``binary=True``. :func:`read_frf_uff` pairs the coherence with its FRF by the DOFs."""
    import pyuff

    path = _new_target(path, overwrite)
    # each point's own unit where the points differ (a UFF's accelerance beside a mobility):
    # every record was written in the first point's unit, a mobility labelled an accelerance
    point_units = list(fs.meta.get("point_units") or ())
    each = [point_units[k] if k < len(point_units) else fs.units for k in range(fs.n_points)]
    axes_of = {}
    for units in dict.fromkeys(each):
        axes = _uff_axes(uff_units(units, fs.source or path))
        for key in ("ordinate_axis_units_lab", "orddenom_axis_units_lab"):
            if len(axes[key]) > UFF_UNITS_CHARS:
                # pyuff would cut the label to its field: the unit would read back as another
                raise FrfError(f"{fs.source or path}: FRF unit {units!r} does not fit a UFF 58 "
                               f"record: {axes[key]!r} has {len(axes[key])} characters, a "
                               f"units label holds {UFF_UNITS_CHARS}")
        axes_of[units] = axes
    with_coherence, _ = uff_coherence_points(fs)
    sets = [pyuff.prepare_164(**UFF_SI_UNITS)]        # the units the records' types are in
    for k in range(fs.n_points):
        axes = axes_of[each[k]]
        label = fs.labels[k] if k < len(fs.labels) else str(k + 1)
        node, direction, ref, ref_direction = uff_point(label, k, rsp_dir, (ref_node, ref_dir))
        common = dict(
            binary=int(binary), id2=UFF_WRITER,
            rsp_node=node, rsp_dir=direction, ref_node=ref, ref_dir=ref_direction,
            abscissa_spacing=_uff_even_abscissa(fs.freq, binary),
            abscissa_spec_data_type=UFF_ABSCISSA_FREQUENCY, abscissa_axis_units_lab="Hz",
            **uff_exponents("abscissa", UFF_ABSCISSA_FREQUENCY),
            x=np.asarray(fs.freq, dtype=float))
        sets.append(pyuff.prepare_58(
            id1=f"FRF {label}", id3=_window_id(fs), func_type=UFF_FRF,
            ord_data_type=6,  # complex double
            **axes, data=np.asarray(fs.frf[k], dtype=complex), **common))
        if k in with_coherence:
            sets.append(pyuff.prepare_58(
                id1=f"Coherence {label}", func_type=UFF_COHERENCE,
                ord_data_type=4,  # real double
                # a dimensionless ratio: specific data types 0 (unknown), no units
                ordinate_spec_data_type=0, orddenom_spec_data_type=0,
                **uff_exponents("ordinate", 0), **uff_exponents("orddenom", 0),
                ordinate_axis_units_lab="NONE", orddenom_axis_units_lab="NONE",
                data=np.asarray(fs.coherence[k], dtype=float), **common))
    return write_uff_sets(path, sets)


def _uff_even_abscissa(freq, binary: bool) -> int:
    """Record 7's abscissa spacing for ``freq`` (Hz): 1 (even: the start and step in the
    header, E13.5, 6 significant digits) where that gives every line back, else 0 (uneven:
    each line's frequency in the data, doubles in binary 58b). Binary is even only where the
    header's start and step give the lines back to 1e-12: a 2000 Hz / 4096-line grid's step
    0.48828125 Hz written as 4.88281e-01 put its top line 0.7 mHz off, though 58b "keeps the
    doubles exactly" (and a grid even only to 1e-5, as np.allclose took it, was moved onto an
    even one). ASCII writes the abscissa in 6 digits either way, so a grid even to 1e-9 is
    even."""
    freq = np.asarray(freq, dtype=float)
    if freq.size < 2:
        return 0
    if not binary:
        step = np.diff(freq)
        return int(bool(np.allclose(step, step[0], rtol=1e-9, atol=0)))
    start, step = (float(f"{v:13.5e}") for v in (freq[0], freq[1] - freq[0]))
    header = start + np.arange(freq.size) * step     # as pyuff reads an even abscissa back
    return int(bool(np.allclose(header, freq, rtol=1e-12, atol=0)))


def uff_ascii(text: str) -> str:
    """``text`` as a Universal File holds it: :data:`UFF_ASCII`'s spellings, accents dropped
    ("ä" "a"), "?" for any other character outside ASCII."""
    import unicodedata

    s = unicodedata.normalize("NFKD", str(text).translate(UFF_ASCII))
    s = "".join(ch for ch in s if not unicodedata.combining(ch))
    return s.encode("ascii", "replace").decode("ascii")


def uff_units(units: str | None, source) -> str | None:
    """The FRF unit ``units`` as laminid writes it to a Universal File: in ASCII ("m/s²/N"
    "m/s^2/N", the same unit); None for a unit not known (written "NONE"); FrfError naming
    ``source`` where a character has no ASCII spelling (the unit would read back as
    another)."""
    if units is None:
        return None
    ascii_ = uff_ascii(units)
    lost = [ch for ch in units if uff_ascii(ch) == "?" and ch != "?"]
    if lost:
        raise FrfError(f"{source}: FRF unit {units!r} cannot be written to a Universal File "
                       f"(ASCII): {', '.join(repr(ch) for ch in dict.fromkeys(lost))} has no "
                       "ASCII spelling; give the unit in ASCII (e.g. 'm/s^2/N')")
    return ascii_


def _uff_axes(units: str | None) -> dict:
    """The ordinate and denominator fields of a type-58 record of an FRF in ``units``: the
    response's unit and type over the force's ("Pa/N": Pa, 15 pressure over N, 13 excitation
    force), split at the last '/'; a unit that is no ratio is the ordinate's, over none; no
    unit (None) "NONE" over "NONE". The reader (:func:`_uff_units`) joins them back."""
    if units is None:
        return {"ordinate_axis_units_lab": "NONE", "orddenom_axis_units_lab": "NONE",
                "ordinate_spec_data_type": 0, "orddenom_spec_data_type": 0,
                **uff_exponents("ordinate", 0), **uff_exponents("orddenom", 0)}
    response, sep, force = units.rpartition("/")
    # a label holds no surrounding spaces (the reader strips them): "m/s^2 / N" is
    # "m/s^2" over "N", and reads back "m/s^2/N"
    response, force = response.strip(), force.strip()
    if not sep or not response or not force:
        response, force = units.strip(), "NONE"
    types = (UFF_RESPONSE_TYPES.get(_unbracketed(response), 0),
             UFF_FORCE_TYPES.get(_unbracketed(force), 0))
    return {"ordinate_axis_units_lab": response, "orddenom_axis_units_lab": force,
            "ordinate_spec_data_type": types[0], "orddenom_spec_data_type": types[1],
            **uff_exponents("ordinate", types[0]), **uff_exponents("orddenom", types[1])}


def uff_exponents(axis: str, spec_type: int) -> dict:
    """pyuff's fields of the length, force and temperature units exponents of a type-58
    record's ``axis`` ("abscissa", "ordinate", "orddenom") of specific data type
    ``spec_type``: :data:`UFF_UNIT_EXPONENTS` (pyuff writes 0 0 0 unless told, which says
    dimensionless to a tool that reads them)."""
    return dict(zip((f"{axis}_len_unit_exp", f"{axis}_force_unit_exp",
                     f"{axis}_temp_unit_exp"), UFF_UNIT_EXPONENTS[spec_type]))


def _unbracketed(unit: str) -> str:
    """``unit`` without one pair of enclosing parentheses: "(m/s^2)" of "(m/s^2)/N", the
    spelling acquire's --help gives, is the acceleration "m/s^2" (the label keeps them)."""
    if unit.startswith("(") and unit.endswith(")"):
        return unit[1:-1].strip()
    return unit


def write_uff_sets(path: Path, sets, error: type[LaminidError] = FrfError) -> Path:
    """Write pyuff's dataset dicts ``sets`` to ``path`` atomically
    (:func:`~laminid_cli.atomic.atomic_path`); a failure is ``error`` naming the file, the
    target untouched. Shared by the FRF (UFF 58) and the mode-shape (UFF 15/55/164) writers."""
    import pyuff

    sets = [{k: uff_ascii(v) if isinstance(v, str) else v for k, v in d.items()} for d in sets]
    try:
        with atomic_path(path) as tmp:
            # "add" to the fresh temporary file: pyuff's "overwrite" truncates the header of a
            # binary record when it reopens the file for the data (pyuff 2.4/2.5)
            pyuff.UFF(str(tmp)).write_sets(sets, mode="add")
    except LaminidError:
        raise
    except Exception as exc:     # pyuff's failures are not documented: any of them, named
        raise error(f"{path}: cannot write the Universal File ({exc})") from exc
    return path
