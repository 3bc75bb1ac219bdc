"""The typed configuration of one agent process (style.md §6, §10): what ``tlfleet agent`` gives
:func:`tlfleet.agent.runtime.process.main`, with no argparse in sight."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from tlfleet.bus.errors import TlfleetError
from tlfleet.bus.lifeline import ORPHAN_AFTER
from tlfleet.bus.transport import TransportConfig


class AgentConfigError(TlfleetError, ValueError):
    """An agent setting out of range (names the setting and the value)."""


@dataclass(frozen=True)
class AgentConfig:
    """How one agent process runs."""

    robot: int  # the robot id this process drives
    scenario: Path | None = None  # scenario file (None when the caller passes a loaded Scenario)
    stale_after: float = 0.5  # [s] wall: no mocap frame for this long → zero command
    collab_timeout: float = 0.25  # [s] wall: longest wait for a partner's stage-2 reply
    heartbeat: bool = False  # a decimated agent also watches the sim's clock key (LoopConfig)
    orphan_after: float = ORPHAN_AFTER  # [s] wall: exit once the coordinator is gone this long
    transport: TransportConfig = field(default_factory=TransportConfig)

    def __post_init__(self) -> None:
        for name in ("stale_after", "collab_timeout", "orphan_after"):
            value = getattr(self, name)
            if not value > 0.0:
                flag = "--" + name.replace("_", "-")
                raise AgentConfigError(f"{flag} must be positive, got {value}")
