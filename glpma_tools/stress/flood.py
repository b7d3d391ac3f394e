"""Overload and burst: more inputs than the node can solve.  The node keeps the newest input and
counts the ones it replaced (dropped), DDS overwrites what its keep-last history cannot hold
(lost in transport); nothing queues, and the node's memory must not grow."""
from __future__ import annotations

import time

from glpma_tools.sim.trajectories import PERIOD_S

from .session import LOST_SLACK, RATE_HZ, RSS_SLACK_MB, WARMUP_S, Session, analyse, counters, diff, node_latency, starts


def flood(session: Session, name: str, n: int, rate_hz: float | None, warmup_s: float = WARMUP_S,
          dt: float | None = None) -> dict:
    """``n`` inputs at ``rate_hz`` (None: as fast as the writer can), after ``warmup_s`` of traffic."""
    ctl = session.controller
    if warmup_s > 0:
        session.send(int(warmup_s * (rate_hz or RATE_HZ)), rate_hz or RATE_HZ)
    before = session.settle()
    rss0 = session.node.rss_kb()
    k0, h0 = len(ctl.listener.poses), len(session.history)
    session.say(f"{name}: {n} inputs " + (f"at {rate_hz:g} Hz" if rate_hz else "as fast as possible"))
    t0 = time.perf_counter()
    sent, late = session.send(n, rate_hz, dt=dt)
    send_s = time.perf_counter() - t0
    after = session.settle(sent[-1].send_ns)
    time.sleep(0.2)
    rss1 = session.node.rss_kb()
    counts = diff(counters(after), counters(before))
    res = {"inputs": len(sent), "send_s": send_s, "send_rate_hz": len(sent) / send_s if send_s > 0 else None,
           "late_sends": late, **counts, "lost_in_transport": len(sent) - counts["received"],
           "rss_before_mb": rss0 / 1024, "rss_after_mb": rss1 / 1024, "rss_growth_mb": (rss1 - rss0) / 1024,
           "node_latency_ms": node_latency(after), "starts": diff(starts(after), starts(before))}
    a = analyse(session.model, sent, session.poses_since(k0), earlier=session.history[:h0])
    res.update(poses=a["poses"], matched=a["matched"], unpaired=a["unpaired"], latency_ms=a["latency_ms"],
               residual_max_m=a["residual_max_m"], on_trajectory_mode=a["on_trajectory_mode"])
    res["checks"] = {
        "node alive": session.node.alive(),
        "every received input accounted for (solved + rejected + dropped)":
            counts["received"] == counts["solved"] + counts["rejected"] + counts["dropped"],
        "one pose per solved input": a["poses"] - a["late"] == counts["solved"],
        "every pose answers an input sent (reproduces its legs)": a["unpaired"] == 0,
        f"RSS growth <= {RSS_SLACK_MB:g} MB": res["rss_growth_mb"] <= RSS_SLACK_MB,
    }
    if rate_hz:
        res["expectations"] = {f"transport lost <= {100 * LOST_SLACK:g} % of inputs":
                               res["lost_in_transport"] <= LOST_SLACK * len(sent)}
    return res


def overload(session: Session, duration_s: float, rate_hz: float = RATE_HZ) -> dict:
    """Inputs at ``rate_hz`` for ``duration_s``."""
    res = flood(session, "overload", int(round(duration_s * rate_hz)), rate_hz)
    res.update(rate_hz=rate_hz, duration_s=duration_s)
    return res


def burst(session: Session, n: int) -> dict:
    """``n`` inputs written as fast as possible, all within less than half a loop of the
    trajectory (so that every input of the burst has legs of its own)."""
    return flood(session, "burst", n, None, warmup_s=0.0, dt=min(1.0 / RATE_HZ, 0.4 * PERIOD_S / n))
