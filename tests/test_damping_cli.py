"""Damping end to end: FRFs with known modal damping -> fit-frf --into -> identify -> loss
factors; the HDF5 /damping group, --json "damping", batch rows and the report page."""

import csv
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli import damping as D
from laminid_cli.cli import cli
from laminid_cli.forward import build_forward_model
from laminid_cli.frf.store import write_frf_h5
from laminid_cli.specimen import read_specimen
from tests.clihelp import without_comments
from tests.frf_synth import synth_frf

S21 = "specimens/example2/S2.1.yaml"
MEASURED_BLOCK = ("  frequencies: [72.78, 121.00, 191.38, 286.78, 315.12, 340.40, 400.12, 433.84, "
                  "634.81, 653.56, 712.43, 789.97]   # Hz, Table 5")
#: true ply loss factors (11, 22, 12, 13, 23); the transverse-shear ones are fixed in the fits
ETA = np.array([0.002, 0.012, 0.018, 0.012, 0.012])
FIX = "nu12,G13,G23,eta13=0.012,eta23=0.012"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def frf_case(tmp_path_factory):
    """S2.1 (6x6 mesh, 1.3 x the initial E1): its first 8 modes with the modal damping of ETA
    (strain energy method) as accelerance FRFs at 4 points, 1 % noise; fit-frf --into."""
    tmp = tmp_path_factory.mktemp("damping")
    spec = read_specimen(S21)
    fm = build_forward_model(spec, (6, 6))
    c0 = fm.initial_constants[0]
    truth = type(c0)(c0.E1 * 1.3, c0.E2, c0.G12, c0.G13, c0.G23, c0.nu12)
    modes = fm.solve([truth], 8)
    zeta = D.modal_loss_factors(D.energy_shares(fm.plate, [truth], modes.phi), ETA) / 2
    freq = np.arange(0.0, 700.0, 0.25)[1:]
    rng = np.random.default_rng(3)
    constants = rng.choice([-1, 1], size=(4, 8)) * rng.uniform(0.3, 1.0, size=(4, 8))
    frf = synth_frf(freq, np.column_stack([modes.freq, zeta]), constants, kind="accelerance",
                    noise=0.01, seed=4)
    write_frf_h5(tmp / "plate.frf.h5", freq, frf, units="(m/s^2)/N")
    (tmp / "plate.yaml").write_text(Path(S21).read_text())
    r = run("fit-frf", tmp / "plate.frf.h5", "--modes", "8", "--into", tmp / "plate.yaml")
    assert r.exit_code == 0, r.output
    return tmp, zeta, truth


def test_fit_frf_into_writes_the_damping(frf_case):
    tmp, zeta, _ = frf_case
    m = read_specimen(tmp / "plate.yaml").measured
    assert np.allclose(m.damping, zeta, rtol=0.03)
    assert np.all(m.damping_sigma >= 0.0199 * m.damping)


@pytest.fixture(scope="module")
def identified(frf_case):
    """identify --json -o of the fitted specimen: (JSON document, result file)."""
    tmp = frf_case[0]
    out = tmp / "plate.result.h5"
    r = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", FIX, "--json", "-o", out)
    assert r.exit_code == 0, r.output
    return json.loads(r.output), out


def test_frf_to_loss_factors_within_their_intervals(frf_case, identified):
    tmp, zeta, truth = frf_case
    doc, out = identified
    assert doc["materials"]["E-glass/R368"]["E1"] == pytest.approx(truth.E1, rel=5e-3)
    d = doc["damping"]
    assert d["labels"] == ["E-glass/R368.eta11", "E-glass/R368.eta22", "E-glass/R368.eta12"]
    lo, hi, val = map(np.array, (d["lower"], d["upper"], d["value"]))
    assert np.all((lo <= ETA[:3]) & (ETA[:3] <= hi)), (lo, val, hi)
    assert val[0] == pytest.approx(ETA[0], rel=0.1) and val[2] == pytest.approx(ETA[2], rel=0.05)
    assert np.allclose(d["measured_loss_factor"], 2 * zeta, rtol=0.03)
    assert np.allclose(d["model_loss_factor"], 2 * zeta, rtol=0.03)
    assert d["fixed"] == {"E-glass/R368.eta13": 0.012, "E-glass/R368.eta23": 0.012}
    assert d["loss_factors"]["E-glass/R368"]["eta13"]["verdict"] == "fixed"
    with h5py.File(out, "r") as f:
        g = f["damping"]
        assert g.attrs["method"] == "modal strain energy" and g.attrs["terms"] == "11,22,12,13,23"
        assert [s.decode() for s in g["labels"][()]] == d["labels"]
        assert np.allclose(g["value"][()], val) and g["value"].attrs["units"] == "1"
        assert g["energy_shares"].shape == (8, 5)
        assert np.allclose(g["energy_shares"][()].sum(axis=1), 1, atol=1e-12)
        assert g["energy_shares"].attrs["labels"].startswith("E-glass/R368.11,")
        assert g["at_bound"].dtype == bool and not g["at_bound"][()].any()
    # the terminal report shows them with their verdicts
    r = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", FIX, "--no-output")
    assert r.exit_code == 0
    assert "ply loss factors (modal strain energy, 95 % intervals" in r.output
    assert "eta13" in r.output and "fixed" in r.output


