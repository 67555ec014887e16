"""``laminid acquire``: impact-test FRFs from a dynamic signal analyser into an FRF HDF5 file.

Thin glue: options -> :class:`~laminid_cli.instrument.base.AcquisitionSettings`, the driver
from :mod:`laminid_cli.instrument.registry`, the workflow in
:func:`laminid_cli.instrument.session.run_session`, the file through
:class:`laminid_cli.frf.store.FrfWriter`. pyvisa, numpy and h5py are imported inside the
command so ``laminid --help`` stays fast.
"""

from __future__ import annotations

import contextlib

import math
import shlex
import sys
from pathlib import Path

import click

from laminid_cli.commands._common import (FRF_UNIT_NOTE, JSON_ERROR_DOC, OUTPUT_FILE,
                                          FiniteFloat, check_hdf5_name, check_output_path,
                                          force_option, quiet, writable_target)
# (seconds the analyser may take to answer one query, unless --timeout says)
from laminid_cli.instrument.transport import DEFAULT_TIMEOUT_S



#: acquire's option for each field of AcquisitionSettings: the checks' messages name them
OPTION_NAMES = {"span_hz": "--span", "start_hz": "--start", "lines": "--lines",
                "averages": "--averages", "trigger_level_pct": "--trigger-level",
                "pretrigger_s": "--pretrigger", "force_window_s": "--force-window",
                "exp_window_s": "--exp-window"}


def _offered(attr: str) -> list:
    """Sorted union of ``attr`` (``LINES``, ``SPANS_HZ``) over every analyser driver: the
    parser refuses a value no supported analyser offers, before any analyser is opened (the
    driver list is imported when an option is parsed, not for ``--help``)."""
    from laminid_cli.instrument.registry import drivers

    return sorted({v for d in drivers().values() for v in getattr(d, attr)})


class OfferedLines(click.ParamType):
    """FFT resolution lines: one of the values a supported analyser offers (100-800)."""

    name = "lines"

    def convert(self, value, param, ctx):
        n = click.INT.convert(value, param, ctx)
        offered = _offered("LINES")
        if n not in offered:
            self.fail(f"{n} lines: the analysers offer {', '.join(map(str, offered))}.",
                      param, ctx)
        return n


class OfferedSpan(FiniteFloat):
    """A span, Hz, that a supported analyser offers (102.4 kHz / 2**k)."""

    name = "span"

    def __init__(self):
        super().__init__(min=0, min_open=True)

    def convert(self, value, param, ctx):
        span = super().convert(value, param, ctx)
        offered = _offered("SPANS_HZ")
        if not any(math.isclose(span, v, rel_tol=1e-6) for v in offered):
            big = [v for v in offered if v >= 50]
            self.fail(f"{span:g} Hz is not a span the analysers offer: 102400 Hz / 2^k: "
                      f"{', '.join(f'{v:g}' for v in reversed(big))}, ... "
                      f"{offered[0]:g} Hz.", param, ctx)
        return span


def check_settings_before_opening(settings, model: str) -> None:
    """Refuse, naming the options, an unknown ``--model`` and settings no analyser of that
    model could take, before any analyser is opened: the driver's own checks when ``--model``
    names one; with ``auto`` the checks every driver shares and the widest baseband (the
    driver's own follow *IDN?). ``settings`` None (``--keep-setup``): the model only."""
    from laminid_cli.instrument.base import check_settings
    from laminid_cli.instrument.registry import accepted_names, drivers, find_driver
    from laminid_cli.instrument.transport import AnalyserSetupError

    if model.lower() != "auto":
        driver = find_driver(model)
        if driver is None:
            raise AnalyserSetupError(f"--model {model!r}: unknown analyser model; choose auto "
                                     f"or one of: {', '.join(accepted_names())} "
                                     "(case-insensitive)")
        if settings is not None:
            driver.validate(settings, names=OPTION_NAMES)
        return
    if settings is None:
        return
    top = max(d.MAX_FREQ_HZ for d in drivers().values())
    if settings.start_hz + settings.span_hz > top * (1 + 1e-9):
        ranges = ", ".join(f"{d.MODEL} 0-{d.MAX_FREQ_HZ:g} Hz" for d in drivers().values())
        raise AnalyserSetupError(f"--start {settings.start_hz:g} Hz + --span "
                                 f"{settings.span_hz:g} Hz is above every supported "
                                 f"analyser's range ({ranges})")
    check_settings(settings, names=OPTION_NAMES)


