"""`laminid identify` end to end through click: report, JSON, HDF5, errors, exit codes."""

import json
import logging
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from laminid_cli.modal import default_factorizer
from laminid_cli.results import read_h5
from tests.clihelp import run, write_s14_with_ranges

S21 = "specimens/example2/S2.1.yaml"


@pytest.fixture(scope="module")
def s21_result(s21_8x8):
    return s21_8x8                      # conftest.py: identify S2.1 --mesh 8x8 --json -o


def test_json_has_the_documented_keys_in_si(s21_result):
    d, _ = s21_result
    mat = d["materials"]["E-glass/R368"]
    assert set(mat) >= {"E1", "E2", "G12", "G13", "G23", "nu12"}
    # Pa: the paper's Table 3 gives 28.8 GPa; this 8x8 mesh 28.73 GPa (measured), within 1 %
    assert mat["E1"] == pytest.approx(28.8e9, rel=0.01)
    assert mat["G12"] == pytest.approx(2.7e9, rel=0.05)               # Table 3: 2.7 GPa
    fr = d["frequencies"]
    assert len(fr["measured"]) == len(fr["model"]) == len(fr["residual_percent"]) == 12
    m, x = np.array(fr["model"]), np.array(fr["measured"])
    assert np.allclose(fr["residual_percent"], (x - m) / x * 100)
    assert d["converged"] is True and d["iterations"] >= 3
    assert d["rms_residual_percent"] < 0.5 and d["objective"] > 0
    assert set(d["global_properties"]) >= {"Ex", "Ey", "Gxy", "Gxz", "Gyz", "nu_xy", "nu_yx"}


def test_json_says_the_unit_of_every_number(s21_result):
    """identify --json gave E1 2.87e10, a 0.2, sigma_hz, covariance 1e18 ... with no unit
    anywhere; "units" names them by field (as modes --json and show --json)."""
    d, _ = s21_result
    u = d["units"]
    assert {k: u[k] for k in ("a", "h", "mass", "E1", "G23", "nu12", "Ex", "nu_xy",
                              "frequencies", "measured", "model", "sigma_hz",
                              "residual_percent", "time_s")} == {
        "a": "m", "h": "m", "mass": "kg", "E1": "Pa", "G23": "Pa", "nu12": "1", "Ex": "Pa",
        "nu_xy": "1", "frequencies": "Hz", "measured": "Hz", "model": "Hz", "sigma_hz": "Hz",
        "residual_percent": "%", "time_s": "s"}
    assert u["lower"] == u["upper"] == u["std"] == "unit of the quantity it belongs to"
    assert u["covariance"].startswith("product of the units")
    assert "model_mass" not in u and "density" not in u       # not in identify's document
    assert d["uncertainty"]["constants"]["E-glass/R368"]["E1"]["lower"] > 1e10   # Pa indeed


def test_hdf5_result_is_self_describing_and_matches_json(s21_result):
    d, out = s21_result
    h = read_h5(out)
    assert h["@attrs"]["format"] == "laminid-result" and h["@attrs"]["converged"]
    assert "(0/90)_2" in h["specimen"]["yaml"]
    name = next(k for k in h["materials"] if not k.startswith("@"))
    assert h["materials"][name]["E1"] == pytest.approx(next(iter(d["materials"].values()))["E1"])
    assert h["history"]["objective"].shape == (d["evaluations"],)
    assert h["history"]["objective"][-1] == pytest.approx(d["objective"], rel=1e-12)
    assert h["sensitivities"]["dlnf_dlnP"].shape == (12, 6)
    assert h["modes"]["w"].shape[1] == 12
    assert np.allclose(h["frequencies"]["model"], d["frequencies"]["model"])
    import h5py
    with h5py.File(out) as f:
        for path in ("frequencies/model", "materials/" + name + "/E1", "history/objective",
                     "sensitivities/dlnf_dlnP", "global_properties/Ex", "modes/w"):
            assert "units" in f[path].attrs, path


def test_report_and_default_output_next_to_the_specimen(tmp_path):
    spec = tmp_path / "S2.1.yaml"
    shutil.copy(S21, spec)
    r = run("identify", str(spec), "--mesh", "6x6")
    assert r.exit_code == 0, r.output
    assert "LD_SLSQP: converged" in r.output
    label = {"cholmod": "CHOLMOD", "banded": "banded Cholesky"}[default_factorizer()]
    assert re.search(rf"\d+ evaluations, \d+\.\d\d s \(reduced solver, {label}, bending "
                     r"equations\)", r.output)
    assert "E1 [GPa]" in r.output and "residual %" in r.output and "RMS residual" in r.output
    assert (tmp_path / "S2.1.result.h5").exists()
    # a second run after editing the specimen: the derived default file is replaced, and said so
    spec.write_text(spec.read_text() + "# re-weighed\n")
    r = run("identify", str(spec), "--mesh", "6x6")
    assert r.exit_code == 0, r.output
    assert "replaced the previous result of this specimen" in r.output
    with h5py.File(tmp_path / "S2.1.result.h5") as f:
        assert "# re-weighed" in f["specimen"]["yaml"][()].decode()
    # a file named with -o is never overwritten silently
    named = str(tmp_path / "mine.h5")
    assert run("identify", str(spec), "--mesh", "6x6", "-o", named).exit_code == 0
    r = run("identify", str(spec), "--mesh", "6x6", "-o", named)
    assert r.exit_code == 2 and "file exists" in r.output and "--force" in r.output
    assert run("identify", str(spec), "--mesh", "6x6", "-o", named, "--force").exit_code == 0
    # something else at the default name is not a derived result: refused, left alone
    (tmp_path / "S2.1.result.h5").write_text("my notes")
    r = run("identify", str(spec), "--mesh", "6x6")
    assert r.exit_code == 2 and "not a laminid result file" in r.output
    assert (tmp_path / "S2.1.result.h5").read_text() == "my notes"