def test_undetermined_loss_factors_make_the_status_check(frf_case, tmp_path):
    """With eta13 and eta23 free, the thin plate's modal damping cannot determine them (less
    than 2 % of any mode's strain energy is in transverse shear): the result is "check", with
    both named, in --json, the HDF5 file and the terminal; with them fixed it is not."""
    tmp = frf_case[0]
    out = tmp_path / "free.h5"
    r = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", "nu12,G13,G23", "--json",
            "-o", out)
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    d = doc["damping"]
    per = d["loss_factors"]["E-glass/R368"]
    assert doc["status"] == "check"
    why = {x["code"]: x["text"] for x in doc["reasons"]}
    for name in ("eta13", "eta23"):
        lab = f"E-glass/R368.{name}"
        if per[name]["at_bound"]:                        # held at 0
            assert per[name]["value"] == 0.0
            assert "lower limit 0" in why["at_bound"] and lab in why["at_bound"]
        else:
            assert per[name]["rel_half_width"] > 0.3
            assert "loss factors not determined by the measured damping" in why["undetermined"]
            assert f"{lab} (±{per[name]['rel_half_width'] * 100:.0f} %)" in why["undetermined"]
    assert not any("eta11" in x["text"] for x in doc["reasons"])      # eta11 is weak: not named
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "check"
        g = f["damping"]
        labels = [x.decode() for x in g["labels"][()]]
        for k, lab in enumerate(labels):
            j = per[lab.rsplit(".", 1)[1]]
            assert (j["bound_side"], j["bound_limit"]) == (
                ("lower", 0.0) if j["at_bound"] else ("", None))
            assert g["bound_side"][k].decode() == j["bound_side"]
            if j["at_bound"]:
                assert np.isinf(g["rel_half_width"][k]) and g["bound_limit"][k] == 0.0
            else:
                assert g["rel_half_width"][k] == j["rel_half_width"]
                assert np.isnan(g["bound_limit"][k])
    t = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", "nu12,G13,G23",
            "--no-output")
    assert "status: CHECK" in t.output and "E-glass/R368.eta23" in t.output
    # the same plate with the two fixed (the fixture's run): no reason from the damping
    r = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", FIX, "--json",
            "--no-output")
    doc = json.loads(r.output)
    assert not any("loss factor" in x["text"] for x in doc["reasons"]), doc["reasons"]


def test_identify_json_loss_factors_carry_the_flag_word_of_the_summaries(frf_case, identified,
                                                                        tmp_path):
    """identify --json's loss factors had no "flag" (its summary.json and summary.csv
    counterparts have one): a script testing it read eta13 "not determined" as a plain value.
    Now the same word as the summaries for the same run (both read from its result file):
    free eta13/eta23 "undetermined" or "at_bound", --fix'ed ones "fixed", eta11 ""."""
    from laminid_cli.batch import damping_of_file
    from laminid_cli.resultfile import read_result

    tmp = frf_case[0]
    out = tmp_path / "free.h5"
    r = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", "nu12,G13,G23", "--json",
            "-o", out)
    assert r.exit_code == 0, r.output
    seen = set()
    for doc, path in ((json.loads(r.output), out), identified):
        per = doc["damping"]["loss_factors"]["E-glass/R368"]
        summary = damping_of_file(read_result(path).damping)["E-glass/R368"]
        flags = {k: v["flag"] for k, v in per.items()}
        assert flags == {k: v["flag"] for k, v in summary.items()}
        assert flags["eta11"] == ""
        seen |= set(flags.values())
    assert {"fixed", ""} < seen and seen & {"undetermined", "at_bound"}


