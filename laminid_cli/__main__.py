"""``laminid`` (the console script) and ``python -m laminid_cli``.

This module imports nothing heavy: the command-line group (click, then each command's module) is
imported inside :func:`main`'s Ctrl-C guard, so an interrupt during start-up ends like one during
a command: "laminid: interrupted" on stderr, exit code 130, no traceback.
"""

from __future__ import annotations

import os
import sys

from laminid_cli.errors import EXIT_INTERRUPTED


def main():
    """Run the ``laminid`` command line (sys.argv) and exit."""
    # laminid's linear algebra is banded and small: BLAS threads only contend with each other
    # (measured: 28 ms single-threaded vs 0.2-6 s with two threads on a loaded 2-core machine).
    # Parallel work goes through processes (batch -j). Must be set before numpy is imported.
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    try:
        from laminid_cli.cli import cli

        cli(prog_name="laminid")
    except KeyboardInterrupt:              # before click took over: importing click or the group
        print("laminid: interrupted", file=sys.stderr)
        _exit_interrupted()
    except SystemExit as exc:
        if exc.code == EXIT_INTERRUPTED:   # the group caught the interrupt and said so
            _exit_interrupted()
        raise


def _exit_interrupted():
    """Exit with code 130 even when CPython would turn it into death by SIGINT.

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
        os._exit(EXIT_INTERRUPTED)


if __name__ == "__main__":
    main()
