"""Ply geometry of a specimen as arrays: interfaces, angles, materials, densities.

z is measured up from the mid-plane; ply 1 is the bottom ply (paper Fig. 6), so ply ``k``
(0-based) lies between ``z[k]`` and ``z[k + 1]`` with ``z[0] = -h/2`` and ``z[-1] = +h/2``.
Angles are in radians here (degrees in files), measured in the x-y plane from x towards y.
Pure numpy; no file or CLI code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from laminid_cli.material import ElasticConstants, GlobalProperties, alphas_from_constants, \
    c_basis, global_properties, global_property_array, ply_stiffness


@dataclass(frozen=True)
class Laminate:
    """Arrays describing the plies of a plate, bottom ply first.

    z : (n_plies + 1,) m, ply interfaces from -h/2 to +h/2
    angle : (n_plies,) rad
    material_index : (n_plies,) int, index into ``material_names`` and ``constants``
    material_names : tuple of str, in specimen-file order
    density : (n_plies,) kg/m^3
    constants : tuple of ElasticConstants, one per material
    """

    z: np.ndarray
    angle: np.ndarray
    material_index: np.ndarray
    material_names: tuple[str, ...]
    density: np.ndarray
    constants: tuple[ElasticConstants, ...]

    @property
    def n_plies(self) -> int:
        return int(self.angle.shape[0])

    @property
    def thickness(self) -> np.ndarray:
        """Ply thicknesses, (n_plies,) m."""
        return np.diff(self.z)

    @property
    def h(self) -> float:
        """Total thickness, m."""
        return float(self.z[-1] - self.z[0])

    @property
    def mass_per_area(self) -> float:
        """sum over plies of rho_k t_k, kg/m^2."""
        return float(np.dot(self.density, self.thickness))

    def ply_stiffness(self) -> np.ndarray:
        """Constitutive matrix Q of every ply in laminate axes, (n_plies, 5, 5), Pa (Eq. 6)."""
        Q = np.empty((self.n_plies, 5, 5))
        for m, constants in enumerate(self.constants):
            mask = self.material_index == m
            if mask.any():
                Q[mask] = ply_stiffness(constants, self.angle[mask])
        return Q

    def global_properties(self) -> GlobalProperties:
        """Equivalent membrane/shear properties of the laminate, paper Appendix A."""
        return global_properties(self.ply_stiffness(), self.thickness)

    def global_properties_of(self, values) -> np.ndarray:
        """The global properties (Appendix A) at many sets of constants at once: ``values``
        (n, n_materials, 6), each material's constants in CONSTANT_NAMES order (SI, materials
        in ``material_names`` order), gives (n, 7) in :class:`GlobalProperties` order. One
        array expression over the sets (Eq. 4's alphas, Eq. 8's basis, A.1-A.2), no loop."""
        v = np.asarray(values, dtype=float)
        a = alphas_from_constants(ElasticConstants(*np.moveaxis(v, -1, 0)))   # (6, n, M)
        scale = v[..., 0] / (8.0 * a[0])                                        # E1 / (8 a0)
        coef = scale[..., None] * np.stack([np.ones_like(a[0]), *a[1:]], axis=-1)
        # Q of every ply of every set: sum_j coef[set, its material, j] C_j(its angle)
        Q = np.einsum("nlj,ljab->nlab", coef[:, self.material_index], c_basis(self.angle))
        return global_property_array(Q, self.thickness)

    def with_constants(self, constants) -> "Laminate":
        """Copy with new constants: a sequence in ``material_names`` order or a dict by name."""
        if isinstance(constants, dict):
            constants = tuple(constants.get(name, old)
                              for name, old in zip(self.material_names, self.constants))
        constants = tuple(constants)
        if len(constants) != len(self.material_names):
            raise ValueError(f"{len(constants)} sets of constants for "
                             f"{len(self.material_names)} materials")
        return Laminate(z=self.z, angle=self.angle, material_index=self.material_index,
                        material_names=self.material_names, density=self.density,
                        constants=constants)

    def stacking_text(self) -> str:
        """One line describing the plies, e.g. ``[45_3/0_3/-45_3/90_3]s, 24 plies x 0.1275 mm,
        h = 3.06 mm``; material tags are added when there are several materials."""
        angles = np.degrees(self.angle)
        t = self.thickness
        several = len(self.material_names) > 1
        keys = [(round(float(a), 6), int(m), round(float(tk) * 1e9)) for a, m, tk in
                zip(angles, self.material_index, t)]
        n = len(keys)
        symmetric = n >= 2 and n % 2 == 0 and keys == keys[::-1]
        half = keys[: n // 2] if symmetric else keys
        runs: list[list] = []
        for key in half:
            if runs and runs[-1][0][:2] == key[:2]:
                runs[-1][1] += 1
            else:
                runs.append([key, 1])
        parts = []
        for (angle, m, _), count in runs:
            text = f"{angle:g}" + (f"_{count}" if count > 1 else "")
            if several:
                text += f":{self.material_names[m]}"
            parts.append(text)
        code = "[" + "/".join(parts) + "]" + ("s" if symmetric else "")
        if np.allclose(t, t[0], rtol=1e-9):
            plies = f"{n} {'ply' if n == 1 else 'plies'} x {t[0] * 1e3:.4g} mm"
        else:
            per = []
            for m, name in enumerate(self.material_names):
                tm = t[self.material_index == m]
                if tm.size and np.allclose(tm, tm[0], rtol=1e-9):
                    per.append(f"{name} {tm[0] * 1e3:.4g} mm")
                elif tm.size:
                    per.append(f"{name} {tm.min() * 1e3:.4g}-{tm.max() * 1e3:.4g} mm")
            plies = f"{n} plies ({', '.join(per)})"
        return f"{code}, {plies}, h = {self.h * 1e3:.4g} mm"


def laminate_from_specimen(spec) -> Laminate:
    """Build the :class:`Laminate` of a :class:`~laminid_cli.specimen.Specimen`.

    The plies fill exactly ``spec.h`` (the specimen reader guarantees that their thicknesses
    add up to h); the interfaces are the cumulative sums from -h/2.
    """
    names = tuple(spec.materials)
    index = {name: k for k, name in enumerate(names)}
    t = np.array([p.thickness for p in spec.plies], dtype=float)
    z = np.concatenate([[0.0], np.cumsum(t)]) - 0.5 * t.sum()
    z[0], z[-1] = -0.5 * spec.h, 0.5 * spec.h
    arrays = dict(
        z=z,
        angle=np.radians([p.angle_deg for p in spec.plies]),
        material_index=np.array([index[p.material] for p in spec.plies], dtype=int),
        density=np.array([spec.densities[p.material] for p in spec.plies], dtype=float),
    )
    for value in arrays.values():
        value.flags.writeable = False
    return Laminate(material_names=names,
                    constants=tuple(spec.materials[n].constants for n in names), **arrays)
