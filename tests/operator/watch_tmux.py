"""`maglead watch` as a person sees it, in a real terminal: tmux at 80x24, then 60x20. The screen
must fit (nothing wraps or scrolls away), show the values the controller reports, and draw the
force trend (setpoint, estimate, load cell) against a time axis. When the server restarts the
screen says "reconnecting", then recovers. Without a terminal (a pipe, or --once) watch prints
plain lines with no escape codes, and also reconnects. On the CiA 402 backend (no load cell) the
load cell reads "none", and only the target that applies now is shown.
Usage: watch_tmux.py MAGLEAD_BIN CONFIG_DIR"""
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time

from op_common import Server, check, finish, run, watchdog

MAGLEAD, CONFIG = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
SOCKET = f"maglead_watch_test_{os.getpid()}"
SESSION = "watch"


def tmux(*args, check_rc=True):
    p = subprocess.run(["tmux", "-L", SOCKET, "-f", "/dev/null", *args], capture_output=True, text=True, timeout=10)
    if check_rc and p.returncode != 0:
        raise RuntimeError(f"tmux {' '.join(args)}: {p.stderr.strip()}")
    return p.stdout


def screen():
    """The pane as the person sees it: one string per terminal row."""
    return tmux("capture-pane", "-p", "-t", SESSION).split("\n")[:-1]


def wait_screen(pred, seconds=15):
    """Waits until pred(rows) holds (or gives up after `seconds`); returns the last rows seen."""
    end = time.time() + seconds
    rows = screen()
    while not pred(rows) and time.time() < end:
        time.sleep(0.1)
        rows = screen()
    return rows


def value_after(rows, label):
    for r in rows:
        m = re.search(re.escape(label) + r"\s+(-?[0-9.]+)", r)
        if m:
            return float(m.group(1))
    return float("nan")


def chart_rows(rows):
    return [r[8:] for r in rows if len(r) >= 8 and r[7] == "|"]


def fits(rows, width, height, what):
    text = "\n".join(rows)
    check(len(rows) <= height and all(len(r) <= width for r in rows),
          f"{what}: {len(rows)} rows, widest {max(len(r) for r in rows)} columns fit {width}x{height}")
    check(rows[0].startswith("maglead watch"), f"{what}: the title is on the first row (nothing scrolled): {rows[0]!r}")
    last = [r for r in rows if r.strip()][-1]
    check(last.rstrip().endswith("now") and re.search(r"-30s", last) is not None,
          f"{what}: the time axis (-30s .. now) is on the last row: {last!r}")
    check("* estimate" in text and "o load cell" in text and "- setpoint" in text, f"{what}: the trend's legend")
    check(len(chart_rows(rows)) >= 3, f"{what}: a chart of {len(chart_rows(rows))} rows")


def clean_up(holder, srv):
    """Whatever a check left: the tmux server, a `set` still holding, the controller."""
    tmux("kill-server", check_rc=False)
    if holder is not None and holder.poll() is None:
        holder.kill()
        holder.wait()
    srv.stop()


