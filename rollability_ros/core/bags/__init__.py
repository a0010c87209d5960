"""rosbag2 bags in MCAP: write, read, recover, convert, play back; message definitions and QoS.

- writer, reader, recover, convert, metadata: the bag files (_mcap_file: the MCAP file layer writer and recover share)
- messages: records <-> bag messages
- msg_definitions: ros2msg definitions and RIHS01 type hashes
- qos: offered QoS profiles
- playback, record_play: pure helpers of the player and recorder nodes

The face is ``__init__.pyi`` beside this file: the names code outside ``core/bags`` imports (``from
rollability_ros.core.bags import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
