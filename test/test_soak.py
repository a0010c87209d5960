"""Soak: SIGKILL the logger, the recorder, an evaluator, the rig and the campaign runner of a miniature study at
seeded random moments over several rounds (each ended round is resumed), then check that no record was lost.

Checked at the end: every outcome the campaign runner reported as stored (its acknowledged trials, counted from
its own log) is in the logger's store exactly once, and every stored outcome is in one of the study's bags or
inside a recording gap the bags report. Minutes long: marked ``slow`` (left out of ``./scripts/test.sh``;
``./scripts/test.sh --slow`` and CI run it). ``SOAK_FIGURES`` lines in the output give rounds, kills, outcomes and
losses for the record.
"""
import os
import random
import re
import signal
import subprocess
import sys
import time

import pytest

from conftest import REPO_ROOT

MINI = str(REPO_ROOT / "test" / "resources" / "mini_study.yaml")

#: Seed of the kill schedule (which node, when); change it to explore other interleavings.
SOAK_SEED = 17

#: Rounds with kills before the final round that runs the study to the end undisturbed.
KILL_ROUNDS = 3

#: The processes the soak kills (supervisor names); the campaign runner ends its round (it is not restarted).
VICTIMS = ("outcome_logger", "recorder", "eval_0", "rig", "campaign_runner")

SOAK_CONFIG = """
/**:
  ros__parameters:
    campaign:
      repetitions: 10
"""

#: The runner's line for an acknowledged (stored) trial: ``<trial id>: upright`` or ``: NOT upright``.
ACKNOWLEDGED = re.compile(r"(\S+/r\d+): (?:upright|NOT upright)")


def _start(tmp_path, name, *args):
    log = tmp_path / f"{name}.log"
    with open(log, "w") as stream:
        process = subprocess.Popen([sys.executable, "-m", "rollability_ros.cli", "study", *args], cwd=tmp_path,
                                   stdout=stream, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    return process, log


#: How to recognise each victim among the study's child processes (in their command line).
_MARKERS = {"outcome_logger": b"rollability_ros.nodes.outcome_logger", "recorder": b"rollability_ros.nodes.recorder",
            "eval_0": b"eval_0", "rig": b"rollability_ros.nodes.rig\x00", "campaign_runner":
            b"rollability_ros.nodes.campaign_runner"}


def _child_pid(parent_pid, victim):
    """The pid of the running child of ``parent_pid`` (the study's supervisor) that is ``victim``, or None."""
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stream:
                fields = stream.read().split(") ")[1].split()
            with open(f"/proc/{entry}/cmdline", "rb") as stream:
                command = stream.read()
        except OSError:
            continue
        if int(fields[1]) == parent_pid and fields[0] != "Z" and b"rollability_ros.nodes" in command \
                and _MARKERS[victim] in command:
            return int(entry)
    return None


@pytest.mark.slow
def test_soak_kills_lose_no_acknowledged_or_stored_outcome(tmp_path):
    from rollability_ros.core.bags.messages import read_records_from_bag
    from rollability_ros.core.bags.recover import recording_gaps
    from rollability_ros.core.graph.study import compare_bags_with_store
    from rollability_ros.core.store import Store

    rng = random.Random(SOAK_SEED)
    config = tmp_path / "soak.yaml"
    config.write_text(SOAK_CONFIG)
    study_id = "soak"
    study_dir = tmp_path / "runs" / study_id
    kills = {name: 0 for name in VICTIMS}
    others = [name for name in VICTIMS if name != "campaign_runner"]
    rng.shuffle(others)
    rounds = 0
    for round_index in range(KILL_ROUNDS + 1):
        rounds += 1
        args = (["--config", MINI, "--config", str(config), "--study-id", study_id] if round_index == 0
                else ["--resume", study_id])
        process, log = _start(tmp_path, f"round{round_index}", *args)
        if round_index < KILL_ROUNDS:
            # two of the other nodes (in a seeded order that covers each of them over the rounds), then the
            # runner, each at a random moment once it is up; the runner's kill ends the round
            deadline = time.monotonic() + 600
            planned = [*others[2 * round_index % len(others):][:2], "campaign_runner"]
            for victim in planned:
                time.sleep(rng.uniform(0.5, 3.0))   # short enough that a resumed round still has work to kill in
                pid = None
                while pid is None and process.poll() is None and time.monotonic() < deadline:
                    pid = _child_pid(process.pid, victim)
                    if pid is None:
                        time.sleep(0.2)
                if pid is None:
                    break
                os.kill(pid, signal.SIGKILL)
                kills[victim] += 1
                if victim == "campaign_runner":
                    break
        try:
            code = process.wait(timeout=900)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            raise AssertionError(f"round {round_index} did not end:\n{log.read_text()}")
        if code == 0:
            break
        assert round_index < KILL_ROUNDS, f"the undisturbed final round failed:\n{log.read_text()}"
    assert code == 0, log.read_text()

    runner_log = (study_dir / "logs" / "campaign_runner.log").read_text(errors="replace")
    acknowledged = set(ACKNOWLEDGED.findall(runner_log))
    with Store(study_dir / "outcomes.sqlite") as store:
        stored = store.launch_outcomes(study_id)
    stored_ids = [o.trial_id for o in stored]
    bag_dirs = sorted(p for p in study_dir.glob("bag*") if p.is_dir())
    bagged = {o.trial_id for bag in bag_dirs for o in read_records_from_bag(bag)[0] if o.run_id == study_id}
    gaps = [gap for bag in bag_dirs for gap in recording_gaps(bag)]
    problem, gap_note = compare_bags_with_store(bagged, stored, gaps)
    lost_acknowledged = acknowledged - set(stored_ids)
    print(f"SOAK_FIGURES seed={SOAK_SEED} rounds={rounds} kills={sum(kills.values())} {kills} "
          f"acknowledged={len(acknowledged)} stored={len(stored_ids)} bagged={len(bagged)} gaps={len(gaps)} "
          f"in_gap_not_bagged={len(set(stored_ids) - bagged)} lost_acknowledged={len(lost_acknowledged)} "
          f"duplicates={len(stored_ids) - len(set(stored_ids))} unexplained={problem or 0}")
    assert all(kills.values()), (kills, "the study ended before every kind of node was killed: give the rounds "
                                        "more work (SOAK_CONFIG) or shorter waits")
    assert len(stored_ids) == len(set(stored_ids)) > 0                 # every trial once
    assert not lost_acknowledged and acknowledged, runner_log[-3000:]
    assert problem == "", (problem, gap_note)
