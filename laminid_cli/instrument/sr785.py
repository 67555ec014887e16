"""Stanford Research Systems SR785 Dynamic Signal Analyzer (its own four-letter command set).

Measurement (paper section 3): display A = frequency response (ch2/ch1) in Nyquist view, so one
``DSPB?`` transfer gives (imag, real) pairs; display B = coherence; RMS averaging (H1),
channel-1 trigger with negative delay, force/exponential window. ``DSPB?`` returns 4-byte IEEE
floats, no header and no terminator (so the byte count comes from ``DSPN?`` first), least
significant byte first. ``DSPB?`` exists only on the GPIB interface: use a GPIB resource (or a
GPIB-LAN gateway), not the RS-232 port. The test emulator serves it over a TCP socket.
Display argument ``d``: 0 = A, 1 = B, 2 = both.

Evidence for every command string (issue 12). "LIGO script" = the public SR785 FFT
transfer-function script (© 2021 MIT, L. McCuller; netgpib), which sends the same set-up
commands with comments giving each code; "pySR785" = a public pyvisa SR785 driver
(``SR785.FFT`` class, ``_param_map`` and ``measure``); "pyHegel SR780" = ``lupien/pyHegel``
``pyHegel/instruments/srs.py`` class ``sr780_analyzer`` (the SR780, the SR785's predecessor with
the same command set and status words; its docstrings give the bit layouts of ``DSPS?``,
``INPS?``, ``ERRS?`` and ``*ESR?``); "Roy SR785" = ``AvirupRoy/research``
``Visa/SR785_New/SR785.py`` (commit ffba586), a PyQt SR785 driver whose settings give the command,
its values and, in tooltips, the page of the SR785 User Manual pdf they come from; "Labber SR785" =
``Labber-software/Drivers`` ``Stanford_SR785/Stanford_SR785.py`` (commit 94ab48c), value tables of
the queries it decodes. "SR785 manual p. 5-n" = SRS, *Model SR785 Dynamic Signal Analyzer,
Operating Manual and Programming Reference*, ch. 5, as stored page by page at
https://manualshive.com/en/manual/stanford-research-systems/sr785/1359464?page=<400+n> (only
some pages are stored there; ``AvirupRoy/research`` has ``SR785m.pdf`` only as binary); "RunPSD"
= ``i-oo/sR785_PSD`` ``RunPSD.c`` (commit eab6fba), a C program for a Prologix GPIB-USB adapter
whose ``DataDump`` sends ``DSPB? 0`` and reads the bytes straight into a C ``float`` array.
Commands no public source gives are marked **unconfirmed**, with where we looked.

``*IDN?`` ``*CLS``
    IEEE 488.2; LIGO script (``*CLS``, IDN check "Stanford_Research_Systems,SR785")
``*ESR?``
    IEEE 488.2 standard event status; bits 4 = execution error, 5 = command error: LIGO script
    ``*ESE 48`` "set bits 4 and 5 ... EXE and CME"; pyHegel SR780 ``get_error``: bit 2 too many
    responses pending, 3 too many commands received, 4 command cannot execute, 5 command syntax
    error, 6 key press, 7 power on (bits 2-5 are errors, 6-7 are not)
``MGRP 2,0``
    LIGO script ``MGRP2,0`` "Measurement Group = FFT"; pySR785
``MEAS 0,11`` ``MEAS 1,9``
    LIGO script: 11 = "Frequency Resp", 9 = "Coherence"; Roy SR785 ``measurementSelect`` and
    Labber SR785 (``MEAS ? 0`` table): 9 = coherence, 11 = frequency response in the FFT group
    (pyHegel's SR780 list has no power-spectrum entries and other indices: SR780 only)
``FBAS 2,1``
    LIGO script ``FBAS2,1`` "Base Frequency = 102.4kHz"; pySR785 ``_fft_base_freq_map`` (0 = 100
    kHz, 1 = 102.4 kHz); pyHegel SR780 ``freq_baseline`` (``FBAS 2,{val}``, index of [100e3,
    102.4e3])
``FSPN 2,<Hz>``
    LIGO script ``FSPN2,``; pySR785 ``stop_Hz`` (spans 102.4 kHz/2^k); SR785 manual p. 5-26
    ("Commands and Units": ``FSPN 2, 51200`` sets a 51.2 kHz span, Hz being the default unit
    when none is sent, and a query answers in that default unit: ``FSPN? 0`` gives Hz)
``FLIN 2,<i>``
    LIGO script / pySR785: 0..3 = 100, 200, 400, 800 lines; Roy SR785 ``lines`` (``FLIN 2,``,
    manual pdf p. 205); Labber SR785 ``FLIN ? 0`` table
``FSTR 2,<Hz>``
    pySR785 ``start_Hz`` (``FSTR 2,``); SR785 manual p. 5-25 ("Command Syntax": ``FSTR (?) d
    {, f}``, ``FSTR 0, 1.024E3`` sets display A's start to 1024 Hz, ``FSTR ? 0`` queries it;
    d = 2 sets both displays and is not allowed in a query, hence ``FSTR? 0``)
``FAVG 2,1``
    LIGO script "Averaging On"
``FAVM 2,2``
    LIGO script ``avgModDict``: 2 = RMS; Roy SR785 ``averageType`` (0 none, 1 vector, 2 rms,
    3 peak hold; manual pdf pp. 305-307); Labber SR785 ``FAVM ? 0`` table
``FAVT 2,0``
    LIGO script "Averaging Type = Linear"; pySR785; Roy SR785 ``fftAverageType`` (0 =
    linear/fixed length, 1 = exponential/continuous; manual pdf p. 304)
``FAVN 2,<n>``
    LIGO script "Number of Averaging"; range 2-32767: Roy SR785 ``numberOfAverages`` (manual
    pdf p. 305) and pyHegel SR780 ``average_count_requested`` (min 2, max 32767), so
    :meth:`SR785.validate` refuses one average before sending anything
``FWIN 2,5``
    LIGO script ``winFuncDict``: 5 = "Force/Exponential"; Roy SR785 ``windowType`` (``FWIN 2,``,
    5 = force/exponential; manual pdf pp. 327-328)
``W1FE 0`` ``W2FE 1``
    Roy SR785 ``forceOrExponential1``/``forceOrExponential2`` (``W1FE``/``W2FE`` with no
    display argument, 0 = force window, 1 = exponential window, "only applicable when
    windowType is force/exponential"; manual pdf pp. 328-329): the force/exponential window
    is chosen per channel, so channel 1 (hammer) is set to force and channel 2 to exponential.
    Until this branch the driver did not send them and the channels kept whatever the
    analyser had
``FWFL 2,<s>``
    Roy SR785 ``forceLength`` (``FWFL 2,``; "points in the time record up to the Force Length
    are unmodified, points past it are zeroed; the maximum ... is the length of the FFT time
    record"; manual pdf p. 329) confirms the command; its unit (seconds) is **unconfirmed**
    (the source gives none; its setting has no unit, range 0-1e5). A hint the other way, for
    the SR780: ``gitpan/Lab-Instrument`` ``lib/Lab/Instrument/SR780.pm`` (© 2006 D. Schröer),
    whose synopsis lists a set-up as ``'FWFL 0,100',# Force 100%`` next to ``'FWTC 0,50',#
    Expo 50%`` (so on that SR780 the force length may be a percentage of the record, like
    FWTC). Looked in (branch instr-evidence): the pages corpus for the SR785/SR780 Window menu
    and Window commands pages (manual pdf p. 329 not stored), Labber SR785 ``.ini`` (no
    window settings), ``ilw/sr785_rs232`` ``SR785.py`` (``FWIN`` only). To settle it on a
    real SR785, send ``FWFL 2,10 ms`` and read ``*ESR?`` and ``FWFL? 0`` (manual pp. 5-25 and
    5-26: a command takes a unit string when its entry field offers a choice of units; a
    percentage field offers none, so the time unit should then be refused, bit 5)
``FWTC 2,<%>``
    Roy SR785 ``expoWindowTimeConstant`` (``FWTC 2,``, unit %, 5-1000; "the percentage of the
    FFT time record where the window function reaches 1/e"; manual pdf p. 329): so
    ``100 tau / T`` with w(tau) = 1/e is the convention, and :meth:`SR785.validate` refuses a
    time constant under 5 % of the record before sending anything
``TSRC 1``
    LIGO script: 1 = "Ch1" (single argument)
``TMOD 0``
    LIGO script "Auto trigger arming"
``TSLP 0``
    **unconfirmed** (0 = rising slope). Looked in: code search for ``TSLP`` (only the SR620
    counter's ``TSLP n,slope``, another instrument), pyHegel SR780 (no trigger devices), Roy
    SR785 (trigger: ``TMAN`` only; ``SR785_Menus.py`` has the Trigger menu's soft-key labels
    only, no values), Labber SR785 (``TAVM`` only; its ``.ini`` has no trigger settings),
    ``awade/netgpibdata`` ``SR785.py``, ``ilw/sr785_rs232`` ``SR785.py`` (no trigger
    commands), RunPSD (none), ``gitpan/Lab-Instrument`` ``SR780.pm`` (no trigger commands),
    the docs corpus, and the pages corpus (SR785 manual pages 5-25, 5-26, 5-71, 5-107 to 5-110
    and 5-124 are stored, the Trigger commands and Trigger menu pages are not)
``TLVL <pct>``
    LIGO script "Sets trigger level in percent"
``TDLA <s>`` ``TDLB <s>``
    LIGO script "Delay for channel 1/2 in s"
``VIEW 0,7`` ``VIEW 1,1``
    LIGO script view table: 7 = Nyquist, 1 = Linear Magnitude; same table in Roy SR785 ``view``,
    Labber SR785 ``VIEW ? 0`` and pyHegel SR780 ``meas_view``. A Nyquist view returns two values
    per bin, Y (imag) then X (real): SR785 manual p. 5-108 (``DSPB?``): "In the case of a 2-D
    view (Nyquist or Nichols), two values per bin are returned (8 bytes per bin). The first
    value is the Y axis value and the second is the X axis value." (a Nyquist diagram has the
    real part on X and the imaginary part on Y); also pyHegel SR780 ``_fetch_getdev``
    ("nyquist and nichols plot ... return 2 values per datapoint")
``STRT``
    LIGO script "Start measurement"; pySR785
``DSPS?`` ``DSPS? 1``
    LIGO script ``DSPS?1`` (loop until averaging done); pySR785 "read AVGA (averaging complete)";
    pyHegel SR780 ``get_display_status``: bit 1 = display A linear average complete; Roy SR785
    ``Display.AVGA = 2**1``
``NAVG? 0``
    LIGO script (averages done)
``DSPN? d`` ``DSPB? d``
    SR785 manual p. 5-107 (``DSPN?``: "Always use the DSPN ? command to determine the display
    length before reading all of the data from a display") and p. 5-108 (``DSPB?``: "This
    command is only available with the GPIB interface"; "returns 4 bytes per bin starting with
    bin 0 ... There is no separation between data points. No line-feed follows the last data
    point, instead, EOI is asserted with the last byte. The 4 bytes are an IEEE floating point
    number"); LIGO script and pySR785 (4-byte floats, no header); Roy SR785 ``retrieveData``
    (``DSPB? %d``, a length that is not a multiple of 4 is refused, unpacked as 4-byte floats)
    and pyHegel SR780 (``DSPB?`` read raw as float32). Least significant byte first: the
    manual's one statement of the byte order of its 4-byte IEEE floats is in the same Data
    Transfer Commands section, p. 5-109 (``TLOD``, host to analyser): "Each 4-byte float is
    transmitted least significant byte first" (the ``DSPB?`` entry itself does not repeat
    it); RunPSD, Roy SR785 and pyHegel SR780 all read ``DSPB?`` in the little-endian PC's
    native order
``FSPN? 0`` ``FLIN? 0`` ``FSTR? 0`` ``FAVN? 0`` ``TLVL?``
    LIGO script / pySR785 queries
``INPS?``
    pyHegel SR780 ``get_input_status``: bit 2 = input 1 exceeded full scale, bit 10 = input 2
    exceeded full scale (:data:`INPS_OVERLOAD_BITS`); same word on the SR785 **unconfirmed**
``ERRS?``
    pyHegel SR780 ``get_error`` (``ERRS?``: bit 0 output error, 1 disk error, 2 math error, 3-12
    memory/calibration test failures, :data:`ERRS_BITS`); the same layout on the SR785 is
    **unconfirmed**, so any non-zero word counts as an error and is printed with its bits.
    For both: SR785 manual p. 5-124 names the same six status words as the SR780 manual
    (p. 5-107, same manualshive site, manual 1359462): "the Serial Poll, Standard Event,
    Instrument, Display, Input and Error status words" -- a hint that the words match, not
    their bit tables, which are on the following pages (not stored). Looked in (branch
    instr-evidence): the pages corpus (SR785 and SR780 status-word pages), code search for
    ``INPS?``/``ERRS?`` (no SR785 reader), Roy SR785 (``Display`` bits only), Labber SR785,
    ``ilw/sr785_rs232``
``PAUS``
    pyHegel SR780 (``PAUS`` "make sure we are not scanning anymore")

Faults: ``*ESR?`` is read after every set-up command (a rejected command is named with the
error bits it set), and ``ERRS?`` + ``*ESR?`` after every trace transfer (issue 15): an error
raised during a transfer makes the driver read the trace again once; if it repeats the point is
refused (:class:`~.base.TransferError`).
"""

