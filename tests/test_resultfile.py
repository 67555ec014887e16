"""The typed reader of result files and the safe group keys of the writer."""

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.modal import default_factorizer
from laminid_cli.resultfile import ResultFileError, read_result
from laminid_cli.results import SCHEMA_VERSION, safe_keys
from tests.clihelp import S14, write_s14_with_ranges
from tests.resultfix import drop_bound_data, make_version_1

S21 = "specimens/example2/S2.1.yaml"
MAT = "E-glass/R368"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    """S2.1 identified on a 6x6 mesh, with a UTF-8 material name that needs a safe key:
    (path, the --json output)."""
    tmp = tmp_path_factory.mktemp("rf")
    text = Path(S21).read_text(encoding="utf-8")
    assert MAT in text
    text = text.replace(MAT, "Glas/Epoxid µ-Lage")
    (tmp / "s.yaml").write_text(text, encoding="utf-8")
    out = tmp / "s.result.h5"
    r = run("identify", tmp / "s.yaml", "--mesh", "6x6", "--fix", "nu12,G13,G23", "-o", out,
            "--json")
    assert r.exit_code == 0, r.output
    return out, json.loads(r.output)


def test_safe_keys():
    assert safe_keys(["IM7/977-2", "a b", "a_b", ".", "", "x.y-z_1", "µ"]) == [
        "IM7_977-2", "a_b", "a_b_2", "_.", "_", "x.y-z_1", "__2"]
    assert safe_keys(["a", "a", "a"]) == ["a", "a_2", "a_3"]


def test_round_trip_of_a_written_result(result):
    path, doc = result
    name = "Glas/Epoxid µ-Lage"
    with h5py.File(path) as f:
        assert f.attrs["schema_version"] == SCHEMA_VERSION == 2
        assert f.attrs["solver"] == doc["solver"] == "reduced"
        assert f.attrs["factorization"] == doc["factorization"] == default_factorizer()
        # S2.1 is symmetric: its bending equations alone; /modes/dofs lists them
        assert f.attrs["equations"] == doc["equations"] == "bending"
        dofs = f["modes"]["dofs"][()]
        assert f["modes"]["phi"].shape[0] == dofs.size and set(dofs % 9) == {2, 3, 4, 7, 8}
        g = f["materials"]["Glas_Epoxid__-Lage"]            # readable in h5ls, no "/" in it
        assert g.attrs["name"] == name                      # UTF-8 round trip
        assert h5py.check_string_dtype(f["specimen"]["yaml"].dtype).encoding == "utf-8"
        assert list(f["initial"]) == ["Glas_Epoxid__-Lage"]
    r = read_result(path)
    assert r.format == "laminid-result" and not r.joint and r.schema_version == 2
    assert list(r.materials) == [name]
    for k, v in doc["materials"][name].items():
        assert r.materials[name][k] == v                    # exactly the numbers of --json
        assert r.initial[name][k] == doc["initial"][name][k]
    assert r.free[name] == tuple(doc["free"][name])
    p = r.plates[0]
    assert p.name == doc["specimen"]["name"] and p.mesh == (6, 6)
    assert np.array_equal(p.frequencies.model, doc["frequencies"]["model"])
    assert np.array_equal(p.frequencies.model_mode, doc["frequencies"]["model_mode"])
    assert p.frequencies.rms_residual_percent == doc["rms_residual_percent"]
    assert "Glas/Epoxid µ-Lage" in p.yaml
    assert r.evaluations == doc["evaluations"] and r.converged == doc["converged"]
    u = r.uncertainty
    assert u.confidence == 0.95
    assert [iv.label for iv in u.intervals] == [f"{name}.{k}" for k in ("E1", "E2", "G12")]
    for iv in u.intervals:
        d = doc["uncertainty"]["constants"][name][iv.constant]
        assert (iv.value, iv.lower, iv.upper) == (d["value"], d["lower"], d["upper"])
    assert r.history.labels[:6] == tuple(f"{name}.{k}" for k in
                                         ("E1", "E2", "G12", "G13", "G23", "nu12"))
    assert r.damping is None
    assert r.status.status == doc["status"]
    assert [(x.code, x.text) for x in r.status.reasons] == [
        (x["code"], x["text"]) for x in doc["reasons"]]


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    """S2.1 with every constant free on a 6x6 mesh (G13 ends at its bound: status "check") and
    measured damping ratios, the UTF-8 material name: (path, the --json output)."""
    tmp = tmp_path_factory.mktemp("rfc")
    text = Path(S21).read_text(encoding="utf-8").replace(MAT, "Glas/Epoxid µ-Lage")
    zeta = "[" + ", ".join(f"{0.002 + 0.0004 * k:.4f}" for k in range(12)) + "]"
    text = text.replace("  frequencies:", f"  damping: {zeta}\n  frequencies:", 1)
    (tmp / "s.yaml").write_text(text, encoding="utf-8")
    out = tmp / "s.result.h5"
    r = run("identify", tmp / "s.yaml", "--mesh", "6x6", "--fix", "eta13=0.01,eta23=0.01",
            "-o", out, "--json")
    assert r.exit_code == 0, r.output
    return out, json.loads(r.output)


