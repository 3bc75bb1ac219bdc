"""How many examples a Hypothesis property runs: ``max_examples=examples(N)``.

``N`` is the property's full budget. By default a run gives each property a quarter of it (at
least 25): with the ``ci`` profile (``.ci/run``, ``CI`` set) the examples are derandomised, the
same on every run; with the ``dev`` profile they are new each time, so local runs keep exploring.
``TLFLEET_HYPOTHESIS=full`` gives every property its whole budget (``make test-full``).
"""

from __future__ import annotations

import os

FULL = os.environ.get("TLFLEET_HYPOTHESIS") == "full"
FLOOR = 25  # fewer examples than this would make a property's failure a matter of luck


def examples(full_budget: int) -> int:
    """The examples a property runs, from its full budget."""
    return full_budget if FULL else min(full_budget, max(FLOOR, full_budget // 4))
