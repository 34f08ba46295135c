"""What the ``vctrain`` commands share: the Typer app (with ``--version`` and ``version``), the
defaults of fit's and adapt's options as the library declares them, help texts and the end of a
command that writes one file. Commands live in one module per group (:mod:`vctrain.cli`)."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Optional

import typer

from vcprep.cliutil import emit_json
from vcprep.labels import LABEL_FORMAT_HELP

from vctrain import __version__
from ..shipped import MODELS, SHIPPED, resolve_model, shipped_models  # noqa: F401 (the commands' names)
from ..training.config import AdaptSettings, TrainConfig

app = typer.Typer(rich_markup_mode=None, pretty_exceptions_enable=False, add_completion=False, no_args_is_help=True,
                  help="Train, predict and evaluate road segmentation in the virtual-camera domain.\n\n"
                       "Add --debug to any command to see a traceback on error.")


_STARTED: list[float] = []  # the perf_counter() at which each command of this process started


def start_clock(loaded: float) -> None:
    """Start the clock of the command about to run (:func:`command_seconds`): at ``loaded``, when the
    commands' code began to load, for the first command of a process (what a user's ``vctrain ...``
    is: its imports are part of its time); now for any later one (tests run several in one process)."""
    _STARTED.append(time.perf_counter() if _STARTED else loaded)


def command_seconds() -> float:
    """The wall clock of the running command so far, from :func:`start_clock` (the interpreter's own
    start before it, about 0.1 s, is not counted); from the first call when no clock was started."""
    if not _STARTED:
        _STARTED.append(time.perf_counter())
    return time.perf_counter() - _STARTED[-1]


def _version(value: bool):
    if value:
        print(f"vctrain {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version.")):
    pass


@app.command("version")
def version_cmd():
    """Print the version.

    \b
    Example:
      vctrain version
    """
    print(f"vctrain {__version__}")


def parse_size(text: Optional[str]) -> Optional[tuple[int, int]]:
    from vcprep.cliutil import parse_size as parse

    return None if text is None else parse(text)


THREADS_HELP = ("threads of torch, OpenCV and onnxruntime (default: OMP_NUM_THREADS if set, else the cores no "
                "other process is running on when the command starts, at least 1: more threads than free cores "
                "make torch several times slower)")


def threads_option():
    """``--threads N`` of predict, export and fit (:func:`pin_threads`)."""
    return typer.Option(None, "--threads", min=1, help=THREADS_HELP)


def pin_threads(threads: Optional[int]) -> int:
    """``--threads``: torch, OpenCV and onnxruntime at ``threads`` (None: the default), as
    :func:`vctrain.threads.use_threads` (imported here: it imports torch)."""
    from ..threads import use_threads

    return use_threads(threads)


TRAIN = TrainConfig()     # the defaults of fit's options, as TrainConfig declares them
ADAPT = AdaptSettings()  # ... and of adapt's


def model_arg(arg: Optional[Path]) -> Optional[Path]:
    """A MODEL argument (:func:`vctrain.shipped.resolve_model`: a file, or a shipped model's name)."""
    return resolve_model(arg)


def path_or_json(out: Path, doc: Any, as_json: bool) -> None:
    """stdout of a command that writes one file: ``doc`` as one JSON object with --json, else the path."""
    if as_json:
        emit_json(doc)
    else:
        print(out)