class _ClickUI:
    """Operator dialogue on the terminal (the session itself never touches click)."""

    def __init__(self, path: Path, tty: bool | None = None, as_json: bool = False):
        self.path = path
        self.as_json = as_json                 # stdout holds the JSON: quality lines to stderr
        self.qualities: dict = {}              # the last quality of each saved point, by label
        self._progress_shown = False
        #: carriage-return progress only on a terminal; one line per event in logs and pipes
        self.tty = sys.stderr.isatty() if tty is None else tty

    def _end_progress(self):
        if self._progress_shown:
            click.echo("", err=True)
            self._progress_shown = False

    def _ask(self, text: str) -> str:
        """The operator's answer to ``text``; standard input closed (a script without
        --no-prompt) is NoOperatorInput, Ctrl-C a KeyboardInterrupt."""
        from laminid_cli.instrument.session import NoOperatorInput

        click.echo(text + ": ", nl=False, err=self.as_json)
        try:
            line = sys.stdin.readline() if sys.stdin is not None else ""
        except (OSError, ValueError, UnicodeDecodeError):    # closed, or not text
            line = ""
        if not line:                         # end of input: nobody at the keyboard
            click.echo("", err=self.as_json)
            raise NoOperatorInput("no answer to the prompt: standard input is closed (a script "
                                  "or a pipe?); run unattended with --no-prompt")
        return line.strip().lower()

    def ready(self, label, index, total):
        self._end_progress()
        answer = self._ask(f"Point {label} ({index}/{total}): press Enter, then hit the plate "
                           "[s = skip, q = quit]")
        return {"s": "skip", "skip": "skip", "q": "quit", "quit": "quit"}.get(answer, "go")

    def progress(self, label, index, total, hits, n_averages):
        head = f"point {label} ({index}/{total}): "
        if hits < 0:  # the analyser cannot report the hit count while averaging
            text = head + f"waiting for {n_averages} hits"
        elif hits >= n_averages:
            text = head + f"{n_averages}/{n_averages} hits averaged"
        else:
            text = head + f"{hits}/{n_averages} hits averaged, waiting for hit {hits + 1}"
        if self.tty:
            click.echo(f"\r{text:<70}", nl=False, err=True)
            self._progress_shown = True
        else:
            click.echo(text, err=True)

    def summary(self, quality):
        self._end_progress()
        self.qualities[quality.label] = quality
        click.echo(quality.line(), err=self.as_json)

    def repeat(self, quality):
        while True:                           # y (or Enter) / n; anything else asks again
            answer = self._ask(f"Repeat point {quality.label}? [Y/n]")
            if answer in ("", "y", "yes"):
                return True
            if answer in ("n", "no"):
                return False


def _refuse_unfinished(out: Path) -> None:
    """An unfinished acquisition at ``-o`` (an FRF file marked not complete: an interrupted or
    quit session) named again without --resume: refused naming its points and --resume. The
    generic "file exists; use --force to overwrite it" pointed at the option that throws the
    measured points away. Any other file: left to check_output_path."""
    from laminid_cli.errors import LaminidError, OutputExistsError
    from laminid_cli.frf.store import read_frf_h5

    try:
        old = read_frf_h5(out)              # probed: a file of unknown origin cannot crash us
    except (LaminidError, OSError, ValueError):
        return
    if old.meta.get("complete", True):
        return
    labels = list(old.labels)
    saved = (f"saved: point{'s' if len(labels) > 1 else ''} {', '.join(labels)}" if labels
             else "no point saved")
    raise OutputExistsError(
        f"{out}: an unfinished acquisition ({saved}); add --resume to measure the rest, or "
        "choose another name with -o (--force would start it again and lose the saved points)")


