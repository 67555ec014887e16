"""Forward problem: specimen -> finite-element plate model -> natural frequencies.

``build_forward_model`` assembles the parametric model once (mesh, layup, densities); its
``solve`` evaluates the modes for any set of material constants (one stiffness combination, one
Cholesky factorisation, one Lanczos run). The identification reuses the same object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from laminid_cli.errors import ModelError, SolverError
from laminid_cli.fe.assembly import PlateModel, boundary_label, build_plate_model
from laminid_cli.fe.mesh import check_element_shape, rectangular_mesh
from laminid_cli.laminate import Laminate, laminate_from_specimen
from laminid_cli.material import ElasticConstants, infeasibility_reasons
from laminid_cli.modal import BandedCholesky, Modes, SparseCholesky, make_factorizer, solve_modes
from laminid_cli.specimen import Specimen

DEFAULT_MESH = (12, 12)


@dataclass(frozen=True)
class ForwardModel:
    """A specimen's assembled plate model, ready to be solved for any constants."""

    specimen: Specimen
    laminate: Laminate
    plate: PlateModel
    factorizer: SparseCholesky | BandedCholesky
    mesh_size: tuple[int, int]
    rigid: np.ndarray | None
    #: for a model of a symmetric laminate's bending equations alone (:func:`bending_model`):
    #: the model of the whole plate it comes from
    whole: "ForwardModel | None" = None

    @property
    def material_names(self) -> tuple[str, ...]:
        return self.laminate.material_names

    @property
    def initial_constants(self) -> tuple[ElasticConstants, ...]:
        return self.laminate.constants

    def solve(self, constants=None, n_modes: int = 12, *, coef: np.ndarray | None = None,
              v0: np.ndarray | None = None, lambda1: float | None = None) -> Modes:
        """Lowest ``n_modes`` elastic modes for the given constants (default: the file's).

        ``constants`` is a sequence of ElasticConstants in ``material_names`` order; ``coef``
        (n_materials, 6) the stiffness coefficients directly; ``v0`` a Lanczos start vector
        (e.g. the sum of the previous step's modes). The shift is minus half ``lambda1`` (the
        caller's estimate of the first eigenvalue, e.g. its previous solution's) when given,
        else minus half a thin-plate estimate. The model keeps no state: the same call gives
        the same answer whatever was solved before.
        """
        if coef is None:
            constants = self.initial_constants if constants is None else tuple(constants)
            for name, c in zip(self.material_names, constants):
                reasons = infeasibility_reasons(c)
                if reasons:
                    raise ModelError(f"material '{name}': infeasible constants: "
                                     + "; ".join(reasons))
            coef = self.plate.coefficients(constants)
        K = self.plate.stiffness(coef=coef)
        lam_est = lambda1 if lambda1 is not None else self.plate.shift_estimate(coef)
        return solve_modes(K, self.plate.M, n_modes, rigid=self.rigid, sigma=-0.5 * lam_est,
                           factorizer=self.factorizer, v0=v0, M_on_pattern=self.plate.M_on_K,
                           M_products=self.plate.mass)


def build_forward_model(specimen: Specimen, mesh: tuple[int, int] = DEFAULT_MESH,
                        boundary: str | None = None,
                        integration: str = "selective",
                        factorizer: str | None = None) -> ForwardModel:
    """Assemble the plate model of a specimen.

    Parameters
    ----------
    mesh : elements along x (side a) and y (side b)
    boundary : overrides the specimen's boundary condition when given
    factorizer : 'cholmod' or 'banded' (default: ``modal.default_factorizer()``)
    """
    lam = laminate_from_specimen(specimen)
    nx, ny = mesh
    check_element_shape(specimen.a, specimen.b, nx, ny)
    plate = build_plate_model(
        rectangular_mesh(specimen.a, specimen.b, nx, ny), lam.h, lam.z, lam.angle,
        lam.material_index, lam.density, material_names=lam.material_names,
        boundary=specimen.boundary if boundary is None else boundary,
        integration=integration)
    plan = make_factorizer(plate.indptr, plate.indices,
                           block=9 if plate.boundary == "FFFF" else 1, kind=factorizer)
    return ForwardModel(specimen=specimen, laminate=lam, plate=plate, factorizer=plan,
                        mesh_size=(int(nx), int(ny)), rigid=plate.rigid_modes())


