"""The files a run leaves after its fleet stopped (steps 6–8 of :mod:`tlfleet.coordinator.run`),
shared by ``tlfleet run`` and ``tlfleet supervise``: ``summary.txt``/``summary.json`` with the run's
verdict, ``report.md``/``report.json`` with the figures, ``run.rrd``; and the optional live
viewer. A failure of the report, of ``run.rrd`` or of the viewer is reported and never fails the
run. rerun (0.9 s to import) and matplotlib are imported only here, and only when used.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from tlfleet.agent.model import Scenario
from tlfleet.coordinator.live.verdict import Verdict
from tlfleet.coordinator.record import rundir
from tlfleet.coordinator.record.run_record import Report, RunSummary, TaskTally
from tlfleet.coordinator.record.rundir import RunFiles
from tlfleet.coordinator.report.summary import write_summary
from tlfleet.coordinator.report.task_tally import task_tally

Say = Callable[[str], None]
Judge = Callable[[RunFiles, RunSummary], Verdict]


class OutputSettings(Protocol):
    """What the outputs and the live viewer read from a run's configuration
    (:class:`tlfleet.coordinator.run.RunConfig` and
    :class:`tlfleet.coordinator.supervise.SuperviseConfig`)."""

    report: bool
    figures: bool
    rrd: bool
    rrd_every: int
    grpc_port: int
    web_port: int


def start_viewer(scenario: Scenario, config: OutputSettings, say: Say) -> Any:
    """A serving :class:`tlfleet.coordinator.report.viewer.LiveView`, or None (reported) when it
    cannot start: the run goes on without."""
    try:
        from tlfleet.coordinator.launch.processes import free_port
        from tlfleet.coordinator.report.viewer import HOST as VIEW_HOST
        from tlfleet.coordinator.report.viewer import LiveView

        view = LiveView.serve(scenario, grpc_port=config.grpc_port or free_port(VIEW_HOST),
                              web_port=config.web_port or free_port(VIEW_HOST))
    except Exception as exc:  # rerun missing, port taken…: never a reason to fail the run
        say(f"no live viewer ({type(exc).__name__}: {exc})")
        return None
    say(f"viewer: {view.url}")
    return view


def write_report(files: RunFiles, summary: RunSummary, figures: bool,
                 say: Say, tally: TaskTally | None = None,
                 figure_format: str = "png") -> tuple[Report | None, str]:
    """Step 7: report.md/json (+ figures); failures are reported, never raised → (Report, error)."""
    try:
        from tlfleet.coordinator.report.run_report import write_report as write

        return write(files, figures=figures, summary=summary, tally=tally,
                     figure_format=figure_format), ""
    except Exception as exc:
        say(f"report not written ({type(exc).__name__}: {exc})")
        return None, f"{type(exc).__name__}: {exc}"


def write_rrd(run: RunFiles | Path, every: int, say: Say) -> dict[str, Any]:
    """Step 8: ``run.rrd`` from the recorded files; failures are reported, never raised."""
    try:
        from tlfleet.coordinator.report.viewer import replay_run

        result = replay_run(run, every=every)
    except Exception as exc:
        say(f"run.rrd not written ({type(exc).__name__}: {exc})")
        return {"error": f"{type(exc).__name__}: {exc}"}
    return {"path": str(result.path), "seconds": round(result.seconds, 3),
            "frames": result.frames}


def write_outputs(run_dir: Path, scenario: Scenario, config: OutputSettings,
                  info: dict[str, Any], write_info: Callable[[dict[str, Any]], None],
                  note: Say, say: Say, judge: Judge | None = None,
                  ) -> tuple[str, RunSummary, Report | None, Path | None, Verdict | None,
                             TaskTally | None]:
    """Steps 6–8 after the fleet stopped: the run directory is read once
    (:func:`rundir.read_run`) and the summary (computed once), the task tally
    (:mod:`tlfleet.coordinator.report.task_tally`), the run's verdict (``judge``), the report
    with its figures and ``run.rrd`` are all made from those files → (summary text, summary
    data, report, rrd path, verdict, tally). ``info`` (run.json) gains the tally, the verdict and
    the report's and the recording's paths or errors; ``summary.txt`` ends with the tally's line
    and the verdict's."""
    files = rundir.read_run(run_dir, scenario=scenario)
    text, summary = write_summary(files)
    tally = tally_or_none(files, summary, say)
    closing = [tally.line] if tally is not None else []
    if tally is not None:
        info["tasks"] = tally.to_json()
    verdict = None
    if judge is not None:
        verdict = judge(files, summary)
        info["outcome"] = verdict.to_json()
        closing.append(verdict.line)
    write_info(info)
    if closing:
        text = "\n".join([text, *closing])
        with open(run_dir / rundir.SUMMARY_TEXT, "a", encoding="utf-8") as summary_file:
            summary_file.write("".join(line + "\n" for line in closing))
    report_result = None
    if config.report:
        report_result, error = write_report(files, summary, config.figures, say, tally,
                                            getattr(config, "figure_format", "png"))
        info["report"] = {"error": error} if report_result is None else {
            "path": str(run_dir / rundir.REPORT_MD),
            "figures": [str(path) for path in report_result.figure_paths]}
        write_info(info)
    rrd_path: Path | None = None
    if config.rrd:
        note(f"writing {run_dir / rundir.RRD} (rerun) …")
        info["rrd"] = write_rrd(files, config.rrd_every, say)
        rrd_path = Path(info["rrd"]["path"]) if "path" in info["rrd"] else None
        write_info(info)
    return text, summary, report_result, rrd_path, verdict, tally


def tally_or_none(files: RunFiles, summary: RunSummary, say: Say) -> TaskTally | None:
    """The task tally; a failure is reported and never fails the run (the process verdict
    still stands)."""
    try:
        return task_tally(files, summary)
    except Exception as exc:
        say(f"task tally not computed ({type(exc).__name__}: {exc})")
        return None
