"""What a ``glpma-fk bag`` run (:mod:`glpma_tools.bag_run`) reports: its :class:`Summary`, the assembly-mode
changes :class:`BranchWatch` counts, and the offline time budget per input (:data:`OFFLINE_BUDGET_MS`)."""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from glpma_ros.estimation.estimator import CONTINUITY_FACTOR, MIN_SPREAD
from glpma_ros.models.pose_kernels import joint_distance
from glpma_ros.node import params as P

#: offline time budget per input: the largest the parameter accepts (ms), so that every status is
#: decided by the work done
OFFLINE_BUDGET_MS = P.SPECS["time_budget_ms"].range[1]


@dataclass
class Summary:
    """What a run did."""

    input: str
    output: str
    storage: str
    input_topic: str
    messages: int = 0                  # messages read (all topics)
    inputs: int = 0                    # messages of the input topic
    converged: int = 0                 # poses written
    rejected: Counter = field(default_factory=Counter)   # reason -> inputs
    mode_changes: int = 0
    skipped_topics: dict = field(default_factory=dict)   # topic -> why it could not be copied
    budget_ms: float = 0.0             # time budget per input
    warm_up_s: float = 0.0
    elapsed_s: float = 0.0             # reading, solving and writing (after the warm-up)
    cpu_s: float = 0.0                 # this process' CPU time meanwhile (a shared machine's wall clock runs ahead)
    solve_s: float = 0.0               # in the service alone

    @property
    def poses_per_s(self) -> float:
        return self.converged / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def as_dict(self) -> dict:
        return {"input": self.input, "output": self.output, "storage": self.storage,
                "input_topic": self.input_topic, "messages": self.messages, "inputs": self.inputs,
                "converged": self.converged, "rejected": sum(self.rejected.values()),
                "rejected_by_reason": dict(self.rejected.most_common()), "assembly_mode_changes": self.mode_changes,
                "skipped_topics": self.skipped_topics, "budget_ms": self.budget_ms, "warm_up_s": self.warm_up_s,
                "elapsed_s": self.elapsed_s, "cpu_s": self.cpu_s, "solve_s": self.solve_s,
                "poses_per_s": self.poses_per_s}

    def text(self) -> str:
        budget = (f"budget {self.budget_ms:g} ms per input, the parameter's maximum: statuses from the work done"
                  if self.budget_ms >= OFFLINE_BUDGET_MS else f"budget {self.budget_ms:g} ms per input (--budget-ms)")
        lines = [f"{self.output} ({self.storage}): {self.messages} messages copied, {self.inputs} inputs on "
                 f"{self.input_topic}: {self.converged} converged, {sum(self.rejected.values())} rejected, "
                 f"{self.mode_changes} assembly-mode changes",
                 f"  {self.elapsed_s:.2f} s, CPU {self.cpu_s:.2f} s ({self.poses_per_s:,.0f} poses/s; solving "
                 f"{self.solve_s:.2f} s, warm-up {self.warm_up_s:.1f} s before; {budget})"]
        lines += [f"  rejected {n}: {reason}" for reason, n in self.rejected.most_common()]
        lines += [f"  not copied: {topic}: {why}" for topic, why in self.skipped_topics.items()]
        return "\n".join(lines)


class BranchWatch:
    """Counts assembly-mode changes: a converged pose farther from the previous one than
    the estimator's continuity bound (``CONTINUITY_FACTOR`` times the leg movement) jumped
    to another branch instead of following the legs.  The distance is the compiled
    ``Manipulator.distance`` (:func:`~glpma_ros.models.pose_kernels.joint_distance`): it runs
    for every input of a bag."""

    def __init__(self, model, x=None, legs=None):
        self.model = model
        self.kind, self.platform = int(model.kind_id), np.ascontiguousarray(model.platform, dtype=float)
        self.floor = MIN_SPREAD * model.scale
        self.x = None if x is None else np.array(x, dtype=float)
        self.legs = None if legs is None else np.array(legs, dtype=float).tolist()

    def __call__(self, x, legs) -> bool:
        x = np.array(x, dtype=float)
        legs = np.asarray(legs, dtype=float).tolist()
        jumped = False
        if self.x is not None:
            movement = max(abs(a - b) for a, b in zip(legs, self.legs))
            bound = max(CONTINUITY_FACTOR * movement, self.floor)
            jumped = joint_distance(self.kind, self.platform, x, self.x) > bound
        self.x, self.legs = x, legs
        return jumped