#: the identification's model of a symmetric laminate leaves out the membrane equations
#: (:func:`bending_model`) when its lowest membrane mode lies at least this factor above the
#: highest measured frequency, at the file's constants (the paper's plates: 1.7 - 5.3; the
#: hybrids 1.7)
MEMBRANE_MARGIN = 1.5


def _family_model(fm: ForwardModel, family: str) -> ForwardModel:
    """The forward model of one family of equations of a decoupled plate, made once."""
    cache = fm.__dict__.setdefault("_families", {})
    if family not in cache:
        plate = fm.plate.restrict(family)
        per_node = len(plate.mass.variables)
        plan = make_factorizer(plate.indptr, plate.indices,
                               block=per_node if plate.boundary == "FFFF" else 1,
                               kind=fm.factorizer.name)
        cache[family] = ForwardModel(specimen=fm.specimen, laminate=fm.laminate, plate=plate,
                                     factorizer=plan, mesh_size=fm.mesh_size,
                                     rigid=plate.rigid_modes(), whole=fm)
    return cache[family]


def membrane_floor_hz(fm: ForwardModel, constants=None) -> float:
    """Lowest elastic membrane frequency (Hz) of a decoupled plate (a symmetric laminate) at the
    given constants (default: the file's): one shift-inverted Lanczos run on its membrane
    equations (S1.1 12x12: 1924 equations, ~10 ms). ``fm``: the whole plate's model or its
    :func:`bending_model`."""
    whole = fm.whole if fm.whole is not None else fm
    mem = _family_model(whole, "membrane")
    coef = mem.plate.coefficients(whole.initial_constants if constants is None
                                  else tuple(constants))
    K = mem.plate.stiffness(coef=coef)
    # the shift: below the membrane modes, of the size of the bending ones (any negative
    # shift is valid; this one is near the answer)
    sigma = -0.5 * mem.plate.shift_estimate(coef)
    modes = solve_modes(K, mem.plate.M, 1, rigid=mem.rigid, sigma=sigma,
                        factorizer=mem.factorizer, M_on_pattern=mem.plate.M_on_K,
                        M_products=mem.plate.mass)
    floor = float(modes.freq[0])
    mem.__dict__["_floor"] = (np.asarray(coef, float), floor)   # for membrane_floor_bound_hz
    return floor


def membrane_floor_bound_hz(fm: ForwardModel, constants) -> float:
    """A lower bound of :func:`membrane_floor_hz` at ``constants`` from the floor last computed
    on this plate (at other constants), with no solve; 0 where none was computed.

    The stiffness is linear in the constitutive matrices, so ``Q(c) >= mu Q(c_ref)`` for
    every material (mu: reduced.stiffness_ratio, 5x5 per material) gives ``K(c) >= mu
    K(c_ref)``; M and the rigid modes (K's null space) do not depend on the constants, so by
    Courant-Fischer on the elastic modes ``lambda_1(c) >= mu lambda_1(c_ref)``: the floor is
    at least ``sqrt(mu) f_ref``. The pipeline's check at the answer (its floor above the
    model's highest mode) needs no Lanczos run where this bound already decides it (S1.1 12x12:
    14 ms of an identify command's 0.6 s)."""
    from laminid_cli.reduced import stiffness_ratio

    whole = fm.whole if fm.whole is not None else fm
    mem = _family_model(whole, "membrane")
    kept = mem.__dict__.get("_floor")
    if kept is None:
        return 0.0
    coef_ref, floor_ref = kept
    mu = stiffness_ratio(np.asarray(mem.plate.coefficients(tuple(constants)), float), coef_ref)
    return float(np.sqrt(mu) * floor_ref) if mu > 0 else 0.0


