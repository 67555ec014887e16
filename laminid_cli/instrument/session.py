"""Roving-hammer session: one averaged FRF per measurement point, saved as soon as it is read.

The workflow knows nothing about click: the command passes a :class:`SessionUI` (prompt, progress,
summary, repeat question), so tests drive it with a scripted UI. Every point goes to the
:class:`~laminid_cli.frf.store.FrfWriter` the moment it is read (the writer rewrites the file
atomically), so Ctrl-C, an instrument fault or a crash leaves a valid file with every finished
point, and ``--resume`` continues with the points not yet in it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from laminid_cli.errors import InstrumentError, LaminidError, Terminated, stop_signals_held
from laminid_cli.frf.store import resonance_lines
from laminid_cli.instrument.base import AcquisitionSettings, Analyser, Measurement

log = logging.getLogger(__name__)


class AcquisitionInterrupted(LaminidError):
    """The operator pressed Ctrl-C; the finished points are in the file (exit 130)."""

    exit_code = 130
    label = "stopped"


class AcquisitionTerminated(AcquisitionInterrupted):
    """The session was ended by SIGTERM; the finished points are in the file (exit 143,
    128 + SIGTERM, what a shell reports for a command ended by it)."""

    exit_code = 143


class SessionIncomplete(LaminidError):
    """The session ended (quit or skipped points) with points missing: the file is valid and
    ``--resume`` completes it (exit 3, so a script never takes a partial file for a full one)."""

    exit_code = 3
    label = "stopped"


class NoOperatorInput(LaminidError):
    """A prompt found standard input closed (a script without --no-prompt): nobody can answer
    it (exit 2; the finished points, if any, are in the file)."""

    exit_code = 2


class PointNotWritten(LaminidError):
    """A measured point could not be written (the disk full, the folder gone or read-only):
    the session stops, the file holds the points saved before (exit 2, as for any file the
    file system refuses)."""

    exit_code = 2


@dataclass(frozen=True)
class SessionOptions:
    """How the session runs.

    n_points : measurement points (labels "1".."n_points" unless ``labels`` is given)
    coherence_min : a point whose coherence at the resonances is below this is "poor"
    prompt : ask before each point and offer to repeat poor points (False: just wait for hits)
    resume_hint : command line that continues the file (shown when the session stops early)
    """

    n_points: int
    coherence_min: float = 0.9
    prompt: bool = True
    labels: tuple[str, ...] | None = None
    resume_hint: str = ""

    def point_labels(self) -> tuple[str, ...]:
        return self.labels if self.labels else tuple(str(i + 1) for i in range(self.n_points))


#: the input channels of the impact test (paper section 3), as the quality line names them
CHANNEL_NAMES = {1: "ch1 hammer", 2: "ch2 response"}


@dataclass(frozen=True)
class PointQuality:
    """One-line quality of a measured point.

    coherence_resonance : mean coherence over the lines where |H| is in its top quarter
        (the resonances; coherence dips at anti-resonances are normal and ignored)
    peak_freq_hz, peak_coherence : frequency of max |H| and the coherence there
    overloads : number of channels over range during the averages (-1: the analyser cannot
        tell); overloaded_channels : which, 1 = hammer force, 2 = response
    """

    label: str
    n_averages: int
    coherence_resonance: float
    peak_freq_hz: float
    peak_coherence: float
    overloads: int
    coherence_min: float
    overloaded_channels: tuple[int, ...] = ()

    @property
    def ok(self) -> bool:
        return self.coherence_resonance >= self.coherence_min and self.overloads <= 0

    def line(self) -> str:
        ovl = "?" if self.overloads < 0 else str(self.overloads)
        if self.overloaded_channels:   # which input: the hammer hit too hard, or the response
            ovl += " (" + ", ".join(CHANNEL_NAMES.get(ch, f"ch{ch}")
                                    for ch in self.overloaded_channels) + ")"
        faults = ([] if self.coherence_resonance >= self.coherence_min else ["POOR coherence"]) \
            + ([] if self.overloads <= 0 else ["OVERLOAD"])
        return (f"point {self.label}: {self.n_averages} hits, coherence at resonances "
                f"{self.coherence_resonance:.3f} (peak {self.peak_coherence:.3f} at "
                f"{self.peak_freq_hz:.1f} Hz), overloads {ovl} - "
                f"{', '.join(faults) if faults else 'ok'}")


def assess_point(label: str, m: Measurement, coherence_min: float) -> PointQuality:
    """Quality summary of one measurement (see :class:`PointQuality`)."""
    mag = np.abs(m.frf)
    use = m.freq > 0  # the DC line of an impact FRF is meaningless
    if not use.any():
        use = np.ones_like(mag, dtype=bool)
    k = int(np.argmax(np.where(use, mag, -np.inf)))
    coh = np.nan_to_num(m.coherence, nan=0.0)
    top = resonance_lines(m.freq, m.frf)
    return PointQuality(label=label, n_averages=m.n_averages,
                        coherence_resonance=float(coh[top].mean()),
                        peak_freq_hz=float(m.freq[k]), peak_coherence=float(coh[k]),
                        overloads=int(m.overloads), coherence_min=coherence_min,
                        overloaded_channels=tuple(int(c) for c in m.overloaded_channels))


class SessionUI(Protocol):
    """Callbacks the session uses to talk to the operator."""

    def ready(self, label: str, index: int, total: int) -> str:
        """Before a point: return "go", "skip" or "quit"."""

    def progress(self, label: str, index: int, total: int, hits: int, n_averages: int) -> None:
        """Hits done so far on the running point (hits = -1 when the analyser cannot tell)."""

    def summary(self, quality: PointQuality) -> None:
        """After a point has been read and saved."""

    def repeat(self, quality: PointQuality) -> bool:
        """Poor point: measure it again (replacing the saved one)?"""


class QuietUI:
    """A UI that never asks (``--no-prompt``) and logs the summaries."""

    def ready(self, label, index, total):
        return "go"

    def progress(self, label, index, total, hits, n_averages):
        pass

    def summary(self, quality):
        log.info("%s", quality.line())

    def repeat(self, quality):
        return False


@dataclass
class SessionResult:
    measured: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    repeated: int = 0
    quit: bool = False
    n_saved: int = 0
    complete: bool = False


def run_session(analyser: Analyser, writer, settings: AcquisitionSettings,
                options: SessionOptions, ui: SessionUI) -> SessionResult:
    """Measure every point not yet in ``writer``'s file; see the module docstring.

    Raises :class:`~laminid_cli.errors.InstrumentError` (exit 1) on an analyser fault and
    :class:`AcquisitionInterrupted` (exit 130) on Ctrl-C, both after the finished points are
    safely on disk and with the number of saved points and the resume command in the message.
    """
    labels = options.point_labels()
    todo = [label for label in labels if label not in writer.labels]
    result = SessionResult()
    total = len(labels)
    #: the point whose hits are being taken: [label, hits done (-1 unknown), hits wanted,
    #: True when it is a repeat of a point already saved]
    taking: list = []
    try:
        for label in todo:
            index = labels.index(label) + 1
            if options.prompt:
                answer = ui.ready(label, index, total)
                if answer == "quit":
                    result.quit = True
                    break
                if answer == "skip":
                    result.skipped.append(label)
                    continue
            replace = False
            while True:
                def progress(hits, n, _label=label, _index=index):
                    taking[:] = [_label, hits, n, replace]
                    ui.progress(_label, _index, total, hits, n)

                # a stop asked for once every hit of the point is taken (while its traces
                # are read and it is written) waits for it to be saved (and its line said):
                # an operator's Ctrl-C just after the last hit no longer throws the hits away
                with contextlib.ExitStack() as held:
                    holding: list = []

                    def hold(_held=held, _holding=holding):
                        if not _holding:      # once: a second call is a no-op
                            _held.enter_context(stop_signals_held())
                            _holding.append(True)
                            taking.clear()    # every hit taken: the point is kept

                    try:
                        m = analyser.measure(settings.averages, progress=progress,
                                             averaged=hold)
                    except InstrumentError as exc:
                        raise InstrumentError(f"point {label}: {exc}; point {label} not "
                                              "saved") from exc
                    if m.freq.shape != writer.freq.shape or \
                            not np.allclose(m.freq, writer.freq, rtol=1e-9):
                        raise InstrumentError(
                            f"{analyser.MODEL}: the frequency axis changed during the session "
                            f"({m.freq.size} lines, {m.freq[0]:g}-{m.freq[-1]:g} Hz; the file "
                            f"has {writer.freq.size}, {writer.freq[0]:g}-{writer.freq[-1]:g} "
                            "Hz); were the analyser's settings changed on its front panel?")
                    hold()      # an analyser without the callback: from here at the latest
                    try:
                        writer.add_point(label, m.frf, m.coherence, n_averages=m.n_averages,
                                         overloads=m.overloads, replace=replace)
                    except OSError as exc:
                        raise PointNotWritten(
                            f"point {label}: cannot write {writer.path}: "
                            f"{exc.strerror or exc}; point {label} not saved (free some space "
                            "or fix the folder, then resume)") from exc
                    quality = assess_point(label, m, options.coherence_min)
                    ui.summary(quality)
                    if label not in result.measured:
                        result.measured.append(label)
                if quality.ok or not options.prompt or not ui.repeat(quality):
                    break
                replace = True
                result.repeated += 1
        result.complete = all(label in writer.labels for label in labels)
        if result.complete:
            # marked complete in the try: a full disk or a stop here is said as for a point
            with stop_signals_held():
                try:
                    writer.close()
                except OSError as exc:
                    raise PointNotWritten(
                        f"every point is measured, but {writer.path} could not be marked "
                        f"complete: {exc.strerror or exc}; its points are all saved and "
                        "fit-frf reads it as it is") from exc
    except Terminated as exc:
        _stop(analyser)
        raise _stopped(AcquisitionTerminated(_saved_message("terminated (SIGTERM)", writer,
                                                            options, _lost(exc, taking))),
                       result, writer) from None
    except KeyboardInterrupt as exc:
        _stop(analyser)
        raise _stopped(AcquisitionInterrupted(_saved_message("interrupted", writer, options,
                                                             _lost(exc, taking))),
                       result, writer) from None
    except NoOperatorInput as exc:
        _stop(analyser)
        raise _stopped(NoOperatorInput(_saved_message(str(exc), writer, options)),
                       result, writer) from None
    except PointNotWritten as exc:
        _stop(analyser)
        # every point in the file (not marked complete): nothing for a resume to measure
        said = dataclasses.replace(options, resume_hint="") if result.complete else options
        raise _stopped(PointNotWritten(_saved_message(str(exc), writer, said)),
                       result, writer) from exc.__cause__
    except InstrumentError as exc:
        _stop(analyser)
        raise _stopped(InstrumentError(_saved_message(str(exc), writer, options)),
                       result, writer) from exc
    result.n_saved = writer.n_points
    return result


def _stopped(exc: LaminidError, result: SessionResult, writer) -> LaminidError:
    """``exc`` carrying the session so far (``exc.result``: points measured, skipped and
    repeated before it stopped, ``n_saved`` those in the file), for the command's --json."""
    result.n_saved = writer.n_points
    exc.result = result
    return exc


