"""Start-up of the ``laminid`` process (laminid_cli.__main__, laminid_cli.cli): which modules a
command imports, and Ctrl-C during start-up.

Both run the real entry point in a fresh interpreter (subprocess). The import budget is checked
by module names, not by timings: ``identify`` needs numpy, scipy.sparse/linalg and nlopt, but
none of the heavy modules that other commands or options use (each costs 40 ms to a second of
start-up; ``laminid identify`` should cost little more than ``laminid modes`` besides the fit).
"""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
S1 = ROOT / "specimens" / "example1" / "S1.1.yaml"

# runs `laminid ARGS...` through the console script's entry point and writes the names of the
# modules imported by the end of the process to the file named by the first argument
_MODULES_AT_EXIT = r"""
import atexit, json, sys
out = sys.argv[1]
atexit.register(lambda: json.dump(sorted(sys.modules), open(out, "w")))
sys.argv = ["laminid"] + sys.argv[2:]
from laminid_cli.__main__ import main
main()
"""

#: imported by other commands or options only (plots, result files, instruments, statistics)
HEAVY = ("scipy.optimize", "scipy.stats", "scipy.special", "scipy.integrate",
         "scipy.interpolate", "matplotlib", "h5py", "pyvisa", "pandas")


def _modules_after(tmp_path, *args):
    out = tmp_path / "modules.json"
    r = subprocess.run([sys.executable, "-c", _MODULES_AT_EXIT, str(out), *map(str, args)],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    return r, set(json.loads(out.read_text()))


def test_identify_imports_none_of_the_heavy_modules(tmp_path):
    r, modules = _modules_after(tmp_path, "identify", S1, "--mesh", "4x4", "--json",
                                "--no-output")
    assert r.returncode == 0, r.stderr[-2000:]
    summary = json.loads(r.stdout)                         # it did identify, with intervals
    assert summary["evaluations"] > 0 and summary["uncertainty"]
    assert {"numpy", "scipy.sparse", "nlopt", "laminid_cli.uncertainty"} <= modules
    heavy = sorted(m for m in modules if m in HEAVY or m.split(".")[0] in HEAVY)
    assert not heavy, f"identify --json --no-output imported {heavy}"
    # the loss factors' module only for a specimen with measured damping or a --fix eta...
    assert "laminid_cli.damping" not in modules


def test_help_imports_no_numerics(tmp_path):
    r, modules = _modules_after(tmp_path, "--help")
    assert r.returncode == 0 and "identify" in r.stdout
    assert not {"numpy", "scipy", "yaml", "laminid_cli.commands.identify"} & modules


# --- Ctrl-C during start-up ----------------------------------------------------------------------

# a module run as `python -m interrupt_at_import MODULE HOW ARGS...`: raises KeyboardInterrupt (a
# real SIGINT to the process) when MODULE is imported, then runs `python -m laminid_cli ARGS...`
# (run as the main module, as `-m` makes a difference: below). With HOW "exec" the signal arrives
# inside exec() of a string, as when Ctrl-C lands in the code that a dataclass definition or
# numpy/scipy's start-up executes: CPython then marks the process as killed by SIGINT and, after
# `python -m`, exits with -2 whatever sys.exit said (laminid_cli.__main__._exit_interrupted)
_INTERRUPT_AT_IMPORT = r"""
import os, runpy, signal, sys, time
target, how = sys.argv[1], sys.argv[2]

class Interrupter:
    def find_spec(self, name, path=None, target_module=None):
        if name == target:
            sys.meta_path.remove(self)
            code = "os.kill(os.getpid(), signal.SIGINT)\ntime.sleep(10)"
            if how == "exec":
                exec(code, {"os": os, "signal": signal, "time": time})
            else:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(10)
        return None

sys.meta_path.insert(0, Interrupter())
sys.argv = ["laminid"] + sys.argv[3:]
runpy.run_module("laminid_cli", run_name="__main__", alter_sys=True)
"""


@pytest.mark.parametrize("module, how", [
    ("click", "plain"),                          # importing the command-line group
    ("laminid_cli.commands.identify", "plain"),  # loading the command
    ("laminid_cli.forward", "exec"),             # in the command, through exec of a string
    ("laminid_cli.uncertainty", "exec"),
])
def test_ctrl_c_during_start_up_exits_130_without_traceback(module, how, tmp_path):
    (tmp_path / "interrupt_at_import.py").write_text(_INTERRUPT_AT_IMPORT)
    path = os.pathsep.join([str(tmp_path)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    # preexec_fn: Ctrl-C as in a terminal. A test run started as a background job of a
    # non-interactive shell has SIGINT ignored, which its children inherit (the interpreter
    # then never raises KeyboardInterrupt: seen with `(pytest ... &)`, the command then ran
    # to its end and exited 0)
    r = subprocess.run([sys.executable, "-m", "interrupt_at_import", module, how, "identify",
                        str(S1), "--json", "--no-output"],
                       capture_output=True, text=True, cwd=ROOT, timeout=120,
                       env={**os.environ, "PYTHONPATH": path},
                       preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert r.returncode == 130, r.stderr[-2000:]
    assert "laminid: interrupted" in r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""


S21 = ROOT / "specimens" / "example2" / "S2.1.yaml"


def _laminid_into_closed_pipe(*args, both=False):
    """``laminid ARGS`` (``python -m laminid_cli``) with stdout (and stderr, ``both``) a pipe
    whose reader has gone, as ``laminid ... | head`` once head has its lines: every write
    meets EPIPE. Returns (exit code, stderr)."""
    read, write = os.pipe()
    os.close(read)
    try:
        r = subprocess.run([sys.executable, "-m", "laminid_cli", *map(str, args)],
                           stdout=write, stderr=write if both else subprocess.PIPE, cwd=ROOT,
                           timeout=300, text=True)
    finally:
        os.close(write)
    return r.returncode, r.stderr or ""


def test_a_reader_that_closes_the_pipe_early_is_no_failure(tmp_path):
    """``laminid identify S.yaml -o R | head`` (with or without --json): exit 0, nothing on
    stderr and the result file whole (was exit 1, silently: click's broken-pipe handling);
    show after it likewise. A shell batch with ``set -o pipefail`` takes 0 for success."""
    from laminid_cli.results import read_h5

    for fmt in ((), ("--json",)):
        out = tmp_path / f"r{len(fmt)}.h5"
        code, err = _laminid_into_closed_pipe("identify", S21, "--mesh", "4x4", "-o", out, *fmt)
        assert (code, err) == (0, "")
        assert read_h5(out)["frequencies"]["model"].shape == (12,)
        code, err = _laminid_into_closed_pipe("show", out, *fmt)
        assert (code, err) == (0, "")
    # stderr into the same closed pipe (2>&1 | head): its message is dropped, not a traceback
    code, _ = _laminid_into_closed_pipe("show", out, "--json", both=True)
    assert code == 0


def test_a_closed_pipe_keeps_the_commands_own_exit_code(tmp_path):
    """A run that did not converge still exits 1 with its message on stderr, its result
    written, when stdout's reader has gone (the command runs to its end; a BrokenPipeError
    caught at the entry point would have cut it short before its exit code was decided)."""
    from laminid_cli.results import read_h5

    out = tmp_path / "n.h5"
    code, err = _laminid_into_closed_pipe("identify", S21, "--mesh", "4x4", "-o", out,
                                          "--max-evaluations", "3")
    assert code == 1
    assert err.startswith("laminid: identification did not converge: not converged: the "
                          "budget of --max-evaluations 3 evaluations ran out"), err
    assert "Traceback" not in err
    assert read_h5(out)["frequencies"]["model"].shape == (12,)
    # a usage error: exit 2 and its message, as without the pipe
    code, err = _laminid_into_closed_pipe("identify", tmp_path / "missing.yaml")
    assert code == 2 and "file not found" in err, err
