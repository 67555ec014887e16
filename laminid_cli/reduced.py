"""Reduced-order eigen model of a plate, exact in the material parameters.

The stiffness is affine in the stiffness coefficients, ``K(c) = sum_mj c_mj K_mj``, and M is
fixed. With a mass-orthonormal basis V (n_dofs x r, ``V^T M V = I``) the projected matrices
``Kr_mj = V^T K_mj V`` are computed once per basis change; an evaluation at any c is then the
small dense eigenproblem ``(sum c_mj Kr_mj) y = theta Mr y`` (Rayleigh-Ritz; ``Mr = V^T M V``
is the identity up to round-off and kept exactly), with eigenvalue gradients
``d theta_i / d c_mj = y_i^T Kr_mj y_i`` (y_i Mr-orthonormal). Ritz values are upper
bounds of the eigenvalues (theta_i >= lambda_i) and only as good as the basis, so the basis is
enriched where the optimiser goes (:meth:`ReducedBasis.enrich`): one factorisation of
``A = K - sigma M`` (sigma < 0, so A is positive definite) and the preconditioned residuals
``s_i = A^-1 (K - theta_i M) u_i`` of the Ritz vectors ``u_i = V y_i`` are added to V.

Error bound (per mode, computed from the same solves): with ``eta_i^2 = r_i^T A^-1 r_i``,
expanding u_i in the M-orthonormal eigenvectors gives ``eta_i^2 = sum_j c_j^2 (lambda_j -
theta_i)^2 / (lambda_j - sigma)``, so some eigenvalue lambda lies within
``d_i = (eta_i^2 + sqrt(eta_i^4 + 4 eta_i^2 (theta_i - sigma))) / 2`` of theta_i; adding
vectors to the basis only moves each theta_i down towards lambda_i (Cauchy interlacing), so the
bound stays valid for the enriched Ritz values. The final check (:meth:`ReducedBasis.check`)
sharpens it where the neighbouring Ritz values leave a gap: Temple's argument with the same
``A^-1`` weights gives ``theta_i - lambda_i <~ eta_i^2 (b - sigma) / (b - theta_i)``, b a lower
bound of the next eigenvalue (:func:`residual_bounds`), quadratic in the residual.
"""

from __future__ import annotations

import copy

import numpy as np
import scipy.linalg as sla

from laminid_cli.errors import SolverError
from laminid_cli.modal import WORK, Modes, _m_orthonormal

#: columns added by an enrichment whose M-norm after orthogonalisation is below this (relative
#: to the normalised residual) add nothing and are dropped
DROP_TOL = 1e-9
#: an enrichment adds no residual of a mode whose relative error bound is below this (its
#: residual is round-off: it would add noise directions to the basis)
CONVERGED = 1e-13
#: with a target bound, a mode whose bound is below this fraction of it adds no residual (it
#: has reached its target; its residual is mostly round-off)
TARGET_MARGIN = 0.1
#: the basis is rebuilt from the current Ritz vectors when it would grow beyond this
MAX_BASIS = 260
#: a vector's even or odd part under the plate's half-turn (ReducedBasis.add) whose M-norm is
#: below this fraction of the vector's is dropped: the error of a vector of the other parity
#: (round-off; an eigen solver's tolerance: kept at 1e-8, the Lanczos modes' parts of 1e-7-1e-5
#: grew S1.1's basis from 96 to 113 vectors and the trials' from 163 to 216, each a direction
#: of noise). Dropping a part only leaves a direction out of the basis: the Ritz values stay
#: upper bounds, and the checks against the full model still decide.
PARITY_TOL = 1e-3
#: ReducedBasis._block_eig asks each class for this many eigenpairs beyond its count among
#: the lowest k at the last call
EXTRA_PER_CLASS = 2


def stiffness_ratio(coef: np.ndarray, coef_ref: np.ndarray) -> float:
    """mu with ``K(coef) >= mu K(coef_ref)`` (positive semi-definite order): the smallest
    generalised eigenvalue of each material's constitutive matrix at ``coef`` against the one
    at ``coef_ref`` (5x5, ply axes), over the materials. The stiffness is a sum over plies and
    elements of ``B^T T^T Q T B`` terms with the material's Q, so the order of the Qs carries
    over (the rotation T is a congruence); with M fixed and a shift sigma < 0, ``K(coef) -
    sigma M >= min(mu, 1) (K(coef_ref) - sigma M)``. Not positive: the ratio gives no bound."""
    return float(stiffness_ratios(coef, [coef_ref])[0])


def stiffness_ratios(coef: np.ndarray, coef_refs) -> np.ndarray:
    """:func:`stiffness_ratio` of ``coef`` (n_materials, 6) against each of ``coef_refs``, in
    one batched 5x5 computation; 0 against a reference whose constitutive matrices are not
    positive definite."""
    from laminid_cli.material import c_basis

    C = c_basis(0.0)                                          # (6, 5, 5)
    Q = np.tensordot(np.atleast_2d(np.asarray(coef, float)), C, axes=([-1], [0]))
    Q0 = np.tensordot(np.asarray(coef_refs, float).reshape(-1, *Q.shape[:1], 6), C,
                      axes=([-1], [0]))                       # (n_ref, n_mat, 5, 5)
    try:
        L_inv = np.linalg.inv(np.linalg.cholesky(Q0))
    except np.linalg.LinAlgError:                             # a reference not positive definite
        return np.array([stiffness_ratios(coef, [c])[0] if _pd(q) else 0.0
                         for c, q in zip(np.asarray(coef_refs, float), Q0)])
    G = L_inv @ Q @ np.swapaxes(L_inv, -1, -2)                # (n_ref, n_mat, 5, 5)
    return np.linalg.eigvalsh(0.5 * (G + np.swapaxes(G, -1, -2))).min(axis=(1, 2))


