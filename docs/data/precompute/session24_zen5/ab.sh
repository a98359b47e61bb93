#!/bin/bash
# usage: ab.sh NAME BIN_A BIN_B ROUNDS [scene]
name=$1; A=$2; Bn=$3; R=$4; S=${5:-/work/shared/scenes/cornell_box_original_gltf/CornellBox-Original.gltf}
cd $(dirname "$0")
for r in $(seq 1 $R); do
  for which in a b; do
    bin=$A; [ $which = b ] && bin=$Bn
    $bin --scene $S --pairs 5 --json ${name}_${which}$r.json > /dev/null 2>&1
    python3 - ${name}_${which}$r.json <<'PY'
import json,sys
d=json.load(open(sys.argv[1]))['link_generation_vs_raw_embree']
t=d['pair_phase_ticks_per_cache']
print(sys.argv[1], 'median %.3f own/trace %.3f total %d' % (d['median_pair_ratio'], d['pair_own_work_per_trace'], sum(t.values())), ' '.join('%s %d' % (k, v) for k, v in t.items()))
PY
  done
done
echo ABDONE