def _refuse_another_model(out: Path, old, dsa) -> None:
    """A ``--resume`` of ``out`` (read as ``old``) on an analyser of another model than the
    one its points were measured with is refused before the set-up is sent (exit 2, the file
    unchanged): it went on, and the file's ``/instrument`` then named the new analyser for
    every point, the first ones' included."""
    from laminid_cli.errors import FrfError

    recorded = old.meta.get("instrument") or {}
    model = str(recorded.get("model") or "").strip()
    if model and model.upper() != dsa.MODEL.upper():
        idn = f" ({recorded['idn']})" if recorded.get("idn") else ""
        raise FrfError(f"{out}: cannot resume on another analyser model: its points were "
                       f"measured with the {model}{idn}, the analyser at "
                       f"{dsa.transport.resource} is the {dsa.MODEL}; the file records one "
                       f"instrument for all its points: resume on the {model}, or write the "
                       "new points to another file (-o)", path=out)


def _nothing_to_measure(old, points: int) -> bool:
    """``--resume`` of ``old`` (the FRF file read) with ``--points points`` measures nothing:
    every point label 1..points is in the file, and the file is marked complete or holds
    exactly those points (a session that saved its last point and stopped before marking the
    file complete). A file not marked complete that holds more points than asked for is left
    to the "asks for fewer" refusal: its session may have more to measure."""
    labels = set(old.labels)
    if not all(str(i + 1) in labels for i in range(points)):
        return False
    return bool(old.meta.get("complete", True)) or old.n_points == points


def _say_complete(out: Path, old, points: int, as_json: bool) -> None:
    """Say that ``out`` (read as ``old``) has every point ``--resume --points points`` asks
    for and what to do next, on stderr (``--json``: the summary document on stdout too, with
    nothing measured); exit status 0. Nothing is opened or written."""
    import shlex

    from laminid_cli.commands._common import echo_json
    from laminid_cli.errors import escaped

    n = old.n_points
    labels = ", ".join(old.labels)
    freq = old.freq
    q = shlex.quote(str(out))
    marked = bool(old.meta.get("complete", True))
    more = (f"; it holds more points than --points {points} asks for" if n > points else "")
    state = ("already complete" if marked else
             "every point measured (the file is not marked complete: its session stopped "
             "after saving the last point)")
    # escaped: a folder 'bd\u202e' in the path reversed the lines (--json keeps it as read)
    click.echo(escaped(f"{out}: {state}: {n} point{'s' if n != 1 else ''} ({labels}), "
                       f"{freq.size} lines {freq[0]:g}-{freq[-1]:g} Hz, {old.units}{more}; "
                       "nothing to measure: the analyser was not opened and the file is "
                       "unchanged"), err=True)
    click.echo(escaped(f"next: laminid fit-frf {q} --into specimen.yaml; to measure the plate "
                       "again write another file (-o NEW.frf.h5) or replace this one (--force, "
                       f"without --resume: its {n} point{'s' if n != 1 else ''} would be lost); "
                       f"to add points --resume --points {n + 1} or more"), err=True)
    if as_json:
        echo_json(_json_summary(out, points, old.units, freq, old.meta.get("instrument") or {},
                                complete=True, already_complete=True, points_saved=n))


def _json_summary(out: Path, points: int, units, freq, instrument, *, complete: bool,
                  already_complete: bool = False, points_saved: int = 0, measured=(),
                  skipped=(), repeated: int = 0, quit: bool = False, qualities=(),
                  resume=None, stopped=None) -> dict:
    """The --json document of a session (``qualities``: its points' as the ``points``
    entries) or of a --resume that found every point saved (nothing measured): one key list
    for both."""
    return {
        "file": str(out), "complete": complete, "already_complete": already_complete,
        "points_requested": points, "points_saved": points_saved, "measured": list(measured),
        "skipped": list(skipped), "repeated": repeated, "quit": quit, "frf_unit": units,
        "units": units,            # frf_unit's old name, kept for 0.2.x (--json help)
        "lines": int(freq.size), "f_start_hz": float(freq[0]), "f_stop_hz": float(freq[-1]),
        "instrument": instrument, "points": list(qualities), "resume": resume,
        "stopped": stopped}


