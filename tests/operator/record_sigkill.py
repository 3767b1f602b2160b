"""Issue 25: a recording survives its recorder being killed. `maglead record` runs against
`maglead serve` and is killed with SIGKILL at random moments, again and again; every file it
leaves must be read by `maglead analyze`'s reader (through `maglead inspect`, which reads with the
same read_recording) with at most one torn last line dropped, and its last row may be at most one
second (of the controller's own cycle counter) behind the controller at the moment of the kill.
Usage: record_sigkill.py MAGLEAD_BIN CONFIG_DIR WORK_DIR [KILLS]"""
import os
import random
import signal
import struct
import subprocess
import sys
import time

from op_common import Server, check, finish, read_regs, run, watchdog

MAGLEAD, CONFIG, WORK = sys.argv[1], sys.argv[2], sys.argv[3]
KILLS = int(sys.argv[4]) if len(sys.argv) > 4 else 20
LOOP_CYCLE_COUNT = 48  # input register (u32), docs/registers.md
MAX_LOST_S = 1.0       # the durability promise of `maglead record --help`


def controller_cycle(port):
    return struct.unpack(">I", struct.pack(">HH", *read_regs(port, 4, LOOP_CYCLE_COUNT, 2)))[0]


def rows_of(path):
    """Header names and data rows as the file holds them (the torn last line, if any, included)."""
    if not os.path.exists(path):
        return [], [], False
    with open(path, "rb") as f:
        lines = f.read().split(b"\n")
    body = [l for l in lines if l and not l.startswith(b"#")]
    if not body:
        return [], [], False
    return body[0].decode().split(","), body[1:], lines[-1] != b""


def one_kill(port, i, rng):
    path = os.path.join(WORK, f"killed_{i:02d}.csv")
    rate = rng.choice([50, 100, 200])
    if os.path.exists(path):
        os.remove(path)
    proc = subprocess.Popen([MAGLEAD, "record", "--port", str(port), "--duration", "30s", "--rate", str(rate),
                             "--load-cell", "yes", "--out", path],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    # The moment is random from the first row on (before it there is nothing to lose; a loaded
    # machine may take a second to start the program).
    deadline = time.time() + 20
    while time.time() < deadline and proc.poll() is None and len(rows_of(path)[1]) < 1:
        time.sleep(0.02)
    time.sleep(rng.uniform(0.0, 0.8))
    proc.send_signal(signal.SIGKILL)
    cycle_after_kill = controller_cycle(port)  # read after the kill: the loss is over-, never under-stated
    proc.wait()

    names, rows, torn = rows_of(path)
    rc, out, err = run(MAGLEAD, "inspect", "--recording", path, timeout=30)
    # A poll the recorder missed leaves a gap the reader fills, and says so: not a loss.
    warnings = [l for l in err.splitlines() if l.startswith("warning:") and "missing rows" not in l]
    first_line = (out.splitlines() or [""])[0]
    read_ok = rc == 0 and len(warnings) <= 1 and (not torn or len(warnings) == 1)
    # Killed after its first row: readers refuse one row for its length (not for damage).
    whole_rows = len(rows) - (1 if torn else 0)
    if whole_rows < 2 and rc == 2 and "need at least 2" in err:
        read_ok = True
    # A recorder the machine's load held up for longer than the reader fills leaves a gap it
    # refuses, saying where to split: a stall of the poller, not a row lost to the kill (the
    # rows written are compared below all the same).
    if rc == 2 and "that are filled in; analyse the rows before and after the gap" in err:
        print(f"note kill {i}: {err.strip()[-200:]}", flush=True)
        read_ok = True
    check(read_ok, f"kill {i}: {os.path.basename(path)} ({len(rows)} rows at {rate} Hz{', torn end' if torn else ''}) "
                   f"is read: rc {rc} {first_line} {err.strip()[-300:]}")
    whole = rows[:-1] if torn else rows
    if not read_ok or not whole:
        check(False, f"kill {i}: no whole row to compare")
        return 0
    last = dict(zip(names, whole[-1].decode().split(",")))
    loop_hz = 1000.0
    with open(path) as f:
        for line in f:
            if line.startswith("# controller_loop_rate_hz:"):
                loop_hz = float(line.split(":", 1)[1])
    lost_s = ((cycle_after_kill - int(float(last["loop_cycle_count"]))) % 2**32) / loop_hz
    check(lost_s <= MAX_LOST_S, f"kill {i}: last row {lost_s:.3f} s behind the controller at the kill "
                                f"(at most {MAX_LOST_S} s)")
    return lost_s


def main():
    watchdog(170)
    os.makedirs(WORK, exist_ok=True)
    seed = int(os.environ.get("MAGLEAD_KILL_SEED", time.time_ns() % 100000))
    print(f"seed {seed} (MAGLEAD_KILL_SEED to repeat)", flush=True)
    rng = random.Random(seed)
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    worst = 0.0
    try:
        check(srv.port is not None, f"serve listens on a free port {srv.port}")
        for i in range(KILLS):
            worst = max(worst, one_kill(srv.port, i, rng))
    finally:
        srv.stop()
    print(f"{KILLS} kills, worst loss {worst:.3f} s of controller time", flush=True)
    finish()


main()
