"""Atomic file writing: a result is either complete on disk or not there at all.

Everything laminid writes (FRF files point by point, modes and identification results, batch
outputs) goes through :func:`atomic_path`: the data are written to a temporary name in the
target's folder, flushed to disk (fsync) and renamed over the target (``os.replace`` is atomic
on POSIX and Windows). A crash or SIGKILL at any instant leaves the previous file or the new
one, never a half-written one; the temporary name starts with a dot and ends in
``.tmp-<pid>`` so that leftovers are easy to recognise (:data:`TEMP_GLOB`).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

#: glob pattern of the temporary files (left behind only by a killed process)
TEMP_GLOB = ".*.tmp-*"


def temporary_name(path) -> Path:
    """The temporary file :func:`atomic_path` writes ``path`` to in this process."""
    path = Path(path)
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; fsync and rename it to ``path`` on success.

    On an exception the temporary file is removed and ``path`` is untouched. A symbolic link
    is written through: its target is replaced, the link stays a link.
    """
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    tmp = temporary_name(path)
    try:
        yield tmp
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_bytes_atomic(path, data: bytes, parents: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`); ``parents``: create
    the missing folders of ``path`` first."""
    if parents:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def remove_stale_temporaries(folder) -> int:
    """Delete temporary files below ``folder`` left by killed processes; returns the count.

    Files of processes still alive (their pid ends the name) are kept.
    """
    return _remove_dead(Path(folder).rglob(TEMP_GLOB))


def remove_stale_temporaries_of(path) -> int:
    """Delete the temporary files of ``path`` (:func:`temporary_name`) that killed processes
    left beside it; returns the count. Those of processes still alive are kept, and so is a
    name ending in no pid (none of laminid's)."""
    import glob

    path = Path(path)
    return _remove_dead(path.parent.glob(f".{glob.escape(path.name)}.tmp-*"),
                        keep_unnumbered=True)


def _remove_dead(paths, keep_unnumbered: bool = False) -> int:
    """Delete those of the temporary files ``paths`` whose process (the pid ending the name)
    no longer runs, and those whose name ends in no pid unless ``keep_unnumbered``; returns
    the count."""
    n = 0
    for p in paths:
        pid = p.name.rsplit("-", 1)[-1]
        if process_alive(int(pid)) if pid.isdigit() else keep_unnumbered:
            continue
        with contextlib.suppress(OSError):
            p.unlink()
            n += 1
    return n


def process_alive(pid: int) -> bool:
    """True while process ``pid`` runs (also when it belongs to another user). A zombie (dead,
    not yet reaped: a killed batch's workers whose parent died too, until init reaps them) is
    not alive; Linux's /proc says which, elsewhere a zombie counts as alive."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat.rsplit(")", 1)[-1].split()[0] != "Z"


#: seconds between two checks that the process that started a worker is still alive
#: (fallback of PR_SET_PDEATHSIG)
PARENT_POLL_S = 0.5


def stop_with_parent(terminate, client_pid: int | None = None) -> None:
    """Make this worker process call ``terminate()`` when the process that started it dies
    (even by SIGKILL, which runs no clean-up): Linux's ``prctl(PR_SET_PDEATHSIG, SIGTERM)``
    signals the worker when its parent dies (``terminate`` should be its SIGTERM handler), and
    a daemon thread checks every :data:`PARENT_POLL_S` s that the parent, and ``client_pid``
    (the batch process, where the parent is a forkserver) when given, are still there (other
    systems have no prctl). Without it a forked pool worker (a batch's, the Monte Carlo
    trials', the profiles') of a killed process waits for work forever."""
    import signal
    import threading
    import time

    parent = os.getppid()
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError, TypeError):
        pass

    def watch():
        while True:
            time.sleep(PARENT_POLL_S)
            if os.getppid() != parent or (client_pid is not None
                                          and not process_alive(client_pid)):
                terminate()

    threading.Thread(target=watch, name="laminid-parent-watch", daemon=True).start()