def test_batch_rows_carry_the_loss_factors(frf_case, tmp_path):
    from laminid_cli.batch import damping_long_rows, read_summary

    tmp, _, _ = frf_case
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "plate.yaml").write_text((tmp / "plate.yaml").read_text())
    r = run("batch", tmp_path / "in", "--mesh", "6x6", "--fix", FIX, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    row = json.loads((tmp_path / "out" / "summary.json").read_text())["specimens"][0]
    eta = row["damping"]["E-glass/R368"]
    assert eta["eta11"]["lower"] <= ETA[0] <= eta["eta11"]["upper"]
    assert eta["eta23"] == {"value": 0.012, "lower": None, "upper": None, "verdict": "fixed",
                            "flag": "fixed"}
    assert (eta["eta11"]["at_bound"], eta["eta11"]["bound_side"], eta["eta11"]["bound_limit"]) \
        == (False, "", None)
    rows = damping_long_rows(row)
    assert [x["constant"] for x in rows] == ["eta11", "eta22", "eta12", "eta13", "eta23"]
    assert all(x["unit"] == "1" and x["material"] == "E-glass/R368" for x in rows)
    assert rows[0]["value"] == pytest.approx(eta["eta11"]["value"])
    # the long summary.csv has them after the elastic constants, and reads them back
    with open(tmp_path / "out" / "summary.csv", newline="") as fh:
        recs = list(csv.DictReader(without_comments(fh)))
    assert [x["constant"] for x in recs] == ["E1", "E2", "G12", "G13", "G23", "nu12", "eta11",
                                             "eta22", "eta12", "eta13", "eta23"]
    e11 = recs[6]
    assert e11["unit"] == "1" and e11["material"] == "E-glass/R368"
    assert float(e11["value"]) == pytest.approx(eta["eta11"]["value"], rel=1e-14)
    assert float(e11["lower"]) <= ETA[0] <= float(e11["upper"])
    assert recs[10]["verdict"] == "fixed" and recs[10]["lower"] == recs[10]["upper"] == ""
    back = read_summary(tmp_path / "out" / "summary.csv")[0]["damping"]["E-glass/R368"]
    assert back["eta23"]["value"] == 0.012 and back["eta23"]["verdict"] == "fixed"
    # the terminal table has them too (%), below the constants: eta23 fixed, "="
    table = {ln.split()[0]: ln.split()[-1] for ln in r.output.splitlines()
             if ln.startswith("eta")}
    assert table["eta23"] == "1.200=" and table["eta13"] == "1.200="
    assert float(table["eta11"].rstrip("^")) == pytest.approx(100 * eta["eta11"]["value"],
                                                              abs=6e-4)
    assert back["eta11"]["value"] == pytest.approx(eta["eta11"]["value"], rel=1e-14)


def test_wide_summary_has_the_loss_factors_and_monte_carlo_ranges_of_the_long_one(frf_case,
                                                                                  tmp_path):
    """--wide dropped the ply loss factors and every Monte Carlo range and side of a bound
    (the long form's only). Now, after the old columns (names and places kept), each
    constant's bound_side and Monte Carlo range, then each loss factor's value, interval,
    verdict and range, equal to the long summary.csv's (1e-9 relative) for the same run
    (S2.1 6x6, --fix nu12: eta13 held at 0; 8 trials); read_summary and the report take them
    from the wide file (a constant's bound_side: test_summary_csv_and_table_have_the_shape_of_
    table_2)."""
    from laminid_cli.batch import LOSS_NAMES, csv_header, read_summary
    from laminid_cli.report import report_pages

    tmp = frf_case[0]
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "plate.yaml").write_text((tmp / "plate.yaml").read_text())
    out = tmp_path / "out"
    args = ("batch", tmp_path / "in", "--mesh", "6x6", "--fix", "nu12", "--monte-carlo", "8",
            "--out", out)
    r = run(*args)
    assert r.exit_code in (0, 1), r.output
    with open(out / "summary.csv", newline="") as fh:
        long = {(x["material"], x["constant"]): x for x in csv.DictReader(without_comments(fh))}
    r = run(*args, "--wide")                                 # up to date: the same rows
    assert "up to date" in r.output
    with open(out / "summary.csv", newline="") as fh:
        head = next(csv.reader(without_comments(fh)))
        fh.seek(0)
        (wide,) = list(csv.DictReader(without_comments(fh)))
    m = "E-glass/R368"
    old = csv_header([m])
    assert head[: len(old)] == old                       # the old columns first, unchanged
    assert head == csv_header([m], damped=[m], monte_carlo=True)

    def same(a, b):
        assert (a == "") == (b == ""), (a, b)
        if a:
            assert float(a) == pytest.approx(float(b), rel=1e-9, abs=0.0)

    for (mat, k), rec in long.items():
        assert mat == m
        if k.startswith("eta"):
            for cell, col in zip(("value", "lower", "upper"), (f"{m} {k} [1]",
                                                               f"{m} {k} lower [1]",
                                                               f"{m} {k} upper [1]")):
                same(wide[col], rec[cell])
            assert wide[f"{m} {k} verdict"] == rec["verdict"]
        else:
            assert wide[f"{m} {k} bound_side"] == rec["bound_side"]
        unit = rec["unit"]
        same(wide[f"{m} {k} mc_lower [{unit}]"], rec["mc_lower"])
        same(wide[f"{m} {k} mc_upper [{unit}]"], rec["mc_upper"])
        assert wide[f"{m} {k} mc_search_limit"] == rec["mc_search_limit"]
    assert [k for (_, k) in long if k.startswith("eta")] == list(LOSS_NAMES)
    assert float(wide[f"{m} eta11 mc_upper [1]"]) > float(wide[f"{m} eta11 mc_lower [1]"]) > 0
    # read back as the long one is
    (w,) = read_summary(out / "summary.csv")
    assert w["damping"][m].keys() == set(LOSS_NAMES)
    for k in LOSS_NAMES:
        e, rec = w["damping"][m][k], long[(m, k)]
        assert e["value"] == pytest.approx(float(rec["value"]), rel=1e-9)
        assert e["verdict"] == rec["verdict"]
        assert (e.get("mc_lower") is None) == (rec["mc_lower"] == "")
        assert e["bound_side"] == rec["bound_side"]          # eta13: held at 0, "lower"
    assert long[(m, "eta13")]["bound_side"] == "lower"
    g13 = w["intervals"][m]["G13"]
    assert g13["mc_lower"] == pytest.approx(float(long[(m, "G13")]["mc_lower"]), rel=1e-9)
    assert "loss-factors" in [p.name for p in report_pages(out / "summary.csv")]


