"""Time and memory bounds on work driven by user input: translating LTL, loading a scenario.

A formula of a few hundred bytes can ask for exponential work (the automaton of some LTL
formulas is exponential in their size), so every command that translates or parses input does
it inside :func:`bounded`: past ``seconds`` of wall time, or past ``megabytes`` of address space
more than the process had when the bound began, the work stops with :class:`LimitExceeded`, a
one-line error naming the limit and the flag that raises it. The bounds use the process's
interval timer (SIGALRM) and ``RLIMIT_AS``; both are restored when the block ends. Main thread
only (a signal handler runs there): elsewhere, and where the OS has neither, the block runs
unbounded.
"""

from __future__ import annotations

import contextlib
import logging
import resource
import signal
import threading
from collections.abc import Iterator

from tlfleet.bus.errors import TlfleetError

logger = logging.getLogger(__name__)

TIME_LIMIT = 60.0  # [s] wall, default bound of one translation or scenario load
MEMORY_LIMIT = 2048  # [MB] default bound on the address space it may add


class LimitExceeded(TlfleetError, RuntimeError):
    """Work on one input stopped at its time or memory bound."""


def _address_space() -> int:
    """Bytes of virtual memory this process maps now (``/proc/self/statm``; 0 if unknown)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as handle:
            pages = int(handle.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 0
    return pages * resource.getpagesize()


@contextlib.contextmanager
def bounded(what: str, seconds: float | None = TIME_LIMIT,
            megabytes: int | None = MEMORY_LIMIT, hint: str = "") -> Iterator[None]:
    """Run the block with at most ``seconds`` of wall time and ``megabytes`` more address
    space; :class:`LimitExceeded` ("``what``: stopped after 60 s (``hint``)") otherwise.
    ``None`` leaves that bound off."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    timed = seconds is not None and seconds > 0 and hasattr(signal, "setitimer")
    previous_handler = None
    if timed:
        def expire(_signum, _frame) -> None:
            raise LimitExceeded(f"{what}: stopped after {seconds:g} s{hint}")

        previous_handler = signal.signal(signal.SIGALRM, expire)
        signal.setitimer(signal.ITIMER_REAL, seconds)
    previous_limit = None
    if megabytes is not None and megabytes > 0:
        base = _address_space()
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = base + megabytes * 1024 * 1024
        if base and (hard == resource.RLIM_INFINITY or limit <= hard):
            with contextlib.suppress(ValueError, OSError):
                resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
                previous_limit = (soft, hard)
    try:
        yield
    except MemoryError:
        raise LimitExceeded(f"{what}: needs more than {megabytes} MB{hint}") from None
    except RecursionError:  # what a deep input does to a recursive step: no traceback either
        raise LimitExceeded(f"{what}: nested too deeply to process") from None
    finally:
        if timed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous_handler)
        if previous_limit is not None:
            resource.setrlimit(resource.RLIMIT_AS, previous_limit)
