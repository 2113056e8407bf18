#!/usr/bin/env python3
"""Read a clv run directory into numpy with the `mcap` and `cbor2` packages.

    python3 scripts/read_run.py RUN_DIR            # a summary
    python3 scripts/read_run.py RUN_DIR --json     # the same as one JSON object

As a library:

    from read_run import read_run
    run = read_run("RUN_DIR")
    run["checkpoints"][step]["g"]      # G_n as a (D, k) array, rows in the paper's ordering
    run["r"][step]                     # R_n as a (k, k) upper-triangular array
    run["stats"][step]["exponents"]    # running spectrum

Every message is one CBOR map; arrays are little-endian f64 byte strings (schemas/*.json
say what each field means).
"""
import glob
import json
import os
import sys

import cbor2
import numpy as np
from mcap.reader import make_reader

ARRAYS = {"phase", "g", "acc_sum", "acc_current", "acc_blocks", "r", "exponents", "stderr", "momentum"}


def decode(data):
    msg = cbor2.loads(data)
    return {k: (np.frombuffer(v, "<f8") if k in ARRAYS else v) for k, v in msg.items()}


def unpack_upper(packed, k):
    r = np.zeros((k, k))
    at = 0
    for j in range(k):
        r[: j + 1, j] = packed[at : at + j + 1]
        at += j + 1
    return r


def read_segment(path):
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages():
            yield channel.topic, message.log_time, decode(message.data)


def read_run(run_dir):
    run = {"run": json.load(open(os.path.join(run_dir, "run.json"))), "checkpoints": {}, "r": {}, "stats": {}}
    for path in sorted(glob.glob(os.path.join(run_dir, "seg-*-*.mcap"))):
        for topic, step, m in read_segment(path):
            if topic == "checkpoint":
                d, k = m["d"], m["k"]
                m["g"] = m["g"].reshape(k, d).T  # column-major D x k
                run["checkpoints"][step] = m
            elif topic == "r":
                run["r"][step] = unpack_upper(m["r"], m["k"])
            elif topic == "stats":
                run["stats"][step] = m
    return run


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    if not os.path.isfile(os.path.join(sys.argv[1], "run.json")):
        sys.exit(f"read_run.py: {sys.argv[1]} is not a run directory (no run.json; a frame file is read by read_frames.py)")
    run = read_run(sys.argv[1])
    if not run["checkpoints"]:
        sys.exit(f"read_run.py: {sys.argv[1]} holds no finished segment yet")
    last = max(run["checkpoints"])
    ortho = max(float(np.abs(c["g"].T @ c["g"] - np.eye(c["g"].shape[1])).max()) for c in run["checkpoints"].values())
    upper = all(np.allclose(np.tril(r, -1), 0) and (np.diag(r) > 0).all() for r in run["r"].values())
    summary = {
        "checkpoints": len(run["checkpoints"]),
        "r_matrices": len(run["r"]),
        "first_step": min(run["checkpoints"]),
        "last_step": last,
        "exponents": run["stats"][last]["exponents"].tolist(),
        "max_orthonormality_error": ortho,
        "r_upper_positive": bool(upper),
    }
    if "--json" in sys.argv:
        print(json.dumps(summary))
    else:
        for k, v in summary.items():
            print(f"{k}: {v if k != 'exponents' else v[:4]}")


if __name__ == "__main__":
    main()