def test_batch_table_has_a_row_per_loss_factor_with_the_constants_marks():
    """The batch's terminal table showed the constants only: a specimen's loss factors were in
    the summaries alone. Now a row per loss factor (%) below the constants, in their marks by
    the summaries' flag: "?" not determined by the damping, "!" held at 0, "=" fixed, and "^"
    for one whose interval is too narrow (leans on an undetermined constant: its flag
    "leans"); "—" for a specimen without measured damping; a legend line."""
    from laminid_cli.batch import CONSTANTS, format_table
    from laminid_cli.damping import VERDICT_LEANS, VERDICT_NOT_DAMPING

    def row(name, damping):
        return {"name": name, "specimen": name, "status": "ok", "cached": False,
                "materials": {"m": {k: 1e10 for k in CONSTANTS}}, "intervals": {},
                "rms_residual_percent": 0.5, "evaluations": 40, "reasons": [],
                "warnings": [], "mesh_check": None, "damping": damping}

    free = {"at_bound": False, "bound_side": "", "bound_limit": None}
    damped = {"m": {
        "eta11": {"value": 0.00201, "lower": 0.0017, "upper": 0.0023, "verdict": "weak"} | free,
        "eta22": {"value": 0.012, "lower": 0.0097, "upper": 0.0143,
                  "verdict": "weak" + VERDICT_LEANS.format(labels="m.E2")} | free,
        "eta12": {"value": 0.0, "lower": None, "upper": None,
                  "verdict": "at bound — not identified", "at_bound": True,
                  "bound_side": "lower", "bound_limit": 0.0},
        "eta13": {"value": 0.0105, "lower": 0.0, "upper": 0.034,
                  "verdict": VERDICT_NOT_DAMPING.format(term="eta13")} | free,
        "eta23": {"value": 0.012, "lower": None, "upper": None, "verdict": "fixed"}}}
    lines = format_table([row("A", damped), row("B", {})]).splitlines()
    cells = {ln.split()[0]: ln.split()[2:] for ln in lines if ln.startswith("eta")}
    assert cells == {"eta11": ["0.201", "—"], "eta22": ["1.200^", "—"],
                     "eta12": ["0.000!", "—"], "eta13": ["1.050?", "—"],
                     "eta23": ["1.200=", "—"]}
    k = [(ln.split() or [""])[0] for ln in lines].index
    assert k("nu12") < k("eta11") < k("RMS")                     # below the constants
    legend = next(ln for ln in lines if "eta [%]: ply loss factors in %" in ln)
    for words in ("? not determined by the measured damping", "! held at 0 by eta >= 0",
                  "^ interval too narrow: its energy share leans on a constant above",
                  "= fixed by --fix", "— no measured damping"):
        assert words in legend, words
    # a batch without loss factors: no such rows, no such legend
    plain = format_table([row("B", {})])
    assert "eta11" not in plain and "eta [%]" not in plain


