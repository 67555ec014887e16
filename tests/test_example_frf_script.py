"""scripts/example_frf.py (make example-frf): a re-run keeps what it would overwrite; fit-frf of
its FRFs gives back the truth.json modes."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("example_frf", ROOT / "scripts/example_frf.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_a_rerun_keeps_the_plate_yaml_that_fit_frf_filled_in(tmp_path, capsys):
    """make example-frf, then fit-frf --into plate.yaml (or an edit), then make example-frf
    again: the filled-in plate.yaml was overwritten by the blank one without a word. It is
    now kept in a backup that overwrites nothing (plate.yaml.bak, as fit-frf --into names
    them), and the run says so; a re-run over its own file keeps nothing."""
    mod = _script()
    out = tmp_path / "ex"
    assert mod.main(["--out", str(out), "--points", "1"]) == 0
    spec = out / "plate.yaml"
    blank = spec.read_text(encoding="utf-8")
    assert mod.main(["--out", str(out), "--points", "1"]) == 0       # its own file: nothing kept
    assert not list(out.glob("plate.yaml.bak*"))
    edited = blank + "# frequencies filled in by hand\n"
    spec.write_text(edited, encoding="utf-8")
    capsys.readouterr()
    assert mod.main(["--out", str(out), "--points", "1"]) == 0
    assert (out / "plate.yaml.bak").read_text(encoding="utf-8") == edited
    assert spec.read_text(encoding="utf-8") == blank
    assert f"kept as {out / 'plate.yaml.bak'}" in capsys.readouterr().out


def test_fit_frf_of_the_example_gives_back_the_modes_it_was_made_from(tmp_path):
    """make example-frf (8 points, 0.5 % noise, seed 0), then fit-frf: every frequency
    within 0.005 % of truth.json's (the FE model's at the truth constants; measured: at most
    0.0012 %, mode 1) and every damping ratio within 1.5 % of the truth's (half the modal
    loss factor of the truth ply loss factors; measured: at most 0.32 %). Both truths are
    made by the script from the model, none by the RFP fitter."""
    import json

    import numpy as np

    from tests.clihelp import run

    out = tmp_path / "ex"
    assert _script().main(["--out", str(out)]) == 0
    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    r = run("fit-frf", out / "plate.frf.h5", "--json")
    assert r.exit_code == 0, r.output
    modes = json.loads(r.output)["modes"]
    f = np.array([m["freq_hz"] for m in modes])
    z = np.array([m["damping_ratio"] for m in modes])
    assert f.size == len(truth["frequencies_hz"]) == 13
    np.testing.assert_allclose(f, truth["frequencies_hz"], rtol=5e-5)
    np.testing.assert_allclose(z, truth["damping_ratios"], rtol=0.015)
