"""Figures of a run, like the paper's Fig. 5–7 (the only matplotlib user; architecture.md §4), as
PNG (200 dpi), PDF or SVG (:data:`FORMATS`: vector for print, ``tlfleet report --figure-format``).

Figures are drawn on ``matplotlib.figure.Figure`` objects with the Agg canvas: no pyplot, no global
state, no window. Inputs are plain numbers (a scenario, a trajectory, status arrays, repair lists)
prepared by ``tlfleet.coordinator.report.run_report``.

* :func:`trajectory_figure` – the arena (walls, obstacles), the LTL regions (discs, named), the
  STL goal points (the constant points of the sub-tasks in the window, × with their tolerance
  circle), and every robot's path during a time window in its own colour whose intensity grows
  with time (the paper: "increasing color intensity"), with start (○) and end markers (robot disc
  + id), as Fig. 5(a)/(b), 6(a), 7(a).
* :func:`robustness_figure` – one STL robot's ρ^ψ(t) with the funnel bounds ρ_max and
  lower = ρ_max − γ(t), the threshold r, its sub-task windows shaded and the repairs marked by
  stage, as Fig. 5(c)–(f), 6(b), 7(b). Rows where the agent is idle (NaN) are gaps.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle
from tlfleet.agent.model import Scenario
from tlfleet.agent.model.scenario import DiscObstacle, RectObstacle
from tlfleet.agent.stl.monitor import Trajectory
from tlfleet.coordinator.report.paper_comparison import RepairEvent

DPI = 200  # PNG resolution; PDF and SVG are vector
FORMATS = ("png", "pdf", "svg")
#: one sequential colour map per robot (by id order): its intensity is the time
ROBOT_MAPS = ("Blues", "Oranges", "Greens", "Reds", "Purples", "Greys", "YlOrBr", "PuRd",
              "BuGn", "RdPu")
STAGE_STYLE = {1: ("o", "tab:orange"), 2: ("D", "tab:green"), 3: ("v", "tab:red")}


def _new_figure(size: tuple[float, float]) -> Figure:
    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def robot_colormap(index: int) -> Any:
    """Robot number ``index`` (0-based, by id)'s colour map, cut to its darker 75 % so that the
    start of a path stays visible on white."""
    from matplotlib import colormaps
    from matplotlib.colors import LinearSegmentedColormap

    base = colormaps[ROBOT_MAPS[index % len(ROBOT_MAPS)]]
    return LinearSegmentedColormap.from_list(f"robot{index}", base(np.linspace(0.25, 1.0, 64)))


def trajectory_figure(scenario: Scenario, traj: Trajectory, window: tuple[float, float],
                      path: Path, *, dpi: int = DPI,
                      goals: Sequence[tuple[int, float, float, float]] = ()) -> Path:
    """Paths of all robots for samples with ``window[0] ≤ t ≤ window[1]`` [s]; ``goals`` are STL
    goal points ``(robot id, x [m], y [m], tolerance [m])`` to mark; writes ``path`` (its suffix
    picks the format)."""
    a, b = window
    fig = _new_figure((6.4, 5.6))
    ax = fig.add_subplot()
    arena = scenario.arena
    ax.add_patch(Rectangle((arena.xmin, arena.ymin), arena.width, arena.height, fill=False,
                           edgecolor="black", linewidth=2.0))
    for obstacle in arena.obstacles:
        if isinstance(obstacle, RectObstacle):
            ax.add_patch(Rectangle((obstacle.xmin, obstacle.ymin), obstacle.xmax - obstacle.xmin,
                                   obstacle.ymax - obstacle.ymin, color="dimgray"))
        elif isinstance(obstacle, DiscObstacle):
            ax.add_patch(Circle(obstacle.center, obstacle.radius, color="dimgray"))
    for region in scenario.regions:
        ax.add_patch(Circle(region.center, region.radius, facecolor="tab:blue", alpha=0.18,
                            edgecolor="tab:blue"))
        ax.annotate(region.name, region.center, xytext=(0, -region.radius * 72 / 1.3 - 6),
                    textcoords="offset points", ha="center", va="top", fontsize=8,
                    color="tab:blue")
    for rid, gx, gy, tolerance in goals:
        ax.add_patch(Circle((gx, gy), tolerance, fill=False, edgecolor="black", linewidth=0.8,
                            linestyle="--"))
        ax.plot(gx, gy, marker="x", color="black", markersize=6, zorder=3)
        ax.annotate(f"goal {rid}", (gx, gy), xytext=(5, -9), textcoords="offset points",
                    fontsize=7)
    norm = Normalize(a, b if b > a else a + 1.0)
    mask = (traj.t >= a) & (traj.t <= b)
    t = traj.t[mask]
    radii = {r.id: r.radius for r in scenario.robots}
    kinds = {r.id: ("LTL" if r.is_ltl else "STL" if r.is_stl else "") for r in scenario.robots}
    lines = None
    for index, rid in enumerate(traj.robot_ids):
        xy = traj.states[rid][mask, :2]
        if len(xy) == 0:
            continue
        if len(xy) > 1:
            segments = np.stack([xy[:-1], xy[1:]], axis=1)
            lines = LineCollection(segments, cmap=robot_colormap(index), norm=norm,
                                   linewidths=1.8)
            lines.set_array(t[:-1])
            ax.add_collection(lines)
        ax.plot(*xy[0], marker="o", markersize=6, markerfacecolor="white",
                markeredgecolor="black", zorder=4)
        ax.add_patch(Circle(tuple(xy[-1]), radii.get(rid, 0.2), facecolor="white",
                            edgecolor="black", alpha=0.85, zorder=5))
        ax.annotate(f"{rid}", tuple(xy[-1]), ha="center", va="center", fontsize=9,
                    fontweight="bold", zorder=6)
        ax.annotate(f"{rid} {kinds.get(rid, '')}".strip(), tuple(xy[0]), xytext=(5, 5),
                    textcoords="offset points", fontsize=7, color="black")
    if lines is not None:  # the time scale, in grey: every robot's map has its intensity
        from matplotlib.cm import ScalarMappable

        fig.colorbar(ScalarMappable(norm, "Greys"), ax=ax, label=r"$t$ [s] (colour intensity)",
                     shrink=0.85)
    margin = 0.2
    ax.set_xlim(arena.xmin - margin, arena.xmax + margin)
    ax.set_ylim(arena.ymin - margin, arena.ymax + margin)
    ax.set_aspect("equal")
    ax.set_xlabel(r"$x$ [m]")
    ax.set_ylabel(r"$y$ [m]")
    ax.set_title(rf"{scenario.name}: $t \in [{a:g}, {b:g}]$ s  (○ start, disc = end)",
                 fontsize=10)
    fig.savefig(path, dpi=dpi)
    return path


def _break_between_subtasks(series: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Insert a NaN row wherever the sub-task index changes, so lines do not join phases."""
    sub = series["subtask"]
    cuts = np.nonzero(np.diff(sub) != 0)[0] + 1
    out = {}
    for key, values in series.items():
        values = np.asarray(values, dtype=float)
        filler = values[cuts] if key == "t" else np.full(len(cuts), np.nan)
        out[key] = np.insert(values, cuts, filler)
    return out