def test_a_loss_factor_at_its_bound_in_the_summary_rows():
    """A loss factor held at 0 by eta >= 0 (/damping/at_bound) has no interval in summary.csv
    (it kept the one-sided 0 .. upper of a file written before: this file's numbers) and gets
    bound_side "lower", bound_limit 0, as an elastic constant at its bound does; the others
    keep their interval and leave both bound columns empty."""
    from laminid_cli.batch import LONG_COLUMNS, damping_of_file, long_rows
    from laminid_cli.resultfile import Damping

    d = Damping(attrs={"fixed": "m.eta23=0.012"}, data={
        "labels": ("m.eta11", "m.eta12"), "value": np.array([0.011, 0.0]),
        "lower": np.array([0.009, 0.0]), "upper": np.array([0.013, 0.062]),
        "verdict": ("well determined", "at bound — not identified"),
        "at_bound": np.array([False, True])})
    per = damping_of_file(d)["m"]
    assert (per["eta12"]["at_bound"], per["eta12"]["bound_side"], per["eta12"]["bound_limit"]) \
        == (True, "lower", 0.0)
    assert (per["eta12"]["lower"], per["eta12"]["upper"]) == (None, None)
    assert (per["eta11"]["lower"], per["eta11"]["upper"]) == (0.009, 0.013)
    assert per["eta11"]["bound_side"] == "" and per["eta11"]["bound_limit"] is None
    row = {"name": "p", "specimen": "p", "status": "ok", "reason": "", "reasons": [],
           "rms_residual_percent": None, "result": None, "materials": {}, "damping": {"m": per}}
    recs = {r[LONG_COLUMNS.index("constant")]: dict(zip(LONG_COLUMNS, r))
            for r in long_rows([row])}
    assert (recs["eta12"]["bound_side"], recs["eta12"]["bound_limit"]) == ("lower", "0.0")
    assert (recs["eta12"]["lower"], recs["eta12"]["upper"]) == ("", "")
    assert (recs["eta11"]["lower"], recs["eta11"]["upper"]) == ("0.009", "0.013")
    assert recs["eta11"]["bound_side"] == recs["eta11"]["bound_limit"] == ""
    assert recs["eta23"]["verdict"] == "fixed" and recs["eta23"]["bound_side"] == ""


def test_a_loss_factors_monte_carlo_end_held_at_0_is_flagged_in_the_summaries():
    """The terminal and the result's damping page mark a loss factor's Monte Carlo end set by
    refits held at 0 ("0*", /damping/monte_carlo/lower_at_zero); summary.csv's mc_search_limit
    was empty for it and summary.json had no mc_lower_at_limit (the synthetic S1.1 of
    scripts/example_frf.py, 6x6, 10 trials: eta23's range 0 .. 1.02 %, 3 refits at 0, left
    unmarked past the result file). Now "lower" and True there, as a constant's end on a search
    limit; an end the data set stays unflagged."""
    from laminid_cli.batch import LONG_COLUMNS, damping_of_file, long_rows
    from laminid_cli.resultfile import Damping

    d = Damping(attrs={}, data={
        "labels": ("m.eta11", "m.eta23"), "value": np.array([0.00187, 0.00774]),
        "lower": np.array([0.00157, 0.0]), "upper": np.array([0.00216, 0.0170]),
        "verdict": ("weak", "not determined by the measured damping"),
        "at_bound": np.array([False, False])},
        monte_carlo={"lower": np.array([0.00154, 0.0]), "upper": np.array([0.00214, 0.0102]),
                     "lower_at_zero": np.array([0, 1], dtype=np.int8)})
    per = damping_of_file(d)["m"]
    assert (per["eta23"]["mc_lower_at_limit"], per["eta23"]["mc_upper_at_limit"]) \
        == (True, False)
    assert (per["eta11"]["mc_lower_at_limit"], per["eta11"]["mc_upper_at_limit"]) \
        == (False, False)
    assert per["eta23"]["mc_lower"] == 0.0 and per["eta23"]["mc_upper"] == 0.0102
    row = {"name": "p", "specimen": "p", "status": "check", "reason": "", "reasons": [],
           "rms_residual_percent": None, "result": None, "materials": {}, "damping": {"m": per}}
    recs = {r[LONG_COLUMNS.index("constant")]: dict(zip(LONG_COLUMNS, r))
            for r in long_rows([row])}
    assert recs["eta23"]["mc_search_limit"] == "lower"
    assert recs["eta23"]["mc_lower"] == "0.0" and recs["eta23"]["mc_upper"] == "0.0102"
    assert recs["eta11"]["mc_search_limit"] == ""


def test_summary_json_loss_factors_carry_the_flag_word_as_summary_csv():
    """summary.csv's flag column said eta13 "undetermined", a loss factor held at 0
    "at_bound", a --fix'ed one "fixed"; summary.json's loss factors had no "flag" at all (its
    constants have one), so a script testing it read them as plain identified values."""
    from laminid_cli.batch import LONG_COLUMNS, damping_of_file, long_rows
    from laminid_cli.damping import VERDICT_NOT_DAMPING
    from laminid_cli.resultfile import Damping

    d = Damping(attrs={"fixed": "m.eta23=0.012"}, data={
        "labels": ("m.eta11", "m.eta12", "m.eta13"), "value": np.array([0.002, 0.0, 0.013]),
        "lower": np.array([0.0016, 0.0, 0.0]), "upper": np.array([0.0023, 0.006, 0.036]),
        "verdict": ("weak", "at bound — not identified", VERDICT_NOT_DAMPING.format(term="eta13")),
        "at_bound": np.array([False, True, False])})
    per = damping_of_file(d)["m"]
    flags = {k: v["flag"] for k, v in per.items()}
    assert flags == {"eta11": "", "eta12": "at_bound", "eta13": "undetermined", "eta23": "fixed"}
    row = {"name": "p", "specimen": "p", "status": "check", "reason": "", "reasons": [],
           "rms_residual_percent": None, "result": None, "materials": {}, "damping": {"m": per}}
    recs = {r[LONG_COLUMNS.index("constant")]: r[LONG_COLUMNS.index("flag")]
            for r in long_rows([row])}
    assert recs == flags


