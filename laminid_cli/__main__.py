"""``laminid`` (the console script) and ``python -m laminid_cli``.

This module imports nothing heavy: the command-line group (click, then each command's module) is
imported inside :func:`main`'s Ctrl-C guard, so an interrupt during start-up ends like one during
a command: "laminid: interrupted" on stderr, exit code 130, no traceback.

A reader that closes the pipe early (``laminid identify S.yaml | head``) is not a failure of
laminid: the rest of what it prints goes to /dev/null, the command finishes its work (result
files written whole) and exits with its own code, 0 when the work succeeded. Not 141 (128 +
SIGPIPE, what a shell reports for a command killed by the signal), nor click's 1 after its first
write that met the closed pipe (the command cut short): both make ``set -o pipefail`` take the
pipeline for a failed one.
"""

from __future__ import annotations

import io
import os
import stat
import sys

from laminid_cli.errors import EXIT_INTERRUPTED, EXIT_TERMINATED


def main():
    """Run the ``laminid`` command line (sys.argv) and exit."""
    # laminid's linear algebra is banded and small: BLAS threads only contend with each other
    # (measured: 28 ms single-threaded vs 0.2-6 s with two threads on a loaded 2-core machine).
    # Parallel work goes through processes (batch -j). Must be set before numpy is imported.
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    quiet_closed_pipes()
    try:
        from laminid_cli.cli import cli

        cli(prog_name="laminid")
    except KeyboardInterrupt:              # before click took over: importing click or the group
        print("laminid: interrupted", file=sys.stderr)
        _exit_interrupted()
    except SystemExit as exc:
        if exc.code in (EXIT_INTERRUPTED, EXIT_TERMINATED):  # the group caught the interrupt
            _exit_interrupted(exc.code)                         # (or SIGTERM) and said so
        raise


class _PipeEnd(io.RawIOBase):
    """File descriptor ``fd`` (1 or 2, a pipe) as a raw stream that takes a closed pipe
    (EPIPE: the reader, ``head``, has gone) as the end of what is read: the descriptor is
    pointed at /dev/null, as the Python docs recommend for BrokenPipeError, and the write, as
    every one after it, counts as done, so that the command carries on to its own end."""

    def __init__(self, fd: int):
        super().__init__()
        self._fd = fd

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def isatty(self) -> bool:
        return os.isatty(self._fd)

    def write(self, data) -> int:
        try:
            return os.write(self._fd, data)
        except BrokenPipeError:
            devnull = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(devnull, self._fd)
            finally:
                os.close(devnull)
            return len(data)


def quiet_closed_pipes() -> None:
    """Make ``sys.stdout`` and ``sys.stderr``, where they are pipes, drop what is written after
    their reader closed them instead of raising BrokenPipeError (:class:`_PipeEnd`); a file or
    terminal stays as it is."""
    for name, fd in (("stdout", 1), ("stderr", 2)):
        stream = getattr(sys, name)
        try:
            if stream is None or stream.fileno() != fd:
                continue
            mode = os.fstat(fd).st_mode
        except (AttributeError, ValueError, OSError):   # io.UnsupportedOperation is both
            continue
        if not (stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode)):
            continue
        stream.flush()
        setattr(sys, name, io.TextIOWrapper(
            io.BufferedWriter(_PipeEnd(fd)), encoding=stream.encoding, errors=stream.errors,
            line_buffering=stream.line_buffering, write_through=stream.write_through))


def _exit_interrupted(code: int = EXIT_INTERRUPTED):
    """Exit with ``code`` (130; 143 for SIGTERM turned into a stop, :class:`Terminated`, a
    KeyboardInterrupt too) even when CPython would turn it into death by SIGINT.

    A KeyboardInterrupt that went through ``exec`` of a string (dataclasses, numpy/scipy start-up)
    marks the interpreter as killed by Ctrl-C, and at exit it re-raises SIGINT on itself (exit
    status -2 / "terminated by signal") whatever ``sys.exit`` said. So: run the exit handlers
    (worker pools, logging), flush the streams and leave with the code itself.
    """
    import atexit

    try:
        atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(code)


if __name__ == "__main__":
    main()
