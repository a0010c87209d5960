"""player node: publishes a recorded bag's messages with their original timing, then exits (unless looping).

Parameters (``player.*``; see :class:`~rollability_ros.core.bags.record_play.PlayerSettings`): ``bag`` (required),
``rate``, ``start_offset_s``, ``loop``, ``clock`` (publish ``/clock`` with each message's recorded time),
``wait_for_subscribers_s`` (longest wait for subscribers before the first message), and the string arrays ``topics`` (recorded topics to play;
empty: all) and ``remap`` (``/recorded:=/new``).

Each topic is published with the recorded type (its Python interface package must be installed) and a QoS
adapted from the recorded publishers' offers (reliable / transient-local only when every original publisher
was). Messages go out as the recorded CDR bytes, untouched (except record messages recorded with an older
definition of their type, re-encoded in the installed one: :class:`~rollability_ros.core.bags.messages.
CurrentDefinitions`), at the times given by
:func:`rollability_ros.core.bags.playback.playback_schedule`; the node waits for reliable subscribers to
acknowledge them (up to ``ACK_TIMEOUT_S`` in all, never holding the GIL meanwhile) before it exits.
"""
import sys
import threading
import time
import typing

from rclpy.node import Node

from rollability_ros.core.bags import (CLOCK_TOPIC, CLOCK_TYPE, BagError, BagReader, CurrentDefinitions,
                                       PlayerSettings, check_readable, check_topic_names, clock_message_cdr,
                                       parse_remaps, playback_schedule, subscription_qos_for)
from rollability_ros.nodes._bag_nodes import declare_string_list, message_class, qos_profile_from_dict
from rollability_ros.nodes._support import ParameterError, declare_settings, run_node, wait_for_acks

#: Longest wait for reliable subscribers to acknowledge the last messages before exiting (all topics together), s.
ACK_TIMEOUT_S = 10.0

#: Time given to subscribers to match the player's publishers after the player has matched them, s.
SETTLE_S = 0.3

#: Publisher queue depth, messages.
PUBLISHER_DEPTH = 1000


