"""The command line's conventions, as a user meets them: --version (and the same version in the
controller's FC43 device identification), unknown commands and options answered with the closest
match and the usage line, paths relative to the working directory, progress only on a terminal
and --quiet, errors in config and model files with FILE:LINE:COLUMN, poll's SI names and JSON
rounded to each register's resolution, and limit errors that say the value, the limit and where
the limit is set.
Usage: cli_conventions.py MAGLEAD_BIN CONFIG_DIR WORK_DIR VERSION"""
import fcntl
import json
import os
import pty
import re
import select
import shutil
import signal
import struct
import subprocess
import sys
import termios
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "controller"))
from modbus_common import Server, check, finish, raw_request, watchdog  # noqa: E402

MAGLEAD, CONFIG, WORK, VERSION = (os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]),
                                  os.path.abspath(sys.argv[3]), sys.argv[4])


def run(*args, cwd=None, env=None, timeout=120):
    p = subprocess.run([MAGLEAD, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd,
                       env=env)
    return p.returncode, p.stdout, p.stderr


def run_in_pty(*args, cwd=None, columns=None):
    """Runs maglead with stdout and stderr on a pseudo-terminal (`columns` wide if given);
    returns (exit code, output)."""
    pid, fd = pty.fork()
    if pid == 0:
        if cwd:
            os.chdir(cwd)
        if columns:
            fcntl.ioctl(1, termios.TIOCSWINSZ, struct.pack("HHHH", 24, columns, 0, 0))
        # COLUMNS would set --help's width (main.cpp): the terminal's is the one tried here.
        os.execve(MAGLEAD, [MAGLEAD, *args], {k: v for k, v in os.environ.items() if k != "COLUMNS"})
    out = b""
    while True:
        r, _, _ = select.select([fd], [], [], 60)
        if not r:
            break
        try:
            chunk = os.read(fd, 65536)
        except OSError:
            break
        if not chunk:
            break
        out += chunk
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    return os.WEXITSTATUS(status) if os.WIFEXITED(status) else -1, out.decode(errors="replace")


def listed_commands(*parent):
    """The commands `maglead [PARENT] --help` lists under Subcommands."""
    _, out, _ = run(*parent, "--help", env={k: v for k, v in os.environ.items() if k != "COLUMNS"})
    listed = out.split("Subcommands:\n", 1)[-1] if "Subcommands:" in out else ""
    return [m.group(1) for m in re.finditer(r"^  (\S+)  ", listed, re.M)]


def copy_config(name):
    d = os.path.join(WORK, name)
    shutil.rmtree(d, ignore_errors=True)
    shutil.copytree(CONFIG, d)
    return d


def main():
    watchdog(300)
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)
    version_and_usage()
    front_door()
    relative_paths_and_progress()
    file_errors()
    against_a_server()
    finish()


