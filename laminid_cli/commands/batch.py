"""``laminid batch``: identify every specimen of folders or file lists, in parallel."""

from __future__ import annotations

import click

from laminid_cli.commands._common import (echo_json, fit_options, json_option,
                                          folder_writable, pass_run_options, quiet,
                                          uncertainty_options)


@click.command(short_help="Identify many specimens in parallel, with a summary table.")
@click.argument("inputs", nargs=-1, required=True, type=click.Path())
@click.option("-j", "--jobs", "n_jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="Worker processes (Dask workers with --scheduler local). With 1 the "
                   "specimens run one after the other in this process, each one's profiles "
                   "and Monte Carlo trials on all cores; with more, one specimen per "
                   "process.")
@click.option("--out", "out_dir", type=click.Path(), default="laminid-results",
              show_default=True, help="Folder of the result files and summary.csv/.json.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Run on Dask: 'local' starts a local cluster of -j workers, "
                   "tcp://HOST:PORT uses a running scheduler (pip install 'laminid[dask]'). "
                   "Workers must see the specimen files at the same paths.")
@fit_options
@uncertainty_options
@click.option("--force", is_flag=True,
              help="Identify every specimen again, also those whose result in OUT is up to "
                   "date (same specimen and FRF file, options and laminid version). Without "
                   "it only new and changed specimens run; their results are replaced either "
                   "way (a batch's results are derived files). Not 'overwrite the output' as "
                   "in identify -o, modes, export, acquire.")
@click.option("--wide", is_flag=True,
              help="summary.csv with one row per specimen (a column per constant, then its "
                   "interval's ends and its verdict: 'IM7/977-2 E2 lower [Pa]', '... upper "
                   "[Pa]', '... verdict') instead of one row per specimen, material and "
                   "constant; its column 'flagged' names the constants at a bound, "
                   "undetermined, fixed or held by their prior; after it each constant's "
                   "bound_side, bound_limit, profile_bound, profile and profile_far (as the "
                   "long form's: '... G13 profile_bound [Pa]', empty when not at a bound), "
                   "with --monte-carlo its range ('... mc_lower [Pa]', '... "
                   "mc_upper [Pa]', '... mc_search_limit'), then the ply loss factors where "
                   "damping was measured ('IM7/977-2 eta22 [1]', its interval, verdict and "
                   "range).")
@click.option("--mesh-check", is_flag=True,
              help="As identify --mesh-check, for each specimen alone: after its "
                   "identification, solve its model on a mesh twice as fine at the identified "
                   "constants; its result file gets /mesh_check, a constant shifted beyond 0.3 "
                   "of its 95 % half-width makes it 'check' (coarse_mesh), and the summaries "
                   "get the largest frequency change in sigmas and the largest shift in "
                   "half-widths (mesh_max_change_sigma, mesh_max_shift_half_width; the long "
                   "summary.csv also each constant's mesh_shift_half_width).")
@json_option
@pass_run_options()
def batch(inputs, n_jobs, out_dir, scheduler, options, force, wide, mesh_check, as_json):
    """Identify every specimen in INPUTS (folders searched recursively for *.yaml/*.yml,
    links to folders followed, or files) as 'laminid identify' does (same options, same
    uncertainty assessment),
    writing OUT/<folder>/<name>.result.h5 per specimen
    (folders relative to the inputs' common root) and OUT/summary.csv and summary.json
    (SI units: summary.csv has one row per specimen, material and constant with value,
    interval, verdict, flag (at_bound, undetermined, fixed or prior: no plain identified
    value), the Monte Carlo range with --monte-carlo (mc_search_limit: its ends set by
    trials on a search limit), unit and status, then the ply loss factors where damping
    was measured; --wide one row per specimen, each constant's value, interval and verdict,
    then its side of a bound, its limit and profile, its Monte Carlo range and the loss
    factors;
    both forms the run options, as summary.json's
    "options", in '#' lines above the header; summary.json a units map). Every result has a
    status, ok or check with its reasons, shown in the table, and its warnings (the specimen
    file's, the run's) are listed below the table (less the specimen file's that this run
    wrote on stderr as it read the file).

    A result whose input has not changed (sha256 of the specimen and its FRF file, the
    options and the laminid version, stored in the file) is not redone unless --force (which
    redoes every specimen). A failing specimen is listed with its reason and the others go
    on; a result it still has in OUT (an earlier input's) is renamed
    <name>.result.stale.h5 (.stale1.h5, ... when that exists), out of the *.result.h5
    pattern, and named in the table and the summaries (stale_result); so is that of a
    specimen an interrupted batch (Ctrl-C, SIGTERM) did not reach, while every finished
    result stays.
    Result files in OUT that no specimen of the inputs has (its file removed, or another
    batch's) are kept and listed as 'not from this batch'. Specimen files that hold one
    plate's measured data (a file copied under another name) are warned of, once per group,
    and listed in summary.json ('duplicates'); both still run. A file that can be no
    specimen (a result, FRF or modes file: HDF5; a PDF, ...) is refused when named among
    INPUTS, before anything runs (exit 2, naming each and what it is), and skipped with a
    warning when a folder holds it as *.yaml, as is an entry so named that is no file (a
    folder with no specimen in it, a broken link). Exit code 0 when all converged (status ok or
    check), 1 when any failed or did not converge, 2 for bad usage (no specimen found, a
    file named that is no specimen); 130 after Ctrl-C and 143 after SIGTERM (kill, timeout,
    a scheduler's time limit), each of which stops the batch with both summaries written
    and the table printed.

    \b
    Examples:
      laminid batch specimens/ -j 2
      laminid batch plates/*.yaml --out results --fix nu12,G13,G23
      laminid batch plates/ --mesh 8x8 --mesh-check
      laminid batch study/ --scheduler tcp://10.0.0.5:8786 -j 64
    """
    from laminid_cli.batch import sigterm_stops_the_batch

    # SIGTERM (kill, timeout, a scheduler's time limit) ends the batch as Ctrl-C does, exit 143
    with sigterm_stops_the_batch():
        _batch(inputs, n_jobs, out_dir, scheduler, options, force, wide, mesh_check, as_json)


