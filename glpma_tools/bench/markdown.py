"""The pieces every section of BENCHMARKS.md is written with: the prose of ``templates/*.md`` (:func:`prose`),
blocks of Markdown, figure links, table cells, the solvers' labels.  A leaf: the sections import it, it
imports no section."""
from __future__ import annotations

import functools
import os
import re
from importlib.resources import files
from string import Template

from glpma_tools.tables import fmt, table

SOLVER_LABEL = {"rcga": "RCGA", "g3pcx": "G3-PCX", "glpma": "GLPMA", "de": "DE"}
_BLOCK = re.compile(r"^<!-- (\w+) -->$", re.M)


@functools.lru_cache(maxsize=None)
def _blocks(section: str) -> dict:
    parts = _BLOCK.split((files(__package__) / "templates" / f"{section}.md").read_text(encoding="utf-8"))
    return {name: text.strip() for name, text in zip(parts[1::2], parts[2::2])}


def prose(section: str, block: str = "intro", **values) -> str:
    """The paragraph ``block`` of ``templates/<section>.md`` with its ``$name`` fields filled in."""
    return Template(_blocks(section)[block]).substitute(values)


def md_blocks(*blocks) -> list[str]:
    """Lines of Markdown: each block (a heading, paragraph or table; empty or None: left out) and a blank line."""
    return [line for block in blocks if block for line in (block, "")]


def figure_link(res, name, md_path, alt=None) -> str | None:
    """The image link of the figure ``name`` (alt text: its file name), None when it was not drawn."""
    path = res["figures"].get(name)
    link = path and os.path.relpath(path, os.path.dirname(os.path.abspath(md_path)))    # from the report's directory
    return link and f"![{alt or os.path.basename(path)}]({link})"


def pct(v, digits: int = 3) -> str:
    """A percentage for a table."""
    return fmt(v, digits) + " %"


def cell(v) -> str:
    """A table cell: text as it is, a tuple as ``a / b``, a number through :func:`fmt`."""
    if isinstance(v, tuple):
        return " / ".join(map(cell, v))
    return v if isinstance(v, str) else fmt(v)


def dict_table(rows: list[dict], first: str | None = None) -> str:
    """Rows of one shape as a table under their keys (the first column's header: ``first`` when given)."""
    head = list(rows[0])
    return table([first or head[0], *head[1:]], [[cell(v) for v in row.values()] for row in rows])


def key_values(title: str, values: dict, unit: str = "value") -> str:
    """A two-column table: each key and its value (under ``unit``)."""
    return table([title, unit], [[k, cell(v)] for k, v in values.items()])
