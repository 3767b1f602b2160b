"""The operator commands (poll, set, enable, disable, reset, record, watch) against `maglead serve`
on the simulated actuator over Modbus TCP. What they print is checked against raw Modbus reads;
refusals are checked to write nothing (the staged commands and setpoints do not change).
Usage: operator_tcp.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import contextlib
import csv
import fcntl
import json
import os
import pty
import re
import select
import shutil
import signal
import socket
import struct
import subprocess
import sys
import termios
import time

from op_common import (Server, check, finish, i32, one_line, raw_request, read_regs, run,
                       watchdog)

MAGLEAD, CONFIG, WORK = sys.argv[1], sys.argv[2], sys.argv[3]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main():
    watchdog(230)
    os.makedirs(WORK, exist_ok=True)
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    try:
        check(srv.port is not None, f"serve listens on a free port {srv.port}")
        scenario(srv.port)
    finally:
        tail = srv.stop()
    check("stopped after" in tail, "serve stops cleanly")
    dropped_connection()
    stroke_end_load()
    step_out_advice()
    finish()


def config_with(name, line):
    """A copy of the configuration with one line of actuator.toml replaced ("key = value")."""
    path = os.path.join(WORK, name)
    shutil.rmtree(path, ignore_errors=True)
    shutil.copytree(CONFIG, path)
    toml = os.path.join(path, "actuator.toml")
    key = line.split("=")[0].strip()
    with open(toml) as f:
        text = re.sub(rf"^{key}\s*=.*$", line, f.read(), flags=re.M)
    with open(toml, "w") as f:
        f.write(text)
    return path


def drive_limits(port, conn):
    """set checks against the limits the controller reports (IR 140/142), not this machine's
    configuration: a wider one does not let more through, a narrower one does not refuse what
    the controller takes."""
    words = read_regs(port, 4, 140, 4)
    push, pull = (struct.unpack(">f", struct.pack(">HH", *words[i:i + 2]))[0] for i in (0, 2))
    check(30 < push < 40 and -40 < pull < -30, f"IR 140/142: the safe force limits {push:.2f} / {pull:.2f} N")
    # docs/plc.md gives them rounded inwards, so a force it names is one 'set force' takes.
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs", "plc.md")) as f:
        m = re.search(r"\+(\d+\.\d+) / −(\d+\.\d+) N with the shipped files", f.read())
    doc = (float(m.group(1)), -float(m.group(2))) if m else (float("nan"),) * 2
    check(0 <= push - doc[0] < 0.01 and 0 <= doc[1] - pull < 0.01,
          f"docs/plc.md's safe limits {doc} N are IR 140/142's {push:.4f} / {pull:.4f} N rounded inwards")
    wide = config_with("wide_config", "safe_force_fraction = 1.0")
    rc, _, err = run(MAGLEAD, "set", *conn, "force", "40", "--config", wide)
    check(rc == 2 and "nothing sent" in err and f"allowed {pull:.6g} .. {push:.6g} N (the controller's limits" in err,
          f"set force 40 past the controller's own limit, with a wider config here: its limits, read from it: {err.strip()}")
    narrow = config_with("narrow_config", "safe_force_fraction = 0.2")
    # 25 N: beyond 0.2 of the peaks here, inside the controller's limits; it passes the limit check
    # and is refused for another reason (the drive is not enabled, --no-claim).
    rc, _, err = run(MAGLEAD, "set", *conn, "force", "25", "--no-claim", "--config", narrow)
    check(rc == 2 and "drop --no-claim" in err and "safe limit" not in err,
          f"set force 25 with a narrower config here: the controller's limits decide: {err.strip()}")


def scenario(port):
    conn = ["--port", str(port)]

    # poll: table, JSON, CSV, raw; values agree with an independent raw read.
    rc, out, err = run(MAGLEAD, "poll", *conn)
    check(rc == 0 and re.search(r"^\s+nut_pos_m\s+0\.0\d+\s+m\s", out, re.M) is not None and "nut_pos_um" not in out
          and "drive_state" in out and "ready" in out,
          f"poll prints a table (rc {rc}) {err.strip()}")
    check("float32" not in out and "nut_pos_m_f32" not in out, "poll hides the float32 duplicates by default")
    check(not [l for l in out.splitlines() if l.endswith(" ")],
          f"poll's lines end without spaces: {[l for l in out.splitlines() if l.endswith(' ')][:3]}")
    check(re.search(r"^\s+twin_drift_zero_load_error_n\s+\S+\s+N\s", out, re.M) is not None
          and re.search(r"^\s+twin_drift_statistic\s", out, re.M) is not None,
          "poll shows the float32-only figures (the drift flag's) under their SI names")
    rc, out, err = run(MAGLEAD, "poll", *conn, "--json")
    j = json.loads(out) if rc == 0 else {}
    raw_pos_um = i32(read_regs(port, 4, 20, 2))
    pos = j.get("values", {}).get("nut_pos_m", float("nan"))
    check(abs(pos * 1e6 - raw_pos_um) <= 100, f"poll --json position {pos} m matches raw read {raw_pos_um} um")
    check(j.get("units", {}).get("nut_pos_m") == "m" and j.get("units", {}).get("force_est_n") == "N"
          and "nut_pos_um" not in j.get("values", {}),
          "poll --json gives SI units from the register table, under SI names")
    check(j.get("drive_state") == "ready" and "ready" in j.get("status_bits", []), "poll --json spells out state")
    check(j.get("alarm", {}).get("name") == "none", "poll --json: no alarm")
    rc, out, _ = run(MAGLEAD, "poll", *conn, "--csv", "--names", "nut_pos_um,loop_rate_hz")
    rows = list(csv.reader(out.splitlines()))
    check(rc == 0 and rows[0] == ["name", "value", "unit"] and len(rows) == 3 and rows[1][0] == "nut_pos_m"
          and rows[2] == ["loop_rate_hz", "1000", "Hz"],
          f"poll --csv --names {rows}")
    rc, out, _ = run(MAGLEAD, "poll", *conn, "--csv", "--raw", "--names", "nut_pos_um")
    raw = int(out.splitlines()[1].split(",")[1]) if rc == 0 else -1
    check(abs(raw - 20000) < 500 and out.splitlines()[1].startswith("nut_pos_um,"),
          f"poll --raw gives the integer as sent under the register name ({raw} um)")
    # A name not known suggests the kind poll shows: the SI name, or under --raw the register's.
    for raw_flag, name in (([], "nut_pos_m"), (["--raw"], "nut_pos_um")):
        rc, _, err = run(MAGLEAD, "poll", *conn, *raw_flag, "nut_pos")
        check(rc == 2 and f"did you mean '{name}'?" in err, f"poll {' '.join(raw_flag)} nut_pos: {err.strip()}")

    # Refusals write nothing: the commands and setpoints (HR 1000-1019) and the refusal reason stay.
    staged0 = read_regs(port, 3, 1000, 20)
    rc, _, err = run(MAGLEAD, "set", *conn, "force", "60", "--config", CONFIG)
    check(rc == 2 and "safe limit" in err and "nothing sent" in err and one_line(err),
          f"set force 60 refused with the reason: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "force", "150N", "--config", CONFIG)
    check(rc == 2 and "beyond the safe limit" in err and "mN" not in err,
          f"set force 150N: the safe limit, not the register's wider range: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "20", "--config", CONFIG)
    check(rc == 2 and "type '20mm' for millimetres" in err and one_line(err),
          f"set position 20 (metres): says what to type: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "20mm", "--speed", "5", "--config", CONFIG)
    check(rc == 2 and "velocity_limit_m_s = 5 m/s" in err and "type '5mm/s'" in err,
          f"--speed 5 (m/s): SI name, what to type: {err.strip()}")
    # A near miss typed without a unit was meant in SI: no advice to type it in millimetres
    # (0.041 mm is in the stroke, but 0.041 m is what was meant).
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "0.041", "--config", CONFIG)
    check(rc == 2 and "outside the stroke" in err and "a number without a unit is in m" in err
          and "type '" not in err and one_line(err), f"set position 0.041 (a near miss in m): no mm hint: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "20mm", "--speed", "0.5", "--config", CONFIG)
    check(rc == 2 and "a number without a unit is in m/s" in err and "type '" not in err,
          f"--speed 0.5 (a near miss in m/s): no mm/s hint: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "20mm", "--accel", "100", "--config", CONFIG)
    check(rc == 2 and "type '100mm/s^2'" in err, f"--accel 100 (m/s^2): what to type: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "20mm", "--accel", "-100", "--config", CONFIG)
    check(rc == 2 and "a number without a unit is in m/s^2" in err and "type '" not in err,
          f"--accel -100: -100 mm/s^2 is refused too, so no hint: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "forse", "12", "--config", CONFIG)
    check(rc == 2 and "did you mean 'force'?" in err, f"set forse: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "45mm", "--config", CONFIG)
    check(rc == 2 and "outside" in err and one_line(err), f"set position 45mm refused: {err.strip()}")
    rc, _, err = run(MAGLEAD, "set", *conn, "position", "20 furlongs", "--config", CONFIG)
    check(rc == 2 and "unit" in err, f"unknown unit refused: {err.strip()}")
    staged1 = read_regs(port, 3, 1000, 20)
    check(staged1 == staged0, f"refusals wrote nothing to the controller (HR 1000-1019 {staged0} -> {staged1})")
    drive_limits(port, conn)

    # reset --resync with neither a step-out nor a fault says so and sends nothing, as reset does.
    before = read_regs(port, 4, 15, 2)  # command_status, command_reject_reason
    rc, out, err = run(MAGLEAD, "reset", *conn, "--resync")
    check(rc == 0 and out.strip() == "no step-out to resync and no fault to reset (drive_state ready)"
          and read_regs(port, 4, 15, 2) == before, f"reset --resync with nothing to do: rc {rc} {out.strip()} {err.strip()}")
    # The controller's own rejection stays for a raw client: a resync edge without a step-out.
    raw_request(port, struct.pack(">BHH", 6, 1000, 1 << 3))
    raw_request(port, struct.pack(">BHH", 6, 1000, 0))
    end = time.time() + 2
    while time.time() < end and read_regs(port, 4, 16, 1) != [7]:  # the loop takes it in a cycle
        time.sleep(0.02)
    reason = read_regs(port, 4, 16, 1)
    check(reason == [7], f"a raw resync edge: rejected not_stepped_out ({reason})")
    # command_status's bits by name, as status_word's are: the rejection is bit 6.
    rc, out, _ = run(MAGLEAD, "poll", *conn, "command_status")
    m = re.search(r"^\s+command_status\s+(\d+)\s+(.*)$", out, re.M)
    bits = ["execute_ack", "execute_done", "reset_ack", "reset_done", "resync_ack", "resync_done", "rejected"]
    named = [n for b, n in enumerate(bits) if m and int(m.group(1)) >> b & 1]
    check(m is not None and "rejected" in named and m.group(2).split() == named,
          f"poll command_status spells out its bits: {out.strip()!r}")

    rc, out, err = run(MAGLEAD, "enable", *conn, "--hold", "0.3s")
    check(rc == 0 and "enabled" in out and "released" in out and "without a fault" in out,
          f"enable --hold: {out.strip()} {err.strip()}")
    # The command said it released control; it did: no fault, the drive ready, nobody owns it.
    w = read_regs(port, 4, 11, 3)
    check(w[0] == 0 and w[2] == 1, f"after enable --hold: no alarm, drive ready (raw {w})")
    # set claims control itself (clears the owner_lost fault, enable edge) and holds it.
    holder = subprocess.Popen([MAGLEAD, "set", *conn, "force", "10", "--config", CONFIG, "--hold", "8s"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.time() + 10
    while time.time() < end and not (read_regs(port, 4, 10, 1)[0] & (1 << 5)):
        time.sleep(0.05)
    w = read_regs(port, 4, 14, 1) + read_regs(port, 4, 34, 2)
    check(w[0] == 2 and i32(w[1:3]) == 10000, f"controller holds 10 N in force mode (raw {w})")
    est = i32(read_regs(port, 4, 60, 2)) * 1e-3
    check(abs(est - 10.0) < 2.0, f"load observer's force near the setpoint: {est:.2f} N")
    load = i32(read_regs(port, 4, 30, 2)) * 1e-3
    check(abs(load - 10.0) < 2.0, f"and the load cell agrees: {load:.2f} N")

    # record while in force mode: load cell, setpoint and the sign convention.
    rec = os.path.join(WORK, "tcp_rec.csv")
    t0 = time.time()
    rc, out, err = run(MAGLEAD, "record", *conn, "--duration", "2s", "--rate", "50", "--out", rec)
    dt = time.time() - t0
    check(rc == 0 and "dropped polls:" in out, f"record 2 s: {out.strip()} {err.strip()}")
    check(dt < 6, f"record ended by itself ({dt:.1f} s)")
    # What record says it left for readers to fill is what a reader fills (polls at 1 kHz fall
    # behind now and then on a busy machine; none is fine too, then both say nothing).
    fast = os.path.join(WORK, "tcp_rec_fast.csv")
    rc, out_f, err_f = run(MAGLEAD, "record", *conn, "--duration", "2s", "--rate", "1000", "--out", fast)
    rc_i, out_i, err_i = run(MAGLEAD, "inspect", fast)
    said = re.search(r"gaps: (\d+) rows missing in (\d+) places", out_f)
    filled = re.search(r"filled (\d+) missing rows in (\d+) gaps", out_i + err_i)
    if rc_i == 0:
        check(rc == 0 and (said.groups() if said else None) == (filled.groups() if filled else None),
              f"record's gaps are inspect's: {said and said.group(0)} / {filled and filled.group(0)}")
    else:  # too many polls fell behind: record said so when it wrote the file
        check(rc == 0 and "readers (analyze, inspect, …) refuse this recording" in err_f,
              f"a recording inspect refuses was said to be so by record: {err_i.strip()[:200]} / {err_f.strip()[:300]}")
    # Ctrl-C before the duration is up: the file is kept whole, and the exit code says 130.
    cut = os.path.join(WORK, "tcp_rec_cut.csv")
    proc = subprocess.Popen([MAGLEAD, "record", *conn, "--duration", "60s", "--rate", "50", "--out", cut],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)
    proc.send_signal(signal.SIGINT)
    out_cut, err_cut = proc.communicate(timeout=10)
    with open(cut) as f:
        rows = [l for l in f if not l.startswith("#")]
    check(proc.returncode == 130 and "interrupted before --duration 60s" in err_cut and len(rows) > 10,
          f"record interrupted: exit {proc.returncode}, {len(rows)} lines kept: {err_cut.strip()}")
    with open(rec) as f:
        lines = f.read().splitlines()
    check(lines[0] == "# format: mls-recording/1", "recording starts with the format line")
    header_at = next(i for i, l in enumerate(lines) if not l.startswith("#"))
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs",
                           "recording-format.md")) as f:
        documented = f.read()
    undocumented = [c for c in lines[header_at].split(",") if f"`{c}`" not in documented]
    keys = [l[2:].split(":")[0] for l in lines[:header_at]]
    check(not undocumented and all(f"`{k}`" in documented for k in keys if k not in ("format", "source", "system")),
          f"every column and header key record writes is in docs/recording-format.md: {undocumented} {keys}")
    names = lines[header_at].split(",")
    data = [[float(x) if x else float("nan") for x in l.split(",")] for l in lines[header_at + 1:]]
    col = {n: [r[i] for r in data] for i, n in enumerate(names)}
    for need in ("t_s", "screw_angle_rad", "nut_pos_m", "out_force_est_n", "force_set_n", "load_force_n"):
        check(need in names, f"recording has column {need}")
    check(70 <= len(data) <= 110, f"about 100 rows at 50 Hz over 2 s ({len(data)})")
    check(all(b >= a for a, b in zip(col["t_s"], col["t_s"][1:])), "t_s non-decreasing")
    span = col["t_s"][-1] - col["t_s"][0]
    check(1.8 <= span <= 2.2, f"controller time spans ~2 s ({span:.3f})")
    check(all(abs(x - 10.0) < 1e-9 for x in col["force_set_n"]), "force_set_n is 10 N throughout")
    # Held at standstill, Coulomb friction takes up to 7.5 N of the 10 N: the spring (load cell)
    # sees less than the estimate, but the same sign of push. The column is the force on the
    # nut (load cell convention), the register the output force: opposite signs.
    mean_load = sum(col["load_force_n"]) / len(data)
    mean_est = sum(col["out_force_est_n"]) / len(data)
    lc_out = i32(read_regs(port, 4, 30, 2)) * 1e-3
    check(abs(mean_est - 10.0) < 2.0, f"recorded estimate near 10 N ({mean_est:.2f})")
    check(mean_load < 0 < lc_out and abs(mean_load + lc_out) < 1.0,
          f"load_force_n = -load-cell output force: column {mean_load:.2f} N, register {lc_out:.2f} N")
    rc, out, err = run(MAGLEAD, "report", "--recording", rec, "--out", os.path.join(WORK, "tcp_report"),
                       "--config", CONFIG, "--no-analysis")
    check(rc == 0 and os.path.exists(os.path.join(WORK, "tcp_report", "index.html")),
          f"report reads what record wrote: {out.strip()} {err.strip()[-300:]}")
    hout, herr = holder.communicate(timeout=20)
    check(holder.returncode == 0 and "done" in hout and "held for 8.0 s" in hout and "released" in hout,
          f"set force 10 --hold 8s: {hout.strip()} {herr.strip()}")
    # The holder released control as it said: disabled without a fault, nobody owns it.
    w = read_regs(port, 4, 11, 3)
    check(w[0] == 0 and w[2] == 1, f"holder done: no alarm, drive ready (raw {w})")
    # A holder that vanishes while owning control (killed, no release): owner loss in force
    # mode releases the force (ramp, then zero) and latches owner_lost.
    holder = subprocess.Popen([MAGLEAD, "set", *conn, "force", "10", "--config", CONFIG],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.time() + 10
    while time.time() < end and not (read_regs(port, 4, 10, 1)[0] & (1 << 5)):
        time.sleep(0.05)
    holder.kill()
    holder.communicate(timeout=10)
    end = time.time() + 3
    while time.time() < end and read_regs(port, 4, 54, 1)[0] != 3:
        time.sleep(0.05)
    w = read_regs(port, 4, 11, 1) + read_regs(port, 4, 54, 1)
    check(w == [7, 3], f"holder killed: alarm owner_lost, force released (raw {w})")
    # On an 80-column terminal the lines for a person break at spaces, never mid-word: poll's
    # alarm meaning, disable's fault and set's held/released lines are longer than 80.
    for args in (["poll"], ["disable"]):
        rc, text = run_pty(*args, *conn)
        check(rc == 0 and "owner_lost" in text and fits(text, 80),
              f"{args[0]} during owner_lost fits 80 columns: {text.strip()!r}")

    rc, text = run_pty("set", *conn, "position", "22mm", "--speed", "10mm/s", "--hold", "0.2s", "--config", CONFIG)
    check(rc == 0 and "done" in text and "released" in text and fits(text, 80),
          f"set position 22mm on an 80-column terminal: {text.strip()!r}")
    pos_um = i32(read_regs(port, 4, 20, 2))
    check(abs(pos_um - 22000) < 100, f"nut at 22 mm ({pos_um} um, raw read)")
    check(i32(read_regs(port, 3, 1008, 2)) == 10000, "speed limit staged as 10 mm/s")
    # A move that takes a while shows its progress on a terminal, one line redrawn in place and
    # replaced by the result; into a pipe nothing but the result (scripts parse it).
    rc, text = run_pty("set", *conn, "position", "24mm", "--speed", "2mm/s", "--hold", "0.1s", "--config", CONFIG)
    m = re.search(r"\rmoving to 24\.000 mm: nut at (2[2-4]\.[0-9]{3}) mm, ([0-9.]+) mm to go", text)
    check(rc == 0 and m is not None and abs(24 - float(m.group(1)) - float(m.group(2))) < 0.06,
          f"set position 24mm at 2 mm/s: a progress line with the nut and the distance to go: {text[:300]!r}")
    screen = rendered(text)
    check("moving to" not in screen and screen.startswith("position 24.000 mm: done (in position)")
          and fits(screen, 80), f"the progress line is replaced by the result: {screen!r}")
    rc, out, err = run(MAGLEAD, "set", *conn, "position", "22mm", "--speed", "2mm/s", "--hold", "0.1s",
                       "--config", CONFIG)
    check(rc == 0 and "moving" not in out and "\r" not in out and "\x1b" not in out
          and out.startswith("position 22.000 mm: done"), f"set into a pipe: no progress line: {out!r}")
    rc, out, err = run(MAGLEAD, "set", *conn, "position", "21mm", "--no-wait", "--hold", "0.2s", "--config", CONFIG)
    check(rc == 0 and "acknowledged" in out, f"set --no-wait returns on ack: {out.strip()} {err.strip()}")
    # A force inside the safe limit that friction keeps from the load: the coupling stops at its
    # limit, and the message gives the force the controller estimates the load gets there, a
    # figure 'set force' then reaches.
    rc, out, err = run(MAGLEAD, "set", *conn, "force", "30", "--config", CONFIG)
    m = re.search(r"the load gets ([0-9.]+) N \(load_force_est_n.*'maglead set force ([0-9.]+)N'", err)
    check(rc == 4 and m is not None and 20 < float(m.group(2)) < 30 and float(m.group(2)) <= float(m.group(1)),
          f"set force 30 stopped at the coupling's limit gives the figure to try: {err.strip()}")
    # On a terminal the wait shows the nut and the force estimate (the climb to the limit takes
    # about 0.9 s), then the error alone.
    rc, text = run_pty("set", *conn, "force", "30", "--config", CONFIG)
    screen = rendered(text)
    check(rc == 4 and re.search(r"\rreaching 30\.000 N: nut at [0-9.]+ mm, force estimate -?[0-9.]+ N", text)
          and "reaching" not in screen and screen.startswith("maglead set: execute:") and fits(screen, 80),
          f"set force 30 on a terminal: a progress line, then the error alone: {text[:300]!r}")
    if m:
        rc, out, err = run(MAGLEAD, "set", *conn, "force", m.group(2), "--hold", "0.1s", "--config", CONFIG)
        check(rc == 0 and "done (force reached)" in out, f"set force {m.group(2)} as advised: {out.strip()} {err.strip()}")
    # Not done within --wait: exit 4 with the controller's own state and reason; control released.
    rc, out, err = run(MAGLEAD, "set", *conn, "force", "12", "--wait", "0.05s", "--config", CONFIG)
    check(rc == 4 and "force not reached within 0.05 s" in err and "force_reached_reason" in err
          and "control released" in err and one_line(err), f"set --wait too short: {err.strip()}")
    w = read_regs(port, 4, 11, 3)
    check(w[0] == 0 and w[2] == 1, f"after the timeout: no alarm, drive ready (raw {w})")
    # Ctrl-C before done: exit 130, no "holding" line, control released and said so.
    mover = subprocess.Popen([MAGLEAD, "set", *conn, "position", "30mm", "--speed", "0.5mm/s",
                              "--config", CONFIG], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)
    mover.send_signal(signal.SIGINT)
    mout, merr = mover.communicate(timeout=20)
    check(mover.returncode == 130 and "interrupted before done" in merr and "holding" not in mout
          and "control released" in merr, f"Ctrl-C before done: rc {mover.returncode} {mout.strip()} {merr.strip()}")
    w = read_regs(port, 4, 11, 3)
    check(w[0] == 0 and w[2] == 1, f"after Ctrl-C: no alarm, drive ready (raw {w})")
    # Ctrl-C on a terminal: it echoes "^C" where the cursor stands, and the closing lines start
    # on a fresh line after it, so they wrap at 80 columns at spaces.
    rec = os.path.join(WORK, "tcp_ctrl_c.csv")
    for args, when, phrase in ((["set", *conn, "force", "10", "--config", CONFIG], b"holding",
                                "drive disabled without a fault"),
                               (["enable", *conn], b"holding", "drive disabled without a fault"),
                               (["--quiet", "record", *conn, "--duration", "20s", "--out", rec], 1.0,
                                "repeated cycles skipped"),
                               (["serve", "--config", CONFIG, "--port", "0"], b"Modbus TCP on",
                                "maglead serve: stopped after")):
        rc, text = run_pty(*args, interrupt_when=when)
        # A loaded machine (a sanitizer) may print serve's overrun note as the ^C is echoed; the
        # closing lines are checked without it.
        text = re.sub(r"maglead serve: loop overrun:.*?every 30 s\.\n?", "", text, flags=re.S)
        after = text[text.find("^C"):]
        joined = re.sub(r" *\n *", " ", after)
        check("^C\n" in text and phrase in joined and fits(text, 80),
              f"{' '.join(args[:2])}: Ctrl-C, then the closing lines on a fresh line, words whole: "
              f"rc {rc} {after!r}")
    # SIGTERM echoes no "^C": the closing line follows the last one, with no empty line between.
    rc, text = run_pty("serve", "--config", CONFIG, "--port", "0", terminate_when=b"Modbus TCP on")
    before = text[:text.find("maglead serve: stopped after")]
    check(rc == 0 and "maglead serve: stopped after" in text and not before.endswith("\n\n"),
          f"serve: SIGTERM on a terminal, no empty line before the closing line: rc {rc} {text[-300:]!r}")
    # Without --hold it returns once the move is done, control released (a script calling it ends).
    rc, out, err = run(MAGLEAD, "set", *conn, "reference-move", timeout=30)
    w = read_regs(port, 4, 13, 5)
    check(rc == 0 and "reference move (mode_command 3): done (in position)" in out
          and "released" in out and "Ctrl-C" not in out and w[0] == 1 and w[4] == 0,
          f"set reference-move runs the configured move to its end and lets go (state, owner {w[0]}, {w[4]}): "
          f"{out.strip()} {err.strip()}")
    # A bare number under the register's own name is in its raw unit (ms), said in SI; with a
    # unit it is read in that unit; under the SI name a bare number is in s.
    for name, typed, raw_ms, said in (("watchdog_ms", "50", 50, "watchdog_s = 0.05 s written (watchdog_ms 50:"),
                                      ("watchdog_ms", "0.07s", 70, "watchdog_s = 0.07 s written;"),
                                      ("watchdog_s", "0.09", 90, "watchdog_s = 0.09 s written;")):
        rc, out, err = run(MAGLEAD, "set", *conn, name, typed)
        got = read_regs(port, 3, 1003, 1)[0]
        check(rc == 0 and said in out and got == raw_ms,
              f"set {name} {typed}: {raw_ms} ms written (raw {got}): {out.strip()} {err.strip()}")
        # Written, and said that the tools cannot feed it (set and enable refuse under it).
        check("cannot feed a watchdog shorter than 0.2 s" in out and "a PLC can feed it" in out,
              f"set {name} {typed}: the note that set and enable cannot feed it: {out.strip()}")
    # A non-zero value the register's resolution rounds to 0 would write another meaning (the
    # watchdog off, 0 N): refused with the resolution and what to type, nothing written. Before,
    # watchdog_ms 0.05 said "watchdog_s = 0 s written" and switched the watchdog off.
    staged = read_regs(port, 3, 1001, 5)  # mode_command, heartbeat, watchdog_ms, force_setpoint_mn
    for name, typed, says in (("watchdog_ms", "0.05", "watchdog_s 5e-05 s is below the register's resolution "
                               "0.001 s; write 0 to switch it off or at least 0.001 s"),
                              ("watchdog_s", "0.0004", "watchdog_s 0.0004 s is below the register's resolution "
                               "0.001 s; write 0 to switch it off or at least 0.001 s"),
                              ("force_setpoint_n", "-0.0004", "force_setpoint_n -0.0004 N is below the register's "
                               "resolution 0.001 N; write 0 or at most -0.001 N"),
                              ("mode_command", "0.4", "mode_command 0.4 is below the register's resolution 1; "
                               "write 0 or at least 1")):
        rc, out, err = run(MAGLEAD, "set", *conn, name, typed)
        check(rc == 2 and says in err and "nothing sent" in err and "written" not in out and one_line(err)
              and read_regs(port, 3, 1001, 5) == staged,
              f"set {name} {typed} (rounds to 0): refused, nothing written: {out.strip()} {err.strip()}")
    rc, out, err = run(MAGLEAD, "set", *conn, "watchdog_ms", "0s")
    check(rc == 0 and "written" in out and "note" not in out, f"set a plain register: {out.strip()} {err.strip()}")
    rc, out, err = run(MAGLEAD, "set", *conn, "watchdog_s", "0.2")
    check(rc == 0 and out.strip() == "watchdog_s = 0.2 s written", f"a watchdog the tools feed, no note: {out.strip()}")
    run(MAGLEAD, "set", *conn, "watchdog_s", "0")
    # A code register takes its number or its name, and says both.
    staged_note = " (staged: applied by the next execute; to apply a mode now type 'maglead set force|position|idle|reference-move')"
    for typed in ("2", "force"):
        rc, out, err = run(MAGLEAD, "set", *conn, "mode_command", typed)
        check(rc == 0 and out.strip() == "mode_command = 2 (force) written" + staged_note
              and read_regs(port, 3, 1001, 1) == [2], f"set mode_command {typed}: {out.strip()} {err.strip()}")
    # A staged setpoint moves nothing until an execute: said, with what applies it now.
    for name, typed, said in (("force_setpoint_n", "5", "to apply a force now type 'maglead set force 5N'"),
                              ("force_setpoint_n_f32", "-2.5", "to apply a force now type 'maglead set force -2.5N'"),
                              ("position_setpoint_m", "20mm", "to move there now type 'maglead set position 20mm'"),
                              ("velocity_limit_m_s", "5mm/s", "the next move's limit"),
                              ("accel_limit_m_s2", "0.1", "the next move's limit")):
        rc, out, err = run(MAGLEAD, "set", *conn, name, typed, "--config", CONFIG)
        check(rc == 0 and "written (staged:" in out and said in out and read_regs(port, 4, 14, 1) == [0],
              f"set {name} {typed}: written, staged until an execute, said so: {out.strip()} {err.strip()}")
    run(MAGLEAD, "set", *conn, "velocity_limit_m_s", "10mm/s")
    rc, _, err = run(MAGLEAD, "set", *conn, "mode_command", "forse")
    check(rc == 2 and "0 idle, 1 position, 2 force, 3 reference_move" in err,
          f"set mode_command forse: the codes: {err.strip()}")
    run(MAGLEAD, "set", *conn, "mode_command", "idle")

    # watch under a pseudo-terminal: draws, quits on q, restores the screen.
    watch_pty(conn, b"q", "q")
    watch_pty(conn, None, "Ctrl-C")

    # Another client owns control: exception 06, one line.
    with socket.create_connection(("127.0.0.1", port), timeout=2) as plc:
        plc.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, 1000, 1))  # FC6 control_word = enable
        plc.recv(64)
        rc, _, err = run(MAGLEAD, "set", *conn, "force", "5", "--config", CONFIG)
        check(rc == 4 and "exception 04" in err and "not_owner: another client owns control" in err
              and "owner 127.0.0.1" in err and one_line(err),
              f"another owner: {err.strip()}")
        # enable while another client holds the drive enabled: refused, never "drive enabled".
        rc, out, err = run(MAGLEAD, "enable", *conn, "--hold", "1s")
        check(rc == 4 and "not_owner" in err and "drive enabled" not in out and "that client must release it" in err,
              f"enable while another owns control: rc {rc} {out.strip()} {err.strip()}")
    time.sleep(0.1)

    # Wrong unit id and a port with nobody listening.
    rc, _, err = run(MAGLEAD, "poll", *conn, "--unit", "7")
    check(rc == 3 and "does not serve unit 7" in err and one_line(err), f"wrong unit: {err.strip()}")
    rc, _, err = run(MAGLEAD, "poll", "--port", str(free_port()))
    check(rc == 3 and "connection refused" in err and one_line(err), f"nobody listening: {err.strip()}")
    # Finding 10: host names and IPv6 addresses are resolved (localhost went to 255.255.255.255).
    rc, out, err = run(MAGLEAD, "poll", "--host", "localhost", "--port", str(port), "--json")
    check(rc == 0 and json.loads(out).get("values", {}).get("device_type") == 0x4D4C, f"--host localhost: {err.strip()}")
    rc, _, err = run(MAGLEAD, "poll", "--host", "no-such-host.invalid", "--port", str(port))
    check(rc == 3 and "cannot resolve host 'no-such-host.invalid'" in err and one_line(err),
          f"unknown host name: {err.strip()}")
    v6 = free_port()
    relay = subprocess.Popen(["socat", f"TCP6-LISTEN:{v6},bind=[::1],reuseaddr,fork", f"TCP4:127.0.0.1:{port}"],
                             stderr=subprocess.DEVNULL)
    try:
        time.sleep(0.3)
        rc, out, err = run(MAGLEAD, "poll", "--host", "::1", "--port", str(v6), "--json")
        check(rc == 0 and json.loads(out).get("values", {}).get("device_type") == 0x4D4C, f"--host ::1 (IPv6): {err.strip()}")
    finally:
        relay.terminate()
        relay.wait(5)

    rc, out, err = run(MAGLEAD, "reset", *conn)
    check(rc == 0 and "fault reset done" in out and read_regs(port, 4, 13, 1)[0] == 1,
          f"reset clears the owner_lost fault: {err.strip()}")
    # A watchdog fault left by a PLC: set says so and what to type, and claims nothing.
    with socket.create_connection(("127.0.0.1", port), timeout=2) as plc:
        for addr, value in ((1003, 300), (1000, 1), (1000, 0)):  # watchdog 0.3 s, enable, release
            plc.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, addr, value))
            plc.recv(64)
            time.sleep(0.6 if addr == 1000 and value == 1 else 0.05)
        plc.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, 1003, 0))
        plc.recv(64)
    check(read_regs(port, 4, 11, 3)[::2] == [3, 3], f"a watchdog fault latched (raw {read_regs(port, 4, 11, 3)})")
    t0 = time.time()
    rc, out, err = run(MAGLEAD, "set", *conn, "force", "5", "--hold", "1s", "--config", CONFIG)
    check(rc == 4 and "alarm 3 watchdog" in err and "run 'maglead reset' first" in err and "holding" not in out
          and "not at 0 N" not in err and time.time() - t0 < 3 and one_line(err),
          f"set during a watchdog fault: rc {rc} {out.strip()} {err.strip()}")
    rc, out, err = run(MAGLEAD, "reset", *conn)
    check(rc == 0 and "fault reset done" in out and read_regs(port, 4, 11, 3)[::2] == [0, 1],
          f"reset clears the watchdog fault: {err.strip()}")
    owner_watchdog_fault(port, conn)
    rc, out, err = run(MAGLEAD, "disable", *conn)
    check(rc == 0 and read_regs(port, 4, 13, 1)[0] == 1, f"disable: drive ready {err.strip()}")
    rc, out, err = run(MAGLEAD, "reset", *conn)
    check(rc == 0 and "no fault to reset" in out, f"reset without a fault says so: {out.strip()} {err.strip()}")
    documented_minimums(port, conn)


def documented_minimums(port, conn):
    """docs/registers.md's lower limits are taken, by the tool and by the controller: 10 um/s
    (1e-05 m/s) and 0.0001 m/s^2. Before, the tool refused "1e-05 m/s is outside its range 1e-05 ..
    0.1 m/s", or passed it and the controller answered exception 03, blamed on the stroke."""
    for name, typed, addr, raw in (("velocity_limit_m_s", "10um/s", 1008, 10),
                                   ("velocity_limit_um_s", "10", 1008, 10),
                                   ("velocity_limit_m_s", "0.00001", 1008, 10),
                                   ("accel_limit_m_s2", "0.0001", 1010, 100)):
        run(MAGLEAD, "set", *conn, name, "1mm/s" if addr == 1008 else "1mm/s^2")
        rc, out, err = run(MAGLEAD, "set", *conn, name, typed)
        got = i32(read_regs(port, 3, addr, 2))
        check(rc == 0 and "written" in out and got == raw,
              f"set {name} {typed}: the documented minimum is written (raw {got}): {out.strip()} {err.strip()}")
    rc, out, err = run(MAGLEAD, "set", *conn, "position", "0.1mm", "--speed", "0.00001", "--accel", "0.0001",
                       "--no-wait", "--hold", "0.2s", "--config", CONFIG)
    staged = [i32(read_regs(port, 3, a, 2)) for a in (1006, 1008, 1010)]
    check(rc == 0 and "acknowledged" in out and "exception" not in err and staged == [100, 10, 100],
          f"set position 0.1mm at the minimum speed and acceleration (staged {staged}): {out.strip()} {err.strip()}")
    run(MAGLEAD, "set", *conn, "velocity_limit_m_s", "10mm/s")
    run(MAGLEAD, "set", *conn, "accel_limit_m_s2", "0.1")