def test_a_reference_range_is_shown_as_the_range_on_the_terminal_and_in_json(tmp_path):
    """E1: [120 GPa, 150 GPa] and global nu_xy: [0.05, 0.07] in the specimen: the terminal
    gives both ends in the interval columns' form (once it gave the midpoint, 135.00 and
    0.060, as if measured); --json gives [low, high] where a single value stays a number."""
    spec = write_s14_with_ranges(tmp_path)
    r = run("identify", spec, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 0, r.output
    rows = {ln.split()[0]: ln for ln in r.output.splitlines() if " [GPa] " in ln}
    assert re.match(r"  E1 \[GPa\] +117\.20 +\d+\.\d\d  120\.00 \.\. 150\.00   ", rows["E1"])
    assert re.match(r"  E2 \[GPa\] +8\.80 +\d+\.\d\d +10\.00   ", rows["E2"])
    # the reference column is as wide as the range: the header's word ends above its end
    head = next(ln for ln in r.output.splitlines() if ln.startswith("  constant"))
    assert head.index("reference") + len("reference") == rows["E1"].index("150.00") + 6
    assert "    reference: nu_xy 0.050 .. 0.070" in r.output.splitlines()
    assert "135.00" not in r.output and "0.060" not in r.output
    r = run("identify", spec, "--mesh", "6x6", "--no-output", "--json")
    assert r.exit_code == 0, r.output
    ref = json.loads(r.output)["reference"]
    assert ref["materials"]["IM7/977-2"] == {"E1": [120e9, 150e9], "E2": 10e9, "G12": 5.8e9,
                                             "nu12": 0.35}
    assert ref["global"] == {"nu_xy": [0.05, 0.07]}


def test_non_convergence_exits_1_with_message_and_keeps_a_complete_file(tmp_path):
    out = tmp_path / "r.h5"
    r = run("identify", S21, "--mesh", "6x6", "--max-evaluations", "3", "-o", str(out))
    assert r.exit_code == 1
    assert "NOT CONVERGED" in r.output and "evaluations ran out" in r.output
    # the constants' table says its values and verdicts are the last point's, not an optimum's
    head = next(ln for ln in r.output.splitlines() if ln.startswith("  constant"))
    assert head.split()[:3] == ["constant", "initial", "last"]
    assert ("  (NOT CONVERGED: the values, intervals and verdicts are those of the last point, "
            "not of an optimum)") in r.output.splitlines()
    assert read_h5(out)["@attrs"]["converged"] is False or read_h5(out)["@attrs"]["converged"] == 0


def test_fix_and_mma_options(tmp_path):
    r = run("identify", S21, "--mesh", "6x6", "--fix", "nu12,G13,G23", "--optimizer", "mma",
            "--json", "--no-output")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    mat = next(iter(d["materials"].values()))
    init = next(iter(d["initial"].values()))
    assert mat["nu12"] == init["nu12"] and mat["G13"] == init["G13"] and mat["G23"] == init["G23"]
    assert d["optimizer"] == "LD_MMA" and d["rms_residual_percent"] < 1.0


def write_variant(tmp_path, old, new):
    p = tmp_path / "v.yaml"
    text = Path(S21).read_text()
    assert old in text
    p.write_text(text.replace(old, new))
    return str(p)


def test_one_frequency_for_six_constants_names_the_field_and_what_to_do(tmp_path):
    """One measured mode for six free constants: "1 weighted frequency" (was "1 weighted
    frequencies for 6 free constants" with no field, line or count to fix)."""
    few = write_variant(tmp_path, "[72.78, 121.00, 191.38, 286.78, 315.12, 340.40, 400.12, "
                        "433.84, 634.81, 653.56, 712.43, 789.97]", "[72.78]")
    line = next(k for k, t in enumerate(Path(few).read_text().splitlines(), 1)
                if t.strip().startswith("frequencies:"))
    r = run("identify", few, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 2, r.output
    assert r.stderr == (
        f"laminid: error: {few}:{line}, field 'measured.frequencies': 1 weighted frequency for "
        "6 free constants (the fit needs at least one per constant): measure more modes, or fix "
        "5 or more of the constants (--fix, e.g. --fix nu12,G13,G23, which a thin plate's modes "
        "determine worst, or the material's 'fixed:' list)\n")
    assert r.stdout == ""


def test_bad_input_exit_2_with_clear_message(tmp_path):
    r = run("identify", S21, "--fix", "nu13")
    assert r.exit_code == 2 and "'nu13' is not a constant" in r.output
    r = run("identify", S21, "--fix", "steel.nu12")
    assert r.exit_code == 2 and "no material 'steel'" in r.output
    # all six constants fixed
    r = run("identify", S21, "--fix", "E1,E2,G12,G13,G23,nu12", "--no-output")
    assert r.exit_code == 2 and "nothing to identify" in r.output
    # frequencies far from the model at the initial guess (mass 10x too large)
    far = write_variant(tmp_path, "mass: 0.2571 kg", "mass: 2.571 kg")
    r = run("identify", far, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 2 and "away from the model" in r.output and "Traceback" not in r.output
    # fewer weighted frequencies than free constants
    few = write_variant(tmp_path, "[72.78, 121.00, 191.38, 286.78, 315.12, 340.40, 400.12, "
                        "433.84, 634.81, 653.56, 712.43, 789.97]", "[72.78, 121.00, 191.38]")
    r = run("identify", few, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 2 and "3 weighted frequencies for 6 free constants" in r.output
    assert "field 'measured.frequencies'" in r.output
    # every weight zero
    zero = write_variant(tmp_path, "789.97]   # Hz, Table 5",
                         "789.97]\n  weights: [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]")
    r = run("identify", zero, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 2 and "weight 0" in r.output
    assert not list(tmp_path.glob("*.h5"))


def test_an_optimum_on_a_feasibility_bound_names_the_constraint(s21_6x6):
    """S2.1 (thin glass plate) drives G13 to its floor: the warning says which constraint holds
    (identify S2.1 --mesh 6x6 --json, conftest.py)."""
    r = s21_6x6[0]
    assert r.exit_code == 0, r.output
    warnings = " ".join(json.loads(r.output)["warnings"])
    assert "runs into a bound" in warnings and "G13 at its minimum (0.0001 E1)" in warnings


def test_huge_interval_ends_print_in_exponent_form():
    """An undetermined constant's interval can run to 4e25 GPa (S1.3 G13, log-space interval):
    printed as 4.17e+25, not with 26 digits; ordinary values keep their fixed decimals."""
    from laminid_cli.commands.text import _num

    assert _num("G13", 4.1736501225891e34) == "4.17e+25"
    assert _num("G23", 1.82e14) == "1.82e+05"
    assert _num("E1", 163.46e9) == "163.46"
    assert _num("nu12", -0.0193) == "-0.019"
    # a modulus at its floor (0.0001 E1): 3 significant digits, not "0.00"
    assert _num("G13", 2.9936e6) == "0.00299" and _num("G23", 0.0) == "0.00"


def test_the_report_laminate_line_writes_moduli_with_the_terminals_digits():
    """The report's laminate line repeated the terminal's digit rule by hand (3 significant
    below 1 GPa) and wrote an undetermined interval end of 1e5 GPa and more with all its
    digits; both now write moduli through laminid_cli.units.gpa_text."""
    from types import SimpleNamespace

    from laminid_cli.commands.text import _num
    from laminid_cli.report import _laminate_text
    from laminid_cli.units import gpa_text

    assert [gpa_text(v) for v in (117.2e9, 2.9936e6, 0.0, 3.1e20, -5e8)] == [
        "117.20", "0.00299", "0.00", "3.10e+11", "-0.5"]
    plate = SimpleNamespace(global_properties={"Ex": 2.9936e6, "Gxz": 3.1e20, "nu_xy": 0.31},
                            reference_global={}, global_uncertainty={})
    text = _laminate_text(plate)
    for k, v in (("Ex", 2.9936e6), ("Gxz", 3.1e20)):
        assert f"{k} {_num('G13', v)} GPa" in text, text
    assert "Ex 0.00299 GPa" in text and "Gxz 3.10e+11 GPa" in text and "nu_xy 0.310" in text


def test_default_result_of_another_specimen_file_is_not_replaced(tmp_path):
    """plate.yaml and plate.yml derive the same plate.result.h5: the second identify refuses
    to replace the first one's result (exit 2) and says how to name its own."""
    shutil.copy("specimens/example1/S1.1.yaml", tmp_path / "plate.yaml")
    shutil.copy(S21, tmp_path / "plate.yml")
    r = run("identify", tmp_path / "plate.yaml", "--mesh", "6x6")
    assert r.exit_code == 0, r.output
    r = run("identify", tmp_path / "plate.yml", "--mesh", "6x6")
    assert r.exit_code == 2
    assert "holds the result of another specimen file (plate.yaml); name this one's result " \
           "with -o" in r.output
    with h5py.File(tmp_path / "plate.result.h5") as f:
        assert f["specimen"].attrs["name"] == "S1.1"
    # the same file again: replaced, as before
    r = run("identify", tmp_path / "plate.yaml", "--mesh", "6x6")
    assert r.exit_code == 0 and "replaced the previous result" in r.output


def test_joint_refuses_the_same_file_twice(tmp_path):
    r = run("identify", S21, "./" + S21, "--joint", "--no-output")
    assert r.exit_code == 2
    assert "the same specimen file as" in r.output and "counts once" in r.output


@pytest.mark.parametrize("solver", ["reduced", "full"])
def test_max_evaluations_caps_the_whole_identification(solver):
    """--max-evaluations bounds the evaluations of every stage together (the reduced solver ran
    one budget per stage before: S1.1 with 20 took 71), the answer's final check included
    (the reduced loop keeps 5 for it and an enrichment). S1.1 at 8x8 needs 94 reduced / 28
    full evaluations to converge. (Refused infeasible points count for nlopt, not here.)"""
    r = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "8x8", "--solver", solver,
            "--max-evaluations", "20", "--json", "--no-output")
    assert r.exit_code == 1, r.output
    d = json.loads(r.stdout)
    assert d["converged"] is False and "--max-evaluations 20 evaluations ran out" in d["optimizer_status"]
    assert 15 <= d["evaluations"] <= 20


@pytest.mark.parametrize("solver", ["reduced", "full"])
def test_max_evaluations_holds_across_re_anchoring_passes(solver):
    """S2.2 re-anchors its pairing and runs a second pass from the start: the cap still bounds
    the evaluations of all passes together (a spent budget runs no later stage)."""
    r = run("identify", "specimens/example2/S2.2.yaml", "--mesh", "8x8", "--solver", solver,
            "--max-evaluations", "30", "--json", "--no-output")
    d = json.loads(r.stdout)
    assert d["evaluations"] <= 30 and d["converged"] is False and r.exit_code == 1


def test_quiet_identify_keeps_its_notes_off_stderr(tmp_path):
    """laminid -q: only errors on stderr; identify's notes (here: the measured damping is not
    used with --joint) still went there. Without -q they do."""
    specs = []
    for name in ("S1.1", "S1.2"):
        text = Path(f"specimens/example1/{name}.yaml").read_text(encoding="utf-8")
        n = len(re.search(r"frequencies: \[([^\]]*)\]", text).group(1).split(","))
        text = text.replace("measured:\n", "measured:\n  damping: [" +
                            ", ".join(["0.01"] * n) + "]\n", 1)
        specs.append(tmp_path / f"{name}.yaml")
        specs[-1].write_text(text, encoding="utf-8")
    args = ["identify", *specs, "--joint", "--mesh", "4x4", "--no-output"]
    r = run(*args)
    assert r.exit_code == 0, r.output
    assert "laminid: note: the measured damping is not used with --joint" in r.stderr
    r = run("-q", *args)
    assert r.exit_code == 0, r.output
    assert r.stderr == "" and "E1" in r.stdout


def test_joint_refuses_a_copy_of_a_specimen_file_under_another_name(tmp_path):
    copy = tmp_path / "S2.1-copy.yaml"
    copy.write_text(Path(S21).read_text().replace("name: S2.1", "name: S2.1b"))
    r = run("identify", S21, copy, "--joint", "--no-output")
    assert r.exit_code == 2
    assert r.output.startswith(f"laminid: error: {copy}: the same plate data as {S21} (the same "
                               "measured frequencies, geometry, mass and layup")
    assert "Traceback" not in r.output


def test_a_specimen_that_now_fails_has_its_earlier_default_result_set_aside(tmp_path):
    """identify failing on a specimen left its earlier default result beside it, a
    *.result.h5 of another input; it is renamed out of the pattern as batch does (bytes kept,
    never over an earlier stale file), and a file named with -o is left alone."""
    spec = tmp_path / "plate.yaml"
    good = Path(S21).read_text()
    spec.write_text(good)
    assert run("identify", spec, "--mesh", "6x6").exit_code == 0
    first = (tmp_path / "plate.result.h5").read_bytes()
    (tmp_path / "plate.result.stale.h5").write_bytes(b"older")
    spec.write_text(good.replace("mass: 0.2571 kg", "mass: [0.2571 kg"))
    r = run("identify", spec, "--mesh", "6x6")
    assert r.exit_code == 2
    lines = r.output.splitlines()
    assert lines[0] == (f"laminid: {tmp_path / 'plate.result.h5'}: the earlier result of "
                        f"another input moved to {tmp_path / 'plate.result.stale1.h5'}")
    assert lines[1].startswith(f"laminid: error: {spec}") and len(lines) == 2
    assert not (tmp_path / "plate.result.h5").exists()
    assert (tmp_path / "plate.result.stale1.h5").read_bytes() == first
    assert (tmp_path / "plate.result.stale.h5").read_bytes() == b"older"
    mine = tmp_path / "mine.h5"
    mine.write_bytes(first)
    r = run("identify", spec, "--mesh", "6x6", "-o", mine, "--force")
    assert r.exit_code == 2 and "moved" not in r.output
    assert mine.read_bytes() == first


def test_a_missing_specimen_is_named_before_its_output_and_leaves_the_earlier_result(
        tmp_path):
    """identify /nope/x.yaml said "/nope/x.result.h5: folder /nope does not exist", and a
    specimen path that names no file set aside the default result of that name as another
    input's: a path is no specimen that now fails. Both say the specimen is not found."""
    missing = tmp_path / "nope" / "plate.yaml"
    r = run("identify", missing)
    assert r.exit_code == 2
    assert r.output == f"laminid: error: {missing}: file not found\n"
    earlier = tmp_path / "plate.result.h5"
    earlier.write_bytes(b"an earlier result")
    r = run("identify", tmp_path / "plate.yaml")
    assert r.exit_code == 2
    assert r.output == f"laminid: error: {tmp_path / 'plate.yaml'}: file not found\n"
    assert earlier.read_bytes() == b"an earlier result"
    assert not list(tmp_path.glob("*.stale*"))


@pytest.mark.parametrize("fix, said", [
    ("g13", "--fix g13: 'g13' is not a constant; choose from E1, E2, G12, G13, G23, nu12; did "
            "you mean 'G13'?"),
    ("IM7/977-2.g23", "--fix IM7/977-2.g23: 'IM7/977-2.g23' is not a constant; choose from E1, "
                      "E2, G12, G13, G23, nu12; did you mean 'IM7/977-2.G23'?"),
    ("NU12", "--fix NU12: 'NU12' is not a constant; choose from E1, E2, G12, G13, G23, nu12; "
             "did you mean 'nu12'?"),
    ("G14", "--fix G14: 'G14' is not a constant; choose from E1, E2, G12, G13, G23, nu12"),
], ids=["g13", "material.g23", "NU12", "no guess"])
def test_a_fix_in_the_wrong_case_names_the_constant_meant(fix, said):
    """--fix g13 was refused with the list of constants only, G13 among them, leaving the lab
    to see that the names are case-sensitive: the constant meant is named."""
    r = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "4x4", "--fix", fix,
            "--no-output")
    assert r.exit_code == 2, r.output
    assert r.stderr == f"laminid: error: {said}\n"


def test_a_mistyped_fix_is_refused_before_any_work_and_leaves_the_earlier_result(tmp_path):
    """--fix G14 is a usage error, not a specimen that now fails: it is refused before the
    run, and the default result of the (unchanged) specimen stays where it is (it was set
    aside as 'the earlier result of another input')."""
    spec = tmp_path / "plate.yaml"
    spec.write_text(Path(S21).read_text())
    assert run("identify", spec, "--mesh", "6x6").exit_code == 0
    first = (tmp_path / "plate.result.h5").read_bytes()
    for fix, words in (("G14", "--fix G14: 'G14' is not a constant; choose from E1, E2, G12"),
                       ("E1=3", f"--fix E1=3: an elastic constant is fixed at its initial "
                                f"value in {spec}; write '--fix E1'"),
                       ("eta13=2", "--fix eta13=2"),
                       # options that do not fit this specimen: still not a new input
                       ("glass.nu12", "--fix glass.nu12: no material 'glass' in"),
                       ("E1,E2,G12,G13,G23,nu12", f"{spec}: every constant is fixed; "
                                                  "nothing to identify")):
        r = run("identify", spec, "--mesh", "6x6", "--fix", fix)
        assert r.exit_code == 2, r.output
        assert r.output.startswith(f"laminid: error: {words}"), r.output
        assert len(r.output.splitlines()) == 1 and "moved" not in r.output
        assert (tmp_path / "plate.result.h5").read_bytes() == first
        assert not list(tmp_path.glob("*.stale*"))


def test_refused_optimiser_points_are_named_as_the_optimisers_not_trials(monkeypatch):
    """S2.2 (6x6): SLSQP proposes points outside Eq. 22's region (1 with CHOLMOD and numpy
    2.4; 3 or 8 with the banded Cholesky; none with numpy 2.5 on Python 3.13: the count
    depends on the library builds' last digits), so the optimiser's first two proposals are
    refused here as such a point is, whatever the build. The warning said "1 trial point(s)
    outside the feasible region were refused", which a lab reads as a Monte Carlo trial lost;
    it names the optimiser, the region's conditions and that the search went on."""
    import dataclasses

    from laminid_cli.objective import Objective

    real, calls = Objective.evaluate, []

    def refusing(self, x, *args, **kwargs):
        ev = real(self, x, *args, **kwargs)
        calls.append(ev.objective)
        if len(calls) in (2, 3):
            return dataclasses.replace(ev, objective=float("nan"), refused=True,
                                       reasons=("forced by the test",), phi=None, modes=None)
        return ev

    monkeypatch.setattr(Objective, "evaluate", refusing)
    r = run("identify", "specimens/example2/S2.2.yaml", "--mesh", "6x6", "--json",
            "--no-output")
    assert r.exit_code == 0, r.output
    w = [x for x in json.loads(r.stdout)["warnings"] if "feasible region" in x]
    assert len(w) == 1
    n = int(w[0].split("proposed ")[1].split(" ")[0])
    assert n >= 2
    assert w[0] == (f"the optimiser proposed {n} point{'s' * (n > 1)} outside the feasible "
                    "region of Eq. 22 (E2 <= E1, |nu12| < 0.95, positive moduli); "
                    f"{'it was' if n == 1 else 'each was'} refused without evaluating the "
                    "model and the search went on inside the region")


def test_frequencies_in_khz_get_the_khz_hint_from_identify_as_from_modes(tmp_path):
    """The same file for both commands: modes warned "look like kHz", identify refused it
    naming only units, mass/density, geometry and constants."""
    text = Path("specimens/example1/S1.1.yaml").read_text()
    khz = "[0.12505, 0.20350, 0.33130, 0.44665, 0.49355, 0.60380, 0.65075, 0.81870, 0.95135, " \
          "0.99065, 1.25675, 1.34380]"
    spec = tmp_path / "khz.yaml"
    spec.write_text(re.sub(r"frequencies: \[[^\]]*\]", f"frequencies: {khz}", text))
    hint = ("the measured frequencies look like kHz: write them in Hz (a bare number is Hz) or "
            "with their unit, '0.125 kHz'")
    r = run("identify", spec, "--mesh", "4x4", "--no-output")
    assert r.exit_code == 2, r.output
    assert f"{spec}: measured mode 1 (0.125 Hz) is 84252 % away from the model (105.48 Hz)" \
        in r.stderr, r.stderr                   # 0.12505 Hz was shown as 0.13 Hz
    assert r.stderr.rstrip().endswith(f"at the initial guess (limit 50 %): {hint}"), r.stderr
    r = run("modes", spec, "--mesh", "4x4")
    assert r.exit_code == 0 and hint in r.stderr


def test_moduli_written_in_mpa_are_refused_with_the_unit_hint(tmp_path):
    """S1.1 with its moduli written in MPa (every one: each alone is a plausible modulus, and
    the six are admissible): identify refused the start naming 'the units, the mass/density,
    the geometry and the initial constants'; the model's frequencies 1/37 of the measured ones
    now point at the moduli's units, in identify's refusal and modes' warning alike."""
    spec = tmp_path / "mpa.yaml"
    spec.write_text(re.sub(r" GPa$", " MPa", Path("specimens/example1/S1.1.yaml").read_text(),
                           flags=re.M))
    hint = ("the model's frequencies are 1/36 of the measured ones, as with moduli 1000 times "
            "too small (frequency goes as sqrt(modulus/density)): check the moduli's units "
            "(MPa written where GPa is meant?), then the mass/density")     # 1/37 at 12x12
    r = run("identify", spec, "--mesh", "4x4")
    assert r.exit_code == 2, r.output
    assert r.stderr == (f"laminid: error: {spec}: measured mode 1 (125.05 Hz) is 97 % away from "
                        f"the model (3.34 Hz) at the initial guess (limit 50 %): {hint}\n")
    assert r.stdout == "" and not (tmp_path / "mpa.result.h5").exists()
    r = run("modes", spec, "--mesh", "4x4")
    assert r.exit_code == 0 and hint in r.stderr


def test_a_mesh_too_coarse_for_the_measured_modes_is_warned_as_modes_warns(tmp_path):
    """identify --mesh 3x3 on S1.1 (360 equations for 12 modes) said nothing of the mesh
    (modes warned of it): its status was poor_fit, naming 'a mesh too coarse' among five
    causes. The result's warnings (terminal, --json, the file) now carry modes' words; the
    count is the whole plate's equations, not the bending model's the fit runs on."""
    spec = "specimens/example1/S1.1.yaml"
    words = ("the mesh 3x3 (360 equations) is coarse for 12 modes: 30 equations per mode, "
             "fewer than 150, where the highest mode computed is typically 1 % or more off a "
             "converged mesh. Use --mesh 8x8 or finer, and check a mesh with 'laminid "
             "identify --mesh-check'")
    r = run("identify", spec, "--mesh", "3x3", "--fix", "nu12,G13,G23", "--json", "--no-output")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["equations"] == "bending" and f"{spec}: {words}" in doc["warnings"]
    r = run("modes", spec, "--mesh", "3x3")
    assert r.exit_code == 0 and f"warning: {spec}: {words}" in r.stderr
    r = run("identify", spec, "--mesh", "8x8", "--fix", "nu12,G13,G23", "--json",
            "--no-output")                              # 2025 equations: 169 per mode
    assert r.exit_code == 0, r.output
    assert not any("coarse" in w for w in json.loads(r.stdout)["warnings"])


def test_ctrl_c_during_the_monte_carlo_says_nothing_was_written(tmp_path, monkeypatch):
    """The result file is written whole when every step has finished: a Ctrl-C during the
    Monte Carlo (or the profiles) left no file and said only "laminid: interrupted". It now
    says nothing was written to -o, and that an earlier result there is left as it was."""
    import laminid_cli.uncertainty as uncertainty

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    out = tmp_path / "r.h5"
    monkeypatch.setattr(uncertainty, "monte_carlo", interrupted)
    r = run("identify", "specimens/example1/S1.4.yaml", "--mesh", "4x4", "--monte-carlo", "10",
            "-o", out)
    assert r.exit_code == 130, r.output
    assert (f"laminid: nothing written to {out}: the result is written when every step has "
            "finished\n") in r.stderr
    assert not out.exists()
    out.write_bytes(b"an earlier result")
    r = run("identify", "specimens/example1/S1.4.yaml", "--mesh", "4x4", "--monte-carlo", "10",
            "-o", out, "--force")
    assert r.exit_code == 130, r.output
    assert "finished (an earlier result there is left as it was)" in r.stderr
    assert out.read_bytes() == b"an earlier result"


def test_jobs_sets_the_processes_of_the_profiles_and_the_monte_carlo_as_its_help_says(
        tmp_path, monkeypatch):
    """-j's help said "Processes for the Monte Carlo trials" only; the profiles of the
    constants on a search limit (S2.1: G13) run in -j processes too. The help names both, and
    both get the -j given."""
    import click

    import laminid_cli.uncertainty as uncertainty
    from laminid_cli.cli import cli

    cmd = cli.get_command(click.Context(cli), "identify")
    help_text = next(p.help for p in cmd.params if p.name == "jobs")
    assert help_text.startswith("Processes for the Monte Carlo trials (--monte-carlo) and for "
                                "the profiles of the constants that stop on a search limit")
    seen = {}
    profiles, monte_carlo = uncertainty.with_profiles, uncertainty.monte_carlo

    def recording(original, name):
        def call(*args, jobs=None, **kwargs):
            seen.setdefault(name, []).append(jobs)
            return original(*args, jobs=1, **kwargs)        # one process here
        return call

    monkeypatch.setattr(uncertainty, "with_profiles", recording(profiles, "profiles"))
    monkeypatch.setattr(uncertainty, "monte_carlo", recording(monte_carlo, "monte_carlo"))
    r = run("identify", S21, "--mesh", "4x4", "--monte-carlo", "4", "-j", "3", "--no-output")
    assert r.exit_code == 0, r.output
    assert seen == {"monte_carlo": [3], "profiles": [3]}, seen


#: the plate of the analyser emulator's modes (tests/instrument/emulator.py PLATE_MODES), as a
#: newcomer describes it: a start whose modes 4 and 5 swap, re-anchored, then kept sorted
EMULATOR_PLATE = """\
name: EMU
geometry: {a: 200 mm, b: 200 mm, h: 3.33 mm}
materials:
  CF: {E1: 120 GPa, E2: 9 GPa, G12: 4 GPa, G13: 4 GPa, G23: 3 GPa, nu12: 0.3,
       density: 1600 kg/m^3}
layup: "[45/-45]2s"
measured:
  frequencies: [212.4188, 318.9141, 497.3129, 633.8092, 841.2167, 1120.6103, 1388.2148]
"""


def test_a_sorted_pairing_kept_for_a_lower_objective_shows_two_different_numbers(tmp_path):
    """The note of a plain sorted pairing kept because it fits better gave both objectives to
    6 digits: 'fits better than the tracked one (objective 0.205571 -> 0.205571)', a gain of
    5e-8 that read as none. The digits now tell them apart, and the kept one is the lower."""
    spec = tmp_path / "emu.yaml"
    spec.write_text(EMULATOR_PLATE)
    r = run("identify", spec, "--json", "--no-output")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output[r.output.index("{"):])
    notes = [s for s in d["swaps"] if "plain sorted pairing from the start fits better" in s]
    assert len(notes) == 1, d["swaps"]
    before, after = re.search(r"objective (\S+) -> ([^)]+)\)", notes[0]).groups()
    assert before != after and float(after) < float(before), notes[0]
    assert float(after) == pytest.approx(d["objective"], rel=1e-7)
    from laminid_cli.identify import objective_change

    # the rule itself: 6 digits where they differ, more where not, the relative change last
    assert objective_change(2.443e-4, 1.536e-4) == "0.0002443 -> 0.0001536"
    assert objective_change(0.20557062, 0.20557061) == "0.20557062 -> 0.20557061"
    assert objective_change(0.1, 0.1 * (1 - 2e-14)) == "0.1 -> 0.1, -2.0e-14 relative"


def test_json_gives_the_unit_of_the_relative_widths_and_thresholds(tmp_path):
    """monte_carlo_rel_half_width (0.0113 for +-1.13 %), the verdicts' thresholds (0.05, 0.3)
    and information_from_prior had no unit in identify --json, where rel_half_width beside
    them has '1 (fraction of the value)' and *_percent fields are percent."""
    r = run("identify", S21, "--mesh", "6x6", "--monte-carlo", "4", "--json", "--no-output")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output[r.output.index("{"):])
    u = d["uncertainty"]
    e1 = u["constants"]["E-glass/R368"]["E1"]
    assert 0 < e1["monte_carlo_rel_half_width"] < 0.2 and u["thresholds"]["weak"] == 0.3
    units = d["units"]
    for key in ("monte_carlo_rel_half_width", "monte_carlo_rel_half_width_lower"):
        assert units[key] == "1 (fraction of the value)" == units["rel_half_width"]
    assert units["well_determined"].startswith("1 (fraction of the value")
    assert units["weak"].startswith("1 (fraction of the value")
    assert units["max_rel_interval"].startswith("1 (fraction of the value")
    assert units["information_from_prior"] == "1 (fraction of what is known of the constant)"


def test_an_nlopt_failure_is_a_run_that_did_not_converge_not_a_traceback(monkeypatch):
    """nlopt 2.11 raises its own nlopt.runtime_error (no RuntimeError) for NLOPT_FAILURE:
    identify's 'except (RuntimeError, ValueError)' let it through as a traceback. It is the
    optimiser's failure: status not_converged, the reason in optimizer_status, exit code 1."""
    import nlopt

    if not hasattr(nlopt, "runtime_error"):
        pytest.skip("this nlopt raises RuntimeError itself")
    assert not issubclass(nlopt.runtime_error, RuntimeError)      # what let it through

    def fail(self, *args):
        raise nlopt.runtime_error("nlopt failure")

    monkeypatch.setattr(nlopt.opt, "optimize", fail)
    r = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "4x4", "--json",
            "--no-output")
    assert r.exit_code == 1, r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), r.exception
    d = json.loads(r.stdout)
    assert d["optimizer_status"] == "not converged: optimiser failure (nlopt failure)"
    assert d["status"] == "check" and "not_converged" in [x["code"] for x in d["reasons"]]
    from laminid_cli.identify import nlopt_failures

    assert issubclass(nlopt.runtime_error, nlopt_failures(nlopt))
    assert RuntimeError in nlopt_failures(nlopt)


