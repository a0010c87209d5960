"""The campaign loop (core/campaign/runner.py) against a real store, and `rollability campaign` in process with
a scripted operator on stdin driving the physical path on the dry-run valve."""
import math
import shlex
import subprocess
import sys

import pytest

from rollability_ros.core.campaign.plan import CampaignSpec, plan_trials
from rollability_ros.core.campaign.runner import (NotStored, StoreAcknowledgements, answer_rig, resume_refusal,
                                                  run_campaign, store_writer)
from rollability_ros.core.records import LaunchOutcome
from rollability_ros.core.rig.rig_session import LaunchAborted, OperatorOutcome
from rollability_ros.core.store import Store

SPEC = CampaignSpec(run_id="loop", configurations=["A", "B"], heights_m=[0.75], speeds_mps=[0.8, 1.5],
                    angles_deg=[0.0], repetitions=2)


def outcome_for(trial, run_id="loop", upright=True):
    return LaunchOutcome(run_id, trial.trial_id, trial.condition, "sim", upright, classified_by="sim")


def test_runs_every_trial_once_and_resumes_after_a_failure(tmp_path):
    plan = plan_trials(SPEC)
    launched, lines = [], []

    def flaky(trial):
        launched.append(trial.trial_id)
        if len(launched) == 3:
            raise LaunchAborted("valve did not fire: fault latched: e-stop")
        return outcome_for(trial)

    with Store(tmp_path / "s.sqlite") as store:
        report = run_campaign(plan, "loop", store.trial_ids("loop"), flaky, store_writer(store), say=lines.append)
        assert (report.stored_now, report.done, report.total) == (2, 2, 8) and not report.complete
        assert "e-stop" in report.stopped_reason and plan[2].trial_id in report.stopped_reason
        assert store.trial_ids("loop") == {plan[0].trial_id, plan[1].trial_id}
        assert "8 remaining" in lines[0] and "2/8 done, 6 remaining" in lines[2]
        assert resume_refusal(2, False, "loop").startswith("run loop already has 2 stored trials")
        assert resume_refusal(2, True, "loop") == ""

        launched.clear()
        report = run_campaign(plan, "loop", store.trial_ids("loop"), outcome_for, store_writer(store), say=lines.append)
        assert report.complete and report.stored_now == 6
        assert [o.trial_id for o in store.launch_outcomes("loop")] == [t.trial_id for t in plan]


def test_attended_run_tells_the_operator_what_to_change_and_can_be_stopped(tmp_path):
    plan = plan_trials(SPEC)
    answers = iter(["", "", "", "q"])
    prompts, lines = [], []

    def ask(prompt):
        prompts.append(prompt)
        return next(answers)

    with Store(tmp_path / "s.sqlite") as store:
        report = run_campaign(plan, "loop", set(), outcome_for, store_writer(store), ask=ask, say=lines.append,
                              pressure_psi_by_speed={0.8: 30.0, 1.5: 60.0})
    assert report.stopped_reason == "stopped by the operator" and report.done == 3
    assert any("mount configuration A" in line for line in lines)
    assert any("set the launch speed to 1.5 m/s (regulator 60 psi) (was 0.8 m/s)" in line for line in lines)
    assert all("place the chassis" in p for p in prompts)


def test_wrong_answer_and_unstored_outcome_stop_the_campaign(tmp_path):
    plan = plan_trials(SPEC)
    with Store(tmp_path / "s.sqlite") as store:
        report = run_campaign(plan, "loop", set(), lambda t: outcome_for(plan[5]), store_writer(store), say=print)
        assert "the rig answered" in report.stopped_reason and not store.trial_ids("loop")


def test_store_acknowledgements_wait_for_the_trial_they_name():
    plan = plan_trials(SPEC)
    spins = []
    acknowledgements = StoreAcknowledgements(lambda: spins.append(1), timeout_s=0.2)
    acknowledgements.acknowledge("other-run", plan[0].trial_id)        # same trial id, another run: not it
    acknowledgements.acknowledge("loop", plan[1].trial_id)
    with pytest.raises(NotStored, match="no outcome_logger acknowledged storing loop/"):
        acknowledgements(outcome_for(plan[0]))
    assert spins                                                        # it kept the executor turning
    acknowledgements(outcome_for(plan[1]))

    # an acknowledgement that arrives while waiting (from the spin) ends the wait
    late = StoreAcknowledgements(lambda: late.acknowledge("loop", plan[2].trial_id), timeout_s=5.0)
    late(outcome_for(plan[2]))

    # the campaign stops at the trial whose acknowledgement never comes; the ones before count
    stored = StoreAcknowledgements(lambda: None, timeout_s=0.1)
    launched = []

    def launch(trial):
        launched.append(trial.trial_id)
        if len(launched) < 3:
            stored.acknowledge("loop", trial.trial_id)
        return outcome_for(trial)

    report = run_campaign(plan, "loop", set(), launch, stored, say=print)
    assert (report.stored_now, report.done) == (2, 2) and plan[2].trial_id in report.stopped_reason


