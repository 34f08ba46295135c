"""Shared CLI plumbing for vcprep and vctrain: error reporting and JSON output.

Library code raises :class:`~vcprep.errors.VCError`; :func:`run_app` turns it into one
``Error: <file>: <problem> (<fix>)`` line on stderr and exit code 1 (``--debug`` shows the
traceback). stdout carries data only.
"""
from __future__ import annotations

import json
import sys
import traceback
from typing import Any

from .errors import InputError, VCError

__all__ = ["run_app", "emit_json", "err"]


def err(msg: str) -> None:
    """Chatter for humans: stderr."""
    print(msg, file=sys.stderr, flush=True)


def emit_json(obj: Any) -> None:
    """One JSON object on one line of stdout."""
    sys.stdout.write(json.dumps(obj, separators=(", ", ": ")) + "\n")


def run_app(app, prog_name: str) -> None:
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
    except OSError as e:
        if debug:
            traceback.print_exc()
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        err(f"Error: {where}{e.strerror or e} (check the path, permissions and free disk space)")
        sys.exit(1)
    except KeyboardInterrupt:
        _interrupted()
    except SystemExit as e:
        # Typer turns Ctrl-C into a silent exit 130 (SystemExit <- Exit(130) <- KeyboardInterrupt)
        if e.code == 130 and isinstance(getattr(e.__context__, "__cause__", None), KeyboardInterrupt):
            _interrupted()
        raise


def _interrupted() -> None:
    err("Interrupted: finished items are saved; run the same command again to resume.")
    sys.exit(130)


def parse_size(text: str, what: str = "--size") -> tuple[int, int]:
    """A 'WIDTHxHEIGHT' option -> (w, h) in whole pixels (the one parser of every command)."""
    from .imageio import MAX_PIXELS

    parts = str(text).lower().replace(" ", "").split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise InputError(f"'{text}' is not WIDTHxHEIGHT", what, "write e.g. --size 480x360")
    w, h = int(parts[0]), int(parts[1])
    if w < 2 or h < 2 or w * h > MAX_PIXELS:
        raise InputError(f"'{text}' is out of range", what, f"width and height >= 2, at most {MAX_PIXELS} pixels")
    return w, h
