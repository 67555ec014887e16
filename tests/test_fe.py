"""Finite-element verification against closed forms, the Navier oracle and element properties."""

import numpy as np
import pytest

from laminid_cli.errors import ModelError, SolverError
from laminid_cli.fe.assembly import boundary_code, build_plate_model
from laminid_cli.fe.element import gauss_rule, shape_functions
from laminid_cli.fe.mesh import parse_mesh, rectangular_mesh
from laminid_cli.material import ElasticConstants
from laminid_cli.modal import solve_modes
from tests.oracles.navier_tsdt import lowest_frequencies
from tests.factorizers import HAVE_CHOLMOD, KINDS

# converged thin-plate frequency parameters omega a^2 sqrt(rho h / D) of the completely free
# square isotropic plate, nu = 0.3, first six elastic modes (README, "How we know it is right")
FREE_SQUARE = np.array([13.468, 19.596, 24.270, 34.801, 34.801, 61.093])


def isotropic(E=70e9, nu=0.3):
    G = E / (2 * (1 + nu))
    return ElasticConstants(E, E, G, G, G, nu)


def single_layer_model(a, b, h, c, rho, n, boundary="free", integration="selective", angle=0.0):
    return build_plate_model(rectangular_mesh(a, b, n, n), h, np.array([-h / 2, h / 2]),
                             np.array([angle]), np.array([0]), np.array([rho]),
                             boundary=boundary, integration=integration), c


def cross_ply_model(angles_deg, a, h, c, rho, n, boundary="simply-supported"):
    z = np.linspace(-h / 2, h / 2, len(angles_deg) + 1)
    pm = build_plate_model(rectangular_mesh(a, a, n, n), h, z, np.deg2rad(angles_deg),
                           np.zeros(len(angles_deg), int), np.full(len(angles_deg), rho),
                           boundary=boundary)
    return pm, z


def solve(pm, constants, n_modes):
    coef = pm.coefficients(constants)
    return solve_modes(pm.stiffness(coef=coef), pm.M, n_modes, rigid=pm.rigid_modes(),
                       sigma=-0.5 * pm.shift_estimate(coef))


# --- element basics -------------------------------------------------------------------------

def test_shape_functions_partition_of_unity_and_nodal_values():
    pts, _ = gauss_rule(3)
    N, dN = shape_functions(pts)
    assert np.allclose(N.sum(axis=1), 1.0, atol=1e-14)
    assert np.allclose(dN.sum(axis=2), 0.0, atol=1e-14)
    from laminid_cli.fe.element import NODE_XI
    Nn, _ = shape_functions(NODE_XI)
    assert np.allclose(Nn, np.eye(8), atol=1e-14)


def test_mesh_counts_of_the_design_notes():
    m = rectangular_mesh(0.2105, 0.311, 12, 12)
    assert m.n_nodes == 481 and m.n_elements == 144
    assert m.nodes[:, 0].max() == pytest.approx(0.2105) and m.nodes[:, 1].max() == pytest.approx(0.311)
    assert parse_mesh("16x24") == (16, 24) and parse_mesh("8") == (8, 8)
    with pytest.raises(ModelError, match="NXxNY"):
        parse_mesh("twelve")


def test_boundary_codes():
    assert boundary_code("free") == "FFFF"
    assert boundary_code("Simply-Supported") == "SSSS"
    assert boundary_code("sfsf") == "SFSF"
    with pytest.raises(ModelError, match="F/S/C"):
        boundary_code("pinned")


def test_rigid_body_motions_have_zero_strain_energy():
    """The six rigid motions, written in the scaled nodal variables, are in the null space of K."""
    h = 0.003
    pm, c = single_layer_model(0.2, 0.3, h, isotropic(), 1600.0, 4)
    K = pm.stiffness([c])
    x, y = pm.mesh.nodes[:, 0], pm.mesh.nodes[:, 1]
    motions = []
    for var in (0, 1, 2):                                  # translations u, v, w
        r = np.zeros((pm.mesh.n_nodes, 9)); r[:, var] = 1.0; motions.append(r)
    r = np.zeros((pm.mesh.n_nodes, 9)); r[:, 0], r[:, 1] = -y, x; motions.append(r)   # about z
    r = np.zeros((pm.mesh.n_nodes, 9)); r[:, 2], r[:, 4] = y, -h / 2; motions.append(r)  # w = y
    r = np.zeros((pm.mesh.n_nodes, 9)); r[:, 2], r[:, 3] = x, -h / 2; motions.append(r)  # w = x
    scale = abs(K).max()
    for r in motions:
        v = r.ravel()
        assert np.abs(K @ v).max() < 1e-9 * scale * np.abs(v).max()


