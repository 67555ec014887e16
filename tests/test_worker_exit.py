"""A killed process leaves none of its forked pool workers behind (the Monte Carlo trials', the
profiles'; a batch's own pool: tests/test_batch.py): identify or batch -j 1 killed with
SIGKILL during hybrid CM's profiles left both workers waiting for work, for ever."""

import os
import signal
import subprocess
import sys
import textwrap
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
