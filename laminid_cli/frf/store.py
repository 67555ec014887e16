"""laminid's FRF HDF5 file: the one layout written by ``laminid acquire`` and read by ``fit-frf``.

Layout (schema_version 1)::

    /                       attrs: format="laminid-frf", schema_version=1, laminid_version,
                                   created, modified (ISO 8601, UTC), complete (bool)
    /frequency              float64 (n_freq,)            attrs: units="Hz"
    /frf                    complex128 (n_points, n_freq) attrs: units (e.g. "Pa/N"; absent
                                                                 when the unit is not known),
                                                                 quantity (e.g. "response/force")
    /coherence              float64 (n_points, n_freq)   attrs: units="1" (NaN where unknown)
    /points/label           str (n_points,)   measurement point names ("1", "2", ... or user's)
    /points/timestamp       str (n_points,)   ISO 8601 UTC time the point was read
    /points/n_averages      int64 (n_points,) hits averaged       attrs: units="1"
    /points/overloads       int64 (n_points,) input channels over range during the point's
                            averages (0-2: ch1 hammer, ch2 response; -1 unknown),
                            attrs: units="1"
    /instrument             attrs: idn, model, resource (empty group when not from an analyser)
    /settings               attrs: one per acquisition setting, unit in the name (span_hz...)

Crash safety: :class:`FrfWriter` keeps the points in memory and, each time a point is added,
writes the *whole* file through :func:`laminid_cli.atomic.atomic_path` (temporary name in the
same folder, fsync, ``os.replace``). Killing the process at any instant leaves either the
previous valid file or the new valid one, never a half-written file. Files are small (a few
MB at most), so the rewrite costs milliseconds.

h5py is imported inside the functions so that importing this module stays cheap.
"""

from __future__ import annotations

import datetime as _dt
import logging
import shlex
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from laminid_cli import __version__
from laminid_cli.atomic import atomic_path, remove_stale_temporaries_of
from laminid_cli.errors import FrfError, OutputExistsError

log = logging.getLogger(__name__)

FORMAT = "laminid-frf"
SCHEMA_VERSION = 1


def resonance_lines(freq, frf) -> np.ndarray:
    """Mask (n_freq,) of the lines where |H| of one FRF is in its top quarter: the resonances,
    where its coherence tells the measurement's quality (the dips at anti-resonances are
    normal). Among the positive frequencies (an impact FRF's DC line is meaningless; all
    lines where none is). Acquire's quality line (instrument.session.assess_point) and
    fit-frf's notes on the points of a file (frf.io.coherence_at_resonances) judge by it.

    freq : (n_freq,) Hz; frf : complex (n_freq,)"""
    mag = np.abs(frf)
    use = np.asarray(freq, float) > 0
    if not use.any():
        use = np.ones_like(mag, dtype=bool)
    return use & (mag >= np.quantile(mag[use], 0.75))


@dataclass(frozen=True)
class FrfSet:
    """A set of FRFs on one frequency axis.

    Attributes
    ----------
    freq : float (n_freq,), Hz, strictly increasing
    frf : complex (n_points, n_freq), in ``units``
    coherence : float (n_points, n_freq) or None, dimensionless
    labels : measurement point names, length n_points
    units : FRF units, e.g. ``"Pa/N"`` (microphone) or ``"m/s^2/N"`` (accelerometer); None
        where the file states none (:func:`units_text` writes it for a reader): "1" only for
        FRFs declared dimensionless
    source : file the set was read from ("" when built in memory)
    meta : instrument identity, settings and per-point records (free-form, JSON-able);
        ``notes``: a reader's sentences on what it assumed (the unit of a CSV phase column
        whose header gives none), printed by the commands that read the set; ``warnings``:
        its sentences on an assumption that may well be wrong (a CSV frequency column whose
        header states no unit, read as Hz), each naming the file, printed as warnings
    """

    freq: np.ndarray
    frf: np.ndarray
    coherence: np.ndarray | None = None
    labels: tuple[str, ...] = ()
    units: str | None = None
    source: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def n_points(self) -> int:
        return int(self.frf.shape[0])


#: the words of an FRF set's ``meta`` that laminid prints or writes again (a point's unit, the
#: instrument's identity and settings, a point's records, the datasets read); not a UFF
#: record's ids, which nothing prints (a tool may pad them with NULs)
PRINTED_META = ("point_units", "instrument", "settings", "points", "frequency_dataset",
                "frf_dataset")


def check_frf_texts(fs: FrfSet, path) -> FrfSet:
    """``fs`` as read from ``path``, FrfError naming the file and where for a text in it that
    laminid prints (a point label, the FRF unit, a point's unit, channel name or other
    record, the instrument's and settings' words: :data:`PRINTED_META`) holding a character
    of :data:`~laminid_cli.errors.NON_PRINTABLE`: an HDF5 label "1\\u202e2" printed as "21" in
    fit-frf's table, an ESC in a units attribute coloured the terminal. Every reader's set
    passes here (io.read_frf, read_frf_h5)."""
    from laminid_cli.errors import non_printable

    def texts():
        for k, label in enumerate(fs.labels, start=1):
            yield f"point label {k}", label
        yield "the FRF unit", fs.units
        for key in PRINTED_META:
            if key in fs.meta:
                yield from _walk(key.replace("_", " "), fs.meta[key])

    for where, text in texts():
        bad = non_printable(text)
        if bad is not None:
            raise FrfError(f"{path}: {where} ({text!r}): {bad} in it; remove it (it can make "
                           "a printed line show other text than the file's)")
    return fs


