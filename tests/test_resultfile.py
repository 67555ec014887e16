"""The typed reader of result files and the safe group keys of the writer."""

import json
import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.resultfile import ResultFileError, read_result
from laminid_cli.results import SCHEMA_VERSION, safe_keys
from tests.resultfix import add_schema2_fields

S21 = "specimens/example2/S2.1.yaml"
MAT = "E-glass/R368"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    """S2.1 identified on a 6x6 mesh, with a UTF-8 material name that needs a safe key:
    (path, the --json output)."""
    tmp = tmp_path_factory.mktemp("rf")
    text = open(S21, encoding="utf-8").read()
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
    # the writer of this branch does not compute a status yet (branch i11a): none is claimed
    assert r.status is None or r.status.status in ("ok", "check")


@pytest.mark.xfail(reason="fixture written for files without i11a status writer; to rewrite after the merge", strict=False)
def test_schema_2_fields_status_intervals_and_damping(result, tmp_path):
    path = tmp_path / "c.result.h5"
    shutil.copy(result[0], path)
    name = "Glas/Epoxid µ-Lage"
    add_schema2_fields(path, status="check",
                       reasons=[("poor_fit", "s² = 31 beyond its 99 % limit 2.9")],
                       at_bound={f"{name}.G12": "at its bound — not identified: G12 <= "
                                                "0.0001 E1"})
    with h5py.File(path, "r+") as f:
        d = f.create_group("damping")
        d.attrs["method"] = "modal strain energy"
        d.create_dataset("value", data=[0.01, 0.02])
    r = read_result(path)
    assert r.status.status == "check"
    assert [(x.code, x.text) for x in r.status.reasons] == [
        ("poor_fit", "s² = 31 beyond its 99 % limit 2.9")]
    assert r.optimizer_status == result[1]["status"]         # the nlopt outcome moved
    g12 = r.uncertainty.get(name, "G12")
    assert g12.at_bound and g12.bound_text.startswith("at its bound") and g12.lower == 0.0
    e1 = r.uncertainty.get(name, "E1")
    assert e1.scale == "log" and not e1.at_bound
    assert e1.lower * e1.upper == pytest.approx(e1.value ** 2, rel=1e-12)   # symmetric in ln
    assert r.damping.attrs["method"] == "modal strain energy"
    assert np.array_equal(r.damping.data["value"], [0.01, 0.02])


def test_not_a_result_and_future_versions(tmp_path, result):
    frf = tmp_path / "x.h5"
    with h5py.File(frf, "w") as f:
        f.attrs["format"] = "laminid-frf"
    with pytest.raises(ResultFileError, match=r"not a laminid identification result .*make "
                                              r"one with laminid identify"):
        read_result(frf)
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
    text = open("specimens/example1/S1.1.yaml", encoding="utf-8").read()
    a.write_text(text.replace("name: S1.1", "name: plate A/1"), encoding="utf-8")
    b.write_text(open("specimens/example1/S1.2.yaml", encoding="utf-8").read(),
                 encoding="utf-8")
    out = tmp_path / "j.h5"
    r = run("identify", a, b, "--joint", "--mesh", "6x6", "-o", out)
    assert r.exit_code == 0, r.output
    with h5py.File(out) as f:
        assert sorted(f["specimens"]) == ["S1.2", "plate_A_1"]
        assert f["specimens"]["plate_A_1"].attrs["name"] == "plate A/1"
        assert f["uncertainty"]["frequency_sigma"]["plate_A_1"].attrs["name"] == "plate A/1"
    res = read_result(out)
    assert res.joint and [p.name for p in res.plates] == ["plate A/1", "S1.2"]
    assert list(res.materials) == ["IM7/977-2"]
    assert "density" in res.plates[0].materials["IM7/977-2"]
