"""Test-session set-up: an isolated ROS 2 graph and deterministic property tests.

Each session gets its own ROS_DOMAIN_ID (from its process id) and keeps DDS
discovery on this machine, so parallel sessions and CI runs do not see each other,
and its own ROS_HOME, so no test reads or writes the user's ~/.ros.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

from hypothesis import settings

os.environ["ROS_DOMAIN_ID"] = str(1 + os.getpid() % 100)
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.pop("ROS_STATIC_PEERS", None)
# Nodes keep state under ROS_HOME (the monitor's locked set): never the user's own.
os.environ["ROS_HOME"] = tempfile.mkdtemp(prefix="ft_tests_ros_home_")
atexit.register(shutil.rmtree, os.environ["ROS_HOME"], ignore_errors=True)

# Property-based tests draw the same examples on every run: failures reproduce.
settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.load_profile("deterministic")
