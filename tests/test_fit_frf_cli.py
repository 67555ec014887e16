"""``laminid fit-frf`` end to end through click's CliRunner."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.frf import io
from laminid_cli.frf.store import FrfSet
from tests.frf_synth import plate_case

# a valid specimen (--into refuses to edit an invalid one): S1.1 with its own measured entry
_S11 = Path(__file__).parent.parent / "specimens" / "example1" / "S1.1.yaml"
SPEC = _S11.read_text().split("measured:")[0].replace("name: S1.1", "name: P1   # keep me") + """\
measured:
  frequencies: [1.0, 2.0]   # Hz
  # frf_file: plate.frf.h5
"""


def run(args):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


@pytest.fixture(scope="module")
def case():
    return plate_case(noise=0.02, seed=8)


@pytest.fixture
def h5(tmp_path, case):
    return io.write_frf(tmp_path / "plate.frf.h5",
                        FrfSet(freq=case.freq, frf=case.frf, units="Pa/N"))


def test_table(h5, case):
    r = run(["fit-frf", str(h5)])
    assert r.exit_code == 0, r.output
    assert "freq (Hz)" in r.output and "zeta (%)" in r.output and "stable orders" in r.output
    rows = [ln.split() for ln in r.output.splitlines() if ln.strip()[:1].isdigit()]
    assert len(rows) == 10
    assert np.allclose([float(row[1]) for row in rows], case.freq_hz, rtol=1e-3)


def test_json_bands_and_modes(h5, case):
    r = run(["fit-frf", str(h5), "--json", "--band", "100:300", "--band", "300:500",
             "--modes", "4"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert [m["mode"] for m in out["modes"]] == [1, 2, 3, 4]
    f = [m["freq_hz"] for m in out["modes"]]
    assert np.allclose(f, case.freq_hz[:4], rtol=1e-3)
    assert all(m["sigma_hz"] > 0 and len(m["modal_constants"]) == 5 for m in out["modes"])
    assert out["bands_hz"] == [[100.0, 300.0], [300.0, 500.0]]


def test_into_and_plot(tmp_path, h5, case):
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    png = tmp_path / "fit.png"
    r = run(["fit-frf", str(h5), "--into", str(spec), "--plot", str(png)])
    assert r.exit_code == 0, r.output
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    text = spec.read_text()
    assert "# keep me" in text and "# frf_file: plate.frf.h5" in text
    measured = yaml.safe_load(text)["measured"]
    assert np.allclose(measured["frequencies"], case.freq_hz, rtol=1e-3)
    assert len(measured["sigma"]) == 10 and min(measured["sigma"]) > 0
    # damping ratios and their sigmas too (RFP of the synthetic case, 6 significant digits)
    assert np.allclose(measured["damping"], case.damping_ratio, rtol=0.05)
    assert all(s >= 0.0199 * z for s, z in zip(measured["damping_sigma"], measured["damping"]))
    assert (tmp_path / "p.yaml.bak").read_text() == SPEC
    # the plot is not overwritten without --force
    r = run(["fit-frf", str(h5), "--plot", str(png)])
    assert r.exit_code == 2 and "file exists" in r.output
    assert "another name with --plot" in r.output and "with -o" not in r.output
    assert run(["fit-frf", str(h5), "--plot", str(png), "--force"]).exit_code == 0


def test_pdf_plot(tmp_path, h5):
    pdf = tmp_path / "fit.pdf"
    assert run(["fit-frf", str(h5), "--band", "100:300", "--plot", str(pdf)]).exit_code == 0
    assert pdf.read_bytes()[:4] == b"%PDF"


@pytest.mark.parametrize("args, message", [
    (["--band", "300:200"], "Invalid value for '--band'"),
    (["--band", "a:b"], "expected LO:HI"),
    (["--band", "120:123"], "holds 4 frequency lines"),
    (["--band", "100:300", "--modes", "5"], "asked for 5 modes but the band(s) 100:300 Hz"),
    (["--modes", "0"], "Invalid value for '--modes'"),
    (["--plot", "fit.gif"], "plot file type '.gif' not supported"),
])
def test_usage_and_fit_errors_exit_2_with_a_message(h5, args, message):
    r = CliRunner().invoke(cli, ["fit-frf", str(h5)] + args)
    assert r.exit_code == 2, r.output
    assert message in r.output
    assert "Traceback" not in r.output


def test_bad_files_exit_2(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("1,1,0\n2,nan,0\n3,1,0\n")
    r = CliRunner().invoke(cli, ["fit-frf", str(bad)])
    assert r.exit_code == 2 and "NaN/inf" in r.output
    bad.write_text("1,1,0\n1,2,0\n")
    r = CliRunner().invoke(cli, ["fit-frf", str(bad)])
    assert r.exit_code == 2 and "not strictly increasing" in r.output
    r = CliRunner().invoke(cli, ["fit-frf", str(tmp_path / "none.h5")])
    assert r.exit_code == 2 and "file not found" in r.output
    r = CliRunner().invoke(cli, ["fit-frf", str(tmp_path / "x.doc")])
    assert r.exit_code == 2 and "unknown FRF file type" in r.output


def test_a_specimen_given_for_the_frfs_is_named_as_such(tmp_path):
    """fit-frf plate.yaml (the specimen where its FRF file is meant) said "unknown FRF file
    type '.yaml'; expected one of .csv, .h5, ...", as if YAML were a format it lacked."""
    spec = tmp_path / "plate.yaml"
    spec.write_text("name: p\n")
    r = CliRunner().invoke(cli, ["fit-frf", str(spec)])
    assert r.exit_code == 2
    assert r.stderr == (f"laminid: error: {spec}: a specimen file (YAML), not FRFs; give the "
                        "FRF file (laminid HDF5 .frf.h5, UFF 58 .uff/.unv, CSV): 'laminid "
                        f"fit-frf FRFS --into {spec}' writes their frequencies into it\n")


