"""HDF5 result files: self-describing, units on every dataset, atomic (README: "Reading a
result file without laminid").

Every file is written to a temporary name in the target folder and renamed over the target
only when complete, so an interrupted run never leaves a half-written result.

Common layout::

    /                     attrs: format ("laminid-modes" | "laminid-result"), schema_version,
                                 laminid_version, created (ISO 8601 UTC), command
    /specimen             attrs: name, path (as given), folder (absolute), a, b, h (m),
                          mass (kg), boundary;
                          dataset yaml: the specimen file verbatim
    /mesh                 nodes (n_nodes, 2) m, elements (n_el, 8), attrs nx, ny
    /materials/<key>      attr name (the material's real name, UTF-8); E1, E2, G12, G13, G23
                          (Pa), nu12 (1), density (kg/m^3). <key> is :func:`safe_keys` of the
                          names (ASCII [A-Za-z0-9_.-], "_" elsewhere, de-duplicated): group
                          keys stay readable in h5ls/h5dump; readers take the name attribute.
                          With an uncertainty assessment each constant's dataset has attrs
                          verdict, lower, upper (NaN: no interval), confidence, as
                          /uncertainty gives them (a fixed one: FIXED_VERDICT or
                          UNDETERMINED_FIXED_VERDICT); /global_properties/<k> likewise
                          (annotate_doubt)
    /frequencies          model, measured (Hz; NaN = not measured), residual_percent, weight
    /modes                w (n_nodes, n_modes) transverse displacement of the mass-normalised
                          modes (m/sqrt(kg)); phi (n_dofs, n_modes) all DOFs; dofs (n_dofs,)
    /global_properties    Ex, Ey, Gxy, Gxz, Gyz (Pa), nu_xy, nu_yx (1)

Identification results ("laminid-result") add: root attrs converged, optimizer_status (the
nlopt outcome; ``status`` in schema version 1), objective, evaluations, time_s, optimizer, solver
(reduced | full), factorization (cholmod | banded: how K - sigma M was factorised; the answers
agree to round-off), equations (all | bending: a symmetric laminate's bending equations alone,
whose modes are the plate's bending modes to round-off; /modes/dofs then lists those
equations); /materials/<name> attrs parametrization, free; /initial/<name>
(the starting constants, same keys); /frequencies/model_mode (pairing) and attrs rms_residual_percent;
/history (evaluation, objective, rms_residual_percent, x, constants, error_bound per evaluation;
error_bound: 0 full model, NaN a reduced-model prediction, else the bound where enriched);
/sensitivities (dlnf_dlnP: d ln f_i / d ln P_j, dlambda_dx); /swaps and /warnings (strings);
/summary_json (what ``identify --json`` printed when the file was written, JSON text; read by
``laminid show``; the typed datasets stay the reference for other programs).

Status (schema version 2; laminid_cli.status)::

    /                     attrs: status ("ok" | "check")
    /status               codes, texts (UTF-8 strings, same length, empty when ok): the
                          reasons, codes not_converged | at_bound | undetermined |
                          fixed_rejected | poor_fit | coarse_mesh | implausible |
                          modes_swapped
                          (laminid_cli.status.CODES)

JSON (``--json``, batch summary rows): top-level ``status``, ``reasons`` ([{code, text}]) and
``optimizer_status``.

With an uncertainty assessment (``laminid identify`` always makes one) they also hold::

    /uncertainty          attrs: confidence, quantile, scaling (requested), scale_used,
                                 variance_factor, s2, chi2, dof, rows, condition_number,
                                 sigma_source, well_determined, weak, max_rel_interval,
                                 flagged, fixed, fixed_undetermined, notes (strings joined by ';'),
                                 verdict_from_monte_carlo (the labels whose verdict the Monte
                                 Carlo range set, marked "(Monte Carlo)" in verdict)
                          labels ("material.constant", the free constants), value, std,
                          std_stated, half_width, lower, upper (Pa; nu12: 1), rel_half_width,
                          verdict (strings), correlation (p, p), covariance (p, p),
                          scale ("log" | "linear" per label: lower/upper are value *
                          exp(-/+ q std/value) for moduli, value -/+ q std clipped to
                          [-nu_max, nu_max] for nu12), at_bound (bool per label; its
                          lower/upper are NaN), bound_text ("" or the one-sided statement,
                          e.g. "at its bound — not identified: G13 <= 0.0001 E1 (0.0154 GPa)"),
                          bound_side ("" | "lower" | "upper": the data push the constant below /
                          above its limit) and bound_limit (that limit, Pa; nu12: 1; NaN when
                          not at a bound);
                          attr chi2_limit_99;
                          weakest_labels/weakest_coefficients (weakest combination)
    /uncertainty/frequency_sigma/<key>   attr name (the specimen name); sigma (Hz per measured
                          mode, NaN = not measured), attr source (per mode: file | relative),
                          sigma_rel, note (how the file's sigmas were made:
                          measured.sigma_source, e.g. by fit-frf)
    /uncertainty/monte_carlo   samples (n_converged, p), mean, std, lower, upper (quantiles
                          (1 -/+ confidence)/2 of the samples), linearized_std (the
                          linearised std; the name keeps its z: programs read it), ratio (std /
                          (linearized_std sqrt(nu / (nu - 2))), nu = attr variance_dof);
                          at_lower_bound, at_upper_bound (trials whose answer has the constant
                          on a limit of the search), lower_at_bound, upper_at_bound (0/1: that
                          end of the range is set by such trials: the search's end, not the
                          data's); inner_lower, inner_upper (the order statistics inside the
                          range's quantiles with probability >= attr evidence_level each: the
                          width the Monte Carlo verdicts use); attrs trials, converged,
                          sigma_factor, seed, jobs, evidence_level,
                          prior_sigma (the prior rows' noise: a prior of weight wp drawn with relative sd prior_sigma / sqrt(wp); 0: no prior),
                          variance_dof (> 0: each trial drew its variance factor, s2 nu / X,
                          X chi-square with nu = variance_dof: Student t as the intervals;
                          0: the stated sigma; absent in older files);
                          with --fix-undetermined: attr fixed_drawn (labels, comma-separated:
                          the fixed values each trial drew from their spread before fixing;
                          "" or absent: the trials held every fixed value, as in older
                          files), fixed_held (fixed on a limit of the search: held),
                          fixed_clipped (trials whose draw was shortened to the search's
                          range) and fixed_samples (n_converged, k; Pa, nu12: 1), the values
                          drawn
    /uncertainty/monte_carlo_rel_half_width, monte_carlo_rel_half_width_lower   per label (with
                          a Monte Carlo): its range's half-width / |value|, and the one it has
                          for sure (what its verdicts use)
    /uncertainty/rel_half_width_given_fixed  per label, with --fix-undetermined: the 95 %
                          half-width / |value| given the fixed values alone (rel_half_width,
                          std, lower, upper and covariance count the spread the fixed values
                          had before fixing: laminid_cli.uncertainty.counting_fixed_spread);
                          attrs spread_counted, spread_not_counted (labels, comma-separated)
    /uncertainty/profile_bound, profile_far, profile_delta_chi2_far (attr threshold),
                          profile_text   per label, of a constant at its bound: where the fit
                          rejects it (profile of the fit; NaN: nowhere within the search up to
                          profile_far), the other end of its scan (NaN where no profile could
                          be made: it reached no stated end), and the statement
                          (laminid_cli.uncertainty.Profile)
    /uncertainty/fixed_ranges  labels, low, high, ratio_to_half_width, text: each constant
                          --fix-undetermined fixed on a limit of the search, the others
                          identified again with it at the search's two ends
                          (laminid_cli.uncertainty.FixedRange)
    /uncertainty/fixed_check  attrs of the test whether the modes reject the values
                          --fix-undetermined fixed, taken together (labels, values, k,
                          chi2_before, chi2, test "chi2" | "F", variance_factor_before,
                          statistic, limit, confidence, rejected, worst, moved_in_half_widths,
                          release, release_chi2, release_ok, text;
                          laminid_cli.uncertainty.FixedCheck)
    /uncertainty/quantile, effective_dof  per label, with --fix-undetermined's spread
                          counted: each interval's quantile, Student t with the Welch-
                          Satterthwaite degrees of freedom of the final run's noise and the
                          spread (attr spread_dof: the run before fixing's; inf on the stated
                          sigma)
    /uncertainty/spread_counted  labels, covariance (of the fixed values counted),
                          cross_covariance (free constants x those)
    /uncertainty/before_fixing  labels, rel_half_width, verdict of the first run when
                          --fix-undetermined fixed constants
    /uncertainty/fixed_undetermined  labels, rel_half_width, verdict, run: each constant fixed
                          by --fix-undetermined with the width of the run that had it fixed
    /global_properties_uncertainty  keys (Ex, Ey, Gxy, Gxz, Gyz, nu_xy, nu_yx), value, std,
                          lower, upper (Pa; nu: 1; NaN: not identified), rel_half_width, verdict
                          (laminid_cli.global_uncertainty; in /specimens/<key> of a joint one);
                          with --monte-carlo: attr verdict_from_monte_carlo (keys, comma-
                          separated: the verdicts marked "(Monte Carlo)"),
                          monte_carlo_rel_half_width, monte_carlo_rel_half_width_lower (per
                          key, as /uncertainty's), and monte_carlo/ mean, std, lower, upper,
                          inner_lower, inner_upper, linearized_std, ratio, trials_at_bound,
                          lower_at_bound, upper_at_bound (per key: the property at each
                          trial's constants, as /uncertainty/monte_carlo; NaN: the trials do
                          not move it), attr evidence_level

With measured damping (``measured.damping`` or an FRF file; laminid_cli.damping)::

    /damping              attrs: method ("modal strain energy"), terms ("11,22,12,13,23"), s2,
                                 chi2, dof, confidence, quantile, scaling, scale_used,
                                 sigma_source, fixed ("material.eta13=0.01,..."), notes
                          labels ("material.eta11", ... the free loss factors), value, std,
                          lower, upper (1; NaN: held at 0, no interval; files before
                          wrote 0 .. a one-sided upper there), rel_half_width (inf: held at
                          0), verdict
                          (strings), at_bound (bool), bound_side ("lower" or ""), bound_limit
                          (0, NaN when not at it);
                          measured_loss_factor (2 zeta), measured_sigma, model_loss_factor,
                          used (bool) per measured mode (NaN where not measured);
                          energy_shares (n_modes, n_materials * 5) with attr labels
                          ("material.k" columns, k = 11, 22, 12, 13, 23);
                          with --monte-carlo: attr verdict_from_monte_carlo (labels, comma-
                          separated) and monte_carlo_rel_half_width,
                          monte_carlo_rel_half_width_lower (1, per label; the width for sure
                          that the verdicts use; NaN: too few trials)
    /damping/monte_carlo  with --monte-carlo (each trial refitted the loss factors at its own
                          constants, laminid_cli.damping.monte_carlo_loss_factors): attrs
                          trials, refits, sigma_factor, seed, confidence, evidence_level,
                          time_s, stream; samples (n_refits, p), mean, std, lower, upper,
                          inner_lower, inner_upper, linearized_std (1, per label of /damping),
                          trials_at_zero, lower_at_zero (0/1: that end is the bound eta >= 0)
                          (files before it have neither: the reader gives None)

With ``identify --mesh-check`` (laminid_cli.meshcheck; files without it have none: the reader
gives None)::

    /mesh_check           attrs: nx, ny (this mesh), fine_nx, fine_ny (twice as fine), limit
                          (0.3: a shift beyond it, in half-widths, makes the mesh too coarse),
                          too_coarse (labels, comma-separated), text (the warning or ""),
                          time_s;
                          per checked measured mode: measured_mode, model_mode, fine_mode
                          (1-based), mac (of w0 at the common nodes), freq_hz, fine_hz (Hz:
                          both models at the identified constants), change_percent,
                          change_sigma (in units of the mode's frequency sigma);
                          per free constant: labels ("material.constant"), shift (Pa; nu12:
                          1; the first-order change on the fine mesh, NaN at a bound),
                          shift_percent (%), shift_half_width (in units of its 95 % half-width)

Joint identifications ("laminid-joint-result", several plates sharing materials): root attrs as
above plus specimens (names, comma-separated); /materials/<name> and /initial/<name> once
(no density: it is per plate); /history and /uncertainty of the joint problem; and each plate's
complete single-plate layout (specimen, mesh, materials with its density, initial, frequencies,
modes, history, sensitivities, global_properties, swaps, warnings) under /specimens/<key>/
(attr name: the specimen name; <key> as for materials).

Strings (attributes and string datasets) are UTF-8 variable-length strings.
schema_version 2 (this round): safe group keys with a ``name`` attribute (schema 1 used the name
with "/" replaced by the look-alike U+2215); the result status and log-space intervals of
SCHEMA.md are added by their own writers. The typed reader
of these files is :func:`laminid_cli.resultfile.read_result`.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import re

import numpy as np

from laminid_cli import __version__
from laminid_cli.atomic import atomic_path
from laminid_cli.material import CONSTANT_UNITS, GLOBAL_UNITS

SCHEMA_VERSION = 2


def safe_keys(names) -> list[str]:
    """HDF5 group keys for names (material, specimen): anything outside ``[A-Za-z0-9_.-]``
    becomes "_", "." / ".." / "" get a leading "_", duplicates get "_2", "_3"... The real name
    goes into the group's ``name`` attribute."""
    keys: list[str] = []
    for name in names:
        key = re.sub(r"[^A-Za-z0-9_.-]", "_", str(name))
        if key in ("", ".", ".."):
            key = "_" + key
        base, k = key, 1
        while key in keys:
            k += 1
            key = f"{base}_{k}"
        keys.append(key)
    return keys


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


