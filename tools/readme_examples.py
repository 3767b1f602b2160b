#!/usr/bin/env python3
"""Generates the examples of README.md and docs/*.md that show what maglead prints, by running
them: starts a fresh `maglead serve --port 0` per example that needs a controller, runs the
example's commands (mbpoll, maglead set/disable/reset, ...) against it, and writes what they
printed into the page. Between `<!-- readme_examples: NAME -->` and `<!-- /readme_examples -->`
a page holds this script's output (NAME is a key of SCENARIOS), so it cannot go stale. The pair
may be indented (a block inside a list item); the block is written with the same indentation.

  tools/readme_examples.py build/bin/maglead config README.md [docs/operator.md ...]           # check (exit 1 on a difference)
  tools/readme_examples.py build/bin/maglead config README.md [docs/operator.md ...] --write   # regenerate

The commands are shown with port 1502 (the default) and run on the server's actual port; paths
into the checkout are shown as REPOSITORY. A figure that varies run to run (a measured time) is
not shown as a number: it is replaced by a letter the page explains, after a check that it is a
number in its plausible range."""
import difflib
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

MAGLEAD, CONFIG = (os.path.abspath(a) for a in sys.argv[1:3])
PAGES = [os.path.abspath(a) for a in sys.argv[3:] if a != "--write"]
WRITE = "--write" in sys.argv[3:]
REPOSITORY = os.path.dirname(CONFIG)  # serve prints CONFIG's path; pages show it as REPOSITORY/config
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the checkout of this script
HOST = "127.0.0.1"


