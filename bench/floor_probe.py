"""The physical floor of one agent tick (issue 17 item 5): an agent-like echo at 100 Hz.

A sender process publishes a 250-byte payload every 10 ms (like the sim's mocap frame); a receiver
process takes it, spends ``--work-us`` of CPU (like decode + step + encode) and answers with a
40-byte payload (like a command). What is measured, per variant, median over ``--runs`` runs:

* ``rx_cpu_us``: CPU time (user + system, every thread) of the receiver process per tick —
  what one agent process costs the machine per frame, the figure the fleet size depends on;
* ``rtt_p50_us`` / ``rtt_p99_us``: sender-side round trip (frame out → answer in), wall clock.

Variants: ``udp`` (a blocking ``recv`` on a bare UDP socket: the floor for a Python process woken
100 times a second), ``udp-relay`` (the same through a third process that forwards every
datagram, as the router forwards a realtime fleet's frames and commands: the round trip has the
fleet's shape, sim → router → agent → router → sim, with nothing but the wake-ups and 30 µs of
work in it, so its p99 is the floor of the fleet's frame → command latency on this machine),
``zenoh-default`` (today's agent pattern before issue 17: a Python callback thread per
subscriber hands the payload to the main thread through a condition variable, zenoh's default
runtime), ``zenoh-minimal`` (the same with ``tlfleet.bus.transport.MINIMAL_RUNTIME``),
``zenoh-direct`` (minimal runtime, ``Callback(indirect=False)``: the callback runs on zenoh's
thread), ``zenoh-fifo`` (minimal runtime, a ``FifoChannel`` read by the main thread with a
blocking ``recv``: the agents' pattern), ``zenoh-inline`` (minimal runtime, the work and the
answer inside a ``Callback(indirect=False)`` on zenoh's own thread: no Python thread is woken
at all; measured in round 13 at 0.86–0.89× the FIFO pattern's CPU, not adopted, see
docs/performance.md). Zenoh variants run peer to peer on loopback (multicast scouting off).
Every process runs under the OS scheduling a realtime ``tlfleet run`` gives the fleet's
(:func:`realtime_sched`: ``SCHED_FIFO`` where permitted), so the latency floor and the fleet's
latency are measured alike.

**The lockstep floor** (:func:`lockstep_probe`): the lockstep fleet's shape with nothing of the
fleet's own in it. A sim-like process publishes a frame to ``agents`` agent-like processes and
one listener (the coordinator's recorder, which records every frame but answers none), waits
for every agent's answer, spends ``sim_work_us`` (the simulator's world tick, commands and
encoding), and publishes the next frame at once; each agent spends ``work_us`` per frame. The
frames per wall second over the mocap rate (100 Hz) are the speed-up that shape allows on this
machine at this moment: over bare UDP (``udp``: the wake-ups alone) and over zenoh as the fleet
runs it (``zenoh``: peers on loopback, minimal runtime, FIFO channels read by the stepping
thread). With 0 µs of work it is the round trip of the wake-ups alone. ``ltl_agents`` adds
decimated agent-like processes (the LTL agents: ``ltl_work_us`` every ``divider``-th frame, at
staggered phases, each on a key of its own as ``mocap_every``), whose ticks the sender waits
for too. Its processes run under the OS scheduling a lockstep ``tlfleet run`` gives the fleet's
(``sched``, default :func:`lockstep_sched`: ``SCHED_FIFO`` where permitted, else
``SCHED_BATCH``; ``tlfleet.cli.process_flags``), so the floor and the fleet are scheduled alike.

    .venv/bin/python bench/floor_probe.py [--runs 3] [--seconds 3]
    .venv/bin/python bench/floor_probe.py --lockstep [--work-us 100] [--sim-work-us 150]
                                          [--ltl-agents 2] [--ltl-work-us 1000]
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
from tlfleet.cli.process_flags import POLICIES, apply_scheduling  # noqa: E402

from bench.common import sorted_quantile  # noqa: E402

VARIANTS = ("udp", "udp-relay", "zenoh-default", "zenoh-minimal", "zenoh-direct", "zenoh-fifo",
            "zenoh-inline")
FRAME = b"f" * 250
ANSWER = b"c" * 40


def _busy(us: float) -> None:
    end = time.thread_time() + us * 1e-6
    while time.thread_time() < end:
        pass


def _config(listen: str | None, connect: str | None):
    import zenoh

    c = zenoh.Config()
    c.insert_json5("mode", '"peer"')
    c.insert_json5("listen/endpoints", json.dumps([listen] if listen else []))
    c.insert_json5("connect/endpoints", json.dumps([connect] if connect else []))
    c.insert_json5("scouting/multicast/enabled", "false")
    return c


def receiver(variant: str, port: int, ticks: int, work_us: float,
             key: str = "probe/frame") -> dict:
    """Answer ``ticks`` frames (zenoh: on ``key``); return CPU per tick of this process."""
    done = 0
    if variant in ("udp", "udp-relay"):
        rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        rx.bind(("127.0.0.1", port + 1))
        rx.settimeout(10.0)
        print("ready", flush=True)
        c0 = resource.getrusage(resource.RUSAGE_SELF)
        while done < ticks:
            _frame, source = rx.recvfrom(2048)
            _busy(work_us)
            rx.sendto(ANSWER, source)  # the sender, or the relay that forwarded the frame
            done += 1
    else:
        import zenoh

        session = zenoh.open(_config(f"tcp/127.0.0.1:{port}", None))
        pub = session.declare_publisher("probe/cmd")
        try:
            if variant == "zenoh-fifo":
                sub = session.declare_subscriber(key, zenoh.handlers.FifoChannel(16))
                print("ready", flush=True)
                c0 = resource.getrusage(resource.RUSAGE_SELF)
                while done < ticks:  # zenoh is reliable: the sender's frames all arrive
                    sample = sub.recv()
                    sample.payload.to_bytes()
                    _busy(work_us)
                    pub.put(ANSWER)
                    done += 1
            elif variant == "zenoh-inline":
                finished = threading.Event()

                def on_frame(sample) -> None:
                    nonlocal done
                    sample.payload.to_bytes()
                    _busy(work_us)
                    pub.put(ANSWER)
                    done += 1
                    if done >= ticks:
                        finished.set()

                session.declare_subscriber(key, zenoh.handlers.Callback(on_frame,
                                                                        indirect=False))
                print("ready", flush=True)
                c0 = resource.getrusage(resource.RUSAGE_SELF)
                finished.wait(ticks * 0.01 + 10.0)
            else:
                cond = threading.Condition()
                box: list[bytes] = []

                def on_sample(sample) -> None:
                    with cond:
                        box.append(sample.payload.to_bytes())
                        cond.notify_all()

                handler = (zenoh.handlers.Callback(on_sample, indirect=False)
                           if variant == "zenoh-direct" else on_sample)
                session.declare_subscriber(key, handler)
                print("ready", flush=True)
                c0 = resource.getrusage(resource.RUSAGE_SELF)
                quiet = time.monotonic() + 10.0
                while done < ticks and time.monotonic() < quiet:
                    with cond:
                        if not box:
                            cond.wait(0.5)
                        got = len(box)
                        box.clear()
                    if not got:
                        continue
                    quiet = time.monotonic() + 3.0  # the sender is done when frames stop
                    _busy(work_us)  # frames that arrived together are answered once, as the
                    pub.put(ANSWER)  # agent's latest-frame mailbox does
                    done += got
        finally:
            c1 = resource.getrusage(resource.RUSAGE_SELF)
            session.close()
        cpu = (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)
        return {"ticks": done, "cpu_us_per_tick": 1e6 * cpu / max(done, 1)}
    c1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (c1.ru_utime + c1.ru_stime) - (c0.ru_utime + c0.ru_stime)
    return {"ticks": done, "cpu_us_per_tick": 1e6 * cpu / max(done, 1)}


def sender(variant: str, port: int, ticks: int, ready) -> list[float]:
    """Send ``ticks`` frames at 100 Hz; the round trips [µs]."""
    rtts: list[float] = []
    period = 0.01
    if variant in ("udp", "udp-relay"):
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        tx.bind(("127.0.0.1", port))
        tx.settimeout(0.5)
        ready()
        to = port + 2 if variant == "udp-relay" else port + 1
        next_t = time.perf_counter()
        for _ in range(ticks):
            sent = time.perf_counter()
            tx.sendto(FRAME, ("127.0.0.1", to))
            try:
                tx.recvfrom(2048)
                rtts.append(1e6 * (time.perf_counter() - sent))
            except TimeoutError:
                pass
            next_t += period
            time.sleep(max(0.0, next_t - time.perf_counter()))
        return rtts
    import zenoh

    session = zenoh.open(_config(None, f"tcp/127.0.0.1:{port}"))
    try:
        sub = session.declare_subscriber("probe/cmd", zenoh.handlers.FifoChannel(64))
        pub = session.declare_publisher("probe/frame")
        ready()
        deadline = time.monotonic() + 10.0
        while not pub.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)
        next_t = time.perf_counter()
        for _ in range(ticks):
            sent = time.perf_counter()
            pub.put(FRAME)
            wait_until = time.monotonic() + 0.5
            while time.monotonic() < wait_until:
                if sub.try_recv() is not None:
                    rtts.append(1e6 * (time.perf_counter() - sent))
                    break
                time.sleep(0.00005)
            next_t += period
            time.sleep(max(0.0, next_t - time.perf_counter()))
    finally:
        session.close()
    return rtts


def listener(transport: str, port: int) -> None:
    """Lockstep probe: receive every frame, answer none (the recorder), until killed."""
    if transport == "udp":
        rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        rx.bind(("127.0.0.1", port + 1))
        print("ready", flush=True)
        while True:
            rx.recvfrom(2048)
    import zenoh

    session = zenoh.open(_config(f"tcp/127.0.0.1:{port}", None))
    sub = session.declare_subscriber("probe/frame", zenoh.handlers.FifoChannel(1024))
    print("ready", flush=True)
    while True:
        sub.recv().payload.to_bytes()


def ltl_phases(n: int, divider: int) -> list[int]:
    """The decimated agents' phases, spread over the period as the fleet's LTL agents are
    (architecture.md §3: φ = ⌊rank·d/n⌋)."""
    return [rank * divider // n for rank in range(n)]


def lockstep_sender(transport: str, ports: list[int], agents: int, ticks: int,
                    sim_work_us: float, ltl_ports: list[int] = (), divider: int = 20) -> dict:
    """Publish a frame, wait for the due agents' answers, spend ``sim_work_us``; ``ticks``
    times (after a warm-up that waits until every agent answers). ``ports``: the every-tick
    agents' then the listener's; ``ltl_ports``: decimated agents, due every ``divider`` frames at
    their phase (zenoh: each reads its own key ``probe/every/<phase>``, as the LTL agents read
    ``mocap_every``). Returns frames per wall second and this process's CPU per frame."""
    warm = 200
    phases = ltl_phases(len(ltl_ports), divider)
    if transport == "udp":
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        tx.bind(("127.0.0.1", 0))
        tx.settimeout(2.0)
        targets = [("127.0.0.1", p + 1) for p in ports]
        decimated = [("127.0.0.1", p + 1) for p in ltl_ports]

        def put(k: int) -> int:
            for target in targets:
                tx.sendto(FRAME, target)
            due = 0
            for target, phase in zip(decimated, phases, strict=True):
                if k % divider == phase:
                    tx.sendto(FRAME, target)
                    due += 1
            return due

        def answer() -> None:
            tx.recvfrom(2048)
    else:
        import zenoh

        config = _config(None, None)
        config.insert_json5("connect/endpoints",
                            json.dumps([f"tcp/127.0.0.1:{p}" for p in (*ports, *ltl_ports)]))
        session = zenoh.open(config)
        sub = session.declare_subscriber("probe/cmd", zenoh.handlers.FifoChannel(64))
        pub = session.declare_publisher("probe/frame")
        every = [session.declare_publisher(f"probe/every/{phase}") for phase in phases]

        def put(k: int) -> int:
            pub.put(FRAME)
            due = 0
            for publisher, phase in zip(every, phases, strict=True):
                if k % divider == phase:
                    publisher.put(FRAME)
                    due += 1
            return due

        def answer() -> None:
            sub.recv()

        # every agent subscribed: a frame on every key answered by all (bounded: 10 s)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            pub.put(FRAME)
            for publisher in every:
                publisher.put(FRAME)
            time.sleep(0.2)
            got = 0
            while sub.try_recv() is not None:
                got += 1
            if got >= agents + len(every):
                break
        else:
            raise RuntimeError("lockstep probe: not every agent answered within 10 s")
    for k in range(warm + ticks):
        if k == warm:
            started = time.perf_counter()
            c0 = time.process_time()
        due = put(k)
        for _ in range(agents + due):
            answer()
        _busy(sim_work_us)
    wall = time.perf_counter() - started
    cpu = time.process_time() - c0
    if transport != "udp":
        session.close()
    return {"frames_per_s": ticks / wall, "sender_cpu_us": 1e6 * cpu / ticks}


