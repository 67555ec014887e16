"""`laminid batch`: same numbers as one-by-one runs, re-runs, failures, kills, Dask."""

import csv
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.batch import BatchOptions, discover_specimens, input_hash, read_summary
from laminid_cli.cli import cli
from tests.clihelp import without_comments

SPECS = {"example1/S1.4.yaml": "specimens/example1/S1.4.yaml",
         "example2/S2.1.yaml": "specimens/example2/S2.1.yaml"}
MESH = "6x6"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def make_tree(root: Path, specs=SPECS) -> Path:
    for rel, src in specs.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(src, root / rel)
    return root


def constants_bytes(path) -> dict:
    """Raw bytes of every dataset of /materials (the identified constants)."""
    out = {}
    with h5py.File(path, "r") as f:
        for name, g in f["materials"].items():
            for key, d in g.items():
                out[f"{name}/{key}"] = d[()].tobytes()
    return out


@pytest.fixture(scope="module")
def batch_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("batch")
    specs = make_tree(tmp / "specs")
    out = tmp / "out"
    r = run("batch", specs, "--mesh", MESH, "-j", "2", "--out", out)
    return specs, out, r


def test_batch_gives_the_constants_of_one_by_one_runs_byte_for_byte(batch_run, tmp_path):
    specs, out, r = batch_run
    assert r.exit_code == 0, r.output
    for rel in SPECS:
        batch_file = out / rel.replace(".yaml", ".result.h5")
        single = tmp_path / (Path(rel).stem + ".h5")
        s = run("identify", specs / rel, "--mesh", MESH, "-o", single, "--json")
        assert s.exit_code == 0, s.output
        a, b = constants_bytes(batch_file), constants_bytes(single)
        assert set(a) == set(b) and len(a) == 7                     # six constants + density
        assert all(a[k] == b[k] for k in a), rel
        with h5py.File(batch_file) as f:
            assert len(f.attrs["batch_input_sha256"]) == 64
            assert f.attrs["batch_name"] == rel[:-5]
            assert json.loads(f.attrs["batch_options"])["mesh"] == MESH


def test_summary_csv_and_table_have_the_shape_of_table_2(batch_run, tmp_path):
    specs, out, r = batch_run
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(without_comments(fh)))
    # long form: one row per specimen, material and constant, SI, the unit in its column
    assert list(rows[0]) == ["name", "specimen", "material", "constant", "value", "lower",
                             "upper", "verdict", "flag", "bound_side", "bound_limit",
                             "profile_bound", "profile", "profile_far", "mc_lower",
                             "mc_upper", "mc_search_limit", "unit", "status", "reasons",
                             "rms_residual [%]", "result", "stale_result"]
    assert all(row["stale_result"] == "" for row in rows)      # nothing set aside
    assert all(row["mc_lower"] == row["mc_upper"] == row["mc_search_limit"] == ""
               for row in rows)                          # no --monte-carlo
    assert [(row["name"], row["constant"]) for row in rows] == [
        (n, k) for n in ("example1/S1.4", "example2/S2.1")
        for k in ("E1", "E2", "G12", "G13", "G23", "nu12")]
    by = {(row["name"], row["constant"]): row for row in rows}
    e1 = by["example1/S1.4", "E1"]
    with h5py.File(out / "example1" / "S1.4.result.h5") as f:
        g = f["materials"]["IM7_977-2"]                # safe key, real name as attribute
        assert g.attrs["name"] == "IM7/977-2"
        E1 = g["E1"][()]
        rms = f["frequencies"].attrs["rms_residual_percent"]
        u = f["uncertainty"]
        k = [x.decode() for x in u["labels"][()]].index("IM7/977-2.E1")
        lo, hi = u["lower"][k], u["upper"][k]
    assert e1["material"] == "IM7/977-2" and e1["unit"] == "Pa" and by[
        "example1/S1.4", "nu12"]["unit"] == "1"
    assert float(e1["value"]) == pytest.approx(E1, rel=1e-14)
    assert 130e9 < float(e1["value"]) < 190e9                       # paper 159.6 GPa
    assert float(e1["lower"]) == pytest.approx(lo, rel=1e-14) and lo < E1 < hi
    assert float(e1["upper"]) == pytest.approx(hi, rel=1e-14)
    assert e1["verdict"] == "well determined" and e1["result"] == "example1/S1.4.result.h5"
    assert float(e1["rms_residual [%]"]) == pytest.approx(rms, rel=1e-5) and rms < 1.0
    # S2.1 on 6x6: G13 ends at its bound, G23 undetermined, s2 far above its 99 % limit
    g13 = by["example2/S2.1", "G13"]
    assert g13["verdict"] == "at bound — not identified" and g13["lower"] == g13["upper"] == ""
    # ... its side and limit in their own columns (the file's /uncertainty/bound_limit),
    # empty for every constant not at its bound
    with h5py.File(out / "example2" / "S2.1.result.h5") as f:
        u = f["uncertainty"]
        k = [x.decode() for x in u["labels"][()]].index("E-glass/R368.G13")
        g13_limit = u["bound_limit"][k]
        g13_profile = u["profile_bound"][k]
    assert g13["bound_side"] == "lower" and float(g13["bound_limit"]) == g13_limit
    # where the fit rejects it (the profile; on this coarse mesh it does, at about 1.5 GPa)
    assert float(g13["profile_bound"]) == g13_profile and 0.1e9 < g13_profile < 18.5e9
    assert g13["profile"] == "bound"
    assert 0 < g13_limit < 0.01e9                           # 0.0001 E1 at the optimum
    assert all(row["bound_side"] == row["bound_limit"] == row["profile_bound"]
               == row["profile"] == "" for key, row in by.items()
               if key != ("example2/S2.1", "G13"))
    assert g13["status"] == "check"
    assert g13["reasons"] == "at_bound, undetermined, poor_fit"
    # ... and what each value is, in a word a script can test (the verdict is for a reader)
    assert g13["flag"] == "at_bound" and by["example2/S2.1", "G23"]["flag"] == "undetermined"
    assert e1["flag"] == ""
    # terminal: one block per material set, specimens as columns, constants as rows, marks
    lines = r.output.splitlines()
    head = next(line for line in lines if line.startswith("IM7/977-2"))
    assert head.split()[-1] == "S1.4"
    line = next(line for line in lines if line.startswith("E1 [GPa]"))
    assert float(line.split()[-1]) == pytest.approx(E1 / 1e9, abs=0.006)
    g13_cells = [line.split()[-1] for line in lines if line.startswith("G13 [GPa]")]
    assert g13_cells[1].endswith("!") and float(g13_cells[1][:-1]) < 0.01
    assert [line.split()[-1] for line in lines if line.startswith("status")] == ["check"] * 2
    assert ("    at_bound: E-glass/R368.G13: at its bound — not identified: stopped on the search's "
            "lower limit, G13 = 0.0001 E1") \
        in r.output
    assert "    poor_fit: the fit misses the data" in r.output
    assert "0 ok, 2 check (0 not converged), 0 failed" in r.output and r.exit_code == 0
    j = json.loads((out / "summary.json").read_text())
    assert j["counts"]["check"] == 2 and j["specimens"][0]["materials"]["IM7/977-2"]["E1"] == E1
    assert j["units"]["E1"] == "Pa" and j["units"]["nu12"] == "1"
    s21 = j["specimens"][1]
    assert [x["code"] for x in s21["reasons"]] == ["at_bound", "undetermined", "poor_fit"]
    assert s21["intervals"]["E-glass/R368"]["G13"]["at_bound"] is True
    assert s21["optimizer_status"].startswith("converged")
    back = read_summary(out / "summary.csv")
    assert back[0]["materials"]["IM7/977-2"]["E1"] == pytest.approx(E1, rel=1e-14)
    back_g13 = back[1]["intervals"]["E-glass/R368"]["G13"]
    assert back_g13["at_bound"] and back_g13["bound_side"] == "lower"
    assert back_g13["bound_limit"] == g13_limit and back_g13["profile_bound"] == g13_profile
    assert not back[1]["intervals"]["E-glass/R368"]["E1"]["at_bound"]
    assert back[1]["status"] == "check" and back[0]["result"] == str(
        out / "example1" / "S1.4.result.h5")
    # the wide table stays as an option, SI units in its headers
    wide = tmp_path / "wide"
    shutil.copytree(out, wide)
    r = run("batch", specs, "--mesh", MESH, "--out", wide, "--wide")
    with open(wide / "summary.csv", newline="") as fh:
        w = list(csv.DictReader(without_comments(fh)))
    assert float(w[0]["IM7/977-2 E1 [Pa]"]) == pytest.approx(E1, rel=1e-14)
    assert w[1]["status"] == "check" and w[1]["reasons"] == "at_bound, undetermined, poor_fit"
    # a value at its bound or not determined is a plain number in its column: the row says
    # which constants those are, as the terminal table's marks do
    assert w[1]["flagged"] == "E-glass/R368.G13 at_bound; E-glass/R368.G23 undetermined"
    assert w[0]["flagged"] == "; ".join(f"IM7/977-2.{k} undetermined" for k, iv in
                                        j["specimens"][0]["intervals"]["IM7/977-2"].items()
                                        if iv["flagged"])
    assert read_summary(wide / "summary.csv")[0]["materials"]["IM7/977-2"]["E1"] == \
        pytest.approx(E1, rel=1e-14)
    # ... and which limit, after the old columns (the wide summary did not say it: the
    # report drew both triangles)
    assert w[1]["E-glass/R368 G13 bound_side"] == "lower"
    assert all(w[1][f"E-glass/R368 {k} bound_side"] == "" for k in ("E1", "E2", "G12", "G23"))
    back_wide = read_summary(wide / "summary.csv")[1]["intervals"]["E-glass/R368"]
    assert back_wide["G13"]["bound_side"] == "lower" and back_wide["G13"]["at_bound"]
    assert back_wide["G23"]["bound_side"] == "" and not back_wide["G23"]["at_bound"]
    # ... its limit and where its profile says the fit rejects it, the long form's cells (the
    # wide one said neither: a constant the data bound read as one the modes do not determine)
    for col, key in (("bound_limit [Pa]", "bound_limit"),
                     ("profile_bound [Pa]", "profile_bound")):
        assert float(w[1][f"E-glass/R368 G13 {col}"]) == pytest.approx(float(g13[key]),
                                                                        rel=1e-12)
    assert w[1]["E-glass/R368 G13 profile"] == g13["profile"] == "bound"
    assert w[1]["E-glass/R368 G13 profile_far [Pa]"] == g13["profile_far"]
    assert back_wide["G13"]["bound_limit"] == pytest.approx(g13_limit, rel=1e-12)
    assert back_wide["G13"]["profile_bound"] == pytest.approx(g13_profile, rel=1e-12)
    assert back_wide["G13"]["profile"] == "bound"
    assert all(w[1][f"E-glass/R368 {k} {c}"] == "" for k in ("E1", "E2", "G12", "G23")
               for c in ("bound_limit [Pa]", "profile_bound [Pa]", "profile",
                         "profile_far [Pa]"))


def test_wide_summary_gives_each_value_its_interval_and_verdict(batch_run, tmp_path):
    """--wide wrote each constant's value with no interval: a "weak" value (S1.4's G12,
    about ±5 % on this mesh) read as exact, and its report had no bars. After each value
    column (names and order kept) come its 95 % interval's ends and its verdict, the long
    summary.csv's and summary.json's numbers to 1e-9 (relative), empty where there is no
    interval (at a bound); read back, they are the long summary's."""
    from laminid_cli.batch import CONSTANTS

    specs, out, _ = batch_run
    wide = tmp_path / "wide"
    shutil.copytree(out, wide)
    r = run("batch", specs, "--mesh", MESH, "--out", wide, "--wide")       # cached: same rows
    assert r.exit_code == 0, r.output
    with open(out / "summary.csv", newline="") as fh:
        long = {(row["specimen"], row["material"], row["constant"]): row
                for row in csv.DictReader(without_comments(fh))}
    doc = json.loads((out / "summary.json").read_text())
    with open(wide / "summary.csv", newline="") as fh:
        reader = csv.DictReader(without_comments(fh))
        header, w = reader.fieldnames, list(reader)
    m1, m2 = "IM7/977-2", "E-glass/R368"
    # the value columns keep their names and order; the three new ones follow each
    values = [c for c in header if c.endswith(("[Pa]", "[1]")) and " lower " not in c
              and " upper " not in c
              and not c.endswith((" bound_limit [Pa]", " profile_bound [Pa]",
                                  " profile_far [Pa]", " bound_limit [1]",
                                  " profile_bound [1]", " profile_far [1]"))]
    assert values == [f"{m} {k} [{'1' if k == 'nu12' else 'Pa'}]" for m in (m1, m2)
                      for k in CONSTANTS]
    i = header.index(f"{m1} E2 [Pa]")
    assert header[i:i + 5] == [f"{m1} E2 [Pa]", f"{m1} E2 lower [Pa]", f"{m1} E2 upper [Pa]",
                               f"{m1} E2 verdict", f"{m1} G12 [Pa]"]
    # 'flagged' ends the old columns; after it (new, so old readers find theirs in place)
    # each constant's side of a bound, its limit and its profile (the long form's bound_side,
    # bound_limit, profile_bound, profile, profile_far)
    k = header.index("flagged")
    assert header[k + 1:] == [f"{m} {c} {x}" for m in (m1, m2) for c in CONSTANTS for x in (
        "bound_side", f"bound_limit [{'1' if c == 'nu12' else 'Pa'}]",
        f"profile_bound [{'1' if c == 'nu12' else 'Pa'}]", "profile",
        f"profile_far [{'1' if c == 'nu12' else 'Pa'}]")]
    n_checked = 0
    for row, spec in zip(w, doc["specimens"]):
        m = m1 if row["name"] == "example1/S1.4" else m2
        assert row[f"{m2 if m == m1 else m1} E1 lower [Pa]"] == ""      # not its material
        for k in CONSTANTS:
            unit = "1" if k == "nu12" else "Pa"
            lc = long[spec["specimen"], m, k]
            js = spec["intervals"][m][k]
            assert row[f"{m} {k} verdict"] == lc["verdict"] == js["verdict"]
            for end in ("lower", "upper"):
                cell = row[f"{m} {k} {end} [{unit}]"]
                assert (cell == "") is (lc[end] == "") is (js[end] is None), (m, k, end)
                if cell:
                    assert float(cell) == pytest.approx(float(lc[end]), rel=1e-9)
                    assert float(cell) == pytest.approx(js[end], rel=1e-9)
                    n_checked += 1
    assert n_checked >= 20
    s14, s21 = w
    # a weak value now shows its doubt beside it
    assert s14[f"{m1} G12 verdict"] == "weak"
    g12 = float(s14[f"{m1} G12 [Pa]"])
    assert float(s14[f"{m1} G12 lower [Pa]"]) < 0.96 * g12
    assert float(s14[f"{m1} G12 upper [Pa]"]) > 1.04 * g12
    # a value at its bound has no interval, its verdict says so
    assert s21[f"{m2} G13 lower [Pa]"] == s21[f"{m2} G13 upper [Pa]"] == ""
    assert s21[f"{m2} G13 verdict"] == "at bound — not identified"
    back = read_summary(wide / "summary.csv")
    iv = back[1]["intervals"][m2]
    assert iv["G13"]["at_bound"] and iv["G13"]["lower"] is None
    assert iv["G23"]["flagged"] and iv["G23"]["verdict"].startswith("not determined")
    assert back[0]["intervals"][m1]["E1"]["lower"] == pytest.approx(
        doc["specimens"][0]["intervals"][m1]["E1"]["lower"], rel=1e-9)


