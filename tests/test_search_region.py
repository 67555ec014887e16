"""The search region of the constants parametrisation when it stands in for the alphas
(laminid_cli.parametrization.ConstantParameters, region 'alpha'): the profiles' refits hold
one constant of a material identified with the alphas and search the others in the alphas'
own region, not in the box [P0 / f, P0 f], which excludes every optimum with a shear modulus
at 1e-4 E1 (hybrid CM's glass: every refit started from the initial values)."""

import numpy as np
import pytest

from laminid_cli.identify import variables_of
from laminid_cli.material import CONSTANT_NAMES, ElasticConstants
from laminid_cli.parametrization import (MIN_MODULUS_RATIO, AlphaParameters,
                                         ConstantParameters, alpha_floor, make_parameters)

GLASS = ElasticConstants(E1=46e9, E2=13e9, G12=4.6e9, G13=4.6e9, G23=4.5e9, nu12=0.27)


def _feasible(p, c: ElasticConstants, tol=1e-12) -> bool:
    x = variables_of(p, c)
    lo, hi = p.bounds()
    A, b = p.linear_constraints()
    return bool(np.all(x >= lo - tol) and np.all(x <= hi + tol) and np.all(A @ x <= b + tol))


def _draws(n, seed=0):
    """Constants around GLASS over the alphas' limits and beyond them: E1 over 0.1-10 times
    its initial value, E2 and the shear moduli from 1e-5 to 1.2 (E2) / 0.9 (G) times E1,
    nu12 over -1..1, and the same at the alphas' limits E2 = E1, G = floor 1e-4 E1, |nu12| =
    0.95, E1 = E1_0 / 5 or 5 E1_0."""
    rng = np.random.default_rng(seed)
    out = []
    r = MIN_MODULUS_RATIO
    for _ in range(n):
        k = rng.integers(0, 8)                 # one constant on an alpha limit, or none
        E1 = GLASS.E1 * (rng.choice([0.2, 5.0]) if k == 6 else 10 ** rng.uniform(-1, 1))
        ratio = lambda top: 10 ** rng.uniform(-5, np.log10(top))   # noqa: E731
        c = dict(E1=E1, E2=E1 * ratio(1.2), G12=E1 * ratio(0.9), G13=E1 * ratio(0.9),
                 G23=E1 * ratio(0.9), nu12=rng.uniform(-1, 1))
        if k == 1:
            c["E2"] = E1
        elif k in (2, 3, 4):
            c[("G12", "G13", "G23")[k - 2]] = r * alpha_floor(ElasticConstants(**c)) * E1
        elif k == 5:
            c["nu12"] = 0.95 * rng.choice([-1, 1])
        out.append(ElasticConstants(**c))
    return out


def _nudged(c: ElasticConstants, k: str, f: float) -> ElasticConstants:
    return ElasticConstants(**{**c.as_dict(), k: getattr(c, k) * f})


@pytest.mark.parametrize("held", ["E2", "G12", "G13", "G23", "nu12", "E1"])
def test_the_alpha_region_with_one_constant_held_is_the_alphas(held):
    """For 1500 constants drawn across the alphas' limits (1 in 8 on one of them): with one
    constant held at its drawn value, and the shear moduli's floor of the drawn constants
    (the optimum profiled, alpha_floor), the constants parametrisation of the alpha region
    accepts the others exactly where the alphas (all six free) accept the six, and so does
    it 1e-6 inside and outside each shear modulus' floor; the box refuses every one on that
    floor."""
    on_limit = box_refuses = 0
    a = AlphaParameters("glass", GLASS)
    for c in _draws(1500, seed=CONSTANT_NAMES.index(held)):
        initial = ElasticConstants(**{**GLASS.as_dict(), held: getattr(c, held)})
        if (initial.E2 > initial.E1 or abs(initial.nu12) > 0.95
                or not GLASS.E1 / 5 <= initial.E1 <= 5 * GLASS.E1):
            # no profile holds a value there: E1 below the initial E2 (_profile_far), nu12
            # beyond nu_max, E1 beyond the search's factor
            continue
        pc = make_parameters("glass", initial, (held,), region="alpha", floor=alpha_floor(c))
        assert isinstance(pc, ConstantParameters) and pc.region == "alpha"
        assert _feasible(a, c) == _feasible(pc, c), c
        for g in ("G12", "G13", "G23"):
            if g == held or abs(getattr(c, g) / (c.E1 * alpha_floor(c)) / MIN_MODULUS_RATIO
                                - 1) > 1e-12:
                continue
            on_limit += 1
            for f in (1 - 1e-6, 1 + 1e-6):
                assert _feasible(a, _nudged(c, g, f)) == _feasible(pc, _nudged(c, g, f))
            box = make_parameters("glass", initial, (held,))
            box_refuses += not _feasible(box, c)
    assert on_limit > 50 and box_refuses == on_limit


def test_the_alpha_region_names_its_constraints_as_the_alphas_do():
    """Its linear constraints carry the alphas' words (the warning of an optimum on a limit):
    E2 = E1 and each modulus 'at its minimum (0.0001 E1)'; a held E1 makes those bounds."""
    p = make_parameters("glass", GLASS, ("nu12",), region="alpha", floor=1.0)
    assert p.constraint_labels() == ("E2 = E1", "E2 at its minimum (0.0001 E1)",
                                     "G12 at its minimum (0.0001 E1)",
                                     "G13 at its minimum (0.0001 E1)",
                                     "G23 at its minimum (0.0001 E1)")
    A, b = p.linear_constraints()
    assert A.shape == (5, 5) and np.all(b == 0)
    # G12 exactly 1e-4 E1 (floor 1) is on its row (zero slack), E2 = E1 on its own
    c = ElasticConstants(E1=40e9, E2=40e9, G12=4e6, G13=1e9, G23=1e9, nu12=0.27)
    slack = A @ variables_of(p, c) - b
    assert slack[0] == pytest.approx(0, abs=1e-12) and slack[2] == pytest.approx(0, abs=1e-12)
    # the alphas' floor of that ply: 1 / (1 - 0.27^2 * 1)
    assert alpha_floor(c) == pytest.approx(1 / (1 - 0.27 ** 2), rel=1e-15)
    q = make_parameters("glass", GLASS, ("E1",), region="alpha")
    assert q.constraint_labels() == () and q.linear_constraints()[0].shape == (0, 5)
    lo, hi = q.bounds()
    i = q.free.index("G13")
    assert lo[i] * GLASS.G13 == pytest.approx(MIN_MODULUS_RATIO * GLASS.E1, rel=1e-12)
    assert hi[q.free.index("E2")] * GLASS.E2 == pytest.approx(GLASS.E1, rel=1e-12)
    with pytest.raises(Exception, match="search region 'disc' unknown"):
        make_parameters("glass", GLASS, ("E1",), region="disc")