def lockstep_sched() -> str:
    """The ``--sched`` a lockstep ``tlfleet run`` gives its processes here (``auto``)."""
    return _run_sched("lockstep")


def realtime_sched() -> str:
    """The ``--sched`` a realtime ``tlfleet run`` gives its processes here (``auto``)."""
    return _run_sched("realtime")


def _run_sched(mode: str) -> str:
    from tlfleet.coordinator.run import RunConfig, child_sched

    return child_sched(RunConfig(Path("-"), mode=mode))


def schedule_role(sched: str | None) -> None:
    """A probe's child process takes ``--sched`` (``tlfleet.cli.process_flags``), saying why it
    could not; the policy it then runs under is :func:`current_policy`."""
    if sched is not None:
        problem = apply_scheduling(sched)
        if problem:
            print(f"--sched {sched}: {problem}", file=sys.stderr)


def current_policy() -> int:
    """This process's OS scheduling policy (``os.SCHED_*``; -1 where the OS has none)."""
    return os.sched_getscheduler(0) if hasattr(os, "sched_getscheduler") else -1


def lockstep_probe(runs: int = 3, seconds: float = 3.0, agents: int = 3,
                   work_us: float = 100.0, sim_work_us: float = 150.0,
                   transports: tuple[str, ...] = ("udp", "zenoh"), base_port: int = 0,
                   ltl_agents: int = 0, ltl_work_us: float = 1000.0, divider: int = 20,
                   sched: str | None = None) -> dict[str, dict]:
    """The lockstep floor (module docstring): per transport, the median over ``runs`` of the
    frames per second and the speed-up over 100 Hz; the run lasts about ``seconds`` at 10×.
    ``ltl_agents`` decimated agents (``ltl_work_us`` per frame, due every ``divider`` frames,
    staggered) add the LTL agents' shape; every process runs under ``sched`` (None: the
    fleet's, :func:`lockstep_sched`)."""
    sched = sched or lockstep_sched()
    port = base_port or (20000 + (os.getpid() * 7) % 20000)
    ticks = int(seconds * 1000)
    out: dict[str, dict] = {}
    for transport in transports:
        rows = []
        for _ in range(max(1, runs)):
            ports = [port + 3 * i for i in range(agents + 1 + ltl_agents)]
            port += 3 * len(ports)
            rows.append(_lockstep_once(transport, ports, agents, ticks, work_us, sim_work_us,
                                       ltl_agents, ltl_work_us, divider, sched))
        ok = [r for r in rows if "error" not in r] or rows
        fps = statistics.median(r["frames_per_s"] for r in ok)
        out[transport] = {"frames_per_s": fps, "speedup": fps / 100.0,
                          "sender_cpu_us": statistics.median(r["sender_cpu_us"] for r in ok),
                          "agents": agents, "work_us": work_us, "sim_work_us": sim_work_us,
                          "ltl_agents": ltl_agents, "ltl_work_us": ltl_work_us,
                          "divider": divider, "sched": sched, "runs": rows}
    return out


