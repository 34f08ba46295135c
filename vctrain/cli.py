"""``vctrain``: the command line of the trainer."""
from __future__ import annotations

import typer

from vcprep.cliutil import run_app

from . import __version__

app = typer.Typer(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False, no_args_is_help=True,
                  help="Train, predict and evaluate road segmentation in the virtual-camera domain.")


@app.command("version")
def version_cmd():
    """Print the version.

    \b
    Example:
      vctrain version
    """
    print(f"vctrain {__version__}")


def main() -> None:
    run_app(app, "vctrain")


if __name__ == "__main__":
    main()
