"""`laminid modes` end to end through click."""

import json
import logging
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.results import read_h5

S11 = "specimens/example1/S1.1.yaml"


def run(*args):
    return CliRunner().invoke(cli, list(args))


def test_table_shows_model_measured_residuals_and_global_properties():
    r = run("modes", S11, "--mesh", "8x8")
    assert r.exit_code == 0, r.output
    assert "mode    model Hz  measured Hz  residual %" in r.output
    assert "125.05" in r.output and "1343.80" in r.output
    assert "6 rigid-body modes dropped" in r.output
    assert "Ex 44.45 GPa" in r.output        # [45/0/-45/90]s quasi-isotropic at the initial guess


def test_json_is_machine_readable_and_consistent():
    r = run("modes", S11, "--mesh", "8x8", "--json", "--modes", "14")
    assert r.exit_code == 0, r.output
    assert "coarse for 14 modes" in r.stderr        # 2025 equations: 145 per mode
    d = json.loads(r.stdout)
    fr = d["frequencies"]
    assert len(fr["model"]) == 14 and fr["measured"][12] is None and fr["weight"][13] == 0
    m, x = np.array(fr["model"][:12]), np.array(fr["measured"][:12])
    assert np.allclose(fr["residual_percent"][:12], (x - m) / x * 100)
    assert d["global_properties"]["Ex"] == pytest.approx(d["global_properties"]["Ey"], rel=1e-9)
    assert d["materials"]["IM7/977-2"]["E1"] == 117.2e9


def test_json_says_the_unit_of_every_number():
    """modes --json gave a = 0.2105, E1 1.172e11, mass 0.3225, frequencies 105.5 ... and no
    word of their units (a program had to know laminid is SI); "units" now names them, the
    existing keys unchanged."""
    r = run("modes", S11, "--mesh", "4x4", "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["units"] == {
        "a": "m", "b": "m", "h": "m", "mass": "kg", "model_mass": "kg", "density": "kg/m^3",
        "E1": "Pa", "E2": "Pa", "G12": "Pa", "G13": "Pa", "G23": "Pa", "Ex": "Pa", "Ey": "Pa",
        "Gxy": "Pa", "Gxz": "Pa", "Gyz": "Pa", "nu12": "1", "nu_xy": "1", "nu_yx": "1",
        "frequencies": "Hz", "measured": "Hz", "model": "Hz", "weight": "1",
        "residual_percent": "%", "rms_residual_percent": "%", "time_s": "s"}
    assert list(d)[:-1] == ["specimen", "mesh", "materials", "frequencies",
                            "rms_residual_percent", "global_properties", "time_s", "warnings"]
    # S1.1 at 4x4: the mesh is coarse for its 12 modes (also on stderr), nothing else
    assert len(d["warnings"]) == 1 and d["warnings"][0].startswith(
        f"{S11}: the mesh 4x4 (") and f"warning: {d['warnings'][0]}\n" == r.stderr
    assert d["specimen"]["a"] == 0.2105 and d["frequencies"]["measured"][0] == 125.05
    assert d["materials"]["IM7/977-2"]["density"] == pytest.approx(1609.9, rel=1e-4)


def test_hdf5_output_round_trip_and_no_silent_overwrite(tmp_path):
    out = tmp_path / "m.h5"
    r = run("modes", S11, "--mesh", "6x6", "-o", str(out), "--json")
    assert r.exit_code == 0, r.output
    d = read_h5(out)
    assert d["@attrs"]["format"] == "laminid-modes"
    assert d["frequencies"]["model"].shape == (12,)
    assert np.allclose(d["frequencies"]["model"], json.loads(r.stdout)["frequencies"]["model"])
    assert d["modes"]["w"].shape == (d["mesh"]["nodes"].shape[0], 12)
    assert "45_3/0_3" in d["specimen"]["yaml"]
    before = out.read_bytes()
    r = run("modes", S11, "--mesh", "6x6", "-o", str(out))
    assert r.exit_code == 2 and "file exists" in r.output
    assert out.read_bytes() == before
    assert not list(tmp_path.glob(".*tmp*"))


