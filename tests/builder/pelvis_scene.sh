#!/bin/sh
# tools/make_pelvis_scene.py writes a scene that fsm-build turns into a model with both sides'
# adnexa (the scale benchmarks' pelvis-sized model). Skipped (77) without the shared VHF meshes.
#   pelvis_scene.sh PYTHON SCRIPT SHARED_VHF_DIR FSM_BUILD WORK_DIR
set -eu
python=$1 script=$2 shared=$3 fsm_build=$4 work=$5
[ -d "$shared" ] || { echo "no shared VHF meshes at $shared: skipped"; exit 77; }
rm -rf "$work"
"$python" "$script" "$work" --shared "$shared" --uterus-radius 0.3 >/dev/null
"$fsm_build" "$work/pelvis.json" -o "$work/pelvis.fsm" -q >"$work/report.txt" 2>&1 || {
  cat "$work/report.txt"; exit 1; }
cat "$work/report.txt"
for part in uterus ovary_left ovary_right tube_left tube_right ligament_left ligament_right \
            suspensory_left suspensory_right; do
  grep -q "^$part " "$work/report.txt" || { echo "part $part missing from the model"; exit 1; }
done
# Both sides fill alike: the mirrored ovary has the left one's sphere count within 10 %.
left=$(awk '$1 == "ovary_left" {print $4}' "$work/report.txt")
right=$(awk '$1 == "ovary_right" {print $4}' "$work/report.txt")
[ $((10 * right)) -ge $((9 * left)) ] && [ $((10 * right)) -le $((11 * left)) ] || {
  echo "ovary_right has $right spheres, ovary_left $left"; exit 1; }
