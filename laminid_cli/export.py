"""Universal File output for other modal tools (issue 12): mode shapes (UFF 55) on the plate
geometry (UFF 15), with the units record (UFF 164). The FRF output (UFF 58) is
:func:`laminid_cli.frf.io.write_frf_uff`.

Written from a result of ``laminid identify``/``batch`` (format "laminid-result"), ``laminid
modes`` ("laminid-modes") or one plate of a joint identification ("laminid-joint-result",
``specimen=``). One file holds, in this order:

- dataset 164, units: SI (code 1: metre, newton, kelvin);
- dataset 15, nodes: the FE mesh nodes, numbered 1..n in mesh order, coordinates x, y in metres
  in the plate's mid-plane (z = 0), global coordinate system 0;
- one dataset 55 per mode: normal-mode data at nodes (model type 1 structural, analysis type 2
  normal mode, data characteristic 2 = 3 DOF translation, specific data type 8 displacement,
  real data): (0, 0, w0) at each node, w0 = transverse displacement of the mass-normalised
  mode in m/sqrt(kg), modal mass 1, the model's natural frequency in Hz, mode number 1..m.
  An identification's result keeps the shapes of the model modes paired with the measured
  ones, in the measured modes' order: each record gets its paired mode's frequency
  (/frequencies/model_mode), and its id1 names the model mode where the two orders differ.

pyuff is imported inside the writer so importing this module stays cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from laminid_cli.errors import LaminidError, OutputExistsError, non_printable

#: result-file formats that carry a mesh and mode shapes
SHAPE_FORMATS = ("laminid-result", "laminid-modes", "laminid-joint-result")


class ExportError(LaminidError):
    """A file cannot be exported (not a result with mode shapes, unknown specimen...)."""


@dataclass(frozen=True)
class PlateShapes:
    """Mode shapes of one plate model, as stored in a result file.

    nodes : (n_nodes, 2) x, y in m; w : (n_nodes, n_modes) transverse displacement of the
    mass-normalised modes, m/sqrt(kg); freq_hz : (n_modes,) the model natural frequency of each
    column of ``w``, Hz; model_mode : (n_modes,) 1-based index of each column's mode among the
    sorted model modes (an identification's pairing: its columns follow the measured modes,
    and a tracked pair that swapped order is not the sorted one)
    """

    specimen: str
    nodes: np.ndarray
    w: np.ndarray
    freq_hz: np.ndarray
    source: str
    model_mode: np.ndarray | None = None


def read_shapes(path, specimen: str | None = None) -> PlateShapes:
    """Mesh nodes and mode shapes of a result file (the one place this module reads results;
    it uses :func:`laminid_cli.results.read_h5`)."""
    from laminid_cli.results import read_h5

    path = Path(path)
    try:
        data = read_h5(path)
    except OSError as exc:
        raise ExportError(f"{path}: not a readable HDF5 file ({exc})") from exc
    fmt = data["@attrs"].get("format")
    if fmt not in SHAPE_FORMATS:
        raise ExportError(f"{path}: no mode shapes in it (format {fmt!r}; expected a result of "
                          "laminid identify/batch/modes)")
    plates = data.get("specimens", {})
    if fmt == "laminid-joint-result":
        names = sorted(k for k in plates if not k.startswith("@"))
        if specimen not in names:
            which = "" if specimen is None else f", none named {specimen!r}"
            raise ExportError(f"{path}: a joint result of {len(names)} plates{which}; choose "
                              f"one with --specimen ({', '.join(names)})")
        data = plates[specimen]
    elif specimen is not None and specimen != data["specimen"]["@attrs"].get("name"):
        raise ExportError(f"{path}: holds specimen {data['specimen']['@attrs'].get('name')!r}, "
                          f"not {specimen!r}")
    try:
        nodes = np.asarray(data["mesh"]["nodes"], dtype=float)
        w = np.asarray(data["modes"]["w"], dtype=float)
        freq = np.asarray(data["modes"]["frequency"], dtype=float)
    except KeyError as exc:
        raise ExportError(f"{path}: dataset {exc} missing (mesh/nodes, modes/w, "
                          "modes/frequency)") from None
    # an identification keeps the shapes of the paired modes only, in the measured modes'
    # order, and /modes/frequency lists every computed mode, sorted: each shape's frequency is
    # that of its paired model mode (/frequencies/model_mode), not the k-th sorted one
    model_mode = (data.get("frequencies") or {}).get("model_mode")
    if model_mode is not None:
        model_mode = np.asarray(model_mode, dtype=int).ravel()
        if model_mode.size != w.shape[1] or model_mode.min(initial=1) < 1 \
                or model_mode.max(initial=1) > freq.size:
            raise ExportError(f"{path}: frequencies/model_mode ({model_mode.size} modes) does "
                              f"not match modes/w ({w.shape[1]} shapes) and modes/frequency "
                              f"({freq.size} modes)")
        freq = freq[model_mode - 1]
    elif freq.size < w.shape[1]:
        raise ExportError(f"{path}: modes/frequency has {freq.size} modes for {w.shape[1]} "
                          "shapes in modes/w")
    else:
        freq = freq[:w.shape[1]]
    _check_shapes(path, nodes, w, freq)
    name = specimen or str(data["specimen"]["@attrs"].get("name", path.stem))
    bad = non_printable(name)
    if bad is not None:
        raise ExportError(f"{path}: the specimen's name {name!r} (attribute 'name' of "
                          f"/specimen): {bad} in it; remove it")
    return PlateShapes(specimen=name, nodes=nodes, w=w, freq_hz=freq, source=str(path),
                       model_mode=model_mode)


def _check_shapes(path, nodes: np.ndarray, w: np.ndarray, freq: np.ndarray) -> None:
    """ExportError naming the file and the dataset where the mesh or the shapes cannot be
    what laminid wrote (a damaged or edited file): no node, coordinates or shapes not
    finite, shapes of another node count, a frequency not finite. A UFF of 0 nodes, or
    of 'inf' and 'nan' in its records, was written with exit 0."""
    if nodes.ndim != 2 or nodes.shape[0] == 0 or nodes.shape[1] != 2 \
            or not np.all(np.isfinite(nodes)):
        raise ExportError(f"{path}: dataset mesh/nodes holds "
                          f"{' x '.join(map(str, nodes.shape))} values, not the finite x, y "
                          "of at least one node; the file is damaged or was edited")
    if w.ndim != 2 or w.shape[0] != nodes.shape[0] or not np.all(np.isfinite(w)):
        raise ExportError(f"{path}: dataset modes/w holds {' x '.join(map(str, w.shape))} "
                          f"values, not finite mode shapes at the {nodes.shape[0]} nodes; the "
                          "file is damaged or was edited")
    if not np.all(np.isfinite(freq)):
        raise ExportError(f"{path}: dataset modes/frequency holds NaN or inf; the file is "
                          "damaged or was edited")


def write_shapes_uff(path, shapes: PlateShapes, *, overwrite: bool = False) -> Path:
    """Write UFF 164 + 15 + 55 (see the module docstring); atomic, no silent overwrite."""
    import pyuff

    from laminid_cli.frf.io import UFF_SI_UNITS, write_uff_sets

    path = Path(path)
    if path.exists() and not overwrite:
        raise OutputExistsError(f"{path}: file exists; use --force to overwrite it")
    n = shapes.nodes.shape[0]
    node_nums = np.arange(1, n + 1)
    sets = [
        pyuff.prepare_164(**UFF_SI_UNITS),
        pyuff.prepare_15(node_nums=node_nums, def_cs=np.zeros(n, int), disp_cs=np.zeros(n, int),
                         color=np.ones(n, int), x=shapes.nodes[:, 0], y=shapes.nodes[:, 1],
                         z=np.zeros(n)),
    ]
    zeros = np.zeros(n)
    for k in range(shapes.w.shape[1]):
        sets.append(pyuff.prepare_55(
            id1=f"laminid mode {k + 1}: {shapes.freq_hz[k]:.6g} Hz"
                + ("" if shapes.model_mode is None or shapes.model_mode[k] == k + 1
                   else f" (model mode {shapes.model_mode[k]})"),
            id2=f"specimen {shapes.specimen}",
            id3="w0 of the mass-normalised mode, m/sqrt(kg)",
            id4=f"from {Path(shapes.source).name}", id5="NONE",
            model_type=1, analysis_type=2, data_ch=2, spec_data_type=8, data_type=2,
            n_data_per_node=3, r1=zeros, r2=zeros, r3=shapes.w[:, k], load_case=1,
            mode_n=k + 1, freq=float(shapes.freq_hz[k]), modal_m=1.0, modal_damp_vis=0.0,
            modal_damp_his=0.0, node_nums=node_nums))
    return write_uff_sets(path, sets, ExportError)
