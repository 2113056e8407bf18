#!/usr/bin/env python3
"""The Lyapunov instability of hard disks against the density of the fluid.

Beyond the paper, which studies one density (rho = 0.7): for N disks in a square box at
densities across the fluid, the full spectrum of each gives lambda_1, the Kolmogorov-Sinai
entropy per disk h_KS / N and the smallest positive exponent lambda_(2N-3) (the slowest
mode), each with its error. Beside them the collision frequency per disk nu, measured,
against the Enskog value 2 rho g(sigma) sqrt(pi kT / m) with Henderson's contact value
g = (1 - 7 eta / 16) / (1 - eta)^2 (eta = pi rho / 4, kT = m = sigma = 1): the check that the
dynamics is the hard-disk fluid, and the scale of the exponents, which the script also
gives per collision (lambda_1 / nu, h_KS / (N nu)).

    python3 scripts/density.py --out density               # N = 36, rho = 0.1 .. 0.8, about 15 s
    python3 scripts/density.py --out d --n 8 --densities 0.2,0.8 --steps 400

Stopped, the same command again continues the study (study.py).

Writes OUT/density.csv and prints it; each run's spectrum (clv forward --json) stays in
OUT/runs.
"""
import math
import os
import sys

import study


def enskog(rho):
    """Collision frequency per disk of the hard-disk fluid (Enskog, Henderson's g(sigma))."""
    eta = math.pi * rho / 4
    g = (1 - 7 * eta / 16) / (1 - eta) ** 2
    return 2 * rho * g * math.sqrt(math.pi)


def main():
    ap = study.arguments(__doc__, "36", "density.csv", min_n=2, one_n=True, density=False)
    ap.add_argument("--densities", type=study.numbers(study.positive, "positive densities", 2, "0.1,0.4,0.7"), default="0.1,0.2,0.3,0.4,0.5,0.6,0.7,0.8", help="number densities rho, comma-separated (the fluid: below about 0.88)")
    ap.add_argument("--steps", type=study.whole(1), default=4000, help="forward steps of tau = 0.6 after the relaxation")
    a = ap.parse_args()
    s = study.Study("density.py", a, "density.csv")
    n, densities = s.ns[0], a.densities

    rows = []
    for rho in densities:
        r = s.saved_forward(os.path.join(s.runs, f"rho{rho}.json"), n, rho, 1.0, a.steps, ["--n", str(n), "--density", str(rho), "--aspect", "1", "--steps", str(a.steps), "--quiet"])
        lam, err, st = r["exponents"], r["stderr"], r["statistics"]
        time = (st["steps"] + st["relax_steps"]) * r["config"]["tau"]
        nu = 2 * st["collisions"] / (n * time)
        h = r["ks_entropy"]
        slow = 2 * n - 4  # 0-based index of lambda_(2N-3), the smallest positive exponent
        row = {
            "density": rho,
            "packing_fraction": math.pi * rho / 4,
            "lambda_1": lam[0], "lambda_1_stderr": err[0],
            "h_KS_per_disk": h["value"] / n, "h_KS_per_disk_stderr": h["stderr"] / n,
            "lambda_2N-3": lam[slow], "lambda_2N-3_stderr": err[slow],
            "nu": nu, "nu_enskog": enskog(rho),
            "lambda_1_per_collision": lam[0] / nu, "h_KS_per_disk_per_collision": h["value"] / n / nu,
        }
        rows.append(row)
        print(f"rho = {rho:.3f}: lambda_1 = {lam[0]:.4f} +- {err[0]:.1e}, h_KS/N = {row['h_KS_per_disk']:.4f}, lambda_2N-3 = {lam[slow]:.4f}, nu = {nu:.3f} (Enskog {row['nu_enskog']:.3f}), lambda_1/nu = {row['lambda_1_per_collision']:.3f}", file=sys.stderr)

    s.write_table(rows)
    worst = max(abs(r["nu"] / r["nu_enskog"] - 1) for r in rows)
    print(f"{len(rows)} densities for N = {n} ({s.version()}); the collision frequency is within {100 * worst:.1f} % of Enskog's; table {s.table}")


if __name__ == "__main__":
    main()
