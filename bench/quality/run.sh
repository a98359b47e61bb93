#!/usr/bin/env bash
# The "Every shared scene" figures of docs/quality.md in one command:
#
#   bench/quality/run.sh --bin BUILD/clients/lightlink --scenes DIR_WITH_SHARED_SCENES --out OUT_DIR
#       [--preset medium] [--max-points 2000] [--target-error 0.02] [--time-budget 300]
#
# Runs `lightlink compare` on every shared scene (the game levels with the light sets of
# tests/levels/lights, the others with their own lights), writing OUT_DIR/<scene>/compare.json
# and its heat maps, then OUT_DIR/quality.md: total and indirect error, the near-contact band
# against the interior, and leaks, one row per scene.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lights="$here/../../tests/levels/lights"
bin="" scenes="" out="" preset="medium" points=2000 target=0.02 budget=300
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --scenes) scenes="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --preset) preset="$2"; shift 2 ;;
    --max-points) points="$2"; shift 2 ;;
    --target-error) target="$2"; shift 2 ;;
    --time-budget) budget="$2"; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 1 ;;
  esac
done
[ -x "$bin" ] && [ -d "$scenes" ] && [ -n "$out" ] || { echo "usage: see the header of $0" >&2; exit 1; }
mkdir -p "$out"
# scene file (relative to --scenes) and, for the levels (no lights of their own), a light set
list="cornell_box_original_gltf/CornellBox-Original.gltf -
cornell_box_mcguire_obj/CornellBox-Original.obj -
cornell_box_vinc3r_lightmapuv/cornellBox-2.80-Eevee-gltf.gltf -
khronos_EmissiveStrengthTest/EmissiveStrengthTest.gltf -
khronos_LightsPunctualLamp/LightsPunctualLamp.gltf -
khronos_MultiUVTest/MultiUVTest.gltf -
revelry_ShadowsDirectional/shadows-directional.gltf -
revelry_ShadowsSpot/shadows-spot.gltf -
redeclipse_cyanide_obj/cyanide.obj cyanide.json
redeclipse_institute_obj/institute.obj institute.json
tesseract_steelribs_obj/steelribs.obj steelribs.json
sauerbraten_memento_obj/memento.obj memento.json
sauerbraten_forge_obj/forge.obj forge.json
sauerbraten_zdm2_level_gltf/zdm2.glb zdm2.json"
while read -r rel lightset; do
  file=$(find "$scenes/$(dirname "$rel")" -maxdepth 3 -name "$(basename "$rel")" | head -1)
  if [ -z "$file" ]; then echo "== $rel: not found, skipped" >&2; continue; fi
  name=$(basename "$(dirname "$rel")")
  extra=()
  [ "$lightset" != "-" ] && extra=(--lights "$lights/$lightset")
  echo "== $name" >&2
  start=$(date +%s.%N)
  if ! "$bin" compare "$file" --preset "$preset" --max-points "$points" --target-error "$target" \
      --time-budget "$budget" -o "$out/$name" -q "${extra[@]}" 2> "$out/$name.log"; then
    echo "   failed: see $out/$name.log" >&2
  fi
  echo "$(date +%s.%N) - $start" | bc > "$out/$name.seconds"
done <<< "$list"
python3 "$here/quality_table.py" "$out" > "$out/quality.md"
cat "$out/quality.md"
