"""twin_healthy (docs/twin.md) on moves against a stiff spring: maglead's position loop moving
the nut across the stroke against a 2000 N/m spring (`simulate --scenario position-moves
--controller maglead --effect spring=2000`), the plant equal to the model. The nut stick-slips
there, and when a stick ends is chaotic: the twin, equal to the plant, times it a few ms apart,
and a PLC alarming on the bit must not trip on every move: `twin-check` reads it healthy on
100 % of ticks. The same recording with an encoder that reads up to 5 counts off at random is
not healthy on 15 % of its ticks or more (about 20 % before the stick timing was allowed for:
the noise's reversals against the screw widen nothing), which shows the check can fail.
Usage: twin_health.py MAGLEAD_BIN CONFIG_DIR WORK_DIR"""
import os
import random
import re
import subprocess
import sys

MAGLEAD, CONFIG, WORK = (os.path.abspath(a) for a in sys.argv[1:4])
os.makedirs(WORK, exist_ok=True)
COUNT_M = 2.16e-5  # config/actuator.toml's linear count
failures = []


def healthy_pct(path):
    p = subprocess.run([MAGLEAD, "twin-check", "--recording", path, "--config", CONFIG],
                       capture_output=True, text=True, timeout=300)
    m = re.search(r"healthy ([0-9.]+) % of ticks", p.stdout)
    if p.returncode != 0 or not m:
        sys.exit(f"twin-check {path}: exit {p.returncode}: {p.stdout}{p.stderr}")
    return float(m.group(1))


clean = os.path.join(WORK, "moves_spring.csv")
subprocess.run([MAGLEAD, "simulate", "--scenario", "position-moves", "--controller", "maglead",
                "--effect", "spring=2000", "--duration", "60s", "--seed", "1", "--config", CONFIG,
                "--out", clean], check=True, capture_output=True, timeout=300)
pct = healthy_pct(clean)
print(f"moves against 2000 N/m, plant equal to the model: healthy {pct} % of ticks")
if pct < 100.0:
    failures.append(f"a plant equal to the model is healthy on {pct} % of ticks, not 100 %")

rng = random.Random(1)
noisy = os.path.join(WORK, "moves_spring_noisy_encoder.csv")
with open(clean) as src, open(noisy, "w") as dst:
    column = None
    for line in src:
        if line.startswith("#"):
            dst.write(line)
        elif column is None:
            column = line.rstrip("\n").split(",").index("nut_pos_m")
            dst.write(line)
        else:
            f = line.rstrip("\n").split(",")
            f[column] = repr(float(f[column]) + COUNT_M * rng.choice([-5, -4, 0, 0, 4, 5]))
            dst.write(",".join(f) + "\n")
pct_noisy = healthy_pct(noisy)
print(f"the same with an encoder up to 5 counts off: healthy {pct_noisy} % of ticks")
if pct_noisy > 85.0:
    failures.append(f"an encoder 5 counts off at random reads healthy on {pct_noisy} % of ticks")

for f in failures:
    print("FAIL:", f)
sys.exit(1 if failures else 0)
