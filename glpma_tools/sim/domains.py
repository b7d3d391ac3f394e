"""A ROS domain of one's own: claimed with a lock, not guessed from a process id.

Two runs on one host -- the test suite beside the demo, two CI jobs, two checkouts on one robot
computer -- must not share a ``ROS_DOMAIN_ID``: a reader on a shared domain takes the other run's
messages.  A domain id derived from the process id is a guess that two processes can make alike.

Here every domain id has a lock file in a directory under the temporary directory, and a process
claims an id by holding an exclusive, non-blocking ``flock`` on its file.  The kernel releases the lock
when the file is closed or the process ends, however it ends (a crash or SIGKILL included), so a claim
is never left behind.  The claim covers everything the claiming process starts with that domain (the
node processes it spawns inherit ``ROS_DOMAIN_ID``, not the lock: the claimer keeps the claim while they
run).

Domain ids 1 .. 101: on Linux, the ports of domains above 101 can collide with the ephemeral port
range (the ROS 2 documentation's "The ROS_DOMAIN_ID"); 0 is every ROS installation's default and is
left to the user, as is the ``ROS_DOMAIN_ID`` of the environment.
"""
from __future__ import annotations

import errno
import fcntl
import os
import tempfile
from pathlib import Path

#: lowest and highest domain id claimed (see the module docstring)
FIRST_DOMAIN = 1
LAST_DOMAIN = 101
#: where the lock files are: one directory for every user of the host (sticky, like /tmp)
LOCK_DIR = Path(tempfile.gettempdir()) / "glpma_ros-domains"


class NoFreeDomain(RuntimeError):
    """Every domain id of the range is claimed by another process."""


class DomainClaim:
    """An exclusive claim on one ROS domain id, held until :meth:`release` or the process ends."""

    def __init__(self, domain_id: int, fd: int):
        self.domain_id = domain_id
        self._fd = fd

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)          # closing the file releases its flock
            self._fd = None

    def __enter__(self) -> DomainClaim:
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def __repr__(self) -> str:
        return f"DomainClaim({self.domain_id}, {'held' if self._fd is not None else 'released'})"


def _lock_dir() -> Path:
    try:
        LOCK_DIR.mkdir(mode=0o1777, exist_ok=True)
        if LOCK_DIR.stat().st_uid == os.getuid():
            LOCK_DIR.chmod(0o1777)      # the mode of mkdir is masked by the umask
    except OSError as exc:
        raise NoFreeDomain(f"cannot create the domain lock directory {LOCK_DIR}: {exc.strerror}") from exc
    return LOCK_DIR


def try_claim(domain_id: int) -> DomainClaim | None:
    """Claim ``domain_id`` if no other process holds it, else None."""
    path = _lock_dir() / f"{domain_id}.lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except PermissionError:
        return None                      # another user's file: theirs
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
            return None
        raise
    return DomainClaim(domain_id, fd)


def claim_domain() -> DomainClaim:
    """Claim a free ROS domain id of FIRST_DOMAIN .. LAST_DOMAIN.

    The search starts at an offset from the process id (so that concurrent claimers rarely try the
    same ids first) and goes round the range once; the lock, not the offset, makes the claim."""
    taken = os.environ.get("ROS_DOMAIN_ID", "").strip()
    ids = list(range(FIRST_DOMAIN, LAST_DOMAIN + 1))
    start = os.getpid() % len(ids)
    for domain_id in ids[start:] + ids[:start]:
        if str(domain_id) == taken:
            continue
        claim = try_claim(domain_id)
        if claim is not None:
            return claim
    raise NoFreeDomain(f"every ROS domain id {FIRST_DOMAIN}-{LAST_DOMAIN} is claimed by another process "
                       f"(locks in {LOCK_DIR}); pass a domain id explicitly")
