"""Exceptions raised by specholo for bad input.

Every error a user can cause is a :class:`SpecholoError` (a ``ValueError``) whose
message is one line naming the bad value, so the CLI can print it as is.
"""


class SpecholoError(ValueError):
    """Bad input or an impossible configuration; the message is one line."""
