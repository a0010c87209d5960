"""Records read back from a recorded bag, and records as bag messages: the bag source of ``rollability report``.

Messages are recognised by type (``rollability_ros/msg/LaunchOutcome``, ``CandidateResult``,
``GenerationSummary``, ``TipEvent``), whatever topic they were recorded on; every other type is skipped. A
record repeated in the bag (a republished outcome) is kept once, under the same key as the store
(:func:`rollability_ros.core.store.unique_key`), first one wins, so a bag and the live store of one campaign
give the same records. A record the one mapping (:mod:`rollability_ros.core.record_messages`) refuses as
malformed is skipped with a warning, as the outcome_logger skips it. Decoding uses rosbags' CDR codec with the
definition the bag stores for each type, so a bag recorded before an interface changed still decodes (a
``LaunchOutcome`` recorded before it had ``seed`` reads with ``NO_SEED``); a bag without stored definitions
decodes with our interface files. :class:`CurrentDefinitions` re-encodes such old record messages in the
installed definitions, so the player can publish them to nodes built with today's interfaces.
"""
import functools
import logging
import os
import typing

from rollability_ros.core.bags.msg_definitions import definition_for, full_type_name, interface_text
from rollability_ros.core import record_messages
from rollability_ros.core.record_messages import (CANDIDATE_TYPE, GENERATION_TYPE, OUTCOME_TYPE, RECORD_TYPES,
                                                          TIP_EVENT_TYPE)
from rollability_ros.core.store import unique_key

if typing.TYPE_CHECKING:  # annotations only: rosbags and the reader are imported where used
    from rosbags.typesys.store import Typestore

    from rollability_ros.core.bags.reader import BagMessage, BagReader

__all__ = ["OUTCOME_TYPE", "CANDIDATE_TYPE", "GENERATION_TYPE", "TIP_EVENT_TYPE", "RECORD_TYPES", "typestore",
           "record_from_message", "message_from_record", "read_records_from_bag", "decoding_typestore",
           "current_record_cdr", "CurrentDefinitions"]

_LOG = logging.getLogger(__name__)


@functools.lru_cache(maxsize=1)
def typestore() -> "Typestore":
    """A rosbags type store of ROS 2 Jazzy's standard types plus this package's record messages."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for type_name in ("rollability_ros/msg/LaunchCondition", "rollability_ros/msg/ValveAuth") + tuple(RECORD_TYPES):
        types.update(get_types_from_msg(interface_text(type_name), type_name))
    store.register(types)
    return store


def make_message(type_name: str, **fields: object) -> object:
    """The rosbags message ``type_name`` with ``fields`` (lists become the float64 arrays rosbags encodes)."""
    import numpy

    for name, value in fields.items():
        if isinstance(value, list):
            fields[name] = numpy.asarray(value, dtype=numpy.float64)
    values: typing.Dict[str, typing.Any] = fields   # each of the field's own type; rosbags checks them
    return typestore().types[type_name](**values)


def record_from_message(type_name: str, msg: object) -> record_messages.Record:
    """A decoded record message -> its validated record (:mod:`~rollability_ros.core.record_messages`)."""
    return record_messages.record_from_message(type_name, msg)


def message_from_record(record: record_messages.Record) -> typing.Tuple[str, object]:
    """``(type name, rosbags message)`` for a record; the inverse of :func:`record_from_message`."""
    return record_messages.message_from_record(make_message, record)


@functools.lru_cache(maxsize=64)
def _installed_definition(type_name):
    return definition_for(type_name)


@functools.lru_cache(maxsize=64)
def decoding_typestore(type_name: str, definition: str) -> "Typestore":
    """The rosbags type store that decodes ``type_name`` as recorded with the full ``ros2msg`` ``definition``:
    :func:`typestore` when the definition is ours (or "", none stored), else one built from that definition alone.

    Raises ``ValueError`` when a stored definition does not parse.
    """
    if not definition or definition == _installed_definition(type_name):
        return typestore()
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    try:
        store.register(get_types_from_msg(definition, type_name))
    except Exception as exc:  # rosbags raises its own parser errors; report them as bad input
        raise ValueError(f"the stored definition of {type_name} does not parse: {exc}") from exc
    return store


def current_record_cdr(type_name: str, definition: str, data: bytes) -> bytes:
    """CDR bytes of a recorded record message in the installed definition of ``type_name``.

    ``data`` itself when it was recorded with that definition (or none is stored) or is not a record type;
    otherwise decoded with the recorded ``definition`` and encoded again through its record (fields the old
    definition lacks take the record's defaults, e.g. ``seed`` = ``NO_SEED``). ``ValueError`` for a record the
    mapping refuses as malformed.
    """
    type_name = full_type_name(type_name)
    if type_name not in RECORD_TYPES or not definition or definition == _installed_definition(type_name):
        return data
    record = record_from_message(type_name, decoding_typestore(type_name, definition).deserialize_cdr(data, type_name))
    return bytes(typestore().serialize_cdr(message_from_record(record)[1], type_name))


class CurrentDefinitions:
    """The messages of a :class:`~rollability_ros.core.bags.reader.BagReader` (re-iterable, as the reader is) with
    record messages of an older definition re-encoded in the installed one (:func:`current_record_cdr`), so a
    node built with today's interfaces can decode them; a malformed one is skipped with a warning."""

    def __init__(self, reader: "BagReader"):
        self.reader = reader

    def __iter__(self) -> typing.Iterator["BagMessage"]:
        for message, definition in self.reader.with_definitions():
            try:
                data = current_record_cdr(message.type_name, definition, message.data)
            except ValueError as exc:
                _LOG.warning("skipped %s on %s: %s", message.type_name, message.topic, exc)
                continue
            yield message if data is message.data else message._replace(data=data)


def _bag_messages(path):
    """``(type name, stored definition, CDR bytes)`` of every message in a bag directory or one ``.mcap`` file."""
    from rollability_ros.core.bags.reader import BagReader, open_mcap, schema_text

    if os.path.isdir(path):
        for message, definition in BagReader(path).with_definitions():
            yield message.type_name, definition, message.data
        return
    with open(path, "rb") as stream:
        reader, _ = open_mcap(path, stream)
        for schema, _, record in reader.iter_messages(log_time_order=True):
            yield (schema.name if schema else ""), schema_text(schema), record.data


def read_records_from_bag(path: typing.Union[str, os.PathLike]) -> typing.Tuple[list, list, list, list]:
    """Read the records of a bag: ``(launch_outcomes, candidates, generations, tip_events)``, each in bag order.

    Parameters
    ----------
    path : str or os.PathLike
        A bag directory (``metadata.yaml`` + storage files, MCAP or SQLite3) or one ``.mcap`` file.
    """
    path = os.fspath(path)
    lists: typing.Dict[str, list] = {type_name: [] for type_name in RECORD_TYPES}
    seen = set()
    for type_name, definition, data in _bag_messages(path):
        type_name = full_type_name(type_name) if type_name.count("/") == 1 else type_name
        if type_name not in lists:
            continue
        try:
            store = decoding_typestore(type_name, definition)
            record = record_from_message(type_name, store.deserialize_cdr(data, type_name))
        except ValueError as exc:   # the outcome_logger refuses the same records, so bag and store agree
            _LOG.warning("skipped malformed %s in %s: %s", type_name.rsplit("/", 1)[-1], path, exc)
            continue
        key = (type_name,) + unique_key(record)
        if key not in seen:
            seen.add(key)
            lists[type_name].append(record)
    outcomes, candidates, generations, tip_events = (lists[type_name] for type_name in RECORD_TYPES)
    return outcomes, candidates, generations, tip_events
