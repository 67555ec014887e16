"""Batch identification: many specimens, one result file each, a summary table.

The flow of ``laminid batch`` as library functions:

1. :func:`discover_specimens` finds the specimen files (``*.yaml``/``*.yml``, recursively in
   folders; files as given) and names each by its path relative to the common root of the
   inputs (``example1/S1.1``), so same-named files in different folders never collide;
2. :func:`plan_batch` gives each a :class:`Job`: its result file
   ``OUT/<relative folder>/<stem>.result.h5`` and the content hash :func:`input_hash`
   (sha256 of the specimen bytes, of the FRF file named by ``measured.frf_file`` if any, of
   the options and of the laminid version). A result whose stored hash (root attribute
   ``batch_input_sha256``) equals the job's is up to date and is not run again;
3. :func:`run_job` (in a worker process: a process pool or a Dask worker) does what
   ``laminid identify SPEC -o OUT`` does and returns the finished HDF5 file as bytes plus its
   status; it never raises for a specimen's fault (bad YAML, infeasible start, no convergence);
4. :func:`write_result_bytes` (in the client) writes the file atomically (laminid_cli.atomic): temporary name in
   the target folder, fsync, rename. Killing the batch at any instant leaves either no file or
   a complete one;
5. :func:`result_row` reads the numbers of the summary back from each result file;
   :func:`write_summary_csv`, :func:`write_summary_json` and :func:`format_table` give the
   table across specimens (the shape of the paper's Table 2: specimens as columns).

Nothing here imports numpy, h5py or the solver at module level, so the command starts fast.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import json
import logging
import os
import tempfile
import time
import traceback
from dataclasses import asdict, dataclass, field
from pathlib import Path

from laminid_cli import __version__
from laminid_cli.atomic import remove_stale_temporaries, write_bytes_atomic
from laminid_cli.errors import LaminidError
from laminid_cli.identify import IdentifyOptions
from laminid_cli.uncertainty import UncertaintyOptions

log = logging.getLogger(__name__)

CONSTANTS = ("E1", "E2", "G12", "G13", "G23", "nu12")
#: summary value units: moduli in GPa in the CSV and the table, Poisson ratio plain
CONSTANT_UNITS = {"E1": "GPa", "E2": "GPa", "G12": "GPa", "G13": "GPa", "G23": "GPa", "nu12": "1"}
SPECIMEN_SUFFIXES = (".yaml", ".yml")
RESULT_SUFFIX = ".result.h5"
SUMMARY_CSV = "summary.csv"
SUMMARY_JSON = "summary.json"
HASH_ATTR = "batch_input_sha256"
#: statuses of a summary row; every status but "ok" makes the batch exit with 1
STATUSES = ("ok", "not converged", "error", "not run")


class BatchError(LaminidError):
    """A batch cannot run: no specimen found, bad output folder, no Dask (exit code 2)."""


@dataclass(frozen=True)
class BatchOptions:
    """The options of ``laminid identify`` passed through to every specimen.

    mesh : "NXxNY"; fix ... pairing as :class:`laminid_cli.identify.IdentifyOptions` (fix is a
    tuple of "nu12" / "glass.nu12" items); sigma_rel ... seed as
    :class:`laminid_cli.uncertainty.UncertaintyOptions` (the Monte Carlo trials of a specimen
    run in its worker: the batch is already parallel over specimens).
    """

    # defaults are those of identify, never restated (they cannot drift apart)
    mesh: str = "12x12"
    fix: tuple[str, ...] = IdentifyOptions.fix
    optimizer: str = IdentifyOptions.optimizer
    parametrization: str = IdentifyOptions.parametrization
    xtol: float = IdentifyOptions.xtol_rel
    ftol: float = IdentifyOptions.ftol_rel
    max_evaluations: int = IdentifyOptions.max_evaluations
    pairing: str = IdentifyOptions.pairing
    solver: str = IdentifyOptions.solver
    sigma_rel: float = UncertaintyOptions.sigma_rel
    covariance_scale: str = UncertaintyOptions.scaling
    max_rel_interval: float = UncertaintyOptions.max_rel_interval
    fix_undetermined: bool = UncertaintyOptions.fix_undetermined
    monte_carlo: int = UncertaintyOptions.monte_carlo
    seed: int = UncertaintyOptions.seed

    def as_dict(self) -> dict:
        d = asdict(self)
        d["fix"] = list(self.fix)
        return d

    def identify_options(self):
        return IdentifyOptions(fix=tuple(self.fix), optimizer=self.optimizer,
                               parametrization=self.parametrization, xtol_rel=self.xtol,
                               ftol_rel=self.ftol, max_evaluations=self.max_evaluations,
                               pairing=self.pairing, solver=self.solver)

    def uncertainty_options(self):
        return UncertaintyOptions(sigma_rel=self.sigma_rel, scaling=self.covariance_scale,
                                  max_rel_interval=self.max_rel_interval,
                                  fix_undetermined=self.fix_undetermined,
                                  monte_carlo=self.monte_carlo, jobs=1, seed=self.seed)


@dataclass(frozen=True)
class Job:
    """One specimen of a batch.

    spec : specimen file (as found); name : path relative to the inputs' root without the
    suffix, posix ("example1/S1.1"); output : result file; key : content hash;
    up_to_date : the output exists and holds this key (nothing to do)
    """

    spec: str
    name: str
    output: str
    key: str
    up_to_date: bool = False


@dataclass
class Outcome:
    """What a worker returns: status ("ok" | "not converged" | "error"), the reason of a
    failure, the result file's bytes (None on error) and the wall time in s."""

    name: str
    status: str
    reason: str = ""
    data: bytes | None = field(default=None, repr=False)
    time_s: float = 0.0


