#!/usr/bin/python3
"""What a recording cannot show is said, and said right (analysis.json's `resolvable`).

usage: resolvable.py MAGLEAD CONFIG_DIR WORK_DIR

A recording with nothing added: the analysis names nothing and lists, per one-column effect, the
smallest change it could name. The list must mean what it says: on the same scenario and seed
with an effect added at 0.4 of its listed size the effect is not named, at 2.5 times it is (and
within 2 standard errors + 10 % of the true total: a named size is a measured size). The
control's conclusion is the one docs/analysis.md shows.
"""
import json, os, subprocess, sys

exe, config, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
SCENARIO = ["--scenario", "mixed-moves", "--duration", "40s", "--seed", "3"]
# plant effect, finding id, parameter, the model's value the plant's change adds to
EFFECTS = [("viscous_friction", "viscous_friction", "viscous_n_s_per_m", 2.0),
           ("coulomb_friction", "coulomb_friction", "coulomb_n", 7.5),
           ("offset", "offset", "offset_n", 0.0)]


def analyse(name, effect=None):
    rec = os.path.join(work, name + ".csv")
    args = [exe, "simulate", *SCENARIO, "--out", rec, "--config", config]
    if effect:
        args += ["--effect", effect]
    subprocess.run(args, check=True, capture_output=True)
    out = os.path.join(work, name)
    r = subprocess.run([exe, "analyze", "--recording", rec, "--out", out, "--config", config,
                        "--no-twin-check"], check=True, capture_output=True, text=True)
    return json.load(open(os.path.join(out, "analysis.json"))), r.stdout


failures = 0
control, text = analyse("control")
if control["effects"]:
    sys.exit(f"the control named {[e['id'] for e in control['effects']]}")
limits = {r["id"]: r for r in control.get("resolvable", [])}
conclusion = text.splitlines()[3]
print("control:", conclusion)
# docs/analysis.md shows this very line (the same scenario and seed): it must not go stale.
docs = open(os.path.join(os.path.dirname(os.path.abspath(config)), "docs", "analysis.md")).read()
shown = docs.split('## What "nothing missing" covers')[1].split("```")[1]
if " ".join(shown.split()) != " ".join(conclusion.split()):
    print(f"FAIL: docs/analysis.md shows\n{shown.strip()}\nbut the control prints\n{conclusion}")
    failures += 1
for plant, fid, par, model in EFFECTS:
    if fid not in limits:
        print(f"FAIL: no smallest change listed for {fid}")
        failures += 1
        continue
    limit = limits[fid]["smallest_change"]
    for factor, named_expected in ((0.4, False), (2.5, True)):
        value = factor * limit
        J, _ = analyse(f"{plant}_{factor}", f"{plant}={value:.6g}")
        found = [e for e in J["effects"] if e["id"] == fid]
        line = f"{plant} = {value:.4g} ({factor} x the listed {limit:.3g} {limits[fid]['unit']})"
        if bool(found) != named_expected:
            print(f"FAIL: {line}: named {bool(found)}, expected {named_expected}")
            failures += 1
            continue
        if found:
            v, se = found[0]["parameters"][par], found[0]["standard_errors"].get(par, 0.0)
            truth = model + value
            ok = abs(v - truth) <= 2 * se + 0.1 * abs(value)
            print(f"{line}: named, {par} {v:.4g} ± {se:.2g} (true {truth:.4g})"
                  + ("" if ok else "  FAIL: not the size added"))
            failures += not ok
        else:
            print(f"{line}: not named, as listed")
sys.exit(1 if failures else 0)