def test_a_loss_factor_held_at_0_has_no_interval_anywhere(tmp_path):
    """S2.1 (6x6) with damping from eta12 = eta23 = 0 plus 3 % noise: the fit holds both at
    0 by eta >= 0 ("at bound — not identified"). They showed the one-sided 0 .. q std of the
    unconstrained spread as their interval (the terminal "<= 0.0092", --json and the file
    0 and that upper, the report "[0, 0.0092]"; hybrid-CM's glass.eta12 "[0, 1e+06] %"), a
    number no lab can act on. Now none, in every place, as an elastic constant on a search
    limit: the terminal "none: held at 0", --json null, the file NaN (its datasets say so),
    the batch row None, the report's table "none — held at 0"; the free ones keep theirs."""
    from laminid_cli.batch import damping_of_file
    from laminid_cli.report_damping import loss_factor_rows, read_damping
    from laminid_cli.resultfile import read_result
    from tests.dampspec import damped_copy

    damped_copy(S21, tmp_path / "held.yaml", np.array([0.002, 0.012, 0.0, 0.012, 0.0]),
                sigma_rel=0.03, mesh="6x6", noise=0.03, seed=1)
    out = tmp_path / "held.result.h5"
    args = ("identify", tmp_path / "held.yaml", "--mesh", "6x6", "--fix",
            "nu12,G13,G23,eta13=0.01")
    r = run(*args, "--json", "-o", out)
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)["damping"]
    assert d["labels"] == [f"E-glass/R368.eta{k}" for k in ("11", "22", "12", "23")]
    assert d["at_bound"] == [False, False, True, True]
    assert d["lower"][2:] == d["upper"][2:] == [None, None]
    per = d["loss_factors"]["E-glass/R368"]
    for name in ("eta12", "eta23"):
        e = per[name]
        assert (e["value"], e["lower"], e["upper"], e["rel_half_width"]) == (0.0, None, None,
                                                                               None)
        assert e["verdict"] == D.VERDICT_AT_BOUND and e["std"] > 0
    for k, name in enumerate(("eta11", "eta22")):
        e = per[name]
        assert 0 < e["lower"] < e["value"] < e["upper"] < 0.02
        assert (d["lower"][k], d["upper"][k]) == (e["lower"], e["upper"])
    with h5py.File(out, "r") as f:
        g = f["damping"]
        assert np.isnan(g["lower"][2:]).all() and np.isnan(g["upper"][2:]).all()
        assert np.isfinite(g["lower"][:2]).all() and np.isfinite(g["upper"][:2]).all()
        assert "NaN for a loss factor held at 0" in g["upper"].attrs["description"]
    lines = {ln.split()[0]: ln for ln in run(*args, "--no-output").output.splitlines()
             if ln.startswith("  eta")}
    for name in ("eta12", "eta23"):
        assert "none: held at 0  at bound — not identified" in lines[name]
        assert "<=" not in lines[name]
    assert f"{100 * per['eta11']['lower']:.3f} .. {100 * per['eta11']['upper']:.3f}" \
        in lines["eta11"]
    # a file written before stored 0 .. upper in its summary: laminid show prints none either
    from laminid_cli.commands.text import format_damping

    before = json.loads(r.output)["damping"]
    before["loss_factors"]["E-glass/R368"]["eta12"].update(lower=0.0, upper=9.2e-5)
    shown = [ln for ln in format_damping(before) if ln.startswith("  eta12")]
    assert len(shown) == 1 and "none: held at 0" in shown[0] and "0.0092" not in shown[0]
    rows = {row[0]: row for row in loss_factor_rows(read_damping(out))}
    assert rows["E-glass/R368.eta12"][2] == rows["E-glass/R368.eta23"][2] == "none — held at 0"
    assert rows["E-glass/R368.eta11"][2] == (f"[{100 * per['eta11']['lower']:.3f}, "
                                             f"{100 * per['eta11']['upper']:.3f}]")
    batch = damping_of_file(read_result(out).damping)["E-glass/R368"]
    assert (batch["eta12"]["lower"], batch["eta12"]["upper"]) == (None, None)
    assert batch["eta11"]["lower"] == per["eta11"]["lower"]


