"""Identify every specimen of Araujo et al. (2000) and print the paper's numbers beside laminid's.

Usage (from the repository root)::

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/paper_comparison.py [--mesh 12x12] [SPEC ...]

For each specimen file (default: all eight of tests/data/paper.py) the identification starts
from the file's initial guess on the paper's 12x12 mesh with the default options, and the table
shows, per material, the paper's identified constants (Tables 2, 3, 6, 7), laminid's and their
relative difference; the global (Appendix A) properties where the paper gives them (Table 4 Ey,
Table 6); the RMS frequency residual over the modes the paper reports (Tables 1, 5, 8), the
number of model evaluations and the time.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from laminid_cli.errors import LaminidError  # noqa: E402
from laminid_cli.fe.mesh import parse_mesh  # noqa: E402
from laminid_cli.forward import build_forward_model  # noqa: E402
from laminid_cli.identify import IdentifyOptions, identify  # noqa: E402
from laminid_cli.material import CONSTANT_NAMES  # noqa: E402
from laminid_cli.specimen import read_specimen  # noqa: E402
from tests.data.paper import IDENTIFIED, IDENTIFIED_GLOBAL, RESIDUALS, SPECIMENS  # noqa: E402

GLOBAL_NAMES = ("Ex", "Ey", "Gxy", "Gxz", "Gyz", "nu_xy")


def paper_rms(path: str) -> tuple[float, np.ndarray]:
    """RMS of the paper's residuals (%) and the mask of the modes it reports."""
    r = RESIDUALS[path]
    mask = np.array([v is not None for v in r])
    vals = np.array([v for v in r if v is not None], float)
    return float(np.sqrt(np.mean(vals**2))), mask


def fmt(name: str, value: float) -> str:
    return f"{value:8.3f}" if name.startswith("nu") else f"{value / 1e9:8.2f}"


def compare_row(name: str, paper: float | None, ours: float) -> str:
    if paper is None:
        return f"    {name:6s} {'-':>8s} {fmt(name, ours)} {'':>8s}"
    diff = (ours - paper) / abs(paper) * 100 if paper else float("nan")
    return f"    {name:6s} {fmt(name, paper)} {fmt(name, ours)} {diff:+7.1f}%"


def run(path: str, mesh: tuple[int, int]) -> dict:
    spec = read_specimen(ROOT / path)
    fm = build_forward_model(spec, mesh)
    t0 = time.perf_counter()
    result = identify(fm, IdentifyOptions())
    dt = time.perf_counter() - t0
    p_rms, mask = paper_rms(path)
    use = mask & (result.weight > 0) & np.isfinite(result.residual_percent)
    our_rms = float(np.sqrt(np.mean(result.residual_percent[use] ** 2)))
    lines = [f"{path}  ({spec.name}, {result.measured_hz.size} modes, "
             f"{len(result.variable_labels)} variables)",
             f"    {'':6s} {'paper':>8s} {'laminid':>8s} {'diff':>8s}   (GPa)"]
    for k, name in enumerate(result.material_names):
        if len(result.material_names) > 1:
            lines.append(f"  material {name}")
        paper = IDENTIFIED[path].get(name, {})
        for c in CONSTANT_NAMES:
            lines.append(compare_row(c, paper.get(c), getattr(result.constants[k], c)))
    if path in IDENTIFIED_GLOBAL:
        lines.append("  global properties (Appendix A)")
        paper_global = IDENTIFIED_GLOBAL[path]
        for g in GLOBAL_NAMES:
            if g in paper_global:
                lines.append(compare_row(g, paper_global[g], result.global_properties[g]))
    lines.append(f"  RMS residual over the paper's {int(use.sum())} modes: paper {p_rms:.3f} %, "
                 f"laminid {our_rms:.3f} % (initial {result.initial_rms_residual_percent:.2f} %)")
    lines.append(f"  {result.status}; {result.evaluations} evaluations, {dt:.1f} s; "
                 f"swaps: {len(result.swaps)}")
    for w in result.warnings:
        lines.append(f"  warning: {w}")
    return {"text": "\n".join(lines), "paper_rms": p_rms, "rms": our_rms,
            "evaluations": result.evaluations, "time": dt, "name": spec.name,
            "converged": result.converged}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("specimens", nargs="*", default=list(SPECIMENS))
    parser.add_argument("--mesh", default="12x12")
    args = parser.parse_args(argv)
    mesh = parse_mesh(args.mesh)
    summary = []
    for path in args.specimens:
        try:
            out = run(path, mesh)
        except LaminidError as exc:
            print(f"{path}: {exc}\n")
            summary.append((path, None))
            continue
        print(out["text"] + "\n", flush=True)
        summary.append((path, out))
    print(f"{'specimen':12s} {'RMS paper %':>11s} {'RMS laminid %':>13s} {'evals':>6s} "
          f"{'time s':>7s} converged")
    for path, out in summary:
        if out is None:
            print(f"{Path(path).stem:12s} failed")
            continue
        print(f"{out['name']:12s} {out['paper_rms']:11.3f} {out['rms']:13.3f} "
              f"{out['evaluations']:6d} {out['time']:7.1f} {out['converged']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
