"""Interchange with other modal tools (issue 12): plain HDF5 FRF files in, UFF 58/55/15 out."""

from __future__ import annotations

import json
import re

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.errors import FrfError
from laminid_cli.frf import io, rfp
from laminid_cli.frf.generic_h5 import read_generic_frf_h5
from laminid_cli.frf.store import FrfSet
from tests.frf_synth import plate_case


def run(args):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


@pytest.fixture(scope="module")
def case():
    return plate_case(noise=0.005, seed=11)          # 5 points x 1601 lines, 10 modes


@pytest.fixture(scope="module")
def native(tmp_path_factory, case):
    path = tmp_path_factory.mktemp("native") / "plate.frf.h5"
    fs = FrfSet(freq=case.freq, frf=case.frf, labels=tuple("12345"), units="m/s^2/N")
    return io.write_frf(path, fs)


#: lines (1-400 Hz, the first 4 of the case's 10 modes) of the FRFs whose only check through
#: fit-frf is the unit it reports: the unit is a label, not the data, and fit-frf on the whole
#: 1601 lines costs ~1 s a run (the fits themselves are checked on the whole band elsewhere)
UNIT_LINES = 400


def _plain(path, case, *, transpose: bool, names=("frequency", "H"), freq_units="Hz",
           extra=None):
    """An HDF5 file as another tool writes it: one axis, one complex FRF, units attributes."""
    with h5py.File(path, "w") as f:
        g = f.create_group("measurement")
        d = g.create_dataset(names[0], data=case.freq)
        if freq_units is not None:
            d.attrs["units"] = freq_units
        h = g.create_dataset(names[1], data=case.frf.T if transpose else case.frf)
        h.attrs["units"] = "m/s^2/N"
        for name, value in (extra or {}).items():
            f.create_dataset(name, data=value)
    return path


def _fit_json(path, *extra):
    r = run(["fit-frf", str(path), "--json", *extra])
    assert r.exit_code == 0, r.output
    return json.loads(r.stdout)          # a reader's warning goes to stderr


@pytest.mark.parametrize("transpose", [False, True], ids=["points x freq", "freq x points"])
def test_plain_hdf5_either_orientation_fits_the_same_as_the_native_file(tmp_path, case, native,
                                                                          transpose):
    path = _plain(tmp_path / "other.h5", case, transpose=transpose)
    fs = io.read_frf(path)
    assert fs.frf.shape == (5, 1601) and fs.units == "m/s^2/N"
    np.testing.assert_array_equal(fs.frf, case.frf)      # same numbers, rows = points
    np.testing.assert_array_equal(fs.freq, case.freq)
    a, b = _fit_json(native), _fit_json(path)
    fa = [m["freq_hz"] for m in a["modes"]]
    assert len(fa) == 10 and fa == [m["freq_hz"] for m in b["modes"]]   # identical fit
    assert np.allclose(fa, case.freq_hz, rtol=1e-4)      # and it is the truth


def test_frequency_in_khz_or_rad_per_s_is_converted_to_hz(tmp_path, case):
    for units, scale in (("kHz", 1e-3), ("rad/s", 2 * np.pi)):
        path = tmp_path / f"{units.replace('/', '_')}.h5"
        with h5py.File(path, "w") as f:
            f.create_dataset("f", data=case.freq * scale).attrs["units"] = units
            f.create_dataset("frf", data=case.frf)
        np.testing.assert_allclose(read_generic_frf_h5(path).freq, case.freq, rtol=1e-12)


def test_ambiguous_file_lists_the_candidates_and_the_options_resolve_it(tmp_path, case):
    path = _plain(tmp_path / "two.h5", case, transpose=False, names=("axis_a", "H"),
                  freq_units=None, extra={"axis_b": case.freq + 0.5})
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    msg = str(info.value)
    assert "several frequency/FRF dataset pairs fit: frequency '/axis_b' (1601) + FRF " \
           "'/measurement/H' (5 x 1601, units 'm/s^2/N'); frequency '/measurement/axis_a' " \
           "(1601) + FRF '/measurement/H'" in msg
    assert "--freq-dataset PATH and --frf-dataset PATH" in msg
    fs = io.read_frf(path, freq_dataset="/axis_b", frf_dataset="measurement/H")
    np.testing.assert_array_equal(fs.freq, case.freq + 0.5)
    r = run(["fit-frf", str(path), "--json", "--freq-dataset", "/measurement/axis_a"])
    assert r.exit_code == 0, r.output


def test_a_name_or_units_decides_between_two_axes(tmp_path, case):
    path = _plain(tmp_path / "named.h5", case, transpose=True, names=("freq_hz", "H"),
                  extra={"time": np.arange(1601) * 1e-3})   # 1-D increasing, but not a freq
    assert read_generic_frf_h5(path).meta["frequency_dataset"] == "/measurement/freq_hz"


@pytest.mark.parametrize("extra, message", [
    ({}, "no complex dataset (FRF) in it; datasets: '/x' (1601)"),
])
def test_file_without_an_frf_is_refused_with_the_datasets(tmp_path, case, extra, message):
    path = tmp_path / "bad.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("x", data=case.freq)
    r = run(["fit-frf", str(path)])
    assert r.exit_code == 2 and message in r.output


def test_named_dataset_that_does_not_fit_says_why(tmp_path, case):
    path = _plain(tmp_path / "n.h5", case, transpose=False)
    with pytest.raises(FrfError, match=r"no numeric 1-D/2-D dataset '/nope' for the frequency"):
        io.read_frf(path, freq_dataset="nope")
    with pytest.raises(FrfError, match=r"'/measurement/frequency' \(1601, units 'Hz'\) is not "
                                       r"complex"):
        io.read_frf(path, frf_dataset="/measurement/frequency")
    with pytest.raises(FrfError, match="dataset paths apply to HDF5 files only"):
        io.read_frf(tmp_path / "x.csv", freq_dataset="/f")


def test_laminid_file_is_still_read_by_the_native_reader(native):
    fs = io.read_frf(native)
    assert fs.labels == tuple("12345") and "frequency_dataset" not in fs.meta


# ------------------------------------------------------------------- laminid export
LABELS = ("3", "7", "12", "15", "21")     # roving-hammer point numbers


@pytest.fixture(scope="module")
def numbered(tmp_path_factory, case):
    path = tmp_path_factory.mktemp("num") / "plate.frf.h5"
    fs = FrfSet(freq=case.freq, frf=case.frf, labels=LABELS, units="Pa/N")
    return io.write_frf(path, fs)


