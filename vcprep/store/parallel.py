"""Running one per-item function over many items: in this process or in a process pool.

:func:`run_items` is the one loop every store command shares (``warp``, ``complete``, ``store
verify``): the per-item function is the same in both modes, so ``--jobs N`` gives results
byte-identical to ``--jobs 1``. Workers compute and write; the parent receives each result (in
completion order) and owns everything shared, such as the manifest.

Stopping: the callback returns False to stop (e.g. at the first bad item). Ctrl-C (SIGINT) is
deferred to the end of the items in flight (a second Ctrl-C interrupts at once); workers ignore
SIGINT from birth (the forkserver is started with it ignored; should a worker still die of one, the
broken pool is read as the Ctrl-C, not as a crashed worker). Either way no new item starts, the items running finish and reach the callback, and then
the loop returns (or raises ``KeyboardInterrupt``): nothing finished is lost.
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import multiprocessing.forkserver as forkserver
import os
import signal
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator

from tqdm import tqdm

from ..errors import StoreError, VCError

__all__ = ["run_items", "ItemError", "default_jobs", "progress_bar"]

_WORKER: tuple[Callable, Any] | None = None


@dataclass(frozen=True)
class ItemError:
    """The result of an item whose function raised a :class:`VCError` (a bad input)."""

    error: VCError


def default_jobs() -> int:
    """The number of cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def progress_bar(total: int, desc: str, enabled: bool) -> tqdm:
    """A tqdm bar on stderr (items/s, ETA). It appears after 1 s, so quick runs print nothing but
    their summary; when stderr is not a terminal (a log file) it is refreshed every 10 s."""
    tty = sys.stderr.isatty()
    return tqdm(total=total, desc=desc, unit="img", disable=not enabled, leave=False, file=sys.stderr,
                delay=1.0, mininterval=0.2 if tty else 10.0, dynamic_ncols=tty)


def _safe(fn: Callable, ctx: Any, task: Any) -> Any:
    try:
        return fn(ctx, task)
    except VCError as e:
        return ItemError(e)


def _init_worker(fn: Callable, ctx: Any) -> None:
    global _WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    import cv2

    cv2.setNumThreads(1)  # one core per worker: the pool is the parallelism
    _WORKER = (fn, ctx)


def _work(task: Any) -> Any:
    fn, ctx = _WORKER
    return _safe(fn, ctx, task)


@contextmanager
def _deferred_sigint() -> Iterator[list]:
    """Record SIGINT instead of raising (only the main thread can install handlers)."""
    hits: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield hits
        return

    def handler(signum, frame):
        hits.append(signum)
        if len(hits) > 1:
            raise KeyboardInterrupt

    old = signal.signal(signal.SIGINT, handler)
    try:
        yield hits
    finally:
        signal.signal(signal.SIGINT, old)


def run_items(fn: Callable[[Any, Any], Any], ctx: Any, tasks: Iterable[Any],
              on_result: Callable[[Any, Any], bool | None], jobs: int = 1, progress: bool = False,
              desc: str = "", total: int | None = None) -> None:
    """Call ``fn(ctx, task)`` for every task and ``on_result(task, result)`` in this process as
    each finishes; a :class:`VCError` raised by ``fn`` arrives as :class:`ItemError`.

    ``fn`` must be a module-level function and ``ctx``/tasks/results picklable (``jobs > 1``).
    ``on_result`` returns False to stop. Raises KeyboardInterrupt after a Ctrl-C stop."""
    tasks = list(tasks)
    bar = progress_bar(len(tasks) if total is None else total, desc, progress)
    try:
        with _deferred_sigint() as interrupted:
            if jobs <= 1 or len(tasks) <= 1:
                for task in tasks:
                    result = _safe(fn, ctx, task)
                    bar.update()
                    if on_result(task, result) is False:
                        break
                    if interrupted:
                        raise KeyboardInterrupt
            else:
                _run_pool(fn, ctx, tasks, on_result, jobs, bar, interrupted)
    finally:
        bar.close()


def _context():
    """A forkserver whose server has imported the heavy modules once: workers start fast and
    never inherit a parent's OpenCV thread pool (forking after OpenCV ran threads can deadlock)."""
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["numpy", "cv2", "vcprep.store.build", "vcprep.warp.completion"])
    # Workers get the SIGINT disposition the server was started with. Started with SIGINT ignored (a
    # disposition exec keeps), every worker ignores Ctrl-C from birth: none can die of one before its
    # initializer runs, which would break the pool and kill the other workers mid-write (orphans).
    if threading.current_thread() is threading.main_thread():
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, old)
    return ctx


def _run_pool(fn, ctx, tasks, on_result, jobs, bar, interrupted) -> None:
    pending = iter(tasks)
    running: dict[cf.Future, Any] = {}
    window = 2 * jobs  # a few queued per worker: busy workers, and little in flight at a stop
    stop = False
    try:
        # forkserver, not fork: forking a parent whose OpenCV thread pool has run (e.g. VP
        # detection before the warp) can deadlock the children
        with cf.ProcessPoolExecutor(jobs, mp_context=_context(), initializer=_init_worker,
                                    initargs=(fn, ctx)) as pool:
            try:
                while True:
                    while not stop and len(running) < window:
                        task = next(pending, _END)
                        if task is _END:
                            break
                        running[pool.submit(_work, task)] = task
                    if not running:
                        break
                    done, _ = cf.wait(running, return_when=cf.FIRST_COMPLETED)
                    for fut in done:
                        task = running.pop(fut)
                        bar.update()
                        if on_result(task, fut.result()) is False:
                            stop = True
                    if interrupted:
                        raise KeyboardInterrupt
            except BaseException:
                # no new items; those already running finish and are handed over
                for fut in running:
                    fut.cancel()
                for fut, task in running.items():
                    if fut.cancelled():
                        continue
                    try:
                        result = fut.result()
                    except BaseException:
                        continue
                    on_result(task, result)
                raise
    except cf.process.BrokenProcessPool:
        if interrupted:  # Ctrl-C reached the whole process group, and a worker still starting (before it
            raise KeyboardInterrupt from None  # ignores SIGINT) died of it: the stop is the user's, not a crash
        raise StoreError("a worker process died (out of memory or killed)", None,
                         "re-run the same command, with fewer --jobs if memory is short; finished items are kept") from None


_END = object()
