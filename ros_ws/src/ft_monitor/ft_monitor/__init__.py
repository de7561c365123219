"""Locked-joint monitor node (`monitor_node`): detection and reduced-Jacobian remapping."""
