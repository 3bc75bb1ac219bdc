"""The run report as text: the console table and ``report.md``, from the typed report
(:class:`tlfleet.coordinator.record.run_record.Report`)."""

from __future__ import annotations

import math

from tlfleet.coordinator.record.run_record import PaperComparison, Plan, Report, Timing
from tlfleet.coordinator.report import task_verdicts
from tlfleet.coordinator.report.fault_table import render_fault_lines


def _fmt(value: object, spec: str = "+.4f") -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        return format(value, spec) if math.isfinite(value) else str(value)
    return str(value)


def _met(value: bool | None) -> str:
    return "–" if value is None else ("met" if value else "NOT met")


def _paper_text(paper: PaperComparison | None) -> str:
    """The printed bound, with the bound actually judged against when they differ."""
    if paper is None:
        return "–"
    return paper.printed if paper.note == "" else f"{paper.printed} → {paper.bound:g}"


def _plan_text(plan: Plan) -> str:
    return f"{' '.join(plan.prefix) or '–'} ({' '.join(plan.suffix) or '–'})ω"


def render_table(report: Report) -> str:
    """The short console table printed at the end of ``make run`` / by ``tlfleet report``."""
    lines = [f"report {report.scenario}: t_end {report.t_end:.2f} s, {report.frames} frames"
             + (f", {report.mode}" if report.mode else "")]
    if report.trajectory_error:
        lines.append(f"  trajectory: {report.trajectory_error}")
    if report.stl:
        lines.append(f"  {'STL sub-task':<14}{'ours':>9}{'r̄ least':>9}{'r final':>9}{'paper':>19}"
                     f"{'best':>8}  met")
    for rid, stl in report.stl.items():
        for s in stl.subtasks:
            p = s.paper
            label = s.label if s.label == f"r{rid}.{s.index + 1}" else f"{s.label} (r{rid})"
            lines.append(f"  {label:<14}{_fmt(s.robustness):>9}{_fmt(s.r_bar):>9}"
                         f"{_fmt(s.r_final):>9}"
                         f"{_paper_text(p):>19}"
                         f"{_fmt(p.best, '+.2f') if p else '–':>8}  "
                         f"{_met(p.met) if p else '–'}")
        if stl.error:
            lines.append(f"    ({stl.error})")
    if report.stl and not _any_paper(report):
        lines.append(f"  ({report.paper_note})")
    for rid, ltl in report.ltl.items():
        visits = ", ".join(f"{n} {v.trajectory if v.trajectory is not None else v.agent}"
                           for n, v in ltl.visits.items())
        mean = ltl.cycle_time_mean
        cycles = f"cycles {ltl.cycles_completed}" + (
            f" (mean {mean:.1f} s)" if mean is not None else "")
        lines.append(f"  LTL r{rid} {ltl.task}: plan {_plan_text(ltl.plan)}; visits "
                     f"{visits}; {cycles}; accepting {_met(ltl.accepting.met)}")
    c = report.contacts
    contacts = f"  contacts: robot-robot {c.robot_robot}, robot-wall {c.robot_wall}"
    ca = report.closest_approach
    if ca:
        contacts += f"; closest gap {ca.gap:+.3f} m (r{ca.pair[0]}-r{ca.pair[1]}, " \
                    f"t {ca.t:.2f} s)"
    lines.append(contacts)
    lines.append("  timing: " + _timing_text(report.timing))
    lines += ["  " + line for line in task_verdicts.render_lines(report.verdicts)]
    return "\n".join(lines)


def _any_paper(report: Report) -> bool:
    """Whether any STL sub-task of the run is one of the paper's."""
    return any(s.paper for stl in report.stl.values() for s in stl.subtasks)


def _timing_text(timing: Timing) -> str:
    parts = []
    if timing.control_due:
        parts.append(f"control deadlines missed {timing.control_missed or 0} of "
                     f"{timing.control_due}")
    else:
        parts.append(f"deadline-miss events {timing.deadline_miss_events} (no sim_stats)")
    if timing.latency_p50_ms is not None:
        parts.append(f"latency p50 {timing.latency_p50_ms:.2f} ms, "
                     f"p99 {_fmt(timing.latency_p99_ms, '.2f')} ms")
    return ", ".join(parts)