EMULATOR_MEASURED = (
    "  sigma: [0.578, 0.6378, 0.9946, 1.2676, 1.6824, 2.2412, 2.7764]\n"
    "  damping: [0.00800422, 0.00599293, 0.00700546, 0.00499946, 0.00900088, 0.0060022, "
    "0.00700205]\n"
    "  damping_sigma: [0.00030992, 0.000219664, 0.000204111, 0.000150209, 0.000217853, "
    "0.000148448, 0.000162969]\n")


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_monte_carlo_of_the_emulators_plate_ends_without_a_traceback(tmp_path, jobs, caplog):
    """identify --monte-carlo of the analyser emulator's plate: a trial's SLSQP raised nlopt
    2.11's runtime_error (no RuntimeError subclass): with -j 1 a traceback, with -j 2 the worker
    could not send it back ("TypeError: cannot pickle 'swig_runtime_data5.SwigPyObject'"),
    exit 1. Such a trial is re-identified with identify(), as any the trial model refuses.
    Seed 26's first trial is one (`laminid -v` logs "trial 1: optimiser failure", asserted
    with -j 1, whose trials log here; seed 14's trial 1 was, before the trials' reduced
    blocks were made contiguous, which moved their last digits): its re-identification
    starts too far off (the plate's fit is poor, RMS 8.9 %, and the trials' frequencies are
    drawn with its variance factor), so 7 of the 8 trials converge, 2 of them through
    identify()."""
    spec = tmp_path / "emu.yaml"
    # (as fit-frf --into writes it from the emulator's FRFs: its sigmas and damping)
    spec.write_text(EMULATOR_PLATE + EMULATOR_MEASURED)
    caplog.set_level(logging.INFO, logger="laminid_cli.uncertainty")
    r = run("-v", "identify", spec, "--mesh", "8x8", "--monte-carlo", "8", "--seed", "26",
            "-j", jobs, "--json", "--no-output")
    assert "Traceback" not in r.output and "pickle" not in r.output, r.output
    assert r.exit_code == 0, r.output
    if jobs == "1":
        assert "trial 1: optimiser failure" in caplog.text, caplog.text
    d = json.loads(r.output[r.output.index("{\n"):])
    mc = d["uncertainty"]["monte_carlo"]
    assert (mc["trials"], mc["converged"], mc["reidentified"]) == (8, 7, 2), mc
    assert mc["failures"][0].startswith("trial 1: ") and "830 % away" in mc["failures"][0]


