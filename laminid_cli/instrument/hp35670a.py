"""HP / Agilent / Keysight 35670A Dynamic Signal Analyzer (SCPI over GPIB).

Command source: *HP 35670A Dynamic Signal Analyzer — GPIB Commands* (the command reference /
Quick Reference of the 35670A), subsystem named in each comment; IEEE 488.2 common commands
(``*IDN?``, ``*CLS``, ``*OPC``, ``*ESR?``) and the definite-length block format (IEEE 488.2
section 8.7.9) are standard. Mnemonics are sent in their short form.

Measurement (paper section 3): FFT instrument mode, two channels, trace A = frequency response
ch2/ch1 (``XFR:POW:RAT 2,1``), trace B = coherence (``XFR:POW:COH 1,2``), RMS (power)
averaging so trace A is H1 = <G21>/<G11>, channel-1 trigger with negative delay (pre-trigger),
force window on channel 1, exponential window on channel 2. Data are read as
``FORM:DATA REAL,64`` blocks: IEEE 754 doubles, big-endian (the 35670A's byte order); trace A
in Nyquist coordinates gives (real, imag) pairs.

Points to confirm on the first real instrument (opt-in hardware test, ``LAMINID_ANALYSER``):
the overload bits of the Questionable Voltage register and the unit of ``TRIG:LEV``; both are
isolated in constants below.
"""

from __future__ import annotations

import math

import numpy as np

from laminid_cli.errors import InstrumentError
from laminid_cli.instrument.base import AcquisitionSettings, Analyser, format_number

#: two-channel FFT spans: 51.2 kHz / 2**k (35670A GPIB Commands, [SENSe:]FREQuency:SPAN)
SPANS_HZ = tuple(51200.0 / 2 ** k for k in range(19))
#: resolution lines ([SENSe:]FREQuency:RESolution); two-channel measurements offer up to 800
#: (cross-checked with a working public 35670A driver, which accepts only 100-800)
LINES = (100, 200, 400, 800)
#: STATus:QUEStionable:VOLTage bits meaning "channel over range" (ch1, ch2)
OVERLOAD_BITS = (1 << 0, 1 << 2)


class HP35670A(Analyser):
    """Driver of the HP/Agilent/Keysight 35670A (two-channel FFT, SCPI).

    >>> HP35670A.matches("HEWLETT-PACKARD,35670A,0,A.02.01")
    True
    """

    MODEL = "35670A"
    MANUAL = "HP/Agilent 35670A GPIB Commands reference"
    SPANS_HZ = SPANS_HZ
    LINES = LINES
    MAX_FREQ_HZ = 51200.0

    @classmethod
    def matches(cls, idn: str) -> bool:
        fields = [f.strip().upper() for f in idn.split(",")]
        return len(fields) >= 2 and fields[1] == "35670A"

    # ------------------------------------------------------------------ set-up
    def configure(self, settings: AcquisitionSettings) -> None:
        """Send the whole impact-test set-up, then check the error queue."""
        self.validate(settings)
        s = settings
        w = self.transport.write
        w("*CLS")                                   # IEEE 488.2: clear status + error queue
        w("INST:NSEL 0")                            # INSTrument:NSELect 0 = FFT analysis mode
                                                    # (cross-checked with a working driver)
        w("INP2 ON")                                # INPut2[:STATe]     (two channels)
        w("CALC1:FEED 'XFR:POW:RAT 2,1'")           # CALCulate:FEED     trace A = H = ch2/ch1
        w("CALC2:FEED 'XFR:POW:COH 1,2'")           # CALCulate:FEED     trace B = coherence
        w(f"FREQ:SPAN {format_number(s.span_hz)} HZ")    # [SENSe:]FREQuency:SPAN
        w(f"FREQ:STAR {format_number(s.start_hz)} HZ")   # [SENSe:]FREQuency:STARt
        w(f"FREQ:RES {s.lines}")                         # [SENSe:]FREQuency:RESolution (lines)
        w("AVER:STAT ON")                           # [SENSe:]AVERage:STATe
        w("AVER:TYPE RMS")                          # [SENSe:]AVERage:TYPE (power avg -> H1)
        w(f"AVER:COUN {s.averages}")                # [SENSe:]AVERage:COUNt
        w("TRIG:SOUR INP1")                         # TRIGger:SOURce  channel 1 (hammer)
        w("TRIG:SLOP POS")                          # TRIGger:SLOPe
        w(f"TRIG:LEV {format_number(s.trigger_level_pct)} PCT")  # TRIGger:LEVel, % of range
        delay = format_number(-s.pretrigger_s)
        w(f"TRIG:DEL1 {delay} S")                   # TRIGger:DELay1 (<0 = pre-trigger)
        w(f"TRIG:DEL2 {delay} S")                   # TRIGger:DELay2
        w("WIND1:TYPE FORC")                        # [SENSe:]WINDow1:TYPE  force (ch1)
        w(f"WIND1:FORC {format_number(s.force_window_s)} S")   # [SENSe:]WINDow:FORCe width
        w("WIND2:TYPE EXP")                         # [SENSe:]WINDow2:TYPE  exponential (ch2)
        w(f"WIND2:EXP {format_number(s.exp_window_s)} S")      # [SENSe:]WINDow:EXPonential tau
        self.prepare_transfer()
        self.check_errors()

    def prepare_transfer(self) -> None:
        w = self.transport.write
        w("FORM:DATA REAL,64")      # FORMat[:DATA] REAL,64: 8-byte IEEE doubles in a # block
        w("CALC1:FORM NYQ")         # CALCulate:FORMat NYQuist: trace A as (real, imag) pairs
        w("CALC2:FORM MLIN")        # CALCulate:FORMat MLINear: coherence, linear magnitude

    def read_settings(self) -> AcquisitionSettings:
        q = self.transport.query
        nan = math.nan
        return AcquisitionSettings(
            span_hz=float(q("FREQ:SPAN?")), start_hz=float(q("FREQ:STAR?")),
            lines=int(float(q("FREQ:RES?"))), averages=int(float(q("AVER:COUN?"))),
            trigger_level_pct=nan, pretrigger_s=nan, force_window_s=nan, exp_window_s=nan)

    def check_errors(self) -> None:
        """Read SYSTem:ERRor? until '+0,"No error"'; raise InstrumentError listing the rest."""
        errors = []
        for _ in range(32):  # the queue is finite; never loop forever on a stuck instrument
            answer = self.transport.query("SYST:ERR?")
            code = answer.split(",", 1)[0].strip()
            try:
                if int(code) == 0:
                    break
            except ValueError as exc:
                raise InstrumentError(f"{self.MODEL}: unexpected answer to SYST:ERR?: "
                                      f"{answer!r}") from exc
            errors.append(answer)
        if errors:
            raise InstrumentError(f"{self.MODEL} reported error(s) after configuring: "
                                  + "; ".join(errors))

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
        return bool(int(self.transport.query("*ESR?")) & 1)

    def overloads(self) -> int:
        """Channels that went over range during the average (STATus:QUEStionable:VOLTage)."""
        word = int(self.transport.query("STAT:QUES:VOLT:EVEN?"))
        return sum(1 for bit in OVERLOAD_BITS if word & bit)

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
