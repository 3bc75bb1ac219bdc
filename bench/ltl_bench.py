"""Benchmark of the LTL planning core (ltl-planning.md §2 and §5). A program, not a test.

Measures, as medians over several runs, CPU time (``time.thread_time``) beside wall time
(``time.perf_counter``), with the load average (``bench.common``):

1. translation time and automaton size for the size-target families (n = 1..8) and for the
   scenarios' formulas;
2. end-to-end planning time (parse + translate + product + search) for every LTL robot of the
   three scenarios with straight-line weights, and **Algorithm 1 as the agent runs it**
   (``tlfleet.agent.runtime.ltl_agent.LtlCore.plan``: the map weights of the global planner, whose
   region-to-region path lengths are computed once per map when the core is built, issue 17
   item 3; target ≤ 5 ms CPU for every robot), plus the same with the map built inside the timing
   (what one ``tlfleet plan`` call pays);
3. a scaling grid: 10, 20, 40 random disc regions × three mission formulas (target for
   ``F r1 & … & F r5`` at 40 regions: ≤ 100 ms; the reference Python implementation P_MAS_TG
   with ltl2ba takes 2.36 s).

4. per formula family — GF-conjunctions n = 1..12, F-conjunctions, sequential
   visits, response patterns, GF of sequential visits, random 6-proposition formulas of size
   20, one formula over 16…64 propositions — states, edges, CPU and wall time; and the state
   counts against Spot 2.9's ``ltl2tgba -B`` from a table of Spot's sizes (``--spot-sizes FILE``,
   when there is one): total ratio, formulas larger than Spot, worst.

Prints a table and writes JSON to ``bench/results/ltl_bench.json``. ``--root DIR`` benchmarks
another checkout (e.g. the code before a change) with this same script.

    .venv/bin/python bench/ltl_bench.py [--quick] [--runs N] [--output PATH] [--root DIR]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
_ROOT_ARG = next((sys.argv[i + 1] for i, a in enumerate(sys.argv[:-1]) if a == "--root"), None)
CODE_ROOT = Path(_ROOT_ARG).resolve() if _ROOT_ARG else ROOT
sys.path.insert(0, str(CODE_ROOT))

from tlfleet.agent.ltl.buchi import translate  # noqa: E402
from tlfleet.agent.ltl.parser import parse  # noqa: E402
from tlfleet.agent.ltl.planner import plan, plan_robot, replan  # noqa: E402
from tlfleet.agent.ltl.transition_system import from_regions, from_scenario  # noqa: E402
from tlfleet.agent.model.scenario import Region  # noqa: E402
from tlfleet.agent.nav.grid_planner import path_length_function  # noqa: E402
from tlfleet.agent.runtime.ltl_agent import LtlCore  # noqa: E402
from tlfleet.agent.scenario import load_scenario  # noqa: E402

from bench.common import Figure, load_average, print_table, time_calls  # noqa: E402

ALGORITHM1_TARGET_MS = 5.0

REFERENCE_SECONDS = {("F r1 & F r2 & F r3 & F r4 & F r5", 40): 2.36, ("G F r1 & G F r2", 40): 0.27}


def median_time(fn: Callable[[], object], runs: int) -> tuple[float, object]:
    """Median wall-clock time [s] of ``fn()`` over ``runs`` runs, and its last result (the
    automaton-size tables; the Algorithm 1 figures use CPU time, ``bench_agent_plans``)."""
    times = []
    result = None
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def families(n: int) -> dict[str, str]:
    chain = f"a{n}"
    for i in range(n - 1, 0, -1):
        chain = f"a{i} & F({chain})"
    return {
        "GF a1 & … & GF an": " & ".join(f"G F a{i}" for i in range(1, n + 1)),
        "F(a1 & F(a2 & … F an))": f"F({chain})",
        "F a1 & … & F an": " & ".join(f"F a{i}" for i in range(1, n + 1)),
        "GF(a1 & F(a2 & … F an))": f"G F({chain})",
    }


def random_regions(count: int, rng: np.random.Generator) -> list[Region]:
    """``count`` non-overlapping disc regions r1..rN (radius 0.25 m) in the 7 m × 7 m arena."""
    centres: list[tuple[float, float]] = []
    while len(centres) < count:
        x, y = rng.uniform(-3.2, 3.2, size=2)
        if all((x - a) ** 2 + (y - b) ** 2 >= 0.6**2 for a, b in centres):
            centres.append((float(x), float(y)))
    return [Region(f"r{i + 1}", c, 0.25) for i, c in enumerate(centres)]


GRID_FORMULAS = (
    "G F r1 & G F r2",
    "F(r1 & F(r2 & F(r3 & F(r4 & F r5))))",
    "F r1 & F r2 & F r3 & F r4 & F r5",
)


def bench_families(max_n: int, runs: int) -> list[dict]:
    rows = []
    for n in range(1, max_n + 1):
        for family, text in families(n).items():
            seconds, buchi = median_time(lambda text=text: translate(text), runs)
            rows.append({"family": family, "n": n, "formula": text, "states": buchi.num_states,
                         "edges": buchi.num_edges, "translate_ms": 1e3 * seconds})
    return rows


def bench_scenarios(runs: int) -> tuple[list[dict], list[dict]]:
    formulas: dict[str, None] = {}
    plans = []
    for i in (1, 2, 3):
        scenario = load_scenario(CODE_ROOT / "scenarios" / f"scenario{i}.toml")
        for robot in sorted(scenario.robots, key=lambda r: r.id):
            if robot.ltl is None:
                continue
            formulas.setdefault(robot.ltl, None)
            seconds, p = median_time(
                lambda s=scenario, r=robot.id: plan_robot(s, r), runs
            )
            plans.append({
                "scenario": scenario.name, "robot": robot.id, "formula": robot.ltl,
                "buchi_states": p.buchi_states, "product_states": p.product_states,
                "product_edges": p.product_edges, "cost": p.cost,
                "prefix": list(p.prefix), "suffix": list(p.suffix),
                "plan_ms": 1e3 * seconds,
            })
    translations = []
    for text in formulas:
        seconds, buchi = median_time(lambda text=text: translate(text), runs)
        translations.append({"formula": text, "states": buchi.num_states,
                             "edges": buchi.num_edges, "translate_ms": 1e3 * seconds})
    return translations, plans


def bench_grid(sizes: list[int], runs: int, seed: int) -> list[dict]:
    rows = []
    for count in sizes:
        rng = np.random.default_rng(seed + count)
        regions = random_regions(count, rng)
        start = (0.0, -3.4)  # on the arena's lower edge, outside every region
        ts = from_regions(regions, start)
        for text in GRID_FORMULAS:
            def end_to_end(text=text, ts=ts):
                return plan(translate(parse(text)), ts, 10.0)

            seconds, p = median_time(end_to_end, runs)
            reference = REFERENCE_SECONDS.get((text, count))
            rows.append({
                "regions": count, "formula": text, "buchi_states": p.buchi_states,
                "product_states": p.product_states, "product_edges": p.product_edges,
                "cost": p.cost, "plan_ms": 1e3 * seconds,
                "reference_ms": 1e3 * reference if reference else None,
            })
    return rows


def cpu_wall(fn: Callable[[], object], runs: int, slow: float = 2.0) -> tuple[float, float, object]:
    """Median CPU and wall time [s] of ``fn()``; a run slower than ``slow`` s is not repeated
    (the code before issue 16 needs ~22 s for GF n = 12). Errors are returned as the result."""
    cpus, walls, result = [], [], None
    for _ in range(runs):
        c0, w0 = time.process_time(), time.perf_counter()
        try:
            result = fn()
        except Exception as exc:  # a benchmark row records the failure
            result = exc
        cpus.append(time.process_time() - c0)
        walls.append(time.perf_counter() - w0)
        if walls[-1] > slow or isinstance(result, Exception):
            break
    return statistics.median(cpus), statistics.median(walls), result


def issue16_families(quick: bool) -> dict[str, list[str]]:
    top = 3 if quick else 12
    def chain(n: int) -> str:
        text = f"a{n}"
        for i in range(n - 1, 0, -1):
            text = f"(a{i} & F({text}))"
        return text
    return {
        "GF a1 & … & GF an": [" & ".join(f"G F a{i}" for i in range(1, n + 1))
                              for n in range(1, top + 1)],
        "F a1 & … & F an": [" & ".join(f"F a{i}" for i in range(1, n + 1))
                            for n in range(1, min(top, 8) + 1)],
        "F(a1 & F(a2 & … F an)) (sequential visits)": [f"F({chain(n)})"
                                                     for n in range(1, top + 1)],
        "G(a1 -> F b1) & … (response)": [" & ".join(f"G(a{i} -> F b{i})" for i in range(1, n + 1))
                                       for n in range(1, min(top, 5) + 1)],
        "GF(a1 & F(a2 & … F an))": [f"G F({chain(n)})" for n in range(1, min(top, 8) + 1)],
    }


def random_formula(rng: np.random.Generator, size: int, atoms: int) -> str:
    """A random formula with ``size`` nodes over p0…p(atoms-1), fully parenthesised (both
    grammars, before and after issue 16, read it the same way)."""
    if size <= 1:
        return f"p{rng.integers(atoms)}" if rng.random() < 0.95 else "true"
    if size == 2 or rng.random() < 0.35:
        op = ["!", "X", "F", "G"][rng.integers(4)]
        return f"{op}({random_formula(rng, size - 1, atoms)})"
    op = ["&", "|", "->", "<->", "U", "R", "W", "M", "xor"][rng.integers(9)]
    left = int(rng.integers(1, size - 1))
    return (f"({random_formula(rng, left, atoms)}) {op} "
            f"({random_formula(rng, size - 1 - left, atoms)})")


def bench_issue16(quick: bool, runs: int, seed: int) -> dict:
    rows = []
    for family, texts in issue16_families(quick).items():
        for n, text in enumerate(texts, 1):
            cpu, wall, b = cpu_wall(lambda text=text: translate(text), runs)
            rows.append(_row(family, n, text, cpu, wall, b))
    rng = np.random.default_rng(seed)
    count = 10 if quick else 100
    randoms = []
    for k in range(count):
        text = random_formula(rng, 20, 6)
        cpu, wall, b = cpu_wall(lambda text=text: translate(text), max(1, runs // 2))
        randoms.append(_row("random size 20, 6 props", k + 1, text, cpu, wall, b))
    props = []
    for n in (16, 20, 40, 64):
        text = "F(" + " & ".join(f"p{i}" for i in range(n)) + ")"
        cpu, wall, b = cpu_wall(lambda text=text: translate(text), runs)
        props.append(_row("F(p0 & … & pn-1)", n, text, cpu, wall, b))
    return {"families": rows, "random": randoms, "propositions": props,
            "random_tail": {"over_target": random_tail(randoms)["over_target"],
                            "target_ms": RANDOM_TARGET_MS}}


RANDOM_TARGET_MS = 100.0
"""Every random 6-proposition formula of size 20 translated within this CPU time."""


def random_tail(randoms: list[dict]) -> dict:
    """The random formulas over :data:`RANDOM_TARGET_MS` (CPU) and the five slowest."""
    slowest = sorted(randoms, key=lambda r: -r["cpu_ms"])[:5]
    return {"over_target": sum(r["cpu_ms"] > RANDOM_TARGET_MS for r in randoms),
            "slowest": slowest}


def _row(family: str, n: int, text: str, cpu: float, wall: float, b: object) -> dict:
    row = {"family": family, "n": n, "formula": text, "cpu_ms": 1e3 * cpu, "wall_ms": 1e3 * wall}
    if isinstance(b, Exception):
        row["error"] = f"{type(b).__name__}: {str(b).splitlines()[0][:120]}"
    else:
        row.update(states=b.num_states, edges=b.num_edges, initial=len(b.initial))
    return row


def bench_spot(path: Path) -> dict | None:
    """Our state counts against Spot's ``ltl2tgba -B`` on the reference table."""
    if not path.is_file():
        return None
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("#") or not line.strip():
            continue
        suite, name, polarity, spot, formula = line.split("\t")
        b = translate(formula)
        rows.append({"suite": suite, "name": name, "polarity": polarity, "spot": int(spot),
                     "states": b.num_states, "initial": len(b.initial), "formula": formula})
    ours = sum(r["states"] for r in rows)
    spot = sum(r["spot"] for r in rows)
    larger = [r for r in rows if r["states"] > r["spot"]]
    worst = sorted(larger, key=lambda r: (r["spot"] - r["states"], r["name"]))[:8]
    suites = {}
    for r in rows:
        s = suites.setdefault(r["suite"], {"formulas": 0, "states": 0, "spot": 0})
        s["formulas"] += 1
        s["states"] += r["states"]
        s["spot"] += r["spot"]
    return {"formulas": len(rows), "states": ours, "spot_states": spot, "ratio": ours / spot,
            "larger": len(larger), "more_than_one_above": sum(
                r["states"] > r["spot"] + 1 for r in rows),
            "worst_excess": max(r["states"] - r["spot"] for r in rows),
            "smaller": sum(r["states"] < r["spot"] for r in rows),
            "several_initial": sum(r["initial"] > 1 for r in rows),
            "worst": worst, "suites": suites, "rows": rows}


