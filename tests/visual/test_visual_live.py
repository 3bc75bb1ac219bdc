"""The live path: LiveView decimates frames, never raises into the run; runner step 7 never fails
the run; rerun stays out of every module but tlfleet.coordinator.report.viewer and out of `tlfleet
run`'s imports.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tlfleet.agent.scenario import load_scenario
from tlfleet.bus.protocol.messages import Event, LtlStatus, MocapFrame, StlStatus
from visual_helpers import ROOT, SCENARIO, read_rrd


def _live_view(path: Path, frame_period: float = 0.05):
    from tlfleet.coordinator.report import viewer

    scenario = load_scenario(SCENARIO)
    recording = viewer.new_recording()
    recording.save(path)
    log = viewer.FleetLog(scenario, recording)
    log.log_static()
    return viewer.LiveView(log, frame_period=frame_period)


def _frame(t: float, seq: int) -> MocapFrame:
    return MocapFrame(t=t, seq=seq, poses=((1, 0.1 * t, 0.0, 0.0), (2, -0.1 * t, 0.5, 1.0)))


def test_live_view_logs_frames_at_the_decimated_rate(tmp_path: Path) -> None:
    view = _live_view(tmp_path / "live.rrd", frame_period=0.05)
    for seq in range(100):  # 1 s of sim time at 100 Hz
        view.on_message("mocap", _frame(round(seq * 0.01, 10), seq))
    view.on_message("status", StlStatus(robot=2, t=0.5, subtask=0, rho=0.1, rho_max=0.8,
                                        lower=-0.4, r=0.2, stage=1, ce=0, c=0, follow=-1))
    view.on_message("status", LtlStatus(robot=1, t=0.5, prefix=("a1",), suffix=("a2", "a1"),
                                        target="a2", buchi_states=(0,), visits=(), rounds=0,
                                        mode="navigate"))
    view.on_message("event", Event(t=0.6, source="coordinator", kind="process_died",
                                   data={"process": "agent-2"}))
    view.close()
    assert view.failed is None
    rrd = read_rrd(tmp_path / "live.rrd")
    assert rrd["timed"]["/world/robots"] == 20  # t = 0, 0.05, …, 0.95
    assert rrd["timed"]["/rho/r2/rho"] == 1
    assert rrd["timed"]["/world/plans/r1/target"] == 1
    assert rrd["timed"]["/events/coordinator"] == 1
    assert rrd["t_range"] == (0.0, 0.95)


def test_live_view_sends_buffered_rows_every_flush_period_of_wall_time(tmp_path: Path) -> None:
    from tlfleet.coordinator.report import viewer

    now = [100.0]
    scenario = load_scenario(SCENARIO)
    recording = viewer.new_recording()
    recording.save(tmp_path / "live.rrd")
    view = viewer.LiveView(viewer.FleetLog(scenario, recording), flush_period=0.2,
                           clock=lambda: now[0])
    for seq in range(10):
        view.on_message("mocap", _frame(seq * 0.05, seq))
    assert view.log.pending == 10 + 5  # 10 frames, 5 trail segments (every 0.1 s)
    now[0] += 0.2
    view.on_message("mocap", _frame(0.5, 10))
    assert view.log.pending == 0
    view.on_message("mocap", _frame(0.55, 11))
    assert view.log.pending == 1
    view.close()
    assert read_rrd(tmp_path / "live.rrd")["timed"]["/world/robots"] == 12


def test_static_scene_with_obstacles(tmp_path: Path) -> None:
    from tlfleet.coordinator.report import viewer

    path = tmp_path / "obstacles.toml"
    path.write_text(SCENARIO.read_text().replace("[sim]", """[[arena.obstacles]]
shape = "rect"
name = "wall"
xmin = 0.0
xmax = 0.5
ymin = 1.0
ymax = 2.0

[[arena.obstacles]]
shape = "disc"
name = "pillar"
center = [-2.0, 2.0]
radius = 0.3

