"""Option audit: mistaken or hostile option values of every command are refused with one line
naming the option and what is wrong (exit 2), before any work and without touching any file.

Each test asserts the exit code, the message and the files left behind.
"""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from laminid_cli.frf.store import write_frf_h5
from tests.clihelp import run
from tests.frf_synth import synth_frf

S11 = Path("specimens/example1/S1.1.yaml")


def no_traceback(r):
    assert "Traceback" not in r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)


# ------------------------------------------------------------------------------- --seed
@pytest.mark.parametrize("command", ["identify", "batch"])
@pytest.mark.parametrize("seed", ["-1", "99999999999999999999999"])
def test_seed_outside_what_the_random_generator_and_the_file_take_is_refused(
        tmp_path, command, seed):
    # was: numpy's "ValueError: expected non-negative integer" as a traceback (identify) or
    # as "internal error" of every specimen (batch); a seed above 2**63 failed writing the
    # result file (h5py: "Object dtype has no native HDF5 equivalent")
    out = tmp_path / "out"
    where = ["-o", out] if command == "identify" else ["--out", out]
    r = run(command, S11, "--mesh", "4x4", "--monte-carlo", "2", "--seed", seed, *where)
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"Invalid value for '--seed': {seed} is not in the range "
            "0<=x<=9223372036854775807.") in r.output
    assert not out.exists()


# ------------------------------------------------------------------ output = an input file
def frf_file(path):
    freq = np.arange(0.0, 801.0)
    write_frf_h5(path, freq, synth_frf(freq, [(200.0, 0.01), (450.0, 0.01)], np.ones((2, 2))),
                 units="Pa/N")
    return path


@pytest.mark.parametrize("command", ["identify", "modes", "export"])
def test_output_named_like_the_input_is_refused_even_with_force(tmp_path, command):
    # was: `laminid identify plate.yaml -o plate.yaml --force` (and modes, and `export
    # plate.frf.h5 -o plate.frf.h5 --force`) replaced the input by the output: the specimen
    # or the acquired FRFs were lost. --force overwrites an earlier output, never the input.
    if command == "export":
        source = frf_file(tmp_path / "plate.frf.h5")
        args = ["export", source, "-o", source, "--force"]
    else:
        source = tmp_path / "plate.yaml"
        shutil.copy(S11, source)
        args = [command, source, "--mesh", "4x4", "-o", source, "--force"]
    before = source.read_bytes()
    r = run(*args)
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"laminid: error: {source}: is the input file; -o must name another file "
            "(--force overwrites an earlier output, never an input)") in r.output
    assert source.read_bytes() == before


def test_output_through_a_link_to_the_input_is_refused(tmp_path):
    source = tmp_path / "plate.yaml"
    shutil.copy(S11, source)
    link = tmp_path / "result.h5"
    link.symlink_to(source)
    before = source.read_bytes()
    r = run("modes", source, "--mesh", "4x4", "-o", link, "--force")
    assert r.exit_code == 2
    assert f"{link}: is the input file; -o must name another file" in r.output
    assert source.read_bytes() == before


def test_joint_output_named_like_the_second_specimen_is_refused(tmp_path):
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    shutil.copy(S11, a)
    shutil.copy("specimens/example1/S1.2.yaml", b)
    before = b.read_bytes()
    r = run("identify", a, b, "--joint", "--mesh", "4x4", "-o", b, "--force")
    assert r.exit_code == 2
    assert f"{b}: is the input file; -o must name another file" in r.output
    assert b.read_bytes() == before


# ------------------------------------------------------------------------- empty names
def test_batch_out_empty_is_refused_not_the_current_folder(tmp_path, monkeypatch):
    # was: --out "" wrote summary.csv, summary.json and the result files into the current
    # folder, exit 0
    spec = tmp_path / "plate.yaml"
    shutil.copy(S11, spec)
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    r = run("batch", spec, "--mesh", "4x4", "--out", "")
    no_traceback(r)
    assert r.exit_code == 2
    assert "laminid: error: --out: the folder name is empty" in r.output
    assert list(work.iterdir()) == []


@pytest.mark.parametrize("value", ["", "  "])
def test_modes_boundary_empty_is_refused_not_the_specimen_boundary(tmp_path, value):
    # was: --boundary "" silently computed the specimen's own boundary (exit 0)
    out = tmp_path / "m.h5"
    r = run("modes", S11, "--mesh", "4x4", "--boundary", value, "-o", out)
    no_traceback(r)
    assert r.exit_code == 2
    assert f"boundary '{value}' not understood: use free, simply-supported, clamped" in r.output
    assert not out.exists()