def test_stiffness_symmetric_psd_and_mass_positive_definite():
    pm, c = single_layer_model(0.2, 0.3, 0.003, ElasticConstants(120e9, 9e9, 5e9, 4e9, 3e9, 0.3),
                               1600.0, 3, angle=np.deg2rad(30))
    K = pm.stiffness([c]).toarray()
    M = pm.M.toarray()
    assert np.abs(K - K.T).max() < 1e-12 * np.abs(K).max()
    assert np.abs(M - M.T).max() < 1e-12 * np.abs(M).max()
    wK = np.linalg.eigvalsh(K)
    assert wK.min() > -1e-9 * wK.max()
    assert np.linalg.eigvalsh(M).min() > 0
    # total mass: rigid translation in x
    ones = np.zeros((pm.mesh.n_nodes, 9)); ones[:, 0] = 1
    assert ones.ravel() @ M @ ones.ravel() == pytest.approx(1600.0 * 0.2 * 0.3 * 0.003, rel=1e-12)


# --- free isotropic plate: converged thin-plate values, no shear locking --------------------

@pytest.mark.parametrize("ratio", [200, 1000])
def test_free_square_isotropic_plate_matches_thin_plate_values(ratio):
    a, E, nu, rho = 1.0, 70e9, 0.3, 2700.0
    h = a / ratio
    pm, c = single_layer_model(a, a, h, isotropic(E, nu), rho, 12)
    modes = solve(pm, [c], 6)
    assert modes.n_rigid == 6
    D = E * h**3 / (12 * (1 - nu**2))
    lam = modes.omega * a**2 * np.sqrt(rho * h / D)
    assert np.all(np.abs(lam / FREE_SQUARE - 1) < 0.005), lam


def test_full_shear_integration_locks_where_selective_does_not():
    """Why the element integrates transverse shear with 2x2 points: 3x3 over-stiffens thin plates."""
    a, h, rho = 1.0, 1e-3, 2700.0
    c = isotropic()
    D = c.E1 * h**3 / (12 * (1 - 0.09))
    errs = {}
    for integ in ("selective", "full"):
        pm, _ = single_layer_model(a, a, h, c, rho, 6, integration=integ)
        lam = solve(pm, [c], 6).omega * a**2 * np.sqrt(rho * h / D)
        errs[integ] = np.abs(lam / FREE_SQUARE - 1).max()
    assert errs["selective"] < 0.01
    assert errs["full"] > 3 * errs["selective"]


# --- simply supported cross-ply: FE -> Navier solution of the same theory --------------------

CROSS = ElasticConstants(E1=40.0, E2=1.0, G12=0.6, G13=0.6, G23=0.5, nu12=0.25)


def scaled(c, E2=10e9):
    return ElasticConstants(c.E1 * E2, c.E2 * E2, c.G12 * E2, c.G13 * E2, c.G23 * E2, c.nu12)


@pytest.mark.parametrize("ratio", [5, 10, 100])
def test_simply_supported_cross_ply_converges_to_navier(ratio):
    a, rho = 1.0, 1500.0
    h = a / ratio
    c = scaled(CROSS)
    angles = [0, 90, 90, 0]
    pm, z = cross_ply_model(angles, a, h, c, rho, 16)
    fe = solve(pm, [c], 4).omega
    plies = [(c, ang, z[k], z[k + 1], rho) for k, ang in enumerate(angles)]
    ref = lowest_frequencies(plies, a, a, 4, kind="all").omega
    assert np.all(np.abs(fe / ref - 1) < 1e-3), (fe / ref - 1)