def print_issue16(result: dict) -> None:
    data = result["issue16"]
    print("\n== families: states / edges / CPU ms / wall ms")
    for row in data["families"] + data["propositions"]:
        cells = (f"{row['states']:>5} {row['edges']:>6}" if "error" not in row
                 else f"{row['error'][:40]:>12}")
        print(f"{row['family'][:44]:<44} n={row['n']:>2}  {cells} {row['cpu_ms']:>10.2f} "
              f"{row['wall_ms']:>10.2f}")
    randoms = data["random"]
    cpus = sorted(r["cpu_ms"] for r in randoms)
    tail = random_tail(randoms)
    print(f"\n== random formulas (size 20, 6 propositions, {len(randoms)}): median "
          f"{statistics.median(cpus):.2f} ms CPU, max {cpus[-1]:.2f} ms, "
          f"{tail['over_target']} over {RANDOM_TARGET_MS:.0f} ms (target: 0), "
          f"states total {sum(r.get('states', 0) for r in randoms)}")
    for r in tail["slowest"]:
        print(f"   slow: #{r['n']:<3} {r['cpu_ms']:>8.1f} ms CPU {r['wall_ms']:>8.1f} ms wall "
              f"{r.get('states', '-'):>4} states  {r['formula'][:70]}")
    spot = result.get("spot")
    if spot:
        print(f"\n== state counts vs Spot 2.9 ltl2tgba -B ({spot['formulas']} formulas): "
              f"{spot['states']} vs {spot['spot_states']} = {spot['ratio']:.3f}×; "
              f"larger on {spot['larger']}, more than 1 above on "
              f"{spot['more_than_one_above']}, smaller on {spot['smaller']}; "
              f"several initial states on {spot['several_initial']}")
        for name, s in spot["suites"].items():
            print(f"   {name:<12} {s['formulas']:>4} formulas  {s['states']:>5} vs {s['spot']:>5}"
                  f"  = {s['states'] / s['spot']:.3f}×")
        print(f"   per formula, worst vs Spot: {spot['worst_excess']:+d} states "
              "(target: at most +1)")
        for r in spot["worst"]:
            print(f"   worst: {r['name']} {r['polarity']}: {r['states']} vs {r['spot']}")