def test_summary_csv_records_the_run_options_above_its_unchanged_table(tmp_path):
    """summary.csv did not say how its numbers were made (summary.json did: "options"): a CSV
    read alone could not tell a 6x6 mesh from 12x12, or whether a Monte Carlo ran. The options
    are now '#' lines above the header, the same as summary.json's; without them the file is
    byte for byte what laminid wrote before (pandas.read_csv(path, comment="#") drops exactly
    those lines), and read_summary reads both."""
    specs = make_tree(tmp_path / "specs", {"S1.4.yaml": SPECS["example1/S1.4.yaml"]})
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--monte-carlo", "3",
            "--solver", "full", "--fix", "nu12")
    assert r.exit_code == 0, r.output
    lines = (out / "summary.csv").read_text().splitlines(keepends=True)
    n = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    assert lines[n].startswith("name,specimen,material,constant,value,")
    assert lines[0].startswith("# laminid ") and "batch summary; run options" in lines[0]
    from laminid_cli.batch import CSV_BATCH_TITLE

    block = [line.rstrip("\n") for line in lines[1:n]]
    block = block[:block.index(CSV_BATCH_TITLE)]        # the batch's own settings below it
    assert '# mesh: "6x6"' in block and '# identify.solver: "full"' in block
    assert "# uncertainty.monte_carlo: 3" in block and '# fix: ["nu12"]' in block
    from laminid_cli.batch import BatchError, read_summary_options

    options = json.loads((out / "summary.json").read_text())["options"]
    assert read_summary_options(out / "summary.csv") == options
    assert len(block) == sum(len(v) if isinstance(v, dict) else 1 for v in options.values())
    # the table below is what a summary without the block (laminid before it) holds
    old = tmp_path / "old" / "summary.csv"
    old.parent.mkdir()
    old.write_text("".join(lines[n:]))
    assert read_summary(out / "summary.csv") == [
        dict(row, result=str(out / "S1.4.result.h5")) for row in read_summary(old)]
    assert read_summary(out / "summary.csv")[0]["materials"]["IM7/977-2"]["nu12"] == 0.35
    assert read_summary_options(old) is None
    # a hand-edited value that is no JSON: named, not a traceback
    (tmp_path / "edited.csv").write_text("".join(lines).replace('"6x6"', "6x6"))
    with pytest.raises(BatchError, match=r"option line '# mesh: 6x6': the value is not JSON"):
        read_summary_options(tmp_path / "edited.csv")
    # the wide summary has the same block
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--monte-carlo", "3",
            "--solver", "full", "--fix", "nu12", "--wide")
    assert r.exit_code == 0 and "1 up to date" in r.output, r.output
    assert read_summary_options(out / "summary.csv") == options
    with open(out / "summary.csv", newline="") as fh:
        wide = list(csv.DictReader(without_comments(fh)))
    assert [w["name"] for w in wide] == ["S1.4"] and float(wide[0]["IM7/977-2 nu12 [1]"]) == 0.35


def test_the_summaries_say_the_batch_processes_apart_from_uncertainty_jobs(tmp_path):
    """batch -j 2's summaries said only the options' 'uncertainty.jobs: 1' (each specimen's
    Monte Carlo trials and profiles in its worker), which read as a batch run on one process.
    They now give the batch's own settings ('batch': jobs, scheduler, what ran) and what
    uncertainty.jobs means, in summary.json and in the CSV's second '#' block; the input hash
    is unchanged by them, so a result of -j 2 stays up to date for -j 1."""
    from laminid_cli.batch import (CSV_BATCH_TITLE, read_summary_batch, read_summary_options,
                                   stored_hash)

    specs = make_tree(tmp_path / "specs", {"S1.4.yaml": SPECS["example1/S1.4.yaml"]})
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out, "-j", "2")
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "summary.json").read_text())
    assert doc["options"]["uncertainty"]["jobs"] == 2          # batch.SPECIMEN_JOBS
    assert doc["batch"]["jobs"] == 2 and doc["batch"]["scheduler"] is None
    assert doc["batch"]["runs_on"] == "up to 2 worker processes, one specimen at a time in each"
    assert doc["batch"]["uncertainty_jobs"].startswith(
        "options.uncertainty.jobs: the processes of one specimen's Monte Carlo trials")
    lines = (out / "summary.csv").read_text().splitlines()
    k = lines.index(CSV_BATCH_TITLE)
    assert "# uncertainty.jobs: 2" in lines[:k]
    assert lines[k + 1:k + 4] == ["# batch.jobs: 2", "# batch.scheduler: null",
                                  '# batch.runs_on: "up to 2 worker processes, one specimen '
                                  'at a time in each"']
    assert lines[k + 4].startswith("name,specimen,material,")
    assert read_summary_options(out / "summary.csv") == doc["options"]
    assert read_summary_batch(out / "summary.csv") == {
        key: doc["batch"][key] for key in ("jobs", "scheduler", "runs_on")}
    key = stored_hash(out / "S1.4.result.h5")
    r = run("batch", specs, "--mesh", MESH, "--out", out, "-j", "1")
    assert r.exit_code == 0 and "1 up to date, 0 to identify" in r.output, r.output
    assert stored_hash(out / "S1.4.result.h5") == key
    doc = json.loads((out / "summary.json").read_text())
    assert doc["options"]["uncertainty"]["jobs"] is None
    assert doc["batch"] == dict(doc["batch"], jobs=1, scheduler=None,
                                runs_on="this process, one specimen after the other")
    assert read_summary_batch(out / "summary.csv")["jobs"] == 1


def test_a_specimen_copied_under_another_name_is_warned_of_once_and_recorded(tmp_path):
    """Two files holding one plate's measured data (a copy under another name) were identified
    as two specimens without a word, one plate counted twice across the batch. Now a warning
    names the files, once per group, and summary.json and --json list the group; the batch
    still runs both (exit code unchanged). Only exact copies of the data: a file written in
    other units and with another name and start is one; a frequency 0.01 Hz off is none."""
    text = Path(SPECS["example1/S1.4.yaml"]).read_text()
    specs = tmp_path / "specs"
    (specs / "sub").mkdir(parents=True)
    (specs / "a.yaml").write_text(text)
    shutil.copy(specs / "a.yaml", specs / "sub" / "b.yaml")
    assert "  h: 3.09 mm\n" in text and "[137.65, " in text and "E2: 8.8 GPa" in text
    (specs / "c.yaml").write_text(text.replace("[137.65, ", "[137.66, "))      # another plate
    (specs / "d.yaml").write_text(text.replace("name: S1.4", "name: S1.4-again")
                                  .replace("  h: 3.09 mm", "  h: 0.00309 m")
                                  .replace("E2: 8.8 GPa", "E2: 9.5 GPa"))   # the same plate
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out)
    assert r.exit_code == 0, r.output
    warnings = [line for line in r.stderr.splitlines() if line.startswith("warning:")]
    assert warnings == [f"warning: specimens {specs / 'a.yaml'}, {specs / 'd.yaml'} and "
                        f"{specs / 'sub' / 'b.yaml'} hold the same measured frequencies and plate "
                        "(geometry, layup, mass): one plate counted 3 times?"]
    doc = json.loads((out / "summary.json").read_text())
    assert doc["duplicates"] == [["a", "d", "sub/b"]]
    assert [row["status"] for row in doc["specimens"]] == ["check"] * 4     # all four ran
    # two of a kind, said as a pair; -q: no warning, the summary still lists them
    (specs / "d.yaml").unlink()
    r = run("-q", "batch", specs, "--mesh", MESH, "--out", out, "--json")
    assert r.exit_code == 0 and r.stderr == "", r.stderr
    assert json.loads(r.stdout)["duplicates"] == [["a", "sub/b"]]
    r = run("batch", specs, "--mesh", MESH, "--out", out)
    assert f"warning: specimens {specs / 'a.yaml'} and {specs / 'sub' / 'b.yaml'} hold the " \
        "same measured frequencies and plate (geometry, layup, mass): one plate counted twice?\n" \
        in r.stderr
    (specs / "sub" / "b.yaml").unlink()
    run("batch", specs, "--mesh", MESH, "--out", out)
    assert json.loads((out / "summary.json").read_text())["duplicates"] == []


def test_specimens_of_one_frf_file_are_duplicates_only_with_the_same_bytes(tmp_path):
    """Specimens measured through an FRF file (measured.frf_file) are the same plate when
    their files hold the same bytes (a copied FRF file too) with the same bands: the FRF
    files are compared only there, not read for every specimen."""
    from laminid_cli.batch import duplicate_specimens, load_specimen_docs

    text = Path(SPECS["example1/S1.4.yaml"]).read_text()
    head, _ = text.split("measured:")
    for name, frf in (("a", "a.frf.h5"), ("b", "b.frf.h5"), ("c", "c.frf.h5"), ("d", "a.frf.h5")):
        (tmp_path / f"{name}.yaml").write_text(f"{head}measured:\n  frf_file: {frf}\n")
    (tmp_path / "a.frf.h5").write_bytes(b"FRF" * 100)
    (tmp_path / "b.frf.h5").write_bytes(b"FRF" * 100)                 # a copy of a's
    (tmp_path / "c.frf.h5").write_bytes(b"FRF" * 99 + b"frf")         # another measurement
    specs = [tmp_path / f"{name}.yaml" for name in "abcd"]
    assert duplicate_specimens(specs, load_specimen_docs(specs)) == [[0, 1, 3]]
    # the same file in other bands: another fit, not a copy
    specs[3].write_text(f"{head}measured:\n  frf_file: a.frf.h5\n  bands: [[100, 500]]\n")
    assert duplicate_specimens(specs, load_specimen_docs(specs)) == [[0, 1]]


def test_summaries_say_in_a_word_which_values_are_no_identified_ones(tmp_path):
    """A script reading summary.csv or summary.json had to parse the verdict's words ("at
    bound — not identified", "not determined by these modes — fix it or ...", "fixed") to
    leave out the values that are no measurement, and summary.json's fixed constants were
    {"verdict": "fixed"} alone (no 'flagged', no interval keys: iv.get("flagged") is None,
    falsy, for a value held at its initial guess). Both give each value's `flag`: at_bound,
    undetermined, fixed, or "" for an identified one; a fixed entry has a free one's keys."""
    specs = make_tree(tmp_path / "in", {"S2.1.yaml": "specimens/example2/S2.1.yaml"})
    text = Path("specimens/example1/S1.4.yaml").read_text()
    (specs / "S1.4-fixed.yaml").write_text(
        text.replace("    nu12: 0.35\n", "    nu12: 0.35\n    fixed: [G13, G23]\n", 1))
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out)
    assert r.exit_code == 0, r.output
    with open(out / "summary.csv", newline="") as fh:
        rows = {(row["specimen"], row["constant"]): row
                for row in csv.DictReader(without_comments(fh))}
    flags = {key: row["flag"] for key, row in rows.items()}
    assert flags["S1.4", "G13"] == flags["S1.4", "G23"] == "fixed"
    assert rows["S1.4", "G13"]["lower"] == rows["S1.4", "G13"]["upper"] == ""
    assert flags["S2.1", "G13"] == "at_bound" and flags["S2.1", "G23"] == "undetermined"
    # the values a script keeps with `flag == ""` are identified ones, each with its interval
    kept = [row for row in rows.values() if row["flag"] == ""]
    assert kept and all(float(row["lower"]) < float(row["value"]) < float(row["upper"])
                        and not row["verdict"].startswith(("not", "at bound", "fixed"))
                        for row in kept)
    doc = json.loads((out / "summary.json").read_text())
    keys = {"lower", "upper", "verdict", "flag", "at_bound", "bound_side", "bound_limit",
            "flagged"}
    for spec in doc["specimens"]:
        for m, per in spec["intervals"].items():
            for k, iv in per.items():
                assert keys <= set(iv), (spec["specimen"], k, iv)
                assert iv["flag"] == flags[spec["specimen"], k]
    fixed = doc["specimens"][0]["intervals"]["IM7/977-2"]["G13"]
    assert fixed | {"flag": "fixed", "verdict": "fixed", "lower": None, "upper": None,
                    "flagged": False, "at_bound": False} == fixed
    # the terminal table marks the same values
    g13 = next(line for line in r.output.splitlines() if line.startswith("G13 [GPa]"))
    assert g13.split()[-1].endswith("=")
    # the wide summary: a fixed value's interval cells empty, its verdict "fixed"
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--wide")
    assert r.exit_code == 0, r.output
    with open(out / "summary.csv", newline="") as fh:
        wide = {row["specimen"]: row for row in csv.DictReader(without_comments(fh))}
    s14 = wide["S1.4"]
    assert s14["IM7/977-2 G13 lower [Pa]"] == s14["IM7/977-2 G13 upper [Pa]"] == ""
    assert s14["IM7/977-2 G13 verdict"] == "fixed" and float(s14["IM7/977-2 G13 [Pa]"]) > 0
    assert float(s14["IM7/977-2 E1 lower [Pa]"]) == pytest.approx(
        float(rows["S1.4", "E1"]["lower"]), rel=1e-9)


def test_values_fixed_because_undetermined_are_flagged_assumed_not_fixed(tmp_path):
    """--fix-undetermined holds S1.1's G13, G23 and nu12 at their initial guesses because the
    modes do not determine them: assumptions, where a constant the file fixes is a value the
    user knows. Both were flag 'fixed' (summary.csv, summary.json), '=' in the table and
    '(fixed)' in identify's table, so a script could not keep the known ones apart. Now:
    'assumed', '#' with its legend, '(assumed: fixed because undetermined)'; the long summary
    reads back with the same flag."""
    from laminid_cli.batch import flag_word

    specs = make_tree(tmp_path / "in", {"S1.1.yaml": "specimens/example1/S1.1.yaml"})
    text = Path("specimens/example1/S1.4.yaml").read_text()
    (specs / "S1.4-fixed.yaml").write_text(
        text.replace("    nu12: 0.35\n", "    nu12: 0.35\n    fixed: [G13, G23]\n", 1))
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--fix-undetermined")
    assert r.exit_code == 0, r.output
    with open(out / "summary.csv", newline="") as fh:
        rows = {(row["specimen"], row["constant"]): row
                for row in csv.DictReader(without_comments(fh))}
    # S1.4's file fixes G13 and G23 (known values); --fix-undetermined holds S1.1's three
    assert rows["S1.4", "G13"]["flag"] == rows["S1.4", "G23"]["flag"] == "fixed"
    assert [rows["S1.1", k]["flag"] for k in ("G13", "G23", "nu12")] == ["assumed"] * 3
    assert all(rows["S1.1", k]["verdict"] == "fixed" for k in ("G13", "G23", "nu12"))
    assert rows["S1.1", "E1"]["flag"] == ""                   # identified, with its interval
    doc = json.loads((out / "summary.json").read_text())
    s11 = next(sp for sp in doc["specimens"] if sp["specimen"] == "S1.1")
    ivs = s11["intervals"]["IM7/977-2"]
    assert [ivs[k]["flag"] for k in ("G13", "G23", "nu12")] == ["assumed"] * 3
    assert ivs["G13"]["assumed"] is True and ivs["G13"]["lower"] is None
    back = {row["specimen"]: row for row in read_summary(out / "summary.csv")}
    assert flag_word(back["S1.1"]["intervals"]["IM7/977-2"]["G23"]) == "assumed"
    assert flag_word(back["S1.4"]["intervals"]["IM7/977-2"]["G23"]) == "fixed"
    # the terminal table: '#' on the assumed values, '=' on the known ones, each legend once
    g13 = next(line for line in r.output.splitlines() if line.startswith("G13 [GPa]"))
    assert sorted(c[-1] for c in g13.split()[2:]) == ["#", "="]
    assert "# assumed: fixed at its initial guess because the modes did not determine it " \
           "(--fix-undetermined)" in r.output
    assert "= fixed at its initial value — not identified (--fix or the file's 'fixed')" \
           in r.output


def test_identify_says_which_fixed_values_are_assumed(tmp_path):
    """identify's constants table: a value --fix-undetermined held reads '(assumed: fixed
    because undetermined)', one the file fixes '(fixed)'."""
    text = Path("specimens/example1/S1.1.yaml").read_text()
    spec = tmp_path / "S.yaml"
    spec.write_text(text.replace("    nu12: 0.35\n", "    nu12: 0.35\n    fixed: [nu12]\n", 1))
    r = run("identify", spec, "--mesh", MESH, "--fix-undetermined", "--no-output")
    assert r.exit_code == 0, r.output
    lines = {ln.split()[0]: ln for ln in r.output.splitlines()
             if ln.startswith(("  G13", "  G23", "  nu12"))}
    assert lines["nu12"].rstrip().endswith("(fixed)")
    assert lines["G13"].rstrip().endswith("(assumed: fixed because undetermined)")
    assert lines["G23"].rstrip().endswith("(assumed: fixed because undetermined)")