def owner_watchdog_fault(port, conn):
    """A PLC that owns control lets its own watchdog expire: the advice names the owner (our
    reset is refused, exception 04), and the owner recovers as docs/plc.md says."""
    with socket.create_connection(("127.0.0.1", port), timeout=2) as plc:
        def fc6(addr, value):
            plc.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, addr, value))
            return plc.recv(64)
        fc6(1003, 300)  # watchdog 0.3 s
        fc6(1000, 1)    # enable: this connection owns control; no heartbeat follows
        end = time.time() + 3
        while time.time() < end and read_regs(port, 4, 11, 1)[0] != 3:
            time.sleep(0.05)
        w = read_regs(port, 4, 11, 3) + read_regs(port, 4, 17, 1)
        check(w[0] == 3 and w[2] == 3 and w[3] != 0, f"the owner's watchdog fault latched, it still owns control (raw {w})")
        for cmd in (["set", *conn, "force", "2", "--config", CONFIG], ["enable", *conn]):
            rc, out, err = run(MAGLEAD, *cmd)
            check(rc == 4 and "alarm 3 watchdog" in err and "another client owns control (the client at 127.0.0.1" in err
                  and "fault_reset edge" in err and "'maglead reset' works" in err
                  and "run 'maglead reset' first" not in err and one_line(err),
                  f"{cmd[0]} while a PLC owns control in fault: the owner must reset: {err.strip()}")
        rc, _, err = run(MAGLEAD, "reset", *conn)
        check(rc == 4 and "not_owner" in err, f"reset from another client is refused: {err.strip()}")
        # The owner: fault_reset edge (enable kept), heartbeats until reset done, watchdog off.
        fc6(1000, 1 + 4)
        fc6(1000, 1)
        end = time.time() + 3  # the last reset's done bit shows until the loop takes this edge
        while time.time() < end and not (read_regs(port, 4, 15, 1)[0] & (1 << 3) and read_regs(port, 4, 13, 1)[0] == 1):
            fc6(1002, 1)
            time.sleep(0.05)
        fc6(1003, 0)
        w = read_regs(port, 4, 11, 3)
        check(w[0] == 0 and w[2] == 1, f"the owner's fault reset: no alarm, drive ready, not enabled (raw {w})")
        fc6(1000, 0)  # a fresh enable edge
        fc6(1000, 1)
        time.sleep(0.1)
        check(read_regs(port, 4, 13, 1)[0] == 2, "the owner enables again with a fresh enable edge")
        fc6(1000, 0)  # release control: ready, no fault
    time.sleep(0.1)
    w = read_regs(port, 4, 11, 3)
    check(w[0] == 0 and w[2] == 1, f"the owner released control: no alarm, drive ready (raw {w})")


