"""Options and output helpers shared by the commands (declared once, as in rasterio's rio)."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import click

class FiniteFloat(click.FloatRange):
    """A float option that refuses ``nan`` and ``inf`` (click's FLOAT and FloatRange take them:
    NaN passes every bound check), with optional bounds as :class:`click.FloatRange`."""

    name = "finite float"

    def convert(self, value, param, ctx):
        if isinstance(value, float) and math.isfinite(value):
            return super().convert(value, param, ctx)
        number = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return super().convert(number, param, ctx)

    def _describe_range(self) -> str:
        # click shows an unbounded range as "x<=None" in the help
        if self.min is None and self.max is None:
            return ""
        return super()._describe_range()


#: the most evaluations --max-evaluations allows (a run's evaluations in all; the result
#: file's reader bounds its /history by it: laminid_cli.resultfile._row_limit)
MAX_EVALUATIONS = 100000


class TrialCount(click.IntRange):
    """The number of Monte Carlo trials: 0 (off) or 2..:data:`MAX_TRIALS` (one trial has no
    spread; the trials' perturbations are drawn up front, so a huge number fills the memory)."""

    name = "trials"
    MAX_TRIALS = 100000

    def __init__(self):
        super().__init__(0, self.MAX_TRIALS)

    def convert(self, value, param, ctx):
        n = click.INT.convert(value, param, ctx)
        if n == 1:
            self.fail("1 trial gives no spread: 0 (off) or at least 2.", param, ctx)
        if n > self.MAX_TRIALS:
            self.fail(f"{n} is more than {self.MAX_TRIALS} trials (hours of work; the "
                      "2.5 %/97.5 % quantiles need a few hundred).", param, ctx)
        return super().convert(n, param, ctx)

    def _describe_range(self) -> str:
        return f"0 (off) or 2<=N<={self.MAX_TRIALS}"


class Fraction(FiniteFloat):
    """A fraction (0.002), also written as a percentage, ``0.2%`` or ``0.2 %`` (0.002), as the
    README and the output say these values and as ``--fix eta13=1%`` takes a loss factor:
    ``--sigma-rel 0.2%`` was refused as "not a valid float", leaving the lab to guess that
    0.002 was meant (and ``0.2``, 20 %, is taken)."""

    name = "fraction"

    def convert(self, value, param, ctx):
        if isinstance(value, str) and value.strip().endswith("%"):
            text = value.strip()[:-1].strip()
            try:
                number = float(text)
            except ValueError:
                self.fail(f"{value!r} is not a number: write a fraction (0.002) or a "
                          "percentage (0.2%).", param, ctx)
            if not math.isfinite(number):
                self.fail(f"{value!r} is not a finite number.", param, ctx)
            return super().convert(number / 100, param, ctx)
        return super().convert(value, param, ctx)


#: a relative standard deviation of a frequency (--sigma-rel): a fraction, 1e-9 <= x < 0.5
#: (uncertainty.SIGMA_REL_MIN: below it the model's own round-off)
SIGMA_REL = Fraction(min=1e-9, max=0.5, max_open=True)


class InputFile(click.Path):
    """A file to read, named on the command line: refused in laminid's one-line format
    (``laminid: error: <file>: ...``, exit 2) when it is a folder, or (``must_exist``) missing,
    not with click's usage text. (Without ``must_exist`` the reader says "file not found",
    after what it can tell from the name alone.)"""

    def __init__(self, must_exist: bool = False, folder_hint=None):
        super().__init__()
        self.must_exist = must_exist
        #: the words added for a folder (the command that takes it), from the folder's path;
        #: "" where there is nothing to add
        self.folder_hint = folder_hint

    def convert(self, value, param, ctx):
        from laminid_cli.errors import InputFileError

        value = super().convert(value, param, ctx)
        path = Path(value)
        if path.is_dir():
            hint = self.folder_hint(path) if self.folder_hint is not None else ""
            raise InputFileError(f"{value}: is a folder, not a file{hint}", path=value)
        if self.must_exist and not path.exists():
            raise InputFileError(f"{value}: file not found", path=value)
        return value


#: the FRF files a folder holds, as fit-frf names them for a folder given as FRF_FILE
FRF_PATTERNS = ("*.frf.h5", "*.uff", "*.unv", "*.csv", "*.txt", "*.mat")


def files_hint(command: str, patterns, what: str):
    """A ``folder_hint`` for :class:`InputFile`: what a folder given for a file holds that
    ``laminid COMMAND`` takes (``patterns`` in the folder itself), one named in the command
    to run ("efrf: is a folder, not a file; it holds 1 FRF file: 'laminid fit-frf
    efrf/plate.frf.h5'"); it was "is a folder, not a file" alone."""
    def hint(folder: Path) -> str:
        import shlex

        # (a batch's summary.csv is no FRF file)
        found = sorted({p for pat in patterns for p in folder.glob(pat)
                        if p.is_file() and p.name != "summary.csv"})
        if not found:
            return ""
        many = len(found) > 1
        return (f"; it holds {len(found)} {what}{'s' if many else ''}: 'laminid {command} "
                f"{shlex.quote(str(found[0]))}'" + (" takes one" if many else ""))
    return hint


#: a file to write, named on the command line: click checks nothing, the command refuses a
#: folder or a file it must not replace in laminid's format (:func:`check_output_path`)
OUTPUT_FILE = click.Path()


def stderr_is_terminal() -> bool:
    """Whether stderr is a terminal: progress lines (``\\r``) are drawn there only (report,
    fit-frf)."""
    import sys

    return sys.stderr.isatty()


def quiet() -> bool:
    """True under ``laminid -q`` (only errors on stderr: no count lines, no progress)."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx is not None and ctx.find_root().params.get("quiet"))


#: what --json prints when the command fails (laminid_cli.cli: the error's document)
JSON_ERROR_DOC = ("{\"error\": {\"kind\", \"message\", \"file\", \"field\", \"line\", "
                  "\"exit_code\"}}")
JSON_ERROR_NOTE = f"a command that fails prints {JSON_ERROR_DOC} instead"

json_option = click.option(
    "--json", "as_json", is_flag=True,
    help="Print the results as JSON on stdout (SI units, frequencies in Hz) instead of tables; "
         "its 'units' maps each field name to its unit (\"E1\": \"Pa\"); "
         + JSON_ERROR_NOTE + ".")

#: the FRF commands' JSON names the FRF's engineering unit ``frf_unit``: ``units``, which
#: held it, is the field -> unit map in the other commands' JSON (modes, identify, show,
#: batch); kept as the same text for one release (0.2.x), then dropped
FRF_UNIT_NOTE = ("'frf_unit' is the FRF's engineering unit (\"Pa/N\"); 'units', its old name, "
                 "holds the same text in this release only (elsewhere 'units' maps each field "
                 "to its unit)")

def echo_frf_warnings(fs) -> list[str]:
    """The warnings the reader of the FRF set ``fs`` left in its ``meta`` (a frequency unit
    not stated: laminid_cli.frf.io), each on stderr as ``warning: ...``; returned for --json's
    ``warnings``."""
    from laminid_cli.errors import escaped

    warnings = list(fs.meta.get("warnings") or ())
    for warning in warnings:
        click.echo(escaped(f"warning: {warning}"), err=True)
    return warnings


frf_json_option = click.option(
    "--json", "as_json", is_flag=True,
    help="Print the results as JSON on stdout (SI units, frequencies in Hz) instead of tables; "
         + FRF_UNIT_NOTE + "; " + JSON_ERROR_NOTE + ".")

force_option = click.option(
    "--force", is_flag=True, help="Overwrite an existing output file.")


def _kind(path: Path) -> str:
    """What a non-regular file is, in words."""
    import stat

    mode = path.stat().st_mode
    for test, word in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return word
    return "not a regular file"


def writable_target(path: str | Path, option: str = "-o") -> Path:
    """``path`` as the file to write: refused (OutputExistsError, exit 2) when its name is
    empty, its folder does not exist, is not a folder or cannot be written to, or it exists and
    is not a regular file (a folder, FIFO or device is never replaced, even with --force). A
    symbolic link is followed: its target is the file written (the link stays)."""
    import os

    from laminid_cli.errors import OutputExistsError

    if str(path).strip() == "":
        raise OutputExistsError(f"{option}: the file name is empty")
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    if path.exists() and not path.is_file():
        raise OutputExistsError(f"{path}: is {_kind(path)}, not a file: laminid writes its results "
                                f"to regular files only; choose another name with {option}",
                                path=path)
    parent = path.parent
    if not parent.exists():
        raise OutputExistsError(f"{path}: folder {parent} does not exist", path=path)
    if not parent.is_dir():
        raise OutputExistsError(f"{path}: {parent} is not a folder", path=path)
    if not folder_writable(parent):
        raise OutputExistsError(f"{path}: folder {parent} cannot be written to (permissions, "
                                "a read-only or special file system); choose another place "
                                f"with {option}", path=path)
    return path


def folder_writable(folder: str | Path) -> bool:
    """True when a file can be created in the existing ``folder``: its permissions, then a
    probe file (root passes os.access; a read-only mount or /proc refuses new files)."""
    import os
    import tempfile

    if not os.access(folder, os.W_OK | os.X_OK):
        return False
    try:
        fd, probe = tempfile.mkstemp(prefix=".laminid-probe-", dir=folder)
    except OSError:
        return False
    os.close(fd)
    try:
        os.unlink(probe)
    except OSError:
        pass
    return True


def _same_file(a: Path, b) -> bool:
    import os

    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):           # one of them does not exist (or is no path)
        return False


def check_output_path(path: str | Path | None, force: bool, option: str = "-o",
                      inputs=()) -> Path | None:
    """Refuse to overwrite an existing file unless --force (exit 2 via OutputExistsError), and
    a target that cannot be written (:func:`writable_target`); a symbolic link gives its target.

    ``option``: the command's option that names this file, for the hint. ``inputs``: the files
    the command reads; the output is never one of them (by name, link or hard link), even with
    --force."""
    from laminid_cli.errors import OutputExistsError

    if path is None:
        return None
    given = path                            # named as given (a link: not its target)
    path = writable_target(path, option)
    if path.exists() and any(_same_file(path, i) for i in inputs):
        raise OutputExistsError(f"{given}: is the input file; {option} must name another file "
                                "(--force overwrites an earlier output, never an input)",
                                path=given)
    if path.exists() and not force:
        raise OutputExistsError(f"{given}: file exists; use --force to overwrite it or choose "
                                f"another name with {option}", path=given)
    return path


#: suffixes of formats other programs (and laminid's own readers) take for something else than
#: HDF5: an HDF5 file written under one of them would be misread (a name without a suffix, or
#: any other, stays the user's choice)
NOT_HDF5_SUFFIXES = (".json", ".csv", ".txt", ".yaml", ".yml", ".pdf", ".png", ".uff", ".unv",
                     ".xls", ".xlsx", ".mat")


def check_hdf5_name(path, what: str, option: str = "-o",
                    csv: str = "laminid batch writes summary.csv") -> None:
    """Refuse an output named like another format (:data:`NOT_HDF5_SUFFIXES`): ``what`` the
    command writes HDF5 there ("identify writes its result"), said with the way to get the
    other format when there is one (``csv``: the command's, for a .csv name: batch's summary
    of results; acquire's FRFs have none)."""
    from laminid_cli.errors import OutputExistsError

    if path is None:
        return
    suffix = Path(path).suffix.lower()
    if suffix in NOT_HDF5_SUFFIXES:
        hint = {".json": "; --json prints JSON on stdout", ".uff": "; laminid export writes UFF",
                ".unv": "; laminid export writes UFF", ".pdf": "; laminid report writes PDF",
                ".png": "; laminid report writes PNG",
                ".csv": f"; {csv}"}.get(suffix, "")
        raise OutputExistsError(f"{path}: {what} as HDF5; name it .h5 ({option}){hint}",
                                path=path)


RESULT_FORMATS = ("laminid-result", "laminid-joint-result")


def derived_output_path(path: str | Path, specimen: str | Path | None = None
                        ) -> tuple[Path, bool]:
    """A default result file derived from its specimen: replaced when it exists (returns
    (path, True)) as long as it is a laminid identification result of the same specimen file
    (``specimen``; plate.yaml and plate.yml derive the same name); anything else at that name
    is refused (OutputExistsError, exit 2) rather than overwritten."""
    from laminid_cli.errors import OutputExistsError

    path = writable_target(path)
    if not path.exists():
        return path, False
    fmt, source = None, None
    try:
        import h5py

        from laminid_cli.h5open import format_of

        with h5py.File(path, "r") as f:
            fmt = format_of(f)
            if "specimen" in f:
                source = f["specimen"].attrs.get("path")
    except (OSError, ValueError):
        pass
    source = source.decode() if isinstance(source, bytes) else source
    if fmt not in RESULT_FORMATS:
        raise OutputExistsError(f"{path}: exists and is not a laminid result file; move it or "
                                "name the result with -o", path=path)
    if specimen is not None and isinstance(source, str) and source \
            and Path(source).name != Path(specimen).name:
        raise OutputExistsError(f"{path}: exists and holds the result of another specimen file "
                                f"({Path(source).name}); name this one's result with -o",
                                path=path)
    return path, True


def result_output(output, default, force: bool, specimen=None, inputs=()
                  ) -> tuple[Path, bool]:
    """The result file of identify: ``-o output`` protected by :func:`check_output_path` (never
    one of the ``inputs``), or the derived ``default`` beside the specimen, replaced
    (:func:`derived_output_path`; a result of another ``specimen`` file is refused). Returns
    (path, replacing an earlier result)."""
    if output is not None:
        out = check_output_path(output, force, inputs=inputs)    # the input itself: first
        check_hdf5_name(output, "identify writes its result")
        return out, False
    return derived_output_path(default, specimen)


def _clean(obj):
    """JSON-safe copy (:func:`laminid_cli.jsonsafe.json_safe`)."""
    from laminid_cli.jsonsafe import json_safe

    return json_safe(obj)


#: key of the click context's ``meta`` (shared by the group's and the command's contexts) set
#: when a command has written its --json document: an error after it (acquire's session that
#: stopped early) adds no second document (laminid_cli.cli)
JSON_WRITTEN = "laminid.json_written"


def echo_json(obj) -> None:
    """Print ``obj`` as indented JSON on stdout (NaN written as null), the command's one
    document (:data:`JSON_WRITTEN`)."""
    text = json.dumps(_clean(obj), indent=2)
    ctx = click.get_current_context(silent=True)
    if ctx is not None:
        ctx.meta[JSON_WRITTEN] = True
    click.echo(text)


def _checked_as_parsed(module: str, name: str):
    """A click callback that checks an option's text with ``module.name`` (a function raising
    ModelError on a mistake) as the option is parsed, so that a mistake is click's "Invalid
    value for '--OPTION'" as for the other options (the --json error document's field the
    option), not a bare "mesh 'abc' not understood" naming no option. The module is imported
    when the option is given (not for --help)."""
    def callback(ctx, param, value):
        import importlib

        from laminid_cli.errors import ModelError

        if value is None:
            return value
        try:
            getattr(importlib.import_module(module), name)(value)
        except ModelError as exc:
            raise click.BadParameter(str(exc), ctx=ctx, param=param) from None
        return value
    return callback


#: --mesh: its words (laminid_cli.fe.mesh.mesh_elements; its memory is checked when the run
#: knows its processes)
check_mesh_text = _checked_as_parsed("laminid_cli.fe.mesh", "mesh_elements")
#: modes' --boundary: the name or edge code (laminid_cli.fe.assembly.boundary_code)
check_boundary_text = _checked_as_parsed("laminid_cli.fe.assembly", "boundary_code")


def _apply(options):
    def decorate(f):
        for option in reversed(options):
            f = option(f)
        return f
    return decorate


#: identification settings shared by ``identify`` and ``batch`` (parameters: mesh, fix,
#: optimizer, parametrization, xtol, ftol, max_evaluations, pairing, solver)
fit_options = _apply([
    click.option("--mesh", default="12x12", show_default=True, metavar="NXxNY",
                  callback=check_mesh_text,
                  help="Elements along x (side a) and y (side b); the paper uses 12x12."),
    click.option("--fix", "fix", default="", metavar="LIST",
                  help="Constants held at their initial values, comma-separated: nu12,G13,G23 "
                       "(all materials) or glass.nu12 (one material). Adds to 'fixed' in the "
                       "file."),
    click.option("--optimizer", type=click.Choice(["slsqp", "mma"]), default="slsqp",
                  show_default=True, help="nlopt algorithm: LD_SLSQP or LD_MMA."),
    click.option("--parametrization", type=click.Choice(["auto", "alpha", "constants"]),
                  default="auto", show_default=True,
                  help="Design variables: alpha = paper Eq. 14 (E1/E1_0, a2, a3, a4, a8, a9); "
                       "constants = free constants / initial values; auto = alpha where all six "
                       "constants of a material are free and it has no prior."),
    click.option("--xtol", type=FiniteFloat(min=0, min_open=True), default=1e-6,
                  show_default=True, help="Step tolerance on the scaled design variables."),
    click.option("--ftol", type=FiniteFloat(min=0, min_open=True), default=1e-8,
                  show_default=True, help="Relative tolerance on the objective."),
    click.option("--max-evaluations", type=click.IntRange(2, MAX_EVALUATIONS), default=3000,
                  show_default=True, help="Most model evaluations of the identification in all "
                  "(full and reduced-model ones, every stage; the answer's final check may add "
                  "a few) before giving up: then 'not converged', exit 1. The paper's plates "
                  "take about 40-270 (12x12), the hybrid CM about 1200."),
    click.option("--pairing", type=click.Choice(["track", "sorted"]), default="track",
                  show_default=True,
                  help="Mode pairing: track = sorted order at the start, then each mode followed "
                       "by MAC so swaps cannot corrupt the fit, re-anchored in sorted order if it "
                       "ends out of order (and then also fitted with sorted order from the start, "
                       "the better answer kept); sorted = sorted order throughout (the paper)."),
    click.option("--solver", type=click.Choice(["reduced", "full"]), default="reduced",
                  show_default=True,
                  help="Eigen solver of the fit: reduced = the optimiser runs on a reduced-order "
                       "model enriched where it goes and converged to the full model (same "
                       "result, several times less work); full = one full eigen solution per "
                       "evaluation (the reference)."),
])

#: uncertainty settings shared by ``identify`` and ``batch`` (parameters: sigma_rel,
#: covariance_scale, max_rel_interval, fix_undetermined, monte_carlo, seed)
uncertainty_options = _apply([
    click.option("--sigma-rel", type=SIGMA_REL, default=0.002, show_default=True, metavar="FRACTION",
                  help="Standard deviation of a measured frequency, as a fraction of it, where the "
                       "specimen file gives no measured.sigma (0.002, or 0.2%); not used for "
                       "the modes of a measured.frf_file, whose RFP fit gives each one's "
                       "(at least 0.2 %)."),
    click.option("--covariance-scale", type=click.Choice(["stated", "residuals", "larger"]),
                  default="larger", show_default=True,
                  help="Intervals from the stated frequency sigma, from the residuals at the "
                       "optimum (s2 = chi2/(n-p), Student t), or the larger of the two."),
    click.option("--max-rel-interval", type=Fraction(min=0, min_open=True, max=0.30),
                  default=0.30, show_default=True, metavar="FRACTION",
                  help="Flag a constant whose 95 % half-width exceeds this fraction of its value "
                       "(0.2, or 20%). "
                       "At most 0.30: above it a constant's verdict is 'not determined', and "
                       "such a constant is always flagged (a status of ok beside it would "
                       "mislead)."),
    click.option("--fix-undetermined", is_flag=True,
                  help="Fix the flagged constants at their initial values and identify again "
                       "(until nothing new is flagged, by the intervals or the Monte Carlo); a "
                       "constant whose initial value would move another out of its 95 % "
                       "interval stays free (the output says why). The others' intervals count "
                       "the spread the fixed values had before fixing (the widths given them "
                       "alone are printed too); one fixed on a search limit is checked by "
                       "identifying again at both ends of the search. If the modes reject the "
                       "fixed values taken together (the rise of chi2 against the chi-square "
                       "or F limit, 95 %), the status is 'fixed_rejected' and names the value "
                       "to leave free."),
    click.option("--monte-carlo", "monte_carlo", type=TrialCount(), default=0,
                  show_default=True, metavar="N", help="Re-identify N times from frequencies perturbed by their "
                                    "uncertainties (and prior values by the noise the "
                                    "intervals count for them; where the intervals are "
                                    "scaled by s2, each trial also draws its variance "
                                    "factor, so that the range is Student t as the "
                                    "intervals) and report the spread (0: "
                                    "off); a range end set by trials on a limit of the "
                                    "search is marked as such (terminal *, JSON, HDF5, "
                                    "report). A range wider than the linearised interval "
                                    "for sure (90 % confidence from the trials' order "
                                    "statistics) sets a worse verdict, marked '(Monte "
                                    "Carlo)'. With measured damping each trial also "
                                    "refits the ply loss factors at its own constants "
                                    "(their range counts the free constants' doubt). With "
                                    "--fix-undetermined each trial also draws the values "
                                    "fixed because undetermined from their spread before "
                                    "fixing (shortened to the search's range), so the "
                                    "range counts that spread as the intervals do."),
    # numpy's generators take no negative seed, the result file no seed above int64
    click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
                  help="Random seed of the Monte Carlo perturbations (a whole number >= 0)."),
])

#: the parameters of :data:`fit_options` and :data:`uncertainty_options`
FIT_PARAMS = ("mesh", "fix", "optimizer", "parametrization", "xtol", "ftol", "max_evaluations",
              "pairing", "solver")
UNCERTAINTY_PARAMS = ("sigma_rel", "covariance_scale", "max_rel_interval", "fix_undetermined",
                      "monte_carlo", "seed")


def run_options_of(params: dict, monte_carlo_jobs: int | None = 1):
    """The :class:`laminid_cli.pipeline.RunOptions` of the :data:`fit_options` and
    :data:`uncertainty_options` parameters, which are taken out of ``params``;
    ``monte_carlo_jobs``: processes of the Monte Carlo trials (None: the number of cores)."""
    from laminid_cli.identify import IdentifyOptions
    from laminid_cli.pipeline import RunOptions
    from laminid_cli.uncertainty import UncertaintyOptions

    p = {k: params.pop(k) for k in FIT_PARAMS + UNCERTAINTY_PARAMS}
    return RunOptions.with_fix(
        p["fix"], mesh=p["mesh"],
        identify=IdentifyOptions(optimizer=p["optimizer"], parametrization=p["parametrization"],
                                 xtol_rel=p["xtol"], ftol_rel=p["ftol"],
                                 max_evaluations=p["max_evaluations"], pairing=p["pairing"],
                                 solver=p["solver"]),
        uncertainty=UncertaintyOptions(sigma_rel=p["sigma_rel"], scaling=p["covariance_scale"],
                                       max_rel_interval=p["max_rel_interval"],
                                       fix_undetermined=p["fix_undetermined"],
                                       monte_carlo=p["monte_carlo"], jobs=monte_carlo_jobs,
                                       seed=p["seed"]))


def pass_run_options(monte_carlo_jobs: str | None = None):
    """Decorator (put it right above the command function): the command receives one argument
    ``options`` (:class:`laminid_cli.pipeline.RunOptions`) in place of the parameters of
    :data:`fit_options` and :data:`uncertainty_options`. ``monte_carlo_jobs`` names the
    command's own parameter that gives the Monte Carlo processes (it is passed on as well);
    without it the trials run in one process."""
    def decorate(f):
        @functools.wraps(f)
        def command(*args, **params):
            jobs = params.get(monte_carlo_jobs) if monte_carlo_jobs else 1
            return f(*args, options=run_options_of(params, jobs), **params)
        return command
    return decorate
