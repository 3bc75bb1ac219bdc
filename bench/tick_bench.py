"""Benchmark of the per-tick Python of the simulator and the agents, in process.

    .venv/bin/python bench/tick_bench.py [--quick] [--out FILE.json]

What every 100 Hz lockstep tick of Scenario 1 runs besides the STL step (``stl_bench``) and
zenoh (``runtime_bench``): the codec of the three per-tick messages (the frame every agent and
the recorder decode, the command the sim decodes once per due robot, the frame, command and
clock encoded) and the simulator's world tick (``World.step`` over one mocap period: 10 physics
sub-steps with the tracking law of 5 robots, then ``World.mocap_poses``). CPU of this thread
(``time.thread_time``) beside wall, medians of ``--runs`` runs; warm caches.

A real agent process is woken 100 times a second, and on a VM whose idle vCPUs halt it pays
several times the warm figure (``docs/performance.md``). So two figures are one STL
agent's tick (decode the frame, step, encode the command) along a replay of Scenario 1, back to
back and after a 10 ms sleep before every tick, and their ratio; the last two are the same for
the agent's whole loop tick (``AgentLoop.run_once`` on the in-memory bus: channel, checks,
inbox, step, publish) of one robot of a generated 30-robot fleet. The figures
are those of the codec ``$TLFLEET_CODEC`` selects; where that is the C codec
(``tlfleet.bus.protocol._wire``), every codec figure and the agent tick are given with the Python
codec too (``*_python``), the ticks interleaved. No targets: the figures
compare trees (run this file from each checkout), codecs and hours.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tlfleet.agent.model.scenario import Scenario  # noqa: E402
from tlfleet.agent.policy.stl import build_agents  # noqa: E402
from tlfleet.agent.runtime.inbox import MalformedCounter  # noqa: E402
from tlfleet.agent.runtime.loop import AgentLoop, LoopConfig, TickInput  # noqa: E402
from tlfleet.agent.runtime.peers import CollabLink  # noqa: E402
from tlfleet.agent.runtime.process import plausibility  # noqa: E402
from tlfleet.agent.runtime.stl_agent import StlCore  # noqa: E402
from tlfleet.agent.scenario import load_scenario  # noqa: E402
from tlfleet.bus.fake import FakeNetwork  # noqa: E402
from tlfleet.bus.protocol import fast_paths, keys  # noqa: E402
from tlfleet.bus.protocol.codec import decode, encode  # noqa: E402
from tlfleet.bus.protocol.messages import Clock, Command, Control, MocapFrame  # noqa: E402
from tlfleet.sim.world import World  # noqa: E402

from bench.common import RESULTS, Figure, load_average, report, time_calls  # noqa: E402
from bench.runtime_bench import generated_fleet  # noqa: E402

SCENARIO1 = ROOT / "scenarios" / "scenario1.toml"
TICK = 0.01  # [s] Scenario 1's mocap period
TIMED_ROBOT = 4  # the STL robot whose ticks are timed (its task couples it to robots 3 and 5)
FLEET_SIZE, FLEET_ROBOT = 30, 7  # the generated fleet and the robot of the loop-tick figure


def replay_frames(scenario: Scenario, ticks: int) -> list[bytes]:
    """Encoded realtime frames of a kinematic replay of ``scenario``: its STL agents step on every
    frame and their robots move as commanded (world-frame velocities over one tick), the LTL
    robots stay where they start."""
    agents = build_agents(scenario)
    cores = {rid: StlCore(agent) for rid, agent in agents.items()}
    states = {rid: core.initial_state() for rid, core in cores.items()}
    poses = {r.id: tuple(map(float, r.pose)) for r in scenario.robots}
    payloads = []
    for k in range(ticks):
        frame = MocapFrame(k * TICK, k, tuple((rid, *pose) for rid, pose in sorted(poses.items())))
        payloads.append(encode(frame))
        for rid, core in cores.items():
            states[rid], out = core.step(states[rid], TickInput(frame))
            (x, y, theta), (vx, vy, omega) = poses[rid], out.u
            poses[rid] = (x + TICK * vx, y + TICK * vy, theta + TICK * omega)
    return payloads


def agent_ticks(core: StlCore, payloads: list[bytes], runs: int, sleep: float
                ) -> tuple[float, float]:
    """Median over ``runs`` replays of the CPU and wall time [s] of one agent tick (decode the
    frame, step from the replay's state, encode the command), ``sleep`` [s] untimed before each."""
    cpu_runs, wall_runs = [], []
    for _ in range(max(3, runs)):
        state = core.initial_state()
        cpu = wall = 0.0
        for payload in payloads:
            if sleep:
                time.sleep(sleep)
            c0, w0 = time.thread_time(), time.perf_counter()
            frame = decode(MocapFrame, payload)
            state, out = core.step(state, TickInput(frame))
            encode(Command(core.robot, frame.t, frame.seq, out.u))
            cpu += time.thread_time() - c0
            wall += time.perf_counter() - w0
        cpu_runs.append(cpu / len(payloads))
        wall_runs.append(wall / len(payloads))
    return statistics.median(cpu_runs), statistics.median(wall_runs)


def loop_ticks(scenario: Scenario, robot: int, payloads: list[bytes], skip: int, runs: int,
               sleep: float) -> tuple[float, float]:
    """Median over ``runs`` of the CPU and wall time [s] of one whole loop tick of ``robot``'s
    STL agent: ``AgentLoop.run_once`` on the in-memory bus (read the frame from the loop's
    channel, check it, the collaboration inbox, step, publish the command), the frame published
    untimed before each, ``sleep`` [s] untimed before each; a fresh loop per run, the first
    ``skip`` frames untimed."""
    cpu_runs, wall_runs = [], []
    fleet = "bench"
    for _ in range(max(3, runs)):
        network = FakeNetwork()
        transport, sim = network.transport(f"agent{robot}"), network.transport("sim")
        core = StlCore(build_agents(scenario, robots=[robot])[robot])
        malformed = MalformedCounter(f"agent/{robot}")
        link = CollabLink(transport, fleet, robot, core.agent.cfg.peers, malformed)
        loop = AgentLoop(transport, LoopConfig(fleet, robot, **plausibility(scenario)), core,
                         core.initial_state(), link=link, malformed=malformed)
        sent: list[bytes] = []
        network.transport("listener").subscribe(keys.cmd(fleet, robot),
                                                lambda _k, p, sent=sent: sent.append(p))
        loop.open()
        try:
            loop.ready()
            sim.publish(keys.control(fleet), encode(Control(cmd="start", t0=0.0)))
            cpu = wall = 0.0
            answered_before = 0
            for k, payload in enumerate(payloads):
                if k == skip:
                    answered_before = len(sent)
                sim.publish(keys.mocap(fleet), payload)
                if sleep and k >= skip:
                    time.sleep(sleep)
                c0, w0 = time.thread_time(), time.perf_counter()
                loop.run_once(0.0)
                if k >= skip:
                    cpu += time.thread_time() - c0
                    wall += time.perf_counter() - w0
        finally:
            loop.close()
        timed = len(payloads) - skip
        if len(sent) - answered_before != timed:  # each timed frame answered, or the figure
            # times something else (frame 0 at t = 0 is the untimed preview nobody answers)
            raise RuntimeError(f"loop tick: {len(sent) - answered_before} commands for the "
                               f"{timed} timed frames")
        cpu_runs.append(cpu / timed)
        wall_runs.append(wall / timed)
    return statistics.median(cpu_runs), statistics.median(wall_runs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer calls per run")
    parser.add_argument("--runs", type=int, default=7, help="runs per figure (≥ 3)")
    parser.add_argument("--out", type=Path, default=RESULTS / "tick_bench.json")
    args = parser.parse_args(argv)
    calls = 2_000 if args.quick else 20_000
    load_before = load_average()
    scenario = load_scenario(SCENARIO1)
    world = World.from_scenario(scenario, np.random.default_rng(0))
    for robot in world.robots.values():  # moving, so the tracking law does its full work
        robot.target = (0.3, -0.2, 0.4) if robot.kind == "omni" else (0.3, 0.4)
    world.step(0.01)
    frame = MocapFrame(12.34, 1234, world.mocap_poses(), (3, 4, 5))
    frame30 = MocapFrame(12.34, 1234, tuple((i, 0.01 * i, -0.02 * i, 0.3) for i in range(1, 31)),
                         tuple(range(1, 31)))
    command = Command(3, 12.34, 1234, (0.1, -0.2, 0.05))
    clock = Clock(12.34, 1234, "lockstep")
    frame_bytes, frame30_bytes, command_bytes = encode(frame), encode(frame30), encode(command)
    cases = [
        ("decode_frame_us", "decode a 5-robot MocapFrame", lambda: decode(MocapFrame, frame_bytes),
         calls),
        ("decode_frame30_us", "decode a 30-robot MocapFrame",
         lambda: decode(MocapFrame, frame30_bytes), calls),
        ("decode_command_us", "decode a Command", lambda: decode(Command, command_bytes), calls),
        ("encode_frame_us", "encode a 5-robot MocapFrame", lambda: encode(frame), calls),
        ("encode_command_us", "encode a Command", lambda: encode(command), calls),
        ("encode_clock_us", "encode a Clock", lambda: encode(clock), calls),
        ("world_tick_us", "sim world tick: World.step(10 ms) + mocap_poses, 5 robots",
         lambda: (world.step(0.01), world.mocap_poses()), calls // 20),
    ]
    # the codec this process runs ($TLFLEET_CODEC, unsuffixed keys), then, where that is the C
    # codec, the Python codec too (``*_python`` keys)
    setting = os.environ.get("TLFLEET_CODEC", "auto")
    what = "C codec" if fast_paths.native_codec() else "Python codec"
    runs = [(setting, "", what)] + ([("python", "_python", "Python codec")]
                                     if fast_paths.native_codec() else [])
    figures = []
    for codec, suffix, what in runs:
        fast_paths.use_codec(codec)
        for key, label, fn, n in cases:
            if suffix and key == "world_tick_us":
                continue  # no message in it
            timing = time_calls(fn, args.runs, n)
            coded = "frame" in key or "command" in key  # the kinds the C codec handles
            figures.append(Figure(key.replace("_us", suffix + "_us"), label, 1e6 * timing.cpu,
                                  "µs", wall=1e6 * timing.wall, note=what if coded else ""))
    payloads = replay_frames(scenario, 60 if args.quick else 300)
    core = StlCore(build_agents(scenario, robots=[TIMED_ROBOT])[TIMED_ROBOT])
    ticks: dict[str, list] = {}
    for _ in range(2):  # the codecs interleaved: this machine's pace drifts
        for codec, suffix, _what in runs:
            fast_paths.use_codec(codec)
            ticks.setdefault(suffix, []).append((agent_ticks(core, payloads, args.runs, 0.0),
                                                 agent_ticks(core, payloads, args.runs, TICK)))
    fast_paths.use_codec(setting)
    for _codec, suffix, what in runs:
        warm = tuple(statistics.median(w[i] for w, _ in ticks[suffix]) for i in (0, 1))
        slept = tuple(statistics.median(s[i] for _, s in ticks[suffix]) for i in (0, 1))
        figures.append(Figure(f"stl_agent_tick{suffix}_us", f"STL agent tick, S1 robot "
                              f"{TIMED_ROBOT}, back to back, {what}", 1e6 * warm[0], "µs",
                              wall=1e6 * warm[1],
                              note=f"decode the frame, step, encode the command; "
                                   f"{len(payloads)} ticks of a replay of Scenario 1"))
        figures.append(Figure(f"stl_agent_tick_after_sleep{suffix}_us",
                              "  the same, after a 10 ms sleep each", 1e6 * slept[0], "µs",
                              wall=1e6 * slept[1],
                              note=f"{slept[0] / warm[0]:.1f}× the tick back to back: what a "
                                   "100 Hz agent pays on a VM whose idle vCPUs halt"))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"fleet{FLEET_SIZE}.toml"
        path.write_text(generated_fleet(FLEET_SIZE, 10.0))
        fleet = load_scenario(path)
    skip = 100  # the generated tasks are active from then on
    fleet_payloads = replay_frames(fleet, skip + (60 if args.quick else 300))
    loop_warm = loop_ticks(fleet, FLEET_ROBOT, fleet_payloads, skip, args.runs, 0.0)
    loop_cold = loop_ticks(fleet, FLEET_ROBOT, fleet_payloads, skip, args.runs, TICK)
    figures.append(Figure("stl_loop_tick_us", f"STL agent's whole loop tick, robot {FLEET_ROBOT} "
                          f"of a generated {FLEET_SIZE}-robot fleet, back to back",
                          1e6 * loop_warm[0], "µs", wall=1e6 * loop_warm[1],
                          note=f"AgentLoop.run_once on the in-memory bus, {what}; "
                               f"{len(fleet_payloads) - skip} ticks"))
    figures.append(Figure("stl_loop_tick_after_sleep_us", "  the same, after a 10 ms sleep each",
                          1e6 * loop_cold[0], "µs", wall=1e6 * loop_cold[1],
                          note=f"{loop_cold[0] / loop_warm[0]:.1f}× the tick back to back"))
    report("tick_bench", figures, args.out, load_before=load_before, quick=args.quick,
           extra={"runs": max(3, args.runs), "calls": calls})
    return 0


if __name__ == "__main__":
    sys.exit(main())