def bench_agent_plans(runs: int) -> list[dict]:
    """Algorithm 1 on the path the LTL agent uses, for every scenario LTL robot: CPU and wall ms
    with the map weights cached once per map (``LtlCore`` built untimed, as at agent start-up),
    and cold (a fresh ``path_length_function`` inside the timing).

    ``core.plan()`` plans with the automaton the agent translated when it was built, so its
    figure leaves step 1 out; ``full_cpu_ms`` is the whole of Algorithm 1 as at agent start-up
    (the parsed formula translated, then product and search with the cached map weights)."""
    rows = []
    for i in (1, 2, 3):
        scenario = load_scenario(ROOT / "scenarios" / f"scenario{i}.toml")
        for robot in sorted(scenario.robots, key=lambda r: r.id):
            if robot.ltl is None:
                continue
            core = LtlCore(scenario, robot.id)
            plans = []
            warm = time_calls(lambda core=core, plans=plans: plans.append(core.plan()), runs)
            cold = time_calls(lambda s=scenario, r=robot.id: plan_robot(
                s, r, distance=path_length_function(s)), runs)
            p = plans[-1]
            translation = time_calls(lambda text=robot.ltl: translate(text), runs)
            full = time_calls(lambda s=scenario, r=robot.id, d=core.agent.distance: plan_robot(
                s, r, distance=d), runs)
            ts = from_scenario(scenario, robot.id, core.agent.distance)
            again = time_calls(lambda core=core, ts=ts, s=scenario: replan(
                core.buchi, ts, core.agent.initial_region, core.buchi.initial,
                s.ltl.suffix_weight), runs)
            rows.append({
                "scenario": scenario.name, "robot": robot.id, "formula": robot.ltl,
                "cost": p.cost, "prefix": list(p.prefix), "suffix": list(p.suffix),
                "cpu_ms": 1e3 * warm.cpu, "wall_ms": 1e3 * warm.wall,
                "cold_cpu_ms": 1e3 * cold.cpu, "cold_wall_ms": 1e3 * cold.wall,
                "translate_cpu_ms": 1e3 * translation.cpu,
                "full_cpu_ms": 1e3 * full.cpu, "full_wall_ms": 1e3 * full.wall,
                "replan_cpu_ms": 1e3 * again.cpu, "replan_wall_ms": 1e3 * again.wall,
                "translate_ms": 1e3 * p.timings.translate, "product_ms": 1e3 * p.timings.product,
                "search_ms": 1e3 * p.timings.search,
            })
    return rows


