"""A killed process leaves none of its forked pool workers behind (the Monte Carlo trials', the
profiles'; a batch's own pool: tests/test_batch.py): identify or batch -j 1 killed with
SIGKILL during hybrid CM's profiles left both workers waiting for work, for ever."""

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

SCRIPT = textwrap.dedent("""
    import multiprocessing, os, signal, sys, time
    from concurrent.futures import ProcessPoolExecutor
    from laminid_cli.uncertainty import _stops_with_parent

    init = _stops_with_parent if sys.argv[1] == "yes" else None
    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork"),
                               initializer=init)
    with open(sys.argv[2], "w") as f:
        f.write(str(pool.submit(os.getpid).result()))
    pool.submit(time.sleep, 30)
    time.sleep(0.2)
    os.kill(os.getpid(), signal.SIGKILL)
""")


def _running(pid: int) -> bool:
    """The process is there and not a zombie (an orphan's zombie waits for init)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork, /proc")
@pytest.mark.parametrize("stops", ["yes", "no"])
def test_a_pool_worker_ends_with_the_process_killed_that_started_it(stops, tmp_path):
    """The worker, busy in a 30 s task when its parent is killed, is gone within 2 s with
    the set-up of the trials' and profiles' pools; without it (the control: what the test
    would see if that set-up did nothing) it is still running 1 s later."""
    # (files, not pipes: a worker left running would hold a pipe open)
    err = tmp_path / "stderr"
    with open(err, "w") as fh:
        proc = subprocess.run([sys.executable, "-c", SCRIPT, stops, str(tmp_path / "pid")],
                              stdout=subprocess.DEVNULL, stderr=fh, timeout=60)
    assert proc.returncode == -signal.SIGKILL, err.read_text()
    worker = int((tmp_path / "pid").read_text())
    try:
        t0 = time.time()
        while _running(worker) and time.time() - t0 < (2.0 if stops == "yes" else 1.0):
            time.sleep(0.05)
        assert _running(worker) == (stops == "no")
    finally:
        if _running(worker):
            os.kill(worker, signal.SIGKILL)


def _death_signal() -> int:
    """This process's parent-death signal (prctl PR_GET_PDEATHSIG; 0: none)."""
    import ctypes

    value = ctypes.c_int()
    ctypes.CDLL(None, use_errno=True).prctl(2, ctypes.byref(value), 0, 0, 0)
    return value.value


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl")
def test_trials_run_in_this_process_leave_its_signals_and_threads_as_they_were():
    """The Monte Carlo trials run in the calling process (the pilot's; all of them with one
    job) set up the trials' state only. The pool worker's process set-up
    (uncertainty._stops_with_parent) ran there too: it reset the caller's SIGTERM handler to
    the default, made it die with its own parent and left a thread watching that parent, one
    more each run (in a test process every later HDF5 probe then started a new interpreter,
    0.2-0.3 s, instead of forking: frf.store._fork_is_safe). S2.1 (6x6, G13 and G23 fixed),
    4 trials with one job."""
    from laminid_cli.forward import build_forward_model
    from laminid_cli.identify import IdentifyOptions, identify
    from laminid_cli.specimen import read_specimen
    from laminid_cli.uncertainty import frequency_sigma, monte_carlo, uncertainty_of

    fm = build_forward_model(read_specimen("specimens/example2/S2.1.yaml"), (6, 6))
    r = identify(fm, IdentifyOptions(fix=("G13", "G23")))
    sigma = frequency_sigma(fm.specimen.measured, 0.002)
    u = uncertainty_of(r, fm, sigma)

    def handler(signum, frame):
        pass

    before = signal.signal(signal.SIGTERM, handler)
    try:
        threads, death = set(threading.enumerate()), _death_signal()
        mc = monte_carlo(r, fm, sigma, u, 4, jobs=1, seed=1)
        assert mc.n_converged == 4 and mc.jobs == 1
        assert signal.getsignal(signal.SIGTERM) is handler
        assert _death_signal() == death
        assert set(threading.enumerate()) == threads
    finally:
        signal.signal(signal.SIGTERM, before)
