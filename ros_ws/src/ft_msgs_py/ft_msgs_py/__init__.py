"""The suite's ROS 2 interface contract in code (filled by the controller issue)."""
