#!/usr/bin/env python3
"""Recompute the tables of a hard-disk report of `clv analyze` from its frames.

    python3 scripts/verify_report.py REPORT_DIR FRAMES.mcap   # exit 1 on a disagreement

REPORT_DIR is the --out of `clv analyze FRAMES.mcap`, FRAMES.mcap a frame file of
`clv backward --with-gs --out FRAMES.mcap` (without GS vectors the GS columns are skipped).
Each quantity is recomputed here with numpy from the frames alone (read by read_frames.py)
and compared with the report's CSV files:

  spectrum.csv         lambda_clv = mean over all frames of the local CLV exponents,
                       lambda_gs_window = mean over all frames of the local GS exponents, and
                       their errors stderr_clv, stderr_gs_window (batch means, below);
  local_exponents.csv  time and lambda_i of each row's frame (matched by step): the frame's time
                       and its local CLV exponent i, ln |D phi^tau v^i| / tau, as the frame holds it;
  finite_time_exponents.csv   for each (i, delta): the local exponents averaged over consecutive
                       windows of delta frames counted from the NEWEST frame (the oldest T mod
                       delta frames fill no window), and windows = their number, mean, std (n - 1;
                       NaN from one window), min and max of exponent i over them;
  domination.csv       for each delta, over the same windows: a pair (i, i + 1) swaps in a window
                       where exponent i + 1 exceeds exponent i; overall = the swap fraction over
                       all windows and all D - 1 pairs, outside_null = the same over the pairs not
                       both inside the null space 2N-2..2N+3 (the two pairs that straddle its
                       borders count), pair_i_j = one pair's, border_unstable_null and
                       border_null_stable = the pairs (2N-3, 2N-2) and (2N+3, 2N+4),
                       split_unstable_null (split_null_stable) = the fraction of windows where some
                       exponent of 1..2N-3 lies below some of 2N-2..2N+3 (some of 2N-2..2N+3 below
                       some of 2N+4..D); a column not recomputed here is a disagreement;
  localization.csv     W_gs, W_clv: W_i = exp(<S_i>) / N with S = -sum_n mu_n ln mu_n, mu_n the
                       share of |v|^2 on disk n (its dq_x, dq_y, dp_x, dp_y); stderr_gs,
                       stderr_clv = W times the batch-means error of <S> over the sampled frames;
  projections.csv      eta_q = <|dq|^2>, eta_p = <|dp|^2> and <cos Theta> = <dq.dp / |dq||dp|>
                       for GS and CLV; a frame whose |dq|^2 or |dp|^2 is below 1e-24 (round-off:
                       a pure position or momentum vector, as the null-space GS vectors) has no
                       Theta and is left out of the mean, which is NaN where no frame has one;
                       eta_q_gs_std, eta_q_clv_std = sample std (n - 1) of |dq|^2 over the frames;
  overlap_gs_clv.csv   abs_g_dot_v_mean = <|g^i . v^i|>, abs_g_dot_v_std its sample std (n - 1);
  overlap_clv_gs.csv   abs_vJ_mean = <|v^J . g^i|>, overlap_clv_clv.csv abs_vJ_mean = <|v^J . v^i|>,
                       and abs_vJ_std the sample std (n - 1) of each over the sampled frames;
  nullspace_alpha.csv, nullspace_beta.csv   g^i . e_k and v^i . e_k (and the row norms) of the six
                       null-space vectors at the earliest sampled frame, with the natural basis
                       e_1 = (p, 0)/|p|, e_2, e_3 = x, y translations of the positions,
                       e_4 = (0, p)/|p|, e_5, e_6 = x, y translations of the momenta;
  theta_min.csv        for every separation s = 1..J-1 (J - 1 the table's largest): min and mean
                       over the sampled frames and the pairs (v^j, v^(j+s)), j + s <= J, of
                       Theta = arccos |v^i . v^j|, computed as 2 arcsin(|v^i -+ v^j| / 2).

Sampling: the spectrum, the local and finite-time exponents and domination use every frame
of the file; the vector statistics use the frames
of the steps that are multiples of m = summary.json's options.every that carry vectors (as
the report says in its head). Frames are put in step order whatever the file's order. Tables
(and _std / stderr columns) the report does not have are skipped.

Batch means (stderr columns): B = the run's `blocks` setting, read from run.json in the
frame file's metadata (summary.json does not hold it; --blocks overrides). Of T frames (all
of them for the spectrum, the sampled ones for localization) blocks of L = max(floor(T / B), 1)
frames are counted from the NEWEST frame, as many as fit: n = floor(T / L) blocks, which is
B when L > 1 and T < B (L + 1) but more otherwise (43 sampled frames, B = 20: 21 blocks of 2;
71 frames: 23 blocks of 3). This was found by trying alternatives against the CSVs: exactly
B blocks of L (leaving T - B L frames out) misses by up to 13 %, blocks counted from the
oldest frame by 19-34 %, std with n instead of n - 1 by 2.5 %; the rule above agrees to
~1e-15 relative. The oldest T mod L frames count in the means, not in the errors. The error
is the sample std (n - 1) of the block means / sqrt(n); NaN with n < 2.

Tolerance: round-off. A value agrees when |mine - report| <= 1e-10 max(1, |report|) (the
quantities are averages of O(1) numbers; the report writes them with all digits); NaN only
against NaN. A stderr agrees when |mine - report| <= 1e-9 |report| or <= 1e-15 (the errors of
exactly vanishing exponents are round-off, ~1e-16). A _std agrees when |mine - report| <=
1e-9 |report| or <= 1e-12 (the spread of a constant, |v^i . v^i| = 1, is round-off). Until
2026-11-27 clv summed x and x^2 over the frames, and its _std of a constant came out ~1e-8
= sqrt(1e-16) instead of 0; this check found it.
The JSON on stdout: {"agree": ..., "checked": {table: largest |mine - report| over its mean
and stderr columns}, "checked_std": {table: the same over its _std columns}, "columns":
{table: [columns compared]}, "frames": n, "sampled": n, "every": m, "blocks": B, ...}.

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
from read_frames import metadata, read_frames  # noqa: E402

TOL = 1e-10
TOL_ERR = 1e-9
ROUND_OFF_SQ = 1e-24


def read_csv(path):
    """Columns of a CSV file as float arrays (None if the file is absent)."""
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else {}


def batch_stderr(x, blocks):
    """Batch-means standard error of the mean over axis 0 of x (rows in increasing step order).

    Blocks of L = floor(T / blocks) rows (at least 1), as many as fit (n = floor(T / L),
    which can exceed blocks: 43 rows, 20 blocks -> 21 blocks of 2), counted from the newest
    row; the oldest T mod L rows fill no block and are left out. The error is the sample
    std (n - 1) of the block means over sqrt(n); NaN with n < 2.
    """
    x = np.asarray(x, float)
    t = x.shape[0]
    length = max(t // blocks, 1)
    count = t // length
    if count < 2:
        return np.full(x.shape[1:], np.nan)
    means = x[t - count * length :].reshape((count, length) + x.shape[1:]).mean(axis=1)
    return means.std(axis=0, ddof=1) / np.sqrt(count)


def sample_std(x):
    """Sample standard deviation (n - 1) over axis 0; NaN with fewer than two rows."""
    x = np.asarray(x, float)
    return x.std(axis=0, ddof=1) if x.shape[0] > 1 else np.full(x.shape[1:], np.nan)


class Checker:
    def __init__(self):
        self.checked, self.checked_std, self.columns, self.bad = {}, {}, {}, []

    def compare_std(self, table, column, index, x, report):
        """A _std column: mine = sample_std(x) over axis 0 of x (frames, rows).

        Agrees if |mine - report| <= TOL_ERR |report| or <= 1e-12 (the spread of a constant
        is round-off). The worst |mine - report| goes to checked_std."""
        mine, report = sample_std(x)[index - 1], np.asarray(report, float)
        worst = self.checked_std.get(table, 0.0)
        self.columns.setdefault(table, []).append(column)
        for idx, m, r in zip(np.ravel(index), mine, report):
            if np.isnan(m) or np.isnan(r):
                ok = np.isnan(m) and np.isnan(r)
            else:
                worst = max(worst, abs(m - r))
                ok = abs(m - r) <= TOL_ERR * abs(r) or abs(m - r) <= 1e-12
            if not ok:
                self.bad.append(f"disagreement: {table} {column} {int(idx)} mine {float(m)!r} report {float(r)!r}")
        self.checked_std[table] = float(worst)

    def compare(self, table, column, index, mine, report, tol=TOL):
        """Compare mine with report element by element; index labels the rows.

        tol is relative: |mine - report| <= tol max(1, |report|), or for errors (tol =
        TOL_ERR) <= tol |report| with an absolute floor of 1e-15 (errors of exactly
        constant columns are round-off, ~1e-16)."""
        mine, report = np.broadcast_to(np.asarray(mine, float), np.shape(report)), np.asarray(report, float)
        worst = self.checked.get(table, 0.0)
        self.columns.setdefault(table, []).append(column)
        for idx, x, y in zip(np.ravel(index), np.ravel(mine), np.ravel(report)):
            if np.isnan(x) or np.isnan(y):
                ok = np.isnan(x) and np.isnan(y)
            else:
                worst = max(worst, abs(x - y))
                bound = TOL * max(1.0, abs(y)) if tol == TOL else max(tol * abs(y), 1e-15)
                ok = abs(x - y) <= bound
            if not ok:
                self.bad.append(f"disagreement: {table} {column} {int(idx)} mine {float(x)!r} report {float(y)!r}")
        self.checked[table] = float(worst)


def disk_weights(x, n):
    """mu_n: |x|^2 on disk n's four components, per frame and vector: (T, N, k)."""
    dq, dp = x[:, : 2 * n], x[:, 2 * n :]
    return dq[:, 0::2] ** 2 + dq[:, 1::2] ** 2 + dp[:, 0::2] ** 2 + dp[:, 1::2] ** 2