from __future__ import annotations

import math

import numpy as np

from laminid_cli.errors import InstrumentError
from laminid_cli.instrument.base import (AcquisitionSettings, Analyser, format_number,
                                         say_setting, setting_names)
from laminid_cli.instrument.transport import AnalyserSetupError

#: spans with the 102.4 kHz base frequency (FBAS 1): 102.4 kHz / 2**k (Frequency commands)
SPANS_HZ = tuple(102400.0 / 2 ** k for k in range(20))
#: FLIN index -> lines (Frequency commands, FFT resolution)
LINES = (100, 200, 400, 800)
# Display Setup commands: MGRP 0 = FFT group; MEAS indices in the FFT group; VIEW indices
MGRP_FFT = 0
MEAS_COHERENCE = 9
MEAS_FREQ_RESPONSE = 11
VIEW_LINEAR_MAG = 1
VIEW_NYQUIST = 7
#: Window commands: FWIN index of the force/exponential window
FWIN_FORCE_EXP = 5
#: W1FE/W2FE: which of the two a channel gets in the force/exponential window
WFE_FORCE = 0
WFE_EXPONENTIAL = 1
#: FWTC range, percent of the time record (Roy SR785 ``expoWindowTimeConstant``)
FWTC_MIN_PCT = 5.0
#: FAVN range (Roy SR785 ``numberOfAverages``, pyHegel SR780): at least two averages
FAVN_MIN = 2
#: Average commands: FAVM 2 = RMS, FAVT 0 = linear (fixed length)
FAVM_RMS = 2
FAVT_LINEAR = 0
#: Trigger commands: TSRC 1 = channel 1
TSRC_CH1 = 1
#: Display status word bit: averaging complete on display A
DSPS_AVGA = 1
#: Input status word bits: channel 1 / channel 2 overload
INPS_OVERLOAD_BITS = (1 << 2, 1 << 10)
#: standard event status bits that mean an error (IEEE 488.2; SR780 layout in pyHegel)
ESR_ERRORS = {2: "query error (too many responses pending)",
              3: "input overflow (too many commands received)",
              4: "execution error (parameter out of range or not allowed now)",
              5: "command error (unknown command or bad syntax)"}
