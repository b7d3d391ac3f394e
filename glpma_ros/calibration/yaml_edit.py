"""NEW.yaml of ``glpma-fk calibrate``: the text of CONFIG with only the identified entries rewritten.

PyYAML cannot write a file back with its comments, and a round-trip YAML library is not a
dependency; the manipulator YAML's top-level entries are simple, so the text is edited instead:
an entry is its key's line at column 0 and the lines after it that are indented, start with ``-``
(a block sequence at the key's indentation) or are blank.  A block list keeps its key line (with
its comment) and the first item's indentation; a flow list (``key: [[..], ..]``) stays a flow list
with its comment; comments on the old items go with them.  ``leg_offsets``, when CONFIG has none,
goes after ``platform`` with a comment saying what it is.  An actuated family's per-leg entries (``origin``,
``crank``, ``axis``, ``rod``, ``platform`` of each item of ``legs``) are rewritten in place, each on its
own line with its comment; its ``actuator_offsets`` goes after ``legs`` when CONFIG has none.  Everything
else -- other keys, comments, blank lines, order -- is CONFIG's text unchanged, and a header comment says
what was calibrated.  The result is parsed again and checked against the values it should hold.
"""
from __future__ import annotations

import re

import numpy as np
import yaml

#: significant digits written: 12 keep a metre-sized geometry to the nanometre in any unit and are
#: far below any standard error of a calibration
DIGITS = 12
_KEY = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*:(.*)$")


def _number(v: float) -> str:
    text = f"{float(v):.{DIGITS}g}"
    return text if any(c in text for c in ".en") else text + ".0"


def _row(values) -> str:
    return "[" + ", ".join(_number(v) for v in values) + "]"


def _flow(value) -> str:
    arr = np.asarray(value, dtype=float)
    return _row(arr) if arr.ndim == 1 else "[" + ", ".join(_row(r) for r in arr) + "]"


def _split_comment(rest: str) -> tuple[str, str]:
    """``value`` and ``# comment`` (with its leading spaces) of the text after a key's colon."""
    k = rest.find("#")
    return (rest, "") if k < 0 else (rest[:k], rest[k:])


def _entries(lines: list) -> dict:
    """Top-level key -> (first line, end line exclusive) of its entry, trailing blank lines excluded."""
    out, k = {}, 0
    while k < len(lines):
        m = _KEY.match(lines[k])
        if not m:
            k += 1
            continue
        end = k + 1
        while end < len(lines) and (lines[end][:1] in (" ", "\t", "-") or not lines[end].strip()):
            end += 1
        last = end
        while last > k + 1 and not lines[last - 1].strip():
            last -= 1
        out[m.group(1)] = (k, last)
        k = end
    return out


def _rewrite(lines: list, start: int, end: int, key: str, value) -> list:
    m = _KEY.match(lines[start])
    val, comment = _split_comment(m.group(2))
    arr = np.asarray(value, dtype=float)
    if val.strip() or arr.ndim == 1:          # flow style (or a flat list: one line)
        return [f"{key}: {_flow(arr)}" + (f"  {comment.strip()}" if comment else "")]
    item = next((ln for ln in lines[start + 1:end] if ln.lstrip().startswith("-")), "  - ")
    indent = item[:len(item) - len(item.lstrip())]
    return [lines[start]] + [f"{indent}- {_row(r)}" for r in arr]


def _scalar_or_flow(value) -> str:
    arr = np.asarray(value, dtype=float)
    return _number(arr) if arr.ndim == 0 else _flow(arr)


def _leg_items(lines: list, start: int, end: int) -> list:
    """(first line, end line exclusive) of each item of the block list ``legs`` spanning lines
    [start, end): an item starts at a ``-`` at the first item's indentation."""
    starts = []
    indent = None
    for k in range(start + 1, end):
        stripped = lines[k].lstrip()
        if not stripped.startswith("-"):
            continue
        here = len(lines[k]) - len(stripped)
        if indent is None:
            indent = here
        if here == indent:
            starts.append(k)
    return [(a, b) for a, b in zip(starts, starts[1:] + [end])]