# -------------------------------------------------------------------------- --monte-carlo
@pytest.mark.parametrize("command", ["identify", "batch"])
@pytest.mark.parametrize("trials, words", [
    ("1", "1 trial gives no spread: 0 (off) or at least 2"),
    # was: accepted, and the trials' perturbations (a list of a billion) filled the memory
    ("1000000000", "1000000000 is more than 100000 trials"),
])
def test_monte_carlo_of_one_or_of_a_huge_number_of_trials_is_refused_before_the_work(
        tmp_path, command, trials, words):
    # was, for 1: the identification ran, then "Monte Carlo needs at least 2 trials, got 1"
    # without the option's name (batch: the same for every specimen, exit 1)
    out = tmp_path / "out"
    where = ["-o", out] if command == "identify" else ["--out", out]
    r = run(command, S11, "--mesh", "4x4", "--monte-carlo", trials, *where)
    no_traceback(r)
    assert r.exit_code == 2
    assert f"Invalid value for '--monte-carlo': {words}" in r.output
    assert not out.exists()


def test_monte_carlo_help_gives_the_range():
    r = run("identify", "--help")
    assert "[default: 0; 0 (off) or 2<=N<=100000]" in " ".join(r.output.split())


# ------------------------------------------------------------------ conflicting options
def test_no_output_with_an_output_file_is_refused(tmp_path):
    # was: -o silently ignored (no file written, exit 0)
    out = tmp_path / "r.h5"
    r = run("identify", S11, "--mesh", "4x4", "--no-output", "-o", out)
    no_traceback(r)
    assert r.exit_code == 2
    assert ("laminid: error: --no-output and -o contradict each other: give one of them"
            in r.output)
    assert not out.exists()


# ------------------------------------------------------- --sigma-rel, --max-rel-interval
@pytest.mark.parametrize("command", ["identify", "batch", "fit-frf"])
@pytest.mark.parametrize("value", ["0", "-0.01", "0.5", "5", "1e-200", "1e-10"])
def test_sigma_rel_outside_0_to_half_is_refused_naming_the_option(tmp_path, command, value):
    # was: "relative frequency uncertainty must be positive ..., got 0" (or "... is 50 % or
    # more"), without the option's name; 1e-200 was taken, and chi2 overflowed to inf with
    # numpy's RuntimeWarnings on the terminal (below 1e-9 the model's own round-off)
    if command == "fit-frf":
        args = ["fit-frf", frf_file(tmp_path / "plate.frf.h5")]
    else:
        args = _run_args(command, tmp_path)
    r = run(*args, "--sigma-rel", value)
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"Invalid value for '--sigma-rel': {float(value)} is not in the range "
            "1e-09<=x<0.5." in r.output)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["identify", "batch"])
@pytest.mark.parametrize("value", ["0", "-1", "0.31", "5"])
def test_max_rel_interval_outside_0_to_0_3_is_refused_by_the_parser(tmp_path, command, value):
    # above 0.30 a constant's verdict is "not determined": a looser flag would let the status
    # read ok beside it
    r = run(*_run_args(command, tmp_path), "--max-rel-interval", value)
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"Invalid value for '--max-rel-interval': {float(value)} is not in the range "
            "0<x<=0.3." in r.output)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command, option, shown", [
    ("identify", "--sigma-rel", "[default: 0.002; 1e-09<=x<0.5]"),
    ("fit-frf", "--sigma-rel", "[default: 0.002; 1e-09<=x<0.5]"),
    ("batch", "--max-rel-interval", "[default: 0.3; 0<x<=0.3]"),
])
def test_fraction_options_show_their_range_in_the_help(command, option, shown):
    r = run(command, "--help")
    text = " ".join(r.output.split())
    assert shown in text[text.index(option):]


# ---------------------------------------------------------------------------- acquire
#: nothing listens there: an option checked after connecting would give an instrument error
NOWHERE = "TCPIP::127.0.0.1::1::SOCKET"


