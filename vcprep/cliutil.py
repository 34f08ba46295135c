"""Shared CLI plumbing for vcprep and vctrain: error reporting and JSON output.

Library code raises :class:`~vcprep.errors.VCError`; :func:`run_app` turns it into one
``Error: <file>: <problem> (<fix>)`` line on stderr and exit code 1 (``--debug`` shows the
traceback). stdout carries data only; a reader that stops reading it early (``| head -1``)
ends the command normally, exit code 0, as ``git log | head`` does.
"""
from __future__ import annotations

import errno
import json
import os
import sys
import traceback
from pathlib import Path
from typing import Any

from .errors import InputError, VCError
from .progress import count, err, rate_text  # (re-exported: the commands' chatter is the library's)

__all__ = ["run_app", "emit_json", "err", "count", "rate_text", "ensure_parent", "check_data_folders", "range_option", "res_option",
           "corridor_option"]


def emit_json(obj: Any) -> None:
    """One JSON object on one line of stdout."""
    sys.stdout.write(json.dumps(obj, separators=(", ", ": ")) + "\n")


def ensure_parent(path: Path) -> Path:
    """Create the folder an output file goes into (``mkdir -p``), as the commands that write
    folders (warp, predict, backproject) create theirs; returns ``path``."""
    parent = Path(path).parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise InputError("cannot create the output's folder: a file is in the way", parent,
                         "move that file, or choose another --out") from None
    return Path(path)


def check_data_folders(images: Path | None, labels: Path | None = None,
                       options: tuple[str, str] = ("--images", "--labels")) -> None:
    """--images and --labels (``options``: the two options' names, e.g. --val-images and
    --val-labels) exist, checked in that order: a missing image folder is named first, and both at
    once when both are missing (the library checks what else they hold)."""
    missing = [p for p in (images, labels) if p is not None and not Path(p).exists()]
    if not missing:
        return
    if len(missing) == 2:
        raise InputError("image and label folders not found", f"{images}, {labels}",
                         f"check {options[0]} and {options[1]}")
    kind, opt = ("image", options[0]) if missing[0] == images else ("label", options[1])
    raise InputError(f"{kind} folder not found", missing[0], f"check {opt}")


def run_app(app, prog_name: str) -> None:
    """Run the Typer ``app`` as the console script ``prog_name``, then exit: 0 done (also when
    the reader closed stdout early), 1 a reported error, 2 a usage error, 130 interrupted."""
    closed = False
    try:
        _run(app, prog_name)
        code = 0
    except SystemExit as e:
        code = e.code
        # Typer catches a write to a closed pipe itself and exits 1 without a word
        if _is_epipe(e.__context__):
            closed, code = _epipe_verdict(e.__context__)
    except BrokenPipeError as e:  # raised outside Typer's own handler
        closed, code = _epipe_verdict(e)
    if not closed:
        try:  # what is still buffered: a reader gone by now is the same normal end
            sys.stdout.flush()
        except BrokenPipeError:
            closed = True
    if closed:
        # as the Python docs advise for SIGPIPE: the buffered rest goes to devnull, so that the
        # interpreter's own flush at exit does not fail again (exit code 120, a traceback)
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.__stdout__.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass
    sys.exit(code)


def _is_epipe(e: BaseException | None) -> bool:
    return isinstance(e, OSError) and e.errno == errno.EPIPE


def _epipe_verdict(e: OSError) -> tuple[bool, int]:
    """(stdout closed, exit code) after a broken pipe: the reader of stdout gone is a normal end
    (0); any other pipe (a worker process) is an error, reported like every OSError (1)."""
    if _stdout_reader_gone():
        return True, 0
    where = f"{e.filename}: " if getattr(e, "filename", None) else ""
    err(f"Error: {where}{e.strerror or e} (a pipe other than stdout broke; run again with --debug)")
    return False, 1


def _stdout_reader_gone() -> bool:
    """Whether stdout is a pipe whose reader has closed it (POLLERR on the write end; where
    poll is missing, assume so, as Typer does)."""
    import select

    if not hasattr(select, "poll"):
        return True
    try:
        poller = select.poll()
        poller.register(sys.__stdout__.fileno(), select.POLLOUT)
        return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poller.poll(0))
    except (OSError, ValueError, AttributeError):
        return True


def _run(app, prog_name: str) -> None:
    """Typer's run with the library's errors turned into one ``Error:`` line and exit 1."""
    debug = "--debug" in sys.argv[1:]
    if debug:
        sys.argv.remove("--debug")
    try:
        app(prog_name=prog_name)
    except VCError as e:
        if debug:
            traceback.print_exc()
        err(f"Error: {e}")
        sys.exit(1)
    except BrokenPipeError:
        raise  # run_app decides: the reader of stdout gone, or another pipe
    except OSError as e:
        if debug:
            traceback.print_exc()
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        err(f"Error: {where}{e.strerror or e} (check the path, permissions and free disk space)")
        sys.exit(1)
    except KeyboardInterrupt as e:
        _interrupted(e)
    except SystemExit as e:
        # Typer turns Ctrl-C into a silent exit 130 (SystemExit <- Exit(130) <- KeyboardInterrupt)
        cause = getattr(e.__context__, "__cause__", None)
        if e.code == 130 and isinstance(cause, KeyboardInterrupt):
            _interrupted(cause)
        raise


class Interrupted(KeyboardInterrupt):
    """Ctrl-C at a step whose kept work is not 'finished items' (``kept`` says what is)."""

    def __init__(self, kept: str):
        super().__init__(kept)
        self.kept = kept


def _interrupted(e: BaseException | None = None) -> None:
    kept = getattr(e, "kept", None) or "finished items are saved"
    err(f"Interrupted: {kept}; run the same command again to resume.")
    sys.exit(130)


def parse_size(text: str, what: str = "--size") -> tuple[int, int]:
    """A 'WIDTHxHEIGHT' option -> (w, h) in whole pixels (the one parser of every command)."""
    from .io.images import MAX_PIXELS

    parts = str(text).lower().replace(" ", "").split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise InputError(f"'{text}' is not WIDTHxHEIGHT", what, "write e.g. --size 480x360")
    w, h = int(parts[0]), int(parts[1])
    if w < 2 or h < 2 or w * h > MAX_PIXELS:
        raise InputError(f"'{text}' is out of range", what, f"width and height >= 2, at most {MAX_PIXELS} pixels")
    return w, h


# the options of every command with a bird's-eye view of the road (vcprep bev, vctrain predict --bev and eval --bev):
# one definition each, parsed by vcprep.bev.parse_range (``when``: 'with --bev: ' where the view is optional)
RANGE_HELP = ("the grid's lateral then forward extent in metres, 'X0,X1,Z0,Z1' (x right of the camera, z ahead of "
              "its foot on the road); default the KITTI road benchmark's -10,10,6,46 (write --range=-10,10,6,46)")


def range_option(when: str = ""):
    """``--range X0,X1,Z0,Z1`` (metres; None: the KITTI benchmark's grid)."""
    import typer

    return typer.Option(None, "--range", help=when + RANGE_HELP)


def res_option(when: str = ""):
    """``--res``: the grid's cell size in metres."""
    import typer

    return typer.Option(0.05, "--res", help=when + "cell size in metres")


def corridor_option(when: str = ""):
    """``--corridor``: the width of the vehicle's corridor ``free_m`` is measured along."""
    import typer

    from .bev.metres import CORRIDOR

    return typer.Option(CORRIDOR, "--corridor", help=when + "width in metres of the vehicle's corridor free_m is "
                        "measured along (centred on the camera)")
