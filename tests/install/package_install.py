"""Install as integrators do, and run what was installed, away from the source and build trees:
1. `cmake --install BUILD --prefix P`: P/bin/maglead finds P/share/maglead by itself; the man
   page is P/share/man/man1/maglead.1.gz;
2. `cpack -G DEB`: the package holds the binary, the configuration under /etc/maglead (as
   conffiles), a systemd unit for `maglead serve` and the man page maglead(1); extracted into a
   clean root (dpkg -x), its binary runs `maglead serve --port 0` and `maglead poll` with
   /etc/maglead as the default configuration (the extracted etc/ laid over /etc in a private
   mount namespace).
Usage: package_install.py BUILD_DIR WORK_DIR VERSION"""
import glob
import gzip
import os
import re
import shutil
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "controller"))
from modbus_common import check, finish, watchdog  # noqa: E402

BUILD, WORK, VERSION = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), sys.argv[3]


def source_dir():
    """The source tree the build was configured from (its config/ is what gets installed)."""
    with open(os.path.join(BUILD, "CMakeCache.txt")) as f:
        for line in f:
            if line.startswith("CMAKE_HOME_DIRECTORY:"):
                return line.split("=", 1)[1].strip()
    raise RuntimeError("no CMAKE_HOME_DIRECTORY in CMakeCache.txt")


CONFIG_FILES = sorted(os.path.basename(p) for p in glob.glob(os.path.join(source_dir(), "config", "*.toml")))
CLEAN_ENV = {k: v for k, v in os.environ.items() if k != "MAGLEAD_CONFIG"}


def sh(*cmd, **kw):
    return subprocess.run(list(cmd), capture_output=True, text=True, timeout=kw.pop("timeout", 300), **kw)


