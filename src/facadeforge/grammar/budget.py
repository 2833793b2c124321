"""The time and memory one derivation may spend.

Every unit of work a rule file can make the interpreter do draws on one :class:`Budget`: a rule
application, a call of a function written in CGA, the pieces a split or repeat is about to make,
the strings an expression builds, the files a rule reads.  Checking only between rule
applications (as before) let a function that calls itself twice run for months and a string
that doubles itself fill the memory, without the derivation ever reaching its next rule.

The clock is read at every check (``time.perf_counter``, tens of nanoseconds); the process's
resident memory at most every :data:`MEMORY_STRIDE` seconds (``/proc/self/statm`` on Linux,
the peak from ``getrusage`` elsewhere), so the checks cost a few per cent of a derivation at
most.  Growth is measured from where the derivation started, so a long-lived process (the
editor's server, the test suite) is not charged for what it held before.
"""

from __future__ import annotations

import os
import sys
import time

from ..errors import DerivationError

#: Seconds between two readings of the process's memory.
MEMORY_STRIDE = 0.05
#: Longest string an expression may build (characters).  Rule strings are names, paths and
#: lists of a few hundred characters; a string that doubles itself passes this in 24 steps.
MAX_STRING = 16 * 1024 * 1024

_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def resident_bytes() -> int:
    """The process's resident memory in bytes (its peak where the current one is unknown)."""
    try:
        with open("/proc/self/statm", "rb") as fh:
            return int(fh.read().split()[1]) * _PAGE
    except (OSError, ValueError, IndexError):
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return peak if sys.platform == "darwin" else peak * 1024  # bytes on macOS, KiB on Linux


class Budget:
    """What one derivation may still spend: a deadline and a memory growth cap.

    Parameters
    ----------
    seconds : float
        Wall-clock seconds from :meth:`start`.
    memory_mb : float
        Growth of the process's resident memory from :meth:`start`, in MiB.
    """

    __slots__ = ("seconds", "memory_mb", "_deadline", "_next_memory", "_base", "_limit_bytes")

    def __init__(self, seconds: float, memory_mb: float):
        self.seconds = float(seconds)
        self.memory_mb = float(memory_mb)
        self._deadline = float("inf")
        self._next_memory = 0.0
        self._base = 0
        self._limit_bytes = int(self.memory_mb * 1024 * 1024)

    def start(self) -> None:
        """Start the clock and take the memory the process holds now as the base."""
        now = time.perf_counter()
        self._deadline = now + self.seconds
        self._next_memory = now + MEMORY_STRIDE
        self._base = resident_bytes()

    def check(self, kind: str, name: str, path: str = "", line: int = 0) -> None:
        """Raise :class:`DerivationError` when the time or the memory is spent, naming what
        was running (``kind`` ``rule``/``function``/an operation, its ``name`` and where it is
        written)."""
        now = time.perf_counter()
        if now < self._next_memory:
            return
        self._next_memory = now + MEMORY_STRIDE
        if now > self._deadline:
            raise DerivationError(f"derivation took longer than {self.seconds:g} s (while in "
                                  f"{_where(kind, name, path, line)}); raise the limit with "
                                  "--max-seconds if the rules really need it")
        grown = resident_bytes() - self._base
        if grown > self._limit_bytes:
            raise DerivationError(f"derivation needs more than {self.memory_mb:g} MiB of memory "
                                  f"(while in {_where(kind, name, path, line)}); raise the "
                                  "limit with --max-memory if the rules really need it")



def _where(kind: str, name: str, path: str, line: int) -> str:
    return f"{kind} '{name}'" + (f", {path}:{line}" if line else "")


def check_string_length(n: int) -> None:
    """Refuse to build a string of ``n`` characters when ``n`` > :data:`MAX_STRING`."""
    if n > MAX_STRING:
        raise DerivationError(f"a string of {n:,} characters is longer than the {MAX_STRING:,} a "
                              "rule may build; a string that grows without end?")


__all__ = ["MAX_STRING", "Budget", "check_string_length", "resident_bytes"]