def test_export_frfs_as_uff58_keeps_numbers_units_and_point_numbering(tmp_path, case,
                                                                      numbered):
    import pyuff

    out = tmp_path / "plate.uff"
    r = run(["export", str(numbered), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    summary = json.loads(r.output)
    assert summary["points"] == {lab: int(lab) for lab in LABELS}
    # the frequency range written, in Hz (the --json output gave only the number of lines)
    assert summary["freq_range_hz"] == [case.freq[0], case.freq[-1]]
    assert summary["n_lines"] == case.freq.size
    assert summary["datasets"] == {"164": 1, "58": 5}
    sets = pyuff.UFF(str(out)).read_sets()
    assert [s["type"] for s in sets] == [164] + [58] * 5
    # the units record the records' types are in: SI (there was none)
    assert (sets[0]["units_code"], sets[0]["length"], sets[0]["force"]) == (1, 1.0, 1.0)
    for k, s in enumerate(sets[1:]):
        assert s["func_type"] == 4 and s["rsp_node"] == int(LABELS[k]) and s["rsp_dir"] == 3
        # the response over the force, each with its unit and UFF specific data type (15
        # pressure, 13 excitation force; it said 12 acceleration with the whole unit "Pa/N"
        # as the ordinate's and no denominator)
        assert s["ordinate_axis_units_lab"].strip() == "Pa"
        assert s["orddenom_axis_units_lab"].strip() == "N"
        assert s["ordinate_spec_data_type"] == 15 and s["orddenom_spec_data_type"] == 13
        assert s["abscissa_axis_units_lab"].strip() == "Hz"
        assert _exponents(s) == {"abscissa": (0, 0, 0), "ordinate": (-2, 1, 0),
                                 "orddenom": (0, 1, 0)}
        np.testing.assert_array_equal(s["data"], case.frf[k])     # binary 58b: lossless
        np.testing.assert_array_equal(s["x"], case.freq)


def _exponents(record) -> dict:
    """The length, force and temperature units exponents of a type-58 record as pyuff reads
    them, per axis."""
    return {axis: tuple(int(record[f"{axis}_{q}_unit_exp"]) for q in ("len", "force", "temp"))
            for axis in ("abscissa", "ordinate", "orddenom")}


#: FRF unit -> (ordinate type, exponents), (denominator type, exponents) as written: the types
#: and the exponents of Addendum A of the dataset 58 definition (translational; acceleration,
#: velocity and displacement length 1, force 1, pressure length -2 force 1), a unit not SI of
#: type 0 (unknown) and exponents 0 ("g" typed acceleration in an SI file is m/s^2 to a tool)
UFF_TYPES_WRITTEN = {
    "m/s^2/N": ((12, (1, 0, 0)), (13, (0, 1, 0))), "m/s/N": ((11, (1, 0, 0)), (13, (0, 1, 0))),
    "m/N": ((8, (1, 0, 0)), (13, (0, 1, 0))), "Pa/N": ((15, (-2, 1, 0)), (13, (0, 1, 0))),
    "(m/s^2)/N": ((12, (1, 0, 0)), (13, (0, 1, 0))), "g/N": ((0, (0, 0, 0)), (13, (0, 1, 0))),
    "mm/s/N": ((0, (0, 0, 0)), (13, (0, 1, 0))), "m/s^2/kN": ((12, (1, 0, 0)), (0, (0, 0, 0))),
    "kPa/lbf": ((0, (0, 0, 0)), (0, (0, 0, 0))), "V/V": ((0, (0, 0, 0)), (0, (0, 0, 0))),
}


@pytest.mark.parametrize("units", sorted(UFF_TYPES_WRITTEN))
def test_uff58_records_carry_the_units_exponents_of_their_types(tmp_path, case, units):
    """Records 8-10 said length, force and temperature exponents 0 0 0 whatever the unit (a
    tool reading them took an accelerance for dimensionless), in a file without a units record;
    pyuff reads the 164 record and the exponents of the spec's table back (ASCII and 58b)."""
    import pyuff

    fs = FrfSet(freq=case.freq[:50], frf=case.frf[:1, :50], labels=("1",), units=units,
                coherence=np.full((1, 50), 0.99))
    for binary in (False, True):
        out = io.write_frf_uff(tmp_path / f"{int(binary)}.uff", fs, binary=binary)
        sets = pyuff.UFF(str(out)).read_sets()
        assert [s["type"] for s in sets] == [164, 58, 58]
        assert (sets[0]["units_code"], sets[0]["length"], sets[0]["force"], sets[0]["temp"]) \
            == (1, 1.0, 1.0, 1.0)
        (num, num_exp), (den, den_exp) = UFF_TYPES_WRITTEN[units]
        frf, coh = sets[1], sets[2]
        assert (frf["ordinate_spec_data_type"], frf["orddenom_spec_data_type"]) == (num, den)
        assert _exponents(frf) == {"abscissa": (0, 0, 0), "ordinate": num_exp,
                                   "orddenom": den_exp}
        assert _exponents(coh) == dict.fromkeys(("abscissa", "ordinate", "orddenom"), (0, 0, 0))
        assert io.read_frf(out).units == units


def test_uff58_round_trip_through_fit_frf_gives_the_same_modes_to_1e9(tmp_path, numbered):
    out = tmp_path / "plate.uff"
    assert run(["export", str(numbered), "-o", str(out)]).exit_code == 0
    a, b = _fit_json(numbered), _fit_json(out)
    fa = np.array([m["freq_hz"] for m in a["modes"]])
    fb = np.array([m["freq_hz"] for m in b["modes"]])
    assert fa.size == 10 and np.allclose(fb, fa, rtol=1e-9, atol=0)
    za = np.array([m["damping_ratio"] for m in a["modes"]])
    zb = np.array([m["damping_ratio"] for m in b["modes"]])
    assert np.allclose(zb, za, rtol=1e-9, atol=0)


def test_ascii_uff58_keeps_12_significant_digits(tmp_path, case, numbered):
    out = tmp_path / "plate_ascii.uff"
    r = run(["export", str(numbered), "-o", str(out), "--ascii"])
    assert r.exit_code == 0, r.output
    back = io.read_frf(out)
    assert np.allclose(back.frf, case.frf, rtol=0, atol=5e-12 * np.abs(case.frf).max())
    assert back.labels == tuple(f"{lab}+Z" for lab in LABELS) and back.units == "Pa/N"


def test_ascii_uff58_round_trip_gives_the_same_modes_to_1e9(tmp_path):
    """The ASCII Universal File keeps 12 significant digits (above): the FRFs read back differ
    by ~5e-12 (relative), and the modes fitted to them now differ from the file's by at most
    1e-9 (relative; measured 2e-14 on these FRFs with 3 % noise, damping 2e-12). They moved by
    up to 4.5e-7 (5e-4 Hz at 1130 Hz) while the pole refinement stopped short of its optimum,
    where the stabilised RFP poles it started from decided (tests/test_rfp.py, continuity)."""
    noisy = plate_case(noise=0.03, seed=1)
    src = io.write_frf(tmp_path / "noisy.frf.h5", FrfSet(freq=noisy.freq, frf=noisy.frf,
                                                         labels=LABELS, units="Pa/N"))
    out = tmp_path / "noisy.uff"
    assert run(["export", str(src), "-o", str(out), "--ascii"]).exit_code == 0
    back = io.read_frf(out)
    assert not np.array_equal(back.frf, noisy.frf)
    a = rfp.find_modes(noisy.freq, noisy.frf)
    b = rfp.find_modes(back.freq, back.frf)
    assert len(a.modes) == len(b.modes) == 10
    np.testing.assert_allclose(b.freq_hz, a.freq_hz, rtol=1e-9, atol=0)
    np.testing.assert_allclose(b.damping_ratio, a.damping_ratio, rtol=1e-8, atol=0)


@pytest.fixture(scope="module")
def modes_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("modes") / "S1.1.modes.h5"
    r = run(["modes", "specimens/example1/S1.1.yaml", "--mesh", "6x6", "-o", str(out)])
    assert r.exit_code == 0, r.output
    return out


def test_export_mode_shapes_as_uff55_on_uff15_nodes_read_back_with_pyuff(tmp_path, modes_file):
    import pyuff

    from laminid_cli.results import read_h5

    out = tmp_path / "S1.1.unv"
    r = run(["export", str(modes_file), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "12 mode shapes of S1.1 (UFF 55) on 133 nodes" in r.output
    ref = read_h5(modes_file)
    nodes, w, freq = ref["mesh"]["nodes"], ref["modes"]["w"], ref["modes"]["frequency"]
    sets = pyuff.UFF(str(out)).read_sets()
    assert [s["type"] for s in sets] == [164, 15] + [55] * 12
    assert sets[0]["units_code"] == 1                              # SI
    n15 = sets[1]
    np.testing.assert_array_equal(n15["node_nums"], np.arange(1, 134))
    # UFF 15 writes E13.5 (6 significant digits): coordinates within 5e-6 of the plate size
    size = np.abs(nodes).max()
    assert np.abs(n15["x"] - nodes[:, 0]).max() < 5e-6 * size
    assert np.abs(n15["y"] - nodes[:, 1]).max() < 5e-6 * size
    assert np.abs(n15["z"]).max() == 0
    for k, s in enumerate(sets[2:]):
        assert s["mode_n"] == k + 1 and s["analysis_type"] == 2 and s["data_ch"] == 2
        assert s["freq"] == pytest.approx(freq[k], rel=5e-6)
        np.testing.assert_array_equal(s["node_nums"], np.arange(1, 134))
        scale = np.abs(w[:, k]).max()
        assert np.abs(s["r3"] - w[:, k]).max() < 5e-6 * scale     # E13.5 again
        assert np.abs(s["r1"]).max() == 0 and np.abs(s["r2"]).max() == 0


def test_export_refuses_to_overwrite_and_names_bad_input(tmp_path, modes_file):
    out = tmp_path / "x.unv"
    out.write_text("keep")
    r = run(["export", str(modes_file), "-o", str(out)])
    assert r.exit_code == 2 and "file exists" in r.output and out.read_text() == "keep"
    r = run(["export", str(modes_file), "-o", str(tmp_path / "y.unv"), "--specimen", "S9"])
    assert r.exit_code == 2 and "holds specimen 'S1.1', not 'S9'" in r.output


def test_export_of_a_specimen_file_says_what_export_takes(tmp_path):
    """A specimen YAML given to export (for its mode shapes) is named with the commands that
    make a result of it; the FRF reader's message named only fit-frf --into."""
    spec = tmp_path / "plate.yaml"
    spec.write_text("name: p\n", encoding="utf-8")
    out = tmp_path / "p.unv"
    r = run(["export", str(spec), "-o", str(out)])
    assert r.exit_code == 2 and not out.exists()
    assert f"{spec}: a specimen file (YAML), neither FRFs nor a result; 'laminid identify " \
           f"{spec}' (or 'laminid modes {spec} -o NAME.modes.h5')" in r.output
    assert "fit-frf" not in r.output
    doc = json.loads(run(["export", str(spec), "-o", str(out), "--json"]).stdout)["error"]
    assert doc["file"] == str(spec) and doc["exit_code"] == 2


def test_matlab_style_compound_real_imag_is_complex(tmp_path, case):
    path = tmp_path / "matlab.h5"
    pair = np.dtype([("real", "<f8"), ("imag", "<f8")])
    data = np.empty(case.frf.T.shape, dtype=pair)
    data["real"], data["imag"] = case.frf.T.real, case.frf.T.imag
    with h5py.File(path, "w") as f:
        f.create_dataset("freq", data=case.freq)
        f.create_dataset("H", data=data)
    np.testing.assert_array_equal(io.read_frf(path).frf, case.frf)


def test_export_one_plate_of_a_joint_result(tmp_path):
    """A joint result holds each plate under /specimens/<name>; --specimen picks one."""
    path = tmp_path / "joint.h5"
    nodes = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.2]])
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "laminid-joint-result"
        for name, scale in (("A", 1.0), ("B", 2.0)):
            g = f.create_group(f"specimens/{name}")
            g.create_group("specimen").attrs["name"] = name
            g.create_dataset("mesh/nodes", data=nodes * scale)
            g.create_dataset("modes/w", data=np.array([[1.0, 2.0], [3.0, -4.0], [5.0, 6.0]]))
            g.create_dataset("modes/frequency", data=[100.0, 200.0])
    out = tmp_path / "B.unv"
    r = run(["export", str(path), "-o", str(out)])
    assert r.exit_code == 2 and "a joint result of 2 plates; choose one with --specimen (A, B)" \
        in r.output
    r = run(["export", str(path), "-o", str(out), "--specimen", "C"])
    assert r.exit_code == 2 and r.output == (
        f"laminid: error: {path}: a joint result of 2 plates, none named 'C'; choose one with "
        "--specimen (A, B)\n")
    r = run(["export", str(path), "-o", str(out), "--specimen", "B", "--json"])
    assert r.exit_code == 0, r.output
    import pyuff

    sets = pyuff.UFF(str(out)).read_sets()
    np.testing.assert_allclose(sets[1]["y"], [0.0, 0.0, 0.4])
    np.testing.assert_allclose(sets[3]["r3"], [2.0, -4.0, 6.0])
    assert sets[3]["freq"] == 200.0 and sets[3]["mode_n"] == 2


def test_a_laminid_result_given_as_frfs_is_named_for_what_it_is(modes_file, tmp_path):
    """fit-frf given a laminid modes or result file names it with what reads it, as
    identify and batch do (it said "a laminid-modes file (results of laminid)" alone)."""
    import h5py

    r = run(["fit-frf", str(modes_file)])
    assert r.exit_code == 2
    assert (f"{modes_file}: a file of 'laminid modes' (a model's modes at a specimen's initial "
            f"constants), not FRFs; 'laminid export {modes_file} -o modes.unv' writes its mode "
            "shapes; give the file written by laminid acquire or another tool's FRF file"
            ) in r.output
    result = tmp_path / "r.h5"
    with h5py.File(result, "w") as f:
        f.attrs["format"] = "laminid-result"
    r = run(["fit-frf", str(result)])
    assert r.exit_code == 2
    assert (f"{result}: a laminid identification result (of laminid identify or batch), not "
            f"FRFs; 'laminid show {result}' prints it, 'laminid report {result}' draws it"
            ) in r.output


@pytest.mark.parametrize("ordinate, denominator, units", [
    ("m/s^2", "N", "m/s^2/N"),          # another tool: the response over the force
    ("Pa", "N", "Pa/N"),
    ("Pa/N", "NONE", "Pa/N"),           # laminid's own export: the whole unit, no denominator
    ("Pa/N", "", "Pa/N"),
    ("m/s^2/N", "N", "m/s^2/N"),        # the whole unit and the denominator again
])
def test_uff58_units_are_the_ordinate_over_its_denominator(tmp_path, case, ordinate,
                                                           denominator, units):
    """A UFF 58 FRF's unit is its ordinate's over its denominator's (record 10 and 11 of the
    header): an accelerance of another tool, "m/s^2" over "N", is m/s^2/N, not m/s^2."""
    import pyuff

    sets = [pyuff.prepare_58(binary=0, func_type=4, rsp_node=k + 1, rsp_dir=3, ref_node=1,
                             ref_dir=3, x=case.freq[:UNIT_LINES],
                             data=case.frf[k, :UNIT_LINES], id1="FRF",
                             abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                             orddenom_spec_data_type=13, ordinate_axis_units_lab=ordinate,
                             orddenom_axis_units_lab=denominator, abscissa_axis_units_lab="Hz")
            for k in range(2)]
    p = tmp_path / "other.uff"
    pyuff.UFF(str(p)).write_sets(sets, mode="add")
    assert io.read_frf(p).units == units
    r = run(["fit-frf", str(p), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["units"] == units


@pytest.mark.parametrize("name", ["plate.csv", "plate.h5", "plate.txt", "plate"])
def test_export_refuses_an_output_it_would_not_write_as_named(tmp_path, numbered, modes_file,
                                                              name):
    """export writes Universal Files only: an output named .csv or .h5 got a binary UFF under
    that name (which no CSV reader, nor laminid itself by its suffix, reads as such)."""
    for source in (numbered, modes_file):
        out = tmp_path / name
        r = run(["export", str(source), "-o", str(out)])
        assert r.exit_code == 2
        assert r.output == (f"laminid: error: {out}: export writes Universal Files; name the "
                            "output .uff or .unv (-o)\n")
        assert not out.exists()


@pytest.mark.parametrize("units, ordinate, ord_type, denominator, den_type", [
    ("m/s^2/N", "m/s^2", 12, "N", 13),
    # acquire --help's spelling, and example_frf.py's: an acceleration (it was 0, unknown)
    ("(m/s^2)/N", "(m/s^2)", 12, "N", 13),
    ("(m/s)/N", "(m/s)", 11, "N", 13),
    ("m/s/N", "m/s", 11, "N", 13),
    ("m/N", "m", 8, "N", 13),
    ("Pa/N", "Pa", 15, "N", 13),
    ("V/V", "V", 0, "V", 0),               # an analyser's voltage ratio: types unknown
    ("1", "1", 0, "NONE", 0),
])
def test_uff58_export_writes_the_response_and_force_units_apart(tmp_path, case, units,
                                                                ordinate, ord_type,
                                                                denominator, den_type):
    import pyuff

    fs = FrfSet(freq=case.freq, frf=case.frf[:1], labels=("1",), units=units)
    out = io.write_frf_uff(tmp_path / "x.uff", fs)
    s = pyuff.UFF(str(out)).read_sets(1)                  # after the units record
    assert (s["ordinate_axis_units_lab"].strip(), s["ordinate_spec_data_type"],
            s["orddenom_axis_units_lab"].strip(), s["orddenom_spec_data_type"]) == (
        ordinate, ord_type, denominator, den_type)
    assert io.read_frf(out).units == units                 # and laminid reads it back


def test_uff58_re_exported_keeps_its_nodes_and_directions(tmp_path, case):
    """A UFF of another tool, points 10..13 (one measured in -Z), exported again: the same
    response nodes and directions (it renumbered them 1..4, all +Z: point 1 then stood on the
    reference node 1, a driving point it is not)."""
    import pyuff

    nodes, dirs = (10, 11, 12, 13), (3, 3, -3, 3)
    sets = [pyuff.prepare_58(binary=0, func_type=4, rsp_node=n, rsp_dir=d, ref_node=1,
                             ref_dir=3, x=case.freq, data=case.frf[k], id1="FRF",
                             abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                             orddenom_spec_data_type=13, ordinate_axis_units_lab="m/s^2",
                             orddenom_axis_units_lab="N")
            for k, (n, d) in enumerate(zip(nodes, dirs))]
    src = tmp_path / "other.uff"
    pyuff.UFF(str(src)).write_sets(sets, mode="add")
    out = tmp_path / "again.uff"
    r = run(["export", str(src), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["points"] == {"10+Z": 10, "11+Z": 11, "12-Z": 12, "13+Z": 13}
    back = [s for s in pyuff.UFF(str(out)).read_sets() if s["type"] == 58]
    assert [(s["rsp_node"], s["rsp_dir"], s["ref_node"], s["ref_dir"]) for s in back] == [
        (n, d, 1, 3) for n, d in zip(nodes, dirs)]
    read = [s for s in pyuff.UFF(str(src)).read_sets() if s["type"] == 58]
    for s, t in zip(back, read):
        np.testing.assert_array_equal(s["data"], t["data"])           # binary 58b: lossless
    assert io.read_frf(out).labels == ("10+Z", "11+Z", "12-Z", "13+Z")


def test_roving_hammer_uff_keeps_its_reference_nodes(tmp_path, case):
    """A roving-hammer test: one response node (the sensor), the reference (hammer) node
    changing. Each FRF was labelled by its response alone, all "5+Z", and export wrote them
    all as 5 over reference 1: the hammer points were lost. The label now names the
    reference too where the references differ, and export keeps both."""
    import pyuff

    sets = [pyuff.prepare_58(binary=0, func_type=4, rsp_node=5, rsp_dir=3, ref_node=k + 1,
                             ref_dir=3 if k else -3, x=case.freq, data=case.frf[k], id1="FRF",
                             abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                             orddenom_spec_data_type=13)
            for k in range(3)]
    src = tmp_path / "roving.uff"
    pyuff.UFF(str(src)).write_sets(sets, mode="add")
    fs = io.read_frf(src)
    assert fs.labels == ("5+Z:1-Z", "5+Z:2+Z", "5+Z:3+Z")
    out = tmp_path / "again.uff"
    r = run(["export", str(src), "-o", str(out)])
    assert r.exit_code == 0, r.output
    back = [s for s in pyuff.UFF(str(out)).read_sets() if s["type"] == 58]
    assert [(s["rsp_node"], s["rsp_dir"], s["ref_node"], s["ref_dir"]) for s in back] == [
        (5, 3, 1, -3), (5, 3, 2, 3), (5, 3, 3, 3)]
    assert io.read_frf(out).labels == fs.labels


@pytest.mark.parametrize("binary", [True, False], ids=["58b", "ascii"])
def test_export_writes_the_coherence_as_uff58_function_type_6_and_reads_it_back(
        tmp_path, case, binary):
    """The coherence that acquire files (and UFF files read in) carry was dropped by export.
    Now each point with a coherence at every line gets a second type-58 record right after its
    FRF: function type 6 (coherence), real double data, the same DOFs. pyuff reads them, and
    laminid's reader (fit-frf) pairs them with their FRF again. A point whose coherence is
    unknown (NaN) at some line gets none: UFF has no 'unknown', and a 0 would be a value."""
    import pyuff

    rng = np.random.default_rng(5)
    coh = 1.0 - 0.3 * rng.random(case.frf.shape)
    coh[1] = np.nan                         # point 7: no coherence recorded
    coh[3, 100:110] = np.nan                # point 15: unknown at 10 lines
    src = io.write_frf(tmp_path / "coh.frf.h5", FrfSet(freq=case.freq, frf=case.frf,
                                                       coherence=coh, labels=LABELS,
                                                       units="Pa/N"))
    out = tmp_path / "coh.uff"
    r = run(["export", str(src), "-o", str(out), "--json"] + ([] if binary else ["--ascii"]))
    assert r.exit_code == 0, r.output
    summary = json.loads(r.output)
    assert summary["datasets"] == {"164": 1, "58": 8}
    assert summary["coherence_points"] == ["3", "12", "21"]
    assert summary["notes"] == ["point 15: coherence unknown at 10 of 1601 lines; not written"]
    sets = pyuff.UFF(str(out)).read_sets()[1:]          # after the units record
    assert [(s["func_type"], s["rsp_node"]) for s in sets] == [
        (4, 3), (6, 3), (4, 7), (4, 12), (6, 12), (4, 15), (4, 21), (6, 21)]
    for s, k in zip([sets[1], sets[4], sets[7]], (0, 2, 4)):
        assert s["ord_data_type"] == 4 and not np.iscomplexobj(s["data"])
        assert (s["rsp_dir"], s["ref_node"], s["ref_dir"]) == (3, 1, 3)
        assert s["ordinate_spec_data_type"] == 0 and s["abscissa_spec_data_type"] == 18
        np.testing.assert_array_equal(s["x"], case.freq)
        if binary:
            np.testing.assert_array_equal(s["data"], coh[k])
        else:
            np.testing.assert_allclose(s["data"], coh[k], rtol=1e-11, atol=0)
    back = io.read_frf(out)
    assert back.labels == ("3+Z", "7+Z", "12+Z", "15+Z", "21+Z")
    expect = coh.copy()
    expect[3] = np.nan
    assert np.array_equal(np.isnan(back.coherence), np.isnan(expect))
    ok = ~np.isnan(expect)
    if binary:
        np.testing.assert_array_equal(back.coherence[ok], expect[ok])
    else:
        np.testing.assert_allclose(back.coherence[ok], expect[ok], rtol=1e-11, atol=0)
    # the text output says it too; a file without coherence writes FRF records only
    r = run(["export", str(src), "-o", str(tmp_path / "c2.uff")])
    assert "and the coherence of 3 (UFF 58 function type 6)" in r.output
    assert "note: point 15: coherence unknown at 10 of 1601 lines; not written" in r.output


#: units laminid writes: acquire's default V/V and its --units examples, the response types of
#: UFF_RESPONSE_TYPES over each force, a ratio of ratios (N/N/N read back as N/N: the reader
#: took an ordinate "N/N" ending in its denominator "N" for the whole unit), non-ASCII
ROUND_TRIP_UNITS = ["V/V", "1", "Pa/N", "kPa/N", "m/s^2/N", "(m/s^2)/N", "m/s2/N", "m/s/N",
                    "mm/s/N", "m/N", "mm/N", "g/N", "m/s^2/kN", "Pa/lbf", "N/N/N", "Pa/N/N",
                    "m/s²/N", "1/N"]


@pytest.mark.parametrize("units", ROUND_TRIP_UNITS)
def test_every_unit_laminid_writes_reads_back_the_same(tmp_path, case, units):
    """Through export (UFF 58b and ASCII, from an acquire-style HDF5 file) and the CSV and
    HDF5 writers, the FRF unit reads back as written; in a Universal File (ASCII) "m/s²/N" is
    written and reads back "m/s^2/N", the same unit, on every pyuff (2.5.3 dropped the "²")."""
    fs = FrfSet(freq=case.freq[:UNIT_LINES], frf=case.frf[:2, :UNIT_LINES], labels=("1", "2"),
                units=units)
    h5 = io.write_frf(tmp_path / "in.frf.h5", fs)
    assert io.read_frf(h5).units == units
    assert io.read_frf(io.write_frf(tmp_path / "in.csv", fs)).units == units
    in_uff = units.replace("²", "^2")
    for extra in ([], ["--ascii"]):
        out = tmp_path / f"out{len(extra)}.uff"
        r = run(["export", str(h5), "-o", str(out), "--json", *extra])
        assert r.exit_code == 0, r.output
        d = json.loads(r.output)
        assert d["frf_unit"] == d["units"] == in_uff     # units: its old name, for 0.2.x
        assert io.read_frf(out).units == in_uff
        r = run(["fit-frf", str(out), "--json"])
        assert r.exit_code == 0, r.output
        assert json.loads(r.stdout)["units"] == in_uff


def test_a_unit_not_stated_stays_not_stated_through_every_writer(tmp_path, case):
    """FRFs of no stated unit (units None) were written as "1" (HDF5 attribute, CSV
    '# ... units 1', UFF ordinate "1"), read back as dimensionless: now written as not stated
    (no attribute, no units line, "NONE" over "NONE") and read back None, with the reader's
    note; a laminid HDF5 file or a plain one without a units attribute reads None too."""
    fs = FrfSet(freq=case.freq[:UNIT_LINES], frf=case.frf[:2, :UNIT_LINES], labels=("1", "2"))
    assert fs.units is None
    h5 = io.write_frf(tmp_path / "in.frf.h5", fs)
    with h5py.File(h5, "r") as f:
        assert "units" not in f["frf"].attrs
    csv_path = io.write_frf(tmp_path / "in.csv", fs)
    first = csv_path.read_text().splitlines()[0]
    assert first == "# laminid FRF, unit not stated in the source file"
    uff = io.write_frf(tmp_path / "in.uff", fs)
    hows = {h5: "no 'units' attribute on '/frf'; acquire --units records it",
            csv_path: "a comment line '# units Pa/N' above the data or the FRF columns' "
                      "headers, 'H1_re [g/N]', state it",
            uff: "FRF records' ordinate units label 'NONE' over 'NONE'"}
    for path, how in hows.items():
        back = io.read_frf(path)
        assert back.units is None, path
        assert back.meta["notes"] == [
            f"{path}: the FRF unit is not stated in the file ({how}): the FRFs and their modal "
            "constants are given without a unit (null in --json)"]
    r = run(["export", str(h5), "-o", str(tmp_path / "out.uff"), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert out["frf_unit"] is None and out["units"] is None
    r = run(["export", str(h5), "-o", str(tmp_path / "out2.uff")])
    assert "FRFs (UFF 58b, unit not stated in file, " in r.output
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["freq"] = case.freq
        f["frf"] = case.frf
    back = io.read_frf(plain)
    assert back.units is None
    assert back.meta["notes"] == [
        f"{plain}: the FRF unit is not stated in the file (no 'units' attribute on '/frf'): "
        "the FRFs and their modal constants are given without a unit (null in --json)"]


def test_export_of_a_csv_whose_frequency_states_no_unit(tmp_path, case):
    """export reads a CSV as fit-frf does: a column headed "f" is written as Hz with the
    reader's warning on stderr and in --json; in kHz (values below 100) it is refused, and
    no Universal File is written."""
    rows = "\n".join(f"{f:.17g},{h.real:.17g},{h.imag:.17g}"
                     for f, h in zip(case.freq, case.frf[0]))
    hz = tmp_path / "hz.csv"
    hz.write_text("f,1_re,1_im\n" + rows + "\n")
    r = run(["export", str(hz), "-o", str(tmp_path / "hz.uff"), "--json"])
    assert r.exit_code == 0, r.output
    warning = (f"{hz}: column 1 ('f'): the frequency states no unit; its values "
               f"{case.freq[0]:g} to {case.freq[-1]:g} are read as Hz")
    assert r.stderr.startswith(f"warning: {warning}") and r.stderr.count("\n") == 1
    out = json.loads(r.stdout)
    assert len(out["warnings"]) == 1 and out["warnings"][0].startswith(warning)
    assert np.array_equal(io.read_frf(tmp_path / "hz.uff").freq, case.freq)
    khz = tmp_path / "khz.csv"
    khz.write_text("f,1_re,1_im\n" + "\n".join(
        f"{f / 1e3:.17g},{h.real:.17g},{h.imag:.17g}" for f, h in zip(case.freq, case.frf[0]))
        + "\n")
    r = run(["export", str(khz), "-o", str(tmp_path / "khz.uff")])
    assert r.exit_code == 2
    assert r.stderr.startswith(f"laminid: error: {khz}: column 1 ('f'): the frequency states "
                               f"no unit, and its values {case.freq[0] / 1e3:g} to "
                               f"{case.freq[-1] / 1e3:g} read as Hz would end below 100 Hz")
    assert not (tmp_path / "khz.uff").exists()


def test_a_universal_file_is_written_in_ascii(tmp_path, case):
    """Text that is not ASCII never reaches the Universal File as such: the unit "m/s²/N" is
    written "m/s^2" over "N" with the acceleration's specific data type (12), a point label
    "Prüfpunkt 1" in the record's id as "Prufpunkt 1", every byte of the ASCII file below 128
    (pyuff 2.5.8 wrote UTF-8, shifting the fixed columns; 2.5.3 dropped the characters, and
    "m/s²" read back "m/s", a velocity); a unit with a character that has no ASCII spelling
    is refused, naming it, and no file is left."""
    import pyuff

    fs = FrfSet(freq=case.freq[:UNIT_LINES], frf=case.frf[:1, :UNIT_LINES],
                labels=("Prüfpunkt 1",), units="m/s²/N")
    out = io.write_frf_uff(tmp_path / "a.uff", fs)
    raw = out.read_bytes()
    assert max(raw) < 128
    d = pyuff.UFF(str(out)).read_sets(1)                  # after the units record
    assert (d["ordinate_axis_units_lab"], d["orddenom_axis_units_lab"]) == ("m/s^2", "N")
    assert (d["ordinate_spec_data_type"], d["orddenom_spec_data_type"]) == (12, 13)
    assert d["id1"].strip() == "FRF Prufpunkt 1"
    bad = FrfSet(freq=fs.freq, frf=fs.frf, labels=("1",), units="Pa/N\u2192", source="in.h5")
    with pytest.raises(FrfError, match=r"in.h5: FRF unit .* '\u2192' has no ASCII spelling"):
        io.write_frf_uff(tmp_path / "b.uff", bad)
    assert not (tmp_path / "b.uff").exists()


def test_uff58_unit_labels_drop_spaces_and_a_label_too_long_is_refused(tmp_path, case):
    """A UFF units label has no surrounding spaces and 20 characters: "m/s^2 / N" reads back
    "m/s^2/N" (the same unit; CSV and HDF5 keep the text as written, the CSV reader took the
    first word, "m/s^2"), and a unit pyuff would cut is refused, naming the file and the
    label, instead of reading back as another."""
    fs = FrfSet(freq=case.freq, frf=case.frf[:1], labels=("1",), units="m/s^2 / N")
    assert io.read_frf(io.write_frf_uff(tmp_path / "s.uff", fs)).units == "m/s^2/N"
    assert io.read_frf(io.write_frf(tmp_path / "s.csv", fs)).units == "m/s^2 / N"
    long = FrfSet(freq=case.freq, frf=case.frf[:1], labels=("1",),
                  units="microphone_channel_3_Pa/N")
    h5 = io.write_frf(tmp_path / "long.frf.h5", long)
    out = tmp_path / "long.uff"
    r = run(["export", str(h5), "-o", str(out)])
    assert r.exit_code == 2
    assert r.output == (f"laminid: error: {h5}: FRF unit 'microphone_channel_3_Pa/N' does not "
                        "fit a UFF 58 record: 'microphone_channel_3_Pa' has 23 characters, a "
                        "units label holds 20\n")
    assert not out.exists()


# ------------------------------------------------- FRF files written by other tools (interop)
def _other_uff(path, freq, frf, *, x=None, binary=0, units164=None, **fields):
    """A UFF 58 file as another modal tool writes it with pyuff: one FRF record per point
    (response node k + 1 +Z, reference 1 +Z), acceleration over force in g/N; ``fields``
    override any record field, ``x`` the abscissa as written (default ``freq`` in Hz);
    ``units164`` pyuff's fields of a units record (dataset 164) at the head of the file."""
    import pyuff

    x = freq if x is None else x
    sets = [] if units164 is None else [pyuff.prepare_164(**units164)]
    for k, h in enumerate(frf):
        record = dict(binary=binary, id1=f"FRF {k + 1}", id2="OtherTool", func_type=4,
                      rsp_node=k + 1, rsp_dir=3, ref_node=1, ref_dir=3, ord_data_type=6,
                      abscissa_spacing=1, abscissa_spec_data_type=18,
                      abscissa_axis_units_lab="Hz", ordinate_spec_data_type=12,
                      ordinate_axis_units_lab="g", orddenom_spec_data_type=13,
                      orddenom_axis_units_lab="N", data=np.asarray(h), x=np.asarray(x))
        record.update({key: (v(k) if callable(v) else v) for key, v in fields.items()})
        sets.append(pyuff.prepare_58(**record))
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path


#: the units record an SI tool writes (LMS, pyuff users): code 1, factors 1, Celsius offset
SI_164 = dict(units_code=1, units_description="SI - mks (Newton)", temp_mode=2, length=1.0,
              force=1.0, temp=1.0, temp_offset=273.15)


def test_a_uff_with_an_si_units_record_reads_as_without(tmp_path, case):
    for binary in (0, 1):
        with_164 = io.read_frf(_other_uff(tmp_path / f"si{binary}.uff", case.freq,
                                          case.frf[:2], units164=SI_164, binary=binary,
                                          ordinate_axis_units_lab="m/s^2"))
        assert with_164.units == "m/s^2/N" and with_164.labels == ("1+Z", "2+Z")
        if binary:
            np.testing.assert_array_equal(with_164.frf, case.frf[:2])
        else:
            np.testing.assert_allclose(with_164.frf, case.frf[:2], rtol=1e-11,
                                       atol=1e-11 * np.abs(case.frf).max())


@pytest.mark.parametrize("types, with_164, units", [
    ((12, 13), True, "m/s^2/N"), ((11, 13), True, "m/s/N"), ((8, 13), True, "m/N"),
    ((15, 13), True, "Pa/N"),
    ((12, 13), False, None),          # no units record: in which system is not said
    ((12, 0), True, None), ((0, 13), True, None),       # a type not known
])
def test_uff_records_without_units_labels_take_the_unit_of_their_types(tmp_path, case, types,
                                                                      with_164, units):
    """pyuff's records typed (12 acceleration over 13 force) but with its default labels
    "NONE": "the FRF unit is not stated", though a tool labels them m/s^2 over N in the SI
    of the file's units record. Now the unit of the types, with a note; without a units
    record or with a type laminid does not know, not stated as before."""
    path = _other_uff(tmp_path / "typed.uff", case.freq[:UNIT_LINES], case.frf[:2, :UNIT_LINES],
                      units164=SI_164 if with_164 else None, ordinate_spec_data_type=types[0],
                      orddenom_spec_data_type=types[1], ordinate_axis_units_lab="NONE",
                      orddenom_axis_units_lab="NONE")
    fs = io.read_frf(path)
    assert fs.units == units and "point_units" not in fs.meta
    if units is None:
        assert "the FRF unit is not stated in the file" in fs.meta["notes"][0]
    else:
        assert fs.meta["notes"] == [
            f"{path}: FRF records 1, 2 state no units label: {units} from the specific data "
            f"types ({types[0]} over {types[1]}) in the units record's SI"]


@pytest.mark.parametrize("code, name, length, force", [
    (5, "MM - mm (milli newton)", 1000.0, 1000.0),
    (7, "IN - Inch (pound f)", 39.37007874015748, 0.2248089430997105),
    (9, "US - USER_DEFINED", 1000.0, 1.0),          # mm and N: code 9, the factors tell
])
def test_a_uff_whose_units_record_is_not_si_is_refused(tmp_path, case, code, name, length,
                                                       force):
    """A units record (dataset 164) not SI makes a record's values mm/s^2 per mN (its factors
    and the acceleration's powers of length and force), while its labels, display text, may
    say m/s^2 over N: laminid took the labels and the values as SI, 1000 times off for mm.
    Refused, naming the file, the record and its factors; no traceback, exit 2."""
    units = dict(units_code=code, units_description=name[:20], temp_mode=1, length=length,
                 force=force, temp=1.0, temp_offset=0.0)
    path = _other_uff(tmp_path / "mm.uff", case.freq, case.frf[:2], units164=units,
                      ordinate_axis_units_lab="mm/s^2")
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value) == (
        f"{path}: its units record (dataset 164) says units code {code} ({name[:20]!r}; length "
        f"factor {length:.10g}, force factor {force:.10g} to SI), not SI: laminid reads FRF "
        "records in SI units only (whether the values follow that record or their units labels "
        "is not said, a factor apart); export them from the tool in SI (units code 1, metre "
        "and newton)")
    r = CliRunner().invoke(cli, ["fit-frf", str(path)])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "its units record (dataset 164) says units code" in r.output


@pytest.mark.parametrize("label, scale", [("rad/s", 2 * np.pi), ("RAD/S", 2 * np.pi),
                                          ("kHz", 1e-3), ("Hz", 1.0), ("NONE", 1.0)])
def test_uff_abscissa_in_rad_per_s_or_khz_is_converted_to_hz(tmp_path, case, label, scale):
    # another tool's axis in rad/s (specific data type 18, "frequency", label rad/s) was read as
    # Hz: every natural frequency came out 2 pi too high (785.7 Hz for the 125.05 Hz mode)
    path = _other_uff(tmp_path / "rad.uff", case.freq, case.frf[:2], x=case.freq * scale,
                      abscissa_axis_units_lab=label, abscissa_spacing=0, binary=1)
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-12)
    fit = rfp.find_modes(fs.freq, fs.frf, bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)


def test_uff_abscissa_in_another_unit_is_refused(tmp_path, case):
    path = _other_uff(tmp_path / "t.uff", case.freq, case.frf[:1], abscissa_axis_units_lab="s",
                      abscissa_spec_data_type=0)
    with pytest.raises(FrfError, match=r"record 1: abscissa unit 's' is not a frequency unit "
                                       r"laminid reads \(hz, .*rad/s"):
        io.read_frf(path)


def test_uff_frf_records_of_real_values_are_refused(tmp_path, case):
    # a tool that wrote |H| as the FRF records (ordinate data type 4, real double): fit-frf said
    # "no stable mode found" and exit 0, as if the plate had no resonance below 1601 Hz
    path = _other_uff(tmp_path / "mag.uff", case.freq, np.abs(case.frf[:2]), ord_data_type=4)
    r = run(["fit-frf", str(path)])
    assert r.exit_code != 0
    assert "FRF record 1 holds real values (ordinate data type 4; 2 of 2 FRF records are " \
           "real)" in r.output and "needs the complex FRF" in r.output


@pytest.mark.parametrize("names, transpose", [(("frf_real", "frf_imag"), False),
                                              (("H_re", "H_im"), True),
                                              (("FRF/real", "FRF/imag"), False)])
def test_plain_hdf5_frf_as_real_and_imaginary_datasets(tmp_path, case, names, transpose):
    # a lab script's h5py file with the FRF's parts apart was refused: "no complex dataset"
    path = tmp_path / "parts.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq
        f[names[0]] = (case.frf.T if transpose else case.frf).real
        f[names[1]] = (case.frf.T if transpose else case.frf).imag
    fs = io.read_frf(path)
    assert np.array_equal(fs.frf, case.frf)
    fit = rfp.find_modes(fs.freq, fs.frf, bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)
    stem = "/" + names[0].rsplit("_", 1)[0].removesuffix("/real")
    assert _fit_json(path, "--frf-dataset", stem, "--band", "100:300")["n_points"] == 5


@pytest.mark.parametrize("shape", ["column", "row"])
def test_plain_hdf5_frequency_as_a_matlab_column_or_row(tmp_path, case, shape):
    # MATLAB writes a vector as n x 1 (or 1 x n); the frequency was not taken for an axis:
    # "frequency candidates: none"
    path = tmp_path / "matlab.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq[:, None] if shape == "column" else case.freq[None, :]
        f["frf"] = case.frf.T
    fs = io.read_frf(path)
    assert np.array_equal(fs.freq, case.freq) and np.array_equal(fs.frf, case.frf)
    fit = rfp.find_modes(fs.freq, fs.frf, bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)


def test_uff_record_in_a_negative_direction_names_its_modal_constants(tmp_path, case):
    # point 2 measured in -Z (its FRF is -H): its modal constants came out with the opposite
    # sign of the +Z truth (0.000192 -> -0.000192 on mode 1), with no word of which FRF was
    # which direction (--json had no point labels)
    frf = case.frf[:3] * np.array([1, -1, 1])[:, None]
    path = _other_uff(tmp_path / "neg.uff", case.freq, frf, rsp_dir=lambda k: -3 if k == 1 else 3)
    out = _fit_json(path, "--band", "100:300")
    assert out["points"] == ["1+Z", "2-Z", "3+Z"]
    assert any(n.startswith("2-Z: measured in a negative direction") for n in out["notes"])
    f = np.array([m["freq_hz"] for m in out["modes"]])
    assert np.allclose(f, case.freq_hz[:3], rtol=1e-4)
    # the constants, in the recorded directions: A = C / (2 j omega_d) of the +Z truth C
    # (a receptance of real C: A imaginary), times the direction's sign
    a = np.array([[b for _, b in m["modal_constants"]] for m in out["modes"]]).T   # (3, 3)
    wd = 2 * np.pi * case.freq_hz[:3] * np.sqrt(1 - case.damping_ratio[:3] ** 2)
    expected = -case.constants[:3, :3] / (2 * wd) * np.array([[1], [-1], [1]])
    assert np.allclose(a, expected, rtol=2e-2)
    text = run(["fit-frf", str(path), "--band", "100:300"]).output
    assert text.splitlines()[0].endswith("3 FRFs (g/N), 1601 lines, bands 100-300 Hz")
    assert "note: 2-Z: measured in a negative direction" in text


@pytest.mark.parametrize("ordinate, denominator, units", [
    ("NONE", "NONE", None), ("", "", None), ("NONE", "N", None), ("g", "N", "g/N"),
    ("m/s2", "N", "m/s2/N"),
    ("(m/s^2)", "N", "(m/s^2)/N"), ("m/s^2/N", "NONE", "m/s^2/N"), ("m/s", "N", "m/s/N")])
def test_other_tools_uff_unit_labels(tmp_path, case, ordinate, denominator, units):
    # pyuff's default labels "NONE" over "NONE" were read as the unit "NONE" (the residues'
    # unit "NONE*rad/s"), then as "1", as if the FRFs were dimensionless: now not stated
    # (null), with a note; the frequencies do not depend on the unit
    path = _other_uff(tmp_path / "u.uff", case.freq[:UNIT_LINES], case.frf[:2, :UNIT_LINES],
                      ordinate_axis_units_lab=ordinate, orddenom_axis_units_lab=denominator)
    out = _fit_json(path, "--band", "100:300")
    assert out["frf_unit"] == units
    note = (f"{path}: the FRF unit is not stated in the file (FRF records' ordinate units "
            f"label {ordinate!r} over {denominator!r}): the FRFs and their modal constants are "
            "given without a unit (null in --json)")
    assert (note in out["notes"]) == (units is None)
    if units is None:
        assert out["modal_constants_unit"] is None
    assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz[:3], rtol=1e-4)


def test_plain_hdf5_angular_frequency_without_units_is_refused(tmp_path, case):
    # a dataset 'omega' in rad/s without a units attribute was read as Hz: every mode 6.28x
    # too high (125.05 Hz found at 785.7 Hz), exit 0
    path = tmp_path / "omega.h5"
    with h5py.File(path, "w") as f:
        f["omega"] = 2 * np.pi * case.freq
        f["frf"] = case.frf.T
    with pytest.raises(FrfError, match=r"dataset '/omega' \(no units attribute; give it one, "
                                       r"'Hz' or 'rad/s': .*attrs\['units'\] = 'rad/s'\): the "
                                       r"frequency 'omega' reads as an angular frequency"):
        io.read_frf(path)
    with h5py.File(path, "r+") as f:
        f["omega"].attrs["units"] = "rad/s"
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-14)
    with h5py.File(path, "w") as f:
        f["omega_rad_s"] = 2 * np.pi * case.freq
        f["frf"] = case.frf.T
    fit = rfp.find_modes(*(lambda s: (s.freq, s.frf))(io.read_frf(path)), bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)


def test_uff_of_mixed_response_units_says_each_points_unit(tmp_path, case):
    # an accelerance beside a mobility: the file's unit was the first record's (g/N) for all,
    # with no word that point 2's modal constants are in m/s/N
    path = _other_uff(tmp_path / "mixed.uff", case.freq, case.frf[:2],
                      ordinate_axis_units_lab=lambda k: "g" if k == 0 else "m/s",
                      ordinate_spec_data_type=lambda k: 12 if k == 0 else 11)
    fs = io.read_frf(path)
    assert fs.units == "g/N" and fs.meta["point_units"] == ["g/N", "m/s/N"]
    out = _fit_json(path, "--band", "100:300")
    assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz[:3], rtol=1e-4)
    assert ("the FRFs are in different units (1+Z g/N; 2+Z m/s/N): the frequencies and damping "
            "ratios are those of every FRF") in " ".join(out["notes"])
    same = _other_uff(tmp_path / "same.uff", case.freq, case.frf[:2])
    assert "point_units" not in io.read_frf(same).meta
    assert not any("different units" in n for n in _fit_json(same, "--band", "100:300")["notes"])


def test_export_of_an_identification_gives_each_shape_its_paired_modes_frequency(
        tmp_path, s11_fix_undetermined_6x6):
    """An identify result keeps the shapes of the paired model modes, in the measured modes'
    order, while /modes/frequency lists every computed mode, sorted: the UFF 55 record of each
    shape has its paired mode's frequency. Was /modes/frequency[k] for shape k: --json's
    freq_hz listed 14 frequencies for 12 shapes, and after a tracked swap two records carried
    each other's frequency."""
    import shutil

    import pyuff

    path = tmp_path / "swapped.h5"
    shutil.copy(s11_fix_undetermined_6x6[1], path)
    with h5py.File(path, "r+") as f:            # modes 3 and 4 paired the other way round
        pairing = f["frequencies/model_mode"][()]
        all_hz = f["modes/frequency"][()]
        assert all_hz.size > pairing.size and np.array_equal(pairing, np.arange(1, 13))
        pairing[[2, 3]] = pairing[[3, 2]]
        f["frequencies/model_mode"][...] = pairing
        f["frequencies/model"][...] = all_hz[pairing - 1]
        w = f["modes/w"][()]
        f["modes/w"][...] = w[:, [0, 1, 3, 2] + list(range(4, w.shape[1]))]
        paired_hz = all_hz[pairing - 1]
    out = tmp_path / "swapped.unv"
    r = run(["export", str(path), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    doc = json.loads(r.output)
    assert doc["n_modes"] == 12 and len(doc["freq_hz"]) == 12
    np.testing.assert_allclose(doc["freq_hz"], paired_hz, rtol=1e-12)
    assert doc["model_mode"] == pairing.tolist()
    assert doc["freq_range_hz"] == [paired_hz.min(), paired_hz.max()]
    shapes = [s for s in pyuff.UFF(str(out)).read_sets() if s["type"] == 55]
    assert [s["freq"] for s in shapes] == pytest.approx(paired_hz, rel=5e-6)
    assert [s["mode_n"] for s in shapes] == list(range(1, 13))
    assert shapes[2]["id1"] == f"laminid mode 3: {paired_hz[2]:.6g} Hz (model mode 4)"
    assert shapes[4]["id1"] == f"laminid mode 5: {paired_hz[4]:.6g} Hz"


# ------------------------------------------- a frequency axis that states no unit (HDF5, UFF)
def _fit_cli(path, *extra):
    """fit-frf's text and --json runs of ``path``: (stderr of the text run, the JSON)."""
    r = run(["fit-frf", str(path), "--band", "100:300", *extra])
    assert r.exit_code == 0, r.output
    j = run(["fit-frf", str(path), "--band", "100:300", "--json", *extra])
    assert j.exit_code == 0, j.output
    return r.stderr, json.loads(j.stdout)


#: the refusal of kHz read as Hz (1 to 400 Hz written in kHz), as every FRF reader words it
KHZ_AS_HZ = ("the frequency states no unit, and its values 0.001 to 0.4 read as Hz would end "
             "below 100 Hz, where a free plate has hardly a mode (they lie at about 20 Hz to "
             "20 kHz): very likely kHz, not Hz")


def test_plain_hdf5_frequency_without_units_is_hz_with_a_warning_or_refused_below_100(
        tmp_path, case):
    # a dataset 'freq' with no units attribute was read as Hz without a word; in kHz (0.001 to
    # 1.601) every mode came out 1000 times too low (125.05 Hz found at 0.125), exit 0
    lines = slice(0, UNIT_LINES)
    path = tmp_path / "plain.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq[lines]
        f["frf"] = case.frf[:2, lines].T
    warning = (f"{path}: dataset '/freq' (no units attribute): the frequency states no unit; "
               f"its values 1 to 400 are read as Hz (were they kHz, every mode would be 1000 "
               "times too low; rad/s, 6.28 times too high); if they are not Hz, give it one: "
               f"h5py.File('{path}', 'r+')['/freq'].attrs['units'] = 'kHz' (or 'rad/s'); a "
               "units attribute 'Hz' confirms Hz and silences this warning")
    assert io.read_frf(path).meta["warnings"] == [warning]
    stderr, out = _fit_cli(path)
    assert stderr == f"warning: {warning}\n" and out["warnings"] == [warning]
    assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz[:3], rtol=1e-4)

    with h5py.File(path, "w") as f:
        f["freq"] = case.freq[lines] / 1e3
        f["frf"] = case.frf[:2, lines].T
    r = run(["fit-frf", str(path)])
    assert r.exit_code == 2, r.output
    assert r.stderr == (
        f"laminid: error: {path}: dataset '/freq' (no units attribute): {KHZ_AS_HZ}; "
        f"give it one: h5py.File('{path}', 'r+')['/freq'].attrs['units'] = 'kHz' (or "
        "'rad/s')\n")
    # stated, by the attribute the message gives or by the name: read without a warning
    with h5py.File(path, "r+") as f:
        f["freq"].attrs["units"] = "kHz"
    stderr, out = _fit_cli(path)
    assert stderr == "" and out["warnings"] == []
    assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz[:3], rtol=1e-4)
    with h5py.File(path, "w") as f:
        f["f_hz"] = case.freq[lines]
        f["frf"] = case.frf[:2, lines].T
    assert "warnings" not in io.read_frf(path).meta


@pytest.mark.parametrize("spec_type", [18, 0], ids=["frequency", "unknown"])
@pytest.mark.parametrize("label", ["NONE", ""])
def test_uff_abscissa_without_a_units_label_is_hz_with_a_warning_or_refused_below_100(
        tmp_path, case, spec_type, label):
    # records whose abscissa has no units label (pyuff's default "NONE") were read as Hz
    # without a word, whatever their values; type 18 says "frequency", not in which unit
    lines = slice(0, UNIT_LINES)
    path = _other_uff(tmp_path / "none.uff", case.freq[lines], case.frf[:2, lines],
                      abscissa_axis_units_lab=label, abscissa_spec_data_type=spec_type)
    kind = "frequency" if spec_type == 18 else "unknown"
    what = (f"{path}: the FRF records' abscissa (specific data type {spec_type}, {kind}; units "
            f"label {label!r})")
    warning = (f"{what}: the frequency states no unit; its values 1 to 400 are read as Hz "
               "(were they kHz, every mode would be 1000 times too low; rad/s, 6.28 times too "
               "high); if they are not Hz, state it in the records' abscissa units label "
               "(record 8, field 6): 'kHz' or 'rad/s' (pyuff: abscissa_axis_units_lab='kHz'); "
               "the label 'Hz' confirms Hz and silences this warning")
    stderr, out = _fit_cli(path)
    assert stderr == f"warning: {warning}\n" and out["warnings"] == [warning]
    assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz[:3], rtol=1e-4)

    khz = _other_uff(tmp_path / "khz.uff", case.freq[lines], case.frf[:2, lines],
                     x=case.freq[lines] / 1e3, abscissa_spacing=0,
                     abscissa_axis_units_lab=label, abscissa_spec_data_type=spec_type)
    r = run(["fit-frf", str(khz)])
    assert r.exit_code == 2, r.output
    assert r.stderr == (
        f"laminid: error: {what.replace(str(path), str(khz))}: {KHZ_AS_HZ}; "
        "state it in the records' abscissa units label (record 8, field 6): 'kHz' or 'rad/s' "
        "(pyuff: abscissa_axis_units_lab='kHz')\n")


@pytest.mark.parametrize("label, scale", [("Hz", 1.0), ("kHz", 1e-3), ("rad/s", 2 * np.pi)])
def test_uff_abscissa_with_a_units_label_is_read_without_a_warning(tmp_path, case, label,
                                                                    scale):
    lines = slice(0, UNIT_LINES)
    path = _other_uff(tmp_path / "stated.uff", case.freq[lines], case.frf[:2, lines],
                      x=case.freq[lines] * scale, abscissa_spacing=0,
                      abscissa_axis_units_lab=label)
    stderr, out = _fit_cli(path)
    assert stderr == "" and out["warnings"] == []
    assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz[:3], rtol=1e-4)


