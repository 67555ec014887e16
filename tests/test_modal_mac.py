"""laminid_cli.modal.mac (the MAC the mesh check prints, 'paired by MAC of w0, lowest ...', and
the mode tracking uses) against closed forms: cos^2 of the angle between two shapes, in the
mass inner product when M is given (Allemang & Brown 1982)."""

import numpy as np
import pytest
import scipy.sparse as sp

from laminid_cli.modal import mac


def test_mac_is_the_squared_cosine_between_the_shapes():
    a = np.array([[1.0, 0.0], [0.0, 1.0]])                  # columns e1, e2
    b = np.array([[1.0], [1.0]])                           # 45 degrees from both
    np.testing.assert_allclose(mac(a, b), [[0.5], [0.5]], rtol=1e-15)
    # any scale or sign of a shape: the same MAC
    np.testing.assert_allclose(mac(-3.0 * a, 0.2 * b), [[0.5], [0.5]], rtol=1e-15)
    # 30 degrees apart: cos^2 = 3/4
    c = np.array([[np.cos(np.pi / 6)], [np.sin(np.pi / 6)]])
    assert mac(a[:, :1], c)[0, 0] == pytest.approx(0.75, rel=1e-14)


def test_mass_weighted_mac():
    """a = (1, 1), b = (1, 2), M = diag(1, 3): (a'Mb)^2 / (a'Ma b'Mb) = 7^2 / (4 * 13);
    without M (a'b)^2 / (a'a b'b) = 3^2 / (2 * 5)."""
    M = sp.diags([1.0, 3.0])
    a = np.array([[1.0], [1.0]])
    b = np.array([[1.0], [2.0]])
    assert mac(a, b, M)[0, 0] == pytest.approx(49 / 52, rel=1e-15)
    assert mac(b, a, M)[0, 0] == pytest.approx(49 / 52, rel=1e-15)
    assert mac(a, b)[0, 0] == pytest.approx(9 / 10, rel=1e-15)


def test_mac_of_two_sampled_beam_shapes():
    """sin(pi x) against sin(pi x) + e sin(2 pi x) on [0, 1] (orthogonal, equal norms):
    MAC = 1 / (1 + e^2); sampled at 2001 midpoints, exact to rounding (discrete orthogonality)."""
    x = (np.arange(2001) + 0.5) / 2001
    e = 0.3
    u = np.sin(np.pi * x)[:, None]
    v = (np.sin(np.pi * x) + e * np.sin(2 * np.pi * x))[:, None]
    assert mac(u, v)[0, 0] == pytest.approx(1 / (1 + e ** 2), rel=1e-12)
    w = np.sin(2 * np.pi * x)[:, None]
    assert mac(u, w)[0, 0] == pytest.approx(0.0, abs=1e-25)
