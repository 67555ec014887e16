"""Free-vibration eigen solution and mode pairing.

Solves ``K phi = lambda M phi`` (paper Eq. 9/10) for the lowest modes with
``scipy.sparse.linalg.eigsh`` in shift-invert mode. The shift sigma is negative (paper Eq. 10's
``K + beta M`` with beta = -sigma), so the singular stiffness of a free plate is never
factorised.

Rigid-body modes: a free plate has a six-fold zero eigenvalue, and single-vector Lanczos can
miss members of a multiple eigenvalue (seen: 5 of 6 found on a 4x4 mesh). So the six rigid
motions, known in closed form, are checked to have zero strain energy, M-orthonormalised and
deflated from the shift-invert operator; a further near-zero eigenvalue among the elastic
modes is a mechanism of the model and fails loudly.
``K - sigma M`` is symmetric positive definite, so it is factorised by Cholesky: CHOLMOD's
supernodal factorisation with a fill-reducing ordering (through cvxopt, the optional ``fast``
extra; 2.5 times faster than the banded one at 12x12, 3 times at 24x24) or, without cvxopt, a
banded Cholesky (LAPACK ``pbtrf`` through SciPy) after a reverse Cuthill-McKee ordering, which
for plate meshes is 3-50 times faster than SuperLU and needs no extra package
(benchmarks/bench_forward.py). ``LAMINID_FACTORIZER=banded`` chooses the latter.

lambda = omega^2 in rad^2/s^2, freq in Hz; mode shapes ``phi`` are (n_dofs, n_modes) and
mass-normalised (phi^T M phi = I).
"""

from __future__ import annotations

import os
import weakref
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import reverse_cuthill_mckee

from laminid_cli.errors import ModelError, SolverError

#: a mode is rigid (a mechanism) when |lambda| < RIGID_TOL * |sigma| (the shift, of the first
#: elastic eigenvalue's order; :func:`solve_modes`)
RIGID_TOL = 1e-6

#: work done by this process: banded factorisations, solve pairs (one right-hand side through
#: the forward and back substitution), Lanczos runs and the reduced models' dense eigen
#: problems (laminid_cli.reduced.ReducedBasis.eig: one per reduced-model evaluation); read by
#: benchmarks/bench_identify.py and bench_uncertainty.py
WORK = {"factorizations": 0, "solve_pairs": 0, "lanczos_runs": 0, "reduced_eigenproblems": 0}


def reset_work() -> dict:
    """Zero the work counter; returns the counts before the reset."""
    before = dict(WORK)
    for k in WORK:
        WORK[k] = 0
    return before


@dataclass(frozen=True)
class Modes:
    """Elastic modes, ascending.

    Attributes
    ----------
    eigenvalues : (n_modes,) lambda = omega^2, rad^2/s^2
    phi : (n_dofs, n_modes) mass-normalised mode shapes
    n_rigid : rigid-body modes found and dropped
    rigid_eigenvalues : their eigenvalues (rad^2/s^2), for diagnostics
    """

    eigenvalues: np.ndarray
    phi: np.ndarray
    n_rigid: int = 0
    rigid_eigenvalues: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def omega(self) -> np.ndarray:
        """Angular frequencies, rad/s."""
        return np.sqrt(np.maximum(self.eigenvalues, 0.0))

    @property
    def freq(self) -> np.ndarray:
        """Natural frequencies, Hz."""
        return self.omega / (2 * np.pi)

    @property
    def n_modes(self) -> int:
        return int(self.eigenvalues.size)

    def columns(self, index) -> np.ndarray:
        """``phi[:, index]`` (reduced.RitzModes forms only those columns)."""
        return self.phi[:, index]


NOT_POSITIVE_DEFINITE = (
    "the factorisation of K - sigma M failed (not positive definite: the stiffness is "
    "indefinite or singular); check that the constants are admissible and the densities "
    "positive, or try another mesh (--mesh)")