@pytest.mark.parametrize("key", ["Unit", "UNITS", "Units"])
def test_plain_hdf5_units_attribute_in_any_case(tmp_path, case, key):
    # a tool's 'Unit' attribute was not read: its kHz axis read as Hz (a warning saying the
    # frequency states no unit) and its FRF unit "not stated"
    path = tmp_path / "unit.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq / 1000.0
        f["freq"].attrs[key] = "kHz"
        f["H_re"], f["H_im"] = case.frf.real, case.frf.imag
        f["H_re"].attrs[key] = "g/N"
        f["H_im"].attrs[key] = "g/N"
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-12)
    assert fs.units == "g/N"
    assert not fs.meta.get("warnings") and not fs.meta.get("notes")


@pytest.mark.parametrize("where", ["dataset", "group", "root"])
def test_plain_hdf5_frequency_as_an_attribute(tmp_path, case, where):
    # a tool that keeps the axis with its FRF (an attribute 'frequency' of the FRF dataset, or
    # of its group) was refused: "no frequency axis matches an FRF dataset; frequency
    # candidates: none"
    path = tmp_path / "attr.h5"
    with h5py.File(path, "w") as f:
        f["meas/H"] = case.frf.T
        f["meas/H"].attrs["units"] = "g/N"
        owner = {"dataset": f["meas/H"], "group": f["meas"], "root": f}[where]
        owner.attrs["frequency"] = 2 * np.pi * case.freq
        owner.attrs["frequency_units"] = "rad/s"
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-12) and np.array_equal(fs.frf, case.frf)
    assert fs.units == "g/N" and not fs.meta.get("warnings")
    named = {"dataset": "/meas/H@frequency", "group": "/meas@frequency", "root": "@frequency"}
    assert fs.meta["frequency_dataset"] == named[where]
    out = _fit_json(path, "--freq-dataset", named[where], "--band", "100:300")
    assert out["n_points"] == 5 and out["frf_unit"] == "g/N"


