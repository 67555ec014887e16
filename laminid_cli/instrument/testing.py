"""Scripted transport: test a driver against the manual's command/response pairs, no hardware.

In the spirit of pymeasure's ``expected_protocol``: the test lists what the driver must send and
what the instrument answers; any other command, order or a leftover step fails the test.

>>> from laminid_cli.instrument.sr785 import SR785
>>> with expected_protocol(SR785, [("*IDN?", "Stanford_Research_Systems,SR785,1,1")]) as sr:
...     sr.idn
'Stanford_Research_Systems,SR785,1,1'
"""

from __future__ import annotations

import contextlib
import struct

from laminid_cli.errors import InstrumentError

_READ = object()  # marks a step that only reads (no command written)


class ScriptedTransport:
    """A :class:`~laminid_cli.instrument.transport.Transport` that follows a script.

    Parameters
    ----------
    steps : list of ``(command, answer)``. ``command`` is the exact string the driver must
        write (``None``: the step is a read with nothing written before it). ``answer`` is
        ``None`` (nothing to read), a ``str`` (a text line), ``bytes`` (raw bytes for
        ``read_bytes``/``read_block``) or an exception instance to raise on the read.
    """

    def __init__(self, steps, resource: str = "SCRIPT::INSTR"):
        self.steps = list(steps)
        self.resource = resource
        self.timeout = 1.0
        self.pos = 0
        self.closed = False
        self.sent: list[str] = []
        self._pending: list = []  # answers waiting to be read, in order

    # --------------------------------------------------------------- helpers
    def _fail(self, message: str):
        raise AssertionError(f"scripted protocol, step {self.pos + 1}: {message}")

    def write(self, command: str) -> None:
        self.sent.append(command)
        if self._pending:
            self._fail(f"driver wrote {command!r} before reading the answer "
                       f"{self._pending[0]!r}")
        if self.pos >= len(self.steps):
            self._fail(f"driver wrote {command!r} after the end of the script")
        expected, answer = self.steps[self.pos]
        if expected != command:
            self._fail(f"expected {expected!r}, driver wrote {command!r}")
        self.pos += 1
        if answer is not None:
            self._pending.append(answer)

    def _next_answer(self):
        if not self._pending:
            # a read-only step (command None)
            if self.pos < len(self.steps) and self.steps[self.pos][0] is None:
                self._pending.append(self.steps[self.pos][1])
                self.pos += 1
            else:
                self._fail("driver read but the instrument has nothing to send")
        answer = self._pending[0]
        if isinstance(answer, BaseException):
            self._pending.pop(0)
            raise answer
        return answer

    def read(self) -> str:
        answer = self._next_answer()
        if not isinstance(answer, str):
            self._fail(f"driver read a text line but the answer is binary {answer[:16]!r}")
        self._pending.pop(0)
        return answer

    def query(self, command: str) -> str:
        self.write(command)
        return self.read()

    def read_bytes(self, n: int) -> bytes:
        answer = self._next_answer()
        if isinstance(answer, str):
            answer = answer.encode()
        if len(answer) < n:
            self._pending.pop(0)
            raise InstrumentError(f"truncated binary transfer: expected {n} bytes, "
                                  f"received {len(answer)}")
        head, rest = answer[:n], answer[n:]
        if rest:
            self._pending[0] = rest
        else:
            self._pending.pop(0)
        return head

    def read_block(self) -> bytes:
        from laminid_cli.instrument.transport import parse_block_header

        head = self.read_bytes(2)
        head += self.read_bytes(int(head[1:2]) if head[1:2].isdigit() else 0)
        _, count = parse_block_header(head)
        data = self.read_bytes(count)
        if self._pending and self._pending[0] in (b"\n", "\n"):
            self._pending.pop(0)
        return data

    def close(self) -> None:
        self.closed = True

    def check_done(self) -> None:
        if self._pending:
            self._fail(f"answer {self._pending[0]!r} was never read")
        if self.pos != len(self.steps):
            self._fail(f"script not finished: next expected command {self.steps[self.pos][0]!r}")


@contextlib.contextmanager
def expected_protocol(driver_cls, steps, **kwargs):
    """Yield ``driver_cls(ScriptedTransport(steps))``; on exit assert the script was used up."""
    transport = ScriptedTransport(steps)
    driver = driver_cls(transport, **kwargs)
    yield driver
    transport.check_done()


def ieee_block(payload: bytes) -> bytes:
    """IEEE 488.2 definite-length block ``#<n><len><payload>`` followed by LF.

    >>> ieee_block(b"abc")
    b'#13abc\\n'
    """
    length = str(len(payload)).encode()
    return b"#" + str(len(length)).encode() + length + payload + b"\n"


def doubles_be(values) -> bytes:
    """Big-endian IEEE 754 doubles (``FORM:DATA REAL,64`` on the 35670A)."""
    values = list(values)
    return struct.pack(f">{len(values)}d", *values)


def floats_le(values) -> bytes:
    """Little-endian 4-byte IEEE floats (SR785 ``DSPB?``)."""
    values = list(values)
    return struct.pack(f"<{len(values)}f", *values)
