"""FRF readers/writers (HDF5, UFF 58, CSV), the --into editor, measured_from_frf_file."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from laminid_cli.errors import FrfError, OutputExistsError, SpecimenError
from laminid_cli.frf import io, rfp
from laminid_cli.frf.into import write_measured
from laminid_cli.frf.store import FrfSet
from tests.frf_synth import plate_case


@pytest.fixture(scope="module")
def frfset():
    case = plate_case(noise=0.01, seed=4)
    return FrfSet(freq=case.freq, frf=case.frf, labels=("1", "2", "3", "4", "5"), units="Pa/N")


@pytest.mark.parametrize("suffix", [".h5", ".uff", ".unv", ".csv"])
def test_round_trip(tmp_path, frfset, suffix):
    path = io.write_frf(tmp_path / f"plate{suffix}", frfset)
    back = io.read_frf(path)
    assert back.frf.shape == frfset.frf.shape
    assert np.array_equal(back.freq, frfset.freq)
    # UFF ASCII keeps ~13 significant digits; HDF5 and CSV are exact
    assert np.allclose(back.frf, frfset.frf, rtol=1e-11, atol=1e-12 * np.abs(frfset.frf).max())
    assert len(back.labels) == 5
    assert back.units == "Pa/N"


def test_same_answer_from_hdf5_uff_and_csv(tmp_path, frfset):
    results = []
    for suffix in (".h5", ".uff", ".csv"):
        path = io.write_frf(tmp_path / f"plate{suffix}", frfset)
        f, sigma, zeta = rfp.measured_from_frf_file(path)
        results.append((f, sigma, zeta))
    f0, s0, z0 = results[0]
    assert f0.size == 10
    # identical up to the 13 significant digits of UFF ASCII (the pole refinement stops at its
    # own tolerance, so 1e-12 changes in the data move the result by ~1e-7 relative)
    for f, s, z in results[1:]:
        assert np.allclose(f, f0, rtol=1e-6)
        assert np.allclose(z, z0, rtol=1e-4)
        assert np.allclose(s, s0, rtol=1e-3, atol=1e-4)


def test_a_specimens_frf_file_without_a_frequency_unit(tmp_path, frfset, caplog):
    """A specimen's measured.frf_file (identify, batch) reads the CSV as fit-frf does: a
    column headed "f" in kHz is refused (was read as Hz: every mode 1000 times too low), one
    in Hz is read with the reader's warning logged, naming the file and the column."""
    laminid = io.write_frf(tmp_path / "lab.csv", frfset).read_text().splitlines()
    assert laminid[1].startswith("freq_Hz,")             # laminid's own CSV states Hz
    body = "\n".join(laminid[2:]) + "\n"
    khz = tmp_path / "khz.csv"
    khz.write_text("f,1_re,1_im,2_re,2_im,3_re,3_im,4_re,4_im,5_re,5_im\n" + "\n".join(
        ",".join([repr(float(row.split(",")[0]) / 1e3)] + row.split(",")[1:])
        for row in laminid[2:]) + "\n")
    with pytest.raises(FrfError, match=rf"{khz}: column 1 \('f'\): the frequency states no "
                                       r"unit, and its values 0\.001 to 1\.601 read as Hz"):
        rfp.measured_from_frf_file(khz)
    hz = tmp_path / "hz.csv"
    hz.write_text("f,1_re,1_im,2_re,2_im,3_re,3_im,4_re,4_im,5_re,5_im\n" + body)
    with caplog.at_level("WARNING", logger="laminid_cli.frf.rfp"):
        f, _, _ = rfp.measured_from_frf_file(hz)
    assert f.size == 10
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 1 and messages[0].startswith(
        f"{hz}: column 1 ('f'): the frequency states no unit; its values 1 to 1601 are read as "
        "Hz"), messages


def test_write_refuses_to_overwrite(tmp_path, frfset):
    path = io.write_frf(tmp_path / "a.csv", frfset)
    with pytest.raises(OutputExistsError):
        io.write_frf(path, frfset)
    io.write_frf(path, frfset, overwrite=True)


def test_csv_variants(tmp_path):
    p = tmp_path / "x.csv"
    p.write_text("# exported\nf [Hz];a.re;a.im\n1;1;0\n2;0.5;-0.5\n3;0.2;-0.1\n")
    fs = io.read_frf(p)
    assert fs.frf.shape == (1, 3)
    assert fs.frf[0, 1] == 0.5 - 0.5j
    p.write_text("100 1 0 2 0\n200 1 1 2 2\n")
    assert io.read_frf(p).frf.shape == (2, 2)


@pytest.mark.parametrize("text, message", [
    # the file's lines named (the axis' indices were, 'line 1: 1 Hz, line 2: 1 Hz' where the
    # lines of a file with a header above are 2 and 3)
    ("1,1,0\n1,2,0\n", "not strictly increasing: line 1: 1 Hz, line 2: 1 Hz"),
    ("f [Hz],re,im\n2,1,0\n1,2,0\n", "not strictly increasing: line 2: 2 Hz, line 3: 1 Hz"),
    ("1,1,0\n2,nan,0\n", "line 2: the FRF of point 1 has NaN/inf at 2 Hz"),
    ("1,1,0\n2,inf,0\n", "line 2: the FRF of point 1 has NaN/inf at 2 Hz"),
    ("f [Hz],re,im\n1,1,0\nnan,1,0\n", r"line 3, column 1 \('f \[Hz\]'\): the frequency "
                                       "nan is not a finite number"),
    ("1,1\n2,1\n", "2 columns"),
    ("1,1,0\n2,1,0,3\n", ":2: 4 columns"),
    ("1,1,0\n2,x,0\n", "not a number"),
    # a file of comments alone was 'no data lines', as an empty one
    ("# nothing\n", r"bad.csv: holds only comments \(1 '#' line\), no data \(expected "
                    r"columns freq, re_1, im_1, ...\)$"),
    ("# f [Hz], H1\n\n# saved by hand\n", r"holds only comments \(2 '#' lines\), no data"),
    ("", r"bad.csv: the file is empty \(0 bytes\) \(expected"),
    ("\n \n", r"bad.csv: holds only blank lines, no data \(expected"),
    (",,,\n", "no data lines"),
])
def test_bad_csv(tmp_path, text, message):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(FrfError, match=message):
        io.read_frf(p)


