"""What the studies (scaling.py and hyperbolicity.py against N, density.py against the
density) share: their options, running clv, the backward stage piped into `clv analyze`,
the study directory, and a power-law fit.

A study that stopped (a kill, a full disk, a failed run) continues when its command is given
again with the same options: finished runs and reports in OUT/runs are kept, an interrupted
forward run is resumed (`clv forward --resume`), and a report that is not finished is made
again. clv refuses to resume a run with options other than its own."""
import argparse
import csv
import fractions
import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def whole(minimum, what="a whole number"):
    """An argparse type: a whole number at least `minimum` (`what` names it in the message)."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected {what} of at least {minimum}, not {text!r}")
        return value
    return parse


def positive(text):
    """An argparse type: a positive number, or a fraction such as 2/11."""
    try:
        value = float(fractions.Fraction(text.strip()))
    except (ValueError, ZeroDivisionError):
        value = None
    if value is None or not 0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"expected a positive number such as 0.7 or 2/11, not {text!r}")
    return value


def directory(text):
    """An argparse type: a directory, or a path where none is yet."""
    if os.path.exists(text) and not os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"expected a directory, not the file {text!r}")
    return text


def program(text):
    """An argparse type: the clv binary, a path or a name on PATH."""
    if shutil.which(text) is None:
        raise argparse.ArgumentTypeError(f"expected the clv binary, not {text!r} (not there or not executable): build it with `cargo build --release` or give its path")
    return text


def numbers(parse_one, what, count, example):
    """An argparse type: at least `count` different comma-separated values of `parse_one`
    (`what` says what they are), returned sorted."""
    def parse(text):
        try:
            values = sorted({parse_one(x) for x in text.split(",") if x.strip()})
        except argparse.ArgumentTypeError:
            values = []
        if len(values) < count:
            raise argparse.ArgumentTypeError(f"expected at least {count} different {what}, comma-separated (e.g. {example}), not {text!r}")
        return values
    return parse


def arguments(doc, default_n, table, min_n, counts=2, one_n=False, density=True):
    """The options every study has (--out, --n, --density unless not `density`, --clv-bin);
    add the study's own to the returned parser. --n takes at least `counts` numbers of disks,
    each at least `min_n` (exactly one with `one_n`)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--out", type=directory, required=True, help=f"directory for the runs and the tables; the same --out and options again continue a study that stopped (one that wrote {table} is finished)")
    if one_n:
        ap.add_argument("--n", type=lambda text: [whole(min_n, "one number of disks")(text)], default=default_n, help=f"number of disks (at least {min_n})")
    else:
        ap.add_argument("--n", type=numbers(whole(min_n), f"numbers of disks, each at least {min_n}", counts, default_n), default=default_n, help=f"numbers of disks, comma-separated (each at least {min_n})")
    if density:
        ap.add_argument("--density", type=positive, default=0.7, help="number density rho")
    ap.add_argument("--clv-bin", type=program, default=os.path.join(os.environ.get("CARGO_TARGET_DIR") or os.path.join(HERE, "..", "target"), "release", "clv"), help="the clv binary (default: release/clv under $CARGO_TARGET_DIR, else target/release/clv of this repository)")
    return ap