def version_and_usage():
    rc, out, err = run("--version")
    check(rc == 0 and out.strip() == f"maglead {VERSION}", f"--version prints the CMake project version: {out!r}")
    rc, out, err = run("pol")
    check(rc == 2 and "unknown command 'pol'" in err and "did you mean 'maglead poll'?" in err
          and "usage: maglead COMMAND [OPTIONS]" in err, f"unknown command: {err.strip()!r}")
    rc, out, err = run("moonwalk")
    check(rc == 2 and "unknown command 'moonwalk'" in err and "did you mean" not in err and "poll" in err,
          f"unknown command with nothing close lists the commands: {err.strip()!r}")
    rc, out, err = run("poll", "--prot", "1502")
    check(rc == 2 and "unknown option '--prot' for 'maglead poll'" in err and "did you mean '--port'?" in err
          and "usage: maglead poll [OPTIONS]" in err, f"unknown option: {err.strip()!r}")
    rc, out, err = run("bench", "modbsu")
    check(rc == 2 and "did you mean 'maglead bench modbus'?" in err, f"unknown subcommand of bench: {err.strip()!r}")
    rc, out, err = run("simulate", "--scenario", "hand-push", "--duraton", "1s", "--out", os.path.join(WORK, "x.csv"))
    check(rc == 2 and "did you mean '--duration'?" in err, f"option typo after valid ones: {err.strip()!r}")
    # Every command that writes a file or a folder takes -o for it, as most command-line tools do.
    for cmd in ("simulate", "analyze", "report", "estimate", "calibrate", "record", "bench analyze"):
        rc, out, err = run(*cmd.split(), "--help")
        check(rc == 0 and "-o,--out" in out, f"{cmd} takes -o for --out")
    rc, out, err = run("simulate", "--scenario", "hand-push", "--duration", "1s", "-o",
                       os.path.join(WORK, "short_o.csv"))
    check(rc == 0 and os.path.exists(os.path.join(WORK, "short_o.csv")), f"simulate -o FILE: {err.strip()!r}")
    # An effect's value may carry its own unit, as set's values do; another unit says which.
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "2s", "--effect", "offset=2N",
                     "-o", os.path.join(WORK, "unit_ok.csv"))
    check(rc == 0, f"simulate --effect offset=2N: {err.strip()!r}")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "2s", "--effect", "offset=2kN",
                     "-o", os.path.join(WORK, "unit_bad.csv"))
    check(rc == 2 and "offset is in N, e.g. offset=2" in err, f"simulate --effect offset=2kN: {err.strip()!r}")
    rc, _, err = run("record", "--rate", "5000", "--duration", "1s", "-o", os.path.join(WORK, "r5k.csv"))
    check(rc == 2 and "5000 Hz is outside 1 .. 1000 Hz" in err, f"record --rate 5000: {err.strip()!r}")
    rc, _, err = run("record", "--rate", "abc", "--duration", "1s", "-o", os.path.join(WORK, "rabc.csv"))
    check(rc == 2 and "'abc' is not a number" in err and "--rate 100" in err,
          f"record --rate abc: {err.strip()!r}")
    # An image name the plot cannot have is refused before anything is written.
    cal_out = os.path.join(WORK, "cal_gif.toml")
    rc, _, err = run("calibrate", "--recording", os.path.join(WORK, "nowhere.csv"), "--out", cal_out,
                     "--plot", os.path.join(WORK, "e.gif"))
    check(rc == 2 and "give the file a .png" in err and not os.path.exists(cal_out),
          f"calibrate --plot e.gif refused first, nothing written: {err.strip()!r}")
    # analyze on an 80-column terminal breaks its long lines at spaces, under their own text; into
    # a pipe every line stays whole (scripts read them).
    moved = os.path.join(WORK, "moved.csv")
    run("simulate", "--scenario", "position-moves", "--duration", "20s", "--effect", "viscous_friction=20",
        "-o", moved)
    rc, text = run_in_pty("analyze", "--recording", moved, "-o", os.path.join(WORK, "moved_out"),
                          "--no-twin-check", columns=80)
    lines = [l for l in text.replace("\r", "").split("\n") if l and "[#" not in l]
    finding = next((i for i, l in enumerate(lines) if l.startswith("1. viscous_friction")), None)
    check(rc == 0 and finding is not None and all(len(l) <= 80 for l in lines)
          and lines[finding + 1].startswith("     ") and not lines[finding + 1].startswith("      "),
          f"analyze wraps to 80 columns on a terminal: {lines[:8]!r}")
    # An error on an 80-column terminal wraps at spaces (the terminal would break words); into a
    # pipe it stays one line, as scripts match it.
    for args in (("set", "force", "5", "--port", "1"), ("analyze", "--recording", moved, "--config", "/nope")):
        rc, text = run_in_pty(*args, columns=80)
        lines = [l for l in text.replace("\r", "").split("\n") if l]
        _, _, piped = run(*args)
        check(rc in (2, 3) and len(lines) >= 2 and all(len(l) <= 80 for l in lines)
              and text.split() == piped.split(),
              f"{args[0]}'s error wraps at spaces on a terminal, one line in a pipe: {lines!r}")
    # Every command's --help (the commands as --help lists them, bench's too) on an 80-column
    # terminal, and into a pipe with COLUMNS=80: no line wider, no word broken in two. Without
    # COLUMNS a pipe (the man page) takes every line whole.
    commands = [[]] + [[c] for c in listed_commands()]
    commands += [["bench", c] for c in listed_commands("bench")]
    check(len(commands) > 15 and ["twin-check"] in commands and ["bench", "analyze"] in commands,
          f"--help lists the commands: {commands!r}")
    env80 = dict(os.environ, COLUMNS="80")
    unset = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    for cmd in commands:
        name = " ".join(["maglead", *cmd])
        _, piped, _ = run(*cmd, "--help", env=unset)
        rc, text = run_in_pty(*cmd, "--help", columns=80)
        rc2, columns80, _ = run(*cmd, "--help", env=env80)
        for how, out in (("on an 80-column terminal", text.replace("\r", "")), ("with COLUMNS=80", columns80)):
            lines = out.split("\n")
            wide = [l for l in lines if len(l) > 80]
            check(rc == 0 and rc2 == 0 and not wide and len(lines) > 5,
                  f"{name} --help fits 80 columns {how}: {wide[:2]!r}")
            check(out.split() == piped.split(), f"{name} --help {how} wraps only at spaces (the same words)")
    _, piped, _ = run("analyze", "--help", env=unset)
    check(any(len(l) > 80 for l in piped.split("\n")), "analyze --help into a pipe keeps its lines whole")
    # No configuration anywhere (an installed binary, no /etc/maglead): where it looked, what to type.
    if not os.path.exists("/etc/maglead/calibration.toml"):
        lone = os.path.join(WORK, "lone", "bin")
        os.makedirs(lone, exist_ok=True)
        shutil.copy(MAGLEAD, os.path.join(lone, "maglead"))
        env = {k: v for k, v in os.environ.items() if k != "MAGLEAD_CONFIG"}
        p = subprocess.run([os.path.join(lone, "maglead"), "simulate", "--scenario", "hand-push", "--duration", "1s",
                            "--out", os.path.join(WORK, "lone.csv")], capture_output=True, text=True, env=env)
        check(p.returncode == 2 and "no configuration directory found (looked in" in p.stderr
              and "--config DIR" in p.stderr and "MAGLEAD_CONFIG" in p.stderr,
              f"no configuration found says where it looked and what to type: {p.stderr.strip()!r}")
    # Angles logged in degrees: refused with the likely unit, not read as 57x the screw's turns.
    moves = os.path.join(WORK, "moves20.csv")
    run("simulate", "--scenario", "mixed-moves", "--duration", "20s", "-o", moves)
    with open(moves) as f:
        lines = f.read().splitlines()
    names = next(l for l in lines if not l.startswith("#")).split(",")
    angle = [i for i, n in enumerate(names) if n.endswith("_angle_rad")]
    deg = os.path.join(WORK, "degrees.csv")
    with open(deg, "w") as f:
        for l in lines:
            if l.startswith("#") or l.startswith("t_s"):
                f.write(l + "\n")
                continue
            v = l.split(",")
            for i in angle:
                v[i] = repr(float(v[i]) * 57.29577951308232)
            f.write(",".join(v) + "\n")
    for cmd in ("estimate", "analyze", "twin-check"):
        out = [] if cmd == "twin-check" else ["--out", os.path.join(WORK, "deg_" + cmd)]
        rc, _, err = run(cmd, "--recording", deg, *out)
        check(rc == 2 and "cannot be in radians" in err and "likely unit: degrees" in err,
              f"{cmd} refuses angles in degrees: {err.strip()[-200:]!r}")
    rc, _, err = run("twin-check", "--recording", moves)
    check(rc == 0, f"the same recording in radians is read: {err.strip()[-200:]!r}")
    # Writing over an earlier recording or result is said beside "wrote", never silent.
    again = os.path.join(WORK, "again.csv")
    outs = [run("simulate", "--scenario", "hand-push", "--duration", "1s", "-o", again)[1] for _ in range(2)]
    check("replacing" not in outs[0] and "wrote " + again + " (replacing the one there):" in outs[1],
          f"simulate over an earlier recording says so: {outs!r}")
    outs = [run("analyze", "--recording", again, "-o", os.path.join(WORK, "again_out"), "--no-twin-check")[1]
            for _ in range(2)]
    check("replacing" not in outs[0] and "(replacing the results there)" in outs[1],
          f"analyze over an earlier result says so: {[o.splitlines()[-1:] for o in outs]!r}")
    # serve's own lines on an 80-column terminal: wrapped under their text, the same words.
    rc, text = run_in_pty("serve", "--port", "0", "--duration", "1s", columns=80)
    lines = [l for l in text.replace("\r", "").split("\n") if l]
    wide = [l for l in lines if len(l) > 80]
    check(rc == 0 and not wide and any(l.startswith("maglead serve: configuration from") for l in lines)
          and all(l.startswith("maglead serve: ") or (l[:15].isspace() and l[15] != " ") for l in lines),
          f"serve's start-up lines fit 80 columns, wrapped under their text: {wide[:2]!r} {lines[:4]!r}")
    rc, out, _ = run("analyze", "--recording", moved, "-o", os.path.join(WORK, "moved_out2"), "--no-twin-check")
    check(rc == 0 and any(l.startswith("1. viscous_friction") and len(l) > 80 for l in out.splitlines()),
          "analyze into a pipe keeps each line whole")