class PlayerNode(Node):
    """Creates one publisher per played topic and publishes from a playback thread."""

    def __init__(self, parameter_overrides=None):
        super().__init__("player", parameter_overrides=parameter_overrides)
        self.settings = declare_settings(self, "player", PlayerSettings)
        topics = declare_string_list(self, "player.topics", "recorded topics to play; empty: every topic",
                                     check_topic_names)
        self.remap = declare_string_list(self, "player.remap", "remappings /recorded/topic:=/new/topic",
                                         parse_remaps)
        try:
            self.reader = BagReader(self.settings.bag, topics=topics or None)
            check_readable(self.reader)
        except (BagError, ValueError) as exc:
            raise ParameterError(f"player.bag: {exc}") from exc
        duration_s = int((self.reader.metadata.get("duration") or {}).get("nanoseconds", 0)) / 1e9
        if self.settings.start_offset_s > duration_s:
            raise ParameterError(f"player.start_offset_s: {self.settings.start_offset_s:g} s is beyond the end of the "
                                 f"bag ({duration_s:.3f} s of recorded time): nothing would be played")
        self.publishers_by_topic = {}
        self.played_topics = []
        for info in self.reader.topic_infos:
            if topics and info.name not in topics:
                continue
            try:
                msg_type = message_class(info.type_name)
            except ValueError as exc:
                self.get_logger().warning(f"not playing {info.name}: {exc}")
                continue
            qos = qos_profile_from_dict(subscription_qos_for(info.offered_qos_profiles, depth=PUBLISHER_DEPTH))
            target = self.remap.get(info.name, info.name)
            self.publishers_by_topic[target] = self.create_publisher(msg_type, target, qos)
            self.played_topics.append(info.name)
        self.clock_publisher = (self.create_publisher(message_class(CLOCK_TYPE), CLOCK_TOPIC, 100)
                                if self.settings.clock else None)
        self.published = 0
        self.error = None              # why the playback stopped early; main() then exits non-zero
        self._stop = threading.Event()
        self.finished = threading.Event()   # set when the playback is over: run_node then stops the node
        self._thread = threading.Thread(target=self._play, name="playback", daemon=True)
        self._thread.start()

    def _play(self):
        settings = self.settings
        logger = self.get_logger()
        logger.info(f"playing {settings.bag}: {', '.join(self.played_topics) or 'no topics'} at rate "
                    f"{settings.rate}" + (" (looping)" if settings.loop else ""))
        if self._wait_for_subscribers():
            return
        start = None
        # record messages of a bag recorded with older interfaces are published re-encoded in the installed ones
        schedule = playback_schedule(CurrentDefinitions(self.reader), rate=settings.rate,
                                     start_offset_s=settings.start_offset_s, loop=settings.loop,
                                     topics=self.played_topics, remap=self.remap)
        try:
            for item in schedule:
                if start is None:
                    # the clock starts at the first message, once it is read: reading may take a while on a
                    # loaded machine, and a clock started earlier would publish the first messages in a burst
                    start = time.monotonic() - item.wall_time_s
                wait_s = start + item.wall_time_s - time.monotonic()
                if wait_s > 0 and self._stop.wait(wait_s):
                    return
                if self._stop.is_set():
                    return
                if self.clock_publisher is not None:
                    self.clock_publisher.publish(clock_message_cdr(item.log_time_ns))
                self.publishers_by_topic[item.topic].publish(item.data)
                self.published += 1
        except BagError as exc:
            self.error = str(exc)
            logger.error(f"playback stopped: {exc}")
        if self.published == 0 and self.error is None and not self._stop.is_set() and any(
                t.message_count for t in self.reader.topic_infos if t.name in self.played_topics):
            self.error = (f"no message at or after the start offset ({settings.start_offset_s:g} s) on the played "
                          "topics: nothing was played")
        unacknowledged = wait_for_acks(self._publishers_to_wait_for(), ACK_TIMEOUT_S, self._stop)
        if unacknowledged and not self._stop.is_set():
            logger.warning(f"{unacknowledged} topic(s) not acknowledged by every reliable subscriber within "
                           f"{ACK_TIMEOUT_S:g} s")
        logger.info(f"played {self.published} messages from {settings.bag}")
        # the playback is the node's whole job: run_node ends the spin (the executor is shut down only once its
        # thread has left it: shutting it down from here would race the wait set being built)
        self.finished.set()

    def _wait_for_subscribers(self):
        """Wait until every played topic has a subscriber (plus a moment for them to match us back), or the
        timeout; return True when the node is stopping."""
        deadline = time.monotonic() + self.settings.wait_for_subscribers_s
        while time.monotonic() < deadline:
            if all(p.get_subscription_count() for p in self._publishers_to_wait_for()):
                return self._stop.wait(min(SETTLE_S, max(0.0, deadline - time.monotonic())))
            if self._stop.wait(0.05):
                return True
        return self._stop.is_set()

    def _publishers_to_wait_for(self):
        return list(self.publishers_by_topic.values()) + ([self.clock_publisher] if self.clock_publisher else [])

    def close(self) -> None:
        """Stop the playback thread (run_node calls this before destroying the node)."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=ACK_TIMEOUT_S + 5)


def main(args: typing.Optional[typing.List[str]] = None,
         parameter_overrides: typing.Optional[typing.List[typing.Any]] = None) -> int:
    """Play the bag; exit 0 when every message was published, 1 when the bag failed part-way, 2 on bad input."""
    nodes = []

    def create() -> PlayerNode:
        nodes.append(PlayerNode(parameter_overrides))
        return nodes[0]

    code = run_node(create, args)
    if code == 0 and nodes and nodes[0].error is not None:
        print(f"error: playback of {nodes[0].settings.bag} stopped: {nodes[0].error}", file=sys.stderr)
        return 1
    return code


if __name__ == "__main__":
    raise SystemExit(main())
