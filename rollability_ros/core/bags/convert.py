"""Convert a rosbag2 bag between MCAP and SQLite3 storage, keeping topics, QoS, type hashes and definitions.

Reads with rosbags' rosbag2 reader (either storage). Writes SQLite3 with rosbags' rosbag2 writer (metadata
version 9) and MCAP with :class:`~rollability_ros.core.bags.writer.BagWriter`, so a converted MCAP bag has
the same layout as a recorded one. Custom data and the ROS distro of the source are carried over. Only the
log (receive) time of each message survives a trip through SQLite3, which stores no publish time.
"""
import os
import typing

from rollability_ros.core.bags.metadata import ROS_DISTRO, read_metadata, topics_from_metadata, write_metadata
from rollability_ros.core.bags.reader import bag_file_errors
from rollability_ros.core.bags.writer import BagWriter
from rollability_ros.core.bags.msg_definitions import definition_for, rihs01_hash

#: Storage ids :func:`convert` writes.
STORAGES = ("mcap", "sqlite3")


def _msg_definition(connection):
    """Return the connection's full ``ros2msg`` definition, from the bag or else from installed interfaces."""
    from rosbags.interfaces import MessageDefinitionFormat

    if connection.msgdef.format == MessageDefinitionFormat.MSG and connection.msgdef.data:
        return connection.msgdef.data
    return definition_for(connection.msgtype)


def convert(src: typing.Union[str, os.PathLike], dst: typing.Union[str, os.PathLike], storage: str = "sqlite3") -> typing.Any:
    """Write a copy of bag ``src`` as a new bag ``dst`` with storage ``"sqlite3"`` or ``"mcap"``.

    Raises
    ------
    ValueError
        Unknown storage, or ``dst`` exists.
    BagError
        ``src`` is not a readable bag.
    """
    from rosbags.rosbag2 import Reader

    if storage not in STORAGES:
        raise ValueError(f"storage must be one of {', '.join(STORAGES)}, got {storage!r}")
    src, dst = os.fspath(src), os.fspath(dst)
    if os.path.exists(dst):
        raise ValueError(f"{dst}: exists; convert writes a new bag and does not overwrite")
    source = read_metadata(src)
    custom_data = source.get("custom_data") or None
    qos = {t.name: t.offered_qos_profiles for t in topics_from_metadata(source)}
    with bag_file_errors(src), Reader(src) as reader:
        if storage == "mcap":
            _write_mcap(reader, dst, custom_data, qos)
        else:
            _write_sqlite3(reader, dst, custom_data)
    if storage == "sqlite3":
        information = read_metadata(dst)
        information["ros_distro"] = source.get("ros_distro") or ROS_DISTRO
        write_metadata(dst, information)


def _write_mcap(reader, dst, custom_data, qos):
    with BagWriter(dst, custom_data=custom_data) as writer:
        for connection in reader.connections:
            writer.add_topic(connection.topic, connection.msgtype, connection.ext.serialization_format,
                             offered_qos_profiles=qos.get(connection.topic), definition=_msg_definition(connection),
                             type_description_hash=connection.digest or None)
        for connection, log_time_ns, data in reader.messages():
            writer.write(connection.topic, bytes(data), log_time_ns)


def _write_sqlite3(reader, dst, custom_data):
    from rosbags.rosbag2 import StoragePlugin, Writer

    writer = Writer(dst, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.SQLITE3)
    for key, value in (custom_data or {}).items():
        writer.set_custom_data(key, value)
    with writer:
        connections = {}
        for connection in reader.connections:
            definition = _msg_definition(connection)
            connections[connection.id] = writer.add_connection(
                connection.topic, connection.msgtype, msgdef=definition,
                rihs01=connection.digest or rihs01_hash(connection.msgtype, definition),
                serialization_format=connection.ext.serialization_format,
                offered_qos_profiles=connection.ext.offered_qos_profiles)
        for connection, log_time_ns, data in reader.messages():
            writer.write(connections[connection.id], log_time_ns, data)
