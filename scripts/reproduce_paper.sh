#!/usr/bin/env bash
# Reproduce every figure and table of Bosetti & Posch, "Covariant Lyapunov Vectors for Rigid
# Disk Systems", end to end: 198 disks, density 0.7, Ly/Lx = 2/11, tau = 0.6, 2.5e5 forward
# steps in all (t_0 = 1e4 of relaxation, then 2.4e5), CLVs for the last 2.5e4 (section 5).
#
#   scripts/reproduce_paper.sh [OUT_DIR] [THREADS]      (defaults: paper-out, 2)
#
# A relative OUT_DIR is taken from the directory the script is started in.
#
# How long, on a 2-core machine of the CI kind (two threads): forward 1.18 h (measured
# 2026-11-23), backward piped into every analysis 10.9 min (measured 2026-11-24); 1.36 h.
# On a faster host (2026-11-27, gemm at 180-200 GFLOP/s): 53.6 + 8.7 min, 1.04 h.
# The run is resumable: start the script again after a crash or a kill and it continues
# (on THREADS threads, which need not be those it started with: the numbers do not change).
# Disk: about 3 GB for the kept checkpoints; the frames are streamed to the analyses.
set -euo pipefail
OUT=${1:-paper-out}
case $OUT in /*) ;; *) OUT=$PWD/$OUT ;; esac
THREADS=${2:-2}
cd "$(dirname "$0")/.."
cargo build --release --quiet
CLV=${CARGO_TARGET_DIR:-target}/release/clv
if [ -f "$OUT/run/run.json" ]; then
  $CLV forward --resume "$OUT/run" --threads "$THREADS"
else
  $CLV forward --n 198 --density 0.7 --aspect 2/11 --tau 0.6 --relax-steps 10000 --steps 240000 \
    --clv-steps 25000 --threads "$THREADS" --out "$OUT/run"
fi
$CLV inspect "$OUT/run"
# The backward pass streams every frame into the analyses without writing them; add
# `--save-every 100 --out FILE` to a separate backward run to keep some. The vector
# statistics use the frames of every 62nd step (about 400; the paper averages 100 frames
# 250 tau apart), the spectrum and local exponents every frame; so the backward pass forms
# the covariant vectors (and copies the GS vectors, 10 MB a frame) only for those steps.
# A rerun of this script regenerates the report (--overwrite).
$CLV backward "$OUT/run" --with-gs --vectors-every 62 --threads "$THREADS" --out - | $CLV analyze - --out "$OUT/report" --overwrite
echo "figures and tables: $OUT/report/index.html"
