"""Restarts and a jump: the controller restarts mid-trajectory (a new DDS participant); the legs
jump to another assembly mode's trajectory (the estimator must recover); the node restarts
mid-trajectory (SIGINT, started again while the controller keeps sending: its first answer is a
cold start, the next ones warm, as ``/diagnostics`` must say).

``checks`` must hold on any machine; ``expectations`` (shares answered, warm starts) hold on an
idle one, and are reported, not judged, since a busy machine makes the node drop inputs and
widen its searches."""
from __future__ import annotations

import threading
import time

import numpy as np

from glpma_tools.sim.controller import Controller
from glpma_tools.sim.trajectories import PERIOD_S, Plan

from .session import MATCH_TIMEOUT_S, PHASE_RATE_HZ, Session, analyse, counters, diff, starts

#: the new controller's inputs that must be answered, and the jump's
ANSWERED_AFTER_RESTART = 0.95
ANSWERED_AFTER_JUMP = 0.9
#: a rejection after a controller restart can only be a solve the budget cut short (a preempted node)
REJECTED_AFTER_RESTART = 0.05
#: after the jump, a pose must come within this many inputs
RECOVERY_INPUTS = 10
#: candidate times of the other trajectory for the jump (the one farthest in legs is taken)
JUMP_CANDIDATES = 200
#: seconds the restarted node has to report its first answer
FIRST_REPORT_TIMEOUT_S = 60.0


def controller_restart(session: Session, phase_s: float) -> dict:
    session.say("controller restart: a new participant continues the trajectory")
    n = int(phase_s * PHASE_RATE_HZ)
    before = session.settle()
    sent_a, _ = session.send(n, PHASE_RATE_HZ)
    h0 = len(session.history)
    t_close = time.monotonic()
    session.controller.close()
    session.controller = Controller(session.model, session.domain_id, depth=session.params["qos_depth"])
    match_s = session.controller.wait_for_node(MATCH_TIMEOUT_S)
    time.sleep(0.3)
    gap_s = time.monotonic() - t_close
    session.t += gap_s                                  # the robot moved on meanwhile
    k0 = len(session.controller.listener.poses)
    mid = session.settle()
    sent_b, _ = session.send(n, PHASE_RATE_HZ)
    after = session.settle(sent_b[-1].send_ns)
    a = analyse(session.model, sent_b, session.poses_since(k0), earlier=session.history[:h0])
    counts_b = diff(counters(after), counters(mid))
    st = diff(starts(after), starts(mid))
    res = {"inputs_before": len(sent_a), "inputs_after": len(sent_b), "gap_s": gap_s, "discovery_s": match_s,
           "after": counts_b, "starts_after": st, "poses_after": a["matched"], "unpaired": a["unpaired"],
           "late_poses_of_the_previous_controller": a["late"],
           "first_pose_latency_ms": a["first_latency_ms"], "residual_max_m": a["residual_max_m"],
           "last_start": after.get("last start"), "totals": diff(counters(after), counters(before))}
    res["checks"] = {
        "node alive": session.node.alive(),
        "new controller answered": a["matched"] >= 1,
        "every pose answers an input sent": a["unpaired"] == 0,
    }
    res["expectations"] = {
        f"new controller answered (>= {100 * ANSWERED_AFTER_RESTART:g} % of its inputs)":
            a["matched"] >= ANSWERED_AFTER_RESTART * len(sent_b),
        "tracking stays warm (no cold start)": st["cold"] == 0 and after.get("last start") == "warm",
        f"rejected <= {100 * REJECTED_AFTER_RESTART:g} % of the inputs":
            counts_b["rejected"] <= REJECTED_AFTER_RESTART * len(sent_b),
    }
    return res