def watch_pty(conn, key, how):
    pid, fd = pty.fork()
    if pid == 0:
        os.execv(MAGLEAD, [MAGLEAD, "watch", *conn, "--rate", "10"])
    out = b""
    end = time.time() + 10
    while time.time() < end and out.count(b"maglead watch") < 3:
        if select.select([fd], [], [], 0.2)[0]:
            try:
                out += os.read(fd, 65536)
            except OSError:
                break
    if key:
        os.write(fd, key)
    else:
        os.kill(pid, signal.SIGINT)
    end = time.time() + 5
    status = None
    while time.time() < end:
        if select.select([fd], [], [], 0.1)[0]:
            try:
                out += os.read(fd, 65536)
            except OSError:
                pass
        done, st = os.waitpid(pid, os.WNOHANG)
        if done:
            status = st
            break
    if status is None:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    os.close(fd)
    text = out.decode(errors="replace")
    check(status is not None and os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, f"watch quits on {how}")
    check("\x1b[?1049h" in text and text.rfind("\x1b[?1049l") > text.rfind("\x1b[?1049h") and "\x1b[?25h" in text,
          f"watch ({how}) restores the screen and cursor")
    # The last command released control as it said: the drive is ready, no alarm.
    check(re.search(r"drive\s+ready\s+mode\s+idle", text) is not None and "alarm none" in text
          and "force [N]" in text and "* estimate" in text and "now" in text,
          f"watch ({how}) shows state and a trend")