def render_markdown(report: Report) -> str:
    """report.md: tables of the STL sub-tasks, LTL robots, contacts and timing; figure links."""
    out = _markdown_head(report)
    out += _markdown_stl(report)
    out += _markdown_ltl(report)
    out += ["## Verdicts, coupling-aware limits and recovery", "",
            "Every STL sub-task: satisfied (ρ^φ > 0), violated by −ρ^φ, or not evaluated (the run "
            "ended before its window did); held = share of the window's samples with ρ^ψ ≥ 0. "
            "Coupling-aware leaders and robustness recovery go beyond the paper "
            "(docs/coupling.md).", ""]
    out += [f"* {line}" for line in task_verdicts.render_lines(report.verdicts)] + [""]
    out += _markdown_contacts_timing(report)
    out += render_fault_lines(report.faults)
    out += _markdown_figures(report)
    return "\n".join(out)


def _markdown_head(report: Report) -> list[str]:
    out = [f"# Run report: {report.scenario}", ""]
    if report.description:
        out += [report.description, ""]
    out += [f"* run directory: `{report.run_dir}`",
            f"* mode: {report.mode or '–'}; {report.frames} frames; "
            f"t_end = {report.t_end:.2f} s (scenario duration {report.duration:g} s)"]
    out.append(f"* **{report.tasks.line}** (LTL: the executed word satisfies the task; "
               f"STL: ρ > 0 over a window the run covered)")
    if report.trajectory_error:
        out.append(f"* **trajectory unusable**: {report.trajectory_error} — robustness, visits "
                   f"and figures from the trajectory are missing")
    if report.lost_frames:
        out.append("* **frames not recorded**: " + "; ".join(
            f"t = {g.t_from:.2f}–{g.t_to:.2f} s ({g.frames} frames)" for g in report.lost_frames)
                   + " — lost on a link and not backfilled, or after the coordinator lost the "
                     "simulator; robustness and visits see only the frames recorded")
    if report.events_skipped_lines:
        out.append(f"* events.jsonl: line(s) {', '.join(map(str, report.events_skipped_lines))} "
                   f"not JSON (torn write?), skipped")
    out.append("")
    return out