@pytest.mark.parametrize("text, where", [
    ("# laminid FRF, units Pa/N\nfreq_Hz,p1_re,p1_im,p2_re,p2_im\n"
     "1,2,3,4,5\n2,0.5,0.25,1.2.3,0.1\n",
     "line 4, column 4 ('p2_re'): '1.2.3' is not a number"),
    ("freq_Hz;1_re;1_im\n1;2;3\n2;;5\n", "line 3, column 2 ('1_re'): empty, where a "
                                         "number is expected"),
    ("1 2 3\n2 2 abc\n", "line 2, column 3 (no header): 'abc' is not a number"),
    ("freq_Hz,1_re,1_im\n" + "1,2,3\n" + "2,3," + "9" * 60 + "x\n",
     "line 3, column 3 ('1_im'): '" + "9" * 37 + "...' is not a number"),
], ids=["header-comma", "empty-cell-semicolon", "no-header-spaces", "long-cell"])
def test_a_bad_csv_cell_names_its_line_and_column(tmp_path, text, where):
    """A bad cell quoted its line cut to 60 characters ("not a number in '2,0.5,0.25,1.2.3,
    0.1'") without saying which column; it now names the line, the column's number and header
    name, and the cell."""
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(FrfError) as info:
        io.read_frf(p)
    assert str(info.value) == f"{p}: {where}"


def test_uff_without_type_58_and_with_mismatched_axes(tmp_path, frfset):
    import pyuff

    p = tmp_path / "nodes.uff"
    pyuff.UFF(str(p)).write_sets(pyuff.prepare_15(node_nums=[1, 2], def_cs=[0, 0], disp_cs=[0, 0],
                                                   color=[0, 0], x=[0.0, 1.0], y=[0.0, 0.0],
                                                   z=[0.0, 0.0]), mode="overwrite")
    with pytest.raises(FrfError, match="no type-58 .* dataset types found: 15"):
        io.read_frf(p)
    a = io.write_frf(tmp_path / "a.uff", frfset)
    b = io.write_frf(tmp_path / "b.uff", FrfSet(freq=frfset.freq * 1.5, frf=frfset.frf[:1]))
    merged = tmp_path / "m.uff"
    merged.write_text(a.read_text() + b.read_text())
    with pytest.raises(FrfError, match="record 6 has a different frequency axis"):
        io.read_frf(merged)


def test_unknown_missing_and_garbage_files(tmp_path):
    with pytest.raises(FrfError, match="unknown FRF file type"):
        io.read_frf(tmp_path / "x.xls")
    with pytest.raises(FrfError, match="file not found"):
        io.read_frf(tmp_path / "x.h5")
    g = tmp_path / "g.h5"
    g.write_text("hello")
    with pytest.raises(FrfError, match="not a readable HDF5"):
        io.read_frf(g)


# --------------------------------------------------------------------------- --into
SPEC = """\
# plate P1 (comments must survive)
name: P1   # id
plate:
  a: 210.5 mm
measured:
  frequencies: [125.05, 203.50, null, 446.65]   # Hz; null = not detected
  weights: [1, 1, 0, 1]          # optional, in [0,1]
  sigma: [0.1, 0.1, null, 0.2]   # optional, Hz
  # frf_file: plate.frf.h5       # taken at load time
identify:
  fix: [nu12]   # keep
"""


def test_into_replaces_measured_and_keeps_everything_else(tmp_path):
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    write_measured(spec, [125.1, 203.4, 300.2, None, 580.0], [0.01, 0.02, 0.03, None, 0.05], validate=False)
    text = spec.read_text()
    # only the lines written change: the frequencies' and sigmas' comments described the values
    # replaced; the weights are the user's, carried to the new modes, and keep theirs
    old = SPEC.splitlines()
    assert text.splitlines() == old[:5] + [
        "  frequencies: [125.1, 203.4, 300.2, null, 580.0]",
        "  weights: [1, 1, 1, 0, 1]          # optional, in [0,1]",
        "  sigma: [0.01, 0.02, 0.03, null, 0.05]"] + old[8:]
    data = yaml.safe_load(text)
    assert data["measured"]["frequencies"] == [125.1, 203.4, 300.2, None, 580.0]
    assert data["measured"]["sigma"] == [0.01, 0.02, 0.03, None, 0.05]
    assert data["measured"]["weights"] == [1, 1, 1, 0, 1]   # length changed: 1 found, 0 null
    assert data["plate"] == {"a": "210.5 mm"} and data["identify"] == {"fix": ["nu12"]}
    assert (tmp_path / "p.yaml.bak").read_text() == SPEC


def test_into_keeps_user_weights_when_the_length_matches(tmp_path):
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC.replace("[1, 1, 0, 1]", "[0.5, 1, 0, 1]"))
    write_measured(spec, [125.1, 203.4, 300.2, None], [0.01, 0.02, 0.03, None], validate=False)
    data = yaml.safe_load(spec.read_text())
    assert data["measured"]["weights"] == [0.5, 1, 1, 0]


def test_into_inserts_measured_when_absent(tmp_path):
    spec = tmp_path / "p.yaml"
    spec.write_text("name: X  # c\nlayup: '[0/90]s'\n")
    write_measured(spec, [100.0, 200.0], [0.1, 0.2], validate=False)
    data = yaml.safe_load(spec.read_text())
    assert data == {"name": "X", "layup": "[0/90]s",
                    "measured": {"frequencies": [100.0, 200.0], "sigma": [0.1, 0.2]}}
    assert "# c" in spec.read_text()


@pytest.mark.parametrize("text, message", [("- a\n- b\n", "must be a YAML mapping"),
                                           ("a: [1, 2\n", "not valid YAML"),
                                           ("measured: 3\n", "'measured' must be a mapping")])
def test_into_never_corrupts_a_bad_specimen(tmp_path, text, message):
    spec = tmp_path / "p.yaml"
    spec.write_text(text)
    with pytest.raises(SpecimenError, match=message):
        write_measured(spec, [100.0], [0.1], validate=False)
    assert spec.read_text() == text
    assert not (tmp_path / "p.yaml.bak").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["p.yaml"]


