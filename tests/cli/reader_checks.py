"""What the readers refuse, every command alike (a test engineer's walkthrough of the recording
reader): a repeated time stamp is refused with its row; `inspect` exits 2 for what `analyze`
refuses, with the same reason; a column in another unit, in upper case or in quotes is named
with what to do; `estimate` and `twin-check` judge a load cell as `analyze` does (the other sign
is not scored); `twin-check --trace` writes a recording the readers take; report, estimate and
twin-check wrap their lines at a terminal's width.
Usage: reader_checks.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import fcntl
import os
import pty
import shutil
import struct
import subprocess
import sys
import termios

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


def axis_files():
    """Broken copies of the EMPS axis recording (t_s, pos_m, ref_pos_m, drive_force_n)."""
    meta, header, rows = split(EMPS)
    rows = rows[:3000]
    names = header.split(",")
    pos, drive = names.index("pos_m"), names.index("drive_force_n")

    def cells(f):
        return [",".join(f(r.split(","))) for r in rows]

    def set_at(row, i, v):
        row = list(row)
        row[i] = v
        return row
    in_ms = [m for m in meta if not m.startswith("# sample_rate_hz")]
    return {
        "two_rows": (meta, header, rows[:2], "too short to analyse (2 rows"),
        "empty_cell": (meta, header, rows[:1500] + [",".join(set_at(rows[1500].split(","), pos, ""))]
                       + rows[1501:], "column 'pos_m' is empty in data row 1501"),
        "pos_mm": (meta, header.replace("pos_m,", "pos_mm,", 1),
                   cells(lambda c: set_at(c, pos, repr(float(c[pos]) * 1e3))),
                   "'pos_mm' looks like pos_m in another unit: convert it to metres"),
        "no_drive": (meta, ",".join(n for n in names if n != "drive_force_n"),
                     cells(lambda c: [v for i, v in enumerate(c) if i != drive]),
                     "a linear axis needs the columns t_s, pos_m, drive_force_n"),
        "ms_as_s": (in_ms, header, cells(lambda c: set_at(c, 0, repr(round(float(c[0]) * 1e3, 6)))),
                    "if t_s is in milliseconds, divide it by 1000"),
        "upper": (meta, header.upper(), rows, "column names are lower case: rename 'T_S' to 't_s'"),
    }


def inspect_refuses_what_analyze_refuses():
    for name, (meta, header, rows, said) in axis_files().items():
        path = write(name + ".csv", meta, header, rows)
        rc, _, err = run("inspect", path, "--config", CONFIG)
        check(rc == 2 and said in err, f"inspect {name}: exit {rc}, {err.strip()!r}")
        rc, _, aerr = run("analyze", path, "--model", EMPS_MODEL, "--out", name + "_out")
        check(rc == 2 and said in aerr, f"analyze {name}: exit {rc}, {aerr.strip()!r}")
    # Quoted names (R's write.csv) are the names: read, not refused.
    meta, header, rows = split(EMPS)
    quoted = write("quoted.csv", meta, ",".join(f'"{n}"' for n in header.split(",")), rows[:3000])
    rc, out, err = run("inspect", quoted, "--config", CONFIG)
    check(rc == 0 and "  pos_m " in out and '"' not in out, f"inspect quoted names: {out[:200]!r} {err!r}")
    # What inspect did not check is said.
    rc, out, err = run("inspect", EMPS, "--config", CONFIG)
    check(rc == 0 and "not checked: the model file" in out, f"inspect EMPS: {out[-200:]!r} {err!r}")


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
    for cmd in (["inspect"], ["twin-check"], ["estimate"], ["analyze", "--out", "deg_out"]):
        rc, _, err = run(*cmd, deg, "--config", CONFIG)
        check(rc == 2 and "'screw_angle_deg' looks like screw_angle_rad in another unit: convert it "
              "to radians" in err, f"{cmd[0]} on screw_angle_deg: {err.strip()!r}")
    # The load cell of the other sign: analyze refuses it, estimate scores nothing against it,
    # twin-check sets it aside, with the analysis's own reason.
    load = names.index("load_force_n")
    sign = write("sign.csv", meta, header,
                 [",".join(v if i != load or v == "" else repr(-float(v))
                           for i, v in enumerate(r.split(","))) for r in rows])
    reason = "newtons of the other sign (load_force_n negated)"
    rc, _, err = run("analyze", sign, "--out", "sign_out", "--config", CONFIG)
    check(rc == 2 and reason in err, f"analyze on a negated load cell: {err.strip()!r}")
    rc, out, err = run("estimate", sign, "--plot", "sign.png", "--config", CONFIG)
    check(rc == 2 and reason in err and "mean absolute error" not in out,
          f"estimate on a negated load cell: exit {rc}, {out.strip()[:200]!r} {err.strip()!r}")
    rc, out, err = run("twin-check", sign, "--config", CONFIG, "--trace", "trace.csv")
    check(rc == 0 and "not judged" in out and reason in out and "MAE" not in out,
          f"twin-check on a negated load cell: exit {rc}, {out.strip()!r} {err.strip()!r}")
    # One empty load-cell cell does not turn the judgement off (it had, and both scored).
    blank_rows = list(rows)
    cells = blank_rows[len(rows) // 2].split(",")
    cells[load] = ""
    blank_rows[len(rows) // 2] = ",".join(cells)
    blank = write("sign_blank.csv", meta, header,
                  [",".join(v if i != load or v == "" else repr(-float(v))
                            for i, v in enumerate(r.split(","))) for r in blank_rows])
    rc, out, err = run("estimate", blank, "--plot", "blank.png", "--config", CONFIG)
    check(rc == 2 and reason in err, f"estimate on a negated load cell with a blank cell: exit {rc}, {err.strip()!r}")
    rc, out, err = run("twin-check", blank, "--config", CONFIG)
    check(rc == 0 and reason in out and "MAE" not in out,
          f"twin-check on a negated load cell with a blank cell: {out.strip()!r}")
    rc, out, err = run("twin-check", rec, "--config", CONFIG)
    check(rc == 0 and "force MAE against load cell" in out, f"twin-check scores a right load cell: {out!r}")
    rc, out, err = run("inspect", sign, "--config", CONFIG)
    check(rc == 0 and reason in out and "estimate refuse it" in out, f"inspect on a negated load cell: {out[-300:]!r}")
    # The trace is a recording: its values not formed yet are empty fields, which the readers take.
    trace = open(os.path.join(WORK, "trace.csv")).read()
    check("nan" not in trace and trace.startswith("# format: mls-recording/1"),
          f"twin-check --trace writes no nan: {trace[:300]!r}")
    rc, out, err = run("inspect", os.path.join(WORK, "trace.csv"), "--config", CONFIG)
    check("is not a number" not in err, f"the trace reads back: {err.strip()!r}")


def at_80_columns(*args):
    """Exit code and stdout of a command whose stdout is a terminal 80 columns wide."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    p = subprocess.Popen([MAGLEAD, *args], stdout=slave, stderr=subprocess.DEVNULL, cwd=WORK, env=ENV)
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the other end closed
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    return p.wait(timeout=300), out.decode().replace("\r\n", "\n")


def wrapped_at_80_columns():
    """report, estimate and twin-check wrap their lines on a terminal as analyze does; report
    says every file it wrote and its --help none it does not write."""
    for args in (["report", "push.csv", "--out", "push_report"], ["estimate", "push.csv", "--plot", "push.png"],
                 ["twin-check", "push.csv"], ["twin-check", "sign.csv"]):
        rc, out = at_80_columns(*args, "--config", CONFIG)
        long = [l for l in out.splitlines() if len(l) > 80]
        check(rc == 0 and out and not long, f"{args[0]} at 80 columns: exit {rc}, {long!r}")
        if args[0] == "report":
            check("report.json" in out, f"report says it wrote report.json: {out[-200:]!r}")
    rc, out, _ = run("report", "--help")
    check(rc == 0 and "PNG" not in out, "report --help promises no PNG it does not write")


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
    inspect_refuses_what_analyze_refuses()
    missing_value_words()
    actuator_files()
    wrapped_at_80_columns()
    if failures:
        sys.exit(f"{len(failures)} failed")


if __name__ == "__main__":
    main()
