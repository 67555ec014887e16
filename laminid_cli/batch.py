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
3. :func:`run_job` (in a worker process: a process pool or a Dask worker) runs the pipeline of
   ``laminid identify SPEC -o OUT`` (laminid_cli.pipeline, the same code) and returns the
   finished HDF5 file (as bytes for a Dask or in-process run) plus its status; it never raises
   for a specimen's fault (bad YAML, infeasible start, no convergence);
4. the file is written atomically (laminid_cli.atomic: temporary name in the target folder,
   fsync, rename) by the pool worker, or by the client from the bytes. Killing the batch at
   any instant leaves either no file or a complete one. A specimen that fails gets no file,
   and :func:`set_aside_result` renames the one an earlier input left at its name out of the
   ``*.result.h5`` pattern (``<name>.result.stale.h5``), so that no result beside this run's
   summary is older than it; so does a specimen an interrupted run did not reach (its file
   kept when it is this input's: --force redoing it). Result files in the output folder that
   no job has (:func:`foreign_results`) get a row "not from this batch" and are not moved;
5. :func:`result_row` reads the numbers of the summary back from each result file with the
   typed reader (laminid_cli.resultfile: values, intervals, verdicts, the status and its
   reasons); :func:`write_summary_csv` (long form: one
   row per specimen, material and constant; ``wide=True`` one row per specimen),
   :func:`write_summary_json` and :func:`format_table` give the table across specimens (the
   shape of the paper's Table 2: specimens as columns, undetermined values marked).

Units: SI everywhere in the files (Pa, 1, %, s). summary.json has a ``units`` map, the long CSV
a ``unit`` column, the wide CSV the unit in each header ("IM7/977-2 E1 [Pa]", then the
interval's "IM7/977-2 E1 lower [Pa]", "IM7/977-2 E1 upper [Pa]" and "IM7/977-2 E1 verdict").
The terminal table shows GPa.

Status of a row: "ok" or "check" (the result's status, laminid_cli.status; a run that did not
converge is "check" with reason ``not_converged``), "error" (no result: bad input, crash),
"not run" (interrupted batch) or "not from this batch" (a result file in the output folder of a
specimen not among the inputs; its path in ``stale_result``).

h5py and the solver are imported where they are used (the option classes bring numpy in).
"""

from __future__ import annotations

import collections
import contextlib
import csv
import hashlib
import json
import logging
import os
import re
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from laminid_cli import __version__
from laminid_cli.atomic import (remove_stale_temporaries, stop_with_parent, temporary_name,
                                write_bytes_atomic)
# sigterm_stops_the_batch: SIGTERM stops the batch as Ctrl-C does (the command's block;
# _note_sigint notes it)
# the loss factors' names
from laminid_cli.damping import LOSS_NAMES
from laminid_cli.errors import NON_PRINTABLE, LaminidError, Terminated, note_stop_signals
from laminid_cli.errors import sigterm_raises_terminated as sigterm_stops_the_batch  # noqa: F401
from laminid_cli.intervals import (FLAG_ASSUMED, FLAG_AT_BOUND, FLAG_FIXED, FLAG_LEANS,
                                   FLAG_PRIOR, FLAG_UNDETERMINED, HELD_BY_PRIOR, VERDICT_AT_BOUND,
                                   VERDICT_FIXED, flag_word)
from laminid_cli.pipeline import RunOptions
# imported here, not on the first summary row: a Ctrl-C landing in an import (in the code
# a dataclass definition executes) can turn the exit code 130 into a kill by SIGINT (-2)
from laminid_cli.resultfile import ResultFileError, read_result

log = logging.getLogger(__name__)

CONSTANTS = ("E1", "E2", "G12", "G13", "G23", "nu12")
#: SI units of the summary files (the terminal table shows GPa)
CONSTANT_UNITS = {"E1": "Pa", "E2": "Pa", "G12": "Pa", "G13": "Pa", "G23": "Pa", "nu12": "1"}
#: the ``units`` map of summary.json
UNITS = {**CONSTANT_UNITS, "lower": "unit of the constant", "upper": "unit of the constant",
         "bound_limit": "unit of the constant", "profile_bound": "unit of the constant",
         "profile_far": "unit of the constant",
         "mc_lower": "unit of the constant", "mc_upper": "unit of the constant",
         "rms_residual_percent": "%", "time_s": "s",
         "max_change_percent": "%", "max_change_sigma": "frequency sigma of the mode",
         "max_shift_half_width": "95 % half-width of the constant",
         "mesh_shift_half_width": "95 % half-width of the constant",
         **{f"eta{k}": "1 (loss factor, eta = 2 zeta)" for k in ("11", "22", "12", "13", "23")}}
#: the columns of the long summary.csv: lower/upper the linearised interval (empty for a
#: constant at its bound), flag what the value is when it is no plain identified one, in a
#: word a script can test (:func:`flag_word`: at_bound, undetermined, fixed, assumed, prior,
#: leans (a loss factor's interval too narrow); empty for an identified value), bound_side/bound_limit of a constant at its bound (the data
#: push it below a "lower" limit, above an "upper" one; no interval), profile_bound where the fit
#: rejects it (uncertainty.Profile) and profile what its profile says ("bound": the fit
#: rejects it beyond profile_bound; "flat": nowhere within its scan, the modes do not
#: determine it there; "none": no profile could be made, its result file says why; resultfile.
#: profile_kind) and profile_far the other end of its scan (a flat profile does not reject any
#: value from the limit to there; nothing beyond was tried; empty where no profile was made,
#: its scan reached nowhere), mc_lower/mc_upper the Monte Carlo
#: range (--monte-carlo), mc_search_limit which of its ends ("lower", "upper", "both") trials
#: on a limit of the search set (the search's end, not the data's)
LONG_COLUMNS = ("name", "specimen", "material", "constant", "value", "lower", "upper", "verdict",
                "flag", "bound_side", "bound_limit", "profile_bound", "profile", "profile_far",
                "mc_lower", "mc_upper",
                "mc_search_limit", "unit",
                "status", "reasons", "rms_residual [%]", "result", "stale_result")
#: the columns a summary.csv gets after those above (long) or before ``flagged`` (wide) when
#: the batch ran with --mesh-check (a summary without it keeps its columns):
#: mesh_shift_half_width (long only) the constant's first-order shift on the mesh twice as fine
#: in units of its 95 % half-width (signed; laminid_cli.meshcheck), mesh_max_change_sigma the
#: specimen's largest |frequency change| there in units of the mode's sigma,
#: mesh_max_shift_half_width its largest |shift| in half-widths (beyond meshcheck.SHIFT_LIMIT:
#: the reason coarse_mesh in status/reasons)
MESH_LONG_COLUMNS = ("mesh_shift_half_width", "mesh_max_change_sigma",
                     "mesh_max_shift_half_width")
MESH_WIDE_COLUMNS = ("mesh_max_change_sigma", "mesh_max_shift_half_width")
SPECIMEN_SUFFIXES = (".yaml", ".yml")
RESULT_SUFFIX = ".result.h5"
SUMMARY_CSV = "summary.csv"
SUMMARY_JSON = "summary.json"
HASH_ATTR = "batch_input_sha256"
#: status of a row naming a result file in --out that no specimen of this batch has (its
#: specimen removed from the inputs, or one of another batch into the same --out): kept as it
#: is, named so that it is not taken for this batch's
NOT_FROM_BATCH = "not from this batch"
#: statuses of a summary row; "error", "not run" and a run that did not converge make the
#: batch exit with 1 ("check" alone does not: the reasons say what to look at; nor does a file
#: not from this batch)
STATUSES = ("ok", "check", "error", "not run", NOT_FROM_BATCH)


class BatchError(LaminidError):
    """A batch cannot run: no specimen found, bad output folder, no Dask (exit code 2)."""


#: The settings every specimen of a batch is identified with: those of ``laminid identify``
#: (laminid_cli.pipeline.RunOptions: the mesh, IdentifyOptions, UncertaintyOptions and the
#: loss factors held by --fix). With one worker (``-j 1``, in the command's process) a
#: specimen's Monte Carlo trials and profiles get the cores, as in identify; on several worker
#: processes SPECIMEN_JOBS each; on Dask's workers (daemonic processes, which may start none)
#: one, in the worker.
BatchOptions = RunOptions

#: processes of one specimen's Monte Carlo trials and profiles when the batch runs on several
#: worker processes (``uncertainty.jobs``): 2, so that a slow specimen (hybrid CM: five
#: profiles, ~30 s of CPU, against 1-3 s for a one-material plate) gets the cores the other
#: workers leave as they run out of specimens. With 1, the batch of the eight paper plates at
#: -j 2 took longer than at -j 1 (36.5 against 28.0 s: hybrid CM's profiles one after the
#: other at the end); with every worker busy the machine runs up to twice as many processes
#: as workers, for as long as two specimens' profiles overlap
SPECIMEN_JOBS = 2


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
    """What a worker returns: status ("ok" | "check" | "error"), the reason of a failure or
    the reason codes of a check, the result file's bytes (None on error) and the wall time.
    ``n_logged``: how many of the result's first warnings (the specimen reader's) the worker
    logged as it read the file (0 where its log level hides warnings: -q)."""

    name: str
    status: str
    reason: str = ""
    data: bytes | None = field(default=None, repr=False)
    time_s: float = 0.0
    n_logged: int = 0


# ----------------------------------------------------------------------------------------------
# discovery, hashing, planning


def discover_specimens(inputs, exclude=(), skipped: list | None = None
                       ) -> list[tuple[Path, str]]:
    """Specimen files of the inputs and their unique names.

    Parameters
    ----------
    inputs : files and folders; folders are searched recursively for ``*.yaml``/``*.yml``
        (hidden files and folders skipped, symbolic links to folders followed, each folder
        once), files are taken whatever their suffix
    exclude : folders not to search (the output folder) where they lie below an input folder
        (an input folder inside one, or itself one, is searched: results beside specimens)
    skipped : a list to which (path, what) is appended of each entry of an input folder
        named ``*.yaml``/``*.yml`` that is no specimen file: a folder that holds none (a
        folder named x.yaml is searched like any other; one with nothing taken from it was
        passed over without a word), a broken symbolic link, not a regular file

    Returns
    -------
    list of (path, name), sorted by name; name = path relative to the common folder of all
    inputs, without the suffix, with '/' separators; with the suffix where two files differ
    only in theirs (plate.yaml and plate.yml: names "plate.yaml" and "plate.yml"), so the names
    are unique.
    """
    exclude = [Path(e).resolve() for e in exclude]
    found: dict[Path, Path] = {}          # resolved -> as found
    # resolved -> where it lies below the resolved input folder: a symbolic link in a folder
    # to a specimen file elsewhere is named by the link, not by its target's place
    placed: dict[Path, Path] = {}
    roots = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            roots.append(p.resolve())
            below = [e for e in exclude if not _inside(p.resolve(), e)]
            folders: list[Path] = []
            taken = []
            for f in sorted(_files_below(p, folders)):
                rel = f.relative_to(p)
                if f.suffix.lower() not in SPECIMEN_SUFFIXES \
                        or any(_inside(f.resolve(), e) for e in below):
                    continue
                if f.is_file():
                    found.setdefault(f.resolve(), f)
                    placed.setdefault(f.resolve(), p.resolve() / rel)
                    taken.append(f)
                elif skipped is not None:
                    skipped.append((f, "a broken symbolic link, not a specimen file" if
                                    f.is_symlink() and not f.exists() else
                                    "not a regular file, so not a specimen file"))
            if skipped is not None:
                skipped += [(d, "a folder, not a specimen file (YAML text), with no specimen "
                                "file in it") for d in folders
                            if d.suffix.lower() in SPECIMEN_SUFFIXES
                            and not any(_inside(d.resolve(), e) for e in below)
                            and not any(_inside(t, d) for t in taken)]
        elif p.exists():
            roots.append(p.resolve().parent)
            found.setdefault(p.resolve(), p)
            placed.setdefault(p.resolve(), p.resolve())
        else:
            from laminid_cli.pipeline import fix_list_hint

            raise BatchError(f"{p}: no such file or folder{fix_list_hint(p)}", path=p)
    if not found:
        return []
    root = Path(os.path.commonpath([str(r) for r in roots]))
    rels = {resolved: (resolved if _inside(resolved, root) else placed[resolved]
                       ).relative_to(root) for resolved in found}
    names = {r: rel.with_name(rel.name[: -len(rel.suffix)] if rel.suffix else rel.name
                              ).as_posix() for r, rel in rels.items()}
    # plate.yaml and plate.yml (or plate) in one folder: their names keep the suffix, so that
    # neither result file overwrites the other
    count = collections.Counter(names.values())
    out = [(as_found, names[r] if count[names[r]] == 1 else rels[r].as_posix())
           for r, as_found in found.items()]
    return sorted(out, key=lambda t: t[1])


def _files_below(folder: Path, folders: list | None = None):
    """The paths below ``folder`` that are no folders, hidden names (and what is below them)
    skipped. A symbolic link to a folder is followed (pathlib's rglob skipped it, and with it
    every specimen of a lab's linked folder, without a word), each real folder once, so that a
    link to a folder above it ends there rather than going round. The folders below it are
    appended to ``folders`` as they are searched."""
    seen = set()

    def walk(d: Path):
        real = os.path.realpath(d)
        if real in seen:
            return
        seen.add(real)
        try:
            entries = sorted(os.scandir(d), key=lambda e: e.name)
        except OSError:                     # unreadable: as rglob, nothing below it
            return
        for entry in entries:
            if entry.name.startswith("."):
                continue
            path = d / entry.name
            try:
                is_dir = entry.is_dir()     # through a symbolic link
            except OSError:
                is_dir = False
            if is_dir:
                if folders is not None:
                    folders.append(path)
                yield from walk(path)
            else:
                yield path

    yield from walk(Path(folder))


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.relative_to(folder)
        return True
    except ValueError:
        return False


#: what batch takes, for the messages on files it does not
BATCH_TAKES = ("batch identifies specimen files (YAML text), named or found in folders "
               "(*.yaml, *.yml)")


def sort_out_non_specimens(specimens, inputs) -> tuple[list, list, list]:
    """(specimens, named, found): the (path, name) of :func:`discover_specimens` that may be
    specimen files, and those that can be none
    (:func:`~laminid_cli.specimen.non_specimen_text`) as (path, what): ``named`` those the
    ``inputs`` name (the command refuses them: a result or FRF file among the files given is
    a slip to be told before anything runs), ``found`` those found in an input folder (a
    ``*.yaml`` that is none: skipped with a warning)."""
    from laminid_cli.errors import escaped, non_printable
    from laminid_cli.specimen import non_specimen_text

    named_inputs = {Path(i).resolve() for i in inputs if Path(i).is_file()}
    kept, named, found = [], [], []
    for path, name in specimens:
        what = non_specimen_text(path)
        is_named = Path(path).resolve() in named_inputs
        bad = non_printable(name)
        if bad is not None:
            # the batch name, from the file's path, is printed and written into the summaries
            # and the result's file name: a right-to-left override in it went there as it was
            what = (f"its batch name '{escaped(name)}', from the file's path: {bad} in it; "
                    "rename the file")
            path = escaped(str(path))
        if what is None:
            kept.append((path, name))
        elif is_named:
            named.append((path, what))
        else:
            found.append((path, what))
    return kept, named, found


def non_specimens_message(named) -> str:
    """The refusal of input files that are no specimen files ((path, what) each)."""
    if len(named) == 1:
        path, what = named[0]
        return f"{path}: {what}; {BATCH_TAKES}: leave it out of the inputs"
    lines = [f"{len(named)} of the inputs are not specimen files; {BATCH_TAKES}: leave them "
             "out of the inputs (a folder given is searched for *.yaml, *.yml only: laminid batch "
             "FOLDER)"]
    lines += [f"  {path}: {what}" for path, what in named]
    return "\n".join(lines)


def _specimen_doc(spec):
    """A specimen file as plain YAML data; None where it cannot be read or parsed (its error
    is the specimen's own, reported with its line when it runs; ValueError and OverflowError:
    a value PyYAML's constructor refuses, e.g. the date 2024-13-45)."""
    import yaml

    try:
        return yaml.safe_load(Path(spec).read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError, ValueError, OverflowError):
        return None


def _frf_file(spec: Path, doc=None) -> Path | None:
    """The FRF file a specimen takes its frequencies from (``measured.frf_file``), if any;
    ``doc``: the file's YAML data when already read (:func:`load_specimen_docs`)."""
    if doc is None:
        doc = _specimen_doc(spec)
    try:
        name = doc["measured"]["frf_file"]
    except (KeyError, TypeError):
        return None
    return spec.parent / str(name) if name else None


def load_specimen_docs(specs) -> list:
    """Each specimen file as plain YAML data (None where it cannot be read or parsed:
    :func:`_specimen_doc`), read once for the checks the batch makes before it runs
    (:func:`check_fix_materials`, :func:`duplicate_specimens`)."""
    return [_specimen_doc(spec) for spec in specs]


def _material_names(doc) -> tuple[str, ...] | None:
    """The material names of a specimen's YAML data (``materials``' keys); None when it has
    none readable (its error is the specimen's own, reported when it runs)."""
    try:
        return tuple(str(k) for k in doc["materials"])
    except (KeyError, TypeError):
        return None


def check_fix_materials(specs, options: BatchOptions, docs=None) -> None:
    """Refuse a --fix item naming a material (``carbon.G13``, ``carbon.eta13=0.01``) that no
    readable specimen of the batch has: a mistyped option, not a failure of each specimen
    (which would set their earlier results aside as another input's). A material some of the
    specimens have applies to those; the others fail with the reason. ``docs``: the files'
    :func:`load_specimen_docs`, read here when not given."""
    docs = load_specimen_docs(specs) if docs is None else docs
    names = [n for n in map(_material_names, docs) if n is not None]
    if not names:
        return
    have = {m for n in names for m in n}
    for item in (*options.identify.fix, *options.fix_loss):
        key = item.split("=", 1)[0].strip()
        mat = key.rsplit(".", 1)[0] if "." in key else None
        if mat is not None and mat not in have:
            raise BatchError(f"--fix {item.strip()}: no specimen of the batch has a material "
                             f"'{mat}' (materials: {', '.join(sorted(have))})")


def _measured_plate(doc):
    """What a specimen's YAML data say of the plate that was measured, comparable across
    files: the sides and thickness and the mass in SI, the layup expanded (``[0/90]s`` and
    ``[0/90/90/0]`` alike) or the plies as written, and the measured frequencies in Hz with
    their weights (1 where not given, 0 for a mode not detected), or for an ``frf_file`` its
    ``bands`` and ``modes`` (the file's bytes are compared by :func:`duplicate_specimens`).
    None where these cannot be read (the specimen
    fails on its own when it runs) or the file has no measured data. The initial constants,
    priors, sigmas, damping and reference are left out: another start on the same data is
    still the same plate."""
    from laminid_cli.specimen import LayupSyntaxError, expand_layup
    from laminid_cli.units import normalize_text, parse_quantity

    try:
        g = doc["geometry"]
        geometry = tuple(parse_quantity(g[k], "length") for k in ("a", "b", "h"))
        mass = None if doc.get("mass") is None else parse_quantity(doc["mass"], "mass")
        if "layup" in doc:
            lay = doc["layup"]
            code = "[" + "/".join(map(str, lay)) + "]" if isinstance(lay, list) else str(lay)
            layup = ("layup", tuple(expand_layup(normalize_text(code))))
        else:
            layup = ("plies", json.dumps(doc["plies"], sort_keys=True, default=str))
        m = doc["measured"]
        if m.get("frf_file"):
            # the same FRF file (its content is compared only within a group: see
            # duplicate_specimens) fitted in the same bands to the same modes
            data = ("frf", json.dumps([m.get("bands"), m.get("modes")], sort_keys=True,
                                      default=str))
        else:
            freq = tuple(None if f is None else parse_quantity(f, "frequency")
                         for f in m["frequencies"])
            w = m.get("weights")
            w = [1.0] * len(freq) if w is None else [parse_quantity(x, "dimensionless")
                                                       for x in w]
            data = ("frequencies", freq,
                    tuple(0.0 if f is None else x for f, x in zip(freq, w, strict=True)))
    except (LaminidError, LayupSyntaxError, KeyError, TypeError, ValueError, AttributeError):
        return None
    return geometry, mass, layup, data


def duplicate_specimens(specs, docs) -> list[list[int]]:
    """Groups of specimens of the batch that hold the same plate's measured data (indices
    into ``specs``, each group in their order): :func:`_measured_plate` equal, and for
    specimens measured through an ``frf_file`` the same bytes in it (compared only for the
    few whose other data agree).

    Why: a specimen file copied under another name (or twice into a study's folders) was
    identified twice and reported as two specimens of the material, one plate counted twice in
    the spread across specimens. Exact equality only: two plates never give the same twelve
    frequencies to the digits written, so nothing a lab measured twice is taken for a copy.

    ``docs``: :func:`load_specimen_docs` of ``specs`` (the files are not read again, except
    the FRF files of candidate duplicates)."""
    groups: dict = collections.defaultdict(list)
    for i, doc in enumerate(docs):
        key = _measured_plate(doc) if isinstance(doc, dict) else None
        if key is not None:
            groups[key].append(i)
    out = []
    for key, members in groups.items():
        if len(members) < 2:
            continue
        if key[3][0] == "frf":
            by_bytes: dict = collections.defaultdict(list)
            for i in members:
                frf = _frf_file(Path(specs[i]), docs[i])
                try:
                    digest = hashlib.sha256(frf.read_bytes()).hexdigest()
                except (OSError, AttributeError):
                    continue                    # unreadable: the specimen's own error
                by_bytes[digest].append(i)
            out += [g for g in by_bytes.values() if len(g) > 1]
        else:
            out.append(members)
    return sorted(out)


def duplicate_text(files) -> str:
    """The warning of one group of :func:`duplicate_specimens` (``files`` as given)."""
    names = [str(f) for f in files]
    listed = (" and ".join(names) if len(names) == 2
              else ", ".join(names[:-1]) + " and " + names[-1])
    times = "twice" if len(names) == 2 else f"{len(names)} times"
    return (f"specimens {listed} hold the same measured frequencies and plate (geometry, "
            f"layup, mass): one plate counted {times}?")


def input_hash(spec, options: BatchOptions) -> str:
    """sha256 (hex) of everything a result depends on: the laminid version, the options, the
    specimen file's bytes and those of its FRF file (``measured.frf_file``) when it has one."""
    spec = Path(spec)
    from laminid_cli.results import SCHEMA_VERSION

    h = hashlib.sha256()
    # "options 2": the options as RunOptions.as_dict (every field of IdentifyOptions and
    # UncertaintyOptions); results hashed by earlier versions never match, so are redone.
    # "verdicts 2": the Monte Carlo range enters the verdicts and --fix-undetermined (stop 27);
    # "verdicts 3": with the width its trials show for sure (stop 28); "verdicts 4": profiles of
    # constants at a limit, the fixed values' spread counted, fixed ranges (stop 30);
    # "verdicts 5": the Monte Carlo trials of --fix-undetermined draw the fixed values;
    # "verdicts 6": the test whether the modes reject the fixed values (status fixed_rejected),
    # and the Monte Carlo trials' variance factors drawn where the intervals are Student t;
    # "verdicts 7": the intervals counting the fixed values' spread on Welch-Satterthwaite's
    # quantiles; "verdicts 8": the profiles' fits search the identification's own region, a
    # rejection checked from the initial values too (stop 38); "verdicts 9": the profiles'
    # fits from the optimum on the profile's reduced model, converged where identify()'s capped
    # fits were not (hybrid CM's glass G12 and G23: bounds instead of no profile), and a prior
    # of weight wp counted as its value known to sigma_unit / sqrt(wp) (stop 43)
    h.update(f"laminid {__version__} schema {SCHEMA_VERSION} options 2 verdicts 9\0".encode())
    settings = options.as_dict()
    # the processes of a specimen's profiles and Monte Carlo trials do not change its result
    # (batch -j 1 gives them the cores, a pool of workers one each): hashed as the 1 that
    # every batch gave them before, so that a result stays up to date whatever -j
    settings["uncertainty"]["jobs"] = 1
    if not settings.get("mesh_check"):
        # results of batches before --mesh-check (none checked) stay up to date
        settings.pop("mesh_check", None)
    h.update(json.dumps(settings, sort_keys=True).encode() + b"\0")
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


#: suffix of a result set aside because its specimen failed in a later run (out of the
#: ``*.result.h5`` pattern); numbered ``.result.stale1.h5``, ... when that exists
STALE_SUFFIX = ".result.stale.h5"
#: most numbered stale names looked for (.stale, .stale1 ... .stale<N>)
MAX_STALE = 9999


def set_aside_result(job: Job) -> tuple[Path | None, str]:
    """Rename the result file of a specimen that failed in this run, or that an interrupted
    run did not reach while its file there is another input's, out of the ``*.result.h5``
    pattern (:func:`set_aside`)."""
    return set_aside(job.output)


def set_aside(path) -> tuple[Path | None, str]:
    """Rename the result file ``path`` out of the ``*.result.h5`` pattern; returns
    ``(new path, "")``, ``(None, "")`` when there is none, or ``(None, why)`` when it could
    not be moved.

    The file was made from an earlier input (this run wrote nothing there: a failing specimen
    gets no result, nor one the run did not reach), so beside this run's summary a script
    globbing ``*.result.h5`` would take it for the current one. Nothing is deleted: it becomes
    ``<name>.result.stale.h5``, else ``<name>.result.stale1.h5``, ... (a hard link taken
    exclusively, then the old name removed, so an earlier stale file is never overwritten;
    a plain rename where the file system has no hard links). Also used by ``identify`` for
    the default result of a specimen that now fails.
    """
    out = Path(path)
    if not out.is_file() or out.is_symlink():
        # a symbolic link at the result's name is the user's own arrangement: left as it is
        return (None, f"{out} is a symbolic link, left in place") if out.is_symlink() \
            else (None, "")
    stem = out.name[: -len(RESULT_SUFFIX)] if out.name.endswith(RESULT_SUFFIX) else out.name
    names = [out.with_name(stem + STALE_SUFFIX)] + [
        out.with_name(f"{stem}.result.stale{k}.h5") for k in range(1, MAX_STALE + 1)]
    for name in names:
        try:
            os.link(out, name)
        except FileExistsError:
            continue
        except OSError:                   # no hard links here (some network/FAT file systems)
            if name.exists():
                continue
            try:
                os.rename(out, name)
            except OSError as exc:
                return None, f"cannot rename {out} ({exc})"
            return name, ""
        try:
            out.unlink()
        except OSError as exc:
            with contextlib.suppress(OSError):
                name.unlink()
            return None, f"cannot remove {out} ({exc})"
        return name, ""
    return None, f"{MAX_STALE + 1} stale results of {stem} exist already; move some away"


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


#: longest failure reason a pool worker sends back (its whole message must stay below the
#: pipe's atomic write size, see :func:`run_job`)
MAX_REASON_CHARS = 1500


def run_job(job: Job, options: BatchOptions, write: bool = False) -> Outcome:
    """Identify one specimen with its uncertainty assessment, as ``laminid identify SPEC -o
    OUT`` does (laminid_cli.pipeline); runs in a worker.

    The result file gets the root attributes ``batch_input_sha256``, ``batch_name`` and
    ``batch_options`` (JSON). ``write=False``: it is returned as bytes (Outcome.data) for the
    client to write (a Dask worker may not see the output folder; an in-process run must not
    write a run that Ctrl-C interrupted). ``write=True`` (pool workers): the worker writes it
    at ``job.output`` itself, atomically, and returns a small Outcome: a few hundred bytes
    travel through the pool's pipe, written in one piece (POSIX pipes write up to 4096 bytes
    at once), so a worker stopped by Ctrl-C can never leave half a message there (the pool's
    reader thread would then wait for the rest forever, and the batch would hang at exit).

    A specimen's own fault (unreadable or invalid file, infeasible start, no convergence,
    solver failure) is an Outcome with status "error" or "check" and its reason, never an
    exception; an unexpected exception is reported the same way (with its type) so that the
    other specimens go on.
    """
    t0 = time.perf_counter()

    def failure(reason: str) -> Outcome:
        if write and len(reason) > MAX_REASON_CHARS:
            reason = reason[:MAX_REASON_CHARS - 1] + "\u2026"
        return Outcome(job.name, "error", reason, None, time.perf_counter() - t0)

    try:
        str(job.spec).encode("utf-8")
    except UnicodeEncodeError:
        return failure("the file name is not valid UTF-8 text; rename the file")
    try:
        from laminid_cli.pipeline import run_identification, write_result

        run = run_identification([job.spec], options, loss_fix_needs_damping=False)
        attrs = {HASH_ATTR: job.key, "batch_name": job.name,
                 "batch_options": json.dumps(options.as_dict(), sort_keys=True)}
        if write:
            out = Path(job.output)
            out.parent.mkdir(parents=True, exist_ok=True)
            part = temporary_name(out)
            _current_tmp.append(part)
            try:
                write_result(out, run, command="laminid batch", attrs=attrs)
            finally:
                _current_tmp.remove(part)
            data = None
        else:
            with tempfile.TemporaryDirectory(prefix="laminid-batch-") as tmp:
                _current_tmp.append(Path(tmp))
                try:
                    path = write_result(Path(tmp) / Path(job.output).name, run,
                                        command="laminid batch", attrs=attrs)
                    data = path.read_bytes()
                finally:
                    _current_tmp.remove(Path(tmp))
        # the specimen reader logged its warnings as it read the file (through the worker's
        # log set-up, at the batch's level); the result's warnings begin with them
        logged = logging.getLogger("laminid_cli.specimen").isEnabledFor(logging.WARNING)
        return Outcome(job.name, run.status.status, ", ".join(run.status.codes), data,
                       time.perf_counter() - t0,
                       len(run.forward_models[0].specimen.warnings) if logged else 0)
    except LaminidError as exc:
        return failure(str(exc))
    except Exception as exc:  # noqa: BLE001 - one specimen's crash must not stop the batch
        log.debug("%s: %s", job.spec, traceback.format_exc())
        return failure(f"internal error {type(exc).__name__}: {exc}")


def lock_out_folder(out_dir) -> int | None:
    """Hold ``out_dir`` for this batch: an exclusive advisory lock (flock) on the folder itself
    (no file is left in it), released when the returned descriptor is closed or the process
    ends, SIGKILL included. Two batches writing into one folder at once replaced each other's
    results under their summaries (a summary giving the 8x8 constants of a file that held the
    other batch's 6x6 ones), so a second one is refused (BatchError) before it touches
    anything. None where the system or the file system has no such lock (Windows, some network
    file systems): the batch runs unguarded, as before."""
    try:
        import fcntl
    except ImportError:
        return None
    try:
        fd = os.open(out_dir, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise BatchError(f"--out {out_dir}: another laminid batch is writing into this folder "
                         "now (two at once replace each other's results under their "
                         "summaries); wait for it to end, or choose another --out",
                         path=out_dir) from None
    except OSError:
        os.close(fd)
        return None
    _held_out.append(fd)
    return fd


def release_out_folder(fd: int | None) -> None:
    """Let go of the folder :func:`lock_out_folder` held (``fd``: what it returned)."""
    if fd is None:
        return
    with contextlib.suppress(ValueError):
        _held_out.remove(fd)
    with contextlib.suppress(OSError):
        os.close(fd)


#: descriptors of the --out folders this process holds (lock_out_folder)
_held_out: list = []


def _close_held_out_in_child() -> None:
    """In a forked child (the Monte Carlo trials', an HDF5 probe): close the inherited copies
    of the held folders' descriptors, so that a child that outlives a killed batch for a
    moment does not keep the next batch out (the parent's lock stays: closing a copy does not
    release it)."""
    for fd in _held_out:
        with contextlib.suppress(OSError):
            os.close(fd)
    _held_out.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_close_held_out_in_child)


def remove_stale_parts(out_dir) -> int:
    """Delete the temporary files a killed batch left in ``out_dir``."""
    return remove_stale_temporaries(out_dir)


def run_jobs(jobs, options: BatchOptions, n_jobs: int = 1, scheduler: str | None = None,
             retry: bool = True):
    """Run the jobs and yield ``(job, outcome)`` in order of completion.

    n_jobs : worker processes; 1 without a scheduler runs in this process
    retry : on a process pool, the jobs a dead worker took down with the pool (one killed, out
        of memory: every job not finished then fails with BrokenProcessPool) run again after
        it, each alone in a new worker, so that only a job that kills its worker again fails
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
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    # forkserver: workers start from a clean interpreter (no inherited h5py handles/threads)
    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    pool = ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs)),
                               mp_context=multiprocessing.get_context(method),
                               initializer=_worker_init,
                               initargs=(os.getpid(), logging.getLogger().getEffectiveLevel()))
    complete = False
    # a Ctrl-C is only noted and acted on at the loop's next look (every SIGINT_POLL s, and
    # after each result the consumer took): raised at once, it could land inside Python's own
    # clean-up (a weakref callback of the pool's), which prints "Exception ignored in ...
    # KeyboardInterrupt" after "laminid: interrupted" (1 of 40 interrupted batches)
    seen, restore = _note_sigint(raise_=False)
    broken = []                      # jobs a dead worker took down with the pool
    try:
        with _sigint_blocked():      # the pool starts its worker processes in submit
            futures = {pool.submit(run_job, job, options, True): i for i, job in enumerate(jobs)}
        pending = set(futures)
        while pending:
            # woken at least every SIGINT_POLL s to act on a noted Ctrl-C (the handler above
            # only notes it)
            done, pending = wait(pending, timeout=SIGINT_POLL, return_when=FIRST_COMPLETED)
            for fut in sorted(done, key=futures.get):
                if seen:
                    raise _interruption(seen)
                job = jobs[futures[fut]]
                if retry and _pool_broke(fut):
                    broken.append(job)
                    continue
                yield job, _outcome_of(fut, job)
            if seen:
                raise _interruption(seen)
        complete = True
    finally:
        # a further Ctrl-C (an impatient user; `timeout -s INT`, which signals the batch and then
        # its process group, at times delivered twice) is still only noted while the pool shuts
        # down (the handler above): raised, it cut the wait short and left the pool's manager
        # thread running into this process's exit (below), or, raised in the generator's
        # close, was printed as "Exception ignored"
        try:
            if not complete:
                # Ctrl-C or an error in the consumer: the workers would finish the jobs already
                # queued to them; stop them now
                _stop_workers(list(getattr(pool, "_processes", {}).values()))
            # wait=True on Ctrl-C too (as the Monte Carlo's `with` pool): the manager thread
            # joins the stopped workers, then drops the queues, whose semaphores the resource
            # tracker holds (forkserver). Not waited for, it did that while this process ran
            # its exit handlers (which also release them) and os._exit: a semaphore unlinked
            # but not yet unregistered when the process ended made the tracker warn "1 leaked
            # semaphore objects" and "[Errno 2] No such file or directory" after "laminid:
            # interrupted" (2 of 30 interrupted batches)
            pool.shutdown(wait=True, cancel_futures=True)
        finally:
            restore()
        if seen and complete:
            raise _interruption(seen)        # as the last job finished: a Ctrl-C like any other
    # a worker died (killed, out of memory) and every job not finished failed with it: each
    # alone in a new worker, one after the other (the least memory), so that the job that
    # killed its worker is the only one to fail, and the others are not 'failed' for it
    for job in broken:
        yield from run_jobs([job], options, n_jobs=2, retry=False)


#: seconds the pool's workers have to exit after SIGTERM before they are killed (SIGKILL)
STOP_GRACE_S = 2.0


def _stop_workers(procs) -> None:
    """Stop the pool's worker processes: SIGTERM (a worker removes its partial file and exits
    at once), then SIGKILL for those still there after :data:`STOP_GRACE_S` s (one inside a
    long compiled call runs no Python signal handler until it returns; its temporary file is
    left to :func:`remove_stale_parts`). Bounds the pool's shutdown, which waits for them."""
    from multiprocessing.connection import wait

    for proc in procs:
        with contextlib.suppress(Exception):
            proc.terminate()
    running = {proc.sentinel: proc for proc in procs}
    deadline = time.monotonic() + STOP_GRACE_S
    while running and (left := deadline - time.monotonic()) > 0:
        for sentinel in wait(list(running), timeout=left):
            del running[sentinel]
    for proc in running.values():
        with contextlib.suppress(Exception):
            proc.kill()


#: seconds between two looks at a noted Ctrl-C while the pool's workers run
SIGINT_POLL = 0.2


def _note_sigint(raise_: bool = True):
    """(seen, restore): in the main thread, SIGINT is noted in the list ``seen`` until
    ``restore()``, and raises KeyboardInterrupt too unless ``raise_`` is False (a caller that
    looks at the note often enough). A KeyboardInterrupt raised where Python swallows
    exceptions (a weakref callback, a finaliser, an optimiser's callback in compiled code) is
    lost; the note is not, and the caller raises it again (seen once in
    test_killed_batch...: the batch then finished and exited 0). Elsewhere a no-op.

    SIGTERM likewise (its :class:`~laminid_cli.errors.Terminated`) where the handler in place
    is a Python one (the batch command's, :func:`~laminid_cli.errors.sigterm_raises_terminated`); its default (the
    process killed) and an ignored SIGTERM are left as they are. :func:`_interruption` gives
    the exception of what was noted first (:func:`~laminid_cli.errors.note_stop_signals`)."""
    return note_stop_signals(take_all=False, raising=_interruption if raise_ else None)


def _interruption(seen) -> KeyboardInterrupt:
    """The exception that stops the batch for the signals noted in ``seen`` (the first one
    decides): :class:`~laminid_cli.errors.Terminated` for SIGTERM, else KeyboardInterrupt."""
    import signal

    return Terminated() if seen and seen[0] == signal.SIGTERM else KeyboardInterrupt()


@contextlib.contextmanager
def _sigint_blocked():
    """Block SIGINT in this thread while worker processes are started.

    A process started meanwhile (the forkserver, a pool worker; fork and exec keep the signal
    mask) cannot be killed by a Ctrl-C before its initializer ignores it: a worker dying in
    its start-up breaks the whole pool. A Ctrl-C meant for this process stays pending and is
    delivered (KeyboardInterrupt) when the block is lifted. No-op outside the main thread and
    where there is no pthread_sigmask (Windows)."""
    import signal
    import threading

    if not hasattr(signal, "pthread_sigmask") or \
            threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


#: temporary folder or file of the job running in this (worker) process, removed on SIGTERM
_current_tmp: list = []


def _worker_signals() -> None:
    """Pool worker set-up: Ctrl-C is the client's business (it terminates the workers);
    SIGTERM removes the running job's temporary folder and exits at once (an exception
    would be caught by the pool's worker loop, which would go on with the next job)."""
    import signal

    def terminate(*_):
        import shutil

        for tmp in _current_tmp:
            if Path(tmp).is_dir():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
        os._exit(143)

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):      # started with it blocked (_sigint_blocked)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGTERM, terminate)
    stop_with_parent(terminate, _CLIENT_PID.get("pid"))


#: pid of the batch process, given to the pool workers through their initializer
_CLIENT_PID: dict = {}


def _worker_init(client_pid: int, log_level: int = logging.WARNING) -> None:
    _CLIENT_PID["pid"] = client_pid
    _worker_signals()
    # a worker starts from a clean interpreter: its log records (a specimen's warning) went
    # out bare through Python's last-resort handler, whatever -q said; as the batch's own
    from laminid_cli.cli import configure_logging

    configure_logging(log_level)
    logging.getLogger().setLevel(log_level)


def _run_here(jobs, options):
    """The jobs one by one in this process. Ctrl-C raised inside compiled code can be
    swallowed there (an optimiser callback, for one) and turn into a failed or stopped run:
    the signal is noted, the job in progress is dropped (never cached as done) and the
    interrupt raised here."""
    seen, restore = _note_sigint()
    try:
        for job in jobs:
            outcome = run_job(job, options)
            if seen:
                raise _interruption(seen)
            yield job, outcome
        if seen:                             # swallowed while the last one was written
            raise _interruption(seen)
    finally:
        restore()


def _pool_broke(fut) -> bool:
    """True when the job of ``fut`` failed because a worker process of its pool died."""
    from concurrent.futures.process import BrokenProcessPool

    return isinstance(fut.exception(), BrokenProcessPool)


def _outcome_of(fut, job: Job) -> Outcome:
    try:
        return fut.result()
    except Exception as exc:  # noqa: BLE001 - a worker died (killed, out of memory)
        if _pool_broke(fut):
            return Outcome(job.name, "error", "worker failed: its worker process died "
                           "(killed, or out of memory?), also when the specimen ran again "
                           "alone in a new one")
        return Outcome(job.name, "error", f"worker failed: {type(exc).__name__}: {exc}")


#: address schemes Dask's Client accepts for a running scheduler
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss")


def check_scheduler(address: str) -> str:
    """Check a ``--scheduler`` value: ``local`` or ``[tcp|tls|ws|wss]://HOST:PORT``.

    Returns it unchanged; raises :class:`BatchError` (one line, exit 2) otherwise, before any
    connection is tried.
    """
    import re

    text = str(address).strip()
    if text == "local":
        return text
    expected = ("expected 'local' or a Dask scheduler address SCHEME://HOST:PORT with SCHEME "
                f"one of {', '.join(SCHEDULER_SCHEMES)} (e.g. tcp://10.0.0.5:8786)")
    match = re.fullmatch(r"(?:([A-Za-z][A-Za-z0-9+.-]*)://)?(\[[0-9A-Fa-f:.]+\]|[^\s/:@]+)"
                         r"(?::([0-9]{1,5}))?", text)
    if not text or match is None:
        raise BatchError(f"--scheduler {address!r} not understood; {expected}")
    scheme, _host, port = match.groups()
    if scheme is not None and scheme.lower() not in SCHEDULER_SCHEMES:
        raise BatchError(f"--scheduler {address!r}: unknown scheme {scheme!r}; {expected}")
    if port is None:
        raise BatchError(f"--scheduler {address!r}: no port; {expected}")
    if not 1 <= int(port) <= 65535:
        raise BatchError(f"--scheduler {address!r}: port {port} is not in 1-65535; {expected}")
    return text


def _run_dask(jobs, options, n_jobs, scheduler):
    scheduler = check_scheduler(scheduler)
    try:
        from distributed import Client, LocalCluster, as_completed

        from laminid_cli.dask_worker import worker_log_level
    except ImportError as exc:
        raise BatchError("--scheduler needs Dask: pip install 'laminid[dask]'") from exc
    # distributed sets its loggers to INFO when imported (its own configuration): at laminid's
    # verbosity (WARNING unless -v) its start-up and shutdown lines (some 40 per batch) are noise
    logging.getLogger("distributed").setLevel(logging.getLogger().getEffectiveLevel())
    cluster = None
    futures: dict = {}
    try:
        if scheduler == "local":
            # no dashboard; the scheduler's HTTP server (which it starts anyway) on a free
            # port of this machine's loopback: on its default 8787, a second batch running
            # at the same time printed distributed's "UserWarning: Port 8787 is already in
            # use. Perhaps you already have a cluster running? ..." (4 lines)
            cluster = LocalCluster(n_workers=max(1, n_jobs), threads_per_worker=1,
                                   processes=True, dashboard_address=None,
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            client = Client(cluster)
            # the cluster's workers leave Ctrl-C to this process (a remote cluster's are its
            # own: a `dask worker` stops on it)
            from laminid_cli.dask_worker import LocalWorkerSetup

            level = logging.getLogger().getEffectiveLevel()
            client.register_plugin(LocalWorkerSetup(worker_log_level(level), level))
        else:
            client = Client(scheduler, timeout="20s")
    except Exception as exc:  # noqa: BLE001 - distributed raises OSError, TimeoutError,
        # ValueError, TypeError... for an unusable address: all are one line for the user
        if cluster is not None:
            cluster.close()
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise BatchError(f"--scheduler {scheduler}: cannot connect ({reason})") from exc
    # a Ctrl-C is noted and acted on at the loop's next look, as with the process pool
    # (run_jobs): raised at once it could land in a weakref callback of distributed's, where
    # Python prints "Exception ignored ... KeyboardInterrupt" and drops it; the batch then
    # went on to its end and exited 0 (1 in 6 interrupted local-cluster batches)
    seen, restore = _note_sigint(raise_=False)
    try:
        # remote workers have their own working folder: give them absolute paths
        remote = [Job(str(Path(j.spec).resolve()), j.name, j.output, j.key) for j in jobs]
        futures = {client.submit(run_job, r, options, key=f"laminid-{j.name}-{j.key[:12]}",
                                 pure=False): j for j, r in zip(jobs, remote)}
        pending = as_completed(list(futures))
        while not pending.is_empty():
            ready = pending.next_batch(block=False)
            for fut in ready:
                if seen:
                    raise _interruption(seen)
                yield futures[fut], _outcome_of(fut, futures[fut])
            if seen:
                raise _interruption(seen)
            if not ready:
                time.sleep(SIGINT_POLL)
    finally:
        # (a further Ctrl-C while the cluster closes is only noted: raised, it cut the close
        # short and left its workers to the parent watch)
        if seen:
            # (the scheduler's and nannies' complaints of a close cut short are as much an
            # artefact as the workers': dask_worker.worker_log_level)
            logging.getLogger("distributed").setLevel(
                worker_log_level(logging.getLogger().getEffectiveLevel()))
        try:
            if futures:
                with contextlib.suppress(Exception):
                    client.cancel(list(futures))
            client.close()
            if cluster is not None:
                cluster.close()
        finally:
            restore()
    if seen:
        raise _interruption(seen)        # noted while the cluster closed after the last job


# ----------------------------------------------------------------------------------------------
# summary


def result_row(job: Job, outcome: Outcome | None = None, cached: bool = False,
               stale: tuple[Path | None, str] = (None, "")) -> dict:
    """One summary row (SI units), with the numbers read back from the job's result file
    (:func:`laminid_cli.resultfile.read_result`, one read).

    Keys: name, specimen (its name field), path, status ("ok" | "check" | "error" | "not run"),
    reasons ([{code, text}], laminid_cli.status), reason (one line: the error, or the codes),
    converged, optimizer_status, cached, materials ({material: {E1.. nu12}}), intervals
    ({material: {constant: {lower, upper, verdict, at_bound, bound_side, bound_limit,
    flagged, flag, profile_bound, profile, profile_text, profile_far}}} for the free constants
    (bound_side "" and bound_limit None when not at a bound; profile: LONG_COLUMNS; flag:
    :func:`flag_word`), with mc_lower, mc_upper and mc_lower_at_limit, mc_upper_at_limit (None:
    the file does not say) after a Monte Carlo; fixed ones the same keys but the profile's,
    no interval, verdict and flag "fixed"),
    rms_residual_percent, evaluations, time_s, result, damping ({material: {eta11: {value,
    lower, upper, verdict}}}, empty without measured damping), mesh_check (with --mesh-check:
    :func:`mesh_summary`, and mesh_shift_half_width in each interval; else None).
    ``flagged`` (not determined) is the file's own flag (the run's --max-rel-interval).
    stale_result: where the earlier result of a failing specimen, or of one not run (an
    interrupted batch), was moved in this run (:func:`set_aside_result`, given as ``stale``),
    else None; when it could not be moved the reason says so.
    """
    row = {"name": job.name, "specimen": "", "path": str(job.spec), "status": "not run",
           "reasons": [], "reason": "", "converged": None, "optimizer_status": "",
           "cached": cached, "materials": {}, "intervals": {}, "rms_residual_percent": None,
           "evaluations": None, "time_s": None, "result": None, "damping": {},
           "mesh_check": None, "warnings": [],
           "stale_result": None if stale[0] is None else str(stale[0])}
    if outcome is not None and outcome.status == "error":
        reason = outcome.reason
        if stale[1]:
            reason += (f"; its earlier result {job.output} is not this input's and could not "
                       f"be set aside: {stale[1]}")
        row.update(status="error", reason=reason, time_s=outcome.time_s)
        return row
    if outcome is None and not cached:
        if stale[1]:
            row["reason"] = (f"its result file {job.output} is an earlier input's, not this "
                             f"batch's, and could not be set aside: {stale[1]}")
        return row
    try:
        res = read_result(job.output)
    except (ResultFileError, OSError, KeyError, ValueError) as exc:
        row.update(status="error", reason=f"result file {job.output} unreadable ({exc})")
        return row
    row.update(_row_of_result(res))
    row["result"] = str(job.output)
    return row


def _fixed_entry(assumed: bool) -> dict:
    """A fixed constant's entry of a summary row's ``intervals``: a free one's keys, no
    interval, verdict "fixed", ``assumed`` where --fix-undetermined held it, its flag."""
    entry = {"lower": None, "upper": None, "verdict": VERDICT_FIXED, "assumed": assumed,
             "at_bound": False, "bound_side": "", "bound_limit": None, "flagged": False}
    entry["flag"] = flag_word(entry)
    return entry


def foreign_results(out_dir, jobs) -> list[Path]:
    """The ``*.result.h5`` files below ``out_dir`` that are no job's result file (hidden
    files and folders and temporaries skipped), sorted: results of specimens not among this
    batch's inputs (their file removed, or another batch's inputs written into the same
    folder). Which of the two cannot be told, so they are named, never moved."""
    out_dir = Path(out_dir)
    ours = {os.path.normcase(os.path.abspath(j.output)) for j in jobs}
    found = []
    for p in out_dir.rglob("*" + RESULT_SUFFIX):
        rel = p.relative_to(out_dir)
        if any(part.startswith(".") for part in rel.parts) or not (p.is_file()
                                                                  or p.is_symlink()):
            continue
        if os.path.normcase(os.path.abspath(p)) not in ours:
            found.append(p)
    return sorted(found)


def foreign_row(path, out_dir) -> dict:
    """The summary row of a result file in --out that this batch did not write
    (:func:`foreign_results`): status :data:`NOT_FROM_BATCH`, no result, the file in
    ``stale_result`` (where it lies, untouched)."""
    rel = Path(os.path.relpath(path, out_dir)).as_posix()
    return {"name": rel[: -len(RESULT_SUFFIX)], "specimen": "", "path": "",
            "status": NOT_FROM_BATCH, "reasons": [],
            "reason": "no specimen of this batch has this result file (its specimen file is not "
                      "among the inputs: removed, or given to another batch); kept as it is",
            "converged": None, "optimizer_status": "", "cached": False, "materials": {},
            "intervals": {}, "rms_residual_percent": None, "evaluations": None,
            "time_s": None, "result": None, "damping": {}, "mesh_check": None,
            "warnings": [], "stale_result": str(path)}


def _row_of_result(res) -> dict:
    """The summary-row fields of a :class:`laminid_cli.resultfile.ResultFile` (schema 1 or 2;
    version 1 recorded no status: "ok" when converged, else "check")."""
    import numpy as np

    row: dict = {"converged": res.converged, "optimizer_status": res.optimizer_status}
    if res.status is not None:
        row["status"] = res.status.status
        row["reasons"] = [{"code": r.code, "text": r.text} for r in res.status.reasons]
    else:
        row["status"] = "ok" if res.converged else "check"
        row["reasons"] = [] if res.converged else [
            {"code": "not_converged", "text": f"the optimiser did not converge "
                                              f"({res.optimizer_status})"}]
    row["reason"] = ", ".join(r["code"] for r in row["reasons"])
    # the run's warnings, the specimen reader's first (ply angles that look like radians, a
    # mass that density x volume contradicts)
    row["warnings"] = list(res.warnings)
    row["specimen"] = res.plates[0].name
    row["evaluations"] = res.evaluations
    row["time_s"] = res.time_s
    row["rms_residual_percent"] = res.rms_residual_percent
    row["materials"] = {m: {k: c[k] for k in CONSTANTS} for m, c in res.materials.items()}
    # a fixed constant's entry has the keys of a free one's (no interval, not flagged as
    # undetermined), so that a script reading them all finds each; its flag says "fixed", or
    # "assumed" where --fix-undetermined fixed it (its initial guess, held because the modes
    # did not determine it: not a value known from elsewhere)
    u = res.uncertainty
    assumed = set(getattr(u, "fixed_undetermined", ()) or ()) if u is not None else set()
    intervals: dict = {m: {k: _fixed_entry(f"{m}.{k}" in assumed) for k in CONSTANTS}
                       for m in res.materials}
    mc = u.monte_carlo if u is not None and u.monte_carlo and "lower" in u.monte_carlo \
        else None
    for j, iv in enumerate(u.intervals if u is not None else ()):
        entry = intervals.setdefault(iv.material, {})[iv.constant] = {
            "lower": iv.lower, "upper": iv.upper, "verdict": iv.verdict,
            "at_bound": iv.at_bound, "bound_side": iv.bound_side,
            "bound_limit": iv.bound_limit, "flagged": iv.flagged,
            "profile_bound": (float(iv.profile_bound) if np.isfinite(iv.profile_bound)
                              else None),
            "profile": iv.profile_kind, "profile_text": iv.profile_text,
            "profile_far": float(iv.profile_far) if np.isfinite(iv.profile_far) else None}
        entry["flag"] = flag_word(entry)
        if mc is not None:               # the Monte Carlo's constants are the intervals'
            entry["mc_lower"] = float(np.ravel(mc["lower"])[j])
            entry["mc_upper"] = float(np.ravel(mc["upper"])[j])
            for side in ("lower", "upper"):      # (files before stop 25 do not say)
                flag = mc.get(f"{side}_at_bound")
                entry[f"mc_{side}_at_limit"] = None if flag is None else \
                    bool(np.ravel(flag)[j])
    row["intervals"] = intervals
    row["damping"] = damping_of_file(res.damping) if res.damping is not None else {}
    row["mesh_check"] = mesh_summary(res.mesh_check)
    for m, per in (res.mesh_check or {}).get("constants", {}).items():
        for k, v in per.items():
            if k in intervals.get(m, {}):
                intervals[m][k]["mesh_shift_half_width"] = v["shift_half_width"]
    return row


def mesh_summary(mc: dict | None) -> dict | None:
    """The summary's ``mesh_check`` of a result's /mesh_check (MeshCheck.as_dict's plain
    data; None: checked without it): fine_mesh ("24x24"), max_change_percent and
    max_change_sigma (the largest |frequency change| on the fine mesh, in percent and in units
    of the mode's sigma), max_shift_half_width (the largest |first-order shift| of a free
    constant in units of its 95 % half-width, NaN shifts skipped), worst (its label), limit,
    coarse_mesh (some shift beyond the limit: the status reason) and text (its words)."""
    import numpy as np

    if mc is None:
        return None
    modes = mc.get("modes") or {}
    labels = list(mc.get("labels") or [])
    shifts = [abs(mc["constants"][lab.rsplit(".", 1)[0]][lab.rsplit(".", 1)[1]]
                  ["shift_half_width"]) for lab in labels]
    finite = [(v, lab) for v, lab in zip(shifts, labels) if np.isfinite(v)]
    worst = max(finite) if finite else (None, "")

    def largest(key):
        a = np.abs(np.asarray(modes.get(key, []), float))
        return float(np.nanmax(a)) if a.size and np.isfinite(a).any() else None

    fine = mc.get("fine_mesh") or {}
    return {"fine_mesh": f"{fine.get('nx')}x{fine.get('ny')}",
            "max_change_percent": largest("change_percent"),
            "max_change_sigma": largest("change_sigma"),
            "max_shift_half_width": None if worst[0] is None else float(worst[0]),
            "worst": worst[1], "limit": float(mc.get("limit", np.nan)),
            "coarse_mesh": bool(mc.get("too_coarse")), "text": str(mc.get("text") or "")}


def damping_of_file(d) -> dict:
    """{material: {etaXY: {value, lower, upper, verdict, at_bound, bound_side, bound_limit,
    flag}}} (flag: :func:`flag_word`, as summary.csv's column)
    of a result's /damping (:class:`laminid_cli.resultfile.Damping`: free loss factors with
    their interval, held at 0 and fixed ones with lower = upper = None, fixed ones with
    verdict "fixed"); with the loss factors' Monte Carlo
    (/damping/monte_carlo: each trial refitted them at its own constants) also mc_lower,
    mc_upper, its range, and mc_lower_at_limit, mc_upper_at_limit (its lower end set by refits
    held at 0; None: the file does not say), as the constants have them."""
    import numpy as np

    out: dict[str, dict] = {}
    g = d.data
    at = g.get("at_bound")
    mc = getattr(d, "monte_carlo", None)
    mc = mc if mc is not None and "lower" in mc and "upper" in mc else None
    for k, lab in enumerate(g["labels"]):
        mat, name = _str(lab).rsplit(".", 1)
        hit = at is not None and bool(at[k])
        # a loss factor at its bound is held at 0 by eta >= 0 (the data push it below): no
        # interval (a file written before kept a one-sided 0 .. upper: left out too), the
        # side and limit as for the constants
        out.setdefault(mat, {})[name] = {
            "value": float(g["value"][k]),
            "lower": None if hit else float(g["lower"][k]),
            "upper": None if hit else float(g["upper"][k]), "verdict": _str(g["verdict"][k]),
            "at_bound": hit, "bound_side": "lower" if hit else "",
            "bound_limit": 0.0 if hit else None}
        if mc is not None:
            # the range's lower end set by refits held at 0 (eta >= 0: the bound's end, not
            # the data's) is flagged as a constant's end on a search limit is (the terminal's
            # "0*"); files before /damping/monte_carlo/lower_at_zero do not say (None)
            zero = mc.get("lower_at_zero")
            out[mat][name].update(mc_lower=float(np.ravel(mc["lower"])[k]),
                                  mc_upper=float(np.ravel(mc["upper"])[k]),
                                  mc_lower_at_limit=None if zero is None
                                  else bool(np.ravel(zero)[k]),
                                  mc_upper_at_limit=None if zero is None else False)
    fixed = _str(d.attrs.get("fixed", ""))
    for item in filter(None, fixed.split(",")):
        lab, value = item.rsplit("=", 1)
        mat, name = lab.rsplit(".", 1)
        out.setdefault(mat, {})[name] = {"value": float(value), "lower": None, "upper": None,
                                         "verdict": "fixed"}
    # the word summary.csv's flag column gives each (summary.json's constants have it; its
    # loss factors had none: a script testing "flag" read eta13 "not determined" as plain)
    for per in out.values():
        for v in per.values():
            v["flag"] = flag_word(v)
    return out


def damping_long_rows(row) -> list[dict]:
    """Loss-factor rows of the long summary CSV for one summary row: one per material and
    loss factor, keys specimen, material, constant (eta11 ...), value, lower, upper, verdict,
    unit ("1"), status; empty when the specimen had no measured damping."""
    out = []
    for mat, per in (row.get("damping") or {}).items():
        for name, v in per.items():
            out.append({"specimen": row.get("specimen") or row["name"], "material": mat,
                        "constant": name, "value": v["value"], "lower": v["lower"],
                        "upper": v["upper"], "verdict": v["verdict"], "unit": "1",
                        "status": row["status"], "bound_side": v.get("bound_side") or "",
                        "bound_limit": v.get("bound_limit"), "mc_lower": v.get("mc_lower"),
                        "mc_upper": v.get("mc_upper"), "mc_search_limit": search_limit_text(v)})
    return out


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


def wide_columns(material: str, constant: str) -> tuple[str, str, str, str]:
    """The wide summary's columns of one constant, SI units in the headers: its value
    ("IM7/977-2 E2 [Pa]"), then its 95 % interval's ends ("... lower [Pa]", "... upper [Pa]";
    empty where it has none: fixed, at a bound, no uncertainty) and its verdict ("...
    verdict", the words of the long summary's ``verdict``).

    Why the verdict, not the relative half-width: the ends give the width already (to the log
    scale's asymmetry), while the verdict says what they cannot: a Monte Carlo that made it
    worse ("weak (Monte Carlo)"), a value held by its prior, at a bound, fixed."""
    unit = CONSTANT_UNITS.get(constant, "1")          # a loss factor's: 1
    return (f"{material} {constant} [{unit}]", f"{material} {constant} lower [{unit}]",
            f"{material} {constant} upper [{unit}]", f"{material} {constant} verdict")


def csv_header(materials, mesh_check: bool = False, damped=(),
               monte_carlo: bool = False) -> list[str]:
    """Columns of the wide summary (one row per specimen), SI units in the headers: each
    constant's value, then its interval and verdict (:func:`wide_columns`; the value columns
    keep the names they had before these); ``mesh_check``: with MESH_WIDE_COLUMNS before
    ``flagged``. After ``flagged`` (so that the columns before keep their names and places):
    each constant's side of a bound, its limit and its profile (:func:`wide_bound_columns`),
    with ``monte_carlo`` its Monte Carlo range (:func:`wide_mc_columns`), then the ply loss
    factors of each material
    of ``damped`` (value, interval, verdict: :func:`wide_columns`, unit "1"; with
    ``monte_carlo`` their range too)."""
    cols = ["name", "specimen", "path", "status", "reasons"]
    cols += [c for m in materials for k in CONSTANTS for c in wide_columns(m, k)]
    cols += ["rms_residual [%]", "evaluations", "time [s]", "cached", "result",
             "stale_result", *(MESH_WIDE_COLUMNS if mesh_check else ()), "flagged"]
    for m in materials:
        cols += [c for k in CONSTANTS for c in wide_bound_columns(m, k)]
        if monte_carlo:
            cols += [c for k in CONSTANTS for c in wide_mc_columns(m, k)]
    for m in damped:
        cols += [c for k in LOSS_NAMES for c in wide_columns(m, k)]
        if monte_carlo:
            cols += [c for k in LOSS_NAMES for c in wide_mc_columns(m, k)]
    return cols



def wide_bound_column(material: str, constant: str) -> str:
    """The wide summary's column of a constant's side of a bound ("IM7/977-2 G13
    bound_side": "lower", "upper", empty when it is not at a bound), the long form's
    ``bound_side``."""
    return f"{material} {constant} bound_side"


def wide_bound_columns(material: str, constant: str) -> tuple[str, str, str, str, str]:
    """The wide summary's columns of a constant stopped on a search limit, the long form's
    bound_side, bound_limit, profile_bound, profile, profile_far named as its Monte Carlo
    columns are (:func:`wide_mc_columns`), the unit in the headers: "IM7/977-2 G13
    bound_side" (:func:`wide_bound_column`), "... bound_limit [Pa]", "... profile_bound [Pa]",
    "... profile" (bound, flat, none), "... profile_far [Pa]"; empty when it is not at a
    bound.

    Why: without them a spreadsheet reading the wide CSV alone could not tell a constant the
    data bound (S2.1's G13 at 6x6: on its lower limit, rejected above ~1.5 GPa) from one the
    modes do not determine at all (a flat profile), nor could the report draw its profile
    without the result files."""
    unit = CONSTANT_UNITS.get(constant, "1")
    return (wide_bound_column(material, constant),
            f"{material} {constant} bound_limit [{unit}]",
            f"{material} {constant} profile_bound [{unit}]", f"{material} {constant} profile",
            f"{material} {constant} profile_far [{unit}]")


def _bound_cells(iv: dict) -> list[str]:
    """The wide summary's cells of one constant's bound and profile
    (:func:`wide_bound_columns`), written as the long form writes them."""
    return [iv.get("bound_side") or "", _num(iv.get("bound_limit")),
            _num(iv.get("profile_bound")), iv.get("profile") or "",
            _num(iv.get("profile_far"))]


def wide_mc_columns(material: str, name: str) -> tuple[str, str, str]:
    """The wide summary's Monte Carlo columns of a constant or loss factor: the trials'
    range ("IM7/977-2 E2 mc_lower [Pa]", "... mc_upper [Pa]") and which of its ends trials on
    a limit of the search set ("IM7/977-2 E2 mc_search_limit": lower, upper, both, empty;
    a loss factor's lower end set by refits held at 0): the long form's mc_lower, mc_upper,
    mc_search_limit."""
    unit = CONSTANT_UNITS.get(name, "1")
    return (f"{material} {name} mc_lower [{unit}]", f"{material} {name} mc_upper [{unit}]",
            f"{material} {name} mc_search_limit")


def damped_materials(rows) -> list[str]:
    """Materials with ply loss factors in some row (measured damping), in order of first
    appearance."""
    names: list[str] = []
    for r in rows:
        names += [m for m in (r.get("damping") or {}) if m not in names]
    return names


def ran_monte_carlo(rows) -> bool:
    """Whether some row has a Monte Carlo range (a constant's or a loss factor's)."""
    return any(v.get("mc_lower") is not None
               for r in rows for group in ("intervals", "damping")
               for per in (r.get(group) or {}).values() for v in per.values())


#: markers of the terminal table: value at a bound (not identified), value not determined,
#: value held fixed (the initial value, not identified), value held by its prior, value
#: assumed (held at its initial guess by --fix-undetermined)
MARK_BOUND, MARK_UNDETERMINED, MARK_FIXED, MARK_PRIOR, MARK_ASSUMED = "!", "?", "=", "~", "#"
#: the terminal table's mark of a loss factor whose interval is too narrow: its energy share
#: leans on a constant (above it in the table) the modes do not determine
#: (laminid_cli.damping.VERDICT_LEANS, whose words LEANS_WORDS are; its flag FLAG_LEANS)
MARK_LEANS = "^"
FLAG_WORDS = {MARK_BOUND: FLAG_AT_BOUND, MARK_UNDETERMINED: FLAG_UNDETERMINED,
              MARK_FIXED: FLAG_FIXED, MARK_PRIOR: FLAG_PRIOR, MARK_ASSUMED: FLAG_ASSUMED,
              MARK_LEANS: FLAG_LEANS}


def flagged_text(row: dict) -> str:
    """The constants of a row that are not plain identified values, with why, as the terminal
    table marks them ("E-glass/R368.G13 at_bound; E-glass/R368.G23 undetermined"): the wide
    summary's values carry no verdict of their own."""
    return "; ".join(f"{m}.{k} {FLAG_WORDS[mark]}" for m, consts in row["materials"].items()
                     for k in CONSTANTS if k in consts
                     and (mark := _mark(row, m, k)) in FLAG_WORDS)


def parse_flagged(text: str | None) -> dict:
    """{material: {constant: word}} of a wide summary's ``flagged`` cell (:func:`flagged_text`;
    words: the values of :data:`FLAG_WORDS`); {} for an empty cell. Items that are not
    "material.constant word" are skipped."""
    out: dict[str, dict] = {}
    for item in filter(None, (x.strip() for x in (text or "").split(";"))):
        label, _, word = item.rpartition(" ")
        m, _, k = label.rpartition(".")
        if m and k in CONSTANTS and word in FLAG_WORDS.values():
            out.setdefault(m, {})[k] = word
    return out


def _num(v) -> str:
    import math

    return "" if v is None or not math.isfinite(v) else repr(float(v))


def long_rows(rows, folder=None, columns=LONG_COLUMNS) -> list[list[str]]:
    """The long summary: one row per specimen, material and constant (``columns``:
    LONG_COLUMNS, :func:`long_columns`), SI, then its loss factors
    (:func:`damping_long_rows`); a specimen without a result has one row with its status and
    reason."""
    out = []
    for r in rows:
        # the codes (the words are in summary.json and the result file); an error's message
        reasons = r["reason"] if r["status"] in ("error", "not run", NOT_FROM_BATCH) else \
            ", ".join(x["code"] for x in r.get("reasons", []))
        common = {"name": r["name"], "specimen": r["specimen"], "status": r["status"],
                  "reasons": reasons,
                  "rms_residual [%]": "" if r["rms_residual_percent"] is None
                  else f"{r['rms_residual_percent']:.6g}",
                  "result": _path_text(r["result"], folder),
                  "stale_result": _path_text(r.get("stale_result"), folder),
                  **_mesh_cells(r)}
        cells = []
        for m, consts in r["materials"].items():
            for k in CONSTANTS:
                iv = (r.get("intervals") or {}).get(m, {}).get(k, {})
                cells.append({"material": m, "constant": k, "value": _num(consts[k]),
                              "lower": _num(iv.get("lower")), "upper": _num(iv.get("upper")),
                              "verdict": iv.get("verdict", ""),
                              "flag": flag_word(iv),
                              "bound_side": iv.get("bound_side") or "",
                              "bound_limit": _num(iv.get("bound_limit")),
                              "profile_bound": _num(iv.get("profile_bound")),
                              "profile": iv.get("profile") or "",
                              "profile_far": _num(iv.get("profile_far")),
                              "mc_lower": _num(iv.get("mc_lower")),
                              "mc_upper": _num(iv.get("mc_upper")),
                              "mc_search_limit": search_limit_text(iv),
                              "mesh_shift_half_width": _num(iv.get("mesh_shift_half_width")),
                              "unit": CONSTANT_UNITS[k]})
        for d in damping_long_rows(r):
            cells.append({"material": d["material"], "constant": d["constant"],
                          "value": _num(d["value"]), "lower": _num(d["lower"]),
                          "upper": _num(d["upper"]), "verdict": d["verdict"],
                          "flag": flag_word(d), "unit": d["unit"],
                          "bound_side": d["bound_side"], "bound_limit": _num(d["bound_limit"]),
                          "mc_lower": _num(d["mc_lower"]), "mc_upper": _num(d["mc_upper"]),
                          "mc_search_limit": d["mc_search_limit"]})
        for cell in cells or [{}]:
            row = common | cell
            out.append([row.get(col, "") for col in columns])
    return out


def checked_mesh(rows) -> bool:
    """Whether some row has a mesh check (the batch ran with --mesh-check)."""
    return any(r.get("mesh_check") for r in rows)


def long_columns(rows) -> tuple[str, ...]:
    """LONG_COLUMNS, with MESH_LONG_COLUMNS after them when some row has a mesh check."""
    return LONG_COLUMNS + (MESH_LONG_COLUMNS if checked_mesh(rows) else ())


def _mesh_cells(row) -> dict:
    """The per-specimen mesh-check cells of a summary.csv row ("" without a check)."""
    mc = row.get("mesh_check") or {}
    return {"mesh_max_change_sigma": _num(mc.get("max_change_sigma")),
            "mesh_max_shift_half_width": _num(mc.get("max_shift_half_width"))}


def _path_text(path, folder) -> str:
    """A file of a summary row as a CSV cell: relative to ``folder`` (None: as given)."""
    if not path:
        return ""
    return os.path.relpath(path, folder) if folder is not None else str(path)


def _mc_cells(iv: dict) -> list[str]:
    """The wide summary's Monte Carlo cells of one entry (:func:`wide_mc_columns`)."""
    return [_num(iv.get("mc_lower")), _num(iv.get("mc_upper")), search_limit_text(iv)]


def search_limit_text(iv: dict) -> str:
    """The long CSV's mc_search_limit of one interval entry: which ends of the Monte Carlo
    range trials on a limit of the search set ("lower", "upper", "both" or "")."""
    ends = [side for side in ("lower", "upper") if iv.get(f"mc_{side}_at_limit")]
    return "both" if len(ends) == 2 else ends[0] if ends else ""


#: the first line of a summary.csv's options block; every line of the block starts with
#: CSV_COMMENT, so that ``pandas.read_csv(path, comment="#")`` and :func:`read_summary` skip it
CSV_COMMENT = "#"
CSV_OPTIONS_TITLE = ('# laminid {version} batch summary; run options as in summary.json '
                     '"options" (one a line, JSON values):')


def options_comment_lines(options: dict) -> list[str]:
    """The options block of a summary.csv: the title, then one ``# key: value`` line per run
    option of ``options`` (RunOptions.as_dict(): nested settings as dotted keys,
    ``uncertainty.monte_carlo: 200``), the value in JSON.

    Why: summary.json had the options, the CSV not, so a CSV read alone (a spreadsheet,
    pandas) could not tell the mesh, the solver or the Monte Carlo trials its numbers were made
    with. Comment lines above the header leave the table itself as it was. JSON values keep
    ``"6x6"``, ``null`` and ``["nu12", "G13"]`` apart, and JSON escapes every line break."""
    lines = [CSV_OPTIONS_TITLE.format(version=__version__)]

    def add(prefix: str, value) -> None:
        if isinstance(value, dict):
            for key, v in value.items():
                add(f"{prefix}{key}.", v)
        else:
            lines.append(f"{CSV_COMMENT} {prefix[:-1]}: {json.dumps(value)}")

    add("", options)
    return lines


#: the title of a summary.csv's second ``#`` block, after the options: the batch's own
#: settings (:func:`batch_settings`), one ``# batch.KEY: value`` a line
CSV_BATCH_TITLE = ('# how the batch ran, as in summary.json "batch" (the options\' '
                   'uncertainty.jobs above are the processes of one specimen\'s Monte Carlo '
                   'trials and profiles, not the batch\'s):')

#: summary.json's ``batch`` note on the options' ``uncertainty.jobs``
UNCERTAINTY_JOBS_NOTE = ("options.uncertainty.jobs: the processes of one specimen's Monte Carlo "
                         "trials and profiles, inside the process identifying it (null: all "
                         "of its cores); the batch's own processes are 'jobs' and 'scheduler'")


def batch_settings(n_jobs: int, scheduler: str | None) -> dict:
    """The batch's own settings, apart from the identification's options (summary.json's
    ``batch``, the CSV's second ``#`` block): ``jobs`` (-j), ``scheduler`` (None, "local" or
    an address), ``runs_on`` (in words) and the meaning of the options' ``uncertainty.jobs``.

    Why: the options say ``uncertainty.jobs: 1`` for a batch on several processes (each
    specimen's trials in its own worker, the batch parallel over specimens), which read as a
    batch run on one process. None of this enters :func:`input_hash`: -j changes no result."""
    if scheduler is None and n_jobs == 1:
        runs_on = "this process, one specimen after the other"
    elif scheduler is None:
        runs_on = f"up to {n_jobs} worker processes, one specimen at a time in each"
    elif scheduler == "local":
        runs_on = (f"a local Dask cluster of {n_jobs} single-threaded worker processes, one "
                   "specimen at a time in each")
    else:
        runs_on = (f"the workers of the Dask scheduler {scheduler} (as many as it has; -j does "
                   "not apply), one specimen at a time in each")
    return {"jobs": int(n_jobs), "scheduler": scheduler, "runs_on": runs_on,
            "uncertainty_jobs": UNCERTAINTY_JOBS_NOTE}


def batch_comment_lines(batch: dict) -> list[str]:
    """The batch block of a summary.csv: CSV_BATCH_TITLE, then ``# batch.KEY: value`` (JSON)
    for each key of ``batch`` (:func:`batch_settings`) but the note, which the title says."""
    return [CSV_BATCH_TITLE] + [f"{CSV_COMMENT} batch.{key}: {json.dumps(value)}"
                                for key, value in batch.items() if key != "uncertainty_jobs"]


def write_summary_csv(path, rows, wide: bool = False, options: dict | None = None,
                      batch: dict | None = None) -> Path:
    """The summary as CSV, SI units, written atomically.

    Long form (default): LONG_COLUMNS, one row per specimen, material and constant, the unit
    in the ``unit`` column. ``wide``: one row per specimen, the unit in each header, each
    constant's value followed by its interval and verdict (:func:`wide_columns`); its result
    column is relative to the CSV's folder. ``options`` (RunOptions.as_dict()): written above
    the header as ``#`` comment lines (:func:`options_comment_lines`), then ``batch``
    (:func:`batch_settings`) as its own block (:func:`batch_comment_lines`)."""
    import io

    path = Path(path)
    buf = io.StringIO()
    if options is not None:
        buf.write("".join(line + "\n" for line in options_comment_lines(options)))
    if batch is not None:
        buf.write("".join(line + "\n" for line in batch_comment_lines(batch)))
    w = csv.writer(buf, lineterminator="\n")
    if not wide:
        columns = long_columns(rows)
        w.writerow(columns)
        w.writerows(long_rows(rows, path.parent, columns))
        return _write_text(path, buf.getvalue())
    mats = material_names(rows)
    mesh = checked_mesh(rows)
    damped, mc = damped_materials(rows), ran_monte_carlo(rows)
    w.writerow(csv_header(mats, mesh, damped, mc))
    for r in rows:
        values = [r["name"], r["specimen"], r["path"], r["status"], r["reason"]]
        for m in mats:
            c = r["materials"].get(m, {})
            for k in CONSTANTS:
                iv = (r.get("intervals") or {}).get(m, {}).get(k) or {}
                values += [repr(c[k]) if k in c else "", _num(iv.get("lower")),
                           _num(iv.get("upper")), iv.get("verdict") or ""]
        values += ["" if r["rms_residual_percent"] is None else f"{r['rms_residual_percent']:.6g}",
                   "" if r["evaluations"] is None else r["evaluations"],
                   "" if r["time_s"] is None else f"{r['time_s']:.3f}",
                   "yes" if r["cached"] else "no",
                   _path_text(r["result"], path.parent),
                   _path_text(r.get("stale_result"), path.parent)]
        if mesh:
            cells = _mesh_cells(r)
            values += [cells[c] for c in MESH_WIDE_COLUMNS]
        values.append(flagged_text(r))
        for m in mats:
            ivs = (r.get("intervals") or {}).get(m, {})
            values += [c for k in CONSTANTS for c in _bound_cells(ivs.get(k) or {})]
            if mc:
                values += [c for k in CONSTANTS for c in _mc_cells(ivs.get(k) or {})]
        for m in damped:
            per = (r.get("damping") or {}).get(m, {})
            for k in LOSS_NAMES:
                e = per.get(k) or {}
                values += [_num(e.get("value")), _num(e.get("lower")), _num(e.get("upper")),
                           e.get("verdict") or ""]
            if mc:
                values += [c for k in LOSS_NAMES for c in _mc_cells(per.get(k) or {})]
        w.writerow(values)
    return _write_text(path, buf.getvalue())


def batch_report(rows, options: BatchOptions, out_dir, interrupted: bool = False,
                 running: bool = False, duplicates=(), batch: dict | None = None,
                 stopped_by: str | None = None) -> dict:
    """The summary as plain data (SI), as written to summary.json and printed by --json;
    ``interrupted``: the run was stopped (Ctrl-C, SIGTERM) before every specimen was done
    (those rows are "not run"), ``stopped_by`` the signal that stopped it ("SIGINT",
    "SIGTERM"; null when it was not); ``running``: written while the batch runs (:func:`pending_row` for the
    specimens it has not finished), replaced when it ends; ``duplicates``: the groups of
    specimens holding the same plate's measured data (:func:`duplicate_specimens`), each a
    list of their rows' ``name``; ``batch``: the batch's own settings (:func:`batch_settings`),
    after ``options`` (left out when None)."""
    counts = {s: sum(r["status"] == s for r in rows) for s in STATUSES}
    counts["not converged"] = sum(r.get("converged") is False for r in rows)
    counts["set aside"] = sum(bool(r.get("stale_result")) for r in rows
                              if r["status"] != NOT_FROM_BATCH)
    head = {"format": "laminid-batch-summary", "laminid_version": __version__,
            "out": str(out_dir), "options": options.as_dict()}
    if batch is not None:
        head["batch"] = dict(batch)
    return {**head, "units": dict(UNITS),
            "n_specimens": len(rows) - counts[NOT_FROM_BATCH], "counts": counts,
            "n_cached": sum(bool(r["cached"]) for r in rows), "interrupted": bool(interrupted),
            "stopped_by": stopped_by if interrupted else None, "running": bool(running), "duplicates": [list(g) for g in duplicates],
            "specimens": rows}


#: while a batch runs, its summaries are written again at most this often (s) as specimens
#: finish (and before its first result file, and when it ends)
SUMMARY_EVERY = 2.0
#: the reason of a specimen's row in a summary written while the batch runs
PENDING_REASON = ("not finished when this summary was written, while the batch ran (a batch "
                  "that ends, or is stopped with Ctrl-C, writes its own; this one remains "
                  "where the batch was killed: run it again)")


def pending_row(job: Job) -> dict:
    """The row of a specimen the running batch has not finished, in the summaries written
    while it runs (:func:`batch_report` ``running``): "not run" with :data:`PENDING_REASON`.
    A batch killed (SIGKILL, power loss) left the summaries of the run before it, which named
    as "ok", with their old values, specimens whose result files it had replaced or set
    aside."""
    row = result_row(job)
    row["reason"] = PENDING_REASON
    return row


def failed(rows) -> bool:
    """True when the batch must exit 1: an error, a run not done or not converged."""
    return any(r["status"] in ("error", "not run") or r.get("converged") is False
               for r in rows)


#: the ``result_paths`` of a summary.json whose result files are given relative to its own
#: folder (as in summary.csv); a summary without it (written before, or the ``--json`` of the
#: batch on stdout) gives them as the batch saw them: relative to its current folder or absolute
RESULT_PATHS = "relative to this file's folder"


def _relative_to(result: str, folder: Path) -> str:
    try:
        return Path(os.path.relpath(result, folder)).as_posix()
    except ValueError:                     # another drive (Windows): kept absolute
        return str(Path(result).absolute())


def write_summary_json(path, report: dict) -> Path:
    """``report`` (:func:`batch_report`) as summary.json, its result files relative to the
    summary's folder (``result_paths``), so that the folder can be moved and read from
    anywhere."""
    path = Path(path)
    doc = dict(report, result_paths=RESULT_PATHS, specimens=[
        dict(r, **{key: _relative_to(r[key], path.parent)
                   for key in ("result", "stale_result") if r.get(key)})
        for r in report["specimens"]])
    return _write_text(path, json.dumps(json_safe(doc), indent=2) + "\n")


def _result_of_json(result: str, path: Path, doc: dict) -> str:
    """The result file of a summary.json row, as a path from the current folder: relative to
    the summary's folder (``result_paths``), or, in a summary without it, as the batch saw it
    where that file exists, else at its place below ``out`` taken from the summary's folder
    (the summary is written into ``out``)."""
    if doc.get("result_paths") == RESULT_PATHS:
        return str(path.parent / result)   # (an absolute result stays itself)
    if Path(result).exists():
        return result
    out = doc.get("out")
    if isinstance(out, str) and out:
        try:
            below = os.path.relpath(result, out)
        except ValueError:
            below = None
        if below is not None and not below.startswith(".."):
            return str(path.parent / below)
    return str(path.parent / Path(result).name)


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
    # a file name that is not UTF-8 (bytes kept as surrogates by Python) is written with
    # backslash escapes (odd\xff.yaml) rather than failing the whole summary
    return write_bytes_atomic(path, text.encode("utf-8", errors="backslashreplace"))


def read_summary(path) -> list[dict]:
    """Rows of a summary.json or summary.csv (CSV constants converted back to SI; the result
    path made relative to the current folder)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        try:
            # (utf-8-sig: a BOM, as an editor on Windows saves it, dropped; it was
            # "not a readable batch summary (Unexpected UTF-8 BOM)", and a CSV's first
            # column '\ufeffname', "not a laminid batch summary")
            doc = json.loads(path.read_text(encoding="utf-8-sig"))
        except (OSError, ValueError) as exc:
            raise BatchError(f"{path}: not a readable batch summary ({exc})") from exc
        if not isinstance(doc, dict) or doc.get("format") != "laminid-batch-summary":
            raise BatchError(f"{path}: not a laminid batch summary (no format "
                             "'laminid-batch-summary')")
        rows = doc.get("specimens")
        _check_json_rows(path, rows)
        _check_json_text(path, rows, "specimens")
        for r in rows:
            for key in ("result", "stale_result"):
                if r.get(key):
                    r[key] = _result_of_json(r[key], path, doc)
        return rows
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            comments = _Counted(fh)
            reader = csv.DictReader(comments)
            records, line_of = [], {}
            for rec in reader:
                records.append(rec)
                # its line in the file (the comment lines above the header counted)
                line_of[id(rec)] = comments.skipped + reader.line_num
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise BatchError(f"{path}: not a readable batch summary ({exc})") from exc
    if not records or "status" not in records[0] or "name" not in records[0]:
        raise BatchError(f"{path}: not a laminid batch summary (columns name, status, ... "
                         "expected)")
    for rec in records:
        for col, val in rec.items():
            for text in (col, val):
                bad = NON_PRINTABLE.search(text) if isinstance(text, str) else None
                if bad is not None:
                    raise BatchError(f"{path}:{line_of[id(rec)]}, column {col!r}: "
                                     f"non-printable character U+{ord(bad.group()):04X}; "
                                     "remove it")
    if "constant" in records[0]:
        return _rows_of_long(records, path, line_of)
    rows = []
    for rec in records:
        where = (path, line_of[id(rec)])
        mats: dict[str, dict] = {}
        for col, val in rec.items():
            # (a header edited to 'x]' without its ' [unit': not a constant's column)
            if col and col.endswith("]") and " [" in col and val not in ("", None):
                head, unit = col[:-1].rsplit(" [", 1)
                if " " in head and head.rsplit(" ", 1)[1] in CONSTANTS:
                    m, k = head.rsplit(" ", 1)
                    mats.setdefault(m, {})[k] = _number_cell(where, col, val) * (
                        1e9 if unit == "GPa" else 1.0)
        res = rec.get("result") or None
        # the constants --wide flags (at a bound, undetermined, fixed); summaries before the
        # column have no key: nothing is known of their doubt
        flags = {} if "flagged" not in rec else {"flagged": parse_flagged(rec["flagged"])}
        # their intervals and verdicts (summaries before those columns: no key, as above)
        intervals = _intervals_of_wide(rec, mats, flags.get("flagged") or {}, where)
        if intervals is not None:
            flags["intervals"] = intervals
        damping = _damping_of_wide(rec, where)
        if damping:
            flags["damping"] = damping
        rows.append(flags | {"mesh_check": _mesh_of_csv(rec, where),
                             "name": rec["name"], "specimen": rec.get("specimen", ""),
                     "path": rec.get("path", ""), "status": rec["status"],
                     "reason": rec.get("reasons", rec.get("reason", "")),
                     "cached": rec.get("cached") == "yes", "materials": mats,
                     "rms_residual_percent": _cell(where, rec, "rms_residual [%]"),
                     "evaluations": _cell(where, rec, "evaluations"),
                     "time_s": _cell(where, rec, "time [s]"),
                     "result": str(path.parent / res) if res else None,
                     "stale_result": _path_of_csv(rec, "stale_result", path)})
    return rows


class _Counted:
    """The lines of a summary.csv from its header on, as :func:`_after_comments` gives them,
    with ``skipped``: how many comment lines it passed over above the header."""

    def __init__(self, lines):
        self._lines, self.skipped, self._started = iter(lines), 0, False

    def __iter__(self):
        return self

    def __next__(self):
        line = next(self._lines)
        while not self._started and line.startswith(CSV_COMMENT):
            self.skipped += 1
            line = next(self._lines)
        self._started = True
        return line


def _number_cell(where: tuple, column: str, text) -> float | None:
    """A number cell of a summary.csv: None where empty; BatchError naming the file, its line
    and the column where it is text or not finite (a summary edited by hand: 'n/a' was a
    ValueError traceback in laminid report, '1e400' one from matplotlib's axis limits)."""
    if text in ("", None):
        return None
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = None
    if value is None or value != value or value in (float("inf"), float("-inf")):
        path, line = where
        shown = text if len(str(text)) <= 40 else str(text)[:37] + "..."
        raise BatchError(f"{path}:{line}, column {column!r}: {shown!r} is not "
                         f"{'a finite number' if value is not None else 'a number'} (empty "
                         "where there is none)")
    return value


#: the words of a summary's profile cell (resultfile.profile_kind; empty: no profile)
PROFILE_WORDS = ("bound", "flat", "none")
#: the words of a bound_side cell (empty: not at a bound) and of an mc_search_limit cell
#: (search_limit_text; empty: no end set by trials on a limit)
SIDE_WORDS = ("lower", "upper")
SEARCH_LIMIT_WORDS = ("lower", "upper", "both")


def _profile_cell(where: tuple, column: str, text) -> str:
    """A profile cell of a summary.csv: "" where empty; BatchError naming the file, its line
    and the column where it is another word (edited by hand: 'Bound' or 'rejected' was taken
    as it stood, a profile the report then neither drew nor named)."""
    return _word_cell(where, column, text, PROFILE_WORDS, "a profile's word")


def _word_cell(where: tuple, column: str, text, words, what: str) -> str:
    """A cell of a summary.csv that holds one of ``words`` or nothing: "" where empty;
    BatchError naming the file, its line, the column and the words where it is another."""
    if text in ("", None):
        return ""
    if text not in words:
        path, line = where
        shown = text if len(str(text)) <= 40 else str(text)[:37] + "..."
        raise BatchError(f"{path}:{line}, column {column!r}: {shown!r} is not {what} "
                         f"({', '.join(words)}; empty where there is none)")
    return text


def _cell(where: tuple, rec: dict, column: str) -> float | None:
    """:func:`_number_cell` of ``rec``'s ``column`` (None where the summary has no such
    column): the summary's other numbers (the residual, a bound's limit, a profile's ends, a
    Monte Carlo range, the mesh check) edited to text were read as none, where a constant's
    were refused."""
    return _number_cell(where, column, rec.get(column))


def _interval_cells(where: tuple, lo_col: str, hi_col: str, rec: dict) -> tuple:
    """An interval's ends from their cells (:func:`_number_cell`), BatchError where the lower
    is above the upper."""
    lower = _number_cell(where, lo_col, rec.get(lo_col))
    upper = _number_cell(where, hi_col, rec.get(hi_col))
    if lower is not None and upper is not None and lower > upper:
        path, line = where
        raise BatchError(f"{path}:{line}, columns {lo_col!r} and {hi_col!r}: the lower end "
                         f"{lower:g} is above the upper {upper:g}")
    return lower, upper


def _check_json_text(path: Path, value, field: str) -> None:
    """BatchError naming the file and the field of a summary.json's text (a key or a value,
    at any depth) holding a non-printable character (:data:`~laminid_cli.errors.NON_PRINTABLE`),
    which report would print or draw: a BEL in a name warned 'Glyph 7 missing from font'."""
    if isinstance(value, str):
        bad = NON_PRINTABLE.search(value)
        if bad is not None:
            raise BatchError(f"{path}: field '{field}': non-printable character "
                             f"U+{ord(bad.group()):04X}; remove it")
    elif isinstance(value, dict):
        for key, item in value.items():
            _check_json_text(path, key, f"{field} (a key)")
            _check_json_text(path, item, f"{field}.{key}")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _check_json_text(path, item, f"{field}[{i}]")


def _check_json_rows(path: Path, rows) -> None:
    """BatchError naming the file and the field where a summary.json edited by hand has not
    the shape laminid report reads (a list of specimens, each with its name and status as
    text, its constants as numbers by material, its intervals by material and constant, its
    result file as text): it was a KeyError, AttributeError or TypeError traceback."""
    def bad(field, what, value):
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
        raise BatchError(f"{path}: field '{field}': {what}, got {shown}")

    def number_or_null(field, value):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                  or value != value or abs(value) == float("inf")):
            bad(field, "expected a finite number or null", value)

    if not isinstance(rows, list):
        bad("specimens", "expected a list of specimens", rows)
    for i, r in enumerate(rows):
        at = f"specimens[{i}]"
        if not isinstance(r, dict):
            bad(at, "expected a mapping (a specimen)", r)
        for key in ("name", "status"):
            if not isinstance(r.get(key), str):
                bad(f"{at}.{key}", "expected text", r.get(key))
        for key in ("result", "stale_result"):
            if r.get(key) is not None and not isinstance(r[key], str):
                bad(f"{at}.{key}", "expected a file name or null", r[key])
        number_or_null(f"{at}.rms_residual_percent", r.setdefault("rms_residual_percent", None))
        for key in ("mesh_check", "flagged"):
            if r.get(key) is not None and not isinstance(r[key], dict):
                bad(f"{at}.{key}", "expected a mapping or null", r[key])
        for key in ("materials", "intervals", "damping"):
            table = r.get(key)
            if table is None and key != "materials":
                continue
            if not isinstance(table, dict):
                bad(f"{at}.{key}", "expected a mapping by material", table)
            for m, consts in table.items():
                if not isinstance(consts, dict):
                    bad(f"{at}.{key}.{m}", "expected a mapping by constant", consts)
                for k, v in list(consts.items()):
                    if key == "materials":
                        number_or_null(f"{at}.{key}.{m}.{k}", v)
                        if v is None:           # (NaN written as null): no value, as a
                            del consts[k]       # summary.csv's empty cell
                    elif not isinstance(v, dict):
                        bad(f"{at}.{key}.{m}.{k}", "expected a mapping (lower, upper, verdict)",
                            v)
                    else:
                        for end in ("value", "lower", "upper"):
                            number_or_null(f"{at}.{key}.{m}.{k}.{end}", v.get(end))
                        if v.get("profile") not in (None, "", *PROFILE_WORDS):
                            bad(f"{at}.{key}.{m}.{k}.profile",
                                f"expected {', '.join(PROFILE_WORDS)} or empty",
                                v["profile"])


def _intervals_of_wide(rec: dict, mats: dict, flagged: dict, where: tuple) -> dict | None:
    """A wide summary record's ``intervals`` ({material: {constant: entry}}, the long reader's
    keys) from its interval and verdict columns (:func:`wide_columns`) and its ``flagged``
    words; None for a summary written before those columns. A constant whose three cells are
    empty (no uncertainty) gets no entry. The side of a bound, its limit and the profile
    (:func:`wide_bound_columns`) as the long reader gives them; a summary written before
    those columns: bound_side "", bound_limit None, no profile keys."""
    found = False
    out: dict[str, dict] = {}
    for col in rec:
        if not (col and col.endswith(" verdict")):
            continue
        m, _, k = col[: -len(" verdict")].rpartition(" ")
        if k not in CONSTANTS or not m:
            continue
        found = True
        _, lo_col, hi_col, _ = wide_columns(m, k)
        lower, upper = _interval_cells(where, lo_col, hi_col, rec)
        verdict = rec.get(col) or ""
        if lower is None and upper is None and not verdict or k not in mats.get(m, {}):
            continue
        word = flagged.get(m, {}).get(k, "")
        # (the side: summaries written before its column do not say, "")
        side_col, limit_col, pb_col, kind_col, far_col = wide_bound_columns(m, k)
        side = _word_cell(where, side_col, rec.get(side_col), SIDE_WORDS, "a bound's side")
        iv = out.setdefault(m, {})[k] = {
            "lower": lower, "upper": upper, "verdict": verdict,
            "at_bound": verdict == VERDICT_AT_BOUND or word == FLAG_AT_BOUND or bool(side),
            "bound_side": side,
            # (summaries written before its column: None, as before)
            "bound_limit": _number_cell(where, limit_col, rec.get(limit_col)),
            "flagged": word == FLAG_UNDETERMINED, "assumed": word == FLAG_ASSUMED,
            "flag": word}
        if kind_col in rec:
            # the profile, in the long reader's keys; a summary written before these columns
            # has none of them (the report takes the result file's profile where found)
            iv.update(profile_bound=_number_cell(where, pb_col, rec.get(pb_col)),
                      profile=_profile_cell(where, kind_col, rec.get(kind_col)),
                      profile_far=_number_cell(where, far_col, rec.get(far_col)))
        iv.update(_mc_of_wide(rec, m, k, where))
    return out if found else None


def _mc_keys(rec: dict, lo_col: str, hi_col: str, limit_col: str, where: tuple) -> dict:
    """The Monte Carlo keys (mc_lower, mc_upper, mc_lower_at_limit, mc_upper_at_limit) of one
    constant or loss factor of a summary.csv record, from its range's columns and the one
    saying which ends trials on a search limit set (:func:`search_limit_text`: the long
    summary's mc_lower, mc_upper, mc_search_limit; the wide one's :func:`wide_mc_columns`);
    {} where it has none (no Monte Carlo, a summary written before those columns)."""
    if rec.get(lo_col) in ("", None):
        return {}
    # ('Lower' was taken as neither end)
    limit = _word_cell(where, limit_col, rec.get(limit_col), SEARCH_LIMIT_WORDS,
                       "a Monte Carlo range's ends")
    return {"mc_lower": _cell(where, rec, lo_col), "mc_upper": _cell(where, rec, hi_col),
            "mc_lower_at_limit": limit in ("lower", "both"),
            "mc_upper_at_limit": limit in ("upper", "both")}


def _mc_of_wide(rec: dict, material: str, name: str, where: tuple) -> dict:
    """:func:`_mc_keys` of one constant or loss factor of a wide summary record."""
    return _mc_keys(rec, *wide_mc_columns(material, name), where)


def _damping_of_wide(rec: dict, where: tuple) -> dict:
    """A wide summary record's ``damping`` ({material: {etaXY: entry}}, the long reader's
    keys) from its loss-factor columns (:func:`csv_header`), their cells checked as the
    constants' (:func:`_number_cell`, :func:`_interval_cells`; ``where``: file and line);
    {} for a specimen without loss factors or a summary written before those columns."""
    out: dict[str, dict] = {}
    for col in rec:
        if not (col and col.endswith(" [1]")):
            continue
        m, _, k = col[: -len(" [1]")].rpartition(" ")
        if k not in LOSS_NAMES or not m or rec.get(col) in ("", None):
            continue
        value_col, lo_col, hi_col, verdict_col = wide_columns(m, k)
        verdict = rec.get(verdict_col) or ""
        # a loss factor held at 0 by eta >= 0: its verdict says so (no interval), side lower
        hit = verdict == VERDICT_AT_BOUND
        lower, upper = _interval_cells(where, lo_col, hi_col, rec)
        out.setdefault(m, {})[k] = {
            "value": _number_cell(where, value_col, rec[value_col]), "lower": lower,
            "upper": upper, "verdict": verdict, "at_bound": hit,
            "bound_side": "lower" if hit else "", "bound_limit": 0.0 if hit else None,
            **_mc_of_wide(rec, m, k, where)}
    return out


def _after_comments(lines):
    """The lines of a summary.csv from its header on: the ``#`` lines above it (the options
    block of :func:`options_comment_lines`; none in a summary written before it) skipped. Only
    those above the header: a data line may start with ``#`` (a folder named ``#2``)."""
    lines = iter(lines)
    for line in lines:
        if not line.startswith(CSV_COMMENT):
            yield line
            break
    yield from lines


def _comment_blocks(path) -> tuple[dict | None, dict | None]:
    """The run options and the batch's settings a summary.csv records above its header
    (:func:`options_comment_lines`, :func:`batch_comment_lines`), each None where the file has
    no such block (a summary written before it)."""
    blocks: dict[str, dict] = {}
    current = None
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            for line in fh:
                if not line.startswith(CSV_COMMENT):
                    break
                text = line.rstrip("\r\n")
                if text == CSV_BATCH_TITLE:
                    current = blocks.setdefault("batch", {})
                    continue
                key, sep, value = line[len(CSV_COMMENT):].strip().partition(": ")
                if not sep or key.startswith("laminid "):
                    current = blocks.setdefault("options", {})
                    continue                          # the title line
                try:
                    parsed = json.loads(value)
                except ValueError as exc:
                    raise BatchError(f"{path}: option line {line.strip()!r}: the value is not "
                                     f"JSON ({exc})") from exc
                if current is None:                   # no title above it: an options line
                    current = blocks.setdefault("options", {})
                *heads, last = key.split(".")
                if current is blocks.get("batch") and heads[:1] == ["batch"]:
                    heads = heads[1:]
                d = current
                for head in heads:
                    d = d.setdefault(head, {})
                d[last] = parsed
    except (OSError, UnicodeDecodeError) as exc:
        raise BatchError(f"{path}: not a readable batch summary ({exc})") from exc
    return blocks.get("options") or None, blocks.get("batch") or None


def read_summary_options(path) -> dict | None:
    """The run options a summary.csv records above its header (RunOptions.as_dict(), as
    summary.json's ``options``); None for a summary written before they were recorded."""
    return _comment_blocks(path)[0]


def read_summary_batch(path) -> dict | None:
    """The batch's own settings a summary.csv records above its header (summary.json's
    ``batch`` without its note on uncertainty.jobs: ``jobs``, ``scheduler``, ``runs_on``);
    None for a summary written before they were recorded."""
    return _comment_blocks(path)[1]


def _rows_of_long(records, path: Path, line_of: dict) -> list[dict]:
    """Rows of a long summary.csv (one record per constant) grouped by specimen."""
    rows: dict[str, dict] = {}
    for rec in records:
        where = (path, line_of[id(rec)])
        r = rows.get(rec["name"])
        if r is None:
            res = rec.get("result") or None
            r = rows[rec["name"]] = {
                "name": rec["name"], "specimen": rec.get("specimen", ""), "path": "",
                "status": rec["status"], "reason": rec.get("reasons", ""), "cached": False,
                "materials": {}, "intervals": {},
                "rms_residual_percent": _cell(where, rec, "rms_residual [%]"),
                "evaluations": None, "time_s": None, "mesh_check": _mesh_of_csv(rec, where),
                "result": str(path.parent / res) if res else None,
                "stale_result": _path_of_csv(rec, "stale_result", path)}
        m, k = rec.get("material"), rec.get("constant")
        if m and k in CONSTANTS and rec.get("value") not in ("", None):
            r["materials"].setdefault(m, {})[k] = _number_cell(where, "value", rec["value"])
            side = _word_cell(where, "bound_side", rec.get("bound_side"), SIDE_WORDS,
                              "a bound's side")
            lower, upper = _interval_cells(where, "lower", "upper", rec)
            iv = r["intervals"].setdefault(m, {})[k] = {
                "lower": lower, "upper": upper,
                "verdict": rec.get("verdict", ""),
                # (summaries written before the bound columns: the verdict says it)
                "at_bound": bool(side) or rec.get("verdict", "") == VERDICT_AT_BOUND,
                "bound_side": side, "bound_limit": _cell(where, rec, "bound_limit"),
                "profile_bound": _cell(where, rec, "profile_bound"),
                "profile": _profile_cell(where, "profile", rec.get("profile")),
                "profile_far": _cell(where, rec, "profile_far"),
                # a value --fix-undetermined held (its verdict is "fixed" as a known one's)
                "assumed": rec.get("flag") == FLAG_ASSUMED}
            iv.update(_mc_keys(rec, "mc_lower", "mc_upper", "mc_search_limit", where))
        elif m and k and k.startswith("eta") and rec.get("value") not in ("", None):
            side = _word_cell(where, "bound_side", rec.get("bound_side"), SIDE_WORDS,
                              "a bound's side")
            lower, upper = _interval_cells(where, "lower", "upper", rec)
            eta = r.setdefault("damping", {}).setdefault(m, {})[k] = {
                "value": _number_cell(where, "value", rec["value"]), "lower": lower,
                "upper": upper, "verdict": rec.get("verdict", ""),
                "at_bound": bool(side), "bound_side": side,
                "bound_limit": _cell(where, rec, "bound_limit")}
            eta.update(_mc_keys(rec, "mc_lower", "mc_upper", "mc_search_limit", where))
    return list(rows.values())


def _mesh_of_csv(rec: dict, where: tuple) -> dict | None:
    """The row's ``mesh_check`` as far as a summary.csv gives it (max_change_sigma,
    max_shift_half_width, coarse_mesh from its reasons); None without a check."""
    if rec.get("mesh_max_shift_half_width") in ("", None) and \
            rec.get("mesh_max_change_sigma") in ("", None):
        return None
    return {"max_change_sigma": _cell(where, rec, "mesh_max_change_sigma"),
            "max_shift_half_width": _cell(where, rec, "mesh_max_shift_half_width"),
            "coarse_mesh": "coarse_mesh" in (rec.get("reasons") or "")}


def _path_of_csv(rec: dict, column: str, path: Path) -> str | None:
    """A file named in a summary.csv column, relative to the CSV's folder (None: empty or a
    summary written before the column)."""
    text = rec.get(column) or None
    return str(path.parent / text) if text else None


def _mark(row: dict, material: str, constant: str) -> str:
    return _mark_of((row.get("intervals") or {}).get(material, {}).get(constant, {}))


def _mark_of(entry: dict) -> str:
    """The terminal table's mark of a constant's or loss factor's entry, by its summaries'
    flag (:func:`flag_word`; " " for none)."""
    word = flag_word(entry) if entry else ""
    return next((mark for mark, w in FLAG_WORDS.items() if w == word), " ")


def format_table(rows, on_stderr=None) -> str:
    """The constants across specimens as text, shaped like the paper's Table 2: one block per
    set of materials, specimens as columns, constants as rows (GPa; a value at its bound
    marked "!", one not determined by the modes "?", a fixed one "=", one assumed by
    --fix-undetermined "#", one held by its prior "~"), a status row; then the
    reasons of every "check", the warnings of each result and the specimens without a
    result. ``on_stderr``: {row name: n}, a result's first n warnings (its specimen reader's)
    are on stderr already, logged as this run read the file: not listed again."""
    lines = []
    groups: dict[tuple, list] = {}
    for r in rows:
        if r["materials"]:
            groups.setdefault(tuple(r["materials"]), []).append(r)
    marked: set[str] = set()
    loss_marked: set[str] = set()           # the marks of loss factors' cells
    plain = False
    for mats, members in groups.items():
        specs = [r["specimen"] for r in members]
        labels = specs if all(specs) and len(set(specs)) == len(specs) else \
            [r["name"] for r in members]
        status_w = [len(r['status'] + (' (cached)' if r['cached'] else '')) for r in members]
        width = max(9, *(len(s) for s in labels), *status_w)
        mesh = checked_mesh(members)
        # the ply loss factors' rows (in %) of the materials some specimen here has them of
        damped = [m for m in mats if any((r.get("damping") or {}).get(m) for r in members)]
        label_w = max(19 if mesh else 18,
                      *(len(f"{m} {k} [GPa]") for m in mats for k in CONSTANTS)) \
            if len(mats) > 1 else 19 if mesh else 18
        head = ", ".join(mats)
        lines.append(f"{head:<{label_w}}" + "".join(f"  {s:>{width}} " for s in labels))
        for m in mats:
            for k in CONSTANTS:
                unit = "" if k == "nu12" else " [GPa]"
                name = f"{m} {k}{unit}" if len(mats) > 1 else f"{k}{unit}"
                cells = []
                for r in members:
                    v = r["materials"][m][k]
                    mark = _mark(r, m, k)
                    marked.add(mark)
                    if mark == " " and ((r.get("intervals") or {}).get(m, {}).get(k) or {}).get(
                            "verdict"):
                        plain = True      # an identified value with its interval, unmarked
                    # a modulus at its floor (a few MPa) keeps 3 digits, not "0.00"
                    gpa = v / 1e9
                    text = (f"{v:.3f}" if k == "nu12" else
                            f"{gpa:.2f}" if abs(gpa) >= 0.1 or gpa == 0 else f"{gpa:.3g}")
                    cells.append(text + mark)
                lines.append(f"{name:<{label_w}}" + "".join(f"  {c:>{width + 1}}" for c in cells))
        for m in damped:
            for k in LOSS_NAMES:
                if not any(k in ((r.get("damping") or {}).get(m) or {}) for r in members):
                    continue
                name = f"{m} {k} [%]" if len(mats) > 1 else f"{k} [%]"
                cells = []
                for r in members:
                    e = ((r.get("damping") or {}).get(m) or {}).get(k)
                    if e is None:                 # no measured damping: no loss factor
                        cells.append("—" + " ")
                        loss_marked.add("—")
                        continue
                    mark = _mark_of(e)        # the constants' marks (held at 0: "!"; "^")
                    marked.add(mark)
                    loss_marked.add(mark)
                    plain = plain or (mark == " " and bool(e.get("verdict")))
                    cells.append(f"{100 * float(e['value']):.3f}" + mark)
                lines.append(f"{name:<{label_w}}" + "".join(f"  {c:>{width + 1}}" for c in cells))
        lines.append(f"{'RMS residual [%]':<{label_w}}" + "".join(
            f"  {r['rms_residual_percent']:>{width}.3f} " for r in members))
        lines.append(f"{'evaluations':<{label_w}}" + "".join(
            f"  {int(r['evaluations']):>{width}d} " for r in members))
        if mesh:
            for label, key in (("mesh change [sigma]", "max_change_sigma"),
                               ("mesh shift [hw]", "max_shift_half_width")):
                lines.append(f"{label:<{label_w}}" + "".join(
                    f"  {_mesh_text(r, key):>{width}} " for r in members))
        lines.append(f"{'status':<{label_w}}" + "".join(
            f"  {(r['status'] + (' (cached)' if r['cached'] else '')):>{width}} "
            for r in members))
        lines.append("")
    legend = [text for mark, text in (
        (MARK_BOUND, f"{MARK_BOUND} at its bound — not identified"),
        (MARK_UNDETERMINED, f"{MARK_UNDETERMINED} not determined by these modes (interval wider "
                            "than --max-rel-interval)"),
        (MARK_FIXED, f"{MARK_FIXED} fixed at its initial value — not identified (--fix or "
                     "the file's 'fixed')"),
        (MARK_ASSUMED, f"{MARK_ASSUMED} assumed: fixed at its initial guess because the modes "
                       "did not determine it (--fix-undetermined) — not identified, not known"),
        (MARK_PRIOR, f"{MARK_PRIOR} held by the prior — mostly the file's prior value, not "
                     "the modes' (the prior gives more than half of what is known of it, "
                     "paper Eq. 15)")) if mark in marked]
    if plain:
        # an unmarked value is no exact one: its interval is in the summaries (the table has
        # room for the value alone)
        legend.append("unmarked: identified, its 95 % interval within --max-rel-interval of "
                      "the value (well determined or weak: summary.csv's lower, upper, verdict)")
    if loss_marked:
        # a loss factor's "?" and "!" say something else than a constant's
        legend.append("eta [%]: ply loss factors in % (modal strain energy), in the same marks"
                      + "".join(text for mark, text in (
                          (MARK_UNDETERMINED, f", {MARK_UNDETERMINED} not determined by the "
                                              "measured damping"),
                          (MARK_BOUND, f", {MARK_BOUND} held at 0 by eta >= 0 — not "
                                       "identified"),
                          (MARK_LEANS, f", {MARK_LEANS} interval too narrow: its energy share "
                                       "leans on a constant above that the modes do not "
                                       "determine (its verdict in the summaries names it)"),
                          (MARK_FIXED, f", {MARK_FIXED} fixed by --fix"),
                          ("—", ", — no measured damping")) if mark in loss_marked))
    if any(checked_mesh(g) for g in groups.values()):
        legend.append("mesh change/shift: on a mesh twice as fine (--mesh-check), the largest "
                      "frequency change in the mode's sigmas and the largest shift of a constant "
                      f"in its 95 % half-widths (beyond {_shift_limit():g}: coarse_mesh)")
    if legend:
        lines.append("; ".join(legend))
        lines.append("")
    checks = [r for r in rows if r["status"] == "check"]
    if checks:
        lines.append("check:")
        for r in checks:
            lines.append(f"  {_who(r)}:")
            lines += [f"    {x['code']}: {x['text']}" for x in r.get("reasons", [])]
    # each result's warnings (the specimen reader's: a mass that density x volume contradicts,
    # ply angles that look like radians; the run's: a coarse mesh...), as summary.json has them
    # (those the specimen reader logged on stderr as this run read the file, not again: a
    # terminal showed each of them twice)
    on_stderr = on_stderr or {}
    warned = [(r, left) for r in rows
              if (left := (r.get("warnings") or [])[on_stderr.get(r["name"], 0):])]
    if warned:
        lines.append("warnings:")
        for r, left in warned:
            lines.append(f"  {_who(r)}:")
            lines += [f"    {w}" for w in left]
    failed_rows = [r for r in rows if r["status"] in ("error", "not run")]
    if failed_rows:
        lines.append("not identified:")
        for r in failed_rows:
            reason = r["reason"] or ""
            text = reason if reason.startswith(r["status"]) else \
                f"{r['status']}: {reason}" if reason else r["status"]
            lines.append(f"  {_who(r)}: {text}")
            if r.get("stale_result"):
                lines.append(f"    its earlier result (of another input) moved to "
                             f"{r['stale_result']}")
    others = [r for r in rows if r["status"] == NOT_FROM_BATCH]
    if others:
        lines.append("not from this batch (no specimen of its inputs has them; kept as they "
                     "are):")
        lines += [f"  {r['stale_result']}" for r in others]
    return printable("\n".join(lines).rstrip() + "\n")


def _who(row: dict) -> str:
    """A row's name in the table's lists of reasons and errors: the batch name (file path
    without suffix, as in the summaries), with the specimen's ``name:`` field first where the
    table's column shows that and it differs ("S1.4 (good)"), so that the two can be tied."""
    name, spec = row["name"], row.get("specimen") or ""
    return name if not spec or spec in (name, name.rsplit("/", 1)[-1]) else f"{spec} ({name})"


def _mesh_text(row: dict, key: str) -> str:
    """A mesh-check cell of the terminal table ("—" for a specimen without a check)."""
    v = (row.get("mesh_check") or {}).get(key)
    return "—" if v is None else f"{v:.2f}"


def _shift_limit() -> float:
    from laminid_cli.meshcheck import SHIFT_LIMIT

    return SHIFT_LIMIT


def printable(text: str) -> str:
    """``text`` with the undecodable bytes of file names (kept by Python as surrogates, e.g.
    ``odd\\udcff``) written as backslash escapes, so that it can be printed and saved."""
    return text.encode("utf-8", errors="backslashreplace").decode("utf-8")
