"""Exception hierarchy.

Every error a user can cause is a :class:`LaminidError` subclass whose message names the file,
the field, the value and what was expected. The CLI prints the message on one line of stderr and
exits with ``exit_code``: 2 for bad input or usage, 1 for a run that failed (no convergence,
instrument fault).
"""

from __future__ import annotations

import contextlib
import re

#: characters refused in text a user's file gives laminid to print or draw, by every reader
#: (a specimen's text, an FRF file's point labels, units and channel names, a CSV's column
#: names, a summary's names and words, a result file's texts): C0/C1 control characters
#: but tab and line feed (an ESC begins a terminal's escape sequence: "\x1b[31m" turned the
#: terminal red; a BEL is a glyph no font has, which matplotlib warned of; a CR returns to
#: the line's start and overwrites it), the bidirectional marks, embeddings, overrides and
#: isolates (U+061C, U+200E/F, U+202A-U+202E, U+2066-U+2069: "S1\u202e2.1" prints as
#: "S11.2", a line that lies about its content; Unicode TR #9, "Explicit Directional
#: Formatting Characters"), the line and paragraph separators (U+2028, U+2029) and the
#: invisible characters that make two names look alike or hide text between them (zero
#: width space U+200B, word joiner and invisible operators U+2060-U+2064, Mongolian vowel
#: separator U+180E, zero width no-break space/BOM U+FEFF). The zero width (non-)joiners
#: U+200C/U+200D are left: Persian, Indic scripts and emoji spell words with them. Refused,
#: not escaped: the text is a name laminid writes into result files and tables, where an
#: escaped one would differ from the file's, and the message says which character to remove
NON_PRINTABLE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u180e\u200b\u200e\u200f"
                           "\u2028-\u202e\u2060-\u2064\u2066-\u2069\ufeff]")


def non_printable(text) -> str | None:
    """What :data:`NON_PRINTABLE` finds in ``text`` for a message: "non-printable character
    U+202E (RIGHT-TO-LEFT OVERRIDE)", its Unicode name where it has one ("U+001B" for ESC);
    None where there is none (or ``text`` is no str)."""
    import unicodedata

    bad = NON_PRINTABLE.search(text) if isinstance(text, str) else None
    if bad is None:
        return None
    char = bad.group()
    name = unicodedata.name(char, "")
    return f"non-printable character U+{ord(char):04X}" + (f" ({name})" if name else "")

#: exit code of a command interrupted by Ctrl-C (128 + SIGINT)
EXIT_INTERRUPTED = 130
#: exit code of a command ended by SIGTERM as Ctrl-C would end it (128 + SIGTERM)
EXIT_TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill PID``, ``timeout``, a job scheduler at its time limit) turned into a
    stop as by Ctrl-C, where a command installs a handler raising it (acquire's session,
    batch): whatever handles Ctrl-C handles it, and the command line says "terminated
    (SIGTERM)" and exits 143 instead of "interrupted" and 130."""


@contextlib.contextmanager
def sigterm_raises_terminated():
    """Within the block SIGTERM (``kill PID``, ``timeout``, systemd, a job scheduler at its
    time limit) raises :class:`Terminated`, so that a command stops as by Ctrl-C, where the
    process would die by the signal saying nothing: acquire's session (the analyser stopped,
    the finished points kept, the resume command), a batch (its workers stopped, both
    summaries written, the table printed; batch._note_sigint notes it as Ctrl-C). The
    handler found is restored after the block; an ignored SIGTERM stays ignored. Only in the
    main thread, where Python runs signal handlers."""
    import signal
    import threading

    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is signal.SIG_IGN):
        yield
        return

    def on_sigterm(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, on_sigterm)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def note_stop_signals(*, take_all: bool = True, raising=None):
    """(seen, restore): in the main thread (where Python runs signal handlers) SIGINT and
    SIGTERM are noted in the list ``seen`` (their numbers, as they come) until ``restore()``
    gives each the handler it had; the handler raises ``raising(seen)`` too where given (None:
    noted only). ``take_all`` False leaves an ignored signal as it is, and SIGTERM where its
    handler is no Python one (its default: the process killed). Elsewhere a no-op (``seen``
    stays empty). For :func:`stop_signals_held` and a batch's run (batch._note_sigint)."""
    import signal
    import threading

    seen: list = []

    def on_signal(signum, frame):
        seen.append(signum)
        if raising is not None:
            raise raising(seen)

    if threading.current_thread() is not threading.main_thread():
        return seen, lambda: None
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    taken = [sig for sig, handler in previous.items()
             if take_all or (handler is not signal.SIG_IGN
                             and (sig == signal.SIGINT or callable(handler)))]
    for sig in taken:
        signal.signal(sig, on_signal)

    def restore():
        for sig in taken:
            signal.signal(sig, previous[sig])

    return seen, restore


