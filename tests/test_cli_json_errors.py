"""``--json`` of a command that fails on a user's mistake: one JSON document on stdout
(``{"error": {kind, message, file, field, line, exit_code}}``), the same one-line message on
stderr and the same exit code as without ``--json`` (laminid_cli.cli)."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli

SPEC = Path(__file__).resolve().parents[1] / "specimens" / "example1" / "S1.1.yaml"


def run(args, input=None):
    return CliRunner().invoke(cli, args, input=input, catch_exceptions=False)


def negative_b(tmp_path) -> Path:
    """S1.1 with side b = -311 mm (line 14 of the file)."""
    path = tmp_path / "neg.yaml"
    text = SPEC.read_text()
    assert text.splitlines()[13] == "  b: 311 mm"
    path.write_text(text.replace("  b: 311 mm", "  b: -311 mm"))
    return path


def bad_csv(tmp_path) -> Path:
    path = tmp_path / "bad.csv"
    path.write_text("f,H1_real,H1_imag\n1,2\n")     # two columns: no FRF
    return path


def both(args):
    """(without --json, with --json) runs of ``args``: --json added last."""
    return run(args), run([*args, "--json"])


def error_of(r) -> dict:
    doc = json.loads(r.stdout)                  # one document, nothing else on stdout
    assert list(doc) == ["error"]
    return doc["error"]


def assert_same_failure(plain, as_json, kind, file=None, field=None, line=None,
                        exit_code=2):
    """--json changes stdout only: the same exit code and stderr, no traceback; stdout the
    error's document, its message stderr's line without 'laminid: error: '."""
    assert plain.exit_code == as_json.exit_code == exit_code, as_json.output
    assert plain.stdout == ""
    assert as_json.stderr == plain.stderr and "Traceback" not in plain.stderr
    e = error_of(as_json)
    assert e == {"kind": kind, "message": e["message"], "file": file, "field": field,
                 "line": line, "exit_code": exit_code}
    assert plain.stderr.endswith(f"laminid: error: {e['message']}\n")
    return e


@pytest.mark.parametrize("command", ["identify", "modes"])
def test_a_specimens_bad_field_names_file_field_and_line(tmp_path, command):
    spec = negative_b(tmp_path)
    plain, as_json = both([command, str(spec)])
    e = assert_same_failure(plain, as_json, "SpecimenError", file=str(spec),
                            field="geometry.b", line=14)
    assert e["message"] == f"{spec}:14, field 'geometry.b': must be positive, got '-311 mm'"
    assert plain.stderr == f"laminid: error: {e['message']}\n"


def test_identify_of_a_missing_specimen(tmp_path):
    missing = tmp_path / "nope.yaml"
    plain, as_json = both(["identify", str(missing)])
    e = assert_same_failure(plain, as_json, "SpecimenError", file=str(missing))
    assert plain.stderr == f"laminid: error: {e['message']}\n"
    assert e["message"] == f"{missing}: file not found"


def test_batch_of_a_missing_folder(tmp_path):
    missing = tmp_path / "nope"
    plain, as_json = both(["batch", str(missing), "--out", str(tmp_path / "out")])
    e = assert_same_failure(plain, as_json, "BatchError", file=str(missing))
    assert plain.stderr == f"laminid: error: {missing}: no such file or folder\n"
    assert e["message"] == f"{missing}: no such file or folder"


@pytest.mark.parametrize("command", ["fit-frf", "export"])
def test_an_unreadable_frf_file_names_it(tmp_path, command):
    csv = bad_csv(tmp_path)
    args = [command, str(csv)] + (["-o", str(tmp_path / "x.uff")] if command == "export"
                                  else [])
    plain, as_json = both(args)
    e = assert_same_failure(plain, as_json, "FrfError", file=str(csv))
    assert e["message"].startswith(f"{csv}: 2 columns; expected the frequency then a real")
    assert plain.stderr == f"laminid: error: {e['message']}\n"
    assert not (tmp_path / "x.uff").exists()


def test_show_of_a_missing_file(tmp_path):
    missing = tmp_path / "nope.result.h5"
    plain, as_json = both(["show", str(missing)])
    e = assert_same_failure(plain, as_json, "InputFileError", file=str(missing))
    assert e["message"] == f"{missing}: file not found"


def test_an_output_that_exists_names_it(tmp_path):
    out = tmp_path / "modes.h5"
    out.write_bytes(b"precious")
    plain, as_json = both(["modes", str(SPEC), "-o", str(out)])
    e = assert_same_failure(plain, as_json, "OutputExistsError", file=str(out))
    assert e["message"] == (f"{out}: file exists; use --force to overwrite it or choose "
                            "another name with -o")
    assert out.read_bytes() == b"precious"


def test_acquire_refusals_before_and_after_the_analyser_is_opened(tmp_path):
    """acquire against the tests' emulator: an existing -o (refused before the analyser is
    asked anything) and --model sr785 with one average (refused before it is opened)."""
    from tests.instrument.emulator import HP35670AEmulator

    out = tmp_path / "exists.frf.h5"
    out.write_bytes(b"precious")
    with HP35670AEmulator() as hp:
        base = ["acquire", "--analyser", hp.resource, "--timeout", "0.5", "--no-prompt"]
        plain, as_json = both([*base, "--points", "2", "-o", str(out)])
        e = assert_same_failure(plain, as_json, "OutputExistsError", file=str(out))
        assert "file exists; use --force" in e["message"]
        plain, as_json = both([*base, "--model", "sr785", "--averages", "1",
                               "-o", str(tmp_path / "new.frf.h5")])
        e = assert_same_failure(plain, as_json, "AnalyserSetupError")
        assert e["message"] == ("SR785 averages at least 2 records (FAVN 2-32767; got "
                                "--averages 1)")
        assert hp.log == []
    assert out.read_bytes() == b"precious"


@pytest.mark.parametrize("args, field, message", [
    (["identify", str(SPEC), "--sigma-rel", "-1"], "--sigma-rel",
     "Invalid value for '--sigma-rel': -1.0 is not in the range 1e-09<=x<0.5."),
    (["identify"], "SPEC", "Missing argument 'SPEC...'."),
    (["modes", str(SPEC), "--modes", "x"], "--modes",
     "Invalid value for '--modes': 'x' is not a valid integer range."),
    (["batch", str(SPEC), "--bogus"], "--bogus",
     "No such option '--bogus'. (Did you mean one of: '--jobs', '--out'?)"),
    (["fit-frf", "x.csv", "--sigma-rel", "nan"], "--sigma-rel",
     "Invalid value for '--sigma-rel': 'nan' is not a finite number."),
    (["acquire", "--analyser", "GPIB0::5", "-o", "x.h5", "--lines", "3"], "--lines",
     "Invalid value for '--lines': 3 lines: the analysers offer 100, 200, 400, 800."),
    # --mesh's words are checked as it is parsed (a ModelError "mesh 'abc' not understood"
    # before, naming neither the option nor giving it as the document's field)
    (["modes", str(SPEC), "--mesh", "abc"], "--mesh",
     "Invalid value for '--mesh': mesh 'abc' not understood: give elements along x and y as "
     "NXxNY, e.g. 12x12"),
    (["identify", str(SPEC), "--mesh", "1x1"], "--mesh",
     "Invalid value for '--mesh': mesh '1x1' is degenerate: at least 2 elements per side are "
     "needed (the paper uses 12x12)"),
    (["modes", str(SPEC), "--boundary", "CFFX"], "--boundary",
     "Invalid value for '--boundary': boundary 'CFFX' not understood: use free, "
     "simply-supported, clamped, or a 4-letter code of F/S/C for the edges x=0, y=0, x=a, y=b "
     "(e.g. SFSF)"),
], ids=["bad-value", "missing-argument", "not-a-number", "no-such-option", "nan",
        "acquire-lines", "mesh-words", "mesh-degenerate", "boundary"])
def test_clicks_usage_errors_give_the_document_too(args, field, message):
    """click's own refusals (a bad option value, a missing argument, an unknown option):
    kind UsageError, the option in 'field', click's message; stderr (usage, 'Error: ...')
    and exit 2 as without --json, whether --json comes before or after the mistake."""
    plain = run(args)
    for with_json in ([*args, "--json"], [args[0], "--json", *args[1:]]):
        r = run(with_json)
        assert r.exit_code == plain.exit_code == 2
        assert r.stderr == plain.stderr and plain.stdout == ""
        assert plain.stderr.startswith(f"Usage: cli {args[0]} [OPTIONS]")
        assert plain.stderr.endswith(f"\n\nError: {message}\n")
        assert error_of(r) == {"kind": "UsageError", "message": message, "file": None,
                               "field": field, "line": None, "exit_code": 2}


def test_json_as_another_options_value_is_no_request_for_json(tmp_path):
    """`--fix --json`: --json is --fix's value (refused as a constant), not the flag: no
    document; likewise after `--`."""
    r = run(["identify", str(SPEC), "--fix", "--json"])
    assert r.exit_code == 2 and r.stdout == ""
    assert "'--json' is not a constant" in r.stderr
    r = run(["identify", "--", "--json"])          # a specimen file named --json
    assert r.exit_code == 2 and r.stdout == ""
    assert r.stderr == "laminid: error: --json: file not found\n"


def test_no_document_without_json_and_none_for_a_command_without_json(tmp_path):
    r = run(["report", str(tmp_path / "nope.h5"), "--json"])    # report has no --json
    assert r.exit_code == 2 and r.stdout == ""


def test_a_refused_file_system_operation_gives_the_document(tmp_path, monkeypatch):
    """An OSError the file system raises (permissions: the user's environment) is said in one
    line, exit 2, as before; under --json with its document (kind the exception's class, file
    its file name)."""
    import laminid_cli.resultfile as resultfile

    def refuse(path):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(resultfile, "read_stored_summary", refuse)
    result = tmp_path / "r.result.h5"
    result.write_bytes(b"")
    plain, as_json = both(["show", str(result)])
    e = assert_same_failure(plain, as_json, "PermissionError", file=str(result))
    assert e["message"] == f"{result}: Permission denied"
    assert plain.stderr == f"laminid: error: {result}: Permission denied\n"


def test_an_analyser_fault_before_the_session_exit_1(tmp_path):
    """The analyser refuses a set-up command (the emulator's error queue after WIND2:EXP):
    InstrumentError, exit 1, nothing measured; under --json its document with exit_code 1."""
    from tests.instrument.emulator import Fault, HP35670AEmulator

    runs = []
    for extra in ([], ["--json"]):
        with HP35670AEmulator(faults=[Fault("WIND2:EXP", "error", 0)]) as hp:
            runs.append(run(["acquire", "--analyser", hp.resource, "--timeout", "0.5",
                             "--no-prompt", "-o", str(tmp_path / "e.frf.h5"), *extra]))
    plain, as_json = runs
    # stderr's first line names the analyser, with the emulator's port: the same otherwise
    assert plain.stderr.split("\n", 1)[1] == as_json.stderr.split("\n", 1)[1]
    assert plain.exit_code == as_json.exit_code == 1 and plain.stdout == ""
    e = error_of(as_json)
    assert e == {"kind": "InstrumentError", "message": e["message"], "file": None,
                 "field": None, "line": None, "exit_code": 1}
    assert e["message"].startswith("35670A rejected 1 command(s) while configuring: "
                                   "'WIND2:EXP 0.1' -> -222,\"Data out of range\"")
    assert as_json.stderr.endswith(f"laminid: error: {e['message']}\n")
    assert not (tmp_path / "e.frf.h5").exists()


def test_acquire_stopped_after_its_summary_adds_no_second_document(tmp_path):
    """A session that stopped (standard input closed at point 2's prompt, exit 2) wrote its
    summary document, whose 'stopped' says why: stdout holds that one document only."""
    from tests.instrument.emulator import HP35670AEmulator

    out = tmp_path / "s.frf.h5"
    with HP35670AEmulator() as hp:
        r = run(["acquire", "--analyser", hp.resource, "--timeout", "0.5", "--averages", "3",
                 "--points", "3", "-o", str(out), "--json"], input="\n")
    assert r.exit_code == 2
    d = json.loads(r.stdout)                # raises on a second document ("Extra data")
    assert "error" not in d and d["points_saved"] == 1
    assert "standard input is closed" in d["stopped"]
    assert "laminid: error: " in r.stderr and "standard input is closed" in r.stderr
