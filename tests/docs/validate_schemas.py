#!/usr/bin/python3
"""analysis.json and report.json against their JSON Schemas (docs/schema/, issue 42).

usage: validate_schemas.py MAGLEAD SOURCE_DIR WORK_DIR

1. The schemas are valid draft 2020-12 schemas and every property has a description.
2. `maglead simulate` writes short recordings of generated cases (none of them is judged here:
   the analysis's accuracy is test_analysis's and test_actuator_suite's): one with no effect
   (no finding), effects the analysis names (with alternatives, a note from the releases, an end
   zone), a friction drift it leaves unexplained, an overload with step-outs, a coupling drift
   the twin's drift flag raises. `maglead analyze` and `maglead report` run on each; so does
   `analyze` on the real EMPS recording (an axis). Every analysis.json and report.json must
   validate against its schema.
3. The analysis not possible: the no-effect recording with its load_force_n column deleted.
   `analyze` fails and writes no analysis.json; `report` still writes report.json, with the
   analysis "not possible" and force_error null. `report --no-analysis`: "skipped".
4. The schemas are tight: an analysis.json and a report.json with a key renamed, a key added, a
   required key dropped or a value of the wrong type fail.
Prints which optional keys the outputs held (the coverage), without judging it.
"""
import concurrent.futures
import copy
import json
import os
import shutil
import subprocess
import sys
import time

try:
    import jsonschema
except ImportError:
    sys.exit("FAIL python3-jsonschema is not installed (tools/setup.sh installs it)")

MAGLEAD, SOURCE, WORK = sys.argv[1], os.path.abspath(sys.argv[2]), os.path.abspath(sys.argv[3])
CONFIG = os.path.join(SOURCE, "config")
SCHEMAS = os.path.join(SOURCE, "docs", "schema")
EMPS = (os.path.join(SOURCE, "data", "emps", "emps_estimation.csv"), os.path.join(CONFIG, "emps_baseline.toml"))
# (name, scenario, seconds, seed, effects): what each adds to the outputs is in the comment.
CASES = [
    ("clean", "hand-push", 30, 3, []),                           # no finding
    ("coulomb", "position-moves", 30, 3, ["coulomb_friction=2"]),  # a finding with alternatives
    ("stribeck", "position-moves", 30, 3, ["stribeck_friction=4.5"]),  # read from releases: note
    ("end_zone", "position-moves", 30, 3, ["end_effect=0.01"]),  # acting share below 100 %
    ("friction_drift", "mixed", 30, 3, ["friction_drift=3"]),    # a force left unexplained
    ("overload", "hand-push", 30, 3, ["offset=30"]),             # step-outs: events, report rows
    ("gain_drift", "force-steps", 30, 4, ["gain_drift=-0.2"]),   # report: a drift window
    ("pulses", "position-moves", 40, 2, ["external_disturbance=8"]),  # external_disturbance events
]
FAILURES = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        FAILURES.append(what)


def run(*args):
    r = subprocess.run([MAGLEAD, "-q", *args], capture_output=True, text=True, timeout=180)
    return r.returncode, r.stdout + r.stderr


