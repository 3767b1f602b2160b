"""`maglead simulate --controller maglead --scenario force-holds` records maglead's own force loop
(issue 44): the load within 1.0 N of each setpoint over the last 0.5 s of each 2.5 s hold. The
same scenario open loop (the paper's inverse) misses by several newtons, which shows the check
can fail. The load cell is read here for checking only.
Usage: simulate_controller.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import csv
import os
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "controller"))
from modbus_common import check, finish, watchdog  # noqa: E402

MAGLEAD, CONFIG, WORK = (os.path.abspath(a) for a in sys.argv[1:4])
HOLD_S, WINDOW_S, TOLERANCE_N = 2.5, 0.5, 1.0


def hold_errors(path):
    """(setpoint, mean output force at the load over the hold's last WINDOW_S) per whole hold."""
    with open(path) as f:
        rows = list(csv.DictReader(l for l in f if not l.startswith("#")))
    t = [float(r["t_s"]) for r in rows]
    out = []
    k = 1
    while k * HOLD_S <= t[-1]:
        idx = [i for i, x in enumerate(t) if k * HOLD_S - WINDOW_S <= x < k * HOLD_S - 1e-6]
        setpoint = float(rows[idx[0]]["force_set_n"])
        load = sum(-float(rows[i]["load_force_n"]) for i in idx) / len(idx)  # output = -load cell
        out.append((setpoint, load))
        k += 1
    return out


def simulate(controller):
    path = os.path.join(WORK, f"holds_{controller}.csv")
    p = subprocess.run([MAGLEAD, "simulate", "--scenario", "force-holds", "--duration", "35s", "--seed", "1",
                        "--controller", controller, "--config", CONFIG, "--out", path],
                       capture_output=True, text=True, timeout=120)
    check(p.returncode == 0, f"simulate --controller {controller}: {p.stderr.strip()}")
    return hold_errors(path)


def main():
    watchdog(120)
    os.makedirs(WORK, exist_ok=True)
    ours = simulate("maglead")
    for setpoint, load in ours:
        check(abs(load - setpoint) <= TOLERANCE_N, f"maglead's loop: setpoint {setpoint:+.1f} N, load {load:+.2f} N")
    open_loop = simulate("open-loop")
    worst = max(abs(load - setpoint) for setpoint, load in open_loop)
    check(worst > TOLERANCE_N, f"open loop misses by up to {worst:.2f} N (the check can fail)")
    p = subprocess.run([MAGLEAD, "simulate", "--scenario", "hand-push", "--controller", "maglead", "--out",
                        os.path.join(WORK, "x.csv"), "--config", CONFIG], capture_output=True, text=True)
    check(p.returncode == 2 and "force-holds" in p.stderr, f"other scenarios say they run open loop: {p.stderr.strip()}")
    finish()


if __name__ == "__main__":
    main()