def test_plain_hdf5_frequency_attribute_without_a_unit_is_hz_with_a_warning(tmp_path, case):
    path = tmp_path / "attr.h5"
    with h5py.File(path, "w") as f:
        f["frf"] = case.frf
        f["frf"].attrs["freq"] = case.freq
        f["frf"].attrs["f_kHz"] = case.freq / 1e3 + 1.0   # another axis, named in kHz
    with pytest.raises(FrfError, match="several frequency/FRF dataset pairs fit"):
        io.read_frf(path)
    fs = io.read_frf(path, freq_dataset="/frf@freq", frf_dataset="/frf")
    assert np.array_equal(fs.freq, case.freq)
    assert fs.meta["warnings"][0].startswith(
        f"{path}: attribute 'freq' of '/frf' (no freq_units attribute beside it): the frequency "
        "states no unit")
    assert "h5py.File(" in fs.meta["warnings"][0] and ".attrs['freq_units'] = 'kHz'" \
        in fs.meta["warnings"][0]
    with h5py.File(path, "r+") as f:          # a dataset named as the frequency comes first
        f["freq"] = case.freq
        f["freq"].attrs["units"] = "Hz"
    assert io.read_frf(path).meta["frequency_dataset"] == "/freq"


@pytest.mark.parametrize("step", [2000 / 4096, 1 / 3])
def test_binary_uff58_keeps_a_grid_whose_step_has_more_than_6_digits_exactly(tmp_path, case,
                                                                              step):
    # the header's start and step hold 6 digits (E13.5): a 2000 Hz / 4096-line grid's
    # 0.48828125 Hz step read back as 0.488281, its top line 0.7 mHz off (5e-7), though
    # binary 58b "keeps the doubles exactly"; such a grid is now written uneven (each line's
    # frequency a double), an exact step still as start and step
    import pyuff

    freq = step * np.arange(1, case.freq.size + 1)
    for grid, spacing in ((freq, 0), (0.5 * np.arange(1, case.freq.size + 1), 1)):
        out = tmp_path / f"grid{spacing}.uff"
        io.write_frf_uff(out, FrfSet(freq=grid, frf=case.frf, units="m/s^2/N"), binary=True)
        back = io.read_frf(out)
        assert np.array_equal(back.freq, grid) and np.array_equal(back.frf, case.frf)
        assert {s["abscissa_spacing"] for s in pyuff.UFF(str(out)).read_sets()[1:]} \
            == {spacing}


