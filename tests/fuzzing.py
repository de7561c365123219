"""How many examples a property-based test draws: the suite's, or a long fuzz run's.

`FT_FUZZ_SCALE=k` multiplies every count by k and draws from fresh random seeds (the
30-minute run of docs/security.md); unset, the suite draws the same examples each run.
"""

from __future__ import annotations

import os

from hypothesis import settings

#: The multiplier of every property-based test's examples (1: the suite's run).
SCALE = max(1, int(os.environ.get("FT_FUZZ_SCALE", "1")))

settings.register_profile("deterministic", derandomize=True, print_blob=True)
settings.register_profile("fuzz", derandomize=False, print_blob=True, database=None)
settings.load_profile("deterministic" if SCALE == 1 else "fuzz")


def examples(count: int) -> int:
    """`count` examples, times `SCALE`."""
    return count * SCALE
