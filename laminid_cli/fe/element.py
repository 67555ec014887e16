"""Eight-node serendipity plate element with the nine-variable third-order displacement field.

Kinematics (paper Eq. 1), written with the normalised thickness coordinate zeta = 2 z / h so
that every nodal variable has the unit of a displacement (m) and the matrices stay well
conditioned for thin plates (a/h up to 1000):

    u = u0 + zeta psi_x + zeta^2 U + zeta^3 Psi_x        psi_x = (h/2) theta_x, U = (h/2)^2 u0*,
    v = v0 + zeta psi_y + zeta^2 V + zeta^3 Psi_y        Psi_x = (h/2)^3 theta_x*, same for y
    w = w0

The nine nodal variables, in this order (``DOF_NAMES``): u0, v0, w0, psi_x, psi_y, U, V, Psi_x,
Psi_y. The scaling is a diagonal change of variables: eigenvalues are unchanged.

Generalised strains
-------------------
In-plane, 12 components, four groups k = 0..3 of [d/dx of x-variable, d/dy of y-variable,
d/dy x + d/dx y] for the variable pairs (u0, v0), (psi), (U, V), (Psi)::

    eps_inplane(z) = sum_k zeta^k e_k

Transverse shear, 6 components, three groups k = 0..2 of [yz, xz] (strain order of Eq. 7)::

    gamma(z) = g_0 + zeta g_1 + zeta^2 g_2
    g_0 = [w,y + (2/h) psi_y,  w,x + (2/h) psi_x],  g_1 = (2/h) [2 V, 2 U],  g_2 = (2/h) [3 Psi_y, 3 Psi_x]

Energy densities per unit area: e^T D_p e with ``D_p = sum_plies kron(H4, Q_pp)`` and
``H4[k, l] = int zeta^(k+l) dz`` (exact per ply), and g^T D_s g with ``D_s = sum kron(H3, Q_ss)``.

Integration: selective by default, 3x3 Gauss points for the in-plane terms and 2x2 for the
transverse shear terms. Full 3x3 shear integration locks as the plate gets thin; the selective
rule does not, and keeps exactly six zero-energy modes for a free plate (tests prove both).
"""

from __future__ import annotations

import numpy as np

DOF_NAMES = ("u0", "v0", "w0", "psi_x", "psi_y", "U", "V", "Psi_x", "Psi_y")
N_DOF_NODE = 9
N_NODE_EL = 8
N_DOF_EL = N_DOF_NODE * N_NODE_EL   # 72

#: (xi, eta) of the eight nodes, order of laminid_cli.fe.mesh
NODE_XI = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [0, -1], [1, 0], [0, 1], [-1, 0]], float)

# DOF index of the "x" and "y" variable of each in-plane group k = 0..3
_INPLANE_X = (0, 3, 5, 7)
_INPLANE_Y = (1, 4, 6, 8)