@pytest.mark.parametrize("binary", [True, False])
def test_a_uff_cut_short_is_refused_not_read_with_fewer_points(tmp_path, case, binary):
    # pyuff drops a dataset that no '    -1' closes: a file cut short (a copy that did not
    # finish) gave 2 of its 5 points and a fit of those, exit 0
    whole = io.write_frf_uff(tmp_path / "whole.uff", FrfSet(freq=case.freq, frf=case.frf),
                             binary=binary)
    data = whole.read_bytes()
    cut = tmp_path / "cut.uff"
    cut.write_bytes(data[:int(len(data) * 0.5)])
    # the units record and 2 of the 5 FRF records
    with pytest.raises(FrfError, match=r"cut\.uff: the file ends inside a dataset, after 3 "
                                       r"complete ones \(no '    -1' line closes the last\)"):
        io.read_frf(cut)
    cut.write_bytes(data + b"\r\n\x1a")      # a DOS end of file after the last tag is whole
    assert io.read_frf(cut).n_points == 5


def test_plain_hdf5_frf_of_one_reference_in_three_axes(tmp_path, case):
    # (n_points, 1, n_freq), a MIMO layout's one reference, was "no complex dataset (FRF) in
    # it; datasets: '/freq'": the FRF not even listed
    path = tmp_path / "mimo.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq
        f["freq"].attrs["units"] = "Hz"
        f["H"] = case.frf[:, None, :]
        f["coherence"] = np.ones((case.frf.shape[0], 1, case.freq.size))
    fs = io.read_frf(path)
    assert np.array_equal(fs.frf, case.frf) and fs.coherence.shape == case.frf.shape
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq
        f["H"] = np.stack([case.frf, case.frf], axis=1)
    with pytest.raises(FrfError, match=r"complex datasets of more than 2 axes: '/H' \(5 x 2 x "
                                       r"1601\) \(laminid reads one reference's FRFs"):
        io.read_frf(path)


