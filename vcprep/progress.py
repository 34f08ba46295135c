"""What a long step tells a person, shared by the library and the commands: chatter on stderr
(:func:`err`) and the wording of counts and rates in summary lines. stdout stays data (the
commands' own)."""
from __future__ import annotations

import sys

__all__ = ["err", "count", "rate_text"]


def err(msg: str) -> None:
    """Chatter for humans: stderr."""
    print(msg, file=sys.stderr, flush=True)


def count(n: int, noun: str) -> str:
    """A count for a summary line: '1 image', '3 images' (the noun given in the singular)."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def rate_text(n: int, seconds: float, noun: str) -> str:
    """How long a run took and how fast, for its summary line: '12.3 s, 4.1 images/s'."""
    rate = n / seconds if seconds > 0 else 0.0
    return f"{seconds:.1f} s, {rate:.1f} {noun}s/s"