def large_jump(session: Session, phase_s: float) -> dict:
    other = Plan(session.params["manipulator_config"], solution=session.plan.other_solution())
    session.say(f"large jump: to the trajectory around known solution {other.solution}")
    n = int(phase_s * PHASE_RATE_HZ)
    ctl = session.controller
    k0, h0 = len(ctl.listener.poses), len(session.history)
    sent_a, _ = session.send(n, PHASE_RATE_HZ)
    before = session.settle()
    a_before = analyse(session.model, sent_a, session.poses_since(k0), earlier=session.history[:h0])
    k0, h0 = len(ctl.listener.poses), len(session.history)
    # jump to the point of the other trajectory whose legs are farthest from the last ones sent
    last_legs = sent_a[-1].legs
    session.t = max(np.linspace(0.0, PERIOD_S, JUMP_CANDIDATES, endpoint=False),
                    key=lambda t: float(np.max(np.abs(other.sample(t)[0] - last_legs))))
    jump_legs = other.sample(session.t)[0]
    sent, _ = session.send(n, PHASE_RATE_HZ, plan=other)
    after = session.settle(sent[-1].send_ns)
    a = analyse(session.model, sent, session.poses_since(k0), earlier=session.history[:h0])
    counts = diff(counters(after), counters(before))
    st = diff(starts(after), starts(before))
    jump = float(np.max(np.abs(jump_legs - last_legs)))
    step = float(np.max(np.abs(sent_a[-1].legs - sent_a[-2].legs)))
    res = {"to_solution": other.solution, "jump_legs_max": jump, "step_legs_max": step,
           "jump_relative": jump / session.model.scale,
           "unit": session.model.unit, "inputs": len(sent), **counts, "starts": st,
           "inputs_until_first_pose": a["first_answered"], "first_pose_latency_ms": a["first_latency_ms"],
           "poses_on_requested_mode": a["on_trajectory_mode"], "poses": a["matched"], "unpaired": a["unpaired"],
           "before": {"inputs": len(sent_a), "poses": a_before["matched"],
                      "on_trajectory_mode": a_before["on_trajectory_mode"]},
           "residual_max_m": a["residual_max_m"], "last_start": after.get("last start")}
    res["checks"] = {
        "node alive": session.node.alive(),
        "recovered: poses after the jump": a["matched"] >= 1,
        "every pose answers an input sent": a["unpaired"] == 0 and a_before["unpaired"] == 0,
    }
    res["expectations"] = {
        f"recovered within {RECOVERY_INPUTS} inputs":
            a["first_answered"] is not None and a["first_answered"] < RECOVERY_INPUTS,
        f">= {100 * ANSWERED_AFTER_JUMP:g} % of the inputs answered": a["matched"] >= ANSWERED_AFTER_JUMP * len(sent),
        "tracking warm again": after.get("last start") == "warm",
    }
    session.plan = other                # the session follows the other trajectory from now on
    return res


def _first_report_with_an_answer(ctl, ready_ns: int) -> dict | None:
    deadline = time.monotonic() + FIRST_REPORT_TIMEOUT_S
    while time.monotonic() < deadline:
        d = ctl.listener.diagnostics
        if ctl.listener.diagnostics_stamp_ns > ready_ns and d and int(d["values"]["inputs solved"]) >= 1:
            return dict(d["values"])
        time.sleep(0.005)
    return None


def node_restart(session: Session, phase_s: float) -> dict:
    """SIGINT the node while the controller streams; start it again; the controller keeps sending."""
    session.say("node restart: SIGINT mid-trajectory, start again, the controller keeps sending")
    ctl = session.controller
    stop = threading.Event()
    out = {}

    def stream():
        out["sent"], _ = session.send(10**9, PHASE_RATE_HZ, stop=stop)

    k0, h0 = len(ctl.listener.poses), len(session.history)
    thread = threading.Thread(target=stream, name="stress-stream", daemon=True)
    thread.start()
    time.sleep(phase_s)
    old_rss = session.node.rss_kb()
    t_kill = time.monotonic()
    kill_ns = time.time_ns()
    status = session.node.stop()
    stopped = session.node.stopped_line()
    try:
        startup = session.node.start()
    except RuntimeError:
        stop.set()
        thread.join(5)
        raise
    session.startup_s.append(startup)
    ready_ns = session.node.ready_ns
    first = _first_report_with_an_answer(ctl, ready_ns)
    t_first = time.monotonic()
    time.sleep(phase_s)
    stop.set()
    thread.join(10)
    sent = out.get("sent", [])
    after = session.settle(sent[-1].send_ns if sent else None)
    poses = session.poses_since(k0)
    new_poses = [p for p in poses if p[1] > ready_ns]
    old_poses = [p for p in poses if p[1] <= kill_ns]
    a = analyse(session.model, sent, new_poses, earlier=session.history[:h0])
    first_pose_s = (min(p[0] for p in new_poses) - ready_ns) * 1e-9 if new_poses else None
    s_first = starts(first) if first else None
    s_end = starts(after)
    res = {"exit_status": status, "stopped": stopped, "rss_old_mb": old_rss / 1024,
           "downtime_s": t_first - t_kill, "startup_s": startup, "first_pose_after_ready_s": first_pose_s,
           "poses_before": len(old_poses), "poses_after": len(new_poses), "inputs_sent": len(sent),
           "first_report": {"starts": s_first, "last start": first.get("last start") if first else None,
                            "solved": int(first["inputs solved"]) if first else 0},
           "final": {"starts": s_end, "last start": after.get("last start"), **counters(after)},
           "unpaired": a["unpaired"], "residual_max_m": a["residual_max_m"],
           "poses_on_trajectory_mode": a["on_trajectory_mode"]}
    res["checks"] = {
        "node stopped cleanly on SIGINT (status 0)": status == 0,
        "restarted node answers": bool(new_poses),
        "first answer cold (the restarted node has no warm state)": s_first is not None and s_first["cold"] >= 1,
        "every pose answers an input sent": a["unpaired"] == 0,
    }
    res["expectations"] = {
        "then warm: no cold start after the first answer":
            s_first is not None and s_end["cold"] == s_first["cold"] and after.get("last start") == "warm"}
    return res
