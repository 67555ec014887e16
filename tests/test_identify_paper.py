"""The paper's identifications (Araujo et al. 2000, Tables 1-8) repeated on its 12x12 mesh.

From the specimen files' initial guesses: E1 within 3 %, E2 and G12 within 8 % of the paper's
identified values, and a final RMS frequency residual no worse than the paper's own over the
same modes (Tables 1, 5, 8). nu12, G13 and G23 are not compared: the paper's values are poorly
determined by the data (normalised sensitivities of 0.001-0.02; laminid lands elsewhere with
residuals as small). S1.1 runs by default (about 4 s); the others are slow.
scripts/paper_comparison.py prints the full table.
"""

import numpy as np
import pytest

from laminid_cli.forward import build_forward_model
from laminid_cli.identify import IdentifyOptions, Problem, identify
from laminid_cli.material import infeasibility_reasons
from laminid_cli.specimen import read_specimen
from tests.data.paper import (CM, ESL, IDENTIFIED, IDENTIFIED_GLOBAL, RESIDUALS, S11, S12, S13,
                              S14, S21, S22)

MESH = (12, 12)
TOLERANCE = {"E1": 0.03, "E2": 0.08, "G12": 0.08}


#: uncertainty of the paper's residual RMS from printing each residual to 0.01 % (half a digit
#: on every residual, taken in the worst case: 0.005 %)
PAPER_RMS_ROUNDING = 0.005


def rms_over_paper_modes(path, result):
    """(laminid RMS, paper RMS) in %, over the modes the paper reports a residual for."""
    paper = np.array([np.nan if v is None else v for v in RESIDUALS[path]])
    use = np.isfinite(paper) & (result.weight > 0) & np.isfinite(result.residual_percent)
    ours = float(np.sqrt(np.mean(result.residual_percent[use] ** 2)))
    return ours, float(np.sqrt(np.mean(paper[use] ** 2)))


def identify_paper(path, **options):
    fm = build_forward_model(read_specimen(path), MESH)
    return identify(fm, IdentifyOptions(**options))


def check_against_paper(path, result, values):
    """values: name -> identified value to compare with IDENTIFIED (or IDENTIFIED_GLOBAL)."""
    assert result.converged, result.status
    # for the ESL (one 0-degree layer) IDENTIFIED holds Table 6's Ex, Ey, Gxy as E1, E2, G12
    ref = IDENTIFIED[path][result.material_names[0]]
    err = {k: values[k] / ref[k] - 1 for k in TOLERANCE}
    ours, paper = rms_over_paper_modes(path, result)
    msg = f"{path}: relative differences {err}, RMS {ours:.3f} % (paper {paper:.3f} %)"
    for k, tol in TOLERANCE.items():
        assert abs(err[k]) < tol, msg
    # the paper prints each residual to 0.01 %: the RMS of its rounded residuals is known to
    # about +-0.003 %, so "no worse than the paper" allows that rounding and nothing more
    assert ours <= paper + PAPER_RMS_ROUNDING, msg


def test_paper_s11():
    """S1.1, Table 2: E1 161.1, E2 9.3, G12 6.8 GPa; Table 1 residual RMS 0.103 %.
    laminid: 161.2, 9.0 (-3.2 %), 6.9 GPa, RMS 0.086 %, 29 evaluations."""
    r = identify_paper(S11)
    c = r.constants[0]
    check_against_paper(S11, r, {"E1": c.E1, "E2": c.E2, "G12": c.G12})


S13_REASON = ("S1.3: E2 10.42 GPa, +8.5 % from the paper's 9.6 (E1 -0.8 %, G12 -0.2 %, RMS "
              "0.311 % < paper 0.330 %): the paper's own residuals on S1.3 are the largest of "
              "Example 1, E2 is determined to a few % only, and laminid's optimum fits better")
# S2.2 and the hybrid ESL: the initial guess has its modes in another order than the plate;
# plain tracking kept that wrong start pairing (RMS 1.12 % and 4.35 %), re-anchoring in sorted
# order at the optimum (laminid_cli.identify.run_optimizer) reaches the paper's optimum on S2.2;
# on the hybrid ESL the plain sorted pairing from the start that follows it fits better
# (1.536e-4, RMS 0.139 %) and is kept (identify._sorted_from_start).


