"""Command-line entry point: ``laminid <command>``.

The group loads each command's module only when that command runs, so ``laminid --help`` and
shell batches start fast (no numpy/scipy/h5py import before they are needed). This module is the
only place that turns a :class:`~laminid_cli.errors.LaminidError` into a message and exit code
(under ``--json`` also a JSON document on stdout: :func:`_echo_json_error`).
"""

from __future__ import annotations

import errno
import importlib
import logging

import click

from laminid_cli import __version__
from laminid_cli.errors import EXIT_INTERRUPTED, EXIT_TERMINATED, Terminated

# command name -> "module:attribute"; each command lives in laminid_cli/commands/<module>.py
COMMANDS = {
    "modes": "laminid_cli.commands.modes:modes",
    "identify": "laminid_cli.commands.identify:identify",
    "fit-frf": "laminid_cli.commands.fit_frf:fit_frf",
    "acquire": "laminid_cli.commands.acquire:acquire",
    "batch": "laminid_cli.commands.batch:batch",
    "report": "laminid_cli.commands.report:report",
    "show": "laminid_cli.commands.show:show",
    "export": "laminid_cli.commands.export:export",
}

SHORT_HELP = {
    "modes": "Natural frequencies of a specimen's plate model vs the measured ones.",
    "identify": "Identify ply elastic constants from measured natural frequencies.",
    "fit-frf": "Extract natural frequencies from measured FRFs (rational fraction polynomials).",
    "acquire": "Acquire impact-test FRFs from a dynamic signal analyser (VISA).",
    "batch": "Identify every specimen of folders/files in parallel; summary table (Table 2).",
    "report": "PDF/PNG report of a result (frequencies, modes, history...) or a batch summary.",
    "show": "Print a result file as identify printed it (--json: as identify --json).",
    "export": "FRFs (UFF 58) or identified mode shapes (UFF 15 + 55) for other modal software.",
}


#: errors of the file system that a user can fix (reported in one line, exit 2)
_FILE_SYSTEM_ERRNOS = {getattr(errno, name) for name in (
    "EROFS", "EACCES", "EPERM", "ENOSPC", "EDQUOT", "ENOTDIR", "EISDIR", "ENAMETOOLONG",
    "ENOENT", "EEXIST", "ETXTBSY", "EFBIG") if hasattr(errno, name)}


