"""What every analyser driver offers, and the acquisition settings they share.

A driver (one module per analyser family, e.g. :mod:`.hp35670a`, :mod:`.sr785`) subclasses
:class:`Analyser`: class attributes list the values the manual allows (``SPANS_HZ``,
``LINES``), :meth:`Analyser.validate` checks settings against them before anything is sent,
and the actions are methods (``configure``, ``start``, ``wait_until_done``, ``read_*``).
The driver sees only a :class:`~laminid_cli.instrument.transport.Transport`, so a scripted
transport can test it command by command.

Measurement set-up of the paper (Araujo et al. 2000, section 3): hammer force on channel 1,
microphone/accelerometer on channel 2, FRF = ch2/ch1 (H1, RMS-averaged spectra) and coherence,
channel-1 level trigger with pre-trigger delay, force window on channel 1, exponential window on
channel 2.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import asdict, dataclass
from typing import Callable, ClassVar, Mapping

import numpy as np

from laminid_cli.errors import NON_PRINTABLE, InstrumentError
from laminid_cli.instrument.transport import AnalyserSetupError, Transport

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class AcquisitionSettings:
    """Analyser settings of an impact test; the unit is in each name (SI).

    Attributes
    ----------
    span_hz : frequency span
    start_hz : start frequency (0 for baseband)
    lines : FFT resolution lines
    averages : hits averaged per measurement point
    trigger_level_pct : channel-1 trigger level, percent of the input range
    pretrigger_s : time recorded before the trigger (sent as a negative trigger delay)
    force_window_s : width of the force window on channel 1
    exp_window_s : time constant of the exponential window on channel 2
    """

    span_hz: float = 1600.0
    start_hz: float = 0.0
    lines: int = 800
    averages: int = 5
    trigger_level_pct: float = 10.0
    pretrigger_s: float = 0.005
    force_window_s: float = 0.01
    exp_window_s: float = 0.1

    @property
    def record_s(self) -> float:
        """Length of the time record, T = lines / span (s)."""
        return self.lines / self.span_hz

    def as_attrs(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Measurement:
    """One averaged point read from the analyser.

    freq : float (n_freq,), Hz; frf : complex (n_freq,), FRF units; coherence : float
    (n_freq,), 1; n_averages : hits averaged; overloads : number of channels that went over
    range during the averages (0-2, -1 unknown); overloaded_channels : which (1 = hammer
    force, 2 = response)
    """

    freq: np.ndarray
    frf: np.ndarray
    coherence: np.ndarray
    n_averages: int
    overloads: int
    overloaded_channels: tuple[int, ...] = ()


ProgressCallback = Callable[[int, int], None]  # (hits done, hits wanted); hits done -1 = unknown


class TransferError(InstrumentError):
    """The analyser flagged an error during a data transfer, twice: the point is not good.

    ``trace`` names the transfer ("FRF", "coherence"); ``errors`` is the analyser's error text.
    """

    def __init__(self, message: str, *, trace: str = "", errors: tuple[str, ...] = ()):
        super().__init__(message)
        self.trace, self.errors = trace, tuple(errors)


def _fmt_list(values) -> str:
    return ", ".join(f"{v:g}" for v in values)


def format_number(x: float) -> str:
    """Short, exact-enough decimal for a command string (no binary noise)."""
    return f"{x:.10g}"


#: what the messages call each setting unless told otherwise (``names`` of the checks)
SETTING_NAMES = {"span_hz": "span", "start_hz": "start", "lines": "lines",
                 "averages": "averages", "trigger_level_pct": "trigger level",
                 "pretrigger_s": "pretrigger", "force_window_s": "force window",
                 "exp_window_s": "exp window"}

#: averages every driver takes at most (SR785 FAVN: 32767; 35670A: 9999 assumed)
MAX_AVERAGES = 9999


def setting_names(names: Mapping[str, str] | None = None) -> dict[str, str]:
    """:data:`SETTING_NAMES` with ``names`` (e.g. the CLI's option names) over it."""
    return {**SETTING_NAMES, **(names or {})}


def say_setting(names, field: str, value: str, before: str = "", after: str = "") -> str:
    """``value`` named as ``names[field]`` says (``--span 1000 Hz``), else in plain words
    (``a span of 1000 Hz``, ``3200 lines``): the drivers' own messages stay as they were."""
    if names and field in names:
        return f"{names[field]} {value}"
    return " ".join(w for w in (before, value, after) if w)


def check_settings(settings: AcquisitionSettings, names: Mapping[str, str] | None = None) -> None:
    """The checks every analyser shares (no span/lines table): averages, trigger level, and
    the pretrigger and windows against the time record T = lines / span. Raise
    :class:`AnalyserSetupError` naming the setting (``names``: see :meth:`Analyser.validate`)
    and its allowed range."""
    s = settings
    n = setting_names(names)
    record = f"{s.record_s:g} s = {n['lines']} {s.lines} / {n['span_hz']} {s.span_hz:g} Hz"
    if not 1 <= s.averages <= MAX_AVERAGES:
        raise AnalyserSetupError(f"{n['averages']} must be 1-{MAX_AVERAGES} (got {s.averages})")
    if not -100 <= s.trigger_level_pct <= 100:
        raise AnalyserSetupError(f"{n['trigger_level_pct']} must be within -100..100 % of "
                                 f"range (got {s.trigger_level_pct:g})")
    if not 0 <= s.pretrigger_s < s.record_s:
        raise AnalyserSetupError(f"{n['pretrigger_s']} {s.pretrigger_s:g} s must be within the "
                                 f"time record (0-{record})")
    for name in ("force_window_s", "exp_window_s"):
        v = getattr(s, name)
        if not 0 < v <= s.record_s:
            raise AnalyserSetupError(f"{n[name]} {v:g} s must be within the time record "
                                     f"(0-{record})")
    # a time constant under a thousandth of the record multiplies its end by e^-1000 and
    # the response's first millisecond by e^-1 already: the FRF is zeroed, and the
    # window's damping 1/(2 pi f tau) buries every mode (fit-frf then finds no peak)
    if s.exp_window_s < s.record_s / 1000:
        raise AnalyserSetupError(
            f"{n['exp_window_s']} {s.exp_window_s:g} s is under a thousandth of the time "
            f"record ({record}): it would zero the response; typical time constants are a "
            f"quarter of the record or more ({s.record_s / 4:g} s)")


class Analyser:
    """Base class of the drivers; use as a context manager.

    Parameters
    ----------
    transport : an open :class:`~laminid_cli.instrument.transport.Transport`
    idn : the analyser's ``*IDN?`` answer, if already read
    poll_s : interval between status polls while waiting for the averages
    """

    #: model name used by ``--model`` and in the file
    MODEL: ClassVar[str] = ""
    #: one-line description with the manual the commands come from
    MANUAL: ClassVar[str] = ""
    #: spans the analyser offers in two-channel FFT mode, Hz
    SPANS_HZ: ClassVar[tuple[float, ...]] = ()
    #: resolution lines it offers
    LINES: ClassVar[tuple[int, ...]] = ()
    #: highest frequency of the baseband, Hz (start + span must not exceed it)
    MAX_FREQ_HZ: ClassVar[float] = math.inf

    def __init__(self, transport: Transport, idn: str | None = None, poll_s: float = 0.05):
        self.transport = transport
        self.poll_s = poll_s
        self._idn = idn
        self._measuring = False

    # ----------------------------------------------------------------- identity
    @classmethod
    def matches(cls, idn: str) -> bool:  # pragma: no cover - overridden
        """True when an ``*IDN?`` answer belongs to this analyser family."""
        return False

    @property
    def idn(self) -> str:
        """The ``*IDN?`` answer (IEEE 488.2 common command, all analysers)."""
        if self._idn is None:
            # a control or bidi character in the answer (a device's firmware, a line's
            # noise) is written as '?': the identity goes into the FRF file, whose readers
            # refuse such text (errors.NON_PRINTABLE), and the file acquire wrote was then
            # unreadable by fit-frf
            self._idn = NON_PRINTABLE.sub("?", self.transport.query("*IDN?"))
        return self._idn

    def query_number(self, command: str, *, integer: bool = False, allowed=None):
        """The analyser's answer to ``command`` as a number (``integer``: a whole number, as
        a status word or a count). An answer that is none (line noise, another talker, a
        garbled reply), or not among ``allowed``, raises :class:`InstrumentError` naming the
        resource, the command and the answer, so the session stops with its finished points
        kept instead of a traceback or a poll that never ends."""
        answer = self.transport.query(command)
        try:
            value = float(answer)
            if not math.isfinite(value) or (integer and value != int(value)):
                raise ValueError(answer)
        except ValueError:
            value = None
        if integer and value is not None:
            value = int(value)
        if value is None or (allowed is not None and value not in allowed):
            want = "" if allowed is None else \
                f" (expected {' or '.join(str(a) for a in allowed)})"
            raise InstrumentError(f"analyser {self.transport.resource}: the {self.MODEL} "
                                  f"answered {command} with {answer!r}, not "
                                  f"{'an integer' if integer else 'a number'}{want}")
        return value

    def identity(self) -> dict:
        return {"idn": self.idn, "model": self.MODEL, "resource": self.transport.resource,
                "manual": self.MANUAL}

    # ---------------------------------------------------------------- validation
    @classmethod
    def validate(cls, settings: AcquisitionSettings,
                 names: Mapping[str, str] | None = None) -> None:
        """Raise :class:`AnalyserSetupError` unless the analyser offers these settings.

        A class method: ``acquire`` checks a ``--model`` it was given before it opens the
        analyser. ``names`` maps a field of :class:`AcquisitionSettings` to the name the
        messages give it (``acquire`` passes its options, e.g. ``{"lines": "--lines"}``).
        """
        s = settings
        n = setting_names(names)
        if not any(math.isclose(s.span_hz, v, rel_tol=1e-6) for v in cls.SPANS_HZ):
            raise AnalyserSetupError(
                f"{cls.MODEL} does not offer "
                f"{say_setting(names, 'span_hz', f'{s.span_hz:g} Hz', 'a span of')}; spans (Hz): "
                f"{_fmt_list(cls.SPANS_HZ)}")
        if s.lines not in cls.LINES:
            what = say_setting(names, "lines", str(s.lines), "", "lines")
            raise AnalyserSetupError(f"{cls.MODEL} does not offer {what}; lines: "
                                     f"{', '.join(str(v) for v in cls.LINES)}")
        if s.start_hz < 0 or s.start_hz + s.span_hz > cls.MAX_FREQ_HZ * (1 + 1e-9):
            raise AnalyserSetupError(
                f"{n['start_hz']} {s.start_hz:g} Hz + {n['span_hz']} {s.span_hz:g} Hz is "
                f"outside {cls.MODEL}'s range 0-{cls.MAX_FREQ_HZ:g} Hz")
        check_settings(s, names)

    # ------------------------------------------------------------------ actions
    def configure(self, settings: AcquisitionSettings) -> None:  # pragma: no cover
        raise NotImplementedError

    def prepare_transfer(self) -> None:
        """Set the data formats the read methods expect (also with ``--keep-setup``)."""

    def read_settings(self) -> AcquisitionSettings:  # pragma: no cover
        """Settings as the analyser has them (for ``--keep-setup``)."""
        raise NotImplementedError

    def start(self) -> None:  # pragma: no cover
        raise NotImplementedError

    def is_done(self) -> bool:  # pragma: no cover
        raise NotImplementedError

    def hits_done(self) -> int:
        """Averages completed so far (-1 if the analyser cannot tell)."""
        return -1

    def wait_until_done(self, n_averages: int, progress: ProgressCallback | None = None) -> None:
        """Poll the analyser's status until the averaging is complete (never a blind sleep).

        Each poll is a short query, so a dead analyser is caught by the transport timeout
        while a slow operator (minutes between hits) is not.
        """
        last = None
        while True:
            done = self.is_done()
            hits = n_averages if done else self.hits_done()
            if progress is not None and hits != last:
                progress(hits, n_averages)
                last = hits
            if done:
                self._measuring = False
                return
            time.sleep(self.poll_s)

    def read_frequency(self) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def read_frf(self) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def read_coherence(self) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def overloaded_channels(self) -> tuple[int, ...] | None:
        """Channels (1 = hammer force, 2 = response) that went over range during the last
        averages; None when the analyser cannot tell."""
        return None

    def overloads(self) -> int:
        """Number of :meth:`overloaded_channels` (-1 unknown)."""
        channels = self.overloaded_channels()
        return -1 if channels is None else len(channels)

    def command_errors(self) -> list[str]:  # pragma: no cover
        """Errors the analyser raised since the last check (its text, one entry each); clears
        them. Used after every set-up command so a rejected command is named."""
        raise NotImplementedError

    def transfer_errors(self) -> list[str]:
        """Errors raised during the last data transfer (default: :meth:`command_errors`)."""
        return self.command_errors()

    def send_checked(self, commands, what: str = "configuring") -> None:
        """Write each command and read the analyser's error state after it.

        Raises :class:`InstrumentError` naming every command the analyser rejected, with its
        error text (all commands are sent, so one message lists every rejection).
        """
        rejected = []
        for command in commands:
            self.transport.write(command)
            errors = self.command_errors()
            if errors:
                rejected.append(f"{command!r} -> {'; '.join(errors)}")
        if rejected:
            raise InstrumentError(f"{self.MODEL} rejected {len(rejected)} command(s) while "
                                  f"{what}: " + " | ".join(rejected))

    def check_axis(self, settings: AcquisitionSettings, freq: np.ndarray) -> None:
        """After configuring: the analyser's axis must have the lines asked for (a resolution
        command the analyser understood differently would show here, not in the fit)."""
        if freq.size not in (settings.lines, settings.lines + 1):
            raise InstrumentError(
                f"{self.MODEL}: the analyser returns {freq.size} frequency lines but "
                f"{settings.lines} lines were set (span {settings.span_hz:g} Hz); the "
                "resolution command was not taken as a number of lines")

    def abort(self) -> None:  # pragma: no cover
        """Stop a running measurement (safe state)."""
        raise NotImplementedError

    def measure(self, n_averages: int, progress: ProgressCallback | None = None,
                freq: np.ndarray | None = None,
                averaged: Callable[[], object] | None = None) -> Measurement:
        """Start, wait for ``n_averages`` hits, read FRF + coherence of one point.
        ``averaged`` is called once every hit is taken, before the transfers (the session
        holds Ctrl-C/SIGTERM from there until the point is saved)."""
        self.start()
        self.wait_until_done(n_averages, progress)
        if averaged is not None:
            averaged()
        channels = self.overloaded_channels()
        freq = self.read_frequency() if freq is None else freq
        frf = self._read_checked("FRF", self.read_frf)
        coh = self._read_checked("coherence", self.read_coherence)
        for name, arr in (("FRF", frf), ("coherence", coh)):
            if arr.shape != freq.shape:
                raise InstrumentError(f"{self.MODEL}: {name} has {arr.size} lines but the "
                                      f"frequency axis has {freq.size}")
        return Measurement(freq=freq, frf=frf, coherence=np.clip(coh, 0.0, 1.0),
                           n_averages=n_averages,
                           overloads=-1 if channels is None else len(channels),
                           overloaded_channels=tuple(channels or ()))

    def _read_checked(self, trace: str, read):
        """Read one trace, then the analyser's error state; an error raised during the transfer
        means the data may be corrupt or stale: read the trace once more, and if the error
        repeats raise :class:`TransferError` (the caller must not save the point)."""
        data = read()
        first = self.transfer_errors()
        if not first:
            return data
        log.warning("%s flagged an error during the %s transfer (%s); reading it again",
                    self.MODEL, trace, "; ".join(first))
        data = read()
        again = self.transfer_errors()
        if not again:
            return data
        raise TransferError(
            f"{self.MODEL} flagged an error during the {trace} transfer, twice (read again "
            f"once): {'; '.join(again)}", trace=trace, errors=tuple(again))

    # ----------------------------------------------------------- context manager
    def close(self) -> None:
        """Leave the analyser safe (measurement stopped) and close the link."""
        try:
            if self._measuring:
                self.abort()
        except InstrumentError:
            log.warning("%s: could not stop the measurement while closing", self.MODEL)
        finally:
            self.transport.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
