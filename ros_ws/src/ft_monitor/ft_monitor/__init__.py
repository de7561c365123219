"""Locked-joint monitor node (filled by the monitor issue)."""
