"""Every real assembly mode, computed in a child process.

:func:`~glpma_ros.modes.multistart.solve_all` (its multistart: hundreds of local solves, until many
starts in a row find nothing new; ``runs`` = parameter ``assembly_modes_runs`` caps the starts)
takes up to a second.  Compiled code holds the GIL while it runs, so in a thread of the node it
would hold up the real-time solve loop (BENCHMARKS.md, "Design measurements").
:class:`ModesWorker` runs them in a child process instead
(a fresh interpreter, ``python -m glpma_ros.node.modes_worker``: nothing of the node is forked
or re-imported), at a lower scheduling priority (``nice`` +5), so that on a multi-core
machine the solve loop does not notice.

The child is started with the node, loads the manipulator and runs a small ``solve_all``
so that Numba's cache is loaded before the first request; it exits at the end of its
stdin (the node closes it, or dies) and ignores SIGINT (Ctrl-C in a terminal reaches the
whole process group; the node shuts it down itself).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np

from ..config import load_manipulator
from ..errors import InputError
from ..modes.multistart import default_method, solve_all
from ..modes.path_tracker import available_cores

#: scheduling priority of the child relative to the node (higher = yields more)
NICE = 5
#: starts of the warm-up solve_all in the child
WARM_UP_STARTS = 2


def modes_threads() -> int:
    """The homotopy's path-tracking threads for a request: every core the process may run on but one, at least
    one (on the 2-core machine: one), so that the real-time solve loop keeps a core of its own while the modes are
    tracked; a request takes a few times longer than with every core (BENCHMARKS.md, "Every assembly mode")."""
    return max(1, available_cores() - 1)


class Modes(list):
    """The solver variables of every mode found (a list), with the multistart's account of the
    work: ``starts`` used, ``stop_reason``, ``miss_probability`` (``None`` when unknown)."""

    def __init__(self, xs=(), starts: int = 0, stop_reason: str = "", miss_probability=None):
        super().__init__(xs)
        self.starts = int(starts)
        self.stop_reason = stop_reason
        self.miss_probability = miss_probability


def modes_of(result) -> Modes:
    """:class:`Modes` of a :class:`~glpma_ros.modes.multistart.AllSolutions`; the homotopy's ``stop_reason`` is
    ``complete`` or ``incomplete`` and its ``miss_probability`` 0 when complete (certified), else None."""
    if result.method == "homotopy":
        return Modes([np.asarray(s.x, dtype=float) for s in result.solutions], 0,
                     "complete" if result.complete else "incomplete", 0.0 if result.complete else None)
    return Modes([np.asarray(s.x, dtype=float) for s in result.solutions], result.starts, result.stop_reason,
                 result.miss_probability)


def find_modes(model, legs, runs: int, seed: int, leg_noise_std=None) -> Modes:
    """What a request computes: the closed form where the model has one (the Delta), the parameter homotopy
    where the model's family has a start system (``runs`` unused for both; its paths on :func:`modes_threads`
    threads), else the multistart, at most
    ``runs`` starts; ``leg_noise_std`` (config unit): redundant legs, the noise a mode's leg residuals are
    tested against (the node's parameter)."""
    method = default_method(model)
    if method == "closed_form":
        return modes_of(solve_all(model, legs, method="closed_form", seed=int(seed)))
    if method == "homotopy":
        return modes_of(solve_all(model, legs, method="homotopy", seed=int(seed), leg_noise_std=leg_noise_std,
                                  threads=modes_threads()))
    return modes_of(solve_all(model, legs, method="multistart", max_starts=int(runs), seed=int(seed),
                              leg_noise_std=leg_noise_std))


def _reply(out, kind: str, payload) -> None:
    out.write(json.dumps([kind, payload]) + "\n")
    out.flush()


def child_main(argv=None) -> int:
    """The child: ``python -m glpma_ros.node.modes_worker CONFIG NICE [WARM_LEGS_JSON]``; one JSON request
    per line on stdin (``[legs, runs, seed, leg_noise_std]``, the last null for the default), one JSON reply per line
    on stdout
    (``["ok", {"modes": [x, ...], "starts": n, "stop_reason": r, "miss_probability": p}]``,
    ``["input_error", reason]`` or ``["error", reason]``); exits at EOF."""
    argv = sys.argv[1:] if argv is None else argv
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        os.nice(int(argv[1]))
    except OSError:
        pass
    out = sys.stdout
    sys.stdout = sys.stderr          # nothing but replies on the pipe
    model = load_manipulator(argv[0])
    if len(argv) > 2:
        try:
            find_modes(model, np.asarray(json.loads(argv[2]), dtype=float), WARM_UP_STARTS, 0)
        except Exception:  # noqa: BLE001 - a failed warm-up only costs time later
            pass
    _reply(out, "ready", None)
    for line in sys.stdin:
        try:
            legs, runs, seed, leg_noise_std = json.loads(line)
            m = find_modes(model, np.asarray(legs, dtype=float), runs, seed, leg_noise_std)
            _reply(out, "ok", {"modes": [x.tolist() for x in m], "starts": m.starts, "stop_reason": m.stop_reason,
                               "miss_probability": m.miss_probability})
        except InputError as exc:
            _reply(out, "input_error", str(exc))
        except Exception as exc:  # noqa: BLE001 - reported to the node, the child lives on
            _reply(out, "error", f"{type(exc).__name__}: {exc}")
    return 0


class ModesWorker:
    """``worker(legs, runs, seed, leg_noise_std=None)`` -> the solver variables of every real assembly mode of
    ``legs`` (config unit) as :class:`Modes`, computed by :func:`find_modes` in a child process
    (``python -m glpma_ros.node.modes_worker``).  The child is (re)started on demand;
    :meth:`close` stops it."""

    def __init__(self, config_path, warm_legs=None, nice: int = NICE):
        self.config_path = str(Path(config_path).resolve())
        self.warm_legs = None if warm_legs is None else [float(v) for v in warm_legs]
        self.nice = int(nice)
        self._lock = threading.Lock()
        self._proc: subprocess.Popen | None = None
        self._ready = False

    def start(self) -> "ModesWorker":
        with self._lock:
            self._ensure_started()
        return self

    def _ensure_started(self) -> None:
        if self._proc is not None and self._proc.poll() is None:
            return
        self._shutdown()
        package_root = str(Path(__file__).resolve().parents[1])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH", "")) if p)
        args = [sys.executable, "-m", "glpma_ros.node.modes_worker", self.config_path, str(self.nice)]
        if self.warm_legs is not None:
            args.append(json.dumps(self.warm_legs))
        self._proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env, text=True,
                                      bufsize=1)
        self._ready = False

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    def _read(self):
        line = self._proc.stdout.readline()
        if not line:
            raise EOFError
        return json.loads(line)

    def __call__(self, legs, runs: int, seed: int, leg_noise_std=None) -> list:
        with self._lock:
            self._ensure_started()
            try:
                if not self._ready:
                    kind, _ = self._read()      # "ready": loaded and warmed up
                    self._ready = True
                noise = None if leg_noise_std is None else float(leg_noise_std)
                self._proc.stdin.write(json.dumps([[float(v) for v in legs], int(runs), int(seed), noise]) + "\n")
                self._proc.stdin.flush()
                kind, payload = self._read()
            except (EOFError, OSError, ValueError):
                self._shutdown()
                raise RuntimeError("the assembly-modes worker process died (restarted on the next request)") \
                    from None
        if kind == "ok":
            return Modes([np.asarray(x, dtype=float) for x in payload["modes"]], payload["starts"],
                         payload["stop_reason"], payload["miss_probability"])
        if kind == "input_error":
            raise InputError(payload)
        raise RuntimeError(payload)

    def _shutdown(self, timeout: float = 2.0) -> None:
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()          # EOF: the child exits
        except OSError:
            pass
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.terminate()
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()

    def close(self) -> None:
        """Stop the child (waits up to a few seconds for a computation in progress)."""
        if self._lock.acquire(timeout=5.0):
            try:
                self._shutdown()
            finally:
                self._lock.release()
        elif self._proc is not None:         # a computation is hanging: do not wait for it
            self._proc.kill()


if __name__ == "__main__":
    sys.exit(child_main())