def test_a_value_held_by_its_prior_is_marked_in_the_table_and_the_summaries(tmp_path):
    """S1.2 with `prior: {nu12: 1.0}`: nu12 ends at its initial 0.350, "well determined (held
    by the prior)", and the table showed it as a plain '0.350' beside the measured values, the
    summaries as an identified value (a script averaging nu12 over the campaign took the
    prior's value for a measurement). It is marked '~' with its legend, flagged 'prior' in
    summary.csv and summary.json, and named in the wide summary's 'flagged'."""
    specs = tmp_path / "in"
    specs.mkdir()
    (specs / "S1.2-prior.yaml").write_text(Path("specimens/example1/S1.2.yaml").read_text()
                                           .replace("    nu12: 0.35\n",
                                                    "    nu12: 0.35\n    prior: {nu12: 1.0}\n",
                                                    1))
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out)
    assert r.exit_code == 0, r.output
    nu12 = next(line for line in r.output.splitlines() if line.startswith("nu12"))
    assert nu12.split()[-1] == "0.350~"
    assert ("~ held by the prior — mostly the file's prior value, not the modes' (the prior "
            "gives more than half of what is known of it, paper Eq. 15)") in r.output
    with open(out / "summary.csv", newline="") as fh:
        rows = {row["constant"]: row for row in csv.DictReader(without_comments(fh))}
    assert rows["nu12"]["verdict"] == "well determined (held by the prior)"
    assert rows["nu12"]["flag"] == "prior" and rows["E1"]["flag"] == ""
    doc = json.loads((out / "summary.json").read_text())
    assert doc["specimens"][0]["intervals"]["IM7/977-2"]["nu12"]["flag"] == "prior"
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--wide")
    assert r.exit_code == 0, r.output
    with open(out / "summary.csv", newline="") as fh:
        wide = next(csv.DictReader(without_comments(fh)))
    assert "IM7/977-2.nu12 prior" in wide["flagged"].split("; ")


def test_summary_carries_the_monte_carlo_range_and_its_search_limit_ends(tmp_path):
    """S1.1 (12x12, --monte-carlo 40, seed 0): the long CSV's mc_lower/mc_upper are the result
    file's /uncertainty/monte_carlo range, and mc_search_limit names the ends the file flags
    as set by trials on a limit of the search (here G23's lower end: trials at G23 = 1e-4
    E1); summary.json and read_summary say the same."""
    specs = make_tree(tmp_path / "in", {"S1.1.yaml": "specimens/example1/S1.1.yaml"})
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", "12x12", "--monte-carlo", "40", "--out", out)
    assert r.exit_code == 0, r.output
    with open(out / "summary.csv", newline="") as fh:
        by = {row["constant"]: row for row in csv.DictReader(without_comments(fh))}
    with h5py.File(out / "S1.1.result.h5") as f:
        u = f["uncertainty"]
        labels = [x.decode().rsplit(".", 1)[1] for x in u["labels"][()]]
        mc = {k: u["monte_carlo"][k][()] for k in ("lower", "upper", "lower_at_bound",
                                                   "upper_at_bound")}
    assert labels == ["E1", "E2", "G12", "G13", "G23", "nu12"]
    for j, k in enumerate(labels):
        assert float(by[k]["mc_lower"]) == pytest.approx(mc["lower"][j], rel=1e-14)
        assert float(by[k]["mc_upper"]) == pytest.approx(mc["upper"][j], rel=1e-14)
        ends = [s for s in ("lower", "upper") if mc[f"{s}_at_bound"][j]]
        assert by[k]["mc_search_limit"] == ("both" if len(ends) == 2 else "".join(ends)), k
    assert by["G23"]["mc_search_limit"] == "lower"
    assert float(by["G23"]["mc_lower"]) == pytest.approx(1e-4 * float(by["E1"]["value"]),
                                                         rel=0.02)
    assert [k for k in labels if by[k]["mc_search_limit"]] == ["G23"]
    j = json.loads((out / "summary.json").read_text())
    g23 = j["specimens"][0]["intervals"]["IM7/977-2"]["G23"]
    assert g23["mc_lower_at_limit"] is True and g23["mc_upper_at_limit"] is False
    assert j["units"]["mc_lower"] == "unit of the constant"
    back = read_summary(out / "summary.csv")[0]["intervals"]["IM7/977-2"]
    assert back["G23"]["mc_lower_at_limit"] and not back["E1"]["mc_lower_at_limit"]
    assert back["E1"]["mc_upper"] == pytest.approx(mc["upper"][0], rel=1e-14)