def _lockstep_once(transport: str, ports: list[int], agents: int, ticks: int,
                   work_us: float, sim_work_us: float, ltl_agents: int = 0,
                   ltl_work_us: float = 0.0, divider: int = 20, sched: str = "default") -> dict:
    """One lockstep probe: ``ports`` are the every-tick agents', the listener's, then the
    decimated agents'."""
    env = dict(os.environ)
    env.pop("ZENOH_RUNTIME", None)
    if transport == "zenoh":
        env["ZENOH_RUNTIME"] = MINIMAL_RUNTIME
    variant = "udp" if transport == "udp" else "zenoh-fifo"
    started: list[subprocess.Popen] = []
    nan = float("nan")
    try:
        phases = ltl_phases(ltl_agents, divider)
        for i, p in enumerate(ports):  # the agents answer (far more frames than sent)
            if i == agents:
                role = ["--role", "listener"]  # only listens
            elif i < agents:
                role = ["--role", "receiver", "--work-us", str(work_us)]
            else:
                role = ["--role", "receiver", "--work-us", str(ltl_work_us),
                        "--key", f"probe/every/{phases[i - agents - 1]}"]
            started.append(subprocess.Popen(
                [sys.executable, __file__, "--variant", variant, "--port", str(p),
                 "--ticks", str(10 * ticks + 10_000), "--sched", sched, *role],
                stdout=subprocess.PIPE, text=True, env=env))
            if started[-1].stdout is None or started[-1].stdout.readline().strip() != "ready":
                return {"frames_per_s": nan, "sender_cpu_us": nan, "error": "did not start"}
        tx = subprocess.run([sys.executable, __file__, "--role", "lockstep-sender",
                             "--variant", variant, "--ports", *map(str, ports[:agents + 1]),
                             "--ltl-ports", *map(str, ports[agents + 1:]),
                             "--divider", str(divider), "--sched", sched,
                             "--agents", str(agents), "--ticks", str(ticks),
                             "--sim-work-us", str(sim_work_us)],
                            capture_output=True, text=True, env=env, timeout=60 + ticks / 100)
        if tx.returncode != 0:
            return {"frames_per_s": nan, "sender_cpu_us": nan, "error": tx.stderr[-500:]}
        return json.loads(tx.stdout.strip().splitlines()[-1])
    except subprocess.TimeoutExpired:
        return {"frames_per_s": nan, "sender_cpu_us": nan, "error": "timed out"}
    finally:
        for p in started:
            p.kill()
            p.wait()


