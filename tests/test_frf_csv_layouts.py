"""The CSV FRF reader's layouts besides ``freq, re_1, im_1, ...``: one column of complex cells
per FRF (numpy/Python ``(a+bj)``, MATLAB/Octave/spreadsheet ``a+bi``) and magnitude/phase
column pairs named in the header (linear or dB; degrees, radians or no unit)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.errors import FrfError
from laminid_cli.frf import io
from tests.frf_synth import synth_frf

#: four modes (Hz, damping ratio) seen from three points, 20-600 Hz at 0.5 Hz, receptance
MODES = ((105.3, 0.012), (236.8, 0.008), (402.45, 0.010), (517.1, 0.006))
#: every value written with repr (17 significant digits): what is read back differs from the
#: truth by the rounding of |H|, angle, dB and degrees (measured ~2e-15); this is the bound
REL = 1e-12


@pytest.fixture(scope="module")
def truth():
    freq = 20.0 + 0.5 * np.arange(1161)
    C = np.array([[1.0, -0.6, 0.8, 0.5], [0.7, 0.9, -0.4, 0.6], [-0.5, 0.4, 0.9, -0.8]])
    C = C * (2 * np.pi * np.array([m[0] for m in MODES])) ** 2 * 1e-3
    return freq, synth_frf(freq, MODES, C)


def _unit_note(path) -> str:
    """The reader's note on a file that states no FRF unit (none of these files has a
    '# units' line)."""
    return (f"{path}: the FRF unit is not stated in the file (a comment line '# units Pa/N' "
            "above the data or the FRF columns' headers, 'H1_re [g/N]', state it): the FRFs "
            "and their modal constants are given without a unit (null in --json)")


#: how a file without a header is told to state its frequency's unit
NO_HEADER_HOW = ("add a header line above the data, one name per column, the first stating "
                 "the unit: 'f [kHz]', 'f [Hz]' or 'f [rad/s]'")


def _freq_warning(path, column: str, values: str, how: str, hz: str) -> str:
    """The reader's warning on a frequency column whose header states no unit (``hz``: the
    header that would state Hz)."""
    return (f"{path}: {column}: the frequency states no unit; its values {values} are read as "
            "Hz (were they kHz, every mode would be 1000 times too low; rad/s, 6.28 times too "
            f"high); if they are not Hz, {how}; '{hz}' confirms Hz and silences this "
            "warning")


def _other_notes(notes) -> list[str]:
    """``notes`` without the reader's note on the FRF unit (:func:`_unit_note`)."""
    return [n for n in notes if "the FRF unit is not stated in the file" not in n]


def _rel_error(got, want) -> float:
    return float(np.max(np.abs(got - want) / np.abs(want)))


def _r(x) -> str:
    return repr(float(x))