@pytest.mark.parametrize("option, value, words", [
    # was: "" recorded V/V, "  " recorded blank units in the file (and in the UFF export)
    ("--units", "", "--units: empty; give the FRF's engineering units, e.g. Pa/N or "
                    "(m/s^2)/N, or leave the option out for V/V"),
    ("--units", "  ", "--units: empty; give the FRF's engineering units"),
    # was: written into the file, which fit-frf then refused (errors.NON_PRINTABLE)
    ("--units", "g/N\u202e", "--units 'g/N\\u202e': non-printable character U+202E "
                              "(RIGHT-TO-LEFT OVERRIDE) in it; give the FRF's engineering "
                              "units as plain text, e.g. Pa/N"),
    # was: "" silently the default backend
    ("--visa-backend", "", "--visa-backend: empty; give @py, @ivi or file.yaml@sim, or leave "
                           "the option out"),
    # was: "analyser resource '' is not a VISA resource string (Could not parse : unknown
    # interface type); ..."
    ("--analyser", " ", "--analyser: empty; give the analyser's VISA resource, e.g. GPIB0::5 "
                        "or TCPIP::192.168.0.7::5025::SOCKET"),
    ("--analyser", "", "--analyser: empty; give the analyser's VISA resource"),
])
def test_acquire_blank_text_options_are_refused_before_connecting(tmp_path, option, value,
                                                                  words):
    out = tmp_path / "plate.frf.h5"
    r = run("acquire", "--analyser", NOWHERE, "--timeout", "0.5", "--no-prompt", option, value,
            "-o", out)
    no_traceback(r)
    assert r.exit_code == 2
    assert f"laminid: error: {words}" in r.output
    assert not out.exists()


# ----------------------------------------------------------------------------- export
@pytest.fixture(scope="module")
def modes_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("modes") / "S1.1.modes.h5"
    r = run("modes", S11, "--mesh", "4x4", "--modes", "3", "-o", out)
    assert r.exit_code == 0, r.output
    return out


@pytest.mark.parametrize("option, value", [("--format", "csv"), ("--freq-dataset", "/f"),
                                           ("--frf-dataset", "/frf")])
def test_export_of_mode_shapes_refuses_the_frf_input_options(tmp_path, modes_file, option,
                                                             value):
    # was: silently ignored (a plain HDF5 FRF file taken for a result would be exported as
    # mode shapes without a word)
    out = tmp_path / "m.unv"
    r = run("export", modes_file, "-o", out, option, value)
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"laminid: error: {modes_file}: holds mode shapes (a laminid-modes file); "
            f"{option} applies to FRF input only") in r.output
    assert not out.exists()


def test_export_of_frfs_refuses_specimen(tmp_path):
    # was: --specimen silently ignored
    source = frf_file(tmp_path / "plate.frf.h5")
    out = tmp_path / "plate.uff"
    r = run("export", source, "-o", out, "--specimen", "S1.1")
    no_traceback(r)
    assert r.exit_code == 2
    assert (f"laminid: error: {source}: holds FRFs; --specimen picks the plate of a joint "
            "result (mode shapes)") in r.output
    assert not out.exists()