def test_navier_convergence_rate_of_quadratic_elements():
    """Eigenvalue error of 8-node elements falls like (element size)^4 (2p with p = 2)."""
    a, rho, h = 1.0, 1500.0, 0.1
    c = scaled(CROSS)
    angles = [0, 90, 90, 0]
    z = np.linspace(-h / 2, h / 2, 5)
    plies = [(c, ang, z[k], z[k + 1], rho) for k, ang in enumerate(angles)]
    ref = lowest_frequencies(plies, a, a, 3, kind="all").omega[2]     # mode with m or n = 2
    errors = []
    for n in (4, 8):
        pm, _ = cross_ply_model(angles, a, h, c, rho, n)
        errors.append(abs(solve(pm, [c], 3).eigenvalues[2] / ref**2 - 1))
    rate = np.log2(errors[0] / errors[1])
    assert 3.0 < rate < 5.5, (errors, rate)


def test_thin_simply_supported_isotropic_plate_matches_kirchhoff():
    a, h, E, nu, rho = 1.0, 0.002, 70e9, 0.3, 2700.0
    pm, c = single_layer_model(a, a, h, isotropic(E, nu), rho, 12, boundary="simply-supported")
    w = solve(pm, [c], 1).omega[0]
    D = E * h**3 / (12 * (1 - nu**2))
    assert w == pytest.approx(2 * np.pi**2 / a**2 * np.sqrt(D / (rho * h)), rel=5e-4)


def test_clamped_plate_is_stiffer_than_simply_supported_and_has_no_rigid_modes():
    c = isotropic()
    f = {}
    for bc in ("simply-supported", "clamped", "CFFF"):
        pm, _ = single_layer_model(1.0, 1.0, 0.01, c, 2700.0, 8, boundary=bc)
        modes = solve(pm, [c], 2)
        assert modes.n_rigid == 0
        f[bc] = modes.omega[0]
    # clamped square plate: omega a^2 sqrt(rho h / D) = 35.99 (Leissa); S-S: 2 pi^2 = 19.74
    D = c.E1 * 0.01**3 / (12 * 0.91)
    lam = {k: v * np.sqrt(2700.0 * 0.01 / D) for k, v in f.items()}
    assert lam["clamped"] == pytest.approx(35.99, rel=0.01)
    assert lam["simply-supported"] == pytest.approx(19.74, rel=0.01)
    assert lam["CFFF"] == pytest.approx(3.492, rel=0.01)      # cantilever square plate (Leissa)


def test_wrong_rigid_body_count_fails_loudly():
    """A free plate solved as if it were supported shows six unexpected zero modes."""
    pm, c = single_layer_model(0.2, 0.3, 0.003, isotropic(), 1600.0, 4)
    coef = pm.coefficients([c])
    with pytest.raises(SolverError, match="expected 0 rigid-body modes but found 6"):
        solve_modes(pm.stiffness(coef=coef), pm.M, 4, sigma=-0.5 * pm.shift_estimate(coef))


def test_rigid_motions_with_strain_energy_are_refused():
    pm, c = single_layer_model(0.2, 0.3, 0.003, isotropic(), 1600.0, 4)
    coef = pm.coefficients([c])
    R = pm.rigid_modes().copy()
    R[:, 5] += np.sin(np.arange(R.shape[0]))        # not a rigid motion
    with pytest.raises(SolverError, match="rigid-body motions have strain energy"):
        solve_modes(pm.stiffness(coef=coef), pm.M, 4, rigid=R,
                    sigma=-0.5 * pm.shift_estimate(coef))


def test_coarse_mesh_few_modes_keeps_all_six_rigid_modes():
    """Regression: plain Lanczos found only 5 of the 6-fold zero eigenvalue here."""
    pm, c = single_layer_model(0.2105, 0.311, 0.00306, isotropic(), 1600.0, 4)
    modes = solve(pm, [c], 2)
    assert modes.n_rigid == 6 and modes.eigenvalues[0] > 0


def test_indefinite_stiffness_is_reported():
    pm, c = single_layer_model(0.2, 0.3, 0.003, isotropic(), 1600.0, 3)
    coef = -pm.coefficients([c])
    with pytest.raises(SolverError, match="not positive definite"):
        solve_modes(pm.stiffness(coef=coef), pm.M, 4, sigma=-1e3)