#: error status word (``ERRS?``) bits, SR780 layout (pyHegel); unconfirmed on the SR785
ERRS_BITS = {0: "output error", 1: "disk error", 2: "math error", 3: "RAM test failed",
             4: "ROM test failed", 5: "video memory test failed", 6: "help memory test failed",
             7: "DSP data memory failed", 8: "DSP program memory failed",
             9: "DSP DRAM failed", 10: "DSP calibration memory failed",
             11: "ch1 calibration memory failed", 12: "ch2 calibration memory failed"}


def esr_text(word: int) -> str:
    """The error bits of a standard event status word, as text ("" when none)."""
    found = [f"bit {bit}: {text}" for bit, text in ESR_ERRORS.items() if word & (1 << bit)]
    return f"*ESR? = {word} ({'; '.join(found)})" if found else ""


def errs_text(word: int) -> str:
    """An error status word as text ("" when 0); bits outside :data:`ERRS_BITS` by number."""
    if not word:
        return ""
    found = [f"bit {b}: {ERRS_BITS.get(b, 'unknown')}" for b in range(16) if word & (1 << b)]
    return f"ERRS? = {word} ({'; '.join(found)})"


class SR785(Analyser):
    """Driver of the SRS SR785 (two-channel FFT).

    >>> SR785.matches("Stanford_Research_Systems,SR785,s/n12345,ver116")
    True
    """

    MODEL = "SR785"
    #: names a lab types for ``--model`` (case-insensitive)
    ALIASES = ("sr785",)
    MANUAL = "SRS SR785 Operating Manual and Programming Reference, ch. 5"
    SPANS_HZ = SPANS_HZ
    LINES = LINES
    MAX_FREQ_HZ = 102400.0

    @classmethod
    def matches(cls, idn: str) -> bool:
        fields = [f.strip().upper() for f in idn.split(",")]
        return len(fields) >= 2 and fields[1] == "SR785"

    # ------------------------------------------------------------------ set-up
    @classmethod
    def validate(cls, settings: AcquisitionSettings, names=None) -> None:
        """The shared checks, then the SR785's own ranges: ``FAVN`` takes 2-32767 averages and
        ``FWTC`` at least 5 % of the record (module docstring)."""
        super().validate(settings, names)
        s = settings
        n = setting_names(names)
        if s.averages < FAVN_MIN:
            got = say_setting(names, "averages", str(s.averages))
            raise AnalyserSetupError(f"{cls.MODEL} averages at least {FAVN_MIN} records "
                                     f"(FAVN 2-32767; got {got})")
        pct = 100.0 * s.exp_window_s / s.record_s
        if pct < FWTC_MIN_PCT * (1 - 1e-9):
            raise AnalyserSetupError(
                f"{cls.MODEL}: {n['exp_window_s']} {s.exp_window_s:g} s is {pct:.3g} % of the "
                f"time record ({s.record_s:g} s); its FWTC takes at least {FWTC_MIN_PCT:g} % "
                f"({FWTC_MIN_PCT / 100 * s.record_s:g} s)")

    def configure(self, settings: AcquisitionSettings) -> None:
        """Send the impact-test set-up; ``*ESR?`` after each command names a rejected one."""
        self.validate(settings)
        s = settings
        pct = 100.0 * s.exp_window_s / s.record_s
        delay = format_number(-s.pretrigger_s)
        self.transport.write("*CLS")                     # clear status words
        self.send_checked([
            f"MGRP 2,{MGRP_FFT}",                        # FFT group, both displays
            f"MEAS 0,{MEAS_FREQ_RESPONSE}",              # display A: frequency response
            f"MEAS 1,{MEAS_COHERENCE}",                  # display B: coherence
            "FBAS 2,1",                                  # base frequency 102.4 kHz
            f"FSPN 2,{format_number(s.span_hz)}",        # span, Hz
            f"FLIN 2,{LINES.index(s.lines)}",            # resolution (index)
            f"FSTR 2,{format_number(s.start_hz)}",       # start, Hz
            "FAVG 2,1",                                  # averaging on
            f"FAVM 2,{FAVM_RMS}",                        # RMS (H1)
            f"FAVT 2,{FAVT_LINEAR}",                     # linear, fixed length
            f"FAVN 2,{s.averages}",                      # number of averages
            f"FWIN 2,{FWIN_FORCE_EXP}",                  # force/exponential window
            f"W1FE {WFE_FORCE}",                         # ch1 (hammer): force window
            f"W2FE {WFE_EXPONENTIAL}",                   # ch2 (response): exponential
            f"FWFL 2,{format_number(s.force_window_s)}",  # force length, s
            f"FWTC 2,{format_number(pct)}",              # expo time constant, % of record
            f"TSRC {TSRC_CH1}",                          # trigger source channel 1
            "TMOD 0",                                    # auto arm
            "TSLP 0",                                    # rising slope
            f"TLVL {format_number(s.trigger_level_pct)}",  # level, % of input range
            f"TDLA {delay}",                             # ch1 delay, s (<0 pre-trigger)
            f"TDLB {delay}",                             # ch2 delay, s
        ] + self.TRANSFER_SETUP)

    #: views the read methods expect (also sent with ``--keep-setup``)
    TRANSFER_SETUP = [f"VIEW 0,{VIEW_NYQUIST}",      # display A as Nyquist: (Y=im, X=re)
                      f"VIEW 1,{VIEW_LINEAR_MAG}"]   # display B: coherence, linear

    def prepare_transfer(self) -> None:
        self.send_checked(self.TRANSFER_SETUP, "setting the display views")

    def read_settings(self) -> AcquisitionSettings:
        q = self.query_number
        nan = math.nan
        return AcquisitionSettings(
            span_hz=q("FSPN? 0"), start_hz=q("FSTR? 0"),
            lines=LINES[q("FLIN? 0", integer=True, allowed=range(len(LINES)))],
            averages=q("FAVN? 0", integer=True),
            trigger_level_pct=q("TLVL?"), pretrigger_s=nan, force_window_s=nan,
            exp_window_s=nan)

    def _esr_errors(self) -> list[str]:
        text = esr_text(self.query_number("*ESR?", integer=True))
        return [text] if text else []

    def command_errors(self) -> list[str]:
        """Error bits of the standard event status (``*ESR?``; reading clears it)."""
        return self._esr_errors()

    def transfer_errors(self) -> list[str]:
        """Error status word (``ERRS?``) and standard event status (``*ESR?``), both cleared
        by reading; any error bit raised during the transfer is returned as text."""
        text = errs_text(self.query_number("ERRS?", integer=True))
        return ([text] if text else []) + self._esr_errors()

    # -------------------------------------------------------------- measuring
    def start(self) -> None:
        self.transport.query("DSPS?")     # reading the display status word clears it
        self.transport.write("STRT")      # start (restart) the measurement and averaging
        self._measuring = True

    def is_done(self) -> bool:
        # DSPS? d answers the one bit, 0 or 1: anything else is no "not yet" (a garbled
        # answer would otherwise be polled for ever)
        return self.query_number(f"DSPS? {DSPS_AVGA}", integer=True, allowed=(0, 1)) == 1

    def hits_done(self) -> int:
        return self.query_number("NAVG? 0", integer=True)

    def overloaded_channels(self) -> tuple[int, ...]:
        """Channels over full scale during the average (INPS?, :data:`INPS_OVERLOAD_BITS`)."""
        word = self.query_number("INPS?", integer=True)
        return tuple(ch for ch, bit in enumerate(INPS_OVERLOAD_BITS, 1) if word & bit)

    def _display_length(self, display: int) -> int:
        n = self.query_number(f"DSPN? {display}", integer=True)
        if n < 2:
            raise InstrumentError(f"{self.MODEL}: display {display} has {n} bins")
        return n

    def _read_floats(self, display: int, per_bin: int) -> np.ndarray:
        n = self._display_length(display)
        self.transport.write(f"DSPB? {display}")
        raw = self.transport.read_bytes(4 * per_bin * n)
        return np.frombuffer(raw, dtype="<f4").astype(float)

    def read_frequency(self) -> np.ndarray:
        """Axis of display A, Hz: start + j * span / lines (Frequency commands, DSPN?)."""
        q = self.query_number
        start = q("FSTR? 0")
        span = q("FSPN? 0")
        lines = LINES[q("FLIN? 0", integer=True, allowed=range(len(LINES)))]
        n = self._display_length(0)
        return start + np.arange(n) * (span / lines)

    def read_frf(self) -> np.ndarray:
        yx = self._read_floats(0, per_bin=2)
        return yx[1::2] + 1j * yx[0::2]

    def read_coherence(self) -> np.ndarray:
        return self._read_floats(1, per_bin=1)

    def abort(self) -> None:
        self.transport.write("PAUS")      # pause the measurement (safe, front panel usable)
        self._measuring = False


DRIVER = SR785
