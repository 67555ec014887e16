"""FRF file -> specimen (measured.frf_file) -> identification: the whole chain in one test."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.errors import SpecimenError
from laminid_cli.forward import build_forward_model
from laminid_cli.frf.store import write_frf_h5
from laminid_cli.specimen import load_specimen_text, read_specimen
from tests.frf_synth import synth_frf

S21 = "specimens/example2/S2.1.yaml"
MEASURED_BLOCK = ("  frequencies: [72.78, 121.00, 191.38, 286.78, 315.12, 340.40, 400.12, 433.84, "
                  "634.81, 653.56, 712.43, 789.97]   # Hz, Table 5")


@pytest.fixture(scope="module")
def frf_specimen(tmp_path_factory):
    """S2.1 with its model's first 8 modes (6x6 mesh, 1.3 x the initial E1) written as FRFs."""
    tmp = tmp_path_factory.mktemp("frf")
    spec = read_specimen(S21)
    fm = build_forward_model(spec, (6, 6))
    c0 = fm.initial_constants[0]
    truth = type(c0)(c0.E1 * 1.3, c0.E2, c0.G12, c0.G13, c0.G23, c0.nu12)
    f_true = fm.solve([truth], 8).freq
    freq = np.arange(0.0, 700.0, 0.5)[1:]
    rng = np.random.default_rng(3)
    constants = rng.choice([-1, 1], size=(4, 8)) * rng.uniform(0.3, 1.0, size=(4, 8))
    modes = np.column_stack([f_true, np.full(8, 0.008)])
    frf = synth_frf(freq, modes, constants, kind="accelerance", noise=0.01, seed=4)
    write_frf_h5(tmp / "plate.frf.h5", freq, frf, units="(m/s^2)/N")
    text = Path(S21).read_text().replace(MEASURED_BLOCK, "  frf_file: plate.frf.h5\n  modes: 8")
    assert "frf_file" in text
    (tmp / "plate.yaml").write_text(text)
    return tmp / "plate.yaml", f_true, truth


def test_specimen_takes_frequencies_and_sigmas_from_its_frf_file(frf_specimen):
    path, f_true, _ = frf_specimen
    spec = read_specimen(path)
    assert spec.measured.freq.shape == (8,)
    assert np.allclose(spec.measured.freq, f_true, rtol=5e-4)          # 1 % noise, RFP
    assert np.all(spec.measured.sigma > 0) and np.all(spec.measured.weight == 1)


