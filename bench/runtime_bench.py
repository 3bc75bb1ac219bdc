"""Benchmark of the distributed runtime (tracker issue 5 §6): real processes on loopback.

    .venv/bin/python bench/runtime_bench.py [--quick] [--runs N] [--out FILE.json]

Every fleet is started by ``tlfleet.coordinator.run.run_fleet`` (router + sim + one process per
agent, exactly as ``tlfleet run``); the figures come from the simulator's ``sim_stats`` event
(``tlfleet.sim.stats``: latency = command arrival at the sim − publication of the frame it answers,
on the sim's own clock; a control deadline of robot r at tick k is missed when its
``Command(seq=k)`` has not arrived when the sim steps past tick k) and from the coordinator's run
record. Medians over
``--runs`` runs (≥ 3):

* ``latency_p50_ms`` / ``latency_p99_ms``: Scenario 1 in realtime (target p99 ≤ 2 ms), over
  every command; ``stl_latency_p99_ms``: the worst per-robot p99 of its STL robots (the LTL
  agents answer 1 frame in 20, so their slower steps are about 3 % of the commands and weigh on
  the fleet's p99), ``ltl_latency_p99_ms`` the same for its LTL robots;
* ``missed_fraction``: missed control deadlines / due ones, same runs (target ≤ 0.1 %);
* ``lockstep_speedup``: Scenario 1 in lockstep, sim seconds per wall second of the supervised
  phase (target ≥ 10×), and beside it the CPU the fleet spends per simulated second
  (``cpu_s_per_sim_s``: every router, sim and agent process, user + system), which does not
  depend on what else the machine runs, and the speed-up that CPU allows on this machine's
  cores (``cpu_bound_speedup`` = cores / CPU-s per sim-s, a ceiling: the round trip sim → agents
  → sim is serial);
* ``max_fleet``: the largest generated fleet of STL robots (omni, a reach task each, on a grid)
  whose realtime runs at 100 Hz miss ≤ 1 % of their deadlines (median over the runs; sizes
  tried in ``--sizes`` order, stopping at the first that fails; target ≥ 30).
* ``max_fleet_2_hosts_tcp`` / ``_tls``: the same generated fleets, 2 × N robots, over two
  network-namespace hosts with a zenoh router each (``tlfleet run --hosts 2``, the multi-host
  mesh; plain TCP and mutual TLS), interleaved run by run with the same fleet run locally
  (``local``), N in ``--host-sizes`` order; root only. Both hosts share this machine's two
  cores, so this measures what the mesh costs, not what a second machine adds.

* ``floor``: ``bench/floor_probe.py`` in the same benchmark: CPU per tick of an agent-like
  process (receive a frame, 30 µs of work, answer) over a bare UDP socket (the floor for a
  Python process woken 100× a second) and over zenoh as tlfleet configures it, so the gap of
  the real agent tick to physics is visible; and the round trip's p99 over bare UDP, directly
  and through a relay process (the realtime fleet's shape: sim → router → agent → router →
  sim), the floor of the latency p99 on this machine at this moment; and the lockstep
  fleet's shape with the fleet's code taken out (``floor_probe.lockstep_probe`` with no work:
  a sim-like process, 3 agent-like ones, 2 decimated LTL-like ones and a listener, over
  zenoh and over bare UDP, scheduled as the fleet), the speed-up the wake-ups and the
  transport alone allow at this moment, beside the real fleet's (until round 16 the probe
  spent round 9's per-frame costs, which the C kernels since made larger than the fleet's own
  and the "floor" slower than the fleet); and the fleet size's floor
  (``bench/fleet_floor.py``): the target's 30 agent-like processes answering a sim-like
  process's spread frames over zenoh, with 30, 150 and 250 µs of work per tick, and the
  deadlines they miss (with ``fleet`` and ``floor``);
* a latency histogram (``latency_histogram_ms``, from ``sim_stats``) of every realtime run.

Besides, for every run, the CPU time of each child process per wall second of the supervised
phase (``psutil`` user + system, sampled every 0.25 s; ``cpu_pct``: mean per role, % of one
core). Wall-clock figures (latency, missed deadlines) depend on whatever else the machine runs;
CPU per process much less so, which makes it the figure to compare changes with on a shared
machine. Realtime tick 0 owes no command (``tlfleet.sim.stats``), so a run misses nothing by
construction.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import math
import os
import resource
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tlfleet.agent.scenario import load_scenario  # noqa: E402
from tlfleet.coordinator.launch.processes import FIFO_PRIORITY, fifo_permitted  # noqa: E402
from tlfleet.coordinator.live.supervisor import SupervisorConfig  # noqa: E402
from tlfleet.coordinator.record.rundir import read_events  # noqa: E402
from tlfleet.coordinator.run import RunConfig, run_fleet  # noqa: E402
from tlfleet.coordinator.run_hosts import run_on_hosts  # noqa: E402

from bench.common import Figure, load_average, report  # noqa: E402
from bench.fleet_floor import SENDER_WORK_US as FLEET_FLOOR_SENDER_US  # noqa: E402
from bench.fleet_floor import SLOTS as FLEET_FLOOR_SLOTS  # noqa: E402
from bench.fleet_floor import fleet_probe  # noqa: E402
from bench.floor_probe import lockstep_probe  # noqa: E402
from bench.floor_probe import probe as floor_probe  # noqa: E402

SCENARIO1 = ROOT / "scenarios" / "scenario1.toml"
TARGETS = {"latency_p99_ms": 2.0, "missed_fraction": 0.001, "lockstep_speedup": 10.0,
           "max_fleet": 30}
FLEET_MISS_LIMIT = 0.01
# the fleet-size floor (bench/fleet_floor.py; its shape, a 30-robot fleet's five frame instants and
# the simulator's share of a core, is that module's SLOTS and SENDER_WORK_US): the agent-like
# work per tick: the floor's 30 µs, 150 µs, and 250 µs, about what a generated fleet's STL agent
# spends per tick in its own Python from cold caches (decode, checks, step, encode)
FLEET_FLOOR_WORK_US = (30.0, 150.0, 250.0)


def generated_fleet(n: int, duration: float) -> str:
    """TOML of ``n`` omni robots on a grid in the 7 m × 7 m arena, each with
    ``F[a,b] (dist(p_i, goal_i) <= 0.1)``, goal 0.3 m to the right of the start."""
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    spacing = min(6.0 / max(cols, 1), 6.0 / max(rows, 1))
    a, b = 0.3 * duration, 0.9 * duration
    lines = [f'name = "fleet{n}"', f"duration = {duration}", "[sim]", "seed = 1"]
    for i in range(n):
        x = -3.0 + spacing * (i % cols + 0.5) - 0.15
        y = -3.0 + spacing * (i // cols + 0.5)
        lines += ["[[robots]]", f"id = {i + 1}", 'kind = "omni"', f"pose = [{x:.3f}, {y:.3f}, 0.0]",
                  f'stl = ["F[{a:g},{b:g}] (dist(p{i + 1}, [{x + 0.3:.3f}, {y:.3f}]) <= 0.1)"]']
    return "\n".join(lines) + "\n"


class CpuSampler:
    """Samples the CPU time (user + system [s]) of every descendant process, by role (the
    ``tlfleet`` subcommand: router, sim, agent-<id>), and of this process (``coordinator``:
    ``run_fleet`` supervises and records in-process; this sampler's own thread is included), in a
    background thread."""

    def __init__(self, period: float = 1.0):  # [s]; every sample scans /proc: keep it rare
        self.period = period
        self.samples: dict[int, tuple[str, list[tuple[float, float]]]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cpu-sampler", daemon=True)

    def __enter__(self) -> CpuSampler:
        self._thread.start()
        return self

    def __exit__(self, *_exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        # a sampler must outrank what it samples: a lockstep fleet runs under SCHED_FIFO where
        # permitted, and this ordinary thread then missed whole runs of samples
        if fifo_permitted():
            with contextlib.suppress(OSError):
                os.sched_setscheduler(threading.get_native_id(), os.SCHED_FIFO,
                                      os.sched_param(FIFO_PRIORITY + 1))
        me = psutil.Process()
        procs: dict[int, tuple[psutil.Process, str]] = {}
        scans = 0
        while not self._stop.is_set():
            now = time.monotonic()
            # the process tree is read from the whole of /proc: every sample until the fleet's
            # processes are there, then every 4th (the sampler is part of the
            # coordinator's CPU it reports; a fleet's processes all start before its mission)
            if len(procs) <= 1 or scans % 4 == 0:
                self._add_children(me, procs)
            scans += 1
            if me.pid not in procs:  # the coordinator runs in this process (run_fleet)
                procs[me.pid] = (me, "coordinator")
            for pid, (proc, role) in list(procs.items()):
                try:
                    with proc.oneshot():  # one read of /proc/<pid>/stat for both
                        if proc.status() == psutil.STATUS_ZOMBIE:  # ended, not yet reaped:
                            raise psutil.ZombieProcess(pid)       # its samples read as idle
                        times = proc.cpu_times()
                except psutil.Error:
                    del procs[pid]
                    continue
                self.samples.setdefault(pid, (role, []))[1].append(
                    (now, times.user + times.system))
            self._stop.wait(self.period)

    @staticmethod
    def _add_children(me: psutil.Process, procs: dict[int, tuple[psutil.Process, str]]
                      ) -> None:
        """Add this process's new descendants that are tlfleet processes, with their roles."""
        try:
            children = me.children(recursive=True)
        except psutil.Error:
            return
        for child in children:
            if child.pid not in procs:
                try:
                    argv = child.cmdline()
                except psutil.Error:
                    continue
                if "tlfleet.cli" in argv[:-1]:
                    role = argv[argv.index("tlfleet.cli") + 1]
                    if "--robot" in argv[:-1]:
                        role += "-" + argv[argv.index("--robot") + 1]
                    procs[child.pid] = (child, role)

    def cpu_per_sim_s(self, start: float, end: float, t_end: float) -> dict[str, float]:
        """CPU seconds per simulated second of each role (summed over its processes) over the
        mission: from ``start`` (monotonic [s], the mission start, interpolated between the
        samples around it) to each child's last sample (it exits when the mission is over) and,
        for this process (``coordinator``, which goes on to write the report), to ``end`` (the
        last progress call), over the mission's ``t_end`` [s] of sim time. Independent of how
        fast the run went, and of when the coordinator saw the frames (an ordinary
        coordinator beside a SCHED_FIFO lockstep fleet drains late, and sim time read from its
        progress made the fleet's CPU per sim second look higher than two cores allow)."""
        if not t_end > 0:
            return {}
        per_role: dict[str, float] = {}
        for role, series in self.samples.values():
            after = [k for k, (t, _c) in enumerate(series) if t >= start]
            if not after or after[0] == len(series) - 1:
                continue
            k = after[0]
            if k > 0:  # interpolate the CPU at the start between the samples around it
                (ta, ca), (tb, cb) = series[k - 1], series[k]
                c0 = ca + (cb - ca) * (start - ta) / max(tb - ta, 1e-9)
            else:  # the process appeared after the start: from its first sample
                c0 = series[0][1]
            if role == "coordinator":
                inside = [c for t, c in series if t <= end]
                c1 = inside[-1] if inside else series[-1][1]
            else:
                c1 = series[-1][1]
            used = (c1 - c0) / t_end
            per_role[role] = per_role.get(role, 0.0) + used
            if role.startswith("agent-"):  # and the sum over every agent process
                per_role["agents"] = per_role.get("agents", 0.0) + used
        return dict(sorted(per_role.items()))

    def cpu_pct(self, begin: float, end: float) -> dict[str, float]:
        """Mean CPU per process of each role over [begin, end] (monotonic [s]), % of a core."""
        per_role: dict[str, list[float]] = {}
        for role, series in self.samples.values():
            inside = [(t, c) for t, c in series if begin <= t <= end]
            if len(inside) >= 2 and inside[-1][0] > inside[0][0]:
                (t0, c0), (t1, c1) = inside[0], inside[-1]
                pct = 100.0 * (c1 - c0) / (t1 - t0)
                per_role.setdefault(role, []).append(pct)
                if role.startswith("agent-"):  # and the mean over every agent process
                    per_role.setdefault("agent", []).append(pct)
        return {role: statistics.mean(v) for role, v in sorted(per_role.items())}


def run_once(scenario: Path, mode: str, duration: float, out: Path,
             ready_timeout: float = 120.0) -> dict:
    """One run; its sim_stats, the coordinator's wall time and speed-up, CPU per role."""
    stl_ids = {r.id for r in load_scenario(scenario).robots if r.is_stl}
    marks: list[float] = []

    def progress(_t: float, _total: float) -> None:
        marks.append(time.monotonic())

    load_before = os.getloadavg()
    children_before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with CpuSampler(period=0.1 if mode == "lockstep" else 0.5) as sampler:
        result = run_fleet(RunConfig(scenario, mode=mode, out=out, duration=duration,
                                     supervisor=SupervisorConfig(
                                         ready_timeout=ready_timeout,
                                         wall_timeout=20 * duration + 120)),
                           progress=progress)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = sampler.cpu_pct(marks[0] + 0.5, marks[-1]) if len(marks) >= 2 else {}
    cpu_sim = sampler.cpu_per_sim_s(marks[0], marks[-1], result.outcome.t_end) \
        if marks else {}
    return {
        "clean": result.clean, "reason": result.outcome.reason, "t_end": result.outcome.t_end,
        "links": result.info.get("links"),  # "peer": sim ↔ agents directly
        "wall_time": result.info.get("wall_time", math.nan),
        "ready_time": result.info.get("ready_time", math.nan),
        "speedup": result.info.get("speedup", math.nan),
        **run_figures(out, stl_ids, cpu),
        "cpu_s_per_sim_s": cpu_sim,
        # nan when the samples missed the run (no role sampled inside the supervised phase)
        "total_cpu_s_per_sim_s": sum(v for k, v in cpu_sim.items() if k != "agents")
        if cpu_sim else math.nan,
        # the cross-check that needs no sampling: every child's CPU over the whole run (start-up
        # included), per sim second
        "children_cpu_s_per_sim_s": (children.ru_utime + children.ru_stime
                                     - children_before.ru_utime - children_before.ru_stime)
        / max(result.outcome.t_end, 1e-9),
        "load_before": load_before[0], "load_after": os.getloadavg()[0],
    }


def run_figures(run_dir: Path, stl_ids: set[int], cpu: dict[str, float]) -> dict:
    """What every realtime or lockstep run reports from the sim's ``sim_stats`` event in
    ``run_dir`` (latency, the STL robots' own, missed deadlines) and from the CPU sampler's
    ``cpu`` (% of a core per role)."""
    events = run_dir / "events.jsonl"
    stats = next((e.data for e in reversed(read_events(events, strict=False))
                  if e.kind == "sim_stats"), {}) if events.is_file() else {}
    due = stats.get("due", 0)
    by_robot = stats.get("latency_p99_ms_by_robot", {})
    return {
        "latency_p50_ms": stats.get("latency_p50_ms", math.nan),
        "latency_p99_ms": stats.get("latency_p99_ms", math.nan),
        "latency_p99_ms_by_robot": by_robot,
        "latency_histogram_ms": stats.get("latency_histogram_ms", {}),
        # the STL robots' commands on ticks where an LTL agent steps too, and on the others
        **{key: stats.get(key, math.nan) for key in (
            "latency_p50_ms_shared", "latency_p99_ms_shared", "latency_p50_ms_alone",
            "latency_p99_ms_alone")},
        "stl_latency_p99_ms": max((v for r, v in by_robot.items() if int(r) in stl_ids),
                                  default=math.nan),
        "ltl_latency_p99_ms": max((v for r, v in by_robot.items() if int(r) not in stl_ids),
                                  default=math.nan),
        "due": due, "missed": stats.get("missed", 0),
        "missed_fraction": stats.get("missed", 0) / due if due else math.nan,
        "cpu_pct": cpu,
        "agent_cpu_pct": cpu.get("agent", math.nan), "sim_cpu_pct": cpu.get("sim", math.nan),
        "router_cpu_pct": cpu.get("router", math.nan),
    }


def run_on_two_hosts(scenario: Path, duration: float, out: Path, *, insecure: bool) -> dict:
    """One realtime run of ``scenario`` over two network-namespace hosts, one zenoh router each,
    the routers connected (``tlfleet run --hosts 2``,
    :func:`tlfleet.coordinator.run_hosts.run_on_hosts`: the sim and the coordinator on host 0, robot
    number j on host j mod 2, so every frame to and every command from the robots of host 1 crosses
    both routers). Secured (mutual TLS and each router's access control, the default of ``--hosts``)
    unless ``insecure`` (plain TCP). Root only. Its figures from ``run.json`` and the sim's
    ``sim_stats``, as :func:`run_once`; CPU per process over the realtime phase (located from the
    sim process's CPU: it works until the duration has run), as % of a core and as CPU-s per sim-s
    (realtime: one sim second per wall second)."""
    stl_ids = {r.id for r in load_scenario(scenario).robots if r.is_stl}
    load_before = os.getloadavg()
    with CpuSampler(period=0.5) as sampler:
        done = run_on_hosts(scenario, 2, out=out, mode="realtime", capture=True,
                            insecure=insecure)
    # the realtime phase: the `duration` [s] up to the last sample at which the sim still worked
    # (over 5 % of a core; afterwards it waits for the coordinator's stop or has ended)
    busy = [t1 for role, series in sampler.samples.values() if role == "sim"
            for (t0, c0), (t1, c1) in itertools.pairwise(series) if c1 - c0 > 0.05 * (t1 - t0)]
    cpu: dict[str, float] = {}
    if busy:
        end = max(busy) - 0.5
        cpu = sampler.cpu_pct(end - duration + 2.0, end)
    info_path = out / "run.json"
    info = json.loads(info_path.read_text()) if info_path.is_file() else {}
    return {
        "clean": bool(info.get("clean")) and done.returncode == 0,
        "reason": info.get("reason", f"tlfleet supervise exited {done.returncode}"),
        "links": "tcp" if insecure else "tls",
        "ready_time": info.get("ready_time", math.nan),
        **run_figures(out, stl_ids, cpu),  # router_cpu_pct: the mean of the two routers
        "cpu_s_per_sim_s": {k: v / 100.0 for k, v in cpu.items() if k.startswith("agent-")},
        "load_before": load_before[0], "load_after": os.getloadavg()[0],
    }


def median(runs: list[dict], key: str) -> float:
    values = [r[key] for r in runs if not math.isnan(r[key])]
    return statistics.median(values) if values else math.nan


def agent_tick_us(runs: list[dict]) -> float:
    """Median CPU µs per control tick of an STL agent process (100 Hz): CPU-s per sim-s of each
    agent process ×10⁴, median over processes and runs."""
    values = [v * 1e4 for r in runs for k, v in r["cpu_s_per_sim_s"].items()
              if k.startswith("agent-")]
    return statistics.median(values) if values else math.nan


#: the ways a 2 × N fleet is run by :func:`hosts_fleets`, interleaved run by run
HOST_VARIANTS = ("local", "2 hosts tcp", "2 hosts tls")


def hosts_fleets(sizes: list[int], runs: int, duration: float, tmpdir: Path
                 ) -> dict[str, dict[int, list[dict]]]:
    """Generated STL fleets of 2 × N robots (N in ``sizes``, in order) in realtime, three ways,
    interleaved run by run so that they see the same machine: ``local`` (``tlfleet run`` on
    loopback, as ``max_fleet``: sim and agents linked as peers), over two namespace hosts (every
    process a client of its host's router) with plain TCP and with mutual TLS
    (:func:`run_on_two_hosts`). Stops after the first size at which neither host variant holds
    (≤ 1 % missed, median over the runs, every run clean). Prints a line per size and variant."""
    out: dict[str, dict[int, list[dict]]] = {v: {} for v in HOST_VARIANTS}
    for n in sizes:
        path = tmpdir / f"hosts{n}.toml"
        path.write_text(generated_fleet(2 * n, duration))
        for k in range(runs):
            for variant in HOST_VARIANTS:
                run_dir = tmpdir / f"hosts{n}-{variant.replace(' ', '-')}-{k}"
                run = (run_once(path, "realtime", duration, run_dir) if variant == "local"
                       else run_on_two_hosts(path, duration, run_dir,
                                             insecure=variant.endswith("tcp")))
                out[variant].setdefault(n, []).append(run)
        for variant in HOST_VARIANTS:
            got = out[variant][n]
            print(f"  2 × {n:>2} STL robots, {variant:<11}: missed "
                  f"{100 * median(got, 'missed_fraction'):.2f} %, latency p50 "
                  f"{median(got, 'latency_p50_ms'):.2f} ms p99 {median(got, 'latency_p99_ms'):.2f}"
                  f" ms, CPU per agent tick {agent_tick_us(got):.0f} µs, router "
                  f"{median(got, 'router_cpu_pct'):.1f} % of a core (each), load "
                  f"{os.getloadavg()[0]:.1f}", flush=True)
        if not any(holds(out[v][n]) for v in HOST_VARIANTS if v != "local"):
            break
    return out


def fleet_floor_figures(fleet_floor: dict[float, list[dict]]) -> list[Figure]:
    """The fleet-size floor (bench/fleet_floor.py): the target's number of agent-like processes
    over zenoh, with the floor's work per tick and with about an agent's Python."""
    out = []
    n = TARGETS["max_fleet"]
    for work in FLEET_FLOOR_WORK_US:
        rows = fleet_floor.get(work, [])
        label = (f"  floor: {n} agent-like processes over zenoh ({work:.0f} µs a tick), missed"
                 if work == FLEET_FLOOR_WORK_US[0] else
                 f"    the same with {work:.0f} µs of Python a tick, missed")
        note = ""
        if rows:
            note = (f"median of {len(rows)}: latency p50 {median(rows, 'latency_p50_ms'):.2f} ms, "
                    f"p99 {median(rows, 'latency_p99_ms'):.2f} ms, receiver CPU "
                    f"{median(rows, 'rx_cpu_us'):.0f} µs a tick, sender "
                    f"{median(rows, 'sender_cpu_pct'):.0f} % of a core, machine idle "
                    f"{median(rows, 'idle_pct'):.0f} %")
            if work == FLEET_FLOOR_WORK_US[0]:
                note += (f"; {FLEET_FLOOR_SLOTS} slots a period, {FLEET_FLOOR_SENDER_US:.0f} µs "
                         "of sender work before each (bench/fleet_floor.py)")
        out.append(Figure(f"floor_fleet_{work:.0f}us_missed_pct", label,
                          100 * median(rows, "missed_fraction") if rows else math.nan, "%",
                          note=note))
    return out


def holds(runs: list[dict]) -> bool:
    """A realtime fleet holds: ≤ 1 % of its control deadlines missed (median) and every run
    clean."""
    return median(runs, "missed_fraction") <= FLEET_MISS_LIMIT and all(r["clean"] for r in runs)


def hosts_figures(two_hosts: dict[str, dict[int, list[dict]]]) -> list[Figure]:
    """The figures of :func:`hosts_fleets`: per variant the largest 2 × N fleet that held, and
    at the largest size every variant ran, missed deadlines, latency p50 (with its ratio to the
    local run of the same size) and CPU per agent tick."""
    nan = math.nan
    ran = list(two_hosts.get("local", {}))
    figures = []
    for variant in HOST_VARIANTS[1:]:
        sizes = two_hosts.get(variant, {})
        held = [n for n in sizes if holds(sizes[n])]
        figures.append(Figure(f"max_fleet_{variant.replace(' ', '_')}",
                              f"largest fleet over 2 namespace hosts ({variant[8:]}), 2 × N",
                              float(2 * max(held)) if held else (0.0 if sizes else nan),
                              "robots"))
    if ran:
        n = max(ran)
        local_p50 = median(two_hosts["local"][n], "latency_p50_ms")
        for variant in HOST_VARIANTS:
            got = two_hosts[variant][n]
            p50 = median(got, "latency_p50_ms")
            ratio = f"; {p50 / local_p50:.2f}× the local p50" if variant != "local" else ""
            figures.append(Figure(
                f"hosts{2 * n}_{variant.replace(' ', '_')}_missed_pct",
                f"  {2 * n} robots, {variant}: missed deadlines", 100 * median(
                    got, "missed_fraction"), "%",
                note=f"latency p50 {p50:.2f} ms, p99 {median(got, 'latency_p99_ms'):.2f} ms"
                     f"{ratio}; CPU per agent tick {agent_tick_us(got):.0f} µs; router "
                     f"{median(got, 'router_cpu_pct'):.1f} % of a core"))
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="short runs (realtime 10 s, lockstep 30 s, fleets 6 s)")
    parser.add_argument("--runs", type=int, default=3, help="runs per figure (≥ 3)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 5, 10, 15, 20, 25, 30, 40],
                        help="generated fleet sizes to try, in order")
    parser.add_argument("--host-sizes", type=int, nargs="+", default=[3, 5, 10, 15],
                        help="robots per host of the 2 × N fleets over two namespace hosts, in "
                             "order (root only)")
    parser.add_argument("--skip", nargs="*", default=[],
                        choices=("realtime", "lockstep", "fleet", "hosts", "floor"),
                        help="parts not to run (their figures are reported as n/a)")
    parser.add_argument("--out", type=Path,
                        default=ROOT / "bench" / "results" / "runtime_bench.json")
    args = parser.parse_args(argv)
    runs = max(3, args.runs)
    realtime_s, lockstep_s, fleet_s = (10.0, 30.0, 6.0) if args.quick else (30.0, 90.0, 10.0)
    started = time.monotonic()
    load_before = load_average()
    realtime: list[dict] = []
    lockstep: list[dict] = []
    fleets: dict[int, list[dict]] = {}
    two_hosts: dict[str, dict[int, list[dict]]] = {}  # variant → robots per host → runs
    beside: list[dict] = []  # floor probes of the UDP round trips, one after each realtime run
    max_fleet = 0
    with tempfile.TemporaryDirectory(prefix="runtime_bench-") as tmp:
        tmpdir = Path(tmp)
        for k in range(runs) if "realtime" not in args.skip else ():
            realtime.append(run_once(SCENARIO1, "realtime", realtime_s, tmpdir / f"rt{k}"))
            if "floor" not in args.skip:  # the latency floor right after each run: same load
                beside.append(floor_probe(runs=1, seconds=realtime_s / 3,
                                          variants=("udp", "udp-relay")))
        if "lockstep" not in args.skip:
            lockstep = [run_once(SCENARIO1, "lockstep", lockstep_s, tmpdir / f"ls{k}")
                        for k in range(runs)]
        for n in args.sizes if "fleet" not in args.skip else ():
            path = tmpdir / f"fleet{n}.toml"
            path.write_text(generated_fleet(n, fleet_s))
            fleets[n] = [run_once(path, "realtime", fleet_s, tmpdir / f"fleet{n}-{k}")
                         for k in range(runs)]
            miss = median(fleets[n], "missed_fraction")
            print(f"  fleet of {n:>3} STL robots: missed {100 * miss:.2f} % (median of {runs}), "
                  f"ready in {median(fleets[n], 'ready_time'):.1f} s, CPU per agent tick "
                  f"{agent_tick_us(fleets[n]):.0f} µs, sim "
                  f"{median(fleets[n], 'sim_cpu_pct'):.1f} %, router "
                  f"{median(fleets[n], 'router_cpu_pct'):.1f} % of a core, load "
                  f"{os.getloadavg()[0]:.1f}", flush=True)
            if not holds(fleets[n]):
                break
            max_fleet = n
        if "hosts" not in args.skip and os.geteuid() != 0:
            print("runtime_bench: the 2 × N fleets over namespace hosts need root: not run",
                  file=sys.stderr)
        elif "hosts" not in args.skip:
            two_hosts = hosts_fleets(args.host_sizes, runs, fleet_s, tmpdir)
    floor = floor_probe(runs=runs, seconds=2.0 if args.quick else 3.0) \
        if "floor" not in args.skip else {}
    lockstep_floor = lockstep_probe(runs=runs, seconds=1.0 if args.quick else 3.0,
                                    work_us=0.0, sim_work_us=0.0, ltl_agents=2,
                                    ltl_work_us=0.0, divider=20) \
        if "floor" not in args.skip and "lockstep" not in args.skip else {}
    fleet_floor = {work: [fleet_probe(TARGETS["max_fleet"], FLEET_FLOOR_SLOTS, work,
                                      FLEET_FLOOR_SENDER_US, 3.0 if args.quick else 5.0)
                          for _ in range(runs)]
                   for work in FLEET_FLOOR_WORK_US} \
        if "floor" not in args.skip and "fleet" not in args.skip else {}
    nan = math.nan
    cpu_sim = median(lockstep, "total_cpu_s_per_sim_s") if lockstep else nan
    cores = os.cpu_count() or 1
    largest = fleets.get(max_fleet) or []

    def fl(variant: str, key: str) -> float:
        return floor.get(variant, {}).get(key, nan)

    def fl_beside(variant: str, key: str) -> float:
        """The UDP round trips measured right after the realtime runs (median), else ``fl``."""
        values = [b[variant][key] for b in beside if variant in b]
        return statistics.median(values) if values else fl(variant, key)

    figures = [
        Figure("latency_p50_ms", "Scenario 1 realtime: frame→command latency p50",
               median(realtime, "latency_p50_ms") if realtime else nan, "ms"),
        Figure("latency_p99_ms", "Scenario 1 realtime: frame→command latency p99 (fleet)",
               median(realtime, "latency_p99_ms") if realtime else nan, "ms",
               TARGETS["latency_p99_ms"]),
        Figure("stl_latency_p99_ms", "  the STL robots alone (worst robot's p99)",
               median(realtime, "stl_latency_p99_ms") if realtime else nan, "ms"),
        Figure("ltl_latency_p99_ms", "  the LTL robots (worst robot's p99)",
               median(realtime, "ltl_latency_p99_ms") if realtime else nan, "ms",
               note="5 Hz: 10 of the fleet's 310 commands a second; with spread frames "
                    "([sim] spread_frames) their frames are sampled 7 ms into the period"),
        Figure("stl_alone_p99_ms", "  STL robots on ticks without an LTL step, p99",
               median(realtime, "latency_p99_ms_alone") if realtime else nan, "ms",
               note=f"p50 {median(realtime, 'latency_p50_ms_alone'):.2f} ms; on the ticks an LTL "
                    f"robot is due on (Scenario 1: 2 of 20, staggered; its frame at 7 ms), p50 "
                    f"{median(realtime, 'latency_p50_ms_shared'):.2f} ms, p99 "
                    f"{median(realtime, 'latency_p99_ms_shared'):.2f} ms" if realtime else ""),
        Figure("floor_relay_p99_ms", "  floor: the fleet's round trip over bare UDP, p99",
               fl_beside("udp-relay", "rtt_p99_us") / 1e3, "ms",
               note="sender → relay → receiver (30 µs of work) → relay → sender at 100 Hz, "
                    "no zenoh: the wake-ups of the fleet's path alone (bench/floor_probe.py), "
                    "measured right after each realtime run"),
        Figure("floor_udp_p99_ms", "  floor: a direct UDP echo (no relay), p99",
               fl_beside("udp", "rtt_p99_us") / 1e3, "ms"),
        Figure("missed_pct", "Scenario 1 realtime: missed control deadlines",
               100 * median(realtime, "missed_fraction") if realtime else nan, "%",
               100 * TARGETS["missed_fraction"]),
        Figure("agent_tick_us", "Scenario 1 realtime: CPU per agent process per tick",
               agent_tick_us(realtime) if realtime else nan, "µs",
               note="median over the 5 agent processes (the 2 LTL agents read only every "
                    "20th frame since issue 17: the median is an STL agent)"),
        Figure("lockstep_speedup", "Scenario 1 lockstep: speed-up over real time (wall)",
               median(lockstep, "speedup") if lockstep else nan, "×",
               TARGETS["lockstep_speedup"], better="higher"),
        Figure("cpu_s_per_sim_s", "Scenario 1 lockstep: CPU of all processes per sim second",
               cpu_sim, "s",
               note="sampled from the mission's start to each process's exit; every child's "
                    "CPU over the whole run, start-up included, per sim second: "
                    + (f"{median(lockstep, 'children_cpu_s_per_sim_s'):.3f} s"
                       if lockstep else "n/a")),
        Figure("cpu_bound_speedup", f"  speed-up that CPU allows on {cores} cores (ceiling)",
               cores / cpu_sim if cpu_sim > 0 else nan, "×"),
        Figure("lockstep_floor_zenoh", "  floor: the lockstep shape over zenoh, speed-up",
               lockstep_floor.get("zenoh", {}).get("speedup", nan), "×",
               note="Scenario 1's shape with no work: a sim-like process, 3 agent-like "
                    "ones, 2 decimated ones (every 20th frame, staggered) and a listener that "
                    "only records, each answering at once: the wake-ups and the transport "
                    "alone; minimal runtime, FIFO channels, every process scheduled as the "
                    "fleet's ("
                    + lockstep_floor.get("zenoh", {}).get("sched", "?")
                    + "; bench/floor_probe.py --lockstep)"),
        Figure("lockstep_floor_udp", "  floor: the same shape over bare UDP, speed-up",
               lockstep_floor.get("udp", {}).get("speedup", nan), "×"),
        Figure("max_fleet", "largest STL fleet at 100 Hz with ≤ 1 % missed",
               float(max_fleet) if fleets else nan, "robots", TARGETS["max_fleet"],
               better="higher"),
        Figure("fleet_agent_tick_us", f"  CPU per agent tick in that fleet ({max_fleet} robots)",
               agent_tick_us(largest) if largest else nan, "µs"),
        *fleet_floor_figures(fleet_floor),
        *hosts_figures(two_hosts),
        Figure("floor_udp_us", "floor: agent-like echo over bare UDP, CPU per tick",
               fl("udp", "rx_cpu_us"), "µs"),
        Figure("floor_zenoh_us", "  the same over zenoh as configured (minimal runtime)",
               fl("zenoh-minimal", "rx_cpu_us"), "µs"),
        Figure("floor_zenoh_default_us", "  the same over zenoh, default runtime (before)",
               fl("zenoh-default", "rx_cpu_us"), "µs"),
        Figure("floor_zenoh_fifo_us", "  the same, FIFO channel read by the stepping thread",
               fl("zenoh-fifo", "rx_cpu_us"), "µs"),
        Figure("floor_zenoh_inline_us", "  the same, work and answer inside zenoh's callback",
               fl("zenoh-inline", "rx_cpu_us"), "µs"),
    ]
    print(f"runtime_bench: {time.monotonic() - started:.0f} s")
    report("runtime_bench", figures, args.out, load_before=load_before, quick=args.quick,
           extra={"runs": runs,
                  "durations_s": {"realtime": realtime_s, "lockstep": lockstep_s,
                                  "fleet": fleet_s},
                  "latency_histograms_ms": [r["latency_histogram_ms"] for r in realtime],
                  "floor": floor, "floor_beside_realtime": beside,
                  "lockstep_floor": lockstep_floor,
                  "fleet_floor": {str(work): rows for work, rows in fleet_floor.items()},
                  "per_run": {"realtime": realtime, "lockstep": lockstep,
                              "fleets": {str(n): r for n, r in fleets.items()},
                              "two_hosts": {v: {str(n): r for n, r in sizes.items()}
                                            for v, sizes in two_hosts.items()}}})
    return 0


if __name__ == "__main__":
    sys.exit(main())
