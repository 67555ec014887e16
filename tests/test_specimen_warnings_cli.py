"""The specimen reader's warnings and refusals through every command that reads a specimen:
on stderr, and in --json's 'warnings' (identify, modes, batch's rows); identify's terminal
report leaves out those already on stderr."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tests.clihelp import run

S21 = Path("specimens/example2/S2.1.yaml")
#: S2.1's model frequencies (6x6 mesh) with its 90s written 1.5: a start near the answer
FREQ_15 = "61.39, 82.25, 170.02, 178.53, 305.33, 337.99, 426.78, 456.58"


def _specimen(tmp_path, layup: str, name: str = "plate.yaml") -> Path:
    text = S21.read_text()
    text = re.sub(r'(?m)^layup: .*$', f'layup: "{layup}"', text)
    text = re.sub(r"(?m)^  frequencies: \[.*$", f"  frequencies: [{FREQ_15}]", text)
    path = tmp_path / name
    path.write_text(text)
    return path


def _line(path: Path, key: str) -> int:
    return next(i for i, ln in enumerate(path.read_text().splitlines(), 1)
                if ln.startswith(key + ":"))


def test_a_layup_in_radians_is_refused_by_every_command_that_reads_it(tmp_path):
    # [(0/1.571)_2/1.571/0/1.571]s: 1.571 is pi/2 to 2e-4; identify and batch fitted it as
    # 1.571 degrees (a plate of nearly parallel plies), modes alone warned
    spec = _specimen(tmp_path, "[(0/1.571)_2/1.571/0/1.571]s")
    message = (f"{spec}:{_line(spec, 'layup')}, field 'layup': the ply angles 1.571 are "
               "radians, not degrees (each a multiple of pi/12 = 15 deg to 0.001, within "
               "+-pi/2, none a whole degree): read as degrees they make a plate of nearly "
               "parallel plies; laminid reads ply angles in degrees: write 90 for 1.571 rad")
    for args in (["identify", spec, "--mesh", "6x6", "--no-output"],
                 ["modes", spec, "--mesh", "6x6"]):
        r = run(*args)
        assert r.exit_code == 2, r.output
        assert r.stderr == f"laminid: error: {message}\n"
    r = run("batch", spec, "--out", tmp_path / "out", "--mesh", "6x6", "--json")
    assert r.exit_code == 1, r.output
    row = json.loads(r.stdout)["specimens"][0]
    assert row["status"] == "error" and row["reason"] == message


def _logged(caplog) -> list[str]:
    """The specimen reader's log records (on stderr as "warning: ..." outside pytest, whose
    own handler takes them here: tests/test_modes_cli.py checks that format)."""
    out = [r.getMessage() for r in caplog.records if r.name == "laminid_cli.specimen"]
    caplog.clear()
    return out


def test_angles_that_may_be_radians_are_warned_of_in_every_commands_json(tmp_path, caplog):
    # 1.5 is 85.9 deg, pi/2 only to 0.07: warned of, on stderr and in --json's 'warnings'
    caplog.set_level("WARNING", logger="laminid_cli.specimen")
    spec = _specimen(tmp_path, "[(0/1.5)_2/1.5/0/1.5]s")
    warning = (f"{spec}:{_line(spec, 'layup')}, field 'layup': the ply angles 1.5 look like "
               "radians; laminid reads ply angles in degrees (write 85.94)")
    r = run("identify", spec, "--mesh", "6x6", "--no-output", "--json")
    assert r.exit_code == 0, r.output
    assert _logged(caplog) == [warning]
    assert json.loads(r.stdout)["warnings"][0] == warning
    r = run("modes", spec, "--mesh", "6x6", "--json")
    assert r.exit_code == 0, r.output
    assert _logged(caplog) == [warning]
    assert json.loads(r.stdout)["warnings"][0] == warning
    r = run("batch", spec, "--out", tmp_path / "out", "--mesh", "6x6", "--json")
    assert r.exit_code == 0, r.output
    assert warning in _logged(caplog)
    row = json.loads(r.stdout)["specimens"][0]
    assert row["status"] in ("ok", "check") and row["warnings"][0] == warning
    # in degrees: no such warning
    plain = _specimen(tmp_path, "[(0/90)_2/90/0/90]s", "degrees.yaml")
    r = run("modes", plain, "--mesh", "8x8", "--json")
    assert r.exit_code == 0 and "radians" not in r.output
    assert not any("radians" in w for w in json.loads(r.stdout)["warnings"])


def test_identify_reports_a_specimen_warning_once_on_the_terminal(tmp_path, caplog):
    # it was on stderr as the file was read and again among the report's warnings on stdout;
    # the report keeps the run's own warnings, and the reader's under -q (none on stderr)
    caplog.set_level("WARNING", logger="laminid_cli.specimen")
    spec = _specimen(tmp_path, "[(0/1.5)_2/1.5/0/1.5]s")
    warning = (f"{spec}:{_line(spec, 'layup')}, field 'layup': the ply angles 1.5 look like "
               "radians; laminid reads ply angles in degrees (write 85.94)")
    coarse = (f"warning: {spec}: the mesh 6x6 (1197 equations) is coarse for 8 modes: 149.6 "
              "equations per mode")
    r = run("identify", spec, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 0, r.output
    assert _logged(caplog) == [warning]
    assert "radians" not in r.stdout
    assert coarse in r.stdout
    r = run("-q", "identify", spec, "--mesh", "6x6", "--no-output")
    assert r.exit_code == 0, r.output
    assert r.stdout.count("radians") == 1 and f"\nwarning: {warning}\n" in r.stdout
    assert coarse in r.stdout
    # --json and the result file keep it
    out = tmp_path / "plate.result.h5"
    r = run("identify", spec, "--mesh", "6x6", "-o", out, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["warnings"][0] == warning
    r = run("show", out)
    assert r.exit_code == 0, r.output
    assert f"\nwarning: {warning}\n" in r.stdout


def test_a_joint_identify_reports_a_specimen_warning_once_on_the_terminal(tmp_path, caplog):
    caplog.set_level("WARNING", logger="laminid_cli.specimen")
    spec = _specimen(tmp_path, "[(0/1.5)_2/1.5/0/1.5]s")
    other = tmp_path / "S2.2.yaml"
    other.write_text(Path("specimens/example2/S2.2.yaml").read_text())
    warning = (f"{spec}:{_line(spec, 'layup')}, field 'layup': the ply angles 1.5 look like "
               "radians; laminid reads ply angles in degrees (write 85.94)")
    r = run("identify", spec, other, "--joint", "--mesh", "6x6", "--no-output")
    assert r.exit_code == 0, r.output
    assert _logged(caplog) == [warning]
    assert "radians" not in r.stdout
    assert f"warning: S2.1: {spec}: the mesh 6x6 (1197 equations) is coarse" in r.stdout
    r = run("-q", "identify", spec, other, "--joint", "--mesh", "6x6", "--no-output")
    assert f"\nwarning: S2.1: {warning}\n" in r.stdout


def test_fit_frf_into_gives_the_specimens_warnings_in_its_json(tmp_path, caplog):
    # on stderr only before: its --json's 'warnings' held the FRF reader's alone
    from laminid_cli.frf import io
    from laminid_cli.frf.store import FrfSet
    from tests.frf_synth import plate_case

    caplog.set_level("WARNING", logger="laminid_cli.specimen")
    case = plate_case(noise=0.02, seed=8)
    frf = io.write_frf(tmp_path / "plate.frf.h5",
                       FrfSet(freq=case.freq, frf=case.frf, units="Pa/N"))
    spec = _specimen(tmp_path, "[(0/1.5)_2/1.5/0/1.5]s")
    warning = (f"{spec}:{_line(spec, 'layup')}, field 'layup': the ply angles 1.5 look like "
               "radians; laminid reads ply angles in degrees (write 85.94)")
    r = run("fit-frf", frf, "--into", spec, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["warnings"] == [warning]
    # once on stderr: the checks before and after the edit logged it twice more
    assert _logged(caplog) == [warning]
    r = run("fit-frf", frf, "--into", spec)
    assert r.exit_code == 0, r.output
    assert _logged(caplog) == [warning]
    # without --into: no specimen, none of its warnings
    r = run("fit-frf", frf, "--json")
    assert r.exit_code == 0 and json.loads(r.stdout)["warnings"] == []


def test_write_measured_as_a_library_logs_the_specimens_warnings_once(tmp_path, caplog):
    # write_measured(validate=True) read the file with its warnings silenced (fit-frf --into
    # gives them itself): a program calling it was told nothing of a layup in radians. Now
    # logged once, as fit-frf --into logs them; log_warnings=False for a caller that did
    from laminid_cli.frf.into import write_measured

    caplog.set_level("WARNING", logger="laminid_cli.specimen")
    spec = _specimen(tmp_path, "[(0/1.5)_2/1.5/0/1.5]s")
    warning = (f"{spec}:{_line(spec, 'layup')}, field 'layup': the ply angles 1.5 look like "
               "radians; laminid reads ply angles in degrees (write 85.94)")
    freq = [float(f) for f in FREQ_15.split(", ")]
    write_measured(spec, freq, [0.1] * len(freq), backup=False)
    assert _logged(caplog) == [warning]
    write_measured(spec, freq, [0.1] * len(freq), backup=False, log_warnings=False)
    assert _logged(caplog) == []
    assert f"frequencies: [{FREQ_15}]" in spec.read_text()


def test_report_does_not_warn_again_of_the_stored_specimen(tmp_path, caplog):
    # drawing the modes page rebuilt the model from the result's stored specimen, and its
    # reader logged the warnings again on stderr; the report's pages carry the result's
    caplog.set_level("WARNING", logger="laminid_cli.specimen")
    spec = _specimen(tmp_path, "[(0/1.5)_2/1.5/0/1.5]s")
    out = tmp_path / "plate.result.h5"
    r = run("identify", spec, "--mesh", "6x6", "-o", out, "--json")
    assert r.exit_code == 0, r.output
    assert len(_logged(caplog)) == 1
    r = run("report", out, "-o", tmp_path / "plate.pdf")
    assert r.exit_code == 0, r.output
    assert _logged(caplog) == []