[sim]"""))
    recording = viewer.new_recording()
    recording.save(tmp_path / "static.rrd")
    viewer.FleetLog(load_scenario(path), recording).log_static()
    recording.disconnect()
    static = read_rrd(tmp_path / "static.rrd")["static"]
    rects = static["/world/obstacles/rects"][0]
    assert rects.column("Boxes2D:half_sizes").to_pylist() == [[[0.25, 0.5]]]
    assert static["/world/obstacles/discs"][0].column("Ellipses2D:centers").to_pylist() == [
        [[-2.0, 2.0]]]
    regions = static["/world/regions"][0]
    assert regions.column("Ellipses2D:centers").to_pylist() == [[[-1.0, 0.0], [1.0, 0.0]]]
    # Names are labelled points at the shapes' own centres, under the same /world flip as the
    # shapes; the shapes carry no labels of their own (rerun draws those unflipped: a region's
    # name stood beside its mirror image).
    for entity in ("/world/obstacles/rects", "/world/obstacles/discs", "/world/regions"):
        assert not [c for c in static[entity][0].schema.names if c.endswith(":labels")], entity
    names = static["/world/regions/names"][0]
    assert names.column("Points2D:labels").to_pylist() == [["a1", "a2"]]
    assert names.column("Points2D:positions").to_pylist() == [[[-1.0, 0.0], [1.0, 0.0]]]
    obstacle_names = static["/world/obstacles/names"][0]
    assert obstacle_names.column("Points2D:labels").to_pylist() == [["wall", "pillar"]]
    assert obstacle_names.column("Points2D:positions").to_pylist() == [[[0.25, 1.5], [-2.0, 2.0]]]
    (flip,) = static["/world"]
    assert flip.column("Transform3D:scale").to_pylist() == [[[1.0, -1.0, 1.0]]]


def test_a_failing_live_view_switches_itself_off_without_raising(tmp_path: Path,
                                                                 caplog) -> None:
    view = _live_view(tmp_path / "live.rrd")
    calls = []

    def broken(*args):
        calls.append(args)
        raise RuntimeError("disk full")

    view.log.frame = broken
    view.on_message("mocap", _frame(0.0, 0))
    view.on_message("mocap", _frame(1.0, 100))
    view.close()
    assert view.failed == "RuntimeError: disk full"
    assert len(calls) == 1  # off after the first failure
    assert "live viewer: logging failed" in caplog.text


def test_runner_reports_a_viewer_that_cannot_start_and_goes_on() -> None:
    import socket

    from tlfleet.coordinator.report.outputs import start_viewer
    from tlfleet.coordinator.run import RunConfig

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        said: list[str] = []
        config = RunConfig(SCENARIO, viewer=True, grpc_port=taken.getsockname()[1])
        assert start_viewer(load_scenario(SCENARIO), config, said.append) is None
    assert len(said) == 1 and said[0].startswith("no live viewer (OSError: gRPC port 127.0.0.1:")


def test_runner_step_7_reports_a_failure_and_returns(tmp_path: Path) -> None:
    from tlfleet.coordinator.report.outputs import write_rrd

    said: list[str] = []
    result = write_rrd(tmp_path, 5, said.append)  # no scenario.toml there
    assert "error" in result and "scenario.toml" in result["error"]
    assert len(said) == 1 and said[0].startswith("run.rrd not written (RunFileError: ")


def test_runner_step_7_writes_run_rrd(run_dir: Path) -> None:
    from tlfleet.coordinator.report.outputs import write_rrd

    result = write_rrd(run_dir, 5, lambda text: None)
    assert result["path"] == str(run_dir / "run.rrd") and result["frames"] == 51
    assert read_rrd(run_dir / "run.rrd")["timed"]["/world/robots"] == 51


def test_run_and_replay_commands_import_rerun_only_when_they_log() -> None:
    code = ("import sys\n"
            "import tlfleet.cli.main, tlfleet.coordinator.run\n"
            "import tlfleet.coordinator.record.recorder\n"
            "import tlfleet.cli.commands.run, tlfleet.cli.commands.replay\n"
            "import tlfleet.agent.runtime.process, tlfleet.agent.runtime.stl_agent\n"
            "import tlfleet.sim.process\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rerun', "
            "'rerun_bindings') or m == 'tlfleet.coordinator.report.viewer'))\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         timeout=60, check=True).stdout
    assert out.strip() == "[]"
