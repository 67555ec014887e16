"""scripts/example_frf.py (make example-frf): a re-run keeps what it would overwrite."""

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
