"""Write fitted natural frequencies into a specimen file's ``measured:`` mapping.

Only ``measured.frequencies`` (Hz, ``null`` for a mode not found), ``measured.sigma`` (Hz,
standard deviations), ``measured.sigma_source`` (how the sigmas were made),
``measured.damping`` and ``measured.damping_sigma`` (viscous damping ratios and their standard
deviations, when given) and, when asked or already present, ``measured.weights`` change, and
only the lines of those entries (:func:`splice_measured`, on the text: every other byte of the
file stays as it was, comments, block scalars, line endings included). A replaced line loses
its comment, which described the values replaced (``# Hz, Table 1`` beside frequencies now
fitted from FRFs); the frequencies line gets the comment the caller gives (``laminid fit-frf``:
``# Hz, laminid fit-frf of plate.frf.h5``); carried weights keep theirs. The file is never
left half-written or invalid:

0. the specimen file is read and validated first (:func:`laminid_cli.specimen.read_specimen`,
   with its bounded YAML checks): an invalid specimen is refused and left untouched;
1. the edited document is serialised to text and parsed back with ``yaml.safe_load``; the
   result must equal the original document except for those keys, and the new lists must read
   back exactly, and the edited text must be a valid specimen;
2. where the edited text is the file's own (the same FRFs fitted into it again), nothing is
   written and no backup made (``MeasuredEdit.unchanged``);
3. the original is copied to a backup that did not exist before: ``SPEC.yaml.bak``, then
   ``SPEC.yaml.bak1``, ``SPEC.yaml.bak2``, ... (an existing backup is never overwritten; when
   the newest backup already holds exactly the current text no new one is made);
4. the text goes to a temporary file in the same folder, is fsynced and renamed over the
   specimen file (``os.replace`` is atomic).
"""

from __future__ import annotations

import codecs
import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from laminid_cli.errors import SpecimenError

KEYS = ("frequencies", "sigma", "weights", "damping", "damping_sigma", "damping_sigma_source")
#: longest line a written entry may have before PyYAML would fold it (never: one line each)
_WIDTH = 10**9
#: a user's weight follows its mode to the new fit when their frequencies are within this
#: relative distance (one to one, nearest first)
WEIGHT_MATCH_REL = 0.01
#: most numbered backups looked for (SPEC.bak, SPEC.bak1 ... SPEC.bak<N>)
MAX_BACKUPS = 9999


@dataclass(frozen=True)
class MeasuredEdit:
    """What :func:`write_measured` did.

    path : the specimen file; backup : the backup holding the previous text (None without
    ``backup``); backup_new : False when the newest backup already held exactly that text;
    weight_notes : sentences on the user's weights that could not follow their modes (empty
    when every weight was kept or none was given); damping_written : False when every damping
    ratio given was null (none written; an earlier fit's lists are removed, ``damping_notes``);
    unchanged : True when the file already held exactly the text to write (a fit-frf --into
    run again on the same FRFs): nothing written, no backup made
    """

    path: Path
    backup: Path | None
    backup_new: bool
    weight_notes: tuple[str, ...]
    damping_written: bool = True
    damping_notes: tuple[str, ...] = ()
    unchanged: bool = False

    @property
    def backup_text(self) -> str:
        if self.unchanged:
            return "unchanged: it held them already; no backup made"
        if self.backup is None:
            return "no backup"
        if self.backup_new:
            return f"previous version in {self.backup}"
        return f"previous version already in {self.backup}"


def _f(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) and v > 0 else None