def bending_model(fm: ForwardModel, f_max_hz: float | None = None) -> ForwardModel:
    """The model of ``fm``'s bending equations alone, where that gives the same modes, else
    ``fm`` itself.

    A symmetric laminate's membrane and bending equations are independent
    (``PlateModel.decoupled``): its modes are bending modes (no membrane component) or
    membrane modes. The bending equations alone (S1.1 12x12: 2405 of 4329) give the same
    bending modes to round-off (1.5e-11), so an identification on them is the same as on the
    whole plate while no membrane mode is among the model's modes. That holds here when the
    lowest membrane mode, at the file's constants, is at least MEMBRANE_MARGIN times
    ``f_max_hz`` (default: the highest measured frequency); the caller checks it again at the
    answer (:func:`membrane_floor_hz`) and otherwise identifies on the whole plate."""
    if not fm.plate.decoupled or fm.whole is not None:
        return fm
    if f_max_hz is None:
        meas = fm.specimen.measured
        f = np.asarray(meas.freq, float) if meas is not None else np.zeros(0)
        f = f[np.isfinite(f)]
        if not f.size:
            return fm
        f_max_hz = float(f.max())
    try:
        floor = membrane_floor_hz(fm)
    except SolverError:
        return fm                     # not known: the whole plate, as without this shortcut
    if not floor >= MEMBRANE_MARGIN * f_max_hz:
        return fm
    return _family_model(fm, "bending")


def residuals_percent(measured_hz: np.ndarray, model_hz: np.ndarray) -> np.ndarray:
    """Paper Eq. 28: r_i = (measured - model) / measured * 100; NaN where not measured."""
    measured_hz = np.asarray(measured_hz, float)
    n = min(measured_hz.size, model_hz.size)
    r = np.full(measured_hz.size, np.nan)
    r[:n] = (measured_hz[:n] - model_hz[:n]) / measured_hz[:n] * 100.0
    return r


def weighted_rms(residual: np.ndarray, weight: np.ndarray) -> float:
    """RMS of the residuals (%) over the modes with a non-zero weight (NaN residuals skipped)."""
    r = np.asarray(residual, float)
    ok = np.isfinite(r) & (np.asarray(weight, float) > 0)
    return float(np.sqrt(np.mean(r[ok] ** 2))) if ok.any() else float("nan")


def measured_arrays(specimen: Specimen, n_modes: int) -> tuple[np.ndarray, np.ndarray]:
    """Measured frequencies (Hz, NaN = none) and weights padded/cut to ``n_modes``."""
    freq = np.full(n_modes, np.nan)
    weight = np.zeros(n_modes)
    if specimen.measured is not None:
        k = min(n_modes, specimen.measured.freq.size)
        freq[:k] = specimen.measured.freq[:k]
        weight[:k] = specimen.measured.weight[:k]
    return freq, weight


#: a weighted measured frequency further than this fraction from its model mode is warned
#: about by ``laminid modes`` (``identify`` refuses to start from it: IdentifyOptions.far_limit)
FAR_FROM_MODEL = 0.5


