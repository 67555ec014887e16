"""laminid_cli.pipeline: the one identification pipeline of `identify` and `batch`."""

import dataclasses
import json

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.batch import BatchOptions, input_hash
from laminid_cli.cli import cli
from laminid_cli.errors import FitInputError, LaminidError
from laminid_cli.identify import IdentifyOptions
from laminid_cli.pipeline import RunOptions, run_identification, write_result
from laminid_cli.uncertainty import UncertaintyOptions

S14 = "specimens/example1/S1.4.yaml"
S21 = "specimens/example2/S2.1.yaml"
MESH = "6x6"


def test_fix_is_split_between_the_stiffness_fit_and_the_loss_factors():
    o = RunOptions.with_fix(" nu12, glass.G13 ,eta13=0.01,carbon.eta23=0.02,", mesh="8x8",
                            identify=IdentifyOptions(optimizer="mma"))
    assert o.identify.fix == ("nu12", "glass.G13") and o.identify.optimizer == "mma"
    assert o.fix_loss == ("eta13=0.01", "carbon.eta23=0.02")
    assert o.fix == ("nu12", "glass.G13", "eta13=0.01", "carbon.eta23=0.02")
    assert o.mesh == "8x8" and RunOptions.with_fix(["G23"]).identify.fix == ("G23",)


def _other(value):
    """A different value of the same kind (for every option field)."""
    if isinstance(value, bool):
        return not value
    if isinstance(value, (int, float)):
        return value * 2 + 1
    if isinstance(value, str):
        return value + "x"
    if isinstance(value, tuple):
        return value + ("nu12",)
    if value is None:
        return 3
    raise AssertionError(f"no other value for {value!r}")


def test_every_option_field_changes_the_batch_hash(tmp_path):
    """The batch options are the identify and uncertainty option classes themselves, so a
    field added to either is hashed without being declared again; all but the processes of
    the profiles and Monte Carlo trials (``uncertainty.jobs``), which do not change a result
    (batch -j 1 gives them the cores, a pool of workers one each)."""
    spec = tmp_path / "p.yaml"
    spec.write_text("x: 1\n")
    base = BatchOptions(mesh=MESH)
    h0 = input_hash(spec, base)
    seen = {h0}
    variants = [dataclasses.replace(base, mesh="7x7"),
                dataclasses.replace(base, fix_loss=("eta13=0.01",))]
    same = []
    for part in ("identify", "uncertainty"):
        opts = getattr(base, part)
        for f in dataclasses.fields(opts):
            changed = dataclasses.replace(opts, **{f.name: _other(getattr(opts, f.name))})
            (same if (part, f.name) == ("uncertainty", "jobs") else variants).append(
                dataclasses.replace(base, **{part: changed}))
    for v in variants:
        h = input_hash(spec, v)
        assert h not in seen, v
        seen.add(h)
    assert len(seen) == 2 + len(dataclasses.fields(IdentifyOptions)) + \
        len(dataclasses.fields(UncertaintyOptions))
    assert len(same) == 1
    for jobs in (None, 2, 1):
        v = dataclasses.replace(base, uncertainty=dataclasses.replace(base.uncertainty,
                                                                      jobs=jobs))
        assert input_hash(spec, v) == h0
    # JSON-safe and stable
    d = base.as_dict()
    assert json.loads(json.dumps(d)) == d and input_hash(spec, BatchOptions(mesh=MESH)) == h0
    assert d["identify"]["xtol_rel"] == IdentifyOptions.xtol_rel and d["mesh"] == MESH


@pytest.mark.parametrize("options, message", [
    (RunOptions(mesh="0x3"), "mesh '0x3' is degenerate: at least 2 elements per side"),
    (RunOptions(mesh="-2x3"), "mesh '-2x3' not understood"),
    (RunOptions(uncertainty=UncertaintyOptions(sigma_rel=-0.1)),
     "relative frequency uncertainty must be positive"),
    (RunOptions(uncertainty=UncertaintyOptions(max_rel_interval=0.0)),
     "--max-rel-interval must be above 0 and at most 0.3 (0.3 = 30 %: a wider interval's "
     "verdict is 'not determined', always flagged), got 0"),
    (RunOptions(uncertainty=UncertaintyOptions(max_rel_interval=0.5)),
     "--max-rel-interval must be above 0 and at most 0.3"),
])
def test_bad_settings_are_refused_before_any_work(options, message):
    with pytest.raises(LaminidError) as err:
        options.check()
    assert message in str(err.value) and err.value.exit_code == 2
    with pytest.raises(LaminidError):
        run_identification([S14], options)


