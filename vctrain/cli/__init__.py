"""``vctrain``: the command line of the trainer. Parses, calls the library, prints; nothing else.

One module per command group, each registering its commands on the app of :mod:`.common`
(imported here in the order ``vctrain --help`` lists them): :mod:`.fit`, :mod:`.predict`
(``predict``, ``export``), :mod:`.adapt`, :mod:`.evaluate` (``eval``), :mod:`.crossval`. What they
share (the app, option defaults, help texts) is in :mod:`.common`.
"""
from __future__ import annotations

from vcprep.cliutil import run_app

from ..cli import fit, predict, adapt, evaluate, crossval  # noqa: F401  (registers the commands, in this order)
from .common import app
from .fit import FIT_NO_OPTION, FIT_NOT_CONFIG, FIT_OPTION_FIELD, _fit_config, _parse_crop

__all__ = ["app", "main", "FIT_NO_OPTION", "FIT_NOT_CONFIG", "FIT_OPTION_FIELD", "_fit_config", "_parse_crop"]


def main() -> None:
    run_app(app, "vctrain")


if __name__ == "__main__":
    main()