def _walk(where: str, value):
    """(where, text) of every str in ``value`` (lists and dicts of a set's meta)."""
    if isinstance(value, str):
        yield where, value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _walk(f"{where} {k!s}", str(k))
            yield from _walk(f"{where} {k!s}", v)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value, start=1):
            yield from _walk(f"{where} {i}", v)


#: how laminid writes the FRF unit of a file that states none (its :attr:`FrfSet.units` None;
#: in --json ``units`` null): "1" read as if the FRFs were dimensionless
UNIT_NOT_STATED = "unit not stated in file"


def units_text(units: str | None) -> str:
    """An FRF unit for a sentence or a table: ``units``, or :data:`UNIT_NOT_STATED`."""
    return UNIT_NOT_STATED if units is None else units


def unit_not_stated_note(source, how: str) -> str:
    """The note of a reader whose file states no FRF unit: ``source`` named, ``how`` the file
    would state it; the FRFs and their modal constants are then given without a unit."""
    return (f"{source}: the FRF unit is not stated in the file ({how}): the FRFs and their "
            "modal constants are given without a unit (null in --json)")


#: a frequency axis whose file states no unit is read as Hz; when its largest value is below
#: this (Hz) it is refused instead. A free plate's modes lie at about 20 Hz - 20 kHz and an
#: analyser's span starts at 0, so a span that ends below 100 "Hz" is far more likely kHz
#: (125.05 Hz written 0.12505: every mode 1000 times too low, exit 0) than a plate test
UNSTATED_FREQ_MIN_SPAN_HZ = 100.0


def unstated_freq_warning(what: str, freq: np.ndarray, how: str, confirm: str) -> str:
    """The warning of a reader whose frequency axis ``freq`` (Hz, increasing) states no unit
    and is read as Hz: ``what`` names the file and the column, dataset or record, ``how`` says
    how to state the unit, ``confirm`` what states Hz. FrfError, the same said, where the
    axis ends below :data:`UNSTATED_FREQ_MIN_SPAN_HZ`: nothing is rescaled on a guess."""
    lo, hi = float(freq[0]), float(freq[-1])
    if hi < UNSTATED_FREQ_MIN_SPAN_HZ:
        raise FrfError(
            f"{what}: the frequency states no unit, and its values {lo:g} to {hi:g} read as Hz "
            f"would end below {UNSTATED_FREQ_MIN_SPAN_HZ:g} Hz, where a free plate has hardly "
            "a mode (they lie at about 20 Hz to 20 kHz): very likely kHz, not Hz; "
            f"{how}")
    return (f"{what}: the frequency states no unit; its values {lo:g} to {hi:g} are read as "
            "Hz (were they kHz, every mode would be 1000 times too low; rad/s, 6.28 times too "
            f"high); if they are not Hz, {how}; {confirm} confirms Hz and silences this "
            "warning")


def nonfinite_dc_lines(freq, values) -> int:
    """How many leading lines of an FRF file to drop as its undefined DC line: lines at 0 Hz
    (exactly) whose FRF values are not all finite. An analyser's H = X/F is 0/0 or x/0 there,
    the force spectrum of a hammer or shaker being 0 at DC, and its export writes NaN or inf;
    no mode lies at 0 Hz. NaN or inf at any other line stays refused (:func:`check_frf_arrays`).

    freq : (n_freq,) as read, Hz; values : (n_freq, ...) the FRF values of each line
    """
    freq, values = np.asarray(freq), np.asarray(values)
    if (freq.ndim != 1 or values.ndim < 1 or values.shape[0] != freq.size
            or freq.dtype.kind not in "fiu" or values.dtype.kind not in "fciu"):
        return 0                              # refused as such by check_frf_arrays
    values = values.reshape(freq.size, -1)
    dc = (freq == 0) & ~np.isfinite(values).all(axis=1)
    return int(np.argmin(dc)) if not dc.all() else 0


def nonfinite_dc_warning(source, n: int, shown: str = "NaN/inf") -> str:
    """The one-line warning of a reader that dropped ``n`` DC lines
    (:func:`nonfinite_dc_lines`) whose values are ``shown``."""
    lines = "the first line" if n == 1 else f"the first {n} lines"
    return (f"{source}: {lines} (0 Hz) dropped: its FRF values are {shown} (a response over "
            "a force spectrum that is 0 at DC, as analysers export it)")


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


#: most frequency lines accepted on an FRF axis (analysers give at most a few 10^4)
MAX_FREQ_LINES = 1_000_000
#: most FRF values (points x lines) accepted in one set: 800 MB of complex numbers
MAX_FRF_VALUES = 50_000_000


def check_frf_size(n_points: int, n_freq: int, source: str = "") -> None:
    """Raise :class:`FrfError` when an FRF set of this size is more than laminid will read
    (:data:`MAX_FREQ_LINES`, :data:`MAX_FRF_VALUES`); call it before reading the data."""
    where = f"{source}: " if source else ""
    if n_freq > MAX_FREQ_LINES:
        raise FrfError(f"{where}{n_freq} frequency lines, more than laminid reads "
                       f"({MAX_FREQ_LINES}); cut the file to the band of interest")
    if n_points * n_freq > MAX_FRF_VALUES:
        raise FrfError(f"{where}{n_points} FRFs of {n_freq} lines ({n_points * n_freq} values), "
                       f"more than laminid reads ({MAX_FRF_VALUES}); split the file")


