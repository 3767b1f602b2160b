#!/usr/bin/python3
"""`maglead analyze` on a rotary axis writes rotary units (docs/analysis.md, a rotary axis).

usage: rotary_cli.py MAGLEAD ROTARY_DRIVE WORK_DIR

The generated servo drive (rotary_drive.hpp: J, b, c known; angle in rad, torque in N·m) is
analysed with a rotary baseline lacking viscous friction: analysis.json names it as
viscous_n_m_s_per_rad, the headline prints N·m·s/rad, and model_corrected.toml holds the rotary's
names (inertia_kg_m2, viscous_n_m_s_per_rad, coulomb_n_m) and is read back by the analysis. The
same file without its '# axis: rotary' line is refused with what to add, and `inspect` refuses
what analyze refuses (t_ms, angle_deg, drive_torque_mn_m, no axis line) with the same message.
The where lines print ranges whose ends differ (3019 … 3025 rad, not 3.02e+03 … 3.03e+03), and
--calibration-accuracy and --calibration, the actuator's, are refused with what to drop.
analysis.json keeps to
its schema (docs/schema/analysis.schema.json, system "rotary"). `report`, `twin-check` and
`estimate`, the actuator's, refuse it with the analyze command to run instead. rotary_drive
prints its usage for -h/--help and for bad use (exit 2) rather than writing a file of that name.
The page (index.html) and the terminal speak of a shaft: torque in N·m, the law τ = -C ω, the
method in torque and angle, the title "Model versus recording" (no twin).
"""
import json, os, subprocess, sys

exe, drive, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
failures = []

# rotary_drive itself: -h/--help prints its usage; a missing or odd argument is bad use (exit 2),
# never a recording written under the option's name.
for args, code in ((["--help"], 0), (["-h"], 0), ([], 2), (["-x"], 2), (["a.csv", "b", "c"], 2),
                   (["a.csv", "fast"], 2)):
    r = subprocess.run([drive] + args, cwd=work, capture_output=True, text=True)
    if r.returncode != code or "usage: rotary_drive OUT.csv" not in r.stdout + r.stderr:
        failures.append(f"rotary_drive {args}: exit {r.returncode}, {r.stdout + r.stderr!r}")
    for name in args:
        if os.path.exists(os.path.join(work, name)):
            failures.append(f"rotary_drive {args} wrote '{name}'")
            os.remove(os.path.join(work, name))
VISCOUS = 2e-3  # the drive's b, N·m·s/rad (rotary_drive.hpp's default)
rec = os.path.join(work, "servo.csv")
subprocess.run([drive, rec, repr(VISCOUS)], check=True)
# The shipped baseline docs/analysis.md's example runs with.
model = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config",
                     "rotary_baseline.toml")


def analyse(recording, out, baseline):
    return subprocess.run([exe, "analyze", "--recording", recording, "--model", baseline,
                           "--out", out], capture_output=True, text=True)


out = os.path.join(work, "out")
r = analyse(rec, out, model)
if r.returncode != 0:
    sys.exit("analyze failed: " + r.stderr)
j = json.load(open(os.path.join(out, "analysis.json")))
ids = [e["id"] for e in j["effects"]]
if ids != ["viscous_friction"]:
    failures.append(f"named {ids}, expected viscous_friction alone")
else:
    p, se = j["effects"][0]["parameters"], j["effects"][0]["standard_errors"]
    value, error = p.get("viscous_n_m_s_per_rad"), se.get("viscous_n_m_s_per_rad")
    if value is None or abs(value - VISCOUS) > 2 * error + 0.04 * VISCOUS:
        failures.append(f"viscous_n_m_s_per_rad {value} ± {error}, true {VISCOUS}")
    print(f"found viscous_n_m_s_per_rad {value} ± {error} (true {VISCOUS})")
import jsonschema  # tools/setup.sh installs it (validate_schemas needs it too)
schema = json.load(open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..",
                                     "docs", "schema", "analysis.schema.json")))
try:
    jsonschema.Draft202012Validator(schema).validate(j)
except jsonschema.ValidationError as e:
    failures.append(f"analysis.json against its schema: {e.message}")
# docs/analysis.md quotes this drive's headline (seed 1, b as here): it is what analyze prints.
doc = open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs",
                        "analysis.md"), encoding="utf-8").read()
quoted = ("`viscous_n_m_s_per_rad 0.001994 ± 0.000004 N·m·s/rad (model 0 N·m·s/rad), or "
          "asymmetric_friction (the data cannot tell them apart)`")
if " ".join(quoted.split()) not in " ".join(doc.split()):
    failures.append("docs/analysis.md no longer quotes the rotary headline " + quoted)
elif quoted.strip("`") not in j["headline"]:
    failures.append("docs/analysis.md quotes " + quoted + ", analyze prints " + j["headline"])
if "N·m·s/rad" not in j["headline"]:
    failures.append("headline without N·m·s/rad: " + j["headline"])
if "inertia_kg_m2" not in j["final"].get("fitted_parameters", {}):
    failures.append(f"final fitted parameters {j['final'].get('fitted_parameters')}")
# The page and the terminal speak of a shaft: torque in N·m, the law in τ and ω, no twin.
page = open(os.path.join(out, "index.html"), encoding="utf-8").read()
for text in ("Model versus recording: analysis", "τ = -C ω", "changes the torque by",
             "N·m RMS", "Method: torque (inverse model: measured torque", "angle at 100 Hz"):
    if text not in page:
        failures.append(f"index.html lacks '{text}'")
