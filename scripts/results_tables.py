#!/usr/bin/env python3
"""Renders the tables of docs/results.md from the benchmarks' recorded output.

A block between `<!-- generated: NAME -->` and `<!-- end generated -->` in docs/results.md is
the output of the renderer NAME below, from the files under docs/data/NAME/ that
`scripts/bench results NAME` writes (each benchmark's JSON plus run.json: machine, commit,
date, commands). `--check` exits 1 and prints the difference when a block is not what its
data gives (a CTest runs it); without it the blocks are rewritten in place.
"""
import csv
import difflib
import json
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
RESULTS = ROOT / "docs" / "results.md"
DATA = ROOT / "docs" / "data"


def load(section, name):
    path = DATA / section / name
    if not path.exists():
        sys.exit(f"results_tables: {path.relative_to(ROOT)} is missing; run scripts/bench results {section}")
    return json.loads(path.read_text())


def provenance(section, pattern=None):
    """The machine, commit and commands a section's figures come from; `pattern` stands for
    commands that differ only in the scene."""
    run = load(section, "run.json")
    out = [f"`scripts/bench results {section}` on {run['cpu']} ({run['hardware_threads']} hardware threads), "
           f"commit {run['commit']}, {run['date']}:", "```"]
    out += [pattern.format(n=len(run["commands"]))] if pattern else run["commands"]
    return out + ["```", ""]


def verdict(ok):
    return "**met**" if ok else "**not met**"


def table(head, rows):
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    return out + ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]


def rays():
    """Raw Embree throughput through rt::Accel (bench/rt/ray_bench)."""
    files = [("city.json", "procedural city"), ("zdm2.json", "zdm2"), ("zdm2_x4.json", "zdm2 x4")]
    docs = [(load("rays", f), label) for f, label in files]
    threads = docs[0][0]["machine"]["tbb_threads"]
    head = ["rays", "query", "api"] + [f"{label} {d['scene']['triangles']:,} tris" for d, label in docs]
    keyed = []
    for d, _ in docs:
        by = {}
        for r in d["results"]:
            by.setdefault((r["rays"], r["query"], r["api"]), {})[r["threads"]] = r["mrays_per_s"]
        keyed.append(by)
    rows = []
    for key in keyed[0]:
        cells = []
        for by in keyed:
            group = [v for k, v in by.items() if k[:2] == key[:2]]
            best = max(max(v.values()) for v in group)
            cell = " / ".join(f"{by[key][t]:.1f}" for t in sorted(by[key]))
            cells.append(f"**{cell}**" if max(by[key].values()) == best else cell)
        rows.append(list(key) + cells)
    return "\n".join(provenance("rays") + [f"Mrays/s at 1 / {threads} threads; bold: the fastest api for that "
                                            "ray kind and query.", ""] + table(head, rows))


def charts():
    """What `lightlink unwrap` makes of the shared scenes (bench/charts/charts_bench)."""
    d = load("charts", "charts.json")
    rows = []
    for r in d["rows"]:
        if "error" in r:
            rows.append([r["scene"], "error: " + r["error"]] + [""] * 6)
        elif not r["generated"]:
            rows.append([r["scene"], f"{r['triangles']:,}", "kept TEXCOORD_1", "-", f"{100 * r['utilisation']:.1f} % (centres)",
                         "-", f"{r['overlaps']:,} overlapping centres", f"{r['seconds_best_of_3']:.3f}"])
        else:
            rows.append([r["scene"], f"{r['triangles']:,}", f"{r['charts']:,}",
                         f"{r['resolution']}², {r['texel_size_m']:.4g} m", f"{100 * r['utilisation']:.1f} %",
                         f"{r['max_area_stretch']:.2f} / {r['mean_area_stretch']:.3f}", r["overlaps"],
                         f"{r['seconds_best_of_3']:.3f}"])
    medium = [r for r in d["rows"] if r.get("generated") and 1000 <= r["triangles"] <= 10000]
    big = next(r for r in d["rows"] if r["scene"].startswith("zdm2 subdivided"))
    low, high = min(r["utilisation"] for r in medium), max(r["utilisation"] for r in medium)
    out = provenance("charts") + ["Default options; time is the best of three unwraps.", ""]
    out += table(["scene", "static tris", "charts", "atlas, texel", "utilisation", "max / mean area stretch",
                  "overlaps", "time s"], rows)
    out += ["", f"Targets: utilisation >= 60 % on the scenes of 1k-10k triangles: {verdict(low >= 0.6)} "
                f"({100 * low:.0f}-{100 * high:.0f} %); unwrap of ~230k triangles < 5 s: "
                f"{verdict(big['seconds_best_of_3'] < 5)} ({big['seconds_best_of_3']:.1f} s)."]
    return "\n".join(out)


