"""Design variables of one material and their maps to the stiffness coefficients.

The plate stiffness depends on a material only through the six coefficients
``coef = s [1, a2, a3, a4, a8, a9]`` with ``s = E1 / (8 alpha0)`` (laminid_cli.fe.assembly). In
engineering constants they are (from Eq. 4)::

    t = s E2 / E1,   s = E1^2 / (8 (E1 - nu12^2 E2))
    coef = [s, 4 s - 4 t, s + (1 - 2 nu12) t - G12/2, s + (1 + 6 nu12) t - G12/2,
            (G13 + G23)/2, (G13 - G23)/2]

Two parametrisations, both with analytic Jacobians ``d coef / d x``:

- :class:`AlphaParameters` — the paper's Eq. 14: ``x = [E1/E1_0, a2, a3, a4, a8, a9]``, all six
  constants free (the default, as in the paper);
- :class:`ConstantParameters` — the free engineering constants, moduli divided by their initial
  values and nu12 as is; used when some constants are fixed or a prior (Eq. 15) is given.

Feasibility (paper Eqs 21/22) is imposed as *linear* inequalities ``A x <= b`` plus bounds,
chosen strictly inside the positive-definite region: moduli above a small fraction of E1,
E2 <= E1, and |nu12| <= nu_max < 1 <= sqrt(E1/E2). The feasible set is then a polytope, so an
optimiser that keeps linear constraints (SLSQP's line search between feasible points, MMA's
conservative steps) never produces a point where the constitutive matrix is not positive
definite.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laminid_cli.errors import FitInputError
from laminid_cli.material import (CONSTANT_NAMES, ElasticConstants, alphas_from_constants,
                                  constants_from_alphas)


class InitialValueError(FitInputError):
    """An initial constant of a material the search cannot start from: ``material``,
    ``constant`` (one of CONSTANT_NAMES) and ``words`` (what is wrong, without where) let the
    caller name the specimen file and the constant's line."""

    def __init__(self, material: str, constant: str, words: str):
        super().__init__(f"material '{material}', field '{constant}': {words}")
        self.material, self.constant, self.words = material, constant, words


#: smallest modulus allowed, as a fraction of E1 (keeps Q safely positive definite)
MIN_MODULUS_RATIO = 1e-4


