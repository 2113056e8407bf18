#!/usr/bin/env python3
"""Check the covariant vectors of a small hard-disk run by finite differences of the flow.

    python3 scripts/verify_disks.py RUN_DIR FRAMES.mcap [--sample 8]   # exit 1 on a disagreement

FRAMES.mcap is a frame file of `clv backward RUN_DIR --out FRAMES.mcap --with-gs` with every
frame (the default --save-every 1). For small N (all pairs are searched for each collision).

Covariance without tangent-space code: for a sample of frames n, the phase point is moved by
eps v^j (each covariant vector in turn), both points are carried over one tau by this
script's own event-driven integrator of elastic unit disks in the periodic box, and the
central difference of the points moved by +eps v^j and -eps v^j, over 2 eps, must point along v^j of frame n+1 and have grown by the frame's
local exponent, e^(lambda_j(n) tau). Only the physics is shared with clv; the code is not.
The central difference carries an error of order eps^2 times the flow's third derivatives
and round-off of order 1e-16 / eps, so the tolerances are looser than round-off (1 - |cos|
below 1e-6; the growth to 1e-4 relative, where the most stable vectors lose most digits).

Every frame is also checked for the exact identities: G_n orthonormal, each v^j of unit
length, G_n^T V_n upper triangular (V = G C), and the CLV spectrum (clv_spectrum.json) the
average of the frames' local exponents.
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from read_frames import frames_to_check, run_json  # noqa: E402


class Disks:
    """Elastic disks of unit diameter and mass in a periodic lx x ly box; phase points in
    the paper's order (q_x1, q_y1, ..., q_yN, p_x1, ..., p_yN)."""

    def __init__(self, n, lx, ly):
        self.n, self.box = n, np.array([lx, ly])
        self.i, self.j = np.triu_indices(n, 1)
        self.images = np.array([[a * lx, b * ly] for a in (-1, 0, 1) for b in (-1, 0, 1)])

    def next_collision(self, q, p):
        """Time to the next contact of approaching disks, the pair and the image shift."""
        dr = (q[self.i] - q[self.j])[None] + self.images[:, None, :]
        dv = np.broadcast_to(p[self.i] - p[self.j], dr.shape)
        b = (dr * dv).sum(-1)
        v2 = (dv * dv).sum(-1)
        disc = b * b - v2 * ((dr * dr).sum(-1) - 1.0)
        t = np.full(b.shape, np.inf)
        hit = (b < 0) & (disc > 0)
        t[hit] = (-b[hit] - np.sqrt(disc[hit])) / v2[hit]
        image, pair = np.unravel_index(np.argmin(t), t.shape)
        return t[image, pair], pair, self.images[image]

    def advance(self, phase, duration):
        q = phase[: 2 * self.n].reshape(self.n, 2).copy()
        p = phase[2 * self.n :].reshape(self.n, 2).copy()
        left = duration
        while True:
            t, pair, shift = self.next_collision(q, p)
            t = max(t, 0.0)
            if t > left:
                q += p * left
                break
            q += p * t
            left -= t
            i, j = self.i[pair], self.j[pair]
            normal = q[i] - q[j] + shift
            normal /= np.linalg.norm(normal)
            exchange = (p[i] - p[j]) @ normal
            p[i] -= exchange * normal
            p[j] += exchange * normal
        return np.concatenate([q.ravel(), p.ravel()])

    def difference(self, a, b):
        """a - b, positions by their nearest periodic image."""
        d = a - b
        dq = d[: 2 * self.n].reshape(self.n, 2)
        dq -= self.box * np.round(dq / self.box)
        return d


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("run")
    p.add_argument("frames")
    p.add_argument("--sample", type=int, default=8, help="frames checked by finite differences")
    p.add_argument("--eps", type=float, default=1e-5)
    args = p.parse_args()

    if args.sample < 1:
        sys.exit(f"verify_disks.py: --sample must be at least 1, not {args.sample}")
    config = run_json(args.run, "verify_disks.py")["config"]
    system, tau = config["system"], config["tau"]
    if system["kind"] != "disks":
        sys.exit(f"{args.run}: a run of {system['kind']}, not of hard disks")
    disks = Disks(system["n"], system["lx"], system["ly"])
    frames = frames_to_check(args.frames, "verify_disks.py", 4 * system["n"])

    dev = {"G_orthonormal": 0.0, "v_unit": 0.0, "GtV_lower": 0.0, "clv_spectrum": 0.0, "covariance": 0.0, "growth": 0.0}
    for f in frames:
        g, v = f["g"], f["v"]
        gtv = g.T @ v
        dev["G_orthonormal"] = max(dev["G_orthonormal"], np.abs(g.T @ g - np.eye(g.shape[1])).max())
        dev["v_unit"] = max(dev["v_unit"], np.abs(np.linalg.norm(v, axis=0) - 1.0).max())
        dev["GtV_lower"] = max(dev["GtV_lower"], np.abs(np.tril(gtv, -1)).max())
    with open(os.path.join(args.run, "clv_spectrum.json")) as f:
        clv_spectrum = np.array(json.load(f)["exponents"])
    dev["clv_spectrum"] = np.abs(np.mean([f["local"] for f in frames], axis=0) - clv_spectrum).max()

    by_step = {f["step"]: f for f in frames}
    pairs = [f for f in frames if f["step"] + 1 in by_step]
    sample = pairs[:: max(1, len(pairs) // args.sample)][: args.sample]
    for f in sample:
        after = by_step[f["step"] + 1]
        for j in range(f["v"].shape[1]):
            moved = [disks.advance(f["phase"] + sign * args.eps * f["v"][:, j], tau) for sign in (1.0, -1.0)]
            d = disks.difference(*moved) / (2.0 * args.eps)
            cos = abs(d @ after["v"][:, j]) / np.linalg.norm(d)
            dev["covariance"] = max(dev["covariance"], 1.0 - cos)
            growth = np.linalg.norm(d) / np.exp(f["local"][j] * tau)
            dev["growth"] = max(dev["growth"], abs(growth - 1.0))

    tol = {"G_orthonormal": 1e-12, "v_unit": 1e-12, "GtV_lower": 1e-12, "clv_spectrum": 1e-12, "covariance": 1e-6, "growth": 1e-4}
    bad = {k: v for k, v in dev.items() if not v <= tol[k]}
    print(json.dumps({"frames": len(frames), "sampled": len(sample), "eps": args.eps, "max_deviation": dev, "tolerance": tol, "agree": not bad}))
    if bad:
        sys.exit(f"disagreement beyond the tolerance: {bad}")


if __name__ == "__main__":
    main()