def test_identify_from_an_frf_file_recovers_the_constants(frf_specimen):
    path, _, truth = frf_specimen
    r = CliRunner().invoke(cli, ["identify", str(path), "--mesh", "6x6", "--fix",
                                 "nu12,G13,G23", "--json", "--no-output"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["uncertainty"]["sigma_source"] == FRF_FILE_SIGMA
    # 0.5 Hz lines: sigma >= max(0.002 f, 0.5/sqrt(12) Hz)
    sig = np.array(d["uncertainty"]["frequency_sigma"]["S2.1"]["sigma_hz"])
    f = np.array(d["frequencies"]["measured"])
    assert np.all(sig >= np.maximum(0.002 * f, 0.5 / np.sqrt(12)) * (1 - 1e-12))
    mat = next(iter(d["materials"].values()))
    assert mat["E1"] == pytest.approx(truth.E1, rel=5e-3)
    assert mat["E2"] == pytest.approx(truth.E2, rel=2e-2)
    assert mat["G12"] == pytest.approx(truth.G12, rel=1e-2)


#: where the sigmas of a specimen with measured.frf_file come from, as identify and the report
#: say it after "σ from" (they said "specimen file (measured.sigma; fit of plate.frf.h5: ...)")
FRF_FILE_SIGMA = ("the RFP fit of the specimen's measured.frf_file plate.frf.h5 (sqrt(RFP "
                  "spread^2 + resolution^2 + window^2), at least 0.2 % of f)")


def test_identify_and_the_report_say_the_sigmas_came_from_fitting_the_frf_file(frf_specimen,
                                                                                tmp_path):
    """The report's page 1 and identify's output said the sigmas came from the specimen
    file's measured.sigma ('σ from specimen file (measured.sigma; fit of plate.frf.h5 ...)')
    when they came from fitting its measured.frf_file; both now name the fit and the file."""
    from tests.figs import result_page

    path, _, _ = frf_specimen
    out = tmp_path / "r.result.h5"
    r = CliRunner().invoke(cli, ["identify", str(path), "--mesh", "6x6", "--fix",
                                 "nu12,G13,G23", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert f"frequency standard deviations: {FRF_FILE_SIGMA}" in r.output
    assert "measured.sigma" not in r.output
    # the damping's sigmas too (they said 'specimen file / FRF fit')
    # (and what set them: the spread or the fit's assumed 2 % floor, as fit-frf says)
    assert ("damping standard deviations: the RFP fit of the specimen's measured.frf_file "
            "plate.frf.h5 (fitted ratio's spread over the stable orders, at least 2 % of the "
            "ratio; dominated by: " in " ".join(r.output.split()))
    page1 = result_page(out, "summary")                    # the report's page 1
    texts = [t.get_text() for t in list(page1.texts) + [t for a in page1.axes for t in a.texts]]
    flat = " ".join(" ".join(texts).split())
    assert f"σ from {FRF_FILE_SIGMA}" in flat
    assert "specimen file (measured.sigma" not in flat


def test_frf_file_errors_name_the_field(tmp_path):
    text = Path(S21).read_text()
    bad = text.replace(MEASURED_BLOCK, "  frf_file: nothere.h5")
    with pytest.raises(SpecimenError, match=r"measured.frf_file.*not found"):
        load_specimen_text(bad, str(tmp_path / "x.yaml"))
    both = text.replace(MEASURED_BLOCK, MEASURED_BLOCK + "\n  frf_file: plate.frf.h5")
    with pytest.raises(SpecimenError, match="either 'frequencies'"):
        load_specimen_text(both, str(tmp_path / "x.yaml"))
    (tmp_path / "junk.h5").write_bytes(b"not hdf5")
    junk = text.replace(MEASURED_BLOCK, "  frf_file: junk.h5")
    with pytest.raises(SpecimenError, match="frf_file"):
        load_specimen_text(junk, str(tmp_path / "x.yaml"))


def test_the_shipped_synthetic_impact_test_recovers_what_made_it(tmp_path):
    """scripts/example_frf.py (make example-frf): S1.1's model with the paper's Table 2
    constants and known ply loss factors as 8 accelerance FRFs (0.5 % noise) -> fit-frf
    --into -> identify with every constant free. Measured: the 13 frequencies within 2e-5,
    E1 161.10, E2 9.30, G12 6.80 GPa and the loss factors 0.200 / 1.20 / 1.50 % back; the
    constants are asserted within 0.3 % (E1) and 2 % (E2, G12), each loss factor inside its
    95 % interval and within 5 % of the truth."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("example_frf", "scripts/example_frf.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--out", str(tmp_path)]) == 0
    truth = json.loads((tmp_path / "truth.json").read_text())
    r = CliRunner().invoke(cli, ["fit-frf", str(tmp_path / "plate.frf.h5"), "--into",
                                 str(tmp_path / "plate.yaml"), "--json"])
    assert r.exit_code == 0, r.output
    got = [m["freq_hz"] for m in json.loads(r.output)["modes"]]
    assert np.allclose(got, truth["frequencies_hz"], rtol=2e-5)
    r = CliRunner().invoke(cli, ["identify", str(tmp_path / "plate.yaml"), "--json",
                                 "--no-output"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    c = d["materials"]["IM7/977-2"]
    assert c["E1"] == pytest.approx(truth["constants_GPa"]["E1"] * 1e9, rel=3e-3)
    for k in ("E2", "G12"):
        assert c[k] == pytest.approx(truth["constants_GPa"][k] * 1e9, rel=2e-2)
    eta = d["damping"]
    for k in ("eta11", "eta22", "eta12"):
        j = eta["labels"].index(f"IM7/977-2.{k}")
        assert eta["lower"][j] <= truth["loss_factors"][k] <= eta["upper"][j], k
        assert eta["value"][j] == pytest.approx(truth["loss_factors"][k], rel=0.05), k


def test_fix_with_a_value_for_an_elastic_constant_says_how(tmp_path):
    """'--fix G13=3.1GPa' (values are for loss factors): the message says that an elastic
    constant is fixed at the specimen's initial value and how to set it; exit 2."""
    for item in ("G13=3.1GPa", "IM7/977-2.G13=3.1GPa"):
        r = CliRunner().invoke(cli, ["identify", "specimens/example1/S1.1.yaml", "--mesh", "6x6",
                                     "--fix", item, "--no-output"])
        assert r.exit_code == 2
        key = item.split("=")[0]
        assert (f"--fix {item}: an elastic constant is fixed at its initial value in "
                f"specimens/example1/S1.1.yaml; write '--fix {key}'") in r.output


def test_an_frf_files_unstated_frequency_unit_is_in_identifys_json_warnings(frf_specimen):
    # a CSV frf_file headed "f" (no unit): fit-frf warned of it, but identify of a specimen
    # naming the file only logged it; the warning is now the specimen's, in --json's too
    from laminid_cli.frf import io

    path, f_true, _ = frf_specimen
    fs = io.read_frf(path.parent / "plate.frf.h5")
    csv = io.write_frf(path.parent / "plate.csv", fs, overwrite=True)
    lines = csv.read_text().splitlines()
    assert lines[1].startswith("freq_Hz,")
    csv.write_text("\n".join([lines[0], "f" + lines[1][len("freq_Hz"):]] + lines[2:]) + "\n")
    spec_path = path.parent / "plate_csv.yaml"
    text = path.read_text().replace("frf_file: plate.frf.h5", "frf_file: plate.csv")
    spec_path.write_text(text)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if "frf_file:" in ln)
    spec = read_specimen(spec_path)
    assert np.allclose(spec.measured.freq, f_true, rtol=5e-4)
    assert spec.warnings == (
        f"{spec_path}:{line}, field 'measured.frf_file': {csv}: column 1 ('f'): the frequency "
        f"states no unit; its values 0.5 to 699.5 are read as Hz (were they kHz, every mode "
        "would be 1000 times too low; rad/s, 6.28 times too high); if they are not Hz, state "
        "it in the header: 'f [kHz]', 'f [Hz]' or 'f [rad/s]' (also 'f (kHz)' or 'f_kHz'); "
        "'f [Hz]' confirms Hz and silences this warning",)
    r = CliRunner().invoke(cli, ["identify", str(spec_path), "--mesh", "6x6", "--fix",
                                 "nu12,G13,G23", "--json", "--no-output"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["warnings"][0] == spec.warnings[0]