def relay(port: int, ticks: int) -> None:
    """``udp-relay``: forward the sender's frames (from ``port``) to the receiver (``port + 1``)
    and the receiver's answers back, on ``port + 2``, until ``ticks`` answers or 3 s of quiet."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", port + 2))
    sock.settimeout(3.0)
    sender_at, receiver_at = ("127.0.0.1", port), ("127.0.0.1", port + 1)
    print("ready", flush=True)
    answers = 0
    while answers < ticks:
        try:
            data, source = sock.recvfrom(2048)
        except TimeoutError:
            return
        if source == receiver_at:
            sock.sendto(data, sender_at)
            answers += 1
        else:
            sock.sendto(data, receiver_at)


def run_pair(variant: str, port: int, seconds: float, work_us: float,
             sched: str = "default") -> dict:
    """One sender (this process's child) and one receiver process (and the relay between
    them for ``udp-relay``), each under ``sched`` (``tlfleet.cli.process_flags``)."""
    ticks = int(seconds * 100)
    env = dict(os.environ)
    env.pop("ZENOH_RUNTIME", None)
    if not variant.startswith("udp") and variant != "zenoh-default":
        env["ZENOH_RUNTIME"] = MINIMAL_RUNTIME
    common = [sys.executable, __file__, "--variant", variant, "--port", str(port),
              "--ticks", str(ticks), "--work-us", str(work_us), "--sched", sched]
    # the receiver binds (UDP) or listens (zenoh) first, then the relay; the sender starts once
    # they are ready
    started = []
    for role in ("receiver", "relay") if variant == "udp-relay" else ("receiver",):
        started.append(subprocess.Popen([*common, "--role", role], stdout=subprocess.PIPE,
                                        text=True, env=env))
        if started[-1].stdout is None or started[-1].stdout.readline().strip() != "ready":
            for p in started:
                p.kill()
                p.wait()
            raise RuntimeError(f"floor probe {role} ({variant}) did not start")
    rx = started[0]
    tx = subprocess.Popen([*common, "--role", "sender"], stdout=subprocess.PIPE, text=True,
                          env=env)
    nan = float("nan")
    try:
        rx_out, _ = rx.communicate(timeout=seconds + 30)
        tx_out, _ = tx.communicate(timeout=seconds + 30)
    except subprocess.TimeoutExpired:
        return {"rx_cpu_us": nan, "ticks": 0, "answered": 0, "rtt_p50_us": nan,
                "rtt_p99_us": nan, "error": "timed out"}
    finally:
        for p in (*started, tx):
            if p.poll() is None:
                p.kill()
                p.wait()
    rx_data = json.loads(rx_out.strip().splitlines()[-1])
    rtts = json.loads(tx_out.strip().splitlines()[-1])["rtt_us"]
    rtts.sort()
    return {"rx_cpu_us": rx_data["cpu_us_per_tick"], "ticks": rx_data["ticks"],
            "answered": len(rtts), "policy": rx_data.get("policy"),
            "rtt_p50_us": sorted_quantile(rtts, 0.5),
            "rtt_p99_us": sorted_quantile(rtts, 0.99)}


PORT_ATTEMPTS = 3  # ports tried per run: the probe's range overlaps the ephemeral ports


def _pair_on_a_free_port(variant: str, port: int, seconds: float, work_us: float,
                         sched: str = "default") -> dict:
    """``run_pair`` from ``port``, the next ports when a receiver cannot listen (a port the OS
    gave a fleet's connection meanwhile); after :data:`PORT_ATTEMPTS` an error row (its figures
    nan), so one busy port does not end a benchmark of minutes."""
    for attempt in range(PORT_ATTEMPTS):
        try:
            return run_pair(variant, port + 3 * attempt, seconds, work_us, sched)
        except RuntimeError as exc:
            problem = str(exc)
    nan = float("nan")
    return {"rx_cpu_us": nan, "ticks": 0, "answered": 0, "rtt_p50_us": nan, "rtt_p99_us": nan,
            "error": f"{problem} on {PORT_ATTEMPTS} ports from {port}"}


def probe(runs: int = 3, seconds: float = 3.0, work_us: float = 30.0,
          variants: tuple[str, ...] = VARIANTS, base_port: int = 0,
          sched: str | None = None) -> dict[str, dict]:
    """Medians per variant (see the module docstring); every process runs under ``sched``
    (None: what a realtime ``tlfleet run`` gives the fleet's, :func:`realtime_sched`)."""
    sched = sched or realtime_sched()
    port = base_port or (20000 + os.getpid() % 20000)
    out: dict[str, dict] = {}
    for variant in variants:
        rows = []
        for _ in range(max(1, runs)):
            rows.append(_pair_on_a_free_port(variant, port, seconds, work_us, sched))
            port += 3 * PORT_ATTEMPTS  # sender, receiver, relay per attempt
        ok = [r for r in rows if "error" not in r] or rows
        out[variant] = {key: statistics.median(r[key] for r in ok)
                        for key in ("rx_cpu_us", "rtt_p50_us", "rtt_p99_us")}
        out[variant]["runs"] = rows
        out[variant]["sched"] = sched
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--role", choices=("sender", "receiver", "relay", "listener",
                                           "lockstep-sender"))
    parser.add_argument("--variant", choices=VARIANTS)
    parser.add_argument("--port", type=int, default=0)
    parser.add_argument("--ticks", type=int, default=300)
    parser.add_argument("--work-us", type=float, default=30.0)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--ports", type=int, nargs="*", default=[])
    parser.add_argument("--ltl-ports", type=int, nargs="*", default=[])
    parser.add_argument("--divider", type=int, default=20)
    parser.add_argument("--key", default="probe/frame")
    parser.add_argument("--agents", type=int, default=3)
    parser.add_argument("--sim-work-us", type=float, default=150.0)
    parser.add_argument("--ltl-agents", type=int, default=2,
                        help="--lockstep: decimated agents (every 20th frame, staggered)")
    parser.add_argument("--ltl-work-us", type=float, default=1000.0)
    parser.add_argument("--lockstep", action="store_true",
                        help="the lockstep floor (lockstep_probe) instead of the echo variants")
    parser.add_argument("--sched", choices=POLICIES, default=None,
                        help="OS scheduling of every process of the probe "
                             "(tlfleet.cli.process_flags; default: what `tlfleet run` uses here, "
                             "realtime for the echo variants, lockstep with --lockstep)")
    args = parser.parse_args(argv)
    if args.role is not None:
        schedule_role(args.sched)
    transport = "udp" if args.variant in ("udp", "udp-relay") else "zenoh"
    if args.role == "listener":
        listener(transport, args.port)
        return 0
    if args.role == "lockstep-sender":
        result = lockstep_sender(transport, args.ports, args.agents, args.ticks,
                                 args.sim_work_us, args.ltl_ports, args.divider)
        result["policy"] = current_policy()
        print(json.dumps(result))
        return 0
    if args.lockstep:
        print(f"load average {os.getloadavg()[0]:.2f}")
        agent_work = args.work_us if args.work_us != 30.0 else 100.0  # (30: the echo's)
        for work, sim_work, ltl in ((agent_work, args.sim_work_us, 0),
                                    (agent_work, args.sim_work_us, args.ltl_agents),
                                    (0.0, 0.0, 0)):
            result = lockstep_probe(args.runs, args.seconds, args.agents, work, sim_work,
                                    ltl_agents=ltl, ltl_work_us=args.ltl_work_us,
                                    sched=args.sched)
            for name, row in result.items():
                print(f"lockstep {name:<6} ({row['sched']}) {args.agents} agents ({work:.0f} µs), "
                      f"{ltl} LTL-like ({row['ltl_work_us']:.0f} µs every "
                      f"{row['divider']}th), sim {sim_work:.0f} µs: "
                      f"{row['frames_per_s']:7.0f} frames/s = {row['speedup']:5.2f}× real time")
        return 0
    if args.role == "receiver":
        result = receiver(args.variant, args.port, args.ticks, args.work_us, args.key)
        result["policy"] = current_policy()
        print(json.dumps(result))
        return 0
    if args.role == "relay":
        relay(args.port, args.ticks)
        return 0
    if args.role == "sender":
        rtts = sender(args.variant, args.port, args.ticks, lambda: None)
        print(json.dumps({"rtt_us": rtts}))
        return 0
    result = probe(args.runs, args.seconds, args.work_us, sched=args.sched)
    print(f"load average {os.getloadavg()[0]:.2f}; every process under --sched "
          f"{next(iter(result.values()))['sched']}")
    for variant, row in result.items():
        print(f"{variant:<14} receiver CPU {row['rx_cpu_us']:7.0f} µs/tick   round trip p50 "
              f"{row['rtt_p50_us']:7.0f} µs  p99 {row['rtt_p99_us']:7.0f} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
