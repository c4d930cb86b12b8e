#!/usr/bin/env python3
"""Interrupt safety of optinav's commands (issue 22).

Kills a command with SIGINT or SIGKILL at a seeded random moment of its run and checks that no
final output is half-written: each output is the old file, no file, or the complete new one, and
an output folder either carries its completion marker with everything complete or is refused by
the next run as an interrupted one.

usage: interrupt_test.py OPTINAV SHARED_DATA COMMAND [--kills N] [--seed S] [--keep]
COMMAND: eval | map-build | sim | vio | mission
"""
import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

FAILURES = []


def fail(msg):
    FAILURES.append(msg)
    print("FAIL: " + msg, flush=True)


def run(cmd, **kw):
    return subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          errors="replace", **kw)


def must(cmd, what):
    r = run(cmd)
    if r.returncode != 0:
        print(r.stdout, r.stderr)
        raise SystemExit(f"setup failed: {what}: exit {r.returncode}")
    return r


def read_bytes(path):
    with open(path, "rb") as f:
        return f.read()


def run_killed(cmd, delay_s, sig):
    """Starts cmd, sends sig after delay_s (if still running); returns (returncode, killed)."""
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + delay_s
    while time.monotonic() < deadline and p.poll() is None:
        time.sleep(min(0.005, max(0.0, deadline - time.monotonic())))
    killed = p.poll() is None
    if killed:
        p.send_signal(sig)
    try:
        _, err = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        fail(f"{' '.join(cmd)}: still running 120 s after {signal.Signals(sig).name}")
        return None, killed, ""
    return p.returncode, killed, err.decode("utf-8", "replace")


def check_exit(name, rc, killed, sig, err):
    if rc is None:
        return
    if not killed:
        if rc != 0:
            fail(f"{name}: finished before the kill with exit {rc}: {err[-400:]}")
        return
    # Killed: the signal's own status (-sig), or 130/137-style exits from a shell; a run that
    # ended by itself in the same instant exits 0. Anything else (an abort, a crash, a
    # sanitizer report) is a finding.
    if rc not in (0, -sig, 128 + sig):
        fail(f"{name}: after {signal.Signals(sig).name} exit {rc} (expected {-sig}): {err[-400:]}")


def file_state(path, old, validate):
    """'none', 'old' or 'new' (complete); a failure otherwise."""
    if not os.path.exists(path):
        return "none"
    data = read_bytes(path)
    if old is not None and data == old:
        return "old"
    problem = validate(path, data)
    return "new" if problem is None else "broken: " + problem


# ---- validators of complete outputs -------------------------------------------------------

def valid_json(_, data):
    try:
        json.loads(data)
        return None
    except ValueError as e:
        return f"not valid JSON ({e})"


def valid_svg(_, data):
    return None if data.rstrip().endswith(b"</svg>") else "SVG does not end with </svg>"


def valid_png(_, data):
    return None if data.startswith(b"\x89PNG") and data.endswith(b"IEND\xaeB`\x82") \
        else "PNG truncated"


def valid_tum(expected_rows):
    def check(_, data):
        rows = [l for l in data.decode("utf-8", "replace").splitlines()
                if l.strip() and not l.startswith("#")]
        for i, l in enumerate(rows):
            parts = l.split()
            if len(parts) != 8:
                return f"row {i + 1} has {len(parts)} fields"
            try:
                [float(x) for x in parts]
            except ValueError:
                return f"row {i + 1} is not numeric"
        if expected_rows is not None and len(rows) != expected_rows:
            return f"{len(rows)} rows, expected {expected_rows}"
        return None
    return check


def equal_to(reference):
    return lambda _, data: None if data == reference else "differs from a complete run's output"


def refused_as_interrupted(tag, folder, cmd):
    """The next run without --force must refuse a killed run's folder and say it was
    interrupted (while it holds optinav_incomplete.txt; after that only the completion marker is
    missing, in the instant between the two, and a plain "not empty" refusal is right)."""
    in_progress = os.path.exists(os.path.join(folder, "optinav_incomplete.txt"))
    r = run(cmd)
    needle = "interrupted" if in_progress else "not empty"
    if r.returncode != 1 or needle not in r.stderr:
        fail(f"{tag}: the next run did not refuse the interrupted folder ({needle}): exit "
             f"{r.returncode}: {r.stderr[-300:]}")
    return in_progress


# ---- the commands ---------------------------------------------------------------------------

class Case:
    """One command: setup() once, then cmd() is run and killed; check() after each kill."""

    def __init__(self, binary, data, work):
        self.bin, self.data, self.work = binary, data, work


