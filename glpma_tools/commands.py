"""The tools' commands of ``glpma-fk``, registered in setup.py's entry-point group ``glpma_fk.commands``
(``"bench = glpma_tools.commands:BENCH [tools]"``, with the extra each needs).  ``glpma-fk --help`` reads
these lines without importing the tools; a command's module is imported when it runs."""
from glpma_ros.cli.api import Command

BAG = Command("the node's poses for a recorded rosbag2, offline", "glpma_tools.bag:main")
BENCH = Command("the papers' tables, peers, latency, deadlines and the node end to end; writes BENCHMARKS.md",
                "glpma_tools.bench.runner:main")
DEMO = Command("the glpma_fk node tracking a simulated manipulator, end to end", "glpma_tools.demo:main")
MAP = Command("assembly-mode map of a 2-D slice of the workspace", "glpma_tools.workspace_map:main")
STRESS = Command("reliability: overload, burst, restarts, deadlines against a real node", "glpma_tools.stress:main")