def _numeric(name: str, array, where: str, complex_ok: bool) -> np.ndarray:
    """``array`` as float64 (complex128 if ``complex_ok``), refusing text, objects, records."""
    array = np.asarray(array)
    kinds = "biufc" if complex_ok else "biuf"
    if array.dtype.kind not in kinds:
        what = {"S": "text", "U": "text", "O": "objects", "V": "records"}.get(
            array.dtype.kind, f"dtype {array.dtype}")
        expected = "numbers (real or complex)" if complex_ok else "real numbers"
        raise FrfError(f"{where}{name} holds {what}; expected {expected}")
    return array.astype(complex if complex_ok else float, copy=False)


def check_frf_arrays(freq, frf, coherence=None, source: str = ""):
    """Check FRF data before anything is computed from it; return it in canonical dtypes.

    The checks every FRF reader shares: numeric dtypes (text, objects and records refused),
    sizes (:func:`check_frf_size`), a 1-D strictly increasing finite non-negative axis in Hz,
    FRFs (n_points, n_freq) and finite, coherence (if any) of the same shape with values in
    [0, 1] (NaN = unknown).

    Returns
    -------
    freq : float64 (n_freq,), Hz
    frf : complex128 (n_points, n_freq)
    coherence : float64 (n_points, n_freq) or None

    Raises :class:`FrfError` naming ``source`` and what is wrong.
    """
    where = f"{source}: " if source else ""
    freq = _numeric("the frequency axis", freq, where, complex_ok=False)
    frf = _numeric("the FRF data", frf, where, complex_ok=True)
    if freq.ndim != 1 or freq.size < 2:
        raise FrfError(f"{where}frequency axis must be 1-D with at least 2 lines (got shape {freq.shape})")
    if frf.ndim == 2:
        check_frf_size(frf.shape[0], frf.shape[1], source)
    else:
        check_frf_size(1, freq.size, source)
    if not np.all(np.isfinite(freq)):
        raise FrfError(f"{where}frequency axis contains NaN or inf")
    if np.any(np.diff(freq) <= 0):
        i = int(np.argmax(np.diff(freq) <= 0))
        raise FrfError(f"{where}frequency axis is not strictly increasing "
                       f"(line {i + 1}: {freq[i]:g} Hz, line {i + 2}: {freq[i + 1]:g} Hz)")
    if freq[0] < 0:
        raise FrfError(f"{where}frequency axis starts below 0 Hz ({freq[0]:g} Hz)")
    if frf.ndim != 2 or frf.shape[1] != freq.size:
        raise FrfError(f"{where}FRF array has shape {frf.shape}; expected (n_points, {freq.size}) "
                       "to match the frequency axis")
    bad = ~np.isfinite(frf)
    if bad.any():
        p, k = np.argwhere(bad)[0]
        raise FrfError(f"{where}FRF of point {p + 1} has NaN/inf at {freq[k]:g} Hz")
    if coherence is not None:
        coherence = _numeric("the coherence", coherence, where, complex_ok=False)
        if coherence.shape != frf.shape:
            raise FrfError(f"{where}coherence has shape {coherence.shape}, FRF has {frf.shape}")
        c = coherence[np.isfinite(coherence)]
        if c.size and (c.min() < -1e-9 or c.max() > 1 + 1e-9):
            raise FrfError(f"{where}coherence outside [0, 1] (min {c.min():g}, max {c.max():g})")
    return freq, frf, coherence


def validate_frf_arrays(freq, frf, coherence=None, source: str = "") -> None:
    """Raise :class:`FrfError` unless the axis and data are usable (:func:`check_frf_arrays`)."""
    check_frf_arrays(freq, frf, coherence, source)


def _dataset(f, name: str, path, required: bool = True):
    """The dataset ``name`` of an open HDF5 file, checked before it is read: present (a
    dangling link counts as missing), a dataset (not a group) of numbers, of a size laminid
    reads. None when absent and not required."""
    import h5py

    where = f"{path}: "
    try:
        obj = f.get(name)
    except (KeyError, OSError, RuntimeError, ValueError, TypeError) as exc:
        raise FrfError(f"{where}'/{name}' cannot be opened (dangling link or damaged file: "
                       f"{_reason(exc)})") from exc
    if obj is None:
        if name in f.keys() or isinstance(f.get(name, getlink=True), h5py.SoftLink):
            raise FrfError(f"{where}'/{name}' is a link to nothing (dangling soft link)")
        if required:
            raise FrfError(f"{where}dataset '/{name}' is missing")
        return None
    if not isinstance(obj, h5py.Dataset):
        raise FrfError(f"{where}'/{name}' is a {type(obj).__name__.lower()}, expected a dataset")
    if obj.dtype.kind not in "biufc":
        raise FrfError(f"{where}dataset '/{name}' holds {obj.dtype} values; expected numbers")
    return obj


def _reason(exc) -> str:
    text = " ".join(str(exc).encode("utf-8", "replace").decode("utf-8", "replace").split())
    return text[:200] or type(exc).__name__


#: seconds a damaged HDF5 file may take to be read in the probe process (a good one: < 1 s)
H5_PROBE_TIMEOUT_S = 30.0

_PROBE = """
import sys
from laminid_cli.errors import LaminidError
from {module} import {reader}
try:
    {reader}(sys.argv[1], probe=False)
except LaminidError:
    pass
"""