def _markdown_stl(report: Report) -> list[str]:
    out = ["## STL tasks", ""]
    if not report.stl:
        return [*out, "No STL robots.", ""]
    out += ["ρ: standard robustness (min/max semantics) from `trajectory.csv`; r̄ (least): the "
            "least r in force over the sub-task (ρ ≥ r̄ is the funnel's guarantee; repairs "
            "lower r, a recovery raises it again but never lowers the guarantee); r final: the "
            "last funnel's r (above r̄ after a recovery); repairs: the "
            "agent's counters per stage 1/2/3 (repair events in `events.jsonl`); met: ρ ≥ "
            "the paper's bound. Best: best achievable ρ (scenarios.md).", "",
            "| robot | label | sub-task | ρ | r̄ (least) | r final | ρ ≥ r̄ | repairs 1/2/3 "
            "(events) | paper | best | ρ − best | met |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for rid, stl in report.stl.items():
        for s in stl.subtasks:
            p = s.paper
            rep = "/".join(_fmt(n, "d") for n in (s.repairs.stage1, s.repairs.stage2,
                                                  s.repairs.stage3))
            ev = "/".join(str(n) for n in (s.repair_events.stage1, s.repair_events.stage2,
                                           s.repair_events.stage3))
            out.append(
                f"| {rid} | {s.label} | `{s.task}` | {_fmt(s.robustness)} | "
                f"{_fmt(s.r_bar)} | {_fmt(s.r_final)} | "
                f"{_fmt(s.robustness_ge_r_bar)} | {rep} ({ev}) | "
                f"{_paper_text(p)} | {_fmt(p.best, '+.2f') if p else '–'} | "
                f"{_fmt(p.gap_to_best) if p else '–'} | {_met(p.met) if p else '–'} |")
            if p and p.note:
                notes.append(f"* {p.label}: {p.note}.")
            if p and p.best_note and p.best is None:
                notes.append(f"* {p.label}: best achievable {p.best_note}.")
        if stl.error:
            notes.append(f"* robot {rid}: {stl.error}")
    out.append("")
    if not _any_paper(report):
        notes.append(f"* {report.paper_note}.")
    return out + ([*notes, ""] if notes else [])


def _markdown_ltl(report: Report) -> list[str]:
    out = ["## LTL tasks", ""]
    if not report.ltl:
        return [*out, "No LTL robots.", ""]
    out += ["Word: region visits from the trajectory (disc entries with hysteresis, repeats "
            "collapsed; `start` = outside every region at t = 0). Cycle: the plan's suffix; "
            "a cycle is completed when the word runs through it back to its first region. "
            "The run is closed into the lasso u·v^ω with v = the last completed cycle (or the "
            "final region repeated when the task needs no cycle or none was completed) and "
            "checked with the exact lasso evaluator and the Büchi automaton "
            "(see `coordinator/report/run_report.py`).", "",
            "| robot | task | plan prefix (suffix)ω | visits agent/trajectory | cycles | "
            "cycle times [s] | mean [s] | lasso u · v^ω | lasso / Büchi | met |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for rid, e in report.ltl.items():
        visits = ", ".join(f"{n} {v.agent}/{_fmt(v.trajectory, 'd')}"
                           for n, v in e.visits.items())
        times = ", ".join(f"{x:.1f}" for x in e.cycle_times) or "–"
        lasso = (f"{' '.join(e.lasso.prefix) or 'ε'} · ({' '.join(e.lasso.loop)})ω"
                 if e.lasso else "–")
        acc = e.accepting
        out.append(f"| {rid} | `{e.task}` | {_plan_text(e.plan)} | {visits} | "
                   f"{e.cycles_completed} | {times} | {_fmt(e.cycle_time_mean, '.1f')} | "
                   f"{lasso} | {_fmt(acc.lasso)} / {_fmt(acc.buchi)} | "
                   f"{_met(acc.met)} |")
    out.append("")
    for rid, e in report.ltl.items():
        out.append(f"* robot {rid}: plan from {e.plan.source}"
                   + (f"; lasso closed by the {e.lasso.closed_by}" if e.lasso else "")
                   + (f"; **{e.note}**" if e.note else "") + ".")
    out.append("")
    return out


def _markdown_contacts_timing(report: Report) -> list[str]:
    c, ca = report.contacts, report.closest_approach
    out = ["## Contacts", "",
           f"robot–robot {c.robot_robot}, robot–wall {c.robot_wall}"
           + (f" ({', '.join(f'{k}: {v}' for k, v in sorted(c.pairs.items()))})"
              if c.pairs else "") + ".",
           ""]
    if ca:
        out += [f"Closest approach: robots {ca.pair[0]} and {ca.pair[1]}, gap "
                f"{ca.gap:+.3f} m (centre distance minus both radii) at t = {ca.t:.2f} s.",
                ""]
    tm = report.timing
    out += ["## Timing", "",
            "| control deadlines due | missed | deadline-miss events | latency p50 [ms] | "
            "p99 [ms] | max [ms] | watchdog stops | stale mocap | malformed |",
            "|---|---|---|---|---|---|---|---|---|",
            f"| {_fmt(tm.control_due, 'd')} | {_fmt(tm.control_missed, 'd')} | "
            f"{tm.deadline_miss_events} | {_fmt(tm.latency_p50_ms, '.2f')} | "
            f"{_fmt(tm.latency_p99_ms, '.2f')} | {_fmt(tm.latency_max_ms, '.2f')} | "
            f"{tm.watchdog_stop} | {tm.stale_mocap} | {tm.malformed} |", ""]
    deaths = report.process_deaths
    if deaths:
        out += [f"Process deaths: {len(deaths)}: "
                + "; ".join(f"{d.process} at t = {_fmt(d.t, '.2f')} s" for d in deaths), ""]
    return out


def _markdown_figures(report: Report) -> list[str]:
    out = ["## Figures", ""]
    if report.figures:
        out += [f"![{name}]({name})" for name in report.figures]
        out += ["", "Trajectory windows: split at the ends of STL sub-tasks followed by another "
                "sub-task (else the two halves of the run); colour = time. Robustness: ρ^ψ(t) "
                "(solid), funnel ρ_max and lower = ρ_max − γ(t) (dashed), r (dotted), sub-task "
                "windows shaded, repairs marked by stage, recoveries by green triangles."]
    else:
        out.append("No figures written.")
    out.append("")
    return out
