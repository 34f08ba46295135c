"""``vcprep``: the command line. Parses, calls the library, prints; the work is in the library.

One module per command group, each registering its commands on the apps of :mod:`.common`
(imported here in the order ``vcprep --help`` lists them): :mod:`.cameras` (``cameras``,
``camera ...``), :mod:`.store` (``warp``, ``complete``, ``store ...``, ``backproject``,
``prior``), :mod:`.bev`, :mod:`.vp`, :mod:`.simulate`, :mod:`.figures` (``figure ...``). What several
commands share (help texts, ``--camera`` loading, image arguments, the end of a build) is in
:mod:`.common`.
"""
from __future__ import annotations

from ..cliutil import run_app
from ..cli import cameras, store, bev, vp, simulate, figures  # noqa: F401  (registers the commands, in this order)
from .common import app, camera_for, image_files, save_figure

__all__ = ["app", "main", "camera_for", "image_files", "save_figure"]


def main() -> None:
    run_app(app, "vcprep")


if __name__ == "__main__":
    main()
