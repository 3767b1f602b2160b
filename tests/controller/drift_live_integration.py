"""The drift flag live (issue 23): two `maglead serve` at once, one whose simulated coupling loses
5 %/min (--sim-effect gain_drift=-0.05), one without the effect. A PLC-style client per server
(pymodbus, the registers a PLC would use) makes ordinary position moves at 5, 20 and 50 mm/s and
a reference move (mode_command 3) every 20 s, polling the block FC4 0+94 between commands.
Asserts: with the effect the drift flag (discrete input 7 in status_word, reason IR 56) rises
within 30 s of the coupling crossing a 3 % change; without it the flag never rises. The crossing
is counted from the start of the run (gain 1), the strictest reading: the flag can only compare
with its reference, formed a little later. No load cell is read (there is none to read: the
plant is free and nothing here looks at IR 30).
Usage: drift_live_integration.py MAGLEAD_BIN CONFIG_DIR [GAIN_PER_MIN RUN_S [force]] (defaults
-0.05 95). GAIN_PER_MIN may instead be friction_drift=N_PER_MIN: the friction rises (the flag is
due within 30 s of a 1 N rise, with reason 3 or 5). With "force" the PLC runs force mode against the default simulated spring instead
(the issue's setpoints, 2.5 s each, no reference moves; docs/drift.md, "Live force control"): there the
flag is asserted within the run, not within 30 s of the crossing (measured 23-39 s after it);
ctest runs it by hand only (drift_live_force_control, label manual: 150 s)."""
import os
import sys
import threading
import time

from modbus_common import Server, check, f32_words, finish, watchdog, words_f32
from pymodbus.client import ModbusTcpClient

MAGLEAD, CONFIG = sys.argv[1], sys.argv[2]
UNIT = 1
CW, MODE, POS_F32, VEL_F32, ACC_F32 = 1000, 1001, 1014, 1016, 1018
ENABLE, EXECUTE = 1, 16
MODE_POSITION, MODE_REFERENCE = 1, 3
EXECUTE_DONE = 1 << 1  # command_status bit 1
ST_FAULT, ST_DRIFT = 1 << 2, 1 << 7
DRIFT = sys.argv[3] if len(sys.argv) > 3 else "-0.05"
FRICTION = DRIFT.startswith("friction_drift=")
if FRICTION:  # the friction F_c + r·t/60: the 1 N
    FRICTION_PER_MIN = float(DRIFT.split("=", 1)[1])
    EFFECT, LABEL = DRIFT, f"friction_drift {FRICTION_PER_MIN:+g} N/min"
    CROSS_S, CHANGE, REASONS = 1.0 / FRICTION_PER_MIN * 60.0, "1 N", (3, 5)
else:  # the coupling 3 % below its start (36 s at -5 %/min)
    GAIN_PER_MIN = float(DRIFT)
    EFFECT, LABEL = f"gain_drift={GAIN_PER_MIN}", f"gain_drift {100 * GAIN_PER_MIN:+.0f} %/min"
    CROSS_S, CHANGE, REASONS = 0.03 / -GAIN_PER_MIN * 60.0, "3 %", (1, 5)
# Wall time per server; the control is judged over all of it.
RUN_S = float(sys.argv[4]) if len(sys.argv) > 4 else 95.0
FORCE_CONTROL = len(sys.argv) > 5 and sys.argv[5] == "force"
# In force control the flag comes 23-39 s after the crossing (four runs: docs/drift.md, "Live force
# control"): within the run is asserted, the 30 s aim is printed, not asserted.
DEADLINE_S = RUN_S if FORCE_CONTROL else CROSS_S + 30.0
DEADLINE_TEXT = "within the run" if FORCE_CONTROL else f"30 s after the {CHANGE} crossing"
MODE_FORCE, FORCE_F32 = 2, 1012
FORCE_STEPS_N = [5.0, 10.0, 15.0, 20.0, -5.0, -10.0, -15.0, 12.0, 8.0, 3.0, 0.0, 18.0, 6.0]
REFERENCE_EVERY_S = 20.0
# Ordinary moves a PLC might make: targets across the stroke (config: 0 .. 40 mm) at three speeds.
MOVES = [(0.008, 0.005), (0.032, 0.020), (0.012, 0.050), (0.030, 0.005), (0.006, 0.050),
         (0.026, 0.020)]