def stroke_end_load():
    """A spring whose free length lies past the force mode's stroke window (39 mm): a force
    execute ends at the window's end (force_limited, force_reached_reason 7), and so does the
    release's 0 N. The release says what the controller said, never a timeout that did not
    happen, and watch names the reason beside force_limited."""
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--sim-spring-anchor", "0.0395", "--sim-start", "0.038")
    try:
        conn = ["--port", str(srv.port)]
        t0 = time.time()
        rc, out, err = run(MAGLEAD, "set", *conn, "force", "5", "--hold", "1s", "--config", CONFIG)
        took = time.time() - t0
        check(rc == 4 and "stroke_end" in err and "control released (force not brought to 0 N: the same reason; " in err
              and "within 5 s" not in err and "drive disabled without a fault" in err and one_line(err),
              f"set force 5 at the stroke end: the release's own reason ({took:.1f} s): {err.strip()}")
        # A PLC holds the force at the stroke end; watch shows why force_limited is set.
        with socket.create_connection(("127.0.0.1", srv.port), timeout=2) as plc:
            plc.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, 1000, 1))  # enable
            plc.recv(64)
            plc.sendall(struct.pack(">HHHBBHHBHH", 2, 0, 11, 1, 16, 1004, 2, 4, 0, 5000))  # force 5 N (5000 mN)
            plc.recv(64)
            for addr, value in ((1001, 2), (1000, 1 + 16), (1000, 1)):  # force mode, execute edge
                plc.sendall(struct.pack(">HHHBBHH", 3, 0, 6, 1, 6, addr, value))
                plc.recv(64)
            end = time.time() + 15
            while time.time() < end and not (read_regs(srv.port, 4, 10, 1)[0] & (1 << 15)):
                time.sleep(0.1)
            reason = read_regs(srv.port, 4, 66, 1)[0]
            rc, out, err = run(MAGLEAD, "watch", *conn, "--once")
            check(rc == 0 and reason == 7 and "force_limited(stroke_end)" in out,
                  f"watch names force_reached_reason beside force_limited (IR 66 = {reason}): {out.strip()} {err.strip()}")
            plc.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, 1000, 0))  # release control
            plc.recv(64)
    finally:
        srv.stop()