# ----------------------------------------------------------------------------------------------
# discovery, hashing, planning


def discover_specimens(inputs, exclude=()) -> list[tuple[Path, str]]:
    """Specimen files of the inputs and their unique names.

    Parameters
    ----------
    inputs : files and folders; folders are searched recursively for ``*.yaml``/``*.yml``
        (hidden files and folders skipped), files are taken whatever their suffix
    exclude : folders not to search (the output folder)

    Returns
    -------
    list of (path, name), sorted by name; name = path relative to the common folder of all
    inputs, without the suffix, with '/' separators (unique because the paths are).
    """
    exclude = [Path(e).resolve() for e in exclude]
    found: dict[Path, Path] = {}          # resolved -> as found
    roots = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            roots.append(p.resolve())
            for f in sorted(p.rglob("*")):
                rel = f.relative_to(p)
                if (f.suffix.lower() in SPECIMEN_SUFFIXES and f.is_file()
                        and not any(part.startswith(".") for part in rel.parts)
                        and not any(_inside(f.resolve(), e) for e in exclude)):
                    found.setdefault(f.resolve(), f)
        elif p.exists():
            roots.append(p.resolve().parent)
            found.setdefault(p.resolve(), p)
        else:
            raise BatchError(f"{p}: no such file or folder")
    if not found:
        return []
    root = Path(os.path.commonpath([str(r) for r in roots]))
    out = []
    for resolved, as_found in found.items():
        rel = resolved.relative_to(root)
        name = rel.with_name(rel.name[: -len(rel.suffix)] if rel.suffix else rel.name)
        out.append((as_found, name.as_posix()))
    return sorted(out, key=lambda t: t[1])


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
        return True
    except ValueError:
        return False


def _frf_file(spec: Path) -> Path | None:
    """The FRF file a specimen takes its frequencies from (``measured.frf_file``), if any."""
    import yaml

    try:
        doc = yaml.safe_load(spec.read_text(encoding="utf-8-sig"))
        name = doc["measured"]["frf_file"]
    except (OSError, UnicodeDecodeError, yaml.YAMLError, KeyError, TypeError):
        return None
    return spec.parent / str(name) if name else None


def input_hash(spec, options: BatchOptions) -> str:
    """sha256 (hex) of everything a result depends on: the laminid version, the options, the
    specimen file's bytes and those of its FRF file (``measured.frf_file``) when it has one."""
    spec = Path(spec)
    h = hashlib.sha256()
    h.update(f"laminid {__version__}\0".encode())
    h.update(json.dumps(options.as_dict(), sort_keys=True).encode() + b"\0")
    h.update(spec.read_bytes())
    frf = _frf_file(spec)
    if frf is not None:
        h.update(b"\0frf_file\0")
        with contextlib.suppress(OSError):
            h.update(frf.read_bytes())
    return h.hexdigest()


