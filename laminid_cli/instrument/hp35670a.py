"""HP / Agilent / Keysight 35670A Dynamic Signal Analyzer (SCPI over GPIB).

Measurement (paper section 3): FFT instrument mode, two channels, trace A = frequency response
ch2/ch1 (``XFR:POW:RAT 2,1``), trace B = coherence (``XFR:POW:COH 1,2``), RMS (power)
averaging so trace A is H1 = <G21>/<G11>, channel-1 input trigger with a negative start delay
(pre-trigger), force window on channel 1, exponential window on channel 2. Data are read as
``FORM:DATA REAL,64`` blocks: IEEE 754 doubles, big-endian; trace A in Nyquist coordinates gives
(real, imag) pairs. Mnemonics are sent in their short form, without the optional ``SENSe:``
root; numbers without a unit suffix are in the SCPI default units (Hz, s).

Evidence for every command string (issue 12). "pymeasure" = the public driver
``pymeasure/pymeasure`` ``pymeasure/instruments/keysight/keysight35670A.py`` (commit b68e0af),
cited by the attribute that defines the command; "fft_dev" = the PyPI package ``fft_dev``
0.4.1a0 ("Driver and UI for 3562A and 35670A FFT analyzer", B. Dubois, FEMTO-ST, LGPL,
https://gitlab.com/bendub/fft_dev), file ``fft_dev/fft35670a/fft35670a_dev_prologix.py``, a
working 35670A driver over a Prologix GPIB-Ethernet adapter on Linux whose docstrings cite the
pages of *GPIB Programming with the Agilent 35670A* (stored as ``pypi-data/pypi-mirror-48``
``packages/fft-dev/fft_dev-0.4.1a0-py3-none-any.whl/...``, commit f0c7712); IEEE 488.2 = the
common commands standard.

``*IDN?`` ``*CLS`` ``*OPC``
    IEEE 488.2 common commands; pymeasure ``SCPIMixin``
``*ESR?``
    IEEE 488.2 (bit 0 = operation complete); pymeasure ``standard_event_status``
``INST:SEL FFT``
    pymeasure ``instrument_mode`` (INSTrument:SELect, ``INSTRUMENT_MODES`` fft = FFT)
``INP2:STAT 1``
    pymeasure ``Keysight35670AInputChannel.state`` (INPut{ch}:STATe %d)
``CALC1:FEED 'XFR:POW:RAT 2,1'``
    pymeasure ``Keysight35670ATrace.feed`` (CALCulate{ch}:FEED '%s'), ``TRACE_FEEDS``
    frequency_response_2_1
``CALC2:FEED 'XFR:POW:COH 1,2'``
    same, ``TRACE_FEEDS`` coherence_1_2
``FREQ:SPAN <Hz>``
    pymeasure ``frequency_span`` (SENSe:FREQuency:SPAN %g)
``FREQ:STAR <Hz>``
    pymeasure ``frequency_start`` (SENSe:FREQuency:STARt %g)
``FREQ:RES <lines>``
    pymeasure ``frequency_resolution`` (SENSe:FREQuency:RESolution %g) confirms the command;
    qkit ``qkitgroup/qkit`` ``qkit/drivers/Keysight_35670A.py`` (commit 34c7e1b)
    ``do_set_frequency_resolution`` that the number is the FFT line count ("sets the frequency
    resolution in lines (unitless)", 100 / 200 / 400 / 800 allowed, lines + 1 points) and
    fft_dev ``set_freq_resolution`` (``SENS:FREQ:RES``, "p.18-31", FFT mode table: 100, 200,
    400, 800 lines give 101, 201, 401, 801 frequency points); still ``acquire`` checks the
    axis length after configuring (``Analyser.check_axis``)
``AVER:STAT 1``
    pymeasure ``averaging_enabled`` (SENSe:AVERage:STATe %d)
``AVER:TYPE RMS``
    pymeasure ``average_type``, ``AVERAGE_TYPES`` rms = RMS
``AVER:COUN <n>``
    pymeasure ``average_count`` (SENSe:AVERage:COUNt %d)
``TRIG:SOUR INT1``
    pymeasure ``trigger_source``, ``TRIGGER_SOURCES`` = IMM, EXT, INT1..INT4, OUTP, BUS (INT1 =
    channel-1 input; there is no ``INP1``)
``TRIG:SLOP POS``
    pymeasure ``trigger_slope`` (POS|NEG)
``TRIG:LEV <pct> PCT``
    pymeasure ``trigger_level`` confirms TRIGger:LEVel %g, not its unit: the ``PCT`` suffix
    (percent of input range) is **unconfirmed**; chosen so that a firmware without it rejects
    the command by name (SCPI suffix error) instead of triggering at 10 V. Looked in (branch
    instrument-evidence): pymeasure ``trigger_level`` ("Control the trigger level.", range
    +-9.9e37, no unit), code search for ``TRIGger:LEVel``/``TRIG:LEV`` (other instruments only),
    the docs and pages corpora (no 35670A manual page). Looked in (branch instr-evidence):
    fft_dev (no trigger commands), qkit ``Keysight_35670A.py`` (none), the pages corpus: the
    35670A Operator's Guide at https://www.easymanua.ls/agilent-technologies/35670a/manual
    (p. I-13 "Triggering" lists the trigger types only) and the *Supplemental Operator's
    Guide* (Seattle Sound and Vibration, Agilent part 35670-90059) at
    http://audio.manualsonline.com/manuals/mfg/agilent_technologies/agilent_35670a.html (its
    hammer-test pages are stored, not the trigger set-up page)
``TRIG:STAR1 <s>`` ``TRIG:STAR2 <s>``
    pymeasure ``trigger_start1``/``trigger_start2`` ("channel 1 trigger start delay in
    seconds"); negative = pre-trigger; there is no TRIGger:DELay node
``WIND1:TYPE FORC`` ``WIND2:TYPE EXP``
    pymeasure ``Keysight35670ASenseWindow.window_type`` (SENSe:WINDow{ch}:TYPE),
    ``WINDOW_TYPES`` force = FORC, exponential = EXP
``WIND1:FORC <s>``
    pymeasure ``force_window_width`` (seconds)
``WIND2:EXP <s>``
    pymeasure ``exponential_window_time_constant`` (seconds)
``FORM:DATA REAL,64``
    pymeasure ``data_format`` (FORMat:DATA ASC|REAL; its reply parser drops a ``,<length>``);
    the ``,64`` and the big-endian byte order: fft_dev ``get_ydata``/``get_xdata`` send
    ``FORM:DATA REAL, 64`` before ``CALC<n>:DATA?``/``CALC<n>:X:DATA?``, and ``_get_bin_data``
    reads the ``#<n><count>`` header, drops the final byte (the terminator) and converts with
    ``array.array("d", ...)`` followed by ``data.byteswap()``, i.e. the doubles arrive most
    significant byte first and the little-endian PC has to swap them (``>f8`` here). Also
    hinted by other SCPI instruments, where big-endian is the default ``FORMat:BORDer
    NORMal``
``CALC1:FORM NYQ`` ``CALC2:FORM MLIN``
    pymeasure ``Keysight35670ATrace.display_format``, ``TRACE_DISPLAY_FORMATS`` nyquist = NYQ,
    linear_magnitude = MLIN; the (real, imag) order of NYQ blocks is **unconfirmed** (pymeasure
    reads CALC:DATA? as one flat list and says nothing of pairs; no other 35670A reader found).
    Looked in (branch instr-evidence): fft_dev (``YAXIS_FORMAT_MAP`` has "Nyquist diagram":
    NYQ, but its readers return the block as one flat array), qkit ``Keysight_35670A.py``
    (``set_trace_format`` lists NYQuist, ``get_single_trace`` parses one flat ASCII list), code
    search for ``CALC1:FORM NYQ`` (none), the pages corpus (Operator's Guide p. 5-17 "To display
    a Nyquist diagram": real part on X, "Imag" on Y, marker read as "R: ... I: ..." -- a screen,
    not the order of the data block)
``SYST:ERR?``
    pymeasure ``_raise_if_errors`` (SYSTem:ERRor? read until code 0 "No error")
``ABOR``
    pymeasure ``abort`` (ABORt)
``INIT:IMM``
    pymeasure ``initiate`` (INITiate:IMMediate)
``STAT:QUES:VOLT:EVEN?``
    pymeasure ``questionable_voltage_event``; the bits (``OVERLOAD_BITS``): Agilent 35670A
    manual, "The Agilent 35670A's Status Registers", p. 1-19, Questionable Voltage Register Set
    (https://www.easymanua.ls/agilent-technologies/35670a/manual/530226?p=37): channel 1
    overload bit 0, channel 2 overload bit 1 (bits 2-3 channels 3-4 of option AY6, bits 8-11
    input half-range). Until stop 28 the driver took bit 2 (channel 3) for channel 2
``CALC1:X:DATA?``
    pymeasure ``Keysight35670ATrace.read_x_data``
``CALC1:DATA?`` ``CALC2:DATA?``
    pymeasure ``Keysight35670ATrace.read_data``
``FREQ:SPAN?`` ``FREQ:STAR?``
    query forms of the properties above
``FREQ:RES?`` ``AVER:COUN?``
    query forms of the properties above

Faults: the error queue (``SYST:ERR?`` until ``+0``) is read after every set-up command, so a
rejected command is reported by name with the analyser's text, and after every trace transfer
(issue 15): an error raised during a transfer makes the driver read the trace again once; if
the error repeats the point is refused (:class:`~.base.TransferError`).
"""