def test_schema_2_fields_status_intervals_and_damping(checked):
    """Status, reasons, physical intervals and /damping as the writer wrote them read back
    equal to the numbers of --json."""
    path, doc = checked
    name = "Glas/Epoxid µ-Lage"
    r = read_result(path)
    assert r.schema_version == 2 and r.status.status == doc["status"] == "check"
    assert [(x.code, x.text) for x in r.status.reasons] == [
        (x["code"], x["text"]) for x in doc["reasons"]]
    assert "at_bound" in [x.code for x in r.status.reasons]
    assert r.optimizer_status == doc["optimizer_status"] and r.optimizer_status.startswith(
        "converged")
    consts = doc["uncertainty"]["constants"][name]
    g13 = r.uncertainty.get(name, "G13")
    assert g13.at_bound and consts["G13"]["at_bound"]
    assert g13.flagged == consts["G13"]["flagged"]
    assert sorted(iv.label for iv in r.uncertainty.intervals if iv.flagged) == sorted(
        doc["uncertainty"]["flagged"])
    assert g13.bound_text == consts["G13"]["bound_text"]
    assert g13.bound_text.startswith("at its bound — not identified: stopped on the search's "
                                     "lower limit, G13 = 0.0001 E1 (")
    assert np.isnan(g13.lower) and np.isnan(g13.upper) and consts["G13"]["lower"] is None
    for k in ("E1", "E2", "G12", "G23", "nu12"):
        iv = r.uncertainty.get(name, k)
        assert not iv.at_bound and iv.bound_text == ""
        assert (iv.value, iv.lower, iv.upper, iv.verdict, iv.scale, iv.flagged) == tuple(
            consts[k][x] for x in ("value", "lower", "upper", "verdict", "scale", "flagged"))
        if k == "nu12":
            assert iv.scale == "linear"
            assert iv.upper - iv.value == pytest.approx(iv.value - iv.lower, rel=1e-9)
        else:                                               # asymmetric, symmetric in ln P
            assert iv.scale == "log" and 0 < iv.lower < iv.value < iv.upper
            assert iv.lower * iv.upper == pytest.approx(iv.value ** 2, rel=1e-12)
    d = r.damping
    assert d.attrs["method"] == "modal strain energy"
    assert list(d.data["labels"]) == doc["damping"]["labels"]
    assert np.array_equal(d.data["value"], doc["damping"]["value"])
    assert np.allclose(d.data["measured_loss_factor"],
                       2 * (0.002 + 0.0004 * np.arange(12)), rtol=1e-12)


