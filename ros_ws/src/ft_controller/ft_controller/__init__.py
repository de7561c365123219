"""Fault-tolerant redundancy-resolution controller node (filled by the controller issue)."""
