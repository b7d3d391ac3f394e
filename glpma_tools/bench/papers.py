"""The published figures the benchmark reproduces, read once from ``papers.yaml`` (its comments cite each: 001
Tables 5 and 8, 002 section 5.5.2, 004 section IV.A and Table II).  A row is a dict named by its table's
``columns``."""
from __future__ import annotations

from importlib.resources import files

import yaml

_DATA = yaml.safe_load((files(__package__) / "papers.yaml").read_text(encoding="utf-8"))


def _rows(table: dict) -> list[dict]:
    return [dict(zip(table["columns"], row)) for row in table["rows"]]


#: 001 Tables 5 and 8 by model kind: {(solver, population, local population or None): row}
PUBLISHED = {kind: {(r["solver"], r["population"], r["local_population"]): r for r in _rows(t)}
             for kind, t in _DATA["tables"].items()}
TABLE_NAME = {kind: t["name"] for kind, t in _DATA["tables"].items()}
#: 002 section 5.5.2
ALL_SOLUTIONS = _DATA["all_solutions"]
#: success (%) of faithful pure G3-PCX implementations on 001 Table 5's protocol in earlier runs of this project
FAITHFUL_3RPR = _DATA["faithful_3rpr"]
#: 004 Table II
TABLE2 = _rows(_DATA["table2"])
#: the protocol of 004 section IV.A: init_range, population, tolerance, runs
TABLE2_PROTOCOL = _DATA["table2"]["protocol"]
