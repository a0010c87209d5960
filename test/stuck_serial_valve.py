"""The valve_controller node whose serial writes block while a file exists: a board (or USB-serial chip) that
stopped taking bytes, as a hung firmware does. Fault injection for the tests; nothing else changes.

``python test/stuck_serial_valve.py <jam file> --ros-args -p ...``
"""
import os
import sys
import time

from rollability_ros.core.rig import valve_boards

JAM = sys.argv.pop(1)
_write = valve_boards._SerialPort.write


def jammed_write(self, data):
    while os.path.exists(JAM):   # blocks like a write (or pyserial's tcdrain) into a port no one drains
        time.sleep(0.01)
    return _write(self, data)


valve_boards._SerialPort.write = jammed_write

if __name__ == "__main__":
    from rollability_ros.nodes import valve_controller

    raise SystemExit(valve_controller.main(sys.argv))