def far_from_model(measured_hz: np.ndarray, model_hz: np.ndarray, weight: np.ndarray,
                   limit: float = FAR_FROM_MODEL) -> str | None:
    """Words for measured frequencies further than ``limit`` (fraction) from the model's, with
    the first such mode's values and a likely cause; None when every weighted mode is nearer.

    measured_hz, model_hz, weight : (n_modes,), Hz (NaN where not measured) and weights.
    A measured/model ratio near 1/1000 reads as frequencies written in kHz.
    """
    n = min(measured_hz.size, model_hz.size)
    x, m, w = measured_hz[:n], model_hz[:n], weight[:n]
    ok = (w > 0) & np.isfinite(x)
    with np.errstate(invalid="ignore"):
        far = ok & (np.abs(x - m) > limit * x)
    if not far.any():
        return None
    i = int(np.flatnonzero(far)[0])
    return (f"measured mode {i + 1} ({x[i]:.4g} Hz) is {abs(x[i] - m[i]) / x[i] * 100:.0f} % "
            f"from the model ({m[i]:.4g} Hz); {int(far.sum())} of {int(ok.sum())} measured "
            f"modes are more than {limit * 100:.0f} % off (identify refuses such a start): "
            f"{far_cause(x, m, w)}")


def far_cause(measured_hz: np.ndarray, model_hz: np.ndarray, weight: np.ndarray) -> str:
    """The likely cause of measured frequencies far from the model's (``modes``' warning and
    ``identify``'s refusal): a median measured/model ratio near 1/1000 (1/3000 to 1/300) reads
    as frequencies written in kHz as bare numbers (bare is Hz); near sqrt(1000) = 31.6 (15 to
    70: an initial guess 2.2 times off in frequency either way) as moduli 1000 times too small,
    MPa written where GPa is meant (or a density 1000 times too large); near 1/31.6 as the
    reverse (a mass in g written as kg is refused as an implausible density before, and one in
    kg written as g is warned of as too light), or a thickness 10 times too large: with the
    density from the mass, frequency goes as h^1.5 (S1.1 with ``h: 3.06 cm`` read 1/25 and was
    told of the moduli and the density only); else the things to check.

    measured_hz, model_hz, weight : (n_modes,), Hz (NaN where not measured) and weights.
    """
    n = min(measured_hz.size, model_hz.size)
    x, m, w = measured_hz[:n], model_hz[:n], weight[:n]
    ok = (w > 0) & np.isfinite(x) & (m > 0)
    ratio = float(np.median(x[ok] / m[ok])) if ok.any() else np.nan
    if 1 / 3000 < ratio < 1 / 300:
        return ("the measured frequencies look like kHz: write them in Hz (a bare number "
                "is Hz) or with their unit, '0.125 kHz'")
    if 15 < ratio < 70:
        return (f"the model's frequencies are 1/{ratio:.0f} of the measured ones, as with "
                "moduli 1000 times too small (frequency goes as sqrt(modulus/density)): check "
                "the moduli's units (MPa written where GPa is meant?), then the mass/density")
    if 1 / 70 < ratio < 1 / 15:
        return (f"the model's frequencies are {1 / ratio:.0f} times the measured ones, as with "
                "moduli 1000 times too large or a density 1000 times too small (frequency goes "
                "as sqrt(modulus/density)), or a thickness 10 times too large (as h^1.5 where "
                "the mass gives the density: h in cm where mm is meant?): check the units of "
                "the moduli, the mass, the density and the thickness")
    return "check the units, the mass/density, the geometry and the initial constants"


#: ``laminid modes`` warns of a mesh with fewer equations than this per mode computed (or fewer
#: than :data:`MESH_MIN_ELEMENTS` elements along a side). Measured against a 32x32 mesh on S1.1,
#: S2.1, hybrid-cm and a 300 x 200 x 3 mm aluminium plate (meshes 2x2 to 16x16, 1 to 40 modes):
#: below 150 equations per mode the worst of the modes computed is 1 % or more off in 94 % of
#: the cases, 0.5 % or more in 99 % (12x12 with 30 modes: 0.4-1.5 %; 6x6 with 12: 0.8-2.4 %;
#: 2x2 with 12: 50-163 %); from 150 on at most 1.3 % (S1.1 at 10x10 with 19 modes; 8x8 with
#: 12: 0.2-0.8 %; 12x12 with 12: 0.04-0.17 %). The default 12x12 (4329 equations) holds 28 modes
MESH_EQUATIONS_PER_MODE = 150
#: a mesh with fewer elements along a side is warned of for any number of modes: at 3x3 the
#: first two modes are 0.8-1.2 % off, at 2x2 mode 1 is 1.3-3.8 % off (S1.1 3.8 %, aluminium
#: 1.5 %); at 4x4 0.4-0.55 %
MESH_MIN_ELEMENTS = 4