def test_export_of_mode_shapes_still_takes_specimen_of_its_plate(tmp_path, modes_file):
    out = tmp_path / "m.unv"
    r = run("export", modes_file, "-o", out, "--specimen", "S1.1", "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["specimen"] == "S1.1" and d["datasets"] == {"164": 1, "15": 1, "55": 3}
    # the frequency range of the modes written, in Hz
    assert d["freq_range_hz"] == [min(d["freq_hz"]), max(d["freq_hz"])]
    assert 0 < d["freq_range_hz"][0] < d["freq_range_hz"][1]
    assert out.stat().st_size > 0


def _run_args(command, tmp_path) -> list:
    """identify or batch of S1.1 on a 4x4 mesh, writing nothing but into tmp_path/out."""
    return [command, S11, "--mesh", "4x4"] + (["--out", tmp_path / "out"]
                                              if command == "batch" else ["--no-output"])


@pytest.mark.parametrize("command, name, hint", [
    ("identify", "r.json", "--json prints JSON on stdout"),
    ("identify", "r.csv", "laminid batch writes summary.csv"),
    ("modes", "m.uff", "laminid export writes UFF"),
    # (batch's summary.csv is no table of modes, nor of FRFs)
    ("modes", "m.csv", "; --json prints the frequencies as JSON, laminid export writes the mode "
                       "shapes as a Universal File (.uff)\n"),
    ("acquire", "a.csv", "; no laminid command writes FRFs as CSV: laminid export writes them "
                         "as a Universal File (.uff)\n"),
    ("modes", "m.txt", ""),
])
def test_an_hdf5_output_named_like_another_format_is_refused(tmp_path, command, name, hint):
    """identify -o result.json wrote HDF5 under a .json name (a JSON reader then fails on it,
    and a user expecting JSON gets none); now refused before the work, with where that format
    comes from; no file written."""
    out = tmp_path / name
    r = run(command, *(["--analyser", "GPIB0::5", "--points", "4"] if command == "acquire"
                       else [S11, "--mesh", "4x4"]), "-o", out)
    no_traceback(r)
    assert r.exit_code == 2
    assert f"{out}: {command} writes" in r.output and "as HDF5; name it .h5 (-o)" in r.output
    assert hint in r.output
    assert not out.exists()


# ------------------------------------------------------------------ --fix split at a space
@pytest.mark.parametrize("command", ["identify", "batch"])
@pytest.mark.parametrize("split", [["G13", "G23"], ["G13,", "nu12,g23"]])
def test_fix_list_split_at_a_space_says_so_not_add_joint(tmp_path, command, split):
    # was: identify "2 specimens given: add --joint to identify them together" for
    # `--fix G13 G23` (the shell gives G23 as a second specimen), which --joint then turned
    # into "G23: file not found"; batch "G23: no such file or folder": neither named --fix
    where = ["-o", tmp_path / "r.h5"] if command == "identify" else ["--out", tmp_path / "out"]
    r = run(command, S11, "--mesh", "4x4", "--fix", *split, *where)
    no_traceback(r)
    assert r.exit_code == 2
    missing = "no such file or folder" if command == "batch" else "file not found"
    assert (f"laminid: error: {split[1]}: {missing}; it reads as a --fix item: --fix takes one "
            "comma-separated list without spaces (--fix G13,G23)") in r.output
    assert list(tmp_path.iterdir()) == []


def test_identify_of_two_files_one_missing_names_it_not_add_joint(tmp_path):
    # was: "2 specimens given: add --joint ...", though --joint could only fail on the file
    r = run("identify", S11, tmp_path / "S1.2.yaml", "-o", tmp_path / "r.h5")
    assert r.exit_code == 2
    assert f"laminid: error: {tmp_path / 'S1.2.yaml'}: file not found\n" in r.output
    assert "--joint" not in r.output and "--fix" not in r.output


@pytest.mark.parametrize("option", ["-q", "--quiet", "-v", "--verbose"])
def test_laminids_own_option_after_the_command_says_where_it_goes(option):
    """`laminid batch plates/ -q` (the README's "not under -q" read as batch's option): click
    said only "No such option '-q'"; the message now says it goes before the command, in the
    --json error document too."""
    r = run("batch", "nowhere", option, "--json")
    assert r.exit_code == 2
    doc = json.loads(r.stdout)["error"]
    assert doc["message"] == (f"No such option: {option} of 'batch'; it is laminid's own, "
                              f"written before the command: laminid {option} batch ...")
    assert doc["field"] == option and doc["kind"] == "UsageError"


def test_report_json_names_where_a_results_json_is(tmp_path):
    """report is the one command without --json; `laminid report R.h5 --json` said only
    "No such option '--json'": it names show --json (and a batch's summary.json). No JSON
    document on stdout: report has none to replace."""
    r = run("report", tmp_path / "r.result.h5", "--json")
    assert r.exit_code == 2 and r.stdout == ""
    assert r.stderr.endswith(
        "Error: No such option: --json of 'report', which draws figures; 'laminid show RESULT "
        "--json' prints a result as JSON (a batch's is its summary.json)\n"), r.stderr


def test_a_folder_given_for_a_file_names_one_the_command_takes(tmp_path):
    """fit-frf and modes of a folder said "is a folder, not a file" alone; each names the
    files there it takes (a batch's summary.csv is no FRF file), one in the command to run."""
    (tmp_path / "b.frf.h5").write_bytes(b"")
    (tmp_path / "a.uff").write_bytes(b"")
    (tmp_path / "summary.csv").write_text("name\n")
    (tmp_path / "plate.yaml").write_text("name: p\n")
    r = run("fit-frf", tmp_path)
    assert r.exit_code == 2
    assert r.stderr == (f"laminid: error: {tmp_path}: is a folder, not a file; it holds 2 FRF "
                        f"files: 'laminid fit-frf {tmp_path / 'a.uff'}' takes one\n")
    r = run("modes", tmp_path)
    assert r.exit_code == 2
    assert r.stderr == (f"laminid: error: {tmp_path}: is a folder, not a file; it holds 1 "
                        f"specimen file: 'laminid modes {tmp_path / 'plate.yaml'}'\n")
    (tmp_path / "plate.yaml").unlink()
    assert run("modes", tmp_path).stderr == f"laminid: error: {tmp_path}: is a folder, not a file\n"
