"""The fleet size's floor (issue 17 item 5): N agent-like processes over zenoh at 100 Hz.

``bench/floor_probe.py`` measures one agent tick's floor; this measures the fleet's. A sim-like
process publishes, every 10 ms period, one 250-byte frame per slot: ``slots`` keys, slot g at
``g / slots`` of the period (as the simulator's spread frames, architecture.md §3), after spending
``sender_work_us`` of CPU before each (the simulator's per-slot Python: its physics part, poses,
encoding). The defaults are a 30-robot fleet's shape since ``[sim] frame_slots`` = 5: five slots,
and 450 µs a slot, which puts the sender, answers included, at the simulator's share of a core
there, 41–42 % (38–43 % measured; ten slots of 100 µs, rounds 14–17's shape, cost the same).
``n`` receiver processes, receiver i on slot ``slot_of(i, n, slots)`` (consecutive receivers
together, as ``Scenario.frame_offset`` groups robots when a fleet has more of them than ``[sim]
frame_slots``), do what an STL agent's runtime does around its step: a ``FifoChannel`` read by
the main thread, the newest of the queued frames taken, ``work_us`` of CPU
(the agent's decode, step and encode), an answer of 12 bytes on a key of its own. Peers on
loopback, multicast scouting off, the minimal zenoh runtime in every process (each a child of the
caller, whose own environment and zenoh runtime stay as they are), every process under the OS
scheduling a realtime ``tlfleet run`` gives the fleet's (``SCHED_FIFO`` where permitted;
``floor_probe.realtime_sched``): the fleet's transport with nothing of the fleet's code in it.

Measured, as the simulator measures a realtime fleet (``tlfleet.sim.stats``): the latency of each
answer from its frame's publication, and the share of the (receiver, period) deadlines missed
(no answer within one period of the frame); the receivers' CPU per tick (median), the
sender's share of a core, and the machine's idle and steal shares during the run
(``/proc/stat``). With ``work_us`` near 0 it is the floor of the fleet size on this machine:
what zenoh and the wake-ups alone allow; with the agent's measured Python per tick it is what
that Python costs at fleet scale.

    .venv/bin/python bench/fleet_floor.py [--n 30] [--slots 5] [--work-us 30 250]
                                          [--sender-work-us 450] [--seconds 5]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tlfleet.bus.transport import MINIMAL_RUNTIME  # noqa: E402
from tlfleet.cli.process_flags import POLICIES  # noqa: E402

from bench.common import sorted_quantile  # noqa: E402
from bench.floor_probe import (  # noqa: E402
    _busy,
    _config,
    current_policy,
    realtime_sched,
    schedule_role,
)

PERIOD = 0.01  # [s] the mocap period at 100 Hz
FRAME_PAD = b"f" * 242  # with the 8-byte period number: a 250-byte frame
READY_TIMEOUT = 60.0  # [s] for every receiver to start (30 processes importing zenoh)
#: a 30-robot fleet's shape since ``[sim] frame_slots`` = 5: its frame instants a period,
#: and the sender's CPU before each [µs] that puts it at the simulator's share of a core there
SLOTS = 5
SENDER_WORK_US = 450.0


def _cpu_stat() -> list[int]:
    """The machine's CPU time counters (``/proc/stat``'s first line, in clock ticks)."""
    with open("/proc/stat") as f:
        return [int(v) for v in f.readline().split()[1:]]


def _free_port() -> int:
    """A loopback TCP port free at this moment (each run listens on a fresh one: a port just
    closed by the previous run may still be held)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def slot_of(index: int, n: int, slots: int) -> int:
    """The slot of receiver ``index`` of ``n``: ⌊index·slots/n⌋ when ``n`` ≥ ``slots`` (the
    fleet's grouping, ``Scenario.frame_offset``), else ``index``."""
    return index * slots // n if n >= slots else index