from __future__ import annotations

import math

import numpy as np

from laminid_cli.errors import InstrumentError
from laminid_cli.instrument.base import AcquisitionSettings, Analyser, format_number

#: two-channel FFT spans: 51.2 kHz / 2**k. The top value is confirmed by qkit's 35670A driver
#: (``span`` and ``startfreq``/``stopfreq`` bounded at 51.2e3 Hz; ``set_input_channels``: with
#: one channel "the highest possible frequency, i.e., 102.4kHz"); the 2**k steps below it are
#: unconfirmed (pymeasure's ``frequency_span`` only bounds the value, 0.015625-102400 Hz;
#: fft_dev gives the log-sweep start/stop tables only; no 35670A span table found in the
#: code, docs or pages corpora); an odd span is refused before sending anything.
SPANS_HZ = tuple(51200.0 / 2 ** k for k in range(19))
#: FFT resolution lines offered in two-channel mode (qkit's 35670A driver, see FREQ:RES above)
LINES = (100, 200, 400, 800)
#: STATus:QUEStionable:VOLTage bits meaning "channel over range" (ch1, ch2): the 35670A
#: manual's Questionable Voltage Register Set (module docstring)
OVERLOAD_BITS = (1 << 0, 1 << 1)


class HP35670A(Analyser):
    """Driver of the HP/Agilent/Keysight 35670A (two-channel FFT, SCPI).

    >>> HP35670A.matches("HEWLETT-PACKARD,35670A,0,A.02.01")
    True
    """

    MODEL = "35670A"
    #: names a lab types for ``--model`` (case-insensitive)
    ALIASES = ("hp35670a", "agilent35670a", "keysight35670a", "35670a")
    MANUAL = ("HP/Agilent/Keysight 35670A SCPI command set (evidence: pymeasure Keysight35670A, "
              "see the driver docstring)")
    SPANS_HZ = SPANS_HZ
    LINES = LINES
    MAX_FREQ_HZ = 51200.0

    @classmethod
    def matches(cls, idn: str) -> bool:
        fields = [f.strip().upper() for f in idn.split(",")]
        return len(fields) >= 2 and fields[1] == "35670A"

    # ------------------------------------------------------------------ set-up
    def configure(self, settings: AcquisitionSettings) -> None:
        """Send the whole impact-test set-up; every command is followed by an error-queue
        read, so a rejected command is named (see the module docstring for the evidence)."""
        self.validate(settings)
        s = settings
        delay = format_number(-s.pretrigger_s)
        self.transport.write("*CLS")                # clear status + error queue
        self.send_checked([
            "INST:SEL FFT",                         # FFT analysis mode
            "INP2:STAT 1",                          # channel 2 on (two-channel measurement)
            "CALC1:FEED 'XFR:POW:RAT 2,1'",         # trace A = H = ch2/ch1
            "CALC2:FEED 'XFR:POW:COH 1,2'",         # trace B = coherence
            f"FREQ:SPAN {format_number(s.span_hz)}",   # Hz
            f"FREQ:STAR {format_number(s.start_hz)}",  # Hz
            f"FREQ:RES {s.lines}",                  # FFT lines
            "AVER:STAT 1",
            "AVER:TYPE RMS",                        # power averaging -> H1
            f"AVER:COUN {s.averages}",
            "TRIG:SOUR INT1",                       # channel-1 input (hammer)
            "TRIG:SLOP POS",
            f"TRIG:LEV {format_number(s.trigger_level_pct)} PCT",
            f"TRIG:STAR1 {delay}",                  # s, < 0 = pre-trigger
            f"TRIG:STAR2 {delay}",
            "WIND1:TYPE FORC",                      # force window on channel 1
            f"WIND1:FORC {format_number(s.force_window_s)}",   # width, s
            "WIND2:TYPE EXP",                       # exponential window on channel 2
            f"WIND2:EXP {format_number(s.exp_window_s)}",      # time constant, s
        ] + self.TRANSFER_SETUP)

    #: data formats the read methods expect (also sent with ``--keep-setup``)
    TRANSFER_SETUP = ["FORM:DATA REAL,64",     # 8-byte IEEE doubles in a # block
                      "CALC1:FORM NYQ",        # trace A as (real, imag) pairs
                      "CALC2:FORM MLIN"]       # coherence, linear magnitude

    def prepare_transfer(self) -> None:
        self.send_checked(self.TRANSFER_SETUP, "setting the data formats")

    def read_settings(self) -> AcquisitionSettings:
        q = self.query_number
        nan = math.nan
        return AcquisitionSettings(
            span_hz=q("FREQ:SPAN?"), start_hz=q("FREQ:STAR?"),
            lines=q("FREQ:RES?", integer=True), averages=q("AVER:COUN?", integer=True),
            trigger_level_pct=nan, pretrigger_s=nan, force_window_s=nan, exp_window_s=nan)

    def command_errors(self) -> list[str]:
        """Entries of the error queue (``SYST:ERR?`` until code 0), each as the analyser's text."""
        errors = []
        for _ in range(32):  # the queue is finite; never loop forever on a stuck instrument
            answer = self.transport.query("SYST:ERR?")
            code = answer.split(",", 1)[0].strip()
            try:
                if int(code) == 0:
                    return errors
            except ValueError as exc:
                raise InstrumentError(f"analyser {self.transport.resource}: the {self.MODEL} "
                                      f"answered SYST:ERR? with {answer!r}, not an error "
                                      "entry (<code>,\"<text>\")") from exc
            errors.append(answer)
        return errors

    # -------------------------------------------------------------- measuring
    def start(self) -> None:
        """Restart the averaging; ``*OPC`` sets ESR bit 0 when the measurement completes."""
        w = self.transport.write
        w("ABOR")          # ABORt: stop anything running
        w("*CLS")          # clear ESR so bit 0 means *this* measurement
        w("INIT:IMM")      # INITiate[:IMMediate]: start, wait for the trigger (hammer hits)
        w("*OPC")          # operation complete -> ESR bit 0 (polled, never blocks the bus)
        self._measuring = True

    def is_done(self) -> bool:
        return bool(self.query_number("*ESR?", integer=True) & 1)

    def overloaded_channels(self) -> tuple[int, ...]:
        """Channels that went over range during the average (STATus:QUEStionable:VOLTage)."""
        word = self.query_number("STAT:QUES:VOLT:EVEN?", integer=True)
        return tuple(ch for ch, bit in enumerate(OVERLOAD_BITS, 1) if word & bit)

    def _read_doubles(self, command: str) -> np.ndarray:
        self.transport.write(command)
        block = self.transport.read_block()
        if len(block) % 8:
            raise InstrumentError(f"{self.MODEL}: answer to {command} has {len(block)} bytes, "
                                  "not a whole number of REAL,64 values")
        return np.frombuffer(block, dtype=">f8").astype(float)

    def read_frequency(self) -> np.ndarray:
        """Frequency axis of trace A, Hz (CALCulate:X:DATA?)."""
        return self._read_doubles("CALC1:X:DATA?")

    def read_frf(self) -> np.ndarray:
        """Complex FRF ch2/ch1 (CALCulate1:DATA? in Nyquist coordinates: re, im pairs)."""
        pairs = self._read_doubles("CALC1:DATA?")
        if pairs.size % 2:
            raise InstrumentError(f"{self.MODEL}: complex trace has an odd number of values")
        return pairs[0::2] + 1j * pairs[1::2]

    def read_coherence(self) -> np.ndarray:
        return self._read_doubles("CALC2:DATA?")

    def abort(self) -> None:
        self.transport.write("ABOR")
        self._measuring = False


DRIVER = HP35670A
