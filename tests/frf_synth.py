"""Synthetic FRFs from known modal parameters, for the FRF tests and the instrument emulator.

The model (proportional damping, real modal constants allowed to be negative or complex)::

    H_p(omega) = (j omega)^k * sum_r  C[p, r] / (omega_r^2 - omega^2 + 2 j zeta_r omega_r omega)

with ``k = 0, 1, 2`` for receptance, mobility, accelerance. A mode with ``freq_hz = 0`` and
``damping_ratio = 0`` is a rigid-body mode: its term ``-C / omega^2`` is the mass line (constant
for accelerance). ``C`` is in FRF units x (rad/s)^2 for receptance (``phi_p phi_q`` of mass-
normalised modes, in m/N x (rad/s)^2).

Public API: :func:`synth_frf` (pure function on arrays) and :func:`plate_case` (the standard
plate-like scenario of the tests: in-band modes, an out-of-band mode, a mass line).

>>> import numpy as np
>>> f = np.arange(1.0, 401.0)
>>> H = synth_frf(f, [(100.0, 0.01)], np.ones((2, 1)))
>>> H.shape
(2, 400)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KINDS = ("receptance", "mobility", "accelerance")
NOISE_KINDS = ("proportional", "rms")


@dataclass(frozen=True)
class SynthCase:
    """A synthetic FRF set with its true modal parameters (sorted by frequency)."""

    freq: np.ndarray            # (n_freq,) Hz
    frf: np.ndarray             # (n_points, n_freq) complex
    freq_hz: np.ndarray         # (n_modes,) true natural frequencies of the in-band modes
    damping_ratio: np.ndarray   # (n_modes,)
    constants: np.ndarray       # (n_points, n_modes) modal constants C
    kind: str = "receptance"


def synth_frf(freq_hz, modes, points, *, kind: str = "receptance", noise: float = 0.0,
              noise_kind: str = "proportional", seed: int | None = 0) -> np.ndarray:
    """FRFs of a proportionally damped structure at ``n_points`` points.

    Parameters
    ----------
    freq_hz : float (n_freq,), Hz
    modes : (n_modes, 2) array-like of (natural frequency Hz, damping ratio); a (0, 0) row is
        a rigid-body mode (mass line)
    points : (n_points, n_modes) modal constants C (real of either sign, or complex), one row per
        measurement point; a 1-D array is one point
    kind : one of :data:`KINDS`
    noise : relative standard deviation of circular complex Gaussian noise
    noise_kind : ``"proportional"`` (std = noise * |H| line by line) or ``"rms"`` (std = noise *
        RMS of |H_p| over the axis, the same at every line of a point)
    seed : seed of ``numpy.random.default_rng``

    Returns
    -------
    complex (n_points, n_freq)
    """
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r}: expected one of {KINDS}")
    if noise_kind not in NOISE_KINDS:
        raise ValueError(f"noise_kind {noise_kind!r}: expected one of {NOISE_KINDS}")
    f = np.asarray(freq_hz, dtype=float)
    m = np.atleast_2d(np.asarray(modes, dtype=float))
    if m.shape[-1] != 2:
        raise ValueError("modes must be (n_modes, 2): frequency Hz, damping ratio")
    C = np.asarray(points)
    C = C.reshape(1, -1) if C.ndim == 1 else C
    if C.shape[1] != m.shape[0]:
        raise ValueError(f"points has {C.shape[1]} modal constants per point, "
                         f"modes has {m.shape[0]}")
    w = 2 * np.pi * f
    wr, zr = 2 * np.pi * m[:, 0], m[:, 1]
    if np.any(wr == 0) and np.any(w == 0) and kind != "accelerance":
        raise ValueError("a rigid-body mode needs a frequency axis without 0 Hz")
    den = wr[:, None] ** 2 - w[None, :] ** 2 + 2j * zr[:, None] * wr[:, None] * w[None, :]
    k = KINDS.index(kind)
    with np.errstate(divide="ignore", invalid="ignore"):
        H = C @ (1.0 / den) * (1j * w) ** k
        if kind == "accelerance" and np.any(wr == 0):   # -C (j w)^2 / w^2 = C, also at 0 Hz
            rigid = wr == 0
            H[:, w == 0] = C[:, rigid].sum(axis=1)[:, None]
    if noise:
        rng = np.random.default_rng(seed)
        e = (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
        scale = np.abs(H) if noise_kind == "proportional" else \
            np.sqrt(np.mean(np.abs(H) ** 2, axis=1, keepdims=True))
        H = H + noise * scale * e
    return H


def plate_case(*, n_points: int = 5, resolution_hz: float = 1.0, n_lines: int = 1601,
               f_start: float = 1.0, noise: float = 0.0, noise_kind: str = "proportional",
               seed: int = 0, kind: str = "receptance", extra_modes=(), weak: float = 1.0,
               rigid: bool = True, out_of_band: bool = True) -> SynthCase:
    """A free composite plate's spectrum seen from ``n_points`` microphone/accelerometer points.

    Ten modes between 125 and 1400 Hz with 0.2-1.5 % damping and modal constants of both signs,
    one mode above the axis (2200 Hz, out of band), and a rigid-body mass line. ``extra_modes``
    adds (freq, damping, constant scale) triples (e.g. a close mode); ``weak`` scales the
    constants of the 446.65 Hz mode (``weak=1/50`` makes it 50 times weaker than its neighbours).
    The returned ``freq_hz`` etc. list only the modes inside the axis, sorted.
    """
    freq = f_start + resolution_hz * np.arange(n_lines)
    base = [  # Hz, damping ratio
        (125.05, 0.006), (203.50, 0.004), (268.30, 0.010), (351.20, 0.002), (446.65, 0.008),
        (580.40, 0.012), (713.90, 0.005), (902.10, 0.015), (1130.70, 0.009), (1388.20, 0.007),
    ]
    rng = np.random.default_rng(1234)   # fixed "mode shapes", independent of the noise seed
    modes = list(base)
    shape = (n_points, len(base))
    C = rng.uniform(0.4, 1.0, shape) * rng.choice([-1.0, 1.0], shape)
    C[:, 4] *= weak
    for fx, zx, scale in extra_modes:
        modes.append((fx, zx))
        col = scale * rng.uniform(0.4, 1.0, (n_points, 1)) * rng.choice([-1.0, 1.0], (n_points, 1))
        C = np.hstack([C, col])
    # amplitudes ~ omega_r^2 so every peak is of similar height x (1/2 zeta) in receptance
    C = C * (2 * np.pi * np.array([m[0] for m in modes])) ** 2 * 1e-3
    all_modes, all_C = list(modes), C
    if out_of_band:
        all_modes.append((2200.0, 0.01))
        c_out = 1e-3 * (2 * np.pi * 2200.0) ** 2 * rng.uniform(1.0, 2.0, (n_points, 1))
        all_C = np.hstack([all_C, c_out])
    if rigid:
        all_modes.append((0.0, 0.0))
        c_rigid = 1e-3 * (2 * np.pi * 20.0) ** 2 * rng.uniform(0.5, 1.0, (n_points, 1))
        all_C = np.hstack([all_C, c_rigid])
    if kind != "receptance":   # keep similar peak heights in every kind
        all_C = all_C / (2 * np.pi * 500.0) ** KINDS.index(kind)
    H = synth_frf(freq, all_modes, all_C, kind=kind, noise=noise, noise_kind=noise_kind, seed=seed)
    fr = np.array([m[0] for m in modes])
    inside = (fr > freq[0]) & (fr < freq[-1])
    order = np.argsort(fr[inside])
    return SynthCase(freq=freq, frf=H, freq_hz=fr[inside][order],
                     damping_ratio=np.array([m[1] for m in modes])[inside][order],
                     constants=C[:, inside][:, order], kind=kind)
