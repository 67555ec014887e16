"""Loopback emulators of the HP 35670A and the SR785 for the tests (127.0.0.1 TCP only).

Each emulator is a small threaded TCP server reached through pyvisa-py as
``TCPIP::127.0.0.1::<port>::SOCKET``. It understands the commands the drivers send (and answers
unknown ones the way the instrument does: an entry in the SCPI error queue for the 35670A, the
command-error bit of ``*ESR?`` for the SR785), keeps state (span, start, lines, averages,
trigger, windows, display set-up), simulates the operator's hammer hits at a fixed interval
after each start, and serves the averaged H1 FRF and coherence of a simulated free plate in
the real binary formats (35670A: ``#`` blocks of big-endian REAL,64; SR785: ``DSPB?`` raw
little-endian 4-byte floats, no header).

The plate: modes ``PLATE_MODES`` (natural frequency Hz, damping ratio) with per-point modal
constants (roving hammer), FRFs from :func:`tests.frf_synth.synth_frf` (same formula computed
here if that module is absent); the exponential window
adds 1/tau to every pole's decay rate, as on the analyser. Per hit the force spectrum varies
(hammer) and the response gets complex Gaussian noise, so H1 = <F* Y>/<|F|^2> and the coherence
|<F* Y>|^2 / (<|F|^2> <|Y|^2>) behave as measured ones (coherence 1 for one hit, dips at
anti-resonances).

Faults (``Fault``): at a given measurement number and command the emulator can stop
answering, send a truncated block, drop the connection mid-transfer, report an error, or flag an
error while still sending the data ("flag": the trace sent is corrupt or stale, issue 15).

The 35670A emulator follows the public command evidence listed in
:mod:`laminid_cli.instrument.hp35670a` (pymeasure's Keysight35670A): it rejects a trigger source
outside IMM|EXT|INT1..INT4|OUTP|BUS with ``-224,"Illegal parameter value"``, any header it does
not know (e.g. ``TRIG:DEL1``) with ``-113,"Undefined header"``, and checks the enumerated
values of the window, average, format and feed commands the same way.
"""

from __future__ import annotations

import _thread
import math
import socket
import struct
import threading
import time
from dataclasses import dataclass

import numpy as np

try:  # the shared synthetic-FRF generator of the FRF tests
    from tests.frf_synth import synth_frf
except ImportError:  # pragma: no cover - same model, computed here
    def synth_frf(freq_hz, modes, points):
        """Receptance sum of modes: H = sum_r C_r / (w_r^2 - w^2 + 2 j zeta_r w_r w)."""
        w = 2 * np.pi * np.asarray(freq_hz, dtype=float)
        m = np.asarray(modes, dtype=float)
        wr, zr = 2 * np.pi * m[:, 0], m[:, 1]
        den = wr[:, None] ** 2 - w[None, :] ** 2 + 2j * zr[:, None] * wr[:, None] * w[None, :]
        return np.atleast_2d(points) @ (1.0 / den)

#: natural frequencies (Hz) and damping ratios of the simulated plate (all inside 0-1600 Hz)
PLATE_MODES = ((212.4, 0.008), (318.9, 0.006), (497.3, 0.007), (633.8, 0.005),
               (841.2, 0.009), (1120.6, 0.006), (1388.2, 0.007))


@dataclass(frozen=True)
class Fault:
    """Misbehave on ``command`` (exact header, upper case) during measurement ``measurement``.

    kind: "silent" (never answer again), "truncate" (send part of the block, then nothing),
    "drop" (send part of the block, then close the connection), "error" (report an error for
    the command instead of executing it: SCPI error queue / ESR execution-error bit), "flag"
    (execute it and send the data, but raise an error during the transfer: 35670A error queue
    ``-230,"Data corrupt or stale"``; SR785 ``*ESR?`` bit 4), "garbage" (answer a line that
    is no number, ``\x15#?garbage``).
    ``measurement`` 0 = before any measurement (configuration). ``times``: how often the fault
    fires (0 = every time the command comes in that measurement).
    """

    command: str
    kind: str
    measurement: int = 1
    times: int = 0


