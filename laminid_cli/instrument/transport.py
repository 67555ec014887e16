"""Byte transport to an analyser, separate from the drivers (as pymeasure's adapters).

A driver talks only to the :class:`Transport` protocol: ``write``, ``query``, ``read``,
``read_bytes(n)``, ``read_block()`` (IEEE 488.2 definite-length block), ``timeout`` and
``close``. :class:`VisaTransport` implements it with pyvisa (pyvisa-py backend ``"@py"`` by
default, NI-VISA ``"@ivi"`` or pyvisa-sim ``"file.yaml@sim"`` when asked);
:class:`laminid_cli.instrument.testing.ScriptedTransport` implements it for tests.

Every failure of the link (timeout, lost connection, truncated block) is raised as
:class:`~laminid_cli.errors.InstrumentError` (exit 1) with the command that was running; a
resource string that VISA cannot parse or find is an :class:`AnalyserSetupError` (exit 2).

pyvisa is imported inside :func:`open_transport` so importing this module stays cheap.
"""

from __future__ import annotations

import logging
import math
import os
import re
import socket
from typing import Protocol, runtime_checkable

from laminid_cli.errors import InstrumentError, LaminidError

log = logging.getLogger(__name__)

DEFAULT_BACKEND = "@py"
BACKEND_ENV = "LAMINID_VISA_BACKEND"
DEFAULT_TIMEOUT_S = 5.0
#: longest timeout VISA can set (2^32 - 2 ms, about 49.7 days); the shortest it can is 1 ms
MAX_TIMEOUT_S = 4294967.294


class AnalyserSetupError(LaminidError):
    """Bad input for an analyser: resource string, model, span, lines... (exit 2)."""

    exit_code = 2


def check_timeout(seconds: float) -> float:
    """``seconds`` if VISA can wait that long, else :class:`AnalyserSetupError` naming --timeout."""
    if not (math.isfinite(seconds) and 0 < seconds <= MAX_TIMEOUT_S):
        raise AnalyserSetupError(f"--timeout {seconds:g} s: must be above 0 and at most "
                                 f"{MAX_TIMEOUT_S:.0f} s (about 49.7 days, VISA's longest timeout)")
    return seconds


@runtime_checkable
class Transport(Protocol):
    """What a driver needs from the link to the instrument."""

    resource: str
    timeout: float  # seconds

    def write(self, command: str) -> None: ...

    def read(self) -> str: ...

    def query(self, command: str) -> str: ...

    def read_bytes(self, n: int) -> bytes: ...

    def read_block(self) -> bytes: ...

    def close(self) -> None: ...


def normalise_resource(resource: str) -> str:
    """Complete a VISA resource string as users write it.

    ``GPIB0::5`` and ``GPIB::5`` become ``GPIB0::5::INSTR``; ``TCPIP::host::5025::SOCKET`` and
    full strings are kept. Raises :class:`AnalyserSetupError` for a string VISA cannot parse.

    >>> normalise_resource("GPIB0::5")
    'GPIB0::5::INSTR'
    >>> normalise_resource("gpib::7")
    'GPIB0::7::INSTR'
    """
    text = resource.strip()
    m = re.fullmatch(r"(?i)gpib(\d*)::(\d+)(?:::(\d+))?", text)
    if m:
        board = m.group(1) or "0"
        sec = f"::{m.group(3)}" if m.group(3) else ""
        text = f"GPIB{board}::{m.group(2)}{sec}::INSTR"
    try:
        from pyvisa import rname

        parsed = rname.parse_resource_name(text)
        if getattr(parsed, "resource_class", "") == "SOCKET" and not str(parsed.port).isdigit():
            raise ValueError(f"port {parsed.port!r} is not a number")
    except Exception as exc:  # pyvisa raises InvalidResourceName (a ValueError) or others
        raise AnalyserSetupError(
            f"analyser resource {resource!r} is not a VISA resource string ({exc}); write e.g. "
            "GPIB0::5, GPIB0::5::INSTR, TCPIP::192.168.0.7::5025::SOCKET or "
            "TCPIP::192.168.0.7::INSTR") from exc
    return str(parsed)


def parse_block_header(head: bytes) -> tuple[int, int]:
    """Parse the start of an IEEE 488.2 definite-length block ``#<n><len>``.

    Returns (header length, payload byte count). Raises :class:`InstrumentError` when the bytes
    are not a definite-length block header (IEEE 488.2 section 8.7.9).

    >>> parse_block_header(b"#216")
    (4, 16)
    """
    if len(head) < 2 or head[:1] != b"#" or not head[1:2].isdigit() or head[1:2] == b"0":
        raise InstrumentError(f"expected an IEEE 488.2 definite-length block ('#<n><length>'), "
                              f"got {head[:12]!r}")
    n = int(head[1:2])
    digits = head[2:2 + n]
    if len(digits) < n or not digits.isdigit():
        raise InstrumentError(f"malformed IEEE 488.2 block header {head[:2 + n]!r}")
    return 2 + n, int(digits)