def test_basis_energies_are_eigenvalue_derivatives():
    """d lambda_i / d coef[m, j] = phi_i^T K_j phi_i (paper Eq. 26), against central differences."""
    h = 0.004
    z = np.linspace(-h / 2, h / 2, 5)
    c1 = ElasticConstants(120e9, 9e9, 5e9, 4e9, 3e9, 0.3)
    c2 = ElasticConstants(45e9, 5e9, 3.5e9, 3.5e9, 3e9, 0.28)
    pm = build_plate_model(rectangular_mesh(0.2, 0.3, 4, 4), h, z, np.deg2rad([0, 45, -45, 90]),
                           np.array([0, 1, 1, 0]), np.array([1500.0, 1900, 1900, 1500]),
                           material_names=("carbon", "glass"))
    coef = pm.coefficients([c1, c2])
    sigma = -0.5 * pm.shift_estimate(coef)
    R = pm.rigid_modes()
    modes = solve_modes(pm.stiffness(coef=coef), pm.M, 5, sigma=sigma, rigid=R)
    E = pm.basis_energies(modes.phi)
    for m, j in [(0, 0), (0, 1), (1, 3), (1, 4), (0, 5)]:
        step = 1e-5 * np.abs(coef).max()
        cp, cm = coef.copy(), coef.copy()
        cp[m, j] += step
        cm[m, j] -= step
        lp = solve_modes(pm.stiffness(coef=cp), pm.M, 5, sigma=sigma, rigid=R).eigenvalues
        lm = solve_modes(pm.stiffness(coef=cm), pm.M, 5, sigma=sigma, rigid=R).eigenvalues
        fd = (lp - lm) / (2 * step)
        assert np.allclose(E[m, j], fd, rtol=1e-5, atol=1e-6 * np.abs(E).max()), (m, j)


@pytest.mark.parametrize("boundary", ["free", "SFCF"])
def test_element_level_basis_products_equal_the_assembled_matrices(boundary):
    """PlateModel.basis_products (element by element) against the assembled sparse basis
    matrices, 1e-12 relative: two materials, a distorted mesh (every element its own shape),
    fixed DOFs, and more columns than one pass."""
    import dataclasses

    h = 0.004
    z = np.linspace(-h / 2, h / 2, 5)
    mesh = rectangular_mesh(0.2, 0.3, 4, 3)
    nodes = mesh.nodes.copy()
    inner = ((nodes[:, 0] > 0) & (nodes[:, 0] < 0.2) & (nodes[:, 1] > 0) & (nodes[:, 1] < 0.3))
    nodes[inner] += np.random.default_rng(1).uniform(-0.004, 0.004, (int(inner.sum()), 2))
    mesh = dataclasses.replace(mesh, nodes=nodes)
    pm = build_plate_model(mesh, h, z, np.deg2rad([0, 45, -45, 90]), np.array([0, 1, 1, 0]),
                           np.array([1500.0, 1900, 1900, 1500]),
                           material_names=("carbon", "glass"), boundary=boundary)
    assert pm.Ke.shape[2] > 1                      # several element shapes
    W = np.random.default_rng(2).standard_normal((pm.n_dofs, 11))
    out = pm.basis_products(W, block=4)
    k = W.shape[1]
    for b in range(12):
        ref = pm.basis_matrix(b // 6, b % 6) @ W
        scale = np.abs(ref).max()
        assert np.abs(out[:, b * k:(b + 1) * k] - ref).max() <= 1e-12 * scale, b


@pytest.mark.parametrize("boundary", ["free", "clamped", "simply-supported"])
def test_kronecker_mass_products_equal_the_assembled_mass(boundary):
    """PlateModel.mass (M = P (S kron J) P^T) against the assembled CSR M: an unsymmetric
    two-material layup of different densities (J couples u with theta: first moments of
    inertia), on a free plate and with fixed DOFs (clamped, SSSS); single vectors and blocks
    of 1, 5 and 40 columns, to round-off. And the modes solved through it are those solved
    through M."""
    from laminid_cli.fe.assembly import KroneckerMass

    h = 0.004
    z = np.array([-h / 2, -h / 4, h / 2])
    pm = build_plate_model(rectangular_mesh(0.3, 0.2, 4, 3), h, z, np.deg2rad([0.0, 35.0]),
                           np.array([0, 1]), np.array([1550.0, 1950.0]),
                           material_names=("carbon", "glass"), boundary=boundary)
    assert isinstance(pm.mass, KroneckerMass) and pm.mass.shape == pm.M.shape
    assert (pm.mass.dofs is None) == (boundary == "free")
    J = pm.mass.J
    assert abs(J[0, 3]) > 1e-3 * J[0, 0]                  # unsymmetric: u-theta coupling
    rng = np.random.default_rng(5)
    for shape in ((pm.n_dofs,), (pm.n_dofs, 1), (pm.n_dofs, 5), (pm.n_dofs, 40)):
        W = rng.standard_normal(shape)
        ref = pm.M @ W
        got = pm.mass @ W
        assert got.shape == ref.shape
        assert np.abs(got - ref).max() <= 1e-14 * np.abs(ref).max()
    c = isotropic()
    coef = pm.coefficients([c, c])
    K = pm.stiffness(coef=coef)
    sigma = -0.5 * pm.shift_estimate(coef)
    a = solve_modes(K, pm.M, 8, rigid=pm.rigid_modes(), sigma=sigma, M_on_pattern=pm.M_on_K)
    b = solve_modes(K, pm.M, 8, rigid=pm.rigid_modes(), sigma=sigma, M_on_pattern=pm.M_on_K,
                    M_products=pm.mass)
    np.testing.assert_allclose(b.eigenvalues, a.eigenvalues, rtol=1e-11)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->j", a.phi, pm.M @ b.phi)), 1.0,
                               rtol=1e-9)


