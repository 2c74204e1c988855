"""Small helpers to look up ROS message classes by name (rosidl_runtime_py has no pip wheel)."""
from __future__ import annotations

import importlib


def message_class(typename: str) -> type:
    """"sensor_msgs/msg/Image" -> the generated Python class."""
    try:
        package, kind, name = typename.split("/")
        return getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ValueError, ImportError, AttributeError) as exc:
        raise LookupError(f"unknown ROS type {typename!r}: {exc}") from exc