def test_bad_input_gives_message_and_exit_2(tmp_path):
    r = run("modes", str(tmp_path / "missing.yaml"))
    assert r.exit_code == 2 and "missing.yaml" in r.output and "not found" in r.output
    bad = tmp_path / "bad.yaml"
    bad.write_text(Path(S11).read_text().replace("h: 3.06 mm", "h: 3.06 GPa"))
    r = run("modes", str(bad))
    assert r.exit_code == 2 and "geometry.h" in r.output and "Traceback" not in r.output
    r = run("modes", S11, "--mesh", "abc")
    assert r.exit_code == 2 and "NXxNY" in r.output
    r = run("modes", S11, "--boundary", "pinned")
    assert r.exit_code == 2 and "F/S/C" in r.output


def test_boundary_override():
    r = run("modes", S11, "--mesh", "6x6", "--boundary", "clamped", "--modes", "3", "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["mesh"]["rigid_modes_dropped"] == 0


def test_an_edge_code_is_a_modes_boundary_not_a_specimens(tmp_path):
    """README: the specimen's boundary is free, simply-supported or clamped; modes --boundary
    also takes an edge code (CFFF: the cantilever), which the specimen file refuses."""
    r = run("modes", S11, "--mesh", "4x4", "--boundary", "CFFF", "--modes", "3", "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["mesh"]["rigid_modes_dropped"] == 0
    spec = tmp_path / "cantilever.yaml"
    spec.write_text(Path(S11).read_text().replace("boundary: free", "boundary: CFFF"))
    r = run("modes", str(spec), "--mesh", "4x4")
    assert r.exit_code == 2
    # it was "unknown boundary condition 'cfff' (valid: ...)": the code lowercased, and not
    # said to be a code that modes --boundary takes
    assert r.output == (f"laminid: error: {spec}:26, field 'boundary': 'CFFF' is an edge code, "
                        "which only 'laminid modes --boundary' takes; a specimen's boundary is "
                        "one of free, simply-supported, clamped (what identify and batch fit)\n")


def test_a_mode_not_measured_keeps_the_columns():
    """A null frequency (mode not detected) prints "-" right-aligned in its columns, so the
    row lines up with the header and the measured rows."""
    from laminid_cli.commands.text import format_frequency_table

    nan = float("nan")
    lines = format_frequency_table({"model": [105.12, 374.66], "measured": [125.05, nan],
                                    "residual_percent": [15.93, nan], "weight": [1.0, 0.0]})
    head, full, missing = lines
    assert len(full) == len(missing) == len(head)
    assert missing.split() == ["2", "374.66", "-", "-", "0"]
    ends = [m.end() for m in re.finditer(r"\S+", head)]            # right-aligned columns
    assert [m.end() for m in re.finditer(r"\S+", missing)] == [ends[0], ends[2], ends[4],
                                                                ends[6], ends[7]]


def test_a_residual_that_rounds_to_zero_has_no_minus():
    """A very good fit's residual of -0.001 % printed "-0.00" (identify, show, modes): now
    "0.00", in the column's width; a residual that does not round to zero keeps its sign, and
    so does the mesh check's signed change ("+0.000", not "-0.000")."""
    from laminid_cli.commands.text import fmt, format_frequency_table

    lines = format_frequency_table({"model": [105.12, 374.66, 500.0],
                                    "measured": [105.12, 374.65, 500.03],
                                    "residual_percent": [-0.001, -0.0049, -0.006],
                                    "weight": [1.0, 1.0, 1.0]})
    head, *rows = lines
    assert [r.split()[3] for r in rows] == ["0.00", "0.00", "-0.01"]
    assert all(len(r) == len(head) for r in rows)
    assert "-0.00" not in "\n".join(lines)
    assert fmt(-4e-4, "+8.3f") == "  +0.000" and fmt(-0.0, ".2f") == "0.00"
    assert fmt(-0.02, "10.2f") == "     -0.02"


HEAVY = """\
name: T
geometry: {a: 200 mm, b: 300 mm, h: 3 mm}
mass: 0.5 kg
materials:
  CFRP: {E1: 117.2 GPa, E2: 8.8 GPa, G12: 3.1 GPa, G13: 3.1 GPa, G23: 3.1 GPa, nu12: 0.35,
         density: 1550 kg/m^3}
layup: "[0/90]s"
measured:
  frequencies: [100, 200, 300]
"""


def test_warnings_read_as_the_commands_own_and_name_their_module_with_v(tmp_path):
    """laminid's logged warnings come out as "warning: ..." (as the commands write theirs), not
    "WARNING laminid_cli.specimen: ..."; -v names the module. The model mass of this plate,
    1550 kg/m^3 x 0.2 x 0.3 x 0.003 m^3 = 0.279 kg, is 44.2 % below the 0.5 kg weighed."""
    import subprocess
    import sys
    from pathlib import Path

    spec = tmp_path / "heavy.yaml"
    spec.write_text(HEAVY)
    root = Path(__file__).resolve().parents[1]
    words = (f"{spec}:3, field 'mass': the model mass 0.279 kg differs from the measured "
             "mass 0.5 kg by -44.2 %: the density 1550 kg/m^3 (line 6) x the volume 200 x 300 "
             "x 3 mm gives 0.279 kg, 0.558 times the mass (more than the 2 % a weighed plate "
             "and its measured sides and thickness agree to); laminid uses the density, not the "
             "mass, and every identified modulus scales with it (E ~ rho f^2); if the weighing "
             "is right, leave out density (then mass / (a b h) = 2778 kg/m^3) or set "
             "scale_density_to_mass: true (the density scaled by 1.792 to the mass)")
    for flags, line in (([], f"warning: {words}"),
                        (["-v"], f"WARNING laminid_cli.specimen: {words}")):
        p = subprocess.run([sys.executable, "-m", "laminid_cli", *flags, "modes", str(spec),
                            "--mesh", "4x4", "--json"], capture_output=True, text=True,
                           cwd=root, timeout=120)
        assert p.returncode == 0, p.stderr
        assert line in p.stderr.splitlines(), p.stderr
        json.loads(p.stdout)


def test_logging_configured_by_the_caller_keeps_its_format(tmp_path):
    """laminid used in-process by a program that set up logging itself (here a "{"-style
    format): the command runs, and the program's handler keeps its formatter (before, every
    plain formatter on the root logger was replaced, and a "{" format made the command fail)."""
    import logging

    spec = tmp_path / "heavy.yaml"
    spec.write_text(HEAVY)
    root = logging.getLogger()
    fmt = logging.Formatter("{levelname} {name}: {message}", style="{")
    handler = logging.StreamHandler()
    handler.setFormatter(fmt)
    root.addHandler(handler)
    try:
        r = run("modes", str(spec), "--mesh", "4x4", "--json")
    finally:
        root.removeHandler(handler)
    assert r.exit_code == 0, r.output
    assert handler.formatter is fmt


def test_laminid_warnings_keep_their_traceback_and_other_loggers_their_name():
    import logging

    from laminid_cli.cli import _UserFormatter

    f = _UserFormatter("%(levelname)s %(name)s: %(message)s")
    try:
        1 / 0
    except ZeroDivisionError:
        import sys

        exc = sys.exc_info()
    own = logging.LogRecord("laminid_cli.batch", logging.ERROR, __file__, 1, "job %s failed",
                            ("S1.1",), exc)
    text = f.format(own).splitlines()
    assert text[0] == "error: job S1.1 failed" and text[-1] == "ZeroDivisionError: division by zero"
    other = logging.LogRecord("distributed.scheduler", logging.WARNING, __file__, 1, "busy", (),
                              None)
    assert f.format(other) == "WARNING distributed.scheduler: busy"


def test_measured_frequencies_in_khz_are_warned_with_the_values(tmp_path):
    """S1.1's measured frequencies written in kHz as bare numbers (bare is Hz): modes said
    nothing beside residuals of -83966 % and exit 0."""
    text = Path(S11).read_text()
    khz = "[0.12505, 0.20350, 0.33130, 0.44665, 0.49355, 0.60380, 0.65075, 0.81870, 0.95135, " \
          "0.99065, 1.25675, 1.34380]"
    spec = tmp_path / "khz.yaml"
    spec.write_text(re.sub(r"frequencies: \[[^\]]*\]", f"frequencies: {khz}", text))
    r = run("modes", str(spec), "--mesh", "8x8", "--json")
    assert r.exit_code == 0, r.output
    assert (f"warning: {spec}: measured mode 1 (0.125 Hz) is 83966 % from the model (105.1 Hz); "
            "12 of 12 measured modes are more than 50 % off") in r.stderr
    assert "look like kHz: write them in Hz" in r.stderr
    json.loads(r.stdout)
    r = run("modes", S11, "--mesh", "8x8")   # the paper's plate: no warning
    assert r.exit_code == 0 and "warning" not in r.stderr


def test_moduli_below_a_gpa_keep_their_digits(tmp_path):
    """S1.1's moduli written in MPa (a unit slip): the material line and the laminate's
    properties showed 'G12 0.00 GPa', then (below 0.1 GPa fixed) 'E1 0.12 GPa', values the
    file does not hold; they show 3 digits as identify's tables do, and the measured modes
    are warned about (exit 0: modes computes)."""
    from laminid_cli.commands.text import _num, format_constant

    spec = tmp_path / "mpa.yaml"
    spec.write_text(re.sub(r" GPa$", " MPa", Path(S11).read_text(), flags=re.M))
    r = run("modes", str(spec), "--mesh", "4x4")
    assert r.exit_code == 0, r.output
    assert ("material IM7/977-2: E1 0.117 GPa, E2 0.0088 GPa, G12 0.0031 GPa, G13 0.0031 GPa, "
            "G23 0.0031 GPa, nu12 0.350") in r.stdout
    assert ("global laminate properties (Appendix A): Ex 0.0445 GPa, Ey 0.0445 GPa, Gxy 0.0167 "
            "GPa, Gxz 0.0031 GPa, Gyz 0.0031 GPa") in r.stdout
    assert "0.00 GPa" not in r.stdout and "0.12 GPa" not in r.stdout
    assert f"warning: {spec}: measured mode 1 (125 Hz) is 97 % from the model" in r.stderr
    # identify's tables (their cells) by the same rule; from 1 GPa two decimals
    assert [_num("E1", v) for v in (0.1172e9, 0.5e9, 0.00293e9, 1.172e9, 117.2e9)] == [
        "0.117", "0.5", "0.00293", "1.17", "117.20"]
    assert format_constant("G12", 0.1172e9) == "0.117 GPa"


def test_a_single_ply_plate_is_one_ply(tmp_path):
    spec = tmp_path / "alu.yaml"
    spec.write_text("geometry: {a: 300 mm, b: 200 mm, h: 3 mm}\nmass: 486 g\n"
                    "materials: {Al: {E: 70 GPa, nu: 0.3}}\nlayup: '[0]'\n")
    r = run("modes", str(spec), "--mesh", "4x4")
    assert r.exit_code == 0, r.output
    assert "plate 300 x 200 x 3 mm, 1 ply, mass 0.486 kg (model 0.486 kg)" in r.stdout
    assert "plies" not in r.stdout


def test_a_plate_1000_times_too_light_is_warned_not_refused(tmp_path, caplog):
    """An aluminium plate of 486 g written 'mass: 0.486 g' (2.7 kg/m^3, inside the accepted
    1-25000 kg/m^3): modes printed a first mode of 5192 Hz (the plate's 164.2 Hz times
    sqrt(1000)) without a word when no frequencies were measured."""
    spec = tmp_path / "alu.yaml"
    spec.write_text("geometry: {a: 300 mm, b: 200 mm, h: 3 mm}\nmass: 0.486 g\n"
                    "materials: {Al: {E: 70 GPa, nu: 0.3}}\nlayup: '[0]'\n")
    with caplog.at_level(logging.WARNING, logger="laminid_cli"):   # (stderr: the CLI's handler)
        r = run("modes", str(spec), "--mesh", "4x4", "--json")
    assert r.exit_code == 0, r.output
    assert (f"{spec}:2, field 'mass': the plate's density, mass / (a b h) = '0.486 g' = "
            "0.000486 kg / (300 x 200 x 3 mm), is 2.7 kg/m^3, lighter than any solid plate"
            in caplog.text), caplog.text
    assert "1000 times it is 2700 kg/m^3" in caplog.text
    light = json.loads(r.stdout)["frequencies"]["model"][0]
    spec.write_text(spec.read_text().replace("0.486 g", "486 g"))
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="laminid_cli"):
        r = run("modes", str(spec), "--mesh", "4x4", "--json")
    assert r.exit_code == 0 and "lighter" not in caplog.text
    real = json.loads(r.stdout)["frequencies"]["model"][0]
    assert light / real == pytest.approx(1000 ** 0.5, rel=1e-9)


def _mode1(*args):
    r = run("modes", S11, "--json", *args)
    assert r.exit_code == 0, r.output
    return r, json.loads(r.stdout)["frequencies"]["model"]


def test_a_mesh_too_coarse_for_the_modes_asked_is_warned_with_a_finer_one():
    """modes --mesh 2x2 said nothing although S1.1's mode 1 is 3.8 % off the 12x12 mesh's
    (105.48 against 101.61 Hz; mode 12 50 % off); it warns now, pointing to a finer mesh and to
    identify --mesh-check, and the default 12x12 (mode 12 0.17 % off 32x32) does not."""
    r, coarse = _mode1("--mesh", "2x2")
    fine_r, fine = _mode1()                                   # the default 12x12
    assert abs(coarse[0] - fine[0]) / fine[0] > 0.03          # measured: 3.8 %
    assert (f"warning: {S11}: the mesh 2x2 (189 equations) is coarse for 12 modes: 15.7 "
            "equations per mode, fewer than 150, where the highest mode computed is typically "
            "1 % or more off a converged mesh. Use --mesh 8x8 or finer, and check a mesh with "
            "'laminid identify --mesh-check'") in r.stderr, r.stderr
    assert "warning" not in fine_r.stderr
    # one mode on 2x2 (189 equations): too few elements all the same (mode 1 3.8 % off)
    r, _ = _mode1("--mesh", "2x2", "--modes", "1")
    assert "coarse for 1 mode: fewer than 4 elements along a side" in r.stderr
    assert "Use --mesh 4x4 or finer" in r.stderr
    # the default mesh holds 28 modes (4329 equations), not 30 (S1.1's mode 30 1.5 % off)
    assert "coarse" not in _mode1("--modes", "28")[0].stderr
    r, _ = _mode1("--modes", "30")
    assert "the mesh 12x12 (4329 equations) is coarse for 30 modes: 144.3 equations" in r.stderr
    # 1197 equations for 8 modes are 149.6 a mode: rounded down, not "150 ..., fewer than 150"
    r, _ = _mode1("--mesh", "6x6", "--modes", "8")
    assert "(1197 equations) is coarse for 8 modes: 149.6 equations per mode, fewer than 150" \
        in r.stderr, r.stderr
    assert "coarse" not in _mode1("--mesh", "8x8")[0].stderr   # 169 per mode, mode 12 0.8 %


def test_a_terminal_is_told_what_runs_on_a_line_erased_when_done(monkeypatch):
    """modes on 40x40 with 40 modes (a convergence check) built and solved for 10 s with
    nothing on a terminal; it now says what it builds, then what it solves, each on a line
    erased when done (12x12 takes 0.4 s: nothing left behind). Not with --json, nor under
    -q or on a pipe."""
    import laminid_cli.commands.modes as cmd

    monkeypatch.setattr(cmd, "stderr_is_terminal", lambda: True)
    r = run("modes", S11, "--mesh", "4x4", "--modes", "3")
    assert r.exit_code == 0, r.output
    steps = ["  building the model on a 4x4 mesh", "  solving 3 modes of 585 equations"]
    assert r.stderr == "".join(s + "\r" + " " * len(s) + "\r" for s in steps)
    assert r.stdout.startswith("S1.1 — ")
    assert run("modes", S11, "--mesh", "4x4", "--modes", "3", "--json").stderr == ""
    assert run("-q", "modes", S11, "--mesh", "4x4", "--modes", "3").stderr == ""
