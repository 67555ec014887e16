"""`laminid report`: what the pages' words, keys and legends say is what the page draws
(figure review: a note, key or legend entry for a mark the page does not have misleads)."""

import pytest
from click.testing import CliRunner

from laminid_cli.cli import cli
from laminid_cli.report import report_pages

S21 = "specimens/example2/S2.1.yaml"


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def ax(fig, gid):
    return next(a for a in fig.axes if a.get_gid() == gid)


def cells(axis) -> list[list[str]]:
    d = axis.tables[0].get_celld()
    n_r = 1 + max(i for i, _ in d)
    n_c = 1 + max(j for _, j in d)
    return [[d[i, j].get_text().get_text() for j in range(n_c)] for i in range(n_r)]


def texts(fig) -> str:
    return " ".join(t.get_text() for a in fig.axes for t in a.texts).replace("\n", " ")


@pytest.fixture(scope="module")
def s21_fixed_at_limit(tmp_path_factory):
    """S2.1 (8x8) with --fix-undetermined: G13, on its lower search limit in the first run,
    fixed ("fixed: it was at a search limit"), G23 fixed because undetermined; no constant
    of the answer is on a search limit."""
    out = tmp_path_factory.mktemp("s21fix") / "S2.1.result.h5"
    r = run("identify", S21, "--mesh", "8x8", "--fix-undetermined", "-o", out)
    assert r.exit_code == 0, r.output
    return out


def test_no_search_limit_note_where_no_constant_is_on_one(s21_fixed_at_limit):
    """The summary page's note on "none — on a search limit" belongs to a constant whose
    interval cell says so; a constant fixed because it was on a limit says "fixed: it was at
    a search limit" and has the note on fixed values (the limit note read as if a constant of
    this answer had stopped on its limit)."""
    fig = {p.name: p.figure for p in report_pages(s21_fixed_at_limit)}["summary"]
    table = cells(ax(fig, "constants"))[1:]
    assert any(row[3] == "fixed: it was at a search limit" for row in table)
    assert not any(row[2].startswith("none — on") for row in table)
    notes = texts(fig)
    assert "none — on a search limit" not in notes
    assert "fixed: held at its initial value, not identified" in notes


def _frequency_figure(measured, weight):
    """The measured-vs-model block of page 1 for a plate of four modes (no identification)."""
    from types import SimpleNamespace

    import numpy as np

    from laminid_cli.report import _figure, frequency_block

    model = np.array([100.0, 200.0, 300.0, 400.0])
    measured = np.asarray(measured, float)
    res = (measured - model) / measured * 100
    fr = SimpleNamespace(model=model, measured=measured, model_mode=np.arange(1, 5),
                         weight=np.asarray(weight, float), residual_percent=res,
                         rms_residual_percent=0.5)
    fig = _figure()
    frequency_block(fig, fig.add_gridspec(1, 1)[0, 0], SimpleNamespace(frequencies=fr))
    return ax(fig, "residuals")


@pytest.mark.parametrize("measured, weight, key", [
    ([100.5, 199.0, 301.0, 398.0], [1, 1, 1, 1], False),          # every mode fitted
    ([100.5, float("nan"), 301.0, 398.0], [1, 0, 1, 1], False),   # not measured: no bar
    ([100.5, 199.0, 301.0, 398.0], [1, 0, 1, 1], True)])          # measured, weight 0
def test_residual_bars_key_hatched_only_where_a_bar_is(measured, weight, key):
    """'hatched: weight 0' under the residual bars where one is hatched (every page 1 said
    it, also with every weight 1 or a weight-0 mode that was not measured and has no bar)."""
    a = _frequency_figure(measured, weight)
    assert a.get_xlabel().startswith("(measured − model)/measured (%)")
    assert ("hatched: weight 0" in a.get_xlabel()) is key
    hatches = [b.get_hatch() for b in a.patches if b.get_hatch()]
    assert bool(hatches) is (0 in weight)