def _resume_command(params: dict, output: Path) -> str:
    args = ["laminid", "acquire", "--analyser", params["analyser"]]
    for name, flag in (("model", "--model"), ("visa_backend", "--visa-backend"),
                       ("span", "--span"), ("start", "--start"), ("lines", "--lines"),
                       ("averages", "--averages"), ("trigger_level", "--trigger-level"),
                       ("pretrigger", "--pretrigger"), ("force_window", "--force-window"),
                       ("exp_window", "--exp-window"), ("points", "--points"),
                       ("coherence_min", "--coherence-min"), ("units", "--units")):
        value = params.get(name)
        if value is not None:
            args += [flag, f"{value:g}" if isinstance(value, float) else str(value)]
    if params.get("timeout") not in (None, DEFAULT_TIMEOUT_S):   # a slow link needs it again
        args += ["--timeout", f"{params['timeout']:g}"]
    if not params.get("configure", True):
        args.append("--keep-setup")
    if params.get("no_prompt"):
        args.append("--no-prompt")
    if params.get("as_json"):
        args.append("--json")
    args += ["-o", str(output), "--resume"]
    return shlex.join(args)


def _stopped_outside_the_session(exc: KeyboardInterrupt, out: Path, resume: bool, result):
    """Ctrl-C or SIGTERM (``exc``) while acquire connected to or set up the analyser, or
    closed it after the session (``result``: the session's, else None), stopped as the
    session's own stop: one line saying what is in ``out`` (exit 130 or 143), and with --json
    an error document. It said "laminid: interrupted", --json printed nothing, and SIGTERM
    killed the process without a word."""
    from laminid_cli.instrument.session import (AcquisitionInterrupted, AcquisitionTerminated,
                                                Terminated)

    cls, what = ((AcquisitionTerminated, "terminated (SIGTERM)") if isinstance(exc, Terminated)
                 else (AcquisitionInterrupted, "interrupted"))
    if result is not None:
        return cls(f"{what} while closing the connection to the analyser, after the session: "
                   f"{result.n_saved} point(s) saved in {out}")
    left = f"{out} left as it was" if resume else f"nothing written to {out}"
    return cls(f"{what} while connecting to or setting up the analyser, before the first "
               f"point: no point measured; {left}")


@contextlib.contextmanager
def _sigint_stops_it_even_in_the_background():
    """SIGINT (``kill -INT PID``) stops acquire as Ctrl-C does also where it started with
    SIGINT ignored: a shell without job control (a script) starts ``laminid acquire ... &``
    so, and Python keeps an ignored SIGINT ignored, so that ``kill -INT`` did nothing. Python's
    own handler (KeyboardInterrupt) is installed for the command and the ignoring restored
    after it. Only in the main thread, where Python runs signal handlers."""
    import signal
    import threading

    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.SIG_IGN):
        yield
        return
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)


@click.command(short_help="Acquire impact-test FRFs from a dynamic signal analyser (VISA).")
@click.option("--analyser", "analyser", required=True, metavar="RESOURCE",
              help="VISA resource: GPIB0::5, GPIB0::5::INSTR, TCPIP::host::5025::SOCKET, ...")
@click.option("--model", default="auto", show_default=True,
              help="Analyser driver: auto (from *IDN?), 35670a (also hp35670a, agilent35670a, "
                   "keysight35670a) or sr785; case-insensitive.")
@click.option("--visa-backend", default=None, metavar="BACKEND",
              help="pyvisa backend: @py (pyvisa-py, default), @ivi (NI/Keysight VISA), "
                   "file.yaml@sim. Default from $LAMINID_VISA_BACKEND.")