def test_into_missing_or_broken_specimen_is_untouched(tmp_path, h5):
    r = CliRunner().invoke(cli, ["fit-frf", str(h5), "--into", str(tmp_path / "no.yaml")])
    assert r.exit_code == 2 and "file not found" in r.output
    spec = tmp_path / "p.yaml"
    for text, message in [("measured: [1, 2]\n", "missing required key 'geometry'"),
                          (SPEC.split("measured:")[0] + "measured: [1, 2]\n",
                           "field 'measured': expected a mapping")]:
        spec.write_text(text)
        r = CliRunner().invoke(cli, ["fit-frf", str(h5), "--into", str(spec)])
        assert r.exit_code == 2 and message in r.output and str(spec) in r.output
        assert spec.read_text() == text
        assert not (tmp_path / "p.yaml.bak").exists()


def test_uff_and_csv_inputs_give_the_same_table(tmp_path, case):
    """The same FRFs through an ASCII UFF 58 and a CSV give the same modes: within 5 % of
    each mode's own standard deviation (a 12-digit ASCII field moves the 2 %-noise fit's
    weakest mode, 1130.69 Hz, by up to 1.7e-3 Hz with numpy 2.5, against its 0.068 Hz; rtol
    1e-6 held with numpy 2.4 and failed there), and to 1e-6 relative for the others."""
    fs = FrfSet(freq=case.freq, frf=case.frf)
    outs, stds = [], []
    for name in ("p.uff", "p.csv"):
        path = io.write_frf(tmp_path / name, fs)
        r = run(["fit-frf", str(path), "--json"])
        assert r.exit_code == 0, r.output
        modes = json.loads(r.output)["modes"]
        outs.append(np.array([m["freq_hz"] for m in modes]))
        stds.append(np.array([m["freq_std_hz"] for m in modes]))
    assert outs[0].shape == outs[1].shape == (10,)
    assert np.all(np.abs(outs[0] - outs[1]) <= 0.05 * np.minimum(*stds))
    assert np.sum(~np.isclose(outs[0], outs[1], rtol=1e-6)) <= 1


def test_into_a_real_specimen_keeps_it_loadable(tmp_path, h5, case):
    from pathlib import Path

    from laminid_cli import specimen

    src = Path(__file__).resolve().parents[1] / "specimens" / "example1" / "S1.1.yaml"
    spec = tmp_path / "S1.1.yaml"
    spec.write_text(src.read_text())
    r = run(["fit-frf", str(h5), "--into", str(spec)])
    assert r.exit_code == 0, r.output
    s = specimen.read_specimen(spec)
    assert np.allclose(s.measured.freq, case.freq_hz, rtol=1e-3)
    assert np.all(s.measured.sigma > 0)
    assert np.allclose(s.measured.damping, case.damping_ratio, rtol=0.05)
    assert np.all(s.measured.damping_sigma > 0)
    before = yaml.safe_load(src.read_text())
    after = yaml.safe_load(spec.read_text())
    before.pop("measured"), after.pop("measured")
    assert before == after
    assert spec.read_text().splitlines()[:9] == src.read_text().splitlines()[:9]  # comments


def test_sigma_is_a_measurement_uncertainty_and_says_what_dominated(h5, case):
    """sigma = max(sqrt(spread^2 + (df/sqrt 12)^2 + window^2), sigma_rel f), per mode."""
    from laminid_cli.frf import rfp

    fit = rfp.find_modes(case.freq, case.frf)
    df = float(np.median(np.diff(case.freq)))
    m = rfp.measurement_sigma(fit, case.freq, sigma_rel=0.002)
    f = fit.freq_hz
    assert np.allclose(m.terms["resolution"], df / np.sqrt(12))
    assert np.allclose(m.terms["floor"], 0.002 * f) and np.all(m.terms["window"] == 0)
    expect = np.maximum(np.hypot(fit.freq_std_hz, df / np.sqrt(12)), 0.002 * f)
    assert np.allclose(m.sigma_hz, expect, rtol=1e-12)
    assert np.all(m.sigma_hz >= 0.002 * f) and np.all(m.sigma_hz > fit.freq_std_hz)
    # a tiny floor: the FRF's own limits dominate
    tiny = rfp.measurement_sigma(fit, case.freq, sigma_rel=1e-7)
    assert set(tiny.dominant) <= {"rfp spread", "resolution"}
    assert np.allclose(tiny.sigma_hz, np.hypot(fit.freq_std_hz, df / np.sqrt(12)))
    # the CLI: a 'from' column, JSON terms, and --into records the rule for identify
    r = run(["fit-frf", str(h5), "--json", "--sigma-rel", "0.002"])
    out = json.loads(r.output)
    assert [mo["sigma_dominant"] for mo in out["modes"]] == list(m.dominant)
    assert out["modes"][0]["sigma_terms_hz"]["resolution"] == pytest.approx(df / np.sqrt(12))
    r = run(["fit-frf", str(h5)])
    assert "from" in r.output and "dominated by" in r.output


def test_exponential_window_shift_of_the_natural_frequency():
    """A pole at 100 Hz, zeta 3 %, tau 0.1 s: |pole| falls from 100 Hz to
    sqrt(omega_d^2 + (zeta omega - 10)^2) / 2 pi once the window's 1/tau is removed."""
    from types import SimpleNamespace

    from laminid_cli.frf import rfp

    fit = SimpleNamespace(modes=[1], freq_hz=np.array([100.0]), freq_std_hz=np.array([0.0]),
                          damping_ratio=np.array([0.03]))
    m = rfp.measurement_sigma(fit, np.arange(0, 200, 0.01), sigma_rel=1e-6, exp_window_s=0.1)
    w = 2 * np.pi * 100.0
    wd2 = w**2 * (1 - 0.03**2)
    expected = (w - np.sqrt(wd2 + (0.03 * w - 10.0) ** 2)) / (2 * np.pi)     # 0.0351 Hz
    assert m.terms["window"][0] == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(0.0351, abs=2e-4) and m.dominant == ("window",)


