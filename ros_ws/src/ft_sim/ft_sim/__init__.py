"""Kinematic plant, failure injection and the end-to-end demo."""
