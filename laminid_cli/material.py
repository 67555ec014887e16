"""Orthotropic ply material model of the paper (Araujo et al. 2000, section 2 and Appendix A).

A ply's constitutive matrix in laminate axes is ``Q = E1 / (8 alpha0) * c(theta)`` (Eq. 6) with
``c`` the 5x5 matrix of Eqs 7-8 in the strain order ``[xx, yy, yz, xz, xy]`` (engineering shear
strains). ``c`` is *affine* in the five alpha parameters of Eq. 4, so

    c(theta) = C0(theta) + a2 C2(theta) + a3 C3(theta) + a4 C4(theta) + a8 C8(theta) + a9 C9(theta)

and :func:`c_basis` returns the six matrices ``[C0, C2, C3, C4, C8, C9]``; the finite-element
stiffness is assembled once per basis matrix (fe.assembly; README, "Reduced-order solver").

Angles: theta in radians in the x-y plane from x towards y (fibre direction 1 at +theta).
Moduli in Pa. Everything here is a pure function on floats or numpy arrays.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

#: names of the engineering constants, in the order used everywhere in laminid
CONSTANT_NAMES = ("E1", "E2", "G12", "G13", "G23", "nu12")
#: names of the design variables of one material (paper Eq. 14; alpha_1 = E1 / E1_initial)
ALPHA_NAMES = ("a1", "a2", "a3", "a4", "a8", "a9")
#: units of the engineering constants
CONSTANT_UNITS = {"E1": "Pa", "E2": "Pa", "G12": "Pa", "G13": "Pa", "G23": "Pa", "nu12": "1"}


@dataclass(frozen=True)
class ElasticConstants:
    """Engineering constants of an orthotropic ply in its own axes (1 fibre, 2 transverse, 3 normal).

    Moduli in Pa; ``nu12`` is the major Poisson ratio (dimensionless).
    """

    E1: float
    E2: float
    G12: float
    G13: float
    G23: float
    nu12: float

    def as_array(self) -> np.ndarray:
        """Constants in :data:`CONSTANT_NAMES` order, shape (6,). (Not ``astuple``: it
        deep-copies each field, and this runs at every optimiser evaluation.)"""
        return np.array([self.E1, self.E2, self.G12, self.G13, self.G23, self.nu12],
                        dtype=float)

    @classmethod
    def from_array(cls, values) -> "ElasticConstants":
        return cls(*(float(v) for v in values))

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


def alpha0(E1, E2, nu12):
    """alpha_0 = 1 - nu12^2 E2 / E1 (paper, after Eq. 4)."""
    return 1.0 - nu12**2 * E2 / E1


def alphas_from_constants(c: ElasticConstants) -> np.ndarray:
    """Alpha parameters ``[a0, a2, a3, a4, a8, a9]`` of Eq. 4, shape (6,)."""
    a0 = alpha0(c.E1, c.E2, c.nu12)
    r = c.E2 / c.E1
    return np.array([
        a0,
        4.0 - 4.0 * r,
        1.0 + (1.0 - 2.0 * c.nu12) * r - 4.0 * a0 * c.G12 / c.E1,
        1.0 + (1.0 + 6.0 * c.nu12) * r - 4.0 * a0 * c.G12 / c.E1,
        4.0 * (c.G13 + c.G23) * a0 / c.E1,
        4.0 * (c.G13 - c.G23) * a0 / c.E1,
    ])


def alpha0_from_alphas(a2, a3, a4):
    """alpha_0 from the alpha parameters (last line of Eq. 5)."""
    return 1.0 - (a4 - a3) ** 2 / (16.0 * (4.0 - a2))


def constants_from_alphas(E1: float, a2: float, a3: float, a4: float, a8: float,
                          a9: float) -> ElasticConstants:
    """Inverse relations, Eq. 5: engineering constants from E1 and the alpha parameters."""
    a0 = alpha0_from_alphas(a2, a3, a4)
    return ElasticConstants(
        E1=E1,
        E2=E1 * (4.0 - a2) / 4.0,
        G12=E1 * (8.0 - a2 - 3.0 * a3 - a4) / (16.0 * a0),
        G13=E1 * (a8 + a9) / (8.0 * a0),
        G23=E1 * (a8 - a9) / (8.0 * a0),
        nu12=(a4 - a3) / (8.0 - 2.0 * a2),
    )


def c_basis(theta) -> np.ndarray:
    """The six basis matrices of the affine split of Eq. 8.

    Parameters
    ----------
    theta : float or array (n,), rad
        Ply angles.

    Returns
    -------
    C : array (6, 5, 5) for a scalar angle, else (n, 6, 5, 5)
        ``[C0, C2, C3, C4, C8, C9]`` with ``c(theta) = C0 + a2 C2 + a3 C3 + a4 C4 + a8 C8 + a9 C9``.
    """
    th = np.asarray(theta, dtype=float)
    scalar = th.ndim == 0
    th = np.atleast_1d(th)
    c2, s2, c4, s4 = np.cos(2 * th), np.sin(2 * th), np.cos(4 * th), np.sin(4 * th)
    one = np.ones_like(th)
    C = np.zeros(th.shape + (6, 5, 5))
    XX, YY, YZ, XZ, XY = 0, 1, 2, 3, 4

    def put(j, i, k, val):
        C[..., j, i, k] = val
        C[..., j, k, i] = val

    # C0: the constant part
    put(0, XX, XX, 8 * one)
    put(0, YY, YY, 8 * one)
    put(0, XY, XY, 4 * one)
    # C2: alpha_2
    put(1, XX, XX, -(1 - c2))
    put(1, XX, XY, 0.5 * s2)
    put(1, YY, YY, -(1 + c2))
    put(1, YY, XY, 0.5 * s2)
    put(1, XY, XY, -0.5 * one)
    # C3: alpha_3
    put(2, XX, XX, -(1 - c4))
    put(2, XX, YY, -c4)
    put(2, XX, XY, s4)
    put(2, YY, YY, -(1 - c4))
    put(2, YY, XY, -s4)
    put(2, XY, XY, -0.5 - c4)
    # C4: alpha_4
    put(3, XX, YY, one)
    put(3, XY, XY, -0.5 * one)
    # C8: alpha_8
    put(4, YZ, YZ, one)
    put(4, XZ, XZ, one)
    # C9: alpha_9
    put(5, YZ, YZ, -c2)
    put(5, YZ, XZ, s2)
    put(5, XZ, XZ, c2)
    return C[0] if scalar else C


def basis_coefficients(c: ElasticConstants) -> np.ndarray:
    """Coefficients ``s * [1, a2, a3, a4, a8, a9]`` with ``s = E1 / (8 a0)``, shape (6,), Pa.

    ``Q(theta) = sum_j coef[j] * c_basis(theta)[j]``.
    """
    a = alphas_from_constants(c)
    s = c.E1 / (8.0 * a[0])
    return s * np.array([1.0, a[1], a[2], a[3], a[4], a[5]])


def ply_stiffness(c: ElasticConstants, theta) -> np.ndarray:
    """Constitutive matrix Q of Eq. 6 in laminate axes, (5, 5) or (n, 5, 5), Pa."""
    return np.tensordot(c_basis(theta), basis_coefficients(c), axes=([-3], [0]))


def feasibility_margins(c: ElasticConstants) -> dict[str, float]:
    """Constraint values of the paper's Eq. 22 (feasible when every value is < 0).

    The paper's g2 = E2 - E1 (alpha_2 >= 0) comes from its choice of design variables, not from
    positive definiteness; laminid uses it for fibre-reinforced plies (E1 is the stiffer axis),
    see :func:`infeasibility_reasons`.
    """
    return {
        "E1 > 0": -c.E1,
        "E2 <= E1": c.E2 - c.E1,
        "G12 > 0": -c.G12 / c.E1,
        "|nu12| < sqrt(E1/E2)": abs(c.nu12) - np.sqrt(c.E1 / c.E2) if c.E2 > 0 else np.inf,
        "G23 > 0": -c.G23 / c.E1,
        "G13 > 0": -c.G13 / c.E1,
    }


def infeasibility_reasons(c: ElasticConstants) -> list[str]:
    """Plain-language list of the violated conditions of Eq. 22 (empty when feasible).

    Positive definiteness of Q needs E1, E2, G12, G13, G23 > 0 and |nu12| < sqrt(E1/E2). The
    paper also asks E2 <= E1 (direction 1 is the fibre direction); E2 == E1 (isotropic) is
    allowed.
    """
    reasons = []
    for name in ("E1", "E2", "G12", "G13", "G23"):
        value = getattr(c, name)
        if not np.isfinite(value) or value <= 0:
            reasons.append(f"{name} must be positive (got {value / 1e9:.4g} GPa)")
    if not np.isfinite(c.nu12):
        reasons.append(f"nu12 must be a finite number (got {c.nu12})")
    if reasons:
        return reasons
    if c.E2 > c.E1:
        reasons.append(f"E2 ({c.E2 / 1e9:.4g} GPa) must not exceed E1 ({c.E1 / 1e9:.4g} GPa): "
                       "direction 1 is the fibre (stiffer) direction")
    limit = np.sqrt(c.E1 / c.E2)
    if abs(c.nu12) >= limit:
        reasons.append(f"|nu12| = {abs(c.nu12):.4g} must be below sqrt(E1/E2) = {limit:.4g} "
                       "(constitutive matrix not positive definite)")
    return reasons


@dataclass(frozen=True)
class GlobalProperties:
    """Equivalent laminate properties of Appendix A, moduli in Pa."""

    Ex: float
    Ey: float
    Gxy: float
    Gxz: float
    Gyz: float
    nu_xy: float
    nu_yx: float

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


GLOBAL_UNITS = {"Ex": "Pa", "Ey": "Pa", "Gxy": "Pa", "Gxz": "Pa", "Gyz": "Pa", "nu_xy": "1",
                "nu_yx": "1"}


def global_properties(Q_plies: np.ndarray, thicknesses: np.ndarray) -> GlobalProperties:
    """Global laminate properties, Appendix A (Eqs A.1, A.2).

    Parameters
    ----------
    Q_plies : array (n_plies, 5, 5), Pa
        Ply constitutive matrices in laminate axes (strain order xx, yy, yz, xz, xy).
    thicknesses : array (n_plies,), m
    """
    return GlobalProperties(*(float(v) for v in global_property_array(Q_plies, thicknesses)))


def global_property_array(Q_plies: np.ndarray, thicknesses: np.ndarray) -> np.ndarray:
    """:func:`global_properties` as an array (..., 7) in :class:`GlobalProperties` order, of
    ``Q_plies`` (..., n_plies, 5, 5): many sets of ply matrices at once (a Monte Carlo's
    trials, laminid_cli.global_uncertainty)."""
    t = np.asarray(thicknesses, dtype=float)
    C = np.einsum("l,...lij->...ij", t, Q_plies)  # Eq. A.1
    S = t.sum() * np.linalg.inv(C)                # Eq. A.2
    Ex, Ey = 1.0 / S[..., 0, 0], 1.0 / S[..., 1, 1]
    return np.stack([Ex, Ey, 1.0 / S[..., 4, 4], 1.0 / S[..., 3, 3], 1.0 / S[..., 2, 2],
                     -S[..., 0, 1] * Ex, -S[..., 1, 0] * Ey], axis=-1)
