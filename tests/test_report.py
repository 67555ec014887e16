"""`laminid report`: files produced, and the numbers drawn are those of the result file."""

import re
import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.forward import build_forward_model
from laminid_cli.frf.store import write_frf_h5
from laminid_cli.report import read_intervals, read_result, report_pages
from laminid_cli.results import read_h5
from laminid_cli.specimen import read_specimen
from tests.frf_synth import synth_frf

S14 = "specimens/example1/S1.4.yaml"
S21 = "specimens/example2/S2.1.yaml"
MEASURED_BLOCK = ("  frequencies: [72.78, 121.00, 191.38, 286.78, 315.12, 340.40, 400.12, 433.84, "
                  "634.81, 653.56, 712.43, 789.97]   # Hz, Table 5")


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture(scope="module")
def batch_dir(tmp_path_factory):
    """A batch over S1.4 and S2.1 (6x6): two result files and the summary."""
    tmp = tmp_path_factory.mktemp("rep")
    for src in (S14, S21):
        shutil.copy(src, tmp / src.rsplit("/", 1)[1])
    r = run("batch", tmp, "--mesh", "6x6", "--out", tmp / "out")
    assert r.exit_code == 0, r.output
    return tmp / "out"


def n_pdf_pages(path) -> int:
    return len(re.findall(rb"/Type\s*/Page\b(?!s)", path.read_bytes()))


def test_pdf_report_of_a_result(batch_dir, tmp_path):
    out = tmp_path / "r.pdf"
    r = run("report", batch_dir / "S1.4.result.h5", "-o", out)
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:5] == b"%PDF-" and out.stat().st_size > 50_000
    # 12 modes: frequencies, one page of modes, history, sensitivities, intervals
    assert n_pdf_pages(out) == 5
    assert "5 pages (frequencies, modes-1, history, sensitivities, intervals)" in r.output
    r = run("report", batch_dir / "S1.4.result.h5", "-o", out)
    assert r.exit_code == 2 and "file exists" in r.output


def test_png_pages_and_default_name(batch_dir, tmp_path):
    src = tmp_path / "S2.1.result.h5"
    shutil.copy(batch_dir / "S2.1.result.h5", src)
    r = run("report", src, "-o", tmp_path / "rep.png", "--dpi", "60")
    assert r.exit_code == 0, r.output
    pngs = sorted(tmp_path.glob("rep-*.png"))
    assert [p.name for p in pngs] == [f"rep-{k}.png" for k in range(1, 6)]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
               for p in pngs)
    r = run("report", src)
    assert r.exit_code == 0 and (tmp_path / "S2.1.report.pdf").stat().st_size > 0


def test_plotted_numbers_come_from_the_result_file(batch_dir):
    path = batch_dir / "S1.4.result.h5"
    h = read_h5(path)
    pages = {p.name: p.figure for p in report_pages(path)}

    def ax(fig, gid):
        return next(a for a in fig.axes if a.get_gid() == gid)

    fr = h["frequencies"]
    bars = ax(pages["frequencies"], "residuals").patches
    assert np.allclose([b.get_height() for b in bars], fr["residual_percent"], rtol=0, atol=0)
    fbars = ax(pages["frequencies"], "frequencies").patches
    n = fr["model"].size
    assert np.array_equal([b.get_height() for b in fbars[n:]], fr["model"])
    assert np.array_equal([b.get_height() for b in fbars[:n]], fr["measured"])
    # mode shapes: title frequencies, and the nodal line at w = 0
    for k in range(n):
        a = ax(pages["modes-1"], f"mode-{k + 1}")
        assert f"{fr['model'][k]:.1f} Hz" in a.get_title()
        assert f"measured {fr['measured'][k]:.1f} Hz" in a.get_title()
    # history and sensitivities
    line = ax(pages["history"], "objective").get_lines()[0]
    assert np.array_equal(line.get_ydata(), h["history"]["objective"])
    img = ax(pages["sensitivities"], "sensitivity").get_images()[0]
    assert np.array_equal(img.get_array(), h["sensitivities"]["dlnf_dlnP"])
    labels = [t.get_text() for t in ax(pages["sensitivities"], "sensitivity").get_xticklabels()]
    assert labels == ["E1", "E2", "G12", "G13", "G23", "nu12"]


def test_mode_shape_interpolation_reproduces_the_nodal_values(batch_dir):
    from laminid_cli.report import mode_shape_grid

    h = read_result(batch_dir / "S1.4.result.h5")
    x, y, tris, w = mode_shape_grid(h, 0, n_sub=2)
    nodes, wn = h["mesh"]["nodes"], h["modes"]["w"][:, 0]
    # with 2 subdivisions every element node is a sample point: same value at the same place
    for (xn, yn), v in zip(nodes[::7], wn[::7]):
        k = np.flatnonzero(np.hypot(x - xn, y - yn) < 1e-9)
        assert k.size and np.allclose(w[k], v, rtol=1e-12, atol=1e-15)
    assert tris.max() < x.size and tris.shape[1] == 3


def test_confidence_intervals_of_the_uncertainty_group(batch_dir):
    path = batch_dir / "S1.4.result.h5"
    h = read_h5(path)
    u = h["uncertainty"]
    iv = read_intervals(read_result(path))
    labels = [x.decode() if isinstance(x, bytes) else x for x in u["labels"]]
    assert len(labels) == 6
    for lab, lo, hi in zip(labels, u["lower"], u["upper"]):
        m, k = lab.rsplit(".", 1)
        assert iv[m][k] == (lo, hi)
    pages = {p.name: p.figure for p in report_pages(path)}
    a = next(a for a in pages["intervals"].axes if a.get_gid() == "intervals")
    segs = a.collections[0].get_segments()
    rel = [(s[0, 0], s[1, 0]) for s in segs]
    assert np.allclose(rel, [((lo - v) / abs(v) * 100, (hi - v) / abs(v) * 100)
                             for lo, hi, v in zip(u["lower"], u["upper"], u["value"])])