@click.option("--timeout", default=DEFAULT_TIMEOUT_S, show_default=True,
              type=FiniteFloat(min=0.01),
              help="Seconds the analyser may take to answer one query.")
@click.option("--span", default=1600.0, show_default=True, type=OfferedSpan(),
              help="Span, Hz: 102400 / 2^k (51200 and below on the 35670A): ... 3200, 1600, "
                   "800, 400 ...")
@click.option("--start", default=0.0, show_default=True, type=FiniteFloat(min=0),
              help="Start frequency, Hz.")
@click.option("--lines", default=800, show_default=True, type=OfferedLines(),
              help="FFT resolution lines: 100, 200, 400 or 800.")
@click.option("--averages", default=5, show_default=True, type=click.IntRange(1, 9999),
              help="Hits averaged per point (the SR785 takes at least 2).")
@click.option("--trigger-level", default=10.0, show_default=True,
              type=FiniteFloat(-100, 100),
              help="Channel-1 (hammer) trigger level, % of input range.")
@click.option("--pretrigger", default=0.005, show_default=True, type=FiniteFloat(min=0),
              help="Time recorded before the trigger, s.")
@click.option("--force-window", default=0.01, show_default=True,
              type=FiniteFloat(min=0, min_open=True),
              help="Force-window width on channel 1, s.")
@click.option("--exp-window", default=0.1, show_default=True,
              type=FiniteFloat(min=0, min_open=True),
              help="Exponential-window time constant on channel 2, s.")
@click.option("--points", default=1, show_default=True, type=click.IntRange(min=1),
              help="Number of measurement points (labels 1..N).")
@click.option("--coherence-min", default=0.9, show_default=True,
              type=FiniteFloat(0, 1), help="Coherence at resonances below which a point "
                                                "is flagged poor (and may be repeated).")
@click.option("--units", default=None, metavar="UNITS",
              help="FRF engineering units to record, e.g. Pa/N (microphone) or (m/s^2)/N "
                   "(accelerometer); default V/V (ratio of the input voltages).")
@click.option("--no-prompt", is_flag=True,
              help="Do not ask before each point; just wait for the hits.")
@click.option("--configure/--keep-setup", default=True, show_default=True,
              help="Send the set-up to the analyser, or keep the one on its front panel.")
@click.option("--resume", is_flag=True, help="Continue an interrupted file: measure the "
                                             "points it does not have yet. A file that has "
                                             "every point is said so (exit 0) without opening "
                                             "the analyser or changing the file.")
@force_option
@click.option("--json", "as_json", is_flag=True,
              help="Print a JSON summary on stdout (file, points saved and missing, the "
                   "quality of each point measured in this run); the quality lines go to "
                   "stderr. Printed also when points are missing (exit 3) or the session "
                   "stopped early (Ctrl-C, analyser fault, closed stdin: 'stopped' says why), "
                   "and for a --resume of a file that has every point ('already_complete': "
                   "true, nothing measured). " + FRF_UNIT_NOTE + "; a command that fails "
                   f"before the session prints {JSON_ERROR_DOC} instead.")
@click.option("-o", "--output", required=True, type=OUTPUT_FILE,
              help="FRF HDF5 file to write (point by point).")
