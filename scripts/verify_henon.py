#!/usr/bin/env python3
"""Check a clv run of the Henon map against an independent implementation in numpy.

    python3 scripts/verify_henon.py RUN_DIR FRAMES.mcap        # exit 1 on a disagreement

RUN_DIR is a finished `clv forward --system henon` run that still holds its checkpoint of
step 0 (a short run: nothing pruned), FRAMES.mcap its frame file of
`clv backward RUN_DIR --out FRAMES.mcap --with-gs` (the default C = identity start).

From the phase point and G of step 0 alone, this script iterates the map x' = a - x^2 + b y,
y' = x, its Jacobian and the QR step (positive diagonal of R) over the whole run, and then
Ginelli's backward iteration C_(n-1) = R_n^-1 C_n with column normalisation from the run's
last step. It compares with what clv wrote: the GS spectrum (spectrum.json), the CLV
spectrum (clv_spectrum.json), and in every frame the phase point, G_n, V_n = G_n C_n (up to
sign) and the local CLV and GS exponents of [t_n, t_(n+1)]. It also checks covariance from
the frames alone: J(x_n) v_n is parallel to v_(n+1), and grows by the frame's local exponent.

Only the map and the algorithm are shared with clv; the code is not. Round-off separates
the two by about 1e-14 (a chaotic orbit doubles an error every ~1.7 steps, but both codes
do the same arithmetic on the same numbers here; a disagreement of more than --tol means a
different computation).
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from read_frames import frames_to_check, run_json  # noqa: E402
from read_run import read_run  # noqa: E402


def qr_positive(a):
    q, r = np.linalg.qr(a)
    s = np.where(np.diag(r) < 0, -1.0, 1.0)
    return q * s, r * s[:, None]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run")
    p.add_argument("frames")
    p.add_argument("--tol", type=float, default=1e-11)
    args = p.parse_args()

    run_json(args.run, "verify_henon.py")  # a clear exit where it is not a run directory
    run = read_run(args.run)
    config = run["run"]["config"]
    if config["system"]["kind"] != "henon":
        sys.exit(f"{args.run}: a run of {config['system']['kind']}, not of the Henon map")
    a, b = config["system"]["a"], config["system"]["b"]
    relax, steps = config["relax_steps"], config["steps"]
    total = relax + steps
    if 0 not in run["checkpoints"]:
        sys.exit(f"{args.run}: no checkpoint of step 0 (pruned); give a run short enough to keep all its segments")
    x = run["checkpoints"][0]["phase"].copy()
    g = run["checkpoints"][0]["g"].copy()

    def jacobian(x):
        return np.array([[-2.0 * x[0], b], [1.0, 0.0]])

    xs, gs, rs = [x.copy()], [g.copy()], [None]
    for _ in range(total):
        g, r = qr_positive(jacobian(x) @ g)
        x = np.array([a - x[0] ** 2 + b * x[1], x[0]])
        xs.append(x)
        gs.append(g)
        rs.append(r)
    ln_r = np.array([np.log(np.diag(rs[n])) for n in range(1, total + 1)])
    gs_spectrum = ln_r[relax:].mean(axis=0) / config["tau"]

    frames = frames_to_check(args.frames, "verify_henon.py", 2)
    first = frames[0]["step"]
    c, cs, local = np.eye(2), {}, {}
    for n in range(total, first, -1):
        c = np.linalg.solve(rs[n], c)
        norms = np.linalg.norm(c, axis=0)
        local[n - 1] = -np.log(norms)
        c = c / norms
        cs[n - 1] = c

    dev = {"gs_spectrum": 0.0, "clv_spectrum": 0.0, "phase": 0.0, "G": 0.0, "V": 0.0, "local_clv": 0.0, "local_gs": 0.0, "covariance": 0.0, "growth": 0.0}
    with open(os.path.join(args.run, "spectrum.json")) as f:
        dev["gs_spectrum"] = np.abs(gs_spectrum - np.array(json.load(f)["exponents"])).max()
    with open(os.path.join(args.run, "clv_spectrum.json")) as f:
        clv_spectrum = np.array(json.load(f)["exponents"])
    dev["clv_spectrum"] = np.abs(np.mean([local[f["step"]] for f in frames], axis=0) - clv_spectrum).max()
    by_step = {f["step"]: f for f in frames}
    for f in frames:
        n = f["step"]
        v = gs[n] @ cs[n]
        dev["phase"] = max(dev["phase"], np.abs(f["phase"] - xs[n]).max())
        dev["G"] = max(dev["G"], np.abs(f["g"] - gs[n]).max())
        dev["V"] = max(dev["V"], np.abs(np.abs(f["v"]) - np.abs(v)).max())
        dev["local_clv"] = max(dev["local_clv"], np.abs(f["local"] - local[n]).max())
        dev["local_gs"] = max(dev["local_gs"], np.abs(f["gs_local"] - np.log(np.diag(rs[n + 1]))).max())
        if n + 1 in by_step:
            w = jacobian(f["phase"]) @ f["v"]
            cos = (w * by_step[n + 1]["v"]).sum(axis=0) / np.linalg.norm(w, axis=0)
            dev["covariance"] = max(dev["covariance"], (1.0 - np.abs(cos)).max())
            dev["growth"] = max(dev["growth"], np.abs(np.log(np.linalg.norm(w, axis=0)) - f["local"]).max())

    bad = {k: v for k, v in dev.items() if not v <= args.tol}
    print(json.dumps({"frames": len(frames), "steps": total, "tol": args.tol, "max_deviation": dev, "agree": not bad}))
    if bad:
        sys.exit(f"disagreement beyond {args.tol}: {bad}")


if __name__ == "__main__":
    main()