def test_uff_coherence_records_are_matched_to_their_frf(tmp_path):
    import pyuff

    f = np.arange(1.0, 101.0)
    H = np.exp(1j * f / 10)
    coh = np.linspace(0.5, 1.0, f.size)
    common = dict(binary=0, rsp_node=7, rsp_dir=3, ref_node=1, ref_dir=3, x=f,
                  abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                  orddenom_spec_data_type=13)
    sets = [pyuff.prepare_58(func_type=4, ord_data_type=6, data=H, id1="FRF", **common),
            pyuff.prepare_58(func_type=6, ord_data_type=4, data=coh, id1="COH", **common)]
    p = tmp_path / "c.uff"
    pyuff.UFF(str(p)).write_sets(sets, mode="overwrite")
    fs = io.read_frf(p)
    assert fs.labels == ("7+Z",)
    assert np.allclose(fs.frf[0], H) and np.allclose(fs.coherence[0], coh)


@pytest.mark.parametrize("before, after", [
    # block sequences: the whole old entry, comments between its items too, becomes one line;
    # the comment lines after it and the other entries stay
    ("a: 1\nmeasured:\n  frequencies:\n    - 1.0   # old\n    # gone\n    - 2.0\n\n"
     "  # after\n  sigma_source: old rule  # c\n  damping: [0.1, 0.2]\nb: |\n  x\n   y\n",
     "a: 1\nmeasured:\n  frequencies: [3.5]   # Hz, fit\n\n  # after\n"
     "  damping: [0.1, 0.2]\n  sigma: [0.25]\nb: |\n  x\n   y\n"),
    # the last entry removed: the new ones take its lines
    ("measured:\n  frequencies: [1.0]\n  sigma_source: old  # c\nb: 2\n",
     "measured:\n  frequencies: [3.5]   # Hz, fit\n  sigma: [0.25]\nb: 2\n"),
    ("measured:\n  frequencies: [1.0]\n  sigma: [1]\n  sigma_source: old\n",
     "measured:\n  frequencies: [3.5]   # Hz, fit\n  sigma: [0.25]\n"),
    # an empty measured, and a null one written out
    ("a: 1\nmeasured:   # to do\nb: 2\n",
     "a: 1\nmeasured:   # to do\n  frequencies: [3.5]   # Hz, fit\n  sigma: [0.25]\nb: 2\n"),
    ("a: 1\nmeasured: ~\nb: 2\n",
     "a: 1\nmeasured:\n  frequencies: [3.5]   # Hz, fit\n  sigma: [0.25]\nb: 2\n"),
    # a flow mapping: written again as a block, its other entries with the same values
    ("a: 1\nmeasured: {frequencies: [1, 2], frf_note: x}  # Table 1\nb: 2\n",
     "a: 1\nmeasured:\n  frequencies: [3.5]   # Hz, fit\n  frf_note: x\n  sigma: [0.25]\nb: 2\n"),
    # absent: after the root's last entry, before the comments that end the file
    ("a: 1\nb: >\n  folded\n  text\n# end\n",
     "a: 1\nb: >\n  folded\n  text\nmeasured:\n  frequencies: [3.5]   # Hz, fit\n"
     "  sigma: [0.25]\n# end\n"),
    # CRLF line endings stay CRLF, the new lines too
    ("a: 1\r\nmeasured:\r\n  frequencies: [1.0]  # Table 1\r\nb: 2\r\n",
     "a: 1\r\nmeasured:\r\n  frequencies: [3.5]   # Hz, fit\r\n  sigma: [0.25]\r\nb: 2\r\n"),
])
def test_splice_measured_changes_only_the_lines_it_writes(before, after):
    from laminid_cli.frf.into import splice_measured

    out = splice_measured(before, {"frequencies": [3.5], "sigma": [0.25]}, ["sigma_source"],
                          comments={"frequencies": "Hz, fit"})
    assert out == after
    expect = yaml.safe_load(before)
    expect["measured"] = {k: v for k, v in (expect.get("measured") or {}).items()
                          if k != "sigma_source"} | {"frequencies": [3.5], "sigma": [0.25]}
    assert yaml.safe_load(out) == expect


def test_into_keeps_a_byte_order_mark_and_refuses_a_flow_root(tmp_path):
    spec = tmp_path / "p.yaml"
    spec.write_bytes(b"\xef\xbb\xbfname: X\nmeasured:\n  frequencies: [1.0]\n")
    write_measured(spec, [100.0], [0.1], validate=False, comment="Hz, fit-frf of f.h5")
    assert spec.read_bytes() == (b"\xef\xbb\xbfname: X\nmeasured:\n  frequencies: [100.0]   "
                                 b"# Hz, fit-frf of f.h5\n  sigma: [0.1]\n")
    spec.write_text("{name: X, measured: {frequencies: [1.0]}}\n")
    with pytest.raises(SpecimenError, match=r"one flow mapping \(\{\.\.\.\}\); --into edits a "
                                            "specimen written in block style"):
        write_measured(spec, [100.0], [0.1], validate=False)
    assert spec.read_text() == "{name: X, measured: {frequencies: [1.0]}}\n"


@pytest.mark.parametrize("sep, header", [(";", True), (";", False), ("\t", True), ("\t", False)])
def test_csv_with_a_decimal_comma_as_a_european_spreadsheet_writes_it(tmp_path, sep, header):
    # "125,05;0,0012;..." (Excel with a German or French locale): without a header the comma was
    # taken for the separator ("'5;0' is not a number"), with one the cells were refused
    case = plate_case(n_points=2, noise=0.002, seed=3)
    lines = [sep.join(["freq", "p1_re", "p1_im", "p2_re", "p2_im"])] if header else []
    for f, h in zip(case.freq, case.frf.T):
        cells = [f"{f:.9g}"] + [f"{v:.9g}" for z in h for v in (z.real, z.imag)]
        lines.append(sep.join(c.replace(".", ",") for c in cells))
    path = tmp_path / "excel.csv"
    path.write_text("\n".join(lines) + "\n")
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-9)
    assert np.allclose(fs.frf, case.frf, rtol=1e-8, atol=1e-8 * np.abs(case.frf).max())
    fit = rfp.find_modes(fs.freq, fs.frf, bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)


def synth_h(freq):
    """Three modes' receptance at ``freq`` (Hz), one point."""
    from tests.frf_synth import synth_frf

    modes = ((105.3, 0.012), (236.8, 0.008), (402.45, 0.010))
    return synth_frf(freq, modes, np.array([[1.0, -0.6, 0.8]]))[0]


def _german(v: float) -> str:
    """``v`` as a spreadsheet with a German locale and "Use 1000 separator" writes it:
    1234.5 "1.234,500000"."""
    return f"{v:,.6f}".translate(str.maketrans(",.", ".,"))