def _w(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if 0 <= v <= 1 else None


def carry_weights(old_freq, old_weights, new_freq, rel: float = WEIGHT_MATCH_REL):
    """The user's weights for the new frequencies, each following its mode by frequency.

    Parameters
    ----------
    old_freq, old_weights : the file's lists (same length; None for a mode not found)
    new_freq : the new frequencies (None for a mode not found)
    rel : two modes are the same when their frequencies differ by at most ``rel`` of the old one

    Modes are paired one to one, nearest relative distance first. A new mode not found gets 0;
    a found mode with no old partner gets 1 (it was not weighted before). Returns ``(weights,
    notes)``: ``notes`` names every old weight other than 1 (of a found mode) that has no
    partner and so is dropped, and the new modes that got 1 for want of one, when the user had
    any weight other than 1.

    >>> carry_weights([100.0, 200.0, 300.0], [1, 0, 0.5], [100.2, 299.0])
    ([1, 0.5], ['the weight 0 of the mode at 200 Hz was dropped: no fitted mode within 1 % of it'])
    """
    old_f = [_f(x) for x in old_freq]
    old_w = [_w(w) for w in old_weights]
    new_f = [_f(x) for x in new_freq]
    pairs = sorted((abs(nf - of) / of, i, j) for i, nf in enumerate(new_f) if nf is not None
                   for j, of in enumerate(old_f) if of is not None and abs(nf - of) <= rel * of)
    partner: dict[int, int] = {}
    used: set[int] = set()
    for _, i, j in pairs:
        if i not in partner and j not in used:
            partner[i] = j
            used.add(j)
    weights = []
    for i, nf in enumerate(new_f):
        if nf is None:
            weights.append(0)
        elif i in partner and old_w[partner[i]] is not None:
            w = old_w[partner[i]]
            weights.append(int(w) if w.is_integer() else w)
        else:
            weights.append(1)
    notes = []
    for j, (of, w) in enumerate(zip(old_f, old_w)):
        if of is not None and j not in used and w is not None and w != 1:
            notes.append(f"the weight {w:g} of the mode at {of:g} Hz was dropped: no fitted mode "
                         f"within {100 * rel:g} % of it")
    custom = any(w is not None and w != 1 for of, w in zip(old_f, old_w) if of is not None)
    fresh = [f"{nf:g}" for i, nf in enumerate(new_f) if nf is not None and i not in partner]
    if custom and fresh:
        notes.append(f"weight 1 for the mode(s) at {', '.join(fresh)} Hz: no mode of the file "
                     f"within {100 * rel:g} % had a weight")
    return weights, notes


def _next_backup(spec_path: Path, text: bytes) -> tuple[Path, bool]:
    """A backup file of ``text`` that overwrites nothing: SPEC.bak, SPEC.bak1, SPEC.bak2...

    The newest existing backup is reused when it holds exactly ``text``. The new file is
    created exclusively (``open(..., "xb")``), so two runs at once cannot take the same name.
    """
    names = [spec_path.with_name(spec_path.name + ".bak")] + [
        spec_path.with_name(f"{spec_path.name}.bak{k}") for k in range(1, MAX_BACKUPS + 1)]
    newest = None
    for k, name in enumerate(names):
        if not name.exists():
            if newest is not None:
                try:
                    if newest.read_bytes() == text:
                        return newest, False
                except OSError:
                    pass
            try:
                with open(name, "xb") as fh:
                    fh.write(text)
                    fh.flush()
                    os.fsync(fh.fileno())
            except FileExistsError:      # taken meanwhile: look further
                newest = name
                continue
            except OSError as exc:
                raise SpecimenError(f"cannot write the backup {name} ({exc}); file left "
                                    "unchanged", path=str(spec_path)) from exc
            shutil.copystat(spec_path, name)
            return name, True
        newest = name
    raise SpecimenError(f"{MAX_BACKUPS + 1} backups ({names[0].name} ... {names[-1].name}) "
                        "exist already; move some away; file left unchanged",
                        path=str(spec_path))


def _content_end(node) -> int:
    """Index just past the last character of ``node``'s own text: PyYAML ends a block
    collection (and may end a block scalar) at the next token, after the blank and comment
    lines between; those belong to what follows."""
    import yaml

    if isinstance(node, yaml.SequenceNode) and not node.flow_style and node.value:
        return _content_end(node.value[-1])
    if isinstance(node, yaml.MappingNode) and not node.flow_style and node.value:
        return _content_end(node.value[-1][1])
    return node.end_mark.index


def _line_end(text: str, index: int) -> int:
    """Index of the line break ending the line that holds ``text[index - 1]`` (len at EOF)."""
    k = index
    while k > 0 and text[k - 1] in " \t\r\n":   # back onto the content's last character
        k -= 1
    end = text.find("\n", k)
    if end < 0:
        return len(text)
    return end - 1 if end > 0 and text[end - 1] == "\r" else end


def _line_start(text: str, index: int) -> int:
    return text.rfind("\n", 0, index) + 1


def _entry_text(key: str, value, comment: str | None = None) -> str:
    """``key: value`` on one line (a list in flow style), PyYAML's plain-safe spelling (so
    that it reads back as the same value), with ``# comment`` after it."""
    import yaml

    # None: the list in flow style, the mapping around it in block style (a scalar alone
    # would make that mapping a flow one)
    line = yaml.safe_dump({key: value}, width=_WIDTH, allow_unicode=True, sort_keys=False,
                          default_flow_style=None if isinstance(value, list) else False
                          ).rstrip("\n")
    if "\n" in line:                   # pragma: no cover - lists of scalars, one-line strings
        raise ValueError(f"{key}: not a one-line value")
    if comment:
        # one line of printable text: a file name may hold anything
        comment = "".join(c if c.isprintable() else "?" for c in " ".join(comment.split()))
        line += f"   # {comment}"
    return line


def splice_measured(text: str, updates: dict, removals=(), comments: dict | None = None,
                    keep_comments=(), path: str = "<string>") -> str:
    """``text`` with the ``measured:`` entries ``updates`` written and ``removals`` removed,
    and not one other character changed.

    Parameters
    ----------
    text : YAML whose root is a block mapping (a specimen file)
    updates : {key: value} of ``measured``; each is written on one line, ``key: [..]``, over
        the lines the key's old entry had (its comments there go with it: they described the
        old values) or, for a new key, on a new line after the mapping's last entry
    removals : keys of ``measured`` whose lines are removed
    comments : {key: text} comments of written lines
    keep_comments : keys whose entry keeps the comment after its old value (the user's weights,
        carried to the new modes, keep what the user said of them)

    A ``measured`` that is absent is added after the root mapping's last entry; one that is
    empty (null) gets its entries below it; one written as a flow mapping
    (``measured: {...}``) is written again as a block mapping (its other entries re-spelt,
    same values). The caller checks that the result reads back as intended.
    """
    import yaml

    comments = comments or {}
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        raise SpecimenError(f"not valid YAML ({exc}); file left unchanged", path=path) from exc
    if not isinstance(root, yaml.MappingNode):
        raise SpecimenError("the specimen file must be a YAML mapping; file left unchanged",
                            path=path)
    if root.flow_style:
        raise SpecimenError("the file is one flow mapping ({...}); --into edits a specimen "
                            "written in block style (one 'key: value' per line); file left "
                            "unchanged", path=path)
    nl = "\r\n" if "\r\n" in text else "\n"
    edits: list[tuple[int, int, str]] = []          # (start, end, new text), disjoint

    entry = next(((k, v) for k, v in root.value
                  if isinstance(k, yaml.ScalarNode) and k.value == "measured"), None)
    if entry is None or not isinstance(entry[1], yaml.MappingNode) or entry[1].flow_style:
        # a whole block of its own: after the root's last entry, or over the old value
        values = {}
        if entry is not None and isinstance(entry[1], yaml.MappingNode):
            values = yaml.safe_load(text[entry[1].start_mark.index:entry[1].end_mark.index])
            values = {k: v for k, v in (values or {}).items() if k not in removals}
        elif entry is not None and not (isinstance(entry[1], yaml.ScalarNode)
                                        and entry[1].tag == "tag:yaml.org,2002:null"):
            raise SpecimenError("'measured' must be a mapping; file left unchanged",
                                path=path, field="measured")
        values.update(updates)
        indent = " " * root.value[0][0].start_mark.column
        lines = [indent + "  " + _entry_text(k, v, comments.get(k)) for k, v in values.items()]
        if entry is None:
            at = _line_end(text, _content_end(root.value[-1][1]))
            edits.append((at, at, nl + indent + "measured:" + nl + nl.join(lines)))
        elif isinstance(entry[1], yaml.MappingNode):
            # the flow mapping's lines, with their comments (of the values replaced)
            colon = text.index(":", entry[0].end_mark.index) + 1
            edits.append((colon, _line_end(text, entry[1].end_mark.index),
                          nl + nl.join(lines)))
        else:
            # null: a "~" or "null" written out goes, the line's comment stays
            value = entry[1]
            if value.end_mark.index > value.start_mark.index:
                colon = text.index(":", entry[0].end_mark.index) + 1
                edits.append((colon, value.end_mark.index, ""))
            at = _line_end(text, entry[0].end_mark.index)
            edits.append((at, at, nl + nl.join(lines)))
    else:
        measured = entry[1]
        indent = " " * measured.value[0][0].start_mark.column
        spans = {k.value: (k.start_mark.index, _line_end(text, _content_end(v)),
                           _content_end(v))
                 for k, v in measured.value if isinstance(k, yaml.ScalarNode)}
        for key, value in updates.items():
            if key in spans:
                start, end, value_end = spans[key]
                piece = _entry_text(key, value, comments.get(key))
                tail = text[value_end:end]
                if key in keep_comments and tail.lstrip(" \t").startswith("#"):
                    piece += tail
                edits.append((start, end, piece))
        new = [indent + _entry_text(k, v, comments.get(k)) for k, v in updates.items()
               if k not in spans]
        last = measured.value[-1][0].value
        for key in removals:
            if key in spans:
                start, end, _ = spans[key]
                if key == last and new:      # its lines become the new entries
                    edits.append((_line_start(text, start), end, nl.join(new)))
                    new = []
                    continue
                # the whole lines, with their line break
                stop = end + len(nl) if text.startswith(nl, end) else end
                edits.append((_line_start(text, start), stop, ""))
        if new:
            at = _line_end(text, _content_end(measured.value[-1][1]))
            edits.append((at, at, nl + nl.join(new)))
    out = text
    for start, end, piece in sorted(edits, reverse=True):
        out = out[:start] + piece + out[end:]
    return out


def _round(x: float | None, digits: int) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return round(float(x), digits)


def _sig(x, digits: int = 6) -> float | None:
    """``x`` to ``digits`` significant digits (damping ratios are small numbers)."""
    if x is None or not math.isfinite(x):
        return None
    return float(f"{float(x):.{digits - 1}e}")


#: the comment of a written ``measured.damping`` line: ratios, not percent, not loss factors
DAMPING_COMMENT = "viscous damping ratios zeta, fractions (0.008 = 0.8 %); loss factor eta = 2 zeta"


def write_measured(spec_path, freq_hz, sigma_hz=None, weights=None, *, damping=None,
                   damping_sigma=None, backup: bool = True,
                   validate: bool = True, sigma_source: str | None = None,
                   damping_sigma_source: str | None = None,
                   comment: str | None = None, log_warnings: bool = True) -> MeasuredEdit:
    """Replace/insert the measured frequencies (and sigma, weights) of a specimen YAML file.

    Parameters
    ----------
    spec_path : specimen YAML file (must exist and hold a mapping)
    freq_hz : (n,) Hz; None/NaN for a mode not found (written as ``null``)
    sigma_hz : (n,) Hz or None; standard deviations (``null`` where the frequency is null)
    weights : (n,) in [0, 1] or None. When None and the file already has ``weights``: each
        weight follows its mode to the new list by frequency (:func:`carry_weights`: within
        1 %, one to one); 0 where the new frequency is null, 1 for a mode with no partner. A
        weight other than 1 that cannot follow is named in the returned ``weight_notes``.
    damping, damping_sigma : (n,) viscous damping ratios and their standard deviations, or
        None (written to ``measured.damping`` / ``measured.damping_sigma``, 6 significant
        digits; None/NaN for a mode without one: null). When every ratio is None/NaN nothing is
        written and lists of an earlier fit are removed (see the returned ``damping_notes``)
    backup : keep the original in a new backup file (``<spec>.bak``, ``<spec>.bak1``, ...;
        an existing one is never overwritten)
    validate : the file must be a valid specimen before and after the edit (``laminid
        fit-frf --into``); without it only the YAML checks (bounded size, depth, aliases, no
        tags) and the structure of ``measured`` are required (any YAML mapping is edited)
    log_warnings : with ``validate``, the specimen reader's warnings on the file as it was
        (a mass that density x volume contradicts...) are logged (laminid_cli.specimen's
        logger), once: the check after the edit logs none. False for a caller that read the
        file itself and gave them already (fit-frf --into, before its fit)
    sigma_source : written as ``measured.sigma_source`` (shown by identify), with ``sigma_hz``
    damping_sigma_source : written as ``measured.damping_sigma_source`` (shown by identify),
        with ``damping_sigma``; an earlier one is removed when damping is written without it
    comment : the comment of the new ``frequencies`` line (where they came from); the lines
        replaced lose theirs, which spoke of the values replaced

    Only the lines of the entries written or removed change; every other byte of the file
    (comments, block and multi-line scalars, line endings, a byte-order mark) is kept
    (:func:`splice_measured`).

    Returns a :class:`MeasuredEdit` (the backup's path, the notes on the weights).
    """
    import yaml

    from laminid_cli.specimen import check_yaml_text, load_specimen_text, read_specimen

    spec_path = Path(spec_path)
    if spec_path.is_symlink():          # edit the file it points to; the link stays a link
        spec_path = Path(os.path.realpath(spec_path))
    parsed = None
    if validate:   # the whole specimen must be valid before anything is edited
        # (its warnings logged here, as fit-frf --into logs them, unless the caller gave them
        # already: fit-frf --into read the file before the fit; after the edit, never again)
        parsed = read_specimen(spec_path, log_warnings=log_warnings)
    try:
        # bytes as they are: line endings and a byte-order mark are kept
        raw = spec_path.read_bytes()
        text = raw.decode("utf-8-sig")
    except FileNotFoundError as exc:
        raise SpecimenError("file not found", path=str(spec_path)) from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecimenError(f"cannot read the file ({exc})", path=str(spec_path)) from exc
    bom = codecs.BOM_UTF8 if raw.startswith(codecs.BOM_UTF8) else b""
    # bounded before PyYAML builds anything from it (aliases, depth, tags, size)
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
    drop_damping = "damping" in extra and all(v is None for v in extra["damping"])
    if drop_damping:   # no mode's damping measured: an all-null list is no valid specimen
        extra.clear()
    if "damping_sigma" in extra and damping_sigma_source:
        extra["damping_sigma_source"] = str(damping_sigma_source)
    if weights is not None:
        if len(weights) != len(freq):
            raise ValueError("weights and freq_hz differ in length")
        wts = [float(w) if ok else 0.0 for w, ok in zip(weights, found)]
    else:
        wts = None

    measured = original.get("measured")
    if measured is not None and not isinstance(measured, dict):
        raise SpecimenError("'measured' must be a mapping; file left unchanged",
                            path=str(spec_path), field="measured")
    measured = measured or {}
    weight_notes: list[str] = []
    carried = wts is None and "weights" in measured
    if carried:
        old = measured["weights"]
        old_f = measured.get("frequencies")
        if parsed is not None and parsed.measured is not None:   # values with units read
            old_f = [None if not math.isfinite(x) else float(x) for x in parsed.measured.freq]
            old = [float(x) for x in parsed.measured.weight]
        if isinstance(old, list) and isinstance(old_f, list) and len(old) == len(old_f):
            # the user's weights follow their modes by frequency
            wts, weight_notes = carry_weights(old_f, old, freq)
        else:
            wts = [1 if ok else 0 for ok in found]
            weight_notes = ["the file's weights did not pair with its frequencies; rewritten "
                            "as 1 for the modes found and 0 for the others"]

    updates: dict = {"frequencies": freq}
    removals = []
    if sig is not None:
        updates["sigma"] = sig
        if sigma_source:
            updates["sigma_source"] = str(sigma_source)
        elif "sigma_source" in measured:
            removals.append("sigma_source")            # it described the previous sigmas
    if wts is not None:
        updates["weights"] = wts
    updates.update(extra)
    damping_notes = []
    if drop_damping:
        for key in ("damping", "damping_sigma"):
            if key in measured:
                removals.append(key)
                damping_notes.append(f"measured.{key} removed (it described an earlier fit)")
    if "damping_sigma_source" in measured and "damping_sigma_source" not in extra and (
            drop_damping or "damping_sigma" in extra):
        removals.append("damping_sigma_source")     # it described the previous sigmas
    comments = {"frequencies": comment} if comment else {}
    if "damping" in updates:
        # 0.008 beside a table's 'zeta (%) 0.800' reads as a loss factor as well: say which
        comments["damping"] = DAMPING_COMMENT
    new_text = splice_measured(text, updates, removals, comments=comments or None,
                               keep_comments=("weights",) if carried else (),
                               path=str(spec_path))

    # re-validate: plain parse; only the measured lists may differ
    try:
        check = yaml.safe_load(new_text)
    except yaml.YAMLError as exc:  # pragma: no cover - would be a bug of splice_measured
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
    if drop_damping:
        exp_measured.pop("damping", None)
        exp_measured.pop("damping_sigma", None)
    if "damping_sigma_source" in removals:
        exp_measured.pop("damping_sigma_source", None)
    expect["measured"] = exp_measured
    try:   # the edited file must be a valid specimen too (e.g. weights of the right length)
        if validate:
            load_specimen_text(new_text, str(spec_path), log_warnings=False)
    except SpecimenError as exc:
        raise SpecimenError(f"the edited file would not be a valid specimen ({exc}); file left "
                            "unchanged", path=str(spec_path)) from exc

    if check != expect:
        raise SpecimenError("edited file would not read back as intended; file left unchanged",
                            path=str(spec_path), field="measured")

    try:
        current = spec_path.read_bytes()
    except OSError as exc:
        raise SpecimenError(f"cannot read ({exc}); file left unchanged",
                            path=str(spec_path)) from exc
    if current == bom + new_text.encode("utf-8"):
        # the same FRFs fitted into the same file again: it was rewritten as it was, with a
        # backup of that same text beside the one before (plate.yaml.bak1 = plate.yaml)
        return MeasuredEdit(path=spec_path, backup=None, backup_new=False,
                            weight_notes=tuple(weight_notes), damping_written=not drop_damping,
                            damping_notes=tuple(damping_notes), unchanged=True)
    bak, bak_new = None, False
    if backup:
        bak, bak_new = _next_backup(spec_path, current)
    tmp = spec_path.with_name(f".{spec_path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as fh:
            fh.write(bom + new_text.encode("utf-8"))
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
    return MeasuredEdit(path=spec_path, backup=bak, backup_new=bak_new,
                        weight_notes=tuple(weight_notes), damping_written=not drop_damping,
                        damping_notes=tuple(damping_notes))
