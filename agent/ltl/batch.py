"""Batch translation, like ``ltl2tgba -F FILE`` (docs/ltl.md "Tools").

One formula per line (blank lines and lines starting with ``#`` are skipped); each is translated
independently, so one bad line is reported with its line number and does not stop the others.
:func:`translate_file` yields one :class:`BatchResult` per formula; the command prints them as
HOA (one automaton after the other, as Spot does) or, with ``--stats``, as one line each.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from pathlib import Path

from tlfleet.agent.ltl.buchi import Buchi, translate
from tlfleet.bus.errors import LtlError, TlfleetError


@dataclass(frozen=True)
class BatchResult:
    """Line ``line`` (1-based) of the input: the automaton or the error, and CPU/wall time [s]."""

    line: int
    formula: str
    buchi: Buchi | None
    error: TlfleetError | None
    cpu_seconds: float
    wall_seconds: float


def read_formulas(path: str | Path) -> list[tuple[int, str]]:
    """``(line number, formula)`` of every non-blank, non-comment line of ``path``."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise LtlError(f"{path}: cannot read the formula file: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise LtlError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    return [(i, line.strip()) for i, line in enumerate(text.splitlines(), 1)
            if line.strip() and not line.lstrip().startswith("#")]


def translate_all(formulas: Iterable[tuple[int, str]],
                  bound: Callable[[], AbstractContextManager] = nullcontext
                  ) -> Iterator[BatchResult]:
    """Translate each ``(line, formula)``, each inside ``bound()`` (the caller's time and memory
    bound); errors are returned, not raised."""
    for line, text in formulas:
        cpu0, wall0 = time.process_time(), time.perf_counter()
        try:
            with bound():
                buchi, error = translate(text), None
        except TlfleetError as exc:
            buchi, error = None, exc
        yield BatchResult(line, text, buchi, error, time.process_time() - cpu0,
                          time.perf_counter() - wall0)


STATS_HEADER = "line\tstates\tedges\taccepting\tinitial\tcpu_ms\tformula"


def stats_line(result: BatchResult) -> str:
    """Tab-separated statistics of one translation (``STATS_HEADER`` names the columns)."""
    if result.buchi is None:
        return f"{result.line}\terror\t\t\t\t\t{result.formula}"
    b = result.buchi
    return (f"{result.line}\t{b.num_states}\t{b.num_edges}\t{len(b.accepting)}\t"
            f"{len(b.initial)}\t{1e3 * result.cpu_seconds:.3f}\t{result.formula}")