def gauss_rule(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Tensor Gauss-Legendre rule on [-1, 1]^2: points (n*n, 2) and weights (n*n,)."""
    x, w = np.polynomial.legendre.leggauss(n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    W = np.outer(w, w)
    return np.column_stack([X.ravel(), Y.ravel()]), W.ravel()


def shape_functions(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Serendipity Q8 shape functions and their (xi, eta) derivatives.

    Parameters
    ----------
    pts : (n_pts, 2) natural coordinates

    Returns
    -------
    N : (n_pts, 8)
    dN : (n_pts, 2, 8), derivatives with respect to xi (row 0) and eta (row 1)
    """
    xi, eta = pts[:, 0:1], pts[:, 1:2]
    xn, yn = NODE_XI[:, 0], NODE_XI[:, 1]
    corner = (xn != 0) & (yn != 0)
    N = np.empty((pts.shape[0], 8))
    dxi = np.empty_like(N)
    deta = np.empty_like(N)
    # corners: 1/4 (1 + xi xi_i)(1 + eta eta_i)(xi xi_i + eta eta_i - 1)
    a, b = 1 + xi * xn, 1 + eta * yn
    c = xi * xn + eta * yn - 1
    N[:, corner] = (0.25 * a * b * c)[:, corner]
    dxi[:, corner] = (0.25 * xn * b * (c + a))[:, corner]
    deta[:, corner] = (0.25 * yn * a * (c + b))[:, corner]
    # mid-sides on xi = 0: 1/2 (1 - xi^2)(1 + eta eta_i)
    mx = xn == 0
    N[:, mx] = (0.5 * (1 - xi**2) * b)[:, mx]
    dxi[:, mx] = (-xi * b)[:, mx]
    deta[:, mx] = (0.5 * (1 - xi**2) * yn)[:, mx]
    # mid-sides on eta = 0: 1/2 (1 + xi xi_i)(1 - eta^2)
    my = yn == 0
    N[:, my] = (0.5 * a * (1 - eta**2))[:, my]
    dxi[:, my] = (0.5 * xn * (1 - eta**2))[:, my]
    deta[:, my] = (-eta * a)[:, my]
    return N, np.stack([dxi, deta], axis=1)


def physical_derivatives(xy: np.ndarray, dN: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function derivatives in x, y and the Jacobian determinant, for all elements at once.

    Parameters
    ----------
    xy : (n_el, 8, 2) node coordinates, m
    dN : (n_gp, 2, 8) natural derivatives

    Returns
    -------
    dNdx : (n_el, n_gp, 2, 8), 1/m
    detJ : (n_el, n_gp), m^2
    """
    J = np.einsum("gan,enb->egab", dN, xy)            # J[a, b] = d x_b / d xi_a
    detJ = J[..., 0, 0] * J[..., 1, 1] - J[..., 0, 1] * J[..., 1, 0]
    if np.any(detJ <= 0):
        from laminid_cli.errors import ModelError

        raise ModelError("mesh has a distorted or inverted element (non-positive Jacobian)")
    inv = np.empty_like(J)
    inv[..., 0, 0] = J[..., 1, 1]
    inv[..., 1, 1] = J[..., 0, 0]
    inv[..., 0, 1] = -J[..., 0, 1]
    inv[..., 1, 0] = -J[..., 1, 0]
    inv /= detJ[..., None, None]
    dNdx = np.einsum("egba,gan->egbn", inv, dN)
    return dNdx, detJ


def inplane_operator(dNdx: np.ndarray) -> np.ndarray:
    """B matrix of the 12 in-plane generalised strains, (n_el, n_gp, 12, 72)."""
    n_el, n_gp = dNdx.shape[:2]
    B = np.zeros((n_el, n_gp, 12, N_NODE_EL, N_DOF_NODE))
    dx, dy = dNdx[:, :, 0, :], dNdx[:, :, 1, :]
    for k, (ix, iy) in enumerate(zip(_INPLANE_X, _INPLANE_Y)):
        B[:, :, 3 * k + 0, :, ix] = dx
        B[:, :, 3 * k + 1, :, iy] = dy
        B[:, :, 3 * k + 2, :, ix] = dy
        B[:, :, 3 * k + 2, :, iy] = dx
    return B.reshape(n_el, n_gp, 12, N_DOF_EL)


def shear_operator(N: np.ndarray, dNdx: np.ndarray, h: float) -> np.ndarray:
    """B matrix of the 6 transverse shear generalised strains, (n_el, n_gp, 6, 72).

    Order [g0_yz, g0_xz, g1_yz, g1_xz, g2_yz, g2_xz] (module docstring).
    """
    n_el, n_gp = dNdx.shape[:2]
    B = np.zeros((n_el, n_gp, 6, N_NODE_EL, N_DOF_NODE))
    r = 2.0 / h
    Nb = np.broadcast_to(N, (n_el, n_gp, N_NODE_EL))
    B[:, :, 0, :, 2] = dNdx[:, :, 1, :]     # w,y
    B[:, :, 0, :, 4] = r * Nb               # (2/h) psi_y
    B[:, :, 1, :, 2] = dNdx[:, :, 0, :]     # w,x
    B[:, :, 1, :, 3] = r * Nb               # (2/h) psi_x
    B[:, :, 2, :, 6] = 2 * r * Nb           # (2/h) 2 V
    B[:, :, 3, :, 5] = 2 * r * Nb           # (2/h) 2 U
    B[:, :, 4, :, 8] = 3 * r * Nb           # (2/h) 3 Psi_y
    B[:, :, 5, :, 7] = 3 * r * Nb           # (2/h) 3 Psi_x
    return B.reshape(n_el, n_gp, 6, N_DOF_EL)


def thickness_moments(z: np.ndarray, h: float, n_pow: int) -> np.ndarray:
    """Exact ply integrals ``int_{z_b}^{z_t} zeta^k dz`` with zeta = 2 z / h.

    Parameters
    ----------
    z : (n_plies + 1,) ply interfaces, m, bottom to top
    n_pow : highest power + 1

    Returns
    -------
    (n_plies, n_pow) in m
    """
    zeta = 2.0 * np.asarray(z, float) / h
    k = np.arange(n_pow)
    upper = zeta[1:, None] ** (k + 1)
    lower = zeta[:-1, None] ** (k + 1)
    return (h / 2.0) * (upper - lower) / (k + 1)


def laminate_operators(z: np.ndarray, h: float, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Generalised constitutive matrices summed over plies.

    Parameters
    ----------
    z : (n_plies + 1,) m
    Q : (..., n_plies, 5, 5) ply matrices in laminate axes, strain order [xx, yy, yz, xz, xy];
        leading axes (e.g. basis index) are kept.

    Returns
    -------
    D_p : (..., 12, 12), in-plane, N/m
    D_s : (..., 6, 6), transverse shear, N/m
    """
    mom = thickness_moments(z, h, 7)                                   # (n_plies, 7)
    k = np.arange(4)
    H4 = mom[:, k[:, None] + k[None, :]]                               # (n_plies, 4, 4)
    k3 = np.arange(3)
    H3 = mom[:, k3[:, None] + k3[None, :]]                             # (n_plies, 3, 3)
    ip = [0, 1, 4]
    sh = [2, 3]
    Qp = Q[..., ip, :][..., :, ip]                                     # (..., n_plies, 3, 3)
    Qs = Q[..., sh, :][..., :, sh]
    D_p = np.einsum("lkm,...lij->...kimj", H4, Qp).reshape(Q.shape[:-3] + (12, 12))
    D_s = np.einsum("lkm,...lij->...kimj", H3, Qs).reshape(Q.shape[:-3] + (6, 6))
    return D_p, D_s


def inertia_operator(z: np.ndarray, h: float, density: np.ndarray) -> np.ndarray:
    """9x9 inertia matrix J of the nodal variables per unit area (kg/m^2).

    Kinetic energy density = 1/2 qdot^T J qdot with q the nine variables at a point; the x
    variables (u0, psi_x, U, Psi_x) couple through ``sum rho int zeta^(k+l) dz``, likewise y.
    """
    mom = thickness_moments(z, h, 7)
    I = np.einsum("l,lk->k", np.asarray(density, float), mom)         # (7,)
    J = np.zeros((N_DOF_NODE, N_DOF_NODE))
    for group in (_INPLANE_X, _INPLANE_Y):
        for k, i in enumerate(group):
            for m, j in enumerate(group):
                J[i, j] = I[k + m]
    J[2, 2] = I[0]
    return J
