"""Helpers of the CLI tests: run a command through click; identify one specimen for a module."""

from __future__ import annotations

import json

from click.testing import CliRunner

from laminid_cli.cli import cli


def run(*args):
    """``laminid <args>`` through click's CliRunner (exceptions caught: the result holds them)."""
    return CliRunner().invoke(cli, [str(a) for a in args])


def identify_json(tmp_path_factory, specimen: str, mesh: str, name: str):
    """(parsed --json output, result file) of ``laminid identify specimen --mesh mesh``,
    asserting exit code 0; for module-scoped fixtures."""
    out = tmp_path_factory.mktemp("id") / name
    r = run("identify", specimen, "--mesh", mesh, "--json", "-o", str(out))
    assert r.exit_code == 0, r.output
    return json.loads(r.output), out