@contextlib.contextmanager
def stop_signals_held():
    """Ctrl-C (SIGINT) and SIGTERM wait until the block ends, then take effect as they would
    have (the handler in place before: KeyboardInterrupt, :class:`Terminated`, ignored, the
    process killed): each signal noted (:func:`note_stop_signals`) is sent again, once, to the
    handler restored. Only in the main thread, where Python runs signal handlers."""
    import os

    seen, restore = note_stop_signals()
    try:
        yield
    finally:
        restore()
        for sig in dict.fromkeys(seen):      # delivered again, to the handler restored
            os.kill(os.getpid(), sig)


def non_printable_in(value, where: str = "") -> tuple[str, str, str] | None:
    """The first text in ``value`` (a str, or lists and dicts of them, keys too: a JSON
    document) holding a character of :data:`NON_PRINTABLE`: (where, as "specimens.S1.name"
    or "warnings[2]", the text, :func:`non_printable`'s words); None where there is none."""
    if isinstance(value, str):
        bad = non_printable(value)
        return None if bad is None else (where, value, bad)
    if isinstance(value, dict):
        items = value.items()
        for key, item in items:
            at = f"{where}.{key}" if where else str(key)
            found = non_printable_in(str(key), at) or non_printable_in(item, at)
            if found is not None:
                return found
    elif isinstance(value, (list, tuple)):
        for k, item in enumerate(value):
            found = non_printable_in(item, f"{where}[{k}]")
            if found is not None:
                return found
    return None


def escaped(text: str) -> str:
    """``text`` with each character of :data:`NON_PRINTABLE` written as its escape
    ("IM7\\u2066/977-2"), for a message that names a field or file by the text that is
    refused: the character itself would act on the line that reports it."""
    return NON_PRINTABLE.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"),
                             text)


class LaminidError(Exception):
    """Base class of all errors laminid reports to a user.

    ``path``: the file the error is about, where the code that raises it knows it (the
    message names it anyway); ``field`` and ``line`` where a specimen's error has them. The
    CLI's --json error document gives them (null when not known)."""

    exit_code = 2
    #: how the one-line message begins ("laminid: error: ..."); an outcome that is not an
    #: error (a session the operator ended early) says what it is instead
    label = "error"
    path: str | None = None
    field: str | None = None
    line: int | None = None

    def __init__(self, *args, path=None):
        super().__init__(*args)
        if path is not None:
            self.path = str(path)


class SpecimenError(LaminidError):
    """A specimen file is missing, unreadable or invalid."""

    def __init__(self, message: str, *, path: str | None = None, field: str | None = None,
                 line: int | None = None):
        where = []
        if path:
            where.append(f"{path}" + (f":{line}" if line else ""))
        if field:
            where.append(f"field '{escaped(field)}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)
        self.path, self.field, self.line = path, field, line


@contextlib.contextmanager
def about_file(path, *kinds: type[LaminidError]):
    """An error of ``kinds`` raised inside the block that does not say which file it is about
    (``path`` None: a reader's many checks name the file in their messages only) gets
    ``path``; for the --json error document."""
    try:
        yield
    except kinds as exc:
        if exc.path is None:
            exc.path = str(path)
        raise


class ModelError(LaminidError):
    """The model cannot be built (bad mesh, infeasible constants, wrong boundary condition)."""


class SolverError(LaminidError):
    """The eigen solver failed or found a wrong number of rigid-body modes."""

    exit_code = 1


class FitError(LaminidError):
    """An identification or curve fit could not run or did not converge."""

    exit_code = 1


class FitInputError(FitError):
    """An identification cannot start: its input is wrong (exit code 2)."""

    exit_code = 2


class FrfError(LaminidError):
    """An FRF file or FRF data is invalid (bad axis, NaN, no type-58 record...)."""


class InstrumentError(LaminidError):
    """The analyser failed: timeout, error queue entry, truncated block, lost connection."""

    exit_code = 1


class OutputExistsError(LaminidError):
    """An output file cannot be written at the name given: it exists and overwriting was not
    asked for, it is a folder or another non-regular file, its folder is missing or cannot be
    written to, or its type is not one laminid writes."""


class InputFileError(LaminidError):
    """A file named on the command line to be read is missing or is a folder."""
