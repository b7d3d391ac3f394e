"""``glpma-fk stress``: reliability: overload, burst, restarts, deadlines against a real node.

The ``glpma_fk`` node under overload, bursts, restarts and deadlines.

Starts a real node process over Cyclone DDS (``python -m glpma_ros.node.dds.node``, cold start,
``/diagnostics`` every 0.2 s) and drives it from this process as a controller would, along the
simulated loop (:mod:`glpma_tools.sim.trajectories`):

* **overload** and **burst** (:mod:`.flood`): inputs at 1 kHz, then as fast as the writer can;
  the node keeps the newest input and counts the ones it replaced, and its memory must not grow;
* **restarts** (:mod:`.restarts`): the controller restarts, the legs jump to another assembly
  mode's trajectory, the node restarts -- the estimator must recover;
* **deadline** (:mod:`.deadline`): in-process Estimator solves that only the deadline stops.

Counts come from the node's ``/diagnostics`` (differences of its counters over each phase);
"lost in transport" is what the controller wrote and the node never received (DDS keep-last
history of ``qos_depth`` on both sides); latency is end to end, controller write -> pose received,
for the inputs that got a pose; every pose is paired with the input it answers
(:mod:`glpma_ros.testing.matching`).  The figures go to a JSON file (``--json-out``) from which
``glpma-fk bench`` renders the Reliability section of BENCHMARKS.md.

Each phase has ``checks``, which hold on any machine (counters add up, every pose answers an
input, the node lives), and ``expectations`` (shares answered, warm starts, little lost in
transport), which hold on an idle machine and are reported as met or missed.

Run: ``python -m glpma_tools.stress [--quick] [--json] [--json-out FILE]``; exit status 0 when
every check passed, 1 when one failed, 2 for bad arguments.
"""
from .cli import SECTIONS, main, run
from .flood import burst, overload
from .restarts import controller_restart, large_jump, node_restart
from .session import LOST_SLACK, RSS_SLACK_MB, Session

__all__ = ["LOST_SLACK", "RSS_SLACK_MB", "SECTIONS", "Session", "burst", "controller_restart", "large_jump", "main",
           "node_restart", "overload", "run"]