def test_resolution_on_an_uneven_grid_is_the_spacing_at_each_mode():
    """Another tool's logarithmic grid (10 to 1000 Hz, 401 lines, ratio 10^(1/200)): the
    resolution term of a mode is the spacing of the two lines around it, not the median
    spacing (that of the grid's middle, ~100 Hz: 5x too large at 20 Hz, 9x too small at
    900 Hz)."""
    from types import SimpleNamespace

    from laminid_cli.frf import rfp

    grid = 10.0 * 10 ** (np.arange(401) / 200)
    f = np.array([20.0, 100.0, 900.0])
    k = np.searchsorted(grid, f)                        # the first line above each mode
    by_hand = grid[k] - grid[k - 1]
    assert rfp.line_spacing(grid, f) == pytest.approx(by_hand, rel=1e-15)
    assert by_hand[2] / by_hand[0] == pytest.approx(45, rel=0.05)   # ~ 900 / 20
    fit = SimpleNamespace(modes=[1, 2, 3], freq_hz=f, freq_std_hz=np.zeros(3),
                          damping_ratio=np.full(3, 0.01))
    m = rfp.measurement_sigma(fit, grid, sigma_rel=1e-9)
    assert m.terms["resolution"] == pytest.approx(by_hand / np.sqrt(12), rel=1e-15)
    # at the ends: the first and the last interval
    assert rfp.line_spacing(grid, [5.0, 2000.0]) == pytest.approx(
        [grid[1] - grid[0], grid[-1] - grid[-2]], rel=1e-15)
    # an even grid: its line spacing everywhere
    even = np.arange(0.0, 200.0, 0.25)
    assert rfp.line_spacing(even, [0.1, 57.3, 199.9]) == pytest.approx(0.25, rel=1e-12)


def test_into_records_the_sigma_rule_and_identify_reports_it(tmp_path, h5, case):
    from pathlib import Path

    from laminid_cli.uncertainty import frequency_sigma
    from laminid_cli.specimen import read_specimen

    src = Path(__file__).resolve().parents[1] / "specimens" / "example1" / "S1.1.yaml"
    spec = tmp_path / "S1.1.yaml"
    spec.write_text(src.read_text())
    assert run(["fit-frf", str(h5), "--into", str(spec)]).exit_code == 0
    measured = yaml.safe_load(spec.read_text())["measured"]
    assert measured["sigma_source"].startswith("plate.frf.h5: fit-frf: sqrt(RFP spread^2")
    s = read_specimen(spec)
    summary = frequency_sigma(s.measured).summary
    assert summary.startswith("the specimen file's measured.sigma (made by: plate.frf.h5: "
                              "fit-frf:")
    assert "dominated by" in summary
    # a second fit without a sigma rule (library call) drops the stale description
    from laminid_cli.frf.into import write_measured

    write_measured(spec, list(s.measured.freq), list(s.measured.sigma))
    assert "sigma_source" not in yaml.safe_load(spec.read_text())["measured"]


def test_into_weights_follow_their_modes_when_the_mode_count_changes(tmp_path, h5, case):
    """--modes 10 into a file of 13 frequencies whose weights hold a 0 (mode 3) and a 0.5
    (mode 12, beyond the fit): the 0 stays on its mode, the 0.5 cannot follow and is named."""
    spec = tmp_path / "p.yaml"
    freqs = [float(f) for f in case.freq_hz] + [1500.0, 1550.0, 1590.0]
    weights = [1, 1, 0, 1, 1, 1, 1, 1, 1, 1, 1, 0.5, 1]
    spec.write_text(SPEC.replace("frequencies: [1.0, 2.0]   # Hz",
                                 f"frequencies: {freqs}   # Hz\n  weights: {weights}   # mine"))
    r = run(["fit-frf", str(h5), "--into", str(spec), "--modes", "10"])
    assert r.exit_code == 0, r.output
    measured = yaml.safe_load(spec.read_text())["measured"]
    assert measured["weights"] == [1, 1, 0, 1, 1, 1, 1, 1, 1, 1]
    assert "# mine" in spec.read_text()
    assert ("weights: the weight 0.5 of the mode at 1550 Hz was dropped: no fitted mode within "
            "1 % of it") in r.output
    # the previous version (13 frequencies, its weights) is in the backup
    assert yaml.safe_load((tmp_path / "p.yaml.bak").read_text())["measured"]["weights"] == weights


def test_into_weights_follow_by_frequency_when_a_mode_is_missing():
    """Same count is not same modes: a mode lost in the middle does not shift the weights."""
    from laminid_cli.frf.into import carry_weights

    w, notes = carry_weights([100.0, 200.0, 300.0, 400.0], [1, 0, 1, 0.5],
                             [100.3, 300.5, 400.2, 505.0])
    assert w == [1, 1, 0.5, 1]
    assert notes == ["the weight 0 of the mode at 200 Hz was dropped: no fitted mode within "
                     "1 % of it", "weight 1 for the mode(s) at 505 Hz: no mode of the file "
                     "within 1 % had a weight"]
    # one to one, nearest first: two new modes near one old one
    w, notes = carry_weights([100.0, None], [0, 0], [99.5, 100.1])
    assert w == [1, 0] and notes == ["weight 1 for the mode(s) at 99.5 Hz: no mode of the file "
                                     "within 1 % had a weight"]
    # all weights 1 and nothing dropped: nothing to say
    assert carry_weights([100.0, 200.0], [1, 1], [100.0, 150.0, None]) == ([1, 1, 0], [])


