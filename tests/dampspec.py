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


def _frequencies_entry(lines) -> tuple[int, int, str]:
    """Where ``measured.frequencies`` is in a specimen file's ``lines``: its first line, the
    line after its value (a flow list continued over several lines, hybrid-cm.yaml's, or a
    block list of ``- f`` lines) and its key's indent. Damping lines inserted right after its
    first line landed inside a list continued below it."""
    k = next(i for i, x in enumerate(lines) if x.lstrip().startswith("frequencies:"))
    indent = lines[k][:len(lines[k]) - len(lines[k].lstrip())]
    end = k + 1
    for i in range(k + 1, len(lines)):
        body = lines[i].split("#", 1)[0]
        if not body.strip():
            continue                                  # blank or comment: ends nothing
        lead = len(body) - len(body.lstrip())
        if lead > len(indent) or (lead == len(indent) and body.lstrip().startswith("- ")):
            end = i + 1                               # the value goes on
        else:
            break
    return k, end, indent


def with_frequencies(text: str, freq) -> str:
    """A specimen file's ``text`` with ``freq`` (Hz) as its measured frequencies, in place of
    the whole list (every line of one continued over several)."""
    lines = text.splitlines(keepends=True)
    k, end, indent = _frequencies_entry(lines)
    lines[k:end] = [indent + "frequencies: [" + ", ".join(f"{f:.10g}" for f in freq) + "]\n"]
    return "".join(lines)


def with_damping(text: str, zeta, sigma) -> str:
    """A specimen file's ``text`` with ``measured.damping`` ``zeta`` and ``damping_sigma``
    ``sigma`` after its frequencies' list, at its key's indent."""
    lines = text.splitlines(keepends=True)
    _, end, indent = _frequencies_entry(lines)
    lines.insert(end, indent + "damping: [" + ", ".join(f"{v:.12g}" for v in zeta) + "]\n"
                 + indent + "damping_sigma: [" + ", ".join(f"{v:.12g}" for v in sigma) + "]\n")
    return "".join(lines)


def damped_copy(src, dst, eta, *, sigma_rel: float, mesh="8x8", noise: float = 0.0,
                seed: int = 1, freq=None):
    """Write ``dst``: ``src`` with damping from ``eta`` (5 loss factors 11, 22, 12, 13, 23) at
    the constants identified on ``mesh`` (``freq``: measured frequencies written in their
    place first, e.g. a model's), damping_sigma ``sigma_rel`` x zeta, zeta times (1 +
    ``noise`` N(0, 1)). Returns zeta (noise-free)."""
    from laminid_cli.pipeline import RunOptions, run_identification

    text = Path(src).read_text()
    if freq is not None:
        text = with_frequencies(text, freq)
        Path(dst).write_text(text)
        src = dst
    run = run_identification([src], RunOptions(mesh=mesh))
    r = run.result
    shares = D.energy_shares(run.forward_models[0].plate, r.constants, r.phi_paired)
    zeta = D.modal_loss_factors(shares, eta) / 2
    z = zeta * (1 + noise * np.random.default_rng(seed).standard_normal(zeta.size))
    Path(dst).write_text(with_damping(text, z, sigma_rel * zeta))
    return zeta
