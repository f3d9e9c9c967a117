"""ROS domains reserved per run (jetpipe_ros.nodes.domain): never shared while held."""

from __future__ import annotations

import random
import socket
import subprocess
import sys

import pytest

from jetpipe_ros.nodes.domain import DomainError, discovery_port, reserve_domain


def test_held_domains_are_never_handed_out_twice(tmp_path, monkeypatch):
    # The lock files alone: the suite's ROS tests, run beside this one, may hold a domain in
    # 1-10 with its discovery ports bound (seen on Jazzy in .ci/run), which is not this test's.
    monkeypatch.setattr("jetpipe_ros.nodes.domain._ports_free", lambda domain: True)
    held = [reserve_domain(range(1, 11), tmp_path) for _ in range(10)]
    assert sorted(r.domain for r in held) == list(range(1, 11))
    with pytest.raises(DomainError, match="no free ROS domain among 10"):
        reserve_domain(range(1, 11), tmp_path)
    held[3].release()
    again = reserve_domain(range(1, 11), tmp_path)
    assert again.domain == held[3].domain
    for r in held + [again]:
        r.release()


def test_a_lock_held_by_another_process_is_respected(tmp_path):
    """The other process holds domain 1 of {1, 2}; ours gets 2 whatever the order tried."""
    script = ("import sys, time; from jetpipe_ros.nodes.domain import reserve_domain; "
              f"r = reserve_domain([1], {str(tmp_path)!r}); print(r.domain, flush=True); "
              "sys.stdin.read()")
    other = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout.readline().strip() == "1"
        for seed in range(5):
            with reserve_domain([1, 2], tmp_path, random.Random(seed)) as mine:
                assert mine.domain == 2
    finally:
        other.communicate("", timeout=10)
    with reserve_domain([1], tmp_path) as mine:  # released when the other process ended
        assert mine.domain == 1


def test_a_domain_in_use_without_the_lock_is_skipped(tmp_path):
    """Nodes not started by us show by their bound discovery port (participant 0)."""
    domain = 90
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind(("", discovery_port(domain)))
        except OSError:
            pytest.skip(f"domain {domain} is in use on this machine")
        with reserve_domain([domain, domain + 1, domain + 2], tmp_path) as mine:
            assert mine.domain != domain
