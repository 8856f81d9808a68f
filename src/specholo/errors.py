"""Exceptions raised by specholo for bad input.

Every error a user can cause is a :class:`SpecholoError` (a ``ValueError``) whose
message is one line naming the bad value, so the CLI can print it as is.
"""


import math


class SpecholoError(ValueError):
    """Bad input or an impossible configuration; the message is one line."""


def positive(name: str, value: float) -> float:
    """``value`` as a float, or a :class:`SpecholoError` naming it unless finite and > 0."""
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise SpecholoError(f"{name} must be a positive number, got {value}")
    return value