def _batch(inputs, n_jobs, out_dir, scheduler, options, force, wide, mesh_check, as_json):
    import contextlib
    import os
    import sys
    import time
    from pathlib import Path

    from laminid_cli.atomic import write_bytes_atomic
    from laminid_cli.batch import (NOT_FROM_BATCH, SUMMARY_CSV, SUMMARY_EVERY, SUMMARY_JSON,
                                   BatchError, batch_report, batch_settings,
                                   check_fix_materials,
                                   check_scheduler, discover_specimens, duplicate_specimens,
                                   duplicate_text, failed, foreign_results, foreign_row,
                                   format_table, load_specimen_docs, non_specimens_message,
                                   lock_out_folder, pending_row, plan_batch, printable,
                                   release_out_folder, remove_stale_parts, result_row,
                                   run_jobs, set_aside_result, sort_out_non_specimens,
                                   stored_hash, write_summary_csv, write_summary_json)
    from laminid_cli.batch import _interruption as interruption
    from laminid_cli.batch import _note_sigint as note_sigint
    from laminid_cli.errors import escaped

    def _unfinished_row(job):
        """The row of a job this run did not finish (Ctrl-C, a lost scheduler)."""
        if stored_hash(job.output) == job.key:
            return result_row(job, cached=True)
        return result_row(job, stale=set_aside_result(job))

    import dataclasses

    from laminid_cli.batch import SPECIMEN_JOBS

    # bad --mesh, --sigma-rel...: exit 2 at once (remote Dask workers check their own memory);
    # the options are those of identify, with the Monte Carlo trials in each specimen's worker
    # (and its mesh check: one plate each, as identify without --joint)
    options = dataclasses.replace(options, mesh_check=mesh_check)
    if scheduler is None:
        # one specimen at a time, in this process: its profiles and Monte Carlo trials get
        # the cores, as in identify (hybrid CM's five profiles one after the other took 37 s
        # of its 44 s); on several worker processes each specimen's get SPECIMEN_JOBS of
        # them (below); the results are the same either way (input_hash counts it as 1)
        options = dataclasses.replace(options, uncertainty=dataclasses.replace(
            options.uncertainty, jobs=None if n_jobs == 1 else SPECIMEN_JOBS))
    options.check(copies=n_jobs if scheduler in (None, "local") else 1)
    options.check_fix()           # a --fix wrong for every specimen: not each one 'failed'
    if scheduler is not None:
        check_scheduler(scheduler)
    if not str(out_dir).strip():        # Path("") is the current folder
        raise BatchError("--out: the folder name is empty; name the folder of the results "
                         "(default: laminid-results)")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise BatchError(f"--out {out}: exists and is not a folder")
    passed_over: list = []              # entries named *.yaml that are no files: said
    specimens = discover_specimens(inputs, exclude=[out], skipped=passed_over)
    # a result, FRF or modes file (HDF5), a PDF... ran as a specimen and failed as one: one
    # named is refused before anything runs, one a folder holds as *.yaml is skipped, said
    specimens, named, found = sort_out_non_specimens(specimens, inputs)
    if named:
        raise BatchError(printable(non_specimens_message(named)))
    if not quiet():
        for path, what in sorted(found + passed_over, key=lambda t: str(t[0])):
            click.echo(escaped(printable(f"warning: {path}: {what}; skipped")), err=True)
    if not specimens:
        raise BatchError(printable(f"no specimen file (*.yaml, *.yml) found in "
                                   f"{escaped(', '.join(inputs))}"))
    docs = load_specimen_docs(p for p, _ in specimens)        # read once for both checks
    check_fix_materials([p for p, _ in specimens], options, docs)  # before anything is touched
    # one plate's data in two files (a copy under another name): said, recorded, still run
    duplicates = [[specimens[i] for i in g]
                  for g in duplicate_specimens([p for p, _ in specimens], docs)]
    if not quiet():
        for group in duplicates:
            click.echo(escaped(printable(f"warning: {duplicate_text(p for p, _ in group)}")),
                       err=True)
    duplicates = [[name for _, name in group] for group in duplicates]
    if out.is_symlink() and not out.exists():
        # mkdir said only "cannot create the folder (File exists)" of a link to nothing
        raise BatchError(f"--out {out}: a symbolic link to {os.readlink(out)}, which does not "
                         "exist; create that folder, or choose another place with --out")
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BatchError(f"--out {out}: cannot create the folder ({exc.strerror or exc}); "
                         "choose another place with --out") from None
    # a folder the results cannot be written to: refused before any specimen runs (it failed
    # at the first result, and then again on the summaries, naming their temporary file)
    if not folder_writable(out):
        raise BatchError(f"--out {out}: the folder cannot be written to (permissions, a "
                         "read-only or special file system); choose another place with --out")
    # one batch at a time in a folder: a second one is refused here, before it reads or moves
    # anything; the lock goes with this command (or its process, however it ends)
    held_out = lock_out_folder(out)
    if held_out is not None:
        click.get_current_context().call_on_close(lambda: release_out_folder(held_out))
    remove_stale_parts(out)
    jobs = plan_batch(specimens, out, options, force=force)
    todo = [j for j in jobs if not j.up_to_date]
    rows = {j.name: result_row(j, cached=True) for j in jobs
            if j.up_to_date}
    shown = not quiet()                    # -q: only errors on stderr
    if not as_json and shown:
        unit = "worker" if scheduler else "process"
        # (local processes: no more than the specimens to identify, as run_jobs starts them;
        # '1 to identify on 2 processes' said otherwise)
        used = n_jobs if scheduler else max(1, min(n_jobs, len(todo)))
        unit = unit if used == 1 else unit + ("s" if scheduler else "es")
        # a running Dask scheduler has the workers it has (-j does not apply to it): say
        # where the jobs go, and that connecting may take its time (up to 20 s)
        where = (f" on the Dask scheduler {scheduler} (connecting)"
                 if scheduler and scheduler != "local" else f" on {used} {unit}")
        click.echo(f"{len(jobs)} specimen{'' if len(jobs) == 1 else 's'}, "
                   f"{len(jobs) - len(todo)} up to date, {len(todo)} to identify"
                   + (where if todo else ""), err=True)

    def show(item):
        return item or ""

    # the summary rows read the result files back (h5py), from the first finished job on and in
    # the `finally` below after a Ctrl-C: imported here, before any job runs, so that an
    # interrupt cannot land inside its import. One that did left h5py half-initialised, and the
    # summary's own import then failed with a traceback (KeyError '__reduce_cython__', exit 1
    # instead of 130; seen once in test_killed_batch..., whose SIGINT follows the first result)
    import h5py  # noqa: F401

    # how the batch runs (-j, --scheduler), beside the options in the summaries: their
    # uncertainty.jobs (1 on several workers) is each specimen's, not the batch's
    settings = batch_settings(n_jobs, scheduler)
    finished = 0
    on_stderr: dict = {}                   # format_table's
    refused = False
    interrupted = False                    # or the KeyboardInterrupt / Terminated that stopped it
    ended = False                          # the run ended, or a Ctrl-C ended it: a table follows
    written = [0.0]                        # when the summaries were last written while running

    def write_running(force: bool = False):
        """The summaries of the run so far (finished specimens, up-to-date ones, the others
        pending_row), written before the run's first result file and at most every
        SUMMARY_EVERY seconds after a specimen finishes: a batch killed mid-run leaves
        summaries that agree with its result files (those it replaced since show as not
        finished), not the run before it's."""
        now = time.monotonic()
        if not force and now - written[0] < SUMMARY_EVERY:
            return
        current = [rows.get(j.name) or pending_row(j) for j in jobs]
        write_summary_csv(out / SUMMARY_CSV, current, wide=wide,
                          options=options.as_dict(), batch=settings)
        write_summary_json(out / SUMMARY_JSON,
                           batch_report(current, options, out, running=True,
                                        duplicates=duplicates, batch=settings))
        written[0] = time.monotonic()

    try:
        # no bar (not even its label) when every result is up to date, nor under -q; on a
        # log or pipe (no terminal) a line per finished specimen instead: click's bar writes
        # only its label there ("identifying", then nothing until the table)
        logged = bool(todo and shown and not sys.stderr.isatty())
        with click.progressbar(length=len(todo), label="identifying", file=sys.stderr,
                               item_show_func=show, show_pos=True) \
                if todo and shown and not logged else contextlib.nullcontext() as bar:
            for job, outcome in run_jobs(todo, options, n_jobs=n_jobs, scheduler=scheduler):
                if not written[0]:
                    # before this run changes a result file (none changes before: a refused
                    # scheduler leaves the folder as it was)
                    write_running(force=True)
                if outcome.data is not None:
                    write_bytes_atomic(job.output, outcome.data, parents=True)
                # a failing specimen gets no result: one at its name is an earlier input's
                stale = set_aside_result(job) if outcome.status == "error" else (None, "")
                rows[job.name] = result_row(job, outcome, stale=stale)
                if scheduler in (None, "local"):
                    # its specimen's warnings went to this terminal (a remote Dask worker's
                    # log is its own)
                    on_stderr[job.name] = outcome.n_logged
                finished += 1
                write_running()
                if bar is not None:
                    bar.update(1, printable(f"{job.name}: {outcome.status}"))
                elif logged:
                    click.echo(printable(f"identified {finished}/{len(todo)}: {job.name}: "
                                         f"{outcome.status}"), err=True)
        ended = True
    except BatchError:   # e.g. --scheduler unreachable: nothing ran, so nothing is written
        refused = finished == 0
        raise
    except KeyboardInterrupt as exc:
        # Ctrl-C (or SIGTERM, Terminated): the summaries, the table (or --json) of what was
        # done, then exit 130 (143)
        interrupted, ended = exc, True
    finally:
        # from here to the table a Ctrl-C or SIGTERM (a second one, or one as the last specimen
        # finished) is noted, not raised: raised while the summaries were written, it left no
        # table and a summary.csv of the finished run beside a summary.json of the running one,
        # or both still 'running' with every result there; now exit 130 (143) after the table
        held, release = note_sigint(raise_=False)
        try:
            if refused:
                if created:
                    with contextlib.suppress(OSError):
                        out.rmdir()
            else:
                # also on Ctrl-C: the summary lists what was done ('not run' for the rest). A
                # result this run did not reach is kept when it is this input's (--force redoing
                # it); another input's is set aside as a failing specimen's, so that no
                # *.result.h5 beside this summary is older than its input. Results of specimens
                # not in this batch are named, not moved (another batch's may share --out).
                ordered = [rows.get(j.name) or _unfinished_row(j) for j in jobs]
                ordered += [foreign_row(p, out) for p in foreign_results(out, jobs)]
                report = batch_report(ordered, options, out, interrupted=bool(interrupted),
                                      stopped_by=_signal_name(interrupted),
                                      duplicates=duplicates, batch=settings)
                write_summary_csv(out / SUMMARY_CSV, ordered, wide=wide,
                                  options=options.as_dict(), batch=settings)
                write_summary_json(out / SUMMARY_JSON, report)
                # once more at the end: a killed run's worker may still have been exiting at the
                # start (its temporary file then counted as a live process's)
                remove_stale_parts(out)
        except BaseException:
            release()
            raise
        if not ended:                 # an error on its way out of the run: no table follows
            release()
    try:
        if as_json:
            echo_json(report)
        else:
            click.echo(format_table(ordered, on_stderr), nl=False)
            c = report["counts"]
            click.echo(f"\n{c['ok']} ok, {c['check']} check ({c['not converged']} not converged), "
                       f"{c['error']} failed ({report['n_cached']} up to date"
                       + (f"; {c['set aside']} earlier result{'' if c['set aside'] == 1 else 's'}"
                          " set aside" if c["set aside"] else "")
                       + (f"; {c[NOT_FROM_BATCH]} result file"
                          f"{' is' if c[NOT_FROM_BATCH] == 1 else 's are'} not from this batch"
                          if c[NOT_FROM_BATCH] else "")
                       + (f"; {c['not run']} not run: {_stop_words(interrupted)}"
                          if interrupted else "")
                       + f"); summary: {out / SUMMARY_CSV}")
    finally:
        release()
    if interrupted:
        raise interrupted
    if held:
        raise interruption(held)
    if failed(ordered):
        sys.exit(1)


def _signal_name(stop) -> str | None:
    """The signal that stopped the batch (``stop``: its KeyboardInterrupt, or False)."""
    from laminid_cli.errors import Terminated

    if not stop:
        return None
    return "SIGTERM" if isinstance(stop, Terminated) else "SIGINT"


def _stop_words(stop) -> str:
    """How the table's last line names the stop: Ctrl-C's 'interrupted', SIGTERM's own."""
    return "terminated (SIGTERM)" if _signal_name(stop) == "SIGTERM" else "interrupted"