@contextlib.contextmanager
def atomic_h5(path, fmt: str, command: str = ""):
    """Open a new HDF5 file for writing; it appears at ``path`` only once complete."""
    import h5py

    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = fmt
        f.attrs["schema_version"] = SCHEMA_VERSION
        f.attrs["laminid_version"] = __version__
        f.attrs["created"] = now_iso()
        f.attrs["command"] = command
        yield f


#: the description of the Monte Carlo groups' ``linearized_std``: the name keeps its z (files
#: since the Monte Carlo have it and programs read it by name; every text says "linearised")
LINEARISED_STD = ("the linearised standard error of each label (the std of its interval), "
                  "to compare the trials' std with; the dataset's name keeps the spelling "
                  "'linearized' of the files programs already read")


def put(group, name: str, value, units: str, *, compression: str | None = None, **attrs):
    """Create a dataset with a ``units`` attribute (and any extra attributes)."""
    d = group.create_dataset(name, data=value, compression=compression)
    d.attrs["units"] = units
    for k, v in attrs.items():
        d.attrs[k] = v
    return d


#: the dataset holding what ``laminid identify --json`` printed when the file was written
SUMMARY_JSON = "summary_json"


def put_summary(f, summary: dict) -> None:
    """/summary_json: the run's summary as ``identify --json`` printed it (JSON text), so that
    ``laminid show`` prints the file as identify did; the typed datasets stay the reference
    for other programs."""
    import json

    from laminid_cli.jsonsafe import json_safe

    d = f.create_dataset(SUMMARY_JSON, data=json.dumps(json_safe(summary),
                                                       separators=(",", ":")))
    d.attrs["description"] = ("what 'laminid identify --json' printed when this file was "
                              "written (JSON, SI units); read by 'laminid show'")


