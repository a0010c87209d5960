"""recorder node: records the project's topics (or chosen ones) into a rosbag2 MCAP bag until SIGINT / SIGTERM.

Bag: ``recorder.output_dir`` (default ``bags/rollability_<UTC date-time>``), written by
:class:`~rollability_ros.core.bags.writer.BagWriter` (metadata.yaml version 9, zstd-chunked MCAP, full ros2msg
schemas, type hashes, offered QoS). A clean stop (SIGINT or SIGTERM) finishes the storage file (summary
section) and writes the final metadata; after ``kill -9``, ``rollability bag recover`` restores every written
chunk (at most ``chunk_size_bytes`` of messages, or ``2 x flush_interval_s`` of them, are lost). A recorder
restarted on the bag a killed one left open recovers it and continues it with a new storage file, so a kill
costs only the open chunk and the time until the restart (``custom_data["recorder_restarts"]`` marks it). What a
transient-local publisher re-delivers to the restarted recorder is recorded only if the bag did not hold it yet
(same topic, send time and bytes; the copies skipped are counted in ``custom_data["recorder_duplicates_skipped"]``):
messages sent while no recorder ran are kept, the ones already in the bag are not written twice.

Topics: ``recorder.topics`` (string array of absolute names; empty = the project's graph, see
:func:`rollability_ros.core.bags.record_play.in_project_graph`), searched for every ``discovery_period_s``; a topic is
subscribed once a publisher exists. Each subscription takes serialized CDR (``raw=True``) with a QoS matched to
the publishers (:func:`~rollability_ros.core.bags.qos.subscription_qos_for`: reliable / transient-local only
when every publisher is). Reliable subscriptions keep all: the recorder's own queue never overwrites a message
(a keep-all publisher is slowed down instead; a keep-last publisher that outruns the recorder loses its oldest
unacknowledged messages on its side). A loss the middleware reports is logged as an ERROR with the topic and
count, and the total is in the closing log line: no silent drops. Each callback also takes what else waits in
its subscription's queue (up to ``DRAIN_LIMIT``), so the rate is not capped by one executor cycle per message.

Other parameters (``recorder.*``): see :class:`~rollability_ros.core.bags.record_play.RecorderSettings`.
"""
import threading
import time
import typing

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node

from rollability_ros.core.bags import (BagWriter, RecorderSettings, check_topic_names, default_bag_directory,
                                       qos_dict_from_profile, select_topics, subscription_qos_for, type_hash_string)
from rollability_ros.nodes._bag_nodes import declare_string_list, message_class, qos_profile_from_dict
from rollability_ros.nodes._support import ParameterError, declare_settings, run_node

#: Longest wait at close for a running callback to finish writing, s.
CLOSE_TIMEOUT_S = 10.0

#: Messages taken straight from a subscription's queue per callback (bounded so timers still run).
DRAIN_LIMIT = 1000