def _mesh_nodes(nx: int, ny: int) -> int:
    """Nodes of an nx x ny mesh of 8-node elements."""
    return (2 * nx + 1) * (2 * ny + 1) - nx * ny


def coarse_mesh(fm: ForwardModel, n_modes: int) -> str | None:
    """Words for a mesh too coarse for ``n_modes`` modes (:data:`MESH_EQUATIONS_PER_MODE`,
    :data:`MESH_MIN_ELEMENTS`) with a finer mesh that is not; None when it is fine enough."""
    nx, ny = (int(n) for n in fm.mesh_size)
    n_eq = int(fm.plate.n_dofs)
    per_mode = n_eq / max(int(n_modes), 1)
    if per_mode >= MESH_EQUATIONS_PER_MODE and min(nx, ny) >= MESH_MIN_ELEMENTS:
        return None
    t = 1.0
    while True:
        sx, sy = (max(MESH_MIN_ELEMENTS, math.ceil(n * t)) for n in (nx, ny))
        if n_eq * _mesh_nodes(sx, sy) / _mesh_nodes(nx, ny) >= MESH_EQUATIONS_PER_MODE * n_modes:
            break
        t *= 1.05
    # (rounded down: 1197 equations for 8 modes are 149.6 a mode, which '.0f' wrote "150
    # equations per mode, fewer than 150")
    why = (f"{math.floor(per_mode * 10) / 10:g} equations per mode, fewer than "
           f"{MESH_EQUATIONS_PER_MODE}" if per_mode < MESH_EQUATIONS_PER_MODE else
           f"fewer than {MESH_MIN_ELEMENTS} elements along a side")
    return (f"the mesh {nx}x{ny} ({n_eq} equations) is coarse for {n_modes} "
            f"mode{'s' if n_modes != 1 else ''}: {why}, where the highest mode computed is "
            f"typically 1 % or more off a converged mesh. Use --mesh "
            f"{sx}x{sy} or finer, and check a mesh with 'laminid identify --mesh-check'")


def modes_summary(fm: ForwardModel, modes: Modes, constants=None) -> dict:
    """Everything ``laminid modes`` reports, as plain data (SI units, frequencies in Hz)."""
    spec = fm.specimen
    constants = fm.initial_constants if constants is None else tuple(constants)
    lam = fm.laminate.with_constants(constants)
    measured, weight = measured_arrays(spec, modes.n_modes)
    residual = residuals_percent(measured, modes.freq)
    return {
        "specimen": {"name": spec.name, "path": str(spec.path), "description": spec.description,
                     "a": spec.a, "b": spec.b, "h": spec.h, "mass": spec.mass,
                     "model_mass": float(lam.mass_per_area * spec.a * spec.b),
                     "n_plies": lam.n_plies, "boundary": boundary_label(fm.plate.boundary)},
        "mesh": {"nx": fm.mesh_size[0], "ny": fm.mesh_size[1], "nodes": fm.plate.mesh.n_nodes,
                 "dofs": fm.plate.n_dofs, "rigid_modes_dropped": modes.n_rigid},
        "materials": {name: {**c.as_dict(), "density": float(spec.densities.get(name, np.nan))}
                      for name, c in zip(fm.material_names, constants)},
        "frequencies": {"model": modes.freq, "measured": measured, "weight": weight,
                        "residual_percent": residual},
        "rms_residual_percent": weighted_rms(residual, weight),
        "global_properties": lam.global_properties().as_dict(),
    }