def _write(path, header, rows, sep=","):
    lines = ([sep.join(header)] if header else []) + [sep.join(r) for r in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# ------------------------------------------------------------------------------ complex cells
@pytest.mark.parametrize("delimiter", [" ", ","])
def test_complex_cells_as_numpy_savetxt_writes_them(tmp_path, truth, delimiter):
    """np.savetxt of a complex array: every cell "(a+bj)", the frequency too ("(20+0j)"),
    the header a '#' comment: its names label the points where it splits as the data do
    (blanks), with a note; written with blanks above comma-separated data, it names nothing
    (the points are numbered)."""
    freq, H = truth
    path = tmp_path / "numpy.csv"
    np.savetxt(path, np.column_stack([freq, H.T]), delimiter=delimiter, header="f H1 H2 H3")
    assert path.read_text().splitlines()[1].lstrip().startswith("(2.0000000")
    fs = io.read_frf(path)
    assert np.array_equal(fs.freq, freq)
    assert _rel_error(fs.frf, H) <= REL
    if delimiter == " ":
        assert fs.labels == ("H1", "H2", "H3")
        assert fs.meta == {"notes": [
            "column names read from the comment line just above the data (line 1, as numpy's "
            "savetxt writes a header): f, H1, H2, H3", _unit_note(path)],
            "warnings": [_freq_warning(path, "column 1 ('f')", "20 to 600",
                                       "state it in the header: 'f_kHz', 'f_Hz' or 'f_rad_s'",
                                       "f_Hz")]}
    else:
        assert fs.labels == ("1", "2", "3")
        assert fs.meta == {"notes": [_unit_note(path)], "warnings": [_freq_warning(
            path, "column 1 (no header)", "20 to 600", NO_HEADER_HOW, "f [Hz]")]}


def test_complex_cells_as_python_writes_them(tmp_path, truth):
    freq, H = truth
    rows = [[_r(f)] + [str(complex(z)) for z in H[:, i]] for i, f in enumerate(freq)]
    path = _write(tmp_path / "py.csv", ["freq_Hz", "H1", "H2", "H3"], rows)
    assert "-" in rows[0][1][1:] and rows[0][1].endswith("j)")       # "(1.2e-05-3.4e-06j)"
    fs = io.read_frf(path)
    assert _rel_error(fs.frf, H) <= REL
    assert fs.labels == ("H1", "H2", "H3")


def _matlab(z: complex, spaced: bool, comma: bool = False) -> str:
    """A cell as MATLAB's writematrix writes it ("a+bi"), or disp ("a - bi"); a value with
    no imaginary part as a plain real number, as some tools write it."""
    if z.imag == 0:
        text = _r(z.real)
    else:
        sign = " - " if z.imag < 0 else " + "
        text = _r(z.real) + (sign if spaced else sign.strip()) + _r(abs(z.imag)) + "i"
    return text.replace(".", ",") if comma else text


@pytest.mark.parametrize("sep, spaced, comma", [(",", False, False), (",", True, False),
                                                (" ", True, False), (";", False, True)],
                         ids=["writematrix", "spaced-comma", "spaced-blank", "decimal-comma"])
def test_complex_cells_as_matlab_or_a_spreadsheet_writes_them(tmp_path, truth, sep, spaced,
                                                              comma):
    """"a+bi" cells; "a - bi" with blanks around the sign even in a blank-separated file;
    a European spreadsheet's "1,2+4,5i" between ';'; a plain real cell ("0") among complex
    ones is a + 0i."""
    freq, H = truth
    H = H.copy()
    H[1, 0] = H[1, 0].real          # written "1.23e-05", no imaginary part
    H[2, 3] = 0.0                   # written "0.0"
    rows = [[_r(f).replace(".", ",") if comma else _r(f)]
            + [_matlab(z, spaced, comma) for z in H[:, i]] for i, f in enumerate(freq)]
    path = _write(tmp_path / "matlab.csv", ["freq_Hz", "a", "b", "c"], rows, sep=sep)
    fs = io.read_frf(path)
    assert np.array_equal(fs.freq, freq)
    assert fs.frf[2, 3] == 0 and fs.frf[1, 0] == H[1, 0]
    ok = H != 0
    assert _rel_error(fs.frf[ok], H[ok]) <= REL
    assert fs.labels == ("a", "b", "c")


def test_two_columns_of_complex_cells_are_two_frfs_not_one_real_imaginary_pair(tmp_path,
                                                                               truth):
    """freq + 2 complex columns (3 columns, as re/im of one FRF would be) and freq + 1 complex
    column (2 columns, refused before as an even count): the cells say which layout."""
    freq, H = truth
    for n in (1, 2):
        rows = [[_r(f)] + [str(complex(z)) for z in H[:n, i]] for i, f in enumerate(freq)]
        fs = io.read_frf(_write(tmp_path / f"n{n}.csv", None, rows))
        assert fs.frf.shape == (n, freq.size)
        assert _rel_error(fs.frf, H[:n]) <= REL


# ------------------------------------------------------------------------------ magnitude/phase
def _deg(z):
    return np.degrees(np.angle(z))


def _db(z):
    return 20 * np.log10(np.abs(z))


#: (magnitude name, phase name, magnitude of H, phase of H, labels read, note expected)
MAG_PHASE = {
    "linear-deg": ("p{k}_mag", "p{k}_phase_deg", np.abs, _deg, ("p1", "p2", "p3"), None),
    "dB-deg": ("H{k} Magnitude [dB]", "H{k} Phase [deg]", _db, _deg, ("H1", "H2", "H3"), None),
    "linear-rad": ("abs(H{k})", "arg(H{k}) [rad]", np.abs, np.angle, ("H1", "H2", "H3"), None),
    "phase-first-dB-degree-sign": ("H{k}_mag (dB)", "H{k}_phase (°)", _db, _deg,
                                   ("H1", "H2", "H3"), None),
    "no-unit-deg": ("|H{k}|", "phase{k}", np.abs, _deg, ("H1", "H2", "H3"),
                    "phase columns 'phase1', 'phase2', 'phase3' with no unit: read in "
                    "degrees: it jumps by 359.9"),
    "no-unit-rad": ("H{k}_amp", "H{k}_phi", np.abs, np.angle, ("H1", "H2", "H3"),
                    "phase columns 'H1_phi', 'H2_phi', 'H3_phi' with no unit: read in "
                    "radians: no |phase| exceeds pi (largest 3.1"),
}


def _mag_phase_file(path, truth, case, sep=","):
    freq, H = truth
    mag_name, phase_name, mag, phase, _, _ = MAG_PHASE[case]
    first = "phase" if case.startswith("phase-first") else "mag"
    header, cols = ["Frequency [Hz]"], []
    for k in range(H.shape[0]):
        pair = [(mag_name.format(k=k + 1), mag(H[k])), (phase_name.format(k=k + 1), phase(H[k]))]
        for name, values in (pair if first == "mag" else pair[::-1]):
            header.append(name)
            cols.append(values)
    rows = [[_r(f)] + [_r(c[i]) for c in cols] for i, f in enumerate(freq)]
    return _write(path, header, rows, sep=sep)


@pytest.mark.parametrize("case", list(MAG_PHASE))
def test_magnitude_and_phase_columns(tmp_path, truth, case):
    freq, H = truth
    fs = io.read_frf(_mag_phase_file(tmp_path / f"{case}.csv", truth, case))
    *_, labels, note = MAG_PHASE[case]
    assert np.array_equal(fs.freq, freq)
    assert _rel_error(fs.frf, H) <= REL
    assert fs.labels == labels
    notes = _other_notes(fs.meta.get("notes", []))
    if note is None:
        assert notes == []
    else:
        assert len(notes) == 1 and notes[0].startswith(note), notes
        assert notes[0].endswith("give the unit in the header ('{0} [deg]' or '{0} [rad]') to "
                                 "read it otherwise".format(note.split("'")[1]))


def test_one_point_of_magnitude_and_phase_with_blanks_in_the_header(tmp_path, truth):
    """"|H| , phase": one FRF labelled H, the phase in degrees by its values."""
    freq, H = truth
    rows = [[_r(f), _r(abs(H[0, i])), _r(_deg(H[0, i]))] for i, f in enumerate(freq)]
    fs = io.read_frf(_write(tmp_path / "one.csv", ["f", "|H| ", " phase"], rows))
    assert _rel_error(fs.frf, H[:1]) <= REL
    assert fs.labels == ("H",)
    assert fs.meta["notes"][0].startswith("phase column 'phase' with no unit: read in degrees")


def test_without_a_header_columns_are_real_and_imaginary_parts(tmp_path):
    """No header: no guessing magnitude/phase from the numbers; the pairs are re/im."""
    path = _write(tmp_path / "plain.csv", None, [["100", "0.5", "90"], ["200", "0.25", "-45"]])
    fs = io.read_frf(path)
    assert np.array_equal(fs.frf, [[0.5 + 90j, 0.25 - 45j]])
    assert fs.meta == {"notes": [_unit_note(path)], "warnings": [_freq_warning(
        path, "column 1 (no header)", "100 to 200", NO_HEADER_HOW, "f [Hz]")]}


# ------------------------------------------------------------------------------ fit-frf end to end
def test_fit_frf_of_a_db_magnitude_and_degree_phase_file(tmp_path, truth):
    path = _mag_phase_file(tmp_path / "db.csv", truth, "dB-deg")
    r = CliRunner().invoke(cli, ["fit-frf", str(path), "--json"], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    f = np.array([m["freq_hz"] for m in out["modes"]])
    want = np.array([m[0] for m in MODES])
    assert f.shape == want.shape
    assert np.max(np.abs(f / want - 1)) < 1e-4          # measured ~1e-15 (noise-free)
    zeta = np.array([m["damping_ratio"] for m in out["modes"]])
    assert np.allclose(zeta, [m[1] for m in MODES], rtol=1e-3)
    assert out["points"] == ["H1", "H2", "H3"]
    assert out["notes"] == [_unit_note(path)]
    assert out["units"] is None and out["modal_constants_unit"] is None


def test_fit_frf_says_which_phase_unit_it_assumed(tmp_path, truth):
    path = _mag_phase_file(tmp_path / "nounit.csv", truth, "no-unit-deg")
    runner = CliRunner()
    r = runner.invoke(cli, ["fit-frf", str(path), "--band", "80:300"], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    assert ("note: phase columns 'phase1', 'phase2', 'phase3' with no unit: read in degrees: "
            "it jumps by 359.9") in r.stdout
    r = runner.invoke(cli, ["fit-frf", str(path), "--band", "80:300", "--json"],
                      catch_exceptions=False)
    out = json.loads(r.stdout)
    assert out["notes"][0].startswith("phase columns 'phase1', 'phase2', 'phase3' with no unit")
    assert np.allclose([m["freq_hz"] for m in out["modes"]], [105.3, 236.8], rtol=1e-4)


# ------------------------------------------------------------------------------ errors
EXPECTED = ("expected the frequency then a magnitude and a phase column per FRF (magnitude: "
            "mag, magnitude, abs, amp, amplitude, modulus or |H| in its name, linear or [dB]; "
            "phase: phase, phi, arg, angle, [deg] or [rad])")


@pytest.mark.parametrize("text, where", [
    ("freq,H1,H2\n1,(1+2j),(3+4j)\n2,(1+2j),(3+4k)\n",
     "line 3, column 3 ('H2'): '(3+4k)' is neither a number nor a complex number (a+bj, a+bi, "
     "(a+bj))"),
    ("1, 1.5+2i, 3+4ii\n2, 1+2i, 3+4i\n",
     "line 1, column 3 (no header): '3+4ii' is neither a number nor a complex number (a+bj, "
     "a+bi, (a+bj))"),
    ("f;H1\n1;1,5+2,5i\n2;1,5+2.5,i\n",
     "line 3, column 2 ('H1'): '1,5+2.5,i' is neither a number nor a complex number (a+bj, "
     "a+bi, (a+bj))"),
], ids=["numpy-header", "matlab-first-line", "decimal-comma"])
def test_a_bad_complex_cell_names_its_line_column_and_header(tmp_path, text, where):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(FrfError) as info:
        io.read_frf(p)
    assert str(info.value) == f"{p}: {where}"


@pytest.mark.parametrize("header, problem", [
    ("f,H1_mag,H1_phase,H2_mag", "column 4 ('H2_mag'), a magnitude, has no phase column after "
                                 "it"),
    ("f,H1_mag,H2_mag,H1_phase,H2_phase", "column 2 ('H1_mag'), a magnitude, is followed by "
                                          "column 3 ('H2_mag'), another magnitude, not its "
                                          "phase"),
    ("f,H1_mag,H1_re,H2_mag,H2_phase", "column 2 ('H1_mag'), a magnitude, is followed by "
                                       "column 3 ('H1_re'), not its phase"),
    ("f,H1,H1_phase", "column 2 ('H1') is neither a magnitude nor a phase"),
], ids=["mag-without-phase", "odd-pairing", "mixed-with-re", "unnamed"])
def test_magnitude_and_phase_columns_that_do_not_pair(tmp_path, header, problem):
    n = header.count(",")
    p = tmp_path / "pairs.csv"
    p.write_text(header + "\n" + "\n".join(",".join([str(i)] + ["0.5"] * n) for i in (1, 2, 3)))
    with pytest.raises(FrfError) as info:
        io.read_frf(p)
    found = ", ".join(repr(h) for h in header.split(","))
    assert str(info.value) == f"{p}: header {found}: {problem}; {EXPECTED}"


@pytest.mark.parametrize("text, where", [
    # a real/imaginary file with one stray complex cell is not read as complex columns
    ("freq,p1_re,p1_im\n1,0.5,0.1\n2,1+2j,0.2\n",
     "column 3 ('p1_im') holds no complex number where column 2 ('p1_re') does (line 3: "
     "'1+2j'); expected the frequency, then a real and an imaginary column per FRF, or one "
     "column of complex numbers per FRF (a+bj, a+bi), or a magnitude and a phase column per "
     "FRF named in the header, not both"),
    # blank-separated: "1.2 -4.5i" is two cells (only a lone sign joins "a - bi")
    ("1 1.2 -4.5i\n2 1.3 -4.4i\n",
     "column 2 (no header) holds no complex number where column 3 (no header) does (line 1: "
     "'-4.5i'); expected the frequency, then a real and an imaginary column per FRF, or one "
     "column of complex numbers per FRF (a+bj, a+bi), or a magnitude and a phase column per "
     "FRF named in the header, not both"),
    ("f,H\n1,(1+0j)\n(2+1e-9j),(1+1j)\n",
     "line 3, column 1 ('f'): the frequency (2+1e-09j) has an imaginary part"),
    ("f,|H|,phase [deg]\n1,0.5,10\n2,-0.5,20\n",
     "line 3, column 2 ('|H|'): magnitude -0.5 is negative (a magnitude in dB says so in its "
     "header: '|H| [dB]')"),
    ("f,|H|,phase [grad]\n1,0.5,10\n2,0.5,20\n",
     "column 3 ('phase [grad]'): phase unit 'grad' is not one laminid reads (deg, °, rad)"),
    ("f,|H| [dBV],phase [deg]\n1,0.5,10\n2,0.5,20\n",
     "column 2 ('|H| [dBV]'): a magnitude in 'dBV'; laminid reads dB re 1 of the FRF's unit "
     "('... [dB]') or a linear magnitude"),
    ("f,H1_mag,H1_phase\n1,(1+2j),3\n2,(1+2j),4\n",
     "the header names magnitude and phase columns ('f', 'H1_mag', 'H1_phase') but the cells "
     "hold complex numbers (column 2 ('H1_mag'), line 2: '(1+2j)'); expected the frequency, "
     "then a real and an imaginary column per FRF, or one column of complex numbers per FRF "
     "(a+bj, a+bi), or a magnitude and a phase column per FRF named in the header"),
], ids=["re-im-with-a-complex-cell", "blank-separated-not-joined", "complex-frequency",
        "negative-magnitude", "phase-unit", "magnitude-unit", "complex-under-mag-header"])
def test_layouts_that_do_not_fit(tmp_path, text, where):
    p = tmp_path / "bad.csv"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(FrfError) as info:
        io.read_frf(p)
    assert str(info.value) == f"{p}: {where}"


def test_export_of_a_csv_says_which_phase_unit_it_assumed(tmp_path, truth):
    """export (CSV to UFF 58) prints the reader's note as fit-frf does, and writes the FRFs."""
    freq, H = truth
    path = _mag_phase_file(tmp_path / "nounit.csv", truth, "no-unit-rad")
    out = tmp_path / "out.uff"
    r = CliRunner().invoke(cli, ["export", str(path), "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    assert ("note: phase columns 'H1_phi', 'H2_phi', 'H3_phi' with no unit: read in radians"
            in r.stdout)
    back = io.read_frf(out)
    assert _rel_error(back.frf, H) <= REL


def test_a_phase_without_unit_that_degrees_and_radians_both_explain_is_refused(tmp_path,
                                                                              truth):
    """A driving point's phase in degrees stays within 0..180 (never wraps), and so does a
    phase in radians unwrapped over a few resonances: without a unit in the header the two
    cannot be told apart, and the file is refused with the way to say it; over 180 with no
    jump it is degrees (radians that far need 57 resonances)."""
    freq, H = truth
    driving = np.abs(_deg(H[0]))                   # a phase between 0 and 180, no jump > 180
    assert driving.max() > 90 and np.abs(np.diff(driving)).max() < 180
    rows = [[_r(f), _r(abs(H[0, i])), _r(driving[i])] for i, f in enumerate(freq)]
    path = _write(tmp_path / "driving.csv", ["f", "H1_mag", "H1_phase"], rows)
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value) == (
        f"{path}: phase column 'H1_phase' with no unit: |phase| reaches {driving.max():.6g} "
        "without wrapping, which degrees (a phase that never crosses +-180, as a driving "
        "point's) and radians (unwrapped over a few resonances) both give; give the unit in "
        "the header ('H1_phase [deg]' or 'H1_phase [rad]')")
    # the same with its unit: read
    path = _write(tmp_path / "driving-deg.csv", ["f", "H1_mag", "H1_phase [deg]"], rows)
    fs = io.read_frf(path)
    assert _rel_error(fs.frf, np.abs(H[0]) * np.exp(1j * np.radians(driving))[None]) <= REL
    # unwrapped degrees beyond 180: degrees
    unwrapped = np.degrees(np.unwrap(np.angle(H[1]))) - 360.0
    assert unwrapped.min() < -180 and np.abs(np.diff(unwrapped)).max() < 180
    rows = [[_r(f), _r(abs(H[1, i])), _r(unwrapped[i])] for i, f in enumerate(freq)]
    fs = io.read_frf(_write(tmp_path / "unwrapped.csv", ["f", "H_mag", "H_phase"], rows))
    assert _rel_error(fs.frf, H[1:2]) <= REL
    assert "read in degrees: |phase| reaches" in fs.meta["notes"][0]


def test_a_row_index_in_the_first_column_is_refused(tmp_path, truth):
    """pandas' DataFrame.to_csv writes its row index first under an empty name: read as the
    frequency it would put every mode at a line number (increasing, so no other check sees
    it)."""
    freq, H = truth
    rows = [[str(i), _r(f), _r(H[0, i].real), _r(H[0, i].imag)] for i, f in enumerate(freq)]
    path = _write(tmp_path / "pandas.csv", ["", "freq_Hz", "H1_re", "H1_im"], rows)
    with pytest.raises(FrfError) as info:
        io.read_frf(path)
    assert str(info.value) == (f"{path}: column 1 holds 0, 1, 2 ... (line numbers): a "
                               "row index, as pandas' to_csv writes one, not the frequency; "
                               "write the file with index=False or delete that column")
    # a frequency column that starts at 0 Hz with a 1 Hz spacing, under its own name: read
    rows = [[str(i), _r(H[0, i].real), _r(H[0, i].imag)] for i in range(freq.size)]
    fs = io.read_frf(_write(tmp_path / "one-hz.csv", ["f [Hz]", "H1_re", "H1_im"], rows))
    assert fs.freq[1] - fs.freq[0] == 1.0


# -------------------------------------------------------------------- encodings of spreadsheets
@pytest.mark.parametrize("encoding", ["cp1252", "utf-16"])
def test_a_spreadsheets_windows_1252_or_utf16_export_is_read(tmp_path, truth, encoding):
    # Excel's "CSV" on Windows writes "Phase [°]" in Windows-1252 (byte 0xB0), its "Unicode
    # Text" in UTF-16 with a BOM: both were refused as "not a text (CSV) file; it looks like
    # binary data, not text"
    freq, H = truth
    header = ["f [Hz]"] + [name for k in range(H.shape[0])
                           for name in (f"H{k + 1} Magnitude", f"H{k + 1} Phase [°]")]
    rows = [[_r(f)] + [_r(v) for k in range(H.shape[0])
                       for v in (abs(H[k, i]), np.degrees(np.angle(H[k, i])))]
            for i, f in enumerate(freq)]
    sep = "\t" if encoding == "utf-16" else ";"
    path = tmp_path / "excel.csv"
    path.write_bytes("\r\n".join([sep.join(header)] + [sep.join(r) for r in rows])
                     .encode(encoding))
    fs = io.read_frf(path)
    assert np.array_equal(fs.freq, freq) and _rel_error(fs.frf, H) <= REL
    assert fs.labels == ("H1", "H2", "H3")
    said = [n for n in _other_notes(fs.meta.get("notes", [])) if "Windows-1252" in n]
    assert len(said) == (encoding == "cp1252"), said


def test_binary_data_named_csv_is_still_refused_as_binary(tmp_path):
    path = tmp_path / "data.csv"
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(FrfError, match=r"not a text \(CSV\) file; it looks like binary data"):
        io.read_frf(path)


# ---------------------------------------------------------------- lines above the header
@pytest.mark.parametrize("sep", [",", ";"])
def test_an_exports_title_and_settings_above_the_header_are_skipped_with_a_note(tmp_path,
                                                                                 truth, sep):
    # an analyser's export writes its title and date above the column names; the first of
    # them was taken for the header: "line 2, column 1 ('Title:'): 'Date:' is not a number"
    freq, H = truth
    header = ["f [Hz]"] + [n for k in range(3) for n in (f"H{k + 1}_re", f"H{k + 1}_im")]
    rows = [[_r(f)] + [_r(v) for k in range(3) for v in (H[k, i].real, H[k, i].imag)]
            for i, f in enumerate(freq)]
    path = tmp_path / "export.csv"
    preamble = "Title: plate S1\nDate: 07.12.2026\n" if sep == "," else "Title;plate\nDate;7.12.\n"
    path.write_text(preamble + "\n".join(sep.join(r) for r in [header] + rows) + "\n")
    fs = io.read_frf(path)
    assert np.array_equal(fs.freq, freq) and _rel_error(fs.frf, H) <= REL
    assert fs.labels == ("H1", "H2", "H3")
    notes = _other_notes(fs.meta.get("notes", []))
    assert len(notes) == 1 and notes[0].startswith(f"{path}: lines 1-2 above the header "
                                                   "skipped ('Title"), notes


def test_a_bad_first_data_line_below_the_header_is_still_named(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("f [Hz],H1_re,H1_im\nx,1,2\n101,3,4\n102,5,6\n")
    with pytest.raises(FrfError, match=r"line 2, column 1 \('f \[Hz\]'\): 'x' is not a number"):
        io.read_frf(path)


# ---------------------------------------------------------------- the FRF unit in the header
@pytest.mark.parametrize("layout", ["re-im", "complex", "mag-phase"])
def test_the_frf_unit_in_the_columns_headers_is_read(tmp_path, truth, layout):
    # "H1 real [g/N]", a spreadsheet's way to state the unit, was read as "not stated" (and
    # the point labelled 'H1 real [g/N]')
    freq, H = truth
    P = H.shape[0]
    if layout == "re-im":
        header = [n for k in range(P) for n in (f"H{k + 1} real [g/N]", f"H{k + 1} imag [g/N]")]
        cols = [c for k in range(P) for c in (H[k].real, H[k].imag)]
    elif layout == "complex":
        header = [f"H{k + 1} (g/N)" for k in range(P)]
        cols = list(H)
    else:
        header = [n for k in range(P)
                  for n in (f"H{k + 1} Magnitude (g/N)", f"H{k + 1} Phase (°)")]
        cols = [c for k in range(P) for c in (np.abs(H[k]), np.degrees(np.angle(H[k])))]
    cell = (lambda v: f"{float(v.real)!r}{v.imag:+.17g}i") if layout == "complex" else _r
    rows = [[_r(f)] + [cell(c[i]) for c in cols] for i, f in enumerate(freq)]
    fs = io.read_frf(_write(tmp_path / "unit.csv", ["f [Hz]"] + header, rows))
    assert fs.units == "g/N" and "point_units" not in fs.meta
    assert fs.labels == ("H1", "H2", "H3")
    assert _rel_error(fs.frf, H) <= REL
    assert not any("not stated" in n for n in fs.meta.get("notes", []))


def test_points_in_different_units_in_the_header_are_each_their_own(tmp_path, truth):
    freq, H = truth
    units = ("g/N", "m/s/N", "g/N")
    header = ["f [Hz]"] + [n for k, u in enumerate(units) for n in (f"H{k + 1}_re [{u}]",
                                                                    f"H{k + 1}_im [{u}]")]
    rows = [[_r(f)] + [_r(v) for k in range(3) for v in (H[k, i].real, H[k, i].imag)]
            for i, f in enumerate(freq)]
    fs = io.read_frf(_write(tmp_path / "mixed.csv", header, rows))
    assert fs.units == "g/N" and fs.meta["point_units"] == list(units)
    # a phase's or a dB magnitude's bracket is no FRF unit
    header = ["f [Hz]"] + [n for k in range(3) for n in (f"H{k + 1} [dB]", f"H{k + 1} [deg]")]
    rows = [[_r(f)] + [_r(v) for k in range(3) for v in (20 * np.log10(abs(H[k, i])),
                                                          np.degrees(np.angle(H[k, i])))]
            for i, f in enumerate(freq)]
    assert io.read_frf(_write(tmp_path / "db.csv", header, rows)).units is None


@pytest.mark.parametrize("style", ["quoted", "trailing-separator"])
def test_quoted_cells_and_a_trailing_separator_are_read(tmp_path, truth, style):
    # '"0.5"' (pandas' QUOTE_ALL, LabVIEW) was "not a number"; "0,5;1,2;" (a spreadsheet's
    # trailing empty column) was "column 8: empty, where a number is expected"
    freq, H = truth
    header = ["f [Hz]"] + [n for k in range(3) for n in (f"H{k + 1}_re", f"H{k + 1}_im")]
    rows = [[_r(f)] + [_r(v) for k in range(3) for v in (H[k, i].real, H[k, i].imag)]
            for i, f in enumerate(freq)]
    if style == "quoted":
        text = "\n".join(",".join(f'"{c}"' for c in r) for r in [header] + rows)
    else:
        text = "\n".join(";".join(r) + ";" for r in [header] + rows)
    path = tmp_path / "lab.csv"
    path.write_text(text + "\n")
    fs = io.read_frf(path)
    assert np.array_equal(fs.freq, freq) and _rel_error(fs.frf, H) <= REL
    assert fs.labels == ("H1", "H2", "H3")
    path.write_text(text.replace(rows[5][3], "", 1) + "\n")   # an empty cell is still named
    with pytest.raises(FrfError, match="line 7, column 4 .*empty, where a number is expected"):
        io.read_frf(path)
