"""A ``glpma_fk`` node as a child process over Cyclone DDS, for the demo, the
stress tool and the benchmark: started with ``--ros-args``, ready when it prints
its ``ready`` line, stopped with SIGINT, its RSS and CPU time read with psutil.  The same for a
stand-in that behaves so (:mod:`.echo_node`)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil

from glpma_ros.config import config_dir

#: a first run on a fresh machine compiles the solvers before the node is ready
READY_TIMEOUT_S = 240.0
#: the directory that holds the glpma_ros and glpma_tools packages (the checkout, or site-packages)
PACKAGE_PARENT = Path(__file__).resolve().parents[2]
#: the module run as the node
NODE_MODULE = "glpma_ros.node.dds.node"


class NodeProcess:
    """``python -m glpma_ros.node.dds.node --ros-args ...`` (or ``module``) with its output in
    files; restartable."""

    def __init__(self, ros_args, env: dict, log_dir: Path, module: str = NODE_MODULE):
        self.module = module
        self.ros_args = list(ros_args)
        self.env = env
        self.log_dir = Path(log_dir)
        self.proc: subprocess.Popen | None = None
        self.starts = 0
        self.stdout = self.stderr = None
        self.ready_ns = 0

    @property
    def pid(self) -> int:
        return self.proc.pid

    def start(self, timeout: float = READY_TIMEOUT_S) -> float:
        """Start and wait for the ``ready`` line; returns the seconds it took."""
        self.stdout = self.log_dir / f"node{self.starts}.out"
        self.stderr = self.log_dir / f"node{self.starts}.err"
        self.starts += 1
        t0 = time.monotonic()
        with open(self.stdout, "w") as fo, open(self.stderr, "w") as fe:
            self.proc = subprocess.Popen([sys.executable, "-m", self.module, "--ros-args", *self.ros_args],
                                         stdout=fo, stderr=fe, env=self.env, cwd=PACKAGE_PARENT)
        while time.monotonic() - t0 < timeout:
            if "ready" in self.stdout.read_text():
                self.ready_ns = time.time_ns()
                return time.monotonic() - t0
            if self.proc.poll() is not None:
                raise RuntimeError(f"the node exited with status {self.proc.returncode} before it was ready:\n"
                                   f"{self.output()}")
            time.sleep(0.05)
        self.kill()
        raise RuntimeError(f"the node was not ready within {timeout:g} s:\n{self.output()}")

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def rss_kb(self) -> int:
        """Resident set size in kB (psutil)."""
        return psutil.Process(self.pid).memory_info().rss // 1024

    def cpu_s(self) -> float:
        """CPU time (user + system) the process has used so far, in seconds (psutil)."""
        times = psutil.Process(self.pid).cpu_times()
        return times.user + times.system

    def stop(self, timeout: float = 15.0) -> int | None:
        """SIGINT, as Ctrl-C; the exit status (None if it had to be killed)."""
        if not self.alive():
            return None if self.proc is None else self.proc.returncode
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            return None

    def kill(self) -> None:
        if self.alive():
            self.proc.kill()
            self.proc.wait()

    def output(self) -> str:
        def tail(p):
            return "\n".join(p.read_text().splitlines()[-20:]) if p and p.exists() else ""
        return f"stdout:\n{tail(self.stdout)}\nstderr:\n{tail(self.stderr)}"

    def stopped_line(self) -> str:
        """The node's last log line ``stopped: received ..., solved ...``, if any."""
        lines = [ln for ln in self.stderr.read_text().splitlines() if "stopped:" in ln] if self.stderr else []
        return lines[-1].split("stopped:", 1)[1].strip() if lines else ""


def node_environment(domain_id: int) -> dict:
    """The node's environment (and this process's, for the controller's participants): loopback
    discovery (the shipped file unless ``CYCLONEDDS_URI`` is set) and a domain of its own."""
    os.environ.setdefault("CYCLONEDDS_URI", (config_dir() / "cyclonedds-localhost.xml").as_uri())
    os.environ["ROS_DOMAIN_ID"] = str(domain_id)
    path = os.pathsep.join(p for p in (str(PACKAGE_PARENT), os.environ.get("PYTHONPATH", "")) if p)
    return dict(os.environ, PYTHONPATH=path)