def _edit_leg_items(lines: list, start: int, end: int, per_leg: dict) -> list:
    """The lines [start, end) of the ``legs`` entry with each item's keys in ``per_leg`` (key -> one value
    per leg) rewritten as flow values, their comments kept."""
    out = list(lines[start:end])
    items = _leg_items(lines, start, end)
    if len(items) != len(next(iter(per_leg.values()))):
        raise RuntimeError("NEW.yaml: the 'legs' list is not one block item per leg")
    for key, values in per_leg.items():
        pattern = re.compile(r"^(\s*(?:-\s+)?)" + key + r"\s*:(.*)$")
        for (a, b), value in zip(items, values):
            k = next((k for k in range(a, b) if pattern.match(lines[k])), None)
            if k is None:
                raise RuntimeError(f"NEW.yaml: a leg has no '{key}' line to rewrite")
            m = pattern.match(lines[k])
            val, comment = _split_comment(m.group(2))
            if not val.strip():
                raise RuntimeError(f"NEW.yaml: a leg's '{key}' is not a flow value")
            new = f"{m.group(1)}{key}: {_scalar_or_flow(value)}"
            if comment:                     # at its old column where the new value leaves room
                column = len(lines[k]) - len(comment)
                new = new.ljust(column) if len(new) + 2 <= column else f"{new}  "
                new += comment.strip()
            out[k - start] = new
    return out


def edit_config(text: str, values: dict, header: list, offsets_comment: list, per_leg: dict | None = None,
                after: str = "platform") -> str:
    """CONFIG's ``text`` with the top-level entries in ``values`` (key -> array) and the ``legs`` items'
    entries in ``per_leg`` (key -> one value per leg) rewritten, ``header`` comment lines first;
    ``offsets_comment`` goes above an offsets entry that CONFIG did not have, after the entry ``after``."""
    lines = text.splitlines()
    entries = _entries(lines)
    if per_leg:
        lines[entries["legs"][0]:entries["legs"][1]] = _edit_leg_items(lines, *entries["legs"], per_leg)
    # bottom-up, so that the earlier entries' line numbers stay valid
    edits = []
    for key, value in values.items():
        if key in entries:
            edits.append((*entries[key], _rewrite(lines, *entries[key], key, value)))
        else:
            at = entries[after][1] if after in entries else len(lines)
            edits.append((at, at, [*offsets_comment, f"{key}: {_flow(value)}"]))
    for start, end, new in sorted(edits, key=lambda e: e[0], reverse=True):
        lines[start:end] = new
    return "\n".join([*header, *lines]) + "\n"


def _written(got, value, scale: float) -> bool:
    got = np.asarray(got, dtype=float)
    return got.shape == np.shape(value) and bool(np.allclose(got, value, rtol=10.0 ** (1 - DIGITS),
                                                             atol=scale * 10.0 ** (1 - DIGITS)))


def check_edit(text: str, values: dict, original: dict, scale: float, per_leg: dict | None = None) -> dict:
    """The parsed NEW text; raises RuntimeError (a bug here) unless it holds ``values`` and ``per_leg`` (to
    the digits written) and every other key of the ``original`` document (and of its legs) unchanged."""
    doc = yaml.safe_load(text)
    for key, value in values.items():
        if not _written(doc[key], value, scale):
            raise RuntimeError(f"NEW.yaml: '{key}' was not written as identified")
    per_leg = per_leg or {}
    for key, value in original.items():
        if key == "legs" and per_leg:
            for leg, old in zip(doc[key], value):
                if {k: v for k, v in leg.items() if k not in per_leg} != {k: v for k, v in old.items()
                                                                            if k not in per_leg}:
                    raise RuntimeError("NEW.yaml: a leg's other entries changed")
        elif key not in values and doc.get(key) != value:
            raise RuntimeError(f"NEW.yaml: '{key}' changed")
    for key, values_ in per_leg.items():
        if not all(_written(leg[key], v, scale) for leg, v in zip(doc["legs"], values_)):
            raise RuntimeError(f"NEW.yaml: the legs' '{key}' were not written as identified")
    return doc