def test_a_trial_model_refuses_points_whose_stiffness_is_no_stiffness(tmp_path):
    """The emulator's plate, seed 14: a trial's SLSQP on the reduced model evaluated a point
    outside the search's limits with G12 = -2.7 MPa (its reduced lowest eigenvalue negative)
    and took it as its answer, whose factorisation then failed: the trial failed ("the
    factorisation of K - sigma M failed") without being identified again. The trial model now
    refuses such points as identify() does (VariableSet.refusal: outside the limits and a
    constitutive matrix not positive definite), and a factorisation that fails is its
    refusal: all 8 trials converge, 1 through identify()."""
    spec = tmp_path / "emu.yaml"
    spec.write_text(EMULATOR_PLATE + EMULATOR_MEASURED)
    r = run("identify", spec, "--mesh", "8x8", "--monte-carlo", "8", "--seed", "14", "-j", "1",
            "--json", "--no-output")
    assert r.exit_code == 0, r.output
    mc = json.loads(r.output[r.output.index("{\n"):])["uncertainty"]["monte_carlo"]
    assert (mc["trials"], mc["converged"], mc["reidentified"]) == (8, 8, 1), mc
    assert mc["failures"] == []
    # the rule itself, on a plate's trial model: the optimum evaluated, G12 below zero refused
    import dataclasses

    from laminid_cli.forward import bending_model, build_forward_model
    from laminid_cli.identify import identify, variables_of
    from laminid_cli.specimen import read_specimen
    from laminid_cli.uncertainty import TrialModel

    fm = bending_model(build_forward_model(read_specimen("specimens/example1/S1.4.yaml"),
                                           (6, 6)))
    res = identify(fm)
    model = TrialModel(fm, res, 1e-6)
    assert not model.refusal(model.x_opt)
    (p,) = model.params
    c = res.constants[0]
    assert model.refusal(variables_of(p, dataclasses.replace(c, G12=-0.001 * c.G12)))