def front_door():
    """A newcomer's first commands at an 80-column terminal."""
    unset = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    # `maglead help` and `maglead version` mean the flags; the command list wraps at spaces.
    for word, flag in (("help", "--help"), ("version", "--version")):
        rc, _, err = run(word)
        check(rc == 2 and f"unknown command '{word}'; did you mean 'maglead {flag}'?" in err,
              f"maglead {word} points to {flag}: {err.strip()!r}")
    rc, text = run_in_pty("help", columns=80)
    lines = [l for l in text.replace("\r", "").split("\n") if l]
    words = [w.strip(",") for w in text.split()]
    check(rc == 2 and all(len(l) <= 80 for l in lines) and "twin-check" in words and "analysis-rules" in words,
          f"maglead help on 80 columns: no line wider, no command broken: {lines!r}")
    # --help names a man page man can open: in a build tree, by its path (man maglead has none).
    repo = os.path.dirname(os.path.dirname(os.path.dirname(MAGLEAD)))
    page = os.path.join(os.path.dirname(os.path.dirname(MAGLEAD)), "man", "maglead.1.gz")
    _, out, _ = run("--help", cwd=repo, env=unset)
    m = re.search(r"See man (?:-l )?(\S+) for every command", out)
    if os.path.exists(page):
        shown = os.path.join(repo, m.group(1)) if m else ""
        check(os.path.exists(shown) and os.path.samefile(shown, page),
              f"--help names the build tree's man page by a path that opens it: {out[:300]!r}")
    else:
        check(m is None, f"no man page built: --help names none: {out[:300]!r}")
    # The top-level list: a line or two per command, details in `maglead COMMAND --help`.
    env80 = dict(os.environ, COLUMNS="80")
    _, out, _ = run("--help", env=env80)
    listed = [l for l in out.split("Subcommands:\n", 1)[-1].split("\n") if l]
    starts = [i for i, l in enumerate(listed) if not l.startswith(" " * 6)] + [len(listed)]
    entries = {listed[a].split()[0]: b - a for a, b in zip(starts, starts[1:])}
    check(len(out.split("\n")) <= 45 and "inspect" in entries and max(entries.values()) <= 2,
          f"maglead --help at 80 columns: {len(out.splitlines())} lines, entries {entries}")
    # serve --help: every continuation of an option's description under its description column.
    _, out, _ = run("serve", "--help", env=env80)
    lines = out.split("\n")
    unit = next(i for i, l in enumerate(lines) if l.lstrip().startswith("--unit "))
    watchdog_at = next(i for i, l in enumerate(lines) if l.lstrip().startswith("--watchdog "))
    indent = lambda l: len(l) - len(l.lstrip(" "))  # noqa: E731
    check(indent(lines[unit + 1]) == 32 and lines[unit].find("Unit id") == 32,
          f"serve --help: --unit continues under its description: {lines[unit:unit + 2]!r}")
    below = lines[watchdog_at + 1:watchdog_at + 4]
    check(all(indent(l) == 30 for l in below),
          f"serve --help: --watchdog's description lines all at column 30: {below!r}")
    # MAGLEAD_CONFIG naming no directory: said, with what to do.
    absent = os.path.join(WORK, "absent")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "1s", "-o",
                     os.path.join(WORK, "absent.csv"), env=dict(os.environ, MAGLEAD_CONFIG=absent))
    check(rc == 2 and f"no configuration directory '{absent}' (from MAGLEAD_CONFIG; unset it or fix it, "
          "or pass --config DIR)" in err, f"MAGLEAD_CONFIG absent: {err.strip()!r}")
    # serve's lengths and times take set's units; a bare number keeps the option's unit.
    for opts in (["--sim-start", "20mm"], ["--sim-spring-anchor", "25 mm"], ["--watchdog", "0.5s"],
                 ["--frame-timeout", "500ms"], ["--sim-spring", "2000N/m"]):
        rc, _, err = run("serve", "--port", "0", "--duration", "0.3s", *opts)
        check(rc == 0, f"serve {' '.join(opts)}: {err.strip()[-300:]!r}")
    rc, _, err = run("serve", "--port", "0", "--duration", "0.3s", "--sim-start", "45mm")
    check(rc == 2 and "0.045 m (45 mm) must lie within the stroke" in err, f"--sim-start 45mm: {err.strip()!r}")
    rc, _, err = run("serve", "--port", "0", "--duration", "0.3s", "--watchdog", "70s")
    check(rc == 2 and "70000 ms is outside 0 .. 60000 ms" in err, f"--watchdog 70s: {err.strip()!r}")
    rc, _, err = run("serve", "--port", "0", "--duration", "0.3s", "--sim-start", "2in")
    check(rc == 2 and "unit 'in' is not one of m, mm" in err and "--sim-start 0.02 or 20mm" in err,
          f"--sim-start 2in: {err.strip()!r}")
    # An effect id misspelt: the closest one; a force far past the coupling: refused with its range.
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "1s", "--effect", "ofset=2",
                     "-o", os.path.join(WORK, "ofset.csv"))
    check(rc == 2 and "unknown effect 'ofset'; did you mean 'offset'?" in err and "viscous_friction" not in err,
          f"--effect ofset=2: {err.strip()!r}")
    rc, _, err = run("simulate", "--scenario", "hand-push", "--duration", "1s", "--effect", "offset=1e9",
                     "-o", os.path.join(WORK, "offset_1e9.csv"))
    check(rc == 2 and re.search(r"effect 'offset' = 1e\+09 N is beyond 10 x the coupling's peak force "
                                r"[\d.]+ N: .* within -[\d.]+ \.\. [\d.]+ N", err) is not None,
          f"--effect offset=1e9: {err.strip()!r}")
    serve_overruns()