def test_into_never_overwrites_a_backup(tmp_path, h5):
    """Each --into keeps the text it replaces in a backup of its own (SPEC.bak, SPEC.bak1...);
    a run that would back up exactly the newest backup's text makes none, and says where. A
    run that would write exactly what the file holds (the same FRFs fitted into it again)
    writes nothing: it rewrote the file as it was, with a backup of that same text."""
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    r = run(["fit-frf", str(h5), "--into", str(spec)])
    assert f"(previous version in {tmp_path / 'p.yaml.bak'})" in r.output
    texts = [SPEC]
    for k, word in ((1, "one"), (2, "two")):       # edited by hand between two fits
        spec.write_text(SPEC.replace("# keep me", f"# keep me {word}"))
        texts.append(spec.read_text())
        r = run(["fit-frf", str(h5), "--into", str(spec), "--json"])
        assert json.loads(r.output)["backup"] == \
            f"previous version in {tmp_path / f'p.yaml.bak{k}'}"
        assert json.loads(r.output)["into_unchanged"] is False
    # the file as the fit left it, backed up by hand: a fit that changes it makes no third copy
    fitted = spec.read_text()
    spec.write_text(SPEC.replace("# keep me", "# keep me two"))
    r = run(["fit-frf", str(h5), "--into", str(spec)])
    assert f"(previous version already in {tmp_path / 'p.yaml.bak2'})" in r.output
    assert spec.read_text() == fitted
    # the same fit again: the file holds it already, nothing is written
    before = spec.stat().st_mtime_ns
    r = run(["fit-frf", str(h5), "--into", str(spec)])
    assert r.exit_code == 0, r.output
    assert r.output.splitlines()[-1].startswith(f"{spec} already holds these ")
    assert r.output.splitlines()[-1].endswith(": left unchanged (no backup made)")
    assert spec.read_text() == fitted and spec.stat().st_mtime_ns == before
    r = run(["fit-frf", str(h5), "--into", str(spec), "--json"])
    assert json.loads(r.output)["into_unchanged"] is True
    assert json.loads(r.output)["backup"] == "unchanged: it held them already; no backup made"
    assert [(tmp_path / n).read_text() for n in ("p.yaml.bak", "p.yaml.bak1", "p.yaml.bak2")] \
        == texts
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "p.yaml", "p.yaml.bak", "p.yaml.bak1", "p.yaml.bak2", "plate.frf.h5"]


def test_into_through_a_symbolic_link_edits_the_file_it_points_to(tmp_path, h5):
    """--into link.yaml (a symbolic link): the file it points to gets the frequencies and its
    backup; the link stays a link."""
    real = tmp_path / "store" / "real.yaml"
    real.parent.mkdir()
    real.write_text(SPEC)
    link = tmp_path / "link.yaml"
    link.symlink_to(real)
    r = run(["fit-frf", str(h5), "--into", str(link)])
    assert r.exit_code == 0, r.output
    assert link.is_symlink() and link.resolve() == real.resolve()
    assert real.read_text() != SPEC and "frequencies:" in real.read_text()
    assert (real.parent / "real.yaml.bak").read_text() == SPEC


def test_into_leaves_every_other_line_byte_for_byte_and_no_stale_comment(tmp_path, h5, case):
    """--into kept the comment of the replaced line ('# Hz, Table 1': the paper's data, now
    beside frequencies fitted from FRFs) and rewrote S1.1's two-line reference.source and a
    'description: |' block onto one line each. Now only the measured entries it writes
    change: the frequencies line says where they came from, and every other line is the
    file's own, in order, byte for byte (line endings too)."""
    text = _S11.read_text().replace(
        "description: IM7/977-2 carbon/epoxy plate [45_3/0_3/-45_3/90_3]s, Araujo et al. 2000, "
        "Example 1\n",
        "description: |\n  IM7/977-2 carbon/epoxy plate\n    [45_3/0_3/-45_3/90_3]s\n\n"
        "  Araujo et al. 2000   # not a comment\n")
    assert "description: |" in text and "    (E1 170 ± 1 GPa" in text
    for newline in ("\n", "\r\n"):
        spec = tmp_path / f"S1.1{len(newline)}.yaml"
        spec.write_bytes(text.replace("\n", newline).encode())
        r = run(["fit-frf", str(h5), "--into", str(spec)])
        assert r.exit_code == 0, r.output
        old = text.split("\n")
        new = spec.read_bytes().decode().split(newline)
        assert all("\r" not in line for line in new)
        k = next(i for i, line in enumerate(old) if line.startswith("  frequencies:"))
        added = len(new) - len(old) + 1
        assert new[:k] == old[:k] and new[k + added:] == old[k + 1:]
        written = new[k:k + added]
        assert [line.split(":")[0] for line in written] == [
            "  frequencies", "  sigma", "  sigma_source", "  damping", "  damping_sigma",
            "  damping_sigma_source"]
        assert "Table 1" not in "".join(written)
        assert written[0].endswith("]   # Hz, laminid fit-frf of plate.frf.h5")
        # the damping line says what its numbers are: 0.008 beside the table's 'zeta (%)
        # 0.800' read as a loss factor as well (identify takes zeta, eta = 2 zeta)
        assert written[3].endswith("]   # viscous damping ratios zeta, fractions (0.008 = "
                                   "0.8 %); loss factor eta = 2 zeta")
        assert all("#" not in line for line in written[1:3] + written[4:])
        measured = yaml.safe_load(spec.read_text())["measured"]
        assert np.allclose(measured["frequencies"], case.freq_hz, rtol=1e-3)
        assert measured["sigma_source"].startswith("plate.frf.h5: ")
        before = yaml.safe_load(text)
        after = yaml.safe_load(spec.read_text())
        assert after["description"] == before["description"] == (
            "IM7/977-2 carbon/epoxy plate\n  [45_3/0_3/-45_3/90_3]s\n\n"
            "Araujo et al. 2000   # not a comment\n")
        before.pop("measured"), after.pop("measured")
        assert before == after


