"""The small shared types of amex.core.types."""

import numpy as np

from amex.core.types import Command


def test_command_task_and_joint_are_the_keyword_forms():
    a, b = np.arange(6.0), np.arange(6.0) + 1
    for fast, keyword in (
        (Command.task(a, b), Command(y=a, yd=b)),
        (Command.joint(a, b), Command(q=a, qd=b)),
    ):
        assert type(fast) is Command and len(fast) == 4
        assert all(x is y for x, y in zip(fast, keyword, strict=True))
    assert Command.task(a, b).q is None and Command.joint(a, b).y is None
