"""The campaign terminal's prompt: a line read from the operator that can be answered from another place too.

``input()`` blocks until Enter: while it waits, the campaign cannot notice that the operator answered the same
question with ``rollability rig confirm`` / ``rig outcome`` in another terminal, or that the valve was stopped.
:class:`TerminalAsk` reads the line itself (``select`` on the input's file descriptor), runs ``idle()`` between
polls (the graph campaign spins its ROS executor there, so valve state and rig feedback arrive while the prompt
waits) and stops waiting as soon as ``interrupted()`` returns something: it raises :class:`AnsweredElsewhere`
with that value, after throwing away what was typed so far (a half-typed answer or a stray Enter must never
answer the next question). Stdlib only.
"""
import os
import sys
import termios
import typing

import select


class AnsweredElsewhere(Exception):
    """The question was answered (or withdrawn) elsewhere while the prompt waited; ``args[0]`` says how."""


class FileDescriptor(typing.Protocol):
    """What :class:`TerminalAsk` reads the operator's lines from: anything with a file descriptor (stdin, a pipe)."""

    def fileno(self) -> int: ...


class TerminalAsk:
    """``ask(prompt, interrupted=None) -> line`` on a terminal or pipe (see the module docstring).

    Parameters
    ----------
    stream, out : file objects
        Where lines come from (its ``fileno()`` is read directly) and where prompts go.
    idle : callable, optional
        Called between polls while waiting (the graph campaign spins its executor there).
    poll_s : float
        Longest wait between checks of ``interrupted``, s.
    """

    def __init__(self, stream: typing.Optional["FileDescriptor"] = None, out: typing.Optional[typing.TextIO] = None,
                 idle: typing.Optional[typing.Callable[[], None]] = None, poll_s: float = 0.05):
        self.stream = stream or sys.stdin
        self.out = out or sys.stdout
        self.idle = idle
        self.poll_s = poll_s
        self._pending = b""

    def __call__(self, prompt: str, interrupted: typing.Optional[typing.Callable[[], object]] = None) -> str:
        """Show ``prompt`` and return the next line typed (without its line end); ``EOFError`` when the input
        closed; :class:`AnsweredElsewhere` when ``interrupted()`` returned a value first."""
        self.out.write(prompt)
        self.out.flush()
        fd = self.stream.fileno()
        while b"\n" not in self._pending:
            if self.idle is not None:
                self.idle()
            if interrupted is not None:
                reason = interrupted()
                if reason is not None:
                    self._discard(fd)
                    self.out.write("\n")
                    self.out.flush()
                    raise AnsweredElsewhere(reason)
            readable, _, _ = select.select([fd], [], [], self.poll_s)
            if readable:
                chunk = os.read(fd, 4096)
                if not chunk:
                    raise EOFError("the operator's input closed")
                self._pending += chunk
        line, self._pending = self._pending.split(b"\n", 1)
        return line.decode("utf-8", "replace").rstrip("\r")

    def _discard(self, fd):
        """Forget what was typed toward the withdrawn question (and, on a terminal, what the kernel holds)."""
        self._pending = b""
        if os.isatty(fd):
            termios.tcflush(fd, termios.TCIFLUSH)