def receiver(port: int, index: int, slot: int, work_us: float, seconds: float) -> dict:
    """One agent-like process: answer the newest frame of slot ``slot`` until ``end``."""
    import zenoh

    session = zenoh.open(_config(None, f"tcp/127.0.0.1:{port}"))
    answered = 0
    try:
        pub = session.declare_publisher(f"probe/fleet/cmd/{index}")
        sub = session.declare_subscriber(f"probe/fleet/frame/{slot}",
                                         zenoh.handlers.FifoChannel(64))
        print("ready", flush=True)
        c0 = resource.getrusage(resource.RUSAGE_SELF)
        me = index.to_bytes(4, "little")
        deadline = time.monotonic() + seconds + READY_TIMEOUT + 30.0
        while time.monotonic() < deadline:
            sample = sub.recv()
            newer = sub.try_recv()
            while newer is not None:  # the newest queued frame, as the agent's mailbox
                sample, newer = newer, sub.try_recv()
            payload = sample.payload.to_bytes()
            if payload == b"end":
                break
            _busy(work_us)
            pub.put(payload[:8] + me)
            answered += 1
        c1 = resource.getrusage(resource.RUSAGE_SELF)
    finally:
        session.close()
    cpu = (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)
    return {"answered": answered, "cpu_us_per_tick": 1e6 * cpu / max(answered, 1)}


def sender(port: int, n: int, slots: int, sender_work_us: float, seconds: float) -> dict:
    """The sim-like process: listen, wait for ``go`` on stdin (every receiver connected), publish
    ``seconds`` of periods, then ``end``; the deadlines and latencies of the answers, its own
    CPU and the machine's idle and steal shares over the periods."""
    import zenoh

    periods = round(seconds / PERIOD)
    arrivals: list[tuple[int, int, float]] = []
    lock = threading.Lock()

    def on_answer(sample) -> None:
        wall = time.monotonic()
        payload = sample.payload.to_bytes()
        with lock:
            arrivals.append((int.from_bytes(payload[:8], "little"),
                             int.from_bytes(payload[8:12], "little"), wall))

    session = zenoh.open(_config(f"tcp/127.0.0.1:{port}", None))
    try:
        session.declare_subscriber("probe/fleet/cmd/*", on_answer)
        pubs = [session.declare_publisher(f"probe/fleet/frame/{g}") for g in range(slots)]
        print("listening", flush=True)
        if sys.stdin.readline().strip() != "go":
            raise RuntimeError("fleet floor sender: no go")
        settle = time.monotonic() + 10.0  # every receiver's subscription known here
        while (not all(pub.matching_status.matching for pub in pubs)
               and time.monotonic() < settle):
            time.sleep(0.01)
        time.sleep(0.5)
        published: dict[tuple[int, int], float] = {}
        stat0, own0 = _cpu_stat(), resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.monotonic() + 0.05
        for k in range(periods):
            for g in range(slots):
                due = t0 + (k + g / slots) * PERIOD
                while (left := due - time.monotonic()) > 0.0:
                    time.sleep(left)
                _busy(sender_work_us)
                published[(k, g)] = time.monotonic()
                pubs[g].put(k.to_bytes(8, "little") + FRAME_PAD)
        time.sleep(2 * PERIOD)
        stat1, own1 = _cpu_stat(), resource.getrusage(resource.RUSAGE_SELF)
        for pub in pubs:
            pub.put(b"end")
        time.sleep(0.1)  # the ends on their way before the session closes
    finally:
        session.close()
    with lock:
        got = {(k, i): wall for k, i, wall in arrivals}
    latencies, missed = [], 0
    for k in range(periods):
        for i in range(n):
            wall = got.get((k, i))
            sent = published[(k, slot_of(i, n, slots))]
            if wall is None or wall - sent > PERIOD:
                missed += 1
            if wall is not None:
                latencies.append(1e3 * (wall - sent))
    latencies.sort()
    delta = [b - a for a, b in zip(stat0, stat1, strict=True)]
    total = sum(delta) or 1
    return {
        "periods": periods, "due": periods * n, "missed": missed,
        "missed_fraction": missed / (periods * n),
        "latency_p50_ms": sorted_quantile(latencies, 0.5),
        "latency_p99_ms": sorted_quantile(latencies, 0.99),
        "sender_cpu_pct": 100.0 * ((own1.ru_utime + own1.ru_stime)
                                   - (own0.ru_utime + own0.ru_stime)) / (periods * PERIOD),
        "idle_pct": 100.0 * delta[3] / total,
        "steal_pct": 100.0 * delta[7] / total if len(delta) > 7 else float("nan"),
    }


def _last_json(out: str) -> dict | None:
    lines = [line for line in out.splitlines() if line.startswith("{")]
    return json.loads(lines[-1]) if lines else None