def serve_overruns():
    """Loop overruns under load: the first said with what it means, later ones summed, not a line
    a second. Stopping serve twice (SIGSTOP) makes a late cycle each time."""
    p = subprocess.Popen([MAGLEAD, "serve", "--port", "0", "--duration", "6s"], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True)
    # Stopped only once it serves: a slow start (a loaded machine, a sanitizer) must not eat the stops.
    started = ""
    while "Modbus TCP on" not in started:
        line = p.stdout.readline()
        if not line:
            break
        started += line
    for _ in range(2):
        time.sleep(0.5)
        p.send_signal(signal.SIGSTOP)
        time.sleep(0.2)
        p.send_signal(signal.SIGCONT)
    rest, _ = p.communicate(timeout=60)
    out = started + rest
    said = [l for l in out.splitlines() if "overrun" in l and not l.startswith("maglead serve: stopped")]
    m = re.search(r"stopped after \d+ cycles, (\d+) overruns", out)
    check(p.returncode == 0 and m is not None and int(m.group(1)) >= 2 and len(said) == 1
          and "A late cycle runs with the period it measured" in said[0],
          f"serve says the first overrun and what it means, not each second's: {said!r} {out[-200:]!r}")


def relative_paths_and_progress():
    # From a directory that is neither the source nor the build tree, every path is relative to it.
    elsewhere = os.path.join(WORK, "elsewhere")
    os.makedirs(os.path.join(elsewhere, "sub"))
    cfg = os.path.relpath(copy_config("cfg_rel"), elsewhere)
    shutil.copy(os.path.join(CONFIG, "model.toml"), os.path.join(elsewhere, "sub", "my_model.toml"))
    rc, out, err = run("simulate", "--scenario", "hand-push", "--duration", "2s", "--seed", "1",
                       "--out", "sub/rec.csv", "--config", cfg, cwd=elsewhere)
    check(rc == 0 and os.path.exists(os.path.join(elsewhere, "sub", "rec.csv")),
          f"simulate --out relative to the working directory: {err.strip()[-200:]}")
    check(err == "", f"no progress when stderr is not a terminal: {err!r}")
    rc, out, err = run("twin-check", "--recording", "sub/rec.csv", "--model", "sub/my_model.toml", "--config", cfg,
                       cwd=elsewhere)
    check(rc == 0, f"twin-check with relative --recording, --model and --config: {err.strip()[-300:]}")
    # Progress only on a terminal, and never with --quiet.
    rc, text = run_in_pty("simulate", "--scenario", "hand-push", "--duration", "2s", "--out", "sub/rec2.csv",
                          "--config", cfg, cwd=elsewhere)
    check(rc == 0 and "simulate hand-push [" in text and "100%" in text, "progress bar on a terminal")
    rc, text = run_in_pty("--quiet", "simulate", "--scenario", "hand-push", "--duration", "2s", "--out",
                          "sub/rec3.csv", "--config", cfg, cwd=elsewhere)
    check(rc == 0 and "[" not in text and "%" not in text and "wrote" in text, f"--quiet: no progress: {text!r}")
    rc, text = run_in_pty("simulate", "--quiet", "--scenario", "hand-push", "--duration", "2s", "--out",
                          "sub/rec4.csv", "--config", cfg, cwd=elsewhere)
    check(rc == 0 and "%" not in text, "--quiet after the command name works too")