def coefficients_and_jacobian(c: ElasticConstants) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness coefficients (6,) Pa and their derivatives w.r.t. the constants (6, 6).

    Columns of the Jacobian follow :data:`~laminid_cli.material.CONSTANT_NAMES`
    (E1, E2, G12, G13, G23, nu12); moduli derivatives are dimensionless, nu12's in Pa.
    """
    E1, E2, G12, G13, G23, nu = c.E1, c.E2, c.G12, c.G13, c.G23, c.nu12
    D = E1 - nu**2 * E2
    s = E1**2 / (8 * D)
    t = E1 * E2 / (8 * D)
    ds = np.array([E1 * (E1 - 2 * nu**2 * E2), E1**2 * nu**2, 0, 0, 0, 2 * E1**2 * nu * E2]) / (8 * D**2)
    dt = np.array([-nu**2 * E2**2, E1**2, 0, 0, 0, 2 * E1 * E2**2 * nu]) / (8 * D**2)
    coef = np.array([s, 4 * s - 4 * t, s + (1 - 2 * nu) * t - G12 / 2,
                     s + (1 + 6 * nu) * t - G12 / 2, (G13 + G23) / 2, (G13 - G23) / 2])
    J = np.zeros((6, 6))
    J[0] = ds
    J[1] = 4 * ds - 4 * dt
    J[2] = ds + (1 - 2 * nu) * dt
    J[2, 5] += -2 * t
    J[2, 2] += -0.5
    J[3] = ds + (1 + 6 * nu) * dt
    J[3, 5] += 6 * t
    J[3, 2] += -0.5
    J[4, 3], J[4, 4] = 0.5, 0.5
    J[5, 3], J[5, 4] = 0.5, -0.5
    return coef, J


@dataclass(frozen=True)
class AlphaParameters:
    """Paper Eq. 14: x = [E1/E1_0, a2, a3, a4, a8, a9] for one material, all constants free."""

    name: str
    initial: ElasticConstants
    nu_max: float = 0.95
    bound_factor: float = 5.0

    kind = "alpha"

    @property
    def free(self) -> tuple[str, ...]:
        return CONSTANT_NAMES

    @property
    def labels(self) -> tuple[str, ...]:
        return ("E1/E1_0", "alpha2", "alpha3", "alpha4", "alpha8", "alpha9")

    def x0(self) -> np.ndarray:
        a = alphas_from_constants(self.initial)
        return np.array([1.0, a[1], a[2], a[3], a[4], a[5]])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        f = self.bound_factor
        r = MIN_MODULUS_RATIO
        lo = np.array([1 / f, 0.0, -20.0, -20.0, 8 * r, -8.0])
        hi = np.array([f, 4.0 * (1 - r), 20.0, 20.0, 8.0, 8.0])
        return lo, hi

    def constraint_labels(self) -> tuple[str, ...]:
        """What each row of :meth:`linear_constraints` holds, for messages."""
        low = f"at its minimum ({MIN_MODULUS_RATIO:g} E1)"
        return (f"G12 {low}", f"G23 {low}", f"G13 {low}", f"nu12 = +{self.nu_max}",
                f"nu12 = -{self.nu_max}")

    def linear_constraints(self) -> tuple[np.ndarray, np.ndarray]:
        """A x <= b: G12, G13, G23 >= r E1 and |nu12| <= nu_max (Eqs 21/22, sufficient form)."""
        r, n = MIN_MODULUS_RATIO, self.nu_max
        A = np.array([
            [0, 1, 3, 1, 0, 0],          # 8 - a2 - 3 a3 - a4 >= 16 r   (G12/E1 >= r)
            [0, 0, 0, 0, -1, 1],         # a8 - a9 >= 8 r               (G23/E1 >= r)
            [0, 0, 0, 0, -1, -1],        # a8 + a9 >= 8 r               (G13/E1 >= r)
            [0, 2 * n, -1, 1, 0, 0],     # a4 - a3 <= 2 nu_max (4 - a2)
            [0, 2 * n, 1, -1, 0, 0],     # a3 - a4 <= 2 nu_max (4 - a2)
        ], dtype=float)
        b = np.array([8 - 16 * r, -8 * r, -8 * r, 8 * n, 8 * n])
        return A, b

    def constants(self, x) -> ElasticConstants:
        c = constants_from_alphas(x[0] * self.initial.E1, *x[1:])
        return ElasticConstants.from_array(c.as_array())

    def coef_jacobian(self, x) -> tuple[np.ndarray, np.ndarray]:
        """coef (6,) and d coef / d x (6, 6)."""
        a1, a2, a3, a4, a8, a9 = x
        d = a4 - a3
        a0 = 1 - d**2 / (16 * (4 - a2))
        da0 = np.array([0, -d**2 / (16 * (4 - a2) ** 2), 2 * d / (16 * (4 - a2)),
                        -2 * d / (16 * (4 - a2)), 0, 0])
        s = a1 * self.initial.E1 / (8 * a0)
        ds = -s / a0 * da0
        ds[0] = self.initial.E1 / (8 * a0)
        vec = np.array([1.0, a2, a3, a4, a8, a9])
        J = np.outer(vec, ds)
        J[1:, 1:] += s * np.eye(5)
        return s * vec, J


#: the moduli other than E1 in a ConstantParameters of the alpha region: each at least
#: MIN_MODULUS_RATIO E1 (the linear constraints of AlphaParameters, exactly)
RATIO_MODULI = ("E2", "G12", "G13", "G23")

#: in the alpha region, E2 and the shear moduli at most this many times the largest E1 of the
#: search (the alphas' own upper limits, a2 >= 0, a3 >= -20, a8 <= 8, |a9| <= 8, allow E2 up
#: to E1, G13 + G23 up to 16 s >= 2 E1 and G12 up to ~5 E1, and no fibre ply comes near them)
ALPHA_REGION_UPPER = 2.0


@dataclass(frozen=True)
class ConstantParameters:
    """The free engineering constants of one material: moduli / initial value, nu12 as is.

    ``region``: the search's limits. 'box' (what a run with fixed constants or a prior
    searches): each modulus within [P0 / f, P0 f], nu12 within +-nu_max, E2 <= E1. 'alpha':
    the region of :class:`AlphaParameters`, for the refits of a material identified with the
    alphas whose constants are held one at a time (the profiles of
    laminid_cli.uncertainty.refit_held, which compare their fits with that identification's:
    the box would exclude its optimum wherever a shear modulus stopped at 1e-4 E1, and they
    would search a different region from the initial values): E1 within [E1_0 / f, E1_0 f],
    E2 at least MIN_MODULUS_RATIO E1 and G12, G13, G23 at least ``floor`` times that (linear
    constraints, or bounds where E1 or the modulus is held), E2 <= E1, |nu12| <= nu_max, and
    E2 and the shear moduli at most ALPHA_REGION_UPPER times the largest E1. The alphas' own
    floor of a shear modulus is ``G >= 8 r s`` (r = MIN_MODULUS_RATIO, s = E1^2 / (8 (E1 -
    nu12^2 E2))), ``r E1 / (1 - nu12^2 E2 / E1)``: not linear in the constants; with
    ``floor = 1 / (1 - nu12^2 E2 / E1)`` at the optimum profiled it is the alphas' floor
    there exactly (and within ~1e-3 relative near it: nu12^2 E2 / E1 is ~0.02 for a fibre
    ply), so a refit with the optimum's own value held ends at the optimum. E2's floor (a2
    <= 4 (1 - r)) and nu12's limits (a4 - a3 <= 2 nu_max (4 - a2)) are the alphas' exactly."""

    name: str
    initial: ElasticConstants
    free: tuple[str, ...] = CONSTANT_NAMES
    nu_max: float = 0.95
    bound_factor: float = 5.0
    region: str = "box"
    floor: float = 1.0

    kind = "constants"

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(f"{k}/{k}_0" if k != "nu12" else "nu12" for k in self.free)

    def _index(self) -> np.ndarray:
        return np.array([CONSTANT_NAMES.index(k) for k in self.free], dtype=int)

    def _scale(self) -> np.ndarray:
        P0 = self.initial.as_array()
        return np.where(np.array(CONSTANT_NAMES) == "nu12", 1.0, P0)

    def x0(self) -> np.ndarray:
        return self.initial.as_array()[self._index()] / self._scale()[self._index()]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.region == "alpha":
            return self._alpha_bounds()
        f = self.bound_factor
        lo = np.array([-self.nu_max if k == "nu12" else 1 / f for k in self.free])
        hi = np.array([self.nu_max if k == "nu12" else f for k in self.free])
        # a fixed E1 or E2 bounds the other through E2 <= E1
        P0 = self.initial.as_array()
        if "E2" in self.free and "E1" not in self.free:
            i = self.free.index("E2")
            hi[i] = min(hi[i], P0[0] / P0[1])
        if "E1" in self.free and "E2" not in self.free:
            i = self.free.index("E1")
            lo[i] = max(lo[i], P0[1] / P0[0])
        # shear moduli above MIN_MODULUS_RATIO * E1 at the largest E1 allowed
        return lo, hi

    def _alpha_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The bounds of the alpha region (class docstring)."""
        f = self.bound_factor
        P0 = self.initial.as_array()
        e1_lo, e1_hi = (P0[0] / f, P0[0] * f) if "E1" in self.free else (P0[0], P0[0])
        lo, hi = [], []
        for k in self.free:
            i = CONSTANT_NAMES.index(k)
            if k == "nu12":
                lo.append(-self.nu_max)
                hi.append(self.nu_max)
            elif k == "E1":
                # a held modulus M >= r E1 and E2 <= E1 bound E1 (held E1 bounds them instead)
                a, b = 1 / f, f
                for m in RATIO_MODULI:
                    if m not in self.free:
                        b = min(b, P0[CONSTANT_NAMES.index(m)] / (self._ratio(m) * P0[0]))
                if "E2" not in self.free:
                    a = max(a, P0[1] / P0[0])
                lo.append(a)
                hi.append(b)
            else:
                top = e1_hi if k == "E2" else ALPHA_REGION_UPPER * e1_hi
                lo.append(self._ratio(k) * e1_lo / P0[i])
                hi.append(top / P0[i])
        return np.array(lo, float), np.array(hi, float)

    def _ratio(self, k: str) -> float:
        """The alpha region's floor of modulus ``k`` over E1."""
        return MIN_MODULUS_RATIO * (1.0 if k == "E2" else self.floor)

    def _alpha_rows(self) -> list[str]:
        """The moduli whose ``M >= r E1`` is a linear constraint in the alpha region (E1 and M
        free both)."""
        if self.region != "alpha" or "E1" not in self.free:
            return []
        return [m for m in RATIO_MODULI if m in self.free]

    def constraint_labels(self) -> tuple[str, ...]:
        both = ("E2 = E1",) if "E1" in self.free and "E2" in self.free else ()
        return both + tuple(f"{m} at its minimum ({MIN_MODULUS_RATIO:g} E1)"
                            for m in self._alpha_rows())

    def linear_constraints(self) -> tuple[np.ndarray, np.ndarray]:
        """E2 <= E1 when both are free (Eq. 22, g2); in the alpha region also ``M >= r E1``
        for each free modulus M of :data:`RATIO_MODULI` with E1 free."""
        A, b = self._e2_rows()
        rows = self._alpha_rows()
        if not rows:
            return A, b
        P0 = self.initial.as_array()
        extra = np.zeros((len(rows), len(self.free)))
        for j, m in enumerate(rows):
            # ratio E1_0 x_E1 - M_0 x_M <= 0, over E1_0
            extra[j, self.free.index("E1")] = self._ratio(m)
            extra[j, self.free.index(m)] = -P0[CONSTANT_NAMES.index(m)] / P0[0]
        return np.vstack([A, extra]), np.concatenate([b, np.zeros(len(rows))])

    def _e2_rows(self) -> tuple[np.ndarray, np.ndarray]:
        if "E1" in self.free and "E2" in self.free:
            P0 = self.initial.as_array()
            row = np.zeros(len(self.free))
            row[self.free.index("E1")] = -P0[0]
            row[self.free.index("E2")] = P0[1]
            return row[None, :] / P0[0], np.zeros(1)
        return np.zeros((0, len(self.free))), np.zeros(0)

    def constants(self, x) -> ElasticConstants:
        P = self.initial.as_array()
        idx = self._index()
        P[idx] = np.asarray(x) * self._scale()[idx]
        return ElasticConstants.from_array(P)

    def coef_jacobian(self, x) -> tuple[np.ndarray, np.ndarray]:
        coef, J = coefficients_and_jacobian(self.constants(x))
        idx = self._index()
        return coef, J[:, idx] * self._scale()[idx]


