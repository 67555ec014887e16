"""Open an HDF5 file for reading, or refuse with the caller's error class and words; read its
``format`` attribute.

One place for the "file not found" / "not an HDF5 file" split that every reader of HDF5 input
makes (result files: :mod:`laminid_cli.resultfile`; plain FRF files of other tools:
:mod:`laminid_cli.frf.generic_h5`), and one reader of the root attribute ``format`` as text
(:func:`format_of`; batch, export, identify's derived result name, the result reader), each
caller keeping its own answer to a file it cannot open; and the words for a laminid file given
to the wrong command (:func:`laminid_kind`). h5py is imported inside the functions.
"""

from __future__ import annotations

from pathlib import Path


def open_h5(path, error: type[Exception], not_hdf5: str):
    """``h5py.File(path, "r")``, or ``error`` raised from the h5py exception: "PATH: file not
    found", or "PATH: " + ``not_hdf5`` (formatted with ``exc``, the h5py message) for a file
    that exists but is not readable HDF5. The caller closes the file (``with``)."""
    import h5py

    path = Path(path)
    try:
        return h5py.File(path, "r")
    except FileNotFoundError as exc:
        raise error(f"{path}: file not found") from exc
    except OSError as exc:
        raise error(f"{path}: " + not_hdf5.format(exc=exc)) from exc


def format_of(f) -> str:
    """The root attribute ``format`` of the open HDF5 file ``f`` ("laminid-result", ...) as
    text: "" when it has none, bytes decoded as UTF-8 (an undecodable byte replaced), any other
    value (a number, an array) as ``str``, so that the callers' ``fmt in FORMATS`` is a plain
    comparison whatever another tool wrote there; opaque data (HDF5's H5T_OPAQUE, numpy's
    void) as "<opaque data, N bytes>", where ``str`` gave its bytes in hex escapes."""
    fmt = f.attrs.get("format", "")
    if getattr(fmt, "shape", None) == () and not isinstance(fmt, (str, bytes)):
        fmt = fmt[()]                 # a 0-d array (of bytes or text): its one element
    dtype = getattr(fmt, "dtype", None)
    if dtype is not None and dtype.kind == "V" and dtype.names is None:
        return f"<opaque data, {fmt.nbytes} bytes>"
    return fmt.decode("utf-8", "replace") if isinstance(fmt, bytes) else str(fmt)


def file_format(path) -> str:
    """:func:`format_of` the HDF5 file ``path``, opened for reading; h5py's exceptions (a
    missing file, no HDF5, a damaged one) are the caller's to turn into its own answer."""
    import h5py

    with h5py.File(path, "r") as f:
        return format_of(f)


#: what a laminid HDF5 file of each ``format`` is, and what takes it ({q}: its quoted name):
#: the words for one given to the wrong command (:func:`laminid_kind`)
LAMINID_KINDS = {
    "laminid-result": ("a laminid identification result (of laminid identify or batch)",
                       "'laminid show {q}' prints it, 'laminid report {q}' draws it"),
    "laminid-joint-result": ("a laminid joint identification result (of laminid identify "
                             "--joint)",
                             "'laminid show {q}' prints it, 'laminid report {q}' draws it"),
    "laminid-frf": ("an FRF file (of laminid acquire)",
                    "'laminid fit-frf {q} --into SPEC.yaml' writes its modes into a specimen "
                    "(or name it in the specimen's measured.frf_file), which identify and "
                    "batch fit"),
    "laminid-modes": ("a file of 'laminid modes' (a model's modes at a specimen's initial "
                      "constants)", "'laminid export {q} -o modes.unv' writes its mode shapes"),
}


def laminid_kind(fmt: str, path) -> tuple[str, str] | None:
    """(what the file ``path`` of ``format`` ``fmt`` is, what takes it) in words, for a file
    given to the wrong command (batch, identify or modes as a specimen:
    specimen.non_specimen_text; fit-frf as FRFs: frf.generic_h5); None for a format laminid
    does not write."""
    import shlex

    kind = LAMINID_KINDS.get(fmt)
    if kind is None:
        return None
    return kind[0], kind[1].format(q=shlex.quote(str(path)))
