"""``glpma-fk bench``: the papers' tables against our solvers and peer
implementations, warm-tracking latency, deadline honouring and the DDS end-to-end
hook; writes BENCHMARKS.md and PNG figures.  See ``runner.build_parser``."""
from .runner import main

__all__ = ["main"]
