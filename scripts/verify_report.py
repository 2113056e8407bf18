#!/usr/bin/env python3
"""Recompute the tables of a hard-disk report of `clv analyze` from its frames.

    python3 scripts/verify_report.py REPORT_DIR FRAMES.mcap   # exit 1 on a disagreement

REPORT_DIR is the --out of `clv analyze FRAMES.mcap`, FRAMES.mcap a frame file of
`clv backward --with-gs --out FRAMES.mcap` (without GS vectors the GS columns are skipped).
Each quantity is recomputed here with numpy from the frames alone (read by read_frames.py)
and compared with the report's CSV files:

  spectrum.csv         lambda_clv = mean over all frames of the local CLV exponents,
                       lambda_gs_window = mean over all frames of the local GS exponents;
  localization.csv     W_gs, W_clv: W_i = exp(<S_i>) / N with S = -sum_n mu_n ln mu_n, mu_n the
                       share of |v|^2 on disk n (its dq_x, dq_y, dp_x, dp_y);
  projections.csv      eta_q = <|dq|^2>, eta_p = <|dp|^2> and <cos Theta> = <dq.dp / |dq||dp|>
                       for GS and CLV; a frame whose |dq|^2 or |dp|^2 is below 1e-24 (round-off:
                       a pure position or momentum vector, as the null-space GS vectors) has no
                       Theta and is left out of the mean, which is NaN where no frame has one;
  overlap_gs_clv.csv   abs_g_dot_v_mean = <|g^i . v^i|>;
  overlap_clv_gs.csv   abs_vJ_mean = <|v^J . g^i|>, overlap_clv_clv.csv abs_vJ_mean = <|v^J . v^i|>;
  nullspace_alpha.csv, nullspace_beta.csv   g^i . e_k and v^i . e_k (and the row norms) of the six
                       null-space vectors at the earliest sampled frame, with the natural basis
                       e_1 = (p, 0)/|p|, e_2, e_3 = x, y translations of the positions,
                       e_4 = (0, p)/|p|, e_5, e_6 = x, y translations of the momenta;
  theta_min.csv        for every separation s = 1..J-1 (J - 1 the table's largest): min and mean
                       over the sampled frames and the pairs (v^j, v^(j+s)), j + s <= J, of
                       Theta = arccos |v^i . v^j|, computed as 2 arcsin(|v^i -+ v^j| / 2).

Sampling: the spectrum uses every frame of the file; the vector statistics use the frames
of the steps that are multiples of m = summary.json's options.every that carry vectors (as
the report says in its head). Tables the report does not have are skipped.

Tolerance: round-off. A value agrees when |mine - report| <= 1e-10 max(1, |report|) (the
quantities are averages of O(1) numbers; the report writes them with all digits); NaN only
against NaN. The largest absolute difference of each table goes into the JSON on stdout:
{"agree": ..., "checked": {table: max_abs_diff}, "frames": n, "sampled": n, "every": m}.

Only the physics and the report's conventions (file layout, columns, the ordering
(dq_x1, dq_y1, ..., dq_yN, dp_x1, ..., dp_yN), 1-based indices) are shared with clv; the code
is not: nothing here comes from clv's Rust.
"""
import argparse
import csv
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from read_frames import read_frames  # noqa: E402

TOL = 1e-10
ROUND_OFF_SQ = 1e-24


def read_csv(path):
    """Columns of a CSV file as float arrays (None if the file is absent)."""
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else {}


class Checker:
    def __init__(self):
        self.checked, self.bad = {}, []

    def compare(self, table, column, index, mine, report):
        """Compare mine with report element by element; index labels the rows."""
        mine, report = np.broadcast_to(np.asarray(mine, float), np.shape(report)), np.asarray(report, float)
        worst = self.checked.get(table, 0.0)
        for idx, x, y in zip(np.ravel(index), np.ravel(mine), np.ravel(report)):
            if np.isnan(x) or np.isnan(y):
                ok = np.isnan(x) and np.isnan(y)
            else:
                worst = max(worst, abs(x - y))
                ok = abs(x - y) <= TOL * max(1.0, abs(y))
            if not ok:
                self.bad.append(f"disagreement: {table} {column} {int(idx)} mine {float(x)!r} report {float(y)!r}")
        self.checked[table] = float(worst)


def disk_weights(x, n):
    """mu_n: |x|^2 on disk n's four components, per frame and vector: (T, N, k)."""
    dq, dp = x[:, : 2 * n], x[:, 2 * n :]
    return dq[:, 0::2] ** 2 + dq[:, 1::2] ** 2 + dp[:, 0::2] ** 2 + dp[:, 1::2] ** 2


def localization(x, n):
    mu = disk_weights(x, n)
    mu = mu / mu.sum(axis=1, keepdims=True)
    terms = np.where(mu > 0, mu * np.log(np.where(mu > 0, mu, 1.0)), 0.0)
    return np.exp(-terms.sum(axis=1).mean(axis=0)) / n


def projections(x, n):
    dq, dp = x[:, : 2 * n], x[:, 2 * n :]
    eq, ep = (dq**2).sum(axis=1), (dp**2).sum(axis=1)
    has_theta = np.minimum(eq, ep) >= ROUND_OFF_SQ
    cos = np.where(has_theta, (dq * dp).sum(axis=1) / np.sqrt(np.where(has_theta, eq * ep, 1.0)), 0.0)
    count = has_theta.sum(axis=0)
    mean_cos = np.where(count > 0, cos.sum(axis=0) / np.maximum(count, 1), np.nan)
    return eq.mean(axis=0), ep.mean(axis=0), mean_cos


