"""Joint identification of plates sharing a material: objective, gradient, recovery of the
truth, sharper intervals, refused inconsistent inputs."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from laminid_cli.errors import FitInputError
from laminid_cli.forward import build_forward_model
from laminid_cli.identify import IdentifyOptions, Problem, identify
from laminid_cli.joint import JointProblem, check_shared_materials, identify_joint
from laminid_cli.material import ElasticConstants
from laminid_cli.specimen import Measured, read_specimen
from laminid_cli.uncertainty import frequency_sigma, uncertainty_of
from tests.data.paper import IDENTIFIED, S11, S13, S21

GPa = 1e9
MAT = "IM7/977-2"
TRUTH = ElasticConstants(**IDENTIFIED[S11][MAT])


def synthetic(path, mesh=(6, 6), n=12):
    spec = read_specimen(path)
    fm = build_forward_model(spec, mesh)
    f = fm.solve([TRUTH], n).freq
    spec = dataclasses.replace(spec, measured=Measured(freq=f, weight=np.ones(n)))
    return dataclasses.replace(fm, specimen=spec)


@pytest.fixture(scope="module")
def plates():
    return [synthetic(S11), synthetic(S13)]


def test_joint_objective_is_the_sum_and_its_gradient_is_analytic(plates):
    opts = IdentifyOptions(parametrization="constants")
    jp = JointProblem(plates, opts)
    assert jp.n_vars == 6 and jp.labels[0] == "IM7/977-2.E1/E1_0"
    x = jp.x0() * np.array([1.3, 1.05, 1.8, 0.9, 1.1, 0.6])
    ev = jp.evaluate(x)
    singles = [Problem(fm, opts).evaluate(x).objective for fm in plates]
    assert ev.objective == pytest.approx(sum(singles), rel=1e-10)
    assert ev.dlam_dx.shape == (24, 6)
    for j in range(6):
        h = 1e-6
        up, dn = x.copy(), x.copy()
        up[j] += h
        dn[j] -= h
        fd = (JointProblem(plates, opts).evaluate(up).objective
              - JointProblem(plates, opts).evaluate(dn).objective) / (2 * h)
        assert ev.gradient[j] == pytest.approx(fd, rel=1e-4, abs=1e-8 * abs(ev.objective)), j


def test_joint_identification_recovers_the_truth_and_sharpens_nu12(plates):
    r = identify_joint(plates, IdentifyOptions())
    assert r.converged and r.material_names == (MAT,)
    assert len(r.specimens) == 2 and r.specimen_names == ("S1.1", "S1.3")
    c = r.constants[0].as_array()
    t = TRUTH.as_array()
    assert np.allclose(c[:3], t[:3], rtol=2e-3), c / t          # E1, E2, G12
    assert abs(c[5] - t[5]) < 0.01                                # nu12
    assert r.rms_residual_percent < 0.01
    for plate in r.specimens:                                     # per-plate results, as usual
        assert plate.constants[0] == r.constants[0]
        assert plate.model_hz.shape == (12,) and plate.rms_residual_percent < 0.01
    sig = [frequency_sigma(fm.specimen.measured, 0.002) for fm in plates]
    uj = uncertainty_of(r, plates, sig, scaling="stated")
    half = {}
    for fm, s in zip(plates, sig):
        r1 = identify(fm, IdentifyOptions(), start=[TRUTH])
        half[fm.specimen.name] = uncertainty_of(r1, fm, s, scaling="stated").half_width
    nu = uj.labels.index(f"{MAT}.nu12")
    assert uj.half_width[nu] < 0.8 * min(h[nu] for h in half.values()), (uj.half_width, half)
    # information adds up: every joint interval is at most the narrower single one
    assert np.all(uj.half_width <= np.minimum(*half.values()) * 1.001)


def test_shared_material_with_different_initial_constants_is_refused(plates):
    a, b = plates
    spec_b = b.specimen.with_constants({MAT: dataclasses.replace(TRUTH, E1=120 * GPa)})
    with pytest.raises(FitInputError) as exc:
        check_shared_materials([a.specimen, spec_b])
    msg = str(exc.value)
    assert "material 'IM7/977-2' differs between specimens/example1/S1.1.yaml and" in msg
    assert "initial E1 117.2 GPa vs 120 GPa" in msg and "same initial constants" in msg
    with pytest.raises(FitInputError, match="initial E1"):
        identify_joint([a, dataclasses.replace(b, specimen=spec_b)])


def test_shared_material_with_different_densities_is_refused(plates):
    a, b = plates
    mats = dict(b.specimen.materials)
    mats[MAT] = dataclasses.replace(mats[MAT], density=1600.0)
    spec_b = dataclasses.replace(b.specimen, materials=mats)
    with pytest.raises(FitInputError, match=r"density not given vs 1600; a shared material "
                                            "needs the same density in every file"):
        check_shared_materials([a.specimen, spec_b])


def test_fixed_lists_are_merged_and_reported(plates):
    a, b = plates
    mats = dict(b.specimen.materials)
    mats[MAT] = dataclasses.replace(mats[MAT], fixed=("G13", "G23"))
    spec_b = dataclasses.replace(b.specimen, materials=mats)
    assert check_shared_materials([a.specimen, spec_b]) == {MAT: ("G13", "G23")}
    jp = JointProblem([a, dataclasses.replace(b, specimen=spec_b)], IdentifyOptions())
    assert jp.params[0].free == ("E1", "E2", "G12", "nu12") and jp.n_vars == 4
    assert jp.merged_fixed == {MAT: ("G13", "G23")}


def test_joint_needs_two_plates_that_share_a_material(plates):
    with pytest.raises(FitInputError, match="two or more specimens"):
        identify_joint(plates[:1])
    glass = build_forward_model(read_specimen(S21), (4, 4))
    with pytest.raises(FitInputError, match="share no material"):
        identify_joint([plates[0], glass])


def test_one_plates_data_under_two_names_is_refused_naming_both_files(tmp_path):
    """A copy of a specimen file under another name (its name and comments edited) was a
    second plate to --joint: the same measured frequencies counted twice. The data are
    compared, not the names; a frequency differing in its last digit is another plate."""
    from laminid_cli.joint import check_distinct_plates
    from laminid_cli.pipeline import run_identification

    text = Path(S11).read_text()
    a, b = tmp_path / "S1.1.yaml", tmp_path / "S1.1-copy.yaml"
    a.write_text(text)
    b.write_text("# copied\n" + text.replace("name: S1.1", "name: S1.1 again"))
    with pytest.raises(FitInputError) as err:
        run_identification([a, b])
    assert str(err.value) == (
        f"{b}: the same plate data as {a} (the same measured frequencies, geometry, mass and "
        "layup; a copy under another name?): a plate measured once counts once in a joint "
        "identification (twice would narrow the intervals by sqrt(2)); give each plate's file "
        "once")
    sa = read_specimen(a)
    f = sa.measured.freq.copy()
    f[-1] = np.nextafter(f[-1], np.inf)
    other = dataclasses.replace(sa, path="other.yaml",
                                measured=dataclasses.replace(sa.measured, freq=f))
    check_distinct_plates([sa, other])                     # no error: another measurement
    thicker = dataclasses.replace(sa, path="thick.yaml", h=sa.h * 1.001)
    check_distinct_plates([sa, thicker])
    check_distinct_plates([sa, read_specimen(S13)])
