"""``glpma-fk bench``: the papers' tables against our solvers and peer implementations, warm-tracking
latency, deadline honouring and the node over DDS end to end; writes BENCHMARKS.md (with the Reliability
figures ``glpma-fk stress`` left as JSON) and PNG figures.  See ``runner.build_parser``."""
from .runner import main as main
