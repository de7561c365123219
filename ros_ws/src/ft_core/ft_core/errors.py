"""The root of the suite's own errors.

Every error the suite raises for an input it refuses (a robot model, a message, a
persisted file, a target out of reach, a model the physics plant cannot simulate) is a
`SuiteError`: catch it to tell the suite's refusals from a bug's. It is a ValueError, as
each of them was, so code that catches ValueError keeps working.
"""

from __future__ import annotations


class SuiteError(ValueError):
    """An input the suite refuses, with the reason as its message."""