@pytest.mark.parametrize("sep", [";", "\t"])
def test_csv_with_thousands_separators_of_a_european_spreadsheet(tmp_path, sep):
    """'1.000,5;0,0012' (1000.5 Hz) was refused as 'not a number'; a file whose decimal marks
    are commas and whose every '.' groups thousands is read so, with a note."""
    freq = 1000.5 + 0.5 * np.arange(400)                  # 1000.5-1200 Hz: '1.000,500000'
    H = 1500.0 * np.exp(1j * np.linspace(0, 3, freq.size)) / (1 + (freq - 1100.0) ** 2 / 400)
    lines = [sep.join(["f [Hz]", "H1_re", "H1_im"])]
    lines += [sep.join(_german(v) for v in (f, h.real, h.imag)) for f, h in zip(freq, H)]
    path = tmp_path / "de.csv"
    path.write_text("\n".join(lines) + "\n")
    fs = io.read_frf(path)
    np.testing.assert_allclose(fs.freq, freq, rtol=0, atol=1e-9)
    for part in (np.real, np.imag):                                      # 6 decimals written
        np.testing.assert_allclose(part(fs.frf[0]), part(H), rtol=0, atol=5.1e-7)
    assert f"{path}: '.' read as a thousands separator and ',' as the decimal mark (line " \
           "2, column 1 ('f [Hz]'): '1.000,500000' is 1000.5): the file's decimal marks are " \
           "commas, and every '.' in it is followed by groups of 3 digits" in fs.meta["notes"]


def test_csv_with_a_thousands_separator_and_a_decimal_point_is_refused(tmp_path):
    """'1.000' beside decimal commas is 1000, beside a decimal point ('1.5') 1: nothing in the
    file says which; refused naming both cells (it read '1.000' as 1, silently)."""
    path = tmp_path / "mixed.csv"
    rows = [f"{100 + k},5;0,{k + 1};0,2" for k in range(200)]
    rows[3] = "103,5;1.000;0,2"
    rows[7] = "107,5;1.5;0,2"
    path.write_text("f [Hz];H1_re;H1_im\n" + "\n".join(rows) + "\n")
    with pytest.raises(FrfError) as err:
        io.read_frf(path)
    assert str(err.value) == (
        f"{path}: line 5, column 2 ('H1_re'): '1.000' reads as a number with '.' grouping "
        "thousands, as the file's decimal commas suggest (line 2, column 1 ('f [Hz]'): "
        "'100,5'), but line 9, column 2 ('H1_re'): '1.5' has a decimal point: with both, "
        "which '.' groups thousands is not known (1.000 is 1 or 1000); save the file again "
        "without thousands separators (the cells' number format: untick 'Use 1000 "
        "separator')")


def test_csv_of_decimal_points_between_semicolons_keeps_them(tmp_path):
    """No decimal comma in the file: '1.250' stays 1.25 (the '.' is the decimal point)."""
    path = tmp_path / "dots.csv"
    rows = [f"{100 + k}.500;1.250;0.002" for k in range(200)]
    path.write_text("f [Hz];H1_re;H1_im\n" + "\n".join(rows) + "\n")
    fs = io.read_frf(path)
    assert fs.freq[0] == 100.5 and fs.frf[0, 0] == 1.25 + 0.002j
    assert not any("thousands" in n for n in fs.meta.get("notes", []))


@pytest.mark.parametrize("comment, units, scale", [
    ("# Units: g/N", "g/N", 1.0),                       # was not read: 'unit not stated'
    ("# units = g/N", "g/N", 1.0),                      # was read as the unit '= g/N'
    ("# FRF units: m/s^2/N", "m/s^2/N", 1.0),
    ("# Unit: [g/N]", "g/N", 1.0),
    ("# Units: kHz, g/N, g/N", "g/N", 1e-3),            # the frequency's unit first
    ("# laminid FRF, units m/s^2 / N", "m/s^2 / N", 1.0),   # laminid's own, as before
    ("# units 1", "1", 1.0),
])
def test_csv_units_comment_line_as_tools_write_it(tmp_path, comment, units, scale):
    """A units comment line of an analyser's CSV export, above a magnitude (dB) and phase
    (deg) file with Windows line endings: the FRF unit it names (and the frequency's, first
    in a list, where the header 'Frequency' states none: read, with a note, no warning)."""
    freq = 20.0 + 0.5 * np.arange(1161)
    H = synth_h(freq)
    rows = ["# Exported by SignalCalc Mobilyzer", comment,
            "Frequency,H1 Magnitude [dB],H1 Phase [deg]"]
    rows += [",".join(repr(float(v)) for v in (f * scale, 20 * np.log10(abs(h)),
                                                np.degrees(np.angle(h))))
             for f, h in zip(freq, H)]
    path = tmp_path / "sc.csv"
    path.write_bytes(("\r\n".join(rows) + "\r\n").encode())
    fs = io.read_frf(path)
    assert fs.units == units
    np.testing.assert_allclose(fs.freq, freq, rtol=1e-12)
    np.testing.assert_allclose(fs.frf[0], H, rtol=1e-12)
    assert ("warnings" in fs.meta) == (scale == 1.0)     # the frequency's unit stated or not
    if scale != 1.0:
        assert f"{path}: the frequency read in kHz, as the comment line 2 says (its first " \
               "unit)" in fs.meta["notes"]


@pytest.mark.parametrize("comment, header, message", [
    ("# Units: Hz, g/N, m/s/N", "f", "line 1: '# Units: Hz, g/N, m/s/N' names more than one FRF "
     "unit (g/N, m/s/N), not which column each is; give one ('# units g/N') or each FRF "
     "column's in the header ('H1_re [g/N]')"),
    ("# Units: kHz, g/N", "f [Hz]", "column 1 ('f [Hz]') states a frequency unit the comment "
     "line 1 contradicts ('kHz', its first unit); make them agree"),
])
def test_csv_units_comment_line_that_does_not_say_one_unit_is_refused(tmp_path, comment,
                                                                      header, message):
    path = tmp_path / "u.csv"
    path.write_text("\n".join([comment, f"{header},H1_re,H1_im"]
                              + [f"{100 + k},0.{k + 1},0.2" for k in range(200)]) + "\n")
    with pytest.raises(FrfError) as err:
        io.read_frf(path)
    assert str(err.value) == f"{path}: {message}"


@pytest.mark.parametrize("name, scale", [("Frequency [rad/s]", 2 * np.pi), ("f (kHz)", 1e-3),
                                         ("omega_rad_s", 2 * np.pi), ("freq_kHz", 1e-3),
                                         ("freq_Hz", 1.0), ("Frequency [Hz]", 1.0), ("f", 1.0)])
