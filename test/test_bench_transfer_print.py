"""bench/bench_transfer.py's checks load the print a study's designs were chosen for (print_config): a study on the
quick default prints with gradual infill from config/optimizer.yaml, which `rollability evaluate` and `sensitivity`
do not read, so the checks would weigh its designs by robot.yaml's 20 % print (and refuse the designs file)."""
import pathlib
import shutil
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.bench_transfer import print_config  # noqa: E402
from rollability_ros.core.config import load_parameters  # noqa: E402

PRINT = ("robot.profile_print.", "robot.profile_mass_scale", "objective.robust.profile_mass_scale_")


def study_with(tmp_path, names):
    """A study folder whose config/ holds the parameter files ``names`` in load order, as `rollability study` keeps."""
    config = tmp_path / "study" / "config"
    config.mkdir(parents=True)
    for number, name in enumerate(names):
        shutil.copy(ROOT / "config" / f"{name}.yaml", config / f"{number:02d}-{name}.yaml")
    return str(tmp_path / "study"), [str(config / f"{number:02d}-{name}.yaml") for number, name in enumerate(names)]


@pytest.mark.parametrize("names, infill, steps, low", [
    (["sim", "robot", "evaluator", "optimizer"], 0.2, 5, 0.8),                    # the quick default: gradual
    (["sim", "robot", "evaluator", "optimizer", "light_print"], 0.1, 0, 0.8),     # an option laid over it
    (["sim", "robot", "evaluator"], 0.2, 0, None),                                # robot.yaml's print, no draw set
])
def test_the_checks_load_the_print_and_mass_draw_the_study_loaded(tmp_path, names, infill, steps, low):
    study_dir, files = study_with(tmp_path, names)
    study = load_parameters(files)
    checks = load_parameters([str(ROOT / "config" / name) for name in ("sim.yaml", "robot.yaml", "evaluator.yaml")]
                             + [print_config(study_dir)])
    chosen = {key: value for key, value in study.items() if key.startswith(PRINT)}
    assert chosen and {key: checks.get(key) for key in chosen} == chosen
    assert (checks["robot.profile_print.infill_fraction"], checks.get("robot.profile_print.gradual_infill_steps", 0)) == (
        infill, steps)
    assert checks.get("objective.robust.profile_mass_scale_min") == low