def file_errors():
    # A model file without its format line, a TOML syntax error, a bad value: FILE:LINE:COLUMN.
    no_fmt = os.path.join(WORK, "no_format.toml")
    with open(os.path.join(CONFIG, "model.toml")) as f:
        body = f.read().split("\n", 1)[1]
    with open(no_fmt, "w") as f:
        f.write(body)
    rec = os.path.join(WORK, "elsewhere", "sub", "rec.csv")
    rc, _, err = run("twin-check", "--recording", rec, "--model", no_fmt, "--config", CONFIG)
    check(rc == 2 and f"{no_fmt}:1:1:" in err and "# format: maglead-model/1" in err,
          f"model without '# format' refused: {err.strip()!r}")
    rc, _, err = run("analyze", "--recording", rec, "--model", no_fmt, "--out", os.path.join(WORK, "an"),
                     "--config", CONFIG)
    check(rc == 2 and f"{no_fmt}:1:1:" in err, f"analyze refuses it too: {err.strip()[-200:]!r}")

    # A recording taken at 1 Hz (record --rate allows it): the twin's commands say the rate it needs.
    with open(rec) as f:
        lines = f.read().splitlines()
    head = [("# sample_rate_hz: 1" if l.startswith("# sample_rate_hz") else l) for l in lines if l.startswith("#")]
    data = [l for l in lines if not l.startswith("#")]
    slow = os.path.join(WORK, "slow.csv")
    with open(slow, "w") as f:
        f.write("\n".join(head + [data[0]] + data[1::1000]) + "\n")
    for cmd in ("twin-check", "report", "estimate"):
        out = [] if cmd == "twin-check" else ["--out", os.path.join(WORK, "slow_" + cmd)]
        rc, _, err = run(cmd, "--recording", slow, "--config", CONFIG, *out)
        check(rc == 2 and "(1 Hz)" in err and "record at 100 Hz or more" in err,
              f"{cmd} on a 1 Hz recording says the rate it needs: {err.strip()[-200:]!r}")

    afile = os.path.join(WORK, "a_file")
    with open(afile, "w") as f:
        f.write("x\n")
    for cmd in ("analyze", "report"):
        rc, _, err = run(cmd, "--recording", rec, "--config", CONFIG, "--out", afile)
        check(rc == 2 and "is a file; --out takes a directory" in err and open(afile).read() == "x\n",
              f"{cmd} --out a file: refused before any work, the file untouched: {err.strip()[-200:]!r}")
    cfg = copy_config("cfg_unit_in_value")
    with open(os.path.join(cfg, "actuator.toml")) as f:
        text = f.read()
    with open(os.path.join(cfg, "actuator.toml"), "w") as f:
        f.write(re.sub(r"(?m)^stroke_max_m = .*$", "stroke_max_m = 40mm", text))
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    check(rc == 2 and "key 'stroke_max_m'" in err and "without a unit" in err,
          f"a unit in a configured number names the key: {err.strip()[-200:]!r}")

    cfg = copy_config("cfg_bad_net")
    with open(os.path.join(cfg, "network.toml"), "a") as f:
        f.write("\n[server]\nread_only = tru\n")
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    m = re.search(r"network\.toml:(\d+):(\d+): ", err)
    check(rc == 2 and m is not None, f"TOML syntax error with line and column: {err.strip()!r}")
    cfg = copy_config("cfg_bad_act")
    with open(os.path.join(cfg, "actuator.toml")) as f:
        lines = f.read().splitlines()
    at = next(i for i, l in enumerate(lines) if l.startswith("coulomb_n"))
    lines[at] = "coulomb_n = -7.5"
    with open(os.path.join(cfg, "actuator.toml"), "w") as f:
        f.write("\n".join(lines) + "\n")
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    check(rc == 2 and f"actuator.toml:{at + 1}:13: [actuator] coulomb_n must be a positive number" in err,
          f"bad value at its line and column: {err.strip()!r}")
    cfg = copy_config("cfg_bad_control")
    with open(os.path.join(cfg, "actuator.toml"), "a") as f:
        f.write("force_reached_tolerance = 1.0\n")
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    check(rc == 2 and re.search(r"actuator\.toml:\d+:27: \[control\] unknown key 'force_reached_tolerance'", err)
          is not None, f"unknown [control] key: {err.strip()!r}")
    # Every command that reads the configuration refuses it, not only those that run the controller.
    moved = os.path.join(WORK, "moved.csv")
    for cmd in (["simulate", "--scenario", "hand-push", "--duration", "1s", "-o", os.path.join(WORK, "c.csv")],
                ["analyze", moved, "-o", os.path.join(WORK, "c_out"), "--no-twin-check"],
                ["report", moved, "-o", os.path.join(WORK, "c_report")], ["twin-check", moved], ["inspect", moved],
                ["calibrate", moved, "-o", os.path.join(WORK, "c_cal.toml")]):
        rc, _, err = run(*cmd, "--config", cfg)
        check(rc == 2 and "[control] unknown key 'force_reached_tolerance'" in err,
              f"{cmd[0]} refuses an unknown [control] key: {err.strip()[-200:]!r}")
    # [reference_move]: read by serve (its banner says so), bad values refused at their line.
    def with_reference_move(name, old, new):
        cfg = copy_config(name)
        with open(os.path.join(cfg, "actuator.toml")) as f:
            lines = f.read().splitlines()
        at = lines.index(old)
        lines[at] = new
        with open(os.path.join(cfg, "actuator.toml"), "w") as f:
            f.write("\n".join(lines) + "\n")
        return cfg, at + 1
    cfg, _ = with_reference_move("cfg_ref_ok", "window_max_m = 0.025", "window_max_m = 0.030")
    srv = Server(MAGLEAD, cfg, "--port", "0")
    srv.stop()
    check(any("reference move (mode_command 3): 15.0 .. 30.0 mm at 10.0 and 40.0 mm/s" in l
              for l in srv.lines), f"serve reads [reference_move]: {srv.lines}")
    cfg, line = with_reference_move("cfg_ref_out", "window_max_m = 0.025", "window_max_m = 0.045")
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    check(rc == 2 and f"actuator.toml:{line}:16: [reference_move] window_max_m must be a position "
          "within the stroke 0 .. 0.04 m" in err, f"window outside the stroke refused: {err.strip()!r}")
    cfg, line = with_reference_move("cfg_ref_speeds", "fast_m_s = 0.040", "fast_m_s = 0.005")
    rc, _, err = run("serve", "--config", cfg, "--port", "0", "--duration", "1s")
    check(rc == 2 and f"actuator.toml:{line}:12: [reference_move] fast_m_s must be above slow_m_s"
          in err, f"fast not above slow refused: {err.strip()!r}")