class RecorderNode(Node):
    """Discovers topics, subscribes raw, writes every message through one :class:`BagWriter`."""

    def __init__(self, parameter_overrides=None):
        super().__init__("recorder", parameter_overrides=parameter_overrides)
        self.settings = declare_settings(self, "recorder", RecorderSettings)
        self.chosen_topics = declare_string_list(
            self, "recorder.topics", "absolute topic names to record; empty: every topic of the project's graph",
            check_topic_names)
        settings = self.settings
        self.directory = settings.output_dir or default_bag_directory()
        try:
            self.writer = BagWriter(self.directory, compression=settings.compression,
                                    split_max_bytes=settings.split_max_bytes,
                                    split_max_duration_s=settings.split_max_duration_s,
                                    chunk_size_bytes=settings.chunk_size_bytes,
                                    flush_interval_s=settings.flush_interval_s,
                                    custom_data={"recorded_by": "rollability_ros recorder"},
                                    continue_open=True)
        except (ValueError, OSError) as exc:
            raise ParameterError(f"recorder.output_dir: {exc}") from exc
        if self.writer.continued is not None:
            self.get_logger().warning(
                f"continuing the bag {self.directory} left open by a killed recorder: recovered "
                f"{self.writer.continued['message_count']} messages; messages sent while no recorder ran are "
                f"missing (the gap is noted in its metadata.yaml)")
        # the writer is not thread-safe: every callback that touches it holds this lock (and they share one
        # mutually exclusive group, so the lock is only contended by close())
        self._lock = threading.Lock()
        self._closed = False
        self._group = MutuallyExclusiveCallbackGroup()
        self._recorded = {}
        self._skipped = set()
        self.lost = {}
        self.create_timer(settings.discovery_period_s, self.discover, callback_group=self._group)
        self._flush_timer = self.create_timer(max(0.05, settings.flush_interval_s / 2), self._flush_if_due,
                                              callback_group=self._group)
        self.get_logger().info(f"recording to {self.directory}: "
                               + (", ".join(self.chosen_topics) if self.chosen_topics else "the project's graph"))
        self.discover()

    def discover(self) -> None:
        """Subscribe to every selected topic that has publishers and is not recorded yet."""
        selected, ambiguous = select_topics(self.get_topic_names_and_types(), self.chosen_topics)
        for topic, types in ambiguous:
            self._skip(topic, f"it has several types on the graph ({', '.join(types)}); a bag channel has one")
        for topic, type_name in selected:
            if topic in self._recorded or topic in self._skipped:
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if publishers:
                self._subscribe(topic, type_name, publishers)

    def _skip(self, topic, reason):
        if topic not in self._skipped:
            self._skipped.add(topic)
            self.get_logger().warning(f"not recording {topic}: {reason}")

    def _subscribe(self, topic, type_name, publishers):
        offered = [qos_dict_from_profile(p.qos_profile) for p in publishers]
        hashes = {type_hash_string(p.topic_type_hash.version, p.topic_type_hash.value) for p in publishers}
        type_hash = hashes.pop() if len(hashes) == 1 else None
        try:
            msg_type = message_class(type_name)
            with self._lock:
                if self._closed:
                    return
                self.writer.add_topic(topic, type_name, offered_qos_profiles=offered, type_description_hash=type_hash)
        except ValueError as exc:
            self._skip(topic, str(exc))
            return
        qos = subscription_qos_for(offered, depth=max([self.settings.queue_depth] + [p["depth"] for p in offered]))
        if qos["reliability"] == "reliable":
            qos["history"] = "keep_all"   # never overwrite a reliable message in our queue (see module docstring)
        holder: typing.List[typing.Any] = []   # the subscription, once created
        subscription = self.create_subscription(
            msg_type, topic, self._make_callback(topic, holder), qos_profile_from_dict(qos),
            callback_group=self._group, raw=True,
            event_callbacks=SubscriptionEventCallbacks(message_lost=self._make_lost_callback(topic)))
        holder.append(subscription)
        self._recorded[topic] = subscription
        self.get_logger().info(f"recording {topic} ({type_name}; {qos['reliability']}, {qos['durability']}, "
                               f"{qos['history']})")

    def _write(self, topic, data, info):
        self.writer.write(topic, data, info.get("received_timestamp") or time.time_ns(),
                          info.get("source_timestamp") or None)

    def _drain(self, topic, subscription, limit=None):
        """Write what waits in ``subscription``'s queue (at most ``limit`` messages); the lock is held."""
        taken = 0
        while limit is None or taken < limit:
            with subscription.handle:
                message = subscription.handle.take_message(subscription.msg_type, True)
            if message is None:
                break
            self._write(topic, *message)
            taken += 1

    def _make_callback(self, topic, holder):
        def on_message(data: typing.Any, info: typing.Any) -> None:
            with self._lock:
                if self._closed:
                    return
                self._write(topic, data, info)
                # take what else is queued now: one executor round trip per message would cap the rate
                self._drain(topic, holder[0], DRAIN_LIMIT)
        return on_message

    def _make_lost_callback(self, topic):
        def on_lost(status: typing.Any) -> None:
            self.lost[topic] = self.lost.get(topic, 0) + status.total_count_change
            self.get_logger().error(f"{topic}: the middleware lost {status.total_count_change} message(s) before "
                                    f"the recorder took them ({self.lost[topic]} on this topic so far)")
        return on_lost

    def _flush_if_due(self):
        with self._lock:
            if not self._closed:
                self.writer.flush_if_due()

    def counts(self) -> typing.Dict[str, int]:
        """``{topic: messages written}`` so far."""
        with self._lock:
            return {name: info.message_count for name, info in self.writer.topics.items()}

    def close(self) -> None:
        """Finish the bag (summary section, final metadata.yaml); idempotent.

        The recorder's callback group is taken for good first: a callback already running (the executor takes
        a message before it calls back) finishes writing, and no new one can start and take a message that
        would then be dropped. Then every message still queued in a subscription is written, so a stop loses
        nothing that had arrived.
        """
        with self._lock:
            if self._closed:
                return
        deadline = time.monotonic() + CLOSE_TIMEOUT_S
        while not self._group.beginning_execution(self._flush_timer) and time.monotonic() < deadline:
            time.sleep(0.001)
        with self._lock:
            self._closed = True
            for topic, subscription in self._recorded.items():   # received before the stop: still recorded
                try:
                    self._drain(topic, subscription)
                except Exception as exc:  # a destroyed handle or context must not keep the bag from closing
                    self.get_logger().warning(f"{topic}: could not take the last queued messages: {exc}")
            self.writer.close()
            counts = {name: info.message_count for name, info in self.writer.topics.items()}
        lost = sum(self.lost.values())
        duplicates = self.writer.duplicates_skipped
        self.get_logger().info(f"closed {self.directory}: {sum(counts.values())} messages on {len(counts)} topics"
                               + (f"; {lost} lost by the middleware" if lost else "; none lost")
                               + (f"; {sum(duplicates.values())} re-delivered copies of messages the bag already "
                                  f"held not recorded again ({', '.join(f'{t} {n}' for t, n in duplicates.items())})"
                                  if duplicates else ""))


def main(args: typing.Optional[typing.List[str]] = None,
         parameter_overrides: typing.Optional[typing.List[typing.Any]] = None) -> int:
    return run_node(lambda: RecorderNode(parameter_overrides), args)


if __name__ == "__main__":
    raise SystemExit(main())
