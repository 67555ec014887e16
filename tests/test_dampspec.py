"""tests/dampspec.py: its copies of every shipped specimen read back with their damping."""

from pathlib import Path

import numpy as np
import pytest

from laminid_cli.specimen import read_specimen
from tests.dampspec import with_damping, with_frequencies

SPECIMENS = sorted((Path(__file__).parent.parent / "specimens").glob("*/*.yaml"))


@pytest.mark.parametrize("src", SPECIMENS, ids=lambda p: p.stem)
def test_damped_copy_text_of_every_shipped_specimen_reads_with_its_damping(src, tmp_path):
    """The damping lines were inserted right after the line of 'frequencies:', inside
    hybrid-cm.yaml's list continued over three lines (a YAML error; the file was repaired by
    hand). Every shipped specimen's copy reads, its frequencies as before, with the damping
    and sigmas written (to 1e-12; none where no mode was found), and a model's frequencies
    put in place of the list."""
    spec = read_specimen(src, log_warnings=False)
    f = spec.measured.freq
    n = f.size
    zeta = 0.001 * (1 + np.arange(n))
    dst = tmp_path / src.name
    dst.write_text(with_damping(src.read_text(), zeta, 0.03 * zeta))
    copy = read_specimen(dst, log_warnings=False)
    np.testing.assert_array_equal(np.isnan(copy.measured.freq), np.isnan(f))
    np.testing.assert_allclose(copy.measured.freq[~np.isnan(f)], f[~np.isnan(f)], rtol=1e-12)
    missed = np.isnan(f)                        # (the reader leaves a mode not found bare)
    np.testing.assert_allclose(copy.measured.damping, np.where(missed, np.nan, zeta),
                               rtol=1e-12)
    np.testing.assert_allclose(copy.measured.damping_sigma,
                               np.where(missed, np.nan, 0.03 * zeta), rtol=1e-12)
    model = 100.0 + 50.0 * np.arange(n)
    dst.write_text(with_damping(with_frequencies(src.read_text(), model), zeta, 0.03 * zeta))
    copy = read_specimen(dst, log_warnings=False)
    np.testing.assert_allclose(copy.measured.freq, model, rtol=1e-12)
    np.testing.assert_allclose(copy.measured.damping, zeta, rtol=1e-12)
