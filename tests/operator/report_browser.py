"""`maglead report` on simulated recordings, opened in headless chromium: the page renders, every
plot decodes (a script in the page marks <body data-images="ok"> only then), and the report finds
the step-outs of a recording with overload pulses but none in a clean one.
Usage: report_browser.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

from op_common import check, finish, run, watchdog

MAGLEAD, CONFIG, WORK = sys.argv[1], sys.argv[2], sys.argv[3]
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage"]


def chromium(*args):
    profile = tempfile.mkdtemp(prefix="maglead-chromium-")
    try:
        return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args],
                              capture_output=True, text=True, timeout=60)
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def report(name, *sim_args, analysis=True, screenshot=False):
    rec = os.path.join(WORK, name + ".csv")
    rc, out, err = run(MAGLEAD, "simulate", "--config", CONFIG, "--out", rec, *sim_args)
    check(rc == 0, f"simulate {name}: {err.strip()[-200:]}")
    out_dir = os.path.join(WORK, name)
    extra = [] if analysis else ["--no-analysis"]
    rc, out, err = run(MAGLEAD, "report", "--config", CONFIG, "--recording", rec, "--out", out_dir, *extra,
                       timeout=120)
    check(rc == 0, f"report {name}: {out.strip()} {err.strip()[-300:]}")
    with open(os.path.join(out_dir, "report.json")) as f:
        j = json.load(f)
    page = os.path.join(out_dir, "index.html")
    dom = chromium("--virtual-time-budget=5000", "--dump-dom", "file://" + page)
    check(dom.returncode == 0 and "<h1>Twin versus actual" in dom.stdout, f"chromium renders {name} ({dom.returncode})")
    n_img = len(re.findall(r"<img ", dom.stdout))
    check(n_img >= 3 and 'data-images="ok"' in dom.stdout and f"all {n_img} plots loaded" in dom.stdout,
          f"all {n_img} plots of {name} load in the browser")
    if not screenshot:
        return j
    shot = os.path.join(WORK, name + "_screenshot.png")
    s = chromium(f"--screenshot={shot}", "--window-size=1200,2400", "--hide-scrollbars", "file://" + page)
    check(s.returncode == 0 and os.path.exists(shot) and os.path.getsize(shot) > 20000,
          f"screenshot of {name} written ({shot})")
    return j


def main():
    watchdog(85)
    os.makedirs(WORK, exist_ok=True)
    check(os.path.exists(CHROMIUM), f"chromium found at {CHROMIUM}")
    clean = report("clean", "--scenario", "hand-push", "--duration", "8s", "--seed", "4", analysis=False)
    check(clean["step_outs"] == [], f"clean recording: no step-out ({clean['step_outs']})")
    check(clean["force_error"] is not None and clean["force_error"]["static"]["mean_abs_n"] < 4.0,
          f"clean: static estimate error against the load cell {clean['force_error']}")
    bad = report("overload", "--scenario", "hand-push", "--duration", "8s", "--seed", "4",
                 "--effect", "offset=30", analysis=False)
    check(len(bad["step_outs"]) >= 1 and bad["headline"].startswith("attention"),
          f"constant 30 N on a nut pushed by hand: step-outs found {len(bad['step_outs'])}, "
          f"headline '{bad['headline']}'")
    check(bad["static_estimate_off_branch_samples"] > 0, "off-branch samples left out of the static estimate")
    drift = report("drift", "--scenario", "force-steps", "--duration", "30s", "--seed", "4",
                   "--effect", "gain_drift=-0.2", screenshot=True)
    check(len(drift["drift_windows"]) >= 1 and drift["step_outs"] == [],
          f"coupling losing 20 %/min: drift window {drift['drift_windows']}")
    effects = [e["id"] for e in drift["analysis"].get("effects", [])]
    check(drift["analysis"]["status"] == "done" and "gain_drift" in effects,
          f"analysis verdict names the drift: {drift['analysis'].get('conclusion')} {effects}")
    finish()


if __name__ == "__main__":
    main()
