#!/usr/bin/env python3
"""docs/quality.md's per-scene table from bench/quality/run.sh's OUT_DIR/<scene>/compare.json."""
import json
import pathlib
import sys


def pct(x):
    return "-" if x is None else f"{100.0 * x:.1f} %"


def num(x, fmt=".3f"):
    return "-" if x is None else format(x, fmt)


def main(out):
    rows = []
    for path in sorted(pathlib.Path(out).glob("*/compare.json")):
        c = json.loads(path.read_text())
        name = path.parent.name
        seconds = path.parent.with_suffix(".seconds")
        wall = float(seconds.read_text()) if seconds.exists() else float("nan")
        band, inner = c["near_contact"]["total"], c["interior"]["total"]
        ratio = (band["rel_rmse"] / inner["rel_rmse"]
                 if band["rel_rmse"] is not None and inner["rel_rmse"] else None)
        rows.append(
            f"| {name} | {c['points']} | {pct(c['total']['rel_rmse'])} | {pct(c['total']['p95_rel_error'])} | "
            f"{num(c['total']['bias'])} | {pct(c['indirect']['rel_rmse'])} | {num(c['indirect']['bias'])} | "
            f"{c['near_contact']['points']} | {pct(band['rel_rmse'])} | {pct(inner['rel_rmse'])} | {num(ratio, '.1f')} | "
            f"{c['leaks']['leaks']} ({c['leaks']['near_contact_leaks']}) | {c['leaks']['missing_light']} | {wall:.0f} s |")
    print("| scene | points | total rel. RMSE | total p95 | total bias | indirect rel. RMSE | indirect bias | "
          "band points | band | interior | band / interior | leaks (in band) | missing light | wall |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