def test_intervals_panel_is_skipped_without_the_group_and_reads_per_material_layout(
        batch_dir, tmp_path):
    path = tmp_path / "u.result.h5"
    shutil.copy(batch_dir / "S2.1.result.h5", path)
    with h5py.File(path, "r+") as f:
        del f["uncertainty"]
    assert "intervals" not in [p.name for p in report_pages(path)]
    with h5py.File(path, "r+") as f:
        g = f["materials"][next(iter(f["materials"]))]
        name = g.attrs["name"]
        value = {k: g[k][()] for k in ("E1", "E2", "G12")}
        u = f.create_group("uncertainty").create_group(next(iter(f["materials"])))
        u.attrs["name"] = name
        for k, v in value.items():
            u.create_dataset(k, data=[0.97 * v, 1.04 * v])
    iv = read_intervals(read_result(path))
    assert iv[name]["E1"] == pytest.approx((0.97 * value["E1"], 1.04 * value["E1"]))
    pages = {p.name: p.figure for p in report_pages(path)}
    a = next(a for a in pages["intervals"].axes if a.get_gid() == "intervals")
    segs = a.collections[0].get_segments()
    assert np.allclose([s[:, 0] for s in segs], [[-3, 4]] * 3)          # percent of the value
    r = run("report", path, "-o", tmp_path / "u.pdf")
    assert r.exit_code == 0 and "intervals" in r.output


def test_frf_page_for_a_specimen_fitted_from_an_frf_file(tmp_path):
    spec = read_specimen(S21)
    fm = build_forward_model(spec, (6, 6))
    f_true = fm.solve([fm.initial_constants[0]], 8).freq
    freq = np.arange(0.5, 700.0, 0.5)
    rng = np.random.default_rng(3)
    constants = rng.choice([-1, 1], size=(3, 8)) * rng.uniform(0.3, 1.0, size=(3, 8))
    frf = synth_frf(freq, np.column_stack([f_true, np.full(8, 0.008)]), constants,
                    kind="accelerance", noise=0.005, seed=4)
    write_frf_h5(tmp_path / "plate.frf.h5", freq, frf, units="(m/s^2)/N")
    text = open(S21).read().replace(MEASURED_BLOCK, "  frf_file: plate.frf.h5\n  modes: 8")
    (tmp_path / "plate.yaml").write_text(text)
    res = tmp_path / "plate.result.h5"
    r = run("identify", tmp_path / "plate.yaml", "--mesh", "6x6", "--fix", "nu12,G13,G23",
            "-o", res)
    assert r.exit_code == 0, r.output
    pages = {p.name: p.figure for p in report_pages(res)}
    a = next(a for a in pages["frf"].axes if a.get_gid() == "frf")
    dashed = [ln.get_xdata()[0] for ln in a.get_lines() if ln.get_linestyle() == "--"]
    assert np.allclose(sorted(dashed), f_true, rtol=1e-3)                # RFP modes
    dotted = [ln.get_xdata()[0] for ln in a.get_lines() if ln.get_linestyle() == ":"]
    assert np.array_equal(dotted, read_h5(res)["frequencies"]["model"])
    r = run("report", res, "-o", tmp_path / "plate.png", "--dpi", "50")
    assert r.exit_code == 0 and "frf" in r.output
    assert (tmp_path / "plate-5.png").stat().st_size > 0


def test_report_of_a_batch_summary(batch_dir, tmp_path):
    for src in ("summary.csv", "summary.json"):
        out = tmp_path / (src + ".pdf")
        r = run("report", batch_dir / src, "-o", out)
        assert r.exit_code == 0, r.output
        assert n_pdf_pages(out) == 2
    pages = {p.name: p.figure for p in report_pages(batch_dir / "summary.csv")}
    a = next(a for a in pages["constants"].axes if a.get_gid() == "across-E1")
    h = read_h5(batch_dir / "S1.4.result.h5")
    E1 = h["materials"][next(k for k in h["materials"] if not k.startswith("@"))]["E1"]
    ys = np.concatenate([ln.get_ydata() for ln in a.get_lines() if len(ln.get_ydata())])
    assert np.any(ys == E1 / 1e9)
    assert [t.get_text() for t in a.get_xticklabels()] == ["S1.4", "S2.1"]


def test_report_errors(batch_dir, tmp_path):
    bad = tmp_path / "x.h5"
    with h5py.File(bad, "w") as f:
        f.attrs["format"] = "laminid-frf"
    r = run("report", bad, "-o", tmp_path / "x.pdf")
    assert r.exit_code == 2 and "not a laminid identification result" in r.output
    r = run("report", batch_dir / "S1.4.result.h5", "-o", tmp_path / "x.svg")
    assert r.exit_code == 2 and "use .pdf or .png" in r.output
    (tmp_path / "s.csv").write_text("a,b\n1,2\n")
    r = run("report", tmp_path / "s.csv", "-o", tmp_path / "s.pdf")
    assert r.exit_code == 2 and "not a laminid batch summary" in r.output
    assert not list(tmp_path.glob("*.pdf"))
