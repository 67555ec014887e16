"""``laminid fit-frf``: natural frequencies from measured FRFs (rational fraction polynomials)."""

from __future__ import annotations

import click

from laminid_cli.commands._common import (FRF_PATTERNS, OUTPUT_FILE, SIGMA_REL, InputFile,
                                          check_output_path, echo_frf_warnings, echo_json,
                                          files_hint, force_option, frf_json_option, quiet,
                                          stderr_is_terminal, writable_target)


def _parse_bands(ctx, param, values):
    bands = []
    for text in values:
        parts = text.replace(",", ":").split(":")
        try:
            lo, hi = (float(p) for p in parts)
        except ValueError:
            raise click.BadParameter(f"{text!r}: expected LO:HI in Hz, e.g. 100:1400") from None
        if not (lo >= 0 and hi > lo) or hi == float("inf"):
            raise click.BadParameter(f"{text!r}: the band is empty; need 0 <= LO < HI (Hz)")
        bands.append((lo, hi))
    return bands or None


#: mode_units' entry for snr: what it is a ratio of, and that it is linear (a signal-to-noise
#: ratio is read in dB where none is said)
SNR_UNIT = ("1 (linear, not dB: the mode's peak contribution over the RMS of the fit's "
            "residual around it)")


#: mode_units' entry for false_alarm
FALSE_ALARM_UNIT = ("1 (a probability: that noise alone gives a pole whose modal constants "
                    "lower the fit's residual as much anywhere in the lines fitted; a mode is "
                    "kept only at 0.01 or less)")


@click.command("fit-frf")
@click.argument("frf_file", type=InputFile(folder_hint=files_hint("fit-frf", FRF_PATTERNS,
                                                                  "FRF file")))
@click.option("--band", "bands", multiple=True, callback=_parse_bands, metavar="LO:HI",
              help="Frequency band in Hz to fit (repeatable); a band with more than six "
                   "resonance peaks is fitted as overlapping sub-bands (the first line lists "
                   "the bands fitted). Default: bands around the peaks of the summed FRF "
                   "magnitude.")
@click.option("--modes", "n_modes", type=click.IntRange(min=1), default=None,
              help="Report the N lowest modes (error if fewer are found).")
@click.option("--format", "fmt", type=click.Choice(["hdf5", "uff", "csv"]), default=None,
              help="FRF file format (default: from the suffix .h5/.uff/.unv/.csv).")
@click.option("--freq-dataset", default=None, metavar="PATH",
              help="Plain HDF5 file of another tool: the frequency dataset (1-D, Hz).")
@click.option("--frf-dataset", default=None, metavar="PATH",
              help="Plain HDF5 file: the complex FRF dataset (n_points x n_freq or its "
                   "transpose). Default: found by name, shape and units attributes.")
@click.option("--plot", "plot_path", type=OUTPUT_FILE, default=None,
              help="Write a figure (PNG/PDF/SVG): FRFs with the fit, poles, stabilisation chart.")
@click.option("--into", "spec_path", type=click.Path(), default=None,
              help="Write the frequencies, their sigmas, the damping ratios (the exponential "
                   "window's damping removed) and their sigmas into this specimen file's "
                   "'measured:' entry (only those lines change, and lose their old comments; "
                   "the previous version goes to a new backup SPEC.bak, SPEC.bak1, ...; "
                   "weights follow their modes by frequency).")
@click.option("--sigma-rel", type=SIGMA_REL, default=0.002, show_default=True, metavar="FRACTION",
              help="Floor of each frequency's standard deviation, as a fraction of it "
                   "(0.002, or 0.2%; supports, temperature, repeatability: what the FRF "
                   "cannot show).")