def step_out_advice():
    """After a step-out only a reset with a resync clears the fault (a plain one is refused,
    still_faulty): every piece of advice names 'maglead reset --resync'. Before, set said "run
    'maglead reset' first", and that reset answered still_faulty, exit 4."""
    # A spring pulling 60 N at start, beyond the coupling's peak: the nut slips leads at once.
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--sim-spring", "3000", "--sim-spring-anchor", "0.010",
                 "--sim-start", "0.030")
    try:
        conn = ["--port", str(srv.port)]
        end = time.time() + 5
        while time.time() < end and read_regs(srv.port, 4, 11, 1)[0] != 1:
            time.sleep(0.05)
        check(read_regs(srv.port, 4, 11, 3)[::2] == [1, 3], f"a step-out latched (raw {read_regs(srv.port, 4, 11, 3)})")
        for cmd in (["set", *conn, "force", "2", "--config", CONFIG], ["enable", *conn], ["reset", *conn]):
            rc, out, err = run(MAGLEAD, *cmd)
            check(rc == 4 and "alarm 1 step_out" in err and "run 'maglead reset --resync'" in err and one_line(err),
                  f"{' '.join(cmd[:1] + cmd[3:4])} after a step-out names the reset that works: {err.strip()}")
        rc, out, err = run(MAGLEAD, "disable", *conn)
        check(rc == 0 and "run 'maglead reset --resync' to clear it" in out, f"disable after a step-out: {out.strip()}")
        rc, out, err = run(MAGLEAD, "reset", *conn, "--resync")
        check(rc == 0 and "fault reset done" in out and read_regs(srv.port, 4, 11, 3)[::2] == [0, 1],
              f"reset --resync clears the step-out: {out.strip()} {err.strip()}")
    finally:
        srv.stop()


