#!/usr/bin/env bash
# Reproduces the force-estimation figures of docs/user-guide.md ("What the estimators achieve"): the
# simulated recordings, every model, and their evaluations, with the project's own commands.
# Usage: scripts/force-figures.sh BUILD_DIR [WORK_DIR]. Everything goes to WORK_DIR (default
# BUILD_DIR/force-work, removed first); each evaluation's table is printed and kept in
# WORK_DIR/eval-*/eval.json. About 30 minutes on two cores and 3 GB of disk (1 kHz CSVs).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:?usage: force-figures.sh BUILD_DIR [WORK_DIR]}
work=${2:-$build/force-work}
v="$(realpath "$build/apps/viscera/viscera")"
scenes="$(realpath scenes)"
rm -rf "$work"
mkdir -p "$work"
cd "$work"

simulate() { "$v" force simulate "$@" | tail -1; }
train() { "$v" force train "$@" --quiet; }
evaluate() {  # MODEL NAME DATA...
  local model=$1 name=$2
  shift 2
  echo "== $model on $name"
  "$v" force eval "$model" "$@" --out "eval-$model-$name" --no-plot --threads 1
}
trocar=(--workspace trocar --trocar --seal)

# Recordings: free space (training 40 min, held out 2 min), palpation (3 x 2 min held out, 10 min
# for the direct estimator), inside a trocar (4 + 4 min of calibration motion that covers the
# workspace for the corrections, 4 min of teleoperation-like motion for comparison, 3 x 1 min
# without contact and 2 min palpating held out), and palpation of the FEM gel of
# scenes/psm_phantom_arm.xml.
simulate free_a --duration 600 --seed 1
simulate free_c --duration 1800 --seed 11
simulate free_b --duration 120 --seed 2
for s in 3 4 5; do simulate "contact_$s" --duration 120 --seed "$s" --phantom; done
simulate contact_train --duration 600 --seed 31 --phantom
simulate trocar_cal --duration 240 --seed 21 --step 0.5 "${trocar[@]}"
simulate trocar_cal_b --duration 240 --seed 24 --step 0.5 "${trocar[@]}"
simulate trocar_walk --duration 240 --seed 21 "${trocar[@]}"
for s in 22 25 26; do simulate "trocar_test_$s" --duration 60 --seed "$s" "${trocar[@]}"; done
simulate trocar_contact --duration 120 --seed 23 "${trocar[@]}" --phantom
simulate scene_a --duration 120 --seed 41 --scene "$scenes/psm_phantom_arm.xml" --transform "$scenes/psm_to_phantom.txt" \
  --depth 0:0.006 --workspace trocar

# Free-space models on the 40 min.
train free_a free_c --kind physical --out physical
train free_a free_c --kind mlp --out mlp --epochs 20 --threads 2
train free_a free_c --kind snn --out snn --epochs 20 --threads 2
train free_a free_c --kind mlp --window 10 --out mlp_w10 --epochs 20 --threads 2
train free_a free_c --kind snn --window 10 --out snn_w10 --epochs 20 --threads 2
train contact_train --kind direct --out direct --epochs 30 --threads 2
# Trocar: corrections of the free-space networks, and LSTMs on the trocar data alone.
train trocar_cal --kind correction --base mlp --out corr4 --epochs 20 --threads 2
train trocar_cal trocar_cal_b --kind correction --base mlp --out corr8 --epochs 20 --threads 2
train trocar_walk --kind correction --base mlp --out corr4_walk --epochs 20 --threads 2
train trocar_cal --kind correction --base mlp_w10 --out corr4_w10 --epochs 20 --threads 2
train trocar_cal --kind lstm --out lstm4 --epochs 20 --threads 2
train trocar_cal trocar_cal_b --kind lstm --out lstm8 --epochs 20 --threads 2

for m in physical mlp snn mlp_w10 snn_w10; do evaluate "$m" free free_b; done
for m in physical mlp snn mlp_w10 direct; do evaluate "$m" contact contact_3 contact_4 contact_5; done
for m in physical mlp snn mlp_w10; do evaluate "$m" scene scene_a; done
for m in mlp corr4 corr8 corr4_walk mlp_w10 corr4_w10 lstm4 lstm8; do
  evaluate "$m" trocar trocar_test_22 trocar_test_25 trocar_test_26
done
for m in mlp corr4 corr8 corr4_w10 lstm4 lstm8; do evaluate "$m" trocar-contact trocar_contact; done
for m in mlp corr4 physical lstm4; do "$v" force bench "$m" trocar_test_22 --threads 1; done
