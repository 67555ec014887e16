"""``identify --mesh-check`` (laminid_cli.meshcheck): the frequency changes against direct
solves, the first-order shift of the constants against re-identifying on the finer mesh, the
verdict, JSON and HDF5."""

import json

import numpy as np
import pytest

from laminid_cli.forward import build_forward_model
from laminid_cli.meshcheck import check_mesh, common_nodes
from laminid_cli.pipeline import RunOptions, run_identification
from laminid_cli.resultfile import read_result
from tests.clihelp import run

S11 = "specimens/example1/S1.1.yaml"


@pytest.fixture(scope="module")
def s11_6():
    return run_identification([S11], RunOptions(mesh="6x6", mesh_check=True))


@pytest.fixture(scope="module")
def s11_12():
    return run_identification([S11], RunOptions(mesh="12x12", mesh_check=True))


def test_every_coarse_node_is_a_fine_node_at_the_same_place():
    fm6 = build_forward_model(_spec(), (6, 6))
    fm12 = build_forward_model(_spec(), (12, 12))
    idx = common_nodes(fm6.plate.mesh, fm12.plate.mesh)
    assert np.array_equal(fm12.plate.mesh.nodes[idx], fm6.plate.mesh.nodes)


def _spec():
    from laminid_cli.specimen import read_specimen

    return read_specimen(S11)


@pytest.mark.parametrize("which", ["s11_6", "s11_12"])
def test_changes_are_those_of_two_direct_solves(which, request):
    # the reference: ForwardModel.solve of the whole plate on both meshes at the same constants
    # (the check runs on the bending equations alone: the same modes to ~1e-11)
    r = request.getfixturevalue(which)
    mc = r.mesh_check
    c = r.result.constants
    coarse = build_forward_model(_spec(), mc.mesh).solve(c, n_modes=14)
    fine = build_forward_model(_spec(), mc.fine_mesh).solve(c, n_modes=14)
    assert mc.fine_mesh == (2 * mc.mesh[0], 2 * mc.mesh[1])
    # S1.1's modes keep their order on the finer mesh (lowest MAC 0.950 at 6x6, 0.9997 at
    # 12x12): the MAC pairing is the sorted order here
    assert np.array_equal(mc.fine_mode, mc.model_mode)
    assert mc.mac.min() > 0.9
    f_c, f_f = coarse.freq[mc.model_mode - 1], fine.freq[mc.fine_mode - 1]
    assert np.allclose(mc.freq_hz, f_c, rtol=1e-9, atol=0)
    assert np.allclose(mc.fine_hz, f_f, rtol=1e-9, atol=0)
    assert np.allclose(mc.change_percent, (f_f - f_c) / f_c * 100, rtol=0, atol=1e-9)
    sigma = 0.002 * r.result.measured_hz[mc.measured_mode - 1]       # --sigma-rel 0.2 %
    assert np.allclose(mc.change_sigma, (f_f - f_c) / sigma, rtol=1e-9, atol=1e-12)


def test_mode_12_of_s11_at_12x12_is_0155_percent_above_24x24(s11_12):
    # the measurement that motivated the check (README, mesh): 0.155 % against 0.2 % sigma
    assert s11_12.mesh_check.change_percent[11] == pytest.approx(-0.1543, abs=2e-4)
    assert s11_12.mesh_check.change_sigma[11] == pytest.approx(-0.772, abs=2e-3)


def _shift_against_reidentifying(r, again):
    """(the first-order shifts of ``r``'s mesh check, the shifts measured by ``again``, S1.1
    identified on the check's finer mesh), in % of each constant."""
    mc = r.mesh_check
    assert tuple(again.forward_models[0].mesh_size) == tuple(mc.fine_mesh)
    u, uf = r.assessment.uncertainty, again.assessment.uncertainty
    assert uf.labels == u.labels == mc.labels
    measured = (uf.value - u.value) / u.value * 100
    return dict(zip(u.labels, mc.shift_percent)), dict(zip(u.labels, measured))


def test_first_order_shift_against_reidentifying_6x6_on_12x12(s11_6, s11_12):
    # S1.1 re-identified on 12x12: s11_12's identification (its mesh check runs after it and
    # changes none of its numbers), instead of a run of its own
    pred, meas = _shift_against_reidentifying(s11_6, s11_12)
    # measured: E1 -3.06 %, E2 -10.5 %, G12 +17.9 %; predicted -2.71, -9.78, +16.8: the
    # first-order step misses by 12 %, 7 %, 7 % of shifts this large (the valley curves
    # over 3-18 %); the tolerance 20 % leaves room for the optimiser's stopping tolerance
    for k in ("E1", "E2", "G12"):
        lab = f"IM7/977-2.{k}"
        assert np.sign(pred[lab]) == np.sign(meas[lab]) != 0
        assert pred[lab] == pytest.approx(meas[lab], rel=0.2)
    assert meas["IM7/977-2.E1"] == pytest.approx(-3.06, abs=0.05)