def test_monte_carlo_table_numbers_keep_their_trailing_zeros():
    """The Monte Carlo table (terminal and report) wrote its range ends and stds with 'g':
    "156 GPa .. 163.7 GPa" and a std "0.5 GPa" beside "0.489 GPa", which read as known to
    fewer digits than their neighbours."""
    from laminid_cli.commands.text import _val
    from laminid_cli.units import significant_text

    assert _val("E1", 156.0e9, 4) == "156.0 GPa" and _val("E1", 163.74e9, 4) == "163.7 GPa"
    assert _val("G12", 0.5e9) == "0.500 GPa" and _val("E2", 0.489e9) == "0.489 GPa"
    assert _val("nu12", 0.05, 4) == "0.05000"
    assert significant_text("E1", 1234.4e9, 4) == "1234"           # no trailing point
    assert significant_text("G13", 8.684992e9, 4) == "8.685"


def test_a_terminal_is_told_of_the_mesh_check(monkeypatch):
    """identify --mesh-check solved the finer mesh (S1.1 at 24x24: 11.6 s) under the last
    "evaluation" line, which looked stuck; a terminal is told the mesh check runs, and the
    line ends before the report."""
    import laminid_cli.commands.identify as cmd

    monkeypatch.setattr(cmd, "stderr_is_terminal", lambda: True)
    r = run("identify", "specimens/example1/S1.1.yaml", "--mesh", "4x4", "--mesh-check",
            "--no-output")
    assert r.exit_code == 0, r.output
    said = "\r" + "  mesh check: the identified constants on 8x8".ljust(78)
    assert said in r.stderr
    after = r.stderr.split(said, 1)[1]
    assert "evaluation" not in after and after.startswith("\n"), after
