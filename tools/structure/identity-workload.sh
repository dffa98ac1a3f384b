#!/usr/bin/env bash
# Usage: identity-workload.sh BIN_DIR OUT_DIR
# Runs a fixed workload (dataset; render with each model and derivatives; optimize with the
# defaults, --refine 0, --model volpath, --model dipole; gradcheck; the --quick experiments) with
# the `translucent` binary in BIN_DIR into OUT_DIR, for compare-outputs.py to hold two builds
# against each other.
set -euo pipefail
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
for e in gradients planar inits volumetric prb timing; do
  $T experiment $e --quick --out exp-$e > exp-$e.log 2>&1 || echo "exp $e failed" >> failures.log
done