class LazyGroup(click.Group):
    """A click group whose subcommands are imported on first use."""

    def list_commands(self, ctx):
        return [name for name in COMMANDS if _module_exists(COMMANDS[name])]

    def get_command(self, ctx, name):
        target = COMMANDS.get(name)
        if target is None:
            return None
        module_name, attr = target.split(":")
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                return None
            raise
        return getattr(module, attr)

    def resolve_command(self, ctx, args):
        cmd_name, cmd, rest = self._resolve_command(ctx, args)
        # the command and its arguments, for an error's --json document (invoke)
        ctx.meta[_INVOKED] = (cmd_name, cmd, tuple(rest))
        return cmd_name, cmd, rest

    def _resolve_command(self, ctx, args):
        # a misspelt command: the nearest one, as a misspelt key of a specimen file gets
        # (click matches against the group's loaded commands, none in a lazy group)
        name = click.utils.make_str(args[0])
        if (not ctx.resilient_parsing and not name.startswith("-")
                and name not in COMMANDS):
            import difflib

            guess = difflib.get_close_matches(name.lower(), list(COMMANDS), n=1, cutoff=0.6)
            hint = f"; did you mean '{guess[0]}'?" if guess else ""
            ctx.fail(f"No such command '{name}'{hint} (commands: {', '.join(COMMANDS)})")
        return super().resolve_command(ctx, args)

    def format_commands(self, ctx, formatter):
        rows = [(name, SHORT_HELP.get(name, "")) for name in self.list_commands(ctx)]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def invoke(self, ctx):
        from laminid_cli.errors import LaminidError, escaped

        try:
            return super().invoke(ctx)
        except LaminidError as exc:
            _echo_json_error(ctx, _error_document(exc, str(exc), exc.exit_code, file=exc.path,
                                                  field=exc.field, line=exc.line))
            # escaped: a file's name in the message ('S1\u202e1.yaml') acted on the line
            # that reports it (its refused text is escaped by the message itself)
            click.echo(f"laminid: {getattr(exc, 'label', 'error')}: {escaped(str(exc))}",
                       err=True)
            ctx.exit(exc.exit_code)
        except click.UsageError as exc:
            if isinstance(exc, click.NoSuchOption) and exc.option_name in _GROUP_OPTIONS:
                # laminid's own -q/-v written after the command ("laminid batch d -q", as the
                # README's "not under -q" reads): say where it goes
                name = ctx.meta.get(_INVOKED, (None,))[0] or "COMMAND"
                exc.message = (f"No such option: {exc.option_name} of '{name}'; it is "
                               f"laminid's own, written before the command: laminid "
                               f"{exc.option_name} {name} ...")
                exc.possibilities = None
            elif (isinstance(exc, click.NoSuchOption) and exc.option_name == "--json"
                  and ctx.meta.get(_INVOKED, (None,))[0] == "report"):
                # the one command without --json (README): "No such option '--json'" alone
                # left the lab to find where a result's JSON is
                exc.message = ("No such option: --json of 'report', which draws figures; "
                               "'laminid show RESULT --json' prints a result as JSON (a batch's "
                               "is its summary.json)")
                exc.possibilities = None
            # click says it (usage, "Error: ...") and exits 2 once this returns
            _echo_json_error(ctx, _error_document(exc, exc.format_message(), exc.exit_code,
                                                  kind="UsageError", field=_option_of(exc)))
            raise
        except Terminated:             # SIGTERM, where the command turns it into a stop (batch)
            click.echo("laminid: terminated (SIGTERM)", err=True)
            ctx.exit(EXIT_TERMINATED)
        except KeyboardInterrupt:
            click.echo("laminid: interrupted", err=True)
            ctx.exit(EXIT_INTERRUPTED)
        except OSError as exc:
            # the file system refused a file (read-only, full, permissions, a file where a
            # folder is expected): the user's environment, not a bug; no traceback
            if exc.errno not in _FILE_SYSTEM_ERRNOS:
                raise
            what = f"{exc.filename}: " if exc.filename else ""
            message = f"{what}{exc.strerror or exc}"
            _echo_json_error(ctx, _error_document(
                exc, message, 2, file=None if exc.filename is None else str(exc.filename)))
            click.echo(f"laminid: error: {message}", err=True)
            ctx.exit(2)

    def make_context(self, info_name, args, parent=None, **extra):
        # parsing the arguments (--help, --version, list_commands); click itself would say
        # "Aborted!" and exit 1
        try:
            return super().make_context(info_name, args, parent=parent, **extra)
        except KeyboardInterrupt:
            click.echo("laminid: interrupted", err=True)
            raise click.exceptions.Exit(EXIT_INTERRUPTED) from None


#: the group's own options (cli below), which a command refuses after its name
_GROUP_OPTIONS = {"-q", "--quiet", "-v", "--verbose"}

#: key of the click context's ``meta``: (name, command, arguments) of the command invoked
_INVOKED = "laminid.invoked"


def _error_document(exc: BaseException, message: str, exit_code: int, *, kind: str | None = None,
                    file=None, field=None, line=None) -> dict:
    """The --json document of an error: what stderr says of it (``message``, without
    "laminid: error: "), the exception's class (``kind``: SpecimenError, FrfError...;
    UsageError for click's), the file, field and line it names where it carries them (a
    specimen's error), else None, and the exit code."""
    return {"error": {"kind": kind or type(exc).__name__, "message": message,
                      "file": None if file is None else str(file), "field": field,
                      "line": line, "exit_code": exit_code}}


def _option_of(exc: click.UsageError) -> str | None:
    """The option or argument a usage error is about (``--sigma-rel``, ``SPEC``), or None."""
    param = getattr(exc, "param", None)
    if param is not None:
        opts = [o for o in getattr(param, "opts", ()) if o.startswith("--")]
        return opts[0] if opts else param.human_readable_name.rstrip(".")   # SPEC...
    return getattr(exc, "option_name", None)