def scenes():
    """The shared scenes as `lightlink inspect` reads them."""
    run = load("scenes", "run.json")
    rows = []
    for path in sorted((DATA / "scenes").glob("*.json")):
        if path.name == "run.json":
            continue
        j = json.loads(path.read_text())
        lights, uv = j["lights"], j["lightmap_uv"]
        rows.append([path.stem, f"{j['triangles']:,}", j["degenerate_triangles_dropped"],
                     f"{lights['point']}/{lights['spot']}/{lights['directional']}", j["emissive_materials"],
                     f"{j['emissive_area_m2']:.4g}", f"{uv['static_instances_with_uv1']} of {uv['static_instances']}",
                     len(j["warnings"])])
    out = provenance("scenes", "build-bench/clients/lightlink inspect --json SCENE > docs/data/scenes/FOLDER.json  "
                               "# for each of the {n} scenes") + table(["scene", "triangles kept", "degenerate dropped", "lights p/s/d",
                                        "emissive materials", "emissive area m²", "meshes with UV1", "warnings"], rows)
    return "\n".join(out + ["", "`tests/scene/shared_scenes_test.cpp` asserts these counts."])


PRECOMPUTE_STAGES = ["unwrap", "surfels", "hierarchy", "bvh", "caches", "links"]


def precompute():
    """Whole precompute::run at medium (bench/precompute/precompute_bench)."""
    files = [("cornell.json", "Cornell (bundled)"), ("zdm2.json", "zdm2, 512²"), ("zdm2_x4.json", "zdm2 x4, 1024²")]
    rows, ratios = [], []
    for f, label in files:
        d = load("precompute", f)
        c, t = d["precompute"]["counts"], d["precompute"]["seconds"]
        rows.append([label, f"{d['triangles']:,}", f"{c['lightmap_caches']:,}", f"{c['grid_caches']:,}"]
                    + [f"{t.get(s, 0.0):.3f}" for s in PRECOMPUTE_STAGES] + [f"**{t['total']:.2f}**"])
        r = d["link_generation_vs_raw_embree"]
        ratios.append([label, f"{r['link_rays_per_second'] / 1e6:.2f}", f"{r['raw_rays_per_second'] / 1e6:.1f}",
                       f"{r['ratio']:.2f}"])
    machine = load("precompute", "cornell.json")["machine"]
    out = provenance("precompute")
    out += [f"nS 32768, nL 128, 3 bands, 1024 rays, HAC hierarchy; {machine['threads']} threads; seconds per stage.", ""]
    out += table(["scene", "tris", "lightmap caches", "grid caches"] + PRECOMPUTE_STAGES + ["total s"], rows)
    worst = min(float(r[3]) for r in ratios[1:])
    out += ["", "Link generation against raw Embree on the same rays (`rtcIntersect16` fans of each cache):", ""]
    out += table(["scene", "link Mrays/s", "raw Mrays/s", "ratio"], ratios)
    out += ["", f"Target: link generation >= 0.7 of raw Embree on the levels: {verdict(worst >= 0.7)} "
                f"({worst:.2f}). Each link ray also pays the owner lookup, the SH projection and the hit sort; on "
                "the 112-triangle box raw Embree's own tracing is so cheap that they weigh more."]
    return "\n".join(out)


RELIGHT_STAGES = [("surfel_direct", "surfel direct"), ("pull", "pull"), ("cache_lighting", "cache lighting"),
                  ("bounce_all", "bounces"), ("fill_dilate", "fill + dilate"), ("texel_filters", "seams + filters"),
                  ("baked_direct", "baked direct")]