class FileOutputsCase(Case):
    """A command whose outputs are files: each is checked by its validator in self.validators
    unless it is the old content put in place by prepare() (self.old)."""

    def cmd(self):
        return self.args

    def check(self, tag):
        for p, v in self.validators.items():
            s = file_state(p, self.old.get(p), v)
            if s.startswith("broken"):
                fail(f"{tag}: {os.path.basename(p)} {s}")


class EvalCase(FileOutputsCase):
    name = "eval"

    def setup(self):
        t = os.path.join(self.data, "trajectories")
        self.out_json = os.path.join(self.work, "ape.json")
        self.out_svg = os.path.join(self.work, "ape.svg")
        self.args = [self.bin, "eval", "ape", os.path.join(t, "KITTI_00_gt.txt"),
                     os.path.join(t, "KITTI_00_ORB.txt"), "--align", "se3", "--json",
                     self.out_json, "--plot", self.out_svg]
        must(self.args, "reference eval")
        self.ref = {p: read_bytes(p) for p in (self.out_json, self.out_svg)}
        self.validators = {self.out_json: equal_to(self.ref[self.out_json]),
                           self.out_svg: equal_to(self.ref[self.out_svg])}

    def prepare(self, rng):
        # Half of the runs start with an old output in place (a different, valid file), half
        # without one.
        self.old = {}
        for p in (self.out_json, self.out_svg):
            if os.path.exists(p):
                os.remove(p)
            if rng.random() < 0.5:
                content = b'{"old": true}\n' if p.endswith(".json") else \
                    b'<svg xmlns="http://www.w3.org/2000/svg"></svg>\n'
                with open(p, "wb") as f:
                    f.write(content)
                self.old[p] = content


class MapBuildCase(Case):
    name = "map-build"

    def setup(self):
        naip = os.path.join(self.data, "geo", "naip", "naip_20090818.tif")
        self.out = os.path.join(self.work, "map.db")
        self.args = [self.bin, "map", "build", "--ortho", naip, "--altitude", "640", "--hfov",
                     "90", "--frame-size", "256x256", "--out", self.out]
        must(self.args, "reference map build")
        self.ref_info = self.info()
        self.old_db = read_bytes(self.out)

    def info(self):
        r = run([self.bin, "map", "info", self.out, "--check", "--json"])
        if r.returncode != 0:
            return None
        j = json.loads(r.stdout)
        j.pop("path", None)
        j.pop("file_bytes", None)
        return json.dumps(j, sort_keys=True)

    def prepare(self, rng):
        self.had_old = rng.random() < 0.5
        if os.path.exists(self.out):
            os.remove(self.out)
        if self.had_old:
            with open(self.out, "wb") as f:
                f.write(self.old_db)

    def cmd(self):
        return self.args

    def check(self, tag):
        if not os.path.exists(self.out):
            if self.had_old:
                fail(f"{tag}: the old map database was removed")
            return
        info = self.info()
        if info is None:
            fail(f"{tag}: map.db does not pass map info --check")
        elif info != self.ref_info:
            fail(f"{tag}: map.db differs from a complete build's")


class SimCase(Case):
    name = "sim"
    marker = "sim_complete.json"

    def setup(self):
        self.out = os.path.join(self.work, "seq")
        self.args = [self.bin, "sim", "--out", self.out, "--world", "urban", "--route", "car",
                     "--duration", "4", "--scale", "0.25", "--seed", "3", "--force"]
        must(self.args, "reference sim")
        self.ref = self.listing()

    def listing(self):
        files = {}
        for root, _, names in os.walk(self.out):
            for n in names:
                p = os.path.join(root, n)
                files[os.path.relpath(p, self.out)] = os.path.getsize(p)
        return files

    def prepare(self, rng):
        pass  # --force replaces whatever the previous (killed or complete) run left

    def cmd(self):
        return self.args

    def check(self, tag):
        if not os.path.isdir(self.out):
            return
        if os.path.exists(os.path.join(self.out, self.marker)):
            got = self.listing()
            missing = sorted(set(self.ref) - set(got))
            if missing:
                fail(f"{tag}: {self.marker} present but {missing[:3]} missing")
            for rel, size in self.ref.items():
                if rel in got and rel != self.marker and got[rel] != size and \
                        not rel.endswith(".png"):
                    fail(f"{tag}: {rel} has {got[rel]} bytes, a complete run {size}")
            return
        if not os.listdir(self.out):
            return
        # Interrupted: the next run without --force must say so, and the dataset readers
        # must not take it for a complete dataset.
        if not refused_as_interrupted(tag, self.out, self.args[:-1]):
            return
        r = run([self.bin, "vio", "--dataset", self.out, "--out",
                 os.path.join(self.work, "probe.tum")])
        if r.returncode != 1 or "interrupted" not in r.stderr:
            fail(f"{tag}: vio accepted an interrupted simulation: exit {r.returncode}: "
                 f"{r.stderr[-300:]}")