class Study:
    """A study named `name` (for messages) writing `table` into a directory that must not hold
    one already: the runs of a study are never replaced, and a study that stopped continues."""

    def __init__(self, name, a, table):
        self.name, self.clv, self.ns = name, a.clv_bin, a.n
        self.table = os.path.join(a.out, table)
        if os.path.exists(self.table):
            self.fail(f"{self.table} exists: this study is finished; choose another --out for a new one")
        self.runs = os.path.join(a.out, "runs")
        try:
            os.makedirs(self.runs, exist_ok=True)
        except OSError as e:
            self.fail(f"cannot make {self.runs}: {e.strerror}")

    def fail(self, message):
        sys.exit(f"{self.name}: {message}")

    def note(self, message):
        print(f"{self.name}: {message}", file=sys.stderr)

    def cannot_start(self, e):
        if isinstance(e, FileNotFoundError):
            self.fail(f"{self.clv} not found; build it with `cargo build --release` or name it with --clv-bin")
        self.fail(f"cannot run {self.clv}: {e.strerror}")

    def run(self, args, **kw):
        """Run clv with `args`; if it fails, stop with its name (its own message is above)."""
        try:
            return subprocess.run([self.clv] + args, check=True, **kw)
        except OSError as e:
            self.cannot_start(e)
        except subprocess.CalledProcessError as e:
            self.fail(f"`clv {' '.join(args[:2])} ...` failed (exit status {e.returncode}); its message is above")

    def forward(self, run_dir, args):
        """`clv forward ARGS --out RUN_DIR`; where the study made RUN_DIR before,
        `clv forward --resume RUN_DIR ARGS`, which continues an interrupted run, leaves a
        finished one as it is, and refuses ARGS other than the run's."""
        if not os.path.exists(os.path.join(run_dir, "run.json")):
            self.run(["forward"] + args + ["--out", run_dir], stdout=subprocess.DEVNULL)
            return
        # A larger --steps would make clv extend the run: a study never does (a mistyped
        # option would change its finished runs), so it compares before it calls clv.
        if "--steps" in args:
            asked = args[args.index("--steps") + 1]
            try:
                with open(os.path.join(run_dir, "run.json")) as f:
                    made = json.load(f)["config"]["steps"]
            except (OSError, ValueError, KeyError, TypeError):
                made = None
            if made is not None and str(made) != str(asked):
                self.fail(f"{run_dir} was made with --steps {made}, not {asked}; give the options the study was started with, or another --out for a new study (a study does not make its runs longer)")
        if not os.path.exists(os.path.join(run_dir, "spectrum.json")):
            self.note(f"resuming the interrupted run {run_dir}")
        try:
            subprocess.run([self.clv, "forward", "--resume", run_dir] + args, check=True, stdout=subprocess.DEVNULL)
        except OSError as e:
            self.cannot_start(e)
        except subprocess.CalledProcessError:
            self.fail(f"could not continue {run_dir} (message above); give the options the study was started with, or another --out for a new study")

    def saved_forward(self, path, n, density, aspect, steps, args):
        """The spectrum of `clv forward ARGS --json` (no run directory), kept in `path`: read
        from there if an earlier start of the study saved it with these settings."""
        if os.path.exists(path):
            try:
                with open(path) as f:
                    saved = json.load(f)
                c = saved["config"]
                same = (c["system"]["n"], c["system"]["density"], c["system"]["aspect"], c["steps"]) == (n, density, aspect, steps)
            except (OSError, ValueError, KeyError, TypeError):
                same = None
            if same:
                self.note(f"{path} is there from an earlier start: kept")
                return saved
            self.fail(f"{path} was computed with other settings" + (" (or is damaged)" if same is None else "") + "; give the options the study was started with, or another --out for a new study")
        out = self.run(["forward"] + args + ["--json"], stdout=subprocess.PIPE, text=True).stdout
        with open(path + ".tmp", "w") as f:
            f.write(out)
        os.replace(path + ".tmp", path)
        return json.loads(out)

    def report_finished(self, run_dir, report, every, files):
        """Whether `report` is finished (its summary.json) and made from the finished backward
        sweep of `run_dir` (its clv_spectrum.json, which `clv forward --resume --steps` moves
        away), both every `every` steps, and holds `files`."""
        try:
            with open(os.path.join(report, "summary.json")) as f:
                summary = json.load(f)
            with open(os.path.join(run_dir, "clv_spectrum.json")) as f:
                sweep = json.load(f)
            st = sweep["statistics"]
            return (
                (summary["frames"], summary["first_step"], summary["last_step"]) == (st["frames"], st["first_frame_step"], st["last_frame_step"])
                and sweep["options"]["vectors_every"] == every
                and summary["options"]["every"] == every
                and all(os.path.exists(os.path.join(report, f)) for f in files)
            )
        except (OSError, ValueError, KeyError, TypeError):
            return False

    def backward_into_analyze(self, run_dir, report, only, files, every=1):
        """`clv backward RUN --out - --vectors-every M | clv analyze - --out REPORT --only ONLY
        --every M`, unless REPORT is already the finished report of this run, with `files`."""
        if self.report_finished(run_dir, report, every, files):
            self.note(f"{run_dir} and its report are finished: kept")
            return
        try:
            sweep = subprocess.Popen([self.clv, "backward", run_dir, "--out", "-", "--quiet", "--vectors-every", str(every)], stdout=subprocess.PIPE)
        except OSError as e:
            self.cannot_start(e)
        self.run(["analyze", "-", "--out", report, "--overwrite", "--quiet", "--only", only, "--every", str(every)], stdin=sweep.stdout)
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