def _stop(analyser: Analyser) -> None:
    try:
        analyser.abort()
    except (InstrumentError, OSError):
        log.debug("could not abort the measurement", exc_info=True)


def _lost(stop: BaseException, taking: list) -> str:
    """What the stop ``stop`` leaves unsaved: a fault that ended the point it waited for
    (a stop held while a point is read comes after it: the fault is its context), else the
    hits of the point being taken."""
    fault = stop.__context__
    if isinstance(fault, (InstrumentError, PointNotWritten)):
        return str(fault)
    return _hits_lost(taking)


def _hits_lost(taking: list) -> str:
    """What a stop during a point's hits discards ("" when no hits were being taken)."""
    if not taking:
        return ""
    label, hits, n, repeat = taking
    what = f"point {label}'s repeat" if repeat else f"point {label}"
    kept = f" (the point {label} measured before is kept)" if repeat else ""
    if hits < 0:                             # an analyser that cannot tell (the 35670A)
        return f"{what} stopped before its {n} hits were taken, not saved{kept}"
    return f"{what} stopped at {hits} of {n} hits, not saved{kept}"


def _saved_message(prefix: str, writer, options: SessionOptions, also: str = "") -> str:
    n = writer.n_points
    also = f"; {also}" if also else ""
    if n and not writer.path.exists():      # removed (its folder too?) during the session
        return f"{prefix}; {writer.path} is gone, with the {n} point(s) saved in it{also}"
    msg = f"{prefix}; {n} point(s) saved in {writer.path}" if n else \
        f"{prefix}; no point finished" + (f" (file {writer.path})" if writer.path.exists() else "")
    msg += also
    if options.resume_hint and writer.path.exists():   # nothing to resume without the file
        msg += f"; continue with: {options.resume_hint}"
    return msg
