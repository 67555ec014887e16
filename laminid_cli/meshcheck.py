"""Is the mesh fine enough? The identification's modes against a mesh twice as fine.

The discretisation error of the default 12x12 mesh is of the order of the frequency noise:
on S1.1 at its identified constants the 12x12 model's mode 12 is 0.155 % above the 24x24
model's, for a stated frequency sigma of 0.2 %. :func:`check_mesh` builds the same specimen's
model on a mesh twice as fine in each direction (every node of the identification's mesh is a
node of the fine one), solves it at the identified constants, pairs its modes with the
identification's paired model modes by the MAC of w0 at the common nodes, and reports per
mode the frequency change, in percent and in units of that mode's frequency sigma.

The bias of the constants follows to first order: a model too stiff by e_i at mode i is a
measured eigenvalue too low by e_i, so the constants move by the least-squares step of the
uncertainty's rows (:func:`laminid_cli.uncertainty.model_change_shift`). ``shift`` is what
identifying on the fine mesh would change (fine minus this mesh), in percent of the value and
in units of the constant's 95 % half-width. A constant that moves by more than
:data:`SHIFT_LIMIT` of its half-width makes the mesh too coarse for these modes (the status
reason ``coarse_mesh``, laminid_cli.status).

No click, no h5py: library code. Frequencies in Hz, constants SI.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

#: a constant whose first-order shift on the fine mesh exceeds this fraction of its 95 %
#: half-width makes the mesh too coarse (S1.1: 12x12 -> 24x24 moves E1 by 0.17 of it, G12 by
#: 0.11; 6x6 -> 12x12 by several half-widths)
SHIFT_LIMIT = 0.3
#: extra fine-mesh modes solved beyond the identification's, for the pairing to choose from
EXTRA_MODES = 4


@dataclass(frozen=True)
class MeshCheck:
    """The identification's paired modes against a mesh twice as fine, and the constants'
    first-order shift there.

    Per checked measured mode (n,): ``measured_mode`` and ``model_mode`` (1-based: the
    measured mode and the identification's model mode paired with it), ``fine_mode`` (1-based,
    the fine model's mode paired with it), ``mac`` (of w0 at the common nodes), ``freq_hz``
    (this mesh's model, solved at the identified constants), ``fine_hz``, ``change_percent``
    ((fine - this) / this * 100), ``change_sigma`` ((fine - this) / the mode's frequency
    sigma). Per free constant (p,): ``labels`` ("material.constant"), ``shift`` (SI; NaN when
    held at a bound), ``shift_percent`` (of the value), ``shift_half_width`` (in units of its
    95 % half-width). ``time_s``: the check's wall time.
    """

    mesh: tuple[int, int]
    fine_mesh: tuple[int, int]
    measured_mode: np.ndarray
    model_mode: np.ndarray
    fine_mode: np.ndarray
    mac: np.ndarray
    freq_hz: np.ndarray
    fine_hz: np.ndarray
    change_percent: np.ndarray
    change_sigma: np.ndarray
    labels: tuple[str, ...]
    shift: np.ndarray
    shift_percent: np.ndarray
    shift_half_width: np.ndarray
    limit: float = SHIFT_LIMIT
    time_s: float = float("nan")

    @property
    def too_coarse(self) -> tuple[str, ...]:
        """The labels whose shift exceeds ``limit`` of their half-width, largest first."""
        r = np.abs(self.shift_half_width)
        bad = [k for k in np.argsort(-np.nan_to_num(r, nan=-1.0)) if r[k] > self.limit]
        return tuple(self.labels[k] for k in bad)

    @property
    def text(self) -> str:
        """The warning when the mesh is too coarse, else ""."""
        bad = self.too_coarse
        if not bad:
            return ""
        k = {lab: i for i, lab in enumerate(self.labels)}
        one = len({lab.rsplit(".", 1)[0] for lab in self.labels}) == 1
        nx, ny = self.fine_mesh
        words = ", ".join(
            f"{lab.rsplit('.', 1)[1] if one else lab} {self.shift_percent[k[lab]]:+.3g} % "
            f"({self.shift_half_width[k[lab]]:+.2f} of its half-width)" for lab in bad)
        return (f"the mesh is too coarse for these modes: at {nx}x{ny} the constants move by "
                f"{words}, beyond {self.limit:g} of their 95 % half-width (identify with "
                f"--mesh {nx}x{ny})")

    def as_dict(self) -> dict:
        """JSON object ``mesh_check`` (frequencies Hz, shifts SI)."""
        per: dict[str, dict] = {}
        for k, lab in enumerate(self.labels):
            mat, const = lab.rsplit(".", 1)
            per.setdefault(mat, {})[const] = {
                "shift": float(self.shift[k]), "shift_percent": float(self.shift_percent[k]),
                "shift_half_width": float(self.shift_half_width[k])}
        return {"mesh": {"nx": self.mesh[0], "ny": self.mesh[1]},
                "fine_mesh": {"nx": self.fine_mesh[0], "ny": self.fine_mesh[1]},
                "modes": {"measured_mode": self.measured_mode, "model_mode": self.model_mode,
                          "fine_mode": self.fine_mode, "mac": self.mac,
                          "freq_hz": self.freq_hz, "fine_hz": self.fine_hz,
                          "change_percent": self.change_percent,
                          "change_sigma": self.change_sigma},
                "constants": per, "labels": list(self.labels), "limit": self.limit,
                "too_coarse": list(self.too_coarse), "text": self.text,
                "time_s": self.time_s}


def fine_mesh_size(mesh: tuple[int, int]) -> tuple[int, int]:
    """The mesh twice as fine in each direction: its nodes include every node of ``mesh``."""
    return 2 * int(mesh[0]), 2 * int(mesh[1])


def common_nodes(coarse, fine) -> np.ndarray:
    """(coarse n_nodes,) index of each node of the Mesh ``coarse`` among the nodes of ``fine``
    (a :func:`fine_mesh_size` mesh of the same plate): coarse grid point (i, j) is fine grid
    point (2i, 2j), never a fine element centre (laminid_cli.fe.mesh.rectangular_mesh)."""
    hx, hy = fine.a / (2 * fine.nx), fine.b / (2 * fine.ny)
    gx = 2 * fine.nx + 1
    key_f = np.rint(fine.nodes[:, 1] / hy).astype(np.int64) * gx + np.rint(
        fine.nodes[:, 0] / hx).astype(np.int64)
    key_c = np.rint(coarse.nodes[:, 1] / hy).astype(np.int64) * gx + np.rint(
        coarse.nodes[:, 0] / hx).astype(np.int64)
    order = np.argsort(key_f)
    pos = np.searchsorted(key_f[order], key_c)
    found = order[np.minimum(pos, order.size - 1)]
    if not np.array_equal(key_f[found], key_c):
        raise ValueError("the coarse mesh's nodes are not all nodes of the fine mesh")
    return found


def pair_modes(w_coarse: np.ndarray, w_fine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one pairing of the coarse modes with fine ones by the MAC of w0 at the common
    nodes: w_coarse (n_nodes, n), w_fine (n_nodes, m >= n). Returns (fine index (n,), MAC
    (n,)) maximising the summed MAC (:func:`laminid_cli.objective.max_assignment`, the
    identification's own pairing)."""
    from laminid_cli.modal import mac
    from laminid_cli.objective import max_assignment

    M = mac(w_coarse, w_fine)
    fine = max_assignment(M)
    return fine, M[np.arange(fine.size), fine]


def fine_model(fm):
    """The model of ``fm``'s specimen on the mesh twice as fine, with the same equations
    (the bending equations alone when ``fm`` has them)."""
    from laminid_cli.forward import _family_model, build_forward_model

    whole = build_forward_model(fm.specimen, fine_mesh_size(fm.mesh_size),
                                boundary=fm.plate.boundary,
                                factorizer=fm.factorizer.name)
    return _family_model(whole, fm.plate.family) if fm.plate.family != "all" else whole


def check_mesh(fm, assessment) -> MeshCheck:
    """Compare a single plate's identification (``assessment``: its
    :class:`laminid_cli.uncertainty.Assessment`, ``fm`` the ForwardModel it was identified on)
    with the same model on a mesh twice as fine (module docstring).

    This mesh's frequencies are those of the full model solved at the identified constants
    (not the reduced model's of the search, within ~1e-11 of them).
    """
    from laminid_cli.uncertainty import material_states, model_change_shift, observations

    t0 = time.perf_counter()
    r = assessment.result
    u = assessment.uncertainty
    sigma = assessment.sigmas[0]
    n_model = int(r.modes.n_modes)
    coarse = fm.solve(r.constants, n_modes=n_model)
    fine_fm = fine_model(fm)
    fine = fine_fm.solve(r.constants, n_modes=n_model + EXTRA_MODES)
    pairing = np.asarray(r.pairing, int)
    measured = np.asarray(r.measured_hz, float)
    checked = np.flatnonzero(np.isfinite(measured) & (pairing >= 0))
    nodes = common_nodes(fm.plate.mesh, fine_fm.plate.mesh)
    w_c = fm.plate.w_shape(coarse.phi[:, pairing[checked]])
    w_f = fine_fm.plate.w_shape(fine.phi)[nodes]
    fine_idx, mac_val = pair_modes(w_c, w_f)
    f_c = coarse.freq[pairing[checked]]
    f_f = fine.freq[fine_idx]
    sig = np.asarray(sigma.sigma_hz, float)[checked]
    # per measured mode: the relative eigenvalue change (0 where not checked: no row there)
    e = np.zeros(measured.size)
    e[checked] = (f_f / f_c) ** 2 - 1.0
    labels = tuple(u.labels)
    obs = observations(fm, r, sigma, labels)
    shift = model_change_shift([obs], material_states(r), [e], nu_max=r.options.nu_max,
                               bound_factor=r.options.bound_factor)
    value = np.asarray(u.value, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        shift_pct = np.where(value != 0, shift / np.abs(value) * 100.0, np.nan)
        shift_hw = shift / np.asarray(u.half_width, float)
    return MeshCheck(
        mesh=tuple(fm.mesh_size), fine_mesh=tuple(fine_fm.mesh_size),
        measured_mode=checked + 1, model_mode=pairing[checked] + 1, fine_mode=fine_idx + 1,
        mac=mac_val, freq_hz=f_c, fine_hz=f_f, change_percent=(f_f - f_c) / f_c * 100.0,
        change_sigma=(f_f - f_c) / sig, labels=labels, shift=shift, shift_percent=shift_pct,
        shift_half_width=shift_hw, time_s=time.perf_counter() - t0)