def probe_hdf5_file(path, reader: str = "read_frf_h5",
                    timeout: float | None = None, module: str = "laminid_cli.frf.store",
                    library: str = "the HDF5 library") -> None:
    """Read an HDF5 file once in a child process before this process touches it.

    libhdf5 can crash (segmentation fault) or loop on a damaged file (seen on files with one
    flipped bit in an object header or a heap), which no Python ``except`` can catch; the
    child takes that risk. Raises :class:`FrfError` when the child dies by a crash signal,
    fails without a LaminidError, or does not finish within ``timeout`` seconds (default
    :data:`H5_PROBE_TIMEOUT_S`). ``reader`` names a function of ``module`` taking
    ``(path, probe=False)``; ``library`` names what reads the file in the messages (scipy's
    MAT-file reader crashes alike on a damaged version 5 MAT-file).

    The child is a fork of this process where that is safe (:func:`_fork_is_safe`), 20–30 ms
    with the modules already imported; elsewhere a new interpreter (0.2–0.3 s). Whatever a
    fork leaves in doubt (out of time: a lock another thread held at the fork could do that;
    killed by a signal that is no crash, such as Ctrl-C; a failure before it read) is decided
    by a new interpreter, so that a good file is never called damaged for the fork's sake.
    """
    timeout = H5_PROBE_TIMEOUT_S if timeout is None else timeout
    outcome = _probe_forked(path, reader, module, timeout) if _fork_is_safe() else _UNSURE
    tries = 1
    if outcome in (_UNSURE, _TIMEOUT):
        tries += outcome == _TIMEOUT
        outcome = _probe_spawned(path, reader, module, timeout)
    if outcome is None:
        return
    if outcome == _TIMEOUT:
        raise FrfError(f"{path}: {library} did not finish reading the file in "
                       f"{timeout:g} s{' (two tries)' if tries > 1 else ''}; the file is "
                       "damaged")
    returncode, tail = outcome
    if returncode < 0:
        raise FrfError(f"{path}: {library} crashed reading the file "
                       f"({_signal_name(-returncode)}); the file is damaged")
    if returncode != 0:
        raise FrfError(f"{path}: the file cannot be read "
                       f"({tail[:200] or 'exit code ' + str(returncode)})")


#: outcomes of a probe other than None (read) and (returncode, reason)
_TIMEOUT = "timeout"
_UNSURE = "unsure"      # the fork cannot say: a new interpreter decides

#: exit code of a forked probe that failed before it began to read the file
_PROBE_NOT_RUN = 3


def _fork_is_safe() -> bool:
    """A fork may read the file: Linux (macOS frameworks are not fork-safe; Windows has no
    fork), no other thread of the ``threading`` module (a Python-level lock one holds, h5py's
    or the logging module's, would stay held in the child), and SIGCHLD not ignored (the
    child could not be waited for). Threads started otherwise (OpenBLAS's pool; execnet's
    receiver under pytest-xdist) are not seen: a fork that waits on a lock of theirs runs out
    of time, and a new interpreter then decides (:func:`probe_hdf5_file`)."""
    import os
    import signal
    import sys
    import threading

    return (sys.platform.startswith("linux") and hasattr(os, "fork")
            and threading.active_count() == 1
            and signal.getsignal(signal.SIGCHLD) != signal.SIG_IGN)


#: signals by which a reading child says the file is damaged; another (SIGINT, SIGTERM,
#: SIGKILL from outside) says nothing of the file
_CRASH_SIGNALS = ("SIGSEGV", "SIGBUS", "SIGABRT", "SIGILL", "SIGFPE")


def _signal_name(number: int) -> str:
    """"SIGSEGV" for 11; "signal 99" for a number the platform does not name."""
    import signal

    try:
        return signal.Signals(number).name
    except ValueError:
        return f"signal {number}"


def _probe_forked(path, reader: str, module: str, timeout: float):
    """Read ``path`` in a fork of this process. Returns None when it read (or failed with a
    LaminidError, which this process then gives itself); ``(returncode, reason)`` when it
    died by a crash signal (negative) or by another exception (1); :data:`_TIMEOUT`; or
    :data:`_UNSURE` where the fork cannot say (no fork, another signal, a failure before it
    read, a child that cannot be waited for)."""
    import os
    import select
    import signal
    import time
    import warnings

    read_end, write_end = os.pipe()
    # no KeyboardInterrupt between the fork and the child's try (it would run this process's
    # code in the child): SIGINT and SIGTERM wait until each side has its handlers
    blocked = {signal.SIGINT, signal.SIGTERM}
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, blocked)
    try:
        with warnings.catch_warnings():
            # Python >= 3.12 warns on a fork with native threads (OpenBLAS's pool); the child
            # uses none of them (see _fork_is_safe)
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
    except OSError as exc:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        os.close(read_end)
        os.close(write_end)
        log.debug("HDF5 probe not forked: %s", exc)
        return _UNSURE
    if pid == 0:
        _probe_child(path, reader, module, read_end, write_end, mask)    # never returns
    os.close(write_end)
    reason = b""
    reaped = False                  # the child waited for (or by someone else): not killed
    try:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)   # a Ctrl-C now: the child is reaped
        poller = select.poll()                             # any fd number, unlike select()
        poller.register(read_end, select.POLLIN)
        deadline = time.monotonic() + timeout
        while True:                                        # the child's words, up to its exit
            left = deadline - time.monotonic()
            if left <= 0 or not poller.poll(left * 1e3):
                return _TIMEOUT
            chunk = os.read(read_end, 4096)
            if not chunk:
                break
            reason += chunk
        while True:                                        # its exit, within the same time
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                reaped = True
                break
            if time.monotonic() > deadline:
                return _TIMEOUT
            time.sleep(0.001)
    except ChildProcessError:                              # reaped elsewhere: no status
        reaped = True
        return _UNSURE
    finally:
        os.close(read_end)
        if not reaped:
            try:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
            except (ProcessLookupError, ChildProcessError):
                pass
    returncode = os.waitstatus_to_exitcode(status)
    if returncode == 0:
        return None
    if returncode < 0:
        return (returncode, "") if _signal_name(-returncode) in _CRASH_SIGNALS else _UNSURE
    if returncode == _PROBE_NOT_RUN and not reason:
        return _UNSURE
    return returncode, reason.decode("utf-8", "replace")


