"""A ROS domain of its own for a process and the nodes it starts: two node graphs in one DDS domain on one machine
talk to each other's nodes (an optimizer sends its goals to another graph's evaluators), so test runs and benches
that run side by side each claim one.

The claim is an exclusive lock on ``rollability-ros-domain-<id>.lock`` in the temp directory, held for as long as
the returned handle stays open (the life of the process), so every claimant on the machine sees it.
"""
import fcntl
import os
import tempfile
import typing


def claim_domain(first: int, last: int, start: typing.Optional[int] = None,
                 skip: typing.Collection[int] = ()) -> typing.Tuple[int, typing.TextIO]:
    """``(domain, lock handle)``: the first domain in ``first..last`` (inclusive, tried from ``start``, default
    ``first + pid mod size``, never one of ``skip``) that no other process holds; ``RuntimeError`` when all are
    held."""
    size = last - first + 1
    start = first + os.getpid() % size if start is None else start
    for offset in range(size):
        domain = first + (start - first + offset) % size
        if domain in skip:
            continue
        handle = open(os.path.join(tempfile.gettempdir(), f"rollability-ros-domain-{domain}.lock"), "w")
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.close()
            continue
        return domain, handle
    raise RuntimeError(f"no free ROS_DOMAIN_ID in {first}..{last} ({size} holders at once?)")