def make_parameters(name: str, initial: ElasticConstants, fixed=(), *, kind: str = "auto",
                    prior: bool = False, nu_max: float = 0.95, bound_factor: float = 5.0,
                    region: str = "box", floor: float = 1.0):
    """Choose the parametrisation of one material.

    ``kind``: 'alpha' (paper Eq. 14; needs all six constants free and no prior), 'constants',
    or 'auto' (alpha when possible). ``region``: the search region of the constants
    parametrisation when it is chosen (:class:`ConstantParameters`: 'box' or 'alpha', with
    ``floor``).
    """
    fixed = tuple(fixed)
    unknown = [k for k in fixed if k not in CONSTANT_NAMES]
    if unknown:
        raise FitInputError(f"material '{name}': cannot fix {', '.join(unknown)}: constants are "
                       f"{', '.join(CONSTANT_NAMES)}")
    free = tuple(k for k in CONSTANT_NAMES if k not in fixed)
    if kind not in ("auto", "alpha", "constants"):
        raise FitInputError(f"parametrisation '{kind}' unknown (auto, alpha, constants)")
    if kind == "alpha" and (fixed or prior):
        raise FitInputError(f"material '{name}': the alpha design variables (paper Eq. 14) need all "
                       "six constants free and no prior; use --parametrization constants")
    if not 0 < nu_max < 1:
        raise FitInputError(f"nu_max must be in (0, 1) (got {nu_max})")
    if abs(initial.nu12) > nu_max:
        raise InitialValueError(name, "nu12", f"the initial nu12 = {initial.nu12:g} is outside "
                                f"the identification's range |nu12| <= {nu_max:g} (fibre plies "
                                "have about 0.2 to 0.4)")
    if initial.E2 > initial.E1:
        raise FitInputError(f"material '{name}': initial E2 > E1; direction 1 must be the fibre "
                       "(stiffer) direction")
    if region not in ("box", "alpha"):
        raise FitInputError(f"search region '{region}' unknown (box, alpha)")
    if not free:
        return ConstantParameters(name, initial, (), nu_max, bound_factor, region, floor)
    if kind == "alpha" or (kind == "auto" and not fixed and not prior):
        _check_alpha_floor(name, initial)
        _check_alpha_ceiling(name, initial)
        return AlphaParameters(name, initial, nu_max, bound_factor)
    return ConstantParameters(name, initial, free, nu_max, bound_factor, region, floor)


