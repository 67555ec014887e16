"""Navier closed-form frequencies of the nine-variable third-order theory (test oracle).

Independent reference for the finite-element model: the same plate theory (paper section 2,
Eq. 1; README, "How we know it is right") solved exactly for a simply supported cross-ply
rectangular plate.
Pure numpy; imports nothing from ``laminid_cli`` so that a mistake there cannot hide here.

Theory
------
Plate ``0 <= x <= a``, ``0 <= y <= b``, ``z`` from the mid-plane. Displacements (paper Eq. 1)::

    u = u0 + z tx + z^2 u0* + z^3 tx*,   v = v0 + z ty + z^2 v0* + z^3 ty*,   w = w0.

Strains, order ``[xx, yy, yz, xz, xy]`` (engineering shear), ``ezz`` ignored (plane stress with
the reduced ply stiffness)::

    exx = u,x    eyy = v,y    gxy = u,y + v,x
    gxz = tx + w0,x + 2 z u0* + 3 z^2 tx*      gyz = ty + w0,y + 2 z v0* + 3 z^2 ty*

Ply law ``sigma = Q eps``; for a 0 deg ply ``Q11 = E1/d``, ``Q22 = E2/d``, ``Q12 = nu12 E2/d``
(``d = 1 - nu12^2 E2/E1``), ``Q44 = G23`` (yz), ``Q55 = G13`` (xz), ``Q66 = G12``; a 90 deg ply
swaps 11 <-> 22 and 44 <-> 55. Energies (exact per-ply z-integration)::

    U = 1/2 int_A sum_plies int eps^T Q eps dz dA,   T = 1/2 int_A sum_plies rho int (u'^2 + v'^2 + w'^2) dz dA.

Navier expansion
----------------
"Hard" simple support: ``v0 = w0 = ty = v0* = ty* = 0`` on ``x = 0, a`` and
``u0 = w0 = tx = u0* = tx* = 0`` on ``y = 0, b``. With ``al = m pi / a``, ``be = n pi / b`` and
the short names ``cs = cos(al x) sin(be y)``, ``sc = sin(al x) cos(be y)``, ``ss``, ``cc``::

    (u0, tx, u0*, tx*) = (U0, Tx, U0s, Txs) cs      (v0, ty, v0*, ty*) = (V0, Ty, V0s, Tys) sc
    w0 = W ss

The amplitude vector, in the finite-element node DOF order (laminid_cli/fe/element.py), is::

    q = [U0, V0, W, Tx, Ty, U0s, V0s, Txs, Tys]          (9,), units m, 1, 1/m, 1/m^2

Writing ``u_k`` / ``v_k`` for the amplitude that multiplies ``z^k`` in ``u`` / ``v``
(``u_0 = U0, u_1 = Tx, u_2 = U0s, u_3 = Txs``), the strain is ``eps = sum_k z^k (B_k q) * f``
where the spatial factor ``f`` is one function per strain component::

    row xx:  -al u_k                                           f = ss
    row yy:  -be v_k                                           f = ss
    row yz:  (k + 1) v_{k+1}  (+ be W for k = 0), k <= 2       f = sc
    row xz:  (k + 1) u_{k+1}  (+ al W for k = 0), k <= 2       f = cs
    row xy:  be u_k + al v_k                                   f = cc

``B_k`` has shape (5, 9). A cross-ply Q couples only xx with yy (same factor ``ss``), so every
product in ``eps^T Q eps`` pairs equal spatial factors and the plate integral reduces to
``F_c = int_A f_c^2 dA`` per component (``ab/4`` when ``m, n >= 1``); an off-axis ply would
couple ``ss`` with ``cc`` and break the expansion, hence the cross-ply restriction. With the
thickness moments ``Q^(p) = sum_plies Q (z_t^(p+1) - z_b^(p+1)) / (p + 1)`` (Pa m^(p+1))::

    K = sum_{k,l=0..3} B_k^T  (F Q^(k+l))  B_l                 F = diag(F_ss, F_ss, F_sc, F_cs, F_cc)

The velocity ``(u', v', w') = i omega sum_k z^k (N_k q) * g`` with ``N_k`` (3, 9) picking
``u_k``, ``v_k`` and (``k = 0`` only) ``W``; factors ``g = (cs, sc, ss)``. With the inertia
moments ``I^(p) = sum_plies rho (z_t^(p+1) - z_b^(p+1)) / (p + 1)`` (kg m^(p-2))::

    M = sum_{k,l=0..3} I^(k+l) N_k^T G N_l                    G = diag(G_cs, G_sc, G_ss)

``U = 1/2 q^T K q``, ``T = 1/2 omega^2 q^T M q`` (time factor removed), so the natural
frequencies are the roots of ``det(K - omega^2 M) = 0``: nine per (m, n) when ``m, n >= 1``.
When ``m = 0`` (or ``n = 0``) the sc (or cs) and ss fields vanish identically; the four DOFs
of the surviving u-type (or v-type) family give in-plane / thickness-shear modes.

Numerics: see :func:`navier_modes` (DOF scaling by ``h^k`` and a Rayleigh-quotient polish keep
the fundamental accurate to ~1e-10 even at ``a/h = 1000``).
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

#: DOF order of the amplitude vector q (same as the finite-element node DOFs)
DOF_NAMES = ("u0", "v0", "w0", "tx", "ty", "u0*", "v0*", "tx*", "ty*")
#: z-power of each DOF in the displacement field (used for scaling and for N_k, B_k)
DOF_Z_POWER = np.array([0, 0, 0, 1, 1, 2, 2, 3, 3])
#: index in q of u_k and v_k, k = 0..3
_U = (0, 3, 5, 7)
_V = (1, 4, 6, 8)
_W = 2
#: strain rows, order [xx, yy, yz, xz, xy]
_XX, _YY, _YZ, _XZ, _XY = range(5)


class Ply(NamedTuple):
    """One ply. ``material``: object with E1, E2, G12, G13, G23, nu12 (Pa) or such a 6-tuple."""

    material: object
    angle_deg: float
    z_bottom: float
    z_top: float
    density: float


def _constants(material) -> tuple[float, float, float, float, float, float]:
    if hasattr(material, "E1"):
        names = ("E1", "E2", "G12", "G13", "G23", "nu12")
        return tuple(float(getattr(material, k)) for k in names)
    values = tuple(float(v) for v in material)
    if len(values) != 6:
        raise ValueError(f"ply material must be (E1, E2, G12, G13, G23, nu12), got {material!r}")
    return values


def _cross_ply_quarter_turns(angle_deg: float) -> int:
    """0 for a 0 deg ply, 1 for a 90 deg ply (angles modulo 180 deg)."""
    r = float(angle_deg) % 180.0
    for turns, ref in ((0, 0.0), (1, 90.0), (0, 180.0)):
        if abs(r - ref) < 1e-9:
            return turns
    raise ValueError(f"Navier solution needs cross-ply plies (0 or 90 deg), got angle_deg={angle_deg}")


def reduced_stiffness(material, angle_deg: float) -> np.ndarray:
    """Plane-stress ply stiffness in laminate axes, (5, 5), Pa, strain order [xx, yy, yz, xz, xy].

    Only 0 and 90 deg (mod 180) are accepted.

    >>> Q = reduced_stiffness((10.0, 10.0, 4.0, 4.0, 4.0, 0.25), 0.0)
    >>> [round(float(v), 6) for v in (Q[0, 0], Q[0, 1], Q[3, 3])]
    [10.666667, 2.666667, 4.0]
    """
    E1, E2, G12, G13, G23, nu12 = _constants(material)
    d = 1.0 - nu12**2 * E2 / E1
    Q = np.zeros((5, 5))
    Q[_XX, _XX] = E1 / d
    Q[_YY, _YY] = E2 / d
    Q[_XX, _YY] = Q[_YY, _XX] = nu12 * E2 / d
    Q[_YZ, _YZ] = G23
    Q[_XZ, _XZ] = G13
    Q[_XY, _XY] = G12
    if _cross_ply_quarter_turns(angle_deg):
        swap = [_YY, _XX, _XZ, _YZ, _XY]
        Q = Q[np.ix_(swap, swap)]
    return Q


def thickness_moments(plies: Sequence) -> tuple[np.ndarray, np.ndarray]:
    """Exact thickness integrals of the stiffness and of the density.

    Returns
    -------
    Qp : array (7, 5, 5), Pa m^(p+1)
        ``Qp[p] = sum_plies Q int z^p dz``, p = 0..6.
    Ip : array (7,), kg m^(p-2)
        ``Ip[p] = sum_plies rho int z^p dz``.
    """
    if len(plies) == 0:
        raise ValueError("at least one ply is needed")
    Qp = np.zeros((7, 5, 5))
    Ip = np.zeros(7)
    p = np.arange(7)
    for material, angle_deg, zb, zt, rho in plies:
        if not zt > zb:
            raise ValueError(f"ply z_top ({zt}) must exceed z_bottom ({zb})")
        zint = (zt ** (p + 1) - zb ** (p + 1)) / (p + 1)
        Qp += zint[:, None, None] * reduced_stiffness(material, angle_deg)
        Ip += float(rho) * zint
    return Qp, Ip


def strain_operators(a: float, b: float, m: int, n: int) -> np.ndarray:
    """Generalised strain operators B_k, (4, 5, 9): ``eps = sum_k z^k (B_k q) * f_row``."""
    al, be = m * np.pi / a, n * np.pi / b
    B = np.zeros((4, 5, 9))
    for k in range(4):
        B[k, _XX, _U[k]] = -al
        B[k, _YY, _V[k]] = -be
        B[k, _XY, _U[k]] = be
        B[k, _XY, _V[k]] = al
        if k < 3:  # d/dz of the z^(k+1) term
            B[k, _XZ, _U[k + 1]] = k + 1
            B[k, _YZ, _V[k + 1]] = k + 1
    B[0, _XZ, _W] = al
    B[0, _YZ, _W] = be
    return B


def velocity_operators() -> np.ndarray:
    """Velocity operators N_k, (4, 3, 9): ``(u, v, w) = sum_k z^k (N_k q) * g_row``."""
    N = np.zeros((4, 3, 9))
    for k in range(4):
        N[k, 0, _U[k]] = 1.0
        N[k, 1, _V[k]] = 1.0
    N[0, 2, _W] = 1.0
    return N


def _area_factors(a: float, b: float, m: int, n: int) -> dict[str, float]:
    """``int_A f^2 dA`` for f in ss, cs, sc, cc (m2)."""
    sx, cx = (a / 2, a / 2) if m else (0.0, a)
    sy, cy = (b / 2, b / 2) if n else (0.0, b)
    return {"ss": sx * sy, "cs": cx * sy, "sc": sx * cy, "cc": cx * cy}


def navier_matrices(plies: Sequence, a: float, b: float, m: int, n: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and mass of one Navier wave pair, in the DOF order :data:`DOF_NAMES`.

    Parameters
    ----------
    plies : sequence of (material, angle_deg, z_bottom, z_top, density)
        ``material`` has attributes E1, E2, G12, G13, G23, nu12 (Pa) or is that 6-tuple;
        angles 0 or 90 deg; z in m from the mid-plane; density kg/m3.
    a, b : float, m
        Plate lengths along x and y.
    m, n : int
        Half-wave numbers along x and y (>= 0, not both 0).

    Returns
    -------
    K : array (9, 9)
    M : array (9, 9)
        SI, entry units such that ``q^T K q`` is in J and ``q^T M q`` in kg m2 (q in the
        units of the module docstring); ``U = q^T K q / 2``, ``T = omega^2 q^T M q / 2``.
        Symmetric; positive definite when ``m, n >= 1``. For ``m = 0`` or ``n = 0`` the rows
        of the vanishing fields are zero.
    """
    if m < 0 or n < 0 or m == n == 0:
        raise ValueError(f"wave numbers must be >= 0 and not both 0, got (m, n) = ({m}, {n})")
    Qp, Ip = thickness_moments(plies)
    A = _area_factors(a, b, m, n)
    F = np.array([A["ss"], A["ss"], A["sc"], A["cs"], A["cc"]])
    G = np.array([A["cs"], A["sc"], A["ss"]])
    B = strain_operators(a, b, m, n)
    N = velocity_operators()
    K = np.zeros((9, 9))
    M = np.zeros((9, 9))
    for k in range(4):
        for l in range(4):
            K += B[k].T @ (F[:, None] * Qp[k + l]) @ B[l]
            M += Ip[k + l] * N[k].T @ (G[:, None] * N[l])
    return K, M