@pytest.mark.parametrize("name, content, looks", [
    ("plate.frf.h5", None, "it looks like an HDF5 file (laminid acquire's FRF file or another "
                           "tool's); read it with --format hdf5 or without --format (its "
                           "suffix .h5 says hdf5)"),
    ("plate.csv", "freq_Hz,1_re,1_im\n1,2,3\n",
     "it looks like text in columns, as a CSV FRF file is (first line 'freq_Hz,1_re,1_im'); "
     "read it with --format csv or without --format (its suffix .csv says csv)"),
    ("notes.uff", "", "it looks like an empty file (0 bytes)"),
    ("truth.uff", '{"modes": [1, 2]}\n', "it looks like JSON text (first line "
                                        "'{\"modes\": [1, 2]}')"),
])
def test_format_uff_on_another_kind_of_file_says_what_it_looks_like(tmp_path, h5, name,
                                                                      content, looks):
    """`fit-frf plate.frf.h5 --format uff` said 'no type-58 record; dataset types found:
    none', as if it were a Universal File without FRFs; it now says the file is not a
    Universal File and what it looks like (and the --format that reads it)."""
    path = h5 if content is None else tmp_path / name
    if content is not None:
        path.write_text(content)
    r = run(["fit-frf", str(path), "--format", "uff"])
    assert r.exit_code == 2, r.output
    assert "types found: none" not in r.output
    assert r.output.strip() == (f"laminid: error: {path}: not a Universal File (no dataset "
                                "between '    -1' lines, as UFF 58 FRF records are); " + looks)


def test_format_csv_on_an_hdf5_file_says_it_is_hdf5(h5):
    r = run(["fit-frf", str(h5), "--format", "csv"])
    assert r.exit_code == 2, r.output
    assert r.output.strip() == (f"laminid: error: {h5}: not a text (CSV) file; it looks like "
                                "an HDF5 file (laminid acquire's FRF file or another tool's); "
                                "read it with --format hdf5 or without --format (its suffix .h5 "
                                "says hdf5)")


def test_a_csv_that_states_no_unit_is_said_so_not_called_dimensionless(tmp_path, case):
    """A CSV file without a '# units' line was reported in unit "1" (table, --json: "units":
    "1", modal constants in "rad/s"), as if its FRFs were dimensionless: now "unit not stated
    in file" on the terminal, null in --json (frf_unit), and a note naming the file and how to
    state it; a file that declares "# units 1" keeps "1"."""
    names = ["freq_Hz"] + [f"{k}_{p}" for k in range(1, 6) for p in ("re", "im")]
    data = np.column_stack([case.freq] + [c for H in case.frf for c in (H.real, H.imag)])
    path = tmp_path / "lab.csv"
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    note = (f"{path}: the FRF unit is not stated in the file (a comment line '# units Pa/N' "
            "above the data or the FRF columns' headers, 'H1_re [g/N]', state it): the FRFs "
            "and their modal constants are given without a unit (null in --json)")
    r = run(["fit-frf", str(path), "--band", "100:300"])
    assert r.exit_code == 0, r.output
    first = r.stdout.splitlines()[0]
    assert first == (f"{path}: 5 FRFs (unit not stated in file), {case.freq.size} lines, "
                     "bands 100-300 Hz")
    assert f"note: {note}" in r.stdout.splitlines()
    out = json.loads(run(["fit-frf", str(path), "--band", "100:300", "--json"]).stdout)
    assert out["frf_unit"] is None and out["units"] is None
    assert out["modal_constants_unit"] is None
    assert out["mode_units"]["modal_constants"] is None
    assert note in out["notes"]
    declared = tmp_path / "ratio.csv"
    declared.write_text("# units 1\n" + path.read_text())
    out = json.loads(run(["fit-frf", str(declared), "--band", "100:300", "--json"]).stdout)
    assert out["frf_unit"] == "1" and out["modal_constants_unit"] == "rad/s"
    assert not any("not stated" in n for n in out["notes"])


def _csv(path, case, first: str, scale: float = 1.0):
    """``case``'s FRFs as a lab's CSV: header ``first`` then re/im columns, the frequency
    times ``scale`` (1e-3: in kHz), no '# units' line."""
    names = [first] + [f"{k}_{p}" for k in range(1, 6) for p in ("re", "im")]
    data = np.column_stack([case.freq * scale] + [c for H in case.frf for c in (H.real, H.imag)])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return path


def test_a_khz_frequency_column_headed_without_unit_is_refused_not_read_as_hz(tmp_path, case):
    """A kHz column headed just "f" was read as Hz without a word (125.05 Hz found at 0.125,
    exit 0, and --into wrote it): its values end below 100 Hz, where a free plate has hardly a
    mode; now refused, naming the file, the column, the range read and the header that states
    the unit; the specimen of --into is left as it was. Headed "f [kHz]" it reads right."""
    path = _csv(tmp_path / "khz.csv", case, "f", 1e-3)
    spec = tmp_path / "plate.yaml"
    spec.write_text(SPEC)
    r = run(["fit-frf", str(path), "--into", str(spec)])
    assert r.exit_code == 2, r.output
    assert r.stderr == (
        f"laminid: error: {path}: column 1 ('f'): the frequency states no unit, and its values "
        f"{case.freq[0] * 1e-3:g} to {case.freq[-1] * 1e-3:g} read as Hz would end below 100 "
        "Hz, where a free plate has hardly a mode (they lie at about 20 Hz to 20 kHz): very "
        "likely kHz, not Hz; state it in the header: 'f [kHz]', 'f [Hz]' or 'f [rad/s]' (also "
        "'f (kHz)' or 'f_kHz')\n")
    assert spec.read_text() == SPEC
    for header in ("f [kHz]", "f (kHz)", "f_kHz"):
        out = json.loads(run(["fit-frf", str(_csv(path, case, header, 1e-3)), "--json"]).stdout)
        assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz, rtol=1e-3)
        assert out["warnings"] == []