def _check_alpha_floor(name: str, initial: ElasticConstants) -> None:
    """Refuse initial constants below the alphas' floor (E2 >= r E1, a shear modulus >= r E1
    / (1 - nu12^2 E2 / E1), r = MIN_MODULUS_RATIO), naming the modulus: a start there is
    outside the search (a shear modulus written in MPa among GPa was refused as "outside the
    feasible region of Eq. 22 (E2 <= E1, |nu12| < 0.95, positive moduli)", none of which it
    is)."""
    r = MIN_MODULUS_RATIO
    for k in RATIO_MODULI:
        value = getattr(initial, k)
        limit = r * initial.E1 * (1.0 if k == "E2" else alpha_floor(initial))
        if value < limit * (1 - 1e-9):
            raise InitialValueError(
                name, k, f"the initial {k} = {value / 1e9:.4g} GPa is below the "
                f"identification's limit {r:g} E1 = {limit / 1e9:.4g} GPa (E1 = "
                f"{initial.E1 / 1e9:.4g} GPa): a unit slip (MPa for GPa?), or a material "
                f"whose {k} is not that small beside E1; the search starts at the file's values")


def _check_alpha_ceiling(name: str, initial: ElasticConstants) -> None:
    """Refuse initial shear moduli above the alphas' limits (:meth:`AlphaParameters.bounds`,
    in terms of the constants with ``s = E1 f / 8``, f = :func:`alpha_floor`: alpha8 <= hi8
    and |alpha9| <= hi9 are G13 + G23 <= 2 s hi8 and |G13 - G23| <= 2 s hi9; alpha3 >= lo3
    and alpha4 >= lo4 are G12 <= 2 s (1 - lo3 + (1 - 2 nu12) E2/E1) and 2 s (1 - lo4 + (1 +
    6 nu12) E2/E1)), naming the modulus and E1: E1 and E2 written in MPa among shear moduli
    in GPa were refused as "outside the feasible region of Eq. 22 (E2 <= E1, |nu12| < 0.95,
    positive moduli, ...)", none of which they are."""
    lo, hi = AlphaParameters(name, initial).bounds()
    E1, nu, ratio = initial.E1, initial.nu12, initial.E2 / initial.E1
    s = E1 * alpha_floor(initial) / 8
    checks = [("G13", initial.G13 + initial.G23, 2 * s * hi[4],
               f"G13 + G23 = {(initial.G13 + initial.G23) / 1e9:.4g} GPa"),
              ("G13" if initial.G13 >= initial.G23 else "G23",
               abs(initial.G13 - initial.G23), 2 * s * hi[5],
               f"|G13 - G23| = {abs(initial.G13 - initial.G23) / 1e9:.4g} GPa"),
              ("G12", initial.G12,
               2 * s * min(1 - lo[2] + (1 - 2 * nu) * ratio, 1 - lo[3] + (1 + 6 * nu) * ratio),
               f"G12 = {initial.G12 / 1e9:.4g} GPa")]
    for k, value, limit, said in checks:
        if value > limit * (1 + 1e-9):
            raise InitialValueError(
                name, k, f"the initial {said} is above the identification's limit "
                f"{limit / E1:.3g} E1 = {limit / 1e9:.4g} GPa (E1 = {E1 / 1e9:.4g} GPa): a "
                f"unit slip in E1 or {k} (E1 in MPa where GPa is meant?); the search starts "
                "at the file's values")


def alpha_floor(c: ElasticConstants) -> float:
    """``1 / (1 - nu12^2 E2 / E1)`` of ``c``: where the alphas' floor of a shear modulus, ``G
    >= 8 r s``, is ``floor * r * E1`` (:class:`ConstantParameters`, region 'alpha')."""
    return float(c.E1 / (c.E1 - c.nu12 ** 2 * c.E2))
