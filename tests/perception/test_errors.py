"""Error type: code, message naming the subtask."""
from __future__ import annotations

from lomanip_perception.errors import MODEL_UNAVAILABLE, ModelUnavailableError, PerceptionError, subtask_label


def test_error_carries_code_message_and_subtask():
    e = PerceptionError("UNKNOWN_OBJECT", "subtask 1 'x': no", 1)
    assert (e.code, e.message, e.subtask_index, str(e)) == ("UNKNOWN_OBJECT", "subtask 1 'x': no", 1, "subtask 1 'x': no")
    assert ModelUnavailableError("absent").code == MODEL_UNAVAILABLE
    assert subtask_label(2, "push the trolley") == "subtask 2 'push the trolley'"