def test_loss_factor_fixes_are_checked_before_the_fit():
    o = RunOptions.with_fix("eta99=0.01", mesh=MESH)
    for strict in (True, False):                      # a bad name is an error for batch too
        with pytest.raises(FitInputError, match="'eta99' is not a loss factor"):
            run_identification([S14], o, loss_fix_needs_damping=strict)
    with pytest.raises(FitInputError, match="has no measured damping"):
        run_identification([S14], RunOptions.with_fix("eta13=0.01", mesh=MESH))
    with pytest.raises(FitInputError, match="no specimen"):
        run_identification([], RunOptions(mesh=MESH))


@pytest.fixture(scope="module")
def s14_run():
    return run_identification([S14], RunOptions(mesh=MESH))


def test_the_pipeline_is_assess_then_status_bit_for_bit(s14_run):
    """The reference: the stages called one by one, as the identify command did before."""
    from laminid_cli.fe.mesh import parse_mesh
    from laminid_cli.forward import bending_model, build_forward_model
    from laminid_cli.specimen import read_specimen
    from laminid_cli.status import result_status
    from laminid_cli.uncertainty import assess

    run = s14_run
    fm = bending_model(build_forward_model(read_specimen(S14), parse_mesh(MESH)))
    assert fm.whole is not None and run.forward_models[0].plate.family == "bending"
    a = assess(fm, IdentifyOptions(), UncertaintyOptions())
    assert not run.joint and run.converged and run.damping is None and run.notes == ()
    for c_run, c_ref in zip(run.result.constants, a.result.constants):
        assert c_run.as_dict() == c_ref.as_dict()                     # exact
    assert np.array_equal(run.assessment.uncertainty.lower, a.uncertainty.lower)
    assert np.array_equal(run.assessment.uncertainty.upper, a.uncertainty.upper)
    assert run.status == result_status(a.result, a.uncertainty)
    s = run.summary
    assert s["status"] == run.status.status and s["mesh"] == {"nx": 6, "ny": 6}
    assert s["materials"]["IM7/977-2"]["E1"] == a.result.constants[0].E1
    assert s["uncertainty"]["labels"] == list(a.uncertainty.labels)


def test_identify_prints_and_writes_what_the_pipeline_gives(s14_run, tmp_path):
    run = s14_run
    out = tmp_path / "lib.result.h5"
    assert write_result(out, run, attrs={"extra": "yes"}) == out
    cli_out = tmp_path / "cli.result.h5"
    r = CliRunner().invoke(cli, ["identify", S14, "--mesh", MESH, "--json", "-o",
                                 str(cli_out)])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["materials"] == run.summary["materials"] and d["status"] == run.status.status
    assert d["reasons"] == run.summary["reasons"] and d["output"] == str(cli_out)
    with h5py.File(out) as f, h5py.File(cli_out) as g:
        assert f.attrs["extra"] == "yes" and "extra" not in g.attrs
        assert f.attrs["command"] == g.attrs["command"] == "laminid identify"
        assert f.attrs["status"] == g.attrs["status"] == run.status.status
        for key in ("E1", "E2", "G12", "G13", "G23", "nu12"):
            assert f["materials/IM7_977-2"][key][()] == g["materials/IM7_977-2"][key][()]
        assert list(f["status/codes"][()]) == list(g["status/codes"][()])
        assert np.array_equal(f["uncertainty/lower"][()], g["uncertainty/lower"][()])


def test_a_membrane_mode_in_band_at_the_answer_reidentifies_on_the_whole_plate(monkeypatch,
                                                                              s14_run,
                                                                              tmp_path):
    """The pipeline identifies a symmetric plate on its bending equations; where the membrane
    floor at the answer is not above the model's highest mode (forced here: 1 Hz at every
    constants but the file's), it says so and identifies again on the whole plate, whose
    answer equals the bending model's (E1 to 1e-8, the objective to 1e-7)."""
    import laminid_cli.forward as F

    real = F.membrane_floor_hz
    monkeypatch.setattr(F, "membrane_floor_hz",
                        lambda fm, constants=None: real(fm) if constants is None else 1.0)
    monkeypatch.setattr(F, "membrane_floor_bound_hz", lambda fm, constants: 0.0)
    run = run_identification([S14], RunOptions(mesh=MESH))
    assert run.forward_models[0].whole is None
    assert run.forward_models[0].plate.family == "all"
    assert run.summary["equations"] == "all" and s14_run.summary["equations"] == "bending"
    assert run.summary["notes"] == list(run.notes) and "notes" not in s14_run.summary
    out = write_result(tmp_path / "r.h5", run)
    with h5py.File(out) as f:                       # the note and the equations in the file
        assert f.attrs["notes"] == run.notes[0] and f.attrs["equations"] == "all"
    assert len(run.notes) == 1 and "membrane mode at 1.0 Hz" in run.notes[0]
    assert "identified on the whole plate" in run.notes[0]
    assert s14_run.forward_models[0].plate.family == "bending" and s14_run.notes == ()
    a, b = run.result, s14_run.result
    assert a.constants[0].E1 == pytest.approx(b.constants[0].E1, rel=1e-8)
    assert a.objective == pytest.approx(b.objective, rel=1e-7)


