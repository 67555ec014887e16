"""`laminid show`: a result file printed as identify printed it (text and --json), for single,
joint, batch and damped results; files it cannot show are refused in one line (exit 2)."""

import json

import h5py
import numpy as np
import pytest

from tests.clihelp import run, write_s14_with_ranges
from tests.dampspec import damped_copy

S11 = "specimens/example1/S1.1.yaml"
S12 = "specimens/example1/S1.2.yaml"
MESH = "6x6"


def _identify(*args):
    r = run("identify", *args)
    assert r.exit_code == 0, r.output
    return r.stdout


def _without_written_line(text: str) -> str:
    # identify's last line names the file it wrote; show names it in its first line
    head, sep, _tail = text.rpartition("\nwritten: ")
    assert sep, text
    return head.rstrip("\n")


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    out = tmp_path_factory.mktemp("show") / "s11.result.h5"
    text = _identify(S11, "--mesh", MESH, "-o", out)
    return out, text


def test_show_prints_what_identify_printed(single):
    out, text = single
    r = run("show", out)
    assert r.exit_code == 0, r.output
    first, body = r.stdout.split("\n", 1)
    assert first.startswith(f"{out}: written 20") and first.endswith(
        f"by laminid 0.2.0 (laminid identify), mesh {MESH}")
    assert body.strip("\n") == _without_written_line(text)
    # the numbers a lab reads are there: E1 with its interval and verdict, the status
    assert "status:" in body and "E1" in body


def test_frequency_table_gives_each_measured_frequency_its_sigma(single):
    """The mode table gave the measured frequencies without their standard deviations (the
    damping table has its '+/-'; the sigmas were in --json, the file and the report's shading
    only): the residuals could not be read against them. S1.1 (0.2 % of each frequency, the
    --sigma-rel default): a '+/- Hz' column, 0.25 Hz for 125.05 Hz, identify and show alike."""
    out, text = single
    lines = text.splitlines()
    head = next(i for i, ln in enumerate(lines) if "residual %" in ln)
    assert lines[head].split()[-3:] == ["weight", "+/-", "Hz"]
    rows = [ln.split() for ln in lines[head + 1:head + 13]]
    measured = np.array([float(r[2]) for r in rows])
    assert measured[0] == 125.05
    assert [r[5] for r in rows] == [f"{0.002 * f:.2f}" for f in measured]
    r = run("show", out)
    assert lines[head] in r.stdout.splitlines() and "\n".join(lines[head:head + 13]) in r.stdout