def put_error_bound(h, history: dict) -> None:
    """/history/error_bound: per evaluation, the relative eigenvalue error bound against the
    full FE model (0: full model; NaN: a reduced-model prediction of unknown error)."""
    if "error_bound" in history:
        put(h, "error_bound", np.asarray(history["error_bound"], float), "1",
            description="relative eigenvalue error bound of the evaluation against the full FE "
            "model: 0 for a full-model evaluation, the bound where the reduced basis was "
            "enriched at that point, NaN for a reduced-model prediction (trust-region trial "
            "point) whose error is not known")


def write_specimen(f, specimen) -> None:
    import h5py

    g = f.create_group("specimen")
    g.attrs["name"] = specimen.name
    g.attrs["path"] = str(specimen.path)
    # the folder it lies in, absolute: "path" is as the command was given it (relative to the
    # folder it ran in), from which a report made elsewhere could not find its frf_file
    from pathlib import Path

    if specimen.path and Path(specimen.path).is_file():
        g.attrs["folder"] = str(Path(specimen.path).resolve().parent)
    g.attrs["boundary"] = specimen.boundary
    g.attrs["description"] = specimen.description or ""
    g.create_dataset("yaml", data=specimen.source_text, dtype=h5py.string_dtype())
    put(g, "a", specimen.a, "m")
    put(g, "b", specimen.b, "m")
    put(g, "h", specimen.h, "m")
    put(g, "mass", np.nan if specimen.mass is None else specimen.mass, "kg")


def write_mesh(f, plate) -> None:
    g = f.create_group("mesh")
    put(g, "nodes", plate.mesh.nodes, "m")
    put(g, "elements", plate.mesh.elements, "1", description="8-node serendipity, node order "
        "corners counter-clockwise then mid-sides")
    g.attrs["nx"], g.attrs["ny"] = plate.mesh.nx, plate.mesh.ny


def write_materials(f, names, constants, densities: dict, group: str = "materials") -> None:
    g = f.create_group(group)
    for key, name, c in zip(safe_keys(names), names, constants):
        gm = g.create_group(key)
        gm.attrs["name"] = name
        for key, value in c.as_dict().items():
            put(gm, key, value, CONSTANT_UNITS[key])
        if name in densities:
            put(gm, "density", densities[name], "kg/m^3")


def write_frequencies(f, model_hz, measured_hz, weight, residual) -> None:
    g = f.create_group("frequencies")
    put(g, "model", model_hz, "Hz")
    put(g, "measured", measured_hz, "Hz", description="NaN where the mode was not measured")
    put(g, "weight", weight, "1")
    put(g, "residual_percent", residual, "%", description="(measured - model)/measured*100, "
        "paper Eq. 28")


def write_modes(f, plate, modes) -> None:
    g = f.create_group("modes")
    put(g, "frequency", modes.freq, "Hz")
    put(g, "w", plate.w_shape(modes.phi), "m/sqrt(kg)",
        description="transverse displacement w0 of the mass-normalised modes at the mesh nodes")
    put(g, "phi", modes.phi, "m/sqrt(kg)", compression="gzip",
        description="all retained DOFs of the mass-normalised modes; DOF = node*9 + variable "
        "(u0, v0, w0, psi_x, psi_y, U, V, Psi_x, Psi_y)")
    put(g, "dofs", plate.dofs, "1")


def write_global_properties(f, props: dict, group: str = "global_properties") -> None:
    """Appendix A properties (name -> value, SI) with their units."""
    g = f.create_group(group)
    for key, value in props.items():
        put(g, key, value, GLOBAL_UNITS[key])


def read_h5(path) -> dict:
    """Read a laminid result/modes file into nested dicts of numpy values (for tests, report)."""
    import h5py

    def walk(node):
        out = {"@attrs": {k: _plain(v) for k, v in node.attrs.items()}}
        for key, item in node.items():
            if isinstance(item, h5py.Group):
                out[key] = walk(item)
            else:
                value = item[()]
                out[key] = value.decode() if isinstance(value, bytes) else value
        return out

    with h5py.File(path, "r") as f:
        from laminid_cli.resultfile import check_declared_sizes

        check_declared_sizes(f, path, what="the file")     # before reading it whole
        return walk(f)


