#!/usr/bin/env python3
"""Generates the README's Modbus examples by running them: starts `maglead serve --port 0`, runs
the example's mbpoll commands against it, and writes what the controller answered (status word,
alarm, ...) into the README's comments. Between `<!-- readme_examples: NAME -->` and
`<!-- /readme_examples -->` the README holds this script's output, so it cannot go stale.

  tools/readme_examples.py build/bin/maglead config README.md           # check (exit 1 on a difference)
  tools/readme_examples.py build/bin/maglead config README.md --write   # regenerate

The commands are shown with port 1502 (the default) and run on the server's actual port."""
import difflib
import json
import os
import re
import signal
import subprocess
import sys
import time

MAGLEAD, CONFIG, README = (os.path.abspath(a) for a in sys.argv[1:4])
WRITE = "--write" in sys.argv[4:]
HOST = "127.0.0.1"


class Server:
    def __init__(self):
        self.proc = subprocess.Popen([MAGLEAD, "serve", "--config", CONFIG, "--port", "0", "--duration", "60s"],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.port = None
        for _ in range(10):
            line = self.proc.stdout.readline()
            m = re.search(r"Modbus TCP on [0-9.]+:(\d+)", line)
            if m:
                self.port = int(m.group(1))
                break
        if self.port is None:
            raise RuntimeError("maglead serve did not start: " + self.proc.stdout.read())

    def stop(self):
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(10)


def registers():
    out = subprocess.run([MAGLEAD, "registers", "--format", "json"], capture_output=True, text=True, check=True).stdout
    return json.loads(out)


REG = registers()
CODES = {k: {c["value"]: c["name"] for c in REG[k]} for k in ("alarm_codes", "drive_states", "modes", "reject_codes")}
STATUS_BITS = {r["address"]: r["name"] for r in REG["registers"] if r["table"] == "discrete_input"}


class Example:
    """Runs mbpoll commands and collects the README lines: the command as shown, and a comment."""

    def __init__(self, port):
        self.port = port
        self.lines = []

    def mbpoll(self, args, comment, value=None):
        shown = f"mbpoll {args} {HOST} -p 1502" + (f" {value}" if value is not None else "")
        run = ["mbpoll", *args.split(), HOST, "-p", str(self.port)] + ([str(value)] if value is not None else [])
        p = subprocess.run(run, capture_output=True, text=True, timeout=10)
        if p.returncode != 0:
            raise RuntimeError(f"{shown}: {p.stdout}{p.stderr}")
        self.lines.append((shown, comment))
        return [float(x) for x in re.findall(r"^\[\d+\]:\s+(-?[0-9.]+)", p.stdout, re.M)]

    def read_ir(self, start, count):
        """A raw read of input registers (not shown): waits on the controller's state."""
        p = subprocess.run(["mbpoll", "-0", "-1", "-t", "3", "-r", str(start), "-c", str(count), HOST, "-p",
                            str(self.port)], capture_output=True, text=True, timeout=10)
        return [int(x) for x in re.findall(r"^\[\d+\]:\s+(-?\d+)", p.stdout, re.M)]

    def wait_until(self, what, pred, seconds=10):
        """Polls IR 10..17 until pred holds and the status word has been the same for 10 reads,
        without twin_lagging: that bit says the machine is too busy for the twin this moment (a
        CI run's other servers on two cores held it up for seconds once), not what the example
        shows, so the README shows the word of a machine that keeps up."""
        lagging = 1 << next(a for a, n in STATUS_BITS.items() if n == "twin_lagging")
        end, same, last = time.time() + seconds, 0, None
        while time.time() < end:
            w = self.read_ir(10, 8)
            same = same + 1 if w == last else 0
            last = w
            if pred(w) and not w[0] & lagging and same >= 10:
                return w
            time.sleep(0.02)
        raise RuntimeError(f"timed out waiting for {what}: {last}")

    def text(self):
        width = max(len(c) for c, _ in self.lines) + 2
        return "\n".join(f"{c:<{width}}# {m}" for c, m in self.lines)


def status_text(words):
    sw, alarm = words[0], words[1]
    bits = [STATUS_BITS[b] for b in sorted(STATUS_BITS) if sw >> b & 1]
    return (f"status word {sw} = {' + '.join(bits) or 'no bits'}; alarm {alarm} ({CODES['alarm_codes'][alarm]}), "
            f"drive_state {words[3]} ({CODES['drive_states'][words[3]]})")


def force(port):
    """Control ends with the connection that claimed it, so one client claims and executes (here
    `maglead set`, in a PLC the same program) while mbpoll reads."""
    e = Example(port)
    setter = subprocess.Popen([MAGLEAD, "set", "force", "10", "--hold", "30s", "--config", CONFIG,
                               "--port", str(port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        e.lines.append(("build/bin/maglead set force 10 --hold 60s &",
                        "claims control, mode force + execute edge, keeps control"))
        e.wait_until("execute done and force reached", lambda w: w[5] & 2 and w[0] & 32)
        e.mbpoll("-0 -1 -t 3:float -B -r 108", "estimated output force [N]: the setpoint within "
                 "force_reached_tolerance_n")
        w = e.mbpoll("-0 -1 -t 3 -r 10 -c 8", "")
        e.lines[-1] = (e.lines[-1][0], status_text([int(x) for x in w]))
    finally:
        setter.kill()
        setter.wait(10)
    return e.text()


def owner_loss(port):
    """A one-shot client that enables: its connection closes, the drive faults (owner lost)."""
    e = Example(port)
    e.mbpoll("-0 -1 -t 4 -r 1000", "enable, then this connection closes", 1)
    e.wait_until("the owner-loss fault", lambda w: w[3] == 3)
    w = e.mbpoll("-0 -1 -t 3 -r 10 -c 8", "")
    e.lines[-1] = (e.lines[-1][0], status_text([int(x) for x in w]))
    e.mbpoll("-0 -1 -t 4 -r 1000", "fault_reset (rising edge); nobody owns control", 4)
    e.wait_until("the reset", lambda w: w[3] == 1)
    w = e.mbpoll("-0 -1 -t 3 -r 10 -c 8", "")
    e.lines[-1] = (e.lines[-1][0], status_text([int(x) for x in w]))
    return e.text()


SCENARIOS = {"force": force, "owner_loss": owner_loss}


def main():
    with open(README) as f:
        readme = f.read()
    pattern = re.compile(r"(<!-- readme_examples: (\w+) -->\n```sh\n)((?:(?!```).)*?)(```\n<!-- /readme_examples -->)",
                         re.S)
    names = [m.group(2) for m in pattern.finditer(readme)]
    if not names:
        print(f"{README}: no <!-- readme_examples: NAME --> blocks")
        return 1
    generated = {}
    for name in names:
        srv = Server()  # a fresh controller per example: each starts from power-up
        try:
            generated[name] = SCENARIOS[name](srv.port)
        finally:
            srv.stop()
    new = pattern.sub(lambda m: m.group(1) + generated[m.group(2)] + "\n" + m.group(4), readme)
    if new == readme:
        print(f"{README}: the examples match what this build prints ({', '.join(names)})")
        return 0
    if WRITE:
        with open(README, "w") as f:
            f.write(new)
        print(f"{README}: examples regenerated ({', '.join(names)})")
        return 0
    sys.stdout.writelines(difflib.unified_diff(readme.splitlines(True), new.splitlines(True), "README.md (committed)",
                                               "README.md (this build)"))
    print("\nThe README's examples differ from what this build prints: run tools/readme_examples.py "
          "build/bin/maglead config README.md --write")
    return 1


if __name__ == "__main__":
    sys.exit(main())
