"""Who can reach the rig: the physical rig's default domain / discovery range, and the doctor's warnings."""
import os
import subprocess
import sys

import pytest

from rollability_ros.core.rig import rig_network


def test_defaults_fill_only_what_the_operator_left_unset():
    assert rig_network.physical_rig_environment({}) == {"ROS_DOMAIN_ID": "73",
                                                        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    assert rig_network.physical_rig_environment({"ROS_DOMAIN_ID": "5", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}) == {}
    with pytest.raises(ValueError, match="discovery range"):
        rig_network.physical_rig_environment({}, discovery_range="WIDE")


def test_subnet_wide_or_default_domain_is_warned_about():
    assert rig_network.exposure_warnings({"ROS_DOMAIN_ID": "73", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}) == []
    warnings = rig_network.exposure_warnings({})
    assert any("local network" in w for w in warnings) and any("domain 0" in w for w in warnings)
    assert any("static peers" in w for w in rig_network.exposure_warnings(
        {"ROS_DOMAIN_ID": "73", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "10.0.0.2"}))


def test_doctor_rig_warns_about_subnet_discovery():
    env = {k: v for k, v in os.environ.items() if k != "ROS_AUTOMATIC_DISCOVERY_RANGE"}
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    out = subprocess.run([sys.executable, "-m", "rollability_ros.cli", "doctor", "--rig"], capture_output=True,
                         text=True, timeout=120, env=env).stdout
    assert "warn  rig exposure" in out and "local network" in out, out
