#!/bin/bash
# Flip one random bit at a time in a run segment (read by `clv backward`) and in a frame file
# (read by `clv analyze`). Each trial must end in a clear error (exit 1) or, where the damage
# is outside what is read, in the undamaged numbers; a panic, an abort or other numbers
# reported as a success count as bad. Prints the counts; exits 1 if any trial was bad.
#
#   scripts/fuzz.sh [TRIALS] [CLV_BINARY]      # default 200 trials of each, $CARGO_TARGET_DIR/release/clv (target/)
set -u
TRIALS=${1:-200}
[[ $TRIALS =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: TRIALS is a whole number of at least 1, not '$TRIALS'" >&2; exit 2; }
C=$(realpath -m "${2:-${CARGO_TARGET_DIR:-$(dirname "$0")/../target}/release/clv}")
[ -x "$C" ] || { echo "fuzz.sh: $C is not an executable clv (build it with cargo build --release, or give its path)" >&2; exit 2; }
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cd "$W"
# The undamaged run, frames and report every trial is compared with: a failure here is the
# setup's, not a finding.
set -e
$C forward --n 16 --aspect 1 --steps 600 --relax-steps 100 --clv-steps 100 --out base --quiet >/dev/null
cp -r base ref && $C backward ref --quiet --json --save-every 0 > ref.json
$C backward base --quiet --with-gs --out frames.mcap > /dev/null
$C analyze frames.mcap --out cleanrep --quiet
[ -s ref.json ] && [ -f cleanrep/spectrum.csv ] || { echo "fuzz.sh: $C made no reference results: is it clv?" >&2; exit 2; }
set +e
flip() { python3 -c "import random,sys; f=open(sys.argv[1],'r+b'); f.seek(0,2); n=f.tell(); o=random.randrange(n); f.seek(o); b=f.read(1); f.seek(o); f.write(bytes([b[0]^(1<<random.randrange(8))])); print(o)" "$1"; }
bad=0; ok=0; failed=0
check() {  # rc, what, offset
    if grep -q -E "panicked|memory allocation" err.txt || [ "$1" -gt 1 ]; then echo "bad: $2 at byte $3 (exit $1): $(head -c 300 err.txt)"; bad=$((bad+1));
    elif [ "$1" = 0 ]; then ok=$((ok+1)); else failed=$((failed+1)); fi
}
SEG=$(cd base && ls seg-*.mcap | tail -1)
for i in $(seq 1 "$TRIALS"); do
    rm -rf t; cp -r base t; rm -f t/backward.json
    at=$(flip "t/$SEG")
    timeout 120 $C backward t --quiet --json --save-every 0 > out.txt 2> err.txt; rc=$?
    if [ $rc = 0 ] && ! python3 -c "import json,sys; sys.exit(json.load(open('out.txt'))['exponents'] != json.load(open('ref.json'))['exponents'])"; then
        echo "bad: segment at byte $at: exit 0 with other exponents"; bad=$((bad+1)); continue
    fi
    check $rc segment "$at"
done
for i in $(seq 1 "$TRIALS"); do
    cp frames.mcap f.mcap; rm -rf rep
    at=$(flip f.mcap)
    timeout 120 $C analyze f.mcap --out rep --quiet > out.txt 2> err.txt; rc=$?
    if [ $rc = 0 ] && ! diff -q rep/spectrum.csv cleanrep/spectrum.csv > /dev/null; then
        echo "bad: frame file at byte $at: exit 0 with other results"; bad=$((bad+1)); continue
    fi
    check $rc "frame file" "$at"
done
echo "$((2 * TRIALS)) flipped bits: $bad bad, $ok gave the undamaged numbers, $failed stopped with an error"
[ $bad = 0 ]
