#!/usr/bin/env bash
# The accuracy-vs-time study in one command (docs/quality.md).
#
#   bench/accuracy/run.sh [--reduced] --bin BUILD/bench/accuracy/accuracy_study \
#       --scenes DIR_WITH_SHARED_SCENES --out OUT_DIR [--cornell clients/demo/cornell_box.gltf] [-- STUDY_ARGS...]
#
# Runs on any machine that has the built binary, a copy of the shared scenes (the folder
# layout of ../shared/scenes) and this directory (for lights/ and plot_pareto.py); no source
# tree or build tree is needed. The bundled Cornell box (--cornell, default: the one next to
# this script in the source tree) gets the sweep, every shared scene found under --scenes
# gets the same sweep (full) or the base point only (--reduced). Scenes without lights get
# a light set from lights/. Writes OUT_DIR/accuracy.csv, accuracy.json, pareto_<scene>.png
# (when /usr/bin/python3 has matplotlib: Debian's python3-matplotlib, see
# scripts/packages-bench.txt) and log.txt. The reference is cached in OUT_DIR/reference_cache,
# so a second run with the same layouts only re-bakes.
#
# --reduced: reduced sweep on the Cornell box, its diagnosis, base point on the shared scenes,
# 200 + 100 compare points: under 10 minutes on 2 cores.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
bin="" scenes="" out="" reduced=0 cornell="$here/../../clients/demo/cornell_box.gltf"
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --reduced) reduced=1; shift ;;
    --bin) bin="$2"; shift 2 ;;
    --scenes) scenes="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --cornell) cornell="$2"; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    *) echo "run.sh: unknown argument $1" >&2; exit 1 ;;
  esac
done
if [ -z "$bin" ] || [ -z "$out" ]; then
  echo "usage: run.sh [--reduced] --bin accuracy_study --scenes DIR --out DIR [--cornell F] [-- study args]" >&2
  exit 1
fi
[ -x "$bin" ] || { echo "run.sh: $bin is not an executable" >&2; exit 1; }
[ -f "$cornell" ] || { echo "run.sh: Cornell box $cornell not found (--cornell)" >&2; exit 1; }

# The bundled box twice: with its lights (the sweep), and with its point light alone for the
# first-bounce diagnosis (relight without bounces vs the single-bounce reference).
args=(--out "$out" --scene "$cornell"
      --scene "$cornell" --lights "$here/lights/cornell_point_only.json" --name cornell_point_only
      --scene-sweep diagnose)
add() {  # add SUBPATH [STUDY OPTIONS FOR IT]: a shared scene when present
  local f="$scenes/$1"
  shift
  if [ -n "$scenes" ] && [ -f "$f" ]; then
    args+=(--scene "$f" "$@")
  elif [ -n "$scenes" ]; then
    echo "run.sh: $f not found, skipped" >&2
  fi
}
add cornell_box_original_gltf/CornellBox-Original.gltf
add cornell_box_vinc3r_lightmapuv/cornellBox-2.80-Eevee-gltf.gltf
add khronos_EmissiveStrengthTest/EmissiveStrengthTest.gltf
add khronos_LightsPunctualLamp/LightsPunctualLamp.gltf
add khronos_MultiUVTest/MultiUVTest.gltf
add revelry_ShadowsSpot/shadows-spot.gltf
add revelry_ShadowsDirectional/shadows-directional.gltf
# zdm2 has no lights (a sun from lights/) and 19k charts: it needs a 4x larger atlas, and a
# one-factor sweep there (up to 1024² x 512 links: gigabytes of links) would dwarf the rest, so
# it gets the presets (base when reduced; its draft's 256² atlas cannot hold the charts).
zdm2_sweep=presets
[ "$reduced" = 1 ] && zdm2_sweep=base
add sauerbraten_zdm2_level_gltf/zdm2.glb --lights "$here/lights/zdm2_sun.json" --resolution-scale 4 \
  --scene-sweep "$zdm2_sweep"
if [ "$reduced" = 1 ]; then
  args+=(--sweep reduced --others base --centres 200 --midpoints 100 --repeats 3)
else
  args+=(--sweep full --others full)
fi
mkdir -p "$out"
"$bin" "${args[@]}" ${extra[@]+"${extra[@]}"} 2>&1 | tee "$out/log.txt"
if /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  /usr/bin/python3 "$here/plot_pareto.py" "$out/accuracy.csv" "$out"
else
  echo "run.sh: no matplotlib for /usr/bin/python3 (apt-get install python3-matplotlib): plots skipped" >&2
fi