def test_rerun_skips_unchanged_redoes_changed_and_forced(batch_run, tmp_path):
    specs, out, _ = batch_run
    work = tmp_path / "out"
    shutil.copytree(out, work)
    mtimes = {p: p.stat().st_mtime_ns for p in work.rglob("*.h5")}
    r = run("batch", specs, "--mesh", MESH, "--out", work, "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["n_cached"] == 2 and all(s["cached"] for s in d["specimens"])
    assert {p: p.stat().st_mtime_ns for p in work.rglob("*.h5")} == mtimes
    # other options: a different hash, so everything is redone
    assert json.loads(run("batch", specs, "--mesh", "5x5", "--out", tmp_path / "o2",
                          "--json").stdout)["n_cached"] == 0
    # a changed specimen file is redone, the other kept
    changed = tmp_path / "specs"
    shutil.copytree(specs, changed)
    with open(changed / "example2" / "S2.1.yaml", "a") as fh:
        fh.write("# re-measured\n")
    r = run("batch", changed, "--mesh", MESH, "--out", work, "--json")
    d = {s["name"]: s for s in json.loads(r.stdout)["specimens"]}
    assert d["example1/S1.4"]["cached"] and not d["example2/S2.1"]["cached"]
    r = run("batch", changed, "--mesh", MESH, "--out", work, "--json", "--force")
    assert json.loads(r.stdout)["n_cached"] == 0 and r.exit_code == 0


def test_failing_specimens_are_listed_and_the_others_go_on(tmp_path):
    specs = make_tree(tmp_path / "in", {"good/S2.1.yaml": SPECS["example2/S2.1.yaml"]})
    (specs / "bad.yaml").write_text("geometry: [1\n")
    text = Path(SPECS["example2/S2.1.yaml"]).read_text()
    (specs / "far.yaml").write_text(text.replace("mass: 0.2571 kg", "mass: 2.571 kg"))
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out", "-j", "2")
    assert r.exit_code == 1, r.output
    assert "bad: error:" in r.output and "not valid YAML" in r.output
    assert "far: error:" in r.output and "away from the model" in r.output
    assert "0 ok, 1 check (0 not converged), 2 failed" in r.output
    rows = {row["name"]: row for row in read_summary(tmp_path / "out" / "summary.csv")}
    assert rows["good/S2.1"]["status"] == "check" and rows["bad"]["status"] == "error"
    assert "not valid YAML" in rows["bad"]["reason"]
    assert sorted(p.name for p in (tmp_path / "out").rglob("*.h5")) == ["S2.1.result.h5"]
    # no convergence: the file is written (as by identify), status and reason in the summary
    r = run("batch", specs / "good", "--mesh", MESH, "--out", tmp_path / "nc",
            "--max-evaluations", "3", "--json")
    assert r.exit_code == 1
    row = json.loads(r.stdout)["specimens"][0]
    assert row["status"] == "check" and row["converged"] is False
    assert row["reasons"][0]["code"] == "not_converged"
    assert "evaluations ran out" in row["reasons"][0]["text"]
    assert "evaluations ran out" in row["optimizer_status"]
    with h5py.File(row["result"]) as f:                 # the values of the file written
        assert row["materials"]["E-glass/R368"]["E1"] == f["materials"]["E-glass_R368"]["E1"][()]
        assert not f.attrs["converged"] and f.attrs["evaluations"] == row["evaluations"]


def test_usage_errors_exit_2(tmp_path):
    r = run("batch", tmp_path)
    assert r.exit_code == 2 and "no specimen file (*.yaml, *.yml) found" in r.output
    r = run("batch", SPECS["example2/S2.1.yaml"], "--mesh", "0x3", "--out", tmp_path / "o")
    assert r.exit_code == 2 and "mesh '0x3' is degenerate" in r.output
    assert not (tmp_path / "o").exists()
    r = run("batch", tmp_path / "missing")
    assert r.exit_code == 2 and "missing: no such file or folder" in r.output
    (tmp_path / "file").write_text("x")
    r = run("batch", SPECS["example2/S2.1.yaml"], "--out", tmp_path / "file")
    assert r.exit_code == 2


def _hdf5_with_format(path: Path, fmt: str) -> Path:
    """An HDF5 file whose root attribute ``format`` is ``fmt`` (what batch looks at)."""
    with h5py.File(path, "w") as f:
        f.attrs["format"] = fmt
        f.attrs["schema_version"] = 2
    return path


def test_an_out_that_is_a_link_to_nothing_is_named_as_such(tmp_path):
    """--out a dangling symbolic link was refused as 'cannot create the folder (File exists)'."""
    (tmp_path / "res").symlink_to(tmp_path / "gone")
    r = run("batch", SPECS["example2/S2.1.yaml"], "--mesh", MESH, "--out", tmp_path / "res")
    assert r.exit_code == 2, r.output
    assert (f"--out {tmp_path / 'res'}: a symbolic link to {tmp_path / 'gone'}, which does not "
            "exist") in r.output
    assert not (tmp_path / "gone").exists()


def test_a_result_frf_or_modes_file_named_as_an_input_is_refused_before_anything_runs(tmp_path):
    """A result file among the files given (laminid batch plates/* with results beside the
    specimens) ran as a specimen and failed as one ("is an HDF5 file (an FRF or result
    file?)", exit 1, a row 'S1.result: error' in the summaries). Now refused at once (exit 2,
    --out not created), naming each file, what it is (its HDF5 'format', whatever its name),
    what takes it and what batch takes."""
    from laminid_cli.frf.store import write_frf_h5

    shutil.copy(SPECS["example2/S2.1.yaml"], tmp_path / "S2.1.yaml")
    result = _hdf5_with_format(tmp_path / "plate.h5", "laminid-result")   # any name
    out = tmp_path / "out"
    r = run("batch", tmp_path / "S2.1.yaml", result, "--mesh", MESH, "--out", out)
    assert r.exit_code == 2, r.output
    assert r.stderr == (
        f"laminid: error: {result}: a laminid identification result (of laminid identify or "
        f"batch), not a specimen file (YAML text); 'laminid show {result}' prints it, "
        f"'laminid report {result}' draws it; batch identifies specimen files (YAML text), "
        "named or found in folders (*.yaml, *.yml): leave it out of the inputs\n")
    assert not out.exists()
    frf = write_frf_h5(tmp_path / "plate.frf.h5", np.linspace(0, 100, 11),
                       np.ones((1, 11), complex), units="Pa/N")
    modes = _hdf5_with_format(tmp_path / "plate-modes.h5", "laminid-modes")
    joint = _hdf5_with_format(tmp_path / "a+b.joint.result.h5", "laminid-joint-result")
    (tmp_path / "notes.pdf").write_bytes(b"%PDF-1.7 ...")
    r = run("batch", *sorted(tmp_path.iterdir()), "--mesh", MESH, "--out", out)
    assert r.exit_code == 2, r.output
    lines = r.stderr.splitlines()
    assert lines[0] == (
        "laminid: error: 5 of the inputs are not specimen files; batch identifies specimen "
        "files (YAML text), named or found in folders (*.yaml, *.yml): leave them out of the "
        "inputs (a folder given is searched for *.yaml, *.yml only: laminid batch FOLDER)")
    assert lines[1:] == [
        f"  {joint}: a laminid joint identification result (of laminid identify --joint), "
        f"not a specimen file (YAML text); 'laminid show {joint}' prints it, 'laminid report "
        f"{joint}' draws it",
        f"  {tmp_path / 'notes.pdf'}: a PDF document, not a specimen file (YAML text)",
        f"  {result}: a laminid identification result (of laminid identify or batch), not a "
        f"specimen file (YAML text); 'laminid show {result}' prints it, 'laminid report "
        f"{result}' draws it",
        f"  {modes}: a file of 'laminid modes' (a model's modes at a specimen's initial "
        f"constants), not a specimen file (YAML text); 'laminid export {modes} -o modes.unv' "
        "writes its mode shapes",
        f"  {frf}: an FRF file (of laminid acquire), not a specimen file (YAML text); 'laminid "
        f"fit-frf {frf} --into SPEC.yaml' writes its modes into a specimen (or name it in the "
        "specimen's measured.frf_file), which identify and batch fit"]
    assert not out.exists() and "Traceback" not in r.output


def test_a_batch_summary_named_as_an_input_is_refused_before_anything_runs(tmp_path):
    """README: --out may be the specimens' own folder; 'laminid batch plates/*' after that
    named its summary.csv and summary.json, which ran as specimens and failed ("unknown key
    'format'"; the CSV's whole text echoed as one YAML line), exit 1. Now refused with the
    results (exit 2), naming each as a batch summary and what draws it; --wide and a CSV
    written before the options block (its header first) too."""
    from laminid_cli.specimen import is_batch_summary

    specs = make_tree(tmp_path / "plates", {"S2.1.yaml": SPECS["example2/S2.1.yaml"]})
    r = run("batch", specs, "--mesh", MESH, "--out", specs)
    assert r.exit_code == 0, r.output
    out = tmp_path / "out"
    r = run("batch", *sorted(specs.iterdir()), "--mesh", MESH, "--out", out)
    assert r.exit_code == 2, r.output
    lines = r.stderr.splitlines()
    assert lines[0].startswith("laminid: error: 3 of the inputs are not specimen files; ")
    assert lines[2:] == [
        f"  {specs / name}: a laminid batch summary, not a specimen file (YAML text); "
        f"'laminid report {specs / name}' draws it" for name in ("summary.csv", "summary.json")]
    assert not out.exists() and "Traceback" not in r.output
    table = (specs / "summary.csv").read_text()
    old = table[table.index("\nname,specimen,") + 1:]
    assert is_batch_summary(table.encode()[:512]) and is_batch_summary(old.encode()[:512])
    r = run("batch", specs / "S2.1.yaml", "--mesh", MESH, "--out", specs, "--wide")
    assert r.exit_code == 0, r.output
    assert is_batch_summary((specs / "summary.csv").read_bytes()[:512])
    assert not is_batch_summary(Path(SPECS["example2/S2.1.yaml"]).read_bytes()[:512])
    assert not is_batch_summary(b'{"name": "S2.1", "format": "laminid-batch-summary"}')


def test_a_yaml_file_in_a_folder_that_is_no_specimen_is_skipped_with_a_warning(tmp_path):
    """A folder searched for *.yaml holding a result file under that name, and a damaged
    HDF5 file: each skipped with a warning naming it and what it is; the specimens run, and
    the summaries have no row for them (they had an 'error' row each, exit 1)."""
    specs = make_tree(tmp_path / "in", {"S2.1.yaml": SPECS["example2/S2.1.yaml"]})
    _hdf5_with_format(specs / "old.yaml", "laminid-result")
    (specs / "broken.yml").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 40)
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert (f"warning: {specs / 'old.yaml'}: a laminid identification result (of laminid "
            f"identify or batch), not a specimen file (YAML text); 'laminid show "
            f"{specs / 'old.yaml'}' prints it, 'laminid report {specs / 'old.yaml'}' draws "
            "it; skipped\n") in r.stderr
    assert f"warning: {specs / 'broken.yml'}: a damaged HDF5 file (" in r.stderr
    assert "not a specimen file (YAML text); skipped" in r.stderr
    assert "1 specimen, 0 up to date, 1 to identify" in r.stderr
    assert [row["name"] for row in read_summary(tmp_path / "out" / "summary.csv")] == ["S2.1"]
    assert "0 ok, 1 check (0 not converged), 0 failed" in r.stdout
    r = run("-q", "batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert r.exit_code == 0 and r.stderr == ""                   # -q: only errors


@pytest.mark.parametrize("fix, words", [
    ("eta13=0.01,eta13=0.02", "--fix eta13=0.02: eta13 is already fixed at 0.01"),
    ("eta13=-1", "--fix eta13=-1: eta13 must be between 0 and 1"),
    ("E7", "--fix E7: 'E7' is not a constant"),
    ("G13=3e9", "--fix G13=3e9: an elastic constant is fixed at its initial value"),
    # a material no specimen of the batch has (S2.1's is E-glass/R368): a mistyped name
    ("IM7.nu12", "--fix IM7.nu12: no specimen of the batch has a material 'IM7' "
                 "(materials: E-glass/R368)"),
    ("E-glass.eta13=0.01", "--fix E-glass.eta13=0.01: no specimen of the batch has a "
                           "material 'E-glass'"),
])
def test_a_bad_fix_is_a_usage_error_before_any_specimen(tmp_path, fix, words):
    """A --fix that is wrong whatever the specimen (name, value, a loss factor given two
    values) is refused at once (exit 2): it made every specimen 'failed' (exit 1) and set each
    earlier result aside as 'of another input'."""
    out = tmp_path / "o"
    out.mkdir()
    earlier = out / "S2.1.result.h5"
    earlier.write_bytes(b"an earlier result")
    r = run("batch", SPECS["example2/S2.1.yaml"], "--mesh", MESH, "--out", out, "--fix", fix)
    assert r.exit_code == 2, r.output
    assert words in r.output, r.output
    assert sorted(p.name for p in out.iterdir()) == ["S2.1.result.h5"]
    assert earlier.read_bytes() == b"an earlier result"


def test_names_are_relative_to_the_common_root_and_never_collide(tmp_path):
    for sub in ("labA", "labB/deep"):
        (tmp_path / sub).mkdir(parents=True)
        (tmp_path / sub / "p1.yaml").write_text("x")
    (tmp_path / "labA" / ".hidden").mkdir()
    (tmp_path / "labA" / ".hidden" / "p2.yaml").write_text("x")
    (tmp_path / "labA" / "notes.txt").write_text("x")
    found = discover_specimens([tmp_path / "labA", tmp_path / "labB"])
    assert [n for _, n in found] == ["labA/p1", "labB/deep/p1"]
    found = discover_specimens([tmp_path / "labB"])
    assert [n for _, n in found] == ["deep/p1"]
    found = discover_specimens([tmp_path / "labA" / "p1.yaml", tmp_path / "labB" / "deep" / "p1.yaml"])
    assert [n for _, n in found] == ["labA/p1", "labB/deep/p1"]


def test_hash_covers_the_specimen_its_frf_file_and_the_options(tmp_path):
    spec = tmp_path / "p.yaml"
    spec.write_text("measured:\n  frf_file: p.frf.h5\n")
    (tmp_path / "p.frf.h5").write_bytes(b"one")
    o = BatchOptions(mesh="6x6")
    h1 = input_hash(spec, o)
    assert input_hash(spec, o) == h1 and len(h1) == 64
    assert input_hash(spec, BatchOptions(mesh="8x8")) != h1
    (tmp_path / "p.frf.h5").write_bytes(b"two")
    h2 = input_hash(spec, o)
    assert h2 != h1
    spec.write_text("measured:\n  frf_file: p.frf.h5\n# note\n")
    assert input_hash(spec, o) not in (h1, h2)


@pytest.mark.parametrize("n_jobs, expected", [("1", None), ("2", 2), ("3", 2)])
def test_one_process_gives_a_specimens_profiles_and_trials_the_cores(tmp_path, monkeypatch,
                                                                      n_jobs, expected):
    """batch -j 1 identifies in its own process, one specimen at a time: the specimen's
    profiles and Monte Carlo trials get the cores (jobs None), as in identify; with a pool of
    workers, two processes each (batch.SPECIMEN_JOBS: the cores that workers out of specimens
    leave). The result's input hash is the same either way (the processes do not change a
    result; hashed as the 1 every batch gave them before)."""
    from laminid_cli import batch as B
    from laminid_cli.pipeline import RunOptions

    seen = []

    def capture(jobs, options, n_jobs=1, scheduler=None):
        seen.append(options)
        yield from ()

    monkeypatch.setattr(B, "run_jobs", capture)
    r = run("batch", SPECS["example2/S2.1.yaml"], "--mesh", MESH, "--out", tmp_path / "o",
            "-j", n_jobs)
    assert "1 to identify" in r.output        # (and nothing done: exit 1, one not run)
    assert [o.uncertainty.jobs for o in seen] == [expected]
    spec = SPECS["example2/S2.1.yaml"]
    o = seen[0]
    one = dataclasses.replace(o, uncertainty=dataclasses.replace(o.uncertainty, jobs=1))
    assert input_hash(spec, o) == input_hash(spec, one) == input_hash(spec, RunOptions(
        mesh=MESH, uncertainty=one.uncertainty, identify=one.identify))


def test_a_specimens_trials_run_in_processes_of_a_batch_worker_as_in_identify(tmp_path):
    """batch -j 2 gives each specimen's Monte Carlo trials two processes of their own, started
    by the batch's worker process (a daemonic worker could start none: every specimen would
    fail): S1.4 and S2.1 with 4 trials each end 'ok'/'check', their Monte Carlo ranges in the
    result files (the trials' samples, their ranges) byte for byte those of identify
    --monte-carlo 4 in one process (-j 1); the files say 2 and 1 processes."""
    specs = make_tree(tmp_path / "specs")
    out = tmp_path / "out"
    r = run("batch", specs, "--mesh", MESH, "--out", out, "-j", "2", "--monte-carlo", "4")
    assert r.exit_code in (0, 1), r.output
    doc = json.loads((out / "summary.json").read_text())
    assert doc["counts"]["error"] == doc["counts"]["not run"] == 0, r.output
    for rel in SPECS:
        single = tmp_path / (Path(rel).stem + ".h5")
        s = run("identify", specs / rel, "--mesh", MESH, "--monte-carlo", "4", "-j", "1",
                "-o", single)
        assert s.exit_code in (0, 1), s.output
        with h5py.File(out / rel.replace(".yaml", ".result.h5")) as a, h5py.File(single) as b:
            ma, mb = a["uncertainty/monte_carlo"], b["uncertainty/monte_carlo"]
            assert ma["samples"][()].tobytes() == mb["samples"][()].tobytes(), rel
            assert ma["lower"][()].tobytes() == mb["lower"][()].tobytes(), rel
            assert ma["upper"][()].tobytes() == mb["upper"][()].tobytes(), rel
            assert int(ma.attrs["converged"]) == int(ma.attrs["trials"]) >= 4
            assert (int(ma.attrs["jobs"]), int(mb.attrs["jobs"])) == (2, 1)


def test_a_summary_row_reads_its_result_file_once(batch_run, monkeypatch):
    """The row comes from the typed reader alone (laminid_cli.resultfile), one open."""
    from laminid_cli.batch import Job, result_row

    specs, out, _ = batch_run
    path = out / "example2" / "S2.1.result.h5"
    real, opened = h5py.File, []

    def counting(name, *args, **kw):
        opened.append(str(name))
        return real(name, *args, **kw)

    monkeypatch.setattr(h5py, "File", counting)
    job = Job(spec=str(specs / "example2" / "S2.1.yaml"), name="example2/S2.1",
              output=str(path), key="")
    row = result_row(job, cached=True)
    assert opened == [str(path)]
    # the numbers: those of the file, read here with h5py directly
    with real(path, "r") as f:
        g = f["materials"]["E-glass_R368"]
        u = f["uncertainty"]
        labels = [x.decode() for x in u["labels"][()]]
        flagged = u.attrs["flagged"].split(",")
        codes = [x.decode() for x in f["status"]["codes"][()]]
        assert row["materials"]["E-glass/R368"] == {k: g[k][()] for k in
                                                    ("E1", "E2", "G12", "G13", "G23", "nu12")}
        assert row["evaluations"] == f.attrs["evaluations"] and row["time_s"] == f.attrs["time_s"]
        assert row["rms_residual_percent"] == f["frequencies"].attrs["rms_residual_percent"]
        assert row["status"] == f.attrs["status"] == "check" and row["reason"] == ", ".join(codes)
        for k, lab in enumerate(labels):
            iv = row["intervals"]["E-glass/R368"][lab.rsplit(".", 1)[1]]
            assert iv["verdict"] == u["verdict"][k].decode()
            assert iv["at_bound"] == bool(u["at_bound"][k])
            assert iv["bound_side"] == u["bound_side"][k].decode()
            assert np.array_equal(iv["bound_limit"], u["bound_limit"][k], equal_nan=True)
            assert iv["flagged"] == (lab in flagged)             # as the assessment flagged it
            assert np.array_equal([iv["lower"], iv["upper"]], [u["lower"][k], u["upper"][k]],
                                  equal_nan=True)
    assert row["specimen"] == "S2.1" and row["converged"] is True and row["cached"]
    assert row["intervals"]["E-glass/R368"]["G13"]["flagged"]          # at its bound
    assert row["result"] == str(path) and row["damping"] == {}


def test_a_pool_worker_writes_its_file_and_sends_back_one_small_message(tmp_path):
    """Only a few hundred bytes go through the pool's pipe, so that a worker stopped by
    Ctrl-C cannot leave half a message there (the pool's reader would wait for the rest
    forever: seen as a batch hanging at exit). POSIX writes up to 4096 bytes to a pipe in one
    piece; the pool adds its own envelope (work id, pickling) to the Outcome."""
    import pickle

    from laminid_cli.batch import MAX_REASON_CHARS, Job, run_job

    out = tmp_path / "out" / "deep" / "S1.4.result.h5"
    job = Job(spec=SPECS["example1/S1.4.yaml"], name="deep/S1.4", output=str(out), key="k")
    outcome = run_job(job, BatchOptions(mesh=MESH), write=True)
    assert outcome.status == "check" and outcome.data is None
    with h5py.File(out, "r") as f:                     # complete, with the batch attributes
        assert f.attrs["batch_input_sha256"] == "k" and f.attrs["batch_name"] == "deep/S1.4"
    assert not [p for p in out.parent.iterdir() if ".tmp-" in p.name]
    assert len(pickle.dumps(outcome)) < 1024
    # a failure whose message is longer than the limit (the path is in it) is shortened
    long_spec = tmp_path.joinpath(*["x" * 200] * 12, "missing.yaml")
    bad = run_job(Job(spec=str(long_spec), name="missing", output=str(tmp_path / "m.h5"),
                      key="k"), BatchOptions(mesh=MESH), write=True)
    assert bad.status == "error" and len(bad.reason) == MAX_REASON_CHARS
    assert bad.reason.endswith("\u2026") and len(pickle.dumps(bad)) < 3000
    full = run_job(Job(spec=str(long_spec), name="missing", output=str(tmp_path / "m.h5"),
                       key="k"), BatchOptions(mesh=MESH))
    assert len(full.reason) > MAX_REASON_CHARS and full.reason.startswith(bad.reason[:-1])


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_temporaries_of_dead_processes_are_removed_even_unreaped(tmp_path):
    """A worker killed with its batch leaves its temporary file; until some init reaps it
    the dead worker is a zombie, which os.kill(pid, 0) still finds: it must count as dead."""
    from laminid_cli.batch import remove_stale_parts

    zombie = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.time() + 30
    while time.time() < deadline and \
            Path(f"/proc/{zombie.pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
        time.sleep(0.05)                                        # exited, not reaped
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "a").mkdir()
        dead_part = tmp_path / "a" / f".x.result.h5.tmp-{zombie.pid}"
        live_part = tmp_path / "a" / f".y.result.h5.tmp-{live.pid}"
        dead_part.write_bytes(b"partial")
        live_part.write_bytes(b"being written")
        assert remove_stale_parts(tmp_path) == 1
        assert not dead_part.exists() and live_part.exists()
    finally:
        live.kill()
        live.wait()
        zombie.wait()


def _hash_of_the_earlier_option_layout(spec, mesh):
    """input_hash as laminid hashed it before the options were RunOptions (a flat dict)."""
    import hashlib

    from laminid_cli import __version__
    from laminid_cli.results import SCHEMA_VERSION

    flat = {"mesh": mesh, "fix": [], "optimizer": "slsqp", "parametrization": "auto",
            "xtol": 1e-6, "ftol": 1e-8, "max_evaluations": 300, "pairing": "track",
            "solver": "reduced", "sigma_rel": 0.002, "covariance_scale": "larger",
            "max_rel_interval": 0.3, "fix_undetermined": False, "monte_carlo": 0, "seed": 0}
    h = hashlib.sha256()
    h.update(f"laminid {__version__} schema {SCHEMA_VERSION}\0".encode())
    h.update(json.dumps(flat, sort_keys=True).encode() + b"\0")
    h.update(Path(spec).read_bytes())
    return h.hexdigest()


def test_results_hashed_by_the_earlier_option_layout_are_redone(tmp_path):
    from laminid_cli.batch import plan_batch, result_path

    specs = make_tree(tmp_path / "in", {"example2/S2.1.yaml": SPECS["example2/S2.1.yaml"]})
    found = discover_specimens([specs])
    (spec, name), = found
    options = BatchOptions(mesh=MESH)
    out = tmp_path / "out"
    result = result_path(out, name)
    result.parent.mkdir(parents=True)
    for stored, up_to_date in ((_hash_of_the_earlier_option_layout(spec, MESH), False),
                               (input_hash(spec, options), True)):
        with h5py.File(result, "w") as f:
            f.attrs["batch_input_sha256"] = stored
        assert [j.up_to_date for j in plan_batch(found, out, options)] == [up_to_date]


def test_a_noted_ctrl_c_stops_the_pool_run_even_when_its_exception_was_swallowed(
        tmp_path, monkeypatch):
    """run_jobs with a process pool notes SIGINT (batch._note_sigint) and looks at the note at
    least every SIGINT_POLL s: a Ctrl-C whose KeyboardInterrupt Python swallowed (raised inside
    a weakref callback it only printed "Exception ignored"; seen once in the killed-batch test
    below, where the batch then finished and exited 0) still ends the run, before the jobs
    finish. And the handler itself: a SIGINT raises KeyboardInterrupt and is noted, and the
    previous handler is back after restore()."""
    import threading

    import laminid_cli.batch as B

    previous = signal.getsignal(signal.SIGINT)
    if previous is signal.SIG_IGN:                     # a background test run: as a terminal
        monkeypatch.setattr(signal, "getsignal", lambda s: signal.default_int_handler)
    seen, restore = B._note_sigint()
    try:
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
        assert seen == [signal.SIGINT]
    finally:
        restore()
    # the pool's run only notes it (raised at once, it could land in Python's own clean-up:
    # "Exception ignored in ... KeyboardInterrupt" printed after "laminid: interrupted")
    seen, restore = B._note_sigint(raise_=False)
    try:
        signal.raise_signal(signal.SIGINT)
        assert seen == [signal.SIGINT]
    finally:
        restore()
    monkeypatch.undo()
    assert signal.getsignal(signal.SIGINT) is previous

    note: list = []
    monkeypatch.setattr(B, "_note_sigint", lambda raise_=True: (note, lambda: None))
    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    jobs = B.plan_batch(discover_specimens([specs]), tmp_path / "out",
                        BatchOptions(mesh="12x12"))
    threading.Timer(0.3, note.append, (signal.SIGINT,)).start()   # noted, nothing raised
    t0, done = time.time(), 0
    with pytest.raises(KeyboardInterrupt):
        for _job, _outcome in B.run_jobs(jobs, BatchOptions(mesh="12x12"), n_jobs=2):
            done += 1
    assert done < len(jobs) and time.time() - t0 < 5      # (as the killed-batch test)


@pytest.fixture
def ctrl_c():
    """SIGINT raises KeyboardInterrupt in the test, as in a terminal (a test run started as a
    background job has it ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("twice", [False, True])
def test_an_interrupted_pool_run_is_shut_down_before_the_interrupt_leaves_it(
        tmp_path, monkeypatch, ctrl_c, twice):
    """Ctrl-C during a pool run: when run_jobs lets the KeyboardInterrupt out, no thread of the
    pool runs any more and its semaphores are released, also when a second Ctrl-C comes while
    the pool shuts down (``twice``; `timeout -s INT` at times delivers two). The pool's manager
    thread, left running, released them while the batch process ran its exit handlers and
    os._exit, and a semaphore unlinked but not yet unregistered then made the resource tracker
    print "1 leaked semaphore objects" and "[Errno 2] No such file or directory" after
    "laminid: interrupted" (about 1 interrupted batch in 25; here the thread is still there
    every time). Nothing is printed as "Exception ignored" (an interrupt raised in the
    generator's close)."""
    import concurrent.futures
    import multiprocessing.synchronize
    import multiprocessing.util
    import threading

    import laminid_cli.batch as B

    if twice:
        shutdown = concurrent.futures.ProcessPoolExecutor.shutdown

        def interrupted_shutdown(self, *args, **kwargs):
            signal.raise_signal(signal.SIGINT)
            return shutdown(self, *args, **kwargs)

        monkeypatch.setattr(concurrent.futures.ProcessPoolExecutor, "shutdown",
                            interrupted_shutdown)
    unraisable: list = []
    monkeypatch.setattr(sys, "unraisablehook", unraisable.append)
    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    options = BatchOptions(mesh=MESH)
    jobs = B.plan_batch(discover_specimens([specs]), tmp_path / "out", options)
    threads = set(threading.enumerate())
    finalizers = set(multiprocessing.util._finalizer_registry)
    done = 0
    with pytest.raises(KeyboardInterrupt):
        for _job, _outcome in B.run_jobs(jobs, options, n_jobs=2):
            done += 1
            signal.raise_signal(signal.SIGINT)             # Ctrl-C after the first result
    assert done == 1
    assert [t for t in threading.enumerate() if t not in threads] == []
    semaphores = [f for key, f in multiprocessing.util._finalizer_registry.items()
                  if key not in finalizers
                  and getattr(f, "_callback", None) is multiprocessing.synchronize.SemLock._cleanup]
    assert semaphores == []
    assert unraisable == []
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def _ignore_sigterm(ready):
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    ready.set()
    time.sleep(60)


@pytest.mark.skipif(sys.platform != "linux", reason="fork start method")
def test_a_worker_that_ignores_sigterm_is_killed_after_the_grace_time(monkeypatch):
    """batch._stop_workers: a worker still there STOP_GRACE_S after SIGTERM (inside a long
    compiled call, Python runs no signal handler) is killed, so that the pool's shutdown after
    a Ctrl-C, which waits for the workers, stays short."""
    import multiprocessing

    import laminid_cli.batch as B

    monkeypatch.setattr(B, "STOP_GRACE_S", 0.3)
    ctx = multiprocessing.get_context("fork")
    ready = ctx.Event()
    proc = ctx.Process(target=_ignore_sigterm, args=(ready,))
    proc.start()
    assert ready.wait(30)
    t0 = time.monotonic()
    B._stop_workers([proc])
    proc.join(10)
    assert proc.exitcode == -signal.SIGKILL
    assert 0.3 <= time.monotonic() - t0 < 5


def _interactive_sigint():
    """In the child: Ctrl-C as in a terminal. A test run started as a background job has
    SIGINT ignored, which its children inherit (and the batch then rightly ignores it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_batch(specs, out, jobs, *extra):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen([sys.executable, "-m", "laminid_cli", "batch", str(specs), "--mesh",
                             MESH, "--out", str(out), "-j", jobs, *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, env=env, cwd=os.getcwd(),
                            preexec_fn=_interactive_sigint)


def _wait_first_result(proc, out, timeout=120):
    t0 = time.time()
    while time.time() - t0 < timeout:
        if list(out.rglob("*.h5")):
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    pytest.fail("no result appeared")


def _pool_workers(pid: int) -> list[int]:
    """The batch ``pid``'s pool workers: the children of its forkserver (Linux /proc)."""
    def children(parent):
        found = []
        for entry in Path("/proc").iterdir():
            if entry.name.isdigit():
                try:
                    stat = (entry / "stat").read_text()
                    cmd = (entry / "cmdline").read_bytes()
                except OSError:
                    continue
                if int(stat.rsplit(")", 1)[1].split()[1]) == parent:
                    found.append((int(entry.name), cmd))
        return found

    servers = [c for c, cmd in children(pid) if b"forkserver" in cmd]
    return [c for s in servers for c, _ in children(s)]


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_killed_worker_fails_no_specimen_that_runs_again_alone(tmp_path):
    """One worker of -j 2 killed (the OOM killer): the pool broke and every specimen not
    finished then was 'failed' ('worker failed: BrokenProcessPool ...', exit 1), none of them
    at fault. They run again, each alone in a new worker: all identified, exit 0."""
    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    out = tmp_path / "out"
    proc = _start_batch(specs, out, "2")
    _wait_first_result(proc, out)
    workers = _pool_workers(proc.pid)
    assert workers and proc.poll() is None
    os.kill(workers[0], signal.SIGKILL)
    _o, _e = proc.communicate(timeout=120)
    assert proc.returncode == 0, _o.decode()[-2000:] + _e.decode()[-2000:]
    rows = read_summary(out / "summary.csv")
    assert {r["name"] for r in rows} == {"example1/S1.1", "example1/S1.2", "example1/S1.4",
                                         "example2/S2.1"}
    assert {r["status"] for r in rows} <= {"ok", "check"}


@pytest.mark.parametrize("sig, jobs", [(signal.SIGKILL, "2"), (signal.SIGINT, "2"),
                                       (signal.SIGINT, "1")])
def test_killed_batch_leaves_only_complete_files_and_a_rerun_finishes(tmp_path, sig, jobs):
    # four specimens: after the first result there is work left for several seconds even when
    # this (loaded) test process is slow to send the signal; a signal that came after the
    # batch had finished would test nothing (and its exit code depends on where it lands)
    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    out = tmp_path / "out"
    as_json = sig == signal.SIGINT and jobs == "1"
    # with -j 1 a specimen's Monte Carlo trials run in forked workers of the batch process
    # (on the cores): a Ctrl-C reaches them too
    mc = ["--monte-carlo", "20"] if jobs == "1" else []
    proc = _start_batch(specs, out, jobs, *(["--json"] if as_json else []), *mc)
    _wait_first_result(proc, out)
    os.killpg(proc.pid, sig)
    t0 = time.time()
    _o, _e = proc.communicate(timeout=60)
    assert time.time() - t0 < 5                          # Ctrl-C stops the workers at once
    if sig == signal.SIGINT:
        assert proc.returncode == 130, _e.decode()[-2000:]
        assert _e.decode().rstrip().endswith("laminid: interrupted")
        rows = read_summary(out / "summary.csv")              # the summary of what was done
        assert {r["status"] for r in rows} <= {"ok", "check", "not run"}
        n_done = sum(r["status"] in ("ok", "check") for r in rows)
        assert n_done >= 1
        # ... and printed as on a finished run, so a shell batch has it on stdout
        if as_json:
            d = json.loads(_o)
            assert d["interrupted"] is True and d["counts"]["not run"] == 4 - n_done
            assert json.loads((out / "summary.json").read_text())["interrupted"] is True
        else:
            text = _o.decode()
            assert text.count("not run") >= 4 - n_done
            assert f"; {4 - n_done} not run: interrupted); summary: " in text, text
    done = sorted(out.rglob("*.h5"))
    assert 1 <= len(done) < 4
    for p in done:                                             # every file opens, is complete
        with h5py.File(p, "r") as f:
            assert f.attrs["format"] == "laminid-result" and "batch_input_sha256" in f.attrs
            assert np.isfinite(f["materials"][next(iter(f["materials"]))]["E1"][()])
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--json", *mc)
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["counts"]["ok"] + d["counts"]["check"] == 4 and d["n_cached"] == len(done)
    assert not [p for p in out.rglob("*") if ".part-" in p.name or ".tmp-" in p.name]


@pytest.mark.parametrize("target, jobs", [("batch", "1"), ("batch", "2"), ("group", "2"),
                                           ("group", "1")])
def test_sigterm_ends_the_batch_as_ctrl_c_does_with_exit_143(tmp_path, target, jobs):
    """SIGTERM to the batch process (``kill PID``, ``timeout``, systemd) or to its whole
    process group (SLURM at the wall-time limit: workers and batch at once) killed the batch
    outright: summaries left "running", no table, exit 143 by the signal. It now ends as
    Ctrl-C does: workers stopped, their partial files removed, both summaries final and
    agreeing with the result files, the table (or --json) printed, saying "terminated
    (SIGTERM)", exit 143. The workers a group SIGTERM killed broke the pool: their specimens
    are 'not run', not run again alone (the retry for a killed worker) nor 'failed'."""
    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    out = tmp_path / "out"
    as_json = jobs == "1"
    mc = ["--monte-carlo", "20"] if jobs == "1" else []     # forked trial workers at -j 1
    proc = _start_batch(specs, out, jobs, *(["--json"] if as_json else []), *mc)
    _wait_first_result(proc, out)
    if target == "group":
        os.killpg(proc.pid, signal.SIGTERM)
    else:
        os.kill(proc.pid, signal.SIGTERM)
    t0 = time.time()
    _o, _e = proc.communicate(timeout=60)
    assert time.time() - t0 < 5, _e.decode()[-2000:]          # no specimen ran again
    assert proc.returncode == 143, _e.decode()[-2000:]
    assert _e.decode().rstrip().endswith("laminid: terminated (SIGTERM)"), _e.decode()[-2000:]
    doc = json.loads((out / "summary.json").read_text())
    assert doc["running"] is False and doc["interrupted"] is True
    assert doc["stopped_by"] == "SIGTERM"
    rows = read_summary(out / "summary.csv")
    assert {r["status"] for r in rows} <= {"ok", "check", "not run"}, rows
    done = sorted(out.rglob("*.result.h5"))
    n_done = sum(r["status"] in ("ok", "check") for r in rows)
    assert 1 <= n_done == len(done) < 4
    for r in rows:                                 # the summary agrees with the result files
        if r["status"] in ("ok", "check"):
            (material,) = r["materials"].values()             # one material per plate
            with h5py.File(out / r["result"], "r") as f:
                (stored,) = f["materials"].values()
                assert material["E1"] == pytest.approx(stored["E1"][()], rel=1e-12)
        else:
            assert not r["result"], r
    assert not [p for p in out.rglob("*") if ".part-" in p.name or ".tmp-" in p.name]
    if as_json:
        d = json.loads(_o)
        assert d["interrupted"] is True and d["stopped_by"] == "SIGTERM"
        assert d["counts"]["not run"] == 4 - n_done
    else:
        text = _o.decode()
        assert f"; {4 - n_done} not run: terminated (SIGTERM)); summary: " in text, text


def test_sigterm_is_noted_as_ctrl_c_where_the_batch_made_it_a_stop(monkeypatch):
    """batch._note_sigint notes SIGTERM (raising Terminated, a KeyboardInterrupt) where the
    handler in place is the batch command's (sigterm_stops_the_batch), which raises
    Terminated itself; both give the handler they found back. SIGTERM's default (the
    process killed, as in a pool worker) is left alone."""
    import laminid_cli.batch as B
    from laminid_cli.errors import Terminated

    before = signal.getsignal(signal.SIGTERM)
    seen, restore = B._note_sigint(raise_=False)
    restore()
    assert signal.getsignal(signal.SIGTERM) is before       # default: not taken over
    with B.sigterm_stops_the_batch():
        handler = signal.getsignal(signal.SIGTERM)
        with pytest.raises(Terminated):
            signal.raise_signal(signal.SIGTERM)
        seen, restore = B._note_sigint(raise_=False)
        try:
            signal.raise_signal(signal.SIGTERM)
            assert seen == [signal.SIGTERM]
            assert isinstance(B._interruption(seen), Terminated)
        finally:
            restore()
        assert signal.getsignal(signal.SIGTERM) is handler
        seen, restore = B._note_sigint()
        try:
            with pytest.raises(Terminated):
                signal.raise_signal(signal.SIGTERM)
        finally:
            restore()
    assert signal.getsignal(signal.SIGTERM) is before
    assert type(B._interruption([signal.SIGINT, signal.SIGTERM])) is KeyboardInterrupt


def test_the_batch_command_gives_sigterm_its_handler_back(tmp_path):
    """The command's SIGTERM handler is the process's only while it runs."""
    before = signal.getsignal(signal.SIGTERM)
    specs = make_tree(tmp_path / "in", {"example1/S1.4.yaml": "specimens/example1/S1.4.yaml"})
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out", "--json")
    assert r.exit_code in (0, 1), r.output
    assert json.loads(r.stdout)["stopped_by"] is None
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_killed_rerun_leaves_summaries_that_agree_with_its_results(tmp_path):
    """A batch killed (SIGKILL) mid-run left the summaries of the run before it: they named
    as "ok", with the old values, specimens whose result files the killed run had already
    replaced. The summaries are written when a run with work starts and again as specimens
    finish: every "ok" or "check" row of what a killed run leaves has its result file's
    values, the others are "not run" as not finished, and summary.json says it was running."""
    from laminid_cli.batch import PENDING_REASON

    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    out = tmp_path / "out"
    first = run("batch", specs, "--mesh", MESH, "--out", out, "--json")
    assert first.exit_code == 0, first.output
    # the run before: another mesh, so that every value differs from the next run's
    old = {p: p.stat().st_mtime_ns for p in out.rglob("*.h5")}
    proc = _start_batch(specs, out, "1", "--mesh", "4x4")
    t0 = time.time()
    while not any(p.stat().st_mtime_ns != m for p, m in old.items() if p.exists()):
        assert proc.poll() is None, proc.communicate()
        assert time.time() - t0 < 120, "no result was replaced"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    doc = json.loads((out / "summary.json").read_text())
    assert doc["running"] is True and doc["options"]["mesh"] == "4x4"
    rows = read_summary(out / "summary.csv")
    assert len(rows) == 4
    for r in rows:
        if r["status"] in ("ok", "check"):
            with h5py.File(out / r["result"], "r") as f:
                m = next(iter(f["materials"]))
                assert r["materials"][m]["E1"] == pytest.approx(f["materials"][m]["E1"][()],
                                                                rel=1e-12)
        else:
            assert r["status"] == "not run" and r["reason"] == PENDING_REASON, r
    assert sum(r["status"] == "not run" for r in rows) >= 1
    # the run again finishes, and its summary is no running one
    again = run("batch", specs, "--mesh", "4x4", "--out", out, "--json")
    assert again.exit_code == 0, again.output
    assert json.loads((out / "summary.json").read_text())["running"] is False


def test_a_remote_scheduler_is_named_not_a_worker_count(tmp_path, monkeypatch):
    """With a running Dask scheduler the workers are the cluster's (-j does not apply): the
    start line said "on 1 worker" and nothing while the connection waited (up to 20 s); it
    names the scheduler and says it is connecting, then the one-line error when it cannot."""
    from laminid_cli import batch as B

    def refused(jobs, options, n_jobs, scheduler):
        raise B.BatchError(f"--scheduler {scheduler}: cannot connect (refused)")
        yield                                             # (a generator, as _run_dask)

    monkeypatch.setattr(B, "_run_dask", refused)
    r = run("batch", SPECS["example2/S2.1.yaml"], "--mesh", MESH, "--out", tmp_path / "o",
            "--scheduler", "tcp://10.0.0.5:8786")
    assert r.exit_code != 0
    assert ("1 specimen, 0 up to date, 1 to identify on the Dask scheduler "
            "tcp://10.0.0.5:8786 (connecting)") in r.output, r.output
    assert "on 1 worker" not in r.output
    assert "laminid: error: --scheduler tcp://10.0.0.5:8786: cannot connect (refused)" \
        in r.output


@pytest.fixture
def no_dask_thread_left():
    """distributed's offload thread ("Dask-Offload_0") ended after the test. A local cluster
    run in this process starts it and it outlives the batch; while a second thread runs, a
    fork is not safe (laminid_cli.frf.store._fork_is_safe), so every later HDF5 probe of
    this test worker started a new interpreter (0.2-0.3 s) instead of forking (20-30 ms):
    test_frf_interchange.py took 38 s instead of 18 s after this test in the same worker.
    The executor is replaced by a new one, which starts its thread when first used."""
    yield
    from concurrent.futures import ThreadPoolExecutor

    du = sys.modules.get("distributed.utils")          # None: the test skipped without Dask
    if du is None:
        return
    du._offload_executor.shutdown(wait=True)
    du._offload_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="Dask-Offload")


def test_dask_local_cluster_gives_the_same_constants(batch_run, tmp_path, no_dask_thread_left):
    pytest.importorskip("distributed")
    specs, out, _ = batch_run
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "dask", "--scheduler", "local",
            "-j", "2", "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["counts"]["ok"] + d["counts"]["check"] == 2 and d["n_cached"] == 0
    for rel in SPECS:
        name = rel.replace(".yaml", ".result.h5")
        assert constants_bytes(tmp_path / "dask" / name) == constants_bytes(out / name)


def test_a_dask_local_batch_prints_no_cluster_log_lines_unless_verbose(tmp_path):
    """distributed sets its loggers to INFO on import: a plain `--scheduler local` batch printed
    some 40 'INFO distributed.scheduler: ...' lines on stderr around the batch's own."""
    pytest.importorskip("distributed")
    p = _dask_local_batch(tmp_path)
    assert p.returncode == 0, p.stderr
    assert "distributed" not in p.stderr, p.stderr
    assert p.stderr.splitlines()[0] == "1 specimen, 0 up to date, 1 to identify on 1 worker"
    assert (tmp_path / "out" / "S1.4.result.h5").is_file()
    p = _dask_local_batch(tmp_path, "--force", verbose=True)
    assert p.returncode == 0 and "INFO distributed.scheduler" in p.stderr, p.stderr


def test_a_dask_local_workers_warning_is_written_as_the_batchs(tmp_path):
    """A local Dask worker starts from a clean interpreter: a specimen's warning logged there
    went out bare through Python's last-resort handler ('/.../S1.4.yaml: measured.damping
    ...'), where the batch in its process and the pool's workers write 'warning: ...'."""
    pytest.importorskip("distributed")
    (tmp_path / "in").mkdir()
    text = Path("specimens/example1/S1.4.yaml").read_text()
    line = next(t for t in text.splitlines() if t.startswith("  frequencies:"))
    (tmp_path / "in" / "S1.4.yaml").write_text(
        text.replace(line, line + "\n  damping: [" + ", ".join(["0.3"] * 12) + "]"))
    p = _dask_local_batch(tmp_path)
    assert p.returncode == 0, p.stderr
    said = [t for t in p.stderr.splitlines() if "every damping ratio is 10 % or more" in t]
    assert len(said) == 1 and said[0].startswith("warning: "), p.stderr
    assert said[0].endswith("if these are percent, write '0.3 %'"), p.stderr


def _dask_local_batch(tmp_path, *extra, verbose=False):
    """`laminid [-v] batch` of S1.4 (4x4) on a one-worker local Dask cluster, in a new
    process (its stderr is the subject: distributed's logging and warnings)."""
    specs = tmp_path / "in"
    if not specs.exists():
        make_tree(specs, {"S1.4.yaml": "specimens/example1/S1.4.yaml"})
    cmd = [sys.executable, "-m", "laminid_cli", *(["-v"] if verbose else []), "batch",
           str(specs), "--mesh", "4x4", "--scheduler", "local", "-j", "1", "--out",
           str(tmp_path / "out"), *extra]
    root = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONPATH=root + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=root)


