"""Write fitted natural frequencies into a specimen file's ``measured:`` mapping.

Only ``measured.frequencies`` (Hz, ``null`` for a mode not found), ``measured.sigma`` (Hz,
standard deviations), ``measured.sigma_source`` (how the sigmas were made),
``measured.damping`` and ``measured.damping_sigma`` (viscous damping ratios and their standard
deviations, when given) and, when asked or already present, ``measured.weights`` change; every
comment, every other key and their order are kept (ruamel.yaml round trip). The file is never
left half-written or invalid:

0. the specimen file is read and validated first (:func:`laminid_cli.specimen.read_specimen`,
   with its bounded YAML checks): an invalid specimen is refused and left untouched;
1. the edited document is serialised to text and parsed back with ``yaml.safe_load``; the
   result must equal the original document except for those keys, and the new lists must read
   back exactly, and the edited text must be a valid specimen;
2. the original is copied to ``SPEC.yaml.bak``;
3. the text goes to a temporary file in the same folder, is fsynced and renamed over the
   specimen file (``os.replace`` is atomic).
"""

from __future__ import annotations

import io
import math
import os
import shutil
from pathlib import Path

from laminid_cli.errors import SpecimenError

KEYS = ("frequencies", "sigma", "weights", "damping", "damping_sigma")


def _round(x: float | None, digits: int) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return round(float(x), digits)


def _sig(x, digits: int = 6) -> float | None:
    """``x`` to ``digits`` significant digits (damping ratios are small numbers)."""
    if x is None or not math.isfinite(x):
        return None
    return float(f"{float(x):.{digits - 1}e}")


