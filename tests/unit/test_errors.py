"""One root for the suite's errors: each refusal is a `SuiteError`, still a ValueError."""

from __future__ import annotations

import pytest
from ft_core.errors import SuiteError
from ft_core.locked_set import LockedSetError
from ft_core.physics import PhysicsError
from ft_core.robots import RobotModelError
from ft_core.selfmotion import UnreachableError
from ft_msgs_py.messages import MessageError


@pytest.mark.parametrize("error", [LockedSetError, PhysicsError, RobotModelError,
                                   UnreachableError, MessageError])
def test_every_refusal_is_a_suite_error_and_a_value_error(error: type[Exception]) -> None:
    assert issubclass(error, SuiteError) and issubclass(error, ValueError)
    with pytest.raises(SuiteError, match="why"):
        raise error("why")
