"""Decode, infer and write overlapped: what lets ``vctrain predict`` keep up with a camera.

A frame's three stages run on three threads: :class:`Prefetch` decodes the next frames (a video's,
or image files) on one, the caller's thread runs the network on the frame at hand, and
:class:`Writer` encodes and writes the frames before it (PNG masks, the overlay and mask videos)
on another. OpenCV's decoders and encoders, zlib and onnxruntime/PyTorch release the GIL, so on
two cores the network gets the time the other two stages leave (benchmarks/speed/predict_e2e.py).

The rules the sequential road had still hold:

* order and completeness: one decoding thread and one writing thread, each a FIFO, so frames are
  written in the order they were read, every one of them (:class:`Writer` never drops a write;
  the queues are bounded, ``depth`` frames, so memory stays flat on a long video);
* errors: an error while decoding is raised in the caller's thread at the frame where it occurred
  (after the frames before it); an error while writing is raised by the next :meth:`Writer.submit`
  or by :meth:`Writer.close`, so a run never ends as if it had succeeded;
* Ctrl-C (or any error): :meth:`Writer.abort` drops the writes not started, waits for the one
  running (each PNG is written atomically, a video under a temporary name), and
  :meth:`Prefetch.close` stops the decoding thread; nothing half-written is left.

Whoever adds a stage (e.g. a bird's-eye view of each mask) adds it to the write a frame submits,
not to the caller's thread: the network's thread does nothing but the network.
"""
from __future__ import annotations

import queue
import threading
from typing import Any, Callable, Generic, Iterable, Iterator, TypeVar

__all__ = ["DEPTH", "Prefetch", "Writer"]

DEPTH = 4  # frames decoded ahead of the network, and frames waiting to be written

T = TypeVar("T")
_END = object()


class _Raised:
    """An exception carried through a queue to the thread that reads it."""

    def __init__(self, error: BaseException):
        self.error = error


class Prefetch(Generic[T]):
    """The items of ``source`` produced on a thread of their own, ``depth`` ahead, and yielded in
    order; an exception of ``source`` is raised where it occurred. Use as a context manager (or
    call :meth:`close`): leaving early stops the thread."""

    def __init__(self, source: Iterable[T], depth: int = DEPTH, name: str = "decode"):
        self._queue: queue.Queue = queue.Queue(maxsize=max(1, depth))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._produce, args=(iter(source),), name=name, daemon=True)
        self._thread.start()

    def _put(self, item: Any) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _produce(self, it: Iterator[T]) -> None:
        try:
            for item in it:
                if not self._put(item):
                    return
        except BaseException as e:  # noqa: BLE001 - carried to the caller's thread
            self._put(_Raised(e))
            return
        self._put(_END)

    def __iter__(self) -> Iterator[T]:
        while True:
            item = self._queue.get()
            if item is _END:
                return
            if isinstance(item, _Raised):
                raise item.error
            yield item

    def close(self) -> None:
        """Stop producing and wait for the thread (it finishes the item it is decoding)."""
        self._stop.set()
        while self._thread.is_alive():
            try:
                while True:
                    self._queue.get_nowait()
            except queue.Empty:
                pass
            self._thread.join(timeout=0.05)

    def __enter__(self) -> "Prefetch[T]":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Writer:
    """Calls submitted with :meth:`submit` run in order on one thread (at most ``depth`` waiting: a
    submit waits for room). The first error a call raises is raised again by the next
    :meth:`submit` or by :meth:`close`; the calls after it are not run."""

    def __init__(self, depth: int = DEPTH, name: str = "write"):
        self._queue: queue.Queue = queue.Queue(maxsize=max(1, depth))
        self._error: BaseException | None = None
        self._abort = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            call = self._queue.get()
            if call is _END:
                return
            if self._error is not None or self._abort.is_set():
                continue  # after an error or an abort: drain, run nothing more
            fn, args = call
            try:
                fn(*args)
            except BaseException as e:  # noqa: BLE001 - raised again in the caller's thread
                self._error = e

    def _raise(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            self._abort.set()
            raise error

    def submit(self, fn: Callable[..., Any], *args: Any) -> None:
        """Run ``fn(*args)`` after the calls submitted before it."""
        self._raise()
        while True:
            try:
                self._queue.put((fn, args), timeout=0.1)
                return
            except queue.Full:
                self._raise()
                if not self._thread.is_alive():
                    raise RuntimeError("the writing thread has ended")

    def close(self) -> None:
        """Wait for every call submitted; raise the first error of one."""
        self._queue.put(_END)
        self._thread.join()
        self._raise()

    def abort(self) -> None:
        """Drop the calls not started, wait for the one running; errors are dropped too (the caller
        is already raising one)."""
        self._abort.set()
        try:
            while True:
                self._queue.get_nowait()
        except queue.Empty:
            pass
        self._queue.put(_END)
        self._thread.join()
        self._error = None