def print_tables(result: dict) -> None:
    print("== translation: size-target families — states (bound) / median ms")
    names = list(dict.fromkeys(row["family"] for row in result["families"]))
    short = ["GF a1&…&GF an", "F(a1&F(a2&…))", "F a1&…&F an", "GF(a1&F(a2&…))"]
    print(f"{'n':>2}  " + "  ".join(f"{s:>22}" for s in short))
    for n in sorted({row["n"] for row in result["families"]}):
        cells = []
        for name in names:
            row = next(r for r in result["families"] if r["family"] == name and r["n"] == n)
            bound = 2**n if name.startswith("F a1") else n + 1
            cells.append(f"{row['states']:>4} ({bound:>3}) {row['translate_ms']:>8.3f} ms")
        print(f"{n:>2}  " + "  ".join(f"{c:>22}" for c in cells))
    print("\n== translation: scenario formulas")
    for row in result["scenario_translations"]:
        print(f"{row['formula']:<40} {row['states']:>4} states {row['edges']:>4} edges "
              f"{row['translate_ms']:>8.3f} ms")
    print("\n== end-to-end planning: scenario LTL robots (target <= 5 ms)")
    for row in result["scenario_plans"]:
        print(f"{row['scenario']:<10} robot {row['robot']}  {row['formula']:<36} "
              f"product {row['product_states']:>4}/{row['product_edges']:<5} "
              f"cost {row['cost']:>8.3f}  {row['plan_ms']:>7.3f} ms")
    print("\n== Algorithm 1 as the LTL agent runs it: map weights (cached once per map); "
          "wall split of the last run")
    for row in result["agent_plans"]:
        print(f"{row['scenario']:<10} robot {row['robot']}  {row['formula']:<36} "
              f"CPU {row['cpu_ms']:>7.3f} ms  wall {row['wall_ms']:>7.3f} ms  "
              f"(translate {row['translate_ms']:.2f}, product {row['product_ms']:.2f}, "
              f"search {row['search_ms']:.2f} ms)  translate alone: CPU "
              f"{row['translate_cpu_ms']:.2f} ms  with translation: CPU "
              f"{row['full_cpu_ms']:.2f} ms  replan: CPU {row['replan_cpu_ms']:.2f} ms  "
              f"cold incl. map: CPU {row['cold_cpu_ms']:.2f} ms")
    print("\n== scaling grid: end-to-end planning (target F r1&…&F r5 @ 40 regions <= 100 ms)")
    print(f"{'regions':>7}  {'formula':<38} {'Büchi':>5} {'product':>13} {'ms':>9} "
          f"{'reference':>10}")
    for row in result["grid"]:
        ref = f"{row['reference_ms']:.0f} ms" if row["reference_ms"] else "-"
        print(f"{row['regions']:>7}  {row['formula']:<38} {row['buchi_states']:>5} "
              f"{row['product_states']:>6}/{row['product_edges']:<6} {row['plan_ms']:>9.3f} "
              f"{ref:>10}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small smoke run")
    parser.add_argument("--runs", type=int, default=None, help="runs per measurement (>= 5)")
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--root", type=Path, default=None,
                        help="benchmark the code of another checkout (read before imports)")
    parser.add_argument("--spot-sizes", type=Path,
                        default=ROOT.parent / "shared" / "ltl" / "spot_sizes.tsv",
                        help="Spot's reference sizes (TSV); skipped when missing")
    parser.add_argument("--output", type=Path, default=ROOT / "bench" / "results" /
                        "ltl_bench.json")
    args = parser.parse_args(argv)
    runs = args.runs or (2 if args.quick else 7)
    max_n = 3 if args.quick else 8
    sizes = [10] if args.quick else [10, 20, 40]
    load_before = load_average()
    translations, plans = bench_scenarios(runs)
    agent_plans = bench_agent_plans(max(runs, 3))
    result = {
        "quick": args.quick,
        "runs": runs,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "families": bench_families(max_n, runs),
        "scenario_translations": translations,
        "scenario_plans": plans,
        "agent_plans": agent_plans,
        "grid": bench_grid(sizes, runs, args.seed),
        "code_root": str(CODE_ROOT),
        "issue16": bench_issue16(args.quick, runs, args.seed),
        "spot": None if args.quick else bench_spot(args.spot_sizes),
    }
    print_tables(result)
    print_issue16(result)
    worst = max(agent_plans, key=lambda row: row["cpu_ms"])
    worst_full = max(agent_plans, key=lambda row: row["full_cpu_ms"])
    figures = [
        Figure("algorithm1_ms", f"Algorithm 1, agent path, worst robot ({worst['scenario']} "
               f"robot {worst['robot']}), automaton kept", worst["cpu_ms"], "ms",
               ALGORITHM1_TARGET_MS, wall=worst["wall_ms"],
               note=f"translating the formula alone (text): {worst['translate_cpu_ms']:.2f} "
                    "ms CPU"),
        Figure("algorithm1_full_ms", f"  the same with step 1, the translation ("
               f"{worst_full['scenario']} robot {worst_full['robot']})",
               worst_full["full_cpu_ms"], "ms", ALGORITHM1_TARGET_MS,
               wall=worst_full["full_wall_ms"]),
        Figure("replan_ms", "  steps 2-4 only (the agent's replan: automaton kept)",
               worst["replan_cpu_ms"], "ms", wall=worst["replan_wall_ms"]),
        Figure("algorithm1_cold_ms", "the same, map weights computed inside the timing",
               worst["cold_cpu_ms"], "ms", wall=worst["cold_wall_ms"]),
    ]
    randoms = result["issue16"]["random"]
    slowest = random_tail(randoms)["slowest"][0]
    figures += [
        Figure("random_max_ms", f"random size-20 formulas, slowest of {len(randoms)} "
               f"(#{slowest['n']})", slowest["cpu_ms"], "ms", RANDOM_TARGET_MS,
               wall=slowest["wall_ms"]),
        Figure("random_over_target", f"random formulas over {RANDOM_TARGET_MS:g} ms CPU",
               random_tail(randoms)["over_target"], "formulas", 0),
    ]
    if result["spot"]:
        figures += [
            Figure("spot_ratio", "total states vs Spot's ltl2tgba -B", result["spot"]["ratio"],
                   "x", 1.0),
            Figure("spot_worst_excess", "worst formula: states above Spot's",
                   result["spot"]["worst_excess"], "states", 1),
        ]
    load_after = load_average()
    print()
    print_table("ltl_bench", figures, load_before, load_after)
    result.update(load_average_before=list(load_before), load_average_after=list(load_after),
                  figures=[{**vars(f), "met": f.met} for f in figures],
                  results={f.key: f.value for f in figures},
                  targets={f.key: f.target for f in figures if f.target is not None},
                  meets_targets={f.key: f.met for f in figures if f.target is not None})
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(f"\nwrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
