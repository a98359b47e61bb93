#!/usr/bin/env python3
"""The docs/results.md "Game levels" table from level_bench's JSON files: levels_table.py OUT_DIR
(writes OUT_DIR/levels.md and prints it)."""
import glob
import json
import os
import sys

out = sys.argv[1]
rows = ["| level | preset | triangles | texel size | pages | charts | lightmap caches | direct layer | probe-lit objects "
        "| grid caches | load s | unwrap s | caches s | direct texels s | links s | precompute s | peak RSS MiB "
        "| relight, 1 bounce (warm) ms | of which direct layer ms | seam jump, direct (before → after) |",
        "|" + "---|" * 20]
for f in sorted(glob.glob(os.path.join(out, "*.json"))):
    d = json.load(open(f))
    s = d["stages"]
    r = d.get("relight_one_bounce_stages", {})
    name = os.path.basename(d["scene"]).rsplit(".", 1)[0] + (f" x{d['tile']}x{d['tile']}" if d["tile"] > 1 else "")
    direct = (f"{d['direct_width']}x{d['direct_height']}, {d['direct_texels']:,}" if d.get("direct_width") else "at the caches")
    seams = d.get("seams", {}).get("direct", {})
    jump = f"{seams['jump_before']:.3f} → {seams['jump_after']:.3f}" if seams.get("edges") else "no smooth seam"
    rows.append(f"| {name} | {d['preset']} | {d['triangles']:,} | {d['texel_size']:.3g} | {d['pages']} x {d['page']}² "
                f"| {d['charts']:,} | {d['lightmap_caches']:,} | {direct} | {d['probe_lit_objects']} | {d['grid_caches']:,} "
                f"| {d['load_seconds']:.2f} | {s['unwrap']:.1f} | {s['caches']:.1f} | {s.get('direct_texels', 0.0):.1f} "
                f"| {s['links']:.1f} | {s['total']:.1f} | {d['peak_rss_mib']:.0f} | {d['relight_one_bounce_ms']:.1f} "
                f"| {1e3 * r.get('direct_layer', 0.0):.1f} | {jump} |")
open(os.path.join(out, "levels.md"), "w").write("\n".join(rows) + "\n")
print("\n".join(rows))
