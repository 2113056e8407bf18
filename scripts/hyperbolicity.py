#!/usr/bin/env python3
"""Does the angle between the unstable and stable subspaces of hard disks close as N grows?

The paper's Sec. 5.6 finds the distribution of Psi, the smallest principal angle between
E^u = v^1 + ... + v^(2N-3) and E^s = v^(2N+4) + ... + v^(4N), well bounded away from zero
for N = 198, so that the system is (partially) hyperbolic, and speculates that for N -> oo
it may reach the origin. This script measures that distribution against N at fixed density
and box shape: for each N a forward run with all 4N vectors, the backward stage streaming
into `clv analyze --only transversality` (Psi in every m-th frame, the same number of
frames for every N), and the quantiles of Psi.

    python3 scripts/hyperbolicity.py --out hyp                 # N = 16 .. 196, 2.5 min on 2 idle cores
    python3 scripts/hyperbolicity.py --out h --n 8,12 --steps 400 --clv-steps 100

Stopped, the same command again continues the study (study.py).

Writes OUT/hyperbolicity.csv (N, frames, and Psi's minimum, 5 % quantile, median and mean
with its standard error, in degrees; for comparison the median smallest angle between
random subspaces of the same dimensions in the 4N - 6 dimensions orthogonal to the null
space, where E^u and E^s lie, which closes like 1/N; and, for the paper's other open question (Sec. 6), how often the
splitting E^u + E^0 + E^s is violated, some finite-time exponent of E^u below one of E^0 or
one of E^0 below one of E^s, in single steps and in the longest windows: never means a
dominated splitting) and OUT/fit.json (the slopes of ln median and ln q05
against ln N with their standard errors), and prints both. The runs and reports stay in
OUT/runs.
"""
import csv
import json
import math
import os
import sys

import numpy as np

import study


def batch_stderr(x, blocks=10):
    """Standard error of the mean from `blocks` batch means (neighbouring frames are correlated)."""
    b = min(blocks, len(x))
    if b < 2:
        return math.nan
    means = [np.mean(c) for c in np.array_split(np.asarray(x), b)]
    return float(np.std(means, ddof=1) / math.sqrt(b))


def random_psi(d, m, samples, rng):
    """Median over `samples` pairs of random m-dimensional subspaces of R^d of their smallest
    principal angle, in degrees: the baseline of no structure. Its sine is the smallest
    singular value of (1 - Q1 Q1^T) Q2 (accurate for small angles, unlike arccos)."""
    angles = []
    for _ in range(samples):
        q1, _ = np.linalg.qr(rng.standard_normal((d, m)))
        q2, _ = np.linalg.qr(rng.standard_normal((d, m)))
        s = np.linalg.svd(q2 - q1 @ (q1.T @ q2), compute_uv=False)
        angles.append(math.degrees(math.asin(min(1.0, s.min()))))
    return float(np.median(angles))


def splitting_violations(path):
    """From the report's domination test: the largest fraction of windows in which the
    splitting E^u | E^0 or E^0 | E^s is violated (some finite-time exponent of the lower
    block above one of the upper), at the shortest window (a single step) and at the
    longest; 0 at the longest means the splitting E^u + E^0 + E^s is dominated in these
    frames."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    worst = [max(float(r["split_unstable_null"]), float(r["split_null_stable"])) for r in rows]
    return {"splitting_violated_shortest": worst[0], "splitting_violated_longest": worst[-1], "longest_window": int(float(rows[-1]["delta"]))}


def main():
    ap = study.arguments(__doc__, "16,36,64,100,144,196", "hyperbolicity.csv", min_n=4)
    ap.add_argument("--aspect", type=study.positive, default=1.0, help="box aspect ratio Ly/Lx, the same for every N")
    ap.add_argument("--steps", type=study.whole(1), default=3000, help="forward steps of tau = 0.6 after the relaxation")
    ap.add_argument("--clv-steps", type=study.whole(1), default=1000, help="steps of the backward window")
    ap.add_argument("--every", type=study.whole(1), default=5, help="Psi from the frames of every m-th step (V is formed for those only)")
    ap.add_argument("--threads", type=study.whole(1), default=min(2, os.cpu_count() or 1))
    a = ap.parse_args()
    if a.clv_steps < a.every:
        ap.error(f"argument --every: expected at most --clv-steps ({a.clv_steps}), not {a.every}")
    s = study.Study("hyperbolicity.py", a, "hyperbolicity.csv")
    common = ["--density", str(a.density), "--aspect", str(a.aspect), "--threads", str(a.threads), "--quiet"]

    rows = []
    for n in s.ns:
        run_dir, report = os.path.join(s.runs, f"n{n}-run"), os.path.join(s.runs, f"n{n}-report")
        s.forward(run_dir, ["--n", str(n), "--steps", str(a.steps), "--clv-steps", str(a.clv_steps)] + common)
        s.backward_into_analyze(run_dir, report, "transversality,local_exponents", ["transversality.csv", "domination.csv"], a.every)
        with open(os.path.join(report, "transversality.csv")) as f:
            psi = np.degrees([float(r["psi_unstable_stable"]) for r in csv.DictReader(f)])
        if len(psi) == 0 or not np.all(np.isfinite(psi)):
            s.fail(f"{report}/transversality.csv holds no finite Psi")
        row = {
            "N": n,
            "frames": len(psi),
            "psi_min_deg": float(psi.min()),
            "psi_q05_deg": float(np.quantile(psi, 0.05)),
            "psi_median_deg": float(np.median(psi)),
            "psi_mean_deg": float(psi.mean()),
            "psi_mean_stderr_deg": batch_stderr(psi),
            "random_median_deg": random_psi(4 * n - 6, 2 * n - 3, 20, np.random.default_rng(n)),
        }
        row.update(splitting_violations(os.path.join(report, "domination.csv")))
        rows.append(row)
        print(f"N = {n:4d}: Psi min {row['psi_min_deg']:.2f}, q05 {row['psi_q05_deg']:.2f}, median {row['psi_median_deg']:.2f}, "
              f"mean {row['psi_mean_deg']:.2f} +- {row['psi_mean_stderr_deg']:.2f} degrees over {len(psi)} frames "
              f"(random subspaces: median {row['random_median_deg']:.3g}); E^u + E^0 + E^s violated in {row['splitting_violated_shortest']:.3g} of single "
              f"steps, {row['splitting_violated_longest']:.3g} of windows of {row['longest_window']}", file=sys.stderr)

    s.write_table(rows)
    x = np.log([r["N"] for r in rows])
    fit = {"clv": s.version(), "density": a.density, "aspect": a.aspect, "steps": a.steps, "clv_steps": a.clv_steps, "every": a.every}
    for key in ["median", "q05"]:
        fit[f"slope_ln_{key}"], fit[f"slope_ln_{key}_stderr"] = study.slope(x, np.log([r[f"psi_{key}_deg"] for r in rows]))
    with open(os.path.join(a.out, "fit.json"), "w") as f:
        json.dump(fit, f, indent=2)
    err = lambda k: "" if fit[k] is None else f" +- {fit[k]:.3f}"
    print(f"Psi ~ N^s from N = {s.ns[0]}..{s.ns[-1]}: median s = {fit['slope_ln_median']:.3f}{err('slope_ln_median_stderr')}, "
          f"5 % quantile s = {fit['slope_ln_q05']:.3f}{err('slope_ln_q05_stderr')}; table {s.table}")


if __name__ == "__main__":
    main()