def test_bound_side_and_limit_are_data(checked, tmp_path):
    """A constant at its bound carries its side and limit as numbers: --json, the HDF5
    datasets and the reader agree; the limit is the one its statement names (3 digits), at
    least the search's floor MIN_MODULUS_RATIO * E1 and at most the value it ended on (a shear
    modulus the data push below its floor). The other constants: side "", limit NaN. A file
    written before these datasets (bound_side/bound_limit removed) is read from the
    statement: the same side, the limit to the statement's 3 digits."""
    import re

    from laminid_cli.parametrization import MIN_MODULUS_RATIO

    path, doc = checked
    name = "Glas/Epoxid µ-Lage"
    consts = doc["uncertainty"]["constants"][name]
    r = read_result(path)
    g13 = r.uncertainty.get(name, "G13")
    assert g13.at_bound and g13.bound_side == consts["G13"]["bound_side"] == "lower"
    assert g13.bound_limit == consts["G13"]["bound_limit"]
    E1, G13 = r.materials[name]["E1"], r.materials[name]["G13"]
    assert MIN_MODULUS_RATIO * E1 * (1 - 1e-12) <= g13.bound_limit <= G13 * (1 + 1e-12)
    stated = float(re.search(r"\(([0-9.e+-]+) GPa", g13.bound_text).group(1))
    assert stated == pytest.approx(g13.bound_limit / 1e9, rel=5e-3)
    with h5py.File(path) as f:
        u = f["uncertainty"]
        k = [x.decode() for x in u["labels"][()]].index(f"{name}.G13")
        assert u["bound_side"][k].decode() == "lower"
        assert u["bound_limit"][k] == g13.bound_limit
        assert u["bound_limit"].attrs["units"] == "Pa (nu12: 1)"
    for k in ("E1", "E2", "G12", "G23", "nu12"):
        iv = r.uncertainty.get(name, k)
        assert iv.bound_side == consts[k]["bound_side"] == "" and np.isnan(iv.bound_limit)
        assert consts[k]["bound_limit"] is None
    old = tmp_path / "old.result.h5"
    shutil.copy(path, old)
    drop_bound_data(old)
    o = read_result(old).uncertainty.get(name, "G13")
    assert o.bound_side == "lower" and o.bound_limit == pytest.approx(g13.bound_limit, rel=5e-3)
    assert np.isnan(read_result(old).uncertainty.get(name, "E1").bound_limit)


def test_version_1_file(checked, tmp_path):
    """A file as schema 1 wrote it: read as far as it goes, status None."""
    path = tmp_path / "v1.result.h5"
    shutil.copy(checked[0], path)
    make_version_1(path)
    with h5py.File(path) as f:
        assert list(f["materials"]) == ["Glas\u2215Epoxid µ-Lage"]
    r = read_result(path)
    name = "Glas/Epoxid µ-Lage"
    assert r.schema_version == 1 and r.status is None and list(r.materials) == [name]
    assert r.optimizer_status == checked[1]["optimizer_status"]
    e1 = r.uncertainty.get(name, "E1")
    assert e1.scale == "linear" and not e1.at_bound
    assert e1.upper - e1.value == pytest.approx(e1.value - e1.lower, rel=1e-9)


