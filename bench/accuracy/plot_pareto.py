#!/usr/bin/python3
"""Pareto plots of the accuracy study (bench/accuracy/accuracy_study's CSV).

One PNG per scene, two panels: indirect irradiance relative RMSE (reference noise removed)
against relight time and against precompute time, both log-scaled; each factor of the sweep
has its own colour, every point is labelled with its value, and the front (points no other
point beats in both error and time) is joined by a line.

Usage: plot_pareto.py accuracy.csv OUT_DIR     (needs Debian's python3-matplotlib)
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = {
    "base": "black", "preset": "tab:purple", "surfels": "tab:blue", "links": "tab:orange",
    "bands": "tab:green", "rays": "tab:red", "builder": "tab:brown", "density": "tab:pink",
    "form": "tab:olive", "bounces": "tab:cyan", "candidate": "tab:gray",
}


def front(points):
    """Indices of the points no other point beats in both coordinates (lower is better)."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    best, out = float("inf"), []
    for i in order:
        if points[i][1] < best:
            best = points[i][1]
            out.append(i)
    return out


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1], newline="") as f:
        # Diagnostic rows (compared with a single-bounce reference) are not on these axes.
        rows = [r for r in csv.DictReader(f) if not r["error"] and r["reference_bounces"] == "-1"]
    os.makedirs(sys.argv[2], exist_ok=True)
    for scene in sorted({r["scene"] for r in rows}):
        sr = [r for r in rows if r["scene"] == scene and float(r["indirect_rmse_net"]) > 0]
        if not sr:  # e.g. no light reaches any cache: nothing to put on a log scale
            print("skipped", scene, "(no non-zero error)")
            continue
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), dpi=80)
        for ax, cost, label in ((axes[0], "relight_ms", "relight time (ms, median, bounces to convergence)"),
                                (axes[1], "precompute_s", "precompute time (s)")):
            pts = [(float(r[cost]), 100 * float(r["indirect_rmse_net"])) for r in sr]
            for fac in COLOURS:
                sel = [i for i, r in enumerate(sr) if r["factor"] == fac]
                if sel:
                    ax.scatter([pts[i][0] for i in sel], [pts[i][1] for i in sel], s=28, c=COLOURS[fac],
                               label=fac, zorder=3)
            for i, r in enumerate(sr):
                ax.annotate(r["value"], pts[i], fontsize=7, xytext=(3, 3), textcoords="offset points")
            fr = front(pts)
            ax.plot([pts[i][0] for i in fr], [pts[i][1] for i in fr], "-", c="gold", lw=4, alpha=0.6,
                    zorder=1, label="Pareto front")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(label)
            ax.set_ylabel("indirect irradiance rel. RMSE (%)")
            ax.grid(True, which="both", alpha=0.3)
            for bound, name in ((10, "medium target"), (5, "high target")):
                ax.axhline(bound, ls="--", c="grey", lw=0.8)
                ax.text(ax.get_xlim()[0], bound, " " + name, fontsize=7, va="bottom", color="grey")
        axes[0].legend(fontsize=7, loc="upper right")
        fig.suptitle(f"{scene}: accuracy vs cost (one factor at a time around medium)", fontsize=10)
        fig.tight_layout()
        out = os.path.join(sys.argv[2], f"pareto_{scene}.png")
        fig.savefig(out)
        plt.close(fig)
        print("wrote", out)


if __name__ == "__main__":
    main()