def natural_basis(phase, n):
    """e_1..e_6 of the null space as columns (D, 6)."""
    d = 4 * n
    p = phase[2 * n :]
    e = np.zeros((d, 6))
    e[: 2 * n, 0] = e[2 * n :, 3] = p / np.linalg.norm(p)
    e[0 : 2 * n : 2, 1] = e[1 : 2 * n : 2, 2] = 1 / np.sqrt(n)
    e[2 * n :: 2, 4] = e[2 * n + 1 :: 2, 5] = 1 / np.sqrt(n)
    return e


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("report")
    ap.add_argument("frames")
    args = ap.parse_args()
    rep = lambda name: read_csv(os.path.join(args.report, name))  # noqa: E731

    with open(os.path.join(args.report, "summary.json")) as f:
        summary = json.load(f)
    every = int(summary["options"]["every"])
    frames = sorted(read_frames(args.frames), key=lambda f: f["step"])
    if not frames:
        sys.exit(f"{args.frames}: no frames")
    d = frames[0]["phase"].size
    if d % 4:
        sys.exit(f"{args.frames}: D = {d} is not 4N: not a hard-disk run")
    n = d // 4
    c = Checker()

    # Spectrum: every frame.
    sp = rep("spectrum.csv")
    if sp is not None:
        i = sp["i"].astype(int)
        c.compare("spectrum.csv", "lambda_clv", i, np.mean([f["local"] for f in frames], axis=0)[i - 1], sp["lambda_clv"])
        if all(f["gs_local"] is not None for f in frames):
            c.compare("spectrum.csv", "lambda_gs_window", i, np.mean([f["gs_local"] for f in frames], axis=0)[i - 1], sp["lambda_gs_window"])

    # Vector statistics: the frames of the steps that are multiples of m.
    sampled = [f for f in frames if f["step"] % every == 0 and f["v"] is not None]
    if not sampled:
        sys.exit(f"{args.frames}: no frame with vectors at a multiple of {every}")
    vecs = {"clv": np.array([f["v"] for f in sampled])}
    if all(f["g"] is not None for f in sampled):
        vecs["gs"] = np.array([f["g"] for f in sampled])

    loc, pr = rep("localization.csv"), rep("projections.csv")
    for name, x in vecs.items():
        if loc is not None:
            i = loc["i"].astype(int)
            c.compare("localization.csv", f"W_{name}", i, localization(x, n)[i - 1], loc[f"W_{name}"])
        if pr is not None:
            i = pr["i"].astype(int)
            for col, mine in zip(("eta_q", "eta_p", "cos_theta"), projections(x, n)):
                c.compare("projections.csv", f"{col}_{name}", i, mine[i - 1], pr[f"{col}_{name}"])

    v, g = vecs["clv"], vecs.get("gs")
    ov = rep("overlap_gs_clv.csv")
    if ov is not None and g is not None:
        i = ov["i"].astype(int)
        c.compare("overlap_gs_clv.csv", "abs_g_dot_v_mean", i, np.abs(np.einsum("tdi,tdi->ti", g, v)).mean(axis=0)[i - 1], ov["abs_g_dot_v_mean"])
    for table, other in (("overlap_clv_gs.csv", g), ("overlap_clv_clv.csv", v)):
        ov = rep(table)
        if ov is None or other is None:
            continue
        i = ov["i"].astype(int)
        for col in ov:
            if col.startswith("abs_v") and col.endswith("_mean"):
                j = int(col[len("abs_v") : -len("_mean")])
                c.compare(table, col, i, np.abs(np.einsum("td,tdi->ti", v[:, :, j - 1], other)).mean(axis=0)[i - 1], ov[col])

    # Null space at the earliest sampled frame (sampled is in increasing step order).
    e = natural_basis(sampled[0]["phase"], n)
    for table, x in (("nullspace_alpha.csv", g), ("nullspace_beta.csv", v)):
        t = rep(table)
        if t is None or x is None:
            continue
        i = t["i"].astype(int)
        mine = x[0][:, i - 1].T @ e
        for k in range(6):
            c.compare(table, f"e{k + 1}", i, mine[:, k], t[f"e{k + 1}"])
        c.compare(table, "row_norm", i, np.linalg.norm(mine, axis=1), t["row_norm"])

    # Figs. 16-17: Theta over pairs of F^(J), J - 1 the largest separation of the table.
    tm = rep("theta_min.csv")
    if tm is not None and len(tm.get("separation", [])):
        seps = tm["separation"].astype(int)
        f_j = v[:, :, : seps.max() + 1]
        mins, means = [], []
        for s in seps:
            a, b = f_j[:, :, s:], f_j[:, :, :-s]
            sign = np.where(np.einsum("tdk,tdk->tk", a, b) >= 0, 1.0, -1.0)
            theta = 2 * np.arcsin(np.minimum(np.linalg.norm(a - sign[:, None, :] * b, axis=1) / 2, 1.0))
            mins.append(theta.min())
            means.append(theta.mean())
        c.compare("theta_min.csv", "min_theta", seps, mins, tm["min_theta"])
        c.compare("theta_min.csv", "mean_theta", seps, means, tm["mean_theta"])

    if not c.checked:
        sys.exit(f"{args.report}: none of the tables this script checks is there")
    print(json.dumps({"agree": not c.bad, "checked": c.checked, "frames": len(frames), "sampled": len(sampled), "every": every, "tolerance": TOL}))
    if c.bad:
        for line in c.bad:
            print(line, file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