def against_a_server():
    # The controller runs with a tighter safe force than the client's configuration believes.
    tight = copy_config("cfg_tight")
    with open(os.path.join(tight, "actuator.toml")) as f:
        text = f.read()
    with open(os.path.join(tight, "actuator.toml"), "w") as f:
        f.write(re.sub(r"safe_force_fraction = [0-9.]+", "safe_force_fraction = 0.4", text))
    # A stroke the position setpoint cannot carry is refused at start, with what to change (the
    # limits block would publish it, and every write near it would be refused as out of range).
    wide = copy_config("cfg_wide_stroke")
    with open(os.path.join(wide, "actuator.toml")) as f:
        text = f.read()
    with open(os.path.join(wide, "actuator.toml"), "w") as f:
        f.write(re.sub(r"^stroke_max_m\s*=.*$", "stroke_max_m = 0.045", text, flags=re.M))
    rc, _, err = run("serve", "--config", wide, "--port", "0", "--duration", "1s")
    check(rc == 2 and "lies beyond what position_setpoint carries" in err and "stroke_max_m" in err,
          f"serve refuses a stroke the register cannot carry: {err.strip()!r}")
    srv = Server(MAGLEAD, tight, "--port", "0")
    try:
        port = str(srv.port)
        check(any("configuration from " + tight in l for l in srv.lines), f"serve names its configuration: {srv.lines}")
        rc, _, err = run("serve", "--config", tight, "--port", port, "--duration", "1s")
        check(rc != 0 and "Address already in use" in err and f"--port {int(port) + 1}" in err,
              f"a second serve on the same port says what to type: {err.strip()[-200:]!r}")
        # FC43 device identification: revision = --version, vendor URL names the project.
        rsp = raw_request(srv.port, bytes([43, 14, 2, 0]))
        objs, p = {}, 7
        for _ in range(rsp[6]):
            oid, n = rsp[p], rsp[p + 1]
            objs[oid] = rsp[p + 2:p + 2 + n].decode()
            p += 2 + n
        check(objs.get(2) == VERSION, f"FC43 revision is the project version: {objs.get(2)!r}")
        check("example" not in objs.get(3, "example") and "maglead" in objs.get(3, ""),
              f"FC43 vendor URL names the project: {objs.get(3)!r}")
        major, minor = (int(x) for x in VERSION.split(".")[:2])
        fw = struct.unpack(">H", raw_request(srv.port, struct.pack(">BHH", 4, 1, 1))[2:4])[0]
        check(fw == major * 256 + minor, f"firmware_version register {fw:#06x} from the project version")

        # poll: SI names carry the unit they print; JSON at each register's resolution.
        rc, out, err = run("poll", "--port", port, "--json")
        j = json.loads(out) if rc == 0 else {}
        rc2, regs_json, _ = run("registers", "--format", "json")
        regs = {r["name"]: r for r in json.loads(regs_json)["registers"]} if rc2 == 0 else {}
        suffix = {"m": "_m", "m/s": "_m_s", "m/s^2": "_m_s2", "rad": "_rad", "N": "_n", "s": "_s"}
        bad_names, noisy = [], []
        raw_text = out.split('"values"', 1)[1].split("}", 1)[0] if rc == 0 else ""
        for name, unit in j.get("units", {}).items():
            if unit in suffix and not name.endswith(suffix[unit]):
                bad_names.append(f"{name} [{unit}]")
        for m in re.finditer(r'"(\w+)": (-?[0-9.eE+-]+)', raw_text):
            name, literal = m.group(1), m.group(2)
            reg = regs.get(name) or next((r for r in regs.values() if r["name"] != name and
                                          name == si_name(r["name"], r["scale"])), None)
            if reg is None or reg["type"] == "f32":
                continue
            decimals = max(0, round(-__import__("math").log10(reg["scale"]))) if reg["scale"] < 1 else 0
            frac = literal.split(".")[1] if "." in literal and "e" not in literal.lower() else ""
            if "e" in literal.lower() or len(frac) > decimals:
                noisy.append(f"{name}={literal}")
        check(rc == 0 and not bad_names and "nut_pos_m" in j.get("values", {}),
              f"poll --json: every SI name carries its unit ({bad_names})")
        check(rc == 0 and not noisy and len(raw_text) > 100, f"poll --json: no digits beyond the resolution ({noisy})")

        # Limits: the controller's own (its limits block, from the tighter configuration it runs),
        # not this machine's --config: value, limit, and that they are the controller's.
        rc, _, err = run("set", "--port", port, "force", "60", "--config", CONFIG)
        check(rc == 2 and "force 60 N" in err and "beyond the safe limit" in err
              and "(the controller's limits, force_limit_pull_n_f32 / force_limit_push_n_f32)" in err,
              f"limit error: value, limit, whose: {err.strip()!r}")
        rc, _, err = run("set", "--port", port, "position", "45mm", "--config", CONFIG)
        check(rc == 2 and "45 mm" in err and "0 .. 40 mm" in err and "the controller's stroke" in err,
              f"stroke error: value, limit, whose: {err.strip()!r}")
        rc, _, err = run("set", "--port", port, "force", "25", "--config", CONFIG)
        m = re.search(r"allowed -\d+\.?\d* \.\. (\d+\.?\d*) N \(the controller's limits", err)
        check(rc == 2 and "nothing sent" in err and m is not None and float(m.group(1)) < 25,
              f"25 N, inside this machine's limits, beyond the controller's: refused with its limit: {err.strip()!r}")
    finally:
        srv.stop()


def si_name(name, scale):
    if scale == 1:
        return name
    for raw, si in (("_um_s2", "_m_s2"), ("_um_s", "_m_s"), ("_um", "_m"), ("_urad", "_rad"), ("_mn", "_n"),
                    ("_ms", "_s"), ("_us", "_s")):
        if name.endswith(raw):
            return name[:-len(raw)] + si
    return name


if __name__ == "__main__":
    main()