def _json_requested(ctx) -> bool:
    """Whether the command invoked (:data:`_INVOKED`) has ``--json`` and its command line asks
    for it. Read with the command's own parser, leniently (unknown options skipped, parsing
    stopped at a mistake): ``--fix --json`` is --fix's value, ``-- --json`` an argument; the
    values are not converted, so a bad value elsewhere does not hide it."""
    name, cmd, args = ctx.meta.get(_INVOKED, (None, None, ()))
    if cmd is None or not any(p.name == "as_json" for p in cmd.params):
        return False
    lenient = cmd.context_class(cmd, info_name=name, resilient_parsing=True,
                                ignore_unknown_options=True)
    opts, _, _ = cmd.make_parser(lenient).parse_args(args=list(args))
    return bool(opts.get("as_json"))


def _echo_json_error(ctx, document: dict) -> None:
    """``document`` on stdout when the command was asked for --json and has not written its
    own document already (acquire's summary of a session that stopped: its ``stopped`` says
    why): a program reading stdout (``| jq``) gets one document, never none or two."""
    import json

    from laminid_cli.commands._common import JSON_WRITTEN

    if ctx.meta.get(JSON_WRITTEN) or not _json_requested(ctx):
        return
    ctx.meta[JSON_WRITTEN] = True
    click.echo(json.dumps(document, indent=2))


def _module_exists(target: str) -> bool:
    import importlib.util

    module_name = target.split(":")[0]
    try:
        return importlib.util.find_spec(module_name) is not None
    except ModuleNotFoundError:
        return False


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="laminid")
@click.option("-v", "--verbose", count=True, help="More log output (-vv for debug).")
@click.option("-q", "--quiet", is_flag=True, help="Only errors on stderr.")
def cli(verbose: int, quiet: bool):
    """laminid: elastic constants of laminated plates from their free-vibration frequencies.

    \b
    Typical chain:
      laminid acquire --analyser GPIB0::5 -o plate.frf.h5     # impact test, FRFs
      laminid fit-frf plate.frf.h5 --into plate.yaml           # natural frequencies
      laminid identify plate.yaml                              # E1, E2, G12, nu12, G13, G23
    """
    configure_logging(logging.ERROR if quiet else
                      (logging.WARNING, logging.INFO, logging.DEBUG)[min(verbose, 2)])


def configure_logging(level: int) -> None:
    """Log records to stderr at ``level``, laminid's own warnings and errors written as the
    commands write theirs (:class:`_UserFormatter`; with -v and -vv every record names its
    logger): the command line's, and a batch's pool workers', which start from a clean
    interpreter. A program that configured logging itself (laminid as a library, a test
    runner) keeps its own handlers and format."""
    root = logging.getLogger()
    before = list(root.handlers)
    logging.basicConfig(level=level, format=_LOG_FORMAT)
    # only the handler basicConfig just added
    for handler in root.handlers:
        if handler not in before:
            handler.setFormatter((_UserFormatter if level >= logging.WARNING
                                  else _EscapingFormatter)(_LOG_FORMAT))


_LOG_FORMAT = "%(levelname)s %(name)s: %(message)s"


class _EscapingFormatter(logging.Formatter):
    """Each record with its errors.NON_PRINTABLE characters escaped, as the error line has
    them (a file's name 'bd/S1\u202e1.yaml' in the specimen reader's warning reversed the
    rest of the line, an ESC sequence in it acted on the terminal)."""

    def format(self, record):
        from laminid_cli.errors import escaped

        return escaped(self._format(record))

    def _format(self, record):
        return super().format(record)


class _UserFormatter(_EscapingFormatter):
    """laminid's own warnings and errors as the commands write theirs ("warning: ..."), with
    a traceback where the record has one; other libraries' records name their logger."""

    _own = logging.Formatter("%(message)s")

    def _format(self, record):
        if record.name.split(".")[0] == "laminid_cli":
            return f"{record.levelname.lower()}: {self._own.format(record)}"
        return super()._format(record)


def main():  # kept for callers of the old entry point: laminid_cli.__main__.main
    from laminid_cli.__main__ import main as entry

    entry()
