"""rosbag2 bags in MCAP: write, read, recover, convert, play back; message definitions and QoS.

- writer, reader, recover, convert, metadata: the bag files (_mcap_file: the MCAP file layer writer and recover share)
- messages: records <-> bag messages
- msg_definitions: ros2msg definitions and RIHS01 type hashes
- qos: offered QoS profiles
- playback, record_play: pure helpers of the player and recorder nodes

The face below is what code outside ``core/bags`` imports (``from rollability_ros.core.bags import BagReader``). It
is lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's module is imported when
the name is first used, so a light caller never pays for the MCAP and rosbags libraries.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.bags import convert, recover
    from rollability_ros.core.bags.messages import CurrentDefinitions, read_records_from_bag
    from rollability_ros.core.bags.metadata import BagError
    from rollability_ros.core.bags.msg_definitions import definition_for, full_type_name, split_type_name
    from rollability_ros.core.bags.playback import CLOCK_TOPIC, CLOCK_TYPE, clock_message_cdr, playback_schedule
    from rollability_ros.core.bags.qos import qos_dict_from_profile, subscription_qos_for
    from rollability_ros.core.bags.reader import BagReader, bag_info, check_readable, format_bag_info
    from rollability_ros.core.bags.record_play import (PlayerSettings, RecorderSettings, check_topic_names,
                                                       default_bag_directory, parse_remaps, select_topics,
                                                       type_hash_string)
    from rollability_ros.core.bags.recover import is_left_open, mark_restart, missed_windows, recording_gaps
    from rollability_ros.core.bags.writer import BagWriter

__all__ = [
    "CLOCK_TOPIC", "CLOCK_TYPE", "BagError", "BagReader", "BagWriter", "CurrentDefinitions", "PlayerSettings",
    "RecorderSettings", "bag_info", "check_readable", "check_topic_names", "clock_message_cdr", "convert",
    "default_bag_directory", "definition_for", "format_bag_info", "full_type_name", "is_left_open", "mark_restart",
    "missed_windows", "parse_remaps", "playback_schedule", "qos_dict_from_profile", "read_records_from_bag",
    "recording_gaps", "recover", "select_topics", "split_type_name", "subscription_qos_for", "type_hash_string",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
