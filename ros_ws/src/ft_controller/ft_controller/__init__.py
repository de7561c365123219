"""Fault-tolerant redundancy-resolution controller node (`controller_node`)."""
