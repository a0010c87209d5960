"""docs/rig-walkthrough.md, run as written: the commands are read from the page (every ``$ `` line of its shell
blocks, and its lab file), each runs as its own process, and a scripted operator types what the page says, in a
campaign terminal, an operator console and other terminals. Issue 45: a technician could not run a physical
campaign from the docs."""
import json
import os
import pathlib
import re
import select
import shlex
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from rollability_ros.cli.rig import CONSOLE_RIG_FOUND

REPO = pathlib.Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "rig-walkthrough.md"
#: What each ``$`` line of the page is, in the page's order.
STEPS = ("simulator", "bringup", "console", "campaign", "confirm", "late outcome", "disarm", "resume", "outcome",
         "report")


def doc_blocks(kind):
    """The fenced blocks of ``kind`` (``shell``, ``yaml``) of the page, in order."""
    return re.findall(rf"```{kind}\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)


def doc_commands():
    """Every command of the page: the ``$ `` lines of its shell blocks, in order."""
    return [line[2:] for block in doc_blocks("shell") for line in block.splitlines() if line.startswith("$ ")]


def argv(command):
    """The page's command as an argv: ``rollability`` is this environment's CLI, ``python`` this interpreter."""
    words = shlex.split(command)
    if words[0] == "rollability":
        return [sys.executable, "-m", "rollability_ros.cli", *words[1:]]
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    raise AssertionError(f"the walkthrough runs only rollability and python commands, got {command!r}")


class Terminal:
    """One process with its output read as it comes (prompts end without a newline) and its stdin to type into."""

    def __init__(self, command, cwd, stdin=True):
        self.command = command
        self.process = subprocess.Popen(argv(command), cwd=cwd, stdin=subprocess.PIPE if stdin else None,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        self.text = ""
        self.mark = 0

    def _read(self, timeout_s):
        readable, _, _ = select.select([self.process.stdout], [], [], timeout_s)
        if readable:
            chunk = os.read(self.process.stdout.fileno(), 65536)
            self.text += chunk.decode("utf-8", "replace")
            return bool(chunk)
        return True

    def expect(self, pattern, timeout_s=90.0):
        """Wait until ``pattern`` (a regex) appears after the last match; returns the match."""
        deadline = time.monotonic() + timeout_s
        while True:
            found = re.compile(pattern).search(self.text, self.mark)
            if found:
                self.mark = found.end()
                return found
            if time.monotonic() > deadline or not self._read(0.1) and self.process.poll() is not None:
                raise AssertionError(f"{self.command!r}: no {pattern!r} within {timeout_s:g} s; output:\n{self.text}")

    def skip(self):
        """Forget the output so far: the next expect looks only at what comes after."""
        self._read(0.0)
        self.mark = len(self.text)

    def type(self, text):
        self.process.stdin.write(text.encode())
        self.process.stdin.flush()

    def wait(self, timeout_s=60.0):
        """Read the output to its end; the exit code."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and self._read(0.1):
            pass
        return self.process.wait(5)

    def stop(self, signum=signal.SIGINT):
        if self.process.poll() is None:
            os.killpg(self.process.pid, signum)


def run(command, cwd, timeout_s=120):
    done = subprocess.run(argv(command), cwd=cwd, capture_output=True, text=True, timeout=timeout_s)
    return done.returncode, done.stdout + done.stderr


@pytest.mark.slow
def test_the_walkthrough_from_an_empty_terminal_to_a_report(tmp_path):
    commands = doc_commands()
    assert len(commands) == len(STEPS), commands
    cmd = dict(zip(STEPS, commands))
    terminals = []
    try:
        # 1. the board
        board = Terminal(cmd["simulator"], tmp_path, stdin=False)
        terminals.append(board)
        port = board.expect(r"relay board simulator ready on (\S+)").group(1)
        # 2. the lab file, as the page shows it, with this board's port
        (lab_yaml,) = doc_blocks("yaml")
        (tmp_path / "lab-rig.yaml").write_text(re.sub(r'port: "[^"]*"', f'port: "{port}"', lab_yaml))
        # 3. the graph
        bringup = Terminal(cmd["bringup"], tmp_path, stdin=False)
        terminals.append(bringup)
        bringup.expect(r"bringup: session runs/walkthrough \(4 nodes, rig backend physical\)")
        # 4. the console
        console = Terminal(cmd["console"], tmp_path)
        terminals.append(console)
        console.expect("console ready: ")
        console.expect(re.escape(CONSOLE_RIG_FOUND))
        # 5. the campaign
        campaign = Terminal(cmd["campaign"], tmp_path)
        terminals.append(campaign)
        campaign.expect(r"Enter to launch, q to stop: ")
        campaign.type("\n")
        campaign.expect(r"set the regulator to 30 psi for 0.8 m/s, then confirm: Enter when done: ")
        # 6. answered from the other place: the campaign stops waiting and shows it
        code, out = run(cmd["confirm"], tmp_path)
        assert code == 0 and "confirm: ok: accepted" in out, out
        campaign.expect("answered: regulator confirmed")
        campaign.expect(r"firing in 3 s")
        campaign.expect(r"\[note\]: ")
        campaign.type("n on its side\n")
        campaign.expect("answered: tipped, note: on its side")
        campaign.expect(r"baseline/h0.75m/v0.8mps/a\+0deg/r0: NOT upright")
        code, out = run(cmd["late outcome"], tmp_path)
        assert code == 1 and "already answered for baseline/h0.75m/v0.8mps/a+0deg/r0: tipped" in out \
            and "this answer (upright) differs and is refused" in out, out
        # 7. the e-stop, during the second launch's countdown, from the console
        campaign.expect(r"Enter to launch, q to stop: ")
        console.skip()   # the first launch's countdown is on the console already
        campaign.type("\n")
        console.expect(r"rig: armed: valve armed; firing in 3 s")
        console.type("e")
        console.expect("E-STOP sent")
        console.expect(r"valve: STOPPED \(e-stop")
        campaign.expect(r"VALVE STOPPED: e-stop")
        resume = campaign.expect(r"to continue, type: (.*)\n").group(1)
        assert campaign.wait() == 3, campaign.text
        assert "rollability rig disarm --session walkthrough" in campaign.text
        assert resume == cmd["resume"], (resume, cmd["resume"])    # the page's resume is what the campaign says
        # 8. acknowledge and resume
        code, out = run(cmd["disarm"], tmp_path)
        assert code == 0 and "disarm: ok" in out, out
        console.expect(r"valve: disarmed")
        resumed = Terminal(cmd["resume"], tmp_path)
        terminals.append(resumed)
        # the stopped launch again (the regulator is asked again after an abort), then the 1.5 m/s pair (asked at
        # the change of speed), the first of which is answered from the other terminal
        for regulator, outcome in ((True, "y\n"), (True, None), (False, "y\n")):
            resumed.expect(r"Enter to launch, q to stop: ")
            resumed.type("\n")
            if regulator:
                resumed.expect(r"Enter when done: ")
                resumed.type("\n")
            resumed.expect(r"\[note\]: ")
            if outcome is None:
                code, out = run(cmd["outcome"], tmp_path)
                assert code == 0 and "outcome: ok: accepted" in out, out
                resumed.expect("answered: tipped")
            else:
                resumed.type(outcome)
        resumed.expect(r"campaign complete: 4/4 trials stored")
        assert resumed.wait() == 0, resumed.text
        # 9. stop the graph, report
        bringup.stop()
        assert bringup.wait(90) == 0, bringup.text
        assert "bringup: stopped (Ctrl-C); outcomes and bag in runs/walkthrough" in bringup.text
        # its progress line follows the campaign, with the campaign's own ETA
        assert re.search(r"campaign rig-walkthrough \| [1-4]/4 launches stored \| ETA \d+ s", bringup.text), bringup.text
        console.type("q")
        assert console.wait() == 0, console.text
        code, out = run(cmd["report"], tmp_path, timeout_s=300)
        assert code == 0, out
        assert "wrote 5 figures, 7 tables and runs/walkthrough-report/report.html" in out, out
        assert "4 trials, 2 grouped conditions (run rig-walkthrough; backend physical)" in out, out
        assert (tmp_path / "runs" / "walkthrough-report" / "report.html").is_file(), out
    finally:
        transcript = os.environ.get("ROLLABILITY_WALKTHROUGH_TRANSCRIPT")   # to compare with the page's outputs
        if transcript:
            pathlib.Path(transcript).write_text("\n".join(f"===== {t.command}\n{t.text}" for t in terminals))
        for terminal in reversed(terminals):
            terminal.stop()
        for terminal in terminals:
            try:
                terminal.process.wait(30)
            except subprocess.TimeoutExpired:
                terminal.stop(signal.SIGKILL)
    # true records: 4 physical, operator-classified, no orientation, no speed from a simulated gate, the run listed
    store = sqlite3.connect(tmp_path / "runs" / "walkthrough" / "outcomes.sqlite")
    rows = store.execute("SELECT trial_id, upright, backend, classified_by, final_orientation, measured_speed_mps, note "
                         "FROM launch_outcomes ORDER BY rowid").fetchall()
    assert [(r[1], r[2], r[3]) for r in rows] == [(0, "physical", "operator"), (1, "physical", "operator"),
                                                   (0, "physical", "operator"), (1, "physical", "operator")], rows
    assert all(r[4] == "[NaN, NaN, NaN, NaN]" and r[5] is None and r[6].startswith("travel time: not measured")
               for r in rows), rows
    ((run_id, kind, info),) = store.execute("SELECT run_id, kind, info FROM runs").fetchall()
    assert (run_id, kind, json.loads(info)["backend"]) == ("rig-walkthrough", "campaign", "physical"), info
