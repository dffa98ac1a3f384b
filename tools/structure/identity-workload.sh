#!/usr/bin/env bash
# Usage: identity-workload.sh BIN_DIR OUT_DIR
# Runs a fixed workload (dataset; render with each model and derivatives; optimize with the
# defaults, --refine 0, --model volpath, --model dipole and a few more options, two refused
# combinations; gradcheck; a tiny accuracy experiment and the --quick experiments) with
# the `translucent` binary in BIN_DIR into OUT_DIR, for compare-outputs.py to hold two builds
# against each other.
set -euo pipefail
R=$(cd "$(dirname "$0")/../.." && pwd)
B=$1; O=$2; rm -rf "$O"; mkdir -p "$O"; cd "$O"
T="$B/translucent --threads 2 -q"
$T dataset --shape sphere --views 3 --res 24 --spp 4 --seed 3 --out ds --sigma-t 60 --albedo 0.9 > dataset.log 2>&1
for m in volpath learned dipole; do
  $T render ds --model $m --derivatives --spp 4 --seed 1 --out render-$m > render-$m.log 2>&1
done
O1="optimize --dataset ds --iterations 4 --spp 2 --final-spp 2 --seed 5"
$T $O1 --out opt-default > opt-default.log 2>&1
$T $O1 --refine 0 --out opt-refine0 > opt-refine0.log 2>&1
$T $O1 --model volpath --out opt-volpath > opt-volpath.log 2>&1
$T $O1 --model dipole --out opt-dipole > opt-dipole.log 2>&1
$T gradcheck --dataset ds --spp 4 --seed 2 --out gc > gc.log 2>&1
$T $O1 --bias-correction --out opt-bc > opt-bc.log 2>&1
$T $O1 --init-sigma-t 30,40,55 --init-albedo 0.7 --fix-albedo --monochrome --out opt-fixed > opt-fixed.log 2>&1
$T $O1 --refine 2 --refine-spp 1 --max-depth 8 --refine-keeps-moments --normalize-views --out opt-refine > opt-refine.log 2>&1
$T optimize --dataset ds --iterations 3 --spp 1 --final-spp 1 --refine-spp 4 --refine 0 --out opt-bad > opt-bad.log 2>&1 || true
$T optimize --dataset ds --model dipole --model-file shipped --out opt-bad2 > opt-bad2.log 2>&1 || true
$T experiment accuracy --shapes sphere --media 1 --views 2 --res 16 --target-spp 2 --iterations 2 --spp 1 --inits 1 --methods ours,dipole --out exp-accuracy > exp-accuracy.log 2>&1 || echo "exp accuracy failed" >> failures.log
for e in gradients planar inits volumetric prb timing; do
  $T experiment $e --quick --out exp-$e > exp-$e.log 2>&1 || echo "exp $e failed" >> failures.log
done
$T experiment robustness --quick --mesh "$R/data/meshes/spot.obj" --out exp-robustness > exp-robustness.log 2>&1 || echo "exp robustness failed" >> failures.log
