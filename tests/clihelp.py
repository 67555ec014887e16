"""Helpers of the CLI tests: run a command through click; identify one specimen for a module."""

from __future__ import annotations

import json

from click.testing import CliRunner

from laminid_cli.cli import cli


def run(*args):
    """``laminid <args>`` through click's CliRunner (exceptions caught: the result holds them)."""
    return CliRunner().invoke(cli, [str(a) for a in args])


def without_comments(lines):
    """The lines of a summary.csv without its ``#`` lines (the run options above the header),
    as ``pandas.read_csv(path, comment="#")`` reads it: ``csv.DictReader(without_comments(fh))``."""
    return (line for line in lines if not line.startswith("#"))


def identify_json(tmp_path_factory, specimen: str, mesh: str | None, name: str, *args):
    """(parsed --json output, result file) of ``laminid identify specimen --mesh mesh [args]``
    (mesh None: the default's), asserting exit code 0; for module- and session-scoped
    fixtures."""
    out = tmp_path_factory.mktemp("id") / name
    r = run("identify", specimen, *(("--mesh", mesh) if mesh else ()), *args, "--json", "-o",
            str(out))
    assert r.exit_code == 0, r.output
    return json.loads(r.output), out


S14 = "specimens/example1/S1.4.yaml"
#: S1.4's strain-gauge E1 as a range, and a global reference range (the format of
#: specimens/README.md): what a reference range must look like everywhere it is shown
S14_REFERENCE = "IM7/977-2: {E1: 170 GPa, E2: 10 GPa, G12: 5.8 GPa, nu12: 0.35}"
S14_RANGES = ("IM7/977-2: {E1: [120 GPa, 150 GPa], E2: 10 GPa, G12: 5.8 GPa, nu12: 0.35}\n"
              "  global: {nu_xy: [0.05, 0.07]}")


def write_s14_with_ranges(folder) -> str:
    """S1.4.yaml with S14_RANGES as its reference, written into ``folder``; its path."""
    from pathlib import Path

    text = Path(S14).read_text(encoding="utf-8")
    assert S14_REFERENCE in text
    path = Path(folder) / "S1.4r.yaml"
    path.write_text(text.replace(S14_REFERENCE, S14_RANGES), encoding="utf-8")
    return str(path)