def relight_rows(d):
    rows = []
    for r in d["relight"]:
        ms = r["ms"]
        rows.append([r["form"], r["bands"], r["bounces"]] + [f"{ms.get(k, 0.0):.2f}" for k, _ in RELIGHT_STAGES]
                    + [f"**{ms['total']:.2f}**"])
    return table(["form", "bands", "bounces"] + [h for _, h in RELIGHT_STAGES] + ["total ms"], rows)


def relight():
    """Full CPU relights, stage by stage (bench/relight/relight_bench)."""
    box, zdm2 = load("relight", "cornell.json"), load("relight", "zdm2.json")
    c = box["counts"]
    out = provenance("relight")
    out += [f"Median of repeated full relights (every light re-traced; emitter sampling reused while emission is "
            f"unchanged); {box['machine']['threads']} threads, AVX2 + F16C {'on' if box['machine']['avx2_f16c'] else 'off'}.",
            "", f"Bundled Cornell box, medium ({c['lightmap_caches']:,} lightmap + {c['grid_caches']:,} grid caches):", ""]
    out += relight_rows(box)
    k = box["cache_lighting_vs_read"]
    krows = [["plain read, projected bytes", f"{k['read_ms']['projected']:.2f}", "1",
              f"{k['bytes']['projected'] / k['read_ms']['projected'] / 1e6:.1f} GB/s"]]
    for name in ("projected_scalar", "projected_avx2", "runtime_scalar", "runtime_avx2"):
        if name in k:
            krows.append([name.replace("_", ", "), f"{k[name]['ms']:.2f}", f"{k[name]['ratio_to_read']:.2f}",
                          f"{k[name]['links_per_second'] / 1e6:.0f} M links/s"])
    out += ["", "Cache lighting kernels against a plain read of the same link bytes:", ""]
    out += table(["kernel", "ms", "x plain read", "rate"], krows)
    inc, em = box["incremental"], box["emission_change"]
    out += ["", f"Incremental relight (one point light of range {inc['range_m']:.2f} m moved, no bounce): "
                f"{inc['ms']:.2f} ms against {inc['full_ms']:.2f} ms full ({inc['surfels_lit']:,} of "
                f"{inc['surfels']:,} surfels re-lit). Emission state sampled afresh (1 bounce, nothing reused): "
                f"{em['total_ms']:.1f} ms, of which emitter sampling {em['emission_only_ms']:.1f} ms."]
    if "emission_edit" in box:
        ed = box["emission_edit"]
        out[-1] += (f" Emission edit (one material's strength and colour, 1 bounce, the emitters' light rescaled "
                    f"per material): {ed['ms']:.1f} ms against {ed['light_move_ms']:.1f} ms for a light move, "
                    f"{ed['ratio']:.2f}x (target <= 2x: {verdict(ed['ratio'] <= 2)}).")
    one = next(r for r in box["relight"] if r["form"] == "projected" and r["bounces"] == 1)["ms"]["total"]
    ratio = k["projected_avx2"]["ratio_to_read"] if "projected_avx2" in k else k["projected_scalar"]["ratio_to_read"]
    out += ["", f"Targets: relight with 1 bounce <= 10 ms on 2 cores: {verdict(one <= 10)} ({one:.1f} ms, "
                f"{box['machine']['threads']} threads); cache lighting within 2x of streaming its link bytes: "
                f"{verdict(ratio <= 2)} ({ratio:.2f}x)."]
    zc = zdm2["counts"]
    out += ["", f"zdm2 at 1024² ({zc['lightmap_caches_valid']:,} valid lightmap caches):", ""]
    out += relight_rows(zdm2)
    rows = []
    for label, d in (("Cornell (bundled), medium", box), ("zdm2, 1024²", zdm2)):
        for key, what in (("incremental_bounces", "range {:.2f} m"), ("incremental_bounces_unranged", "no range")):
            if key not in d:
                continue
            r, a = d[key], d[key]["accuracy"]
            rows.append([label, what.format(r["range_m"]), f"**{r['ms']:.1f}**", f"{r['full_ms']:.1f}",
                         f"{r['rounds']} / {r['full_bounces']}",
                         f"{r['surfels_gathered']:,} / {r['full_surfels_gathered']:,}",
                         f"{a['l1_vs_full']:.1e}",
                         f"{a['l1_vs_converged']:.1e} / {a['full_l1_vs_converged']:.1e} ({a['converged_bounces']})"])
    if rows:
        out += ["", "Incremental relight with bounces (default options, bounces to convergence; one point light "
                    "moved): the change propagated on top of the last solution against a full relight. Distances "
                    "are the relative L1 of the lightmap SH; \"converged\" is a full relight to a threshold of "
                    "1e-5 (its bounce count in brackets).", ""]
        out += table(["scene", "light", "incremental ms", "full ms", "rounds / bounces", "surfel gathers",
                      "L1 to full", "L1 to converged: incremental / full"], rows)
    return "\n".join(out)