def load(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def undescribed(schema, where="#"):
    """Paths of the properties in a schema that have no description."""
    out = []
    if isinstance(schema, dict):
        for name, sub in schema.get("properties", {}).items():
            if not isinstance(sub, dict) or "description" not in sub:
                out.append(f"{where}/properties/{name}")
        for key, sub in schema.items():
            out += undescribed(sub, f"{where}/{key}")
    elif isinstance(schema, list):
        for k, sub in enumerate(schema):
            out += undescribed(sub, f"{where}/{k}")
    return out


def key_paths(x, path="", acc=None):
    """Every key path in a document, array items as [], parameter names as *."""
    acc = set() if acc is None else acc
    if isinstance(x, dict):
        for k, v in x.items():
            k = "*" if path.endswith(("parameters", "standard_errors")) else k
            acc.add(f"{path}.{k}")
            key_paths(v, f"{path}.{k}", acc)
    elif isinstance(x, list):
        for v in x:
            key_paths(v, f"{path}[]", acc)
    return acc


def simulate(name, scenario, seconds, seed, effects):
    rec = os.path.join(WORK, name + ".csv")
    args = ["simulate", "--scenario", scenario, "--duration", f"{seconds}s", "--seed", str(seed),
            "--out", rec, "--config", CONFIG]
    for e in effects:
        args += ["--effect", e]
    rc, out = run(*args)
    return rec if rc == 0 else f"simulate {name}: {out.strip()[-300:]}"


def analyze_and_report(name, rec, model=None, analyze=True, report=True, report_args=()):
    """Runs analyze and report on rec; returns (name, analyze's exit code and output, report's)."""
    extra = ["--model", model] if model else []
    rc_a, out_a, rc_r, out_r = None, "", None, ""
    if analyze:
        rc_a, out_a = run("analyze", "--recording", rec, "--out", os.path.join(WORK, name, "analyze"),
                          "--config", CONFIG, *extra)
    if report:
        rc_r, out_r = run("report", "--recording", rec, "--out", os.path.join(WORK, name, "report"),
                          "--config", CONFIG, *report_args)
    return name, rc_a, out_a, rc_r, out_r


def without_load_cell(src, dst):
    """The recording with its load_force_n column deleted (header lines kept)."""
    with open(src, encoding="utf-8") as f:
        lines = f.read().splitlines()
    col, out = None, []
    for line in lines:
        if line.startswith("#"):
            out.append(line)
            continue
        fields = line.split(",")
        if col is None:
            col = fields.index("load_force_n")
        del fields[col]
        out.append(",".join(fields))
    with open(dst, "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")


def mutations(doc, kind):
    """(what, changed document) pairs a tight schema must reject."""
    out = []
    d = copy.deepcopy(doc)
    d["unexpected_key"] = 1
    out.append(("a key added at the top", d))
    if kind == "analysis":
        d = copy.deepcopy(doc)
        d["baseline"]["rms_n"] = d["baseline"].pop("rms")
        out.append(("baseline.rms renamed rms_n", d))
        d = copy.deepcopy(doc)
        del d["conclusion"]
        out.append(("conclusion dropped", d))
        d = copy.deepcopy(doc)
        d["samples"] = str(d["samples"])
        out.append(("samples as a string", d))
        d = copy.deepcopy(doc)
        d["method"]["decimation"] = 1.5
        out.append(("method.decimation not a whole number", d))
        if doc["effects"]:
            d = copy.deepcopy(doc)
            d["effects"][0]["evidence"]["gain_pct"] = d["effects"][0]["evidence"].pop("heldout_gain_pct")
            out.append(("effects[0].evidence.heldout_gain_pct renamed", d))
            d = copy.deepcopy(doc)
            d["effects"][0]["parameters"]["x"] = "1"
            out.append(("a parameter as a string", d))
    else:
        d = copy.deepcopy(doc)
        d["analysis"]["status"] = "failed"
        out.append(("analysis.status not one of its values", d))
        d = copy.deepcopy(doc)
        del d["force_error"]
        out.append(("force_error dropped", d))
        d = copy.deepcopy(doc)
        d["twin_residual_pos_rms_um"] = d.pop("twin_residual_pos_rms_m")
        out.append(("twin_residual_pos_rms_m renamed", d))
        if doc["force_error"]:
            d = copy.deepcopy(doc)
            d["force_error"]["static"]["mean_n"] = d["force_error"]["static"].pop("mean_abs_n")
            out.append(("force_error.static.mean_abs_n renamed", d))
        if doc["step_outs"]:
            d = copy.deepcopy(doc)
            d["step_outs"][0]["leads"] = 0.5
            out.append(("step_outs[0].leads not a whole number", d))
    return out


def main():
    start = time.monotonic()
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)

    # 1. The schemas themselves.
    validators = {}
    for kind in ("analysis", "report"):
        path = os.path.join(SCHEMAS, f"{kind}.schema.json")
        schema = load(path)
        try:
            jsonschema.Draft202012Validator.check_schema(schema)
            check(True, f"{kind}.schema.json is a valid draft 2020-12 schema")
        except jsonschema.SchemaError as e:
            check(False, f"{kind}.schema.json is a valid draft 2020-12 schema: {e.message}")
            continue
        missing = undescribed(schema)
        check(not missing, f"{kind}.schema.json: every property has a description {missing[:5]}")
        validators[kind] = jsonschema.Draft202012Validator(schema)
    if len(validators) < 2:
        return

    # 2. Generated recordings, the EMPS recording; 3. the analysis not possible, skipped.
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        recs = list(pool.map(lambda c: simulate(*c), CASES))
        for (name, *_), rec in zip(CASES, recs):
            check(os.path.exists(rec), f"simulate {name}" if os.path.exists(rec) else rec)
        clean = dict(zip([c[0] for c in CASES], recs))["clean"]
        no_load_cell = os.path.join(WORK, "no_load_cell.csv")
        if os.path.exists(clean):
            without_load_cell(clean, no_load_cell)
        jobs = [pool.submit(analyze_and_report, name, rec) for (name, *_), rec in zip(CASES, recs)
                if os.path.exists(rec)]
        jobs.append(pool.submit(analyze_and_report, "emps", EMPS[0], model=EMPS[1], report=False))
        if os.path.exists(no_load_cell):
            jobs.append(pool.submit(analyze_and_report, "no_load_cell", no_load_cell))
        if os.path.exists(clean):
            jobs.append(pool.submit(analyze_and_report, "no_analysis", clean, analyze=False,
                                    report_args=["--no-analysis"]))
        results = [j.result() for j in jobs]

    docs = {"analysis": {}, "report": {}}
    for name, rc_a, out_a, rc_r, out_r in results:
        a_json = os.path.join(WORK, name, "analyze", "analysis.json")
        r_json = os.path.join(WORK, name, "report", "report.json")
        if rc_a is None:
            pass
        elif name == "no_load_cell":
            check(rc_a != 0 and not os.path.exists(a_json),
                  f"{name}: analyze fails and writes no analysis.json (rc {rc_a}: {out_a.strip()[-150:]})")
        else:
            ok = rc_a == 0 and os.path.exists(a_json)
            check(ok, f"{name}: analyze writes analysis.json" + ("" if ok else f" (rc {rc_a}): {out_a.strip()[-300:]}"))
        if rc_r is not None:
            ok = rc_r == 0 and os.path.exists(r_json)
            check(ok, f"{name}: report writes report.json" + ("" if ok else f" (rc {rc_r}): {out_r.strip()[-300:]}"))
        # The pages embed their figures: nothing beside them but what the docs list.
        for folder, listed in (("analyze", {"analysis.json", "index.html", "model_corrected.toml"}),
                               ("report", {"index.html", "report.json"})):
            where = os.path.join(WORK, name, folder)
            extra = set(os.listdir(where)) - listed if os.path.isdir(where) else set()
            check(not extra, f"{name}: {folder} writes only {sorted(listed)}, not {sorted(extra)}")
        for kind, path in (("analysis", a_json), ("report", r_json)):
            if not os.path.exists(path):
                continue
            doc = load(path)
            docs[kind][name] = doc
            errors = sorted(validators[kind].iter_errors(doc), key=lambda e: list(e.absolute_path))
            check(not errors, f"{name}: {kind}.json validates" + "".join(
                f"\n       at /{'/'.join(map(str, e.absolute_path))}: {e.message[:300]}" for e in errors[:5]))

    # The cases the brief names are there: a finding, none, not possible, skipped.
    a = docs["analysis"]
    r = docs["report"]
    check(any(d["effects"] for d in a.values()), "some analysis.json holds a finding")
    check("clean" in a and a["clean"]["effects"] == [], "clean: analysis.json holds no finding")
    nl = r.get("no_load_cell", {})
    check(nl.get("analysis", {}).get("status") == "not possible" and nl.get("force_error", 0) is None,
          f"no load cell: report.json says the analysis is not possible, force_error null {nl.get('analysis')}")
    check(r.get("no_analysis", {}).get("analysis", {}).get("status") == "skipped",
          "report --no-analysis: the analysis is skipped")
    check("emps" in a and a["emps"]["system"] == "axis", "EMPS: an axis's analysis.json")

    # 4. Tight enough that a drift fails.
    for kind, names in (("analysis", ["coulomb", "overload"]), ("report", ["coulomb", "overload", "no_load_cell"])):
        for name in filter(docs[kind].get, names):
            for what, changed in mutations(docs[kind][name], kind):
                check(not validators[kind].is_valid(changed), f"{kind}.schema.json rejects {name}'s with {what}")

    for kind in ("analysis", "report"):
        seen = sorted(set().union(*[key_paths(d) for d in docs[kind].values()]))
        print(f"coverage: {len(docs[kind])} {kind}.json files held {len(seen)} key paths:", " ".join(seen))
    print(f"{time.monotonic() - start:.1f} s")


if __name__ == "__main__":
    main()
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed:", *FAILURES, sep="\n  ")
        sys.exit(1)
    print("all checks passed")