def fleet_probe(n: int = 30, slots: int = SLOTS, work_us: float = 30.0,
                sender_work_us: float = SENDER_WORK_US, seconds: float = 5.0, port: int = 0,
                sched: str | None = None) -> dict:
    """One run: a sender and ``n`` receiver processes (module docstring), all on zenoh's minimal
    runtime and under ``sched`` (None: what a realtime ``tlfleet run`` gives the fleet's); this
    process only starts them and collects what they report."""
    port = port or _free_port()
    sched = sched or realtime_sched()
    env = dict(os.environ, ZENOH_RUNTIME=MINIMAL_RUNTIME)
    common = [sys.executable, __file__, "--port", str(port), "--seconds", str(seconds),
              "--sched", sched]
    tx = subprocess.Popen([*common, "--role", "sender", "--n", str(n), "--slots", str(slots),
                           "--sender-work-us", str(sender_work_us)],
                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    procs: list[subprocess.Popen] = []
    try:
        if tx.stdout is None or tx.stdout.readline().strip() != "listening":
            raise RuntimeError("fleet floor: the sender did not start")
        for i in range(n):
            procs.append(subprocess.Popen(
                [*common, "--role", "receiver", "--index", str(i),
                 "--slot", str(slot_of(i, n, slots)), "--work-us", str(work_us)],
                stdout=subprocess.PIPE, text=True, env=env))
        started = time.monotonic()
        for p in procs:
            line = p.stdout.readline().strip() if p.stdout is not None else ""
            if line != "ready" or time.monotonic() - started > READY_TIMEOUT:
                raise RuntimeError(f"fleet floor: a receiver did not start ({line!r})")
        tx_out, _ = tx.communicate("go\n", timeout=seconds + 60.0)
        result = _last_json(tx_out)
        if result is None:
            raise RuntimeError("fleet floor: the sender reported nothing")
        rows = [row for p in procs if (row := _last_json(p.communicate(timeout=30.0)[0]))]
    finally:
        for p in (tx, *procs):
            if p.poll() is None:
                p.kill()
                p.wait()
    return {
        "n": n, "slots": slots, "work_us": work_us, "sender_work_us": sender_work_us,
        "sched": sched, **result,
        "rx_cpu_us": (statistics.median(r["cpu_us_per_tick"] for r in rows) if rows
                      else float("nan")),
        "receivers_reported": len(rows),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--role", choices=("sender", "receiver"))
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--index", type=int, default=0)
    parser.add_argument("--slot", type=int, default=0)
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--slots", type=int, default=SLOTS)
    parser.add_argument("--work-us", type=float, nargs="+", default=[30.0, 250.0])
    parser.add_argument("--sender-work-us", type=float, default=SENDER_WORK_US)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--sched", choices=POLICIES, default=None,
                        help="OS scheduling of every process (tlfleet.cli.process_flags; "
                             "default: what a realtime `tlfleet run` uses here)")
    args = parser.parse_args(argv)
    if args.role is not None:
        schedule_role(args.sched)
    if args.role == "sender":
        result = sender(args.port, args.n, args.slots, args.sender_work_us, args.seconds)
        result["policy"] = current_policy()
        print(json.dumps(result), flush=True)
        return 0
    if args.role == "receiver":
        print(json.dumps(receiver(args.port, args.index, args.slot, args.work_us[0],
                                  args.seconds)), flush=True)
        return 0
    print(f"load average {os.getloadavg()[0]:.2f}")
    for work in args.work_us:
        row = fleet_probe(args.n, args.slots, work, args.sender_work_us, args.seconds,
                          sched=args.sched)
        print(f"{row['n']} agent-like processes ({row['sched']}), {work:.0f} µs of work each, "
              f"{row['slots']} slots, sender {row['sender_work_us']:.0f} µs a slot: missed "
              f"{100 * row['missed_fraction']:.2f} %, latency p50 {row['latency_p50_ms']:.2f} "
              f"ms p99 {row['latency_p99_ms']:.2f} ms, receiver CPU {row['rx_cpu_us']:.0f} "
              f"µs/tick, sender {row['sender_cpu_pct']:.0f} % of a core, idle "
              f"{row['idle_pct']:.0f} %, steal {row['steal_pct']:.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
