"""Every command's --help: exits 0, documents every option, and shows only meaningful ranges."""

from __future__ import annotations

import click
import pytest

from laminid_cli.cli import cli
from laminid_cli.commands._common import FiniteFloat
from tests.clihelp import run

COMMANDS = cli.list_commands(click.Context(cli))


def test_the_commands_are_listed():
    assert set(COMMANDS) == {"modes", "identify", "fit-frf", "acquire", "batch", "report", "show",
                             "export"}


@pytest.mark.parametrize("name", COMMANDS)
def test_help_documents_every_option_and_shows_no_empty_range(name):
    """click's FloatRange shows an unbounded range as "x<=None" (seen on acquire --span and
    identify --sigma-rel until stop 27); every option carries a help text."""
    r = run(name, "--help")
    assert r.exit_code == 0, r.output
    assert r.output.startswith("Usage:")
    assert "None" not in r.output, r.output
    cmd = cli.get_command(click.Context(cli), name)
    missing = [p.opts for p in cmd.params if isinstance(p, click.Option) and not p.help]
    assert not missing, missing


def test_finite_float_describes_its_range_only_when_bounded():
    assert FiniteFloat()._describe_range() == ""
    assert FiniteFloat(min=0.01)._describe_range() == "x>=0.01"
    assert FiniteFloat(0, 1)._describe_range() == "0<=x<=1"
    assert FiniteFloat(min=0, min_open=True)._describe_range() == "x>0"


@pytest.mark.parametrize("option, value", [("--span", "-5"), ("--span", "0"), ("--start", "-1"),
                                           ("--pretrigger", "-0.001"), ("--exp-window", "0"),
                                           ("--force-window", "-1"),
                                           ("--trigger-level", "150")])
def test_acquire_refuses_an_impossible_setting_before_it_opens_the_analyser(tmp_path, option,
                                                                           value):
    """Exit 2 naming the option, with no attempt to open the resource (which would fail
    differently here: there is no analyser) and no file written."""
    out = tmp_path / "x.frf.h5"
    r = run("acquire", "--analyser", "GPIB0::5", option, value, "-o", out)
    assert r.exit_code == 2, r.output
    assert option in r.output and "cannot open" not in r.output
    assert not out.exists()


@pytest.mark.parametrize("typed, words", [
    ("identfy", "No such command 'identfy'; did you mean 'identify'?"),
    ("Identify", "No such command 'Identify'; did you mean 'identify'?"),
    ("fitfrf", "No such command 'fitfrf'; did you mean 'fit-frf'?"),
    ("frobnicate", "No such command 'frobnicate' (commands: "),
])
def test_a_misspelt_command_gets_the_nearest_one(typed, words):
    """`laminid identfy` said only "No such command 'identfy'" (click suggests among a group's
    loaded commands, none in laminid's lazy group): the nearest command, and the list; a usage
    error, exit 2."""
    r = run(typed, "specimens/example1/S1.1.yaml")
    assert r.exit_code == 2, r.output
    assert f"Error: {words}" in r.output
    assert r.output.rstrip().endswith("(commands: modes, identify, fit-frf, acquire, batch, "
                                      "report, show, export)")
    if typed == "frobnicate":                   # nothing near: no guess
        assert "did you mean" not in r.output


@pytest.mark.parametrize("name", ["modes", "identify", "show", "batch", "fit-frf", "export",
                                  "acquire"])
def test_json_help_says_what_units_means(name):
    """'units' in --json was a map of each field's unit (modes, identify, show, batch) or the
    FRF's engineering unit as text (acquire, fit-frf, export), and no help said which. The
    FRF commands name that one 'frf_unit' ('units' kept as the same text for one release);
    each --json help says what its keys hold."""
    cmd = cli.get_command(click.Context(cli), name)
    text = next(p.help for p in cmd.params if p.name == "as_json")
    if name in ("fit-frf", "export", "acquire"):
        assert ("'frf_unit' is the FRF's engineering unit (\"Pa/N\"); 'units', its old name, "
                "holds the same text in this release only (elsewhere 'units' maps each field "
                "to its unit)") in text, text
    else:
        assert "its 'units' maps each field name to its unit (\"E1\": \"Pa\")" in text, text
    # and what it prints when the command fails (tests/test_cli_json_errors.py)
    assert text.endswith('prints {"error": {"kind", "message", "file", "field", "line", '
                         '"exit_code"}} instead.'), text


def test_a_fraction_may_be_written_as_a_percentage():
    """--sigma-rel 0.2% (the README's and the output's "0.2 %") was refused as "not a valid
    float", and --max-rel-interval 20% likewise; both read it as the fraction (0.002, 0.2),
    as --fix eta13=1% reads a loss factor. A bare number stays a fraction."""
    import json

    r = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "4x4", "--no-output",
            "--json", "--sigma-rel", "0.2 %", "--max-rel-interval", "20%")
    assert r.exit_code == 0, r.output
    u = json.loads(r.stdout)["uncertainty"]
    assert abs(u["frequency_sigma"]["S1.1"]["sigma_rel"] - 0.002) < 1e-15
    assert abs(u["thresholds"]["max_rel_interval"] - 0.2) < 1e-15
    for value, said in (("0.2x%", "'0.2x%' is not a number: write a fraction (0.002) or a "
                                  "percentage (0.2%)."),
                        ("nan%", "'nan%' is not a finite number."),
                        ("50%", "0.5 is not in the range 1e-09<=x<0.5.")):
        r = run("identify", "specimens/example1/S1.1.yaml", "--sigma-rel", value)
        assert r.exit_code == 2
        assert r.stderr.endswith(f"Invalid value for '--sigma-rel': {said}\n"), r.stderr
