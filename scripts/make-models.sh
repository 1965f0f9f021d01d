#!/usr/bin/env bash
# Makes the learned models shipped in scenes/models/ with the project's own commands:
#   stepper_coarse    a graph U-Net stepper for scenes/gel_phantom_coarse.xml, trained on randomised
#                     palpations of the scene (viscera learn record / train);
#   corrector_coarse  a 2D correction for the same phantom simulated 4x too stiff under gravity,
#                     trained on measured clouds of a 5 kPa phantom (a virtual depth camera, 1 mm noise).
# Usage: scripts/make-models.sh BUILD_DIR [WORK_DIR]. Each model is trained in WORK_DIR (default
# BUILD_DIR/models-work, removed first) and then replaces the shipped folder. About 70 minutes on
# two cores.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:?usage: make-models.sh BUILD_DIR [WORK_DIR]}
work=${2:-$build/models-work}
v="$build/apps/viscera/viscera"
scene=scenes/gel_phantom_coarse.xml
box="0 0 0 68.7 39.3 35.8"
gravity="/root.gravity=0 0 -9810"
camera=(--position "34.35 -150 330" --look-at "34.35 19.65 30" --rate 10 --sigma0 "1 mm" --tissue-only --no-wrench)

rm -rf "$work"
mkdir -p "$work" scenes/models

# The stepper: 96 palpations of 20 s (top and sides, depth 2-6 mm) to learn from, in two
# recordings whose seeds are far enough apart that they share no rollout (rollout k uses seed + k);
# the network predicts next offsets, with a cosine learning-rate schedule over 14 epochs.
"$v" learn record "$scene" --out "$work/rollouts" --rollouts 48 --time 20 --seed 1
"$v" learn record "$scene" --out "$work/rollouts101" --rollouts 48 --time 20 --seed 101
"$v" learn train "$work/rollouts" "$work/rollouts101" --out "$work/stepper_coarse" --width 128 --instrument-all \
  --noise 0.02 --output offset --schedule cosine --epochs 14 --warmup 1 --seed 1

# The corrector: a 90 s measured palpation of the top (5 kPa, gravity on), replayed by the scene
# with a 4x too stiff phantom.
"$v" trajectory --box "$box" --duration 90 --seed 21 --faces top --depth 6 --out "$work/palpation.csv"
"$v" dataset make "$scene" --out "$work/measured" --time 90 --set "instrument/replay.filename=$(realpath "$work")/palpation.csv" \
  --set "$gravity" "${camera[@]}" --quiet
"$v" learn record "$scene" --data "$work/measured" --out "$work/pairs" --set "$gravity" --set "phantom/fem.youngModulus=20 kPa"
"$v" learn train "$work/pairs" --out "$work/corrector_coarse" --width 16 --epochs 30 --seed 1

for m in stepper_coarse corrector_coarse; do
  rm -rf "$work/$m/checkpoint"
  rm -rf "scenes/models/$m.old"
  if [ -d "scenes/models/$m" ]; then mv "scenes/models/$m" "scenes/models/$m.old"; fi
  mv "$work/$m" "scenes/models/$m"
  rm -rf "scenes/models/$m.old"
done
echo "models: scenes/models/stepper_coarse, scenes/models/corrector_coarse (training data and logs in $work)"