def test_damping_report_page(frf_case, identified, tmp_path):
    from laminid_cli.report_damping import damping_figures

    zeta = frf_case[1]
    out = identified[1]
    figs = damping_figures(out)
    assert [name for name, _ in figs] == ["damping"]
    fig = figs[0][1]
    ax_modal, ax_share = fig.axes[:2]
    # measured points are the file's 2 zeta, in %
    meas = ax_modal.lines[0].get_ydata()
    assert np.allclose(meas, 100 * 2 * zeta, rtol=0.03)
    # stacked shares reach 100 % in every mode
    tops = np.zeros(8)
    for bars in ax_share.containers:
        tops = np.maximum(tops, [b.get_y() + b.get_height() for b in bars])
    assert np.allclose(tops, 100, atol=1e-9)
    fig.savefig(tmp_path / "damping.png", dpi=80)
    # among the report's pages (the command writing them all: test_report.py, ~7 s here)
    from laminid_cli.report import report_pages

    assert "damping" in [p.name for p in report_pages(out)]


def test_result_without_damping_has_no_damping_group(tmp_path):
    out = tmp_path / "S21.result.h5"
    r = run("identify", S21, "--mesh", "4x4", "--fix", "nu12,G13,G23", "-o", out)
    assert r.exit_code == 0, r.output
    with h5py.File(out, "r") as f:
        assert "damping" not in f
    from laminid_cli.report_damping import damping_figures

    assert damping_figures(out) == []


def test_joint_says_the_damping_is_not_used(frf_case, tmp_path):
    tmp = frf_case[0]
    text = (tmp / "plate.yaml").read_text()
    (tmp_path / "a.yaml").write_text(text)
    # a second plate (one copy of the same data is refused: test_joint): another mass
    assert "mass: 0.2571 kg" in text
    (tmp_path / "b.yaml").write_text(text.replace("mass: 0.2571 kg", "mass: 0.2590 kg"))
    r = run("identify", tmp_path / "a.yaml", tmp_path / "b.yaml", "--joint", "--mesh", "4x4",
            "--fix", "nu12,G13,G23", "--no-output")
    assert r.exit_code == 0, r.output
    assert "measured damping is not used with --joint" in r.output
    r = run("identify", tmp_path / "a.yaml", tmp_path / "b.yaml", "--joint", "--mesh", "4x4",
            "--fix", "nu12,eta13=0.01", "--no-output")
    assert r.exit_code == 2 and "single plates only, not with --joint" in r.output


def test_loss_factors_leaning_on_undetermined_constants_say_so(frf_case):
    """S2.1 (6x6) with only nu12 fixed: G13 stops on its limit and G23 is not determined, so
    the strain-energy shares of eta13 and eta23 rest on values the modes do not give; their
    intervals take them as identified, and the damping notes now say so (before: nothing).
    With G13 and G23 fixed by the user (the fixture's run) there is no such note."""
    tmp = frf_case[0]
    r = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", "nu12", "--json",
            "--no-output")
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)["damping"]
    note = [n for n in d["notes"] if "take the elastic constants as identified" in n]
    assert len(note) == 1, d["notes"]
    head, _, tail = note[0].partition(": the loss factors")
    assert {"E-glass/R368.eta13", "E-glass/R368.eta23"} <= set(head.split(", "))
    assert "E-glass/R368.G13" in tail and "E-glass/R368.G23" in tail
    assert tail.endswith("known less well than the interval says")
    # E2 is not determined either: eta22's verdict was a plain "weak" (summary.csv's flag
    # empty); it now says what its interval leans on (eta13 is held at 0, eta23 not
    # determined already: theirs stay), the others' plain
    verdict = dict(zip(d["labels"], d["verdict"]))
    assert verdict["E-glass/R368.eta22"] == (
        "weak — interval too narrow: its energy share leans on E-glass/R368.E2, not determined "
        "by the modes")
    assert verdict["E-glass/R368.eta11"] == "weak"
    assert verdict["E-glass/R368.eta23"].startswith("not determined by the measured damping")
    fixed = run("identify", tmp / "plate.yaml", "--mesh", "6x6", "--fix", FIX, "--json",
                "--no-output")
    assert not [n for n in json.loads(fixed.output)["damping"]["notes"]
                if "take the elastic constants as identified" in n]


