"""A stand-in for libgpiod's ``gpiod`` module in a child process (no GPIO chip here): every line request, value
and release is appended to the JSON-lines file named by ``FAKE_GPIOD_LOG``, with CLOCK_MONOTONIC times."""
import json
import os
import time
import types

line = types.SimpleNamespace(Direction=types.SimpleNamespace(OUTPUT="output"),
                             Value=types.SimpleNamespace(ACTIVE="active", INACTIVE="inactive"))


def _log(**entry):
    with open(os.environ["FAKE_GPIOD_LOG"], "a", encoding="utf-8") as stream:
        stream.write(json.dumps({**entry, "pid": os.getpid(), "monotonic_s": time.monotonic()}) + "\n")


class LineSettings:
    def __init__(self, direction=None, active_low=False, output_value=None):
        self.direction, self.active_low, self.output_value = direction, active_low, output_value


class _Request:
    def __init__(self, path, config):
        for offset, settings in config.items():
            _log(event="request", path=path, offset=offset, value=settings.output_value,
                 active_low=settings.active_low)

    def set_value(self, offset, value):
        _log(event="set", offset=offset, value=value)

    def release(self):
        _log(event="release")


def request_lines(path, consumer=None, config=None, **_options):
    return _Request(path, config)