def test_export_of_mixed_response_units_writes_each_record_in_its_own(tmp_path, case):
    # every record was written in the first point's unit: the mobility of point 2 labelled
    # g over N, ordinate type 12 (acceleration), and read back as an accelerance
    import pyuff

    path = _other_uff(tmp_path / "mixed.uff", case.freq, case.frf[:2],
                      ordinate_axis_units_lab=lambda k: "g" if k == 0 else "m/s",
                      ordinate_spec_data_type=lambda k: 12 if k == 0 else 11)
    out = tmp_path / "out.uff"
    r = run(["export", str(path), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    assert ("the FRFs are in different units, each record written in its own: 1+Z g/N; "
            "2+Z m/s/N") in json.loads(r.stdout)["notes"]
    sets = pyuff.UFF(str(out)).read_sets()
    assert [(s["ordinate_axis_units_lab"], s["orddenom_axis_units_lab"],
             s["ordinate_spec_data_type"]) for s in sets[1:]] == [("g", "N", 0), ("m/s", "N", 11)]
    assert io.read_frf(out).meta["point_units"] == ["g/N", "m/s/N"]


@pytest.mark.parametrize("units, scale", [("[Hz]", 1.0), ("(kHz)", 1e-3), ("rad s^-1", 2 * np.pi),
                                          ("1/sec", 1.0)])
def test_plain_hdf5_frequency_units_in_brackets_or_other_spellings(tmp_path, case, units,
                                                                    scale):
    # '[Hz]' (a unit as a plot label writes it) or 'rad s^-1' made the dataset no axis: "no
    # frequency axis matches an FRF dataset; frequency candidates: none"
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq * scale
        f["freq"].attrs["units"] = units
        f["frf"] = case.frf
    assert np.allclose(io.read_frf(path).freq, case.freq, rtol=1e-12)


def test_plain_hdf5_frequency_in_a_unit_not_read_is_named_in_the_message(tmp_path, case):
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        f["freq"] = case.freq
        f["freq"].attrs["units"] = "cycles/s"
        f["frf"] = case.frf
    with pytest.raises(FrfError, match=r"set aside for a units attribute that is no frequency "
                                       r"unit laminid reads \(hz, .*\): '/freq' \(1601, units "
                                       r"'cycles/s'\)"):
        io.read_frf(path)


@pytest.mark.parametrize("encoding", ["cp1252", "utf-8"])
def test_uff_units_label_with_a_superscript_of_a_windows_tool(tmp_path, case, encoding):
    # "m/s²" in Windows-1252 (byte 0xB2) read as 'm/s\ufffd/N' (pyuff's replacement
    # character), and beside another record's "m/s^2" as two units
    plain = io.write_frf_uff(tmp_path / "plain.uff",
                             FrfSet(freq=case.freq, frf=case.frf[:2], units="m/s^2/N"),
                             binary=True)
    data = plain.read_bytes()
    label = b"m/s^2" + b" " * 15
    assert data.count(label) == 2
    path = tmp_path / "win.uff"
    path.write_bytes(data.replace(label, "m/s²".encode(encoding).ljust(20), 1))
    fs = io.read_frf(path)
    assert fs.units == "m/s^2/N" and "point_units" not in fs.meta
    assert np.array_equal(fs.frf, case.frf[:2])


def test_a_dof_measured_twice_keeps_each_records_coherence(tmp_path, case):
    """Two FRF records of one DOF (a repeated measurement), each followed by its coherence:
    the coherence was looked up by DOF alone, and both FRFs got the second's (0.9 where the
    first was 0.3). Paired in file order now, with a note naming the records."""
    import pyuff

    f, H = case.freq[:UNIT_LINES], case.frf[:3, :UNIT_LINES]
    sets = []
    for k, (node, c) in enumerate(((1, 0.3), (1, 0.9), (2, 0.6))):
        common = dict(binary=0, rsp_node=node, rsp_dir=3, ref_node=1, ref_dir=3,
                      abscissa_spacing=1, abscissa_spec_data_type=18,
                      abscissa_axis_units_lab="Hz", ordinate_axis_units_lab="m/s^2",
                      orddenom_axis_units_lab="N", ordinate_spec_data_type=12,
                      orddenom_spec_data_type=13, x=f)
        sets.append(pyuff.prepare_58(func_type=4, ord_data_type=6, data=H[k], **common))
        sets.append(pyuff.prepare_58(func_type=6, ord_data_type=4, data=np.full(f.size, c),
                                     **common))
    path = tmp_path / "repeat.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    fs = io.read_frf(path)
    assert fs.labels == ("1+Z", "1+Z", "2+Z")
    np.testing.assert_array_equal(fs.coherence, np.repeat([[0.3], [0.9], [0.6]], f.size, 1))
    assert fs.meta["notes"] == [
        f"{path}: the same DOF in more than one FRF record (1+Z: records 1, 2): each fitted as "
        "a point of its own, its coherence the DOF's record of the same rank"]
    out = io.write_frf(tmp_path / "again.uff", fs)          # and through laminid's writer
    np.testing.assert_array_equal(io.read_frf(out).coherence, fs.coherence)


def test_export_json_lists_every_record_where_point_labels_repeat(tmp_path, case):
    """export --json's ``points`` (label -> node) held one entry per label: a DOF measured
    twice (1+Z, records 1 and 2) and scalar records at node 0 (labelled '0', both) were one
    entry each, 4 records shown as 2. ``point_nodes`` lists every record in file order with
    its DOFs as written; ``points`` stays, the last record of a label."""
    import pyuff

    f, H = case.freq[:UNIT_LINES], case.frf[:4, :UNIT_LINES]
    sets = [pyuff.prepare_58(binary=0, func_type=4, ord_data_type=6, rsp_node=node,
                             rsp_dir=d, ref_node=1, ref_dir=3, abscissa_spacing=1,
                             abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz",
                             ordinate_axis_units_lab="m/s^2", orddenom_axis_units_lab="N",
                             ordinate_spec_data_type=12, orddenom_spec_data_type=13,
                             x=f, data=H[k])
            for k, (node, d) in enumerate(((1, 3), (1, 3), (0, 0), (0, 0)))]
    src = tmp_path / "repeat.uff"
    pyuff.UFF(str(src)).write_sets(sets, mode="add")
    out = tmp_path / "again.uff"
    r = run(["export", str(src), "-o", str(out), "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["datasets"]["58"] == 4
    assert d["points"] == {"1+Z": 1, "0": 0}
    assert d["point_nodes"] == [
        {"label": "1+Z", "node": 1, "direction": "+Z", "ref_node": 1, "ref_direction": "+Z"},
        {"label": "1+Z", "node": 1, "direction": "+Z", "ref_node": 1, "ref_direction": "+Z"},
        {"label": "0", "node": 0, "direction": "+Z", "ref_node": 1, "ref_direction": "+Z"},
        {"label": "0", "node": 0, "direction": "+Z", "ref_node": 1, "ref_direction": "+Z"}]
    back = [s for s in pyuff.UFF(str(out)).read_sets() if s["type"] == 58]
    assert [(s["rsp_node"], s["rsp_dir"]) for s in back] == [
        (p["node"], 3) for p in d["point_nodes"]]                # as written


@pytest.mark.parametrize("where, after", [("head", False), ("between the records", True)])
def test_a_malformed_units_record_is_named_by_dataset_line_and_field(tmp_path, case, where,
                                                                     after):
    """A units record (dataset 164) pyuff cannot read was refused as 'cannot read its units
    record (dataset 164) (Error when reading data-set(s).)', pyuff's words: now the dataset's
    number in the file, its line, the record and field that is no number, and what to do;
    one line, exit 2, in fit-frf and export, text and --json, no file written."""
    import pyuff

    f, H = case.freq[:UNIT_LINES], case.frf[:2, :UNIT_LINES]
    src = _other_uff(tmp_path / "ok.uff", f, H, ordinate_axis_units_lab="m/s^2")
    sets = pyuff.UFF(str(src)).read_sets()
    sets.insert(1 if after else 0, pyuff.prepare_164(**SI_164))
    path = tmp_path / "bad164.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    text = path.read_text()
    line = text[:text.index("   164 ")].count("\n")              # its opening '    -1'
    lines = text.splitlines()
    factors = lines[line + 2].split()                # record 2 (line + 3, 1-based)
    assert [float(v.replace("D", "e")) for v in factors] == [1.0, 1.0, 1.0]
    lines[line + 2] = "".join(f"{v:>25}" for v in (factors[0], "1.0O00e+00", factors[2]))
    path.write_text("\n".join(lines) + "\n")
    message = (f"{path}: cannot read its units record (dataset 164): dataset "
               f"{2 if after else 1} of the file, line {line}: record 2 (line {line + 3}), the "
               "force factor: '1.0O00e+00' is not a number; export the file again, or delete "
               "that dataset where the file is in SI (its FRF records are then read by their "
               "units labels)")
    out = tmp_path / "x.uff"
    for args in (["fit-frf", str(path)], ["export", str(path), "-o", str(out)]):
        r = run(args)
        assert (r.exit_code, r.stdout, r.stderr) == (2, "", f"laminid: error: {message}\n")
        r = run([*args, "--json"])
        assert r.exit_code == 2 and json.loads(r.stdout)["error"] == {
            "kind": "FrfError", "message": message, "file": str(path), "field": None,
            "line": None, "exit_code": 2}
    assert not out.exists()


def _matlab_v73(path, freq, frf, freq_shape):
    """A MAT-file as MATLAB's save(..., '-v7.3') writes it: HDF5 behind a 512-byte user
    block holding the MAT header, each variable a dataset with a MATLAB_class attribute,
    stored transposed (column-major: MATLAB's lines x points H is points x lines here), a
    complex one a compound of real and imag."""
    with h5py.File(path, "w", userblock_size=512) as f:
        H = np.empty(frf.shape, np.dtype([("real", "<f8"), ("imag", "<f8")]))
        H["real"], H["imag"] = frf.real, frf.imag
        f.create_dataset("H", data=H).attrs["MATLAB_class"] = np.bytes_("double")
        f.create_dataset("f", data=freq.reshape(freq_shape)).attrs["MATLAB_class"] = \
            np.bytes_("double")
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Dec  7 08:00:00 "
                 b"2026 HDF5 schema 1.00 .".ljust(116) + bytes(8) + b"\x00\x02IM")
    return path


@pytest.mark.parametrize("freq_shape", [(1, -1), (-1, 1)])
def test_a_matlab_v73_mat_file_is_read_as_plain_hdf5(tmp_path, case, freq_shape):
    """A MAT-file saved with '-v7.3' is HDF5, but '.mat' was 'unknown FRF file type': it is
    read as a plain HDF5 file now (the same modes as the native file to 1e-9); a version 5
    MAT-file (save's default, no HDF5) is refused saying how to save one laminid reads."""
    f, H = case.freq[:UNIT_LINES], case.frf[:, :UNIT_LINES]
    path = _matlab_v73(tmp_path / "plate.mat", f, H, freq_shape)
    fs = io.read_frf(path)
    np.testing.assert_array_equal(fs.freq, f)
    np.testing.assert_array_equal(fs.frf, H)                    # as the native file holds
    out = _fit_json(path)                                       # and through the CLI
    np.testing.assert_allclose([m["freq_hz"] for m in out["modes"]][:3], case.freq_hz[:3],
                               rtol=2e-3)
    v5 = tmp_path / "old.mat"
    v5.write_bytes(b"MATLAB 5.0 MAT-file, Platform: PCWIN64, Created on: Mon Dec 7 2026"
                   .ljust(116) + bytes(8) + b"\x00\x01IM" + bytes(64))
    r = run(["fit-frf", str(v5)])
    assert (r.exit_code, r.stderr) == (2, (
        f"laminid: error: {v5}: not a MATLAB MAT-file laminid can read (Did not read any "
        "bytes); save the frequency and FRF variables again, or write them as a CSV\n"))


def _matlab_char(f, name, text):
    """A MATLAB char variable as save -v7.3 writes it: UTF-16 codes, 1 x n stored n x 1."""
    d = f.create_dataset(name, data=np.array([[ord(c)] for c in text], np.uint16))
    d.attrs["MATLAB_class"] = np.bytes_("char")


@pytest.mark.parametrize("unit, scale", [("kHz", 1e-3), ("rad/s", 2 * np.pi), ("Hz", 1.0)])
@pytest.mark.parametrize("version", ["v5", "v7.3"])
def test_a_mat_files_units_variable_gives_the_frequency_unit(tmp_path, case, version, unit,
                                                            scale):
    """MATLAB writes no attribute, so a lab saves a text variable units = 'kHz' beside f and
    H: it was not read (v7.3: its char codes a numeric dataset; v5, scipy.io.savemat and
    save's default, refused as no HDF5), a kHz axis read as Hz, every mode 1000 times too
    low. Read as the frequency's unit now, in both versions, the frequency in Hz to 1e-12;
    frf_unit gives the FRFs'."""
    f, H = case.freq[:UNIT_LINES], case.frf[:, :UNIT_LINES]
    path = tmp_path / "plate.mat"
    if version == "v5":
        import scipy.io

        scipy.io.savemat(path, {"f": f * scale, "H": H.T, "units": unit, "frf_unit": "g/N"})
    else:
        _matlab_v73(path, f * scale, H, (-1, 1))
        with h5py.File(path, "r+") as h5:
            _matlab_char(h5, "units", unit)
            _matlab_char(h5, "frf_unit", "g/N")
    fs = io.read_frf(path)
    np.testing.assert_allclose(fs.freq, f, rtol=1e-12, atol=0)
    np.testing.assert_allclose(fs.frf, H, rtol=1e-15, atol=0)
    assert fs.units == "g/N" and "warnings" not in fs.meta


@pytest.mark.parametrize("variables, words", [
    ({"units": "mm"}, "variable 'units' is 'mm': neither a frequency unit laminid reads (Hz, "
                      "kHz, rad/s, 1/s) nor an FRF's (a response over a force, 'g/N'); name "
                      "the frequency's 'freq_unit' and the FRFs' 'frf_unit'"),
    ({"freq_unit": "cycles"}, "variable 'freq_unit' is 'cycles', not a frequency unit laminid "
                              "reads (Hz, kHz, rad/s, 1/s); the frequencies would be read in "
                              "the wrong unit"),
    ({"f_kHz": None, "unit": "Hz"}, "variable 'unit' gives the frequency in 'Hz', its name in "
                                    "'khz' ('/f_kHz'): which is meant cannot be told")])
@pytest.mark.parametrize("version", ["v5", "v7.3"])
def test_a_mat_files_unknown_or_contradicting_unit_is_refused(tmp_path, case, version,
                                                             variables, words):
    """A units variable laminid cannot read as a frequency unit is refused naming it, not
    left out (the axis then read as Hz); one contradicting the axis' name too."""
    import scipy.io

    f, H = case.freq[:UNIT_LINES], case.frf[:, :UNIT_LINES]
    name = "f_kHz" if "f_kHz" in variables else "f"
    texts = {k: v for k, v in variables.items() if v is not None}
    path = tmp_path / "plate.mat"
    if version == "v5":
        scipy.io.savemat(path, {name: f, "H": H, **texts})
    else:
        with h5py.File(path, "w", userblock_size=512) as h5:
            h5[name], h5["H"] = f.reshape(-1, 1), H
            for k, v in texts.items():
                _matlab_char(h5, k, v)
    r = run(["fit-frf", str(path)])
    assert (r.exit_code, r.stderr) == (2, f"laminid: error: {path}: {words}\n")


def _matlab_cell(h5, name, entries):
    """A MATLAB cell array as save -v7.3 writes it: a dataset of object references (1 x n
    stored n x 1) to the entries in the group '#refs#', MATLAB_class 'cell' (texts as
    :func:`_matlab_char`, numbers as 'double')."""
    refs = h5.require_group("#refs#")
    targets = []
    for k, x in enumerate(entries):
        key = f"{name}_{k}"
        if isinstance(x, str):
            _matlab_char(refs, key, x)
        else:
            refs.create_dataset(key, data=np.array([[x]])).attrs["MATLAB_class"] = \
                np.bytes_("double")
        targets.append(refs[key].ref)
    d = h5.create_dataset(name, data=np.array(targets, dtype=h5py.ref_dtype).reshape(-1, 1))
    d.attrs["MATLAB_class"] = np.bytes_("cell")


def _mat_with_labels(path, case, version, entries):
    f, H = case.freq[:UNIT_LINES], case.frf[:, :UNIT_LINES]
    if version == "v5":
        import scipy.io

        cell = np.empty((1, len(entries)), object)
        for k, x in enumerate(entries):
            cell[0, k] = x if isinstance(x, str) else np.array([[x]])
        scipy.io.savemat(path, {"f": f, "H": H.T, "freq_unit": "Hz", "labels": cell})
    else:
        _matlab_v73(path, f, H, (-1, 1))
        with h5py.File(path, "r+") as h5:
            _matlab_char(h5, "freq_unit", "Hz")
            _matlab_cell(h5, "labels", entries)
    return path


@pytest.mark.parametrize("version", ["v5", "v7.3"])
def test_a_mat_files_cell_array_of_labels_names_the_points(tmp_path, case, version):
    """A lab's MAT-file names its points in a cell array beside f and H, labels =
    {'1+Z', ...}: it was left out (v5: cells dropped; v7.3: references into '#refs#' not
    followed), the points numbered 1..5 whatever it said. Its texts are the point labels,
    in both versions; the FRFs as before (to 1e-15)."""
    names = ["1+Z", "2+Z", "tip -Y", "4+Z", "5+Z"]
    path = _mat_with_labels(tmp_path / "plate.mat", case, version, names)
    fs = io.read_frf(path)
    assert fs.labels == tuple(names)
    np.testing.assert_allclose(fs.frf, case.frf[:, :UNIT_LINES], rtol=1e-15, atol=0)
    assert _fit_json(path)["points"] == names


@pytest.mark.parametrize("entries, words", [
    (["1+Z", "2+Z"], "is a cell array of 2 entries, the FRF {frf} has 5 points: which label "
                     "goes with which point cannot be told; give one text per point"),
    (["1+Z", 2.0, "3", "4", "5"], "is a cell array whose entry 2 is no text; laminid reads a "
                                  "cell array of texts, one per point, as the point labels"),
    (["1+Z", "", "3", "4", "5"], "is a cell array whose entry 2 is an empty text, where a "
                                 "point label is expected")])
@pytest.mark.parametrize("version", ["v5", "v7.3"])
def test_a_mat_files_labels_that_cannot_be_the_points_are_refused(tmp_path, case, version,
                                                                  entries, words):
    """A labels cell of another count than the FRF's points, or holding a number, is
    refused naming the variable (it was left out: points numbered 1, 2, ...)."""
    path = _mat_with_labels(tmp_path / "plate.mat", case, version, entries)
    frf = "'/H' (5 x 400)" if version == "v7.3" else "'/H' (400 x 5)"
    r = run(["fit-frf", str(path)])
    assert (r.exit_code, r.stderr) == (
        2, f"laminid: error: {path}: variable 'labels' {words.format(frf=frf)}\n")


def test_labels_of_a_huge_declared_text_are_refused_unread(tmp_path, case):
    """A labels variable of fixed-length texts of 10**9 bytes each (chunked, unwritten: a
    small file) would be read whole, 5 GB for 5 points; refused by its declared size."""
    path = _matlab_v73(tmp_path / "plate.mat", case.freq[:UNIT_LINES],
                       case.frf[:, :UNIT_LINES], (-1, 1))
    with h5py.File(path, "r+") as h5:
        h5.create_dataset("labels", shape=(5,), dtype="S1000000000", chunks=(1,),
                          compression="gzip")
    assert path.stat().st_size < 1e6
    r = run(["fit-frf", str(path)])
    assert (r.exit_code, r.stderr) == (2, (
        f"laminid: error: {path}: variable 'labels': texts of 1000000000 bytes, more than a "
        "point label laminid reads (200 characters)\n"))


def test_a_damaged_v5_mat_file_is_refused_never_a_crash(tmp_path):
    """A bit-flipped version 5 MAT-file: scipy's reader crashed the process (SIGSEGV) on
    this one (byte 632 of the file below set to 193, found by flipping bytes); it is read
    first in a child process, as an HDF5 file is, and refused naming the file; a truncated
    one by scipy's reason."""
    import scipy.io

    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, {"f": np.linspace(100, 2000, 50), "H": np.full((50, 2), 1 + 2j),
                            "units": "Hz"})
    data = bytearray(path.read_bytes())
    path.write_bytes(data[:len(data) // 2])
    with pytest.raises(FrfError, match=rf"^{path}: not a MATLAB MAT-file laminid can read"):
        io.read_frf(path)
    data[632] = 193
    path.write_bytes(data)
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    # (SIGSEGV or SIGBUS: which the forked child gets depends on the parent's heap, SIGBUS
    # after the MAT-file tests of labels ran before it in this module)
    assert re.fullmatch(rf"{re.escape(str(path))}: scipy's MAT-file reader crashed reading "
                        r"the file \((SIGSEGV|SIGBUS)\); the file is damaged", str(info.value))


def test_a_uff_of_ascii_and_binary_records_mixed_is_read_whole(tmp_path, case):
    """A file another tool appended to over a session: ASCII and binary 58b records mixed,
    each FRF's coherence in the other form. Every record read, each coherence with its FRF
    (binary exactly, ASCII to its 12-13 significant digits)."""
    import pyuff

    f, H = case.freq[:UNIT_LINES], case.frf[:3, :UNIT_LINES]
    sets = [pyuff.prepare_164(**SI_164)]
    for k in range(3):
        common = dict(rsp_node=k + 1, rsp_dir=3, ref_node=1, ref_dir=3, abscissa_spacing=1,
                      abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz", x=f)
        sets.append(pyuff.prepare_58(binary=k % 2, func_type=4, ord_data_type=6, data=H[k],
                                     ordinate_axis_units_lab="m/s^2", ordinate_spec_data_type=12,
                                     orddenom_axis_units_lab="N", orddenom_spec_data_type=13,
                                     **common))
        sets.append(pyuff.prepare_58(binary=(k + 1) % 2, func_type=6, ord_data_type=4,
                                     data=np.full(f.size, 0.5 + 0.1 * k),
                                     ordinate_axis_units_lab="NONE", ordinate_spec_data_type=0,
                                     orddenom_axis_units_lab="NONE", orddenom_spec_data_type=0,
                                     **common))
    path = tmp_path / "mixed.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    fs = io.read_frf(path)
    assert fs.labels == ("1+Z", "2+Z", "3+Z") and fs.units == "m/s^2/N"
    np.testing.assert_array_equal(fs.frf[1], H[1])                       # binary: exact
    np.testing.assert_allclose(fs.frf[[0, 2]], H[[0, 2]], rtol=1e-11,
                               atol=1e-11 * np.abs(H).max())              # ASCII
    np.testing.assert_allclose(fs.coherence, np.repeat([[0.5], [0.6], [0.7]], f.size, 1),
                               rtol=1e-12)


def test_a_coherence_record_not_used_is_said_with_why(tmp_path, case):
    """A coherence record on another axis than the FRFs' (100 lines of 1601), or one with no
    FRF of its DOF left to pair with (a DOF without FRF, a second coherence of one FRF), was
    dropped without a word: a file whose every coherence was written on the wrong axis read
    as one without coherence. Each is named now, with why; the others are used as before."""
    import pyuff

    f, H = case.freq[:UNIT_LINES], case.frf[:2, :UNIT_LINES]
    common = dict(binary=0, rsp_dir=3, ref_node=1, ref_dir=3, abscissa_spacing=1,
                  abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz",
                  ordinate_axis_units_lab="m/s^2", orddenom_axis_units_lab="N",
                  ordinate_spec_data_type=12, orddenom_spec_data_type=13)

    def coh(node, c, n=f.size):
        return pyuff.prepare_58(func_type=6, ord_data_type=4, data=np.full(n, c), x=f[:n],
                                rsp_node=node, **common)
    sets = [pyuff.prepare_58(func_type=4, ord_data_type=6, data=H[0], x=f, rsp_node=1,
                             **common), coh(1, 0.7, n=10), coh(1, 0.8), coh(1, 0.5),
            pyuff.prepare_58(func_type=4, ord_data_type=6, data=H[1], x=f, rsp_node=2,
                             **common), coh(9, 0.6)]
    path = tmp_path / "coherence.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    fs = io.read_frf(path)
    assert np.isnan(fs.coherence[1]).all()
    np.testing.assert_array_equal(fs.coherence[0], np.full(f.size, 0.8))   # the first that fits
    assert fs.meta["notes"] == [
        f"{path}: coherence (function type 6) not used: type-58 record 2: 10 lines where the "
        f"FRFs have {f.size}; type-58 record 4: no FRF record of its DOF left to pair it with; "
        "type-58 record 6: no FRF record of its DOF left to pair it with"]


@pytest.mark.parametrize("edit, why", [
    (lambda x: np.where(np.arange(x.size) == 7, np.nan, x), "NaN or inf at index 7"),
    (lambda x: x - 1000.0, "it starts below 0 Hz (-995)"),
    (lambda x: np.concatenate([x[:10], x[9:-1]]), "not increasing at index 10 (50, then 50)")])
def test_a_frequency_dataset_that_is_no_axis_says_why(tmp_path, edit, why):
    """A plain HDF5 file whose '/freq' holds a NaN, starts below 0 or repeats a line was
    refused with 'frequency candidates: none' beside it, the lab left to guess why; the
    message says what is wrong with it."""
    f = np.linspace(5.0, 2000.0, 400)
    path = tmp_path / "p.h5"
    with h5py.File(path, "w") as h5:
        h5["freq"], h5["H"] = edit(f), np.ones((2, 400)) * (1 + 1j)
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value) == (
        f"{path}: no frequency axis matches an FRF dataset; frequency candidates: none; FRF "
        "candidates: '/H' (2 x 400) (an FRF axis must have the frequency's length); '/freq' "
        f"is no axis: {why}")


def test_a_declared_huge_dataset_is_not_read_into_memory(tmp_path):
    """A plain HDF5 file declares its datasets' sizes before any data: a '/freq' of 10**9
    lines (chunked, nothing written: a 1.6 kB file) was read whole to check it as an axis,
    7.5 GiB ('MemoryError' where memory is limited, else the machine's memory taken); it is
    named as more lines than laminid reads without being read, as is an FRF of 10**6
    points (400 million values)."""
    path = tmp_path / "big.h5"
    with h5py.File(path, "w") as h5:
        h5.create_dataset("freq", shape=(10**9,), dtype=float, chunks=(1024,))
        h5.create_dataset("H", shape=(2, 10**9), dtype=complex, chunks=(1, 1024))
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value).endswith("; '/freq' is no axis: 1000000000 lines, more than "
                                    "laminid reads (1000000)")
    with h5py.File(path, "w") as h5:
        h5["freq"] = np.linspace(5.0, 2000.0, 400)
        h5.create_dataset("H", shape=(10**6, 400), dtype=complex, chunks=(16, 400))
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value) == (f"{path}: '/H': 1000000 FRFs of 400 lines (400000000 values), "
                               "more than laminid reads (50000000); split the file")


def test_a_mat_files_variable_larger_than_laminid_reads_is_left_out(tmp_path, monkeypatch):
    """A compressed v5 MAT-file's variable of 10**8 zeros is 150 kB on disk and 800 MB once
    read: each variable's size is taken from its header first and one larger than laminid
    reads is not loaded (here the limit lowered to 1000 values), and named where no FRF is
    found; the file's FRF read as before."""
    import scipy.io

    from laminid_cli.frf import generic_h5

    monkeypatch.setattr(generic_h5, "MAX_FRF_VALUES", 1000)
    f = np.linspace(5.0, 2000.0, 400)
    H = np.exp(1j * f / 300.0)[None, :]
    path = tmp_path / "p.mat"
    scipy.io.savemat(path, {"f": f, "H": H, "freq_unit": "Hz", "T": np.zeros(2000)},
                     do_compression=True)
    fs = generic_h5.read_mat_frf(path, probe=False)
    np.testing.assert_array_equal(fs.freq, f)
    np.testing.assert_array_equal(fs.frf, H)
    scipy.io.savemat(path, {"f": f, "H": np.zeros((2, 400)), "T": np.zeros(2000)})
    with pytest.raises(FrfError) as info:
        generic_h5.read_mat_frf(path, probe=False)
    assert str(info.value).endswith("; left out, larger than laminid reads (1000 values): "
                                    "'T' (2000 values)")
