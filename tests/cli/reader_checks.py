"""What the readers refuse, every command alike (a test engineer's walkthrough of the recording
reader): a repeated time stamp is refused with its row; a column in another unit is named with
what to do, in every command that reads it.
Usage: reader_checks.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import os
import shutil
import subprocess
import sys

MAGLEAD, CONFIG, WORK = (os.path.abspath(a) for a in sys.argv[1:4])
ROOT = os.path.dirname(CONFIG)
EMPS = os.path.join(ROOT, "data", "emps", "emps_estimation.csv")
EMPS_MODEL = os.path.join(CONFIG, "emps_baseline.toml")
ENV = {k: v for k, v in os.environ.items() if k != "MAGLEAD_CONFIG"}
failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what)
    if not ok:
        failures.append(what)


def run(*args):
    p = subprocess.run([MAGLEAD, *args], capture_output=True, text=True, cwd=WORK, env=ENV,
                       timeout=300)
    return p.returncode, p.stdout, p.stderr


def split(path):
    """(metadata lines, header, rows) of a recording."""
    lines = open(path).read().splitlines()
    header = next(i for i, l in enumerate(lines) if not l.startswith("#"))
    return lines[:header], lines[header], lines[header + 1:]


def write(name, meta, header, rows):
    path = os.path.join(WORK, name)
    with open(path, "w") as f:
        f.write("\n".join(meta + [header] + rows) + "\n")
    return path


def repeated_rows():
    meta, header, rows = split(EMPS)
    rows = rows[:3000]
    dup = write("dup.csv", meta, header, rows[:1000] + [rows[999]] + rows[1000:])
    for cmd in (["inspect", dup, "--config", CONFIG],
                ["analyze", dup, "--model", EMPS_MODEL, "--out", "dup_out"]):
        rc, _, err = run(*cmd)
        check(rc == 2 and "1 row repeats the time of the row before, at data row 1001" in err
              and "delete them" in err, f"{cmd[0]} refuses a repeated row: {err.strip()!r}")
    stamp = list(rows)
    stamp[1000] = rows[999].split(",")[0] + "," + rows[1000].split(",", 1)[1]
    twice = write("stamp_twice.csv", meta, header, stamp)
    rc, _, err = run("analyze", twice, "--model", EMPS_MODEL, "--out", "twice_out")
    check(rc == 2 and "at data row 1001" in err and "fix t_s" in err and "filled" not in err,
          f"analyze refuses a time stamp written twice: {err.strip()!r}")


def actuator_files():
    rec = os.path.join(WORK, "push.csv")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--seed", "1", "--duration", "20s",
                     "--out", rec, "--config", CONFIG)
    if rc != 0:
        sys.exit("simulate failed: " + err)
    meta, header, rows = split(rec)
    names = header.split(",")
    # Degrees for radians: the angle's name says it, and every reader says to convert it.
    keep = [i for i, n in enumerate(names) if n != "motor_angle_rad"]
    deg = write("deg.csv", meta, ",".join(names[i] for i in keep).replace("screw_angle_rad", "screw_angle_deg"),
                [",".join(r.split(",")[i] for i in keep) for r in rows])
    for cmd in (["twin-check"], ["estimate"], ["analyze", "--out", "deg_out"]):
        rc, _, err = run(*cmd, deg, "--config", CONFIG)
        check(rc == 2 and "'screw_angle_deg' looks like screw_angle_rad in another unit: convert it "
              "to radians" in err, f"{cmd[0]} on screw_angle_deg: {err.strip()!r}")


def missing_value_words():
    meta, header, rows = split(EMPS)
    na = write("na.csv", meta, header, rows[:10] + [rows[10].split(",")[0] + ",NA," + ",".join(rows[10].split(",")[2:])] + rows[11:3000])
    rc, _, err = run("inspect", na, "--config", CONFIG)
    check(rc == 2 and "'NA' is not a number: a missing value is an empty field" in err,
          f"NA says how to write a missing value: {err.strip()!r}")


def main():
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)
    repeated_rows()
    missing_value_words()
    actuator_files()
    if failures:
        sys.exit(f"{len(failures)} failed")


if __name__ == "__main__":
    main()
