"""``vctrain``: the command line of the trainer. Parses, calls the library, prints; nothing else.

One module per command group, each registering its commands on the app of :mod:`.common`
(imported here in the order ``vctrain --help`` lists them): :mod:`.fit`, :mod:`.predict`
(``predict``, ``export``), :mod:`.adapt`, :mod:`.evaluate` (``eval``), :mod:`.crossval`. What they
share (the app, option defaults, help texts) is in :mod:`.common`.
"""
from __future__ import annotations

import atexit
import gc
import time

LOADED = time.perf_counter()  # when the commands' code began to load: the first command's clock starts here
# At exit the interpreter's last garbage collections walk every object still alive, torch's among them: 1.3-1.7 s
# of a command's wall clock on 2 busy cores, after it has said its time. Frozen first, they are skipped (what
# is alive then is never collected anyway: the process ends), and that time is saved (issue 80).
atexit.register(gc.freeze)

from vcprep.cliutil import run_app  # noqa: E402  (after the clock: loading the commands is part of a command's time)

from ..cli import fit, predict, adapt, evaluate, crossval  # noqa: F401,E402  (registers the commands, in this order)
from .common import app, start_clock  # noqa: E402
from .fit import FIT_NO_OPTION, FIT_NOT_CONFIG, FIT_OPTION_FIELD, _fit_config, _parse_crop

__all__ = ["app", "main", "FIT_NO_OPTION", "FIT_NOT_CONFIG", "FIT_OPTION_FIELD", "_fit_config", "_parse_crop"]


def main() -> None:
    start_clock(LOADED)
    run_app(app, "vctrain")


if __name__ == "__main__":
    main()
