#!/usr/bin/env python3
"""The HTML report in a real browser (ctest report/browser).

Makes a small mission run (2 runs over the real NAIP map) and a small GNSS benchmark (40 s of
the outdoor flight, two conditions, two norms), each with --html, then loads every report in
Debian's headless Chromium and checks that
  - the browser logged no console message (script errors, failed loads; --enable-logging) and the
    page's own error hook counted none;
  - the page finished building its maps (#report-status data-state="ready");
  - the DOM holds the map container and exactly the paths, fixes and markers the command's other
    outputs call for (mission: 2 paths and start + target per run, one dot per found fix in the
    runs' steps.csv; bench gnss: the document's visible layers);
  - the page loads nothing from the network;
  - a click on a fix opens its popup (time, error, method; inliers for a mission);
and saves a screenshot of each. Exit 77 (ctest: skipped) only when chromium is not installed.

Usage: report_browser_test.py OPTINAV_BINARY SHARED_DATA_DIR [--work DIR] [--shots DIR]
"""
import argparse
import csv
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

CHROMIUM = "/usr/bin/chromium"


def fail(msg):
    print("report_browser_test: FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def run(cmd, timeout=600):
    print("+ " + " ".join(cmd), flush=True)
    t0 = time.monotonic()
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if p.returncode not in (0, 3):  # mission: 3 = some run missed the target, still a report
        fail("%s exited %d:\n%s\n%s" % (cmd[1], p.returncode, p.stdout[-3000:], p.stderr[-3000:]))
    return p.stdout, time.monotonic() - t0


def chromium(args, timeout=120):
    profile = tempfile.mkdtemp(prefix="optinav_chromium_")
    try:
        cmd = [CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu",
               "--user-data-dir=" + profile, "--no-first-run", "--hide-scrollbars",
               "--virtual-time-budget=8000"] + args
        return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def visible(view, items):
    hidden = set(view.get("hidden_layers", []))
    return [x for x in items if x.get("layer") not in hidden]


def check_report(html_path, expected, shot_path, popup_words=()):
    html = open(html_path, encoding="utf-8").read()
    # Offline: the file has no <link> and no script or image from a URL, and its style sheets
    # refer only to data URIs (checked again on the DOM the scripts built).
    def check_offline(text, what):
        for m in re.finditer(r'<(?:script|img|link|iframe)\b[^>]*\b(?:src|href)="([^"]*)"', text):
            if not m.group(1).startswith("data:"):
                fail("%s (%s) loads %s" % (html_path, what, m.group(1)))
        css = "".join(re.findall(r"<style[^>]*>(.*?)</style>", text, re.S) +
                      re.findall(r'style="([^"]*)"', text))
        if re.search(r"url\((?!data:|#)", css):  # "#default#VML": old IE behaviour, no load
            fail("%s (%s): a style sheet url() that is not a data URI" % (html_path, what))
    check_offline(html, "file")
    url = "file://" + os.path.abspath(html_path)
    p = chromium(["--enable-logging=stderr", "--v=0", "--window-size=1280,1600", "--dump-dom",
                  url])
    if p.returncode != 0:
        fail("chromium exited %d on %s:\n%s" % (p.returncode, html_path, p.stderr[-3000:]))
    console = [l for l in p.stderr.splitlines() if ":CONSOLE" in l]
    if console:
        fail("console messages on %s:\n%s" % (html_path, "\n".join(console)))
    dom = p.stdout
    check_offline(dom, "DOM")
    status = re.search(r'<div id="report-status"([^>]*)>([^<]*)<', dom)
    if not status:
        fail("%s: no #report-status in the DOM" % html_path)
    attrs = dict(re.findall(r'data-([a-z]+)="([^"]*)"', status.group(1)))
    if attrs.get("errors") != "0":
        fail("%s: the page caught script errors: %s" % (html_path, status.group(2)))
    if attrs.get("state") != "ready":
        fail("%s: the page did not finish (state %s)" % (html_path, attrs.get("state")))
    maps = len(re.findall(r'<div class="map leaflet-container', dom))
    counts = {k: len(re.findall(r'class="optinav-%s[ "]' % k, dom))
              for k in ("path", "fix", "marker")}
    counts["map"] = maps
    for key, want in expected.items():
        if counts[key] != want:
            fail("%s: %d %s element(s) in the DOM, expected %d" % (html_path, counts[key], key,
                                                                   want))
    if "leaflet-control-layers" not in dom:
        fail("%s: no layer switcher" % html_path)
    if "<svg" not in dom:
        fail("%s: no error chart" % html_path)
    # A click on the first fix opens its popup with the time, error, method and inliers.
    clicked = html_path + ".click.html"
    with open(clicked, "w", encoding="utf-8") as f:
        f.write(html.replace("</body>", """<script>window.addEventListener('load', function () {
  document.querySelector('path.optinav-fix').dispatchEvent(
      new MouseEvent('click', {bubbles: true, clientX: 1, clientY: 1}));
});</script></body>"""))
    p = chromium(["--enable-logging=stderr", "--v=0", "--window-size=1280,1600", "--dump-dom",
                  "file://" + os.path.abspath(clicked)])
    popup = re.search(r'<div class="leaflet-popup-content"[^>]*>(.*?)</div>', p.stdout)
    if not popup:
        fail("%s: clicking a fix opened no popup" % html_path)
    for word in ("time ", " s<br>error ", " m<br>method ") + tuple(popup_words):
        if word not in popup.group(1):
            fail("%s: the fix popup lacks '%s': %s" % (html_path, word, popup.group(1)))
    print("ok: fix popup: " + popup.group(1))
    p = chromium(["--window-size=1200,1500", "--screenshot=" + shot_path, url])
    if p.returncode != 0 or not os.path.isfile(shot_path):
        fail("no screenshot of %s:\n%s" % (html_path, p.stderr[-2000:]))
    with open(shot_path, "rb") as f:
        if f.read(8) != b"\x89PNG\r\n\x1a\n":
            fail("%s is not a PNG" % shot_path)
    print("ok: %s in chromium: %s, screenshot %s (%d bytes)" %
          (html_path, counts, shot_path, os.path.getsize(shot_path)))


def mission_expected(out):
    summary = json.load(open(os.path.join(out, "summary.json")))
    runs = summary["per_run"]
    fixes = 0
    for steps in sorted(glob.glob(os.path.join(out, "run_*", "steps.csv"))):
        with open(steps, newline="") as f:
            fixes += sum(1 for row in csv.DictReader(f) if row["fix_found"] == "1")
    missed = sum(1 for r in runs if not r["reached"])
    return {"map": 1, "path": 2 * len(runs), "fix": fixes, "marker": 2 * len(runs) + missed}


def document_expected(out):
    doc = json.load(open(os.path.join(out, "report.json")))
    e = {"map": len(doc["views"]), "path": 0, "fix": 0, "marker": 0}
    for v in doc["views"]:
        e["path"] += sum(1 for p in visible(v, v["paths"]) if p["points"])
        e["fix"] += len(visible(v, v["fixes"]))
        e["marker"] += len(visible(v, v["markers"]))
    return e


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("optinav")
    ap.add_argument("data")
    ap.add_argument("--work", help="keep the outputs here (default: a temporary folder)")
    ap.add_argument("--shots", help="screenshots here (default: the work folder)")
    a = ap.parse_args()
    if not os.access(CHROMIUM, os.X_OK):
        print("report_browser_test: SKIPPED: %s is not installed (scripts/setup.sh installs the "
              "Debian package chromium)" % CHROMIUM)
        return 77
    # $OPTINAV_SHARED_DATA overrides the configured default, as for every other test.
    data = os.environ.get("OPTINAV_SHARED_DATA") or a.data
    naip = os.path.join(data, "geo", "naip")
    if not os.path.isdir(naip):
        fail("no NAIP data in %s (set OPTINAV_SHARED_DATA)" % naip)
    work = a.work or tempfile.mkdtemp(prefix="optinav_report_")
    shots = a.shots or work
    os.makedirs(work, exist_ok=True)
    os.makedirs(shots, exist_ok=True)
    try:
        db = os.path.join(work, "naip.db")
        if not os.path.isfile(db):
            run([a.optinav, "map", "build", "--ortho", os.path.join(naip, "naip_20090818.tif"),
                 "--altitude", "640", "--hfov", "90", "--frame-size", "256x256", "--out", db])
        mission = os.path.join(work, "mission")
        out, _ = run([a.optinav, "mission", "--map", db, "--start", "47.0178,-99.1711",
                      "--target", "47.0150,-99.1500", "--runs", "2", "--speed", "40", "--step",
                      "2", "--frames-from", os.path.join(naip, "naip_20170827.tif"),
                      "--pictures", "none", "--out", mission, "--force", "--html"])
        if "report: " not in out:
            fail("mission --html printed no report line")
        expected = mission_expected(mission)
        if expected["fix"] == 0:
            fail("the mission found no fix: nothing to check the dots against")
        check_report(os.path.join(mission, "report.html"), expected,
                     os.path.join(shots, "report_mission.png"), popup_words=["inliers "])
        # `optinav report DIR --out` renders the same document again.
        again = os.path.join(work, "again.html")
        run([a.optinav, "report", mission, "--out", again])
        if open(again, "rb").read() != open(os.path.join(mission, "report.html"), "rb").read():
            fail("optinav report and mission --html differ")

        bench = os.path.join(work, "bench_gnss")
        run([a.optinav, "bench", "gnss", "--out", bench, "--sequences", "outdoor",
             "--conditions", "sigma1.5,outliers", "--norms", "huber,tukey", "--seeds", "1",
             "--scale", "0.3", "--duration", "40", "--jobs", "2", "--reuse", "--html"])
        expected = document_expected(bench)
        doc = json.load(open(os.path.join(bench, "report.json")))
        layers = {p["layer"] for p in doc["views"][0]["paths"]}
        for want in ("ground truth", "VIO alone (first 5 s aligned)"):
            if want not in layers:
                fail("bench gnss report lacks the layer '%s' (has %s)" % (want, sorted(layers)))
        if expected["fix"] == 0 or expected["path"] < 3:
            fail("bench gnss report: too little drawn: %s" % expected)
        check_report(os.path.join(bench, "report.html"), expected,
                     os.path.join(shots, "report_bench_gnss.png"))
    finally:
        if not a.work:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
