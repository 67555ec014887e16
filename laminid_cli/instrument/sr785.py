"""Stanford Research Systems SR785 Dynamic Signal Analyzer (its own four-letter command set).

Command source: *SR785 Dynamic Signal Analyzer, Operating Manual and Programming Reference*
(SRS, rev. 1.5, 2017), chapter 5 "Programming": Command Syntax (p. 5-25: ``d`` = display,
0 = A, 1 = B, 2 = both; default units Hz and s), Frequency, Display Setup, Window, Average
(p. 5-69 ff., ``NAVG?``), Input and Trigger commands, Data Transfer commands (p. 5-107/108:
``DSPN? d`` length of a display, ``DSPB? d`` binary display data: 4-byte IEEE floats, no header
and no terminator, so the byte count must be known first; 2-D views such as Nyquist return two
floats per bin, Y value first, then X) and Status Word Definitions (p. 5-124: reading a status
word clears it; standard event bits 4 = execution error, 5 = command error).

Measurement (paper section 3): display A = frequency response (ch2/ch1) in Nyquist view, so
one DSPB? transfer gives (imag, real) pairs; display B = coherence; RMS averaging (H1),
channel-1 trigger with negative delay, force/exponential window. Floats arrive least
significant byte first (little-endian), as in the manual's binary transfers.

``DSPB?`` exists only on the GPIB interface (manual p. 5-108): use a GPIB resource (or a
GPIB-LAN gateway), not the RS-232 port. The test emulator serves it over a TCP socket.

Points to confirm on the first real instrument (opt-in hardware test): the measurement/view/
window index tables and the input-status overload bits, isolated in the constants below.
"""

from __future__ import annotations

import math

import numpy as np

from laminid_cli.errors import InstrumentError
from laminid_cli.instrument.base import AcquisitionSettings, Analyser, format_number

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
#: Average commands: FAVM 2 = RMS, FAVT 0 = linear (fixed length)
FAVM_RMS = 2
FAVT_LINEAR = 0
#: Trigger commands: TSRC 1 = channel 1
TSRC_CH1 = 1
#: Display status word bit: averaging complete on display A
DSPS_AVGA = 1
#: Input status word bits: channel 1 / channel 2 overload
INPS_OVERLOAD_BITS = (1 << 2, 1 << 10)
#: standard event status: execution error, command error
ESR_ERRORS = {4: "execution error (parameter out of range or not allowed now)",
              5: "command error (unknown command or bad syntax)"}


class SR785(Analyser):
    """Driver of the SRS SR785 (two-channel FFT).

    >>> SR785.matches("Stanford_Research_Systems,SR785,s/n12345,ver116")
    True
    """

    MODEL = "SR785"
    MANUAL = "SRS SR785 Operating Manual and Programming Reference, ch. 5"
    SPANS_HZ = SPANS_HZ
    LINES = LINES
    MAX_FREQ_HZ = 102400.0

    @classmethod
    def matches(cls, idn: str) -> bool:
        fields = [f.strip().upper() for f in idn.split(",")]
        return len(fields) >= 2 and fields[1] == "SR785"

    # ------------------------------------------------------------------ set-up
    def configure(self, settings: AcquisitionSettings) -> None:
        self.validate(settings)
        s = settings
        w = self.transport.write
        w("*CLS")                                        # clear status words
        w(f"MGRP 2,{MGRP_FFT}")                          # Display Setup: FFT group, both
        w(f"MEAS 0,{MEAS_FREQ_RESPONSE}")                # display A: frequency response
        w(f"MEAS 1,{MEAS_COHERENCE}")                    # display B: coherence
        w("FBAS 2,1")                                    # Frequency: base 102.4 kHz
        w(f"FSPN 2,{format_number(s.span_hz)}")          # Frequency: span, Hz
        w(f"FLIN 2,{LINES.index(s.lines)}")              # Frequency: resolution (index)
        w(f"FSTR 2,{format_number(s.start_hz)}")         # Frequency: start, Hz
        w("FAVG 2,1")                                    # Average: on
        w(f"FAVM 2,{FAVM_RMS}")                          # Average: RMS (H1)
        w(f"FAVT 2,{FAVT_LINEAR}")                       # Average: linear, fixed length
        w(f"FAVN 2,{s.averages}")                        # Average: number of averages
        w(f"FWIN 2,{FWIN_FORCE_EXP}")                    # Window: force/exponential
        w(f"FWFL 2,{format_number(s.force_window_s)}")   # Window: force length, s
        pct = 100.0 * s.exp_window_s / s.record_s
        w(f"FWTC 2,{format_number(pct)}")                # Window: expo time constant, % of T
        w(f"TSRC {TSRC_CH1}")                            # Trigger: source channel 1
        w("TMOD 0")                                      # Trigger: auto arm
        w("TSLP 0")                                      # Trigger: rising slope
        w(f"TLVL {format_number(s.trigger_level_pct)}")  # Trigger: level, % of input range
        delay = format_number(-s.pretrigger_s)
        w(f"TDLA {delay}")                               # Trigger: ch1 delay (<0 pre-trigger)
        w(f"TDLB {delay}")                               # Trigger: ch2 delay
        self.prepare_transfer()
        self.check_errors()

    def prepare_transfer(self) -> None:
        w = self.transport.write
        w(f"VIEW 0,{VIEW_NYQUIST}")       # display A as Nyquist: DSPB? gives (Y=im, X=re)
        w(f"VIEW 1,{VIEW_LINEAR_MAG}")    # display B: coherence, linear

    def read_settings(self) -> AcquisitionSettings:
        q = self.transport.query
        nan = math.nan
        return AcquisitionSettings(
            span_hz=float(q("FSPN? 0")), start_hz=float(q("FSTR? 0")),
            lines=LINES[int(q("FLIN? 0"))], averages=int(float(q("FAVN? 0"))),
            trigger_level_pct=float(q("TLVL?")), pretrigger_s=nan, force_window_s=nan,
            exp_window_s=nan)

    def check_errors(self) -> None:
        """Standard event status (``*ESR?``): command / execution error bits."""
        word = int(self.transport.query("*ESR?"))
        found = [text for bit, text in ESR_ERRORS.items() if word & (1 << bit)]
        if found:
            raise InstrumentError(f"{self.MODEL} reported after configuring: "
                                  + "; ".join(found) + f" (*ESR? = {word})")

    # -------------------------------------------------------------- measuring
    def start(self) -> None:
        self.transport.query("DSPS?")     # reading the display status word clears it
        self.transport.write("STRT")      # start (restart) the measurement and averaging
        self._measuring = True

    def is_done(self) -> bool:
        return self.transport.query(f"DSPS? {DSPS_AVGA}").strip() == "1"

    def hits_done(self) -> int:
        return int(float(self.transport.query("NAVG? 0")))

    def overloads(self) -> int:
        word = int(self.transport.query("INPS?"))
        return sum(1 for bit in INPS_OVERLOAD_BITS if word & bit)

    def _display_length(self, display: int) -> int:
        n = int(self.transport.query(f"DSPN? {display}"))
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
        q = self.transport.query
        start = float(q("FSTR? 0"))
        span = float(q("FSPN? 0"))
        lines = LINES[int(q("FLIN? 0"))]
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