def strain_energy(plies: Sequence, a: float, b: float, m: int, n: int,
                  q: np.ndarray) -> np.ndarray:
    """``q^T K q`` evaluated through the strains, (n_vec,) J, for amplitude columns q (9, n_vec).

    Forming the strain amplitudes first (``tx + al W`` is one number) avoids the cancellation
    hidden in ``q^T K q`` for a thin plate, where the flexural mode has ``tx ~ -al W`` and the
    shear entries of K exceed the bending ones by ``(a/h)^2``.
    """
    Qp, _ = thickness_moments(plies)
    A = _area_factors(a, b, m, n)
    F = np.array([A["ss"], A["ss"], A["sc"], A["cs"], A["cc"]])
    e = np.einsum("kij,jv->kiv", strain_operators(a, b, m, n), q)      # (4, 5, n_vec)
    return sum(np.einsum("iv,ij,jv->v", e[k], F[:, None] * Qp[k + l], e[l])
               for k in range(4) for l in range(4))


def navier_modes(plies: Sequence, a: float, b: float, m: int, n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies and amplitude vectors of one wave pair.

    The DOFs are rescaled to lengths (``h^k q_k``), the problem is reduced to standard form
    with the Cholesky factor of M and solved by ``eigh``; each eigenvalue is then replaced by
    the Rayleigh quotient of its eigenvector with the strain energy computed by
    :func:`strain_energy`. That step matters only for very thin plates: at ``a/h = 1000`` the
    eigenvalues span twelve decades and ``eigh`` alone leaves ~1e-5 relative error on the
    fundamental; the quotient (second-order in the eigenvector error) brings it to ~1e-10.

    Returns
    -------
    omega : array (n_dof,), rad/s, ascending (n_dof = 9 when m, n >= 1, else 4)
    q : array (9, n_dof)
        Amplitudes in :data:`DOF_NAMES` order, ``q.T @ M @ q = I``.
    """
    K, M = navier_matrices(plies, a, b, m, n)
    h = max(p[3] for p in plies) - min(p[2] for p in plies)
    active = np.flatnonzero(np.diag(M) > 0.0)
    s = h ** -DOF_Z_POWER[active].astype(float)     # q_k = s_k * (h^k q_k): all lengths
    Ks = s[:, None] * K[np.ix_(active, active)] * s
    Ms = s[:, None] * M[np.ix_(active, active)] * s
    Linv = np.linalg.inv(np.linalg.cholesky(Ms))
    _, y = np.linalg.eigh(Linv @ Ks @ Linv.T)
    q = np.zeros((9, active.size))
    q[active] = s[:, None] * (Linv.T @ y)
    lam = strain_energy(plies, a, b, m, n, q) / np.einsum("iv,ij,jv->v", q, M, q)
    order = np.argsort(lam)
    return np.sqrt(lam[order]), q[:, order]


def navier_frequencies(plies: Sequence, a: float, b: float, m: int, n: int) -> np.ndarray:
    """Angular frequencies of wave pair (m, n), (9,) rad/s ascending ((4,) if m or n is 0).

    For m, n >= 1 the lowest one is the flexural mode; see :func:`navier_matrices` for the
    arguments.
    """
    return navier_modes(plies, a, b, m, n)[0]


def flexural_index(q: np.ndarray, M: np.ndarray) -> int:
    """Column of q whose kinetic energy has the largest share in w (the flexural mode)."""
    w_share = q[_W] ** 2 * M[_W, _W] / np.einsum("ij,ik,kj->j", q, M, q)
    return int(np.argmax(w_share))


class WaveModes(NamedTuple):
    """Plate frequencies labelled by their Navier wave pair."""

    omega: np.ndarray   # (n_modes,), rad/s, ascending
    m: np.ndarray       # (n_modes,), int, half-waves along x
    n: np.ndarray       # (n_modes,), int, half-waves along y


def lowest_frequencies(plies: Sequence, a: float, b: float, n_modes: int,
                       max_wave: int | None = None, kind: str = "flexural") -> WaveModes:
    """The ``n_modes`` lowest plate frequencies over all wave pairs, with their (m, n).

    Parameters
    ----------
    kind : {"flexural", "all"}
        "flexural": one mode per (m, n >= 1), the one with the largest w share of kinetic
        energy, i.e. the transverse-bending family an FE eigen-solution mostly shows.
        "all": every root of every (m, n), including the in-plane / thickness-shear modes and
        the m = 0 or n = 0 families (a 4-vector each), i.e. the full spectrum of the plate.
    max_wave : int, optional
        Largest m and n scanned; default ``n_modes`` (enough because frequencies grow with m
        and with n along each family, so the k-th lowest has m, n <= k).
    """
    kinds = ("flexural", "all")
    if kind not in kinds:
        raise ValueError(f"kind must be one of {kinds}, got {kind!r}")
    if n_modes < 1:
        raise ValueError(f"n_modes must be >= 1, got {n_modes}")
    max_wave = n_modes if max_wave is None else int(max_wave)
    first = 1 if kind == "flexural" else 0
    found = []
    for m in range(first, max_wave + 1):
        for n in range(first, max_wave + 1):
            if m == n == 0:
                continue
            omega, q = navier_modes(plies, a, b, m, n)
            if kind == "flexural":
                _, M = navier_matrices(plies, a, b, m, n)
                found.append((omega[flexural_index(q, M)], m, n))
            else:
                found.extend((w, m, n) for w in omega)
    found.sort(key=lambda t: t[0])
    found = found[:n_modes]
    return WaveModes(omega=np.array([t[0] for t in found]),
                     m=np.array([t[1] for t in found], dtype=int),
                     n=np.array([t[2] for t in found], dtype=int))