@pytest.mark.parametrize("kind", KINDS)
def test_factorisations_solve_and_give_energies_of_the_matrix_itself(kind):
    """Both factorisations (modal.make_factorizer) on a plate's K + 1e3 M: solves backward
    stable for 1, 5 and 40 right-hand sides; r^T A^-1 r against a dense solve; two factors
    alive at once stay those of their own matrices (CHOLMOD's analyses are pooled and reused
    only once a factor is gone); a plan that went through pickle (spawned worker processes)
    factorises again."""
    import pickle

    import scipy.sparse as sp

    from laminid_cli.modal import WORK, make_factorizer

    pm, c = single_layer_model(0.3, 0.2, 0.003, isotropic(), 2700.0, 3)
    coef = pm.coefficients([c])
    K = pm.stiffness(coef=coef)
    plan = make_factorizer(pm.indptr, pm.indices, block=9, kind=kind)
    assert plan.name == kind
    assert np.array_equal(K.indices, pm.indices)
    A1, A2 = (sp.csr_matrix((K.data + s * pm.M_on_K, pm.indices, pm.indptr), shape=K.shape)
              for s in (1e3, 1e5))
    before = WORK["factorizations"]
    f1 = plan.factor(A1.data)
    f2 = plan.factor(A2.data)
    assert WORK["factorizations"] == before + 2
    rng = np.random.default_rng(4)
    for n_rhs in (1, 5, 40):
        B = rng.standard_normal((pm.n_dofs, n_rhs))
        for A, f in ((A1, f1), (A2, f2)):
            X = f(B)
            scale = abs(A).sum(axis=1).max() * np.abs(X).max()
            assert np.abs(A @ X - B).max() <= 1e-13 * scale
    b = rng.standard_normal(pm.n_dofs)
    x = f1(b)
    assert x.shape == b.shape
    assert np.abs(A1 @ x - b).max() <= 1e-13 * abs(A1).sum(axis=1).max() * np.abs(x).max()
    R = rng.standard_normal((pm.n_dofs, 13))
    ref = np.einsum("ij,ij->j", R, np.linalg.solve(A2.toarray(), R))
    np.testing.assert_allclose(f2.energy(R), ref, rtol=1e-10)
    assert f2.energy(R[:, 0]) == pytest.approx(ref[0], rel=1e-10)
    del f1
    f3 = plan.factor(A1.data)                 # (CHOLMOD: on f1's analysis, back in the pool)
    np.testing.assert_allclose(f3(b), x, rtol=1e-12, atol=1e-14 * np.abs(x).max())
    again = pickle.loads(pickle.dumps(plan)).factor(A2.data)
    np.testing.assert_allclose(again.energy(R), ref, rtol=1e-10)