def test_csv_frequency_column_in_the_unit_its_header_names(tmp_path, name, scale):
    # the header's unit was ignored: "Frequency [rad/s]" gave the 125.05 Hz mode at 785.7 Hz,
    # "f (kHz)" at 0.125 Hz, exit 0
    case = plate_case(n_points=2, noise=0.002, seed=3)
    path = tmp_path / "f.csv"
    rows = [[repr(float(f * scale))] + [repr(float(v)) for z in h for v in (z.real, z.imag)]
            for f, h in zip(case.freq, case.frf.T)]
    path.write_text("\n".join([",".join([name, "a_re", "a_im", "b_re", "b_im"])]
                              + [",".join(r) for r in rows]) + "\n")
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-12)
    fit = rfp.find_modes(fs.freq, fs.frf, bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)


@pytest.mark.parametrize("delimiter", [",", " ", "\t"])
def test_csv_written_by_numpy_savetxt_with_its_header_in_a_comment(tmp_path, delimiter):
    """numpy's savetxt writes ``header=`` as a comment line ("# f (kHz),a_real,a_imag"): it was
    ignored, so its kHz was lost (the 125.05 Hz mode read at 0.125 Hz, exit 0) and its names
    too. The comment line just above the data, with as many cells as the data, names the
    columns (and a note says it was read); a comment line above it, or one with another
    number of cells, does not (laminid's own '# laminid FRF, units m/N' keeps its meaning)."""
    case = plate_case(n_points=2, noise=0.002, seed=3)
    data = np.column_stack([case.freq * 1e-3, case.frf.T.real[:, 0], case.frf.T.imag[:, 0],
                            case.frf.T.real[:, 1], case.frf.T.imag[:, 1]])
    names = ["f (kHz)", "a_real", "a_imag", "b_re", "b_im"] if delimiter != " " else \
        ["f_kHz", "a_real", "a_imag", "b_re", "b_im"]
    path = tmp_path / "np.csv"
    np.savetxt(path, data, delimiter=delimiter, header=delimiter.join(names),
               fmt="%.17g")
    assert path.read_text().startswith("# " + delimiter.join(names) + "\n")
    fs = io.read_frf(path)
    assert np.allclose(fs.freq, case.freq, rtol=1e-12)          # kHz, not Hz
    assert fs.labels == ("a", "b")
    assert fs.meta["notes"] == [
        "column names read from the comment line just above the data (line 1, as numpy's "
        f"savetxt writes a header): {', '.join(names)}",
        f"{path}: the FRF unit is not stated in the file (a comment line '# units Pa/N' above "
        "the data or the FRF columns' headers, 'H1_re [g/N]', state it): the FRFs and their "
        "modal constants are given without a unit (null in --json)"]
    assert fs.units is None
    fit = rfp.find_modes(fs.freq, fs.frf, bands=[(100.0, 300.0)])
    assert np.allclose(fit.freq_hz, case.freq_hz[:3], rtol=1e-4)
    # not a header: a comment with another number of cells; laminid's unit comment is read
    # as before, and a comment above the line above the data names nothing: its kHz lost,
    # the data has no header, and 0.001-1.601 "Hz" is refused (was read, every mode 1000
    # times too low)
    for head in ("# laminid FRF, units m/N\n# f (kHz), a\n",
                 "# f (kHz),a_real,a_imag,b_re,b_im\n# laminid FRF, units m/N\n"):
        body = path.read_text().split("\n", 1)[1]
        other = tmp_path / "other.csv"
        other.write_text(head + body)
        with pytest.raises(FrfError, match=r"other.csv: column 1 \(no header\): the frequency "
                                           r"states no unit, and its values 0.001 to 1.601 "):
            io.read_frf(other)
        # ... and read with a header line that states it (the unit's name in brackets holds
        # a blank: "f [kHz]" only where blanks do not separate the cells)
        first = "f [kHz]" if delimiter != " " else "f_kHz"
        other.write_text(head + delimiter.join([first, "a_re", "a_im", "b_re", "b_im"]) + "\n"
                         + body)
        fs = io.read_frf(other)
        assert fs.labels == ("a", "b") and np.allclose(fs.freq, case.freq, rtol=1e-12)
        assert fs.units == "m/N" and not fs.meta.get("notes") and not fs.meta.get("warnings")


def test_csv_first_column_in_another_unit_is_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("time [s],a_re,a_im\n0,1,0\n0.001,0.5,0.1\n0.002,0.2,0.1\n")
    with pytest.raises(FrfError, match=r"column 1 \('time \[s\]'\): unit 's' is not a "
                                       r"frequency unit laminid reads \(hz, .*rad/s"):
        io.read_frf(p)


@pytest.mark.parametrize("name", ["omega", "w", "Omega", "angular_freq"])
def test_csv_angular_frequency_without_its_unit_is_refused(tmp_path, name):
    # "omega" in rad/s was read as Hz: the 125.05 Hz mode at 785.7 Hz, exit 0
    p = tmp_path / "w.csv"
    p.write_text(f"{name},a_re,a_im\n0,1,0\n10,0.5,0.1\n20,0.2,0.1\n")
    with pytest.raises(FrfError, match=rf"w.csv: column 1 \('{name}'; give its unit in the "
                                       rf"header, '{name} \[rad/s\]' or '{name} \[Hz\]'\): the "
                                       rf"frequency '{name}' reads as an angular frequency but "
                                       r"says no unit"):
        io.read_frf(p)
    for header, hz in ((f"{name} [rad/s]", 1000 / (2 * np.pi)), (f"{name}_hz", 1000.0),
                       ("frequency", 1000.0)):
        p.write_text(f"{header},a_re,a_im\n0,1,0\n1000,0.5,0.1\n2000,0.2,0.1\n")
        assert io.read_frf(p).freq[1] == pytest.approx(hz, rel=1e-15)


