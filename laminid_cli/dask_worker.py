"""Set-up of the worker processes of ``laminid batch --scheduler local`` (a local Dask cluster).

Imported only by :func:`laminid_cli.batch._run_dask` (it needs distributed): the workers
import it again when they unpickle the plugin.
"""

from __future__ import annotations

import logging
import signal

from distributed.diagnostics.plugin import WorkerPlugin


class LocalWorkerSetup(WorkerPlugin):
    """Ctrl-C is the client's business, as for the process pool's workers
    (batch._worker_signals): a terminal sends SIGINT to the whole process group, the local
    cluster's worker processes included, and each one interrupted in its event loop printed
    its tracebacks ("Process Dask Worker process (from Nanny)", CancelledError,
    KeyboardInterrupt; some 300 lines) before the batch's "laminid: interrupted". They ignore
    it; the client cancels the jobs and closes the cluster. SIGTERM likewise: sent to the
    whole group (a cluster's wall-time limit, ``timeout``), it killed the workers before the
    batch acted on it; their nannies restarted them and the scheduler logged the lost
    results ("Removing worker ... caused the cluster to lose already computed task(s)",
    "Restarting worker") above "laminid: terminated (SIGTERM)". The cluster's close still
    ends them: a stop message, then SIGKILL after its timeout (distributed.nanny.
    WorkerProcess.kill), never SIGTERM. Their loggers get laminid's
    verbosity (:func:`worker_log_level`): the messages of that close only with -v.

    laminid's own records (a specimen's warning) are written as the batch writes them
    (:func:`laminid_cli.cli.configure_logging`, "warning: ..."): a worker starts from a clean
    interpreter, where they went out bare through Python's last-resort handler, as the process
    pool's did before its initializer configured them (batch._worker_init).

    log_level : the level of the workers' ``distributed`` loggers (logging.CRITICAL unless -v)
    level : laminid's level (the batch's: WARNING, ERROR with -q, INFO/DEBUG with -v)
    """

    idempotent = True
    name = "laminid-local-worker-setup"

    def __init__(self, log_level: int = logging.CRITICAL, level: int = logging.WARNING):
        self.log_level = log_level
        self.level = level

    def setup(self, worker) -> None:
        from laminid_cli.cli import configure_logging

        # (a worker plugin runs in the worker process' main thread, where signals are set)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        configure_logging(self.level)
        logging.getLogger().setLevel(self.level)
        logging.getLogger("distributed").setLevel(self.log_level)


def worker_log_level(level: int) -> int:
    """The level of a local worker's ``distributed`` loggers at laminid's level ``level``
    (WARNING, or INFO/DEBUG with -v).

    Without -v, CRITICAL: what a worker logs as the cluster closes is an artefact of the
    close, not news, and the batch reports every job's outcome itself (a job's exception, a
    killed worker) through its future. Even ERROR was too much: a worker whose heartbeat
    found the scheduler already closed after a Ctrl-C printed "distributed.worker - ERROR -
    Failed to communicate with scheduler during heartbeat" and a 30-line traceback before
    "laminid: interrupted" (once, in CI, on a loaded 2-core machine). With -v, laminid's
    level: the user asked to see it.
    """
    return logging.CRITICAL if level >= logging.WARNING else level