def localization(x, n, blocks):
    """W = exp(<S>) / N and its error W * batch_stderr(S)."""
    mu = disk_weights(x, n)
    mu = mu / mu.sum(axis=1, keepdims=True)
    terms = np.where(mu > 0, mu * np.log(np.where(mu > 0, mu, 1.0)), 0.0)
    entropy = -terms.sum(axis=1)
    w = np.exp(entropy.mean(axis=0)) / n
    return w, w * batch_stderr(entropy, blocks)


def projections(x, n):
    dq, dp = x[:, : 2 * n], x[:, 2 * n :]
    eq, ep = (dq**2).sum(axis=1), (dp**2).sum(axis=1)
    has_theta = np.minimum(eq, ep) >= ROUND_OFF_SQ
    cos = np.where(has_theta, (dq * dp).sum(axis=1) / np.sqrt(np.where(has_theta, eq * ep, 1.0)), 0.0)
    count = has_theta.sum(axis=0)
    mean_cos = np.where(count > 0, cos.sum(axis=0) / np.maximum(count, 1), np.nan)
    return {"eta_q": eq.mean(axis=0), "eta_p": ep.mean(axis=0), "cos_theta": mean_cos}, {"eta_q": eq, "eta_p": ep}


def windows(local, delta):
    """Finite-time exponents: means of local over consecutive windows of delta frames, counted
    from the newest frame (the oldest T mod delta frames fill no window): (W, k).

    Each window is summed one frame at a time from its newest frame, then divided by delta:
    the null-space exponents vanish, their differences are round-off, and whether such a pair
    swaps in domination.csv depends on the order of summation (numpy's mean missed one swap
    of 1860 at delta = 5 in the test's run; this order matches all)."""
    t = local.shape[0]
    count = t // delta
    x = local[t - count * delta :].reshape((count, delta) + local.shape[1:])
    total = np.zeros((count,) + local.shape[1:])
    for k in range(delta - 1, -1, -1):
        total = total + x[:, k]
    return total / delta


