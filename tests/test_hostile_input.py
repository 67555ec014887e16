"""Hostile and broken input (issue 13): one named regression test per class of failure seen.

Each test asserts the exit code and the message (file:line or the field, and what is wrong),
never only the exit code. The generated (fuzz) counterpart is tests/test_fuzz.py.
"""

import json
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli

S11 = Path("specimens/example1/S1.1.yaml")
BASE = S11.read_text()


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def spec(tmp_path, text, name="plate.yaml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def modes_error(tmp_path, text):
    """``laminid modes`` on a specimen text that must be refused: (exit code, stderr line)."""
    path = spec(tmp_path, text)
    r = run("modes", path, "--mesh", "4x4")
    assert "Traceback" not in r.output
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    return r.exit_code, r.output, path


# ---------------------------------------------------------------------------------- YAML


def test_yaml_alias_bomb_is_refused_at_once(tmp_path):
    # a few hundred bytes expanding to 10^8 values
    bomb = "x0: &a0 [1,1,1,1,1,1,1,1,1,1]\n" + "".join(
        f"x{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 10) + "]\n" for i in range(1, 8))
    t0 = time.perf_counter()
    code, out, path = modes_error(tmp_path, bomb + BASE)
    assert time.perf_counter() - t0 < 5
    assert code == 2
    assert f"{path}:5: the YAML expands to more than 100000 values" in out


def test_yaml_too_many_aliases_are_refused(tmp_path):
    text = BASE + "x0: &a 1\nxs: [" + ", ".join(["*a"] * 150) + "]\n"
    code, out, path = modes_error(tmp_path, text)
    assert code == 2 and "more than 100 YAML aliases" in out and f"{path}:" in out


def test_yaml_nesting_1000_deep_is_refused_not_recursion_error(tmp_path):
    code, out, path = modes_error(tmp_path, BASE + "x: " + "[" * 1000 + "]" * 1000 + "\n")
    n = BASE.count("\n") + 1
    assert code == 2 and f"{path}:{n}: nesting deeper than 32 levels" in out


def test_yaml_control_character_is_refused_with_its_line(tmp_path):
    code, out, path = modes_error(tmp_path, BASE.replace("name: S1.1", "name: S1\x07"))
    line = BASE.splitlines().index("name: S1.1") + 1
    assert code == 2
    assert f"{path}:{line}: non-printable character U+0007" in out


def test_yaml_merge_key_is_refused(tmp_path):
    text = BASE.replace("geometry:\n", "g0: &g {a: 1}\ngeometry:\n  <<: *g\n")
    code, out, path = modes_error(tmp_path, text)
    line = text.splitlines().index("  <<: *g") + 1
    assert code == 2 and f"{path}:{line}: YAML merge keys (<<) are not allowed" in out


@pytest.mark.parametrize("value, shown", [("!!int abc", "!!int"), ("!foo 1", "!foo"),
                                          ("!!binary AAAA", "!!binary")])
def test_yaml_tags_are_refused(tmp_path, value, shown):
    text = BASE.replace("mass: 0.3225 kg", f"mass: {value}")
    code, out, path = modes_error(tmp_path, text)
    line = text.splitlines().index(f"mass: {value}") + 1
    assert code == 2 and f"{path}:{line}: YAML tag '{shown}' is not allowed" in out


def test_huge_integer_frequency_is_refused_not_overflow_error(tmp_path):
    code, out, path = modes_error(tmp_path, BASE.replace("125.05,", "1" + "0" * 400 + ","))
    assert code == 2
    assert "field 'measured.frequencies[1]'" in out and "is too large a number" in out


def test_file_bigger_than_any_specimen_is_refused(tmp_path):
    code, out, path = modes_error(tmp_path, BASE + "#" + "x" * 1_100_000 + "\n")
    assert code == 2 and "more than a specimen file can have" in out


# ---------------------------------------------------------------------------------- units


def test_full_width_and_compatibility_units_read_as_what_they_look_like():
    from laminid_cli.units import parse_quantity

    assert parse_quantity("２１０.５ ｍｍ", "length") == pytest.approx(0.2105)
    assert parse_quantity("125.05 ㎐", "frequency") == pytest.approx(125.05)
    assert parse_quantity("117.2 ＧＰａ", "modulus") == pytest.approx(117.2e9)


def test_full_width_units_in_a_specimen_give_the_same_model(tmp_path):
    text = BASE.replace("210.5 mm", "２１０.５ ｍｍ").replace("125.05,", '"125.05 ㎐",')
    r1 = run("modes", spec(tmp_path, text), "--mesh", "4x4", "--json")
    r2 = run("modes", S11, "--mesh", "4x4", "--json")
    assert r1.exit_code == 0, r1.output
    f1, f2 = (json.loads(r.output)["frequencies"]["model"] for r in (r1, r2))
    assert f1 == pytest.approx(f2, rel=1e-12)


def test_modulus_in_millipascal_is_refused_by_plausibility(tmp_path):
    code, out, path = modes_error(tmp_path, BASE.replace("117.2 GPa", "117200 mPa"))
    assert code == 2
    assert "field 'materials.IM7/977-2.E1'" in out
    assert "'117200 mPa' = 1.172e-07 GPa is not a plausible modulus" in out


def test_ambiguous_case_of_a_prefix_is_refused(tmp_path):
    code, out, _ = modes_error(tmp_path, BASE.replace("117.2 GPa", "117200 mpa"))
    assert code == 2 and "unit 'mpa' in '117200 mpa' is ambiguous" in out


def test_thickness_in_the_wrong_unit_is_refused_by_plausibility(tmp_path):
    code, out, _ = modes_error(tmp_path, BASE.replace("h: 3.06 mm", "h: 3.06 um"))
    assert code == 2 and "field 'geometry.h'" in out and "is not a plausible length" in out


def test_ply_thickness_contradicting_h_is_refused_even_when_scaling(tmp_path):
    text = BASE.replace("layup:", "ply_thickness: 0.5 mm\nscale_thickness: true\nlayup:")
    code, out, _ = modes_error(tmp_path, text)
    assert code == 2
    assert "field 'ply_thickness'" in out
    assert "the ply thicknesses add up to 12 mm, which contradicts h = 3.06 mm" in out


# ---------------------------------------------------------------------------------- command line


def test_mesh_too_big_for_memory_is_refused_with_estimate_and_largest_that_fits():
    from laminid_cli.fe.mesh import check_mesh_memory, model_memory_bytes
    from laminid_cli.errors import ModelError

    # 4 GB: 200x200 needs ~72 GB; the answer names the largest square mesh that fits
    with pytest.raises(ModelError) as err:
        check_mesh_memory(200, 200, available=4e9)
    msg = str(err.value)
    assert "mesh 200x200 needs about 71.8 GB of memory, and 4 GB is available" in msg
    fits = int(msg.split("fits is ")[1].split("x")[0])
    assert model_memory_bytes(fits, fits) <= 4e9 < model_memory_bytes(fits + 1, fits + 1)
    check_mesh_memory(12, 12, available=4e9)          # the paper's mesh: no complaint


def test_mesh_too_big_for_memory_on_the_command_line(monkeypatch):
    import laminid_cli.fe.mesh as mesh

    monkeypatch.setattr(mesh, "available_memory_bytes", lambda: 2e9)
    r = run("modes", S11, "--mesh", "200x200")
    assert r.exit_code == 2
    assert "laminid: error: mesh 200x200 needs about 71.8 GB of memory, and 2 GB is available: " \
           "the largest mesh that fits is" in r.output


def test_batch_counts_one_model_per_worker_in_the_memory_estimate(tmp_path, monkeypatch):
    import laminid_cli.fe.mesh as mesh

    one = mesh.model_memory_bytes(40, 40)
    monkeypatch.setattr(mesh, "available_memory_bytes", lambda: 1.5 * one)
    r = run("batch", S11, "--mesh", "40x40", "-j", "2", "--out", tmp_path / "out")
    assert r.exit_code == 2 and "for 2 worker processes" in r.output
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("mesh, words", [
    ("1x1", "mesh '1x1' is degenerate: at least 2 elements per side"),
    ("1x12", "mesh '1x12' is degenerate"),
    ("2x60", "mesh 2x60 on a 210.5 x 311 mm plate makes elements 20.3 times longer than wide"),
])
def test_degenerate_mesh_is_refused(mesh, words):
    r = run("modes", S11, "--mesh", mesh)
    assert r.exit_code == 2 and words in r.output


@pytest.mark.parametrize("option", ["--xtol", "--ftol", "--sigma-rel", "--max-rel-interval"])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_nan_and_inf_options_are_refused_by_the_parser(tmp_path, option, value):
    out = tmp_path / "o.h5"
    r = run("identify", S11, "--mesh", "4x4", option, value, "-o", out)
    assert r.exit_code == 2
    assert f"Invalid value for '{option}': '{value}' is not a finite number." in r.output
    assert not out.exists()


def test_identify_without_measured_frequencies_is_refused(tmp_path):
    path = spec(tmp_path, BASE.split("measured:")[0])
    r = run("identify", path, "--mesh", "4x4", "-o", tmp_path / "o.h5")
    assert r.exit_code == 2, r.output
    assert f"laminid: error: {path}: no measured frequencies: add 'measured:" in r.output
    assert not (tmp_path / "o.h5").exists()


@pytest.mark.parametrize("address, words", [
    ("bogus", "--scheduler 'bogus': no port"),
    ("http://host:8786", "unknown scheme 'http'"),
    ("tcp://host:99999", "port 99999 is not in 1-65535"),
    ("tcp://a b:1", "not understood"),
])
def test_every_scheduler_problem_is_one_line(tmp_path, address, words):
    r = run("batch", S11, "--scheduler", address, "--out", tmp_path / "out")
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and lines[0].startswith("laminid: error:")
    assert not (tmp_path / "out").exists()


def test_unreachable_tcpip_analyser_is_an_instrument_error_naming_the_resource(tmp_path):
    r = run("acquire", "--analyser", "TCPIP0::no-such-host.invalid::5025::SOCKET",
            "-o", tmp_path / "x.h5")
    assert r.exit_code == 1, r.output
    assert "laminid: error: analyser TCPIP0::no-such-host.invalid::5025::SOCKET is unreachable" \
           in r.output
    assert not (tmp_path / "x.h5").exists()


# ---------------------------------------------------------------------------------- numerics


@pytest.mark.parametrize("failure, words", [
    ("noconv", "the eigen solver (ARPACK) did not converge for 16 modes"),
    ("error", "the eigen solver (ARPACK) failed for 16 modes"),
])
def test_arpack_failure_exits_1_with_what_to_try(monkeypatch, failure, words):
    import numpy as np
    import scipy.sparse.linalg as spla

    def eigsh(*args, **kwargs):
        if failure == "noconv":
            raise spla.ArpackNoConvergence("no convergence", np.zeros(0), np.zeros((0, 0)))
        raise spla.ArpackError(-9999)

    monkeypatch.setattr(spla, "eigsh", eigsh)
    r = run("modes", S11, "--mesh", "4x4")
    assert r.exit_code == 1
    assert words in r.output and "try fewer modes (--modes), another mesh (--mesh)" in r.output


def test_singular_factorisation_exits_1_with_what_to_try(monkeypatch):
    import numpy as np
    import scipy.linalg as sla

    def cholesky_banded(*args, **kwargs):
        raise np.linalg.LinAlgError("1-th leading minor not positive definite")

    monkeypatch.setattr(sla, "cholesky_banded", cholesky_banded)
    r = run("modes", S11, "--mesh", "4x4")
    assert r.exit_code == 1
    assert "the factorisation of K - sigma M failed" in r.output and "try another mesh" in r.output