def _probe_child(path, reader: str, module: str, read_end: int, write_end: int, mask) -> None:
    """The forked probe: reads the file, writes an unexpected exception's words to
    ``write_end``, and leaves by ``os._exit`` whatever happens (no atexit handler, no flush of
    this process's buffers or files)."""
    import os

    code = _PROBE_NOT_RUN           # until the file is being read
    try:
        import fcntl
        import gc
        import importlib
        import signal

        gc.disable()                # no collection of the parent's objects (an h5py File open
        os.close(read_end)          # for writing would be closed, and flushed, from here)
        # the pipe above the standard streams (they may have been closed in the parent, and
        # os.pipe then gave 1 and 2), before /dev/null goes over them
        high = fcntl.fcntl(write_end, fcntl.F_DUPFD, 3)
        os.close(write_end)
        write_end = high
        null = os.open(os.devnull, os.O_RDWR)
        for fd in (0, 1, 2):
            os.dup2(null, fd)
        if null > 2:
            os.close(null)
        import faulthandler

        faulthandler.disable()      # a crash is the parent's to report, without a dump
        for sig in (signal.SIGINT, signal.SIGTERM):
            # the default action (the parent's handlers are the parent's), or ignored as in
            # the parent (`laminid ... &` in a script ignores Ctrl-C)
            if signal.getsignal(sig) != signal.SIG_IGN:
                signal.signal(sig, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        from laminid_cli.errors import LaminidError

        code = 1
        try:
            getattr(importlib.import_module(module), reader)(path, probe=False)
            code = 0
        except LaminidError:
            code = 0
        except BaseException as exc:    # noqa: BLE001 - reported to the parent
            os.write(write_end, f"{type(exc).__name__}: {_reason(exc)}".encode())
    finally:
        os._exit(code)


def _probe_spawned(path, reader: str, module: str, timeout: float):
    """Read ``path`` in a new interpreter; the outcome as :func:`_probe_forked`'s (None too
    when no process can be started: the file is then read in-process as before)."""
    import subprocess
    import sys

    code = _PROBE.format(reader=reader, module=module)
    try:
        done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                              timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return _TIMEOUT
    except OSError as exc:   # cannot start a process: read in-process as before
        log.debug("HDF5 probe not run: %s", exc)
        return None
    if done.returncode == 0:
        return None
    tail = " ".join(done.stderr.decode("utf-8", "replace").strip().splitlines()[-1:])
    return done.returncode, tail


def read_frf_h5(path, probe: bool = True) -> FrfSet:
    """Read a laminid FRF HDF5 file (see module docstring). Raises :class:`FrfError`.

    Structure, dtypes and sizes are checked before the data are read; a damaged file (flipped
    bits, truncated, dangling links) is a FrfError with h5py's reason, never an h5py exception.
    With ``probe`` the file is first read in a child process (:func:`probe_hdf5_file`), so that
    a file that crashes or hangs libhdf5 is refused instead of killing this process.
    """
    path = Path(path)
    if probe and path.is_file():
        probe_hdf5_file(path)
    return read_hdf5(path, lambda f: _read_open_h5(f, path), "laminid FRF file")


#: what h5py raises, besides OSError, for a damaged file (bit flips, truncation, dangling links)
H5_DAMAGE_ERRORS = (KeyError, OSError, RuntimeError, TypeError, ValueError, IndexError,
                    UnicodeDecodeError, AttributeError)


def read_hdf5(path: Path, read, what: str):
    """``read(f)`` of the HDF5 file ``path`` opened for reading, h5py's errors made FrfErrors.

    A missing file, a file libhdf5 cannot open and a damaged one ("damaged or malformed
    ``what``", with h5py's reason) are each a :class:`FrfError` naming the file; a FrfError
    of ``read`` passes unchanged.
    """
    import h5py

    try:
        f = h5py.File(path, "r")
    except FileNotFoundError as exc:
        raise FrfError(f"{path}: file not found") from exc
    except (OSError, RuntimeError, ValueError) as exc:
        if path.is_file() and path.stat().st_size == 0:
            # (libhdf5 said "Unable to synchronously open file (file signature not found)")
            raise FrfError(f"{path}: the file is empty (0 bytes), not an HDF5 file") from exc
        raise FrfError(f"{path}: not a readable HDF5 file ({_reason(exc)})") from exc
    try:
        with f:
            return read(f)
    except FrfError:
        raise
    except H5_DAMAGE_ERRORS as exc:
        raise FrfError(f"{path}: damaged or malformed {what} ({type(exc).__name__}: "
                       f"{_reason(exc)})") from exc


def _read_open_h5(f, path: Path) -> FrfSet:
    from laminid_cli.h5open import format_of

    # (format_of: undecodable bytes were a UnicodeDecodeError, said as a "damaged" file)
    fmt = format_of(f)
    if fmt != FORMAT:
        found = f"attribute 'format' is {fmt!r}" if "format" in f.attrs else \
            "no attribute 'format'"
        raise FrfError(f"{path}: not a laminid FRF file ({found}, expected {FORMAT!r})")
    raw_version = _attr(f.attrs.get("schema_version", 0))
    try:
        version = int(raw_version)
    except (TypeError, ValueError):
        raise FrfError(f"{path}: attribute 'schema_version' is {raw_version!r}; expected an "
                       "integer") from None
    if version > SCHEMA_VERSION:
        raise FrfError(f"{path}: schema_version {version} is newer than this laminid "
                       f"understands ({SCHEMA_VERSION}); upgrade laminid")
    d_freq = _dataset(f, "frequency", path)
    d_frf = _dataset(f, "frf", path)
    d_coh = _dataset(f, "coherence", path, required=False)
    if d_freq.ndim != 1:
        raise FrfError(f"{path}: '/frequency' has shape {d_freq.shape}; expected (n_freq,)")
    if d_frf.ndim != 2 or (d_frf.shape[0] and d_frf.shape[1] != d_freq.shape[0]):
        raise FrfError(f"{path}: '/frf' has shape {d_frf.shape}; expected (n_points, "
                       f"{d_freq.shape[0]}) to match '/frequency'")
    check_frf_size(d_frf.shape[0], d_freq.shape[0], str(path))
    if d_coh is not None and d_coh.shape != d_frf.shape:
        raise FrfError(f"{path}: '/coherence' has shape {d_coh.shape}, '/frf' has "
                       f"{d_frf.shape}")
    freq = d_freq[()]
    frf = d_frf[()]
    if frf.size == 0:
        frf = np.zeros((0, freq.size), dtype=complex)
    coherence = d_coh[()] if d_coh is not None else None
    pts = f.get("points")
    import h5py

    if pts is not None and not isinstance(pts, h5py.Group):
        raise FrfError(f"{path}: '/points' is not a group")
    n_points = frf.shape[0]
    labels = tuple(str(i + 1) for i in range(n_points))
    points = {}
    if pts is not None:
        for k in pts:
            item = pts[k]
            if not isinstance(item, h5py.Dataset) or item.ndim != 1 or item.shape[0] != n_points:
                raise FrfError(f"{path}: '/points/{k}' must be a list of {n_points} values (one "
                               f"per FRF), got {getattr(item, 'shape', 'a group')}")
            points[k] = [_attr(x) for x in item[()]]
        if "label" in points:
            labels = tuple(_as_str(x) for x in points["label"])
    meta = {
        "instrument": _attrs(f, "instrument"),
        "settings": _attrs(f, "settings"),
        "points": points,
        "created": str(_attr(f.attrs.get("created", ""))),
        "complete": bool(_attr(f.attrs.get("complete", True))),
    }
    units = _attr(d_frf.attrs.get("units"))
    if units is not None and not isinstance(units, str):
        raise FrfError(f"{path}: attribute 'units' of '/frf' is {units!r}; expected text "
                       "(e.g. 'm/s^2/N')")
    if units is None or not units.strip():
        units = None
        meta["notes"] = [unit_not_stated_note(path, "no 'units' attribute on '/frf'; "
                                                    "acquire --units records it")]
    if frf.shape[0]:
        freq, frf, coherence = check_frf_arrays(freq, frf, coherence, source=str(path))
    return check_frf_texts(FrfSet(freq=freq, frf=frf, coherence=coherence, labels=labels,
                                  units=units, source=str(path), meta=meta), path)


def _attrs(f, name: str) -> dict:
    import h5py

    group = f.get(name)
    if group is None:
        return {}
    if not isinstance(group, (h5py.Group, h5py.Dataset)):
        raise FrfError(f"{f.filename}: '/{name}' is not a group")
    return {k: _attr(v) for k, v in group.attrs.items()}


def _as_str(x) -> str:
    return x.decode() if isinstance(x, bytes) else str(x)


def _attr(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return v


#: acquisition settings that change what a saved point means (name in the file: option, unit).
#: A point measured with other values is another measurement (an exponential window's 1/tau is
#: in every pole's decay rate; the force window and the pre-trigger decide how much of the hit
#: and of the response the analyser keeps; span, start and lines the axis), so ``--resume``
#: must not add such points to a file, nor record the new values as if they held for all.
#: Averages, trigger level and the coherence threshold only change the noise or the quality
#: check, and may differ.
RESUME_SETTINGS = {"span_hz": ("--span", "Hz"), "start_hz": ("--start", "Hz"),
                   "lines": ("--lines", ""), "pretrigger_s": ("--pretrigger", "s"),
                   "force_window_s": ("--force-window", "s"),
                   "exp_window_s": ("--exp-window", "s")}


def _setting_value(v) -> float | None:
    """A recorded/requested setting as a number; None when absent or unknown (NaN, "")."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if np.isfinite(x) else None


def check_resume_settings(path, recorded: dict, requested: dict, *,
                          units: tuple[str | None, str | None] | None = None,
                          instrument: dict | None = None) -> None:
    """Raise :class:`FrfError` when ``requested`` settings differ from those ``path`` records
    for any of :data:`RESUME_SETTINGS` (keys absent from ``requested`` are not checked), or
    when ``units`` = (recorded, requested) FRF units differ (Pa/N points and V/V points in one
    file would not be one measurement either).

    The message names the file, each differing setting with its recorded and requested value,
    and the options that would resume the file as it was measured. A setting the file does
    not record (a file measured with ``--keep-setup``, whose windows laminid cannot read back
    from the analyser, or a file written by another program, ``instrument`` naming it) cannot
    be matched: the message says which, why that matters and what can be done instead.
    """
    diffs, keep, unrecorded = [], [], []
    if units is not None and units[0] != units[1]:
        diffs.append(f"units: recorded {units_text(units[0])}, requested "
                     f"{units_text(units[1])} (--units)")
        if units[0] is not None:
            keep.append(f"--units {shlex.quote(units[0])}")
    for key, (flag, unit) in RESUME_SETTINGS.items():
        if key not in requested:
            continue
        rec, req = _setting_value(recorded.get(key)), _setting_value(requested.get(key))
        if rec is None and req is None:
            continue
        if rec is not None and req is not None and np.isclose(rec, req, rtol=1e-9, atol=0):
            continue
        name = key.rsplit("_", 1)[0].replace("_", " ")
        u = f" {unit}" if unit else ""
        if rec is None:
            unrecorded.append((name, f"{flag} {req:g}{u}"))
            continue
        req_txt = ("unknown (--keep-setup does not read it back)" if req is None
                   else f"{req:g}{u} ({flag})")
        diffs.append(f"{name}: recorded {rec:g}{u}, requested {req_txt}")
        keep.append(f"{flag} {rec:g}")
    if not diffs and not unrecorded:
        return
    parts = []
    if diffs:
        parts.append(f"its points were measured with other settings than this run's "
                     f"({'; '.join(diffs)}): points of both kinds in one file would not be "
                     "one measurement")
    if unrecorded:
        names = [n for n, _ in unrecorded]
        listed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
        keep_setup = str(recorded.get("configured", "")).lower() in ("false", "0")
        model = (instrument or {}).get("model")
        if keep_setup:
            source = ("it was measured with --keep-setup, the analyser's own set-up, whose "
                      "windows and pre-trigger laminid cannot read back")
        else:
            source = ("it was not measured by laminid acquire, which records its set-up"
                      + (f"; its instrument: {model}" if model else ""))
        windowed = any(n in ("exp window", "force window") for n in names)
        parts.append(
            f"the file does not record its {listed} ({source}), so this run's "
            f"{', '.join(v for _, v in unrecorded)} cannot be checked against what its points "
            "measured" + ("; an exponential window's 1/tau is in every pole's damping, so "
                          "points of unknown windows would not compare" if windowed else ""))
    if unrecorded:
        keep_setup = str(recorded.get("configured", "")).lower() in ("false", "0")
        how = ("resume it with --keep-setup and the analyser's set-up unchanged, or write the "
               "new points to another file (-o)" if keep_setup and not diffs
               else "write the new points to another file (-o)")
    elif keep and len(keep) == len(diffs):
        how = (f"resume with the recorded values ({' '.join(keep)}, without --keep-setup) "
               "or write the new points to another file (-o)")
    else:
        how = ("resume the file the way it was measured (with or without --keep-setup, the "
               "same values) or write the new points to another file (-o)")
    raise FrfError(f"{path}: cannot resume, {'; and '.join(parts)}; {how}")


class FrfWriter:
    """Crash-safe, point-by-point writer of a laminid FRF file.

    Parameters
    ----------
    path : output file
    freq : float (n_freq,), Hz
    units : FRF units, e.g. "Pa/N" (None: not known, no attribute written)
    settings : acquisition settings (name -> number/str; put the unit in the name: ``span_hz``)
    instrument : identity (``idn``, ``model``, ``resource``)
    resume : continue an existing file (its axis, units and the :data:`RESUME_SETTINGS` must
        match: :func:`check_resume_settings`)
    overwrite : replace an existing file; without it (and without ``resume``) an existing file
        raises :class:`~laminid_cli.errors.OutputExistsError`

    Use :meth:`add_point` for every point read; each call leaves a complete valid file on disk.
    :meth:`close` marks the file complete.
    """

    def __init__(self, path, freq, *, units: str | None = None, settings: dict | None = None,
                 instrument: dict | None = None, resume: bool = False, overwrite: bool = False,
                 quantity: str = "response/force"):
        self.path = Path(path)
        self.freq = np.asarray(freq, dtype=float)
        self.units, self.quantity = units, quantity
        self.settings = dict(settings or {})
        self.instrument = dict(instrument or {})
        self.frf: list[np.ndarray] = []
        self.coherence: list[np.ndarray] = []
        self.points: dict[str, list] = {"label": [], "timestamp": [], "n_averages": [], "overloads": []}
        self.created = _now()
        if self.path.exists():
            if resume:
                self._load_existing()
            elif not overwrite:
                raise OutputExistsError(f"{self.path}: file exists; use --resume to continue it "
                                        "or choose another output name")
        elif resume:
            raise FrfError(f"{self.path}: cannot resume, the file does not exist")
        validate_frf_arrays(self.freq, np.zeros((1, self.freq.size)), source=str(self.path))
        # a session killed (SIGKILL, power cut) while writing left its temporary file beside
        # the FRF file, kept for ever: the next session writing it removes it
        remove_stale_temporaries_of(self.path)

    def _load_existing(self) -> None:
        old = read_frf_h5(self.path)
        if old.freq.shape != self.freq.shape or not np.allclose(old.freq, self.freq, rtol=1e-9):
            raise FrfError(f"{self.path}: cannot resume, the file's frequency axis "
                           f"({old.freq.size} lines, {old.freq[0]:g}-{old.freq[-1]:g} Hz) differs "
                           f"from the analyser's ({self.freq.size} lines, "
                           f"{self.freq[0]:g}-{self.freq[-1]:g} Hz)")
        recorded = dict(old.meta.get("settings") or {})
        check_resume_settings(self.path, recorded, self.settings, units=(old.units, self.units),
                              instrument=old.meta.get("instrument"))
        # what this run does not state stays as recorded (never dropped by a resume)
        self.settings = {**recorded, **self.settings}
        self.frf = list(old.frf)
        coh = old.coherence if old.coherence is not None else np.full(old.frf.shape, np.nan)
        self.coherence = list(coh)
        for key in self.points:
            self.points[key] = list(old.meta["points"].get(key, [""] * old.n_points))
        self.created = old.meta.get("created") or self.created

    @property
    def n_points(self) -> int:
        return len(self.frf)

    @property
    def labels(self) -> list[str]:
        return [str(x) for x in self.points["label"]]

    def add_point(self, label: str, frf, coherence=None, *, n_averages: int = 0,
                  overloads: int = 0, replace: bool = False) -> None:
        """Append (or, with ``replace``, overwrite) one point and rewrite the file atomically.

        A write that fails (a full disk: ``OSError``; Ctrl-C) leaves the writer as the file on
        disk is, without the point: :attr:`n_points` counts only points saved."""
        frf = np.asarray(frf, dtype=complex).reshape(-1)
        coh = (np.full(frf.shape, np.nan) if coherence is None
               else np.asarray(coherence, dtype=float).reshape(-1))
        validate_frf_arrays(self.freq, frf[None, :], coh[None, :], source=str(self.path))
        record = {"label": str(label), "timestamp": _now(), "n_averages": int(n_averages),
                  "overloads": int(overloads)}
        before = (list(self.frf), list(self.coherence),
                  {key: list(values) for key, values in self.points.items()})
        if replace and str(label) in self.labels:
            i = self.labels.index(str(label))
            self.frf[i], self.coherence[i] = frf, coh
            for key, value in record.items():
                self.points[key][i] = value
        else:
            self.frf.append(frf)
            self.coherence.append(coh)
            for key, value in record.items():
                self.points[key].append(value)
        try:
            self._write(complete=False)
        except BaseException:
            self.frf, self.coherence, self.points = before
            raise

    def close(self) -> None:
        """Mark the file complete (rewrites it once more)."""
        self._write(complete=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if exc[0] is None:
            self.close()
        return False

    def _write(self, complete: bool) -> None:
        write_frf_h5(self.path, self.freq, np.array(self.frf).reshape(-1, self.freq.size),
                     np.array(self.coherence).reshape(-1, self.freq.size), units=self.units,
                     labels=self.labels, points=self.points, settings=self.settings,
                     instrument=self.instrument, created=self.created, complete=complete,
                     quantity=self.quantity, overwrite=True)


def write_frf_h5(path, freq, frf, coherence=None, *, units: str | None = None, labels=None,
                 points: dict | None = None, settings: dict | None = None,
                 instrument: dict | None = None, created: str | None = None,
                 complete: bool = True, quantity: str = "response/force",
                 overwrite: bool = False) -> Path:
    """Write a whole FRF set atomically (temporary file + fsync + rename). Returns the path.

    The HDF5 image is built in memory and written to the temporary file as bytes: a disk that
    fills (or a file-size limit) is then an ``OSError`` naming the file, the temporary file
    removed and ``path`` untouched. HDF5 writing to the disk itself failed on close, where
    h5py printed tracebacks and the process died of a segmentation fault, losing the session.
    """
    import h5py

    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputExistsError(f"{path}: file exists (not overwritten)")
    freq = np.asarray(freq, dtype=float)
    frf = np.asarray(frf, dtype=complex).reshape(-1, freq.size)
    n = frf.shape[0]
    if coherence is None:
        coherence = np.full(frf.shape, np.nan)
    labels = [str(x) for x in (labels if labels is not None else range(1, n + 1))]
    points = dict(points or {})
    points["label"] = labels
    points.setdefault("timestamp", [_now()] * n)
    points.setdefault("n_averages", [0] * n)
    points.setdefault("overloads", [0] * n)
    # the core driver without a backing store: nothing touches the disk; its image is
    # byte for byte the file HDF5 writes there
    f = h5py.File(f"{path.name} (in memory)", "w", driver="core", backing_store=False)
    with f:
        f.attrs["format"] = FORMAT
        f.attrs["schema_version"] = SCHEMA_VERSION
        f.attrs["laminid_version"] = __version__
        f.attrs["created"] = created or _now()
        f.attrs["modified"] = _now()
        f.attrs["complete"] = bool(complete)
        d = f.create_dataset("frequency", data=freq)
        d.attrs["units"] = "Hz"
        d = f.create_dataset("frf", data=frf)
        if units is not None:          # not known: no attribute, read back as None
            d.attrs["units"] = units
        d.attrs["quantity"] = quantity
        d = f.create_dataset("coherence", data=np.asarray(coherence, dtype=float).reshape(frf.shape))
        d.attrs["units"] = "1"
        g = f.create_group("points")
        str_dt = h5py.string_dtype()
        for key, values in points.items():
            values = list(values)
            if values and all(isinstance(v, (int, np.integer)) for v in values):
                # counts (hits, channels): unit 1, as every number of the file has its unit
                d = g.create_dataset(key, data=np.asarray(values, dtype=np.int64))
                d.attrs["units"] = "1"
            elif values and all(isinstance(v, (int, float, np.number)) for v in values):
                g.create_dataset(key, data=np.asarray(values, dtype=float))
            else:
                g.create_dataset(key, data=np.asarray([str(v) for v in values], dtype=object),
                                 dtype=str_dt)
        gi = f.create_group("instrument")
        for k, v in (instrument or {}).items():
            gi.attrs[k] = v if v is not None else ""
        gs = f.create_group("settings")
        for k, v in (settings or {}).items():
            gs.attrs[k] = v if v is not None else ""
        f.flush()
        image = f.id.get_file_image()
    with atomic_path(path) as tmp:
        tmp.write_bytes(image)
    return path