def main():
    watchdog(220)
    if shutil.which("tmux") is None:
        check(False, "tmux is installed (tools/setup.sh installs it)")
        finish()
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    port = srv.port
    conn = ["--port", str(port)]
    holder = None
    try:
        # The shell stays after watch: tmux discards what a process wrote if it exits before tmux
        # has read it (on a loaded machine, the restored screen and watch's closing line).
        tmux("new-session", "-d", "-s", SESSION, "-x", "80", "-y", "24",
             f"{shlex.quote(MAGLEAD)} watch --port {port} --rate 5; echo \"watch exited $?\"; sleep 60")
        tmux("set-option", "-t", SESSION, "remain-on-exit", "on")
        rows = wait_screen(lambda r: "now" in "\n".join(r) and "position" in "\n".join(r))
        fits(rows, 80, 24, "80x24")
        _, out, _ = run(MAGLEAD, "poll", *conn, "--json")
        poll = json.loads(out)["values"]
        pos_mm = value_after(rows, "position")
        check(abs(pos_mm - poll["nut_pos_m"] * 1e3) < 0.1,
              f"80x24: position {pos_mm} mm as poll reads {poll['nut_pos_m'] * 1e3:.3f} mm")
        check(re.search(r"drive ready\s+mode idle", "\n".join(rows)) is not None, "80x24: drive state spelled out")

        # Force control: the setpoint, the estimate and the load cell all appear in the trend.
        # Control ends with the command that claimed it (owner loss), so `set` holds it while the
        # screen is checked at 80x24 and at 60x20.
        holder = subprocess.Popen([MAGLEAD, "set", *conn, "force", "10", "--config", CONFIG, "--hold", "60s"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Where curves share a cell the chart shows '#': once the force is at the load, estimate,
        # load cell and setpoint lie on one row.
        plotted = lambda r, m: any(m in c or "#" in c for c in chart_rows(r))
        rows = wait_screen(lambda r: value_after(r, "setpoint") == 10.0 and "force_reached" in "\n".join(r) and
                           all(plotted(r, m) for m in "*o-"))
        text = "\n".join(rows)
        check(value_after(rows, "setpoint") == 10.0 and "drive enabled" in text and "force_reached" in text,
              "80x24: setpoint 10.00 N, drive enabled, force_reached shown")
        est = value_after(rows, "estimate")
        check(abs(est - 10.0) < 2.0, f"80x24: estimate {est} N near the setpoint")
        check(all(plotted(rows, m) for m in "*o-"),
              "80x24: the chart plots estimate (*), load cell (o) and setpoint (-), # where they meet")
        fits(rows, 80, 24, "80x24 in force control")
        # The twin's force and its position residual, labelled, in µm as serve writes µs.
        twin = re.search(r"twin\s+-?\d+\.\d\d N, residual -?\d+\.\d µm", text)
        check(twin is not None, f"80x24: the twin's residual labelled, in µm: {[r for r in rows if 'twin' in r]}")

        tmux("resize-window", "-t", SESSION, "-x", "60", "-y", "20")
        rows = wait_screen(lambda r: len(r) == 20 and r[0].startswith("maglead watch") and
                           [x for x in r if x.strip()][-1].rstrip().endswith("now"))
        fits(rows, 60, 20, "60x20")
        check(value_after(rows, "setpoint") == 10.0 and value_after(rows, "position") > 0,
              "60x20: the values are still there")
        check(holder.poll() is None, "set force 10 --hold 60s still holds control")
        bound = re.search(r"\[(-?\d+\.\d), (-?\d+\.\d)\]", "\n".join(rows))
        check(bound is not None, f"60x20: the estimate's bound keeps both ends: {[r for r in rows if 'est' in r]}")
        # The holder vanishes (killed, no release): its connection closes while it owns control,
        # so the drive faults with owner_lost.
        holder.kill()
        hout, herr = holder.communicate(timeout=10)
        check("force 10.000 N: done" in hout, f"set force 10 reached the force: {hout.strip()} {herr.strip()}")
        rows = wait_screen(lambda r: re.search(r"drive fault\s+mode", "\n".join(r)) is not None
                           and "owner_lost" in "\n".join(r))
        check(re.search(r"drive fault\s+mode", "\n".join(rows)) is not None and "owner_lost" in "\n".join(rows),
              f"60x20: the holder gone, the screen shows the owner_lost fault: {rows[:2]}")
        # The alarm's meaning is wrapped, never cut: it ends with what to do.
        alarm = " ".join(r.strip() for r in rows)
        check("then an enable edge" in alarm, f"60x20: the alarm text is whole: {rows[3:8]}")
        # The PLC's wording, and the tool's: what to type at this terminal.
        check("from a terminal: run 'maglead reset'" in alarm, f"60x20: the alarm says the tool's command: {rows[3:8]}")

        # The server restarts on the same port: "reconnecting", then back with fresh values.
        srv.stop()
        rows = wait_screen(lambda r: r[0].startswith("RECONNECTING"))
        check(rows[0].startswith("RECONNECTING to 127.0.0.1:" + str(port)), f"restart: the screen says so: {rows[0]!r}")
        check(re.search(r"127\.0\.0\.1:%d\b" % port, " ".join(rows[:3])) is not None,
              f"restart: the port is never cut: {rows[:3]}")
        fits_rows = len(rows) <= 20 and all(len(r) <= 60 for r in rows)
        check(fits_rows, "60x20 while reconnecting")
        srv = Server(MAGLEAD, CONFIG, "--port", str(port))
        rows = wait_screen(lambda r: r[0].startswith("maglead watch") and "connected" in r[0]
                           and "drive ready" in "\n".join(r))
        check(rows[0].startswith("maglead watch") and "drive ready" in "\n".join(rows),
              f"restart: recovered, the new controller's state shown: {rows[:2]}")
        tmux("resize-window", "-t", SESSION, "-x", "80", "-y", "24")  # room for the closing line
        tmux("send-keys", "-t", SESSION, "q")
        rows = wait_screen(lambda r: any("watch exited" in x for x in r))
        last = [x for x in rows if "maglead watch:" in x]
        check(bool(last) and "1 reconnect" in last[0], f"q quits, the screen is restored, one line: {last}")
        check(any(x.strip() == "watch exited 0" for x in rows), f"watch exits 0 on q: {[x for x in rows if 'watch exited' in x]}")
    finally:
        clean_up(holder, srv)
    plain()
    cia402()
    alarm_beside_a_rejection()
    finish()


def plain():
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    port = str(srv.port)
    try:
        rc, out, err = run(MAGLEAD, "watch", "--port", port, "--once")
        check(rc == 0 and out.count("\n") == 1 and "\x1b" not in out and "drive=ready" in out and "nut_pos_m=" in out,
              f"--once: one plain line: {out!r}")
        rc, out, err = run(MAGLEAD, "watch", "--port", port, "--count", "3", "--rate", "20")
        check(rc == 0 and out.count("\n") == 3 and "\x1b" not in out, f"stdout a pipe: plain lines: {out!r}")
        p = subprocess.Popen([MAGLEAD, "watch", "--port", port, "--rate", "10"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        lines = [p.stdout.readline() for _ in range(2)]
        srv.stop()
        seen = [""]
        while seen[-1] is not None and not any("reconnecting" in x for x in seen):
            seen.append(p.stdout.readline() or None)
        srv = Server(MAGLEAD, CONFIG, "--port", port)
        while seen[-1] is not None and not any("reconnected" in x for x in seen if x):
            seen.append(p.stdout.readline() or None)
        after = p.stdout.readline()
        p.terminate()
        p.wait(5)
        check(all("drive=" in x for x in lines), "pipe: lines before the drop")
        check(any(x and "reconnecting to" in x for x in seen) and any(x and "reconnected" in x for x in seen)
              and "drive=ready" in after, f"pipe: reconnecting, reconnected, then lines again: {seen[-2:]} {after!r}")
    finally:
        srv.stop()
    rc, out, err = run(MAGLEAD, "watch", "--port", port, "--once")
    check(rc == 3 and "connection refused" in err, f"--once without a controller: exit 3 ({err.strip()})")


def cia402():
    """On the CiA 402 backend, which has no load cell, watch says so rather than show 0 N; and it
    shows only the target that applies now: the controller keeps its last one through a mode
    change and a disable, which read as a target still held."""
    srv = Server(MAGLEAD, CONFIG, "--backend", "cia402", "--can", "sim", "--port", "0")
    conn = ["--port", str(srv.port)]
    holder = None

    def hold(*what):
        return subprocess.Popen([MAGLEAD, "set", *conn, *what, "--config", CONFIG, "--hold", "60s"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def release(p):
        p.send_signal(2)  # Ctrl-C: released cleanly, the drive disabled without a fault
        p.communicate(timeout=10)

    text = lambda r: "\n".join(r)
    try:
        rc, out, err = run(MAGLEAD, "watch", *conn, "--once")
        check(rc == 0 and "load_cell_force_n=none" in out and "active_force_setpoint_n=none" in out,
              f"cia402 --once: no load cell and no setpoint said so: {out.strip()} {err.strip()}")
        rc, out, err = run(MAGLEAD, "poll", *conn, "--json")
        check(rc == 0 and json.loads(out)["values"]["load_cell_force_n"] is None,
              f"cia402 poll --json: no load cell is null, not 0 N: {out[:200]} {err.strip()}")
        rc, out, err = run(MAGLEAD, "poll", *conn, "load_cell_force_n")
        check(rc == 0 and re.search(r"load_cell_force_n\s+none\s+no load cell on this backend", out) is not None,
              f"cia402 poll: the load cell is none: {out.strip()}")
        rec = os.path.join(os.environ.get("TMPDIR", "/tmp"), f"cia402_rec_{os.getpid()}.csv")
        rc, out, err = run(MAGLEAD, "record", *conn, "--duration", "0.5s", "--out", rec)
        with open(rec) as f:
            header = next(l for l in f if not l.startswith("#"))
        check(rc == 0 and "load_force_n" not in header, f"cia402 record: no load_force_n column: {header.strip()}")
        with open(rec) as f:
            meta = [l for l in f if l.startswith("#")]
        check(not any("load_force_sign" in l for l in meta), f"cia402 record: no load_force_sign line: {meta}")
        rc, out, err = run(MAGLEAD, "estimate", rec, "--config", CONFIG)
        check(rc == 2 and "maglead twin-check --recording" in err,
              f"estimate without a load cell says what judges it instead: {err.strip()}")
        rc, out, err = run(MAGLEAD, "record", *conn, "--duration", "0.5s", "--out", rec + ".yes", "--load-cell", "yes")
        check(rc == 2 and "no load cell" in err and not os.path.exists(rec + ".yes"),
              f"cia402 record --load-cell yes: refused, nothing written: {err.strip()}")
        os.remove(rec)
        tmux("new-session", "-d", "-s", SESSION, "-x", "80", "-y", "24",
             f"{shlex.quote(MAGLEAD)} watch {' '.join(conn)} --rate 5; sleep 60")
        rows = wait_screen(lambda r: "drive ready" in text(r) and "now" in text(r))
        check("load cell:  none on this backend" in text(rows) and "* estimate (no load cell) - setpoint" in text(rows)
              and not any("o" in c for c in chart_rows(rows)),
              f"cia402: the load cell is none, not 0 N, and not plotted: {rows[5:7]} {rows[9:10]}")
        at_rest = re.compile(r"setpoint\s+-\s+target\s+-\s*$", re.M)
        check(at_rest.search(text(rows)) is not None, f"cia402 at rest: no target, no setpoint: {rows[7:8]}")
        holder = hold("position", "22mm")
        rows = wait_screen(lambda r: re.search(r"target\s+22\.000 mm", text(r)) is not None)
        check(re.search(r"setpoint\s+-\s+target\s+22\.000 mm", text(rows)) is not None,
              f"cia402 in position mode: the target: {rows[7:8]}")
        release(holder)
        holder = hold("force", "5")
        rows = wait_screen(lambda r: re.search(r"setpoint\s+5\.00 N", text(r)) is not None)
        check(re.search(r"setpoint\s+5\.00 N\s+target\s+-\s*$", text(rows), re.M) is not None,
              f"cia402 in force mode: the setpoint, not the 22 mm target left from before: {rows[7:8]}")
        release(holder)
        rows = wait_screen(lambda r: "drive ready" in text(r) and at_rest.search(text(r)) is not None)
        check("drive ready" in text(rows) and at_rest.search(text(rows)) is not None,
              f"cia402 after the disable: neither the setpoint nor a target: {rows[1:2]} {rows[7:8]}")
    finally:
        clean_up(holder, srv)


def alarm_beside_a_rejection():
    """A fault's way out stays on screen when a command ran into it: after a step-out a plain
    reset is rejected (still_faulty); the screen shows the alarm with 'maglead reset --resync'
    and the rejection, both."""
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--sim-effect", "offset=55")  # steps out at once
    conn = ["--port", str(srv.port)]
    text = lambda r: "\n".join(r)
    try:
        for _ in range(50):  # the slip takes a few cycles to latch
            if "step_out" in run(MAGLEAD, "poll", *conn, "alarm_code")[1]:
                break
            time.sleep(0.1)
        rc, out, err = run(MAGLEAD, "reset", *conn)
        check(rc == 4 and "still_faulty" in err, f"a plain reset after a step-out is rejected: {rc} {err.strip()}")
        tmux("new-session", "-d", "-s", SESSION, "-x", "80", "-y", "24",
             f"{shlex.quote(MAGLEAD)} watch {' '.join(conn)} --rate 5; sleep 60")
        rows = wait_screen(lambda r: "drive fault" in text(r) and "rejected" in text(r))
        flat = " ".join(x.strip() for x in rows)
        check("maglead reset --resync" in flat and "last command rejected: still_faulty" in flat,
              f"the alarm's way out beside the rejection: {rows[:8]}")
        fits(rows, 80, 24, "80x24 with an alarm and a rejection")
    finally:
        clean_up(None, srv)


if __name__ == "__main__":
    main()
