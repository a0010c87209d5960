"""The twin's parameter files a user gives the commands that fit or plan on it (``rollability calibrate --config``,
the adaptive campaign's ``--twin-config``): each key applied or refused, a print file's search keys taken unread,
and the designs they launch checked against the print loaded (what their masses assume)."""
import os
import typing

from rollability_ros.core.config import check_given_files, load_parameters

if typing.TYPE_CHECKING:
    from rollability_ros.core.sim import LaunchTwinSettings

#: What a print file (config/gradual_print.yaml, light_print.yaml, low_infill_print.yaml) sets beside the print:
#: the search's robust draw of the print model's error. The twin's fit and plan draw no robust launch (they launch
#: at the loaded values and the sampled unknowns) and bound a fitted ``robot.profile_mass_scale`` by
#: ``calibration.lower`` / ``upper``, so these change nothing they compute; they are taken from a file that sets a
#: ``profile_print``, named as not read, and left out of the loaded parameters (so out of a prepared likelihood's
#: fingerprint). In any other file they are refused as every key the command does not read.
PRINT_FILE_SEARCH_KEYS = frozenset({"objective.robust.profile_mass_scale_min",
                                    "objective.robust.profile_mass_scale_max"})
#: The namespaces of the print settings (``print_instructions()``): the built-in chassis's and a URDF robot's.
PRINT_NAMESPACES = ("robot.profile_print.", "urdf_robot.profile_print.")


def print_file_search_key(name: str, file_parameters: typing.Mapping[str, object]) -> bool:
    """Whether ``name`` is one of :data:`PRINT_FILE_SEARCH_KEYS` in a print file (one whose flat
    ``file_parameters`` set a print setting)."""
    return name in PRINT_FILE_SEARCH_KEYS and any(key.startswith(PRINT_NAMESPACES) for key in file_parameters)


def load_twin_files(defaults: typing.Sequence[str], given: typing.Sequence[str], reads: typing.Iterable[str],
                    command: str) -> typing.Tuple[typing.Dict[str, object], str]:
    """The flat parameters of ``defaults`` then the user's files ``given`` (each key of them in a namespace of
    ``reads``, or a print file's search key: :data:`PRINT_FILE_SEARCH_KEYS`; anything else is refused in one line
    naming the file, the key and ``command``), without the search keys; and the line that names those not read
    ("" for none)."""
    unread = check_given_files(given, reads, command, unread=print_file_search_key)
    parameters = load_parameters([*defaults, *given])
    for _, name in unread:
        parameters.pop(name, None)
    if not unread:
        return parameters, ""
    files = ", ".join(dict.fromkeys(os.path.basename(path) for path, _ in unread))
    names = ", ".join(sorted({name for _, name in unread}))
    return parameters, (f"{command}: not read from {files}: {names} (the search's robust draws of the print model's "
                        "error; calibration.lower / upper bound a fitted robot.profile_mass_scale)")


def check_designs_print(twin: "LaunchTwinSettings", option: str) -> None:
    """Refuse the twin's designs file (``launch_twin.designs.designs_file``) when its designs were chosen for
    another print than the twin's robot's (:func:`~rollability_ros.core.profile.check_printed_with`: one line
    naming each setting that differs and the parameter file to give with ``option``). A missing file is left to
    the launch that names it."""
    from rollability_ros.core.profile import check_printed_with

    designs_file = twin.twin.designs.designs_file
    if designs_file and os.path.isfile(designs_file):
        check_printed_with(designs_file, twin.print_instructions(), option)
