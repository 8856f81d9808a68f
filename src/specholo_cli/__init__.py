"""The ``specholo`` command line: a thin layer over the :mod:`specholo` library."""

from __future__ import annotations

import os
import signal
import sys
from typing import Any

#: What Ctrl-C prints. Every file is written whole or not at all, and an output
#: folder is replaced whole once all of it is done (``specholo.folders.publish``).
INTERRUPTED = "error: interrupted; no file was left half-written"
#: Whether this process is the ``specholo`` command itself (set by ``cli.main``),
#: not a caller in Python: a Ctrl-C may then end it at once, and a first run may
#: start a second process to compile kernels beside it.
END_AT_ONCE = [False]


def exit_interrupted() -> None:
    """End the process at once after a Ctrl-C: one line, status 130.

    Only where no scratch file exists (nothing to clean up). On a terminal the
    cursor is shown again and the status line cleared, as a progress display
    would on its way out.
    """
    err = sys.__stderr__
    if err is not None:
        try:
            if err.isatty():
                err.write("\r\x1b[2K\x1b[?25h")
            err.write(INTERRUPTED + "\n")
            err.flush()
        except (OSError, ValueError):
            pass
    os._exit(130)


def early_sigint(signum: int, frame: Any) -> None:
    """Ctrl-C while the ``specholo`` command is still loading its modules."""
    exit_interrupted()


# Run as the ``specholo`` command, a Ctrl-C while the libraries load ends it
# with the same one line; ``cli.main`` takes over once it runs.
if (os.path.basename(sys.argv[0] if sys.argv else "") == "specholo"
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
    signal.signal(signal.SIGINT, early_sigint)