@force_option
@frf_json_option
def fit_frf(frf_file, bands, n_modes, fmt, freq_dataset, frf_dataset, plot_path, spec_path,
            sigma_rel, force, as_json):
    """Fit the FRFs in FRF_FILE (laminid HDF5, UFF 58 or CSV) and list the natural frequencies.

    A plain HDF5 file of another tool is read too: a 1-D frequency dataset and a complex FRF
    dataset of matching length (either orientation), found by name, shape and units
    attributes; name them with --freq-dataset/--frf-dataset when several fit (also a MATLAB
    MAT-file, .mat, of any version; a text variable freq_unit = 'kHz' gives the frequency's
    unit, frf_unit the FRFs', units either). A CSV file holds
    the frequency (its unit in the header, 'f [kHz]', 'f [Hz]', 'f [rad/s]': a header that
    states none is read as Hz with a warning, and refused where its values end below 100),
    then per FRF a real and an imaginary column, one column of complex numbers
    (a+bj, a+bi) or a magnitude and a phase column named in its header (H1_mag, H1_phase;
    '[dB]', '[deg]' or '[rad]' as the header says; a phase without a unit: radians within
    +-pi, degrees where it wraps at +-180 or exceeds 180, with a note; else give its unit).

    A global rational fraction polynomial fit (Richardson & Formenti) of all FRFs with shared
    poles, over a sweep of model orders; poles stable across orders are the modes.

    The uncertainty (+/-, a standard deviation in Hz, written by --into as measured.sigma) is a
    measurement uncertainty: sqrt(RFP spread^2 + resolution^2 + window^2), at least
    --sigma-rel of the frequency. RFP spread: over the stable orders; resolution: line
    spacing / sqrt(12); window: the shift of |pole| by an exponential window's 1/tau (when the
    FRF file records exp_window_s). The 'from' column names the term that dominated.

    \b
    --json, per mode (units of every field in mode_units):
      sigma_hz        the uncertainty above, Hz: what --into writes as measured.sigma
                      and identify uses
      freq_std_hz     the RFP spread term alone, Hz: the standard deviation of the
                      frequency over the stable model orders (the fit's own precision,
                      not the measurement's); sigma_terms_hz holds every term
      modal_constants [re, im] residue A of each FRF, in (FRF units)*rad/s
                      (modal_constants_unit; units and it null where the file
                      states no FRF unit, with a note):
                      H(s) = A/(s - pole) + conj(A)/(s - conj(pole))
                      of the FRF of each entry of points (its label: "12-Z", a UFF
                      record measured in -Z, is of that direction, and so are its
                      constants)
      false_alarm     the probability that noise alone gives a pole whose modal
                      constants lower the fit's residual as much anywhere in the
                      lines fitted (a mode is kept at 0.01 or less; 0 for a clear one)
      dropped_poles   the stable poles dropped as no credible modes, each with
                      freq_hz, damping_ratio, band_hz, reason ('reach': its
                      output-error fit leaves its bounds; 'noise': its peak below
                      5 x the residual; 'chance': its modal constants lower the
                      residual no more than noise alone does anywhere in the lines
                      fitted, false_alarm above 0.01; 'twice': a mode another pole
                      found)
                      and why (the figures); the table lists them under 'dropped:'

    Damping: when the FRF file records the exponential window acquire applied to the response
    (exp_window_s = tau), every fitted pole decays faster by 1/tau; fit-frf removes it
    (damping = fitted - about 1/(tau*omega_n), the 'window' column) in the table, --json and
    --into. A mode whose fitted damping is not above the window's gets no damping ratio
    (null), with a note. The standard deviation is the fitted ratio's (the spread over the
    stable orders, at least 2 % of the fitted ratio); a 'zeta +/-' line under the table
    (--json: damping_sigma_rule, per mode damping_sigma_dominant) says for how many modes the
    2 % floor, an assumed figure, set it.

    \b
    Examples:
      laminid fit-frf plate.frf.h5
      laminid fit-frf plate.uff --band 100:700 --band 700:1500 --modes 8 --plot fit.png
      laminid fit-frf plate.frf.h5 --into plate.yaml
    """
    from pathlib import Path

    import numpy as np

    from laminid_cli.errors import OutputExistsError, SpecimenError, escaped
    from laminid_cli.frf import rfp
    from laminid_cli.frf.io import negative_direction_points, point_quality_notes, read_frf
    from laminid_cli.frf.store import units_text

    if plot_path is not None:
        from laminid_cli.frf.plot import PLOT_SUFFIXES

        writable_target(plot_path, option="--plot")     # a folder...: said first
        if Path(plot_path).suffix.lower() not in PLOT_SUFFIXES:
            raise OutputExistsError(f"{plot_path}: plot file type "
                                    f"{Path(plot_path).suffix!r} not supported; use one of "
                                    f"{', '.join(PLOT_SUFFIXES)} (--plot)")
        plot_path = check_output_path(plot_path, force, option="--plot")
    if spec_path is not None and Path(spec_path).is_dir():
        raise SpecimenError("is a folder, not a specimen file (--into needs an existing "
                            "specimen file)", path=spec_path)
    if spec_path is not None and not Path(spec_path).is_file():
        raise SpecimenError("file not found (--into needs an existing specimen file)",
                            path=spec_path)
    from laminid_cli.uncertainty import check_sigma_rel

    check_sigma_rel(sigma_rel)
    warnings = []
    if spec_path is not None:   # an invalid specimen is refused before the fit, and untouched
        from laminid_cli.specimen import read_specimen

        # its reader's warnings (a mass that density x volume contradicts...): logged on
        # stderr as it read the file, and first in --json's, as identify and modes give them
        warnings += read_specimen(spec_path).warnings
    fs = read_frf(frf_file, fmt, freq_dataset=freq_dataset, frf_dataset=frf_dataset)
    # the FRF reader's doubts (a frequency column whose unit the file does not state)
    warnings += echo_frf_warnings(fs)
    # a terminal is told what runs: the fit and the plot took 2.8-7.6 s (the synthetic S1.1's
    # 8 FRFs, busy machine) with nothing on it, the table printed after the plot
    show_progress = not as_json and stderr_is_terminal() and not quiet()
    head = escaped(f"  fitting {fs.n_points} FRF{'' if fs.n_points == 1 else 's'} of "
                   f"{frf_file}")
    if show_progress:
        click.echo(head, err=True, nl=False)
    try:
        fit = rfp.find_modes(fs.freq, fs.frf, bands=bands, n_modes=n_modes,
                             source=str(frf_file))
    except BaseException:
        if show_progress:               # the line ends before the error
            click.echo("", err=True)
        raise
    if show_progress and plot_path is None:     # ... and before the table (after the plot)
        click.echo("", err=True)
    tau = rfp.window_time_constant(fs)
    msig = rfp.measurement_sigma(fit, fs.freq, sigma_rel=sigma_rel, exp_window_s=tau)
    sigma = msig.sigma_hz
    wc = rfp.window_corrected_damping(fit, tau)
    # what set each damping ratio's sigma: its spread over the orders, or the 2 % floor (an
    # assumed figure, which the table did not tell apart from a measured one)
    zdom = rfp.damping_sigma_dominant(fit)
    # the reader's first (a CSV phase column's assumed unit): they concern the data fitted
    notes = (list(fs.meta.get("notes") or ()) + point_quality_notes(fs)
             + wc.below_notes(fit.freq_hz) + rfp.missed_peak_notes(fit, fs.freq, fs.frf))
    negative = negative_direction_points(fs.labels)
    if negative:
        notes.append(f"{', '.join(negative)}: measured in a negative direction; the FRF and its "
                     "modal constants are as recorded, of that direction (times -1 for the "
                     "positive one)")
    point_units = fs.meta.get("point_units")
    if point_units:
        notes.append("the FRFs are in different units (" + "; ".join(
            f"{lab} {units_text(u)}" for lab, u in zip(fs.labels, point_units)) + "): the "
            "frequencies and damping ratios are those of every FRF (the poles do not depend on "
            f"the response quantity); each point's modal constants are in its own FRF's unit, "
            f"not {units_text(fs.units)} (the first's, given as the file's)")
    settings = fs.meta.get("settings") or {}
    try:
        record_s = float(settings["lines"]) / float(settings["span_hz"])
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        record_s = None
    limit = rfp.window_limit_note(fit, fs.freq, tau, record_s)
    if limit is not None:
        notes.append(limit)
    if rfp.window_unknown(fs):
        notes.append(f"{frf_file} does not record the exponential window's time constant "
                     "(acquired with --keep-setup): the damping ratios are as fitted and include "
                     "whatever damping the analyser's window added")
    if plot_path is not None:
        from laminid_cli.frf.plot import plot_fit

        if show_progress:
            click.echo("\r" + escaped(f"  drawing {plot_path}").ljust(len(head)), err=True,
                       nl=False)
        try:
            plot_fit(plot_path, fs.freq, fs.frf, fit, units=fs.units, coherence=fs.coherence,
                     title=f"{Path(frf_file).name}: {len(fit.modes)} modes", sigma_hz=sigma)
        finally:
            if show_progress:
                click.echo("", err=True)
    into = None
    if spec_path is not None and not fit.modes:
        from laminid_cli.errors import FrfError

        # was: "the edited file would not be a valid specimen (...: the list of frequencies
        # is empty)", the specimen blamed for the fit's empty list
        bands_txt = ", ".join(f"{b.band_hz[0]:g}:{b.band_hz[1]:g}" for b in fit.bands)
        raise FrfError(f"{frf_file}: no stable mode found (band(s) {bands_txt} Hz): nothing to "
                       f"write into {spec_path}, left unchanged; fit other bands (--band LO:HI)")
    if spec_path is not None:
        from laminid_cli.frf.into import write_measured

        into = write_measured(spec_path, fit.freq_hz.tolist(), sigma.tolist(),
                              damping=wc.damping.tolist(), damping_sigma=wc.sigma.tolist(),
                              sigma_source=f"{Path(frf_file).name}: {msig.summary()}",
                              damping_sigma_source=(f"{Path(frf_file).name}: fit-frf: "
                                                    f"{rfp.damping_sigma_summary(zdom)}"
                                                    if zdom else None),
                              comment=f"Hz, laminid fit-frf of {Path(frf_file).name}",
                              log_warnings=False)        # logged as it read it, above
    if as_json:
        def damping_fields(i):
            return {"damping_ratio": float(wc.damping[i]), "damping_sigma": float(wc.sigma[i]),
                    "damping_sigma_dominant": zdom[i],
                    "damping_ratio_fitted": float(wc.fitted[i]),
                    "damping_window_removed": float(wc.removed[i])}

        residue_unit = _times_rad_per_s(fs.units)
        echo_json({
            "file": str(frf_file), "n_points": fs.n_points, "frf_unit": fs.units,
            "units": fs.units,             # frf_unit's old name, kept for 0.2.x (--json help)
            "points": list(fs.labels),   # one per FRF: the order of modal_constants
            "modal_constants_unit": residue_unit,
            "mode_units": {   # sigma_hz: the measurement's sigma; freq_std_hz: RFP spread only
                "freq_hz": "Hz", "sigma_hz": "Hz", "freq_std_hz": "Hz", "sigma_terms_hz": "Hz",
                "damping_ratio": "1", "damping_sigma": "1", "damping_ratio_fitted": "1",
                "damping_window_removed": "1", "damping_std": "1", "band_hz": "Hz",
                # a linear ratio (895, not dB), which "1" alone did not say
                "snr": SNR_UNIT, "false_alarm": FALSE_ALARM_UNIT,
                "modal_constants": residue_unit},
            "bands_hz": [list(b.band_hz) for b in fit.bands],
            "modes": [dict(m.as_dict(), mode=i + 1, sigma_hz=float(s),
                           sigma_terms_hz={t: float(msig.terms[t][i]) for t in msig.terms},
                           sigma_dominant=msig.dominant[i], **damping_fields(i))
                      for i, (m, s) in enumerate(zip(fit.modes, sigma))],
            "sigma_rule": msig.summary(), "sigma_rel": sigma_rel,
            "exp_window_s": tau, "damping_rule": wc.summary() or None,
            "damping_sigma_rule": rfp.damping_sigma_summary(zdom) if zdom else None,
            "dropped_poles": [d.as_dict() for d in fit.dropped],
            "notes": notes,
            "warnings": warnings,
            "plot": plot_path, "into": spec_path,
            "backup": None if into is None else into.backup_text,
            "into_unchanged": None if into is None else into.unchanged,
            "weights": None if into is None else list(into.weight_notes),
            "into_notes": None if into is None else list(into.damping_notes),
        })
        return
    bands_txt = ", ".join(f"{b.band_hz[0]:g}-{b.band_hz[1]:g}" for b in fit.bands)
    frfs = f"{fs.n_points} FRF{'' if fs.n_points == 1 else 's'}"     # (was "1 FRFs")
    click.echo(escaped(f"{frf_file}: {frfs} ({units_text(fs.units)}), {fs.freq.size} lines, "
                       f"bands {bands_txt} Hz"))
    windowed = wc.exp_window_s is not None
    if not fit.modes:
        click.echo("no stable mode found")
    else:
        click.echo(f"{'mode':>4}  {'freq (Hz)':>11}  {'+/- (Hz)':>9}  {'from':>10}  "
                   f"{'zeta (%)':>11}  {'+/- (%)':>7}  "
                   + (f"{'window (%)':>10}  " if windowed else "") + f"{'stable orders':>13}")
        for i, (m, s) in enumerate(zip(fit.modes, sigma), start=1):
            z = wc.damping[i - 1]
            zs = wc.sigma[i - 1]
            z_txt = (f"{100 * z:>11.3f}  " + (f"{100 * zs:>7.3f}" if np.isfinite(zs)
                                               else f"{'—':>7}")
                     if np.isfinite(z) else f"{'below win.':>11}  {'—':>7}")
            w_txt = ""
            if windowed:
                r = wc.removed[i - 1] if np.isfinite(z) else wc.window[i - 1]
                w_txt = f"{100 * r:>10.3f}  "
            click.echo(f"{i:>4}  {m.freq_hz:>11.3f}  {s:>9.3f}  {msig.dominant[i - 1]:>10}  "
                       f"{z_txt}  {w_txt}{m.orders_stable:>13d}")
        click.echo(f"freq +/-: one standard deviation, {msig.summary()}")
        click.echo(f"zeta +/-: one standard deviation, the {rfp.damping_sigma_summary(zdom)}")
        if windowed:
            click.echo(f"damping: {wc.summary()}; as fitted = damping + window (--json: "
                       "damping_ratio_fitted)")
    for d in fit.dropped:
        click.echo(f"dropped: pole at {d.freq_hz:.3f} Hz (zeta {100 * d.damping_ratio:.3g} %, "
                   f"band {d.band_hz[0]:g}-{d.band_hz[1]:g} Hz), no credible mode: {d.why}")
    for note in notes:
        click.echo(f"note: {note}")
    if plot_path is not None:
        click.echo(escaped(f"plot written to {plot_path}"))
    if into is not None:
        what = "frequencies and damping ratios" if into.damping_written else \
            "frequencies (no damping ratio: none is above the window's)"
        if into.unchanged:
            click.echo(escaped(f"{spec_path} already holds these {len(fit.modes)} {what}: "
                               "left unchanged (no backup made)"))
        else:
            click.echo(escaped(f"{len(fit.modes)} {what} written to {spec_path} "
                               f"({into.backup_text})"))
        for note in into.damping_notes:
            click.echo(f"note: {note}")
        for note in into.weight_notes:
            click.echo(f"weights: {note}")


def _times_rad_per_s(units: str | None) -> str | None:
    """The unit of an FRF's residues: the FRF's ``units`` times rad/s (``(Pa/N)*rad/s``);
    None where the FRF's unit is not known (not "rad/s", the residues of dimensionless FRFs)."""
    if units is None:
        return None
    u = units.strip() or "1"
    if u == "1":
        return "rad/s"
    simple = not any(c in u for c in "/*· ")
    return f"{u}*rad/s" if simple else f"({u})*rad/s"
