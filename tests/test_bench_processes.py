"""The ports tests and benches hand to the processes they start: picked where no other worker and no bind to port 0
picks, so a port let go before its user binds it is not taken by something else meanwhile."""

from __future__ import annotations

import itertools
import os
import socket
import subprocess
import sys

import pytest

from bench import processes


def pools(count: int) -> list[range]:
    """Each of `count` pytest-xdist workers' pool, as a worker process of that name computes it."""
    program = "from bench.processes import worker_pool as w; p = w(); print(p.start, p.stop)"
    ranges = []
    for index in range(count):
        env = {**os.environ, "PYTEST_XDIST_WORKER": f"gw{index}", "PYTEST_XDIST_WORKER_COUNT": str(count)}
        out = subprocess.run([sys.executable, "-c", program], env=env, capture_output=True, text=True, check=True)
        start, stop = map(int, out.stdout.split())
        ranges.append(range(start, stop))
    return ranges


def test_workers_pools_are_disjoint_and_below_the_ports_the_kernel_hands_out():
    ranges = pools(4)
    low = processes.ephemeral_low()
    for index, pool in enumerate(ranges):
        assert len(pool) >= 1000
        assert pool.start >= processes.POOL_FLOOR and pool.stop <= low
        assert all(pool.stop <= later.start for later in ranges[index + 1 :])
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:  # what a link binding port 0 gets
        sock.bind(("127.0.0.1", 0))
        assert not any(sock.getsockname()[1] in pool for pool in ranges)


def test_a_picked_port_is_free_in_this_workers_pool_and_not_handed_out_twice_in_a_row():
    pool = processes.worker_pool()
    picked = [processes.free_udp_port() for _ in range(20)] + [processes.free_tcp_port() for _ in range(20)]
    assert all(port in pool for port in picked)
    assert len(set(picked)) == len(picked)
    for port in picked[:20]:
        assert processes.bindable(port, socket.SOCK_DGRAM)


def test_a_held_port_is_skipped_a_block_is_free_end_to_end_and_a_full_pool_says_so(monkeypatch):
    small = processes.worker_pool()[:10]
    monkeypatch.setattr(processes, "_pool", small)
    monkeypatch.setattr(processes, "_next", itertools.count(0))
    held = []
    try:
        for port in small[::2]:  # every other port of the pool held by something else
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            held.append(sock)
            sock.bind(("127.0.0.1", port))
        picks = [processes.free_udp_port() for _ in range(10)]
        assert set(picks) == set(small[1::2])
        with pytest.raises(OSError, match="no 2 free consecutive ports"):
            processes.free_udp_port_block(2)
        held.pop().close()  # small[8] let go: small[7]-small[8] and small[8]-small[9] are free blocks
        assert processes.free_udp_port_block(2) in (small[7], small[8])
    finally:
        for sock in held:
            sock.close()
