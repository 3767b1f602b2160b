"""The operator commands over Modbus RTU: `maglead serve` on one end of a socat pty pair (8E1,
unit 3), poll / enable / set / record / disable on the other, a wrong unit id answered by silence.
Usage: operator_rtu.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import json
import os
import sys
import time

from op_common import check, finish, one_line, rtu_server, run, watchdog

MAGLEAD, CONFIG, WORK = sys.argv[1], sys.argv[2], sys.argv[3]
UNIT = 3


def main():
    watchdog(85)
    os.makedirs(WORK, exist_ok=True)
    with rtu_server(MAGLEAD, CONFIG, UNIT, "maglead-op-rtu-") as (_, dev_b):
        scenario(dev_b)
    finish()


def scenario(dev):
    line = ["--serial", dev, "--baud", "19200", "--parity", "E", "--unit", str(UNIT)]
    rc, out, err = run(MAGLEAD, "poll", *line, "--json")
    j = json.loads(out) if rc == 0 else {}
    check(rc == 0 and j.get("drive_state") == "ready", f"poll over RTU: {err.strip()}")
    check(abs(j.get("values", {}).get("nut_pos_m", 0) - 0.02) < 1e-3, "position about 20 mm over RTU")
    check(j.get("values", {}).get("control_owner") == 0, "nobody owns control")

    rc, _, err = run(MAGLEAD, "set", *line, "force", "-60", "--config", CONFIG)
    check(rc == 2 and "safe limit" in err and one_line(err), f"set force -60 refused locally: {err.strip()}")
    rc, out, err = run(MAGLEAD, "enable", *line, "--hold", "0.2s")
    check(rc == 0 and "released" in out, f"enable over RTU: {out.strip()} {err.strip()}")
    # set holds control while it runs (the serial line is this client's meanwhile), then
    # releases it: over RTU too the drive is disabled without a fault.
    rc, out, err = run(MAGLEAD, "set", *line, "force", "-8", "--config", CONFIG, "--hold", "1s")
    check(rc == 0 and "done" in out and "released" in out, f"set force -8 over RTU: {out.strip()} {err.strip()}")
    # poll shows SI values under SI names (register names work in --names too).
    rc, out, err = run(MAGLEAD, "poll", *line, "--json", "--names", "active_mode,active_force_setpoint_n,"
                       "status_word,drive_state,alarm_code")
    v = json.loads(out)["values"] if rc == 0 else {}
    check(v.get("drive_state") == 1 and v.get("alarm_code") == 0, f"released over RTU: ready, no alarm: {v}")

    rec = os.path.join(WORK, "rtu_rec.csv")
    rc, out, err = run(MAGLEAD, "record", *line, "--duration", "1s", "--rate", "20", "--out", rec)
    check(rc == 0 and "dropped polls:" in out, f"record over RTU: {out.strip()}")
    with open(rec) as f:
        rows = [l for l in f.read().splitlines() if l and not l.startswith("#")]
    check(15 <= len(rows) - 1 <= 22, f"about 20 rows at 20 Hz ({len(rows) - 1})")

    t0 = time.time()
    rc, _, err = run(MAGLEAD, "poll", "--serial", dev, "--unit", str(UNIT + 1), "--timeout", "0.5")
    check(rc == 3 and f"no reply from unit {UNIT + 1}" in err and one_line(err) and time.time() - t0 < 5,
          f"wrong unit over RTU: {err.strip()}")
    rc, _, err = run(MAGLEAD, "poll", "--serial", os.path.join(os.path.dirname(dev), "nonexistent"))
    check(rc == 3 and "cannot open serial line" in err and one_line(err), f"missing device: {err.strip()}")

    rc, out, err = run(MAGLEAD, "disable", *line)
    check(rc == 0, f"disable over RTU: {err.strip()}")


if __name__ == "__main__":
    main()