def stored_hash(path) -> str | None:
    """The ``batch_input_sha256`` of a result file; None when absent or unreadable."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            value = f.attrs.get(HASH_ATTR)
    except (OSError, ValueError):
        return None
    return value.decode() if isinstance(value, bytes) else value


def result_path(out_dir, name: str) -> Path:
    return Path(out_dir) / (name + RESULT_SUFFIX)


def plan_batch(specimens, out_dir, options: BatchOptions, force: bool = False) -> list[Job]:
    """Jobs of the (path, name) pairs of :func:`discover_specimens`; up to date unless forced."""
    jobs = []
    for spec, name in specimens:
        out = result_path(out_dir, name)
        try:
            key = input_hash(spec, options)
        except OSError as exc:
            key = f"unreadable: {exc}"
        done = not force and out.exists() and stored_hash(out) == key
        jobs.append(Job(spec=str(spec), name=name, output=str(out), key=key, up_to_date=done))
    return jobs


# ----------------------------------------------------------------------------------------------
# running


def run_job(job: Job, options: BatchOptions) -> Outcome:
    """Identify one specimen with its uncertainty assessment, as ``laminid identify SPEC -o
    OUT`` does; runs in a worker.

    Returns the result file as bytes, with the root attributes ``batch_input_sha256``,
    ``batch_name`` and ``batch_options`` (JSON) added. A specimen's own fault (unreadable or
    invalid file, infeasible start, no convergence, solver failure) is an Outcome with status
    "error" or "not converged" and its reason, never an exception; an unexpected exception
    is reported the same way (with its type) so that the other specimens go on.
    """
    t0 = time.perf_counter()
    try:
        import h5py

        from laminid_cli.fe.mesh import parse_mesh
        from laminid_cli.forward import build_forward_model
        from laminid_cli.results import (identification_summary, uncertainty_summary,
                                         write_identification_file)
        from laminid_cli.specimen import read_specimen
        from laminid_cli.uncertainty import assess

        specimen = read_specimen(job.spec)
        fm = build_forward_model(specimen, parse_mesh(options.mesh))
        assessment = assess(fm, options.identify_options(), options.uncertainty_options())
        result = assessment.result
        summary = identification_summary(result)
        summary["mesh"] = {"nx": fm.mesh_size[0], "ny": fm.mesh_size[1]}
        summary["uncertainty"] = uncertainty_summary(assessment)
        with tempfile.TemporaryDirectory(prefix="laminid-batch-") as tmp:
            _current_tmp.append(tmp)
            try:
                path = Path(tmp) / Path(job.output).name
                write_identification_file(path, fm, result, summary, command="laminid batch",
                                          assessment=assessment)
                with h5py.File(path, "r+") as f:
                    f.attrs[HASH_ATTR] = job.key
                    f.attrs["batch_name"] = job.name
                    f.attrs["batch_options"] = json.dumps(options.as_dict(), sort_keys=True)
                data = path.read_bytes()
            finally:
                _current_tmp.remove(tmp)
        status = "ok" if result.converged else "not converged"
        reason = "" if result.converged else str(result.status)
        return Outcome(job.name, status, reason, data, time.perf_counter() - t0)
    except LaminidError as exc:
        return Outcome(job.name, "error", str(exc), None, time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001 - one specimen's crash must not stop the batch
        log.debug("%s: %s", job.spec, traceback.format_exc())
        return Outcome(job.name, "error", f"internal error {type(exc).__name__}: {exc}", None,
                       time.perf_counter() - t0)


def write_result_bytes(path, data: bytes) -> Path:
    """Write a result file atomically (laminid_cli.atomic), creating its folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_bytes_atomic(path, data)


def remove_stale_parts(out_dir) -> int:
    """Delete the temporary files a killed batch left in ``out_dir``."""
    return remove_stale_temporaries(out_dir)