def domination(x, n):
    """Swap fractions of the finite-time exponents x (W windows, k) of N disks.

    A pair (i, i + 1) swaps in a window where exponent i + 1 exceeds exponent i. overall:
    mean over all windows and pairs; outside_null: the same over the pairs not both inside
    the null space 2N-2..2N+3 (the two that straddle its borders count); pair_i_j: one pair;
    border_unstable_null, border_null_stable: the pairs (2N-3, 2N-2), (2N+3, 2N+4);
    split_unstable_null (split_null_stable): the fraction of windows in which some exponent
    of 1..2N-3 lies below some exponent of 2N-2..2N+3 (some of the null space below some of
    2N+4..D)."""
    k = x.shape[1]
    swap = x[:, 1:] > x[:, :-1]  # column a - 1: the pair (a, a + 1)
    lo, hi = 2 * n - 2, 2 * n + 3  # the null space, 1-based
    out = [a - 1 for a in range(1, k) if not (lo <= a and a + 1 <= hi)]
    result = {"windows": x.shape[0], "overall": swap.mean(), "outside_null": swap[:, out].mean()}
    for a in range(1, k):
        result[f"pair_{a}_{a + 1}"] = swap[:, a - 1].mean()
    if hi < k:
        result["border_unstable_null"] = swap[:, lo - 2].mean()
        result["border_null_stable"] = swap[:, hi - 1].mean()
        result["split_unstable_null"] = np.mean(x[:, : lo - 1].min(axis=1) < x[:, lo - 1 : hi].max(axis=1))
        result["split_null_stable"] = np.mean(x[:, lo - 1 : hi].min(axis=1) < x[:, hi:].max(axis=1))
    return result


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
    ap.add_argument("--blocks", type=int, help="the run's blocks setting (default: run.json's, from the frame file's metadata)")
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
    if args.blocks is not None:
        blocks = args.blocks
    else:
        run = metadata(args.frames).get("run.json", {})
        blocks = (run.get("config", run) or {}).get("blocks")
        if blocks is None:
            sys.exit(f"{args.frames}: no run.json blocks setting in its metadata: give --blocks")
    blocks = int(blocks)
    c = Checker()

    # Spectrum: every frame.
    local = np.array([f["local"] for f in frames])
    sp = rep("spectrum.csv")
    if sp is not None:
        i = sp["i"].astype(int)
        c.compare("spectrum.csv", "lambda_clv", i, local.mean(axis=0)[i - 1], sp["lambda_clv"])
        c.compare("spectrum.csv", "stderr_clv", i, batch_stderr(local, blocks)[i - 1], sp["stderr_clv"], TOL_ERR)
        if all(f["gs_local"] is not None for f in frames):
            gs_local = np.array([f["gs_local"] for f in frames])
            c.compare("spectrum.csv", "lambda_gs_window", i, gs_local.mean(axis=0)[i - 1], sp["lambda_gs_window"])
            c.compare("spectrum.csv", "stderr_gs_window", i, batch_stderr(gs_local, blocks)[i - 1], sp["stderr_gs_window"], TOL_ERR)

    # Local exponents, finite-time exponents and domination: every frame.
    le = rep("local_exponents.csv")
    if le is not None and len(le.get("step", [])):
        steps = np.array([f["step"] for f in frames])
        rows = np.searchsorted(steps, le["step"].astype(np.int64))
        if np.any(rows >= len(frames)) or np.any(steps[np.minimum(rows, len(frames) - 1)] != le["step"]):
            c.bad.append("disagreement: local_exponents.csv has steps that are not frames")
            rows = np.minimum(rows, len(frames) - 1)
        idx = le["step"].astype(np.int64)
        c.compare("local_exponents.csv", "time", idx, np.array([frames[r]["time"] for r in rows]), le["time"])
        for col in le:
            if col.startswith("lambda_"):
                c.compare("local_exponents.csv", col, idx, local[rows, int(col[len("lambda_") :]) - 1], le[col])
    ft = rep("finite_time_exponents.csv")
    if ft is not None and len(ft.get("i", [])):
        for col in ("windows", "mean", "std", "min", "max"):
            mine = []
            for i, delta in zip(ft["i"].astype(int), ft["delta"].astype(int)):
                x = windows(local, delta)[:, i - 1]
                mine.append({"windows": len(x), "mean": x.mean(), "std": sample_std(x[:, None])[0], "min": x.min(), "max": x.max()}[col])
            c.compare("finite_time_exponents.csv", col, ft["i"].astype(int), mine, ft[col])
    dm = rep("domination.csv")
    if dm is not None and len(dm.get("delta", [])):
        deltas = dm["delta"].astype(int)
        mine = {}
        for delta in deltas:
            for col, value in domination(windows(local, delta), n).items():
                mine.setdefault(col, []).append(value)
        for col in dm:
            if col in mine:
                c.compare("domination.csv", col, deltas, mine[col], dm[col])
            elif col != "delta":
                c.bad.append(f"disagreement: domination.csv column {col} is not recomputed here")

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
            w, err = localization(x, n, blocks)
            c.compare("localization.csv", f"W_{name}", i, w[i - 1], loc[f"W_{name}"])
            if f"stderr_{name}" in loc:
                c.compare("localization.csv", f"stderr_{name}", i, err[i - 1], loc[f"stderr_{name}"], TOL_ERR)
        if pr is not None:
            i = pr["i"].astype(int)
            means, per_frame = projections(x, n)
            for col, mine in means.items():
                c.compare("projections.csv", f"{col}_{name}", i, mine[i - 1], pr[f"{col}_{name}"])
            for col, values in per_frame.items():  # eta_q_gs_std (eta_p_*_std where the report has it)
                if f"{col}_{name}_std" in pr:
                    c.compare_std("projections.csv", f"{col}_{name}_std", i, values, pr[f"{col}_{name}_std"])

    v, g = vecs["clv"], vecs.get("gs")
    ov = rep("overlap_gs_clv.csv")
    if ov is not None and g is not None:
        i = ov["i"].astype(int)
        a = np.abs(np.einsum("tdi,tdi->ti", g, v))
        c.compare("overlap_gs_clv.csv", "abs_g_dot_v_mean", i, a.mean(axis=0)[i - 1], ov["abs_g_dot_v_mean"])
        if "abs_g_dot_v_std" in ov:
            c.compare_std("overlap_gs_clv.csv", "abs_g_dot_v_std", i, a, ov["abs_g_dot_v_std"])
    for table, other in (("overlap_clv_gs.csv", g), ("overlap_clv_clv.csv", v)):
        ov = rep(table)
        if ov is None or other is None:
            continue
        i = ov["i"].astype(int)
        for col in ov:
            if col.startswith("abs_v") and col.endswith("_mean"):
                j = int(col[len("abs_v") : -len("_mean")])
                a = np.abs(np.einsum("td,tdi->ti", v[:, :, j - 1], other))
                c.compare(table, col, i, a.mean(axis=0)[i - 1], ov[col])
                if f"abs_v{j}_std" in ov:
                    c.compare_std(table, f"abs_v{j}_std", i, a, ov[f"abs_v{j}_std"])

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
    print(json.dumps({"agree": not c.bad, "checked": c.checked, "checked_std": c.checked_std, "columns": c.columns, "frames": len(frames), "sampled": len(sampled), "every": every, "blocks": blocks, "tolerance": TOL, "tolerance_errors": TOL_ERR}))
    if c.bad:
        for line in c.bad:
            print(line, file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
