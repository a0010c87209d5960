"""Progress display of study / bringup: every generation once in a log, a live line on a terminal, honest ETAs."""
import io
import os

import pytest

from rollability_ros.core.graph.progress import JobProgress, ProgressDisplay, eta_s, format_duration


class Terminal(io.StringIO):
    """A stream that says it is a terminal, as a console's stdout does."""

    def isatty(self):
        return True


def test_eta_and_text():
    assert eta_s(4, 30, 80.0) == pytest.approx(520.0)      # 20 s per generation, 26 to go
    assert eta_s(0, 30, 80.0) is None and eta_s(5, 0, 10.0) is None and eta_s(30, 30, 99.0) == 0.0
    assert format_duration(42) == "42 s" and format_duration(600) == "10 min" and format_duration(7200) == "2.0 h"
    text = JobProgress("optimizing", 4, 30, 0.851, 480, eta_s=520.0, trials_label="simulated trials evaluated").text()
    assert text == "optimizing | generation 4/30 | best 0.85 | 480 simulated trials evaluated | ETA 9 min"
    assert JobProgress("launch campaign", trials_stored=12, trials_total=36).text() == \
        "launch campaign | 12/36 trials stored | ETA unknown"


def test_plain_lines_when_not_a_terminal_each_change_once():
    stream = io.StringIO()
    with ProgressDisplay(stream) as display:
        assert not display.live
        for _ in range(3):   # the same snapshot on every tick of a silent phase: printed once
            display.update(JobProgress("optimizing: nodes starting"))
        display.say("optimizing the profile")
        for generation in (1, 2, 3):
            display.update(JobProgress("optimizing", generation, 3, 0.5, 10 * generation, eta_s=3.0 - generation))
    lines = stream.getvalue().splitlines()
    assert lines == ["  optimizing: nodes starting", "optimizing the profile",   # no end to estimate: no ETA
                     "  optimizing | generation 1/3 | best 0.50 | 10 trials stored | ETA 2 s",
                     "  optimizing | generation 2/3 | best 0.50 | 20 trials stored | ETA 1 s",
                     "  optimizing | generation 3/3 | best 0.50 | 30 trials stored | ETA 0 s"]
    assert "\r" not in stream.getvalue() and "\x1b" not in stream.getvalue()


def test_a_terminal_gets_one_live_line(monkeypatch):
    pytest.importorskip("rich")
    # the terminal this test needs, whatever the caller's (rich draws no live line on TERM=dumb or unknown)
    monkeypatch.setenv("TERM", "xterm-256color")
    for name in ("NO_COLOR", "FORCE_COLOR", "TTY_COMPATIBLE", "TTY_INTERACTIVE", "COLUMNS", "LINES"):
        monkeypatch.delenv(name, raising=False)
    stream = Terminal()
    with ProgressDisplay(stream) as display:
        assert display.live
        display.update(JobProgress("optimizing", 2, 30, 0.7, 40, eta_s=600.0))
        display.say("designs selected: A, B")
    output = stream.getvalue()
    assert "designs selected: A, B" in output and "\x1b[" in output   # cursor control: the line is redrawn


class Observed:
    """What a GraphObserver would have received: ``run.progress()`` after each generation (what the optimizer node
    publishes on optimizer_progress) and the logger's counts. The real one over DDS: test/test_graph_observer.py."""

    def __init__(self):
        self.progress, self.launches, self.trials, self.campaign = [], None, {}, None

    def optimizer_progress(self):
        return list(self.progress)

    def stored_launches(self):
        return self.launches

    def stored_trials(self, run_id):
        return self.trials.get(run_id)

    def campaign_progress(self):
        return self.campaign

    def follow(self, run):
        self.progress.append(run.progress())
        run.on_generation = lambda _record: self.progress.append(run.progress())


