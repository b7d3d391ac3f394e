"""``glpma-fk modes``: ask a running node (over Cyclone DDS) for every assembly mode of its last input.  No
compiled code runs here: the node computes the modes."""
from __future__ import annotations

from ..node.dds import modes_client
from .api import OneLineParser, command_main, positive_float

#: the command's --help text
DESCRIPTION = ("Publish ~/request_assembly_modes to a running glpma_fk node over Cyclone DDS (ROS_DOMAIN_ID, "
               "CYCLONEDDS_URI as for the node), wait for its answer on ~/assembly_modes and print the poses "
               "(metres, quaternion x y z w). Exit 1 when no node answers or the node reports why it could not.")


def build_parser() -> OneLineParser:
    q = OneLineParser(prog="glpma-fk modes", description=DESCRIPTION)
    q.add_argument("--node", default="glpma_fk", help="name of the node (default glpma_fk)")
    q.add_argument("--timeout", type=positive_float, default=120.0,
                   help="seconds to wait for the answer (default 120)")
    q.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return q




@command_main
def main(argv=None) -> int:
    return modes_client.main(build_parser().parse_args(argv))