def test_first_order_shift_against_reidentifying_12x12_on_24x24(s11_12):
    pred, meas = _shift_against_reidentifying(
        s11_12, run_identification([S11], RunOptions(mesh="24x24")))
    # measured: E1 -0.275 %, E2 -0.90 %, G12 +1.21 % (README); predicted -0.275, -0.93,
    # +1.23: within 4 % (the shifts are small, the step is nearly linear); asked: 30 % on E1
    assert meas["IM7/977-2.E1"] == pytest.approx(-0.27, abs=0.01)
    assert pred["IM7/977-2.E1"] == pytest.approx(meas["IM7/977-2.E1"], rel=0.05)
    for k in ("E2", "G12"):
        lab = f"IM7/977-2.{k}"
        assert np.sign(pred[lab]) == np.sign(meas[lab]) != 0
        assert pred[lab] == pytest.approx(meas[lab], rel=0.1)


def test_6x6_is_too_coarse_and_12x12_is_not(s11_6, s11_12):
    mc = s11_6.mesh_check
    # E1 moves by 0.82 of its half-width on 12x12 (test above: -2.7 % of -3.1 % measured)
    assert mc.too_coarse[0] == "IM7/977-2.E1"
    hw = dict(zip(mc.labels, mc.shift_half_width))
    assert hw["IM7/977-2.E1"] == pytest.approx(-0.82, abs=0.02)
    assert "coarse_mesh" in s11_6.status.codes
    text = dict(zip(s11_6.status.codes, s11_6.status.texts))["coarse_mesh"]
    assert text.startswith("the mesh is too coarse for these modes: at 12x12")
    assert "E1 -2.71 % (-0.82 of its half-width)" in text
    assert text.endswith("(identify with --mesh 12x12)")
    # 12x12: the largest is E1 at -0.17 of its half-width (below 0.3)
    mc12 = s11_12.mesh_check
    assert mc12.too_coarse == () and mc12.text == ""
    assert np.nanmax(np.abs(mc12.shift_half_width)) == pytest.approx(0.166, abs=0.005)
    assert "coarse_mesh" not in s11_12.status.codes


def test_json_and_hdf5_round_trip(tmp_path):
    out = tmp_path / "s11.h5"
    r = run("identify", S11, "--mesh", "6x6", "--mesh-check", "--json", "-o", out)
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)["mesh_check"]
    assert d["fine_mesh"] == {"nx": 12, "ny": 12}
    assert d["too_coarse"][0] == "IM7/977-2.E1"
    assert d["constants"]["IM7/977-2"]["E1"]["shift_half_width"] == pytest.approx(-0.82, abs=0.02)
    back = read_result(out)
    assert back.mesh_check["text"] == d["text"] != ""
    assert back.mesh_check["labels"] == d["labels"]
    for key in ("freq_hz", "fine_hz", "change_percent", "change_sigma", "mac"):
        assert np.allclose(back.mesh_check["modes"][key], d["modes"][key], rtol=1e-12)
    assert np.array_equal(back.mesh_check["modes"]["fine_mode"], d["modes"]["fine_mode"])
    for k, v in d["constants"]["IM7/977-2"].items():
        assert back.mesh_check["constants"]["IM7/977-2"][k] == pytest.approx(v, rel=1e-12)
    assert "coarse_mesh" in back.status.codes


def test_without_the_flag_no_check_is_made(tmp_path, monkeypatch):
    import laminid_cli.meshcheck as meshcheck

    def refuse(*a, **k):
        raise AssertionError("a mesh check without --mesh-check")

    monkeypatch.setattr(meshcheck, "check_mesh", refuse)
    monkeypatch.setattr(meshcheck, "fine_model", refuse)
    out = tmp_path / "s11.h5"
    r = run("identify", S11, "--mesh", "6x6", "--json", "-o", out)
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert "mesh_check" in d and d["mesh_check"] is None
    assert "coarse_mesh" not in [x["code"] for x in d["reasons"]]
    assert read_result(out).mesh_check is None          # files without the group still read


def test_terminal_table_and_refusal_with_joint():
    r = run("identify", S11, "--mesh", "6x6", "--mesh-check", "--no-output")
    assert r.exit_code == 0, r.output
    assert "mesh check: 6x6 against 12x12" in r.output
    assert "mode        6x6 Hz      12x12 Hz  change %  change/sigma" in r.output
    assert "coarse_mesh: the mesh is too coarse for these modes: at 12x12" in r.output
    assert "warning: the mesh is too coarse" in r.output
    r = run("identify", S11, "specimens/example1/S1.2.yaml", "--joint", "--mesh-check",
            "--no-output")
    assert r.exit_code == 2
    assert "--mesh-check checks one plate's identification, not a joint one" in r.output


def test_check_mesh_needs_no_cli(s11_6):
    # the library function alone, on the run's model and assessment: the same numbers
    mc = check_mesh(s11_6.forward_models[0], s11_6.assessment)
    assert np.allclose(mc.shift, s11_6.mesh_check.shift, rtol=1e-9, equal_nan=True)


def test_report_summary_line(tmp_path):
    from laminid_cli.report import mesh_check_note

    out = tmp_path / "s11.h5"
    assert run("identify", S11, "--mesh", "6x6", "--mesh-check", "-o", out).exit_code == 0
    note = mesh_check_note(read_result(out).mesh_check)
    # mode 12: -2.003 % at 6x6 against 12x12, 10.06 sigma of 0.2 %; E1 0.82 half-width
    assert note.startswith("mesh check, 6x6 against 12x12: largest frequency change -2.003 % "
                           "(10.06 σ, mode 12); the constants move by at most 0.82 of their "
                           "95 % half-width (E1): too coarse")