def test_a_hz_frequency_column_headed_without_unit_is_read_as_hz_with_a_warning(tmp_path, case):
    """A plausible axis (1-1601 Hz) headed "f" is read as Hz, with a warning on stderr (and in
    --json) naming the file, the column, the range read and how to state the unit; headed
    "f [Hz]" or "freq_Hz" (laminid's own CSV) it is read the same, without one."""
    path = _csv(tmp_path / "hz.csv", case, "f")
    warning = (f"{path}: column 1 ('f'): the frequency states no unit; its values "
               f"{case.freq[0]:g} to {case.freq[-1]:g} are read as Hz (were they kHz, every "
               "mode would be 1000 times too low; rad/s, 6.28 times too high); if they are not "
               "Hz, state it in the header: 'f [kHz]', 'f [Hz]' or 'f [rad/s]' (also 'f (kHz)' "
               "or 'f_kHz'); 'f [Hz]' confirms Hz and silences this warning")
    r = run(["fit-frf", str(path)])
    assert r.exit_code == 0, r.output
    assert r.stderr == f"warning: {warning}\n"
    rows = [ln.split() for ln in r.stdout.splitlines() if ln.strip()[:1].isdigit()]
    assert np.allclose([float(row[1]) for row in rows], case.freq_hz, rtol=1e-3)
    r = run(["fit-frf", str(path), "--json"])
    assert json.loads(r.stdout)["warnings"] == [warning]
    for header in ("f [Hz]", "freq_Hz"):
        r = run(["fit-frf", str(_csv(path, case, header)), "--json"])
        assert r.exit_code == 0 and r.stderr == "", r.output
        out = json.loads(r.stdout)
        assert out["warnings"] == []
        assert np.allclose([m["freq_hz"] for m in out["modes"]], case.freq_hz, rtol=1e-3)


