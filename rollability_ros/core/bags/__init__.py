"""rosbag2 bags in MCAP: write, read, recover, convert, play back; message definitions and QoS.

- writer, reader, recover, convert, metadata: the bag files (mcap_file: the MCAP file layer writer and recover share)
- messages: records <-> bag messages
- msg_definitions: ros2msg definitions and RIHS01 type hashes
- qos: offered QoS profiles
- playback, record_play: pure helpers of the player and recorder nodes
"""
