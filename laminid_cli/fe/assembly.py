"""Assembly of the parametric plate model (README, "Reduced-order solver (design notes)").

The stiffness is linear in the coefficients ``coef[m, j] = s_m * [1, a2, a3, a4, a8, a9][j]``
(``s_m = E1_m / (8 alpha0_m)``) of each material m::

    K(p) = sum_m sum_j coef[m, j] * K_basis[m, j]

The ``n_materials * 6`` basis matrices share one CSR pattern and are stored as data arrays
(``PlateModel.K_data``, shape (n_materials, 6, nnz)), so forming K for new constants is one
small dense product, and the basis strain energies ``phi_i^T K_basis[m, j] phi_i`` needed by
the sensitivities (paper Eq. 26) are one product with the mode shapes.

Element matrices are computed in batches over elements and Gauss points (einsum); elements of
identical shape (all of them in a regular mesh) are computed once. The global matrices come
from one COO -> CSR conversion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from laminid_cli.errors import ModelError
from laminid_cli.fe import element as fe_el
from laminid_cli.fe.mesh import Mesh
from laminid_cli.material import basis_coefficients, c_basis

#: accepted boundary names -> edge code (edges in the order x=0, y=0, x=a, y=b)
BOUNDARY_NAMES = {
    "free": "FFFF",
    "simply-supported": "SSSS",
    "clamped": "CCCC",
}
#: DOFs fixed by a simply supported edge, by edge direction ("hard" support: tangential
#: in-plane variables and w fixed, normal ones free)
_SS_X_EDGE = (1, 2, 4, 6, 8)     # on x = 0, a: v0, w0, psi_y, V, Psi_y
_SS_Y_EDGE = (0, 2, 3, 5, 7)     # on y = 0, b: u0, w0, psi_x, U, Psi_x


def boundary_code(boundary: str) -> str:
    """Normalise a boundary name ('free', 'simply-supported', 'clamped') or 4-letter edge code.

    The code gives F (free), S (simply supported) or C (clamped) for the edges x = 0, y = 0,
    x = a, y = b in this order, e.g. ``SFSF``.
    """
    text = str(boundary).strip()
    if text.lower() in BOUNDARY_NAMES:
        return BOUNDARY_NAMES[text.lower()]
    aliases = {"ss": "SSSS", "simply supported": "SSSS", "simply_supported": "SSSS"}
    if text.lower() in aliases:
        return aliases[text.lower()]
    code = text.upper()
    if len(code) == 4 and set(code) <= set("FSC"):
        return code
    raise ModelError(f"boundary '{boundary}' not understood: use free, simply-supported, "
                     "clamped, or a 4-letter code of F/S/C for the edges x=0, y=0, x=a, y=b "
                     "(e.g. SFSF)")


def boundary_label(code: str) -> str:
    """'free' / 'simply-supported' / 'clamped' for uniform codes, else the code itself."""
    names = {v: k for k, v in BOUNDARY_NAMES.items()}
    return names.get(code, f"{code} (edges x=0, y=0, x=a, y=b)")


def fixed_dofs(mesh: Mesh, boundary: str) -> np.ndarray:
    """Global indices of the DOFs fixed by the boundary conditions (sorted, unique)."""
    code = boundary_code(boundary)
    x, y = mesh.nodes[:, 0], mesh.nodes[:, 1]
    tol = 1e-9 * max(mesh.a, mesh.b)
    edges = [(np.abs(x) < tol, "x"), (np.abs(y) < tol, "y"),
             (np.abs(x - mesh.a) < tol, "x"), (np.abs(y - mesh.b) < tol, "y")]
    fixed = []
    for letter, (on_edge, direction) in zip(code, edges):
        if letter == "F":
            continue
        dofs = range(9) if letter == "C" else (_SS_X_EDGE if direction == "x" else _SS_Y_EDGE)
        nodes = np.flatnonzero(on_edge)
        fixed.append((nodes[:, None] * 9 + np.asarray(dofs)[None, :]).ravel())
    if not fixed:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate(fixed))


#: the nodal variables of bending (w0, psi_x, psi_y, Psi_x, Psi_y; the others are membrane
#: variables: u0, v0, U, V), by their index in ``fe.element.DOF_NAMES``
BENDING_VARIABLES = (2, 3, 4, 7, 8)
#: membrane-bending coupling (relative) below which a laminate counts as decoupled: round-off
#: is ~1e-17 on symmetric layups (2e-17 S1.1, 4e-16 S2.2); a [0/90/0] whose middle ply sits
#: delta of the thickness off centre couples by 1.8 delta (measured for delta = 1e-3 ... 1e-9),
#: so only layups symmetric to ~5e-13 of their thickness count; the entries left out then
#: change the eigenvalues by far less than the solves' round-off
DECOUPLE_TOL = 1e-12
#: the bending equations among an element's 72 (local equation ``node * 9 + variable``)
BENDING_LOCAL = np.isin(np.arange(72) % 9, BENDING_VARIABLES)
BENDING_LOCAL.setflags(write=False)


class KroneckerMass:
    """The mass matrix as ``M = P (S kron J) P^T``, for products with it.

    Every element's mass matrix is ``(int N_a N_b dA) kron J`` (:func:`element_matrices`: the
    same 9x9 inertia per unit area J over the whole plate), so the assembled mass over all
    node variables (index node * 9 + variable) is ``S kron J`` with S the scalar consistent
    mass of the shape functions (n_nodes x n_nodes), and M keeps the retained rows and columns
    (P). ``M @ W`` is then one 9x9 product per node and one sparse product with S, which has
    ~1/33 of M's entries: at 12x12 a vector 31 against 127 us, 16 columns 0.23 against 0.87 ms
    (the same values to round-off; tests/test_fe.py holds them to the assembled M).
    Supports ``@`` with (n,) and (n, k) arrays, as the CSR matrix does.

    ``variables``: the node variables kept (default all nine; a plate model of one family of a
    symmetric laminate keeps five or four, :meth:`PlateModel.restrict`): J is then their block
    of the inertia, which is exact when the other variables do not couple to them.
    """

    def __init__(self, S: sp.csr_matrix, J: np.ndarray, dofs: np.ndarray, n_nodes: int,
                 variables=None):
        self.S = S.tocsr()
        self.variables = tuple(range(9)) if variables is None else tuple(int(v) for v in variables)
        nv = len(self.variables)
        J = np.asarray(J, dtype=float)
        self.J_all = J
        self.J = np.ascontiguousarray(J[np.ix_(self.variables, self.variables)])
        self.n_nodes = int(n_nodes)
        self.nv = nv
        # the kept equations in the numbering node * nv + (position of the variable)
        position = -np.ones(9, dtype=np.int64)
        position[list(self.variables)] = np.arange(nv)
        dofs = np.asarray(dofs, dtype=np.int64)
        local = (dofs // 9) * nv + position[dofs % 9]
        if np.any(position[dofs % 9] < 0):
            raise ModelError("mass matrix: an equation outside the kept variables")
        self.dofs = None if len(dofs) == nv * self.n_nodes else local
        self.shape = (len(dofs), len(dofs))

    def __matmul__(self, W):
        W = np.asarray(W, dtype=float)
        nn, nv = self.n_nodes, self.nv
        if W.ndim == 1:
            X = W if self.dofs is None else _scatter_rows(W, self.dofs, nv * nn)
            Y = (self.S @ (X.reshape(nn, nv) @ self.J.T)).reshape(-1)
            return Y if self.dofs is None else Y[self.dofs]
        k = W.shape[1]
        X = W if self.dofs is None else _scatter_rows(W, self.dofs, nv * nn)
        Z = np.matmul(self.J, X.reshape(nn, nv, k))         # (n_nodes, nv, k)
        Y = (self.S @ Z.reshape(nn, nv * k)).reshape(nv * nn, k)
        return Y if self.dofs is None else Y[self.dofs]


def _scatter_rows(W: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    X = np.zeros((n,) + W.shape[1:])
    X[rows] = W
    return X


@dataclass(frozen=True)
class PlateModel:
    """Discretised plate: parametric stiffness basis, mass matrix, mesh and DOF bookkeeping.

    Attributes
    ----------
    mesh : the FE mesh
    h : total thickness, m
    boundary : edge code (x=0, y=0, x=a, y=b), e.g. 'FFFF'
    material_names : names of the materials, index m of ``K_data``
    dofs : (n_dofs,) global DOF index (node * 9 + variable) of each retained equation
    indptr, indices : CSR pattern shared by every basis matrix and by K and M, (n_dofs x n_dofs)
    K_data : (n_materials, 6, nnz) basis stiffness data, N/m per unit coefficient (Pa)
    M : (n_dofs, n_dofs) CSR mass matrix with its own (sparser) pattern, kg; products with it
        go faster through ``mass``
    M_on_K : (nnz,) the mass matrix on the stiffness pattern (for ``K - sigma M``)
    Ke : (n_materials, 6, n_shapes, 72, 72) element basis matrices of each distinct element
        shape; ``element_shape`` (n_el,) maps elements to them and ``element_dofs`` (n_el, 72)
        gives each element's equations (-1 where fixed), for element-level sensitivities
    D_bending : (n_materials, 6, 3, 3) bending stiffness basis ``int z^2 C_j dz`` (m^3), for
        the shift estimate
    mass_per_area : kg/m^2
    mass : M for products, ``mass @ W`` (:class:`KroneckerMass`)
    decoupled : the pattern leaves out the membrane-bending entries (a symmetric laminate,
        :func:`build_plate_model`)
    family : 'all' (every node variable), or 'bending' / 'membrane' for the equations of one
        family of a decoupled plate (:meth:`restrict`)
    """

    mesh: Mesh
    h: float
    boundary: str
    material_names: tuple[str, ...]
    dofs: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray
    K_data: np.ndarray
    M: sp.csr_matrix
    M_on_K: np.ndarray
    Ke: np.ndarray
    element_shape: np.ndarray
    element_dofs: np.ndarray
    D_bending: np.ndarray
    mass_per_area: float
    mass: KroneckerMass
    decoupled: bool = False
    family: str = "all"

    @property
    def n_dofs(self) -> int:
        return int(self.dofs.size)

    def restrict(self, family: str) -> "PlateModel":
        """The plate model of one family of equations of a decoupled plate (a symmetric
        laminate, :func:`build_plate_model`): 'bending' (w0, psi, Psi) or 'membrane' (u0, v0,
        U, V). The matrices are the blocks of this model's, which holds no entry between the
        families; the modes of the block are modes of the whole plate (the other family's
        components zero), with the eigenvalues of this model to round-off."""
        if family not in ("bending", "membrane"):
            raise ModelError(f"unknown family of equations '{family}' (bending or membrane)")
        if not self.decoupled or self.family != "all":
            raise ModelError("only a decoupled plate model (a symmetric laminate) splits into "
                             "bending and membrane equations")
        variables = (BENDING_VARIABLES if family == "bending" else
                     tuple(v for v in range(9) if v not in BENDING_VARIABLES))
        keep = np.isin(self.dofs % 9, variables)
        n, k = self.n_dofs, int(keep.sum())
        new_index = -np.ones(n, dtype=np.int64)
        new_index[keep] = np.arange(k)
        rows = np.repeat(np.arange(n), np.diff(self.indptr))
        entry = keep[rows]
        if not np.all(keep[self.indices[entry]]):
            raise ModelError("the plate model couples bending and membrane equations")
        indptr = np.concatenate([[0], np.cumsum(np.bincount(new_index[rows[entry]],
                                                            minlength=k))])
        element_dofs = np.where(self.element_dofs >= 0,
                                new_index[np.maximum(self.element_dofs, 0)], -1)
        return PlateModel(
            mesh=self.mesh, h=self.h, boundary=self.boundary,
            material_names=self.material_names, dofs=self.dofs[keep], indptr=indptr,
            indices=new_index[self.indices[entry]], K_data=self.K_data[:, :, entry],
            M=self.M[keep][:, keep].tocsr(), M_on_K=self.M_on_K[entry], Ke=self.Ke,
            element_shape=self.element_shape, element_dofs=element_dofs,
            D_bending=self.D_bending, mass_per_area=self.mass_per_area,
            mass=KroneckerMass(self.mass.S, self.mass.J_all, self.dofs[keep],
                               self.mesh.n_nodes, variables),
            decoupled=True, family=family)

    def coefficients(self, constants) -> np.ndarray:
        """(n_materials, 6) stiffness coefficients for a sequence of ElasticConstants."""
        constants = list(constants)
        if len(constants) != len(self.material_names):
            raise ModelError(f"expected constants for {len(self.material_names)} materials "
                             f"({', '.join(self.material_names)}), got {len(constants)}")
        return np.array([basis_coefficients(c) for c in constants])

    def stiffness(self, constants=None, *, coef: np.ndarray | None = None) -> sp.csr_matrix:
        """Global stiffness K for the given constants (or stiffness coefficients), N/m."""
        if coef is None:
            coef = self.coefficients(constants)
        data = np.tensordot(np.asarray(coef, float), self.K_data, axes=([0, 1], [0, 1]))
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_dofs,) * 2)

    def shift_estimate(self, coef: np.ndarray) -> float:
        """Rough first elastic eigenvalue (rad^2/s^2) from thin-plate theory.

        lambda_1 ~ (c pi^2 / (a b))^2 D / (rho h) with D the geometric mean of the bending
        stiffnesses D11, D22 and 4 D66; used as the shift of the eigen solver (paper Eq. 10:
        "beta of the same magnitude as the first non-zero eigenvalue"). Within a factor of a
        few of the truth for plates, which is all shift-invert Lanczos needs.
        """
        D = np.tensordot(np.asarray(coef, float), self.D_bending, axes=([0, 1], [0, 1]))
        d = np.array([D[0, 0], D[1, 1], 4 * D[2, 2]])
        D_ref = float(np.exp(np.mean(np.log(np.maximum(d, 1e-30 * d.max())))))
        a, b = self.mesh.a, self.mesh.b
        return (1.4 * np.pi**2 / (a * b)) ** 2 * D_ref / self.mass_per_area

    def rigid_modes(self) -> np.ndarray | None:
        """The rigid-body motions of a free plate in the nodal variables, (n_dofs, 6): six, or
        the three of each family of equations of a :meth:`restrict` ed model.

        Translations u, v, w; rotation about z (u = -y, v = x); rotations w = y and w = x, with
        the normal staying normal (theta_y = -1 resp. theta_x = -1, i.e. psi = -h/2 in the
        scaled variables of laminid_cli.fe.element). None when any edge is supported.
        """
        if self.boundary != "FFFF":
            return None
        x, y = self.mesh.nodes[:, 0], self.mesh.nodes[:, 1]
        R = np.zeros((self.mesh.n_nodes, 9, 6))
        R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
        R[:, 0, 3], R[:, 1, 3] = -y, x
        R[:, 2, 4], R[:, 4, 4] = y, -self.h / 2
        R[:, 2, 5], R[:, 3, 5] = x, -self.h / 2
        R = R.reshape(-1, 6)[self.dofs]
        # one family of a decoupled plate (restrict) keeps the motions in its variables
        return R[:, np.abs(R).max(axis=0) > 0]

    def rotation_symmetry(self):
        """The plate's half-turn about its normal through its centre on its equations, as
        ``(perm, sign)``: ``(S W)[perm] = sign[:, None] * W`` (``rotate``); None where the
        model is not invariant under it (a supported edge whose opposite edge is not, a mesh
        that the turn does not map onto itself).

        Any laminate is invariant: the turn reverses every in-plane direction, and each
        stiffness component has an even number of in-plane indices (Q_ij of the plies, the
        transverse shear Q44, Q45, Q55), so K_b = S K_b S^T for every basis matrix and
        M = S M S^T; w0 keeps its sign, every in-plane variable (u0, v0, the rotations psi,
        U, V, Psi) changes it. Checked here on one random combination of the basis matrices
        and on M (relative 1e-12: round-off is ~3e-16). Its use: a basis of vectors even or
        odd under the turn splits the reduced eigenproblem in two
        (laminid_cli.reduced.ReducedBasis). Computed once per model."""
        cached = self.__dict__.get("_rotation", False)
        if cached is not False:
            return cached
        out = self._rotation_symmetry()
        object.__setattr__(self, "_rotation", out)
        return out

    def _rotation_symmetry(self):
        mesh = self.mesh
        ij = np.rint(mesh.nodes[:, :2] * np.array([2 * mesh.nx / mesh.a, 2 * mesh.ny / mesh.b])
                     ).astype(np.int64)
        key = ij[:, 0] * (2 * mesh.ny + 1) + ij[:, 1]
        turned = (2 * mesh.nx - ij[:, 0]) * (2 * mesh.ny + 1) + (2 * mesh.ny - ij[:, 1])
        order = np.argsort(key)
        where = np.searchsorted(key[order], turned)
        if np.any(where >= key.size) or np.any(key[order][np.minimum(where, key.size - 1)]
                                              != turned):
            return None
        node_map = order[where]                           # node -> its turned node
        var = self.dofs % 9
        n_all = mesh.n_nodes * 9
        position = -np.ones(n_all, dtype=np.int64)
        position[self.dofs] = np.arange(self.n_dofs)
        perm = position[node_map[self.dofs // 9] * 9 + var]
        if np.any(perm < 0):                              # a turned equation is fixed
            return None
        sign = np.where(var == 2, 1.0, -1.0)
        n = self.n_dofs
        S = sp.csr_matrix((sign, (perm, np.arange(n))), shape=(n, n))
        coef = np.random.default_rng(0).uniform(0.5, 1.5, self.K_data.shape[:2])
        K = self.stiffness(coef=coef)
        for A in (K, self.M):
            scale = abs(A).max()
            if not abs(S @ A @ S.T - A).max() <= 1e-12 * scale:
                return None
        return perm, sign

    @staticmethod
    def rotate(symmetry, W: np.ndarray) -> np.ndarray:
        """``S W`` for ``symmetry = (perm, sign)`` of :meth:`rotation_symmetry`."""
        perm, sign = symmetry
        out = np.empty_like(W)
        out[perm] = sign.reshape((-1,) + (1,) * (W.ndim - 1)) * W
        return out

    def basis_matrix(self, m: int, j: int) -> sp.csr_matrix:
        """Basis stiffness matrix K_basis[m, j] (Pa coefficient units)."""
        return sp.csr_matrix((self.K_data[m, j], self.indices, self.indptr),
                             shape=(self.n_dofs,) * 2)

    def basis_products(self, W: np.ndarray, block: int = 32) -> np.ndarray:
        """``K_basis[b] @ W`` for every basis matrix b, side by side: (n_dofs, n_b * k) with
        columns ``b * k ... (b + 1) * k - 1`` holding ``K_basis[b] @ W`` (n_b = n_materials * 6,
        in the order of ``K_data``).

        Element by element: ``K_b W = S blockdiag(Ke_b) S^T W`` with S the 0/1 assembly
        matrix; the gather ``S^T W`` is an index, the element products one dense matrix
        product per distinct element shape for all bases, the scatter one sparse product with a
        single entry per element equation per basis. About 4x faster than the sparse products
        with the assembled basis matrices, whose pattern (every equation of every element
        coupled to every other) has ~7x the entries of S. ``block``: columns per pass (memory
        ~ 8 n_el 72 n_b block bytes)."""
        return self._element_products(self._element_blocks, W, block)

    def stiffness_products(self, coef: np.ndarray, W: np.ndarray) -> np.ndarray:
        """``K(coef) @ W`` element by element (as :meth:`basis_products`, with the element
        stiffness ``sum_b coef_b Ke_b`` of each element shape formed first)."""
        c = np.asarray(coef, float).reshape(-1)
        blocks = [np.tensordot(c, Kb, axes=(0, 0))[None] for Kb in self._element_blocks]
        return self._element_products(blocks, W)

    def _element_products(self, blocks, W: np.ndarray, block: int = 32) -> np.ndarray:
        """``[A_c W]`` side by side for assembled matrices A_c of element matrices given by
        their diagonal ``blocks`` in the local order of :attr:`_scatter` (each (n_c, n_shapes,
        s, s); one block of 72 unless decoupled) (see :meth:`basis_products`)."""
        W = np.asarray(W, float)
        if W.ndim == 1:
            W = W[:, None]
        n, k = W.shape
        n_c = blocks[0].shape[0]
        S_parts, groups, dofs_t = self._scatter
        n_el = dofs_t.shape[1]
        out = np.empty((n, n_c * k))
        padded = np.vstack([W, np.zeros((1, k))])                  # row -1: fixed DOF = 0
        for c0 in range(0, k, block):
            c1 = min(k, c0 + block)
            kc = c1 - c0
            X = padded[:, c0:c1][dofs_t]                            # (72, n_el, kc)
            a = 0
            for Kb, S in zip(blocks, S_parts):                      # diagonal blocks
                s = Kb.shape[-1]
                KX = np.empty((n_c, s, n_el, kc)) if len(groups) > 1 else None
                for u, els in enumerate(groups):                    # distinct shapes only
                    Xu = X[a:a + s] if els is None else X[a:a + s, els]
                    P = np.matmul(Kb[:, u], Xu.reshape(s, -1)).reshape(n_c, s, -1, kc)
                    if els is None:
                        KX = P
                    else:
                        KX[:, :, els] = P
                for b in range(n_c):
                    part = S @ KX[b].reshape(s * n_el, kc)
                    if a == 0:
                        out[:, b * k + c0:b * k + c1] = part
                    else:
                        out[:, b * k + c0:b * k + c1] += part
                a += s
        return out

    @property
    def _local_order(self) -> tuple[np.ndarray, tuple[int, ...]]:
        """(order, sizes): the element's 72 equations reordered into diagonal blocks of these
        sizes: the bending then the membrane equations when decoupled (a symmetric laminate:
        the element matrices are block diagonal, and products with the two blocks take
        (40^2 + 32^2) / 72^2 = 51 % of the work), else all 72 in their order."""
        if not self.decoupled:
            return np.arange(72), (72,)
        bending = BENDING_LOCAL
        live = np.any(self.element_dofs >= 0, axis=0)               # (72,) used at all
        order, sizes = [], []
        for part in (bending, ~bending):              # a restricted model: its family only
            idx = np.flatnonzero(part & live)
            if idx.size:
                order.append(idx)
                sizes.append(int(idx.size))
        return np.concatenate(order), tuple(sizes)

    @property
    def _element_blocks(self) -> list:
        """The element basis matrices of every distinct shape as the diagonal blocks of
        :attr:`_local_order`, each (n_b, n_shapes, s, s), made once."""
        cached = self.__dict__.get("_blocks_cache")
        if cached is None:
            order, sizes = self._local_order
            Ke = self.Ke.reshape(self.K_data.shape[0] * 6, -1, 72, 72)
            cached, a = [], 0
            for s in sizes:
                idx = order[a:a + s]
                cached.append(np.ascontiguousarray(Ke[:, :, idx[:, None], idx]))
                a += s
            object.__setattr__(self, "_blocks_cache", cached)
        return cached

    @property
    def _scatter(self):
        """(S parts, groups, element equations): per diagonal block of :attr:`_local_order`
        the assembly matrix S_a (n_dofs, s n_el), column ``i n_el + e`` for local equation i
        of the block in element e; per distinct element shape its elements (None: all); and
        (72, n_el) the elements' equations in that local order (-1 where fixed)."""
        cached = self.__dict__.get("_scatter_cache")
        if cached is None:
            n_el = self.element_dofs.shape[0]
            order, sizes = self._local_order
            dofs_t = np.ascontiguousarray(self.element_dofs[:, order].T)    # (72, n_el)
            parts, a = [], 0
            for s in sizes:
                d = dofs_t[a:a + s].ravel()                         # (i, e) order
                ok = d >= 0
                parts.append(sp.csr_matrix((np.ones(int(ok.sum())), (d[ok], np.flatnonzero(ok))),
                                           shape=(self.n_dofs, s * n_el)))
                a += s
            n_shapes = self.Ke.shape[2]
            groups = ([None] if n_shapes == 1 else
                      [np.flatnonzero(self.element_shape == u) for u in range(n_shapes)])
            cached = (parts, groups, dofs_t)
            object.__setattr__(self, "_scatter_cache", cached)
        return cached

    def basis_energies(self, phi: np.ndarray) -> np.ndarray:
        """``phi_i^T K_basis[m, j] phi_i`` for every mode i: (n_materials, 6, n_modes).

        With mass-normalised phi, d lambda_i / d coef[m, j] equals this (paper Eq. 26). Summed
        element by element (Eq. 27) with the element matrices of each distinct element shape,
        as batched matrix products.
        """
        phi = np.asarray(phi, float)
        n_modes = phi.shape[1]
        padded = np.vstack([phi, np.zeros((1, n_modes))])          # row -1: fixed DOF = 0
        n_mat = self.Ke.shape[0]
        dofs_t = self._scatter[2]                                   # (72, n_el), local order
        out = np.zeros((n_mat * 6, n_modes))
        for u in range(self.Ke.shape[2]):                           # distinct shapes only
            X = padded[dofs_t[:, self.element_shape == u]]          # (72, n_e, n_modes)
            a = 0
            for Kb in self._element_blocks:                         # diagonal blocks
                s = Kb.shape[-1]
                Y = X[a:a + s].reshape(s, -1)
                KY = np.matmul(Kb[:, u], Y)                         # (n_b, s, n_e * n_modes)
                out += np.einsum("bik,ik->bk", KY, Y).reshape(n_mat * 6, -1,
                                                              n_modes).sum(axis=1)
                a += s
        return out.reshape(n_mat, 6, n_modes)

    def w_shape(self, phi: np.ndarray) -> np.ndarray:
        """Transverse displacement w0 at every mesh node, (n_nodes, n_modes); 0 on fixed DOFs."""
        full = np.zeros((self.mesh.n_nodes * 9,) + phi.shape[1:])
        full[self.dofs] = phi
        return full[2::9]


