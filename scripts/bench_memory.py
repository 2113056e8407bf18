#!/usr/bin/env python3
"""Peak memory (RSS) of the forward and backward stages against the run length.

Runs `clv forward` for S and 10 S steps and `clv backward` for CLV windows W and 10 W on the
same system, each in a child process, and reports the children's peak resident set size
(getrusage). Bounded memory means the ratios stay close to 1.

    python3 scripts/bench_memory.py [--n 40] [--steps 2000] [--clv 400] [--clv-bin target/release/clv]
"""
import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile


def peak_rss_kb(cmd):
    """Run cmd in a fresh child (via a tiny wrapper so each measurement has its own maximum)."""
    wrapper = "import resource,subprocess,sys; subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
    out = subprocess.run([sys.executable, "-c", wrapper] + cmd, capture_output=True, text=True)
    if out.returncode != 0:  # clv's own message, not the wrapper's traceback
        said = [l for l in out.stderr.splitlines() if l.startswith("clv")] or out.stderr.strip().splitlines()[-1:]
        sys.exit(f"bench_memory.py: {' '.join(cmd[:2])} ... failed: " + " / ".join(said))
    return int(out.stdout.strip())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--clv", type=int, default=400)
    ap.add_argument("--clv-bin", default=os.path.join(os.environ.get("CARGO_TARGET_DIR") or os.path.join(os.path.dirname(__file__), "..", "target"), "release", "clv"))
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="clv-mem-")
    rows = []
    try:
        base = [a.clv_bin, "forward", "--n", str(a.n), "--relax-steps", "100", "--quiet"]
        for scale in (1, 10):
            steps = a.steps * scale
            out = os.path.join(tmp, f"fwd{scale}")
            rss = peak_rss_kb(base + ["--steps", str(steps), "--clv-steps", str(a.clv), "--transient", str(a.clv // 2), "--out", out])
            rows.append({"stage": "forward", "steps": steps, "peak_rss_mb": rss / 1024})
        for scale in (1, 10):
            clv = a.clv * scale
            out = os.path.join(tmp, f"bwd{scale}")
            if subprocess.run(base + ["--steps", str(4 * clv), "--clv-steps", str(clv), "--transient", str(clv // 2), "--out", out], stdout=subprocess.DEVNULL).returncode != 0:
                sys.exit("bench_memory.py: the forward run for the backward stage failed (message above)")
            rss = peak_rss_kb([a.clv_bin, "backward", out, "--quiet", "--save-every", "0"])
            rows.append({"stage": "backward", "clv_steps": clv, "peak_rss_mb": rss / 1024})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    f, b = [r for r in rows if r["stage"] == "forward"], [r for r in rows if r["stage"] == "backward"]
    result = {
        "n": a.n, "rows": rows,
        "forward_ratio_10x_steps": f[1]["peak_rss_mb"] / f[0]["peak_rss_mb"],
        "backward_ratio_10x_window": b[1]["peak_rss_mb"] / b[0]["peak_rss_mb"],
    }
    for r in rows:
        print(f"{r['stage']:9s} {r.get('steps', r.get('clv_steps')):>8} steps  peak RSS {r['peak_rss_mb']:8.1f} MB", file=sys.stderr)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
