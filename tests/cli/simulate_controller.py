"""`maglead simulate --controller maglead --scenario force-holds` records maglead's own force loop
(issue 44): the load within 1.0 N of each setpoint over the last 0.5 s of each 2.5 s hold. The
same scenario open loop (the paper's inverse) misses by several newtons, which shows the check
can fail. `force-steps` with maglead's loop: over its steps and ramps (the first 65 % of the run)
the load follows the setpoint within 1.0 N mean absolute, where the open loop is several newtons
off; the sweep's last third (above 1.4 Hz) is beyond the loop's bandwidth, and the test prints
its error without judging it (docs/simulation.md says so). `position-moves` with maglead's
position loop: at the end of each move's 0.5 s pause the nut rests within 3 linear-encoder counts
of the target (the loop integrates only errors beyond 1.5 counts; a count more is the encoder's
own quantization, half a count the noise), where the open loop rests up to 10 counts off. The load
cell is read here for checking only.
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


def run_simulate(scenario, controller, duration):
    path = os.path.join(WORK, f"{scenario}_{controller}.csv")
    p = subprocess.run([MAGLEAD, "simulate", "--scenario", scenario, "--duration", duration, "--seed", "1",
                        "--controller", controller, "--config", CONFIG, "--out", path],
                       capture_output=True, text=True, timeout=120)
    check(p.returncode == 0, f"simulate --scenario {scenario} --controller {controller}: {p.stderr.strip()}")
    # Which controller ran is said in the printed line and in the recording's header: two runs
    # that differ only in --controller must not look alike.
    said = {"open-loop": "open-loop, the paper's inverse",
            "maglead": "maglead, its position loop" if scenario == "position-moves" else "maglead, its force loop"}
    with open(path) as f:
        header = [l.rstrip("\n") for l in f if l.startswith("#")]
    check(f"s of {scenario} (controller: {said[controller]})" in p.stdout
          and f"# controller: {said[controller]}" in header,
          f"simulate --controller {controller} says which ran: {p.stdout.strip()!r} {header!r}")
    return path


def simulate(controller):
    return hold_errors(run_simulate("force-holds", controller, "35s"))


def tracking_error(path, start, end):
    """Mean absolute output-force error [N] over the run's share [start, end) of its duration."""
    with open(path) as f:
        rows = list(csv.DictReader(l for l in f if not l.startswith("#")))
    span = float(rows[-1]["t_s"])
    errs = [abs(-float(r["load_force_n"]) - float(r["force_set_n"])) for r in rows
            if start * span <= float(r["t_s"]) < end * span]
    return sum(errs) / len(errs)


# The parts of force-steps docs/simulation.md's table names, as shares of the run's duration.
FORCE_STEPS_PARTS = {"steps": (0.0, 0.40), "ramps": (0.40, 0.65), "sweep ±20 N": (0.65, 0.65 + 0.35 / 3),
                     "sweep 0.8": (0.65 + 0.35 / 3, 0.65 + 0.70 / 3), "sweep 1.4": (0.65 + 0.70 / 3, 1.0)}


def documented_force_steps():
    """{part: (maglead's loop, open loop)} [N] from docs/simulation.md's force-steps table."""
    with open(os.path.join(CONFIG, "..", "docs", "simulation.md")) as f:
        rows = [l for l in f if l.startswith("| ") and " N | " in l]
    out = {}
    for part in FORCE_STEPS_PARTS:
        cells = [c.strip() for c in next(r for r in rows if r.startswith("| " + part)).split("|")[1:-1]]
        out[part] = tuple(float(c.split()[0]) for c in cells[1:3])
    return out


def check_force_steps():
    """The steps and ramps within TOLERANCE_N; the documented table is what this run measures."""
    ours, theirs = (run_simulate("force-steps", c, "60s") for c in ("maglead", "open-loop"))
    steps_ramps = tracking_error(ours, 0.0, 0.65)
    open_loop = tracking_error(theirs, 0.0, 0.65)
    check(steps_ramps <= TOLERANCE_N, f"force-steps with maglead's loop: steps and ramps {steps_ramps:.2f} N mean absolute")
    check(open_loop > TOLERANCE_N, f"force-steps open loop: steps and ramps {open_loop:.2f} N (the check can fail)")
    for part, (doc_ours, doc_theirs) in documented_force_steps().items():
        a, b = FORCE_STEPS_PARTS[part]
        got = (tracking_error(ours, a, b), tracking_error(theirs, a, b))
        # 0.02 N: the table's two decimals; 2 %: floating point that differs between builds
        check(all(abs(g - d) <= 0.02 + 0.02 * d for g, d in zip(got, (doc_ours, doc_theirs))),
              f"docs/simulation.md force-steps '{part}': {doc_ours:.2f} / {doc_theirs:.2f} N documented, "
              f"{got[0]:.2f} / {got[1]:.2f} N measured (maglead's loop / open loop)")


COUNT_M = 2.15986e-5  # the linear encoder's count (config/actuator.toml)
REST_TOLERANCE_M = 3 * COUNT_M


def rest_errors(path):
    """|nut - target| [m], mean over the last 0.1 s of each 0.5 s pause after a move."""
    with open(path) as f:
        rows = list(csv.DictReader(l for l in f if not l.startswith("#")))
    t = [float(r["t_s"]) for r in rows]
    target = [float(r["pos_set_m"]) for r in rows]
    pos = [float(r["nut_pos_m"]) for r in rows]
    moving = [False] + [abs(b - a) > 1e-12 for a, b in zip(target, target[1:])]
    out = []
    for i in range(1, len(t) - 501):
        if moving[i] and not moving[i + 1] and not any(moving[i + 1:i + 501]):
            window = range(i + 400, i + 500)
            out.append(sum(abs(pos[k] - target[k]) for k in window) / len(window))
    return out


def check_position_moves():
    ours, theirs = (rest_errors(run_simulate("position-moves", c, "40s")) for c in ("maglead", "open-loop"))
    check(len(ours) >= 10, f"position-moves: {len(ours)} moves ended in the run")
    worst = max(ours)
    check(worst <= REST_TOLERANCE_M,
          f"position-moves with maglead's loop: rests within {worst * 1e3:.4f} mm of each target "
          f"(tolerance {REST_TOLERANCE_M * 1e3:.3f} mm)")
    check(max(theirs) > REST_TOLERANCE_M, f"position-moves open loop rests up to {max(theirs) * 1e3:.4f} mm off "
          "(the check can fail)")


def main():
    watchdog(120)
    os.makedirs(WORK, exist_ok=True)
    ours = simulate("maglead")
    for setpoint, load in ours:
        check(abs(load - setpoint) <= TOLERANCE_N, f"maglead's loop: setpoint {setpoint:+.1f} N, load {load:+.2f} N")
    open_loop = simulate("open-loop")
    worst = max(abs(load - setpoint) for setpoint, load in open_loop)
    check(worst > TOLERANCE_N, f"open loop misses by up to {worst:.2f} N (the check can fail)")
    check_force_steps()
    check_position_moves()
    p = subprocess.run([MAGLEAD, "simulate", "--scenario", "hand-push", "--controller", "maglead", "--out",
                        os.path.join(WORK, "x.csv"), "--config", CONFIG], capture_output=True, text=True)
    check(p.returncode == 2 and "force-holds" in p.stderr and "position-moves" in p.stderr,
          f"other scenarios say they run open loop: {p.stderr.strip()}")
    finish()


if __name__ == "__main__":
    main()