def test_the_membrane_check_at_the_answer_is_decided_by_the_floor_at_the_start(monkeypatch):
    """S1.4: the answer's membrane floor is bounded below by sqrt(mu) times the one computed at
    the file's constants (forward.membrane_floor_bound_hz), far above the model's highest mode:
    the check at the answer runs no second Lanczos (membrane_floor_hz called once, at the
    start), and the run stays on the bending equations with no note."""
    import laminid_cli.forward as F

    real, calls = F.membrane_floor_hz, []

    def counted(fm, constants=None):
        calls.append(constants)
        return real(fm, constants)

    monkeypatch.setattr(F, "membrane_floor_hz", counted)
    run = run_identification([S14], RunOptions(mesh=MESH))
    assert calls == [None]
    fm, plate = run.forward_models[0], run.result
    assert fm.plate.family == "bending" and run.notes == ()
    bound = F.membrane_floor_bound_hz(fm, plate.constants)
    assert bound > float(np.max(plate.modes.freq))
    assert bound <= real(fm, plate.constants) * (1 + 1e-12)


def test_a_membrane_mode_in_band_is_found_before_the_monte_carlo(monkeypatch):
    """The membrane check of the answer comes before the Monte Carlo (assess's ``accept``):
    a run identified again on the whole plate runs its trials once, on the whole plate, not
    first on the bending equations whose answer it drops."""
    import laminid_cli.forward as F
    import laminid_cli.uncertainty as U

    real_floor, real_mc = F.membrane_floor_hz, U.monte_carlo
    monkeypatch.setattr(F, "membrane_floor_hz",
                        lambda fm, constants=None: real_floor(fm) if constants is None else 1.0)
    monkeypatch.setattr(F, "membrane_floor_bound_hz", lambda fm, constants: 0.0)
    families = []

    def mc(result, fm, *args, **kw):
        families.append(fm.plate.family)
        return real_mc(result, fm, *args, **kw)

    monkeypatch.setattr(U, "monte_carlo", mc)
    options = RunOptions(mesh=MESH, uncertainty=UncertaintyOptions(monte_carlo=3, jobs=1))
    run = run_identification([S14], options)
    assert families == ["all"]
    assert run.assessment.monte_carlo is not None and run.assessment.monte_carlo.n_trials == 3
    assert len(run.notes) == 1 and "identified on the whole plate" in run.notes[0]


def test_membrane_modes_not_computed_means_the_whole_plate(monkeypatch):
    """Where the membrane floor cannot be computed (a solver failure), the shortcut is not
    taken: at the start bending_model keeps the whole plate; at the answer the run is
    identified again on the whole plate, and the note says why."""
    import laminid_cli.forward as F
    from laminid_cli.errors import SolverError
    from laminid_cli.fe.mesh import parse_mesh
    from laminid_cli.specimen import read_specimen

    real = F.membrane_floor_hz

    def fail(fm, constants=None):
        raise SolverError("ARPACK did not converge (test)")

    fm = F.build_forward_model(read_specimen(S14), parse_mesh(MESH))
    monkeypatch.setattr(F, "membrane_floor_hz", fail)
    assert F.bending_model(fm) is fm
    monkeypatch.setattr(F, "membrane_floor_hz",
                        lambda fm, constants=None: real(fm) if constants is None else fail(fm))
    monkeypatch.setattr(F, "membrane_floor_bound_hz", lambda fm, constants: 0.0)
    run = run_identification([S14], RunOptions(mesh=MESH))
    assert run.forward_models[0].plate.family == "all" and run.converged
    assert len(run.notes) == 1 and "membrane modes at the answer not computed" in run.notes[0]