class Server:
    def __init__(self):
        self.proc = subprocess.Popen([MAGLEAD, "serve", "--config", CONFIG, "--port", "0", "--duration", "60s"],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.port = None
        self.banner = []  # what serve printed up to and including its port line
        for _ in range(10):
            line = self.proc.stdout.readline()
            self.banner.append(line.rstrip("\n"))
            m = re.search(r"Modbus TCP on [0-9.]+:(\d+)", line)
            if m:
                self.port = int(m.group(1))
                break
        if self.port is None:
            raise RuntimeError("maglead serve did not start: " + "\n".join(self.banner) + self.proc.stdout.read())

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


def force(srv):
    """Control ends with the connection that claimed it, so one client claims and executes (here
    `maglead set`, in a PLC the same program) while mbpoll reads."""
    port = srv.port
    e = Example(port)
    setter = subprocess.Popen([MAGLEAD, "set", "force", "10", "--hold", "30s", "--config", CONFIG,
                               "--port", str(port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        e.lines.append(("build/bin/maglead set force 10 --hold 60s &",
                        "claims control, mode force + execute edge, keeps control"))
        e.wait_until("execute done and force reached", lambda w: w[5] & 2 and w[0] & 32)
        e.mbpoll("-0 -1 -t 3:float -B -r 128", "load observer's force at the load [N]: the "
                 "setpoint within force_reached_tolerance_n")
        w = e.mbpoll("-0 -1 -t 3 -r 10 -c 8", "")
        e.lines[-1] = (e.lines[-1][0], status_text([int(x) for x in w]))
    finally:
        setter.kill()
        setter.wait(10)
    return e.text()


def owner_loss(srv):
    """A one-shot client that enables: its connection closes, the drive faults (owner lost)."""
    e = Example(srv.port)
    e.mbpoll("-0 -1 -t 4 -r 1000", "enable, then this connection closes", 1)
    e.wait_until("the owner-loss fault", lambda w: w[3] == 3)
    w = e.mbpoll("-0 -1 -t 3 -r 10 -c 8", "")
    e.lines[-1] = (e.lines[-1][0], status_text([int(x) for x in w]))
    e.mbpoll("-0 -1 -t 4 -r 1000", "fault_reset (rising edge); nobody owns control", 4)
    e.wait_until("the reset", lambda w: w[3] == 1)
    w = e.mbpoll("-0 -1 -t 3 -r 10 -c 8", "")
    e.lines[-1] = (e.lines[-1][0], status_text([int(x) for x in w]))
    return e.text()


def maglead(args, srv=None, rc=0, config=False):
    """`$ build/bin/maglead ARGS` and what it printed (stdout and stderr as a terminal shows
    them), run with --config CONFIG if config and, against a controller, its --port."""
    extra = (["--config", CONFIG] if config else []) + (["--port", str(srv.port)] if srv else [])
    p = subprocess.run([MAGLEAD, *args.split(), *extra], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                       text=True, timeout=60)
    if p.returncode != rc:
        raise RuntimeError(f"maglead {args}: exit {p.returncode}, expected {rc}: {p.stdout}")
    return [f"$ build/bin/maglead {args}"] + p.stdout.rstrip("\n").split("\n")


def masked(lines, pattern, letter, low, high):
    """Replaces the measured figure of pattern's group 1 with letter, after checking it is a
    number in [low, high): it varies run to run, so the page names it instead of showing it."""
    out, seen = [], 0
    for line in lines:
        m = re.search(pattern, line)
        if m:
            value = float(m.group(1))
            if not low <= value < high:
                raise RuntimeError(f"{line!r}: {value} is outside [{low}, {high})")
            line, seen = line[:m.start(1)] + letter + line[m.end(1):], seen + 1
        out.append(line)
    if seen != 1:
        raise RuntimeError(f"expected one line matching {pattern!r}, found {seen}: {lines}")
    return out


def serve_startup(srv):
    """The lines of serve's start that name the configuration and the model it serves."""
    lines = [l for l in srv.banner if re.match(r"maglead serve: (configuration|model) from ", l)]
    if len(lines) != 2:
        raise RuntimeError(f"serve did not print its configuration and model: {srv.banner}")
    return "\n".join(l.replace(REPOSITORY, "REPOSITORY") for l in lines)


def set_force(srv):
    """set force: reached (T: the time it took), held for --hold (H: measured), released."""
    lines = maglead("set force 12 --hold 2s", srv, config=True)
    lines = masked(lines, r"done \(force reached\) after (\d+\.\d+) s$", "T", 0.0, 30.0)
    lines = masked(lines, r"^held for (\d+\.\d+) s;", "H", 2.0, 10.0)
    return "\n".join(lines)


def disable_in_fault(srv):
    """An owner-loss fault, then `maglead disable` (says what to type), reset, disable again."""
    e = Example(srv.port)
    e.mbpoll("-0 -1 -t 4 -r 1000", "a one-shot client enables and closes: owner_lost fault", 1)
    e.wait_until("the owner-loss fault", lambda w: w[3] == 3)
    lines = ["$ " + e.text()]
    for args in ("disable", "reset", "disable"):
        lines += maglead(args, srv)
    return "\n".join(lines)


def usage_error(srv):
    """A value out of range and a mistyped option: exit 2, one line, and what to type."""
    return "\n".join(maglead("poll --port 0", rc=2) + maglead("poll --prot 3", rc=2))


def recording_head(srv):
    """The header and first two rows of docs/recording-format.md's simulate command."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "hand.csv")
        subprocess.run([MAGLEAD, "simulate", "--scenario", "hand-push", "--seed", "1", "--out", out, "--config",
                        CONFIG], capture_output=True, text=True, check=True, timeout=60)
        with open(out) as f:
            lines = f.read().split("\n")
    header = next(i for i, l in enumerate(lines) if not l.startswith("#"))
    return "\n".join(lines[:header + 3])


# NAME: (function, whether it needs a fresh `maglead serve`)
SCENARIOS = {"force": (force, True), "owner_loss": (owner_loss, True), "serve_startup": (serve_startup, True),
             "set_force": (set_force, True), "disable_in_fault": (disable_in_fault, True),
             "usage_error": (usage_error, False), "recording_head": (recording_head, False)}
BLOCK = re.compile(r"^([ \t]*)<!-- readme_examples: (\w+) -->\n\1(```\w*)\n(.*?)^\1```\n\1<!-- /readme_examples -->$",
                   re.M | re.S)


def generate(name):
    run, needs_server = SCENARIOS[name]
    if not needs_server:
        return run(None)
    srv = Server()  # a fresh controller per example: each starts from power-up
    try:
        return run(srv)
    finally:
        srv.stop()


def check(page):
    """0 when the page's blocks are what this build prints (or were rewritten with --write)."""
    with open(page) as f:
        text = f.read()
    names = [m.group(2) for m in BLOCK.finditer(text)]
    if not names:
        print(f"{page}: no <!-- readme_examples: NAME --> blocks")
        return 1
    unknown = [n for n in names if n not in SCENARIOS]
    if unknown:
        print(f"{page}: unknown examples {', '.join(unknown)} (known: {', '.join(SCENARIOS)})")
        return 1
    generated = {name: generate(name) for name in dict.fromkeys(names)}

    def block(m):
        indent, name, fence = m.group(1), m.group(2), m.group(3)
        body = "".join((indent + l if l else l) + "\n" for l in generated[name].split("\n"))
        return (f"{indent}<!-- readme_examples: {name} -->\n{indent}{fence}\n{body}{indent}```\n"
                f"{indent}<!-- /readme_examples -->")

    new = BLOCK.sub(block, text)
    rel = os.path.relpath(page, ROOT)
    if new == text:
        print(f"{rel}: the examples match what this build prints ({', '.join(names)})")
        return 0
    if WRITE:
        with open(page, "w") as f:
            f.write(new)
        print(f"{rel}: examples regenerated ({', '.join(names)})")
        return 0
    sys.stdout.writelines(difflib.unified_diff(text.splitlines(True), new.splitlines(True), f"{rel} (committed)",
                                               f"{rel} (this build)"))
    print(f"\n{rel}'s examples differ from what this build prints: run tools/readme_examples.py "
          f"build/bin/maglead config {rel} --write")
    return 1


def main():
    if not PAGES:
        print(__doc__)
        return 2
    return max(check(page) for page in PAGES)


if __name__ == "__main__":
    sys.exit(main())