TEMPORAL_RUNS = {"default": "default options", "fixed_bounces": "same bounce count every frame",
                 "surfels_unshadowed": "same bounce count, surfels lit without shadow rays"}


def temporal_row(label, what, m):
    lit = m["lit_texels"]
    return [label, what, f"{m['step']['roughness']:.3f}", f"{m['half_step']['roughness']:.3f}", f"**{m['ratio']:.2f}**",
            f"{m['step']['p999_d2']:.1f} / {m['half_step']['p999_d2']:.1f}",
            f"{m['popping_texels']:,} of {lit:,} ({100 * m['popping_texels'] / max(lit, 1):.1f} %)",
            f"{m['without_popping']['ratio']:.2f}"]


def temporal():
    """Lightmaps along a moving light's path (bench/relight/flicker_bench)."""
    out = provenance("temporal")
    out += ["Ratio = R(s/2) / R(s), R = RMS of the second difference over RMS of the first, per texel relative to "
            "its mean over the path, over lit texels: 0.5 when the lightmap follows the light smoothly, about 0.7 "
            "at kinks, 1 or more when texels jump. p99.9: the 99.9th percentile of |d2| over the RMS of d1, at s and "
            "s/2. Popping: texels whose largest change does not shrink when the step halves. The direct layer is the "
            "same in every run.", ""]
    rows, notes, default, smooth = [], [], {}, {}
    for f, label in (("cornell.json", "Cornell (bundled), medium"), ("zdm2.json", "zdm2, medium preset")):
        d = load("temporal", f)
        path, light = d["path"], d["light"]
        moved = (f"{light['id']} ({light['kind']}) along {path['length_m']:.3g} m in {path['steps']} steps"
                 if path["kind"] == "line" else
                 f"{light['id']} ({light['kind']}) turned {path['angle_rad']:.3g} rad in {path['steps']} steps")
        runs = {r["name"]: r for r in d["runs"]}
        rows.append(temporal_row(f"{label}: {moved}", "direct", runs["default"]["direct"]))
        for name, what in TEMPORAL_RUNS.items():
            if name in runs:
                rows.append(temporal_row("", f"indirect, {what}", runs[name]["indirect"]))
        run = runs["default"]
        ind = run["indirect"]
        default[label] = ind["ratio"]
        if "surfels_unshadowed" in runs:
            smooth[label] = runs["surfels_unshadowed"]["indirect"]["ratio"]
        if ind["popping_texels"]:
            lo, hi = min(run["bounces"]), max(run["bounces"])
            note = (f"{label}: {ind['popping_texels']:,} indirect texels pop with the default options "
                    f"({lo if lo == hi else f'{lo}-{hi}'} bounces per frame)")
            if "fixed_bounces" in runs:
                note += f", {runs['fixed_bounces']['indirect']['popping_texels']:,} with the same bounce count every frame"
            note += (f"; a popping texel jumps by {100 * ind['popping_jump']['median']:.0f} % of its light in one step "
                     f"(median; up to {100 * ind['popping_jump']['max']:.0f} %)")
            if "surfel_share" in ind:
                share = ind["surfel_share"]
                note += (f", and one surfel holds {100 * share['popping_median']:.0f} % of its cache's view (median; "
                         f"{100 * share['all_median']:.1f} % over every texel)")
            notes.append(note + ".")
        if "incremental_vs_full" in d:
            inc, full = runs["no_bounce_incremental"], runs["no_bounce_full"]
            notes.append(f"{label}, no bounce: incremental relights give ratios {inc['indirect']['ratio']:.2f} "
                         f"(indirect) and {inc['direct']['ratio']:.2f} (direct), full ones {full['indirect']['ratio']:.2f} "
                         f"and {full['direct']['ratio']:.2f}; the largest difference between them is "
                         f"{max(d['incremental_vs_full'].values()):.2g} of the largest value.")
    out += table(["scene, light path", "layer, run", "R(s)", "R(s/2)", "ratio", "p99.9 at s / s/2", "popping texels",
                  "ratio without them"], rows)
    out += [""] + [f"- {n}" for n in notes]
    listed = ", ".join(f"{v:.2f}" for v in default.values())
    listed_smooth = ", ".join(f"{v:.2f}" for v in smooth.values())
    out += ["", f"Target: a light moving smoothly gives a smoothly changing indirect (ratio <= 0.7): "
                f"{verdict(max(default.values()) <= 0.7)} ({listed}); with the surfels lit without shadow rays: "
                f"{verdict(bool(smooth) and max(smooth.values()) <= 0.7)} ({listed_smooth})."]
    return "\n".join(out)


