#!/usr/bin/env bash
# The encoding figures of docs/outputs.md ("Encodings: figures") in one command:
#
#   bench/output/run.sh --bin BUILD/bench/output/encoding_bench --scenes DIR_WITH_SHARED_SCENES --out OUT_DIR
#
# Runs encoding_bench on zdm2 (the smallest shared game level) at the medium preset with its
# light set from tests/levels/lights: bytes, write time and error against the float L2 result
# for l0, l1 and l2 in half and float (OUT_DIR/encodings.json); then the KTX2 step
# (clients/tools/ktx2/ktx2_encode.mjs, needs node and its npm packages) on the half L2 bake:
# each KTX2's bytes, encode time and error against its EXR (OUT_DIR/l2_half/ktx2.json).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$here/../.."
bin="" scenes="" out=""
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --scenes) scenes="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 1 ;;
  esac
done
[ -x "$bin" ] && [ -d "$scenes" ] && [ -n "$out" ] || { echo "usage: see the header of $0" >&2; exit 1; }
mkdir -p "$out"
"$bin" "$scenes/sauerbraten_zdm2_level_gltf/zdm2.glb" --preset medium --lights "$root/tests/levels/lights/zdm2.json" \
  --cache-dir "$out/cache" --out "$out" --json "$out/encodings.json"
node "$root/clients/tools/ktx2/ktx2_encode.mjs" "$out/l2_half"
