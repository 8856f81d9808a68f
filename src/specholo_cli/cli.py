"""The ``specholo`` command: its entry point, Ctrl-C handling and one-line errors.

The commands live one family to a module (:mod:`.design`, :mod:`.verification`,
:mod:`.pictures`, :mod:`.jobs`, :mod:`.studio`, :mod:`.probing`), over what they
share (:mod:`.app`). They parse options and print; the work happens in the
library."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from pathlib import Path
from typing import Any, NoReturn

import click

from specholo.errors import SpecholoError
from specholo_cli import END_AT_ONCE, INTERRUPTED, early_sigint, exit_interrupted
from specholo_cli import design as _design  # noqa: F401  (registers the command)
from specholo_cli import jobs as _jobs  # noqa: F401
from specholo_cli import pictures as _pictures  # noqa: F401
from specholo_cli import probing as _probing  # noqa: F401
from specholo_cli import studio as _studio  # noqa: F401
from specholo_cli import verification as _verification  # noqa: F401
from specholo_cli.app import _DESIGN_OPTIONS as _DESIGN_OPTIONS
from specholo_cli.app import _read_config as _read_config
from specholo_cli.app import cli

#: SIGINTs received by the running command (see :func:`main`).
_SIGINTS: list[int] = []


def _on_sigint(signum: int, frame: Any) -> None:
    """Ctrl-C: end at once where nothing needs cleaning up (a library that was
    importing an optional module cannot swallow it then), else unwind, so the
    scratch files go."""
    from specholo.fabrication.atomic import scratch_open

    _SIGINTS.append(signum)
    if END_AT_ONCE[0] and not scratch_open():
        exit_interrupted()
    raise KeyboardInterrupt


def _interrupted(exc: BaseException) -> bool:
    """Whether an error stands for a Ctrl-C: compiled (numba) code that was
    running when it came returns with the KeyboardInterrupt set, and Python
    reports a SystemError caused by it; a library that was importing an
    optional module keeps the KeyboardInterrupt as that module's import error
    and fails later in some other way. Any error after a SIGINT counts."""
    if _SIGINTS:
        return True
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; every failure is one line on stderr and a non-zero exit.

    Run as the ``specholo`` command (no ``argv``), the process ends as soon as
    the command is done (:func:`_end`).
    """
    args = [str(a) for a in (sys.argv[1:] if argv is None else argv)]
    command = argv is None  # the command itself, not a caller in Python
    _SIGINTS.clear()
    END_AT_ONCE[0] = command
    previous = None
    with contextlib.suppress(ValueError):  # ValueError: not the main thread
        if signal.getsignal(signal.SIGINT) in (signal.default_int_handler, early_sigint):
            previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        code = _main(args)
    except SystemExit as exc:  # a command that ends with sys.exit (check)
        if not command:
            raise
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    finally:
        if previous is not None and not command:
            signal.signal(signal.SIGINT, previous)
    if command:
        _end(code, previous is not None)
    return code


#: The exit status of the command that has just ended (see :func:`_end`).
_RESULT = [0]


def _end(code: int, handle_sigint: bool) -> NoReturn:
    """End the ``specholo`` command now that its work is done, with status ``code``.

    Python's own exit spends a few tenths of a second more tearing down the
    modules, with Ctrl-C already handed back to the system: a Ctrl-C then
    ended the process without a word. Here every file is closed, written
    whole or removed, and nothing registered to run at exit is needed.
    """
    _RESULT[0] = code
    if handle_sigint:
        with contextlib.suppress(ValueError):
            signal.signal(signal.SIGINT, _sigint_after_run)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe
            stream.flush()
    os._exit(code)


def _sigint_after_run(signum: int, frame: Any) -> None:
    """Ctrl-C while the command exits: its outputs are complete (a run that
    failed has said so in its own one line, and keeps its status)."""
    code = _RESULT[0]
    err = sys.__stderr__
    if code == 0 and err is not None:
        with contextlib.suppress(OSError, ValueError):
            err.write(FINISHED_INTERRUPTED + "\n")
            err.flush()
    os._exit(130 if code == 0 else code)


#: What a Ctrl-C prints once the command has done its work.
FINISHED_INTERRUPTED = ("error: interrupted as it exited; the run had finished and its "
                        "outputs are complete")


def _os_error(exc: OSError) -> str:
    """An operating-system error as one line naming the file, if it names one."""
    what = exc.strerror or " ".join(str(exc).split()) or type(exc).__name__
    # os.replace(scratch, destination) names the destination second.
    name = exc.filename2 if exc.filename2 is not None else exc.filename
    if name is None:
        return what[:1].lower() + what[1:]
    path = Path(os.fsdecode(name))
    if path.name.startswith(".") and ".part" in path.name:
        # a scratch file beside the real one: the folder is what the user knows
        return f"cannot write in {path.parent}: {what}"
    return f"{path}: {what}"


def _main(args: list[str]) -> int:
    try:
        # click's own main() would print an empty line on Ctrl-C: a second line.
        with cli.make_context("specholo", list(args), obj={"argv": ["specholo", *args]}) as ctx:
            cli.invoke(ctx)
    except click.exceptions.Exit as exc:
        return int(exc.exit_code)
    except click.Abort:
        click.echo("error: aborted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return exc.exit_code
    except SpecholoError as exc:
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        click.echo(f"error: {str(exc).splitlines()[0] if str(exc) else 'bad input'}", err=True)
        return 1
    except KeyboardInterrupt:
        click.echo(INTERRUPTED, err=True)
        return 130
    except MemoryError as exc:
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        click.echo("error: out of memory; try fewer stipples", err=True)
        return 1
    except OSError as exc:
        # The system refused a read or a write (a full disk, a folder gone or
        # read-only, a link loop): the user's to fix, not a fault of the program.
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        click.echo(f"error: {_os_error(exc)}", err=True)
        return 1
    except Exception as exc:  # noqa: BLE001 - the promise is one line, never a traceback
        if _interrupted(exc):
            click.echo(INTERRUPTED, err=True)
            return 130
        if os.environ.get("SPECHOLO_DEBUG"):
            raise
        if isinstance(exc, ValueError) and "null byte" in str(exc):
            # click.Path stats its argument, and a NUL byte makes os.stat raise
            click.echo("error: a path holds a NUL byte", err=True)
            return 2
        click.echo(f"error: internal error ({type(exc).__name__}: {exc}); "
                   "set SPECHOLO_DEBUG=1 for details", err=True)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