def run_jobs(jobs, options: BatchOptions, n_jobs: int = 1, scheduler: str | None = None):
    """Run the jobs and yield ``(job, outcome)`` in order of completion.

    n_jobs : worker processes; 1 without a scheduler runs in this process
    scheduler : None (concurrent.futures process pool), "local" (a local Dask cluster of
        ``n_jobs`` single-threaded worker processes) or a Dask scheduler address
        ("tcp://host:8786"); the workers must see the specimen files at the same paths.

    Closing the generator (or an exception in the consumer, e.g. KeyboardInterrupt) cancels
    what has not started.
    """
    jobs = list(jobs)
    if not jobs:
        return
    if scheduler is not None:
        yield from _run_dask(jobs, options, n_jobs, scheduler)
        return
    if n_jobs <= 1:
        yield from _run_here(jobs, options)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # forkserver: workers start from a clean interpreter (no inherited h5py handles/threads)
    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    pool = ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs)),
                               mp_context=multiprocessing.get_context(method),
                               initializer=_worker_signals)
    complete = False
    try:
        futures = {pool.submit(run_job, job, options): job for job in jobs}
        for fut in as_completed(futures):
            yield futures[fut], _outcome_of(fut, futures[fut])
        complete = True
    finally:
        if not complete:
            # Ctrl-C or an error in the consumer: the workers would finish the jobs already
            # queued to them; stop them now (their partial work is in their own temp folders)
            for proc in list(getattr(pool, "_processes", {}).values()):
                with contextlib.suppress(Exception):
                    proc.terminate()
        pool.shutdown(wait=complete, cancel_futures=True)


#: temporary folder of the job running in this (worker) process, removed on SIGTERM
_current_tmp: list = []


def _worker_signals() -> None:
    """Pool worker set-up: Ctrl-C is the client's business (it terminates the workers);
    SIGTERM removes the running job's temporary folder and exits at once (an exception
    would be caught by the pool's worker loop, which would go on with the next job)."""
    import signal

    def terminate(*_):
        import shutil

        for tmp in _current_tmp:
            shutil.rmtree(tmp, ignore_errors=True)
        os._exit(143)

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, terminate)


def _run_here(jobs, options):
    """The jobs one by one in this process. Ctrl-C raised inside compiled code can be
    swallowed there (an optimiser callback, for one) and turn into a failed or stopped run:
    the signal is noted, the job in progress is dropped (never cached as done) and the
    interrupt raised here."""
    import signal
    import threading

    seen: list = []

    def on_sigint(signum, frame):
        seen.append(signum)
        raise KeyboardInterrupt

    main = (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN)
    previous = signal.signal(signal.SIGINT, on_sigint) if main else None
    try:
        for job in jobs:
            outcome = run_job(job, options)
            if seen:
                raise KeyboardInterrupt
            yield job, outcome
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)


def _outcome_of(fut, job: Job) -> Outcome:
    try:
        return fut.result()
    except Exception as exc:  # noqa: BLE001 - a worker died (killed, out of memory)
        return Outcome(job.name, "error", f"worker failed: {type(exc).__name__}: {exc}")


