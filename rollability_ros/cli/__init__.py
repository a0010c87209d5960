"""`rollability <verb>`: the command line over the core.

Each module in this package that defines ``register(subparsers)`` adds one verb; ``register`` adds a subparser
and sets its ``func(args) -> int`` default. Verb modules import heavy dependencies inside ``func`` only, so
``rollability --help`` works on a robot computer without the simulation extras.
"""
import argparse
import importlib
import os
import pkgutil
import sys
import typing

from rollability_ros.core.config import ConfigError
from rollability_ros.core.optional import MissingDependency

#: What a verb module's ``register`` receives: the parser's subcommand table.
Subparsers: typing.TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every verb module registered."""
    parser = argparse.ArgumentParser(
        prog="rollability",
        description="Design and validate passive self-righting profiles for small wheeled robots.",
    )
    subparsers = parser.add_subparsers(dest="verb", metavar="VERB")
    subparsers.required = True
    for module_info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if module_info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{module_info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(subparsers)
    return parser


SESSION_HELP = ("join a running study or bringup session: its directory, its session.yaml, or the name it printed "
                "(looked up under bringup.output_dir); sets the ROS domain, discovery range, namespace and valve key "
                "file from its session.yaml (docs/sessions.md)")


def add_session_argument(parser: argparse.ArgumentParser) -> None:
    """The joining verbs' ``--session SESSION``."""
    parser.add_argument("--session", default=None, metavar="SESSION", help=SESSION_HELP)


def join_session(session: typing.Optional[str], config_files: typing.Sequence[str] = ()) -> typing.Any:
    """Put this process on ``session``'s graph (``os.environ``, before ROS starts) and return its
    :class:`~rollability_ros.core.graph.session.SessionInfo`; None when no session was named."""
    if session is None:
        return None
    from rollability_ros.core.graph import load_graph_settings, load_session, parameter_files

    output_dir = load_graph_settings(parameter_files(["bringup", *config_files])).output_dir
    info = load_session(session, output_dir)
    if not info.running():
        raise ValueError(f"session {info.name} ({info.directory}) is not running: its process {info.pid} has ended "
                         "(its files stay; start a new session, or resume a study with `rollability study --resume`)")
    info.apply(os.environ)
    return info


def line_buffered_output() -> None:
    """Flush stdout and stderr at every line, whatever they are (terminal, pipe, file).

    Python block-buffers stdout into a pipe or a file, so ``rollability study > study.log`` and a supervisor or
    test reading the output would see nothing for minutes.
    """
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)   # absent when a caller swapped in a plain stream
        if reconfigure is not None:
            reconfigure(line_buffering=True)


def main(argv: typing.Optional[typing.Sequence[str]] = None) -> int:
    """Run one verb and return its exit code; known user errors print one line instead of a traceback."""
    line_buffered_output()
    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)   # as typed: a verb can print the command to rerun
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, inside the try, not at interpreter exit
        return code
    except BrokenPipeError:
        # the reader went away (`rollability bag info --json | head`): stop quietly, as a tool killed by SIGPIPE
        # does; stdout goes to /dev/null so the interpreter's final flush cannot raise again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (ConfigError, MissingDependency, FileNotFoundError, FileExistsError, IsADirectoryError, NotADirectoryError,
            PermissionError, ValueError) as exc:   # user errors about paths included: one line, never a traceback
        print(f"rollability {args.verb}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"rollability {args.verb}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