@pytest.mark.parametrize("kind", KINDS)
def test_factorisation_of_an_indefinite_matrix_says_what_to_try(kind):
    """A real indefinite K - sigma M (sigma above the first elastic eigenvalue) is refused by
    either factorisation with the same SolverError."""
    from laminid_cli.modal import make_factorizer

    pm, c = single_layer_model(0.3, 0.2, 0.003, isotropic(), 2700.0, 3)
    K = pm.stiffness(coef=pm.coefficients([c]))
    lam1 = solve_modes(K, pm.M, 1, rigid=pm.rigid_modes(), sigma=-1e3,
                       M_on_pattern=pm.M_on_K).eigenvalues[0]
    plan = make_factorizer(pm.indptr, pm.indices, block=9, kind=kind)
    with pytest.raises(SolverError, match="K - sigma M failed .*not positive definite"):
        plan.factor(K.data - 1.5 * lam1 * pm.M_on_K)


def test_factorisation_chosen_by_environment(monkeypatch):
    """LAMINID_FACTORIZER chooses the factorisation; an unknown value is a clear error (exit
    code 2 on the command line); without it, CHOLMOD where cvxopt is installed."""
    from laminid_cli.modal import FACTORIZER_ENV, default_factorizer

    monkeypatch.delenv(FACTORIZER_ENV, raising=False)
    assert default_factorizer() == ("cholmod" if HAVE_CHOLMOD else "banded")
    monkeypatch.setenv(FACTORIZER_ENV, " Banded ")
    assert default_factorizer() == "banded"
    monkeypatch.setenv(FACTORIZER_ENV, "superlu")
    with pytest.raises(ModelError, match="LAMINID_FACTORIZER='superlu' is not a "
                                         "factorisation laminid knows .*cholmod, banded"):
        default_factorizer()
    # on the command line: a setting error, exit code 2, no traceback
    from click.testing import CliRunner

    from laminid_cli.cli import cli

    r = CliRunner().invoke(cli, ["modes", "specimens/example1/S1.1.yaml", "--mesh", "4x4"])
    assert r.exit_code == 2
    assert "LAMINID_FACTORIZER='superlu' is not a factorisation laminid knows" in r.output
    assert "Traceback" not in r.output


