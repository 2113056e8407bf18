#!/usr/bin/env bash
# Long-run soak: a mid-size forward + backward run killed with SIGKILL at random moments and
# resumed each time, compared at the end with an uninterrupted reference run: the forward
# and CLV spectra, and every frame of the two frame files decoded (step, time, phase point,
# vectors, local exponents), bit for bit. The files themselves may differ in their MCAP
# layout (a resumed sweep writes its frames in other chunks).
#
#   scripts/soak.sh [N] [STEPS] [KILLS]      (defaults: 60 disks, 20000 steps, 30 kills)
#
# The kills come at random moments within the reference run's duration. Prints the kills
# that landed (on a running clv) and what was compared; exits non-zero on any difference,
# and when no kill landed (nothing was tested). Also reports the collisions simulated and the
# energy drift. Needs the readers' packages: python3 -m pip install mcap cbor2 numpy.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-60}; STEPS=${2:-20000}; KILLS=${3:-30}
for v in "$N" "$STEPS" "$KILLS"; do
  [[ $v =~ ^[1-9][0-9]*$ ]] || { echo "soak.sh: N, STEPS and KILLS are whole numbers of at least 1, not '$v'" >&2; exit 2; }
done
# The CLV window is a tenth of the run: fewer than 10 steps would keep none.
[ "$STEPS" -ge 10 ] || { echo "soak.sh: STEPS must be at least 10 (the backward window is STEPS / 10 steps), not $STEPS" >&2; exit 2; }
python3 -c "import mcap, cbor2, numpy" 2> /dev/null || { echo "soak.sh: the frames are compared with scripts/read_frames.py: python3 -m pip install mcap cbor2 numpy" >&2; exit 1; }
cargo build --release --quiet
CLV=${CARGO_TARGET_DIR:-target}/release/clv
WORK=$(mktemp -d /tmp/clv-soak.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
ARGS=(--n "$N" --steps "$STEPS" --relax-steps 500 --clv-steps $((STEPS / 10)) --checkpoint-every 100 --quiet)
ms() { echo $(($(date +%s%N) / 1000000)); }
# Sleep a random time below $1 milliseconds (at least 1).
pause() { local d=$((RANDOM * 32768 + RANDOM)); d=$((d % ($1 > 1 ? $1 : 1) + 1)); sleep "$((d / 1000)).$(printf %03d $((d % 1000)))"; }
# Kill clv $pid; 0 if it was still running (it died of the SIGKILL).
landed() { local status=0; kill -9 "$pid" 2> /dev/null || true; wait "$pid" 2> /dev/null || status=$?; [ "$status" -eq 137 ]; }

echo "reference: N = $N, $STEPS steps"
t0=$(ms)
$CLV forward "${ARGS[@]}" --out "$WORK/ref" --json > "$WORK/ref.json"
t1=$(ms)
$CLV backward "$WORK/ref" --quiet --out "$WORK/ref-frames.mcap" --json > "$WORK/ref-clv.json"
t2=$(ms)
forward_ms=$((t1 - t0)); backward_ms=$((t2 - t1))

landed_forward=0
for ((i = 0; i < KILLS; i++)); do
  if [ -f "$WORK/soak/run.json" ]; then
    $CLV forward --resume "$WORK/soak" --quiet > /dev/null 2>&1 &
  else
    $CLV forward "${ARGS[@]}" --out "$WORK/soak" > /dev/null 2>&1 &
  fi
  pid=$!
  pause "$forward_ms"
  if landed; then landed_forward=$((landed_forward + 1)); fi
  [ -f "$WORK/soak/spectrum.json" ] && break
done
$CLV forward --resume "$WORK/soak" --quiet --json > "$WORK/soak.json"
landed_backward=0
for ((i = 0; i < (KILLS + 2) / 3; i++)); do
  $CLV backward "$WORK/soak" --quiet --out "$WORK/soak-frames.mcap" $([ -f "$WORK/soak/backward.json" ] && echo --resume) > /dev/null 2>&1 &
  pid=$!
  pause "$backward_ms"
  if landed; then landed_backward=$((landed_backward + 1)); else break; fi
done
if [ ! -f "$WORK/soak/clv_spectrum.json" ]; then
  $CLV backward "$WORK/soak" --quiet --out "$WORK/soak-frames.mcap" --resume > /dev/null
fi

python3 - "$WORK" "$landed_forward" "$landed_backward" << 'PY'
import json, sys
import numpy as np
sys.path.insert(0, "scripts")
from read_frames import read_frames
work, kf, kb = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
ref, soak = json.load(open(f"{work}/ref.json")), json.load(open(f"{work}/soak.json"))
rc = json.load(open(f"{work}/ref/clv_spectrum.json"))
sc = json.load(open(f"{work}/soak/clv_spectrum.json"))
def same(a, b):
    if a is None or b is None:
        return a is None and b is None
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes() if isinstance(a, np.ndarray) else a == b
ra, sa = list(read_frames(f"{work}/ref-frames.mcap")), list(read_frames(f"{work}/soak-frames.mcap"))
differ = [r["step"] for r, s in zip(ra, sa) if r.keys() != s.keys() or not all(same(r[k], s[k]) for k in r)]
frames_same = len(ra) == len(sa) and not differ
forward_same, clv_same = ref["exponents"] == soak["exponents"], rc["exponents"] == sc["exponents"]
print(f"kills landed: {kf + kb} ({kf} forward, {kb} backward)")
print(f"collisions: {soak['statistics']['collisions']}, energy drift {soak['statistics']['energy_drift']:.2e}")
print(f"forward spectrum identical: {forward_same}; CLV spectrum identical: {clv_same}")
print(f"frames: {len(ra)} and {len(sa)}, decoded" + (" identical" if frames_same else f", differ (first at step {differ[0]})" if differ else ", differ in number"))
if kf + kb == 0:
    print("soak.sh: no kill landed (each run finished before its kill), so nothing was tested; give more STEPS or a larger N", file=sys.stderr)
    sys.exit(1)
sys.exit(0 if forward_same and clv_same and frames_same else 1)
PY