def _run_dask(jobs, options, n_jobs, scheduler):
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError as exc:
        raise BatchError("--scheduler needs Dask: pip install 'laminid[dask]'") from exc
    cluster = None
    futures: dict = {}
    try:
        if scheduler == "local":
            cluster = LocalCluster(n_workers=max(1, n_jobs), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
            client = Client(cluster)
        else:
            client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        if cluster is not None:
            cluster.close()
        raise BatchError(f"--scheduler {scheduler}: cannot connect ({exc})") from exc
    try:
        # remote workers have their own working folder: give them absolute paths
        remote = [Job(str(Path(j.spec).resolve()), j.name, j.output, j.key) for j in jobs]
        futures = {client.submit(run_job, r, options, key=f"laminid-{j.name}-{j.key[:12]}",
                                 pure=False): j for j, r in zip(jobs, remote)}
        for fut in as_completed(list(futures)):
            yield futures[fut], _outcome_of(fut, futures[fut])
    finally:
        if futures:
            with contextlib.suppress(Exception):
                client.cancel(list(futures))
        client.close()
        if cluster is not None:
            cluster.close()


# ----------------------------------------------------------------------------------------------
# summary


def result_row(job: Job, outcome: Outcome | None = None, cached: bool = False) -> dict:
    """One summary row (SI units), with the numbers read back from the job's result file.

    Keys: name, specimen (its name field), path, status, reason, cached, materials
    ({material: {E1.. nu12}}), rms_residual_percent, evaluations, time_s, result.
    """
    row = {"name": job.name, "specimen": "", "path": str(job.spec), "status": "not run",
           "reason": "", "cached": cached, "materials": {}, "rms_residual_percent": None,
           "evaluations": None, "time_s": None, "result": None}
    if outcome is not None and outcome.status == "error":
        row.update(status="error", reason=outcome.reason, time_s=outcome.time_s)
        return row
    if outcome is None and not cached:
        return row
    import h5py

    try:
        with h5py.File(job.output, "r") as f:
            converged = bool(f.attrs["converged"])
            row["status"] = "ok" if converged else "not converged"
            row["reason"] = "" if converged else _str(f.attrs["status"])
            row["specimen"] = _str(f["specimen"].attrs["name"])
            row["evaluations"] = int(f.attrs["evaluations"])
            row["time_s"] = float(f.attrs["time_s"])
            row["rms_residual_percent"] = float(f["frequencies"].attrs["rms_residual_percent"])
            for g in f["materials"].values():
                row["materials"][_str(g.attrs["name"])] = {k: float(g[k][()]) for k in CONSTANTS}
    except (OSError, KeyError) as exc:
        row.update(status="error", reason=f"result file {job.output} unreadable ({exc})")
        return row
    row["result"] = str(job.output)
    return row


def _str(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def material_names(rows) -> list[str]:
    """Materials of all rows, in order of first appearance."""
    names: list[str] = []
    for r in rows:
        for m in r["materials"]:
            if m not in names:
                names.append(m)
    return names


def csv_header(materials) -> list[str]:
    cols = ["name", "specimen", "path", "status", "reason"]
    cols += [f"{m} {k} [{CONSTANT_UNITS[k]}]" for m in materials for k in CONSTANTS]
    return cols + ["rms_residual [%]", "evaluations", "time [s]", "cached", "result"]


def _gpa(key: str, value: float) -> float:
    return value if key == "nu12" else value / 1e9


def write_summary_csv(path, rows) -> Path:
    """One row per specimen; constants in GPa (nu12 plain), units in the header. The result
    column is relative to the CSV's folder. Written atomically."""
    import io

    path = Path(path)
    mats = material_names(rows)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(csv_header(mats))
    for r in rows:
        values = [r["name"], r["specimen"], r["path"], r["status"], r["reason"]]
        for m in mats:
            c = r["materials"].get(m, {})
            values += [repr(_gpa(k, c[k])) if k in c else "" for k in CONSTANTS]
        values += ["" if r["rms_residual_percent"] is None else f"{r['rms_residual_percent']:.6g}",
                   "" if r["evaluations"] is None else r["evaluations"],
                   "" if r["time_s"] is None else f"{r['time_s']:.3f}",
                   "yes" if r["cached"] else "no",
                   "" if not r["result"] else os.path.relpath(r["result"], path.parent)]
        w.writerow(values)
    return _write_text(path, buf.getvalue())


def batch_report(rows, options: BatchOptions, out_dir) -> dict:
    """The summary as plain data (SI), as written to summary.json and printed by --json."""
    counts = {s: sum(r["status"] == s for r in rows) for s in STATUSES}
    return {"format": "laminid-batch-summary", "laminid_version": __version__,
            "out": str(out_dir), "options": options.as_dict(), "n_specimens": len(rows),
            "counts": counts, "n_cached": sum(bool(r["cached"]) for r in rows),
            "specimens": rows}


def write_summary_json(path, report: dict) -> Path:
    return _write_text(Path(path), json.dumps(json_safe(report), indent=2) + "\n")


def json_safe(obj):
    """Copy with NaN/inf as None (JSON has no NaN)."""
    import math

    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _write_text(path: Path, text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))


def read_summary(path) -> list[dict]:
    """Rows of a summary.json or summary.csv (CSV constants converted back to SI; the result
    path made relative to the current folder)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise BatchError(f"{path}: not a readable batch summary ({exc})") from exc
        if not isinstance(doc, dict) or doc.get("format") != "laminid-batch-summary":
            raise BatchError(f"{path}: not a laminid batch summary (no format "
                             "'laminid-batch-summary')")
        rows = doc["specimens"]
        for r in rows:
            if r.get("result") and not Path(r["result"]).is_absolute() \
                    and not Path(r["result"]).exists():
                r["result"] = str(path.parent / Path(r["result"]).name)
        return rows
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            records = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise BatchError(f"{path}: not a readable batch summary ({exc})") from exc
    if not records or "status" not in records[0] or "name" not in records[0]:
        raise BatchError(f"{path}: not a laminid batch summary (columns name, status, ... "
                         "expected)")
    rows = []
    for rec in records:
        mats: dict[str, dict] = {}
        for col, val in rec.items():
            if col and col.endswith("]") and val not in ("", None):
                head = col.rsplit(" [", 1)[0]
                if " " in head and head.rsplit(" ", 1)[1] in CONSTANTS:
                    m, k = head.rsplit(" ", 1)
                    v = float(val)
                    mats.setdefault(m, {})[k] = v if k == "nu12" else v * 1e9
        res = rec.get("result") or None
        rows.append({"name": rec["name"], "specimen": rec.get("specimen", ""),
                     "path": rec.get("path", ""), "status": rec["status"],
                     "reason": rec.get("reason", ""), "cached": rec.get("cached") == "yes",
                     "materials": mats,
                     "rms_residual_percent": _float(rec.get("rms_residual [%]")),
                     "evaluations": _float(rec.get("evaluations")),
                     "time_s": _float(rec.get("time [s]")),
                     "result": str(path.parent / res) if res else None})
    return rows


def _float(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def format_table(rows) -> str:
    """The constants across specimens as text, shaped like the paper's Table 2: one block per
    set of materials, specimens as columns, constants as rows; failures listed below."""
    lines = []
    groups: dict[tuple, list] = {}
    for r in rows:
        if r["materials"]:
            groups.setdefault(tuple(r["materials"]), []).append(r)
    for mats, members in groups.items():
        specs = [r["specimen"] for r in members]
        labels = specs if all(specs) and len(set(specs)) == len(specs) else \
            [r["name"] for r in members]
        width = max(9, *(len(s) for s in labels))
        label_w = max(18, *(len(f"{m} {k} [GPa]") for m in mats for k in CONSTANTS)) \
            if len(mats) > 1 else 18
        head = ", ".join(mats)
        lines.append(f"{head:<{label_w}}" + "".join(f"  {s:>{width}}" for s in labels))
        for m in mats:
            for k in CONSTANTS:
                unit = "" if k == "nu12" else " [GPa]"
                name = f"{m} {k}{unit}" if len(mats) > 1 else f"{k}{unit}"
                cells = []
                for r in members:
                    v = r["materials"][m][k]
                    cells.append(f"{v:.3f}" if k == "nu12" else f"{v / 1e9:.2f}")
                lines.append(f"{name:<{label_w}}" + "".join(f"  {c:>{width}}" for c in cells))
        lines.append(f"{'RMS residual [%]':<{label_w}}" + "".join(
            f"  {r['rms_residual_percent']:>{width}.3f}" for r in members))
        lines.append(f"{'evaluations':<{label_w}}" + "".join(
            f"  {int(r['evaluations']):>{width}d}" for r in members))
        lines.append(f"{'status':<{label_w}}" + "".join(
            f"  {('cached' if r['cached'] and r['status'] == 'ok' else r['status']):>{width}}"
            for r in members))
        lines.append("")
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        lines.append("not identified:" if any(r["status"] != "not converged" for r in failed)
                     else "not converged:")
        for r in failed:
            reason = r["reason"] or ""
            text = reason if reason.startswith(r["status"]) else \
                f"{r['status']}: {reason}" if reason else r["status"]
            lines.append(f"  {r['name']}: {text}")
    return "\n".join(lines).rstrip() + "\n"