class VioCase(FileOutputsCase):
    name = "vio"

    def setup(self):
        self.seq = os.path.join(self.work, "seq")
        must([self.bin, "sim", "--out", self.seq, "--world", "urban", "--route", "car",
              "--duration", "6", "--scale", "0.25", "--seed", "3"], "sim for vio")
        self.out = os.path.join(self.work, "traj.tum")
        self.stats = os.path.join(self.work, "stats.json")
        self.args = [self.bin, "vio", "--dataset", self.seq, "--out", self.out, "--stats",
                     self.stats]
        must(self.args, "reference vio")
        rows = [l for l in open(self.out) if l.strip() and not l.startswith("#")]
        self.validators = {self.out: valid_tum(len(rows)), self.stats: valid_json}
        self.old_content = {self.out: b"# old\n0 0 0 0 0 0 0 1\n", self.stats: b'{"old": 1}\n'}

    def prepare(self, rng):
        self.old = {}
        for p in (self.out, self.stats):
            if os.path.exists(p):
                os.remove(p)
            if rng.random() < 0.5:
                with open(p, "wb") as f:
                    f.write(self.old_content[p])
                self.old[p] = self.old_content[p]


class MissionCase(Case):
    name = "mission"
    marker = "summary.json"

    def setup(self):
        naip = os.path.join(self.data, "geo", "naip")
        self.db = os.path.join(self.work, "map.db")
        must([self.bin, "map", "build", "--ortho", os.path.join(naip, "naip_20090818.tif"),
              "--altitude", "640", "--hfov", "90", "--frame-size", "256x256", "--out", self.db],
             "map for mission")
        self.out = os.path.join(self.work, "mission")
        self.args = [self.bin, "mission", "--map", self.db, "--start", "random", "--target",
                     "random", "--runs", "1", "--seed", "4", "--min-distance", "1000",
                     "--frames-from", os.path.join(naip, "naip_20170827.tif"), "--out",
                     self.out, "--pictures", "summary", "--force"]
        must(self.args, "reference mission")
        self.ref = sorted(self.listing())

    def listing(self):
        out = []
        for root, _, names in os.walk(self.out):
            out += [os.path.relpath(os.path.join(root, n), self.out) for n in names]
        return out

    def prepare(self, rng):
        pass

    def cmd(self):
        return self.args

    def check(self, tag):
        if not os.path.isdir(self.out) or not os.listdir(self.out):
            return
        got = self.listing()
        if self.marker in got:
            missing = sorted(set(self.ref) - set(got))
            if missing:
                fail(f"{tag}: {self.marker} present but {missing[:3]} missing")
            validators = {".json": valid_json, ".svg": valid_svg, ".png": valid_png,
                          ".geojson": valid_json}
            for rel in got:
                v = validators.get(os.path.splitext(rel)[1])
                if v:
                    p = os.path.join(self.out, rel)
                    problem = v(p, read_bytes(p))
                    if problem:
                        fail(f"{tag}: {rel}: {problem}")
            return
        refused_as_interrupted(tag, self.out, self.args[:-1])


CASES = {c.name: c for c in (EvalCase, MapBuildCase, SimCase, VioCase, MissionCase)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("data")
    ap.add_argument("command", choices=sorted(CASES))
    ap.add_argument("--kills", type=int, default=50)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", action="store_true")
    a = ap.parse_args()
    data = os.environ.get("OPTINAV_SHARED_DATA", a.data)
    work = tempfile.mkdtemp(prefix=f"optinav_interrupt_{a.command}_")
    try:
        case = CASES[a.command](os.path.abspath(a.binary), data, work)
        t0 = time.monotonic()
        case.setup()
        # One timed, uninterrupted run gives the span the kill moments are drawn from.
        case.prepare(random.Random(0))
        t0 = time.monotonic()
        must(case.cmd(), "timed run")
        span = time.monotonic() - t0
        print(f"{a.command}: a complete run takes {span:.2f} s; {a.kills} seeded kills",
              flush=True)
        finished = 0
        for i in range(a.kills):
            rng = random.Random(a.seed * 100003 + i)
            sig = signal.SIGINT if i % 2 == 0 else signal.SIGKILL
            delay = rng.uniform(0.0, 0.95 * span)
            case.prepare(rng)
            rc, killed, err = run_killed(case.cmd(), delay, sig)
            tag = f"{a.command} kill {i} ({signal.Signals(sig).name} at {delay:.3f} s)"
            check_exit(tag, rc, killed, sig, err)
            case.check(tag)
            finished += 0 if killed else 1
        print(f"{a.command}: {a.kills} kills ({finished} runs ended before the signal), "
              f"{len(FAILURES)} failure(s)")
    finally:
        if a.keep:
            print("kept", work)
        else:
            shutil.rmtree(work, ignore_errors=True)
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main())