class Plc:
    """One PLC on one connection: commands, and the poll block between them."""

    def __init__(self, name, port, t0):
        self.name, self.t0 = name, t0
        self.c = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
        self.samples = []  # (t since the server started, status, reason, regs 76..93)
        self.errors = []

    def now(self):
        return time.time() - self.t0

    def poll(self):
        rr = self.c.read_input_registers(0, 94, slave=UNIT)
        if rr.isError():
            self.errors.append(f"poll at {self.now():.1f} s: {rr}")
            return None
        r = rr.registers
        self.samples.append((self.now(), r[10], r[56], r[76:94]))
        return r

    def execute(self, mode, timeout_s=15.0):
        """Stages the mode and gives an execute edge; polls until the drive reports it done."""
        self.c.write_register(MODE, mode, slave=UNIT)
        self.c.write_register(CW, ENABLE | EXECUTE, slave=UNIT)
        self.c.write_register(CW, ENABLE, slave=UNIT)
        end = time.time() + timeout_s
        while time.time() < end:
            time.sleep(0.05)
            r = self.poll()
            if r is not None and r[15] & EXECUTE_DONE:
                return True
        self.errors.append(f"mode {mode} not done within {timeout_s} s at {self.now():.1f} s")
        return False

    def run(self):
        try:
            self._run()
        except Exception as e:  # reported as a failed check, not a silent thread death
            self.errors.append(f"client raised {e!r}")

    def _run(self):
        if not self.c.connect():
            self.errors.append("no connection")
            return
        while self.now() < 3.0:  # the drive synchronises, then is ready
            r = self.poll()
            if r is not None and r[13] == 1:
                break
            time.sleep(0.05)
        self.c.write_register(CW, ENABLE, slave=UNIT)
        self.c.write_registers(ACC_F32, f32_words(0.5), slave=UNIT)
        if FORCE_CONTROL:
            self._force_steps()
            self.c.close()
            return
        next_reference, i = 2.0, 0
        while self.now() < RUN_S:
            if self.now() >= next_reference:
                self.execute(MODE_REFERENCE)
                next_reference += REFERENCE_EVERY_S
                continue
            target, speed = MOVES[i % len(MOVES)]
            i += 1
            self.c.write_registers(POS_F32, f32_words(target), slave=UNIT)
            self.c.write_registers(VEL_F32, f32_words(speed), slave=UNIT)
            self.execute(MODE_POSITION)
            for _ in range(4):  # a short dwell at the target, still polling
                time.sleep(0.05)
                self.poll()
        self.c.close()

    def _force_steps(self):
        """Force mode against the spring: each setpoint held 2.5 s, polling."""
        i = 0
        while self.now() < RUN_S:
            self.c.write_registers(FORCE_F32, f32_words(FORCE_STEPS_N[i % len(FORCE_STEPS_N)]),
                                   slave=UNIT)
            i += 1
            self.execute(MODE_FORCE)
            end = time.time() + 2.5
            while time.time() < end:
                time.sleep(0.05)
                self.poll()

    def first_flag(self):
        return next((s for s in self.samples if s[1] & ST_DRIFT), None)


def figures(regs):
    """IR 76..93: observability, separable, then float32 pairs from 78."""
    f = lambda a: words_f32(regs[a - 76:a - 74])
    rated = (f"{f(82):+.2f} ± {f(84):.2f} N" if regs[1] else f"{f(82):+.2f} N (worst case: all gain)")
    return (f"observability {regs[0]}, separable {regs[1]}, error {f(78):+.2f} ± {f(80):.2f} N at "
            f"zero load, {rated} at the rated force, statistic {f(92):.2f}, {f(90):.1f} s of free "
            "moves")


def max_statistic(plc):
    return max((words_f32(s[3][16:18]) for s in plc.samples), default=0.0)


def write_trace(path, plcs):
    """The drift registers of every poll, for a look at the statistic over a run."""
    with open(path, "w") as out:
        out.write("plc,t_s,status,reason,observability,zero_load_n,zero_load_se_n,known_s,statistic\n")
        for p in plcs:
            for t, status, reason, regs in p.samples:
                f = lambda a: words_f32(regs[a - 76:a - 74])
                out.write(f"{p.name},{t:.3f},{status},{reason},{regs[0]},{f(78):.5f},{f(80):.5f},"
                          f"{f(90):.2f},{f(92):.4f}\n")


def main():
    watchdog(int(RUN_S) + 75)
    duration = f"{RUN_S + 10:.0f}s"
    t0 = time.time()  # before the loop starts: plant times below are upper bounds (strict)
    load = [] if FORCE_CONTROL else ["--sim-spring", "0"]  # force control presses the spring
    drift = Server(MAGLEAD, CONFIG, "--port", "0", *load, "--sim-effect", EFFECT,
                   duration=duration)
    control = Server(MAGLEAD, CONFIG, "--port", "0", *load, duration=duration)
    plcs = [Plc(LABEL, drift.port, t0), Plc("control", control.port, t0)]
    threads = [threading.Thread(target=p.run) for p in plcs]
    try:
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    finally:
        drift.stop()
        control.stop()
    if os.environ.get("MAGLEAD_DRIFT_TRACE"):
        write_trace(os.environ["MAGLEAD_DRIFT_TRACE"], plcs)
    for p in plcs:
        check(not p.errors, f"{p.name}: the PLC's commands and polls went through {p.errors[:3]}")
        check(len(p.samples) > 500 and p.samples[-1][0] >= RUN_S - 1,
              f"{p.name}: polled to the end ({len(p.samples)} polls, last at "
              f"{p.samples[-1][0] if p.samples else 0:.1f} s)")
        check(not any(s[1] & ST_FAULT for s in p.samples), f"{p.name}: no fault")
        last = p.samples[-1]
        print(f"{p.name}: at {last[0]:.1f} s {figures(last[3])}", flush=True)
    drifting, clean = plcs
    flag = drifting.first_flag()
    if flag:
        print(f"{drifting.name}: {CHANGE} crossed at {CROSS_S:.1f} s, flagged at {flag[0]:.1f} s "
              f"({flag[0] - CROSS_S:+.1f} s), reason {flag[2]}; {figures(flag[3])}", flush=True)
    check(flag is not None and flag[0] <= DEADLINE_S,
          f"{drifting.name}: flagged by {DEADLINE_S:.0f} s ({DEADLINE_TEXT})")
    named = "friction rose (3)" if FRICTION else "coupling fell (1)"
    check(flag is not None and flag[2] in REASONS, f"the reason says the {named} or the error "
          f"rose, not separable (5): {flag[2] if flag else None}")
    print(f"{clean.name}: drift statistic at most {max_statistic(clean):.2f} (1 or more for 2 s "
          "raises the flag)", flush=True)
    check(clean.first_flag() is None, f"{clean.name}: never flagged ({clean.first_flag()})")
    check(clean.samples[-1][3][0] == 2,
          f"{clean.name}: the flag really compared (observability 2 at the end)")
    finish()


if __name__ == "__main__":
    main()