def test_the_study_shows_every_generation_the_optimizer_reported(tmp_path):
    """Generations completed between two ticks are all shown, with the trials evaluated and an ETA."""
    pytest.importorskip("cma")
    import numpy as np

    from rollability_ros.core.graph.study import Study, study_config
    from doubles import SyntheticEvaluator
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    from rollability_ros.core.profile.geometry import ProfileGrid

    stream = io.StringIO()
    observed = Observed()
    study = Study(study_config(study_id="progress"), display=ProgressDisplay(stream), observer=observed)
    study.study_dir = str(tmp_path)
    study.parameters["optimizer.max_generations"] = 4
    assert study._progress_optimization()[0].phase == "optimizing: nodes starting"
    grid = ProfileGrid(rows=3, cols=3)
    run = OptimizationRun(study.optimization_dir, run_config({"optimizer.max_generations": 4, "optimizer.trials": 10}),
                          grid, SyntheticEvaluator(np.full(9, 0.2), trials=10))
    observed.follow(run)
    assert study._progress_optimization()[0].phase == "optimizing: first generation under evaluation"
    run.run()
    run.close()
    shown = study._progress_optimization()
    assert [p.generation for p in shown] == [1, 2, 3, 4] and all(p.max_generations == 4 for p in shown)
    assert "simulated trials evaluated" in shown[-1].text()   # not "stored": no launch has happened yet
    assert shown[-1].trials_stored == sum(c.trials for c in run_candidates(study.optimization_dir))
    assert shown[-1].eta_s == 0.0 and shown[0].eta_s > 0
    assert [p.generation for p in study._progress_optimization()] == [4]   # nothing new: the latest again
    assert study._progress_campaign(8)[0].phase == "launch campaign: starting"
    observed.trials["progress"] = 2
    assert study._progress_campaign(8)[0].trials_stored == 2


def test_a_resumed_run_reports_its_earlier_trials(tmp_path):
    pytest.importorskip("cma")
    import numpy as np

    from doubles import SyntheticEvaluator
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    from rollability_ros.core.profile.geometry import ProfileGrid

    parameters, grid = {"optimizer.max_generations": 2, "optimizer.trials": 10}, ProfileGrid(rows=3, cols=3)
    run = OptimizationRun(str(tmp_path / "opt"), run_config(parameters), grid, SyntheticEvaluator(np.full(9, 0.2), trials=10))
    run.step()
    first = run.progress()
    run.close()
    again = OptimizationRun(str(tmp_path / "opt"), run_config(parameters), grid, SyntheticEvaluator(np.full(9, 0.2), trials=10),
                            resume=True)
    assert again.progress() == first and first.generation == 1 and first.trials == 10 * len(run_candidates(
        str(tmp_path / "opt")))
    again.close()


def run_candidates(run_dir):
    from rollability_ros.core.store import Store

    with Store(os.path.join(run_dir, "store.sqlite")) as store:
        return store.candidates()


def test_a_bringup_session_shows_its_optimization_and_stored_launches(tmp_path):
    pytest.importorskip("cma")
    import numpy as np

    from rollability_ros.core.graph.progress import session_progress
    from doubles import SyntheticEvaluator
    from rollability_ros.core.optimization.optimization_run import OptimizationRun, run_config
    from rollability_ros.core.profile.geometry import ProfileGrid

    observed = Observed()
    empty = session_progress(observed, 7, 65.0)
    # no end to estimate, no "ETA unknown"; whole minutes, so a log gets a line per change, not one a second
    assert empty.text() == "session up 1 min, 7 nodes supervised"
    assert session_progress(observed, 7, 119.0).text() == empty.text()
    observed.campaign = ("rig-walkthrough", 1, 4, None)     # the graph campaign's own count, then its ETA
    assert session_progress(observed, 7, 65.0).text() == (
        "session up 1 min, 7 nodes supervised, campaign rig-walkthrough | 1/4 launches stored | ETA unknown")
    observed.campaign = ("rig-walkthrough", 2, 4, 130.0)
    assert session_progress(observed, 7, 65.0).text().endswith("2/4 launches stored | ETA 2 min")
    observed.campaign = None
    run = OptimizationRun(str(tmp_path / "opt-1"), run_config({"optimizer.max_generations": 3, "optimizer.trials": 10}),
                          ProfileGrid(rows=3, cols=3), SyntheticEvaluator(np.full(9, 0.2), trials=10))
    observed.follow(run)
    run.run()
    run.close()
    observed.launches = 5
    progress = session_progress(observed, 7, 65.0)
    assert (progress.generation, progress.max_generations, progress.eta_s) == (3, 3, 0.0)
    assert "optimizing run opt-1" in progress.phase and progress.best_so_far is not None
    assert progress.trials_stored == 5