def serve_and_poll(prefix_cmd, binary, cwd, env, what):
    """Starts `BINARY serve --port 0` (without --config), then `BINARY poll`; returns serve's
    'configuration from' directory and poll's output."""
    srv = subprocess.Popen(prefix_cmd + [binary, "serve", "--port", "0", "--duration", "30s"], cwd=cwd, env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines, port, config_dir = [], None, None
    for _ in range(10):
        line = srv.stdout.readline()
        if not line:
            break
        lines.append(line.rstrip())
        m = re.search(r"configuration from (\S+)", line)
        config_dir = m.group(1) if m else config_dir
        m = re.search(r"Modbus TCP on [0-9.]+:(\d+)", line)
        if m:
            port = m.group(1)
            break
    check(port is not None, f"{what}: serve --port 0 listens: {lines}")
    poll = sh(*prefix_cmd, binary, "poll", "--port", port or "1", "--json", cwd=cwd, env=env) if port else None
    srv.send_signal(signal.SIGINT)
    try:
        srv.wait(10)
    except subprocess.TimeoutExpired:
        srv.kill()
        srv.wait()
    return config_dir, poll


def main():
    watchdog(280)
    shutil.rmtree(WORK, ignore_errors=True)
    os.makedirs(WORK)
    check(len(CONFIG_FILES) >= 4, f"the source tree's config/ holds the configuration: {CONFIG_FILES}")

    # 1. cmake --install into a prefix; run from / with no --config and no $MAGLEAD_CONFIG.
    prefix = os.path.join(WORK, "prefix")
    r = sh("cmake", "--install", BUILD, "--prefix", prefix)
    check(r.returncode == 0, f"cmake --install: {r.stderr.strip()[-300:]}")
    binary = os.path.join(prefix, "bin", "maglead")
    check(os.access(binary, os.X_OK), "installed bin/maglead")
    check(sorted(os.listdir(os.path.join(prefix, "share", "maglead"))) == CONFIG_FILES,
          "installed share/maglead holds the configuration")
    unit = os.path.join(prefix, "lib", "systemd", "system", "maglead.service")
    text = open(unit).read() if os.path.exists(unit) else ""
    check(f"ExecStart={binary} serve" in text, f"the unit starts the installed binary: {unit}")
    config_dir, poll = serve_and_poll([], binary, "/", CLEAN_ENV, "prefix install")
    check(config_dir == os.path.join(prefix, "share", "maglead"),
          f"prefix install finds its configuration next to the binary: {config_dir}")
    check(poll is not None and poll.returncode == 0 and '"drive_state": "ready"' in poll.stdout,
          "prefix install: poll reads the controller")
    r = sh(binary, "--version")
    check(r.stdout.strip() == f"maglead {VERSION}", f"installed --version: {r.stdout.strip()}")
    man = os.path.join(prefix, "share", "man", "man1", "maglead.1.gz")
    page = gzip.open(man, "rt").read() if os.path.exists(man) else ""
    check(".TH MAGLEAD \"1\"" in page and ".SH COMMANDS" in page, "installed share/man/man1/maglead.1.gz, maglead(1)")
    # Outside /usr, man's own path may not hold the prefix: --help names the page by its path.
    r = sh(binary, "--help", cwd="/", env={k: v for k, v in os.environ.items() if k != "COLUMNS"})
    check(f"See man -l {man} for every command." in r.stdout,
          f"installed --help names the installed man page: {r.stdout[:400]!r}")

    # 2. The .deb.
    pkg = os.path.join(WORK, "pkg")
    r = sh("cpack", "-G", "DEB", "-B", pkg, "--config", os.path.join(BUILD, "CPackConfig.cmake"), timeout=600)
    debs = glob.glob(os.path.join(pkg, "*.deb"))
    check(r.returncode == 0 and len(debs) == 1, f"cpack -G DEB builds one package: {r.stdout.strip()[-300:]}"
          f"{r.stderr.strip()[-300:]}")
    if not debs:
        finish()
    deb = debs[0]
    check(os.path.basename(deb).startswith(f"maglead_{VERSION}"), f"package name and version: {deb}")
    contents = sh("dpkg-deb", "-c", deb).stdout
    info = sh("dpkg-deb", "-I", deb).stdout
    check("./usr/bin/maglead" in contents, "package: /usr/bin/maglead")
    check(all(f"./etc/maglead/{f}" in contents for f in CONFIG_FILES), "package: /etc/maglead/*.toml")
    check("./usr/share/maglead/" not in contents, "package: no second copy of the configuration in /usr/share")
    check("./usr/lib/systemd/system/maglead.service" in contents, "package: the systemd unit")
    check("./usr/share/man/man1/maglead.1.gz" in contents, "package: the man page maglead(1)")
    check(re.search(r"Depends:.*libmodbus5", info) is not None, "package: depends on libmodbus (dpkg-shlibdeps)")
    root = os.path.join(WORK, "root")
    os.makedirs(root)
    r = sh("dpkg-deb", "-x", deb, root)
    check(r.returncode == 0, "dpkg -x into a clean root")
    ctrl = os.path.join(WORK, "ctrl")
    sh("dpkg-deb", "-e", deb, ctrl)
    listed = open(os.path.join(ctrl, "conffiles")).read().split() if os.path.exists(os.path.join(ctrl, "conffiles")) else []
    check(sorted(listed) == [f"/etc/maglead/{f}" for f in CONFIG_FILES], f"package: conffiles {listed}")
    unit_text = open(os.path.join(root, "usr/lib/systemd/system/maglead.service")).read()
    check("ExecStart=/usr/bin/maglead serve" in unit_text and "WantedBy=multi-user.target" in unit_text,
          "the unit runs /usr/bin/maglead serve and is enabled for multi-user.target")
    r = sh("systemd-analyze", "verify", "--root", root, "/usr/lib/systemd/system/maglead.service") \
        if shutil.which("systemd-analyze") else None
    if r is not None:
        # The extracted root has no sysinit.target: only the unit's own lines count (syntax, keys).
        problems = [l for l in (r.stdout + r.stderr).splitlines()
                    if "maglead.service" in l and "sysinit.target not found" not in l]
        check(not problems, f"systemd-analyze verify finds nothing wrong in the unit: {problems}")

    binary = os.path.join(root, "usr", "bin", "maglead")
    # The extracted /etc/maglead must be where the binary looks: lay the root's etc/ over /etc in a
    # private mount namespace (the host's /etc is untouched).
    probe = sh("unshare", "--mount", "--propagation", "private", "true") if shutil.which("unshare") else None
    if probe is not None and probe.returncode == 0:
        script = (f"mount -t overlay overlay -o lowerdir={root}/etc:/etc /etc && exec \"$@\"")
        prefix_cmd = ["unshare", "--mount", "--propagation", "private", "sh", "-c", script, "sh"]
        config_dir, poll = serve_and_poll(prefix_cmd, binary, "/", CLEAN_ENV, "package")
        check(config_dir == "/etc/maglead", f"the packaged binary's default configuration is /etc/maglead: {config_dir}")
    else:
        print("note: no private mount namespace here; the package runs with MAGLEAD_CONFIG=<root>/etc/maglead")
        env = dict(CLEAN_ENV, MAGLEAD_CONFIG=os.path.join(root, "etc", "maglead"))
        config_dir, poll = serve_and_poll([], binary, "/", env, "package")
    check(poll is not None and poll.returncode == 0 and '"drive_state": "ready"' in poll.stdout,
          f"package: poll reads the packaged controller {poll.stderr.strip() if poll else ''}")
    finish()


if __name__ == "__main__":
    main()
