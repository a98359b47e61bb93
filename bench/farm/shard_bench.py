#!/usr/bin/env python3
"""Sharded precompute against one machine (docs/farm.md "Figures").

Runs `lightlink precompute SCENE` once, then for each N the N shards `--shard I/N` one after
another (each alone on the machine, as on N nodes) and `lightlink merge`, and checks that the
merged artifact is byte-identical to the single run's. Per run it records the wall time and
the CPU time (user + sys of the child, from wait4), and from each shard's report the seconds of
its link stage and of everything else (the stages every shard repeats).

Printed per N: the single run's wall and CPU time, the sum of the shards' CPU times and its
overhead over the single run (the stages every shard repeats), the slowest shard's and the
merge's CPU time, and the projected wall time on N nodes: the shards run at once, the merge
after them, so single wall x (slowest shard CPU + merge CPU) / single CPU, i.e. each node as
parallel as the single run was. The speed-up is single CPU / (slowest shard + merge CPU).
A CSV of every run and a JSON summary go to --out.

usage: bench/farm/shard_bench.py --lightlink build/clients/lightlink --scene SCENE [--shards 1,2,4,8]
                                 [--out DIR] [--subdivide K] [-- PRECOMPUTE_OPTIONS...]
"""
import argparse
import csv
import filecmp
import json
import os
import platform
import subprocess
import sys
import time


def run(cmd):
    """Runs cmd, returns (wall seconds, cpu seconds); raises on a non-zero exit."""
    start = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.monotonic() - start
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        sys.exit(f"shard_bench: {' '.join(cmd)} exited {code}:\n{err}")
    return wall, usage.ru_utime + usage.ru_stime


def stage_split(report_path):
    """(link seconds, other stages' seconds) from a precompute report."""
    seconds = json.load(open(report_path))["seconds"]
    links = seconds.get("links", 0.0)
    return links, seconds["total"] - links


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lightlink", required=True)
    ap.add_argument("--scene", required=True)
    ap.add_argument("--shards", default="1,2,4,8")
    ap.add_argument("--out", default="shard_bench_out")
    ap.add_argument("--subdivide", type=int, default=0)
    ap.add_argument("options", nargs="*", help="precompute options (after --), e.g. --preset medium")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    base = [a.lightlink, "precompute", a.scene, "-q"] + a.options
    if a.subdivide:
        base += ["--subdivide", str(a.subdivide)]

    single = os.path.join(a.out, "single.llk")
    single_report = os.path.join(a.out, "single.json")
    wall1, cpu1 = run(base + ["-o", single, "--report", single_report])
    links1, other1 = stage_split(single_report)
    print(f"single machine: wall {wall1:.2f} s, cpu {cpu1:.2f} s (links {links1:.2f} s, other stages {other1:.2f} s)",
          flush=True)

    rows, summary = [], []
    for n in [int(x) for x in a.shards.split(",")]:
        parts, shard_walls, shard_cpus, shard_links, shard_other = [], [], [], [], []
        for i in range(n):
            part = os.path.join(a.out, f"part_{i}of{n}.llkpart")
            report = os.path.join(a.out, f"part_{i}of{n}.json")
            wall, cpu = run(base + ["--shard", f"{i}/{n}", "-o", part, "--report", report])
            links, other = stage_split(report)
            parts.append(part)
            shard_walls.append(wall)
            shard_cpus.append(cpu)
            shard_links.append(links)
            shard_other.append(other)
            rows.append({"n": n, "run": f"shard {i}", "wall_s": wall, "cpu_s": cpu, "links_s": links,
                         "other_stages_s": other, "bytes": os.path.getsize(part)})
        merged = os.path.join(a.out, f"merged_{n}.llk")
        mwall, mcpu = run([a.lightlink, "merge", *parts, "-o", merged, "-q"])
        identical = filecmp.cmp(single, merged, shallow=False)
        rows.append({"n": n, "run": "merge", "wall_s": mwall, "cpu_s": mcpu, "links_s": 0, "other_stages_s": 0,
                     "bytes": os.path.getsize(merged)})
        for p in parts:
            os.remove(p)
        os.remove(merged)
        # Projected on N nodes from CPU times: the slowest shard then the merge, each at the
        # single run's parallel efficiency (wall / CPU). Wall times measured on a machine that
        # others share swing by 2x and more; CPU times far less (both are in the CSV).
        critical_cpu = max(shard_cpus) + mcpu
        projected = wall1 * critical_cpu / cpu1
        s = {"n": n, "single_wall_s": wall1, "single_cpu_s": cpu1, "shard_cpu_sum_s": sum(shard_cpus),
             "cpu_overhead": sum(shard_cpus) / cpu1 - 1.0, "max_shard_wall_s": max(shard_walls),
             "min_shard_wall_s": min(shard_walls), "shard_links_max_s": max(shard_links),
             "shard_other_stages_mean_s": sum(shard_other) / n, "merge_wall_s": mwall, "merge_cpu_s": mcpu,
             "max_shard_cpu_s": max(shard_cpus), "critical_path_cpu_s": critical_cpu,
             "projected_wall_s": projected, "projected_speedup": cpu1 / critical_cpu, "byte_identical": identical}
        summary.append(s)
        print(f"N={n}: shard cpu sum {s['shard_cpu_sum_s']:.2f} s ({100 * s['cpu_overhead']:+.0f} %), "
              f"slowest shard cpu {max(shard_cpus):.2f} s, shard wall {s['min_shard_wall_s']:.2f}.."
              f"{s['max_shard_wall_s']:.2f} s, merge {mwall:.2f} s wall {mcpu:.2f} s cpu, "
              f"projected on {n} nodes {projected:.2f} s ({s['projected_speedup']:.2f}x), "
              f"byte-identical {identical}", flush=True)
        if not identical:
            sys.exit(f"shard_bench: the {n}-shard merge differs from the single-machine artifact")

    with open(os.path.join(a.out, "runs.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    machine = {"cpus": os.cpu_count(), "platform": platform.platform(), "processor": platform.processor()}
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump({"scene": a.scene, "subdivide": a.subdivide, "options": a.options, "machine": machine,
                   "single": {"wall_s": wall1, "cpu_s": cpu1, "links_s": links1, "other_stages_s": other1},
                   "shards": summary}, f, indent=2)

    print()
    print("| N | single: wall / CPU (s) | sum of shard CPU (s) | sharding overhead | slowest shard CPU (s) "
          "| merge CPU (s) | projected wall on N nodes (s) | speed-up | byte-identical |")
    print("|---|---|---|---|---|---|---|---|---|")
    for s in summary:
        print(f"| {s['n']} | {s['single_wall_s']:.1f} / {s['single_cpu_s']:.1f} | {s['shard_cpu_sum_s']:.1f} "
              f"| {100 * s['cpu_overhead']:+.0f} % | {s['max_shard_cpu_s']:.1f} | {s['merge_cpu_s']:.2f} "
              f"| {s['projected_wall_s']:.1f} | {s['projected_speedup']:.2f}x | {'yes' if s['byte_identical'] else 'NO'} |")

if __name__ == "__main__":
    main()