class PlateSimulator:
    """Averaged H1 and coherence of the simulated plate at a measurement point."""

    def __init__(self, modes=PLATE_MODES, noise: float = 2e-3, seed: int = 7):
        self.modes = tuple(modes)
        self.noise = noise
        self.seed = seed
        rng = np.random.default_rng(seed)
        n = len(self.modes)
        self._shape = rng.uniform(0.4, 1.0, (64, n)) * rng.choice([-1.0, 1.0], (64, n))
        self._scale = (2 * np.pi * np.array([m[0] for m in self.modes])) ** 2 * 1e-3

    def windowed_modes(self, exp_tau_s: float):
        """(freq Hz, damping) after the exponential window (decay rate + 1/tau)."""
        out = []
        for f, z in self.modes:
            w = 2 * np.pi * f
            sigma = z * w + (1.0 / exp_tau_s if exp_tau_s > 0 else 0.0)
            wd2 = w * w * (1 - z * z)
            wn = math.sqrt(sigma * sigma + wd2)
            out.append((wn / (2 * np.pi), sigma / wn))
        return out

    def average(self, freq, point: int, hits: int, exp_tau_s: float, measurement: int):
        """(H1, coherence) averaged over ``hits`` simulated hits."""
        C = self._shape[(point - 1) % len(self._shape)] * self._scale
        H = synth_frf(freq, self.windowed_modes(exp_tau_s), C)[0]
        if hits <= 0:
            return np.zeros_like(H), np.zeros(H.shape)
        rng = np.random.default_rng([self.seed, measurement])
        sigma = self.noise * float(np.max(np.abs(H)))
        sxx = np.zeros(H.shape)
        syy = np.zeros(H.shape)
        sxy = np.zeros(H.shape, dtype=complex)
        for _ in range(hits):
            force = rng.uniform(0.7, 1.3) * (1 + 0.05 * (rng.standard_normal(H.shape)
                                                         + 1j * rng.standard_normal(H.shape)))
            resp = H * force + sigma * (rng.standard_normal(H.shape)
                                        + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
            sxx += np.abs(force) ** 2
            syy += np.abs(resp) ** 2
            sxy += np.conj(force) * resp
        h1 = sxy / sxx
        coh = np.abs(sxy) ** 2 / (sxx * syy)
        return h1, np.clip(coh, 0.0, 1.0)


def _number(text: str) -> float:
    return float(text.strip().split()[0])


class _Silent(Exception):
    """Stop answering from now on."""


class _Drop(Exception):
    """Close the connection now."""


class EmulatorBase:
    """TCP server plumbing, hit timing and fault injection shared by both emulators."""

    IDN = ""

    #: the status-word bits of an input over range, (channel 1, channel 2): the instrument's
    #: own (each emulator sets them from its manual)
    OVERLOAD_BITS = (0, 0)

    def __init__(self, plate: PlateSimulator | None = None, hit_interval_s: float = 0.01,
                 faults=(), idn: str | None = None, overloads=None):
        self.plate = plate or PlateSimulator()
        self.hit_interval_s = hit_interval_s
        self.faults = list(faults)
        # {measurement number: channels over range during it} (1 hammer, 2 response): the
        # input status word flags them until it is read
        self.overloads = {int(k): tuple(v) for k, v in (overloads or {}).items()}
        self.idn = idn or self.IDN
        self.log: list[str] = []
        self.measurement = 0          # number of starts seen
        self.point = 0                # roving-hammer point = measurement index
        self.measuring = False
        self.t_start = 0.0
        self.overload_word = 0
        self.silent = False
        self._fired: dict = {}
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._sock.bind(("127.0.0.1", 0))
        self._sock.listen(4)
        self._sock.settimeout(0.2)
        self.port = self._sock.getsockname()[1]
        self._hits_final = 0
        self._stop = threading.Event()
        self._stopped = threading.Event()
        self._conns: set = set()
        self.reset()

    # ------------------------------------------------------------ lifecycle
    @property
    def resource(self) -> str:
        return f"TCPIP::127.0.0.1::{self.port}::SOCKET"

    def start(self):
        """Serve from a thread of the ``_thread`` module, which ``threading`` does not list: a
        real analyser is another machine, so laminid's process has one Python thread, and its
        HDF5 probe forks (laminid_cli.frf.store._fork_is_safe) as it does in the field. A
        ``threading.Thread`` made every probe of a run beside an emulator (``acquire
        --resume`` reading its file) start a new interpreter instead: 36 probes of
        test_acquire_cli.py, ~0.3 s each against ~0.03 s. The server takes no lock the
        probe's child could need (no logging, no h5py)."""
        _thread.start_new_thread(self._serve_until_stopped, ())
        return self

    def _serve_until_stopped(self):
        try:
            self._serve()
        finally:
            self._stopped.set()

    def stop(self):
        """Stop serving at once: shutting the sockets down wakes the server thread's accept()
        or recv() now instead of at its next 0.2 s timeout."""
        self._stop.set()
        for sock in (self._sock, *self._conns):
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        self._stopped.wait(timeout=2)
        self._sock.close()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
        return False

    def _serve(self):
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except (socket.timeout, OSError):
                continue
            with conn:
                conn.settimeout(0.2)
                self._conns.add(conn)
                try:
                    self._handle(conn)
                finally:
                    self._conns.discard(conn)

    def _handle(self, conn):
        buf = b""
        while not self._stop.is_set():
            try:
                data = conn.recv(65536)
            except socket.timeout:
                continue
            except OSError:
                return
            if not data:
                return
            buf += data
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                for command in line.decode(errors="replace").split(";"):
                    command = command.strip()
                    if not command:
                        continue
                    self.log.append(command)
                    if self.silent:
                        continue
                    try:
                        answer = self.dispatch(command)
                    except _Silent:
                        self.silent = True
                        continue
                    except _Drop as drop:
                        try:
                            conn.sendall(drop.args[0] if drop.args else b"")
                        finally:
                            conn.shutdown(socket.SHUT_RDWR)
                        return
                    if answer is not None:
                        try:
                            conn.sendall(answer)
                        except OSError:
                            return

    # ---------------------------------------------------------- simulation
    def hits_done(self) -> int:
        if self.measurement == 0:
            return 0
        if not self.measuring:
            return self._hits_final
        n = int((time.monotonic() - self.t_start) / self.hit_interval_s)
        return min(n, self.averages)

    def begin_measurement(self):
        self.measurement += 1
        self.point = self.measurement
        self.measuring = True
        self._hits_final = 0
        self.t_start = time.monotonic()
        for channel in self.overloads.get(self.measurement, ()):
            self.overload_word |= self.OVERLOAD_BITS[channel - 1]

    def end_measurement(self):
        if self.measuring:
            self._hits_final = self.hits_done()
            self.measuring = False

    def averaging_complete(self) -> bool:
        if self.measuring and self.hits_done() >= self.averages:
            self.end_measurement()
            self._hits_final = self.averages
            return True
        return not self.measuring and self.measurement > 0 and self._hits_final >= self.averages

    def freq_axis(self) -> np.ndarray:
        return self.start_hz + np.arange(self.lines + 1) * (self.span_hz / self.lines)

    def data(self):
        return self.plate.average(self.freq_axis(), max(self.point, 1), self.hits_done(),
                                  self.exp_tau_s(), self.measurement)

    def exp_tau_s(self) -> float:  # pragma: no cover - overridden
        return 0.0

    def fault_for(self, header: str, command: str = ""):
        """The fault for this command: ``Fault.command`` is a header ("DSPB?") or a whole
        command as sent ("DSPB? 1")."""
        for f in self.faults:
            if f.command in (header, command.upper()) and f.measurement == self.measurement:
                n = self._fired.get(f, 0)
                if f.times and n >= f.times:
                    continue
                self._fired[f] = n + 1
                return f
        return None

    def apply_fault(self, fault: Fault, payload: bytes | None):
        """Raise/return according to the fault; returns the payload to send (or None)."""
        if fault.kind == "silent":
            raise _Silent()
        if fault.kind == "truncate":
            self.silent = True
            return payload[: max(len(payload) // 3, 1)]
        if fault.kind == "drop":
            raise _Drop(payload[: max(len(payload) // 3, 1)])
        if fault.kind == "garbage":         # a line noise / another talker's text
            return b"\x15#?garbage\n"
        return payload


class HP35670AEmulator(EmulatorBase):
    """The 35670A subset the driver uses (SCPI, error queue, REAL,64 blocks)."""

    IDN = "HEWLETT-PACKARD,35670A,0,A.02.01"
    # STATus:QUEStionable:VOLTage: bit 0 channel 1 over range, bit 1 channel 2 (the manual's
    # Questionable Voltage Register Set, as laminid_cli.instrument.hp35670a.OVERLOAD_BITS)
    OVERLOAD_BITS = (1 << 0, 1 << 1)
    SPANS = tuple(51200.0 / 2 ** k for k in range(19))
    LINES = (100, 200, 400, 800)
    # enumerated values (pymeasure Keysight35670A tables)
    TRIGGER_SOURCES = {"IMM", "EXT", "INT1", "INT2", "INT3", "INT4", "OUTP", "BUS"}
    WINDOW_TYPES = {"HANN", "FLAT", "UNIF", "FORC", "EXP", "LAG", "LLAG"}
    AVERAGE_TYPES = {"MAX", "RMS", "TIME", "VECT", "ECON"}
    MODES = {"FFT", "CORR", "HIST", "OCT", "ORD", "SINE"}
    CALC_FORMATS = {"MLIN", "MLOG", "PHAS", "REAL", "IMAG", "NYQ", "UPH", "GDEL", "POL"}
    FEEDS = {"XFR:POW:RAT 2,1", "XFR:POW:COH 1,2", "XFR:POW 1", "XFR:POW 2"}
    BOOLEAN = {"0": 0, "1": 1, "ON": 1, "OFF": 0}

    def reset(self):
        self.span_hz, self.start_hz, self.lines, self.averages = 51200.0, 0.0, 400, 1
        self.settings = {}
        self.errors: list[str] = []
        self.esr = 0
        self.opc_armed = False
        self.form = "ASC"
        self.calc_form = {1: "MLIN", 2: "MLIN"}
        self.feed = {}

    def exp_tau_s(self):
        return float(self.settings.get("WIND2:EXP", 0.0)) \
            if self.settings.get("WIND2:TYPE") == "EXP" else 0.0

    def _error(self, text):
        self.errors.append(text)

    def _block(self, values) -> bytes:
        values = np.asarray(values, dtype=float)
        if self.form == "REAL,64":
            payload = struct.pack(f">{values.size}d", *values)
            length = str(len(payload)).encode()
            return b"#" + str(len(length)).encode() + length + payload + b"\n"
        return (",".join(f"{v:.10E}" for v in values) + "\n").encode()

    def dispatch(self, command: str):
        header, _, arg = command.partition(" ")
        header = header.upper()
        for root in ("SENSE:", "SENS:"):      # [SENSe:] is the optional root
            if header.startswith(root):
                header = header[len(root):]
        fault = self.fault_for(header, command)
        if fault is not None and fault.kind == "error":
            self._error('-222,"Data out of range"')
            return None
        answer = self._dispatch(header, arg.strip())
        if fault is not None and fault.kind == "flag":
            self._error('-230,"Data corrupt or stale"')
            return answer
        if fault is not None:
            return self.apply_fault(fault, answer)
        return answer

    def _illegal(self):
        self._error('-224,"Illegal parameter value"')

    def _number(self, arg, suffixes=()):
        """Number with an optional unit suffix; None (and -131 Invalid suffix) otherwise."""
        parts = arg.split()
        try:
            value = float(parts[0])
        except (ValueError, IndexError):
            self._error('-104,"Data type error"')
            return None
        if len(parts) > 1 and parts[1].upper() not in suffixes:
            self._error('-131,"Invalid suffix"')
            return None
        return value

    def _choice(self, header, arg, allowed):
        value = arg.upper()
        if value not in allowed:
            self._illegal()
        else:
            self.settings[header] = value

    def _dispatch(self, header, arg):
        if header == "*IDN?":
            return (self.idn + "\n").encode()
        if header == "*CLS":
            self.esr, self.errors, self.opc_armed = 0, [], False
            return None
        if header == "*OPC":
            self.opc_armed = True
            return None
        if header == "*ESR?":
            if self.opc_armed and self.averaging_complete():
                self.esr |= 1
                self.opc_armed = False
            value, self.esr = self.esr, 0
            return f"+{value}\n".encode()
        if header == "SYST:ERR?":
            return ((self.errors.pop(0) if self.errors else '+0,"No error"') + "\n").encode()
        if header == "INST:SEL":
            return self._choice(header, arg, self.MODES)
        if header == "INST:NSEL":
            v = self._number(arg)
            if v is not None and not (0 <= v <= 5 and v == int(v)):
                self._illegal()
            return None
        if header in ("INP2", "INP2:STAT", "AVER:STAT"):
            return self._choice(header, arg, self.BOOLEAN)
        if header == "AVER:TYPE":
            return self._choice(header, arg, self.AVERAGE_TYPES)
        if header == "TRIG:SOUR":
            return self._choice(header, arg, self.TRIGGER_SOURCES)
        if header == "TRIG:SLOP":
            return self._choice(header, arg, {"POS", "NEG"})
        if header in ("WIND1:TYPE", "WIND2:TYPE"):
            return self._choice(header, arg, self.WINDOW_TYPES)
        if header in ("CALC1:FEED", "CALC2:FEED"):
            feed = arg.strip("'\"")
            if feed not in self.FEEDS:
                self._illegal()
            else:
                self.feed[int(header[4])] = feed
            return None
        if header in ("CALC1:FORM", "CALC2:FORM"):
            if arg.upper() not in self.CALC_FORMATS:
                self._illegal()
            else:
                self.calc_form[int(header[4])] = arg.upper()
            return None
        if header == "TRIG:LEV":
            v = self._number(arg, ("PCT", "V"))
            if v is not None:
                self.settings[header] = v
            return None
        if header in ("TRIG:STAR1", "TRIG:STAR2", "WIND1:FORC", "WIND2:EXP", "WIND1:EXP",
                      "WIND2:FORC"):
            v = self._number(arg, ("S",))
            if v is not None:
                self.settings[header] = v
            return None
        if header == "FREQ:SPAN":
            v = self._number(arg, ("HZ",))
            if v is not None and not any(math.isclose(v, s, rel_tol=1e-9) for s in self.SPANS):
                self._error('-222,"Data out of range"')
            elif v is not None:
                self.span_hz = v
            return None
        if header == "FREQ:STAR":
            v = self._number(arg, ("HZ",))
            if v is not None:
                self.start_hz = v
            return None
        if header == "FREQ:RES":
            v = self._number(arg)
            if v is not None and int(v) not in self.LINES:
                self._error('-222,"Data out of range"')
            elif v is not None:
                self.lines = int(v)
            return None
        if header == "AVER:COUN":
            v = self._number(arg)
            if v is not None:
                self.averages = int(v)
            return None
        if header == "FORM:DATA":
            form = arg.upper().replace(" ", "")
            if form not in ("ASC", "REAL", "REAL,32", "REAL,64", "ASC,12"):
                self._illegal()
            else:
                self.form = "REAL,64" if form == "REAL" else form
            return None
        if header == "ABOR":
            self.end_measurement()
            return None
        if header == "INIT:IMM":
            self.begin_measurement()
            return None
        if header == "STAT:QUES:VOLT:EVEN?":
            value, self.overload_word = self.overload_word, 0
            return f"+{value}\n".encode()
        if header == "FREQ:SPAN?":
            return f"{self.span_hz:.10E}\n".encode()
        if header == "FREQ:STAR?":
            return f"{self.start_hz:.10E}\n".encode()
        if header == "FREQ:RES?":
            return f"+{self.lines}\n".encode()
        if header == "AVER:COUN?":
            return f"+{self.averages}\n".encode()
        if header == "CALC1:X:DATA?":
            return self._block(self.freq_axis())
        if header in ("CALC1:DATA?", "CALC2:DATA?"):
            h1, coh = self.data()
            trace = 1 if header.startswith("CALC1") else 2
            feed = self.feed.get(trace, "")
            values = h1 if "RAT" in feed else coh
            if self.calc_form[trace] == "NYQ":
                values = np.column_stack([np.real(values), np.imag(values)]).ravel()
            else:
                values = np.abs(values)
            return self._block(values)
        self._error(f'-113,"Undefined header; {header}"')
        return None


class SR785Emulator(EmulatorBase):
    """The SR785 subset the driver uses (four-letter commands, ESR bits, DSPB raw floats)."""

    IDN = "Stanford_Research_Systems,SR785,s/n00001,ver116"
    # INPS? input status word: bit 2 channel 1 overload, bit 10 channel 2 (as
    # laminid_cli.instrument.sr785.INPS_OVERLOAD_BITS; on the SR785 unconfirmed, see there)
    OVERLOAD_BITS = (1 << 2, 1 << 10)
    SPANS = tuple(102400.0 / 2 ** k for k in range(20))
    LINES = (100, 200, 400, 800)

    def reset(self):
        self.span_hz, self.start_hz, self.lines, self.averages = 102400.0, 0.0, 400, 1
        self.settings = {}
        self.esr = 0
        self.errs = 0
        self.dsps = 0
        self.meas = {0: 0, 1: 0}
        self.view = {0: 0, 1: 0}
        # per-channel choice in the force/exponential window (0 force, 1 exponential); the
        # real power-on value is not known, so the emulator starts with force on both and the
        # response is windowed only when the driver sets W2FE 1
        self.wfe = {1: 0, 2: 0}

    def exp_tau_s(self):
        if self.settings.get("FWIN") != 5 or self.wfe[2] != 1:
            return 0.0
        return float(self.settings.get("FWTC", 0.0)) / 100.0 * self.lines / self.span_hz

    def dispatch(self, command: str):
        header, _, arg = command.partition(" ")
        header = header.upper()
        if header.endswith("?") is False and "?" in header:  # e.g. "DSPS?1"
            header, arg = header.split("?", 1)[0] + "?", header.split("?", 1)[1] + arg
        fault = self.fault_for(header, command)
        if fault is not None and fault.kind == "error":
            self.esr |= 1 << 4
            return None
        args = [a.strip() for a in arg.split(",")] if arg.strip() else []
        try:
            answer = self._dispatch(header, args)
        except (ValueError, IndexError):   # missing or malformed argument
            self.esr |= 1 << 5
            return None
        if fault is not None and fault.kind == "flag":
            self.esr |= 1 << 4          # execution error: the data sent are not good
            return answer
        if fault is not None:
            return self.apply_fault(fault, answer)
        return answer

    def _displays(self, d):
        return (0, 1) if int(d) == 2 else (int(d),)

    def _dispatch(self, header, args):
        exe_error = False
        if header == "*IDN?":
            return (self.idn + "\n").encode()
        if header == "*CLS":
            self.esr, self.dsps = 0, 0
            return None
        if header == "*ESR?":
            value, self.esr = self.esr, 0
            return f"{value}\n".encode()
        if header == "ERRS?":
            value, self.errs = self.errs, 0
            return f"{value}\n".encode()
        if header in ("MEAS", "VIEW"):
            table = self.meas if header == "MEAS" else self.view
            for d in self._displays(args[0]):
                table[d] = int(args[1])
            return None
        if header == "FBAS" and args[1] not in ("0", "1"):   # 0 = 100 kHz, 1 = 102.4 kHz
            exe_error = True
        elif header in ("MGRP", "FBAS", "FAVG", "FAVM", "FAVT", "FWIN"):
            self.settings[header] = int(args[1])
        elif header in ("FWFL", "FWTC"):
            self.settings[header] = float(args[1])
        elif header in ("W1FE", "W2FE"):
            if len(args) != 1 or args[0] not in ("0", "1"):
                exe_error = True
            else:
                self.wfe[int(header[1])] = int(args[0])
        elif header == "FSPN":
            v = float(args[1])
            if any(math.isclose(v, s, rel_tol=1e-9) for s in self.SPANS):
                self.span_hz = v
            else:
                exe_error = True
        elif header == "FLIN":
            i = int(args[1])
            if 0 <= i < len(self.LINES):
                self.lines = self.LINES[i]
            else:
                exe_error = True
        elif header == "FSTR":
            self.start_hz = float(args[1])
        elif header == "FAVN":
            self.averages = int(args[1])
        elif header == "TSRC" and (len(args) != 1 or not 0 <= int(args[0]) <= 6):
            exe_error = True
        elif header in ("TSRC", "TMOD", "TSLP"):
            self.settings[header] = int(args[0])
        elif header in ("TLVL", "TDLA", "TDLB"):
            self.settings[header] = float(args[0])
        elif header == "STRT":
            self.begin_measurement()
        elif header == "PAUS":
            self.end_measurement()
        elif header == "DSPS?":
            if self.averaging_complete():
                self.dsps |= 1 << 1
            if args:
                bit = int(args[0])
                value = (self.dsps >> bit) & 1
                self.dsps &= ~(1 << bit)
            else:
                value, self.dsps = self.dsps, 0
            return f"{value}\n".encode()
        elif header == "NAVG?":
            return f"{self.hits_done()}\n".encode()
        elif header == "INPS?":
            value, self.overload_word = self.overload_word, 0
            return f"{value}\n".encode()
        elif header == "FSPN?":
            return f"{self.span_hz:g}\n".encode()
        elif header == "FSTR?":
            return f"{self.start_hz:g}\n".encode()
        elif header == "FLIN?":
            return f"{self.LINES.index(self.lines)}\n".encode()
        elif header == "FAVN?":
            return f"{self.averages}\n".encode()
        elif header == "TLVL?":
            return f"{self.settings.get('TLVL', 0.0):g}\n".encode()
        elif header == "DSPN?":
            return f"{self.lines + 1}\n".encode()
        elif header == "DSPB?":
            d = int(args[0])
            h1, coh = self.data()
            values = h1 if self.meas[d] == 11 else coh
            if self.view[d] == 7:
                values = np.column_stack([np.imag(values), np.real(values)]).ravel()
            else:
                values = np.abs(values)
            return struct.pack(f"<{values.size}f", *values)   # no header, no terminator
        else:
            self.esr |= 1 << 5
            return None
        if exe_error:
            self.esr |= 1 << 4
        return None
