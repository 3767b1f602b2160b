#!/usr/bin/python3
"""The corrected model never makes the twin worse on the recording it came from (issue 24).

usage: twin_round_trip.py MAGLEAD CONFIG_DIR WORK_DIR

For generated recordings (one effect each, and a control): `maglead analyze` writes
model_corrected.toml and prints "twin force error A → B N"; `maglead estimate --estimator twin`
with the configured model and then with `--model model_corrected.toml` must print the same two
figures (the analysis ran the very estimator a user runs), and B must not exceed A by more than
the force the recording resolves (analysis.json's twin_force_check.resolved_n: the rule by which
the analysis keeps a term). A viscous friction found on moves at up to 50 mm/s (a few counts a
sample) must be kept: the twin with the right viscous term is better there, not worse.
"""
import json, os, re, subprocess, sys

exe, config, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
CASES = [("position-moves", []),
         ("position-moves", ["viscous_friction=50"]),
         ("position-moves", ["viscous_friction=20"]),
         ("hand-push", ["offset=2"]),
         ("force-steps", ["backlash=0.05"]),
         ("hand-push", ["gain_drift=-0.05"]),
         ("position-moves", ["stribeck_friction=4.5"]),
         ("force-steps", ["load_cell_delay=0.01"])]


def run(*args):
    r = subprocess.run([exe, *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"maglead {' '.join(args)} failed:\n{r.stdout}{r.stderr}")
    return r.stdout


def mae(text):
    m = re.search(r"mean absolute error\s+([0-9.]+) N", text)
    return float(m.group(1))


failures = 0
print("| case | analyze: twin force error | estimate: configured | estimate: corrected |")
for k, (scenario, effects) in enumerate(CASES):
    rec = os.path.join(work, f"case{k}.csv")
    out = os.path.join(work, f"case{k}")
    args = ["simulate", "--scenario", scenario, "--duration", "40s", "--seed", "5",
            "--out", rec, "--config", config]
    for e in effects:
        args += ["--effect", e]
    run(*args)
    text = run("analyze", "--recording", rec, "--out", out, "--config", config)
    m = re.search(r"twin force error ([0-9.]+) → ([0-9.]+) N", text)
    if not m:
        sys.exit(f"no twin force error line in:\n{text}")
    a, b = float(m.group(1)), float(m.group(2))
    png = os.path.join(work, "p.png")
    base = mae(run("estimate", "--recording", rec, "--estimator", "twin", "--config", config,
                   "--plot", png))
    corr = mae(run("estimate", "--recording", rec, "--estimator", "twin", "--config", config,
                   "--model", os.path.join(out, "model_corrected.toml"), "--plot", png))
    name = scenario + (" " + " ".join(effects) if effects else " (control)")
    print(f"| {name} | {a:.2f} → {b:.2f} N | {base:.2f} N | {corr:.2f} N |")
    if abs(a - base) > 0.011 or abs(b - corr) > 0.011:
        print(f"  FAIL: analyze and estimate disagree")
        failures += 1
    check = json.load(open(os.path.join(out, "analysis.json")))["twin_force_check"]
    if corr > base + check["resolved_n"]:
        print(f"  FAIL: the corrected model made the twin worse by more than "
              f"{check['resolved_n']:.3f} N")
        failures += 1
    print(f"  left out: {check['dropped'] or 'none'}")
    if any(e.startswith("viscous_friction=") for e in effects) and check["dropped"]:
        print(f"  FAIL: left out {check['dropped']}, found on a recording made with them")
        failures += 1
sys.exit(1 if failures else 0)
