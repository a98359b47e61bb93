#!/bin/bash
# Two runs of every shared scene and the bundled box, current tree (16d0948), this Zen 5 VM.
B=/work/main/build-lead/bench/precompute/precompute_bench
SC=/work/shared/scenes
declare -A S=(
 [cbo]=$SC/cornell_box_original_gltf/CornellBox-Original.gltf
 [emissive]=$SC/khronos_EmissiveStrengthTest/EmissiveStrengthTest.gltf
 [sd]=$SC/revelry_ShadowsDirectional/shadows-directional.gltf
 [ss]=$SC/revelry_ShadowsSpot/shadows-spot.gltf
 [vinc3r]=$SC/cornell_box_vinc3r_lightmapuv/cornellBox-2.80-Eevee-gltf.gltf
 [lamp]=$SC/khronos_LightsPunctualLamp/LightsPunctualLamp.gltf
 [multiuv]=$SC/khronos_MultiUVTest/MultiUVTest.gltf
)
cd $(dirname "$0")
for run in 1 2; do
  for k in cbo emissive sd ss vinc3r lamp multiuv; do
    $B --scene ${S[$k]} --pairs 5 --json pb_r${run}_$k.json > pb_r${run}_$k.txt 2>&1
  done
  $B --pairs 5 --json pb_r${run}_bundled.json > pb_r${run}_bundled.txt 2>&1
done
$B --scene $SC/sauerbraten_zdm2_level_gltf/zdm2.glb --resolution 512 --pairs 3 --json pb_zdm2_512.json > pb_zdm2_512.txt 2>&1
echo ALLDONE
