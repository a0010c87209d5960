"""A resumed study recovers the bag its killed recorder left open before it records into the next one."""
import os
import shutil
import types

from rollability_ros.core.bags import bag_info, is_left_open
from rollability_ros.core.graph.study import Study

KILLED_BAG = os.path.join(os.path.dirname(__file__), "..", "resources", "killed_bag")


def test_a_resumed_study_recovers_the_open_bag_and_records_into_the_next(tmp_path):
    shutil.copytree(KILLED_BAG, tmp_path / "bag")
    assert is_left_open(str(tmp_path / "bag"))
    lines = []
    study = types.SimpleNamespace(study_dir=str(tmp_path), say=lines.append)
    study.bag_dirs = lambda: Study.bag_dirs(study)
    assert Study._next_bag_dir(study) == str(tmp_path / "bag-2")   # the first resume's bag
    assert not is_left_open(str(tmp_path / "bag")) and bag_info(str(tmp_path / "bag"))["message_count"] == 60
    assert any("its recorder was killed" in line for line in lines)
