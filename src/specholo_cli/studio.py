"""``specholo studio``: a local page to pose a model and design it live."""

from __future__ import annotations

import contextlib
import signal
import webbrowser
from pathlib import Path

import click

from specholo_cli.app import cli


@cli.command()
@click.argument("model", required=False, type=click.Path(path_type=Path))
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="Port on 127.0.0.1 (0: any free port).")
@click.option("--out", "-o", type=click.Path(path_type=Path), default=Path("studio-out"),
              show_default=True, help="Folder the exact designs are written under, one "
              "subfolder a model.")
@click.option("--no-browser", is_flag=True, help="Print the address; do not open a browser.")
def studio(model: Path | None, port: int, out: Path, no_browser: bool) -> None:
    """Design live in a local page: pose MODEL on the plate, see the glints, design it.

    MODEL defaults to the bundled examples/bunny.obj; without it the page asks
    for a model. The page is served on 127.0.0.1 only, at an address holding
    this run's secret, until Ctrl-C (which prints "studio stopped", status 0).
    """
    from specholo.errors import SpecholoError
    from specholo.studio.server import default_model, make_server

    if model is not None and not model.is_file():
        raise SpecholoError(f"model {model} does not exist" if not model.exists()
                            else f"model {model} is not a file")
    server = make_server(model if model is not None else default_model(), out, port)
    previous = None
    with contextlib.suppress(ValueError):  # ValueError: not the main thread (tests)
        # Ctrl-C unwinds through here rather than ending the process at once, so
        # the uploaded files go.
        previous = signal.signal(signal.SIGINT, _interrupt)
    try:
        click.echo(f"specholo studio: {server.url}  (designs go to {out.resolve()}; "
                   "Ctrl-C to stop)")
        if not no_browser:
            try:
                webbrowser.open(server.url)
            except webbrowser.Error:
                click.echo("no browser found: open the address above", err=True)
        try:
            server.serve_forever()
        except KeyboardInterrupt:
            # Ctrl-C is how the studio is meant to stop, not an error: a plain
            # line and status 0. A design still running is left as it was
            # (its folder is published whole or not at all).
            click.echo("studio stopped")
    finally:
        server.server_close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt
