#!/usr/bin/env python3
"""How the leading Lyapunov instability of hard disks scales with the number of disks N.

Beyond the paper, which cites the results (its Sec. 5.2): at fixed density, the fraction of
disks that carry the maximal perturbation, W_1 = exp(<S>)/N of v^1 = g^1, falls like
N^-eta (strong localisation), and lambda_1 approaches its thermodynamic limit slowly. For
each N this script runs the whole pipeline with one vector (a step costs O(collisions), so
N = 1024 takes under a minute), and for the smaller N the full spectrum for the
Kolmogorov-Sinai entropy per disk, h_KS / N, which has a thermodynamic limit too.

    python3 scripts/scaling.py --out scaling                   # N = 16 .. 1024, two to three minutes
    python3 scripts/scaling.py --out s --n 8,16 --steps 600 --clv-steps 200

Stopped, the same command again continues the study (study.py).

Writes OUT/scaling.csv (N, lambda_1, W_1 and h_KS / N with their errors, h_KS where the
full spectrum was computed) and OUT/fit.json (eta from a least-squares line of ln W_1
against ln N, with its standard error), and prints both. The runs stay in OUT/runs, with the
full spectra (clv forward --json) as nN-full.json.
"""
import csv
import json
import math
import os
import sys

import numpy as np

import study


def main():
    ap = study.arguments(__doc__, "16,32,64,128,256,512,1024", "scaling.csv", min_n=2)
    ap.add_argument("--steps", type=study.whole(1), default=20000, help="forward steps of tau = 0.6 after the relaxation")
    ap.add_argument("--clv-steps", type=study.whole(1), default=2000, help="frames of the backward window (W_1 is averaged over them)")
    ap.add_argument("--full-up-to", type=study.whole(0), default=64, help="compute the full spectrum (h_KS) for N up to this")
    a = ap.parse_args()
    s = study.Study("scaling.py", a, "scaling.csv")
    common = ["--density", str(a.density), "--aspect", "1", "--quiet"]

    rows = []
    for n in s.ns:
        run_dir, report = os.path.join(s.runs, f"n{n}-run"), os.path.join(s.runs, f"n{n}-report")
        s.forward(run_dir, ["--n", str(n), "--vectors", "1", "--steps", str(a.steps), "--clv-steps", str(a.clv_steps)] + common)
        with open(os.path.join(run_dir, "spectrum.json")) as f:
            spectrum = json.load(f)
        s.backward_into_analyze(run_dir, report, "localization", ["localization.csv"])
        with open(os.path.join(report, "localization.csv")) as f:
            first = next(csv.DictReader(f))
        w1 = float(first["W_clv"])
        row = {"N": n, "lambda_1": spectrum["exponents"][0], "lambda_1_stderr": spectrum["stderr"][0], "W_1": w1, "W_1_stderr": float(first["stderr_clv"]), "h_KS_per_disk": math.nan, "h_KS_per_disk_stderr": math.nan}
        if n <= a.full_up_to:
            full = s.saved_forward(os.path.join(s.runs, f"n{n}-full.json"), n, a.density, 1.0, a.steps, ["--n", str(n), "--steps", str(a.steps)] + common)
            h = full["ks_entropy"]
            row["h_KS_per_disk"], row["h_KS_per_disk_stderr"] = h["value"] / n, h["stderr"] / n
        rows.append(row)
        print(f"N = {n:5d}: lambda_1 = {row['lambda_1']:.4f} +- {row['lambda_1_stderr']:.1e}, W_1 = {w1:.4f} +- {row['W_1_stderr']:.1e}, h_KS/N = {row['h_KS_per_disk']:.4f}", file=sys.stderr)

    s.write_table(rows)
    # ln W_1 = c - eta ln N: least squares, with the standard error of the slope.
    x = np.log([r["N"] for r in rows])
    y = np.log([r["W_1"] for r in rows])
    minus_eta, se = study.slope(x, y)
    # The slope between neighbouring N: constant for a pure power law. Its error from the two
    # W_1 errors (relative errors are those of ln W_1).
    rel = [r["W_1_stderr"] / r["W_1"] for r in rows]
    local = [
        {"from": int(s.ns[i]), "to": int(s.ns[i + 1]), "eta": -(y[i + 1] - y[i]) / (x[i + 1] - x[i]), "eta_stderr": float(np.hypot(rel[i], rel[i + 1]) / (x[i + 1] - x[i]))}
        for i in range(len(s.ns) - 1)
    ]
    fit = {"clv": s.version(), "eta": -minus_eta, "eta_stderr": se, "points": len(x), "local_eta": local, "density": a.density, "steps": a.steps, "clv_steps": a.clv_steps}
    with open(os.path.join(a.out, "fit.json"), "w") as f:
        json.dump(fit, f, indent=2)
    between = ", ".join(f"{l['eta']:.3f} +- {l['eta_stderr']:.3f} ({l['from']}-{l['to']})" for l in local)
    error = " (no error from two points)" if se is None else f" +- {se:.3f}"
    print(f"W_1 ~ N^-eta: eta = {fit['eta']:.3f}{error} from N = {s.ns[0]}..{s.ns[-1]}; between neighbours {between}; table {s.table}")


if __name__ == "__main__":
    main()
