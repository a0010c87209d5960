"""The report's "run this launch again" command, as a test runs it: the command printed for a stored launch, the
command's printed lines, and the check that they repeat the stored outcome exactly."""
import html
import re
import shlex

import pytest

from rollability_ros.cli import main as cli_main
from rollability_ros.core.store import Store


def printed_command(store, out_dir, configuration):
    """The re-simulation command the report of ``store`` prints for the launch of ``configuration``, and that
    launch's stored outcome."""
    assert cli_main(["report", str(store), "--out", str(out_dir)]) == 0
    page = (out_dir / "report.html").read_text()
    with Store(store) as opened:
        target = next(o for o in opened.launch_outcomes() if o.condition.configuration == configuration)
    row = dict(re.findall(r"<tr id='trial-[^']*'><td>([^<]*)</td>(.*?)</tr>", page))[html.escape(target.trial_id)]
    commands = re.findall(r"<code>(rollability campaign [^<]*)</code>", row)
    assert len(commands) == 1
    return html.unescape(commands[0]), target


def resimulated(command, capsys):
    """Run a printed command; its exit code, its printed ``name: value`` lines and its stderr."""
    capsys.readouterr()
    code = cli_main(shlex.split(command)[1:])
    captured = capsys.readouterr()
    return code, dict(line.split(": ", 1) for line in captured.out.splitlines()), captured.err


def assert_reproduces(printed, target):
    """The printed lines of a re-simulation repeat the stored outcome ``target`` exactly."""
    assert printed["upright"] == str(target.upright).lower()
    assert tuple(float(v) for v in printed["final_orientation (x, y, z, w)"].split()) == target.final_orientation
    assert float(printed["travel_time_s"]) == pytest.approx(target.travel_time_s, abs=1e-12, nan_ok=True)
    for name, value in target.continuous().items():
        assert float(printed[name]) == pytest.approx(value, abs=1e-12, nan_ok=True), name
