"""Test helper: copies of a specimen file with synthetic measured modal damping.

:func:`damped_copy` writes the specimen with ``measured.damping`` (zeta = eta_i / 2) and
``measured.damping_sigma``: eta_i = sum of the strain-energy shares x the ply loss factors
``eta`` (damping.modal_loss_factors) of the modes of an identification of that specimen (its
``phi_paired`` at its ``constants``), so that the main damping fit finds ``eta`` (noise-free,
``noise=0``) and the loss factors' doubt is what the stated sigmas and the constants' give.
"""

from pathlib import Path

import numpy as np

from laminid_cli import damping as D


def damped_copy(src, dst, eta, *, sigma_rel: float, mesh="8x8", noise: float = 0.0,
                seed: int = 1, freq=None):
    """Write ``dst``: ``src`` with damping from ``eta`` (5 loss factors 11, 22, 12, 13, 23) at
    the constants identified on ``mesh`` (``freq``: measured frequencies written in their
    place first, e.g. a model's), damping_sigma ``sigma_rel`` x zeta, zeta times (1 +
    ``noise`` N(0, 1)). Returns zeta (noise-free)."""
    from laminid_cli.pipeline import RunOptions, run_identification

    text = Path(src).read_text()
    if freq is not None:
        lines = text.splitlines(keepends=True)
        k = next(i for i, x in enumerate(lines) if x.strip().startswith("frequencies:"))
        lines[k] = "  frequencies: [" + ", ".join(f"{f:.10g}" for f in freq) + "]\n"
        text = "".join(lines)
        Path(dst).write_text(text)
        src = dst
    run = run_identification([src], RunOptions(mesh=mesh))
    r = run.result
    shares = D.energy_shares(run.forward_models[0].plate, r.constants, r.phi_paired)
    zeta = D.modal_loss_factors(shares, eta) / 2
    z = zeta * (1 + noise * np.random.default_rng(seed).standard_normal(zeta.size))
    lines = text.splitlines(keepends=True)
    k = next(i for i, x in enumerate(lines) if x.strip().startswith("frequencies:"))
    lines.insert(k + 1, "  damping: [" + ", ".join(f"{v:.12g}" for v in z) + "]\n"
                 "  damping_sigma: [" + ", ".join(f"{sigma_rel * v:.12g}" for v in zeta)
                 + "]\n")
    Path(dst).write_text("".join(lines))
    return zeta

