#!/usr/bin/env python3
"""Renders the tables of docs/results.md from the benchmarks' recorded output.

A block between `<!-- generated: NAME -->` and `<!-- end generated -->` in docs/results.md is
the output of the renderer NAME below, from a file under docs/data/. `--check` exits 1 and
prints the difference when a block is not what its data gives (a CTest runs it); without it
the blocks are rewritten in place. Sections whose runs were not recorded are still written
by hand, each with its command and machine.
"""
import csv
import difflib
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "docs" / "results.md"


def pct(x):
    return f"{100.0 * float(x):.2f} %"


def accuracy():
    """Factor study around medium on the bundled Cornell box (bench/accuracy, --reduced)."""
    path = "docs/data/accuracy/reduced_local_pick_devvm.csv"
    rows = {}
    with open(ROOT / path, newline="") as f:
        for r in csv.DictReader(f):
            if r["scene"] == "cornell_box":
                rows[(r["factor"], r["value"])] = r

    def row(key):
        if key not in rows:
            sys.exit(f"results_tables: {path} has no cornell_box row {key}")
        return rows[key]

    def cells(keys, field, fmt):
        return " / ".join(fmt(row(k)[field]) for k in keys)

    def mb(x):
        return f"{float(x) / 1e6:.1f}"

    def bias(x):
        return f"{float(x):.3f}"

    points = [
        ("draft (nS 4k, nL 64, 512 rays, 64²)", [("preset", "draft")], True),
        ("**medium** (nS 32k, nL 128, 3 bands, 1024 rays, 128²)", [("base", "medium")], True),
        ("high (nS 16k, nL 256, 3 bands, 2048 rays, 128²)", [("preset", "high")], True),
        ("nL 32 / nL 512", [("links", "32"), ("links", "512")], True),
        ("2 bands / 4 bands", [("bands", "2"), ("bands", "4")], False),
        ("runtime links, 3 bands", [("form", "runtime3")], True),
        ("kd hierarchy", [("builder", "kd")], True),
        ("0 / 1 / 2 bounces", [("bounces", "0"), ("bounces", "1"), ("bounces", "2")], False),
    ]
    out = [f"Data: `{path}`.", "",
           "| point | indirect RMSE (net) | debiased | indirect bias | total RMSE | memory MB |",
           "|---|---|---|---|---|---|"]
    for label, keys, debiased in points:
        rmse = cells(keys, "indirect_rmse_net", pct)
        if len(keys) == 1 and keys[0] in (("base", "medium"), ("preset", "high")):
            rmse = f"**{rmse}**"
        out.append(" | ".join([
            f"| {label}", rmse, cells(keys, "indirect_rmse_debiased", pct) if debiased else "",
            cells(keys, "indirect_bias", bias), cells(keys, "total_rmse", pct),
            cells(keys, "memory_bytes", mb) if len({row(k)["memory_bytes"] for k in keys}) > 1
            else mb(row(keys[0])["memory_bytes"])]) + " |")
    medium, high = float(row(("base", "medium"))["indirect_rmse_net"]), float(row(("preset", "high"))["indirect_rmse_net"])
    met = medium <= 0.10 and high <= 0.05
    out += ["", f"Targets: indirect RMSE <= 10 % at medium and <= 5 % at high: "
                f"**{'met' if met else 'not met'}** ({pct(medium)}, {pct(high)})."]
    return "\n".join(out)


RENDERERS = {"accuracy": accuracy}
BLOCK = re.compile(r"(<!-- generated: (\w+) -->\n)(.*?)(<!-- end generated -->)", re.S)


def render(text):
    def one(m):
        name = m.group(2)
        if name not in RENDERERS:
            sys.exit(f"results_tables: docs/results.md names an unknown block '{name}'")
        return m.group(1) + RENDERERS[name]() + "\n" + m.group(4)
    return BLOCK.sub(one, text)


def main(argv):
    check = "--check" in argv
    text = RESULTS.read_text()
    if not BLOCK.search(text):
        sys.exit("results_tables: docs/results.md has no generated block")
    new = render(text)
    if check:
        if new != text:
            sys.stdout.writelines(difflib.unified_diff(text.splitlines(True), new.splitlines(True),
                                                       "docs/results.md", "rendered"))
            print("results_tables: docs/results.md is not what its data gives; run scripts/results_tables.py")
            return 1
        return 0
    RESULTS.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
