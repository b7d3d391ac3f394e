"""NEW.yaml of ``glpma-fk calibrate``: the text of CONFIG with only the identified entries rewritten.

PyYAML cannot write a file back with its comments, and a round-trip YAML library is not a
dependency; the manipulator YAML's top-level entries are simple, so the text is edited instead:
an entry is its key's line at column 0 and the lines after it that are indented, start with ``-``
(a block sequence at the key's indentation) or are blank.  A block list keeps its key line (with
its comment) and the first item's indentation; a flow list (``key: [[..], ..]``) stays a flow list
with its comment; comments on the old items go with them.  ``leg_offsets``, when CONFIG has none,
goes after ``platform`` with a comment saying what it is.  Everything else -- other keys, comments,
blank lines, order -- is CONFIG's text unchanged, and a header comment says what was calibrated.
The result is parsed again and checked against the values it should hold.
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


def edit_config(text: str, values: dict, header: list, offsets_comment: list) -> str:
    """CONFIG's ``text`` with the entries in ``values`` (key -> array) rewritten, ``header`` comment
    lines first; ``offsets_comment`` goes above a ``leg_offsets`` entry that CONFIG did not have."""
    lines = text.splitlines()
    entries = _entries(lines)
    # bottom-up, so that the earlier entries' line numbers stay valid
    edits = []
    for key, value in values.items():
        if key in entries:
            edits.append((*entries[key], _rewrite(lines, *entries[key], key, value)))
        else:
            at = entries["platform"][1] if "platform" in entries else len(lines)
            edits.append((at, at, [*offsets_comment, f"{key}: {_flow(value)}"]))
    for start, end, new in sorted(edits, key=lambda e: e[0], reverse=True):
        lines[start:end] = new
    return "\n".join([*header, *lines]) + "\n"


def check_edit(text: str, values: dict, original: dict, scale: float) -> dict:
    """The parsed NEW text; raises RuntimeError (a bug here) unless it holds ``values`` (to the digits written)
    and every other key of the ``original`` document unchanged."""
    doc = yaml.safe_load(text)
    for key, value in values.items():
        got = np.asarray(doc[key], dtype=float)
        if got.shape != np.shape(value) or not np.allclose(got, value, rtol=10.0 ** (1 - DIGITS),
                                                           atol=scale * 10.0 ** (1 - DIGITS)):
            raise RuntimeError(f"NEW.yaml: '{key}' was not written as identified")
    for key, value in original.items():
        if key not in values and doc.get(key) != value:
            raise RuntimeError(f"NEW.yaml: '{key}' changed")
    return doc
