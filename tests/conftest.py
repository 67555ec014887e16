"""Test-session set-up: single-threaded BLAS (as the CLI does) before numpy is imported; the
identifications several test modules read, run once per test process."""

import os
import sys

import pytest

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector):
    """Where PYTHONDONTWRITEBYTECODE is set (as on CI), pytest rewrote the asserts of every
    test module again in every test process, ~4.5 s of each worker's collection (6.8 s
    against 2.3 s once written). While a test module is collected, Python may write bytecode
    as it does without the variable: pytest's rewritten test module to tests/__pycache__
    (hash-checked; pytest reads it whether or not it may write it), as ``make bytecode``
    writes the package's; and the .pyc of a module first imported then that has none (the
    package's and the tests' helpers have theirs from make bytecode; a virtualenv's packages
    installed without theirs get them, among them scipy.stats' _bws_test and
    _page_trend_test, which pytest rewrites for their names)."""
    if not (isinstance(collector, pytest.Module) and sys.dont_write_bytecode):
        return (yield)
    sys.dont_write_bytecode = False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = True


@pytest.fixture(scope="session")
def s11_fix_undetermined_6x6(tmp_path_factory):
    """``laminid identify S1.1 --mesh 6x6 --fix-undetermined --json -o``: (parsed JSON,
    result file). G13, G23, nu12 are undetermined in the first run and fixed, E2 in a later
    round; G12 stays free (its initial value is rejected), E1 and G12 identified. Read by
    test_identify_cli_uncertainty.py, test_report.py and test_resultfile.py (which changes a
    copy): one run of ~1.5 s per test process instead of one per module."""
    from tests.clihelp import identify_json

    return identify_json(tmp_path_factory, "specimens/example1/S1.1.yaml", "6x6", "f.result.h5",
                         "--fix-undetermined")


@pytest.fixture(scope="session")
def s11_fix_undetermined(tmp_path_factory):
    """``laminid identify S1.1 --fix-undetermined --json -o`` (its 12x12 mesh): (parsed JSON,
    result file). G13, G23, nu12 fixed together, which the modes reject (fixed_rejected,
    nu12 to release); the intervals count the spread they had before fixing. Read by
    test_fixed_check.py and test_fixed_spread.py, which each ran it (~1.5 s)."""
    from tests.clihelp import identify_json

    return identify_json(tmp_path_factory, "specimens/example1/S1.1.yaml", None, "r.h5",
                         "--fix-undetermined")


@pytest.fixture(scope="session")
def s21_6x6(tmp_path_factory):
    """``laminid identify S2.1 --mesh 6x6 -o --json`` and ``... --no-output``: (the --json
    run's click Result, the terminal run's Result, the result file). Status check: G13 at
    its lower search limit (a feasibility bound), G23 undetermined, a poor fit. Read by
    test_status.py, test_identify_cli.py and test_report_output.py, which each ran it."""
    from tests.clihelp import run

    out = tmp_path_factory.mktemp("s21_6x6") / "s21.h5"
    j = run("identify", "specimens/example2/S2.1.yaml", "--mesh", "6x6", "-o", out, "--json")
    t = run("identify", "specimens/example2/S2.1.yaml", "--mesh", "6x6", "--no-output")
    return j, t, out


@pytest.fixture(scope="session")
def s21_8x8(tmp_path_factory):
    """``laminid identify S2.1 --mesh 8x8 --json -o``: (parsed JSON, result file); G13 stops on
    its lower search limit (a flat profile), G23's interval runs to 11 GPa. Read by
    test_identify_cli.py, test_global_uncertainty.py, test_profile.py and
    test_report_figures.py, which each identified it once."""
    from tests.clihelp import identify_json

    return identify_json(tmp_path_factory, "specimens/example2/S2.1.yaml", "8x8",
                         "S2.1.result.h5")


@pytest.fixture(scope="session")
def s21_8x8_fix_undetermined(tmp_path_factory):
    """``laminid identify S2.1 --mesh 8x8 --fix-undetermined --json -o``: (parsed JSON,
    result file). G13, on its lower search limit in the first run, fixed ("fixed: it was at
    a search limit", checked across the search's range), G23 fixed because undetermined; no
    constant of the answer on a search limit. Read by test_profile.py and
    test_report_figures.py, which each ran it."""
    from tests.clihelp import identify_json

    return identify_json(tmp_path_factory, "specimens/example2/S2.1.yaml", "8x8",
                         "S2.1.result.h5", "--fix-undetermined")


@pytest.fixture(scope="session")
def s21_8x8_terminal():
    """The terminal output of ``laminid identify S2.1 --mesh 8x8 --no-output`` (the run of
    s21_8x8), read by test_global_uncertainty.py and test_profile.py."""
    from tests.clihelp import run

    r = run("identify", "specimens/example2/S2.1.yaml", "--mesh", "8x8", "--no-output")
    assert r.exit_code == 0, r.output
    return r.output



@pytest.fixture(autouse=True)
def _no_thread_left():
    """Every test leaves the process's threads as it found them: a thread that a command
    started and left alive (a Monte Carlo run in the calling process once left one per run,
    watching its parent) makes every later HDF5 probe of that process start an interpreter
    instead of forking (frf.store._fork_is_safe), and in a user's batch it outlives the
    specimen. A new thread still alive 2 s after the test is an error of the test."""
    import threading
    import time

    before = {t.ident for t in threading.enumerate()}
    yield
    deadline = time.monotonic() + 2.0
    left = [t for t in threading.enumerate() if t.ident not in before]
    for t in left:
        t.join(max(0.0, deadline - time.monotonic()))
    alive = [t for t in left if t.is_alive()]
    if alive:
        pytest.fail("the test left threads running: " + ", ".join(
            f"{t.name} ({type(t).__name__}{', daemon' if t.daemon else ''})" for t in alive))