def test_a_dask_local_batch_beside_another_cluster_prints_nothing_of_its_port(tmp_path):
    """The local cluster's scheduler starts an HTTP server whatever the dashboard, on port
    8787 by default: a second batch running at the same time (or anything else on 8787)
    printed distributed's 'UserWarning: Port 8787 is already in use. Perhaps you already have
    a cluster running? Hosting the HTTP server on port ... instead' (4 lines). It takes a
    free port of the loopback."""
    import socket

    pytest.importorskip("distributed")
    busy = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        busy.bind(("0.0.0.0", 8787))               # (taken already: as good for the test)
        busy.listen(1)
    except OSError:
        pass
    try:
        p = _dask_local_batch(tmp_path)
    finally:
        busy.close()
    assert p.returncode == 0, p.stderr
    assert p.stderr.splitlines() == ["1 specimen, 0 up to date, 1 to identify on 1 worker",
                                     "identified 1/1: S1.4: check"], p.stderr


def test_a_local_workers_shutdown_errors_are_muted_without_v():
    """After a Ctrl-C a worker whose heartbeat found the scheduler already closed logged
    "distributed.worker - ERROR - Failed to communicate with scheduler during heartbeat" and
    a 30-line traceback before "laminid: interrupted" (CI, a loaded 2-core machine): the
    workers' loggers were at ERROR. Without -v they are at CRITICAL; with -v at laminid's
    level."""
    pytest.importorskip("distributed")
    import logging

    from laminid_cli.dask_worker import LocalWorkerSetup, worker_log_level

    assert worker_log_level(logging.WARNING) == logging.CRITICAL
    assert worker_log_level(logging.INFO) == logging.INFO
    assert worker_log_level(logging.DEBUG) == logging.DEBUG
    dist = logging.getLogger("distributed")
    before_level, before_sigint = dist.level, signal.getsignal(signal.SIGINT)
    before_sigterm = signal.getsignal(signal.SIGTERM)
    root = logging.getLogger()
    before_root = (root.level, list(root.handlers))
    try:
        LocalWorkerSetup(worker_log_level(logging.WARNING)).setup(worker=None)
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
        assert dist.level == logging.CRITICAL
        assert not logging.getLogger("distributed.worker").isEnabledFor(logging.ERROR)
        LocalWorkerSetup(worker_log_level(logging.INFO)).setup(worker=None)
        assert logging.getLogger("distributed.worker").isEnabledFor(logging.INFO)
    finally:
        dist.setLevel(before_level)
        signal.signal(signal.SIGINT, before_sigint)
        signal.signal(signal.SIGTERM, before_sigterm)
        root.setLevel(before_root[0])
        root.handlers[:] = before_root[1]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_or_sigterm_on_a_dask_local_batch_prints_no_worker_tracebacks(tmp_path, sig):
    """Ctrl-C reaches the whole process group, the local cluster's worker processes too: each
    one printed its tracebacks ("Process Dask Worker process (from Nanny)", CancelledError,
    KeyboardInterrupt; some 300 lines in all) and the cluster warned of cancelled tasks before
    "laminid: interrupted". The workers leave it to the batch, as the process pool's do: one
    line, exit 130, the finished results kept and the rest done by a re-run. SIGTERM to the
    whole group (a cluster's wall-time limit) ends it the same way, exit 143, the summary
    final and saying so (the process pool's test: test_sigterm_ends_the_batch_as_ctrl_c_...)."""
    pytest.importorskip("distributed")
    specs = make_tree(tmp_path / "in", {**SPECS, "example1/S1.1.yaml":
                                        "specimens/example1/S1.1.yaml", "example1/S1.2.yaml":
                                        "specimens/example1/S1.2.yaml"})
    out = tmp_path / "out"
    proc = _start_batch(specs, out, "2", "--scheduler", "local")
    _wait_first_result(proc, out)
    os.killpg(proc.pid, sig)
    _o, err = proc.communicate(timeout=60)
    err = err.decode()
    assert "Traceback" not in err and "distributed" not in err, err[-3000:]
    if sig == signal.SIGINT:
        assert proc.returncode == 130, err[-3000:]
        assert err.splitlines()[-1] == "laminid: interrupted", err[-3000:]
    else:
        assert proc.returncode == 143, err[-3000:]
        assert err.splitlines()[-1] == "laminid: terminated (SIGTERM)", err[-3000:]
        doc = json.loads((out / "summary.json").read_text())
        assert doc["running"] is False and doc["stopped_by"] == "SIGTERM"
        assert doc["counts"]["not run"] == 4 - len(list(out.rglob("*.result.h5")))
    assert not [p for p in out.rglob("*") if ".part-" in p.name or ".tmp-" in p.name]
    done = sorted(out.rglob("*.result.h5"))
    assert 1 <= len(done) <= 4
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["n_cached"] == len(done)