def service():
    """Light change to a polling client over the daemon (bench/service/service_bench)."""
    out = provenance("service")
    rows, at50 = [], {}
    for f, label in (("bounces.json", "daemon default (bounces to convergence)"), ("no_bounce.json", "no bounce")):
        d = load("service", f)
        first = True
        for s in d["latency"]:
            lat, over = s["latency_ms"], s["latency_minus_relight_ms"]
            rows.append([f"{label}, mean relight {d['relight']['mean_relight_ms']:.1f} ms" if first else "",
                         s["mode"], s["clients"], f"{lat['p50']:.1f} / {lat['p99']:.1f}",
                         f"{over['p50']:.1f} / {over['p99']:.1f}", f"{s['poll_not_modified_ms']['p50']:.2f}"])
            first = False
            if s["clients"] == 50:
                at50[f] = lat
        last = d
    out += [f"Medium bundled Cornell box ({last['lightmap']['width']}² texels, {last['lightmap']['bands']} bands), "
            "daemon and clients on the same machine over loopback; latency from UpdateLights to a client holding "
            "the new lightmap.", ""]
    out += table(["daemon relight", "mode", "clients", "latency p50 / p99 ms", "minus relight p50 / p99 ms",
                  "not-modified poll p50 ms"], rows)
    prog = load("service", "progressive.json")
    prow = []
    for s_ in prog["latency"]:
        lat, conv = s_["latency_ms"], s_["latency_converged_ms"]
        prow.append([s_["mode"], s_["clients"], f"{lat['p50']:.1f} / {lat['p99']:.1f}",
                     f"{conv['p50']:.1f} / {conv['p99']:.1f}"])
    first1 = next((s_["latency_ms"]["p50"] for s_ in prog["latency"] if s_["clients"] == 1), float("nan"))
    out += ["", f"Progressive daemon (`--progressive`, default bounces): the first result of a light change is one "
                f"bounce iteration from the last solution, further iterations follow as new versions; a change of one "
                f"light on a converged result is relit incrementally and converges at once (mean relight "
                f"{prog['relight']['mean_relight_ms']:.1f} ms, {prog['relight']['previews']} of "
                f"{prog['relight']['relights']} results unconverged):", ""]
    out += table(["mode", "clients", "first result p50 / p99 ms", "converged p50 / p99 ms"], prow)
    out += ["", f"Target light move to the first published version <= 10 ms (one client): {verdict(first1 <= 10)} "
                f"({first1:.1f} ms p50)."]
    if (DATA / "service" / "level.json").exists():
        lv = load("service", "level.json")
        s_ = next(s_ for s_ in lv["latency"] if s_["clients"] == 1)
        lat, over = s_["latency_ms"], s_["latency_minus_relight_ms"]
        out += ["", f"A shared level: zdm2 at medium ({lv['lightmap']['width']}² texels), its light set "
                    f"`tests/levels/lights/zdm2.json`, lamp0 moved on a 1 m circle, daemon default options (a change "
                    f"of one light relit incrementally, bounces included; mean relight "
                    f"{lv['relight']['mean_relight_ms']:.1f} ms): one long-polling client holds the new lightmap "
                    f"after {lat['p50']:.1f} ms p50, {lat['p99']:.1f} ms p99 ({over['p50']:.1f} / {over['p99']:.1f} ms "
                    f"beyond the relight)."]
    if (DATA / "service" / "preview.json").exists():
        pv = load("service", "preview.json")
        prow = [[pathlib.Path(s_["scene"]).name, f"{s_['triangles']:,}", f"{s_['grid_points']:,}",
                 f"**{s_['preview_s_median']:.2f}**", f"{s_['update_s_median']:.2f}"] for s_ in pv["scenes"]]
        worst = max((s_["preview_s_median"] for s_ in pv["scenes"] if s_["triangles"] > 10000), default=float("nan"))
        out += ["", "Instant preview (`--preview on`, the default): OpenScene to the first version (a grid lit "
                    "without links) at the client, and a light change re-lit while the links are computed "
                    f"(median of {pv['scenes'][0]['runs']} runs, preset {pv['preset']}):", ""]
        out += table(["scene", "triangles", "grid points", "OpenScene to preview s", "light change s"], prow)
        out += ["", f"Target first preview <= 1 s after OpenScene on a ~60k-triangle level: {verdict(worst <= 1)} "
                    f"({worst:.2f} s, the slower level)."]
    tp, mem = last["throughput"], last["memory"]
    best = at50.get("no_bounce.json", {"p50": float("nan"), "p99": float("nan")})
    dh, df = load("service", "decode_half.json"), load("service", "decode_float.json")
    out += ["", f"Target p50 <= 20 ms and p99 <= 50 ms at 50 clients: "
                f"{verdict(best['p50'] <= 20 and best['p99'] <= 50)} ({best['p50']:.0f} / {best['p99']:.0f} ms "
                "without bounces). Every stream's writes interleave on gRPC's callback API, so each client's "
                "result completes near the end of the burst.",
            "", f"Throughput {tp['updates_per_s']:.0f} updates/s acknowledged; resident "
                f"{mem['resident_bytes'] / 1048576:.1f} MiB per scene. Client decode of one result with the "
                f"generated parser: {dh['generated_us_per_result']:.0f} µs ({dh['result']['megabytes']:.1f} MB, half) "
                f"and {df['generated_us_per_result']:.0f} µs ({df['result']['megabytes']:.1f} MB, float)."]
    return "\n".join(out)