@pytest.mark.parametrize("n_rhs", [1, 5, 40])
def test_banded_cholesky_solves_block_by_block_as_lapack(n_rhs):
    """The block-by-block triangular solves of BandedCholesky (many right-hand sides) against
    LAPACK's banded solve and against the matrix itself: a plate whose equations are not a
    multiple of the bandwidth (a partial last block)."""
    import scipy.linalg as sla

    from laminid_cli.modal import BLOCK_RHS, BandedCholesky, _BandBlocks

    pm, c = single_layer_model(0.3, 0.2, 0.003, isotropic(), 2700.0, 3)
    coef = pm.coefficients([c])
    A = (pm.stiffness(coef=coef) + 1e3 * pm.M).tocsr()
    A.sort_indices()
    chol = BandedCholesky.from_pattern(A.indptr, A.indices)
    assert chol.n % chol.bandwidth != 0
    solve = chol.factor(A.data)
    B = np.random.default_rng(3).standard_normal((pm.n_dofs, n_rhs))
    X = solve(B)
    # backward stable: residual of the order of round-off in ||A|| ||X||
    scale = abs(A).sum(axis=1).max() * np.abs(X).max()
    assert np.abs(A @ X - B).max() <= 1e-13 * scale
    # the block solver itself, against pbtrs on the same factor
    ab = np.zeros((chol.bandwidth + 1) * chol.n)
    ab[chol.band_index] = A.data[chol.upper_slots]
    cb = sla.cholesky_banded(ab.reshape(chol.bandwidth + 1, chol.n))
    Bp = B[chol.perm]
    ref = sla.cho_solve_banded((cb, False), Bp)
    np.testing.assert_allclose(_BandBlocks(cb).solve(Bp), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    # a factor this small stays in the cache: block by block from 2 x BLOCK_RHS columns (40 is)
    assert _BandBlocks(cb)._blocked(Bp) == (n_rhs >= 2 * BLOCK_RHS)
    assert 2 * BLOCK_RHS <= 40


# --- symmetric laminates: membrane and bending equations stored apart ----------------------

def _thick_hybrid(angles_deg, boundary="free", decouple=True):
    """A thick (a/h = 8) two-material plate, so that membrane modes are among the lowest."""
    h = 0.012
    z = np.linspace(-h / 2, h / 2, len(angles_deg) + 1)
    mat = np.array([0, 1, 0][:len(angles_deg)])
    pm = build_plate_model(rectangular_mesh(0.1, 0.08, 4, 4), h, z, np.deg2rad(angles_deg),
                           mat, np.where(mat == 0, 1500.0, 1900.0),
                           material_names=("carbon", "glass"), boundary=boundary,
                           decouple=decouple)
    c = [ElasticConstants(120e9, 9e9, 5e9, 4e9, 3e9, 0.3),
         ElasticConstants(45e9, 5e9, 3.5e9, 3.5e9, 3e9, 0.28)]
    return pm, pm.coefficients(c)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("boundary", ["free", "SFCF"])
def test_symmetric_laminate_is_stored_decoupled_with_the_same_modes(boundary, kind):
    """A symmetric two-material layup [30/-60/30] (carbon/glass/carbon): its element matrices
    couple membrane and bending variables only by round-off (<= 1e-15 relative), so the
    pattern leaves those entries out (fewer than 55 % of the coupled pattern's entries, none
    between the families); the lowest 30 modes, membrane modes among them (a/h = 8), equal
    those of the coupled assembly to 1e-10 relative, with either factorisation."""
    from laminid_cli.fe.assembly import BENDING_VARIABLES, membrane_bending_coupling
    from laminid_cli.modal import make_factorizer

    pm, coef = _thick_hybrid([30, -60, 30], boundary)
    ref, _ = _thick_hybrid([30, -60, 30], boundary, decouple=False)
    assert membrane_bending_coupling(pm.Ke, np.zeros((1, 72, 72))) <= 1e-15
    assert pm.decoupled and not ref.decoupled
    assert pm.indices.size < 0.55 * ref.indices.size
    bend = np.isin(pm.dofs % 9, BENDING_VARIABLES)
    rows = np.repeat(np.arange(pm.n_dofs), np.diff(pm.indptr))
    assert np.all(bend[rows] == bend[pm.indices])
    out = []
    for p in (pm, ref):
        plan = make_factorizer(p.indptr, p.indices, block=9 if boundary == "free" else 1,
                               kind=kind)
        out.append(solve_modes(p.stiffness(coef=coef), p.M, 30, rigid=p.rigid_modes(),
                               sigma=-0.5 * p.shift_estimate(coef), factorizer=plan,
                               M_on_pattern=p.M_on_K))
    assert np.abs(out[0].eigenvalues / out[1].eigenvalues - 1).max() < 1e-10
    membrane = np.linalg.norm(out[0].phi[~bend], axis=0) > 0.99
    assert 3 <= membrane.sum() <= 25                       # both families among the 30


def test_unsymmetric_laminate_keeps_its_coupling():
    """[30/-60] is unsymmetric: coupling of order one; the pattern is the coupled one."""
    from laminid_cli.fe.assembly import membrane_bending_coupling

    pm, _ = _thick_hybrid([30, -60])
    ref, _ = _thick_hybrid([30, -60], decouple=False)
    assert membrane_bending_coupling(pm.Ke, np.zeros((1, 72, 72))) > 1e-2
    assert not pm.decoupled
    assert np.array_equal(pm.indices, ref.indices) and np.array_equal(pm.indptr, ref.indptr)


def test_banded_plan_orders_independent_blocks_apart():
    """A decoupled pattern's banded plan takes the block-after-block order: a band narrower
    than the coupled pattern's (S1.1-like 12x12 free plate: 204 against 368), and the same
    solves as the coupled matrix."""
    from laminid_cli.modal import BandedCholesky

    h = 0.0021
    z = np.linspace(-h / 2, h / 2, 9)
    args = (rectangular_mesh(0.2105, 0.311, 12, 12), h, z, np.deg2rad([0, 90] * 2 + [90, 0] * 2),
            np.zeros(8, int), np.full(8, 1540.0))
    pm = build_plate_model(*args)
    ref = build_plate_model(*args, decouple=False)
    assert pm.decoupled
    a = BandedCholesky.from_pattern(pm.indptr, pm.indices, block=9)
    b = BandedCholesky.from_pattern(ref.indptr, ref.indices, block=9)
    assert a.bandwidth < 0.6 * b.bandwidth
    coef = pm.coefficients([ElasticConstants(140e9, 10e9, 5e9, 5e9, 3.5e9, 0.3)])
    A, B = (p.stiffness(coef=coef).data + 1e3 * p.M_on_K for p in (pm, ref))
    x = np.random.default_rng(3).standard_normal((pm.n_dofs, 3))
    ya, yb = a.factor(A)(x), b.factor(B)(x)
    assert np.abs(ya - yb).max() <= 1e-8 * np.abs(yb).max()


@pytest.mark.parametrize("boundary", ["free", "SFCF"])
def test_bending_and_membrane_models_of_a_symmetric_laminate(boundary):
    """PlateModel.restrict: the bending and the membrane equations of [30/-60/30] as models of
    their own. Their modes are the whole plate's modes of each family (eigenvalues to 1e-10,
    from a dense solve of the whole plate classified by the membrane share of each mode);
    their mass products are their CSR mass matrices' (1e-14); a free plate keeps three rigid
    motions in each. An unsymmetric layup does not split."""
    import scipy.linalg as sla

    from laminid_cli.fe.assembly import BENDING_VARIABLES

    pm, coef = _thick_hybrid([30, -60, 30], boundary)
    K, M = pm.stiffness(coef=coef).toarray(), pm.M.toarray()
    lam, phi = sla.eigh(K, M)
    n_rigid = 3 if boundary == "free" else 0
    lam, phi = lam[2 * n_rigid:], phi[:, 2 * n_rigid:]       # the six rigid modes mix
    bend = np.isin(pm.dofs % 9, BENDING_VARIABLES)
    share = np.linalg.norm(phi[~bend], axis=0) / np.linalg.norm(phi, axis=0)
    assert np.all((share < 1e-6) | (share > 1 - 1e-6))      # each mode in one family
    for family, members, eqs in (("bending", share < 0.5, bend), ("membrane", share > 0.5, ~bend)):
        part = pm.restrict(family)
        assert part.family == family and part.n_dofs == int(eqs.sum())
        R = part.rigid_modes()
        assert (0 if R is None else R.shape[1]) == n_rigid
        W = np.random.default_rng(4).standard_normal((part.n_dofs, 5))
        assert np.abs(part.mass @ W - part.M @ W).max() <= 1e-14 * np.abs(part.M @ W).max()
        modes = solve_modes(part.stiffness(coef=coef), part.M, 8, rigid=R,
                            sigma=-0.5 * pm.shift_estimate(coef), M_on_pattern=part.M_on_K,
                            M_products=part.mass)
        ref = lam[members][:8]
        assert np.abs(modes.eigenvalues / ref - 1).max() < 1e-10, family
    unsym, _ = _thick_hybrid([30, -60])
    with pytest.raises(ModelError, match="decoupled"):
        unsym.restrict("bending")


def test_most_modes_of_a_coarse_model_are_no_mechanism():
    """150 modes of S1.1 on a 3x3 mesh (360 equations): the highest is about 1e6 times the
    first eigenvalue; the mechanism check used to compare with it and called the first
    elastic modes zeros. The first ten are those of a 10-mode solve (1e-8)."""
    from laminid_cli.forward import build_forward_model
    from laminid_cli.specimen import read_specimen

    fm = build_forward_model(read_specimen("specimens/example1/S1.1.yaml"), (3, 3))
    many = fm.solve(n_modes=150)
    few = fm.solve(n_modes=10)
    assert many.eigenvalues[-1] / many.eigenvalues[0] > 1e5
    np.testing.assert_allclose(many.freq[:10], few.freq, rtol=1e-8)
