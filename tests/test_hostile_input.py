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