def test_an_unfinished_acquisition_is_noted_when_fitted(tmp_path):
    """fit-frf of a file whose acquire session stopped (1 of 4 points, 'complete' false)
    fitted it without a word, as if it were the whole test; a note now says so, with the
    points saved of those asked for and the resume. A finished file has no such note."""
    from laminid_cli.frf.store import FrfWriter, read_frf_h5

    freq = np.linspace(0.0, 100.0, 51)
    frf = 1.0 / (50.0 ** 2 - freq ** 2 + 2j * 0.02 * 50.0 * freq)
    w = FrfWriter(tmp_path / "s.h5", freq, units="Pa/N", settings={"n_points": 4})
    w.add_point("1", frf, np.ones(51))
    notes = io.point_quality_notes(read_frf_h5(tmp_path / "s.h5", probe=False))
    assert notes == [f"{tmp_path / 's.h5'}: an unfinished acquisition (its session stopped): "
                     "1 point of the 4 asked for, fitted as saved (a mode with a nodal line "
                     "through every point measured goes unseen); laminid acquire ... --resume "
                     "measures the rest"]
    w.close()
    assert io.point_quality_notes(read_frf_h5(tmp_path / "s.h5", probe=False)) == []


def test_every_point_saved_but_not_marked_complete_is_not_noted_unfinished(tmp_path):
    """acquire stopped after saving its last point, before marking the file complete (a full
    disk then): every point asked for is there, no 'unfinished acquisition' note."""
    from laminid_cli.frf.store import FrfWriter, read_frf_h5

    freq = np.linspace(0.0, 100.0, 51)
    w = FrfWriter(tmp_path / "s.h5", freq, units="Pa/N", settings={"n_points": 1})
    w.add_point("1", 1.0 / (50.0 ** 2 - freq ** 2 + 2j * freq), np.ones(51))
    assert io.point_quality_notes(read_frf_h5(tmp_path / "s.h5", probe=False)) == []


# ------------------------------------------------------------- an undefined FRF at 0 Hz
#: two modes (Hz, damping ratio) seen from two points, 0-400 Hz at 0.5 Hz, receptance
DC_MODES = ((105.3, 0.012), (236.8, 0.008))


@pytest.fixture(scope="module")
def dc_truth():
    from tests.frf_synth import synth_frf

    freq = 0.5 * np.arange(801)
    C = np.array([[1.0, -0.6], [0.7, 0.9]]) * 1e3
    return freq, synth_frf(freq, DC_MODES, C)


def _dc_warning(path, n: int = 1) -> str:
    lines = "the first line" if n == 1 else f"the first {n} lines"
    return (f"{path}: {lines} (0 Hz) dropped: its FRF values are NaN/inf (a response over a "
            "force spectrum that is 0 at DC, as analysers export it)")


def _dc_csv(path, freq, H, layout: str, dc_cells) -> None:
    """A CSV of ``H`` in ``layout`` whose 0 Hz line holds ``dc_cells`` after the frequency."""
    def cells(row):
        if layout == "re/im":
            return [repr(float(v)) for h in row for v in (h.real, h.imag)]
        if layout == "complex":
            return [f"{float(h.real)!r}{float(h.imag):+.17g}i" for h in row]
        return [repr(float(v)) for h in row for v in (20 * np.log10(abs(h)),
                                                       np.degrees(np.angle(h)))]
    header = {"re/im": "f [Hz],H1_re,H1_im,H2_re,H2_im", "complex": "f [Hz],H1,H2",
              "mag/phase": "f [Hz],H1 Magnitude [dB],H1 Phase [deg],H2 Magnitude [dB],"
                           "H2 Phase [deg]"}[layout]
    lines = [header, ",".join(["0"] + list(dc_cells))]
    lines += [",".join([repr(float(f))] + cells(H[:, k])) for k, f in enumerate(freq) if k]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("layout, dc_cells", [
    ("re/im", ["nan", "nan", "inf", "-inf"]),      # 0/0 at one point, x/0 at the other
    ("re/im", ["NaN", "0", "1.5", "0"]),           # MATLAB's NaN, in one cell only
    ("complex", ["nan+nani", "inf+0i"]),
    ("mag/phase", ["inf", "nan", "inf", "nan"]),
])
def test_a_csv_whose_0_hz_line_is_nan_or_inf_is_read_from_the_next_line(tmp_path, dc_truth,
                                                                         layout, dc_cells):
    """H = X/F at 0 Hz, where the force spectrum is 0, is NaN or inf, as analysers export it:
    the file was refused ("FRF of point 1 has NaN/inf at 0 Hz"); the line is dropped with a
    warning saying so, the rest read as written (to 1e-12, repr's rounding through dB and
    degrees), fit-frf finds the modes (exit 0) and prints the warning."""
    freq, H = dc_truth
    path = tmp_path / "dc.csv"
    _dc_csv(path, freq, H, layout, dc_cells)
    fs = io.read_frf(path)
    assert fs.meta["warnings"] == [_dc_warning(path)]
    np.testing.assert_array_equal(fs.freq, freq[1:])
    np.testing.assert_allclose(fs.frf, H[:, 1:], rtol=1e-12, atol=0)
    from click.testing import CliRunner

    from laminid_cli.cli import cli

    r = CliRunner().invoke(cli, ["fit-frf", str(path), "--json"])
    assert r.exit_code == 0, r.output
    assert f"warning: {_dc_warning(path)}" in r.stderr
    import json

    got = [m["freq_hz"] for m in json.loads(r.stdout)["modes"]]
    np.testing.assert_allclose(got, [m[0] for m in DC_MODES], rtol=1e-6)


@pytest.mark.parametrize("where, dc_cells, message", [
    # above 0 Hz: refused, naming the file's line (the header is line 1, 0 Hz line 2)
    ("0.5 Hz", None, "line 3: the FRF of point H1 has NaN/inf at 0.5 Hz; only a 0 Hz line "
                     "of them is dropped"),
    ("0 and 1 Hz", ["nan", "nan", "nan", "nan"], "line 4: the FRF of point H1 has NaN/inf at "
                                                 "1 Hz; only a 0 Hz line of them is dropped"),
])
def test_nan_above_0_hz_stays_refused(tmp_path, dc_truth, where, dc_cells, message):
    freq, H = dc_truth
    H = H.copy()
    H[0, 2 if dc_cells else 1] = np.nan
    path = tmp_path / "nan.csv"
    _dc_csv(path, freq, H, "re/im",
            dc_cells or [repr(float(v)) for h in H[:, 0] for v in (h.real, h.imag)])
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value) == f"{path}: {message}"


def test_a_finite_0_hz_line_is_kept_without_a_word(tmp_path, dc_truth):
    freq, H = dc_truth
    path = tmp_path / "dc.csv"
    _dc_csv(path, freq, H, "re/im", [repr(float(v)) for h in H[:, 0] for v in (h.real, h.imag)])
    fs = io.read_frf(path)
    assert "warnings" not in fs.meta and fs.freq[0] == 0 and fs.freq.size == freq.size


