"""What the studies (scaling.py and hyperbolicity.py against N, density.py against the
density) share: running clv, the backward stage piped into `clv analyze`, the study
directory, and a power-law fit."""
import argparse
import csv
import math
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def arguments(doc, default_n, table):
    """The options every study has (--out, --n, --density, --clv-bin); add the study's own to
    the returned parser."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--out", required=True, help=f"directory for the runs and the tables (must not hold {table})")
    ap.add_argument("--n", default=default_n, help="numbers of disks, comma-separated")
    ap.add_argument("--density", type=float, default=0.7)
    ap.add_argument("--clv-bin", default=os.path.join(HERE, "..", "target", "release", "clv"))
    return ap


class Study:
    """A study named `name` (for messages) writing `table` into a directory that must not hold
    one already: the runs of a study are never replaced."""

    def __init__(self, name, a, table, min_n, min_count=2):
        self.name, self.clv = name, a.clv_bin
        self.ns = sorted({int(x) for x in a.n.split(",") if x.strip()})
        if len(self.ns) < min_count or self.ns[0] < min_n:
            self.fail(f"--n needs at least {min_count} number(s) of disks, each at least {min_n}")
        self.table = os.path.join(a.out, table)
        if os.path.exists(self.table):
            self.fail(f"{self.table} exists; choose another --out (the runs of a study are not replaced)")
        self.runs = os.path.join(a.out, "runs")
        os.makedirs(self.runs, exist_ok=True)

    def fail(self, message):
        sys.exit(f"{self.name}: {message}")

    def run(self, args, **kw):
        """Run clv with `args`; if it fails, stop with its name (its own message is above)."""
        try:
            return subprocess.run([self.clv] + args, check=True, **kw)
        except FileNotFoundError:
            self.fail(f"{self.clv} not found; build it with `cargo build --release` or name it with --clv-bin")
        except subprocess.CalledProcessError as e:
            self.fail(f"`clv {' '.join(args[:2])} ...` failed (exit status {e.returncode}); its message is above")

    def backward_into_analyze(self, run_dir, report, backward, analyze):
        """`clv backward RUN --out - BACKWARD | clv analyze - --out REPORT ANALYZE`."""
        try:
            sweep = subprocess.Popen([self.clv, "backward", run_dir, "--out", "-", "--quiet"] + backward, stdout=subprocess.PIPE)
        except FileNotFoundError:
            self.fail(f"{self.clv} not found; build it with `cargo build --release` or name it with --clv-bin")
        self.run(["analyze", "-", "--out", report, "--overwrite", "--quiet"] + analyze, stdin=sweep.stdout)
        sweep.stdout.close()
        if sweep.wait() != 0:
            self.fail(f"clv backward {run_dir} failed; its message is above")

    def write_table(self, rows):
        """The study's table: one CSV row per dict of `rows` (all with the same keys)."""
        with open(self.table, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)

    def version(self):
        return self.run(["--version"], stdout=subprocess.PIPE, text=True).stdout.strip()


def slope(x, y):
    """Least-squares slope of y against x and its standard error (None from two points)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    a = np.vstack([np.ones_like(x), x]).T
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    dof = len(x) - 2
    resid = y - a @ coef
    se = math.sqrt(resid @ resid / dof / np.sum((x - x.mean()) ** 2)) if dof > 0 else None
    return float(coef[1]), se