def test_a_killed_workers_temporary_file_is_removed_at_the_end_if_it_was_exiting_at_the_start(
        tmp_path, monkeypatch):
    """A worker killed just before the re-run may still be exiting when the re-run starts: its
    temporary file then belongs to a 'live' process and stays; the re-run removes it at the
    end, when the process is gone (seen once under load in the kill test above)."""
    import laminid_cli.atomic as atomic

    specs = make_tree(tmp_path / "in", {"example1/S1.4.yaml": "specimens/example1/S1.4.yaml"})
    out = tmp_path / "out"
    (out / "example1").mkdir(parents=True)
    stale = out / "example1" / ".S1.4.result.h5.tmp-999999"
    stale.write_bytes(b"half a file")
    calls = []

    def alive_at_first(pid):
        calls.append(pid)
        return pid == 999999 and len(calls) == 1      # alive at the start, gone at the end

    monkeypatch.setattr(atomic, "process_alive", alive_at_first)
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--json")
    assert r.exit_code == 0, r.output
    assert calls.count(999999) == 2
    assert not stale.exists()
    assert (out / "example1" / "S1.4.result.h5").exists()


def test_a_linked_specimen_file_from_elsewhere_is_named_by_its_link(tmp_path):
    """A folder's symbolic link to a specimen file outside it was a traceback ('... is not in
    the subpath of ...'); it is a specimen named by the link, beside the folder's own."""
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "S1.2.yaml").write_text("x")
    (tmp_path / "lab" / "a").mkdir(parents=True)
    (tmp_path / "lab" / "a" / "p1.yaml").write_text("x")
    (tmp_path / "lab" / "latest.yaml").symlink_to(tmp_path / "elsewhere" / "S1.2.yaml")
    found = discover_specimens([tmp_path / "lab"])
    assert [n for _, n in found] == ["a/p1", "latest"]


def test_a_linked_folder_is_searched_once_and_a_link_loop_ends(tmp_path):
    """A symbolic link to a folder (a lab's data elsewhere) was skipped without a word; it is
    searched as a folder, each real folder once: a link back up ends there."""
    (tmp_path / "elsewhere" / "deep").mkdir(parents=True)
    (tmp_path / "elsewhere" / "deep" / "p2.yaml").write_text("x")
    (tmp_path / "lab" / "a").mkdir(parents=True)
    (tmp_path / "lab" / "a" / "p1.yaml").write_text("x")
    (tmp_path / "lab" / "a" / "up").symlink_to(tmp_path / "lab")          # a loop
    (tmp_path / "lab" / "nov").symlink_to(tmp_path / "elsewhere")
    (tmp_path / "lab" / ".hid").symlink_to(tmp_path / "elsewhere")        # hidden: skipped
    found = discover_specimens([tmp_path / "lab"])
    assert [n for _, n in found] == ["a/p1", "nov/deep/p2"]


def test_specimens_differing_only_in_their_suffix_keep_both_results(tmp_path):
    """plate.yaml and plate.yml in one folder: two results (names with their suffix), each with
    its own plate's constants; nothing overwritten."""
    d = tmp_path / "c"
    d.mkdir()
    shutil.copy("specimens/example1/S1.1.yaml", d / "plate.yaml")
    shutil.copy("specimens/example2/S2.1.yaml", d / "plate.yml")
    shutil.copy("specimens/example1/S1.2.yaml", d / "other.yaml")
    assert [n for _, n in discover_specimens([d])] == ["other", "plate.yaml", "plate.yml"]
    out = tmp_path / "r"
    r = run("batch", d, "--mesh", "6x6", "--out", out, "-j", "1")
    assert r.exit_code == 0, r.output
    with h5py.File(out / "plate.yaml.result.h5") as f:
        assert f["specimen"].attrs["name"] == "S1.1"
    with h5py.File(out / "plate.yml.result.h5") as f:
        assert f["specimen"].attrs["name"] == "S2.1"
    rows = read_summary(out / "summary.csv")
    assert sorted({(row["name"], row["specimen"]) for row in rows}) == [
        ("other", "S1.2"), ("plate.yaml", "S1.1"), ("plate.yml", "S2.1")]


def test_table_marks_fixed_bound_and_undetermined_values():
    """The batch table marks a value held fixed "=", at a bound "!", undetermined "?", and its
    legend names only the marks it uses."""
    from laminid_cli.batch import format_table

    consts = {"E1": 150e9, "E2": 9e9, "G12": 5e9, "G13": 3.1e9, "G23": 2.95e6, "nu12": 0.35}
    iv = {"E1": {"verdict": "well determined"}, "E2": {"verdict": "weak"},
          "G12": {"verdict": "not determined", "flagged": True}, "G13": {"verdict": "fixed"},
          "G23": {"verdict": "at bound — not identified", "at_bound": True, "flagged": True},
          "nu12": {"verdict": "fixed"}}
    row = {"name": "p", "specimen": "P", "status": "check", "cached": False, "reason": "",
           "reasons": [], "materials": {"m": consts}, "intervals": {"m": iv},
           "rms_residual_percent": 0.3, "evaluations": 40}
    lines = format_table([row]).splitlines()
    cell = {ln.split()[0]: ln.split()[-1] for ln in lines if ln[:3] in ("E1 ", "E2 ", "G12", "G13",
                                                                         "G23", "nu1")}
    assert cell == {"E1": "150.00", "E2": "9.00", "G12": "5.00?", "G13": "3.10=",
                    "G23": "0.00295!", "nu12": "0.350="}
    legend = next(ln for ln in lines if ln.startswith("! "))
    assert legend.count(";") == 3 and "= fixed at its initial value — not identified" in legend
    # E1 and E2, unmarked, are no exact values: the legend says where their intervals are
    # (it said nothing of them: a weak E2 read as a number known like E1)
    assert legend.endswith("; unmarked: identified, its 95 % interval within --max-rel-interval "
                           "of the value (well determined or weak: summary.csv's lower, upper, "
                           "verdict)")
    row["intervals"] = {"m": {k: {"verdict": "fixed"} if k == "nu12" else {} for k in consts}}
    legend = [ln for ln in format_table([row]).splitlines() if "not identified" in ln]
    assert legend == ["= fixed at its initial value — not identified (--fix or the file's "
                      "'fixed')"]