GPU_STAGES = [("shadow_maps", "shadow maps"), ("surfel_direct", "surfel direct"), ("emission", "emission"),
              ("pull", "pull"), ("node_radiosity", "node radiosity"), ("cache_lighting", "cache lighting"),
              ("bounces_gather", "bounces: gather + fill"), ("bounces_pull", "bounces: pull"),
              ("bounces_cache_lighting", "bounces: cache lighting"), ("baked_direct", "baked direct"),
              ("surfel_emitter", "emitters at the surfels"), ("surfel_emitter_gpu", "of which GPU sampling (device)"),
              ("emissive_direct", "emitters' direct light per texel"),
              ("emissive_direct_gpu", "of which GPU sampling (device)"), ("grid_emitter", "emitters at the grid caches"),
              ("grid_emitter_gpu", "of which GPU sampling (device)"), ("fill_dilate", "fill + texels + dilation"),
              ("readback", "readback"), ("wall", "**relight wall time**")]


def gpu():
    """GL compute relight against the CPU on the same machine (bench/gpu/gpu_relight_bench)."""
    d = load("gpu", "medium.json")
    m = d["machine"]
    runs = d["relight"]
    head = ["stage, ms (median)"] + [f"GPU, {r['link_form']}, {r['max_bounces']} bounces" for r in runs] \
        + [f"CPU, {r['link_form']}, {r['max_bounces']} bounces" for r in runs if r["max_bounces"] > 0]
    rows = []
    for key, label in GPU_STAGES:
        cells = [f"{1e3 * r['gpu_seconds'][key]:.2f}" if key in r["gpu_seconds"] else "—" for r in runs]
        cells += [f"{1e3 * r['cpu_seconds'][key]:.2f}" if key in r["cpu_seconds"] else "—"
                  for r in runs if r["max_bounces"] > 0]
        if any(c != "—" for c in cells):  # stages a run did not have (older data) leave no row
            rows.append([label] + cells)
    out = provenance("gpu")
    out += [f"{m['gpu']}, OpenGL {m['gl']} through EGL ({m['egl_platform']}); host {m['cpu']} x {m['threads']}; "
            f"medium bundled Cornell box. GPU stage times are GL timer queries.", ""]
    out += table(head, rows)
    gbps = [r["cache_lighting_GBps"] for r in runs]
    out += ["", f"Cache lighting streams its link bytes at {min(gbps):.0f}-{max(gbps):.0f} GB/s against "
                f"{d['bandwidth']['read_GBps']:.0f} GB/s measured: a 0.1 ms pass has too few workgroups to reach "
                "the bandwidth bound."]
    return "\n".join(out)