@pytest.fixture(scope="module")
def ranged(tmp_path_factory):
    """S1.4 with a reference range for E1 and for nu_xy (clihelp.S14_RANGES), 6x6."""
    tmp = tmp_path_factory.mktemp("rr")
    out = tmp / "r.result.h5"
    r = run("identify", write_s14_with_ranges(tmp), "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    return out


def test_reference_ranges_read_back_and_an_old_file_with_single_values(ranged, tmp_path):
    """The reader gives every reference as (low, high): a range as written in the specimen
    (once it was left out), one value as low == high. A schema 1 file whose specimen has
    single values (as every file before ranges were kept) reads the same way."""
    r = read_result(ranged)
    mat = "IM7/977-2"
    assert r.reference == {mat: {"E1": (120e9, 150e9), "E2": (10e9, 10e9),
                                 "G12": (5.8e9, 5.8e9), "nu12": (0.35, 0.35)}}
    assert r.plates[0].reference_global == {"nu_xy": (0.05, 0.07)}
    old = tmp_path / "v1.result.h5"
    shutil.copy(ranged, old)
    make_version_1(old)
    with h5py.File(old, "r+") as f:
        del f["specimen"]["yaml"]
        f["specimen"].create_dataset("yaml", data=Path(S14).read_text(encoding="utf-8"),
                                     dtype=h5py.string_dtype("utf-8"))
    r = read_result(old)
    assert r.schema_version == 1
    assert r.reference == {mat: {"E1": (170e9, 170e9), "E2": (10e9, 10e9),
                                 "G12": (5.8e9, 5.8e9), "nu12": (0.35, 0.35)}}
    assert r.plates[0].reference_global == {}
    assert r.plates[0].reference_source.startswith("strain gauge tests")


def test_a_reference_written_value_plus_minus_half_width_reads_as_its_range(tmp_path):
    """"170 ± 1 GPa" (also "+/-", "+-" and a half-width in %) is the range the specimen reader
    gives it, in the result files' reader too: the report read it as a unit error and left the
    reference out of its table and panels (the terminal showed 169.00 .. 171.00)."""
    from laminid_cli.resultfile import parse_global_reference, parse_reference
    from laminid_cli.specimen import read_specimen

    text = Path(S14).read_text(encoding="utf-8")
    head, _, _ = text.partition("\nreference:")
    spec = tmp_path / "pm.yaml"
    spec.write_text(head + "\nreference:\n  source: a table\n  materials:\n"
                    "    IM7/977-2: {E1: 170 ± 1 GPa, E2: 10 GPa +- 0.5 GPa, "
                    "G12: 5.8 GPa +/- 5 %, nu12: 0.35}\n"
                    "  global: {Ex: 62 ± 2 GPa, nu_xy: 0.30 ± 0.02}\n", encoding="utf-8")
    yaml_text = spec.read_text(encoding="utf-8")
    mats, source = parse_reference(yaml_text)
    got = mats["IM7/977-2"]
    expect = {"E1": (169e9, 171e9), "E2": (9.5e9, 10.5e9), "G12": (5.51e9, 6.09e9),
              "nu12": (0.35, 0.35)}
    assert sorted(got) == sorted(expect) and source == "a table"
    for k, (lo, hi) in expect.items():
        assert got[k] == pytest.approx((lo, hi), rel=1e-12), k
    glob = parse_global_reference(yaml_text)
    assert glob["Ex"] == pytest.approx((60e9, 64e9), rel=1e-12)
    assert glob["nu_xy"] == pytest.approx((0.28, 0.32), rel=1e-12)
    # the specimen reader's ranges, the same to round-off
    ref = read_specimen(spec).reference["materials"]["IM7/977-2"]
    for k in ("E1", "E2", "G12"):
        assert tuple(ref[k]) == pytest.approx(got[k], rel=1e-12), k


def test_not_a_result_and_future_versions(tmp_path, result):
    frf = tmp_path / "x.h5"
    with h5py.File(frf, "w") as f:
        f.attrs["format"] = "laminid-frf"
    with pytest.raises(ResultFileError, match=r"an FRF file, not an identification result: "
                                              r"laminid fit-frf .* --plot x.fit.pdf draws"):
        read_result(frf)
    other = tmp_path / "y.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "another tool's"
    with pytest.raises(ResultFileError, match=r"not a laminid identification result .*make "
                                              r"one with laminid identify"):
        read_result(other)
    with pytest.raises(ResultFileError, match="file not found"):
        read_result(tmp_path / "missing.h5")
    new = tmp_path / "new.h5"
    shutil.copy(result[0], new)
    with h5py.File(new, "r+") as f:
        f.attrs["schema_version"] = 99
    with pytest.raises(ResultFileError, match="schema_version 99 is not readable"):
        read_result(new)
    with h5py.File(new, "r+") as f:
        f.attrs["schema_version"] = 2
        del f["frequencies"]
    with pytest.raises(ResultFileError, match="incomplete result file"):
        read_result(new)


def test_joint_groups_have_safe_keys_and_names(tmp_path):
    a = tmp_path / "a.yaml"
    b = tmp_path / "b.yaml"
    text = Path("specimens/example1/S1.1.yaml").read_text(encoding="utf-8")
    a.write_text(text.replace("name: S1.1", "name: plate A/1"), encoding="utf-8")
    b.write_text(Path("specimens/example1/S1.2.yaml").read_text(encoding="utf-8"),
                 encoding="utf-8")
    out = tmp_path / "j.h5"
    r = run("identify", a, b, "--joint", "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    with h5py.File(out) as f:
        assert sorted(f["specimens"]) == ["S1.2", "plate_A_1"]
        assert f["specimens"]["plate_A_1"].attrs["name"] == "plate A/1"
        assert f["uncertainty"]["frequency_sigma"]["plate_A_1"].attrs["name"] == "plate A/1"
        assert f.attrs["factorization"] == default_factorizer()
    res = read_result(out)
    assert res.joint and [p.name for p in res.plates] == ["plate A/1", "S1.2"]
    assert list(res.materials) == ["IM7/977-2"]
    assert "density" in res.plates[0].materials["IM7/977-2"]


def test_fixed_and_fixed_because_undetermined_are_read(tmp_path, s11_fix_undetermined_6x6):
    """``--fix-undetermined`` writes /uncertainty@fixed, @fixed_undetermined and the first
    run's assessment in /uncertainty/before_fixing: the reader gives all three (S1.1 at 6x6:
    the first run leaves G13, G23, nu12 undetermined, a later round fixes E2 too and keeps
    G12 free, its initial value being rejected; the free constants are E1 and G12). A file without them (an --fix run of an older laminid) reads
    as nothing fixed-because-undetermined, with ``fixed`` from /materials@free."""
    doc, shared = s11_fix_undetermined_6x6          # conftest.py; changed below: a copy
    out = tmp_path / "f.result.h5"
    shutil.copy(shared, out)
    res = read_result(out)
    u = res.uncertainty
    mat = "IM7/977-2"
    labels = [f"{mat}.{k}" for k in ("G13", "G23", "nu12", "E2")]
    assert u.fixed_undetermined == tuple(doc["uncertainty"]["fixed_undetermined"]) == \
        tuple(labels)
    assert set(u.fixed) == set(labels) and res.free == {mat: ("E1", "G12")}
    first = doc["uncertainty"]["before_fixing"]
    assert set(u.before_fixing) == {f"{mat}.{k}" for k in ("E1", "E2", "G12", "G13", "G23",
                                                            "nu12")}
    for lab, (rel, verdict) in u.before_fixing.items():
        assert rel == first[lab]["rel_half_width"] and verdict == first[lab]["verdict"]
    assert u.before_fixing[f"{mat}.G13"][1].startswith("not determined")
    assert u.before_fixing[f"{mat}.E2"][1] == "weak"           # fixed in the later round
    with h5py.File(out, "r+") as f:
        for key in ("fixed", "fixed_undetermined"):
            del f["uncertainty"].attrs[key]
        del f["uncertainty"]["before_fixing"]
    old = read_result(out).uncertainty
    assert old.fixed == old.fixed_undetermined == () and old.before_fixing == {}


def test_every_numeric_dataset_carries_its_units(result, s11_fix_undetermined_6x6):
    """A program reading a result file with plain h5py finds each number's unit in its
    `units` attribute (README, "Reading a result file without laminid"):
    /uncertainty/fixed_undetermined/run (the run of --fix-undetermined that fixed each) had
    none, the one numeric dataset of 300-odd without."""
    missing = []

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fiub" \
                and "units" not in obj.attrs:
            missing.append(name)

    for path in (result[0], s11_fix_undetermined_6x6[1]):
        with h5py.File(path, "r") as f:
            f.visititems(visit)
            if "fixed_undetermined" in f["uncertainty"]:
                run = f["uncertainty/fixed_undetermined/run"]
                assert run.attrs["units"] == "1" and list(run[()]) == [1, 1, 1, 2]
    assert missing == []


def test_each_constant_and_property_dataset_carries_its_doubt(checked, result,
                                                              s11_fix_undetermined_6x6):
    """A program reading /materials/<key>/G13 with plain h5py finds its verdict and interval
    beside the value (attrs verdict, lower, upper, confidence), as --json gives them: a value
    on a search limit, a guess held fixed and an identified one read alike before, a bare
    number each. The laminate's /global_properties likewise."""
    from laminid_cli.results import FIXED_VERDICT, UNDETERMINED_FIXED_VERDICT

    def attrs(path, group, key):
        with h5py.File(path) as f:
            g = f[group]
            return float(g[key][()]), dict(g[key].attrs)

    path, doc = checked                       # G13 at its bound, the others free
    consts = doc["uncertainty"]["constants"]["Glas/Epoxid µ-Lage"]
    for k, c in consts.items():
        value, a = attrs(path, "materials/Glas_Epoxid__-Lage", k)
        assert value == c["value"] and a["verdict"] == c["verdict"] and a["confidence"] == 0.95
        for end in ("lower", "upper"):
            assert (np.isnan(a[end]) and c[end] is None) or a[end] == c[end], (k, end)
    assert consts["G13"]["at_bound"] and attrs(path, "materials/Glas_Epoxid__-Lage", "G13")[1][
        "verdict"] == "at bound — not identified"
    for k, c in doc["global_uncertainty"].items():
        _, a = attrs(path, "global_properties", k)
        assert a["verdict"] == c["verdict"], k
        assert (np.isnan(a["lower"]) and c["lower"] is None) or a["lower"] == c["lower"], k
    _, a = attrs(result[0], "materials/Glas_Epoxid__-Lage", "G23")        # --fix G23
    assert a["verdict"] == FIXED_VERDICT and np.isnan(a["lower"]) and np.isnan(a["upper"])
    _, a = attrs(result[0], "materials/Glas_Epoxid__-Lage", "E1")
    assert a["lower"] == result[1]["uncertainty"]["constants"]["Glas/Epoxid µ-Lage"]["E1"][
        "lower"] > 0
    doc, path = s11_fix_undetermined_6x6      # G13 fixed because undetermined
    _, a = attrs(path, "materials/IM7_977-2", "G13")
    assert a["verdict"] == UNDETERMINED_FIXED_VERDICT and np.isnan(a["upper"])


def test_bound_statement_reads_both_forms():
    """The statement of a constant at its bound, as files before stop 29 wrote it ("G13 <=
    0.0001 E1 (...)") and as later ones do ("stopped on the search's lower limit, G13 =
    0.0001 E1 (...)"): the same side and limit from both; no inequality sign in the limit."""
    from laminid_cli.resultfile import bound_from_text, bound_statement

    head = "at its bound — not identified: "
    for old, new, side, limit, words in (
            ("G13 <= 0.0001 E1 (0.0154 GPa)",
             "stopped on the search's lower limit, G13 = 0.0001 E1 (0.0154 GPa)",
             "lower", 1.54e7, "0.0001 E1 (0.0154 GPa)"),
            ("G23 <= 0.0001 E1 (0.00295 GPa at the optimum)",
             "stopped on the search's lower limit, G23 = 0.0001 E1 (0.00295 GPa at the optimum)",
             "lower", 2.95e6, "0.0001 E1 (0.00295 GPa at the optimum)"),
            ("nu12 >= 0.95", "stopped on the search's upper limit, nu12 = 0.95", "upper", 0.95,
             "0.95"),
            ("E2 >= E1 (58.5 GPa)", "stopped on the search's upper limit, E2 = E1 (58.5 GPa)",
             "upper", 58.5e9, "E1 (58.5 GPa)"),
            ("G12 >= 5 x initial (15.5 GPa)",
             "stopped on the search's upper limit, G12 = 5 x initial (15.5 GPa)", "upper",
             15.5e9, "5 x initial (15.5 GPa)")):
        for text in (head + old, head + new):
            assert bound_statement(text) == (side, words)
            s, v = bound_from_text(text)
            assert s == side and v == pytest.approx(limit, rel=1e-12)
    assert bound_statement("") == ("", "") and bound_statement(head + "somewhere") == ("", "")
    assert np.isnan(bound_from_text(head + "somewhere")[1])


def test_every_constants_json_entry_has_the_same_keys(result, s11_fix_undetermined_6x6):
    """The README says uncertainty.constants.<material>.<constant> has the same keys for every
    constant; a fixed one lacked scale, verdict_from, information_from_prior (and quantile,
    effective_dof, rel_half_width_given_fixed after --fix-undetermined), a free one "assumed".
    Each has them all now, null where they do not apply, "assumed" false for a free one."""
    for doc in (result[1], s11_fix_undetermined_6x6[0]):
        entries = {f"{m}.{k}": e for m, per in doc["uncertainty"]["constants"].items()
                   for k, e in per.items()}
        keys = {lab: set(e) for lab, e in entries.items()}
        assert len({frozenset(v) for v in keys.values()}) == 1, keys
        free = [lab for lab, e in entries.items() if e["verdict"] != "fixed"]
        fixed = [lab for lab, e in entries.items() if e["verdict"] == "fixed"]
        assert free and fixed
        assert all(entries[lab]["assumed"] is False for lab in free)
        assert all(entries[lab]["scale"] is None and entries[lab]["verdict_from"] is None
                   for lab in fixed)
    e = s11_fix_undetermined_6x6[0]["uncertainty"]["constants"]["IM7/977-2"]
    assert e["G13"]["quantile"] is None and e["E1"]["quantile"] > 1.9


def test_a_fixed_constants_json_entry_has_a_free_ones_keys(result, s11_fix_undetermined_6x6):
    """identify --json gave a fixed constant {"verdict": "fixed", "flagged": false} alone: a
    program reading uncertainty.constants[m][k]["value"] or ["lower"] of every constant got a
    KeyError. It has a free one's keys now, its value, no interval, and "assumed" where
    --fix-undetermined held it (summary.json's flag "assumed")."""
    path, doc = result                             # --fix nu12,G13,G23
    consts = doc["uncertainty"]["constants"]["Glas/Epoxid µ-Lage"]
    free_keys = {"value", "std", "lower", "upper", "half_width", "rel_half_width", "verdict",
                 "flagged", "at_bound", "bound_side", "bound_limit"}
    for k in ("G13", "G23", "nu12"):
        e = consts[k]
        assert free_keys <= set(consts["E1"]) and free_keys <= set(e), k
        assert e["value"] == doc["materials"]["Glas/Epoxid µ-Lage"][k] == doc["initial"][
            "Glas/Epoxid µ-Lage"][k]
        assert (e["lower"], e["upper"], e["verdict"], e["assumed"]) == (None, None, "fixed",
                                                                         False)
    assert consts["nu12"]["value"] == pytest.approx(0.28, rel=1e-12)
    doc, _ = s11_fix_undetermined_6x6              # G13, G23, nu12, E2 fixed: assumed
    g13 = doc["uncertainty"]["constants"]["IM7/977-2"]["G13"]
    assert g13["assumed"] is True and g13["value"] == pytest.approx(3.1e9, rel=1e-12)
    assert g13["lower"] is None and g13["verdict"] == "fixed"