@pytest.mark.slow
@pytest.mark.parametrize("path", [
    S12,
    pytest.param(S13, marks=pytest.mark.xfail(strict=True, raises=AssertionError,
                                              reason=S13_REASON)),
    S14, S21, S22])
def test_paper_examples_1_and_2(path):
    r = identify_paper(path)
    c = r.constants[0]
    check_against_paper(path, r, {"E1": c.E1, "E2": c.E2, "G12": c.G12})


@pytest.mark.slow
def test_paper_s22_sorted_pairing():
    """S2.2 with the paper's plain sorted pairing reaches the paper's optimum (RMS 0.22 %)."""
    r = identify_paper(S22, pairing="sorted")
    c = r.constants[0]
    check_against_paper(S22, r, {"E1": c.E1, "E2": c.E2, "G12": c.G12})


@pytest.mark.slow
def test_paper_hybrid_esl_global_properties():
    """Table 6, ESL column: Ex 76.2, Ey 15.3, Gxy 3.7 GPa."""
    assert all(IDENTIFIED[ESL]["ESL"][a] == IDENTIFIED_GLOBAL[ESL][b]
               for a, b in (("E1", "Ex"), ("E2", "Ey"), ("G12", "Gxy")))
    r = identify_paper(ESL)
    g = r.global_properties
    check_against_paper(ESL, r, {"E1": g["Ex"], "E2": g["Ey"], "G12": g["Gxy"]})


@pytest.mark.slow
def test_paper_hybrid_esl_sorted_pairing():
    r = identify_paper(ESL, pairing="sorted")
    g = r.global_properties
    check_against_paper(ESL, r, {"E1": g["Ex"], "E2": g["Ey"], "G12": g["Gxy"]})


@pytest.mark.slow
def test_paper_hybrid_complete_model():
    """Two materials, 12 variables, 20 modes (Tables 7, 8).

    The paper's ply thicknesses and densities are not published (the file's are estimates), so
    the per-material constants cannot be compared; what is asserted: convergence to a feasible
    point (positive definite constitutive matrices, inside the bounds and constraints) and an
    RMS residual no worse than Table 8's (0.22 %). laminid: RMS 0.138 %; glass G12, G13 and
    G23 go to their lower limit (a modulus at 1e-4 E1), a sign that they are not determined by
    these modes with these thicknesses; Ex: see test_paper_hybrid_complete_model_global_ex.
    """
    fm = build_forward_model(read_specimen(CM), MESH)
    r = identify(fm, IdentifyOptions())
    assert r.converged, r.status
    assert len(r.variable_labels) == 12
    for c in r.constants:
        assert not infeasibility_reasons(c), c
    assert Problem(fm, IdentifyOptions()).feasible(r.x)
    ours, paper = rms_over_paper_modes(CM, r)
    assert ours <= paper, (ours, paper)


CM_EX_REASON = (
    "hybrid CM: the model's optimum has Ex 77.2 GPa, +10.8 % from Table 6's 69.7, with a lower "
    "objective (1.51554e-4) and RMS (0.1376 %): found by the reduced solver and confirmed by the "
    "full solver with ftol 1e-12 / xtol 1e-9 (1.51554e-4, Ex 77.24 GPa). The full solver's "
    "default tolerances stopped early at 69.2 GPa (objective 1.5231e-4); with the glass G12, "
    "G13, G23 at their lower limits Ex is not determined to 3 % by these modes")


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError, reason=CM_EX_REASON)
def test_paper_hybrid_complete_model_global_ex():
    """Table 6's CM column: Ex 69.7 GPa within 3 % (not met: see CM_EX_REASON)."""
    fm = build_forward_model(read_specimen(CM), MESH)
    r = identify(fm, IdentifyOptions())
    assert r.converged, r.status
    assert abs(r.global_properties["Ex"] / IDENTIFIED_GLOBAL[CM]["Ex"] - 1) < 0.03