def test_a_loss_factor_leaning_on_an_undetermined_constant_says_so_in_its_verdict():
    """The synthetic S1.1 of scripts/example_frf.py (6x6; --fix-undetermined then leaves E2
    and G12 not determined): eta22 and eta12 were "weak" with an interval, summary.csv's flag
    empty, while their energy shares rest on E2 and G12; only a note said so, and the
    summaries carry no notes. Without a Monte Carlo range that counts the constants' doubt,
    their verdict now says it in every form (terminal, --json, HDF5, summaries, report); one
    not determined already, or held at 0, keeps its verdict. Its flag was empty, a plain
    one's (a script keeping the rows with no flag kept it as identified); it is "leans"."""
    import dataclasses
    from types import SimpleNamespace

    from laminid_cli.batch import flag_word
    from laminid_cli.damping import VERDICT_LEANS, leaning, with_leaning_verdicts

    @dataclasses.dataclass(frozen=True)
    class Fit:
        labels: tuple
        verdict: tuple
        at_bound: tuple

    m = "IM7/977-2"
    fit = Fit(labels=tuple(f"{m}.eta{t}" for t in ("11", "22", "12", "13", "23")),
              verdict=("weak", "weak", "well determined", "not determined by the measured "
                       "damping", "weak"), at_bound=(False, False, False, False, True))
    u = SimpleNamespace(flagged=(f"{m}.E2", f"{m}.G12"), labels=(f"{m}.G13",), at_bound=(True,))
    assert leaning(fit, u, (f"{m}.G23",)) == {f"{m}.eta22": [f"{m}.E2"],
                                               f"{m}.eta12": [f"{m}.G12"],
                                               f"{m}.eta13": [f"{m}.G13"],
                                               f"{m}.eta23": [f"{m}.G23"]}
    out = with_leaning_verdicts(fit, u, (f"{m}.G23",))
    assert out.verdict == (
        "weak", "weak" + VERDICT_LEANS.format(labels=f"{m}.E2"),
        "well determined — interval too narrow: its energy share leans on IM7/977-2.G12, not "
        "determined by the modes",
        "not determined by the measured damping", "weak")
    assert [flag_word({"verdict": v}) for v in out.verdict] == [
        "", "leans", "leans", "undetermined", ""]


def test_fix_takes_loss_factors_in_percent_on_the_command_line(frf_case):
    """'--fix eta13=1.2%' is read as the specimen file reads '1.2 %' (before: refused); a bad
    value is refused before the fit, in one line naming the option, the item and the value."""
    tmp = frf_case[0]
    r = run("identify", tmp / "plate.yaml", "--mesh", "4x4", "--fix",
            "nu12,G13,G23,eta13=1.2%,eta23=1.2 %", "--json", "--no-output")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["damping"]["fixed"] == {"E-glass/R368.eta13": 0.012,
                                                         "E-glass/R368.eta23": 0.012}
    r = run("identify", tmp / "plate.yaml", "--mesh", "4x4", "--fix", "nu12,eta13=12x",
            "--no-output")
    assert r.exit_code == 2
    assert ("laminid: error: --fix eta13=12x: eta13 = '12x': unknown unit 'x' in '12x'; "
            "expected a plain number or a percentage (0.004 or '0.4 %')") in r.output
    assert "Traceback" not in r.output


def test_a_loss_factors_interval_has_its_values_digits():
    """The interval's ends were written with 3 significant digits beside a value with 3
    decimals ("0.199  0.178 .. 0.22": the top end looked a digit short, its doubt
    narrower); in the terminal and the report they have the value's decimals, as the
    constants' intervals have the value's (_num), and so has the Monte Carlo range."""
    from laminid_cli.commands.text import format_damping
    from laminid_cli.report_damping import loss_factor_rows

    v = {"value": 0.00199, "lower": 0.00178, "upper": 0.0022, "verdict": "identified"}
    d = {"method": "modal strain energy", "confidence": 0.95,
         "loss_factors": {"glass": {"eta11": v}}, "s2": 1.0,
         "scaling": {"used": "stated"}, "sigma_source": "damping_sigma", "dof": 3,
         "energy_share_labels": ["glass.eta11"], "measured_loss_factor": [0.002],
         "measured_sigma": [0.0001], "used": [True], "model_loss_factor": [0.00199],
         "energy_shares": [[1.0]],
         "monte_carlo": {"refits": 20, "trials": 20, "sigma_factor": 1.0, "time_s": 0.5,
                         "loss_factors": {"glass": {"eta11": {
                             "linearized_std": 1e-4, "std": 1.1e-4, "ratio": 1.1,
                             "lower": 0.0, "upper": 0.0021, "lower_at_zero": True}}}}}
    lines = format_damping(d)
    assert "  eta11            0.199       0.178 .. 0.220  identified" in lines
    assert [ln for ln in lines if ln.startswith("  eta11") and "*" in ln] == [
        "  eta11                  0.01             0.011   1.10        0.000* .. 0.210"]
    rows = loss_factor_rows({"labels": ["glass.eta11"], "value": [0.00199],
                             "lower": [0.00178], "upper": [0.0022], "at_bound": [False],
                             "verdict": ["identified"],
                             "monte_carlo": {"lower": [0.0], "upper": [0.0021],
                                             "lower_at_zero": [True]}})
    assert rows[0][1:3] == ["0.199", "[0.178, 0.220]\nMonte Carlo 0.000*–0.210"]