def test_json_states_the_unit_of_the_modal_constants_and_which_spread_is_which(h5, case):
    """--json gave modal_constants without a unit and freq_std_hz (the RFP spread only) beside
    sigma_hz (the uncertainty identify uses) with nothing to tell them apart. It now states
    modal_constants_unit ((FRF units)*rad/s: residues of A/(s - pole) + conj) and the unit of
    every mode field (mode_units); --help says what each spread is. The keys stay."""
    r = run(["fit-frf", str(h5), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert out["frf_unit"] == "Pa/N" and out["modal_constants_unit"] == "(Pa/N)*rad/s"
    assert out["units"] == "Pa/N"          # frf_unit's old name, kept for 0.2.x
    assert out["mode_units"]["modal_constants"] == "(Pa/N)*rad/s"
    assert out["mode_units"]["sigma_hz"] == out["mode_units"]["freq_std_hz"] == "Hz"
    # snr (895 for the emulator's mode 1) was '1': a signal-to-noise ratio reads as dB
    assert out["mode_units"]["snr"] == ("1 (linear, not dB: the mode's peak contribution over "
                                        "the RMS of the fit's residual around it)")
    assert all(m["snr"] > 5 for m in out["modes"])           # rfp's min_snr, linear
    counts = {"mode", "orders_stable", "sigma_dominant", "damping_sigma_dominant"}   # words
    for m in out["modes"]:
        assert set(m) - counts == set(out["mode_units"])
        # freq_std_hz is the 'rfp spread' term alone; sigma_hz is every term, floored
        assert m["freq_std_hz"] == m["sigma_terms_hz"]["rfp spread"]
        quad = np.sqrt(sum(v ** 2 for t, v in m["sigma_terms_hz"].items() if t != "floor"))
        assert m["sigma_hz"] == pytest.approx(max(quad, m["sigma_terms_hz"]["floor"]))
        assert m["sigma_hz"] >= m["freq_std_hz"]
    assert max(m["sigma_hz"] / m["freq_std_hz"] for m in out["modes"]) > 3   # not the same
    # the unit is right: at mode 1's natural frequency its residue term alone gives the FRF
    # there (Pa/N) within the other modes' share (10 %)
    m = out["modes"][0]
    wn = 2 * np.pi * m["freq_hz"]
    z = m["damping_ratio_fitted"]
    pole = complex(-z * wn, wn * np.sqrt(1 - z * z))
    k = int(np.argmin(np.abs(case.freq - m["freq_hz"])))
    s = 1j * 2 * np.pi * case.freq[k]
    for p, (re, im) in enumerate(m["modal_constants"]):
        a = complex(re, im)
        h = a / (s - pole) + a.conjugate() / (s - pole.conjugate())
        assert abs(h - case.frf[p, k]) < 0.1 * abs(case.frf[p, k]), (p, h, case.frf[p, k])
    r = run(["fit-frf", "--help"])
    text = " ".join(r.output.split())
    assert ("sigma_hz the uncertainty above, Hz: what --into writes as measured.sigma and "
            "identify uses") in text
    assert ("freq_std_hz the RFP spread term alone, Hz: the standard deviation of the "
            "frequency over the stable model orders") in text
    assert "modal_constants [re, im] residue A of each FRF, in (FRF units)*rad/s" in text


@pytest.mark.parametrize("n_points", [1, 2])
def test_a_narrow_band_is_swept_up_to_the_order_its_lines_hold(tmp_path, n_points):
    """The order sweep of a band stops at the most modes its lines can be fitted with; the cap
    was one mode above the fits' own rule for 1 or 2 FRFs, so a band of 18 lines (2 FRFs; an
    automatic band around noise peaks of a poorly coherent acquire file) was refused with
    exit 2: 'band 110:144 Hz holds 18 lines, too few for 11 modes (at least 19 lines needed);
    widen the band or ask fewer modes', to a user who asked for no number of modes."""
    case = plate_case(n_points=n_points, resolution_hz=2.0, n_lines=800, f_start=2.0)
    path = io.write_frf(tmp_path / "narrow.frf.h5",
                        FrfSet(freq=case.freq, frf=case.frf, units="Pa/N"))
    lines = int(((case.freq >= 110) & (case.freq <= 144)).sum())
    assert lines == 18
    r = run(["fit-frf", str(path), "--band", "110:144", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert [m["freq_hz"] for m in out["modes"]] == pytest.approx([125.05], rel=1e-5)
    r = run(["fit-frf", str(path), "--band", "110:144", "--modes", "12"])
    assert r.exit_code == 2
    assert r.output.startswith("laminid: error: ") and "band 110:144 Hz holds 18 lines, too " \
        "few to fit 12 modes; widen the band or ask fewer modes" in r.output


def test_into_with_no_mode_found_names_the_fit_not_the_specimen(tmp_path, h5):
    """A band with no resonance and --into: the message blamed the specimen ('the edited file
    would not be a valid specimen (...: the list of frequencies is empty)'); it says the fit
    found no mode in the band, the file is unchanged (exit 2)."""
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    r = run(["fit-frf", str(h5), "--band", "20:60", "--into", str(spec)])
    assert r.exit_code == 2
    assert r.output == (f"laminid: error: {h5}: no stable mode found (band(s) 20:60 Hz): "
                        f"nothing to write into {spec}, left unchanged; fit other bands "
                        "(--band LO:HI)\n")
    assert spec.read_text() == SPEC and not list(tmp_path.glob("p.yaml.bak*"))


def test_damping_sigma_says_whether_the_floor_or_the_spread_set_it(h5, case):
    """A damping ratio's +/- is its spread over the stable orders, at least 2 % of the ratio.
    The table named what set each frequency's sigma ('from', the footnote) but not the
    damping's: on the synthetic S1.1 (scripts/example_frf.py) 12 of 13 damping sigmas were
    exactly the assumed 2 % floor, shown as if the FRFs had measured them. Now --json gives
    each mode's damping_sigma_dominant and damping_sigma_rule, and the table a footnote with
    the counts, matching the sigmas themselves."""
    from laminid_cli.frf import rfp

    fit = rfp.find_modes(case.freq, case.frf)
    z = np.asarray(fit.damping_ratio)
    std = np.array([m.damping_std for m in fit.modes])
    expect = ["rfp spread" if s > 0.02 * v else "floor" for s, v in zip(std, z)]
    assert rfp.damping_sigma_dominant(fit) == expect
    r = run(["fit-frf", str(h5), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    got = [mo["damping_sigma_dominant"] for mo in out["modes"]]
    assert got == expect
    for mo, d in zip(out["modes"], got):                # the sigma is the term it names
        floor = 0.02 * mo["damping_ratio"]
        assert mo["damping_sigma"] == pytest.approx(floor if d == "floor" else mo["damping_std"],
                                                    rel=1e-12)
    n_floor = expect.count("floor")
    assert f"floor {n_floor} (modes)" in out["damping_sigma_rule"] if n_floor else True
    r = run(["fit-frf", str(h5)])
    line = next(ln for ln in r.output.splitlines() if ln.startswith("zeta +/-:"))
    assert "at least 2 % of the ratio" in line and out["damping_sigma_rule"] in line
    # the frequencies' line names its column too (a bare '+/-:' over two +/- columns)
    line = next(ln for ln in r.output.splitlines() if "+/-: one standard deviation, fit-frf" in ln)
    assert line.startswith("freq +/-: ")


def test_into_records_the_damping_sigma_rule_and_identify_reports_it(tmp_path, h5, case):
    """--into wrote the damping sigmas without a word of how they were made, and identify
    said "the specimen file's measured.damping_sigma", as if measured: 12 of 13 of the
    synthetic S1.1's were the RFP fit's assumed 2 % floor. Now measured.damping_sigma_source
    says so (the fit's counts), identify repeats it ("made by: ..."), a later fit without it
    drops the stale one, and one without damping_sigma is refused."""
    from laminid_cli.errors import SpecimenError
    from laminid_cli.frf import rfp
    from laminid_cli.frf.into import write_measured
    from laminid_cli.specimen import read_specimen

    spec = tmp_path / "S1.1.yaml"
    spec.write_text(_S11.read_text())
    assert run(["fit-frf", str(h5), "--into", str(spec)]).exit_code == 0
    rule = rfp.damping_sigma_summary(rfp.damping_sigma_dominant(
        rfp.find_modes(case.freq, case.frf)))
    measured = yaml.safe_load(spec.read_text())["measured"]
    assert measured["damping_sigma_source"] == f"plate.frf.h5: fit-frf: {rule}"
    assert read_specimen(spec).measured.damping_sigma_source == f"plate.frf.h5: fit-frf: {rule}"
    r = run(["identify", str(spec), "--mesh", "6x6", "--no-output", "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["damping"]["sigma_source"] == (
        f"the specimen file's measured.damping_sigma (made by: plate.frf.h5: fit-frf: {rule})")
    s = read_specimen(spec).measured
    write_measured(spec, list(s.freq), list(s.sigma), damping=list(s.damping),
                   damping_sigma=list(s.damping_sigma))
    assert "damping_sigma_source" not in yaml.safe_load(spec.read_text())["measured"]
    lines = [ln if not ln.startswith("  damping_sigma:") else "  damping_sigma_source: by eye"
             for ln in spec.read_text().splitlines()]
    bad = tmp_path / "bad.yaml"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(SpecimenError, match="'damping_sigma_source' describes 'damping_sigma', "
                                            "which is missing"):
        read_specimen(bad)


def test_plot_legend_gives_the_frequencies_sigma_span(tmp_path, h5, case):
    """fit-frf --plot labelled the natural frequencies with their values alone (124.98); the
    legend now gives the span of their standard deviations, the table's +/- column."""
    from laminid_cli.frf import rfp
    from laminid_cli.frf.plot import fit_figure, sigma_label

    fit = rfp.find_modes(case.freq, case.frf)
    sig = rfp.measurement_sigma(fit, case.freq, sigma_rel=0.002).sigma_hz
    fig = fit_figure(case.freq, case.frf, fit, sigma_hz=sig)
    texts = [t.get_text() for a in fig.axes if a.get_legend() for t in a.get_legend().get_texts()]
    want = f"RFP natural frequency (± {sig.min():.3g}–{sig.max():.3g} Hz, one standard deviation)"
    assert want in texts
    assert sigma_label(None) == "RFP natural frequency"
    assert sigma_label([0.25, 0.25]) == "RFP natural frequency (± 0.25 Hz, one standard deviation)"
    r = run(["fit-frf", str(h5), "--plot", str(tmp_path / "fit.png")])
    assert r.exit_code == 0, r.output


def test_a_terminal_is_told_what_runs(tmp_path, h5, monkeypatch):
    """fit-frf --plot fitted and drew for 2.8-7.6 s (the synthetic S1.1's 8 FRFs) with nothing
    on a terminal, its table printed after the plot; it now says it fits, then draws, and ends
    the line before the table. Not with --json, nor on a pipe or a log. (The plot is stood in
    for: what is said, not what is drawn.)"""
    import laminid_cli.commands.fit_frf as cmd
    import laminid_cli.frf.plot as plot

    drawn = []
    monkeypatch.setattr(plot, "plot_fit", lambda path, *a, **k: drawn.append(path))
    monkeypatch.setattr(cmd, "stderr_is_terminal", lambda: True)
    out = tmp_path / "fit.png"
    r = CliRunner().invoke(cli, ["fit-frf", str(h5), "--plot", str(out)])
    assert r.exit_code == 0, r.output
    head = f"  fitting 5 FRFs of {h5}"
    assert r.stderr == head + "\r" + f"  drawing {out}".ljust(len(head)) + "\n"
    assert drawn == [out] and r.stdout.startswith(f"{h5}: 5 FRFs (Pa/N)")
    r = CliRunner().invoke(cli, ["fit-frf", str(h5)])
    assert r.exit_code == 0 and r.stderr == head + "\n"
    r = CliRunner().invoke(cli, ["fit-frf", str(h5), "--json"])
    assert r.exit_code == 0 and r.stderr == ""


def test_one_frf_is_said_in_the_singular(tmp_path, case):
    """A lab's CSV of one FRF (frequency, real, imaginary) was "1 FRFs" in fit-frf's first
    line, its progress line and export's line."""
    path = tmp_path / "one.csv"
    with open(path, "w") as fh:
        fh.write("f [Hz],H1_re,H1_im\n")
        for f, h in zip(case.freq, case.frf[0]):
            fh.write(f"{float(f)!r},{float(h.real)!r},{float(h.imag)!r}\n")
    r = run(["fit-frf", str(path), "--band", "100:300"])
    assert r.exit_code == 0, r.output
    assert r.output.startswith(f"{path}: 1 FRF (unit not stated in file), {case.freq.size} "
                               "lines, bands 100-300 Hz\n"), r.output
    r = run(["export", str(path), "-o", str(tmp_path / "one.uff")])
    assert r.exit_code == 0, r.output
    assert r.output.startswith(f"{tmp_path / 'one.uff'}: 1 FRF (UFF 58b, ")


def test_a_pole_dropped_as_no_credible_mode_is_reported_with_why(tmp_path):
    """Two FRFs of pure noise (seed 3, 1-400 Hz): a stable pole at 69.23 Hz was listed as a
    mode. It is dropped (rfp.pole_false_alarm) and said so: a 'dropped:' line under the table
    and --json's dropped_poles, with its reason and the figures."""
    rng = np.random.default_rng(3)
    H = (rng.standard_normal((2, 400)) + 1j * rng.standard_normal((2, 400))) / np.sqrt(2)
    path = io.write_frf(tmp_path / "noise.frf.h5",
                        FrfSet(freq=np.arange(1.0, 401.0), frf=H, units="Pa/N"))
    r = run(["fit-frf", str(path)])
    assert r.exit_code == 0, r.output
    assert "no stable mode found" in r.output
    line = [ln for ln in r.output.splitlines() if ln.startswith("dropped: pole at 69.226 Hz")]
    assert len(line) == 1, r.output
    assert "no credible mode: its modal constants lower the residual by chi-squared" in line[0]
    assert line[0].endswith("with probability 1 > 0.01")
    out = json.loads(run(["fit-frf", str(path), "--json"]).output)
    assert out["modes"] == []
    d = [d for d in out["dropped_poles"] if abs(d["freq_hz"] - 69.226) < 1e-3]
    assert len(d) == 1 and d[0]["reason"] == "chance" and d[0]["false_alarm"] == 1.0
    assert d[0]["band_hz"] == [41.0, 71.0] and 0 < d[0]["damping_ratio"] < 0.01


def test_json_gives_each_modes_false_alarm_probability(h5, case):
    """Each mode's credibility as a probability: that noise alone gives a pole whose modal
    constants lower the residual as much anywhere in the lines fitted (rfp.pole_false_alarm);
    at most 0.01 for a mode kept, and far below it for the plate's ten clear modes at 2 %
    noise (measured 0: chi-squared of thousands on 10 degrees of freedom)."""
    out = json.loads(run(["fit-frf", str(h5), "--json"]).output)
    assert len(out["modes"]) == 10
    assert all(0 <= m["false_alarm"] < 1e-12 for m in out["modes"]), out["modes"]
    assert out["mode_units"]["false_alarm"].startswith("1 (a probability: that noise alone")
    text = " ".join(run(["fit-frf", "--help"]).output.split())
    assert ("false_alarm the probability that noise alone gives a pole whose modal constants "
            "lower the fit's residual as much anywhere in the lines fitted") in text
