"""Perception errors with the lomanip error-code names (no ROS import here).

Why: the core raises one exception type carrying a code that conversions.py maps onto
lomanip_msgs/ErrorCode, and a one-line message that names the subtask it concerns, so a user can act
on it ("subtask 0 'push the refrigerator': no object of class 'refrigerator' in the scene ...").
"""
from __future__ import annotations

#: Names of lomanip_msgs/ErrorCode constants this package uses.
INVALID_REQUEST = "INVALID_REQUEST"
UNKNOWN_OBJECT = "UNKNOWN_OBJECT"
NO_HUMAN_FOUND = "NO_HUMAN_FOUND"
CONTACT_TRANSFER_FAILED = "CONTACT_TRANSFER_FAILED"
MODEL_UNAVAILABLE = "MODEL_UNAVAILABLE"
NOT_READY = "NOT_READY"
TIMEOUT = "TIMEOUT"
FAILURE = "FAILURE"


class PerceptionError(RuntimeError):
    """A perception request that cannot be answered; ``code`` is an ErrorCode constant name."""

    def __init__(self, code: str, message: str, subtask_index: int | None = None):
        super().__init__(message)
        self.code = code
        self.message = message
        self.subtask_index = subtask_index

    def __repr__(self) -> str:
        return f"PerceptionError({self.code}, {self.message!r})"


class ModelUnavailableError(PerceptionError):
    """A configured model backend cannot be loaded (weights absent, adapter not built)."""

    def __init__(self, message: str):
        super().__init__(MODEL_UNAVAILABLE, message)


def subtask_label(index: int, prompt: str) -> str:
    """How every message names a subtask."""
    return f"subtask {index} {prompt!r}"
