"""A ROS domain of one's own on this machine, for tests and benchmarks that start nodes.

ROS 2 graphs are separated by ``ROS_DOMAIN_ID`` (and kept on the machine by
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``). Two runs at once (two checkouts' test suites, a
benchmark beside them) must never share a domain, which ``pid % 100`` does not guarantee. A
domain is reserved by an exclusive ``flock`` on a file named after it in the system's temporary
directory: the kernel releases it when the holder closes it or dies, even when killed, so there
is nothing stale to clean up, and any number of processes can race for domains safely. Domains
are tried in random order; one whose DDS discovery ports are already bound (a process that does
not take the lock: a user's nodes, a ``ros2`` daemon) is skipped too.

No ROS import: the reservation is made before ``rclpy.init``.
"""

from __future__ import annotations

import errno
import fcntl
import os
import random
import socket
import tempfile
from collections.abc import Iterable
from pathlib import Path

#: Domains handed out: 0 is everybody's default; up to 101 the DDS ports stay below Linux's
#: ephemeral range (ROS 2 documentation, "The ROS_DOMAIN_ID").
DOMAINS = range(1, 102)
#: Participants per domain whose discovery port is probed (RTPS: 7410 + 250 d + 2 p).
PROBED_PARTICIPANTS = 4


class DomainError(RuntimeError):
    """No domain could be reserved; the message says which were tried."""


def discovery_port(domain: int, participant: int = 0) -> int:
    """UDP port of a participant's unicast discovery traffic in ``domain`` (RTPS defaults)."""
    return 7400 + 250 * domain + 10 + 2 * participant


def _ports_free(domain: int) -> bool:
    for participant in range(PROBED_PARTICIPANTS):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            try:
                sock.bind(("", discovery_port(domain, participant)))
            except OSError:
                return False
    return True


class DomainReservation:
    """A reserved domain; held until :meth:`release` (or the process ends)."""

    def __init__(self, domain: int, fd: int, path: Path) -> None:
        self.domain = domain
        self.path = path  #: the lock file
        self._fd: int | None = fd

    def release(self) -> None:
        """Give the domain back (idempotent)."""
        if self._fd is not None:
            os.close(self._fd)  # closing drops the flock
            self._fd = None

    def __enter__(self) -> DomainReservation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def reserve_domain(domains: Iterable[int] = DOMAINS, lock_dir: str | Path | None = None,
                   rng: random.Random | None = None) -> DomainReservation:
    """Reserve a free domain among ``domains`` (tried in random order).

    A domain is free when its lock file in ``lock_dir`` (default: the system's temporary
    directory) can be locked exclusively and its DDS discovery ports are not bound. Raises
    :class:`DomainError` when none is.
    """
    directory = Path(lock_dir or tempfile.gettempdir())
    candidates = list(domains)
    (rng or random.SystemRandom()).shuffle(candidates)
    for domain in candidates:
        path = directory / f"jetpipe_ros_domain_{domain}.lock"
        try:
            fd = os.open(path, os.O_RDONLY | os.O_CREAT, 0o666)
        except OSError:
            continue  # e.g. another user's file we may not open
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
                continue  # held by another run
            raise
        if _ports_free(domain):
            return DomainReservation(domain, fd, path)
        os.close(fd)
    raise DomainError(f"no free ROS domain among {len(candidates)} candidates (lock files "
                      f"{directory}/jetpipe_ros_domain_*.lock held, or discovery ports bound)")
