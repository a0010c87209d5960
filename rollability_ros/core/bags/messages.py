"""Records read back from a recorded bag, and records as bag messages: the bag source of ``rollability report``.

Messages are recognised by type (``rollability_ros/msg/LaunchOutcome``, ``CandidateResult``,
``GenerationSummary``, ``TipEvent``), whatever topic they were recorded on; every other type is skipped. A
record repeated in the bag (a republished outcome) is kept once, under the same key as the store
(:func:`rollability_ros.core.results.store.unique_key`), first one wins, so a bag and the live store of one campaign
give the same records. A record the one mapping (:mod:`rollability_ros.core.results.record_messages`) refuses as
malformed is skipped with a warning, as the outcome_logger skips it. Decoding uses rosbags' CDR codec with our
interface files.
"""
import functools
import logging
import os
import typing

from rollability_ros.core.bags.msg_definitions import full_type_name, interface_text
from rollability_ros.core.results import record_messages
from rollability_ros.core.results.record_messages import (CANDIDATE_TYPE, GENERATION_TYPE, OUTCOME_TYPE, RECORD_TYPES,
                                                          TIP_EVENT_TYPE)
from rollability_ros.core.results.store import unique_key

__all__ = ["OUTCOME_TYPE", "CANDIDATE_TYPE", "GENERATION_TYPE", "TIP_EVENT_TYPE", "RECORD_TYPES", "typestore",
           "record_from_message", "message_from_record", "read_records_from_bag"]

_LOG = logging.getLogger(__name__)


@functools.lru_cache(maxsize=1)
def typestore() -> typing.Any:
    """A rosbags type store of ROS 2 Jazzy's standard types plus this package's record messages."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for type_name in ("rollability_ros/msg/LaunchCondition",) + tuple(RECORD_TYPES):
        types.update(get_types_from_msg(interface_text(type_name), type_name))
    store.register(types)
    return store


def make_message(type_name: str, **fields: typing.Any) -> typing.Any:
    """The rosbags message ``type_name`` with ``fields`` (lists become the float64 arrays rosbags encodes)."""
    import numpy

    for name, value in fields.items():
        if isinstance(value, list):
            fields[name] = numpy.asarray(value, dtype=numpy.float64)
    return typestore().types[type_name](**fields)


def record_from_message(type_name: str, msg: typing.Any) -> record_messages.Record:
    """A decoded record message -> its validated record (:mod:`~rollability_ros.core.results.record_messages`)."""
    return record_messages.record_from_message(type_name, msg)


def message_from_record(record: record_messages.Record) -> typing.Tuple[str, typing.Any]:
    """``(type name, rosbags message)`` for a record; the inverse of :func:`record_from_message`."""
    return record_messages.message_from_record(make_message, record)


def _bag_messages(path):
    """``(type name, CDR bytes)`` of every message in a bag directory or a single ``.mcap`` file."""
    from rollability_ros.core.bags.reader import BagReader, open_mcap

    if os.path.isdir(path):
        for message in BagReader(path):
            yield message.type_name, message.data
        return
    with open(path, "rb") as stream:
        reader, _ = open_mcap(path, stream)
        for schema, _, message in reader.iter_messages(log_time_order=True):
            yield (schema.name if schema else ""), message.data


def read_records_from_bag(path: typing.Union[str, os.PathLike]) -> typing.Tuple[list, list, list, list]:
    """Read the records of a bag: ``(launch_outcomes, candidates, generations, tip_events)``, each in bag order.

    Parameters
    ----------
    path : str or os.PathLike
        A bag directory (``metadata.yaml`` + storage files, MCAP or SQLite3) or one ``.mcap`` file.
    """
    path = os.fspath(path)
    store = typestore()
    lists = {type_name: [] for type_name in RECORD_TYPES}
    seen = set()
    for type_name, data in _bag_messages(path):
        type_name = full_type_name(type_name) if type_name.count("/") == 1 else type_name
        if type_name not in lists:
            continue
        try:
            record = record_from_message(type_name, store.deserialize_cdr(data, type_name))
        except ValueError as exc:   # the outcome_logger refuses the same records, so bag and store agree
            _LOG.warning("skipped malformed %s in %s: %s", type_name.rsplit("/", 1)[-1], path, exc)
            continue
        key = (type_name,) + unique_key(record)
        if key not in seen:
            seen.add(key)
            lists[type_name].append(record)
    return tuple(lists[type_name] for type_name in RECORD_TYPES)