def _plain(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def write_modes_file(path, fm, modes, summary: dict) -> None:
    """Write the result of ``laminid modes`` (format "laminid-modes")."""
    with atomic_h5(path, "laminid-modes", command="laminid modes") as f:
        write_specimen(f, fm.specimen)
        write_mesh(f, fm.plate)
        write_materials(f, fm.material_names, fm.initial_constants, fm.specimen.densities)
        fr = summary["frequencies"]
        write_frequencies(f, fr["model"], fr["measured"], fr["weight"], fr["residual_percent"])
        write_modes(f, fm.plate, modes)
        write_global_properties(f, summary["global_properties"])


def run_fields(r) -> dict:
    """Optimisation outcome shared by single and joint summaries."""
    return {
        "objective": r.objective,
        "iterations": r.evaluations,
        "evaluations": r.evaluations,
        "converged": r.converged,
        "optimizer_status": r.status,
        "optimizer": {"slsqp": "LD_SLSQP", "mma": "LD_MMA"}[r.options.optimizer],
        "solver": r.options.solver,
        "factorization": getattr(r, "factorization", ""),
        "equations": getattr(r, "equations", "all"),
        "work": dict(getattr(r, "work", {}) or {}),
        "time_s": r.time_s,
        "swaps": list(r.swaps),
        "warnings": list(r.warnings),
    }


def write_run_attrs(f, r) -> None:
    """Root attributes of a result file: the optimisation outcome (as :func:`run_fields`)."""
    run = run_fields(r)
    for key in ("converged", "optimizer_status", "objective", "evaluations", "time_s",
                "optimizer", "solver", "factorization", "equations"):
        f.attrs[key] = run[key]


def write_status(f, status) -> None:
    """Root attribute ``status`` and group /status (codes, texts) of a
    :class:`laminid_cli.status.ResultStatus`."""
    import h5py

    f.attrs["status"] = status.status
    g = f.create_group("status")
    dt = h5py.string_dtype(encoding="utf-8")
    for key, values in (("codes", status.codes), ("texts", status.texts)):
        g.create_dataset(key, data=np.array(list(values), dtype=object), dtype=dt)


def status_of(r, assessment=None, damping=None, mesh_check=None):
    """The ResultStatus of a result: the assessment's when given, else from ``r`` alone; with
    the ply loss factors' fit ``damping`` when there is one, and the MeshCheck of
    ``identify --mesh-check``."""
    from laminid_cli.status import result_status

    if assessment is not None:
        return result_status(assessment.result, assessment.uncertainty, damping, mesh_check)
    return result_status(r, damping=damping)


def identification_summary(r) -> dict:
    """Everything ``laminid identify`` reports, as plain data (SI units, frequencies in Hz).

    ``r`` is a :class:`laminid_cli.identify.Identification`.
    """
    spec = r.specimen
    ref = spec.reference or {}
    return {
        "specimen": {"name": spec.name, "path": str(spec.path), "description": spec.description,
                     "a": spec.a, "b": spec.b, "h": spec.h, "mass": spec.mass,
                     "n_plies": len(spec.plies), "boundary": spec.boundary},
        "materials": {n: c.as_dict() for n, c in zip(r.material_names, r.constants)},
        "initial": {n: c.as_dict() for n, c in zip(r.material_names, r.initial)},
        "free": {n: list(v) for n, v in r.free.items()},
        "parametrization": dict(r.parametrization),
        # a value as the specimen gives it: a number, or [low, high] for a range
        "reference": {"source": ref.get("source", ""), "materials": ref.get("materials", {}),
                      "global": ref.get("global", {})},
        "frequencies": {"measured": r.measured_hz, "model": r.model_hz,
                        "residual_percent": r.residual_percent, "weight": r.weight,
                        "model_mode": r.pairing + 1,
                        # relative eigenvalue error bound against the full FE model (0: solved)
                        "error_bound": r.error_bound},
        "rms_residual_percent": r.rms_residual_percent,
        "initial_rms_residual_percent": r.initial_rms_residual_percent,
        "global_properties": r.global_properties,
        **run_fields(r),
    }


def write_identification_file(path, fm, r, summary: dict, command: str = "laminid identify",
                              assessment=None, damping=None, status=None,
                              attrs: dict | None = None, mesh_check=None) -> None:
    """Write an identification result (format "laminid-result", layout in the module docstring
    plus /history, /sensitivities and the initial constants; /uncertainty when ``assessment``,
    a :class:`laminid_cli.uncertainty.Assessment`, is given; /damping when ``damping``, a
    :class:`laminid_cli.damping.DampingFit`, is given). ``status``: the ResultStatus when the
    caller has it already (else :func:`status_of`); ``attrs``: extra root attributes;
    ``mesh_check``: the :class:`laminid_cli.meshcheck.MeshCheck` of ``--mesh-check``
    (/mesh_check)."""
    with atomic_h5(path, "laminid-result", command=command) as f:
        _write_identification(f, fm, r, summary)
        write_status(f, status if status is not None
                     else status_of(r, assessment, damping, mesh_check))
        if mesh_check is not None:
            write_mesh_check(f, mesh_check)
        for key, value in (attrs or {}).items():
            f.attrs[key] = value
        if assessment is not None:
            write_uncertainty(f, assessment, [fm.specimen.name])
            if summary.get("global_uncertainty"):
                write_global_uncertainty(f, summary["global_uncertainty"])
            annotate_doubt(f, assessment)
        if damping is not None:
            write_damping(f, damping)
        put_summary(f, summary)


def write_mesh_check(f, mc) -> None:
    """Write a :class:`laminid_cli.meshcheck.MeshCheck` as /mesh_check (module docstring)."""
    g = f.create_group("mesh_check")
    g.attrs["nx"], g.attrs["ny"] = mc.mesh
    g.attrs["fine_nx"], g.attrs["fine_ny"] = mc.fine_mesh
    g.attrs["limit"] = mc.limit
    g.attrs["too_coarse"] = ",".join(mc.too_coarse)
    g.attrs["text"] = mc.text
    g.attrs["time_s"] = mc.time_s
    for key in ("measured_mode", "model_mode", "fine_mode"):
        put(g, key, getattr(mc, key), "1")
    put(g, "mac", mc.mac, "1", description="MAC of w0 at the common nodes")
    put(g, "freq_hz", mc.freq_hz, "Hz", description="this mesh's model at the identified "
        "constants")
    put(g, "fine_hz", mc.fine_hz, "Hz", description="the fine mesh's model, same constants")
    put(g, "change_percent", mc.change_percent, "%")
    put(g, "change_sigma", mc.change_sigma, "1",
        description="frequency change in units of the mode's frequency sigma")
    data, dt = _strings(mc.labels)
    g.create_dataset("labels", data=data, dtype=dt)
    put(g, "shift", mc.shift, "Pa (nu12: 1)",
        description="first-order change of the constants on the fine mesh")
    put(g, "shift_percent", mc.shift_percent, "%")
    put(g, "shift_half_width", mc.shift_half_width, "1",
        description="the shift in units of the constant's 95 % half-width")


def _write_material_settings(f, r) -> None:
    """Parametrization and free constants as attributes of each /materials group."""
    for key, name in zip(safe_keys(r.material_names), r.material_names):
        g = f["materials"][key]
        g.attrs["parametrization"] = r.parametrization[name]
        g.attrs["free"] = ",".join(r.free[name])


def _write_identification(f, fm, r, summary: dict) -> None:
    """The single-plate layout into a file or group ``f``."""
    import h5py

    write_run_attrs(f, r)
    write_specimen(f, fm.specimen)
    write_mesh(f, fm.plate)
    write_materials(f, r.material_names, r.constants, fm.specimen.densities)
    _write_material_settings(f, r)
    write_materials(f, r.material_names, r.initial, {}, group="initial")
    write_frequencies(f, r.model_hz, r.measured_hz, r.weight, r.residual_percent)
    put(f["frequencies"], "model_mode", r.pairing + 1, "1",
        description="1-based index of the sorted model mode paired with each measured one")
    f["frequencies"].attrs["rms_residual_percent"] = r.rms_residual_percent
    f["frequencies"].attrs["initial_rms_residual_percent"] = r.initial_rms_residual_percent
    g = f.create_group("modes")
    put(g, "frequency", r.modes.freq, "Hz", description="all computed model modes, sorted")
    put(g, "w", fm.plate.w_shape(r.phi_paired), "m/sqrt(kg)",
        description="transverse displacement w0 at the mesh nodes of the model modes paired "
        "with the measured ones (mass-normalised)")
    put(g, "phi", r.phi_paired, "m/sqrt(kg)", compression="gzip",
        description="the paired modes at the model's equations (dofs: node*9 + variable; "
        "with root attribute equations = bending, a symmetric laminate's membrane variables, "
        "zero in its bending modes, are left out)")
    put(g, "dofs", fm.plate.dofs, "1")
    h = f.create_group("history")
    for key, unit in (("evaluation", "1"), ("objective", "1"), ("rms_residual_percent", "%")):
        put(h, key, r.history[key], unit)
    put_error_bound(h, r.history)
    put(h, "x", r.history["x"], "1", labels=",".join(r.variable_labels))
    labels = [f"{n}.{k}" for n in r.material_names for k in ("E1", "E2", "G12", "G13", "G23", "nu12")]
    put(h, "constants", r.history["constants"], "Pa (nu12: 1)", labels=",".join(labels))
    s = f.create_group("sensitivities")
    put(s, "dlnf_dlnP", r.sensitivity, "1", labels=",".join(r.sensitivity_labels),
        description="normalised sensitivity d ln f_i / d ln P_j of each measured mode to "
        "each constant at the optimum")
    put(s, "dlambda_dx", r.dlam_dx, "rad^2/s^2", labels=",".join(r.variable_labels),
        description="eigenvalue derivatives w.r.t. the design variables (paper Eq. 26)")
    write_global_properties(f, r.global_properties)
    str_dt = h5py.string_dtype()
    f.create_dataset("swaps", data=np.array(list(r.swaps), dtype=object), dtype=str_dt)
    f.create_dataset("warnings", data=np.array(list(r.warnings), dtype=object), dtype=str_dt)


def _strings(values):
    import h5py

    return np.array([str(v) for v in values], dtype=object), h5py.string_dtype(encoding="utf-8")


def write_uncertainty(f, a, plate_names) -> None:
    """Write an Assessment's uncertainty as /uncertainty (layout in the module docstring)."""
    u = a.uncertainty
    g = f.create_group("uncertainty")
    for key, value in (("confidence", u.confidence), ("quantile", u.quantile),
                       ("scaling", u.scaling), ("scale_used", u.scale_used),
                       ("variance_factor", u.variance_factor), ("s2", u.s2), ("chi2", u.chi2),
                       ("dof", u.dof), ("rows", u.n_rows), ("condition_number", u.condition),
                       ("sigma_source", u.sigma_source),
                       ("well_determined", u.thresholds["well_determined"]),
                       ("weak", u.thresholds["weak"]),
                       ("max_rel_interval", u.thresholds["max_rel_interval"]),
                       ("flagged", ",".join(u.flagged)), ("fixed", ",".join(u.fixed)),
                       ("verdict_from_monte_carlo", ",".join(u.verdict_from_monte_carlo)),
                       ("fixed_undetermined", ",".join(a.fixed_undetermined)),
                       ("kept_free", "; ".join(f"{k}: {v}" for k, v in a.kept_free.items())),
                       ("notes", "; ".join(u.notes))):
        g.attrs[key] = value
    data, dt = _strings(u.labels)
    g.create_dataset("labels", data=data, dtype=dt)
    unit = "Pa (nu12: 1)"
    for key in ("value", "std", "std_stated", "half_width", "lower", "upper"):
        put(g, key, getattr(u, key), unit)
    put(g, "rel_half_width", u.rel_half_width, "1",
        description="95 % half-width / |value|")
    data, dt = _strings(u.verdict)
    g.create_dataset("verdict", data=data, dtype=dt)
    data, dt = _strings(u.scale)
    g.create_dataset("scale", data=data, dtype=dt)
    put(g, "at_bound", np.asarray(u.at_bound, bool), "1",
        description="the constant ended on a limit of the search: not identified, no interval")
    data, dt = _strings(u.bound_text)
    g.create_dataset("bound_text", data=data, dtype=dt)
    p = len(u.labels)
    data, dt = _strings(u.bound_side or ("",) * p)
    g.create_dataset("bound_side", data=data, dtype=dt)
    put(g, "bound_limit", u.bound_limit if u.bound_limit is not None else np.full(p, np.nan),
        unit, description="of a constant at its bound: the limit of the search it ended on "
        "(the data push it below a lower limit, above an upper one; bound_side); NaN: not at "
        "a bound")
    if u.mc_rel_half_width is not None:
        put(g, "monte_carlo_rel_half_width", u.mc_rel_half_width, "1",
            description="the Monte Carlo range's half-width / |value|")
    if u.mc_rel_half_width_lower is not None:
        put(g, "monte_carlo_rel_half_width_lower", u.mc_rel_half_width_lower, "1",
            description="the half-width / |value| the Monte Carlo range has for sure "
            "(monte_carlo/@evidence_level): the width its verdicts use; NaN: too few trials")
    if u.profiles:
        put(g, "profile_bound", np.array([u.profiles[lab].bound if lab in u.profiles
                                          else np.nan for lab in u.labels]), unit,
            description="of a constant at its bound: where the fit rejects it at the "
            "intervals' level (profile: the others identified again with it held there); NaN: "
            "not at a bound, or the fit does not reject it within the search (profile_text)")
        put(g, "profile_far", np.array([u.profiles[lab].far if lab in u.profiles else np.nan
                                        for lab in u.labels]), unit,
            description="the other end of the profile's scan (where a flat profile stops); "
            "NaN: not at a bound, or no profile could be made (profile_text says why; its "
            "scan reached no stated end)")
        put(g, "profile_delta_chi2_far", np.array(
            [u.profiles[lab].delta_far if lab in u.profiles else np.nan for lab in u.labels]),
            "1", description="rise of chi2 (scaled as the intervals) at profile_far; "
            "threshold q^2 in the attribute; NaN where profile_far is")
        g["profile_delta_chi2_far"].attrs["threshold"] = float(u.quantile) ** 2
        data, dt = _strings([u.profiles[lab].text if lab in u.profiles else ""
                             for lab in u.labels])
        g.create_dataset("profile_text", data=data, dtype=dt)
    if u.rel_half_width_given_fixed is not None:
        put(g, "rel_half_width_given_fixed", u.rel_half_width_given_fixed, "1",
            description="95 % half-width / |value| given the values --fix-undetermined fixed "
            "(rel_half_width counts their spread before fixing: attr spread_counted)")
    if getattr(u, "quantile_per_label", None) is not None:
        put(g, "quantile", u.quantile_per_label, "1",
            description="the quantile of each interval counting the fixed values' spread: "
            "Student t with effective_dof degrees of freedom (Welch-Satterthwaite of the "
            "final run's noise and the spread; attr spread_dof, inf: the stated sigma)")
        put(g, "effective_dof", u.effective_dof, "1")
        g.attrs["spread_dof"] = float(u.spread_dof)
    if u.spread_counted:
        data, dt = _strings(u.spread_counted)
        gs = g.create_group("spread_counted")
        gs.create_dataset("labels", data=data, dtype=dt)
        put(gs, "covariance", u.spread_covariance, "Pa^2 (nu12: Pa, 1)",
            description="covariance of the fixed values counted (their spread before fixing)")
        put(gs, "cross_covariance", u.spread_cross, "Pa^2 (nu12: Pa, 1)",
            description="covariance of the free constants (rows: /uncertainty/labels) with the "
            "fixed values counted (columns: labels)")
    if u.fixed_ranges:
        gr = g.create_group("fixed_ranges")
        labels = list(u.fixed_ranges)
        data, dt = _strings(labels)
        gr.create_dataset("labels", data=data, dtype=dt)
        for key in ("low", "high"):
            put(gr, key, np.array([getattr(u.fixed_ranges[x], key) for x in labels]),
                "Pa (nu12: 1)", description="end of the search the constant was held at")
        put(gr, "ratio_to_half_width", np.array([u.fixed_ranges[x].ratio for x in labels]),
            "1", description="largest move of a free constant between the ends, over its "
            "half-width (> 1: its interval is given a value that is not known)")
        data, dt = _strings([u.fixed_ranges[x].text for x in labels])
        gr.create_dataset("text", data=data, dtype=dt)
    fc = getattr(u, "fixed_check", None)
    if fc is not None:
        gc = g.create_group("fixed_check")
        for key, v in fc.as_dict().items():
            if key == "labels":
                v = ",".join(v)
            elif key == "values":
                v = np.asarray(v, float)
            gc.attrs[key] = v
        gc.attrs["values_unit"] = "Pa (nu12: 1), in the order of labels"
    g.attrs["spread_counted"] = ",".join(u.spread_counted)
    g.attrs["spread_not_counted"] = ",".join(u.spread_not_counted)
    g.attrs["chi2_limit_99"] = u.chi2_limit
    put(g, "correlation", u.correlation, "1")
    put(g, "covariance", u.covariance, "Pa^2 (nu12 row/column: Pa, 1)")
    data, dt = _strings([lab for lab, _ in u.weakest])
    g.create_dataset("weakest_labels", data=data, dtype=dt)
    put(g, "weakest_coefficients", np.array([c for _, c in u.weakest], float), "1",
        description="right singular vector of the smallest singular value of the whitened "
        "Jacobian over relative constants")
    gs = g.create_group("frequency_sigma")
    for key, name, sig in zip(safe_keys(plate_names), plate_names, a.sigmas):
        d = put(gs, key, sig.sigma_hz, "Hz",
                description="standard deviation of each measured frequency (NaN: not measured)")
        d.attrs["name"] = name
        d.attrs["source"] = ",".join(sig.source)
        d.attrs["sigma_rel"] = sig.sigma_rel
        d.attrs["note"] = sig.note
    if a.monte_carlo is not None:
        from laminid_cli.uncertainty import MC_EVIDENCE

        mc = a.monte_carlo
        gm = g.create_group("monte_carlo")
        for key in ("trials", "converged", "sigma_factor", "seed", "jobs", "time_s",
                    "prior_sigma", "variance_dof"):
            gm.attrs[key] = {"trials": mc.n_trials, "converged": mc.n_converged}.get(
                key, getattr(mc, key, None))
        for key in ("samples", "mean", "std", "lower", "upper"):
            put(gm, key, getattr(mc, key), unit)
        put(gm, "linearized_std", mc.linearized_std, unit, description=LINEARISED_STD)
        put(gm, "ratio", mc.ratio, "1", description="Monte Carlo std / linearised std")
        inner_lo, inner_hi = mc.inner_range()
        for key, value in (("inner_lower", inner_lo), ("inner_upper", inner_hi)):
            put(gm, key, value, unit, description="order statistic of the samples inside the "
                "range's quantile with probability >= evidence_level (NaN: too few trials); "
                "the Monte Carlo verdicts use the width inner_upper - inner_lower")
        gm.attrs["evidence_level"] = MC_EVIDENCE
        # the values --fix-undetermined fixed that each trial drew (uncertainty.FixedDraw)
        gm.attrs["fixed_drawn"] = ",".join(mc.fixed_labels)
        gm.attrs["fixed_held"] = ",".join(mc.fixed_held)
        gm.attrs["fixed_clipped"] = int(mc.fixed_clipped)
        if mc.fixed_samples is not None:
            put(gm, "fixed_samples", mc.fixed_samples, "Pa (nu12: 1)",
                description="per converged trial (rows of samples), the values of the "
                "constants in attr fixed_drawn it drew from their spread before fixing (ln G "
                "for moduli, linear for nu12; shortened to the search's range: attr "
                "fixed_clipped trials)")
        for side, count, flag in zip(("lower", "upper"), mc.bound_counts(), mc.ends_at_bound()):
            put(gm, f"at_{side}_bound", count, "1",
                description=f"converged trials whose answer has the constant on "
                f"{'an' if side == 'upper' else 'a'} {side} limit of the search")
            put(gm, f"{side}_at_bound", np.asarray(flag, np.int8), "1",
                description=f"1: the {side} end of the range is set by trials at a limit of the "
                "search (the search's end, not the data's)")
    if a.fixed_widths:
        gf = g.create_group("fixed_undetermined")
        labels = list(a.fixed_widths)
        data, dt = _strings(labels)
        gf.create_dataset("labels", data=data, dtype=dt)
        put(gf, "rel_half_width", np.array([a.fixed_widths[x][0] for x in labels], float), "1",
            description="95 % half-width / value in the run that had it fixed (the Monte "
            "Carlo's for-sure width where that flagged it)")
        data, dt = _strings([a.fixed_widths[x][1] for x in labels])
        gf.create_dataset("verdict", data=data, dtype=dt)
        put(gf, "run", np.array([a.fixed_widths[x][2] for x in labels], int), "1",
            description="the run of --fix-undetermined whose assessment flagged it (1: the "
            "first identification, before anything was fixed)")
    if a.before_fixing is not None:
        b = a.before_fixing
        gb = g.create_group("before_fixing")
        data, dt = _strings(b.labels)
        gb.create_dataset("labels", data=data, dtype=dt)
        put(gb, "rel_half_width", b.rel_half_width, "1")
        data, dt = _strings(b.verdict)
        gb.create_dataset("verdict", data=data, dtype=dt)


def uncertainty_summary(a) -> dict:
    """JSON block "uncertainty" of an Assessment (SI; see laminid_cli.uncertainty)."""
    from laminid_cli.joint import unique_names
    from laminid_cli.uncertainty import sensitivity_table

    r = a.result
    plates = list(getattr(r, "specimens", ())) or [r]
    names = unique_names([p.specimen.name for p in plates])
    out = a.uncertainty.as_dict()
    out["frequency_sigma"] = {n: {"sigma_hz": s.sigma_hz, "source": list(s.source),
                                  "sigma_rel": s.sigma_rel, "note": s.note}
                              for n, s in zip(names, a.sigmas)}
    out["sensitivity"] = sensitivity_table(r)
    out["fixed_undetermined"] = list(a.fixed_undetermined)
    # a fixed constant's entry has a free one's keys (its value, no interval, "assumed" where
    # --fix-undetermined held it), as summary.json's: {"verdict", "flagged"} alone sent a
    # program reading constants[m][k]["value"] or ["lower"] into a KeyError
    values = {f"{n}.{k}": v for n, c in zip(r.material_names, r.constants)
              for k, v in c.as_dict().items()}
    for lab in a.uncertainty.fixed:
        mat, const = lab.rsplit(".", 1)
        entry = out["constants"].setdefault(mat, {}).setdefault(const, {})
        entry.update({"value": values.get(lab), "std": None, "std_stated": None,
                      "lower": None, "upper": None, "half_width": None, "rel_half_width": None,
                      "verdict": entry.get("verdict", "fixed"), "flagged": False,
                      "at_bound": False, "bound_text": "", "bound_side": "",
                      "bound_limit": None, "assumed": lab in a.fixed_undetermined})
    # ... all of them: the README's "the same keys for every constant" missed a fixed one's
    # scale, verdict_from, information_from_prior (and quantile, effective_dof... where the
    # free ones have them), and a free one's "assumed"; null where it does not apply
    entries = [e for per in out["constants"].values() for e in per.values()]
    keys = list(dict.fromkeys(k for e in entries for k in e))
    for e in entries:
        e.setdefault("assumed", False)
        for k in keys:
            e.setdefault(k, None)
    out["kept_free"] = dict(a.kept_free)
    out["fixed_undetermined_widths"] = {
        lab: {"rel_half_width": w[0], "verdict": w[1], "run": w[2]}
        for lab, w in a.fixed_widths.items()}
    out["runs"] = a.runs
    if a.before_fixing is not None:
        out["before_fixing"] = {
            lab: {"rel_half_width": float(a.before_fixing.rel_half_width[k]),
                  "verdict": a.before_fixing.verdict[k]}
            for k, lab in enumerate(a.before_fixing.labels)}
    if a.monte_carlo is not None:
        out["monte_carlo"] = a.monte_carlo.as_dict()
        held = getattr(a, "monte_carlo_given_fixed", None)
        if held is not None and a.monte_carlo.fixed_labels:
            # the trials that held the fixed values (their flags decided what to fix): the
            # range given them, beside rel_half_width_given_fixed
            per: dict = {}
            for k, lab in enumerate(held.labels):
                mat, const = lab.rsplit(".", 1)
                v = float(a.uncertainty.value[list(a.uncertainty.labels).index(lab)])
                per.setdefault(mat, {})[const] = {
                    "std": float(held.std[k]), "lower": float(held.lower[k]),
                    "upper": float(held.upper[k]),
                    "rel_half_width": float(0.5 * (held.upper[k] - held.lower[k]) / abs(v))
                    if v else float("inf")}
            out["monte_carlo"]["given_fixed"] = {"converged": held.n_converged,
                                                 "time_s": held.time_s, "constants": per}
    return out


def joint_identification_summary(r) -> dict:
    """Everything ``laminid identify --joint`` reports, as plain data (SI, Hz).

    Materials once at the top level; per plate (key: specimen name) the single-plate summary
    without its material keys.
    """
    from laminid_cli.joint import unique_names

    plates = {}
    for name, p in zip(unique_names([q.specimen.name for q in r.specimens]), r.specimens):
        s = identification_summary(p)
        for key in ("materials", "initial", "free", "parametrization", "optimizer", "iterations",
                    "evaluations", "converged", "optimizer_status", "time_s"):
            s.pop(key, None)
        plates[name] = s
    return {
        "joint": True,
        "specimen_names": list(plates),
        "materials": {n: c.as_dict() for n, c in zip(r.material_names, r.constants)},
        "initial": {n: c.as_dict() for n, c in zip(r.material_names, r.initial)},
        "free": {n: list(v) for n, v in r.free.items()},
        "parametrization": dict(r.parametrization),
        "specimens": plates,
        "rms_residual_percent": r.rms_residual_percent,
        "initial_rms_residual_percent": r.initial_rms_residual_percent,
        **run_fields(r),
    }


def write_joint_identification_file(path, fms, r, summary: dict, assessment=None,
                                    command: str = "laminid identify --joint", status=None,
                                    attrs: dict | None = None) -> None:
    """Write a joint identification (format "laminid-joint-result", module docstring);
    ``status`` and ``attrs`` as in :func:`write_identification_file`."""
    import h5py

    from laminid_cli.joint import unique_names

    names = unique_names([p.specimen.name for p in r.specimens])
    with atomic_h5(path, "laminid-joint-result", command=command) as f:
        write_run_attrs(f, r)
        write_status(f, status if status is not None else status_of(r, assessment))
        for key, value in (attrs or {}).items():
            f.attrs[key] = value
        f.attrs["specimens"] = ",".join(names)
        f.attrs["rms_residual_percent"] = float(r.rms_residual_percent)
        write_materials(f, r.material_names, r.constants, {})
        _write_material_settings(f, r)
        write_materials(f, r.material_names, r.initial, {}, group="initial")
        h = f.create_group("history")
        for key, unit in (("evaluation", "1"), ("objective", "1"), ("rms_residual_percent", "%")):
            put(h, key, r.history[key], unit)
        put_error_bound(h, r.history)
        put(h, "x", r.history["x"], "1", labels=",".join(r.variable_labels))
        labels = [f"{n}.{k}" for n in r.material_names
                  for k in ("E1", "E2", "G12", "G13", "G23", "nu12")]
        put(h, "constants", r.history["constants"], "Pa (nu12: 1)", labels=",".join(labels))
        str_dt = h5py.string_dtype()
        f.create_dataset("swaps", data=np.array(list(r.swaps), dtype=object), dtype=str_dt)
        f.create_dataset("warnings", data=np.array(list(r.warnings), dtype=object), dtype=str_dt)
        sg = f.create_group("specimens")
        for key, name, fm, plate in zip(safe_keys(names), names, fms, r.specimens):
            g = sg.create_group(key)
            g.attrs["name"] = name
            _write_identification(g, fm, plate, summary["specimens"][name] | {
                "optimizer": summary["optimizer"]})
            if summary["specimens"][name].get("global_uncertainty"):
                write_global_uncertainty(g, summary["specimens"][name]["global_uncertainty"])
        if assessment is not None:
            write_uncertainty(f, assessment, names)
            annotate_doubt(f, assessment)
        put_summary(f, summary)


#: a fixed constant's verdict on its /materials dataset (annotate_doubt)
FIXED_VERDICT = "fixed at its initial value — not identified"
UNDETERMINED_FIXED_VERDICT = "fixed because undetermined — not identified (an assumption)"


def annotate_doubt(f, a) -> None:
    """Each constant's dataset under /materials (a joint file's root and each plate's) and
    each global property's under /global_properties gets its doubt as attributes: ``verdict``
    and ``lower``, ``upper`` (SI; NaN: no interval, a constant at its bound or fixed) at
    ``confidence``, as /uncertainty and /global_properties_uncertainty give them; a fixed
    constant the verdict FIXED_VERDICT or UNDETERMINED_FIXED_VERDICT. A program reading
    /materials/<key>/G13 alone took a value at a search limit, or a guess held fixed, for an
    identified one."""
    u = a.uncertainty
    index = {lab: i for i, lab in enumerate(u.labels)}
    assumed = set(a.fixed_undetermined)
    tables = [f] + [g for g in f["specimens"].values()] if "specimens" in f else [f]

    def put_doubt(d, verdict, lower, upper):
        d.attrs["verdict"] = str(verdict)
        d.attrs["lower"], d.attrs["upper"] = float(lower), float(upper)
        d.attrs["confidence"] = float(u.confidence)

    for g in tables:
        for gm in (g["materials"].values() if "materials" in g else ()):
            name = str(gm.attrs.get("name", ""))
            for k in CONSTANT_UNITS:
                if k not in gm:
                    continue
                lab = f"{name}.{k}"
                if lab in index:
                    i = index[lab]
                    put_doubt(gm[k], u.verdict[i], u.lower[i], u.upper[i])
                else:
                    put_doubt(gm[k], UNDETERMINED_FIXED_VERDICT if lab in assumed
                              else FIXED_VERDICT, np.nan, np.nan)
        if "global_properties" in g and "global_properties_uncertainty" in g:
            h = g["global_properties_uncertainty"]
            keys = [x.decode() if isinstance(x, bytes) else str(x) for x in h["keys"][()]]
            verdicts = [x.decode() if isinstance(x, bytes) else str(x)
                        for x in h["verdict"][()]]
            for i, k in enumerate(keys):
                if k in g["global_properties"]:
                    put_doubt(g["global_properties"][k], verdicts[i], h["lower"][i],
                              h["upper"][i])


def write_global_uncertainty(g, unc: dict) -> None:
    """``global_properties_uncertainty`` of a plate's group (the root of a single result,
    /specimens/<key> of a joint one): the laminate's global properties (Appendix A) with their
    intervals and verdicts (laminid_cli.global_uncertainty; NaN interval: not identified)."""
    import h5py

    keys = list(unc)
    h = g.create_group("global_properties_uncertainty")
    data, dt = _strings(keys)
    h.create_dataset("keys", data=data, dtype=dt)
    unit = "Pa (nu_xy, nu_yx: 1)"
    for field in ("value", "std", "lower", "upper"):
        put(h, field, np.array([np.nan if unc[k][field] is None else unc[k][field]
                                for k in keys], float), unit)
    put(h, "rel_half_width", np.array([np.nan if unc[k]["rel_half_width"] is None
                                       else unc[k]["rel_half_width"] for k in keys], float), "1")
    h.create_dataset("verdict", data=[unc[k]["verdict"] for k in keys],
                     dtype=h5py.string_dtype())
    if not any("monte_carlo" in unc[k] for k in keys):
        return
    # with a Monte Carlo: each property at every trial's constants, summarised as the
    # constants' ranges are (/uncertainty/monte_carlo; NaN: the trials do not move it)
    from laminid_cli.uncertainty import MC_EVIDENCE

    h.attrs["verdict_from_monte_carlo"] = ",".join(
        k for k in keys if unc[k].get("verdict_from") == "monte_carlo")
    for key, what in (("monte_carlo_rel_half_width", "the Monte Carlo range's half-width / "
                       "|value|"),
                      ("monte_carlo_rel_half_width_lower", "the half-width / |value| the "
                       "Monte Carlo range has for sure (monte_carlo/@evidence_level): the "
                       "width its verdicts use; NaN: no range, or too few trials")):
        put(h, key, np.array([unc[k].get(key, np.nan) for k in keys], float), "1",
            description=what)
    gm = h.create_group("monte_carlo")
    gm.attrs["evidence_level"] = MC_EVIDENCE
    gm.attrs["description"] = (
        "each property at each converged trial's constants (its free ones, the fixed ones it "
        "drew, the others the result's); NaN: the trials do not move it (it depends on fixed "
        "values only, or on one fixed because undetermined that they held)")
    mc = [unc[k].get("monte_carlo") or {} for k in keys]
    for field in ("mean", "std", "lower", "upper", "inner_lower", "inner_upper",
                  "linearized_std"):
        put(gm, field, np.array([m.get(field, np.nan) for m in mc], float), unit)
    put(gm, "ratio", np.array([m.get("ratio", np.nan) for m in mc], float), "1",
        description="Monte Carlo std / linearised std (times t's std, as the constants')")
    put(gm, "trials_at_bound", np.array([m.get("trials_at_bound", 0) for m in mc], int), "1",
        description="converged trials whose answer has a constant the property depends on "
        "on a limit of the search")
    for side in ("lower", "upper"):
        put(gm, f"{side}_at_bound", np.array([m.get(f"{side}_at_bound", False) for m in mc],
                                             np.int8), "1",
            description=f"1: the {side} end of the range is set by such trials (the "
            "search's end, not the data's)")


def write_damping(f, d) -> None:
    """Write a :class:`laminid_cli.damping.DampingFit` as /damping (module docstring)."""
    g = f.create_group("damping")
    for key, value in (("method", d.method), ("terms", "11,22,12,13,23"), ("s2", d.s2),
                       ("chi2", d.chi2), ("dof", d.dof), ("confidence", d.confidence),
                       ("quantile", d.quantile), ("scaling", d.scaling),
                       ("scale_used", d.scale_used), ("sigma_source", d.sigma_source),
                       ("fixed", ",".join(f"{k}={v:g}" for k, v in d.fixed.items())),
                       ("notes", "; ".join(d.notes))):
        g.attrs[key] = value
    data, dt = _strings(d.labels)
    g.create_dataset("labels", data=data, dtype=dt)
    for key in ("value", "std"):
        put(g, key, np.asarray(getattr(d, key), float), "1")
    for key in ("lower", "upper"):
        put(g, key, np.asarray(getattr(d, key), float), "1",
            description=f"{key} end of the interval; NaN for a loss factor held at 0 (no "
            "interval)")
    put(g, "rel_half_width", np.asarray(d.rel_half_width, float), "1",
        description="95 % half-width / value (inf for a loss factor held at 0)")
    data, dt = _strings(d.verdict)
    g.create_dataset("verdict", data=data, dtype=dt)
    g.create_dataset("at_bound", data=np.asarray(d.at_bound, bool))
    at = np.asarray(d.at_bound, bool)
    data, dt = _strings(["lower" if b else "" for b in at])
    g.create_dataset("bound_side", data=data, dtype=dt)
    put(g, "bound_limit", np.where(at, 0.0, np.nan), "1",
        description="0 for a loss factor held at its lower limit (eta >= 0), NaN otherwise")
    put(g, "measured_loss_factor", d.measured_loss_factor, "1",
        description="2 x measured viscous damping ratio; NaN where not measured")
    put(g, "measured_sigma", d.measured_sigma, "1",
        description="standard deviation of the measured modal loss factor")
    put(g, "model_loss_factor", d.model_loss_factor, "1",
        description="sum of energy share x ply loss factor (modal strain energy)")
    g.create_dataset("used", data=np.asarray(d.used, bool))
    put(g, "energy_shares", d.energy_shares, "1", labels=",".join(d.share_labels),
        description="U_mik / U_i: strain energy of mode i in term k of material m (material "
        "axes; the nu12 coupling split equally between 11 and 22)")
    mc = getattr(d, "monte_carlo", None)
    if mc is None:
        return
    from laminid_cli.damping import DAMPING_STREAM

    g.attrs["verdict_from_monte_carlo"] = ",".join(d.verdict_from_monte_carlo)
    put(g, "monte_carlo_rel_half_width", np.asarray(d.mc_rel_half_width, float), "1",
        description="the loss factors' Monte Carlo range half-width / value")
    put(g, "monte_carlo_rel_half_width_lower", np.asarray(d.mc_rel_half_width_lower, float),
        "1", description="half-width / value of the range its trials show for sure "
        "(monte_carlo/@evidence_level): the width its verdicts use; NaN: too few trials")
    gm = g.create_group("monte_carlo")
    for key, value in (("trials", mc.n_trials), ("refits", mc.n_refits),
                       ("sigma_factor", mc.sigma_factor),
                       ("seed", -1 if mc.seed is None else mc.seed),
                       ("confidence", mc.confidence), ("evidence_level", mc.evidence_level),
                       ("time_s", mc.time_s), ("stream", DAMPING_STREAM)):
        gm.attrs[key] = value
    gm.attrs["description"] = ("each converged trial refitted the free loss factors at its own "
                               "identified constants (its modes' strain-energy shares) from the "
                               "measured damping perturbed by its sigma x sigma_factor")
    for key in ("samples", "mean", "std", "lower", "upper", "inner_lower", "inner_upper"):
        put(gm, key, np.asarray(getattr(mc, key), float), "1")
    put(gm, "linearized_std", np.asarray(mc.linearized_std, float), "1",
        description=LINEARISED_STD)
    put(gm, "trials_at_zero", np.asarray(mc.trials_at_zero, int), "1",
        description="refits that held the loss factor at its bound 0")
    put(gm, "lower_at_zero", np.asarray(mc.lower_at_zero, np.int8), "1",
        description="1: the range's lower end is set by refits at the bound 0 (the bound's "
        "end, not the data's)")

