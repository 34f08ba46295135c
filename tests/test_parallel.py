"""vcprep.store.parallel: the process pool the store commands share (Ctrl-C handling at its source)."""
from __future__ import annotations

import concurrent.futures as cf
import signal

from vcprep.store.parallel import _context


def test_pool_workers_ignore_ctrl_c_from_birth():
    """A worker must not die of a Ctrl-C that reaches the process group while it is still starting
    (before its initializer ignores SIGINT): that breaks the pool, which kills the other workers
    mid-write and leaves orphan files. Without an initializer, a worker shows the disposition it was
    born with. The parent starts with Python's own Ctrl-C handler, as in a terminal: a test worker
    inherits SIGINT ignored when the suite runs in the background (`make test &`, some CI), and
    whether an earlier test in the worker had set a handler decided this test (issue 61)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with cf.ProcessPoolExecutor(1, mp_context=_context()) as pool:
            assert pool.submit(signal.getsignal, signal.SIGINT).result() == signal.SIG_IGN
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the parent's Ctrl-C is untouched
    finally:
        signal.signal(signal.SIGINT, before)
