"""Test helper: turn a result file written by today's writer into one with the schema-2 fields
of /work SCHEMA.md that branch i11a writes (status + reasons, physical intervals, scale,
at_bound, bound_text), so the reader and the report can be tested before that writer exists."""

import h5py
import numpy as np


def add_schema2_fields(path, *, status="ok", reasons=(), at_bound=None, log_scale=True):
    """Add root attrs status/optimizer_status, /status (codes, texts) and the /uncertainty
    datasets scale, at_bound, bound_text to the result file ``path`` (in place).

    ``reasons``: [(code, text)]; ``at_bound``: {label: bound_text} of constants at a bound (their
    verdict becomes "at bound — not identified", their interval one-sided from 0 to the value's
    upper end). With ``log_scale`` the moduli intervals are recomputed on ln P from the stored
    value and std (asymmetric, > 0), as i11a does: exp(ln v -/+ q std/v).
    """
    at_bound = at_bound or {}
    s = h5py.string_dtype()
    with h5py.File(path, "r+") as f:
        if "optimizer_status" not in f.attrs:         # version 1 file: status was nlopt's
            f.attrs["optimizer_status"] = f.attrs["status"]
        f.attrs["status"] = status
        if "status" in f:                               # the writer's own /status replaced
            del f["status"]
        g = f.create_group("status")
        g.create_dataset("codes", data=np.array([c for c, _ in reasons], dtype=object), dtype=s)
        g.create_dataset("texts", data=np.array([t for _, t in reasons], dtype=object), dtype=s)
        if "uncertainty" not in f:
            return
        u = f["uncertainty"]
        labels = [x.decode() if isinstance(x, bytes) else x for x in u["labels"][()]]
        value, std = u["value"][()], u["std"][()]
        q = float(u.attrs["quantile"])
        lower, upper = u["lower"][()], u["upper"][()]
        scale, flags, texts = [], [], []
        verdict = [x.decode() if isinstance(x, bytes) else x for x in u["verdict"][()]]
        for j, lab in enumerate(labels):
            is_mod = not lab.endswith(".nu12")
            scale.append("log" if is_mod and log_scale else "linear")
            if is_mod and log_scale:
                r = q * std[j] / abs(value[j])
                lower[j], upper[j] = value[j] * np.exp(-r), value[j] * np.exp(r)
            flags.append(lab in at_bound)
            texts.append(at_bound.get(lab, ""))
            if lab in at_bound:
                verdict[j] = "at bound — not identified"
                lower[j] = 0.0
        u["lower"][...] = lower
        u["upper"][...] = upper
        del u["verdict"]
        u.create_dataset("verdict", data=np.array(verdict, dtype=object), dtype=s)
        for key in ("scale", "at_bound", "bound_text"):   # the writer's own, replaced
            if key in u:
                del u[key]
        u.create_dataset("scale", data=np.array(scale, dtype=object), dtype=s)
        u.create_dataset("at_bound", data=np.array(flags, bool))
        u.create_dataset("bound_text", data=np.array(texts, dtype=object), dtype=s)