def test_summary_json_finds_its_results_after_the_folder_moves_and_from_elsewhere(
        tmp_path, monkeypatch):
    """summary.json gives each result file relative to its own folder (as summary.csv does),
    so a summary moved with its folder, or read from another directory by a plain json.load,
    still finds every result; summaries written before (paths as the batch saw them, relative
    to its current folder) are still read right, subfolders included."""
    work = tmp_path / "work"
    make_tree(work / "specs")
    monkeypatch.chdir(work)
    r = run("batch", "specs", "--mesh", MESH, "--out", "res", "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads((work / "res" / "summary.json").read_text())
    assert doc["result_paths"] == "relative to this file's folder"
    assert [row["result"] for row in doc["specimens"]] == [
        "example1/S1.4.result.h5", "example2/S2.1.result.h5"]
    # the --json on stdout, for the shell that ran the batch: as the batch saw them
    printed = json.loads(r.stdout)
    assert "result_paths" not in printed and [row["result"] for row in printed["specimens"]] \
        == ["res/example1/S1.4.result.h5", "res/example2/S2.1.result.h5"]
    # moved with its folder and read from another directory
    shutil.move(work / "res", tmp_path / "archive")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    summary = Path("..") / "archive" / "summary.json"
    doc = json.loads(summary.read_text())
    for row in doc["specimens"]:
        with h5py.File(summary.parent / row["result"], "r") as f:
            assert f.attrs["batch_name"] == row["name"]
    rows = read_summary(summary)
    assert [Path(row["result"]).resolve() for row in rows] == [
        (tmp_path / "archive" / rel).resolve()
        for rel in ("example1/S1.4.result.h5", "example2/S2.1.result.h5")]
    # a summary of the earlier layout: paths relative to the batch's current folder
    old = json.loads(summary.read_text())
    old.pop("result_paths", None)
    for row in old["specimens"]:
        row["result"] = "res/" + row["result"]
    old["out"] = "res"
    (tmp_path / "archive" / "old.json").write_text(json.dumps(old))
    rows = read_summary(Path("..") / "archive" / "old.json")
    assert [Path(row["result"]).resolve() for row in rows] == [
        (tmp_path / "archive" / rel).resolve()
        for rel in ("example1/S1.4.result.h5", "example2/S2.1.result.h5")]
    # ... absolute, the folder moved since
    old["out"] = str(work / "res")
    for row in old["specimens"]:
        row["result"] = str(work / row["result"])
    (tmp_path / "archive" / "old.json").write_text(json.dumps(old))
    rows = read_summary(Path("..") / "archive" / "old.json")
    assert [Path(row["result"]).resolve() for row in rows] == [
        (tmp_path / "archive" / rel).resolve()
        for rel in ("example1/S1.4.result.h5", "example2/S2.1.result.h5")]
    # ... and from the folder the batch ran in, where its paths are right as they are
    old["out"] = "archive"
    for row in old["specimens"]:
        row["result"] = "archive" + row["result"][len(str(work / "res")):]
    (tmp_path / "archive" / "old.json").write_text(json.dumps(old))
    monkeypatch.chdir(tmp_path)
    assert [row["result"] for row in read_summary(Path("archive") / "old.json")] == [
        "archive/example1/S1.4.result.h5", "archive/example2/S2.1.result.h5"]


def test_out_may_be_the_specimens_own_folder(tmp_path, monkeypatch):
    """--out naming the input folder itself (results beside the specimens, as identify writes
    them) identifies its specimens; it said "no specimen file found" (the output folder's
    files are not read as specimens, and that folder was the input). A yaml inside an --out
    below the inputs is still not taken for a specimen."""
    specs = make_tree(tmp_path / "specs")
    r = run("batch", specs, "--mesh", MESH, "--out", specs)
    assert r.exit_code == 0, r.output
    assert "2 specimens, 0 up to date, 2 to identify" in r.output
    for rel in SPECS:
        with h5py.File(specs / rel.replace(".yaml", ".result.h5"), "r") as f:
            assert f.attrs["batch_name"] == rel[:-5]
    monkeypatch.chdir(specs / "example1")
    r = run("batch", ".", "--mesh", MESH, "--out", ".")
    assert r.exit_code == 0, r.output
    assert "1 specimen, 1 up to date, 0 to identify" in r.output     # the same file
    assert (specs / "example1" / "S1.4.result.h5").is_file()
    # an --out below the inputs: a yaml there is not a specimen
    (specs / "res").mkdir()
    shutil.copy(specs / "example2" / "S2.1.yaml", specs / "res" / "copy.yaml")
    assert [name for _, name in discover_specimens([specs], exclude=[specs / "res"])] == [
        "example1/S1.4", "example2/S2.1"]


def test_quiet_batch_writes_nothing_but_errors_on_stderr(tmp_path):
    """laminid -q: "only errors on stderr"; the batch still wrote its count line and its
    progress label there. The table stays on stdout, a failing specimen's line too."""
    specs = make_tree(tmp_path / "specs")
    r = run("-q", "batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert r.stderr == ""
    assert "0 ok, 2 check (0 not converged), 0 failed" in r.stdout
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert r.stderr == "2 specimens, 2 up to date, 0 to identify\n"          # without -q


def test_a_batch_logged_to_a_file_says_each_specimen_as_it_finishes(tmp_path):
    """stderr on a log or pipe (no terminal): click's progress bar wrote its label
    "identifying" and nothing more until the table, so a long batch's log said nothing of
    its progress. A line per finished specimen, with its status, instead of the bar."""
    specs = make_tree(tmp_path / "specs")
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines() == ["2 specimens, 0 up to date, 2 to identify on 1 process",
                                     "identified 1/2: example1/S1.4: check",
                                     "identified 2/2: example2/S2.1: check"], r.stderr


def test_the_count_line_says_the_processes_the_batch_starts(tmp_path):
    """-j 2 with one specimen to identify said "1 to identify on 2 processes"; run_jobs starts
    no more processes than specimens (the walkthrough)."""
    specs = make_tree(tmp_path / "specs")
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out", "-j", "2")
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines()[0] == "2 specimens, 0 up to date, 2 to identify on 2 processes"
    (specs / "example1" / "S1.4.yaml").write_text(
        (specs / "example1" / "S1.4.yaml").read_text().replace("name: ", "name: edited ", 1))
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out", "-j", "2")
    assert r.exit_code == 0, r.output
    assert r.stderr.splitlines()[0] == "2 specimens, 1 up to date, 1 to identify on 1 process"


def test_a_result_whose_specimen_now_fails_is_set_aside_out_of_the_result_pattern(tmp_path):
    """A specimen that once succeeded and now fails (its file edited into an error) left its
    old S2.1.result.h5 in --out beside the new summary: a script globbing *.result.h5 took it
    for current. It is renamed S2.1.result.stale.h5 (then .stale1, ...: never over an earlier
    one), bytes unchanged, and the terminal, --json, summary.csv and summary.json name it."""
    specs = make_tree(tmp_path / "in", {"S2.1.yaml": SPECS["example2/S2.1.yaml"]})
    good = (specs / "S2.1.yaml").read_text()
    out = tmp_path / "out"
    assert run("batch", specs, "--mesh", MESH, "--out", out).exit_code == 0
    first = (out / "S2.1.result.h5").read_bytes()
    (specs / "S2.1.yaml").write_text("geometry: [1\n")
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--json")
    assert r.exit_code == 1, r.output
    assert sorted(p.name for p in out.iterdir()) == [
        "S2.1.result.stale.h5", "summary.csv", "summary.json"]
    assert not list(out.glob("*.result.h5"))
    assert (out / "S2.1.result.stale.h5").read_bytes() == first
    row = json.loads(r.stdout)["specimens"][0]
    assert row["status"] == "error" and row["result"] is None
    assert row["stale_result"] == str(out / "S2.1.result.stale.h5")
    doc = json.loads((out / "summary.json").read_text())
    assert doc["specimens"][0]["stale_result"] == "S2.1.result.stale.h5"
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(without_comments(fh)))
    assert [(x["status"], x["result"], x["stale_result"]) for x in rows] == [
        ("error", "", "S2.1.result.stale.h5")]
    assert read_summary(out / "summary.csv")[0]["stale_result"] == str(
        out / "S2.1.result.stale.h5")
    assert read_summary(out / "summary.json")[0]["stale_result"] == str(
        out / "S2.1.result.stale.h5")
    # fixed, identified again, broken again: the next stale name, the first one untouched
    (specs / "S2.1.yaml").write_text(good)
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--wide")
    assert r.exit_code == 0, r.output
    second = (out / "S2.1.result.h5").read_bytes()
    (specs / "S2.1.yaml").write_text("mass: [\n")
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--wide")
    assert r.exit_code == 1
    assert (out / "S2.1.result.stale.h5").read_bytes() == first
    assert (out / "S2.1.result.stale1.h5").read_bytes() == second
    assert not list(out.glob("*.result.h5"))
    lines = r.stdout.splitlines()
    k = lines.index("not identified:")
    assert lines[k + 1].startswith("  S2.1: error: ") and "not valid YAML" in lines[k + 1]
    assert lines[k + 2] == (f"    its earlier result (of another input) moved to "
                            f"{out / 'S2.1.result.stale1.h5'}")
    assert "1 earlier result set aside" in r.stdout
    with open(out / "summary.csv", newline="") as fh:
        wide = list(csv.DictReader(without_comments(fh)))
    assert wide[0]["stale_result"] == "S2.1.result.stale1.h5"
    # failing once more: nothing left to set aside, nothing renamed
    r = run("batch", specs, "--mesh", MESH, "--out", out, "--json")
    assert json.loads(r.stdout)["specimens"][0]["stale_result"] is None
    assert sorted(p.name for p in out.glob("*.h5")) == [
        "S2.1.result.stale.h5", "S2.1.result.stale1.h5"]


def test_set_aside_result_never_overwrites_and_leaves_a_symbolic_link(tmp_path, monkeypatch):
    from laminid_cli.batch import Job, set_aside_result

    job = Job(spec="p.yaml", name="p", output=str(tmp_path / "p.result.h5"), key="k")
    assert set_aside_result(job) == (None, "")                 # nothing there
    (tmp_path / "p.result.stale.h5").write_bytes(b"older")
    (tmp_path / "p.result.h5").write_bytes(b"old")
    # a file system without hard links: a plain rename to the first free name
    monkeypatch.setattr("os.link", lambda *a: (_ for _ in ()).throw(PermissionError("no")))
    assert set_aside_result(job) == (tmp_path / "p.result.stale1.h5", "")
    assert (tmp_path / "p.result.stale1.h5").read_bytes() == b"old"
    assert (tmp_path / "p.result.stale.h5").read_bytes() == b"older"
    assert not (tmp_path / "p.result.h5").exists()
    monkeypatch.undo()
    (tmp_path / "target.h5").write_bytes(b"kept")
    (tmp_path / "p.result.h5").symlink_to(tmp_path / "target.h5")
    path, why = set_aside_result(job)
    assert path is None and why == f"{tmp_path / 'p.result.h5'} is a symbolic link, left in place"
    assert (tmp_path / "p.result.h5").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "p.result.h5", "p.result.stale.h5", "p.result.stale1.h5", "target.h5"]


def test_results_of_specimens_not_in_this_batch_are_named_and_kept(batch_run, tmp_path):
    """A specimen file removed from the inputs left its result in --out, where a glob of
    *.result.h5 took it for one of this batch. It is not moved (another batch may write into
    the same --out: which of the two cannot be told), but the table, --json and both
    summaries name it "not from this batch", and it makes no failure."""
    specs, out, _ = batch_run
    work, inputs = tmp_path / "out", tmp_path / "specs"
    shutil.copytree(out, work)
    shutil.copytree(specs, inputs)
    (inputs / "example1" / "S1.4.yaml").unlink()
    orphan = work / "example1" / "S1.4.result.h5"
    before = orphan.read_bytes()
    r = run("batch", inputs, "--mesh", MESH, "--out", work)
    assert r.exit_code == 0, r.output
    assert orphan.read_bytes() == before                        # kept as it is
    lines = r.stdout.splitlines()
    k = lines.index("not from this batch (no specimen of its inputs has them; kept as they "
                    "are):")
    assert lines[k + 1] == f"  {orphan}"
    assert "0 ok, 1 check (0 not converged), 0 failed (1 up to date; 1 result file is not " \
           "from this batch)" in r.stdout
    r = run("batch", inputs, "--mesh", MESH, "--out", work, "--json")
    d = json.loads(r.stdout)
    assert d["n_specimens"] == 1 and d["counts"]["not from this batch"] == 1
    assert d["counts"]["set aside"] == 0
    row = d["specimens"][-1]
    assert (row["name"], row["status"], row["result"], row["stale_result"]) == (
        "example1/S1.4", "not from this batch", None, str(orphan))
    assert row["reason"].startswith("no specimen of this batch has this result file")
    doc = json.loads((work / "summary.json").read_text())
    assert doc["specimens"][-1]["stale_result"] == "example1/S1.4.result.h5"
    with open(work / "summary.csv", newline="") as fh:
        rows = [x for x in csv.DictReader(without_comments(fh)) if x["name"] == "example1/S1.4"]
    assert [(x["status"], x["result"], x["stale_result"]) for x in rows] == [
        ("not from this batch", "", "example1/S1.4.result.h5")]
    assert "kept as it is" in rows[0]["reasons"]
    assert {r["name"]: r["status"] for r in read_summary(work / "summary.json")} == {
        "example2/S2.1": "check", "example1/S1.4": "not from this batch"}


def test_an_interrupted_batch_sets_aside_the_results_it_did_not_reach_and_keeps_the_rest(
        batch_run, tmp_path, monkeypatch):
    """Ctrl-C after the first of two specimens whose options changed: the finished result
    stays; the other specimen's file is an earlier input's (other options), so it is renamed
    out of the *.result.h5 pattern, bytes unchanged, and the summaries name it."""
    import laminid_cli.batch as batch_mod

    specs, out, _ = batch_run
    work = tmp_path / "out"
    shutil.copytree(out, work)
    old = (work / "example2" / "S2.1.result.h5").read_bytes()
    real = batch_mod.run_jobs

    def first_then_ctrl_c(jobs, options, **kw):
        yield from real(jobs[:1], options)
        raise KeyboardInterrupt

    monkeypatch.setattr(batch_mod, "run_jobs", first_then_ctrl_c)
    r = run("batch", specs, "--mesh", "5x5", "--out", work)
    assert r.exit_code == 130, r.output
    with h5py.File(out / "example1" / "S1.4.result.h5", "r") as f:
        first_key = f.attrs["batch_input_sha256"]
    with h5py.File(work / "example1" / "S1.4.result.h5", "r") as f:   # finished: in place
        assert f.attrs["batch_input_sha256"] != first_key                # (the 5x5 input's)
    assert sorted(p.relative_to(work).as_posix() for p in work.rglob("*.h5")) == [
        "example1/S1.4.result.h5", "example2/S2.1.result.stale.h5"]
    assert (work / "example2" / "S2.1.result.stale.h5").read_bytes() == old
    rows = {x["name"]: x for x in read_summary(work / "summary.json")}
    assert rows["example2/S2.1"]["status"] == "not run"
    assert rows["example2/S2.1"]["stale_result"] == str(work / "example2" /
                                                        "S2.1.result.stale.h5")
    assert rows["example1/S1.4"]["status"] in ("ok", "check")
    with open(work / "summary.csv", newline="") as fh:
        csv_rows = [x for x in csv.DictReader(without_comments(fh)) if x["name"] == "example2/S2.1"]
    assert [(x["status"], x["result"], x["stale_result"]) for x in csv_rows] == [
        ("not run", "", "example2/S2.1.result.stale.h5")]
    # the re-run identifies it again; the set-aside file is left alone
    monkeypatch.undo()
    r = run("batch", specs, "--mesh", "5x5", "--out", work, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["n_cached"] == 1
    assert (work / "example2" / "S2.1.result.stale.h5").read_bytes() == old


def test_a_ctrl_c_while_the_final_summaries_are_written_waits_for_them_and_the_table(
        batch_run, tmp_path, monkeypatch):
    """Ctrl-C as the batch wrote its final summaries (every specimen done) was raised inside
    the write: summary.json stayed the running one beside the final summary.csv, and no table.
    Now both summaries are the final ones, the table is printed, then exit 130."""
    import laminid_cli.batch as batch_mod

    specs, out, _ = batch_run
    work = tmp_path / "out"
    shutil.copytree(out, work)
    real = batch_mod.write_summary_json

    def ctrl_c_then_write(path, report):
        if not report.get("running"):
            os.kill(os.getpid(), signal.SIGINT)
        return real(path, report)

    monkeypatch.setattr(batch_mod, "write_summary_json", ctrl_c_then_write)
    r = run("batch", specs, "--mesh", MESH, "-j", "2", "--out", work)
    assert r.exit_code == 130, r.output
    assert "summary: " in r.stdout and "not run" not in r.stdout
    doc = json.loads((work / "summary.json").read_text())
    assert doc["running"] is False
    assert doc["counts"]["check"] + doc["counts"]["ok"] == 2
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_batch_that_ends_in_an_error_leaves_ctrl_c_as_it_found_it(batch_run, tmp_path,
                                                                     monkeypatch):
    """The summaries' and table's hold on Ctrl-C is let go when an error ends the run (a
    scheduler lost before any job: exit 2) as when the run ends: a Ctrl-C raises again."""
    import laminid_cli.batch as batch_mod
    from laminid_cli.batch import BatchError

    specs, out, _ = batch_run
    work = tmp_path / "out"
    shutil.copytree(out, work)

    def refused(jobs, options, **kw):
        raise BatchError("scheduler gone")
        yield                                   # a generator, as run_jobs

    monkeypatch.setattr(batch_mod, "run_jobs", refused)
    before = signal.getsignal(signal.SIGINT)
    r = run("batch", specs, "--mesh", "5x5", "--out", work)
    assert r.exit_code == 2 and "scheduler gone" in r.output, r.output
    assert signal.getsignal(signal.SIGINT) is before


def test_a_second_batch_into_the_same_out_at_once_is_refused_before_it_touches_it(
        batch_run, tmp_path):
    """Two batches writing into one --out at once replaced each other's results under their
    summaries (the one ending last gave its own constants for files holding the other's). While
    one holds the folder, another is refused (exit 2, naming it) and changes nothing; the folder
    is free again when a batch ends."""
    import fcntl

    specs, out, _ = batch_run
    work = tmp_path / "out"
    shutil.copytree(out, work)
    before = {p: p.read_bytes() for p in work.rglob("*") if p.is_file()}
    fd = os.open(work, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)       # a batch running into it
        r = run("batch", specs, "--mesh", "5x5", "--out", work)
        assert r.exit_code == 2, r.output
        assert f"--out {work}: another laminid batch is writing into this folder" in r.output
        assert {p: p.read_bytes() for p in work.rglob("*") if p.is_file()} == before
        fcntl.flock(fd, fcntl.LOCK_UN)
        r = run("batch", specs, "--mesh", MESH, "--out", work, "-j", "2")
        assert r.exit_code == 0, r.output
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)       # released by the batch's end
    finally:
        os.close(fd)


def test_a_forked_child_of_a_batch_does_not_hold_its_out_folder(tmp_path):
    """A Monte Carlo trial forked from the batch that outlived it for a moment (SIGKILL) kept
    the next batch out; a forked child closes its copy, the parent's hold stays."""
    import fcntl

    from laminid_cli.batch import lock_out_folder, release_out_folder

    fd = lock_out_folder(tmp_path)
    try:
        pid = os.fork()
        if pid == 0:
            try:
                os.fstat(fd)
                os._exit(1)
            except OSError:
                os._exit(0)
        assert os.waitpid(pid, 0)[1] == 0
        other = os.open(tmp_path, os.O_RDONLY)
        with pytest.raises(BlockingIOError):
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.close(other)
    finally:
        release_out_folder(fd)


def test_an_interrupted_forced_batch_keeps_the_results_of_the_same_input(batch_run, tmp_path,
                                                                        monkeypatch):
    """--force redoes up-to-date results: one the interrupted run did not reach is still this
    input's result, so it stays where it is (a cached row, not set aside)."""
    import laminid_cli.batch as batch_mod

    specs, out, _ = batch_run
    work = tmp_path / "out"
    shutil.copytree(out, work)
    before = {p: p.read_bytes() for p in work.rglob("*.h5")}

    def ctrl_c(jobs, options, **kw):
        raise KeyboardInterrupt
        yield                                   # a generator, as run_jobs

    monkeypatch.setattr(batch_mod, "run_jobs", ctrl_c)
    r = run("batch", specs, "--mesh", MESH, "--out", work, "--force")
    assert r.exit_code == 130, r.output
    assert {p: p.read_bytes() for p in work.rglob("*.h5")} == before
    rows = read_summary(work / "summary.json")
    assert [(x["status"], x["cached"], x["stale_result"]) for x in rows] == [
        ("check", True, None), ("check", True, None)]


