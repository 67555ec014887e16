"""A synthetic impact test of the paper's plate S1.1, to try the FRF chain without an analyser.

Writes, in OUT (default ``out/example-frf``):

* ``plate.frf.h5``: accelerance FRFs ((m/s^2)/N, laminid's FRF file, as ``laminid acquire``
  writes it) at POINTS hammer positions, accelerometer fixed near a corner, 0.5 Hz lines up to
  midway between the model's 13th and 14th modes (1425 Hz; the
  modes up to the 15th are in the sum), from the plate model (12x12 mesh) with known
  constants and known ply loss factors, plus circular Gaussian noise of NOISE x |H| per line;
  the coherence is a stand-in, 1 - (4 NOISE)^2 at every line (no averaging is simulated);
* ``plate.yaml``: S1.1's specimen file without its measured frequencies (what ``laminid
  fit-frf plate.frf.h5 --into plate.yaml`` fills in);
* ``truth.json``: the constants, loss factors, frequencies and damping ratios the FRFs were
  made from, to compare with what ``fit-frf`` and ``identify`` find.

The "truth" is the paper's identified S1.1 (Table 2: E1 161.1, E2 9.3, G12 6.8, G13 3.1,
G23 3.2 GPa, nu12 0.166) and loss factors typical of carbon/epoxy (eta11 0.2 %, eta22 1.2 %,
eta12 1.5 %, eta13 = eta23 = 1 %); each mode's damping ratio is half its modal loss factor by
the modal strain energy model (laminid_cli.damping). Every FRF is the modal sum
H_p = -omega^2 sum_r phi_r(p) phi_r(ref) / (omega_r^2 - omega^2 + 2 j zeta_r omega_r omega)
of the mass-normalised modes (tests/frf_synth.py's model), deterministic for a given SEED.

Run: .venv/bin/python scripts/example_frf.py [--out DIR] [--points 8] [--noise 0.005]
     [--seed 0] (``make example-frf``)
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SPEC = ROOT / "specimens" / "example1" / "S1.1.yaml"
#: the paper's identified constants of S1.1 (Table 2), GPa
TRUTH_GPA = {"E1": 161.1, "E2": 9.3, "G12": 6.8, "G13": 3.1, "G23": 3.2}
TRUTH_NU12 = 0.166
#: ply loss factors eta11, eta22, eta12, eta13, eta23 (laminid_cli.damping's term order)
ETA = (0.002, 0.012, 0.015, 0.010, 0.010)
#: hammer positions as fractions of (a, b): off every symmetry line, so each mode is seen
POSITIONS = ((0.12, 0.07), (0.37, 0.21), (0.81, 0.13), (0.63, 0.42), (0.24, 0.58),
             (0.93, 0.66), (0.46, 0.86), (0.08, 0.94), (0.72, 0.91), (0.55, 0.31))
ACCELEROMETER = (0.04, 0.05)


def nearest_node(nodes, a, b, frac):
    target = np.array([frac[0] * a, frac[1] * b])
    return int(np.argmin(np.sum((nodes - target) ** 2, axis=1)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "out" / "example-frf"))
    ap.add_argument("--points", type=int, default=8, choices=range(1, len(POSITIONS) + 1),
                    metavar=f"1..{len(POSITIONS)}")
    ap.add_argument("--noise", type=float, default=0.005,
                    help="relative noise per line (default 0.005)")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from laminid_cli.damping import energy_shares, modal_loss_factors
    from laminid_cli.forward import build_forward_model
    from laminid_cli.frf.store import write_frf_h5
    from laminid_cli.material import ElasticConstants
    from laminid_cli.specimen import read_specimen
    from tests.frf_synth import synth_frf

    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    spec = read_specimen(SPEC)
    fm = build_forward_model(spec, (12, 12))
    truth = ElasticConstants(E1=TRUTH_GPA["E1"] * 1e9, E2=TRUTH_GPA["E2"] * 1e9,
                             G12=TRUTH_GPA["G12"] * 1e9, G13=TRUTH_GPA["G13"] * 1e9,
                             G23=TRUTH_GPA["G23"] * 1e9, nu12=TRUTH_NU12)
    modes = fm.solve([truth], 15)
    eta_modal = modal_loss_factors(energy_shares(fm.plate, [truth], modes.phi), ETA)
    zeta = eta_modal / 2
    n_in = 13                        # modes inside the axis (the 14th and 15th act from above)
    top = 0.5 * (modes.freq[n_in - 1] + modes.freq[n_in])
    freq = np.arange(0.5, top, 0.5)
    w = fm.plate.w_shape(modes.phi)                   # (n_nodes, n_modes), m/sqrt(kg)
    nodes = np.asarray(fm.plate.mesh.nodes, float)
    la, lb = fm.plate.mesh.a, fm.plate.mesh.b
    ref = nearest_node(nodes, la, lb, ACCELEROMETER)
    hits = [nearest_node(nodes, la, lb, p) for p in POSITIONS[:a.points]]
    C = w[hits, :] * w[ref, :]                        # phi_r(p) phi_r(ref), (points, modes)
    frf = synth_frf(freq, np.column_stack([modes.freq, zeta]), C, kind="accelerance",
                    noise=a.noise, seed=a.seed)
    coh = np.clip(1 - (a.noise * 4) ** 2 * np.ones(frf.shape), 0, 1)
    points = {"x_m": [float(nodes[h, 0]) for h in hits], "y_m": [float(nodes[h, 1]) for h in hits]}
    write_frf_h5(out / "plate.frf.h5", freq, frf, coh, units="(m/s^2)/N",
                 labels=[f"hit {i + 1}" for i in range(len(hits))], points=points,
                 instrument={"model": "synthetic (scripts/example_frf.py)"},
                 settings={"span_hz": float(freq[-1]), "lines": int(freq.size)}, overwrite=True)
    text = SPEC.read_text(encoding="utf-8")
    text = re.sub(r"(?m)^measured:\n  frequencies: .*\n", "", text)
    text = text.replace("name: S1.1\n", "name: S1.1-synthetic\n", 1)
    text = ("# Synthetic impact test of S1.1 (scripts/example_frf.py): fill in the measured\n"
            "# frequencies with  laminid fit-frf plate.frf.h5 --into plate.yaml\n") + text
    # a plate.yaml that is no longer what this script wrote (fit-frf --into filled in its
    # frequencies, or it was edited) is kept in a backup that overwrites nothing, as
    # fit-frf --into keeps one, before it is written again: a re-run lost it without a word
    spec_path = out / "plate.yaml"
    kept = None
    if spec_path.exists() and spec_path.read_bytes() != text.encode("utf-8"):
        from laminid_cli.frf.into import _next_backup

        kept = _next_backup(spec_path, spec_path.read_bytes())[0]
    spec_path.write_text(text, encoding="utf-8")
    (out / "truth.json").write_text(json.dumps({
        "constants_GPa": TRUTH_GPA, "nu12": TRUTH_NU12,
        "loss_factors": dict(zip(("eta11", "eta22", "eta12", "eta13", "eta23"), ETA)),
        "frequencies_hz": [round(float(f), 4) for f in modes.freq[:n_in]],
        "damping_ratios": [round(float(z), 6) for z in zeta[:n_in]],
        "noise": a.noise, "seed": a.seed, "points": len(hits)}, indent=2) + "\n")
    print(f"{out / 'plate.frf.h5'}: {len(hits)} points, {freq.size} lines to {freq[-1]:.1f} Hz, "
          f"{n_in} modes ({modes.freq[0]:.1f}-{modes.freq[n_in - 1]:.1f} Hz), noise "
          f"{a.noise:g}\n{out / 'plate.yaml'}: S1.1 without its frequencies\n"
          f"{out / 'truth.json'}: what the FRFs were made from")
    if kept is not None:
        print(f"{spec_path}: the one there before (edited, or filled in by fit-frf --into) "
              f"kept as {kept}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
