"""Playback timing for the player node: when to publish each recorded message, on which topic.

:func:`playback_schedule` turns recorded messages into :class:`PlaybackItem` s with the wall-clock time
(seconds after playback starts) at which to publish each one; the player node only sleeps until then and
publishes the bytes (and, when asked, a ``/clock`` message built by :func:`clock_message_cdr`).
"""
import struct
import typing

#: Topic and type of simulated-time messages.
CLOCK_TOPIC = "/clock"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"


class PlaybackItem(typing.NamedTuple):
    """One message to publish.

    ``wall_time_s``: when to publish, s after playback start; ``delay_s``: wait after the previous item, s;
    ``topic``: topic to publish on (after remapping); ``type_name``; ``data``: CDR bytes; ``log_time_ns``:
    recorded log time, ns (the /clock value to publish with it); ``loop_index``: 0 for the first pass.
    """

    wall_time_s: float
    delay_s: float
    topic: str
    type_name: str
    data: bytes
    log_time_ns: int
    loop_index: int


def playback_schedule(messages: typing.Iterable[typing.Tuple[str, str, bytes, int]], rate: float = 1.0,
                      start_offset_s: float = 0.0, loop: bool = False,
                      topics: typing.Optional[typing.Iterable[str]] = None,
                      remap: typing.Optional[typing.Mapping[str, str]] = None,
                      bag_start_time_ns: typing.Optional[int] = None) -> typing.Iterator[PlaybackItem]:
    """Yield the :class:`PlaybackItem` s of a playback, keeping the recorded spacing divided by ``rate``.

    Parameters
    ----------
    messages : iterable
        Recorded messages in log-time order, as ``(topic, type_name, data, log_time_ns)`` (e.g. a
        :class:`~rollability_ros.core.bags.reader.BagReader`). With ``loop`` it must be re-iterable (a reader
        or a list), not a one-shot iterator.
    rate : float
        Playback speed factor (> 0): 2.0 plays twice as fast.
    start_offset_s : float
        Skip the first ``start_offset_s`` seconds of recorded time (>= 0), counted from ``bag_start_time_ns``.
    loop : bool
        Start again from the beginning after the last message, forever; each pass starts right after the
        previous one's last message.
    topics : iterable of str, optional
        Recorded topic names to play (default all).
    remap : dict of str to str, optional
        ``{recorded topic: topic to publish on}``.
    bag_start_time_ns : int, optional
        Recorded time that ``start_offset_s`` counts from; default the first message's log time.

    Raises
    ------
    ValueError
        Bad rate or offset, or ``loop`` with a one-shot iterator.
    """
    if not rate > 0:
        raise ValueError(f"rate must be > 0, got {rate!r}")
    if not start_offset_s >= 0:
        raise ValueError(f"start_offset_s must be >= 0, got {start_offset_s!r}")
    if loop and iter(messages) is messages:
        raise ValueError("loop needs re-iterable messages (a BagReader or a list), not a one-shot iterator")
    # integer nanoseconds throughout: a float sum of an epoch time (~1.8e18 ns) rounds by up to 256 ns and
    # once skipped a bag's first message
    start_offset_ns = round(start_offset_s * 1_000_000_000)
    selected = None if topics is None else set(topics)
    remap = dict(remap or {})
    pass_start_wall_s = 0.0
    previous_wall_s = 0.0
    loop_index = 0
    while True:
        first_ns = None
        last_wall_s = pass_start_wall_s
        for topic, type_name, data, log_time_ns in messages:
            if bag_start_time_ns is None:
                bag_start_time_ns = log_time_ns
            if log_time_ns - bag_start_time_ns < start_offset_ns:
                continue
            if selected is not None and topic not in selected:
                continue
            if first_ns is None:
                first_ns = log_time_ns
            wall_s = pass_start_wall_s + (log_time_ns - first_ns) / 1e9 / rate
            yield PlaybackItem(wall_s, wall_s - previous_wall_s, remap.get(topic, topic), type_name, data,
                               log_time_ns, loop_index)
            previous_wall_s = last_wall_s = wall_s
        if not loop or first_ns is None:
            return
        pass_start_wall_s = last_wall_s
        loop_index += 1


def clock_message_cdr(time_ns: int) -> bytes:
    """Return the CDR bytes of a ``rosgraph_msgs/msg/Clock`` holding ``time_ns`` (ns since the epoch)."""
    seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
    return b"\x00\x01\x00\x00" + struct.pack("<iI", seconds, nanoseconds)