def test_answer_rig_maps_feedback_to_operator_answers():
    typed = iter(["", "perhaps", "n 0.41 lid"])
    assert answer_rig("waiting_for_operator", "set the regulator to 60 psi for 1.5 m/s, then confirm",
                      lambda p: next(typed)) == ("confirm", None)
    assert answer_rig("classifying", "record the outcome of t: upright or not", lambda p: next(typed)) == (
        "outcome", OperatorOutcome(False, 0.41, "lid"))
    assert answer_rig("armed", "valve armed", lambda p: pytest.fail("asked")) is None
    assert answer_rig("classifying", "IMU: upright", lambda p: pytest.fail("asked")) is None


CAMPAIGN_YAML = """/**:
  ros__parameters:
    campaign:
      run_id: cli-physical
      configurations: [A]
      heights_m: [0.75]
      speeds_mps: [0.8, 1.5]
      angles_deg: [0.0]
      repetitions: 2
"""
RIG_OVERRIDE_YAML = """/**:
  ros__parameters:
    rig:
      countdown_s: 0.0
"""


def test_cli_physical_in_process_with_a_scripted_operator(tmp_path):
    (tmp_path / "campaign.yaml").write_text(CAMPAIGN_YAML)
    (tmp_path / "fast.yaml").write_text(RIG_OVERRIDE_YAML)
    store = tmp_path / "store.sqlite"
    command = [sys.executable, "-m", "rollability_ros.cli", "campaign", "--backend", "physical", "--config",
               str(tmp_path / "campaign.yaml"), "--rig-config", "rig", "--rig-config", str(tmp_path / "fast.yaml"),
               "--store", str(store)]
    # trial 1: Enter, regulator Enter, outcome; trial 2: Enter, outcome; then the operator stops
    first = subprocess.run(command, input="\n\ny\n\nn 0.5 on its lid\nq\n", capture_output=True, text=True,
                           timeout=60)
    assert first.returncode == 3, first.stdout + first.stderr
    assert "stopped by the operator" in first.stdout
    assert f"to continue, type: rollability {shlex.join(command[3:])} --resume" in first.stdout   # the real command
    again = subprocess.run(command, input="", capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and "--resume" in again.stderr
    resumed = subprocess.run(command + ["--resume"], input="\n\ny\n\ny\n", capture_output=True, text=True,
                             timeout=60)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert "campaign complete: 4/4" in resumed.stdout and "60 psi" in resumed.stdout
    with Store(store) as stored:
        outcomes = stored.launch_outcomes("cli-physical")
    assert [o.upright for o in outcomes] == [True, False, True, True]
    assert outcomes[1].note == "travel time: typed by the operator (rig outcome --travel-time-s); on its lid"
    assert outcomes[1].classified_by == "operator" and outcomes[1].travel_time_s == 0.5
    # the shipped speed gate is simulated: its made-up times are not a physical record's speed
    assert all(o.backend == "physical" and math.isnan(o.measured_speed_mps) for o in outcomes if o != outcomes[1])


def test_the_operator_prompt_stops_waiting_when_the_question_was_answered_elsewhere():
    """Issue 45: after `rollability rig confirm` the campaign terminal stayed blocked on its own prompt, and the
    Enter typed there then answered nothing (or the next question)."""
    import os

    from rollability_ros.core.campaign import AnsweredElsewhere, TerminalAsk, resume_command

    read_fd, write_fd = os.pipe()
    out = []

    class Out:
        def write(self, text):
            out.append(text)

        def flush(self):
            pass

    idle = []
    ask = TerminalAsk(os.fdopen(read_fd, "rb", buffering=0), Out(), idle=lambda: idle.append(1), poll_s=0.01)
    os.write(write_fd, b"y 0.4\nsecond")
    assert ask("outcome: ") == "y 0.4" and out == ["outcome: "]
    polls = []
    with pytest.raises(AnsweredElsewhere, match="classifying: answered: tipped"):
        ask("next: ", interrupted=lambda: polls.append(1) or ("classifying: answered: tipped" if len(polls) > 3
                                                                else None))
    assert idle and len(polls) == 4
    os.write(write_fd, b"\n")     # the half-typed "second" went with the withdrawn question: not the next answer
    assert ask("again: ") == ""
    os.close(write_fd)
    with pytest.raises(EOFError):
        ask("closed: ")
    assert resume_command(["campaign", "--backend", "physical", "--config", "my file.yaml"]) == \
        "rollability campaign --backend physical --config 'my file.yaml' --resume"
    assert resume_command(["campaign", "--resume"]).count("--resume") == 1
