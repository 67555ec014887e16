"""fit-frf removes the exponential window's added damping (1/tau on every pole's decay rate).

References (independent of the fitter):

- a record windowed sample by sample: impulse responses of known modes, multiplied by
  exp(-t/tau) in the time domain, then Fourier transformed (no pole-shift formula involved);
- the analyser emulators of tests/instrument/ (HP 35670A: tau in s, SR785: % of the record),
  whose plate has the damping ratios ``PLATE_MODES``;
- a file without a recorded window: the damping is the fitted one, as before.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.frf import io, rfp
from laminid_cli.frf.store import FrfSet, write_frf_h5
from tests.frf_synth import synth_frf
from tests.instrument.emulator import PLATE_MODES, HP35670AEmulator, SR785Emulator
from tests.test_fit_frf_cli import SPEC

#: modes of the time-domain case (Hz, damping ratio): the window's 1/(tau omega) (1.06 % at
#: 150 Hz with tau = 0.1 s) is larger than three of the four true ratios
MODES = ((150.0, 0.004), (420.0, 0.010), (655.0, 0.006), (880.0, 0.003))
TAU = 0.1


def run(args):
    return CliRunner().invoke(cli, args, catch_exceptions=False)


def windowed_record_frf(tau, noise=0.0, seed=5):
    """FRFs (receptance) of MODES at 4 points from impulse responses windowed in the time
    domain: span 1000 Hz, 1000 lines (T = 1 s), sampled at 32 kHz."""
    span, lines, fs = 1000.0, 1000, 32000.0
    t = np.arange(int(round(lines / span * fs))) / fs
    rng = np.random.default_rng(3)
    C = rng.uniform(0.5, 1.0, (4, len(MODES))) * rng.choice([-1.0, 1.0], (4, len(MODES)))
    H = []
    for c in C:
        h = np.zeros_like(t)
        for (f, z), a in zip(MODES, c):
            w = 2 * np.pi * f
            wd = w * np.sqrt(1 - z * z)
            h += a * np.exp(-z * w * t) * np.sin(wd * t) / wd
        H.append(np.fft.rfft(h * np.exp(-t / tau)) / fs)
    freq = np.fft.rfftfreq(t.size, 1 / fs)
    keep = freq <= span
    H = np.array(H)[:, keep]
    if noise:
        r = np.random.default_rng(seed)
        H = H + noise * np.abs(H).max(axis=1, keepdims=True) * (
            r.standard_normal(H.shape) + 1j * r.standard_normal(H.shape)) / np.sqrt(2)
    return freq[keep], H


def h5_file(path, freq, H, settings):
    return write_frf_h5(path, freq, H, units="m/N", settings=settings)


def test_time_domain_window_is_removed_to_the_true_damping(tmp_path):
    """Noise-free: the corrected ratios equal the modes' within 1e-6 (relative); the fitted
    ones are those of poles moved left by 1/tau (within 1e-6), ~ zeta + 1/(tau omega_n), 1.38-3.7x
    the truth."""
    freq, H = windowed_record_frf(TAU)
    path = h5_file(tmp_path / "w.h5", freq, H, {"exp_window_s": TAU, "span_hz": 1000.0})
    r = run(["fit-frf", str(path), "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert out["exp_window_s"] == TAU and "removed" in out["damping_rule"]
    zeta = np.array([z for _, z in MODES])
    w = 2 * np.pi * np.array([f for f, _ in MODES])
    got = np.array([m["damping_ratio"] for m in out["modes"]])
    fitted = np.array([m["damping_ratio_fitted"] for m in out["modes"]])
    removed = np.array([m["damping_window_removed"] for m in out["modes"]])
    np.testing.assert_allclose(got, zeta, rtol=1e-6)
    # the windowed record's poles: decay zeta w + 1/tau, damped frequency w sqrt(1 - zeta^2)
    decay = zeta * w + 1 / TAU
    np.testing.assert_allclose(fitted, decay / np.hypot(w * np.sqrt(1 - zeta**2), decay),
                               rtol=1e-6)
    np.testing.assert_allclose(fitted, zeta + 1 / (TAU * w), rtol=1e-4)   # to first order
    np.testing.assert_allclose(removed, fitted - got, rtol=1e-12)
    assert np.all(fitted / zeta > 1.35)
    # the standard deviation is the fitted ratio's (the 1/tau removed is exact)
    sig = np.array([m["damping_sigma"] for m in out["modes"]])
    assert np.all(sig >= 0.02 * fitted * (1 - 1e-9))


def test_time_domain_window_with_noise_within_three_sigma(tmp_path):
    """0.5 % noise: each corrected ratio within 3 of its standard deviations of the truth."""
    freq, H = windowed_record_frf(TAU, noise=0.005)
    path = h5_file(tmp_path / "n.h5", freq, H, {"exp_window_s": TAU})
    out = json.loads(run(["fit-frf", str(path), "--json"]).output)
    got = np.array([m["damping_ratio"] for m in out["modes"]])
    sig = np.array([m["damping_sigma"] for m in out["modes"]])
    zeta = np.array([z for _, z in MODES])
    assert np.all(np.abs(got - zeta) <= 3 * sig), (got, zeta, sig)


@pytest.mark.parametrize("emu_cls", [HP35670AEmulator, SR785Emulator])
def test_emulator_damping_after_acquire_and_fit_frf_into(tmp_path, emu_cls):
    """acquire (tau = 0.1 s, the default) -> fit-frf --into: the specimen gets the emulator's
    damping within 0.5 % (relative; measured 0.16 % at worst), not zeta + 1/(tau omega)
    (1.16-1.94x the truth), and the output says what was removed."""
    out = tmp_path / "p.frf.h5"
    with emu_cls(hit_interval_s=0.01) as emu:
        r = run(["acquire", "--analyser", emu.resource, "--timeout", "0.5", "--averages", "3",
                 "--points", "3", "--no-prompt", "-o", str(out)])
    assert r.exit_code == 0, r.output
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    r = run(["fit-frf", str(out), "--into", str(spec)])
    assert r.exit_code == 0, r.output
    assert "window (%)" in r.output
    assert "the exponential window's 1/(tau*omega_n) (tau = 0.1 s" in r.output
    measured = yaml.safe_load(spec.read_text())["measured"]
    truth = np.array([z for _, z in PLATE_MODES])
    w = 2 * np.pi * np.array([f for f, _ in PLATE_MODES])
    np.testing.assert_allclose(measured["damping"], truth, rtol=5e-3)
    assert np.all(np.abs(np.array(measured["damping"]) - (truth + 1 / (0.1 * w)))
                  > 0.1 * truth)
    # the table's damping column is the same number, then its +/-, the window column
    # 1/(tau omega)
    rows = [ln.split() for ln in r.output.splitlines() if ln.strip()[:1].isdigit()
            and "written" not in ln]
    np.testing.assert_allclose([float(row[4]) / 100 for row in rows], truth, rtol=5e-3,
                               atol=6e-6)
    np.testing.assert_allclose([float(row[6]) / 100 for row in rows], 1 / (0.1 * w),
                               rtol=2e-3, atol=6e-6)
    # beside the damping, its standard deviation (the --json damping_sigma, 3 decimals in %)
    assert all(0 < float(row[5]) < float(row[4]) for row in rows)


def test_file_without_a_recorded_window_is_unchanged(tmp_path):
    """No exp_window_s in the file: damping = the fitted ratio, no window column or note."""
    freq, H = windowed_record_frf(TAU)
    path = h5_file(tmp_path / "x.h5", freq, H, {"span_hz": 1000.0})
    out = json.loads(run(["fit-frf", str(path), "--json"]).output)
    fit = rfp.find_modes(freq, H)
    got = [m["damping_ratio"] for m in out["modes"]]
    assert got == [m["damping_ratio_fitted"] for m in out["modes"]]
    np.testing.assert_allclose(got, fit.damping_ratio, rtol=0)
    np.testing.assert_allclose([m["damping_sigma"] for m in out["modes"]],
                               rfp.damping_sigma(fit), rtol=0)
    assert out["exp_window_s"] is None and out["damping_rule"] is None and out["notes"] == []
    r = run(["fit-frf", str(path)])
    assert "window (%)" not in r.output and "removed" not in r.output
    assert "note:" not in r.output
    # the same FRFs as UFF (no settings at all): the same damping
    uff = io.write_frf(tmp_path / "x.uff", FrfSet(freq=freq, frf=H))
    out2 = json.loads(run(["fit-frf", str(uff), "--json"]).output)
    np.testing.assert_allclose([m["damping_ratio"] for m in out2["modes"]], got, rtol=1e-9)


def test_a_window_recorded_as_unknown_is_said(tmp_path):
    """--keep-setup records exp_window_s as NaN (not read back): the damping is as fitted and
    the output says the window is unknown."""
    freq, H = windowed_record_frf(TAU)
    path = h5_file(tmp_path / "k.h5", freq, H, {"exp_window_s": float("nan")})
    r = run(["fit-frf", str(path)])
    assert r.exit_code == 0, r.output
    assert "does not record the exponential window's time constant" in r.output
    out = json.loads(run(["fit-frf", str(path), "--json"]).output)
    assert [m["damping_ratio"] for m in out["modes"]] == \
        [m["damping_ratio_fitted"] for m in out["modes"]]


def test_damping_below_the_windows_is_null_with_a_note_never_negative(tmp_path):
    """A file claiming a shorter window than its FRFs show (1/tau = 50 /s): mode 1 (100 Hz,
    fitted decay 3.1 /s) falls below it, mode 2 (1000 Hz, decay 94 /s) stays above. The
    table says so, --json gives null, --into writes null (and its sigma null)."""
    freq = np.arange(0.0, 1601.0, 0.5)
    H = synth_frf(freq, [(100.0, 0.005), (1000.0, 0.015)], np.array([[1.0, 1.0], [0.7, -0.8]]))
    path = h5_file(tmp_path / "b.h5", freq, H, {"exp_window_s": 0.02})
    r = run(["fit-frf", str(path)])
    assert r.exit_code == 0, r.output
    rows = [ln.split() for ln in r.output.splitlines() if ln.strip()[:1].isdigit()
            and "written" not in ln]
    assert rows[0][4:6] == ["below", "win."] and "-" not in rows[0][4]
    assert float(rows[1][4]) == pytest.approx(100 * (0.015 - 1 / (0.02 * 2 * np.pi * 1000)),
                                              rel=1e-3)
    assert "note: mode 1 (100.00 Hz): fitted damping 0.5 % is not above the window's" \
           in r.output and "not measured (null in --json and --into)" in r.output
    out = json.loads(run(["fit-frf", str(path), "--json"]).output)
    assert out["modes"][0]["damping_ratio"] is None and out["modes"][0]["damping_sigma"] is None
    assert out["modes"][0]["damping_ratio_fitted"] == pytest.approx(0.005, rel=1e-6)
    assert out["modes"][1]["damping_ratio"] > 0 and len(out["notes"]) == 2
    assert out["notes"][1].startswith("below 80 Hz the exponential window (tau = 0.02 s) "
                                      "alone adds more than 10% damping")
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    r = run(["fit-frf", str(path), "--into", str(spec)])
    assert r.exit_code == 0, r.output
    m = yaml.safe_load(spec.read_text())["measured"]
    assert m["damping"][0] is None and m["damping_sigma"][0] is None
    assert m["damping"][1] == pytest.approx(0.015 - 1 / (0.02 * 2 * np.pi * 1000), rel=1e-3)
    from laminid_cli.specimen import read_specimen

    s = read_specimen(spec)
    assert np.isnan(s.measured.damping[0]) and s.measured.damping[1] > 0


def test_no_damping_above_the_window_writes_none_and_removes_stale_lists(tmp_path):
    """Every fitted damping below the window's: the frequencies are written, the damping lists
    of an earlier fit are removed (an all-null list is no valid specimen), and it is said."""
    freq = np.arange(0.0, 1601.0, 0.5)
    H = synth_frf(freq, [(100.0, 0.005), (300.0, 0.004)], np.array([[1.0, 1.0], [0.7, -0.8]]))
    path = h5_file(tmp_path / "a.h5", freq, H, {"exp_window_s": 0.02})
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC.replace("frequencies: [1.0, 2.0]   # Hz",
                                 "frequencies: [1.0, 2.0]   # Hz\n  damping: [0.01, 0.02]"))
    r = run(["fit-frf", str(path), "--into", str(spec)])
    assert r.exit_code == 0, r.output
    assert "2 frequencies (no damping ratio: none is above the window's) written" in r.output
    assert "note: measured.damping removed (it described an earlier fit)" in r.output
    m = yaml.safe_load(spec.read_text())["measured"]
    assert "damping" not in m and "damping_sigma" not in m
    np.testing.assert_allclose(m["frequencies"], [100.0, 300.0], rtol=1e-4)


def test_measured_frf_file_in_a_specimen_gets_the_corrected_damping(tmp_path):
    """A specimen naming the FRF file (measured.frf_file) is fitted on loading: the same
    window correction as fit-frf."""
    freq, H = windowed_record_frf(TAU)
    h5_file(tmp_path / "plate.frf.h5", freq, H, {"exp_window_s": TAU})
    f, s, z, zs = rfp.measured_from_frf_file(tmp_path / "plate.frf.h5", with_damping_sigma=True)
    np.testing.assert_allclose(z, [zt for _, zt in MODES], rtol=1e-6)
    assert np.all(zs > 0)


@pytest.mark.parametrize("ascii_", [False, True])
def test_window_survives_export_to_uff(tmp_path, ascii_):
    """export of a windowed acquire file (tau = 0.1 s) writes tau in each FRF record's id3,
    and fit-frf of the UFF removes it as of the HDF5 file: the same damping ratios (the UFF
    used to lose it: every ratio came back with 1/(tau omega_n) added, 1.38-3.7x the truth
    here); the export says so. A window recorded as unknown (--keep-setup) stays unknown."""
    import pyuff

    freq, H = windowed_record_frf(TAU)
    h5 = h5_file(tmp_path / "w.h5", freq, H, {"exp_window_s": TAU, "span_hz": 1000.0})
    uff = tmp_path / "w.uff"
    r = run(["export", str(h5), "-o", str(uff)] + (["--ascii"] if ascii_ else []))
    assert r.exit_code == 0, r.output
    assert ("note: the FRFs carry the analyser's exponential window (tau = 0.1 s), written in "
            "each record's id3: laminid fit-frf of the Universal File removes it") in r.output
    ids = [d["id3"].strip() for d in pyuff.UFF(str(uff)).read_sets() if d.get("func_type") == 4]
    assert ids == ["exponential window tau = 0.1 s"] * 4
    assert io.read_frf(uff).meta["settings"] == {"exp_window_s": 0.1}
    from_h5 = json.loads(run(["fit-frf", str(h5), "--json"]).output)
    from_uff = json.loads(run(["fit-frf", str(uff), "--json"]).output)
    assert from_uff["exp_window_s"] == TAU
    zeta = np.array([z for _, z in MODES])
    got = np.array([m["damping_ratio"] for m in from_uff["modes"]])
    np.testing.assert_allclose(got, zeta, rtol=1e-6)
    np.testing.assert_allclose(got, [m["damping_ratio"] for m in from_h5["modes"]],
                               rtol=1e-5 if ascii_ else 1e-12)
    # --keep-setup: the window's tau unknown, and said so after the round trip too
    h5k = h5_file(tmp_path / "k.h5", freq, H, {"exp_window_s": float("nan")})
    uffk = tmp_path / "k.uff"
    assert run(["export", str(h5k), "-o", str(uffk)]).exit_code == 0
    assert np.isnan(io.read_frf(uffk).meta["settings"]["exp_window_s"])
    r = run(["fit-frf", str(uffk)])
    assert "does not record the exponential window's time constant" in r.output


def test_a_window_too_short_for_the_lowest_modes_is_said(tmp_path):
    """A time constant of 1 % of the record (tau 0.01 s, T = 1 s) adds 1/(tau omega) = 10.6 %
    to the 150 Hz mode, above the 10 % a mode may have: fit-frf listed the other three modes
    and nothing else, and --into wrote them as the plate's first three (identify pairs 420 Hz
    with the plate's first mode). The note names the frequency below which no mode can be
    found (1/(2 pi tau 0.1) = 159 Hz) and the time constant to measure with."""
    freq, H = windowed_record_frf(0.01)
    path = h5_file(tmp_path / "short.h5", freq, H,
                   {"exp_window_s": 0.01, "span_hz": 1000.0, "lines": 1000})
    r = run(["fit-frf", str(path), "--json", "--band", "250:1000"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.output)
    assert [round(m["freq_hz"]) for m in out["modes"]] == [420, 655, 880]
    assert out["notes"] == [
        "below 159 Hz the exponential window (tau = 0.01 s) alone adds more than 10% damping, "
        "the most a mode may have: no mode can be found there, and the lowest mode found is at "
        "420.5 Hz. If the plate has a mode below 159 Hz, this list lacks it, and identify would "
        "pair each mode with the model mode below it; measure again with a longer --exp-window "
        "(a quarter of the time record or more: 0.25 s)"]
    r = run(["fit-frf", str(path)])          # its automatic band finds none of the modes
    assert r.exit_code == 0 and "no stable mode found" in r.output
    assert "note: below 159 Hz the exponential window (tau = 0.01 s) alone adds more than 10% " \
        "damping, the most a mode may have: no mode can be found there, and no mode was " \
        "found." in r.output
    # the acquire default (tau 0.1 s: 15.9 Hz, under a quarter of the lowest mode): no note
    freq, H = windowed_record_frf(TAU)
    path = h5_file(tmp_path / "ok.h5", freq, H, {"exp_window_s": TAU})
    out = json.loads(run(["fit-frf", str(path), "--json"]).output)
    assert len(out["modes"]) == 4 and out["notes"] == []


def test_a_pole_the_gap_search_finds_again_is_not_listed_twice():
    """Bands 100:560 and 540:1000 of the record windowed with tau = 0.01 s: the first band's
    pole at 420.46 Hz was dropped as noise after its refinement, the gap search found it again
    and appended it beside the dropped candidate; both refined onto one pole and the mode was
    listed twice (420.4604536837 and 420.4604536945 Hz), which --into would have written."""
    freq, H = windowed_record_frf(0.01)
    fit = rfp.find_modes(freq, H, bands=[(100, 560), (540, 1000)])
    f = np.sort(fit.freq_hz)
    assert np.all(np.diff(f) > 0.002 * f[:-1]), f