class BandedCholesky:
    """Banded Cholesky factorisation for a fixed symmetric sparsity pattern.

    The fallback of :class:`SparseCholesky` (needs no extra package). The ordering and the map
    from CSR slots to LAPACK's upper band storage are computed once (:meth:`from_pattern`);
    :meth:`factor` then costs one scatter and one ``pbtrf``.
    """

    name = "banded"

    def __init__(self, n: int, perm: np.ndarray, bandwidth: int, upper_slots: np.ndarray,
                 band_index: np.ndarray):
        self.n, self.perm, self.bandwidth = n, perm, bandwidth
        self.upper_slots, self.band_index = upper_slots, band_index

    @classmethod
    def from_pattern(cls, indptr: np.ndarray, indices: np.ndarray,
                     block: int = 1) -> "BandedCholesky":
        """Plan the factorisation of matrices with this CSR pattern (sorted indices).

        ``block`` > 1 orders whole nodes (``block`` consecutive equations each) with reverse
        Cuthill-McKee on the node graph, which gives a narrower band for FE matrices than
        ordering single equations; the natural order is kept when it is narrower still. A
        pattern of independent blocks (a symmetric laminate's membrane and bending equations,
        ``fe.assembly.build_plate_model``) is ordered block after block, each in the order of
        a candidate above: the band is the widest block's (S1.1 12x12: 204 equations instead
        of 368, a factorisation 25 -> 11 ms).
        """
        from scipy.sparse.csgraph import connected_components

        n = len(indptr) - 1
        rows_nat = np.repeat(np.arange(n), np.diff(indptr))
        candidates = [np.arange(n)]
        pattern = sp.csr_matrix((np.ones(len(indices)), indices, indptr), shape=(n, n))
        if block > 1 and n % block == 0:
            nodes = sp.csr_matrix((np.ones(len(indices)), (rows_nat // block, indices // block)),
                                  shape=(n // block,) * 2)
            node_perm = reverse_cuthill_mckee(nodes.tocsr(), symmetric_mode=True)
            candidates.append((node_perm[:, None] * block + np.arange(block)).ravel())
        else:
            candidates.append(reverse_cuthill_mckee(pattern, symmetric_mode=True))
        n_blocks, label = connected_components(pattern, directed=False)
        for perm in list(candidates) if n_blocks > 1 else ():
            position = np.empty(n, dtype=np.int64)
            position[perm] = np.arange(n)
            candidates.append(np.lexsort((position, label)))
        best = None
        for perm in candidates:
            perm = np.asarray(perm, dtype=np.int64)
            inv = np.empty(n, dtype=np.int64)
            inv[perm] = np.arange(n)
            rows, cols = inv[rows_nat], inv[indices]
            bw = int(np.max(np.abs(cols - rows)))
            if best is None or bw < best[1]:
                best = (perm, bw, rows, cols)
        perm, bw, rows, cols = best
        upper = np.flatnonzero(rows <= cols)
        # LAPACK upper band storage: ab[bw + i - j, j] = A[i, j] for i <= j
        band_index = (bw + rows[upper] - cols[upper]) * n + cols[upper]
        return cls(n, perm, bw, upper, band_index)

    def factor(self, data: np.ndarray):
        """Factorise the matrix with CSR ``data`` on this pattern; returns ``solve(x)``."""
        ab = np.zeros((self.bandwidth + 1) * self.n)
        ab[self.band_index] = data[self.upper_slots]
        try:
            cb = sla.cholesky_banded(ab.reshape(self.bandwidth + 1, self.n), overwrite_ab=True,
                                     check_finite=False)
        except np.linalg.LinAlgError as exc:
            raise SolverError(NOT_POSITIVE_DEFINITE) from exc
        WORK["factorizations"] += 1
        return BandFactor(cb, self.perm)


class BandFactor:
    """``A = U^T U`` on a :class:`BandedCholesky` plan (LAPACK upper band storage ``cb``, the
    plan's ordering ``perm``): ``A^-1 x`` by calling it, and ``r^T A^-1 r = |U^-T r|^2`` per
    column by :meth:`energy` (one triangular solve: half a solve pair)."""

    def __init__(self, cb: np.ndarray, perm: np.ndarray):
        self.cb, self.perm = cb, perm
        self.blocks = _BandBlocks(cb)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        WORK["solve_pairs"] += 1 if x.ndim == 1 else x.shape[1]
        y = np.empty_like(x)
        y[self.perm] = self.blocks.solve(x[self.perm])
        return y

    def energy(self, R: np.ndarray) -> np.ndarray:
        """``r^T A^-1 r`` of each column of R (n, k), counted as half a solve pair each."""
        R = np.asarray(R, float)
        if R.ndim == 1:
            R = R[:, None]
        WORK["solve_pairs"] += (R.shape[1] + 1) // 2
        Z = self.blocks.forward(R[self.perm])
        return np.einsum("ij,ij->j", Z, Z)


#: the factorisations :func:`make_factorizer` knows, fastest first
FACTORIZERS = ("cholmod", "banded")
#: environment variable that chooses one of FACTORIZERS (default: the first available)
FACTORIZER_ENV = "LAMINID_FACTORIZER"


def cholmod_available() -> bool:
    """Whether CHOLMOD (through cvxopt, the optional ``fast`` extra) can be imported."""
    try:
        import cvxopt.cholmod  # noqa: F401
    except ImportError:
        return False
    return True


def default_factorizer() -> str:
    """The factorisation used when none is asked for: ``$LAMINID_FACTORIZER`` when set, else
    CHOLMOD when cvxopt is installed, else the banded Cholesky."""
    asked = os.environ.get(FACTORIZER_ENV, "").strip().lower()
    if asked:
        if asked not in FACTORIZERS:
            raise ModelError(f"{FACTORIZER_ENV}={asked!r} is not a factorisation laminid "
                             f"knows (one of {', '.join(FACTORIZERS)})")
        if asked == "cholmod" and not cholmod_available():
            raise ModelError(f"{FACTORIZER_ENV}=cholmod, but cvxopt (CHOLMOD) is not "
                             "installed: pip install 'laminid[fast]' or cvxopt")
        return asked
    return "cholmod" if cholmod_available() else "banded"


def make_factorizer(indptr: np.ndarray, indices: np.ndarray, block: int = 1,
                    kind: str | None = None):
    """A factorisation plan for symmetric positive definite matrices with this CSR pattern
    (sorted indices): :class:`SparseCholesky` (CHOLMOD) or :class:`BandedCholesky`, by ``kind``
    (default :func:`default_factorizer`). Both give ``factor(data)`` -> a factor that solves
    (``factor(x)``) and gives ``r^T A^-1 r`` (``factor.energy(R)``)."""
    kind = default_factorizer() if kind is None else kind
    if kind == "cholmod":
        return SparseCholesky.from_pattern(indptr, indices)
    if kind == "banded":
        return BandedCholesky.from_pattern(indptr, indices, block=block)
    raise ModelError(f"unknown factorisation {kind!r} (one of {', '.join(FACTORIZERS)})")


class SparseCholesky:
    """Supernodal sparse Cholesky (CHOLMOD, through cvxopt) for a fixed symmetric pattern.

    The fill-reducing ordering (AMD) and the supernodal analysis (~6 ms at 12x12) are made
    at the first :meth:`factor` (none for a plan never used), and once for each factor alive
    at the same time: a factor no longer referenced returns its
    analysis to a pool, and the next :meth:`factor` costs one gather of the lower triangle
    and CHOLMOD's numeric factorisation. With ``P A P^T = L L^T``, a solve is two supernodal triangular solves and
    ``r^T A^-1 r = |L^-1 P r|^2`` needs the forward one only.

    On S1.1 at 12x12 (4329 equations, single thread), against :class:`BandedCholesky`: 743 k
    entries in L against 1.6 M in the band; factorisation 10.7 against 27 ms; a solve of 16
    right-hand sides 5.9 against 7.6 ms; one of a single vector 0.36 against 0.46 ms
    (benchmarks/bench_forward.py).
    """

    name = "cholmod"

    def __init__(self, n: int, slots: np.ndarray, rows: np.ndarray, cols: np.ndarray):
        self.n, self.slots, self.rows, self.cols = n, slots, rows, cols
        self._A = None
        self._pool = []

    @classmethod
    def from_pattern(cls, indptr: np.ndarray, indices: np.ndarray,
                     block: int = 1) -> "SparseCholesky":
        """Plan the factorisation of matrices with this symmetric CSR pattern (sorted indices;
        ``block`` is accepted for the banded plan's signature and not needed here)."""
        n = len(indptr) - 1
        rows_csr = np.repeat(np.arange(n), np.diff(indptr))
        # the upper triangle of row i, in CSR order, is column i of the lower triangle (A is
        # symmetric): already in CHOLMOD's compressed-column order, rows ascending
        slots = np.flatnonzero(indices >= rows_csr)
        # the pattern matrix and its analysis (~8 ms at 12x12) wait for the first factor():
        # a plan never factorised costs nothing (the whole plate's, when an identification
        # works on its bending equations alone: forward.bending_model)
        return cls(n, slots, indices[slots].astype(np.int64), rows_csr[slots].astype(np.int64))

    def __getstate__(self):                  # CHOLMOD's objects do not pickle: redone there
        return {"n": self.n, "slots": self.slots, "rows": self.rows, "cols": self.cols}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._A, self._pool = None, []

    def _matrix(self):
        if self._A is None:
            from cvxopt import spmatrix

            self._A = spmatrix(np.ones(len(self.slots)), self.rows, self.cols, (self.n, self.n))
        return self._A

    def _analyse(self, supernodal: int = 2):
        """CHOLMOD's ordering and analysis of the pattern: supernodal (2, BLAS-3 blocks) for
        the factorisations; simplicial (0) gives a factor whose entries can be read
        (``cholmod.getfactor``, benchmarks/bench_forward.py)."""
        from cvxopt import cholmod

        saved = dict(cholmod.options)
        cholmod.options["supernodal"] = supernodal
        try:
            return cholmod.symbolic(self._matrix(), uplo="L")
        finally:
            cholmod.options.clear()
            cholmod.options.update(saved)

    def factor(self, data: np.ndarray) -> "CholmodFactor":
        """Factorise the matrix with CSR ``data`` on this pattern."""
        from cvxopt import cholmod, matrix

        A = self._matrix()
        A.V = matrix(np.ascontiguousarray(data[self.slots], dtype=float))
        F = self._pool.pop() if self._pool else self._analyse()
        try:
            cholmod.numeric(A, F)
        except ArithmeticError as exc:
            raise SolverError(NOT_POSITIVE_DEFINITE) from exc
        WORK["factorizations"] += 1
        out = CholmodFactor(F)
        weakref.finalize(out, self._pool.append, F)
        return out


class CholmodFactor:
    """A :class:`SparseCholesky` factor: ``A^-1 x`` by calling it, ``r^T A^-1 r`` per column
    by :meth:`energy` (the forward triangular solve only: half a solve pair)."""

    def __init__(self, F):
        self.F = F

    def __call__(self, x: np.ndarray) -> np.ndarray:
        from cvxopt import cholmod, matrix

        x = np.asarray(x, float)
        WORK["solve_pairs"] += 1 if x.ndim == 1 else x.shape[1]
        X = matrix(x)
        cholmod.solve(self.F, X)
        return np.array(X).reshape(x.shape)

    def energy(self, R: np.ndarray) -> np.ndarray:
        """``r^T A^-1 r`` of each column of R (n, k), counted as half a solve pair each."""
        from cvxopt import cholmod, matrix

        R = np.asarray(R, float)
        if R.ndim == 1:
            R = R[:, None]
        WORK["solve_pairs"] += (R.shape[1] + 1) // 2
        X = matrix(R)
        cholmod.solve(self.F, X, sys=7)      # P r
        cholmod.solve(self.F, X, sys=4)      # L^-1 P r
        Z = np.array(X)
        return np.einsum("ij,ij->j", Z, Z)


#: right-hand sides from which a solve goes block by block (level-3 BLAS) instead of through
#: LAPACK's column-by-column banded solve, when the factor is larger than BLOCK_BAND_BYTES;
#: twice as many when it is smaller (it then stays in the cache, and LAPACK's passes through
#: it are cheap). Measured on S1.1, single thread, 32 MiB L3, solve blocked / LAPACK, 16
#: right-hand sides: 8x8 (4 MB) 2.6 / 2.6 ms, 12x12 (13 MB) 10.1 / 8.7, 16x16 (29 MB)
#: 22.7 / 39.5, 24x24 (91 MB) 77 / 154; 24: 12x12 12.0 / 13.0
BLOCK_RHS = 12
BLOCK_BAND_BYTES = 16e6
#: the same for the forward half alone (BandFactor.energy): LAPACK's tbtrs is better for
#: longer (16 columns: 12x12 5.8 / 3.6 ms, 16x16 14.2 / 11.3, 24x24 43 / 43; 24 columns:
#: 16x16 15.7 / 17.0, 24x24 52 / 72; 36 columns: 12x12 8.7 / 7.6)
BLOCK_RHS_FORWARD = 24


class _BandBlocks:
    """Triangular solves with a banded Cholesky factor ``A = U^T U`` (LAPACK upper band storage
    ``cb``, bandwidth bw) block by block, for many right-hand sides at once.

    With blocks of bw equations, U is block bidiagonal: upper-triangular diagonal blocks
    ``U_ii`` and lower-triangular blocks ``U_i,i+1`` above them. ``U^T y = b`` is then
    ``y_i = U_ii^-T (b_i - U_i-1,i^T y_i-1)`` and ``U x = y`` is ``x_i = U_ii^-1 (y_i - U_i,i+1
    x_i+1)``: triangular solves and products with all right-hand sides at once, where
    ``cho_solve_banded`` (LAPACK pbtrs) goes column by column through the whole factor and is
    bound by memory traffic. In the column-major band storage ``U[r, c]`` sits at flat index
    ``bw + r + c bw``, so each block is a strided view (leading dimension bw) of the factor: the
    diagonal blocks are used as they are (the triangular solves read only their upper
    triangle), the off-diagonal ones are copied once with their lower triangle.
    """

    def __init__(self, cb: np.ndarray):
        self.cb = cb
        self.bw = bw = cb.shape[0] - 1
        self.n = n = cb.shape[1]
        self.edges = list(range(0, n, max(bw, 1))) + [n]
        self._off = None

    def _view(self, r0, nr, c0, nc):
        flat = self.cb.ravel(order="F")
        bw = self.bw
        item = flat.itemsize
        return np.lib.stride_tricks.as_strided(flat[bw + r0 + c0 * bw:], shape=(nr, nc),
                                               strides=(item, item * bw), writeable=False)

    def _blocks(self):
        if self._off is None:
            e = self.edges
            diag, off = [], []
            for i in range(len(e) - 1):
                nr = e[i + 1] - e[i]
                diag.append(self._view(e[i], nr, e[i], nr))
                if i + 2 < len(e):
                    nc = e[i + 2] - e[i + 1]
                    off.append(np.tril(self._view(e[i], nr, e[i + 1], nc), nr - self.bw))
            self._diag, self._off = diag, off
        return self._diag, self._off

    def _blocked(self, b: np.ndarray, forward: bool = False) -> bool:
        """Whether ``b`` goes block by block (else through LAPACK, column by column), for a
        solve or (``forward``) the forward half alone (BLOCK_RHS, BLOCK_RHS_FORWARD)."""
        if not (self.bw > 0 and self.cb.flags.f_contiguous and b.ndim == 2):
            return False
        k = BLOCK_RHS_FORWARD if forward else BLOCK_RHS
        return b.shape[1] >= (k if self.cb.nbytes > BLOCK_BAND_BYTES else 2 * k)

    def forward(self, b: np.ndarray, blocked: bool | None = None) -> np.ndarray:
        """``U^-T b`` (a new array); ``blocked``: the choice of the caller (default: the
        forward half's own)."""
        if not (self._blocked(b, forward=True) if blocked is None else blocked):
            from scipy.linalg.lapack import dtbtrs

            z, info = dtbtrs(self.cb, b, uplo="U", trans="T")
            if info:
                raise SolverError(f"triangular band solve failed (LAPACK info {info})")
            return z
        from scipy.linalg.blas import dtrsm

        diag, off = self._blocks()
        e = self.edges
        x = np.array(b, float, order="C", copy=True)
        # a row block x_i (C order) is x_i^T in column-major order: solve x_i^T U_ii = b_i^T
        # in place, from the right
        for i in range(len(diag)):                                 # U^T y = b
            xi = x[e[i]:e[i + 1]]
            if i:
                xi -= off[i - 1].T @ x[e[i - 1]:e[i]]
            xt = dtrsm(1.0, diag[i], xi.T, side=1, lower=0, trans_a=0, overwrite_b=1)
            if not np.shares_memory(xt, xi):
                xi[:] = xt.T
        return x

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b``."""
        if not self._blocked(b):
            return sla.cho_solve_banded((self.cb, False), b, check_finite=False)
        from scipy.linalg.blas import dtrsm

        diag, off = self._blocks()
        e = self.edges
        x = self.forward(b, blocked=True)
        for i in range(len(diag) - 1, -1, -1):                     # U x = y
            xi = x[e[i]:e[i + 1]]
            if i + 1 < len(diag):
                xi -= off[i] @ x[e[i + 1]:e[i + 2]]
            # x_i^T U_ii^T = y_i^T
            xt = dtrsm(1.0, diag[i], xi.T, side=1, lower=0, trans_a=1, overwrite_b=1)
            if not np.shares_memory(xt, xi):
                xi[:] = xt.T
        return x


def solve_modes(K: sp.spmatrix, M: sp.spmatrix, n_modes: int, *, sigma: float,
                rigid: np.ndarray | None = None, margin: int = 4, tol: float = 1e-12,
                factorizer=None, v0: np.ndarray | None = None,
                M_on_pattern: np.ndarray | None = None, M_products=None) -> Modes:
    """Lowest ``n_modes`` elastic modes of ``K phi = lambda M phi``.

    Parameters
    ----------
    K, M : sparse symmetric (n, n); K positive semi-definite, M positive definite
    n_modes : elastic modes wanted
    sigma : shift (rad^2/s^2), negative, of the order of minus the first elastic eigenvalue
        (e.g. ``-PlateModel.shift_estimate(coef)`` or minus the last solution's first
        eigenvalue); shift-invert converges fast when |sigma| is close to the wanted ones
    rigid : (n, n_rigid) rigid-body motions (``PlateModel.rigid_modes()``) to deflate; they
        must have zero strain energy, else :class:`SolverError`
    margin : extra modes asked of Lanczos so that the wanted ones converge well
    factorizer : precomputed plan (:func:`make_factorizer`) for the CSR pattern of K; made here
        when omitted
    M_on_pattern : M's values on K's pattern (``PlateModel.M_on_K``) when M is stored with a
        sparser pattern of its own; needed with a factorizer unless K and M share a pattern
    v0 : starting vector for Lanczos (e.g. a combination of the previous step's modes)
    M_products : M in a form faster for products (``M_products @ x`` equal to ``M @ x``, e.g.
        ``PlateModel.mass``); M itself when omitted
    """
    n = K.shape[0]
    n_rigid = 0 if rigid is None else rigid.shape[1]
    k = n_modes + margin
    if n_modes < 1:
        raise SolverError("at least one mode must be asked for")
    if k + n_rigid >= n - 1:
        raise SolverError(f"{n_modes} modes asked but the model has only {n} equations; "
                          "use a finer mesh or fewer modes")
    if not sigma < 0:
        raise SolverError(f"the shift must be negative (got {sigma})")
    if factorizer is None:
        A = (K - sigma * M).tocsr()
        A.sort_indices()
        factorizer = make_factorizer(A.indptr, A.indices)
        solve = factorizer.factor(A.data)
    else:
        if M_on_pattern is None:
            if K.nnz != M.nnz or not np.array_equal(K.indices, M.indices):
                raise SolverError("K and M must share one sparsity pattern with a factorizer")
            M_on_pattern = M.data
        solve = factorizer.factor(K.data - sigma * M_on_pattern)

    Mx = M if M_products is None else M_products
    rigid_lambda = np.zeros(0)
    if n_rigid:
        R = _m_orthonormal(rigid, Mx)
        MR = Mx @ R
        rigid_lambda = np.einsum("ij,ij->j", R, K @ R)
        if np.abs(rigid_lambda).max() > RIGID_TOL * abs(sigma):
            raise SolverError("the rigid-body motions have strain energy: the element or the "
                              "boundary conditions are wrong")

        def op(x):
            y = solve(x)
            return y - R @ (MR.T @ y)
    else:
        op = solve
    if v0 is None:
        v0 = np.random.default_rng(12345).standard_normal(n)
    if n_rigid:
        v0 = v0 - R @ (MR.T @ v0)
    OPinv = spla.LinearOperator(K.shape, matvec=op, dtype=float)
    M_op = M if M_products is None else spla.LinearOperator(
        M.shape, matvec=lambda x: Mx @ x, matmat=lambda X: Mx @ X, dtype=float)
    WORK["lanczos_runs"] += 1
    try:
        vals, vecs = spla.eigsh(K, k=k, M=M_op, sigma=sigma, which="LM", OPinv=OPinv,
                                tol=tol, v0=v0)
    except spla.ArpackNoConvergence as exc:
        raise SolverError(f"the eigen solver (ARPACK) did not converge for {k} modes of a "
                          f"{n}-equation model; try fewer modes (--modes), another mesh "
                          "(--mesh) or check the constants and densities") from exc
    except (spla.ArpackError, ValueError) as exc:
        reason = " ".join(str(exc).split())
        raise SolverError(f"the eigen solver (ARPACK) failed for {k} modes of a {n}-equation "
                          f"model ({reason}); try fewer modes (--modes), another mesh (--mesh) "
                          "or check the constants and densities") from exc
    order = np.argsort(vals)
    vals, vecs = vals[order], vecs[:, order]
    # a mechanism is zero against the first elastic eigenvalue (|sigma| is of its order); not
    # against the largest computed one, which for most of a coarse model's modes is 1e6 times
    # the first and made its lowest elastic modes look like zeros
    near_zero = np.abs(vals) < RIGID_TOL * abs(sigma)
    if near_zero.any():
        raise SolverError(
            f"expected {n_rigid} rigid-body modes but found {n_rigid + int(near_zero.sum())} "
            f"near-zero frequencies (lowest elastic: "
            f"{np.array2string(np.sqrt(np.abs(vals[:3])) / (2 * np.pi), precision=4)} Hz): "
            "the model has a mechanism, or a support that does not hold the plate")
    if np.any(vals <= 0):
        raise SolverError("negative eigenvalue: the stiffness is not positive semi-definite "
                          "(infeasible constants?)")
    phi = vecs[:, :n_modes]
    # eigsh returns M-orthonormal vectors; normalise again to remove round-off drift
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, Mx @ phi))
    return Modes(eigenvalues=vals[:n_modes], phi=phi, n_rigid=n_rigid,
                 rigid_eigenvalues=rigid_lambda)


def _m_orthonormal(R: np.ndarray, M: sp.spmatrix) -> np.ndarray:
    """M-orthonormal basis of the columns of R (Cholesky of the small Gram matrix)."""
    G = R.T @ (M @ R)
    try:
        L = np.linalg.cholesky(G)
    except np.linalg.LinAlgError as exc:
        raise SolverError("the rigid-body motions are not independent under the mass matrix "
                          "(singular factorisation); check the densities and ply thicknesses, "
                          "or try another mesh (--mesh)") from exc
    return np.linalg.solve(L, R.T).T


def mac(phi_a: np.ndarray, phi_b: np.ndarray, M: sp.spmatrix | None = None) -> np.ndarray:
    """Modal assurance criterion matrix (n_a, n_b), mass-weighted when M is given."""
    Mb = phi_b if M is None else M @ phi_b
    Ma = phi_a if M is None else M @ phi_a
    num = np.abs(phi_a.T @ Mb) ** 2
    den = np.outer(np.einsum("ij,ij->j", phi_a, Ma), np.einsum("ij,ij->j", phi_b, Mb))
    return num / den