def levels():
    """The game levels at each preset (bench/levels/level_bench)."""
    rows, medium_pre, medium_rel, big = [], [], [], None
    for path in sorted((DATA / "levels").glob("*.json")):
        if path.name == "run.json":
            continue
        d = json.loads(path.read_text())
        s = d["stages"]
        r = d.get("relight_one_bounce_stages", {})
        name = pathlib.Path(d["scene"]).stem + (f" x{d['tile']}x{d['tile']}" if d["tile"] > 1 else "")
        direct = f"{d['direct_width']}x{d['direct_height']}" if d.get("direct_width") else "at the caches"
        seams = d.get("seams", {}).get("direct", {})
        jump = f"{seams['jump_before']:.3f} → {seams['jump_after']:.3f}" if seams.get("edges") else "no smooth seam"
        rows.append([name, d["preset"], f"{d['triangles']:,}", f"{d['texel_size']:.3g}", f"{d['pages']} x {d['page']}²",
                     f"{d['charts']:,}", f"{d['lightmap_caches']:,}", direct, f"{d['grid_caches']:,}",
                     f"{s['total']:.1f}", f"{d['peak_rss_mib']:.0f}", f"{d['relight_one_bounce_ms']:.1f}",
                     f"{1e3 * r.get('direct_layer', 0.0):.1f}", jump])
        if d["tile"] > 1:
            big = d
        elif d["preset"] == "medium":
            medium_pre.append((s["total"], name))
            medium_rel.append((d["relight_one_bounce_ms"], name))
    out = provenance("levels")
    out += ["Light sets of `tests/levels/lights/`; relight = one-bounce CPU relight after `invalidate` (every light "
            "re-traced), warm; seam jump = the direct layer's largest step across a smooth chart seam, before and "
            "after stitching.", ""]
    out += table(["level", "preset", "triangles", "texel size", "pages", "charts", "lightmap caches", "direct layer",
                  "grid caches", "precompute s", "peak RSS MiB", "relight ms", "of which direct layer ms",
                  "seam jump, direct"], rows)
    slow = [n for ms, n in medium_rel if ms >= 50]
    out += ["", f"Targets: medium precompute < 60 s: {verdict(max(medium_pre)[0] < 60)} "
                f"({min(medium_pre)[0]:.1f}-{max(medium_pre)[0]:.1f} s); medium relight < 50 ms: "
                f"{verdict(not slow)} ({min(medium_rel)[0]:.0f}-{max(medium_rel)[0]:.0f} ms"
                f"{'; ' + ', '.join(slow) + ' over' if slow else ''})"]
    if big:
        out[-1] += (f"; ~1M triangles (forge 4x4) < 10 min and < 8 GB: "
                    f"{verdict(big['stages']['total'] < 600 and big['peak_rss_mib'] < 8192)} "
                    f"({big['stages']['total']:.0f} s, {big['peak_rss_mib'] / 1024:.1f} GiB)")
    out[-1] += "."
    return "\n".join(out)


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


RENDERERS = {"rays": rays, "charts": charts, "scenes": scenes, "precompute": precompute, "relight": relight,
             "temporal": temporal, "service": service, "gpu": gpu, "levels": levels, "accuracy": accuracy}
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