def test_uff_and_plain_hdf5_0_hz_line_of_nan_is_dropped_the_same(tmp_path, dc_truth):
    """The UFF and plain HDF5 readers share the check: their 0 Hz line of NaN/inf (coherence
    beside it) was refused too; dropped with the same warning, NaN at 0.5 Hz still refused."""
    import h5py
    import pyuff

    freq, H = dc_truth
    bad = H.copy()
    bad[:, 0] = [np.nan, complex(np.inf, 0)]
    uff = tmp_path / "dc.uff"
    # ASCII, 4E20.12 a line: pyuff writes NaN as 0, another tool's export "NaN" as here
    sets = [pyuff.prepare_58(binary=0, id1=f"FRF {k + 1}", func_type=4, rsp_node=k + 1,
                             rsp_dir=3, ref_node=1, ref_dir=3, ord_data_type=6,
                             abscissa_spacing=1, abscissa_spec_data_type=18,
                             abscissa_axis_units_lab="Hz", ordinate_axis_units_lab="m",
                             ordinate_spec_data_type=8, orddenom_spec_data_type=13,
                             orddenom_axis_units_lab="N", data=H[k], x=freq)
            for k in range(2)]
    coh = [pyuff.prepare_58(binary=0, id1="Coh 1", func_type=6, rsp_node=1, rsp_dir=3,
                            ref_node=1, ref_dir=3, ord_data_type=4, abscissa_spacing=1,
                            abscissa_spec_data_type=18, abscissa_axis_units_lab="Hz",
                            ordinate_spec_data_type=0, orddenom_spec_data_type=0,
                            data=np.linspace(0.5, 1.0, freq.size), x=freq)]
    pyuff.UFF(str(uff)).write_sets(sets + coh, mode="add")
    lines = uff.read_text().split("\n")
    heads = [i for i, line in enumerate(lines) if line.strip() == "58"]
    for i, dc in zip(heads, ("                 NaN                 NaN",
                             "                 inf" + 19 * " " + "0")):
        lines[i + 12] = dc + lines[i + 12][40:]          # record 12's first line: re, im
    uff.write_text("\n".join(lines))
    h5 = tmp_path / "dc.h5"
    with h5py.File(h5, "w") as f:
        f.create_dataset("frequency", data=freq).attrs["units"] = "Hz"
        f.create_dataset("H", data=bad).attrs["units"] = "m/N"
    for path in (uff, h5):
        fs = io.read_frf(path)
        assert fs.meta["warnings"] == [_dc_warning(path)]
        np.testing.assert_array_equal(fs.freq, freq[1:])
        np.testing.assert_allclose(fs.frf, H[:, 1:], rtol=1e-11, atol=0)   # ASCII: 12 digits
    np.testing.assert_allclose(io.read_frf(uff).coherence[0],
                               np.linspace(0.5, 1.0, freq.size)[1:], rtol=1e-11, atol=0)
    bad[0, 1] = np.nan
    with h5py.File(h5, "w") as f:
        f.create_dataset("frequency", data=freq).attrs["units"] = "Hz"
        f.create_dataset("H", data=bad).attrs["units"] = "m/N"
    with pytest.raises(FrfError, match=r"FRF of point 1 has NaN/inf at 0\.5 Hz"):
        io.read_frf(h5)


# ------------------------------------------------------------- spreadsheet exports
@pytest.mark.parametrize("sep", [",", ";", "\t"], ids=["comma", "semicolon", "tab"])
def test_a_spreadsheets_empty_trailing_columns_and_rows_are_blank(tmp_path, dc_truth, sep):
    """A spreadsheet writes the columns and rows formatted but empty as separators: lines
    ending ",," and lines ",,,,," below the data were refused ("line 2, column 6: empty,
    where a number is expected"), and so was a tab-separated line ending in one tab, whose
    tab the test for a separator at the end stripped as a blank. Read as the data alone."""
    freq, H = dc_truth
    cells = [[repr(float(f)), repr(float(H[0, k].real)), repr(float(H[0, k].imag))]
             for k, f in enumerate(freq) if k]
    trail = sep * (1 if sep == "\t" else 2)
    text = [sep.join(["f [Hz]", "H1_re", "H1_im"]) + trail]
    text += [sep.join(c) + trail for c in cells] + [sep * 4] * 3
    path = tmp_path / "sheet.csv"
    path.write_text("\r\n".join(text) + "\r\n")
    fs = io.read_frf(path)
    np.testing.assert_array_equal(fs.freq, freq[1:])
    np.testing.assert_array_equal(fs.frf, H[:1, 1:])
    assert fs.labels == ("H1",) and "warnings" not in fs.meta


def test_a_missing_last_value_is_still_named(tmp_path):
    p = tmp_path / "gap.csv"
    p.write_text("f [Hz],H_re,H_im\n1,2,3\n2,3,\n")       # one empty cell: as before
    with pytest.raises(FrfError, match=r":3: 2 columns, the first data line has 3"):
        io.read_frf(p)


@pytest.mark.parametrize("error", ["#DIV/0!", "#NUM!", "#div/0!"])
def test_a_spreadsheets_division_by_zero_at_0_hz_is_dropped_as_nan(tmp_path, dc_truth, error):
    """A spreadsheet that computed H = X/F writes its error value where F is 0, at 0 Hz: the
    file was refused ("line 2, column 2 ('H1_re'): '#DIV/0!' is neither a number ..."); that
    line is dropped as a NaN one, with the warning naming the value. Elsewhere it is still
    refused by line and column."""
    freq, H = dc_truth
    path = tmp_path / "div0.csv"
    _dc_csv(path, freq, H, "re/im", [error] * 4)
    fs = io.read_frf(path)
    assert fs.meta["warnings"] == [_dc_warning(path).replace("NaN/inf", f"NaN/inf or {error}")]
    np.testing.assert_array_equal(fs.freq, freq[1:])
    np.testing.assert_allclose(fs.frf, H[:, 1:], rtol=1e-12, atol=0)
    lines = path.read_text().splitlines()
    lines[5] = lines[5].split(",")[0] + f",{error},1,2,3"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value).startswith(f"{path}: line 6, column 2 ('H1_re'): '{error}' is ")


