"""What a new user expects of the tools (issue 41), each item tried as that user would:
the configuration found is the one the user edits (a checkout's config/, no build-tree copy);
`set` and `enable` say what happens when they end and do it (release without a fault); usage
errors exit 2 with `maglead: error:` and what to type; poll --raw signed, every code with its
name, set takes poll's names; the analysis headline names the finding or says what was not
judged; and the smaller items (negative totals, separators, first bad row, a model file's bad
key at its line, bind_address with its file, numbers as written, image formats, --help
defaults, disable in fault, JSON codes as integers).
Usage: user_expectations.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "controller"))
from modbus_common import Server, check, finish, watchdog  # noqa: E402

MAGLEAD, CONFIG, WORK = (os.path.abspath(a) for a in sys.argv[1:4])
ENV = {k: v for k, v in os.environ.items() if k != "MAGLEAD_CONFIG"}


def run(*args, binary=MAGLEAD, cwd=None, timeout=120):
    p = subprocess.run([binary, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd or WORK,
                       env=ENV)
    return p.returncode, p.stdout, p.stderr


def usage_errors():
    cases = [(["simulate"], "--scenario is required", "maglead simulate --help"),
             (["serve", "--port", "99999"], "--port", "maglead serve --help"),
             (["simulate", "--scenario", "hand-push", "--duration", "0s", "--out", "x.csv"],
              "--duration: '0s' is not a positive duration (e.g. --duration 30s", "simulate"),
             (["analyze", "--recording", "x.csv", "--out", "o", "--model", "nosuch.toml"], "nosuch.toml", ""),
             # What to type, not the positional's internal name ("what is required").
             (["set"], "say what to set: maglead set force|position|idle|reference-move|SETTING [VALUE]",
              "maglead set --help"),
             # The project's range wording (units, what to type), not CLI11's "Value 100 not in range".
             (["watch", "--rate", "100"],
              "--rate: 100 Hz is outside 0.5 .. 50 Hz (refreshes per second): type e.g. --rate 10",
              "maglead watch --help")]
    # Every duration error names its option, as '--hold -1s' does (nothing is connected to: no
    # controller runs on port 9).
    for cmd, option in ((["set", "force", "5"], "--hold"), (["set", "force", "5"], "--wait"),
                        (["enable"], "--hold"), (["watch"], "--window"),
                        (["record", "--out", "x.csv"], "--duration"), (["serve"], "--duration")):
        cases.append(([*cmd, "--port", "9", option, "0s"], f"{option}: '0s' is not a positive duration",
                      f"maglead {cmd[0]} --help"))
    # One time vocabulary: "m" is metres in every command, so no time option reads it as minutes.
    for cmd, option in ((["simulate", "--scenario", "hand-push", "--out", "x.csv"], "--duration"),
                        (["record", "--port", "9", "--out", "x.csv"], "--duration"),
                        (["serve"], "--duration"), (["serve"], "--idle-timeout"),
                        (["set", "force", "5", "--port", "9"], "--hold")):
        cases.append(([*cmd, option, "2m"], f"{option}: '2m' is metres; for minutes type 2min",
                      f"maglead {cmd[0]} --help"))
    cases.append((["watch", "--port", "9", "--window", "soon"], "--window: 'soon' is not a duration",
                  "maglead watch --help"))
    for args, says, hint in cases:
        rc, _, err = run(*args)
        check(rc == 2 and err.startswith("maglead: error:") and says in err and hint in err,
              f"maglead {' '.join(args)}: exit 2, 'maglead: error:', what to type (rc {rc}): {err.strip()!r}")
    rc, out, _ = run("analyze", "--help")
    check(rc == 0 and "{false}" not in out and "--no-twin-check" in out, "analyze --help: no '{false}' default")
    rc, out, _ = run("simulate", "--help")
    check(rc == 0 and "--config DIR" in out and "=/" not in out and "$MAGLEAD_CONFIG" in out,
          "--help states the configuration rule, not a build-tree path")


def checkout_config():
    """A checkout laid out as a user has it: the program reads <checkout>/config, so an edit there
    takes effect on the next run, without a rebuild."""
    repo = os.path.join(WORK, "checkout")
    os.makedirs(os.path.join(repo, "build", "bin"))
    shutil.copytree(CONFIG, os.path.join(repo, "config"))
    open(os.path.join(repo, "CMakeLists.txt"), "w").close()
    binary = os.path.join(repo, "build", "bin", "maglead")
    shutil.copy(MAGLEAD, binary)
    path = os.path.join(repo, "config", "actuator.toml")
    with open(path) as f:
        text = f.read()
    with open(path, "w") as f:
        f.write(re.sub(r"stroke_max_m = [0-9.]+", "stroke_max_m = 0.030", text))
    srv = Server(binary, None, "--port", "0", duration="30s", env=ENV)
    try:
        check(any("configuration from " + os.path.join(repo, "config") in l and "read actuator.toml" in l
                  for l in srv.lines), f"serve reads the checkout's config/ and names the files: {srv.lines}")
        rc, _, err = run("set", "--port", str(srv.port), "position", "35mm", binary=binary)
        check(rc == 2 and "0 .. 30 mm" in err, f"the edited stroke (30 mm) refuses 35 mm: {err.strip()!r}")
    finally:
        srv.stop()


def poll_json(port, names):
    rc, out, err = run("poll", "--port", port, "--json", "--names", names)
    check(rc == 0, f"poll {names}: {err.strip()}")
    return json.loads(out) if rc == 0 else {"values": {}, "alarm": {}}


def against_a_server():
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    try:
        port = str(srv.port)
        # Signed registers signed in --raw: the observer's lower bound at rest is negative.
        rc, out, _ = run("poll", "--port", port, "--raw", "--json", "--names", "load_force_lo_mn,phase_urad")
        raw = json.loads(out)["values"]
        si = poll_json(port, "load_force_lo_mn")["values"]
        check(raw["load_force_lo_mn"] < 0 and abs(raw["load_force_lo_mn"] - 1000 * si["load_force_lo_n"]) <= 50,
              f"poll --raw prints a signed register signed: {raw} (SI {si})")
        rc, out, _ = run("poll", "--port", port)
        for name, code in (("fault_reaction", "none"), ("write_refusal_reason", "none"),
                           ("twin_drift_reason", "none"), ("force_loop_state", "off"),
                           ("force_reached_reason", "not_force_mode"), ("twin_health_reason", ""),
                           ("twin_step_out_reason", ""), ("observer_basis", "")):
            row = next((l for l in out.splitlines() if l.split()[:1] == [name]), "")
            check(len(row.split()) >= 3 and (code in row.split()[2:] if code else True),
                  f"poll names the code of {name}: {row.strip()!r}")
        # set takes the names poll prints, with units.
        for name, value, shown in (("watchdog_s", "0.5s", "watchdog_s = 0.5 s"),
                                   ("velocity_limit_m_s", "5mm/s", "velocity_limit_m_s = 0.005 m/s")):
            rc, out, err = run("set", "--port", port, name, value)
            check(rc == 0 and shown in out, f"set {name} {value}: {out.strip()} {err.strip()}")
        run("set", "--port", port, "watchdog_s", "0s")
        # set force: says it holds, then releases cleanly, and the state agrees.
        rc, out, err = run("set", "--port", port, "force", "8", "--hold", "1s")
        check(rc == 0 and "done" in out and "holding force 8.000 N for 1.0 s" in out and "released" in out,
              f"set force 8 --hold 1s says what it does: {out.strip()} {err.strip()}")
        j = poll_json(port, "drive_state,alarm_code,control_owner")
        check(j["drive_state"] == "ready" and j["alarm"]["code"] == 0 and isinstance(j["alarm"]["code"], int)
              and j["values"]["control_owner"] == 0,
              f"after set exits: drive ready, no alarm (an integer code), nobody owns control: {j}")
        # Without --hold it holds until Ctrl-C, then releases.
        holder = subprocess.Popen([MAGLEAD, "set", "--port", port, "force", "6"], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, env=ENV)
        end = time.time() + 10
        while time.time() < end and poll_json(port, "drive_state")["drive_state"] != "enabled":
            time.sleep(0.1)
        time.sleep(1.0)
        check(holder.poll() is None and poll_json(port, "drive_state")["drive_state"] == "enabled",
              "set force without --hold keeps control")
        holder.send_signal(2)
        hout, herr = holder.communicate(timeout=10)
        check(holder.returncode == 0 and "until Ctrl-C" in hout and "released" in hout,
              f"Ctrl-C releases: {hout.strip()} {herr.strip()}")
        check(poll_json(port, "drive_state")["drive_state"] == "ready", "after Ctrl-C: drive ready, no fault")
        # A drive left in fault: disable says so and what to type, never "drive disabled".
        holder = subprocess.Popen([MAGLEAD, "enable", "--port", port], stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True, env=ENV)
        end = time.time() + 10
        while time.time() < end and poll_json(port, "drive_state")["drive_state"] != "enabled":
            time.sleep(0.1)
        holder.kill()
        holder.communicate(timeout=10)
        end = time.time() + 5
        while time.time() < end and poll_json(port, "drive_state")["drive_state"] != "fault":
            time.sleep(0.1)
        rc, out, err = run("disable", "--port", port)
        check(rc == 0 and "stays in fault" in out and "owner_lost" in out and "maglead reset" in out
              and "drive disabled" not in out, f"disable in fault says so: {out.strip()} {err.strip()}")
        run("reset", "--port", port)
    finally:
        srv.stop()


def force_at_the_stroke_end():
    """Force mode on the 40 mm stroke against a soft spring: a push (then a pull) ends at the
    window's end as a defined outcome (no fault), the client says so, and the next setpoint is
    taken at once."""
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--sim-spring", "600")
    try:
        port = str(srv.port)
        rc, out, err = run("set", "--port", port, "force", "15", "--config", CONFIG)
        check(rc == 4 and "stroke window ended before the force" in err and "control released" in err,
              f"set force 15 on a 600 N/m spring: the stroke end before the force: {err.strip()}")
        j = poll_json(port, "drive_state,alarm_code,nut_pos_m")
        check(j["alarm"]["code"] == 0 and j["drive_state"] == "ready" and j["values"]["nut_pos_m"] <= 0.040,
              f"no stroke_limit fault, the nut inside the stroke: {j}")
        # The next setpoint reached at once is checked in simulated time (ForceEnvelope.*): here the
        # controller takes it (acknowledged, force mode again, no fault).
        rc, out, err = run("set", "--port", port, "force", "5", "--no-wait", "--hold", "0.2s", "--config", CONFIG)
        check(rc == 0 and "acknowledged" in out, f"the next setpoint is taken: {out.strip()} {err.strip()}")
        # The other way: a pull of 15 N needs 25 mm below the anchor, past the stroke's start.
        rc, out, err = run("set", "--port", port, "force", "-15", "--config", CONFIG)
        check(rc == 4 and "stroke window ended before the force" in err,
              f"set force -15: the stroke's start before the force: {err.strip()}")
        j = poll_json(port, "drive_state,alarm_code,nut_pos_m")
        check(j["alarm"]["code"] == 0 and j["values"]["nut_pos_m"] >= 0.0,
              f"pulling: no stroke_limit fault, the nut inside the stroke: {j}")
    finally:
        srv.stop()


def recordings_and_files():
    rec = os.path.join(WORK, "hand.csv")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "8s", "--seed", "4", "--out", rec,
                     "--config", CONFIG)
    check(rc == 0, f"simulate: {err.strip()}")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "2s", "--effect", "viscous_friction=-50",
                     "--out", "neg.csv", "--config", CONFIG)
    check(rc == 2 and "viscous_friction" in err and "-48" in err, f"a negative viscous total refused: {err.strip()!r}")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "2s", "--effect", "mass_error=0.05",
                     "--out", "mass.csv", "--config", CONFIG)
    check(rc == 0, f"a positive mass change accepted: {err.strip()!r}")
    with open(rec) as f:
        lines = f.read().splitlines()
    header = next(i for i, l in enumerate(lines) if not l.startswith("#"))
    names = lines[header].split(",")
    # A semicolon export: the error names the separator.
    semi = os.path.join(WORK, "semi.csv")
    with open(semi, "w") as f:
        f.write("\n".join(l if l.startswith("#") else l.replace(",", ";") for l in lines) + "\n")
    rc, _, err = run("analyze", "--recording", semi, "--out", "semi_out", "--config", CONFIG)
    check(rc == 2 and "separated by ';'" in err, f"semicolon CSV: {err.strip()!r}")
    # Millimetres from row 3 on: the error cites row 3, the first, not the largest.
    pos = names.index("nut_pos_m")
    mm = os.path.join(WORK, "mm.csv")
    out = lines[:header + 1]
    for k, l in enumerate(lines[header + 1:]):
        f = l.split(",")
        if k >= 2:
            f[pos] = repr(float(f[pos]) * 1000)
        out.append(",".join(f))
    with open(mm, "w") as f:
        f.write("\n".join(out) + "\n")
    rc, _, err = run("analyze", "--recording", mm, "--out", "mm_out", "--config", CONFIG)
    check(rc == 2 and "at data row 3 " in err and "millimetres" in err, f"first row beyond the bound: {err.strip()!r}")
    # The load cell in kilonewtons, or of the other sign: refused with the likely unit, not
    # analysed into "found: …".
    lc = names.index("load_force_n")
    for name, scale, says in (("kn", 1e-3, "likely unit: kilonewtons"), ("flipped", -1.0, "of the other sign")):
        bad = os.path.join(WORK, name + ".csv")
        out = lines[:header + 1]
        for l in lines[header + 1:]:
            f = l.split(",")
            f[lc] = repr(float(f[lc]) * scale)
            out.append(",".join(f))
        with open(bad, "w") as f:
            f.write("\n".join(out) + "\n")
        rc, _, err = run("analyze", "--recording", bad, "--out", name + "_out", "--config", CONFIG)
        check(rc == 2 and "column load_force_n cannot be the load in newtons" in err and says in err,
              f"load cell ×{scale}: refused with the likely unit: {err.strip()!r}")
        # report compares nothing with it: no "static force estimate off by …" from a wrong unit.
        rc, out_text, err = run("report", bad, "--out", name + "_report", "--config", CONFIG)
        head = out_text.splitlines()[0] if out_text else ""
        with open(os.path.join(WORK, name + "_report", "report.json")) as f:
            force_error = json.load(f)["force_error"]
        check(rc == 0 and head.startswith("not judged: ") and "off by" not in head
              and "force estimate (load_force_n is not the load in newtons" in head and force_error is None,
              f"report, load cell ×{scale}: not compared, said so: {head!r} force_error {force_error}")
    # The screw angle in degrees on a hand push (the screw held: too little travel for the
    # turns-per-lead check): the phase lies off the coupling's stable branch, and that is said,
    # not blamed on the load cell.
    deg = os.path.join(WORK, "deg.csv")
    th = names.index("screw_angle_rad")
    keep = [i for i, n in enumerate(names) if n != "motor_angle_rad"]
    with open(deg, "w") as f:
        rows = [",".join(names[i] for i in keep)]
        for l in lines[header + 1:]:
            x = l.split(",")
            x[th] = repr(math.degrees(float(x[th])))
            rows.append(",".join(x[i] for i in keep))
        f.write("\n".join(lines[:header] + rows) + "\n")
    for cmd, extra in (("analyze", ["--out", "deg_out"]), ("twin-check", []), ("estimate", [])):
        rc, _, err = run(cmd, deg, *extra, "--config", CONFIG)
        check(rc == 2 and "stable branch" in err and "likely in another unit (degrees" in err
              and "load_force_n" not in err, f"{cmd}, screw angle in degrees: {err.strip()!r}")
    # No load cell: nothing judged is said so, never "no anomaly found".
    lc = names.index("load_force_n")
    nolc = os.path.join(WORK, "nolc.csv")
    with open(nolc, "w") as f:
        for l in lines:
            if l.startswith("#"):
                f.write(l + "\n")
            else:
                parts = l.split(",")
                del parts[lc]
                f.write(",".join(parts) + "\n")
    rc, out, err = run("report", "--recording", nolc, "--out", "nolc_report", "--config", CONFIG)
    first = out.splitlines()[0] if out else ""
    check(rc == 0 and first.startswith("not judged") and "load_force_n" in first and "no anomaly" not in first,
          f"report without a load cell: {first!r}")
    rc, _, err = run("analyze", "--recording", nolc, "--out", "nolc_out", "--config", CONFIG)
    check(rc == 2 and "missing required column 'load_force_n'" in err and "load cell" in err
          and f"maglead twin-check --recording {nolc}" in err and not os.path.exists(os.path.join(WORK, "nolc_out")),
          f"analyze without a load cell points at twin-check: {err.strip()!r}")
    rc, _, err = run("twin-check", "--recording", nolc, "--config", CONFIG)
    check(rc == 0, f"twin-check, where analyze points, takes a recording without a load cell: {err.strip()!r}")
    missing_columns(lines, header, rec)
    analyze_options(rec)
    recording_positional(rec, nolc)
    # A finding is named in the first line, with its value and the model's.
    vis = os.path.join(WORK, "vis.csv")
    run("simulate", "--scenario", "mixed-moves", "--duration", "40s", "--seed", "3", "--effect",
        "viscous_friction=20", "--out", vis, "--config", CONFIG)
    rc, out, err = run("analyze", "--recording", vis, "--out", "vis_out", "--config", CONFIG)
    first = out.splitlines()[0] if out else ""
    m = re.match(r"found: viscous friction viscous_n_s_per_m (\d+\.\d+) ± ([0-9.]+) N·s/m, "
                 r"calibration ± ([0-9.]+) N·s/m \(model 2 N·s/m\)", first)
    # The truth (2 + 20) within two standard errors and the calibration's share of the error.
    check(rc == 0 and m is not None and
          abs(float(m.group(1)) - 22.0) <= 2 * float(m.group(2)) + float(m.group(3)),
          f"analyze names the finding first, beside the model's value: {first!r} {err.strip()[-200:]}")
    with open(os.path.join(WORK, "vis_out", "analysis.json")) as f:
        check(json.load(f)["headline"] == first, "analysis.json carries the same headline")
    with open(os.path.join(WORK, "vis_out", "index.html")) as f:
        page = f.read()
    check(page.find('id="headline"') < page.find("<h2"), "the page puts the headline above the first section")
    # Findings the data cannot tell apart: the terminal names each one, with its parameters.
    # In moves alone a gear's play reads like Coulomb friction (the screw lags by half the play
    # on the side friction loads it).
    play = os.path.join(WORK, "play.csv")
    run("simulate", "--scenario", "position-moves", "--duration", "40s", "--seed", "1", "--effect",
        "backlash=0.05", "--out", play, "--config", CONFIG)
    rc, out, _ = run("analyze", "--recording", play, "--out", "play_out", "--no-twin-check",
                     "--config", CONFIG)
    told = re.search(r"cannot tell (\w+) from ([\w, ]+) here", out)
    alternatives = re.findall(r"^     or (\w+): .*\(reproduces [0-9.]+ % of it\)$", out, re.M)
    check(rc == 0 and told is not None and "backlash" in told.group(2) and "backlash" in alternatives
          and all(a in told.group(2) for a in alternatives),
          f"alternatives named and listed: {told.group(0) if told else out[-300:]!r} {alternatives}")
    # Images are what their names say.
    rc, _, err = run("estimate", "--recording", rec, "--plot", "est.jpg", "--config", CONFIG)
    with open(os.path.join(WORK, "est.jpg"), "rb") as f:
        check(rc == 0 and f.read(2) == b"\xff\xd8", f"--plot x.jpg writes a JPEG: {err.strip()!r}")
    rc, _, err = run("estimate", "--recording", rec, "--plot", "est.gif", "--config", CONFIG)
    check(rc == 2 and ".png" in err, f"--plot x.gif refused with what to type: {err.strip()!r}")


def missing_columns(lines, header, rec):
    """A recording the analysis cannot read says what it has and what to type."""
    # An axis's recording against the actuator's baseline: the --model it needs, as report says.
    emps = os.path.join(os.path.dirname(CONFIG), "data", "emps", "emps_estimation.csv")
    for command in (["analyze", "--out", "emps_out"], ["report", "--out", "emps_report"]):
        rc, _, err = run(command[0], "--recording", emps, *command[1:], "--config", CONFIG)
        check(rc == 2 and "a linear axis's recording" in err and "no column" not in err
              and f"Analyse an axis with: maglead analyze --recording {emps} --model BASELINE.toml" in err,
              f"{command[0]} on the EMPS axis says what to type: {err.strip()!r}")
    # A column renamed to another unit: the columns found, and what to convert and rename.
    renamed = os.path.join(WORK, "renamed.csv")
    with open(renamed, "w") as f:
        f.write("\n".join(lines[:header] + [lines[header].replace("nut_pos_m", "nut_pos_mm")]
                          + lines[header + 1:]) + "\n")
    rc, _, err = run("analyze", "--recording", renamed, "--out", "renamed_out", "--config", CONFIG)
    check(rc == 2 and "header has: t_s," in err and "nut_pos_mm" in err
          and "convert it to metres and name it 'nut_pos_m'" in err, f"nut_pos_mm: {err.strip()!r}")
    # An empty file: what the header looks like, and where the format is described.
    empty = os.path.join(WORK, "empty.csv")
    open(empty, "w").close()
    rc, _, err = run("analyze", "--recording", empty, "--out", "empty_out", "--config", CONFIG)
    check(rc == 2 and "no header row" in err and "t_s,screw_angle_rad,nut_pos_m,load_force_n" in err
          and "docs/recording-format.md" in err, f"empty recording: {err.strip()!r}")
    # Data without its header row: said so, not read as columns named "0", "138.23", ….
    nohdr = os.path.join(WORK, "nohdr.csv")
    with open(nohdr, "w") as f:
        f.write("\n".join(lines[header + 1:]) + "\n")
    for cmd, extra in (("inspect", []), ("analyze", ["--out", "nohdr_out"]), ("twin-check", [])):
        rc, _, err = run(cmd, nohdr, *extra, "--config", CONFIG)
        check(rc == 2 and "no header row: this row is numbers" in err and "t_s,screw_angle_rad" in err,
              f"{cmd} on data without a header: {err.strip()!r}")
    # A header and fewer than two data rows: every reader refuses it, naming the file and its rows,
    # and inspect says so (exit 2), as its help promises. Before, inspect printed "0 rows" and
    # exited 0, and twin-check said "replay: needs at least two samples" without the file.
    for rows in (0, 1):
        short = os.path.join(WORK, f"short{rows}.csv")
        with open(short, "w") as f:
            f.write("\n".join(lines[:header + 1 + rows]) + "\n")
        said = f"{short}: {rows} data row{'' if rows == 1 else 's'} below its header"
        for cmd, extra in (("inspect", []), ("twin-check", []), ("analyze", ["--out", "short_out"]),
                           ("report", ["--out", "short_out"]), ("estimate", [])):
            rc, out, err = run(cmd, short, *extra, "--config", CONFIG)
            check(rc == 2 and said in err and "need at least 2" in err and "replay:" not in err,
                  f"{cmd} on a recording of {rows} data rows: {out.strip()[:80]!r} {err.strip()!r}")


def recording_positional(rec, nolc):
    """Every command that reads a recording takes its path as `maglead CMD FILE` as well as
    `--recording FILE`; both given, or neither, is refused with what to type."""
    rc, out, err = run("inspect", rec, "--config", CONFIG)
    rc2, out2, _ = run("inspect", "--recording", rec, "--config", CONFIG)
    check(rc == 0 and rc2 == 0 and out == out2 and "rows" in out,
          f"inspect FILE reads as inspect --recording FILE: {out[:80]!r} {err.strip()!r}")
    rc, _, err = run("twin-check", nolc, "--config", CONFIG)
    check(rc == 0, f"twin-check FILE: {err.strip()!r}")
    rc, _, err = run("estimate", rec, "--plot", "positional.png", "--config", CONFIG)
    check(rc == 0 and os.path.exists(os.path.join(WORK, "positional.png")), f"estimate FILE: {err.strip()!r}")
    outs = {"analyze": ["--out", "pos_out"], "report": ["--out", "pos_out"], "calibrate": ["--out", "pos.toml"],
            "inspect": [], "twin-check": [], "estimate": []}
    for cmd, more in outs.items():
        # The path reaches the reader: its error names the file, never a missing option.
        rc, _, err = run(cmd, "nosuch.csv", *more, "--config", CONFIG)
        check(rc == 2 and "nosuch.csv" in err and "required" not in err,
              f"{cmd} FILE reads FILE: {err.strip()!r}")
        rc, _, err = run(cmd, rec, "--recording", "other.csv", *more, "--config", CONFIG)
        check(rc == 2 and "the recording is given twice" in err and "other.csv" in err
              and f"type it once, e.g. maglead {cmd} {rec}" in err and not os.path.exists(os.path.join(WORK, "pos_out")),
              f"{cmd} FILE --recording OTHER refused: {err.strip()!r}")
        rc, _, err = run(cmd, *more, "--config", CONFIG)
        check(rc == 2 and f"a recording is required: type e.g. maglead {cmd} FILE (or --recording FILE)" in err,
              f"{cmd} without a recording says what to type: {err.strip()!r}")


def analyze_options(rec):
    """Option values the analysis cannot use are refused with the range and what to type, before
    anything is written; a filter that leaves no sliding sample is named as the cause."""
    cases = [(["--folds", "0"], "0 is outside 3 .. 100", "--folds 10"),
             (["--folds", "1"], "1 is outside 3 .. 100", "--folds 10"),
             (["--folds", "3"], "below the actuator analysis's 4 held-out segments", "--folds 10"),
             (["--min-gain", "-5"], "-5 % is outside 0 .. 100 %", "--min-gain 1"),
             (["--filter-hz", "-5"], "-5 Hz is below 0 Hz", "--filter-hz 20"),
             (["--decimation", "-2"], "-2 is outside 0 .. 1000", "--decimation 1"),
             (["--calibration-accuracy", "-2"], "-2 N is below 0 N", "--calibration-accuracy 0.5")]
    for args, says, typed in cases:
        out = os.path.join(WORK, "opt_out")
        rc, _, err = run("analyze", "--recording", rec, "--out", out, *args, "--config", CONFIG)
        check(rc == 2 and says in err and "type e.g. " + typed in err and not os.path.exists(out),
              f"analyze {' '.join(args)}: refused with the range and what to type: {err.strip()!r}")
    # The axis's --decimation with the actuator's model: refused, not silently ignored.
    out = os.path.join(WORK, "opt_out")
    rc, _, err = run("analyze", "--recording", rec, "--out", out, "--decimation", "2",
                     "--config", CONFIG)
    check(rc == 2 and "applies to an axis's model only" in err and "drop --decimation" in err
          and not os.path.exists(out), f"analyze --decimation 2 on the actuator: {err.strip()!r}")
    # The hand push slides at about 1 mm/s: a 60 Hz filter counts sliding from 1.3 mm/s.
    rc, out, err = run("analyze", rec, "--out", "filter_out", "--filter-hz", "60",
                       "--no-twin-check", "--config", CONFIG)
    note = next((l for l in out.splitlines() if l.startswith("note: ")), "")
    check(rc == 0 and "--filter-hz 60 sets" in note and "leave --filter-hz out or lower it" in note
          and "barely slides" not in note, f"--filter-hz 60: the note names the option: {note!r}")
    # A nut that barely slides (Stribeck break-away, 390 sliding samples): no held-out segments,
    # so no held-out figure, never "baseline 0 N".
    stuck = os.path.join(WORK, "stuck.csv")
    run("simulate", "--scenario", "mixed-moves", "--duration", "40s", "--seed", "2", "--effect",
        "stribeck_friction=3", "--out", stuck, "--config", CONFIG)
    rc, out, err = run("analyze", "--recording", stuck, "--out", "stuck_out", "--no-twin-check", "--config", CONFIG)
    held = next((l for l in out.splitlines() if l.startswith("held-out:")), "")
    check(rc == 0 and "not judged (too few sliding samples" in held and " 0 N" not in held,
          f"held-out with too few sliding samples: not judged, not 0 N: {held!r} {err.strip()[-200:]}")


def config_files():
    # A model file's unknown parameter: the error points at the key's own line.
    model = os.path.join(WORK, "bad_model.toml")
    with open(model, "w") as f:
        f.write("# format: maglead-model/1\n[model]\nnut_mass_kg = 0.12\nviscous_n_s_per_m = 2.0\n"
                "coulomb_n = 7.5\n\n[[term]]\nid = \"offset\"\nofset_n = 1.0\n")
    rc, _, err = run("twin-check", "--recording", os.path.join(WORK, "hand.csv"), "--model", model,
                     "--config", CONFIG)
    check(rc == 2 and f"{model}:9:" in err and "ofset_n" in err and "offset_n" in err,
          f"bad key at its own line, with the parameters: {err.strip()!r}")
    cfg = os.path.join(WORK, "cfg_net")
    shutil.copytree(CONFIG, cfg)
    net = os.path.join(cfg, "network.toml")
    with open(net) as f:
        text = f.read()
    with open(net, "w") as f:
        f.write(re.sub(r'bind_address = "[^"]*"', 'bind_address = "localhost:80"', text))
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    check(rc == 2 and "network.toml:" in err and "bind_address" in err and "IPv4" in err,
          f"bind_address error names the file: {err.strip()!r}")
    with open(net, "w") as f:
        f.write(re.sub(r"port = \d+", "port = 99999", text))
    rc, _, err = run("serve", "--config", cfg, "--duration", "1s")
    check(rc == 2 and "99999 is outside 0 .. 65535" in err, f"numbers as a person writes them: {err.strip()!r}")


def readme_tour():
    """The README's tour, as a newcomer types it: the headline it quotes is what analyze prints."""
    readme = os.path.join(os.path.dirname(CONFIG), "README.md")
    with open(readme) as f:
        text = f.read()
    m = re.search(r"`analyze` prints the headline first \(`([^`]*)`", text.replace("\n", " "))
    check(m is not None, "README quotes analyze's headline")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "40s", "--seed", "5", "--effect",
                     "offset=2", "--out", "out/push.csv")
    rc2, out, err2 = run("analyze", "--recording", "out/push.csv", "--out", "out/push")
    first = out.splitlines()[0] if out else ""
    check(rc == 0 and rc2 == 0 and m is not None and first == m.group(1),
          f"README's tour: analyze prints {first!r}, the README says {m.group(1) if m else None!r}")
    rc, out, err = run("estimate", "--recording", "out/push.csv", "--estimator", "twin", "--model",
                       "out/push/model_corrected.toml")
    quoted = re.search(r"It prints `(mean absolute error[^`]*)`", text.replace("\n", " "))
    check(rc == 0 and quoted is not None and quoted.group(1) in out,
          f"README's tour: estimate with the corrected model prints what the README quotes "
          f"({quoted.group(1) if quoted else None!r}): {out.strip()[:200]} {err.strip()}")


def main():
    watchdog(240)
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)
    usage_errors()
    readme_tour()
    checkout_config()
    against_a_server()
    force_at_the_stroke_end()
    recordings_and_files()
    config_files()
    finish()


if __name__ == "__main__":
    main()