@click.pass_context
def acquire(ctx, analyser, model, visa_backend, timeout, span, start, lines, averages,
            trigger_level, pretrigger, force_window, exp_window, points, coherence_min, units,
            no_prompt, configure, resume, force, as_json, output):
    """Acquire impact-test FRFs (ch2/ch1) and coherence from a dynamic signal analyser.

    Hammer force on channel 1, microphone or accelerometer on channel 2 (paper section 3).
    For each measurement point the analyser averages the hits, laminid reads FRF and coherence,
    prints a one-line quality summary and saves the point at once: an interrupted session
    keeps every finished point, and --resume continues it.

    Exit status: 0 when every point is saved (also for --resume of a file that already has
    them all: said so, the analyser not opened, the file unchanged); 3 when the session ended
    with points missing (quit or skipped; the file is valid, continue with --resume); 1 on an
    analyser fault (finished points kept); 130 on Ctrl-C or SIGINT (kill -INT, also of an
    acquire started with '&' in a script, where SIGINT is ignored), 143 on SIGTERM (kill;
    both keep the finished points and print the --resume command); 2 for bad input (options, the
    output file, no analyser answering at --analyser: nothing measured).

    \b
    Example:
      laminid acquire --analyser GPIB0::5 --span 1600 --lines 800 --averages 5 \\
          --points 12 --units Pa/N -o plate.frf.h5
      laminid fit-frf plate.frf.h5 --into plate.yaml
    """
    ctx.with_resource(_sigint_stops_it_even_in_the_background())
    from laminid_cli.errors import FrfError, LaminidError, escaped, sigterm_raises_terminated
    from laminid_cli.errors import non_printable
    from laminid_cli.frf.store import FrfWriter
    from laminid_cli.instrument.base import AcquisitionSettings
    from laminid_cli.instrument.registry import open_analyser
    from laminid_cli.instrument.session import SessionOptions, run_session

    from laminid_cli.instrument.transport import AnalyserSetupError

    # a blank text is a mistake, not a request for the default
    if not analyser.strip():         # was "Could not parse : unknown interface type"
        raise AnalyserSetupError("--analyser: empty; give the analyser's VISA resource, e.g. "
                                 "GPIB0::5 or TCPIP::192.168.0.7::5025::SOCKET")
    if units is not None and not units.strip():
        raise AnalyserSetupError("--units: empty; give the FRF's engineering units, e.g. Pa/N "
                                 "or (m/s^2)/N, or leave the option out for V/V")
    bad = non_printable(units)
    if bad is not None:
        # (written into the file, whose readers refuse it: the session's file unreadable)
        raise AnalyserSetupError(f"--units {units!r}: {bad} in it; give the FRF's "
                                 "engineering units as plain text, e.g. Pa/N")
    if visa_backend is not None and not visa_backend.strip():
        raise AnalyserSetupError("--visa-backend: empty; give @py, @ivi or file.yaml@sim, or "
                                 "leave the option out")
    out = Path(output)
    writable_target(out)                   # a folder is refused, --resume or not
    units = units or "V/V"
    if resume and not out.exists() and not quiet():
        # scripts may pass --resume every time: a new file, said so (not silently)
        click.echo(escaped(f"laminid: note: {out}: no file to resume; starting a new one"),
                   err=True)
    # (.csv: it named batch's summary.csv, no FRFs; export writes UFF only, its --help)
    check_hdf5_name(out, "acquire writes the FRFs", csv="no laminid command writes FRFs as "
                    "CSV: laminid export writes them as a Universal File (.uff)")
    resume = resume and out.exists()
    if not resume and not force and out.is_file():
        _refuse_unfinished(out)
    if not resume:
        out = check_output_path(out, force)          # a symbolic link: its target
    settings = AcquisitionSettings(
        span_hz=span, start_hz=start, lines=lines, averages=averages,
        trigger_level_pct=trigger_level, pretrigger_s=pretrigger, force_window_s=force_window,
        exp_window_s=exp_window)
    # --keep-setup reads the analyser's own set-up: the model only
    check_settings_before_opening(settings if configure else None, model)
    if resume:   # refused before the analyser is touched (again when writing)
        from laminid_cli.frf.store import check_resume_settings, read_frf_h5

        old = read_frf_h5(out)
        # --keep-setup reads the set-up back from the analyser, later: units only then. Checked
        # before a complete file's shortcut too: --resume --span 800 of a 1600 Hz file said
        # "already complete", exit 0, as if the file were what was asked for
        check_resume_settings(out, old.meta.get("settings") or {},
                              settings.as_attrs() if configure else {},
                              units=(old.units, units),
                              instrument=old.meta.get("instrument"))
        if _nothing_to_measure(old, points):
            # every point asked for is in the file: the analyser is not opened and the file
            # not rewritten (it was, marked complete again, after a connection to the
            # analyser; with none at --analyser the command failed)
            _say_complete(out, old, points, as_json)
            return
        if old.n_points > points:
            raise FrfError(f"{out}: cannot resume, the file already holds {old.n_points} "
                           f"points ({', '.join(old.labels)}) and --points {points} asks for "
                           f"fewer: nothing to measure; give the session's number of points "
                           f"(at least --points {old.n_points}) to measure the rest")
    params = dict(ctx.params)
    hint = _resume_command(params, out)
    options = SessionOptions(n_points=points, coherence_min=coherence_min, prompt=not no_prompt,
                             resume_hint=hint)
    ui = _ClickUI(out, as_json=as_json)  # --no-prompt: the session never calls ready()/repeat()

    result = None
    try:   # SIGTERM as Ctrl-C also while connecting and setting up (it killed acquire)
        with sigterm_raises_terminated(), open_analyser(
                analyser, model=model, backend=visa_backend, timeout=timeout) as dsa:
            click.echo(f"{dsa.MODEL} at {dsa.transport.resource}: {dsa.idn}", err=True)
            if resume:
                _refuse_another_model(out, old, dsa)
            if configure:
                dsa.validate(settings, names=OPTION_NAMES)   # the model *IDN? named (auto)
                dsa.configure(settings)
            else:
                dsa.prepare_transfer()
                settings = dsa.read_settings()
            freq = dsa.read_frequency()
            if configure:
                dsa.check_axis(settings, freq)
            attrs = settings.as_attrs()
            attrs.update(coherence_min=coherence_min, n_points=points,
                         configured=bool(configure),
                         frf_estimator="H1 (RMS-averaged cross/auto spectra)",
                         channels="ch1 = hammer force, ch2 = response")
            writer = FrfWriter(out, freq, units=units, settings=attrs,
                               instrument=dsa.identity(), resume=resume, overwrite=force)
            if resume:
                click.echo(escaped(f"{out}: resuming, {writer.n_points} of {points} point(s) "
                                   "already measured"), err=True)
            identity = dsa.identity()

            def summary(result, stopped=None):
                """The --json document: also when the session stopped early (Ctrl-C, an
                analyser fault, a closed stdin), with what was saved before and the resume
                command."""
                from dataclasses import asdict

                from laminid_cli.commands._common import echo_json

                echo_json(_json_summary(
                    out, points, units, freq, identity, complete=result.complete,
                    points_saved=result.n_saved, measured=result.measured,
                    skipped=result.skipped, repeated=result.repeated, quit=result.quit,
                    # an analyser that cannot tell its overloads: null, not a count of -1
                    qualities=[asdict(q) | {"ok": q.ok} | (
                        {"overloads": None, "overloaded_channels": None}
                        if q.overloads < 0 else
                        {"overloaded_channels": list(q.overloaded_channels)})
                        for q in ui.qualities.values()],
                    resume=None if result.complete or not out.exists() else hint,
                    stopped=stopped))

            try:
                result = run_session(dsa, writer, settings, options, ui)
            except LaminidError as exc:
                if as_json and getattr(exc, "result", None) is not None:
                    summary(exc.result, stopped=str(exc))
                raise
    except KeyboardInterrupt as exc:    # outside the session, which says what it saved
        raise _stopped_outside_the_session(exc, out, resume, result) from None

    if as_json:
        summary(result)
    if not result.complete:
        from laminid_cli.instrument.session import SessionIncomplete

        raise SessionIncomplete(f"{out}: {result.n_saved} of {points} point(s) saved; "
                                f"continue with: {hint}")
    click.echo(escaped(f"{out}: {result.n_saved} point(s), {freq.size} lines "
                       f"{freq[0]:g}-{freq[-1]:g} Hz; next: laminid fit-frf {out} --into "
                       "specimen.yaml"), err=True)