@pytest.mark.parametrize("error", ["#DIV/0!", "#VALUE!", "#N/A", "#REF!"])
@pytest.mark.parametrize("where", ["middle", "first"])
def test_a_spreadsheet_error_as_the_frequency_is_refused_by_line_not_skipped(tmp_path, dc_truth,
                                                                           error, where):
    """A spreadsheet's error value in the frequency column begins the line with '#': it was
    skipped as a comment line, the measured line lost without a word (in the middle), or
    taken for numpy's commented header (the first line, no header above: its error value the
    frequency's name). It is refused naming the line and the column, as the same value in an
    FRF column is (the 0 Hz line's #DIV/0!, X/F at F = 0, the one case dropped)."""
    freq, H = dc_truth
    rows = [",".join([repr(float(f))] + [repr(float(v)) for h in H[:, k] for v in (h.real,
                                                                                      h.imag)])
            for k, f in enumerate(freq) if k]
    k = 3 if where == "middle" else 0
    rows[k] = error + rows[k][rows[k].index(","):]
    head = "f [Hz],H1_re,H1_im,H2_re,H2_im\n" if where == "middle" else ""
    path = tmp_path / "sheet.csv"
    path.write_text(head + "\n".join(rows) + "\n")
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    column = "column 1 ('f [Hz]')" if where == "middle" else "column 1 (no header)"
    assert str(info.value) == (f"{path}: line {k + 1 + bool(head)}, {column}: '{error}' is a "
                               "spreadsheet's error value, not a number (the formula of that "
                               "cell failed: correct it in the sheet and save the CSV again)")


def test_a_comment_line_beginning_like_an_error_value_is_still_a_comment(tmp_path, dc_truth):
    """Only a whole first cell that is an error value makes a '#' line data: '#NAME of the
    test' and '#N/Aside' stay comments."""
    freq, H = dc_truth
    rows = [",".join([repr(float(f)), repr(float(H[0, k].real)), repr(float(H[0, k].imag))])
            for k, f in enumerate(freq) if k]
    path = tmp_path / "c.csv"
    path.write_text("#NAME of the test\n#N/Aside\nf [Hz],H1_re,H1_im\n" + "\n".join(rows))
    np.testing.assert_array_equal(io.read_frf(path).freq, freq[1:])


def test_an_excel_csv_with_a_thousands_separator_reads_its_frequencies(tmp_path, dc_truth):
    """Excel writes a column formatted 'Use 1000 separator' as quoted "1,000.5" cells in a
    ','-separated CSV: the line at 1000 Hz was refused ("'1,000.5' is not a number"). ','
    is read as grouping thousands where every ',' in the file's numbers is followed by groups
    of 3 digits and its decimal mark is '.', with a note; the axis as written, exactly. A
    file with a decimal comma in a quoted cell ("0,5") is read as before (refused)."""
    freq, H = dc_truth
    f = freq[1:] * 3.0                                  # 1.5 .. 1200 Hz, so some above 1000
    rows = [",".join([f'"{x:,.1f}"', repr(float(h.real)), repr(float(h.imag))])
            for x, h in zip(f, H[0, 1:])]
    path = tmp_path / "excel.csv"
    path.write_text("Frequency (Hz),H1 Real,H1 Imag\r\n" + "\r\n".join(rows) + "\r\n")
    fs = io.read_frf(path)
    np.testing.assert_array_equal(fs.freq, f)
    np.testing.assert_array_equal(fs.frf[0], H[0, 1:])
    k = int(np.argmax(f >= 1000)) + 2
    assert fs.meta["notes"][0] == (
        f"{path}: ',' read as a thousands separator (line {k}, column 1 ('Frequency (Hz)'): "
        f"'{f[k - 2]:,.1f}' is {float(f[k - 2])!r}): every ',' in the file's numbers is followed "
        "by groups of 3 digits, and its decimal mark is '.'")
    path.write_text(path.read_text().replace('"1.5"', '"1,5"'))
    with pytest.raises(FrfError, match="line 2, column 1 .*'1,5' is not a number"):
        io.read_frf(path)


def test_a_header_of_names_over_units_gives_the_points_and_the_unit(tmp_path, dc_truth):
    """Column names over a line of their units, as loggers and spreadsheets write them: the
    units' line was taken for the header and the names' line skipped as a title, so the
    points were named "m/s^2/N", "m/s^2/N" and the FRF unit was not stated. Each name now
    takes its unit: points H1, H2 in m/s^2/N, the frequency in kHz converted, the magnitude
    in dB and the phase in degrees by their units; a title above stays skipped."""
    freq, H = dc_truth
    f_khz = [repr(float(f) / 1000) for f in freq[1:]]
    reim = [",".join([f] + [repr(float(v)) for h in H[:, k + 1] for v in (h.real, h.imag)])
            for k, f in enumerate(f_khz)]
    path = tmp_path / "two.csv"
    path.write_text("Export of test 3\nFrequency,H1 Real,H1 Imag,H2 Real,H2 Imag\n"
                    "kHz,m/s^2/N,m/s^2/N,m/s^2/N,m/s^2/N\n" + "\n".join(reim) + "\n")
    fs = io.read_frf(path)
    assert fs.labels == ("H1", "H2") and fs.units == "m/s^2/N" and "warnings" not in fs.meta
    np.testing.assert_allclose(fs.freq, freq[1:], rtol=1e-15)
    np.testing.assert_array_equal(fs.frf, H[:, 1:])
    assert f"{path}: a header of two lines: the column names (line 2) over their units (line " \
           "3), read as Frequency [kHz], H1 Real [m/s^2/N], H1 Imag [m/s^2/N], H2 Real " \
           "[m/s^2/N], H2 Imag [m/s^2/N]" in fs.meta["notes"]
    assert any("lines 1-1 above the header skipped ('Export of test 3')" in n
               for n in fs.meta["notes"])
    magph = [";".join([repr(float(f))] + [repr(float(v)) for h in H[:, k]
                                          for v in (20 * np.log10(abs(h)),
                                                    np.degrees(np.angle(h)))])
             for k, f in enumerate(freq) if k]
    path = tmp_path / "magph.csv"
    path.write_text("f;Pt1 Magnitude;Pt1 Phase;Pt2 Magnitude;Pt2 Phase\n"
                    "[Hz];[dB];[deg];[dB];[deg]\n" + "\n".join(magph) + "\n")
    fs = io.read_frf(path)
    assert fs.labels == ("Pt1", "Pt2") and "warnings" not in fs.meta
    np.testing.assert_allclose(fs.frf, H[:, 1:], rtol=1e-12, atol=0)