def robustness_figure(robot_id: int, series: Mapping[str, np.ndarray],
                      subtasks: Sequence[tuple[str, float, float]],
                      repairs: Sequence[RepairEvent], path: Path, *, t_end: float,
                      dpi: int = DPI) -> Path:
    """ρ^ψ(t), ρ_max, lower, r of STL robot ``robot_id`` (``series``: arrays ``t, rho, rho_max,
    lower, r, subtask`` (N,), NaN when idle), ``subtasks`` as ``(label, a, b)`` [s], ``repairs``
    its repair events (stage "recovery" for a robustness recovery); writes ``path``."""
    fig = _new_figure((8.4, 3.6))
    ax = fig.add_subplot()
    for k, (label, a, b) in enumerate(subtasks):
        ax.axvspan(a, b, color="gray" if k % 2 == 0 else "silver", alpha=0.18, linewidth=0)
        a, b = max(a, 0.0), min(b, t_end)  # label the visible part (a run may end early)
        if a >= b:
            continue
        ax.annotate(label, ((a + b) / 2, 1.0), xycoords=("data", "axes fraction"),
                    xytext=(0, -3), textcoords="offset points", ha="center", va="top",
                    fontsize=9)
    s = _break_between_subtasks(series) if len(series["t"]) else series
    t = s["t"]
    has_data = bool(len(t)) and bool(np.isfinite(s["rho"]).any())
    if has_data:
        funnel = np.isfinite(s["rho_max"]) & np.isfinite(s["lower"])
        ax.fill_between(t, s["lower"], s["rho_max"], where=funnel, color="tab:blue", alpha=0.12,
                        linewidth=0, label="funnel")
        ax.plot(t, s["rho_max"], "--", color="tab:blue", linewidth=1.0,
                label=r"$\rho^{\max}$")
        ax.plot(t, s["lower"], "--", color="tab:cyan", linewidth=1.0,
                label=r"$\rho^{\max} - \gamma(t)$")
        ax.plot(t, s["r"], ":", color="black", linewidth=1.2, label=r"$r$")
        ax.plot(t, s["rho"], "-", color="tab:purple", linewidth=1.6,
                label=r"$\rho^{\psi}(t)$")
    else:
        ax.text(0.5, 0.5, "no STL status rows", transform=ax.transAxes, ha="center",
                va="center", color="gray")
    ax.axhline(0.0, color="black", linewidth=0.6)
    for stage, (marker, colour) in STAGE_STYLE.items():
        hits = [e for e in repairs if e.stage == stage]
        if not hits:
            continue
        ts = np.array([e.t for e in hits], dtype=float)
        ys = np.array([e.r if e.r is not None else np.nan for e in hits], dtype=float)
        if has_data:  # no r in the event: put the marker on ρ at that time
            missing = ~np.isfinite(ys)
            finite = np.isfinite(series["rho"])
            if missing.any() and finite.any():
                ys[missing] = np.interp(ts[missing], series["t"][finite], series["rho"][finite])
        ys = np.where(np.isfinite(ys), ys, 0.0)
        ax.scatter(ts, ys, marker=marker, s=22, color=colour, zorder=5,
                   label=f"stage {stage} repair ({len(hits)})")
    recoveries = [e for e in repairs if e.stage == "recovery"]
    if recoveries:  # robustness recovery (tlfleet.agent.stl.recovery): the raised r
        ts = np.array([e.t for e in recoveries], dtype=float)
        ys = np.array([e.r if e.r is not None else 0.0 for e in recoveries], dtype=float)
        ax.scatter(ts, ys, marker="^", s=26, color="tab:green", zorder=5,
                   label=f"recovery ({len(recoveries)})")
    ax.set_xlim(0.0, t_end)
    ax.set_xlabel(r"$t$ [s]")
    ax.set_ylabel("robustness")
    ax.set_title(rf"robot {robot_id}: $\rho^{{\psi}}(t)$, funnel and repairs", fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        fig.legend(loc="outside right center", fontsize=7)
    fig.savefig(path, dpi=dpi)
    return path
