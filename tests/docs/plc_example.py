#!/usr/bin/env python3
"""Runs docs/plc.md's pymodbus example against a real controller, so the page cannot show a
program that no longer works (issue 42): takes the ```python block after
`<!-- tested: plc_pymodbus -->`, starts `maglead serve --port 0`, runs the block with Debian's
pymodbus (/usr/bin/python3) on the server's port in place of 1502, and checks that it does what
the page says: exit 0, prints `force_reached` with the load force within
force_reached_tolerance_n (config/actuator.toml) of the 10 N it sets, and leaves the drive ready
(drive_state 1) with no alarm, control released without a fault.

  tests/docs/plc_example.py build/bin/maglead config docs/plc.md"""
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

try:
    import tomllib
except ImportError:  # Python < 3.11
    import tomli as tomllib

MAGLEAD, CONFIG, PAGE = (os.path.abspath(a) for a in sys.argv[1:4])
PYTHON = "/usr/bin/python3"  # the page names Debian 12's python3-pymodbus
MARKER = "<!-- tested: plc_pymodbus -->"
SETPOINT_N = 10.0


def example():
    with open(PAGE, encoding="utf-8") as f:
        text = f.read()
    m = re.search(re.escape(MARKER) + r"\n```python\n(.*?)^```$", text, re.M | re.S)
    if not m:
        sys.exit(f"{PAGE}: no ```python block after {MARKER}")
    code = m.group(1)
    if code.count("port=1502") != 1 or f"f32_words({SETPOINT_N})" not in code:
        sys.exit(f"{PAGE}: the example should connect with port=1502 once and set f32_words({SETPOINT_N})")
    return code


def start_server():
    proc = subprocess.Popen([MAGLEAD, "serve", "--config", CONFIG, "--port", "0", "--duration", "50s"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    seen = []
    for _ in range(10):
        line = proc.stdout.readline()
        seen.append(line)
        m = re.search(r"Modbus TCP on [0-9.]+:(\d+)", line)
        if m:
            return proc, int(m.group(1))
    proc.kill()
    sys.exit("maglead serve did not start: " + "".join(seen) + proc.stdout.read())


def drive_state_and_alarm(port):
    """IR 13 (drive_state) and IR 11 (alarm_code), read with mbpoll."""
    p = subprocess.run(["mbpoll", "-0", "-1", "-t", "3", "-r", "10", "-c", "4", "127.0.0.1", "-p", str(port)],
                       capture_output=True, text=True, timeout=10)
    words = [int(x) for x in re.findall(r"^\[\d+\]:\s+(-?\d+)", p.stdout, re.M)]
    if len(words) != 4:
        sys.exit(f"mbpoll could not read IR 10..13: {p.stdout}{p.stderr}")
    return words[3], words[1]


def main():
    code = example()
    with open(os.path.join(CONFIG, "actuator.toml"), "rb") as f:
        tolerance = tomllib.load(f)["control"]["force_reached_tolerance_n"]
    proc, port = start_server()
    failures = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            script = os.path.join(tmp, "plc_pymodbus.py")
            with open(script, "w") as f:
                f.write(code.replace("port=1502", f"port={port}"))
            p = subprocess.run([PYTHON, script], capture_output=True, text=True, timeout=30)
        print(f"the example printed: {p.stdout.strip()}")
        if p.returncode != 0:
            failures.append(f"exit {p.returncode}: {p.stdout}{p.stderr}")
        m = re.fullmatch(r"(force_reached|not reached) (-?\d+\.\d+) N at the load", p.stdout.strip())
        if not m:
            failures.append(f"unexpected output: {p.stdout!r}")
        else:
            if m.group(1) != "force_reached":
                failures.append("force_reached was not set 2 s after the execute edge")
            if abs(float(m.group(2)) - SETPOINT_N) > tolerance:
                failures.append(f"load force {m.group(2)} N is not within {tolerance} N of {SETPOINT_N} N")
        end = time.time() + 5
        while True:
            state, alarm = drive_state_and_alarm(port)
            if (state, alarm) == (1, 0) or time.time() > end:
                break
            time.sleep(0.05)
        if (state, alarm) != (1, 0):
            failures.append(f"after the release drive_state is {state} and alarm {alarm}, not ready (1) and none (0)")
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            failures.append("maglead serve did not stop on SIGINT")
    for f in failures:
        print(f"FAIL: {f}")
    if not failures:
        print(f"{os.path.basename(PAGE)}: the pymodbus example reaches {SETPOINT_N} N and releases control without a fault")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