def _pd(Q: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(Q)
    except np.linalg.LinAlgError:
        return False
    return True


def residual_bound(theta: np.ndarray, eta2: np.ndarray, sigma: float) -> np.ndarray:
    """Absolute error bound of each Ritz value ``theta_i`` from ``eta2_i = r_i^T A^-1 r_i`` (A =
    K - sigma M, or an upper bound of it): some eigenvalue lies within ``d_i = (eta2 +
    sqrt(eta2^2 + 4 eta2 (theta_i - sigma))) / 2`` of theta_i (module docstring)."""
    return 0.5 * (eta2 + np.sqrt(eta2**2 + 4 * eta2 * (theta - sigma)))


def residual_bounds(theta: np.ndarray, eta2: np.ndarray, sigma: float) -> np.ndarray:
    """Absolute error bounds of Ritz values ``theta`` (M-orthonormal Ritz vectors of one
    Rayleigh-Ritz projection of the full matrices, any order) from ``eta2_i = r_i^T A^-1 r_i``
    (A = K - sigma M, or an upper bound of it): the smaller of the linear bound
    (:func:`residual_bound`) and a quadratic one where it applies.

    Quadratic (Temple's argument with the A^-1 weights), in ascending order of theta: with
    ``u_i = sum_j c_j phi_j``, ``theta_i >= lambda_i`` (interlacing), ``a = theta_(i-1) >=
    lambda_(i-1)`` and ``b = theta_(i+1) - d_(i+1) <= lambda_(i+1)`` (d the linear bound: the
    next Ritz value matched with the next eigenvalue, as the per-mode reading of the linear
    bound already assumes), ``(lambda - sigma) / (lambda - theta)`` decreasing above b and
    ``sum_j c_j^2 (lambda_j - theta_i) = 0`` give
    ``c_i^2 (theta_i - lambda_i) <= eta2 (b - sigma) / (b - theta_i)`` and
    ``1 - c_i^2 <= eta2 max((b - sigma) / (b - theta_i)^2, (a - sigma) / (theta_i - a)^2)``.
    The highest value keeps its linear bound (no next one). The quadratic bound is of order
    ``eta2 / gap``: a vector with relative residual 1e-6 has an eigenvalue exact to ~1e-12."""
    theta = np.asarray(theta, float)
    eta2 = np.asarray(eta2, float)
    order = np.argsort(theta, kind="stable")
    t_s, e_s = theta[order], eta2[order]
    lin = residual_bound(t_s, e_s, sigma)
    out = lin.copy()
    for i in range(t_s.size - 1):
        t, b = t_s[i], t_s[i + 1] - lin[i + 1]
        if not b > t:
            continue
        spill = (b - sigma) / (b - t) ** 2
        if i > 0:
            a = t_s[i - 1]
            if not a < t:
                continue
            spill = max(spill, (a - sigma) / (t - a) ** 2)
        ci2 = 1.0 - e_s[i] * spill
        if ci2 > 0:
            out[i] = min(lin[i], e_s[i] * (b - sigma) / ((b - t) * ci2))
    bound = np.empty_like(out)
    bound[order] = out
    return bound


def checked_ritz(U: np.ndarray, KU: np.ndarray, MU: np.ndarray, solve, sigma: float,
                 scale: float = 1.0):
    """(theta, R, bound) of M-normalised vectors U with ``KU = K U``, ``MU = M U`` (the full
    matrices): Rayleigh quotients, residuals ``K u - theta M u`` and the absolute error bounds of
    :func:`residual_bounds` from ``r^T A^-1 r <= scale r^T A_ref^-1 r`` (``solve.energy``: the
    forward half of the solve with a factor of ``A_ref = K_ref - sigma M``). The check of an
    identification's answer (:meth:`ReducedBasis.check`) and of a Monte Carlo trial's
    (``uncertainty.TrialModel.check``) both go through it."""
    theta = np.einsum("ij,ij->j", U, KU)
    R = KU - MU * theta
    eta2 = np.maximum(solve.energy(R), 0.0) * scale
    return theta, R, residual_bounds(theta, eta2, sigma)


class RitzModes(Modes):
    """Ritz modes of a reduced basis: :class:`Modes` whose shapes ``V Y`` are formed when first
    asked for (an optimiser's evaluation needs only the eigenvalues and the reduced vectors)."""

    def __init__(self, eigenvalues: np.ndarray, V: np.ndarray, Y: np.ndarray, n_rigid: int = 0):
        object.__setattr__(self, "eigenvalues", eigenvalues)
        object.__setattr__(self, "n_rigid", n_rigid)
        object.__setattr__(self, "rigid_eigenvalues", np.zeros(0))
        object.__setattr__(self, "_VY", (V, Y))       # V is replaced, never changed, on add

    @property
    def phi(self) -> np.ndarray:
        phi = self.__dict__.get("_phi")
        if phi is None:
            V, Y = self._VY
            phi = V @ Y
            object.__setattr__(self, "_phi", phi)
        return phi

    def columns(self, index) -> np.ndarray:
        """``phi[:, index]``, formed from those columns of Y only unless phi is formed."""
        phi = self.__dict__.get("_phi")
        if phi is not None:
            return phi[:, index]
        V, Y = self._VY
        return V @ Y[:, index]


class ReducedBasis:
    """Mass-orthonormal basis V of one plate and the projected basis stiffness matrices."""

    def __init__(self, fm, split: bool = False):
        plate = fm.plate
        self.fm = fm
        self.M = plate.mass                  # products M @ W (fe.assembly.KroneckerMass)
        n = plate.n_dofs
        n_mat = plate.K_data.shape[0]
        self.n_b = n_mat * 6
        self.n_mat = n_mat
        self.R = None
        if fm.rigid is not None:
            self.R = _m_orthonormal(fm.rigid, self.M)
            self.MR = self.M @ self.R
        self.V = np.zeros((n, 0))
        self.MV = np.zeros((n, 0))
        self.Kr = np.zeros((n_mat, 6, 0, 0))
        self.Mr = np.zeros((0, 0))          # V^T M V: I up to round-off, kept exactly
        # ``split``: the plate's half-turn about its normal
        # (fe.assembly.PlateModel.rotation_symmetry), where the model has it: every column of
        # V is then even (+1) or odd (-1) under it, and the reduced eigenproblem splits into
        # the two classes (eig); None: no split (parity 0). For the Monte Carlo trials'
        # basis (uncertainty.TrialModel), whose ~1600 eigenproblems per 200 trials it makes
        # ~40 % cheaper (200 trials of S1.1 12x12: CPU -17 %); not for an identification's,
        # whose ~90 eigenproblems gain less than the split costs its additions (S1.1 12x12:
        # 0.22-0.24 against 0.19-0.22 s)
        self.symmetry = plate.rotation_symmetry() if split else None
        self.parity = np.zeros(0)
        #: identity of the vectors: the basis only grows (its first columns stay) until a
        #: restart gives it a new lineage; copies share it
        self.lineage = object()

    @property
    def size(self) -> int:
        return self.V.shape[1]

    def copy(self) -> "ReducedBasis":
        """An independent basis with the same vectors (arrays are replaced, never changed in
        place, so a shallow copy suffices); a lineage of its own, since it grows apart."""
        out = copy.copy(self)
        out.lineage = object()
        return out

    @classmethod
    def from_vectors(cls, fm, V: np.ndarray) -> "ReducedBasis":
        """A basis of ``fm`` spanning the columns of V (e.g. another process's basis)."""
        b = cls(fm)
        b.add(V)
        return b

    def _project_out(self, W: np.ndarray, MW: np.ndarray, Z: np.ndarray | None = None,
                     MZ: np.ndarray | None = None) -> None:
        """Remove from W (in place) its M-components along the rigid motions and the columns
        of Z (default: the basis; ``MZ`` = M Z, M-orthonormal) (one classical Gram-Schmidt
        pass), and the same combination from MW = M W."""
        if Z is None:
            Z, MZ = self.V, self.MV
        if self.R is not None:
            C = self.MR.T @ W
            W -= self.R @ C
            MW -= self.MR @ C
        C = MZ.T @ W
        W -= Z @ C
        MW -= MZ @ C

    def _m_normalised(self, W: np.ndarray):
        """(W, M W, kept) with every column of W M-normalised; zero columns dropped (``kept``:
        the columns of the given W that remain)."""
        MW = self.M @ W
        norm = np.sqrt(np.einsum("ij,ij->j", W, MW))
        ok = norm > 0
        return W[:, ok] / norm[ok], MW[:, ok] / norm[ok], ok

    @staticmethod
    def _independent(W: np.ndarray, MW: np.ndarray) -> np.ndarray:
        """The directions of W with M-norm above DROP_TOL, M-orthonormalised by an eigen
        decomposition of their Gram matrix (``MW`` = M W)."""
        G = W.T @ MW
        d, Q = np.linalg.eigh(0.5 * (G + G.T))
        keep = d > DROP_TOL**2
        return W @ (Q[:, keep] / np.sqrt(d[keep]))

    def add(self, W: np.ndarray) -> int:
        """Add the directions of W (n, k) not yet in the basis; returns how many were added.

        With the plate's half-turn (:attr:`symmetry`), each column's even and odd parts
        ``(w +- S w) / 2`` are added as directions of their own class (a part below PARITY_TOL
        of its column is round-off and dropped), so that every basis vector is even or odd and
        :meth:`eig` solves the two classes apart."""
        W = np.array(W, float, copy=True)
        if W.ndim == 1:
            W = W[:, None]
        if self.symmetry is None:
            return self._add(W, np.zeros(W.shape[1]))
        rotate = self.fm.plate.rotate
        SW = rotate(self.symmetry, W)
        # (M commutes with the turn: M P is made of M W and its turn, one product with M)
        MW = self.M @ W
        SMW = rotate(self.symmetry, MW)
        norm = np.sqrt(np.einsum("ij,ij->j", W, MW))
        parts, labels = [], []
        for parity in (1, -1):
            P = 0.5 * (W + parity * SW)
            MP = 0.5 * (MW + parity * SMW)
            part = np.sqrt(np.maximum(np.einsum("ij,ij->j", P, MP), 0.0))
            keep = part > PARITY_TOL * norm
            parts.append(P[:, keep])
            labels.append(np.full(int(keep.sum()), float(parity)))
        return self._add(np.hstack(parts), np.concatenate(labels))

    def _add(self, W: np.ndarray, parity: np.ndarray) -> int:
        """Add the directions of W (n, k) not yet in the basis, column j of ``parity[j]``
        (+1 even, -1 odd under the half-turn, 0 without it); returns how many were added.
        Vectors of different parity are M-orthogonal by the symmetry: the steps that mix
        columns (the Gram matrix's eigen decomposition, the orthonormalisation) run per class,
        so that each added vector keeps its class.

        Classical Gram-Schmidt in the M inner product, twice; an eigen decomposition of the
        Gram matrix drops the directions that add nothing (M-norm below DROP_TOL); then twice
        more with an M-orthonormalisation for round-off. M W is formed twice (at the start and
        after the eigen decomposition, whose scaling amplifies round-off in the directions it
        keeps) and otherwise carried along by the same combinations as W."""
        W, MW, kept = self._m_normalised(W)
        parity = parity[kept]
        for _ in range(2):                                   # classical Gram-Schmidt, twice
            self._project_out(W, MW)
        classes = [parity == c for c in np.unique(parity)]
        if len(classes) <= 1:
            W = self._independent(W, MW)
            parity = np.full(W.shape[1], parity[0] if parity.size else 0.0)
        else:
            kept = [self._independent(W[:, c], MW[:, c]) for c in classes]
            parity = np.concatenate([np.full(w.shape[1], parity[c][0])
                                     for w, c in zip(kept, classes)])
            W = np.hstack(kept)
        if W.shape[1] == 0:
            return 0
        W = self._purified(W, parity)
        MW = self.M @ W
        classes = [parity == c for c in np.unique(parity)]
        for _ in range(2):                                   # clean up once more
            self._project_out(W, MW)
            if len(classes) == 1:
                W, MW = self._orthonormalised(W, MW)
            else:
                for c in classes:
                    W[:, c], MW[:, c] = self._orthonormalised(W[:, c], MW[:, c])
            W, MW = self._purified(W, parity), self._purified(MW, parity)
        k = W.shape[1]
        r = self.size
        n_b = self.n_b
        # K_b W side by side, (n, n_b k): V^T K_b W and W^T K_b W as one product each
        KW = self.fm.plate.basis_products(W)
        top = (self.V.T @ KW).reshape(r, n_b, k).transpose(1, 0, 2)     # (n_b, r, k)
        low = (W.T @ KW).reshape(k, n_b, k).transpose(1, 0, 2)          # (n_b, k, k)
        Kr = np.zeros((n_b, r + k, r + k))
        Kr[:, :r, :r] = self.Kr.reshape(n_b, r, r)
        Kr[:, :r, r:] = top
        Kr[:, r:, :r] = top.transpose(0, 2, 1)
        Kr[:, r:, r:] = 0.5 * (low + low.transpose(0, 2, 1))
        self.Kr = Kr.reshape(self.n_mat, 6, r + k, r + k)
        Mr = np.zeros((r + k, r + k))
        Mr[:r, :r] = self.Mr
        Mr[:r, r:] = self.V.T @ MW
        Mr[r:, :r] = Mr[:r, r:].T
        G = W.T @ MW
        Mr[r:, r:] = 0.5 * (G + G.T)
        self.Mr = Mr                         # (the standard form is extended when next asked)
        self.V = np.hstack([self.V, W])
        self.MV = np.hstack([self.MV, MW])
        self.parity = np.concatenate([self.parity, parity])
        return k

    def _purified(self, W: np.ndarray, parity: np.ndarray) -> np.ndarray:
        """Each column of W projected on its class, ``(w + p S w) / 2`` (p its parity, +1 or
        -1 in a split basis); also right for M W, since M commutes with S. W itself where the
        basis is not split (:attr:`symmetry` None, parity 0).

        The steps of :meth:`_add` that scale nearly dependent directions up (the Gram
        matrix's small eigenvalues, down to DROP_TOL^2) scale their round-off of the other
        class up too: unprojected, a class' new vectors came out 5e-6 impure after the
        sensitivities of S1.1 with G13, G23, nu12 fixed, their cross-class products were left
        out of the orthonormalisation, and after a few more additions the basis had lost its
        M-orthogonality (Cholesky of the reduced mass failed)."""
        if self.symmetry is None or not np.any(parity):
            return W
        return 0.5 * (W + parity * self.fm.plate.rotate(self.symmetry, W))

    @staticmethod
    def _orthonormalised(W: np.ndarray, MW: np.ndarray):
        """(W L^-T, M W L^-T) with ``W^T M W = L L^T``: W M-orthonormalised."""
        G = W.T @ MW
        try:
            L = np.linalg.cholesky(0.5 * (G + G.T))
        except np.linalg.LinAlgError as exc:
            raise SolverError("the reduced basis lost its M-orthogonality (singular Gram "
                              "matrix): a mesh too coarse for the measured modes (use a "
                              "finer --mesh; the paper uses 12x12) or try --solver full"
                              ) from exc
        return (sla.solve_triangular(L, W.T, lower=True, check_finite=False).T,
                sla.solve_triangular(L, MW.T, lower=True, check_finite=False).T)

    def _factorisation(self, coef: np.ndarray, first_eigenvalue):
        """(sigma, solve) at ``coef``: the factorisation of ``A = K - sigma M`` kept from the
        last call at the same ``coef``, else a new one with ``sigma = -lambda_1 / 2``,
        ``lambda_1 = first_eigenvalue(K)`` (an estimate of the first elastic eigenvalue)."""
        last = getattr(self, "_factor", None)
        if last is not None and last[0] == coef.tobytes():
            return last[1:]
        plate = self.fm.plate
        K = plate.stiffness(coef=coef)
        sigma = -0.5 * float(first_eigenvalue(K))
        # the old factor goes first (this attribute and the local ``last``): where no one else
        # holds it, its memory (and CHOLMOD's analysis, modal.SparseCholesky) serves the new one
        self._factor = last = None
        solve = self.fm.factorizer.factor(K.data - sigma * plate.M_on_K)
        self._factor = (coef.tobytes(), sigma, solve)
        return sigma, solve

    def add_sensitivities(self, coef: np.ndarray, phi: np.ndarray) -> int:
        """Add ``A^-1 K_b phi_i`` for every basis stiffness K_b and mode phi_i (one
        factorisation of A = K - sigma M at ``coef``): the directions of the first-order change
        of the modes with every stiffness coefficient, so that the basis follows the modes
        over a neighbourhood in every parameter direction (the poorly determined constants
        move far). Returns the directions added."""
        coef = np.asarray(coef, float)
        p0 = phi[:, 0]
        _, solve = self._factorisation(
            coef, lambda K: (p0 @ (K @ p0)) / (p0 @ (self.M @ p0)))
        return self.add(solve(self.fm.plate.basis_products(phi)))

    def eig(self, coef: np.ndarray, k: int):
        """Lowest ``k`` Ritz values and reduced eigenvectors (r, k) at coefficients ``coef``."""
        if k > self.size:
            raise SolverError(f"reduced basis of {self.size} vectors cannot give {k} modes")
        Linv, Kt = self._standard()
        WORK["reduced_eigenproblems"] += 1
        classes = self._classes()
        if classes is not None:
            # even and odd vectors are M- and K-orthogonal (the turn maps one class to minus
            # itself): the standard form is block diagonal in them up to round-off, and each
            # block gives its lowest values; two eigenproblems of r/2 cost ~0.6 of one of r
            theta, Z = self._block_eig(np.asarray(coef, float).reshape(-1),
                                       self._blocks_of(Kt, classes), classes, k)
            return theta, Linv.T @ Z
        A = (np.asarray(coef, float).reshape(-1) @ Kt.reshape(self.n_b, -1)).reshape(Linv.shape)
        _, Z = sla.eigh(A, subset_by_index=[0, k - 1], check_finite=False)
        # the eigenvalues as Rayleigh quotients of the eigenvectors: eigh's values carry an
        # absolute error of ~eps ||A||, and the basis' stiff directions make ||A|| ~1e5-1e6
        # times the lowest (relative error up to ~5e-10, seen); the quotient's error is
        # quadratic in the vectors' (~5e-12 against the full matrices' quotients, seen)
        theta = np.einsum("ij,ij->j", Z, A @ Z)
        order = np.argsort(theta)
        return theta[order], Linv.T @ Z[:, order]

    def _blocks_of(self, M: np.ndarray, classes) -> list:
        """The diagonal blocks ``M[..., idx, idx]`` of a stack of r x r matrices (the standard
        form Kt, or Kr) for each class of ``classes``, kept while ``M`` is the same array."""
        cache = self.__dict__.get("_block_cache", {})
        hit = cache.get(id(M))
        if hit is not None and hit[0] is M:
            return hit[1]
        # C-contiguous copies: numpy lays out ``M[..., idx]`` with the indexed axis outermost
        # (strides (96, 14016) on the last two axes of a 292-vector basis' block), so every
        # _block_eig copied each block again to reshape it (~0.9 ms a block) and energies'
        # matmul on it went by numpy's loops, not BLAS (0.74 against 0.14 ms)
        blocks = [np.ascontiguousarray(M[..., idx, :][..., idx]) for idx in classes]
        # (Kt's and Kr's of this basis size; a copy keeps its own dict)
        cache = {key: v for key, v in cache.items()
                 if v[0].shape[-1] == M.shape[-1] and key != id(M)}
        cache[id(M)] = (M, blocks)
        self._block_cache = cache
        return blocks

    def _block_eig(self, coef: np.ndarray, forms: list, classes, k: int):
        """(theta (k,), Z (r, k)): the lowest ``k`` eigenvalues of the standard form at
        ``coef`` (flat) from its diagonal blocks ``forms`` (:meth:`_blocks_of`) of
        ``classes``, ascending, with their eigenvectors in the whole basis' coordinates (zeros
        in the other class); the values as Rayleigh quotients, as :meth:`eig` says why.

        Each class is asked for as many as it gave at the last call plus EXTRA_PER_CLASS
        (half of k at the first): one class of r/2 with ~k/2 vectors costs ~0.3 of the whole
        eigenproblem with k (r = 164, k = 16: 2 x 0.38 against 1.34 ms). Where a class gave
        all it was asked for below the k-th value of the two together, it is asked again for
        k (its next values could be among the lowest k)."""
        hint = self.__dict__.get("_class_counts")
        if hint is None or len(hint) != len(classes):
            hint = [k // 2] * len(classes)
        mats = [(coef @ F.reshape(self.n_b, -1)).reshape(F.shape[1:]) for F in forms]

        def lowest(A, kk):
            _, Zb = sla.eigh(A, subset_by_index=[0, kk - 1], check_finite=False)
            return np.einsum("ij,ij->j", Zb, A @ Zb), Zb

        sols = [lowest(A, min(idx.size, k, h + EXTRA_PER_CLASS))
                for A, idx, h in zip(mats, classes, hint)]
        values = np.sort(np.concatenate([v for v, _ in sols]))
        kth = values[min(k, values.size) - 1]
        for c, (A, idx) in enumerate(zip(mats, classes)):
            if sols[c][0].size < min(idx.size, k) and np.max(sols[c][0]) <= kth:
                sols[c] = lowest(A, min(idx.size, k))
        theta = np.concatenate([v for v, _ in sols])
        order = np.argsort(theta, kind="stable")[:k]
        owner = np.concatenate([np.full(v.size, c) for c, (v, _) in enumerate(sols)])
        column = np.concatenate([np.arange(v.size) for v, _ in sols])
        self._class_counts = [int(np.count_nonzero(owner[order] == c))
                              for c in range(len(classes))]
        Z = np.zeros((sum(idx.size for idx in classes), k))
        for c, idx in enumerate(classes):
            mine = owner[order] == c
            Z[np.ix_(idx, np.flatnonzero(mine))] = sols[c][1][:, column[order][mine]]
        return theta[order], Z

    def reset_class_counts(self) -> None:
        """Forget :meth:`_block_eig`'s counts of the last call (the next one asks each class
        for half of k). A Monte Carlo trial starts with it, so that what it computes does not
        depend on the trials its process ran before (the subset asked for moves the
        eigenvectors in their last digits: 200 trials of S1.1 differed by up to 1.1e-8
        relative between -j 1 and -j 2)."""
        self.__dict__.pop("_class_counts", None)

    def _classes(self):
        """The column indices of the even and of the odd basis vectors (:meth:`add`), or None
        where the basis has no split (no half-turn, or one class only)."""
        if self.symmetry is None or self.parity.size != self.size:
            return None
        even = np.flatnonzero(self.parity > 0)
        odd = np.flatnonzero(self.parity < 0)
        if even.size == 0 or odd.size == 0 or even.size + odd.size != self.size:
            return None
        return even, odd

    def _standard(self):
        """(L^-1, L^-1 Kr_b L^-T) with ``Mr = L L^T``: the reduced eigenproblem in standard
        form, ``(sum c_b Kt_b) z = theta z``, ``y = L^-T z`` (what the generalised ``eigh``
        does at every call), once per basis change. The basis only grows (:meth:`add` appends
        columns), so after a change the form is extended (:meth:`_extend_standard`) rather
        than computed again."""
        std = getattr(self, "_std", None)
        r = self.size
        if std is not None and std[0].shape[0] == r:
            return std[0], std[1]
        if std is not None and 0 < std[0].shape[0] < r:
            self._std = std = self._extend_standard(*std)
            return std[0], std[1]
        L = np.linalg.cholesky(self.Mr)
        Linv = sla.solve_triangular(L, np.eye(r), lower=True, check_finite=False)
        Kb = self.Kr.reshape(self.n_b, r, r)
        Kt = Linv @ Kb @ Linv.T
        Kt = 0.5 * (Kt + Kt.transpose(0, 2, 1))
        self._std = (Linv, Kt, L)
        return Linv, Kt

    def _extend_standard(self, Linv, Kt, L):
        """The standard form of the first r0 columns, (L^-1, Kt, L), extended to the whole
        basis. With ``Mr = [[M11, B], [B^T, C]]`` and ``M11 = L L^T``, the new factor is
        ``[[L, 0], [E, F]]`` with ``E = B^T L^-T``, ``F F^T = C - E E^T``, and its inverse
        ``[[L^-1, 0], [G1, G2]]`` with ``G2 = F^-1``, ``G1 = -G2 E L^-1``; Kt keeps its block
        and gains ``L^-1 X`` and ``G1 X + G2 (K21 G1^T + K22 G2^T)`` with ``X = K11 G1^T + K12
        G2^T``: O(r^2 k) per basis matrix instead of O(r^3) (S1.1 12x12, r = 96 + 14: 0.22
        against 0.97 ms for the form computed again)."""
        r0, r = L.shape[0], self.size
        k = r - r0
        Mr = self.Mr
        E = (Linv @ Mr[:r0, r0:]).T                                  # (k, r0)
        F = np.linalg.cholesky(Mr[r0:, r0:] - E @ E.T)
        G2 = sla.solve_triangular(F, np.eye(k), lower=True, check_finite=False)
        G1 = -G2 @ E @ Linv                                          # (k, r0)
        Kb = self.Kr.reshape(self.n_b, r, r)
        K11, K12, K22 = Kb[:, :r0, :r0], Kb[:, :r0, r0:], Kb[:, r0:, r0:]
        X = K11 @ G1.T + K12 @ G2.T                                  # (n_b, r0, k)
        top = Linv @ X
        low = G1 @ X + G2 @ (K12.transpose(0, 2, 1) @ G1.T + K22 @ G2.T)
        Kt_new = np.empty((self.n_b, r, r))
        Kt_new[:, :r0, :r0] = Kt
        Kt_new[:, :r0, r0:] = top
        Kt_new[:, r0:, :r0] = top.transpose(0, 2, 1)
        Kt_new[:, r0:, r0:] = 0.5 * (low + low.transpose(0, 2, 1))
        Linv_new = np.zeros((r, r))
        Linv_new[:r0, :r0] = Linv
        Linv_new[r0:, :r0] = G1
        Linv_new[r0:, r0:] = G2
        L_new = np.zeros((r, r))
        L_new[:r0, :r0] = L
        L_new[r0:, :r0] = E
        L_new[r0:, r0:] = F
        return Linv_new, Kt_new, L_new

    def energies(self, Y: np.ndarray) -> np.ndarray:
        """``y_i^T Kr_mj y_i``: d theta_i / d coef[m, j], (n_materials, 6, k). Where the basis
        splits into even and odd vectors (:meth:`eig`), each y_i lies in one class (the other
        class' entries are round-off) and the products go by the class' block of Kr."""
        classes = self._classes()
        if classes is None:
            KY = np.matmul(self.Kr, Y)                       # (n_mat, 6, r, k)
            return np.einsum("mjak,ak->mjk", KY, Y)
        E = np.zeros(self.Kr.shape[:2] + (Y.shape[1],))
        weight = np.stack([np.einsum("ij,ij->j", Y[idx], Y[idx]) for idx in classes])
        owner = np.argmax(weight, axis=0)
        for c, (idx, K) in enumerate(zip(classes, self._blocks_of(self.Kr, classes))):
            cols = np.flatnonzero(owner == c)
            if cols.size:
                Yc = Y[np.ix_(idx, cols)]
                E[..., cols] = np.einsum("mjak,ak->mjk", np.matmul(K, Yc), Yc)
        return E

    def solve(self, coef: np.ndarray, k: int):
        """Ritz modes (a :class:`Modes` with full-size vectors) and their basis energies."""
        theta, Y = self.eig(coef, k)
        if np.any(theta <= 0):
            raise SolverError("reduced model: non-positive eigenvalue (infeasible constants?)")
        n_rigid = 0 if self.R is None else self.R.shape[1]
        return RitzModes(theta, self.V, Y, n_rigid), self.energies(Y), Y

    def mac(self, phi_ref, Y: np.ndarray, ritz=None) -> np.ndarray:
        """Mass-weighted MAC (n_ref, k) between full vectors ``phi_ref`` and the Ritz vectors
        of reduced eigenvectors ``Y`` (Mr-orthonormal): through ``V^T M phi_ref``, which is exact
        for vectors in the span of V (earlier Ritz vectors: the basis only grows).

        ``ritz = (lineage, r, Y_ref)`` when ``phi_ref`` are Ritz vectors ``V[:, :r] Y_ref`` of
        this basis' lineage: then ``V^T M phi_ref = Mr[:, :r] Y_ref`` and no product with the
        full vectors is needed. ``phi_ref`` may be a function that gives the vectors: it is
        called only when they are needed (an evaluation forms its Ritz vectors at full size
        on demand)."""
        if ritz is not None and ritz[0] is self.lineage and ritz[1] <= self.size:
            r, Y_ref = ritz[1], ritz[2]
            P = self.Mr[:, :r] @ Y_ref                        # (size, n_ref)
            den = np.einsum("ij,ij->j", Y_ref, P[:r])[:, None]
            return (P.T @ Y) ** 2 / den
        if callable(phi_ref):
            phi_ref = phi_ref()
        cached = getattr(self, "_mac_ref", None)
        if cached is None or cached[0] is not phi_ref or cached[1] != self.size:
            P = self.MV.T @ phi_ref                          # (r, n_ref)
            den = np.einsum("ij,ij->j", phi_ref, self.M @ phi_ref)[:, None]
            self._mac_ref = cached = (phi_ref, self.size, P, den)
        P, den = cached[2], cached[3]
        return (P.T @ Y) ** 2 / den

    def enrich(self, coef: np.ndarray, k: int, rounds: int = 2, target: float = 0.0,
               reuse: float = 0.0, keep: int = 0):
        """Enrich the basis at ``coef`` with the preconditioned residuals of the lowest ``k``
        Ritz modes: one factorisation (kept for a further call at the same ``coef``), up to
        ``rounds`` block solves with it, fewer when every relative bound is below ``target``.

        ``reuse`` > 0: when the kept factorisation is of coefficients within this relative
        distance of ``coef`` (every coefficient), it preconditions the residuals instead of a
        new one (the residuals themselves are those of the stiffness at ``coef``), and the
        bound holds with ``A_ref^-1`` in place of ``A^-1`` scaled by ``1 / min(mu, 1)``
        (:func:`stiffness_ratio`: ``A(coef) >= min(mu, 1) A_ref`` for the shift of A_ref).

        ``keep``: a basis restarted (it would grow beyond MAX_BASIS) keeps at least this many
        Ritz vectors (the modes its evaluations need, when ``k`` is fewer).

        Returns (Ritz values before, Ritz values after, absolute error bound of the values
        after, rad^2/s^2)."""
        coef = np.asarray(coef, float)
        kept = self._kept(coef, reuse)
        if kept is not None:
            return self._enrich_with(coef, k, rounds, *kept, target, keep=keep)
        theta0, Y = self.eig(coef, k)
        sigma, solve = self._factorisation(coef, lambda K: theta0[0])
        return self._enrich_with(coef, k, rounds, solve, sigma, 1.0, target, theta0, Y, keep)

    def _kept(self, coef: np.ndarray, reuse: float):
        """(solve, sigma, scale) of the kept factorisation when it is of other coefficients
        within ``reuse`` (relative, every coefficient) of ``coef``: ``A_ref^-1`` with its shift
        and the factor ``1 / min(mu, 1)`` that makes ``r^T A_ref^-1 r`` a bound of ``r^T
        A(coef)^-1 r``; None otherwise."""
        last = getattr(self, "_factor", None)
        if reuse <= 0 or last is None or last[0] == coef.tobytes():
            return None
        c0 = np.frombuffer(last[0]).reshape(coef.shape)
        if not np.all(np.abs(coef - c0) <= reuse * np.abs(c0)):
            return None
        mu = stiffness_ratio(coef, c0)
        if not mu > 0:
            return None
        return last[2], last[1], 1.0 / min(mu, 1.0)

    def residuals(self, coef: np.ndarray, theta: np.ndarray, Y: np.ndarray, solve):
        """(R, solve(R)): the residuals ``K u_i - theta_i M u_i`` of the Ritz vectors ``u_i =
        V y_i`` at ``coef`` and their preconditioned form (``solve``: (K_ref - sigma M)^-1),
        the directions an enrichment adds."""
        U = self.V @ Y
        R = self.fm.plate.stiffness_products(coef, U) - (self.M @ U) * theta
        return R, solve(R)

    def _enrich_with(self, coef, k, rounds, solve, sigma, scale=1.0, target=0.0, theta0=None,
                     Y=None, keep=0):
        """The block solves of :meth:`enrich` with ``solve`` = (K_ref - sigma M)^-1 and
        ``r^T A^-1 r <= scale r^T solve(r)``."""
        if self.size + rounds * k > MAX_BASIS:               # restart from the Ritz vectors
            theta, Y = self.eig(coef, max(k, keep))
            U = self.V @ Y
            self.__init__(self.fm)
            self.add(U)
            theta0 = None
        if theta0 is None:
            theta0, Y = self.eig(coef, k)
        theta = theta0
        bound = np.full(k, np.inf)
        for _ in range(rounds):
            Rs, S = self.residuals(coef, theta, Y, solve)
            eta2 = np.maximum(np.einsum("ij,ij->j", Rs, S), 0.0) * scale
            bound = residual_bound(theta, eta2, sigma)
            if np.max(bound / theta) <= target:
                break
            # a mode already converged to round-off adds only noise directions
            active = bound / theta > max(CONVERGED, TARGET_MARGIN * target)
            if not active.any():
                break
            added = self.add(S[:, active])
            theta, Y = self.eig(coef, k)
            if added == 0:
                break
        return theta0, theta, bound

    def check(self, coef: np.ndarray, U: np.ndarray, reuse: float = 0.0, target: float = 0.0,
              rounds: int = 1, n: int | None = None):
        """Ritz vectors ``U`` (n, k) checked with the full matrices at ``coef``: their Rayleigh
        quotients ``u^T K u / u^T M u`` (free of the round-off that the projected matrices
        carry from their stiff directions), the M-normalised vectors and the absolute error
        bound of each quotient (:func:`residual_bounds`: the linear bound of :meth:`enrich`, or
        the quadratic one where the neighbouring values leave a gap; with the factorisation
        kept from an enrichment at the same ``coef``, or within ``reuse`` of it, when there is
        one). The quadratic bound makes a mode whose vector has a relative residual of ~1e-6
        pass a 1e-9 eigenvalue target: the refinement below is then rarely needed more than
        once (S1.1: one step, where the linear bound took about six).

        ``target`` > 0: while some relative bound is above it, up to ``rounds - 1`` times, the
        vectors are refined by a Rayleigh-Ritz step on a local space: the vectors, and the
        preconditioned residuals of this and the earlier steps (block Davidson, with the same
        factorisation). The local space, k to a few k vectors, is not added to the basis: a
        step costs one block solve and k products with K and M, where an enrichment of the
        basis also projects the new vectors on the basis and on every basis stiffness (the
        bounds are of the vectors returned, whatever space they come from).

        ``n``: only the first n vectors are checked and returned; the others are refined with
        them as guards (the convergence of the highest wanted mode depends on its distance to
        the lowest one outside the local space)."""
        coef = np.asarray(coef, float)
        u0 = U[:, 0]
        kept = self._kept(coef, reuse)
        if kept is not None:
            solve, sigma, scale = kept
        else:
            sigma, solve = self._factorisation(
                coef, lambda K: (u0 @ (K @ u0)) / (u0 @ (self.M @ u0)))
            scale = 1.0
        plate = self.fm.plate
        k = U.shape[1]
        Z = U / np.sqrt(np.einsum("ij,ij->j", U, self.M @ U))
        KZ, MZ = plate.stiffness_products(coef, Z), self.M @ Z
        A, B = Z.T @ KZ, Z.T @ MZ                           # the local space's projections
        U, KU, MU = Z, KZ, MZ
        for step in range(max(rounds, 1)):
            if step:                                         # Rayleigh-Ritz on the local space
                _, C = sla.eigh(0.5 * (A + A.T), 0.5 * (B + B.T), subset_by_index=[0, k - 1],
                                check_finite=False)
                U, KU, MU = Z @ C, KZ @ C, MZ @ C
                norm = np.sqrt(np.einsum("ij,ij->j", U, MU))
                U, KU, MU = U / norm, KU / norm, MU / norm
            # r^T A^-1 r by the forward half of the solve for every vector; the whole solve
            # only for the residuals a refinement adds (at the end of a fit, a few guard modes)
            theta, Rs, bound = checked_ritz(U, KU, MU, solve, sigma, scale)
            rel = bound / theta
            if target <= 0 or step == rounds - 1 or np.max(rel[:n]) <= target:
                break
            active = rel > max(CONVERGED, TARGET_MARGIN * target)
            W, MW = self._orthonormal_to(solve(Rs[:, active]) if active.any()
                                         else Rs[:, :0], Z, MZ)
            if W.shape[1] == 0:
                break
            KW = plate.stiffness_products(coef, W)
            m = Z.shape[1]
            A2, B2 = np.empty((m + W.shape[1],) * 2), np.empty((m + W.shape[1],) * 2)
            for G, P, PW in ((A2, A, KW), (B2, B, MW)):
                G[:m, :m] = P
                G[:m, m:] = Z.T @ PW
                G[m:, :m] = G[:m, m:].T
                G[m:, m:] = W.T @ PW
            A, B = A2, B2
            Z, KZ, MZ = np.hstack([Z, W]), np.hstack([KZ, KW]), np.hstack([MZ, MW])
        if Z.shape[1] > k:
            # the refined vectors in the order of the vectors given (their identities: a
            # Rayleigh-Ritz step sorts by value, which may swap two close modes)
            P = (MZ[:, :k].T @ U) ** 2
            perm = np.argmax(P, axis=1)
            if np.array_equal(np.sort(perm), np.arange(k)):
                theta, U, bound = theta[perm], U[:, perm], bound[perm]
        return theta[:n], U[:, :n], bound[:n]

    def _orthonormal_to(self, W: np.ndarray, Z: np.ndarray, MZ: np.ndarray):
        """(W', M W'): the directions of W M-orthogonal to the columns Z (``MZ`` = M Z,
        M-orthonormal up to the conditioning a Rayleigh-Ritz step tolerates) and to the rigid
        motions, M-orthonormalised; those whose M-norm after orthogonalisation is below
        DROP_TOL (relative) dropped. One classical Gram-Schmidt pass: the local space's
        Rayleigh-Ritz step takes its Gram matrix as it is."""
        if W.shape[1] == 0:
            return W, W.copy()
        W, MW, _ = self._m_normalised(W)
        self._project_out(W, MW, Z, MZ)
        W = self._independent(W, MW)
        return W, self.M @ W
