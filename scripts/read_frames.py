#!/usr/bin/env python3
"""Read a clv frame file (covariant Lyapunov vectors) into numpy with `mcap` and `cbor2`.

    python3 scripts/read_frames.py FRAMES.mcap            # a summary
    python3 scripts/read_frames.py FRAMES.mcap --json     # the same as one JSON object

The summary's mean_local_clv_exponents is the
mean of the local CLV exponents over the frames in the file only. It is the sweep's CLV
spectrum only when the file holds every frame of the window (clv backward --save-every 1);
the sweep's spectrum over all its frames is RUN_DIR/clv_spectrum.json.

As a library:

    from read_frames import read_frames
    for f in read_frames("run/frames.mcap"):
        f["step"], f["time"]
        f["v"]        # (D, k) array: column j is the covariant vector v^(j+1), unit norm;
                      # None in frames without vectors (clv backward --vectors-every)
        f["g"]        # (D, k) Gram-Schmidt vectors, or None without --with-gs
        f["local"]    # (k,) local CLV exponents over [t_n, t_n+1]
        f["gs_local"] # (k,) local GS exponents over [t_n, t_n+1], or None (files before 2026-11-25)
        f["phase"]    # (D,) phase point (q_x1, q_y1, ..., p_yN)

Frames are written newest first (the backward pass runs backward in time); read_frames
yields them oldest first, as the mcap reader sorts messages by their log time (the frame's
time). The file's
metadata holds the run's configuration (run.json), its forward spectrum (spectrum.json) and
the backward stage's options (backward.json).
"""
import json
import os
import sys

import cbor2
import numpy as np
from mcap.reader import make_reader


def read_frames(path):
    with open(path, "rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(topics=["frame"]):
            m = cbor2.loads(message.data)
            d, k = m["d"], m["k"]
            g = np.frombuffer(m["g"], "<f8")
            v = np.frombuffer(m["v"], "<f8")
            yield {
                "step": m["step"],
                "time": m["time"],
                "phase": np.frombuffer(m["phase"], "<f8"),
                "v": v.reshape(k, d).T if v.size else None,
                "local": np.frombuffer(m["local"], "<f8"),
                "gs_local": np.frombuffer(m["gs_local"], "<f8") if "gs_local" in m else None,
                "g": g.reshape(k, d).T if g.size else None,
            }


def metadata(path):
    with open(path, "rb") as f:
        for record in make_reader(f).iter_metadata():
            if record.name == "clv.run":
                return {k: json.loads(v) for k, v in record.metadata.items()}
    return {}


def load_frames(path, script):
    """The frames of `path` in step order, or an exit naming why there are none."""
    if not os.path.isfile(path):
        sys.exit(f"{script}: {path} is not a file (give a frame file of `clv backward --out FILE`)")
    try:
        frames = sorted(read_frames(path), key=lambda f: f["step"])
    except Exception as e:  # not MCAP, or damaged: the reader's own words
        sys.exit(f"{script}: {path} cannot be read as a frame file: {e}")
    if not frames:
        sys.exit(f"{script}: {path} holds no frames (a run segment? frames come from `clv backward --out FILE`)")
    return frames


def frames_to_check(path, script, d, gs=True):
    """[load_frames] for a check that needs every step's frame with D = `d` and its vectors
    (and G_n if `gs`); exits with a message naming what is missing."""
    frames = load_frames(path, script)
    if frames[0]["phase"].size != d:
        sys.exit(f"{script}: {path} holds frames of D = {frames[0]['phase'].size}, the run D = {d}: the frames of another run")
    steps = [f["step"] for f in frames]
    if any(b - a != 1 for a, b in zip(steps, steps[1:])):
        sys.exit(f"{script}: {path} does not hold every step's frame (--save-every?): this check needs consecutive frames")
    if any(f["v"] is None or (gs and f["g"] is None) for f in frames):
        sys.exit(f"{script}: {path}: every frame needs V_n" + (" and G_n (clv backward --with-gs" if gs else " (clv backward") + ", without --vectors-every)")
    return frames


def run_json(run_dir, script):
    """RUN_DIR/run.json, or an exit naming what is wrong."""
    path = os.path.join(run_dir, "run.json")
    if not os.path.isfile(path):
        sys.exit(f"{script}: {run_dir} is not a run directory (no run.json)")
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        sys.exit(f"{script}: {path} cannot be read: {e}")


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    path = sys.argv[1]
    frames = load_frames(path, "read_frames.py")
    local = np.array([f["local"] for f in frames])
    norms = [float(np.abs(np.linalg.norm(f["v"], axis=0) - 1).max()) for f in frames if f["v"] is not None]
    worst_norm = max(norms) if norms else None  # None: no frame carries vectors (--vectors-every)
    meta = metadata(path)
    mean_local = local.mean(axis=0).tolist()
    summary = {
        "frames": len(frames),
        "first_step": min(f["step"] for f in frames),
        "last_step": max(f["step"] for f in frames),
        "mean_local_clv_exponents": mean_local,
        "max_unit_norm_error": worst_norm,
        "with_gs": any(f["g"] is not None for f in frames),
        "frames_with_vectors": sum(f["v"] is not None for f in frames),
        "run_seed": meta.get("run.json", {}).get("config", {}).get("seed"),
    }
    if "--json" in sys.argv:
        print(json.dumps(summary))
    else:
        for key, value in summary.items():
            if key == "mean_local_clv_exponents":
                print(f"mean local CLV exponents over the {len(frames)} frames in this file: {value[:4]}"
                      f"{' ...' if len(value) > 4 else ''} (the sweep's CLV spectrum: RUN_DIR/clv_spectrum.json)")
            else:
                print(f"{key}: {value}")


if __name__ == "__main__":
    main()
