"""The project's one exception family.

Library code raises :class:`VCError` (or a subclass); the CLI turns it into a single
``Error: <file>: <problem> (<what to do>)`` line on stderr and a non-zero exit code.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable

__all__ = ["VCError", "InputError", "GeometryError", "StoreError", "one_of"]


class VCError(Exception):
    """A user-facing error: which file, what is wrong, and what to do about it."""

    def __init__(self, problem: str, file: str | Path | None = None, fix: str | None = None):
        self.problem = problem
        self.file = str(file) if file is not None else None
        self.fix = fix
        super().__init__(str(self))

    def __str__(self) -> str:
        text = f"{self.file}: {self.problem}" if self.file else self.problem
        if self.fix:
            text += f" ({self.fix})"
        return text


class InputError(VCError):
    """A bad input file or argument (image, label, camera file, CSV...)."""


class GeometryError(VCError):
    """A camera/pose for which the requested mapping is not defined (e.g. a folded homography)."""


class StoreError(VCError):
    """A virtual-camera image store that is missing, inconsistent or built with other parameters."""


def one_of(name: str, choices: Iterable[str], also: str = "", what: str = "use one of") -> str:
    """The fix for ``name`` rejected from the table ``choices``: "did you mean 'camvid'? use one of
    camvid, kitti, ..." (the closest names by :func:`difflib.get_close_matches`, where any is close),
    ``also`` appended (e.g. "or a camera YAML file"). The one wording of every name refused from a table."""
    import difflib

    choices = [str(c) for c in choices]
    close = difflib.get_close_matches(str(name), choices, n=2, cutoff=0.6)
    mean = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
    return f"{mean}{what} {', '.join(choices)}" + (f" {also}" if also else "")