class VisaTransport:
    """:class:`Transport` over a pyvisa resource.

    Parameters
    ----------
    resource : VISA resource string (normalised with :func:`normalise_resource`)
    backend : pyvisa backend: ``"@py"`` (pyvisa-py, default), ``"@ivi"`` (NI/Keysight VISA),
        ``"path.yaml@sim"`` (pyvisa-sim); default from env ``LAMINID_VISA_BACKEND``
    timeout : seconds for each read
    """

    def __init__(self, resource: str, backend: str | None = None,
                 timeout: float = DEFAULT_TIMEOUT_S):
        import pyvisa

        check_timeout(timeout)           # before anything is opened
        self._pyvisa = pyvisa
        self.resource = normalise_resource(resource)
        self.backend = backend or os.environ.get(BACKEND_ENV) or DEFAULT_BACKEND
        self._last = ""
        try:
            self._rm = pyvisa.ResourceManager(self.backend)
        except (OSError, ValueError, pyvisa.errors.Error) as exc:
            raise AnalyserSetupError(f"VISA backend {self.backend!r} is not usable ({exc}); "
                                     "use '@py' (pyvisa-py) or install NI-VISA for '@ivi'") from exc
        try:
            self._inst = self._rm.open_resource(self.resource)
        except pyvisa.errors.VisaIOError as exc:
            self._rm.close()
            code = getattr(exc, "error_code", None)
            if code == pyvisa.constants.StatusCode.error_resource_not_found:
                raise AnalyserSetupError(f"analyser {self.resource}: no such VISA resource on "
                                         f"backend {self.backend} ({exc.description})") from exc
            raise InstrumentError(f"analyser {self.resource}: cannot open ({exc.description})") from exc
        except (socket.timeout, socket.gaierror, TimeoutError) as exc:
            # a host that does not resolve or answer: no analyser answering at --analyser, bad
            # input as a refused connection is (exit 2, README), not an analyser fault (1)
            self._rm.close()
            raise AnalyserSetupError(f"analyser {self.resource} is unreachable "
                                  f"({' '.join(str(exc).split()) or type(exc).__name__}); check "
                                  "the address, the network and that the analyser is on") from exc
        except (ValueError, OSError, pyvisa.errors.Error) as exc:
            self._rm.close()
            hint = ""
            if self.resource.upper().startswith("GPIB") and self.backend == "@py":
                hint = ("; for GPIB with pyvisa-py install the extra: pip install "
                        "'laminid[gpib]' (gpib-ctypes, over the NI-488.2 or linux-gpib "
                        "driver), or use NI-VISA with --visa-backend @ivi")
            raise AnalyserSetupError(f"analyser {self.resource}: cannot open with backend "
                                     f"{self.backend} ({' '.join(str(exc).split())}){hint}") \
                from exc
        except Exception as exc:  # noqa: BLE001 - pyvisa-py raises a bare Exception ("could not
            # connect: ...") when a TCPIP host does not resolve or answer
            self._rm.close()
            raise AnalyserSetupError(f"analyser {self.resource} is unreachable "
                                  f"({' '.join(str(exc).split()) or type(exc).__name__}); check "
                                  "the address, the network and that the analyser is on") from exc
        # Text messages end with LF; raw sockets have no EOI, so the terminator is required
        # there, and harmless on GPIB (EOI also ends a message). Binary blocks are read with
        # read_bytes, which does not stop at the terminator.
        self._inst.read_termination = "\n"
        self._inst.write_termination = "\n"
        self.timeout = timeout
        self._disable_nagle()

    def _disable_nagle(self) -> None:
        """Raw TCP sockets: send each command at once (TCP_NODELAY), as NI-VISA does by default.

        pyvisa-py (0.8) leaves Nagle's algorithm on for ``::SOCKET`` sessions and refuses
        ``VI_ATTR_TCPIP_NODELAY``; a command with no answer followed by a query then waits for the
        peer's delayed ACK (about 40 ms on Linux) before the query leaves. Set on the socket
        itself when the attribute is refused; a no-op for other resources and backends.
        """
        if not self.resource.upper().endswith("::SOCKET"):
            return
        constants = self._pyvisa.constants
        try:
            self._inst.set_visa_attribute(constants.VI_ATTR_TCPIP_NODELAY, constants.VI_TRUE)
            return
        except Exception:  # noqa: BLE001 - pyvisa-py raises its own UnknownAttribute
            pass
        sessions = getattr(getattr(self._rm, "visalib", None), "sessions", None)
        session = sessions.get(self._inst.session) if isinstance(sessions, dict) else None
        sock = getattr(session, "interface", None)
        if isinstance(sock, socket.socket):
            try:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except OSError:
                log.debug("cannot set TCP_NODELAY on %s", self.resource, exc_info=True)

    @property
    def timeout(self) -> float:
        return self._inst.timeout / 1000.0

    @timeout.setter
    def timeout(self, seconds: float) -> None:
        self._inst.timeout = max(1, int(round(check_timeout(seconds) * 1000)))

    def _fail(self, exc: Exception, what: str) -> LaminidError:
        err = self._pyvisa.errors
        if isinstance(exc, ConnectionRefusedError):
            return AnalyserSetupError(f"no analyser at {self.resource} (connection refused); "
                                      "check the address, port and that the analyser is on")
        if isinstance(exc, err.VisaIOError) and exc.error_code == \
                self._pyvisa.constants.StatusCode.error_timeout:
            msg = (f"analyser {self.resource} did not answer within {self.timeout:g} s "
                   f"(waiting for the answer to {self._last!r}, {what})")
        elif isinstance(exc, err.VisaIOError):
            msg = f"analyser {self.resource}: {exc.description} ({what}, after {self._last!r})"
        else:
            msg = f"analyser {self.resource}: connection lost ({what}, after {self._last!r}: {exc})"
        return InstrumentError(msg)

    def _errors(self):
        return (self._pyvisa.errors.Error, OSError, EOFError)

    def write(self, command: str) -> None:
        log.debug("-> %s", command)
        self._last = command
        try:
            self._inst.write(command)
        except self._errors() as exc:
            raise self._fail(exc, "write") from exc

    def read(self) -> str:
        try:
            text = self._inst.read()
        except self._errors() as exc:
            raise self._fail(exc, "read") from exc
        except UnicodeDecodeError as exc:
            raise InstrumentError(f"analyser {self.resource}: unreadable answer to "
                                  f"{self._last!r} ({exc})") from exc
        log.debug("<- %s", text.strip())
        return text.strip()

    def query(self, command: str) -> str:
        self.write(command)
        return self.read()

    def read_bytes(self, n: int) -> bytes:
        """Read exactly ``n`` bytes (in chunks, so a short transfer says how much came)."""
        got = bytearray()
        chunk = 65536
        while len(got) < n:
            try:
                got += self._inst.read_bytes(min(chunk, n - len(got)))
            except self._errors() as exc:
                raise InstrumentError(
                    f"analyser {self.resource}: truncated binary transfer after {self._last!r}: "
                    f"expected {n} bytes, received {len(got)} "
                    f"({self._fail(exc, 'binary read')})") from exc
        return bytes(got)

    def read_block(self) -> bytes:
        """Read one IEEE 488.2 definite-length block and its trailing terminator."""
        head = self.read_bytes(2)
        n_digits = int(head[1:2]) if head[1:2].isdigit() else 0
        head += self.read_bytes(n_digits)
        try:
            _, count = parse_block_header(head)
        except InstrumentError as exc:      # which analyser and query: the message is alone
            raise InstrumentError(f"analyser {self.resource}: answer to {self._last!r}: "
                                  f"{exc}") from exc
        data = self.read_bytes(count)
        self._drain_terminator()
        return data

    def _drain_terminator(self) -> None:
        # The block is followed by LF (EOI on GPIB); take it off so the next read starts clean.
        old = self._inst.timeout
        try:
            self._inst.timeout = 200
            self._inst.read_bytes(1)
        except self._errors():
            pass
        finally:
            self._inst.timeout = old

    def clear(self) -> None:
        """Device clear (GPIB SDC): abandons a pending answer."""
        try:
            self._inst.clear()
        except self._errors():
            pass

    def close(self) -> None:
        for obj in (getattr(self, "_inst", None), getattr(self, "_rm", None)):
            if obj is None:
                continue
            try:
                obj.close()
            except self._errors():
                pass
            except Exception:  # noqa: BLE001 - closing must never mask the original error
                log.debug("error while closing %s", self.resource, exc_info=True)


def open_transport(resource: str, backend: str | None = None,
                   timeout: float = DEFAULT_TIMEOUT_S) -> VisaTransport:
    """Open ``resource`` through pyvisa (see :class:`VisaTransport`)."""
    return VisaTransport(resource, backend=backend, timeout=timeout)