def test_batch_force_help_says_it_redoes_every_specimen():
    r = run("batch", "--help")
    assert r.exit_code == 0
    text = " ".join(r.output.split())
    assert ("--force Identify every specimen again, also those whose result in OUT is up to "
            "date (same specimen and FRF file, options and laminid version).") in text
    assert "Not 'overwrite the output' as in identify -o, modes, export, acquire." in text


def test_batch_mesh_check_is_identify_mesh_check_per_specimen(tmp_path):
    """batch --mesh-check checks each specimen alone, as identify --mesh-check: S1.1 at 6x6
    moves E1 by -0.82 of its half-width on 12x12 (coarse_mesh), and the batch's result file,
    summary.json, --json, summary.csv (long and wide) and table carry exactly identify's
    numbers; at 12x12 (0.17 half-width at most) it is fine. A batch up to date without the
    check is redone with it; without the flag the summaries keep their columns."""
    from laminid_cli.batch import LONG_COLUMNS, MESH_LONG_COLUMNS, csv_header
    from laminid_cli.report import report_pages
    from laminid_cli.resultfile import read_result

    specs = make_tree(tmp_path / "in", {"S1.1.yaml": "specimens/example1/S1.1.yaml"})
    out = tmp_path / "out"
    plain = run("batch", specs, "--mesh", "6x6", "--out", out)
    assert plain.exit_code == 0, plain.output
    with open(out / "summary.csv", newline="") as fh:
        assert tuple(next(csv.reader(without_comments(fh)))) == LONG_COLUMNS
    assert json.loads((out / "summary.json").read_text())["specimens"][0]["mesh_check"] is None
    assert read_result(out / "S1.1.result.h5").mesh_check is None
    r = run("batch", specs, "--mesh", "6x6", "--mesh-check", "--out", out, "--json")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["n_cached"] == 0 and doc["options"]["mesh_check"] is True   # redone
    row = doc["specimens"][0]
    one = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "6x6", "--mesh-check",
              "--json", "--no-output")
    ident = json.loads(one.stdout)
    mc = ident["mesh_check"]
    # the result file: identify's check, number for number
    back = read_result(out / "S1.1.result.h5").mesh_check
    assert back["text"] == mc["text"] != "" and back["labels"] == mc["labels"]
    for key, v in mc["modes"].items():
        np.testing.assert_array_equal(np.asarray(back["modes"][key]), np.asarray(v))
    assert back["constants"] == mc["constants"]
    assert ident["status"] == row["status"] == "check"
    assert [x for x in row["reasons"] if x["code"] == "coarse_mesh"] == \
        [x for x in ident["reasons"] if x["code"] == "coarse_mesh"]
    # the summary's figures
    s = row["mesh_check"]
    e1 = mc["constants"]["IM7/977-2"]["E1"]["shift_half_width"]
    assert s["worst"] == "IM7/977-2.E1" and s["max_shift_half_width"] == abs(e1)
    assert s["max_shift_half_width"] == pytest.approx(0.82, abs=0.01) and s["coarse_mesh"]
    assert s["max_change_sigma"] == max(abs(x) for x in mc["modes"]["change_sigma"])
    assert s["max_change_sigma"] == pytest.approx(10.06, abs=0.05) and s["fine_mesh"] == "12x12"
    assert json.loads((out / "summary.json").read_text())["specimens"][0]["mesh_check"] == s
    with open(out / "summary.csv", newline="") as fh:
        recs = list(csv.DictReader(without_comments(fh)))
    assert tuple(recs[0]) == LONG_COLUMNS + MESH_LONG_COLUMNS
    rec = next(x for x in recs if x["constant"] == "E1")
    assert float(rec["mesh_shift_half_width"]) == e1
    assert float(rec["mesh_max_shift_half_width"]) == s["max_shift_half_width"]
    assert float(rec["mesh_max_change_sigma"]) == s["max_change_sigma"]
    assert "coarse_mesh" in rec["reasons"].split(", ") and rec["status"] == "check"
    back_rows = read_summary(out / "summary.csv")
    assert back_rows[0]["mesh_check"]["max_shift_half_width"] == s["max_shift_half_width"]
    # the table and the report's residuals page
    t = run("batch", specs, "--mesh", "6x6", "--mesh-check", "--out", out)
    assert "up to date" in t.output
    table = t.output.splitlines()
    assert next(ln for ln in table if ln.startswith("mesh shift [hw]")).split() == \
        ["mesh", "shift", "[hw]", "0.82"]
    assert next(ln for ln in table if ln.startswith("mesh change [sigma]")).split()[-1] == \
        "10.06"
    assert "    coarse_mesh: the mesh is too coarse for these modes: at 12x12" in t.output
    fig = {p.name: p.figure for p in report_pages(out / "summary.csv")}["residuals"]
    words = [x.get_text() for x in fig.axes[0].texts]
    assert any("mesh shift 0.82 hw" in w for w in words), words
    # the wide summary: the two specimen figures before 'flagged'
    w = run("batch", specs, "--mesh", "6x6", "--mesh-check", "--out", out, "--wide")
    assert w.exit_code == 0
    with open(out / "summary.csv", newline="") as fh:
        head = next(csv.reader(without_comments(fh)))
    assert head == csv_header(["IM7/977-2"], mesh_check=True)
    k = head.index("flagged")           # (then the constants' sides of a bound: new ones last)
    assert head[k - 2:k + 1] == ["mesh_max_change_sigma", "mesh_max_shift_half_width", "flagged"]
    # 12x12: fine enough
    r = run("batch", specs, "--mesh", "12x12", "--mesh-check", "--out", tmp_path / "o12",
            "--json")
    assert r.exit_code == 0, r.output
    row = json.loads(r.stdout)["specimens"][0]
    assert not row["mesh_check"]["coarse_mesh"] and "coarse_mesh" not in row["reason"]
    assert 0.1 < row["mesh_check"]["max_shift_half_width"] < 0.3
    assert row["mesh_check"]["fine_mesh"] == "24x24"


def test_batch_mesh_check_is_in_help_and_refuses_a_too_fine_mesh(tmp_path):
    """--help names it; a mesh whose double is refused is a usage error before any work, as
    in identify (batch has no --joint: each specimen is checked alone)."""
    h = run("batch", "--help")
    words = " ".join(h.output.split())
    assert "--mesh-check As identify --mesh-check, for each specimen alone" in words
    specs = make_tree(tmp_path / "in", {"S1.1.yaml": "specimens/example1/S1.1.yaml"})
    r = run("batch", specs, "--mesh", "80x80", "--mesh-check", "--out", tmp_path / "o")
    one = run("identify", specs / "S1.1.yaml", "--mesh", "80x80", "--mesh-check",
              "--no-output")
    assert r.exit_code == one.exit_code == 2 and r.output == one.output, (r.output, one.output)
    assert r.output.startswith("laminid: error: mesh ")          # (160x160 or 80x80 too big)
    assert not (tmp_path / "o").exists()


def test_the_table_ties_a_column_to_its_reasons_when_name_and_file_differ(tmp_path):
    """good.yaml has 'name: S1.4': its column said "S1.4" and its reasons "good:", with
    nothing to tie them; the reasons now say "S1.4 (good):". A file named as its specimen
    keeps one name."""
    text = Path("specimens/example1/S1.4.yaml").read_text()
    assert "name: S1.4" in text
    specs = tmp_path / "in"
    specs.mkdir()
    (specs / "good.yaml").write_text(text)
    shutil.copy("specimens/example1/S1.1.yaml", specs / "S1.1.yaml")
    r = run("batch", specs, "--mesh", "6x6", "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert lines[0].split()[1:] == ["S1.1", "S1.4"]
    assert "  S1.4 (good):" in lines and "  S1.1:" in lines
    assert "  good:" not in lines


@pytest.mark.parametrize("n_jobs, scheduler, runs_on", [
    (1, None, "this process, one specimen after the other"),
    (4, None, "up to 4 worker processes, one specimen at a time in each"),
    (8, "local", "a local Dask cluster of 8 single-threaded worker processes, one specimen at "
                 "a time in each"),
    (1, "tcp://10.0.0.5:8786", "the workers of the Dask scheduler tcp://10.0.0.5:8786 (as many "
                               "as it has; -j does not apply), one specimen at a time in each")])
def test_batch_settings_say_where_the_specimens_ran(n_jobs, scheduler, runs_on):
    from laminid_cli.batch import batch_settings

    s = batch_settings(n_jobs, scheduler)
    assert (s["jobs"], s["scheduler"], s["runs_on"]) == (n_jobs, scheduler, runs_on)


@pytest.mark.parametrize("level, stderr", [(30, "warning: plate.yaml:25, field 'layup': x\n"),
                                           (40, "")])
def test_a_pool_workers_warnings_read_as_the_batchs_at_its_level(level, stderr):
    # a pool worker starts from a clean interpreter: a specimen's warning came out bare
    # (Python's last-resort handler, no "warning: "), and under -q (ERROR) too
    code = ("import logging; from laminid_cli.batch import _worker_init; "
            f"_worker_init(1, {level}); logging.getLogger('laminid_cli.specimen')"
            ".warning(\"plate.yaml:25, field 'layup': x\")")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       cwd=Path(__file__).resolve().parents[1], timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stderr == stderr


def test_the_table_lists_each_results_warnings_below_it():
    """The text table said nothing of a result's warnings (summary.json has them): they follow
    the reasons of the checks, per specimen, and the table's rows are unchanged."""
    from laminid_cli.batch import format_table

    consts = {"E1": 150e9, "E2": 9e9, "G12": 5e9, "G13": 3.1e9, "G23": 2.95e9, "nu12": 0.35}
    row = {"name": "p", "specimen": "P", "status": "check", "cached": False, "reason": "",
           "reasons": [{"code": "poor_fit", "text": "the fit misses"}],
           "materials": {"m": consts}, "intervals": {"m": {k: {} for k in consts}},
           "rms_residual_percent": 0.3, "evaluations": 40}
    quiet = {**row, "name": "q", "specimen": "Q", "status": "ok", "reasons": [], "warnings": []}
    before = format_table([row, quiet])
    row["warnings"] = ["p.yaml:5, field 'mass': the model mass differs", "a coarse mesh"]
    lines = format_table([row, quiet]).splitlines()
    assert lines[:len(before.splitlines())] == before.splitlines()
    assert lines[len(before.splitlines()):] == [
        "warnings:", "  P (p):", "    p.yaml:5, field 'mass': the model mass differs",
        "    a coarse mesh"]


def test_batch_text_output_names_a_specimens_warning_once(tmp_path):
    """End to end, in a process of its own (the terminal's two streams): the warning of a
    specimen whose ply angles look like radians is said once. The reader logs it on stderr as
    it reads the file; the list below the table repeated it (twice on the terminal), and now
    keeps only what stderr did not say: the warnings of a result up to date (not read this
    run), and all of them under -q (nothing on stderr)."""
    import re

    text = Path("specimens/example2/S2.1.yaml").read_text()
    text = re.sub(r'(?m)^layup: .*$', 'layup: "[(0/1.5)_2/1.5/0/1.5]s"', text)
    text = re.sub(r"(?m)^  frequencies: \[.*$", "  frequencies: [61.39, 82.25, 170.02, 178.53, "
                  "305.33, 337.99, 426.78, 456.58]", text)
    spec = tmp_path / "rad.yaml"
    spec.write_text(text)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith("layup:"))
    warning = (f"{spec}:{line}, field 'layup': the ply angles 1.5 look like radians; laminid "
               "reads ply angles in degrees (write 85.94)")
    root = Path(__file__).resolve().parents[1]

    def batch(*args):
        p = subprocess.run([sys.executable, "-m", "laminid_cli", *args, "batch", str(spec),
                            "--out", str(tmp_path / "out"), "--mesh", "8x8"],
                           capture_output=True, text=True, cwd=root, timeout=120)
        assert p.returncode == 0, p.stderr
        return p

    p = batch()
    assert p.stderr.count(warning) == 1 and f"warning: {warning}\n" in p.stderr
    assert warning not in p.stdout           # the run's own warnings are still listed there
    for p in (batch(), batch("-q")):        # up to date: not read, so not on stderr
        assert warning not in p.stderr
        below = p.stdout.split("\nwarnings:\n", 1)[1].splitlines()
        assert below[:2] == ["  S2.1 (rad):", f"    {warning}"]
    (tmp_path / "out" / "rad.result.h5").unlink()
    p = batch("-q")                         # -q: read again, nothing on stderr, all below
    assert p.stderr == ""
    below = p.stdout.split("\nwarnings:\n", 1)[1].splitlines()
    assert below[:2] == ["  S2.1 (rad):", f"    {warning}"]

@pytest.mark.parametrize("name", ["summary.csv", "summary.json"])
def test_a_summary_saved_with_a_bom_reads_as_without(batch_run, tmp_path, name):
    """A summary opened and saved again in an editor on Windows (Excel's 'CSV UTF-8', Notepad)
    begins with a UTF-8 BOM: report refused it ('not a laminid batch summary (columns name,
    status, ... expected)', its first column read as '\\ufeffname'; JSON: 'Unexpected UTF-8
    BOM'). It is read as the file without one: the same rows, E1 to the last digit."""
    _, out, _ = batch_run
    bom = tmp_path / name
    bom.write_bytes(b"\xef\xbb\xbf" + (out / name).read_bytes().replace(b"\n", b"\r\n"))
    want = read_summary(out / name)
    got = read_summary(bom)
    assert [r["name"] for r in got] == [r["name"] for r in want]
    assert got[0]["materials"]["IM7/977-2"]["E1"] == want[0]["materials"]["IM7/977-2"]["E1"]


def test_an_entry_named_yaml_that_is_no_file_is_said_skipped(tmp_path):
    """A folder searched for *.yaml holding a folder named x.yaml (nothing in it), a broken
    link named dead.yaml: passed over without a word (only 'no specimen file found'); each is
    a warning naming it and what it is, as a *.yaml file that is no specimen is. A folder
    named *.yml whose specimens are taken is searched as any other, no warning."""
    specs = tmp_path / "in"
    (specs / "x.yaml").mkdir(parents=True)
    (specs / "dead.yaml").symlink_to(tmp_path / "nowhere.yaml")
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert (r.exit_code, r.stderr) == (2, (
        f"warning: {specs / 'dead.yaml'}: a broken symbolic link, not a specimen file; "
        "skipped\n"
        f"warning: {specs / 'x.yaml'}: a folder, not a specimen file (YAML text), with no "
        "specimen file in it; skipped\n"
        f"laminid: error: no specimen file (*.yaml, *.yml) found in {specs}\n"))
    (specs / "full.yml").mkdir()
    (specs / "full.yml" / "p1.yaml").write_text("x")
    skipped = []
    found = discover_specimens([specs], skipped=skipped)
    assert [n for _, n in found] == ["full.yml/p1"]
    assert sorted(p.name for p, _ in skipped) == ["dead.yaml", "x.yaml"]


def test_a_batch_name_with_a_bidi_override_is_refused_or_skipped(tmp_path):
    """The batch name comes from the file's path and goes into the progress lines, both
    summaries and the result's file name: a right-to-left override in it ('S1\\u202e1.yaml'
    listed as 'S11.yaml' backwards) went there as it was, even with a 'name:' in the file.
    A file found in a folder is skipped with a warning, one named among the inputs refused,
    each naming the character with the path escaped; nothing written."""
    specs = tmp_path / "in"
    specs.mkdir()
    bad = specs / "S1\u202e1.yaml"
    bad.write_text(SPECS["example2/S2.1.yaml"])
    shown = f"{specs}/S1\\u202e1.yaml"
    words = ("its batch name 'S1\\u202e1', from the file's path: non-printable character "
             "U+202E (RIGHT-TO-LEFT OVERRIDE) in it; rename the file")
    r = run("batch", specs, "--mesh", MESH, "--out", tmp_path / "out")
    assert (r.exit_code, r.stderr) == (2, (
        f"warning: {shown}: {words}; skipped\n"
        f"laminid: error: no specimen file (*.yaml, *.yml) found in {specs}\n"))
    r = run("batch", bad, "--mesh", MESH, "--out", tmp_path / "out")
    assert r.exit_code == 2 and r.stderr.startswith(f"laminid: error: {shown}: {words}; ")
    assert "\u202e" not in r.stderr and not (tmp_path / "out").exists()