for text in ("Twin versus", "changes the force", "force it would explain", " N RMS",
             "force error", "the nut", "F = -C v"):
    if text in page:
        failures.append(f"index.html on a rotary axis says '{text}'")
for text in ("missing force", "F = -C v", " N RMS"):
    if text in r.stdout:
        failures.append(f"analyze prints '{text}' on a rotary axis: {r.stdout}")
corrected = open(os.path.join(out, "model_corrected.toml")).read()
for key in ("system = \"rotary\"", "inertia_kg_m2 =", "viscous_n_m_s_per_rad =", "coulomb_n_m ="):
    if key not in corrected:
        failures.append(f"model_corrected.toml lacks '{key}'")
again = analyse(rec, os.path.join(work, "again"), os.path.join(out, "model_corrected.toml"))
if again.returncode != 0:
    failures.append("the corrected model is not read back: " + again.stderr)
elif json.load(open(os.path.join(work, "again", "analysis.json")))["effects"]:
    failures.append("the corrected model still misses something: " + again.stdout)

# Without the header line: refused, saying what to add.
bare = os.path.join(work, "servo_no_header.csv")
with open(rec) as src, open(bare, "w") as dst:
    dst.writelines(line for line in src if not line.startswith("# axis:"))
r = analyse(bare, os.path.join(work, "bare"), model)
if r.returncode == 0 or "add the header line '# axis: rotary'" not in r.stderr:
    failures.append(f"no header: exit {r.returncode}, {r.stderr.strip()}")

# inspect checks an axis's recording as analyze does: what analyze refuses, inspect refuses with
# the same message (exit 2), and the servo's own recording passes (exit 0).
def variant(name, edit_line):
    path = os.path.join(work, name)
    with open(rec) as src, open(path, "w") as dst:
        for line in src:
            line = edit_line(line)
            if line is not None:
                dst.write(line)
    return path


def error(run):
    return [line for line in run.stderr.splitlines() if line.startswith("maglead: error:")]


HEADER = "t_s,angle_rad,drive_torque_n_m,ref_angle_rad\n"
for name, edit_line, fix in (
        ("servo_t_ms.csv", lambda l: l.replace("t_s,", "t_ms,", 1) if l == HEADER else l,
         "'t_ms' looks like t_s in another unit: convert it to seconds and name it 't_s'"),
        ("servo_deg.csv", lambda l: l.replace("angle_rad,d", "angle_deg,d") if l == HEADER else l,
         "'angle_deg' looks like angle_rad in another unit: convert it to radians"),
        ("servo_mnm.csv", lambda l: l.replace("_n_m,", "_mn_m,") if l == HEADER else l,
         "'drive_torque_mn_m' looks like drive_torque_n_m in another unit: convert it to newton "
         "metres"),
        ("servo_no_axis.csv", lambda l: None if l.startswith("# axis:") else l,
         "add the header line '# axis: rotary'")):
    path = variant(name, edit_line)
    i = subprocess.run([exe, "inspect", path], capture_output=True, text=True)
    a = analyse(path, os.path.join(work, "refused"), model)
    if i.returncode != 2 or fix not in i.stderr or a.returncode != 2 or fix not in a.stderr:
        failures.append(f"{name}: inspect exit {i.returncode} {i.stderr.strip()!r}, analyze exit "
                        f"{a.returncode} {a.stderr.strip()!r}")
    elif name != "servo_no_axis.csv" and error(i) != error(a):  # one check, one message
        failures.append(f"{name}: inspect says {error(i)!r}, analyze {error(a)!r}")
    elif name == "servo_no_axis.csv" and "the columns are a rotary axis's" not in i.stderr:
        # Without a model inspect still says what the columns are, not what a linear axis needs.
        failures.append(f"{name}: inspect opens with {i.stderr.strip()!r}")
i = subprocess.run([exe, "inspect", rec], capture_output=True, text=True)
if i.returncode != 0:
    failures.append(f"inspect on the servo's recording: exit {i.returncode}, {i.stderr.strip()}")

# The where lines' ranges print the digits that tell their ends apart: thousands of radians are
# "3019 … 3025 rad", never "3.02e+03 … 3.03e+03 rad".
import re
for w in j["where"]:
    for lo, hi in re.findall(r"(-?[0-9.e+]+) … (-?[0-9.e+]+)", w):
        if lo == hi or "e+" in lo + hi:
            failures.append(f"a range of '{w}' prints {lo} … {hi}")
# --calibration-accuracy and --calibration are the actuator's: refused on an axis with what to drop.
for option, value in (("--calibration-accuracy", "0.5"), ("--calibration", model)):
    r = subprocess.run([exe, "analyze", "--recording", rec, "--model", model, "--out",
                        os.path.join(work, "accuracy"), option, value],
                       capture_output=True, text=True)
    if r.returncode != 2 or "applies to the actuator only" not in r.stderr or \
            f"drop {option}" not in r.stderr:
        failures.append(f"{option} on a rotary axis: exit {r.returncode}, {r.stderr}")

# The actuator's commands refuse an axis's recording with what to run instead (exit 2).
for command in (["report", "--out", os.path.join(work, "report")], ["twin-check"], ["estimate"]):
    r = subprocess.run([exe, command[0], "--recording", rec] + command[1:], capture_output=True,
                       text=True)
    if r.returncode != 2 or "maglead analyze --recording " + rec not in r.stderr:
        failures.append(f"{command[0]} on a rotary axis: exit {r.returncode}, {r.stderr.strip()}")

for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