def stop_server_then_wait(srv, client):
    """Stops the controller under a running client, then waits for the client's (stdout, stderr)."""
    srv.stop()
    try:
        return client.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        client.kill()
        return client.communicate()


def dropped_connection():
    """The controller goes away during a recording: one line, exit 3, the rows so far kept."""
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    rec = os.path.join(WORK, "tcp_dropped.csv")
    with contextlib.suppress(FileNotFoundError):
        os.remove(rec)  # a rerun's old file would look like rows already on disk
    rec_proc = subprocess.Popen([MAGLEAD, "record", "--port", str(srv.port), "--duration", "20s", "--rate", "50",
                                 "--out", rec], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Drop the controller once rows are on disk (the recorder streams them), not after a fixed
    # time: under a sanitizer on a loaded machine the recorder takes a while to start.
    end = time.time() + 15
    while time.time() < end and rec_proc.poll() is None:
        with contextlib.suppress(FileNotFoundError), open(rec) as f:
            if sum(1 for l in f if l[:1].isdigit()) >= 25:
                break
        time.sleep(0.1)
    out, err = stop_server_then_wait(srv, rec_proc)
    rc = rec_proc.returncode
    # A row the loaded machine missed before the drop is filled and said in a warning line of
    # its own; the error is the one line besides it.
    error = "\n".join(l for l in err.splitlines() if not l.startswith("warning:"))
    check(rc == 3 and one_line(error) and ("dropped" in error or "connection" in error),
          f"record across a dropped connection: rc {rc}: {err.strip()[-300:]}")
    with open(rec) as f:
        rows = [l for l in f.read().splitlines() if l and not l.startswith("#")]
    check(len(rows) > 10, f"rows before the drop are kept ({len(rows) - 1})")

    # The controller goes away while set or enable holds control: what that means and what to type.
    for args, again in ((["set", "force", "10", "--config", CONFIG, "--hold", "30s"], "maglead set force 10"),
                        (["set", "position", "20mm", "--config", CONFIG, "--hold", "30s"], "maglead set position 20mm"),
                        (["enable", "--hold", "30s"], "maglead enable")):
        srv = Server(MAGLEAD, CONFIG, "--port", "0")
        holder = subprocess.Popen([MAGLEAD, args[0], "--port", str(srv.port), *args[1:]],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Stop the server once the tool says it holds (a loaded machine may take a while to get
        # there; stopped earlier, the tool is still commanding, not holding).
        said, end = "", time.time() + 20
        while time.time() < end and "holding" not in said:
            if select.select([holder.stdout], [], [], 0.1)[0]:
                line = holder.stdout.readline()
                if not line:
                    break
                said += line
        out, err = stop_server_then_wait(srv, holder)
        out = said + out
        check(holder.returncode == 3 and one_line(err) and "lost the controller while holding" in err
              and "control and the hold are lost" in err and "owner_lost" in err
              and f"then run '{again}' again" in err and ("dropped" in err or "no reply" in err),
              f"{args[0]} {args[1]}: the controller gone while holding: rc {holder.returncode} {err.strip()}")

    # watch when the controller goes away: it says "reconnecting" and keeps going; q still quits
    # cleanly (the full reconnect, in a real terminal, is tests/operator/watch_tmux.py).
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    pid, fd = pty.fork()
    if pid == 0:
        os.execv(MAGLEAD, [MAGLEAD, "watch", "--port", str(srv.port), "--rate", "10"])
    # Stop the server only once watch has drawn a connected screen: under a sanitizer on a loaded
    # machine it can take over a second to start, and a watch that never connected exits instead.
    out = b""
    end = time.time() + 15
    while time.time() < end and b"drive" not in out:
        out += read_pty(fd, 0.1)
    srv.stop()
    end = time.time() + 8
    while time.time() < end and b"RECONNECTING" not in out:
        out += read_pty(fd, 0.1)
    os.write(fd, b"q")
    status = None
    end = time.time() + 8
    while time.time() < end and status is None:
        out += read_pty(fd, 0.1)
        done, st = os.waitpid(pid, os.WNOHANG)
        status = st if done else None
    if status is None:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    out += read_pty(fd, 0.2)
    os.close(fd)
    text = out.decode(errors="replace")
    tail = text[text.rfind("\x1b[?1049l"):] if "\x1b[?1049l" in text else ""
    check("RECONNECTING" in text, "watch says it is reconnecting when the connection drops")
    check(status is not None and os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0,
          f"watch still quits on q while reconnecting ({status})")
    check("maglead watch:" in tail and tail.count("\n") <= 2, f"watch: screen restored, then one line: {tail.strip()!r}")


def run_pty(*args, columns=80, interrupt_when=None, terminate_when=None):
    """Runs maglead with stdout and stderr on a `columns`-wide pseudo-terminal; returns (exit code,
    output with the terminal's CR LF as LF). With `interrupt_when`, types Ctrl-C once that text
    has appeared (or that many seconds have passed): the terminal sends SIGINT and echoes "^C",
    as it does for a person. With `terminate_when` (text), sends SIGTERM once that text has
    appeared, as a service manager does: the terminal echoes nothing."""
    pid, fd = pty.fork()
    if pid == 0:
        fcntl.ioctl(1, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))
        os.execve(MAGLEAD, [MAGLEAD, *args], {k: v for k, v in os.environ.items() if k != "COLUMNS"})
    out, status, start = b"", None, time.time()
    end = start + 30
    while status is None and time.time() < end:
        out += read_pty(fd, 0.1)
        if isinstance(interrupt_when, float) and time.time() - start > interrupt_when:
            interrupt_when = b""  # seconds: then at once
        if isinstance(interrupt_when, bytes) and interrupt_when in out:
            os.write(fd, b"\x03")
            interrupt_when = None
        if terminate_when is not None and terminate_when in out:
            os.kill(pid, signal.SIGTERM)
            terminate_when = None
        done, st = os.waitpid(pid, os.WNOHANG)
        status = st if done else None
    if status is None:
        os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
    out += read_pty(fd, 0.1)
    os.close(fd)
    rc = os.WEXITSTATUS(status) if os.WIFEXITED(status) else -1
    return rc, out.decode(errors="replace").replace("\r\n", "\n")


def rendered(text):
    """The lines as a terminal leaves them: a line redrawn in place (CR, text, erase to its end)
    shows only what was drawn last."""
    return "\n".join(line.split("\r")[-1] for line in text.replace("\x1b[K", "").split("\n"))


def fits(text, columns):
    """Every line within `columns` characters."""
    return all(len(line) <= columns for line in text.splitlines())


def read_pty(fd, seconds):
    out = b""
    end = time.time() + seconds
    while time.time() < end:
        if select.select([fd], [], [], 0.05)[0]:
            try:
                out += os.read(fd, 65536)
            except OSError:
                break
    return out


if __name__ == "__main__":
    main()