def _unique_elements(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Group elements of identical shape: (index of a representative per group, group of each)."""
    rel = xy - xy[:, :1, :]
    scale = np.abs(rel).max() or 1.0
    key = np.round(rel.reshape(len(xy), -1) / scale, 10)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return first, inverse.ravel()


def _btdb(B: np.ndarray, D: np.ndarray, wdet: np.ndarray) -> np.ndarray:
    """sum over Gauss points of w detJ B^T D_b B for every basis b, as batched BLAS products.

    B : (n_el, n_gp, n_s, 72); D : (n_b, n_s, n_s); wdet : (n_el, n_gp) -> (n_b, n_el, 72, 72)
    """
    n_el, n_gp, n_s, n_d = B.shape
    DB = np.matmul(D[:, None, None], B[None])                      # (n_b, n_el, n_gp, n_s, 72)
    Bw = (B * wdet[:, :, None, None]).reshape(n_el, n_gp * n_s, n_d)
    return np.matmul(Bw.transpose(0, 2, 1)[None], DB.reshape(len(D), n_el, n_gp * n_s, n_d))


def element_matrices(xy: np.ndarray, h: float, D_p: np.ndarray, D_s: np.ndarray,
                     J: np.ndarray, integration: str = "selective"):
    """Element stiffness per basis and element mass, batched.

    Parameters
    ----------
    xy : (n_el, 8, 2) node coordinates, m
    D_p : (n_b, 12, 12), D_s : (n_b, 6, 6) generalised constitutive matrices per basis
    J : (9, 9) inertia per unit area, kg/m^2
    integration : 'selective' (3x3 in-plane, 2x2 shear) or 'full' (3x3 everywhere)

    Returns
    -------
    Ke : (n_b, n_el, 72, 72), Me : (n_el, 72, 72)
    """
    if integration not in ("selective", "full"):
        raise ModelError(f"integration '{integration}' unknown (selective or full)")
    pts3, w3 = fe_el.gauss_rule(3)
    N3, dN3 = fe_el.shape_functions(pts3)
    dNdx3, det3 = fe_el.physical_derivatives(xy, dN3)
    wd3 = w3[None, :] * det3                                              # (n_el, 9)
    Bp = fe_el.inplane_operator(dNdx3)
    Ke = _btdb(Bp, D_p, wd3)
    if integration == "selective":
        pts2, w2 = fe_el.gauss_rule(2)
        N2, dN2 = fe_el.shape_functions(pts2)
        dNdx2, det2 = fe_el.physical_derivatives(xy, dN2)
        Bs = fe_el.shear_operator(N2, dNdx2, h)
        wds = w2[None, :] * det2
    else:
        Bs = fe_el.shear_operator(N3, dNdx3, h)
        wds = wd3
    Ke += _btdb(Bs, D_s, wds)
    Nmass = np.einsum("ga,gb,eg->eab", N3, N3, wd3)                       # (n_el, 8, 8)
    Me = np.einsum("eab,ij->eaibj", Nmass, J).reshape(-1, 72, 72)
    return Ke, Me


def build_plate_model(mesh: Mesh, h: float, z: np.ndarray, angle: np.ndarray,
                      material_index: np.ndarray, density: np.ndarray,
                      material_names=("material",), boundary: str = "free",
                      integration: str = "selective", decouple: bool = True) -> PlateModel:
    """Assemble the basis stiffness matrices and the mass matrix of a laminated plate.

    Parameters
    ----------
    mesh : Q8 mesh of the plate
    h : total thickness, m
    z : (n_plies + 1,) ply interfaces from -h/2 to h/2, m (ply 1 at the bottom)
    angle : (n_plies,) ply angles, rad
    material_index : (n_plies,) index of each ply's material in ``material_names``
    density : (n_plies,) kg/m^3
    boundary : 'free' (default), 'simply-supported', 'clamped' or an edge code like 'SFSF'
    integration : 'selective' (default) or 'full' (locks for thin plates; for tests)
    decouple : leave the membrane-bending coupling entries out of the matrices' pattern when
        every element matrix has none (a symmetric laminate; :func:`membrane_bending_coupling`)

    A symmetric laminate's stiffness and mass couple the membrane variables (u0, v0, U, V) to
    the bending ones (w0, psi, Psi) only by round-off (odd moments of the ply stiffnesses and
    densities through the thickness vanish: ~1e-17 relative on the paper's plates). Those
    entries are then not stored: K - sigma M is block diagonal after a permutation, and a
    fill-reducing ordering factorises the two blocks apart (half the entries of K, half the
    time of a factorisation at 12x12, a third less per solve; the modes are the same to the
    round-off of a solve). The modes of both families are still found: nothing is dropped
    but zeros.
    """
    z = np.asarray(z, float)
    angle = np.asarray(angle, float)
    mat = np.asarray(material_index, int)
    n_mat = len(material_names)
    if z.size != angle.size + 1 or mat.size != angle.size or np.size(density) != angle.size:
        raise ModelError("ply arrays have inconsistent lengths")
    if not np.isclose(z[-1] - z[0], h, rtol=1e-6) or np.any(np.diff(z) <= 0):
        raise ModelError(f"ply interfaces must rise from -h/2 to h/2 (h = {h} m)")
    if mat.min() < 0 or mat.max() >= n_mat:
        raise ModelError("ply material index out of range")
    code = boundary_code(boundary)

    # --- generalised constitutive matrices per (material, basis) ----------------------------
    C = c_basis(angle)                                          # (n_plies, 6, 5, 5)
    Qb = np.zeros((n_mat, 6, angle.size, 5, 5))
    for m in range(n_mat):                                      # loop over materials only
        Qb[m, :, mat == m] = C[mat == m]
    D_p, D_s = fe_el.laminate_operators(z, h, Qb.reshape(n_mat * 6, angle.size, 5, 5))
    J = fe_el.inertia_operator(z, h, density)
    D_bending = (h**2 / 4) * D_p[:, 3:6, 3:6].reshape(n_mat, 6, 3, 3)

    # --- element matrices, computed once per distinct element shape ---------------------------
    xy = mesh.nodes[mesh.elements]                              # (n_el, 8, 2)
    first, group = _unique_elements(xy)
    Ke_u, Me_u = element_matrices(xy[first], h, D_p, D_s, J, integration)

    # --- one COO -> CSR pattern, with fixed DOFs removed -------------------------------------
    n_glob = mesh.n_nodes * 9
    fixed = fixed_dofs(mesh, code)
    keep = np.ones(n_glob, bool)
    keep[fixed] = False
    new_index = -np.ones(n_glob, dtype=np.int64)
    new_index[keep] = np.arange(keep.sum())
    edofs = (mesh.elements[:, :, None] * 9 + np.arange(9)).reshape(-1, 72)
    red = new_index[edofs]                                      # (n_el, 72)
    rows = np.broadcast_to(red[:, :, None], (len(red), 72, 72)).ravel()
    cols = np.broadcast_to(red[:, None, :], (len(red), 72, 72)).ravel()
    ok = (rows >= 0) & (cols >= 0)
    decoupled = bool(decouple) and membrane_bending_coupling(Ke_u, Me_u) <= DECOUPLE_TOL
    if decoupled:
        bending = BENDING_LOCAL
        cross = bending[:, None] != bending[None, :]
        ok &= ~np.broadcast_to(cross, (len(red), 72, 72)).ravel()
    rows, cols = rows[ok], cols[ok]
    n = int(keep.sum())
    pattern = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    pattern.sum_duplicates()
    pattern.sort_indices()
    slot_rows = np.repeat(np.arange(n), np.diff(pattern.indptr))
    slot_key = slot_rows * n + pattern.indices
    slot = np.searchsorted(slot_key, rows * n + cols)           # entry -> CSR slot

    # scatter matrix: CSR slot <- (element shape, local entry); one sparse product per model
    entry_group = np.broadcast_to(group[:, None], (len(group), 72 * 72)).ravel()[ok]
    entry_local = np.broadcast_to(np.arange(72 * 72)[None, :], (len(group), 72 * 72)).ravel()[ok]
    scatter = sp.csr_matrix((np.ones(slot.size), (slot, entry_group * 72 * 72 + entry_local)),
                            shape=(slot_key.size, len(first) * 72 * 72))
    K_data = (scatter @ np.ascontiguousarray(Ke_u.reshape(n_mat * 6, -1).T)).T
    M_data = scatter @ Me_u.reshape(-1)
    M = sp.csr_matrix((M_data.copy(), pattern.indices.copy(), pattern.indptr.copy()), shape=(n, n))
    M.eliminate_zeros()         # the inertia couples only x-x, y-y and w-w variables
    # the scalar mass of the shape functions: the w-w block of the element mass over J_ww
    nodes = mesh.elements
    Nmass = Me_u.reshape(len(first), 8, 9, 8, 9)[:, :, 2, :, 2] / J[2, 2]
    S = sp.csr_matrix((Nmass[group].ravel(),
                       (np.broadcast_to(nodes[:, :, None], (len(nodes), 8, 8)).ravel(),
                        np.broadcast_to(nodes[:, None, :], (len(nodes), 8, 8)).ravel())),
                      shape=(mesh.n_nodes,) * 2)
    S.sum_duplicates()
    return PlateModel(mesh=mesh, h=float(h), boundary=code, material_names=tuple(material_names),
                      dofs=np.flatnonzero(keep), indptr=pattern.indptr, indices=pattern.indices,
                      K_data=K_data.reshape(n_mat, 6, -1), M=M, M_on_K=M_data,
                      Ke=Ke_u.reshape(n_mat, 6, len(first), 72, 72), element_shape=group,
                      element_dofs=red, D_bending=D_bending,
                      mass_per_area=float(J[2, 2]),
                      mass=KroneckerMass(S, J, np.flatnonzero(keep), mesh.n_nodes),
                      decoupled=decoupled)


def membrane_bending_coupling(Ke: np.ndarray, Me: np.ndarray) -> float:
    """Largest membrane-bending entry of the element matrices, relative to the largest entry of
    the same matrix (each basis stiffness and the mass): zero (to round-off) for a symmetric
    laminate. ``Ke``: (..., 72, 72) element stiffness matrices, ``Me``: (..., 72, 72) element
    mass matrices; local equation ``node * 9 + variable``."""
    bending = BENDING_LOCAL
    worst = 0.0
    for A in (np.asarray(Ke).reshape(-1, Ke.shape[-3], 72, 72),
              np.asarray(Me).reshape(1, -1, 72, 72)):
        scale = np.abs(A).max(axis=(1, 2, 3))
        cross = np.abs(A[:, :, bending][:, :, :, ~bending]).max(axis=(1, 2, 3))
        ok = scale > 0
        if ok.any():
            worst = max(worst, float(np.max(cross[ok] / scale[ok])))
    return worst