def write_measured(spec_path, freq_hz, sigma_hz=None, weights=None, *, damping=None,
                   damping_sigma=None, backup: bool = True,
                   validate: bool = True, sigma_source: str | None = None) -> Path:
    """Replace/insert the measured frequencies (and sigma, weights) of a specimen YAML file.

    Parameters
    ----------
    spec_path : specimen YAML file (must exist and hold a mapping)
    freq_hz : (n,) Hz; None/NaN for a mode not found (written as ``null``)
    sigma_hz : (n,) Hz or None; standard deviations (``null`` where the frequency is null)
    weights : (n,) in [0, 1] or None. When None and the file already has ``weights``: kept if
        its length matches (0 where the new frequency is null, 1 where a mode null before is
        now found), otherwise rewritten as 1 for found modes and 0 for null ones.
    damping, damping_sigma : (n,) viscous damping ratios and their standard deviations, or
        None (written to ``measured.damping`` / ``measured.damping_sigma``, 6 significant digits)
    backup : keep the original as ``<spec>.bak``
    validate : the file must be a valid specimen before and after the edit (``laminid
        fit-frf --into``); without it only the YAML checks (bounded size, depth, aliases, no
        tags) and the structure of ``measured`` are required (any YAML mapping is edited)
    sigma_source : written as ``measured.sigma_source`` (shown by identify), with ``sigma_hz``

    Returns the backup path (or the spec path when ``backup`` is false).
    """
    import yaml
    from ruamel.yaml import YAML
    from ruamel.yaml.comments import CommentedMap, CommentedSeq

    from laminid_cli.specimen import check_yaml_text, load_specimen_text, read_specimen

    spec_path = Path(spec_path)
    if validate:   # the whole specimen must be valid before anything is edited
        text = read_specimen(spec_path).source_text
    else:
        try:
            text = spec_path.read_text(encoding="utf-8")
        except FileNotFoundError as exc:
            raise SpecimenError("file not found", path=str(spec_path)) from exc
        except (OSError, UnicodeDecodeError) as exc:
            raise SpecimenError(f"cannot read the file ({exc})", path=str(spec_path)) from exc
    # bounded before ruamel or PyYAML builds anything from it (aliases, depth, tags, size)
    check_yaml_text(text, str(spec_path))
    try:
        original = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SpecimenError(f"not valid YAML ({exc}); file left unchanged",
                            path=str(spec_path)) from exc
    if not isinstance(original, dict):
        raise SpecimenError("the specimen file must be a YAML mapping; file left unchanged",
                            path=str(spec_path))

    freq = [_round(None if f is None else float(f), 4) for f in freq_hz]
    found = [f is not None for f in freq]
    sig = None
    if sigma_hz is not None:
        if len(sigma_hz) != len(freq):
            raise ValueError("sigma_hz and freq_hz differ in length")
        sig = [_round(None if s is None else float(s), 4) if ok else None
               for s, ok in zip(sigma_hz, found)]
    extra = {}
    for key, values in (("damping", damping), ("damping_sigma", damping_sigma)):
        if values is not None:
            if len(values) != len(freq):
                raise ValueError(f"{key} and freq_hz differ in length")
            extra[key] = [_sig(v) if ok else None for v, ok in zip(values, found)]
    if weights is not None:
        if len(weights) != len(freq):
            raise ValueError("weights and freq_hz differ in length")
        wts = [float(w) if ok else 0.0 for w, ok in zip(weights, found)]
    else:
        wts = None

    rt = YAML()
    rt.preserve_quotes = True
    rt.width = 4096
    try:
        doc = rt.load(text)
    except Exception as exc:  # ruamel's error classes vary by version
        raise SpecimenError(f"cannot parse for editing ({exc}); file left unchanged",
                            path=str(spec_path)) from exc
    measured = doc.get("measured")
    if measured is None:
        measured = CommentedMap()
        doc["measured"] = measured
    elif not isinstance(measured, dict):
        raise SpecimenError("'measured' must be a mapping; file left unchanged",
                            path=str(spec_path), field="measured")
    if wts is None and "weights" in measured:
        old = measured["weights"]
        old_f = measured.get("frequencies")
        old_f = list(old_f) if isinstance(old_f, list) else [None] * len(freq)
        if isinstance(old, list) and len(old) == len(freq) and len(old_f) == len(freq):
            # the user's weights stay, except for modes that appear or disappear
            wts = [(1 if of is None else (w if w is not None else 0)) if ok else 0
                   for w, ok, of in zip(old, found, old_f)]
        else:
            wts = [1 if ok else 0 for ok in found]

    def put(key, values):
        old = measured.get(key)
        if isinstance(old, CommentedSeq):   # edit in place: keeps the flow style and comments
            old[:] = values
        else:
            seq = CommentedSeq(values)
            seq.fa.set_flow_style()
            measured[key] = seq

    put("frequencies", freq)
    if sig is not None:
        put("sigma", sig)
        if sigma_source:
            measured["sigma_source"] = str(sigma_source)
        elif "sigma_source" in measured:
            del measured["sigma_source"]               # it described the previous sigmas
    if wts is not None:
        put("weights", wts)
    for key, values in extra.items():
        put(key, values)

    buf = io.StringIO()
    rt.dump(doc, buf)
    new_text = buf.getvalue()
    # re-validate: plain parse; only the measured lists may differ
    try:
        check = yaml.safe_load(new_text)
    except yaml.YAMLError as exc:  # pragma: no cover - would be a ruamel bug
        raise SpecimenError(f"edited file would not parse ({exc}); file left unchanged",
                            path=str(spec_path)) from exc
    expect = dict(original)
    exp_measured = dict(original.get("measured") or {})
    exp_measured["frequencies"] = freq
    if sig is not None:
        exp_measured["sigma"] = sig
        if sigma_source:
            exp_measured["sigma_source"] = str(sigma_source)
        else:
            exp_measured.pop("sigma_source", None)
    if wts is not None:
        exp_measured["weights"] = wts
    exp_measured.update(extra)
    expect["measured"] = exp_measured
    try:   # the edited file must be a valid specimen too (e.g. weights of the right length)
        if validate:
            load_specimen_text(new_text, str(spec_path))
    except SpecimenError as exc:
        raise SpecimenError(f"the edited file would not be a valid specimen ({exc}); file left "
                            "unchanged", path=str(spec_path)) from exc

    if check != expect:
        raise SpecimenError("edited file would not read back as intended; file left unchanged",
                            path=str(spec_path), field="measured")

    bak = spec_path.with_name(spec_path.name + ".bak")
    if backup:
        shutil.copy2(spec_path, bak)
    tmp = spec_path.with_name(f".{spec_path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(new_text)
            fh.flush()
            os.fsync(fh.fileno())
        shutil.copymode(spec_path, tmp)
        os.replace(tmp, spec_path)
    except OSError as exc:
        raise SpecimenError(f"cannot write ({exc}); file left unchanged",
                            path=str(spec_path)) from exc
    finally:
        if tmp.exists():
            tmp.unlink()
    return bak if backup else spec_path