def test_show_json_is_identify_json_plus_file_and_written(tmp_path):
    out = tmp_path / "s11.h5"
    d = json.loads(_identify(S11, "--mesh", MESH, "--json", "-o", out))
    r = run("show", out, "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s.pop("file") == str(out)
    written = s.pop("written")
    assert written["command"] == "laminid identify" and written["format"] == "laminid-result"
    assert written["laminid_version"] == "0.2.0" and written["created"].startswith("20")
    d.pop("output"), d.pop("output_replaced")
    assert s == d                                   # bit for bit: nothing is computed again
    # and the typed datasets agree with it (the file's reference for other programs)
    with h5py.File(out, "r") as f:
        e1 = f["materials"][next(iter(f["materials"]))]["E1"][()]
    assert s["materials"]["IM7/977-2"]["E1"] == pytest.approx(float(e1), rel=1e-12)


def test_show_json_of_a_file_written_before_units_gets_them(single):
    """A result written before identify --json had "units" (its /summary_json without them):
    show --json gives them, the same as identify's now."""
    out, _ = single
    fresh = json.loads(run("show", out, "--json").stdout)
    assert fresh["units"]["E1"] == "Pa" and fresh["units"]["frequencies"] == "Hz"
    old_file = out.with_name("old.result.h5")
    old_file.write_bytes(out.read_bytes())
    with h5py.File(old_file, "r+") as f:
        old = json.loads(f["summary_json"][()])
        del old["units"]
        del f["summary_json"]
        f.create_dataset("summary_json", data=json.dumps(old))
    s = json.loads(run("show", old_file, "--json").stdout)
    assert s["units"] == fresh["units"]
    assert list(s)[-3:] == ["units", "file", "written"]


def test_show_prints_a_residual_that_rounds_to_zero_without_minus(single, tmp_path):
    """A mode fitted to -0.001 % was shown "-0.00" in the residual column: now "0.00"."""
    out, _ = single
    edited = tmp_path / "tiny.result.h5"
    edited.write_bytes(out.read_bytes())
    with h5py.File(edited, "r+") as f:
        s = json.loads(f["summary_json"][()])
        s["frequencies"]["residual_percent"][:2] = [-0.001, -0.0042]
        del f["summary_json"]
        f.create_dataset("summary_json", data=json.dumps(s))
    r = run("show", edited)
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    head = next(i for i, ln in enumerate(lines) if "residual %" in ln)
    assert [lines[head + k].split()[3] for k in (1, 2)] == ["0.00", "0.00"]
    assert "-0.00 " not in r.stdout and not r.stdout.rstrip().endswith("-0.00")


def test_show_of_a_reference_range_and_of_an_old_file_that_stored_its_midpoint(tmp_path):
    """A reference range is shown as identify shows it ([low, high] in --json, "low .. high"
    on the terminal). A file of an earlier laminid stored the range's midpoint in its summary
    (E1 135 GPa for [120 GPa, 150 GPa]): show gives the range of the specimen the file holds,
    and leaves its single values as stored."""
    spec = write_s14_with_ranges(tmp_path)
    out = tmp_path / "r.h5"
    d = json.loads(_identify(spec, "--mesh", MESH, "--json", "-o", out))
    s = json.loads(run("show", out, "--json").stdout)
    assert s["reference"] == d["reference"]
    assert s["reference"]["materials"]["IM7/977-2"]["E1"] == [120e9, 150e9]
    with h5py.File(out, "r+") as f:                  # as laminid before ranges were kept
        old = json.loads(f["summary_json"][()])
        old["reference"]["materials"]["IM7/977-2"]["E1"] = 135e9
        old["reference"]["global"]["nu_xy"] = 0.06
        del f["summary_json"]
        f.create_dataset("summary_json", data=json.dumps(old))
    r = run("show", out)
    assert r.exit_code == 0, r.output
    e1 = next(ln for ln in r.stdout.splitlines() if ln.startswith("  E1 [GPa]"))
    assert "  120.00 .. 150.00   " in e1 and "135.00" not in r.stdout
    assert "    reference: nu_xy 0.050 .. 0.070" in r.stdout.splitlines()
    s = json.loads(run("show", out, "--json").stdout)
    assert s["reference"] == d["reference"]          # the range again; E2 10 GPa as stored
    assert s["reference"]["materials"]["IM7/977-2"]["E2"] == 10e9


def test_show_of_a_joint_result(tmp_path):
    out = tmp_path / "joint.h5"
    text = _identify(S11, S12, "--joint", "--mesh", MESH, "-o", out)
    r = run("show", out)
    assert r.exit_code == 0, r.output
    first, body = r.stdout.split("\n", 1)
    assert first.endswith(f"(laminid identify --joint), mesh {MESH}")
    assert body.strip("\n") == _without_written_line(text)
    assert "S1.1" in body and "S1.2" in body


def test_show_of_a_batch_result_matches_the_batch_summary(tmp_path):
    out = tmp_path / "out"
    r = run("batch", S11, "--mesh", MESH, "--out", out, "--json")
    assert r.exit_code == 0, r.output
    row = json.loads(r.stdout)["specimens"][0]
    r = run("show", row["result"], "--json")
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["written"]["command"] == "laminid batch"
    for k, v in row["materials"]["IM7/977-2"].items():
        assert s["materials"]["IM7/977-2"][k] == pytest.approx(v, rel=1e-12), k
    assert s["status"] == row["status"]
    # the terminal form names the batch and the mesh it ran on, which nothing else in the
    # output said (identify's own output leaves it to its command line)
    r = run("show", row["result"])
    assert r.exit_code == 0, r.output
    assert r.stdout.split("\n", 1)[0].endswith(f"(laminid batch), mesh {MESH}")


def test_show_of_a_damped_result_prints_the_loss_factors(tmp_path):
    spec = tmp_path / "damped.yaml"
    damped_copy(S11, spec, np.array([0.002, 0.012, 0.018, 0.012, 0.012]), sigma_rel=0.03,
                mesh=MESH)
    out = tmp_path / "damped.h5"
    text = _identify(spec, "--mesh", MESH, "-o", out)
    r = run("show", out)
    assert r.exit_code == 0, r.output
    assert r.stdout.split("\n", 1)[1].strip("\n") == _without_written_line(text)
    assert "eta22" in r.stdout or "η22" in r.stdout


def test_files_show_cannot_print_are_refused_in_one_line(single, tmp_path):
    out, _ = single
    old = tmp_path / "old.h5"
    old.write_bytes(out.read_bytes())
    with h5py.File(old, "a") as f:                  # as written before /summary_json
        del f["summary_json"]
    r = run("show", old)
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert (f"{old}: written by laminid 0.2.0 before result files kept what identify printed "
            f"(no /summary_json); 'laminid report {old}' draws it") in r.output
    bad = tmp_path / "bad.h5"
    bad.write_bytes(out.read_bytes())
    with h5py.File(bad, "a") as f:
        del f["summary_json"]
        f["summary_json"] = "{not json"
    r = run("show", bad)
    assert r.exit_code == 2 and f"{bad}: /summary_json is not readable JSON" in r.output
    text = tmp_path / "notes.txt"
    text.write_text("E1 = 117 GPa\n")
    r = run("show", text)
    assert r.exit_code == 2 and "not a laminid identification result" in r.output
    summary = tmp_path / "summary.csv"
    summary.write_text("name,status\nS1.1,ok\n")
    r = run("show", summary)
    assert r.exit_code == 2 and (f"{summary}: a batch summary is text already (a spreadsheet, "
                                 f"jq); 'laminid report {summary}' draws it") in r.output
    r = run("show", tmp_path / "missing.h5")
    assert r.exit_code == 2 and "missing.h5" in r.output and "Traceback" not in r.output


def test_show_help_names_json_and_the_report():
    r = run("show", "--help")
    assert r.exit_code == 0
    text = " ".join(r.output.split())
    assert "--json" in text and "laminid report" in text and "Nothing is computed again" in text


def test_show_and_report_of_a_modes_file_say_what_it_is_and_what_reads_it(tmp_path):
    """`laminid modes S1.1.yaml -o m.h5` then `show m.h5` (or `report`) said "not a laminid
    identification result (a 'laminid-modes' file; expected format 'laminid-result')": it
    names the command that wrote it and the ones that read it (modes again, export)."""
    m = tmp_path / "m.h5"
    assert run("modes", S11, "--mesh", "4x4", "-o", m).exit_code == 0
    for command in ("show", "report"):
        r = run(command, m)
        assert r.exit_code == 2 and r.stdout == "", r.output
        assert " ".join(r.stderr.split()) == (
            f"laminid: error: {m}: a file of 'laminid modes' (the model's modes at the "
            "specimen's constants), not an identification result: 'laminid modes SPEC.yaml' "
            f"prints its table again, 'laminid export {m} -o modes.unv' writes its mode shapes; "
            "a result is made with laminid identify SPEC.yaml (or laminid identify A.yaml "
            "B.yaml --joint, laminid batch FOLDER)")
    # and what it names reads it
    assert run("export", m, "-o", tmp_path / "modes.unv").exit_code == 0


def test_show_and_report_of_a_cut_short_result_say_it_is_damaged_not_no_hdf5(tmp_path):
    # was: "not an HDF5 file, so not a laminid identification result; make one with laminid
    # identify ...": a result copied only in part (a full USB stick, a sync cut off) sent the
    # lab to look for a wrong file, not a broken one
    whole = tmp_path / "whole.h5"
    with h5py.File(whole, "w") as f:
        f.attrs["format"] = "laminid-result"
        f["history"] = np.arange(20000.0)
    cut = tmp_path / "S1.1.result.h5"
    cut.write_bytes(whole.read_bytes()[:50000])
    for command in ("show", "report"):
        r = run(command, cut)
        assert r.exit_code == 2 and r.stdout == "", r.output
        assert r.stderr.startswith(f"laminid: error: {cut}: an HDF5 file that cannot be read ("), \
            r.stderr
        assert "truncated file" in r.stderr
        assert "): damaged or incomplete (a copy cut short?); copy it again, or make it again " \
               "with laminid identify SPEC.yaml" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["S1.1.result.h5", "whole.h5"]


def test_a_folder_names_the_result_files_it_holds(tmp_path):
    """`laminid show results` (a batch's --out) said "is a folder, not a file" alone; it names
    one of the result files it holds (one level down, as batch writes them) and the summary to
    report. A folder without results keeps the plain words."""
    (tmp_path / "example1").mkdir()
    for name in ("S1.2", "S1.1"):
        (tmp_path / "example1" / f"{name}.result.h5").write_bytes(b"")
    (tmp_path / "summary.csv").write_text("name\n")
    r = run("show", tmp_path)
    assert r.exit_code == 2
    assert r.stderr == (f"laminid: error: {tmp_path}: is a folder, not a file; it holds 2 result "
                        f"files: 'laminid show {tmp_path / 'example1' / 'S1.1.result.h5'}' prints "
                        f"one, 'laminid report {tmp_path / 'summary.csv'}' draws the batch\n")
    r = run("show", tmp_path / "example1" / "..")
    assert r.exit_code == 2 and "it holds 2 result files" in r.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    r = run("show", empty)
    assert r.stderr == f"laminid: error: {empty}: is a folder, not a file\n"


def _edited_copy(out, tmp_path, edit):
    """A copy of the result ``out`` (tmp_path/edited.result.h5) with ``edit(h5py file)`` done."""
    edited = tmp_path / "edited.result.h5"
    edited.write_bytes(out.read_bytes())
    with h5py.File(edited, "r+") as f:
        edit(f)
    return edited


@pytest.mark.parametrize("edit, words", [
    (lambda f: f["materials/IM7_977-2"].__delitem__("E1") or
     f["materials/IM7_977-2"].create_dataset("E1", data="abc"),
     "dataset '/materials/IM7_977-2/E1' holds 'abc', not numbers; the result file is damaged "
     "or was edited"),
    (lambda f: f["specimen"].__delitem__("a") or f["specimen"].create_dataset("a", data=[1, 2]),
     "dataset '/specimen/a' holds 2 values, where one number is expected; the result file is "
     "damaged or was edited"),
    (lambda f: f["frequencies"].__delitem__("model") or
     f["frequencies"].create_dataset("model", data=np.array([b"x"] * 12)),
     "dataset '/frequencies/model' holds [b'x', b'x', b'x', b'x', b'x', b'x', ..., not numbers; the "
     "result file is damaged or was edited")])
@pytest.mark.parametrize("command", ["show", "report"])
def test_a_result_with_text_where_a_number_belongs_is_refused_naming_the_dataset(
        single, tmp_path, edit, words, command):
    """A result file edited by hand or damaged with text where a number is stored: show and
    report died of 'ValueError: could not convert string to float: b'abc'' (a traceback,
    exit 1); the file and the dataset are named, exit 2, no report written."""
    out, _ = single
    edited = _edited_copy(out, tmp_path, edit)
    pdf = tmp_path / "r.pdf"
    r = run(command, edited, *(["-o", pdf] if command == "report" else []))
    assert (r.exit_code, r.output) == (2, f"laminid: error: {edited}: {words}\n")
    assert not pdf.exists()


def _set(path, value):
    def edit(f):
        del f[path]
        f[path] = value
    return edit


@pytest.mark.parametrize("edit, words", [
    (_set("specimen/a", np.nan), "dataset '/specimen/a' is nan, not a plate's length in m"),
    (_set("specimen/h", -3e-3), "dataset '/specimen/h' is -0.003, not a plate's length in m"),
    (_set("materials/IM7_977-2/E1", np.inf),
     "dataset '/materials/IM7_977-2/E1' is inf, not a finite number"),
    (lambda f: f["mesh/elements"].__setitem__(0, 10**9),
     "dataset '/mesh/elements' names nodes outside 0 .. 132 (the nodes of mesh/nodes)"),
    (_set("mesh/nodes", np.zeros((0, 2))),
     "dataset '/mesh/nodes' holds 0 x 2 values, not the finite x, y of at least one node"),
    (lambda f: f["modes/w"].__setitem__((0, 0), np.inf),
     "dataset '/modes/w' holds 133 x 12 values, not finite mode shapes at the 133 nodes"),
    (_set("frequencies/model", np.zeros(3)),
     "dataset '/frequencies/model' holds 3 values, frequencies/measured 12")])
def test_a_result_whose_values_cannot_be_drawn_is_refused_naming_the_dataset(
        single, tmp_path, edit, words):
    """A damaged or hand-edited result: report died with a traceback on each (a NaN side:
    'Axis limits cannot be NaN or Inf'; an element naming node 10**9: 'index 1000000000 is
    out of bounds'; 3 model frequencies for 12 measured: 'shape mismatch'); the file and the
    dataset are named, exit 2, no report written."""
    out, _ = single
    edited = _edited_copy(out, tmp_path, edit)
    pdf = tmp_path / "r.pdf"
    r = run("report", edited, "-o", pdf)
    assert (r.exit_code, r.output) == (2, f"laminid: error: {edited}: {words}; the result "
                                          "file is damaged or was edited\n")
    assert not pdf.exists()


def _summary_name(f):
    s = json.loads(f["summary_json"][()])
    s["specimen"] = "S1\u202e1.2"
    del f["summary_json"]
    f["summary_json"] = json.dumps(s)


@pytest.mark.parametrize("edit, words", [
    (lambda f: f["specimen"].attrs.__setitem__("name", "S1\u202e1.2"),
     "attribute 'name' of '/specimen' ('S1\\u202e1.2'): non-printable character U+202E "
     "(RIGHT-TO-LEFT OVERRIDE) in it"),
    (lambda f: f["specimen"].attrs.__setitem__("description", "plate \x1b[31mred"),
     "attribute 'description' of '/specimen' ('plate \\x1b[31mred'): non-printable character "
     "U+001B in it"),
    (_summary_name, "/summary_json, field 'specimen' ('S1\\u202e1.2'): non-printable "
                    "character U+202E (RIGHT-TO-LEFT OVERRIDE) in it")])
def test_a_results_text_with_a_bidi_override_or_escape_is_refused(single, tmp_path, edit,
                                                                  words):
    """A result file's name, description or summary text with a right-to-left override or
    an ESC (edited, or written by another tool) was printed by show and drawn by report as
    it came, 'S1\\u202e1.2' shown as 'S12.11'; refused as the specimen reader refuses it
    (errors.NON_PRINTABLE), the file and the field named."""
    out, _ = single
    edited = _edited_copy(out, tmp_path, edit)
    r = run("show", edited)
    assert (r.exit_code, r.output) == (2, f"laminid: error: {edited}: {words}; the result "
                                          "file is damaged or was edited\n")


@pytest.mark.parametrize("edit, words", [
    (lambda f: f["modes/w"].__setitem__((0, 0), np.inf),
     "dataset modes/w holds 133 x 12 values, not finite mode shapes at the 133 nodes"),
    (_set("mesh/nodes", np.zeros((0, 2))),
     "dataset mesh/nodes holds 0 x 2 values, not the finite x, y of at least one node")])
def test_export_of_shapes_that_are_not_finite_writes_no_uff(single, tmp_path, edit, words):
    """export wrote a UFF of 0 nodes, or with 'inf' in a mode's record, from a damaged
    result, exit 0; refused naming the dataset, no file written."""
    out, _ = single
    edited = _edited_copy(out, tmp_path, edit)
    unv = tmp_path / "modes.unv"
    r = run("export", edited, "-o", unv)
    assert (r.exit_code, r.output) == (2, f"laminid: error: {edited}: {words}; the file is "
                                          "damaged or was edited\n")
    assert not unv.exists()


def test_export_of_a_result_whose_name_has_a_bidi_override_writes_no_uff(single, tmp_path):
    """The specimen's name goes into each UFF 55 record's id2 ('specimen S1\\u202e1.2'): the
    override was written into the file; refused as the readers refuse it."""
    out, _ = single
    edited = _edited_copy(out, tmp_path,
                          lambda f: f["specimen"].attrs.__setitem__("name", "S1\u202e1.2"))
    unv = tmp_path / "modes.unv"
    r = run("export", edited, "-o", unv)
    assert (r.exit_code, r.output) == (2, (
        f"laminid: error: {edited}: the specimen's name 'S1\\u202e1.2' (attribute 'name' of "
        "/specimen): non-printable character U+202E (RIGHT-TO-LEFT OVERRIDE) in it; remove "
        "it\n"))
    assert not unv.exists()


@pytest.mark.parametrize("command", ["show", "report"])
def test_an_empty_result_file_is_said_to_be_empty(tmp_path, command):
    """A 0-byte result (a copy cut off before it began) was 'not an HDF5 file, so not a
    laminid identification result', as a file of another kind; it says it is empty."""
    path = tmp_path / "s.result.h5"
    path.write_bytes(b"")
    r = run(command, path)
    assert r.exit_code == 2 and r.output.startswith(
        f"laminid: error: {path}: the file is empty (0 bytes), a copy that did not finish?; "
        "copy it again, or make it again with laminid identify SPEC.yaml")
    assert r.output.count("\n") == 1


def _declared(path, rows):
    """An edit replacing dataset ``path`` with one of ``rows`` rows (its other axes kept),
    chunked and compressed with nothing written: a file of a few hundred kB declaring it."""
    def edit(f):
        old = f[path] if path in f else None
        tail = old.shape[1:] if old is not None else (6,)
        if old is not None:
            del f[path]
        f.create_dataset(path, shape=(rows, *tail), dtype=float, chunks=(1000, *tail),
                         compression="gzip")
    return edit


@pytest.mark.parametrize("command, path, shown, words", [
    ("show", "history/constants", "1000000000 x 6",
     "more rows than the evaluations laminid records (200000)"),
    ("report", "modes/w", "1000000000 x 12",
     "more rows than the nodes of the finest mesh laminid builds (120801)"),
    ("show", "uncertainty/monte_carlo/samples", "1000000000 x 6",
     "more rows than the Monte Carlo trials (100000)"),
    ("export", "history/x", "1000000000 x 6",
     "more rows than the evaluations laminid records (200000)")])
def test_a_result_declaring_a_huge_dataset_is_refused_before_it_is_read(
        single, tmp_path, command, path, shown, words):
    """A tampered result whose /history/constants (or /modes/w, the Monte Carlo samples)
    declares 10**9 rows, chunked and unwritten (a 200 kB file), was read whole: 44.7 GiB, a
    MemoryError traceback (or the machine's memory taken). The declared shapes are checked
    against what laminid writes before anything is read; the dataset named, exit 2, no
    output file."""
    out, _ = single
    edited = _edited_copy(out, tmp_path, _declared(path, 10**9))
    assert edited.stat().st_size < 2e6
    target = tmp_path / ("r.pdf" if command == "report" else "m.unv")
    r = run(command, edited, *(["-o", target] if command != "show" else []))
    tail = "the result file" if command != "export" else "the file"
    assert (r.exit_code, r.output) == (2, f"laminid: error: {edited}: dataset '/{path}' "
                                          f"declares {shown} values, {words}; {tail} is "
                                          "damaged or was edited\n")
    assert not target.exists()


def test_a_result_dataset_larger_than_the_memory_is_refused(single, tmp_path, monkeypatch):
    """Within the limits of what laminid writes a dataset may still not fit the memory left:
    a covariance of 20000 x 6 values (0.96 MB) with 1.5 MB available is refused, named; with
    1 GB it is shown."""
    out, _ = single
    edited = _edited_copy(out, tmp_path, _declared("uncertainty/covariance", 20000))
    monkeypatch.setattr("laminid_cli.memory.available_memory_bytes", lambda: 1.5e6)
    r = run("show", edited)
    assert (r.exit_code, r.output) == (2, (
        f"laminid: error: {edited}: dataset '/uncertainty/covariance' declares 20000 x 6 "
        "values, 0.96 MB to read, more than half the memory available (1.5 MB); the result "
        "file is damaged or was edited\n"))
    monkeypatch.setattr("laminid_cli.memory.available_memory_bytes", lambda: 1e9)
    r = run("show", edited)           # with room it is read (show does not use the covariance)
    assert r.exit_code == 0, r.output
