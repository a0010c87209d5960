"""The face of ``rollability_ros.core.bags``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .convert import convert
from .messages import CurrentDefinitions, read_records_from_bag
from .metadata import BagError
from .msg_definitions import definition_for, full_type_name, split_type_name
from .playback import CLOCK_TOPIC, CLOCK_TYPE, clock_message_cdr, playback_schedule
from .qos import qos_dict_from_profile, subscription_qos_for
from .reader import BagReader, bag_info, check_readable, format_bag_info
from .record_play import (PlayerSettings, RecorderSettings, check_topic_names, default_bag_directory, parse_remaps,
                          select_topics, type_hash_string)
from .recover import is_left_open, mark_restart, missed_windows, recording_gaps, recover
from .writer import BagWriter

__all__ = [
    "CLOCK_TOPIC", "CLOCK_TYPE", "BagError", "BagReader", "BagWriter", "CurrentDefinitions", "PlayerSettings",
    "RecorderSettings", "bag_info", "check_readable", "check_topic_names", "clock_message_cdr", "convert",
    "default_bag_directory", "definition_for", "format_bag_info", "full_type_name", "is_left_open", "mark_restart",
    "missed_windows", "parse_remaps", "playback_schedule", "qos_dict_from_profile", "read_records_from_bag",
    "recording_gaps", "recover", "select_topics", "split_type_name", "subscription_qos_for", "type_hash_string"
]
