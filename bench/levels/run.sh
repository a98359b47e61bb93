#!/usr/bin/env bash
# The "Game levels" figures of docs/results.md in one command:
#
#   bench/levels/run.sh --bin BUILD/bench/levels/level_bench --scenes DIR_WITH_SHARED_SCENES --out OUT_DIR
#       [--presets "draft medium high"] [--tile N]
#
# Runs level_bench on each shared game level (and zdm2) at each preset with the light sets
# of tests/levels/lights, then the ~1M-triangle level (forge tiled --tile x --tile, default
# 4, medium). Writes OUT_DIR/<level>_<preset>.json; `scripts/bench results levels` runs this into
# docs/data/levels and renders the table of docs/results.md from it.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lights="$here/../../tests/levels/lights"
bin="" scenes="" out="" presets="draft medium high" tile=4
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --scenes) scenes="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --presets) presets="$2"; shift 2 ;;
    --tile) tile="$2"; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 1 ;;
  esac
done
[ -x "$bin" ] && [ -d "$scenes" ] && [ -n "$out" ] || { echo "usage: see the header of $0" >&2; exit 1; }
mkdir -p "$out"
levels="redeclipse_cyanide_obj/cyanide.obj redeclipse_institute_obj/institute.obj tesseract_steelribs_obj/steelribs.obj
sauerbraten_memento_obj/memento.obj sauerbraten_forge_obj/forge.obj sauerbraten_zdm2_level_gltf/zdm2.glb"
for level in $levels; do
  name=$(basename "$level"); name=${name%.*}
  for preset in $presets; do
    echo "== $name $preset" >&2
    "$bin" "$scenes/$level" --preset "$preset" --lights "$lights/$name.json" --json "$out/${name}_$preset.json" >/dev/null
  done
done
if [ "$tile" -gt 1 ]; then
  echo "== forge x$tile medium" >&2
  "$bin" "$scenes/sauerbraten_forge_obj/forge.obj" --preset medium --lights "$lights/forge.json" --tile "$tile" \
    --repeats 3 --json "$out/forge_x${tile}_medium.json" >/dev/null
fi
