"""Test helpers that edit a result file written by ``laminid identify`` (schema 2) in place:

- :func:`mark_at_bound` marks free constants as at a bound exactly as the writer marks one
  (results.py: at_bound True, bound_text, bound_side, bound_limit, the at-bound verdict,
  lower/upper NaN) and sets the
  status and its reasons, for pages that need a bound hit on a specimen with reference values;
- :func:`make_version_1` turns the file into what schema version 1 wrote (results.py before
  the typed reader: material groups keyed by the name with the look-alike slash U+2215, the
  nlopt outcome in the root attribute ``status``, no /status group, symmetric linear intervals
  value -/+ half_width, no scale/at_bound/bound_text/bound_side/bound_limit);
- :func:`drop_bound_data` removes /uncertainty/bound_side and bound_limit, as files written
  before stop 28 lack them.
"""

import h5py
import numpy as np

from laminid_cli.uncertainty import VERDICT_AT_BOUND

STR = h5py.string_dtype()


def _strings(ds) -> list[str]:
    return [x.decode() if isinstance(x, bytes) else str(x) for x in ds[()]]


def _replace(group, key, data, dtype=None):
    if key in group:
        del group[key]
    group.create_dataset(key, data=data, dtype=dtype)


def mark_at_bound(path, at_bound: dict, *, status="check", reasons=()):
    """``at_bound``: {label: (bound_text, side, limit SI)}; ``reasons``: [(code, text)] of the
    new status."""
    with h5py.File(path, "r+") as f:
        f.attrs["status"] = status
        g = f["status"]
        _replace(g, "codes", np.array([c for c, _ in reasons], dtype=object), STR)
        _replace(g, "texts", np.array([t for _, t in reasons], dtype=object), STR)
        u = f["uncertainty"]
        labels = _strings(u["labels"])
        verdict, texts = _strings(u["verdict"]), _strings(u["bound_text"])
        sides, limits = _strings(u["bound_side"]), u["bound_limit"][()].copy()
        flags = u["at_bound"][()].copy()
        lower, upper = u["lower"][()], u["upper"][()]
        for lab, (text, side, limit) in at_bound.items():
            j = labels.index(lab)
            flags[j], texts[j], verdict[j] = True, text, VERDICT_AT_BOUND
            sides[j], limits[j] = side, limit
            lower[j] = upper[j] = np.nan
        u["bound_limit"][...] = limits
        _replace(u, "bound_side", np.array(sides, dtype=object), STR)
        u["lower"][...], u["upper"][...] = lower, upper
        _replace(u, "at_bound", flags)
        _replace(u, "bound_text", np.array(texts, dtype=object), STR)
        _replace(u, "verdict", np.array(verdict, dtype=object), STR)


def make_version_1(path):
    """Rewrite a single-plate schema-2 result as schema version 1 wrote it (module docstring)."""
    with h5py.File(path, "r+") as f:
        f.attrs["schema_version"] = 1
        f.attrs["status"] = f.attrs["optimizer_status"]
        del f.attrs["optimizer_status"]
        del f["status"]
        for group in ("materials", "initial"):
            for key in list(f[group]):
                name = f[group][key].attrs["name"]
                f[group].move(key, name.replace("/", "\u2215"))
        if "uncertainty" in f:
            u = f["uncertainty"]
            for key in ("scale", "at_bound", "bound_text", "bound_side", "bound_limit"):
                del u[key]
            del u.attrs["chi2_limit_99"]
            v, hw = u["value"][()], u["half_width"][()]
            u["lower"][...], u["upper"][...] = v - hw, v + hw


def drop_bound_data(path):
    """Remove /uncertainty/bound_side and bound_limit (module docstring)."""
    with h5py.File(path, "r+") as f:
        for key in ("bound_side", "bound_limit"):
            del f["uncertainty"][key]
