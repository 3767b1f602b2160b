"""Shared helpers for the Modbus integration tests: start `maglead serve`, raw MBAP frames."""
import contextlib
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

FAILURES = []


def crc16(data):
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return struct.pack("<H", crc)



def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        FAILURES.append(what)


def finish():
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed:", *FAILURES, sep="\n  ")
        sys.exit(1)
    print("all checks passed")
    sys.exit(0)


def watchdog(seconds):
    """The whole test stops by itself, whatever hangs."""
    def expire(*_):
        print(f"FAIL test exceeded {seconds} s", flush=True)
        os._exit(3)
    signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)


class Server:
    """`maglead serve` as a child process; the port is read from its first lines."""

    def __init__(self, maglead, config, *args, duration="120s", env=None):
        # config None: no --config, the program finds its configuration itself.
        where = ["--config", config] if config else []
        self.proc = subprocess.Popen([maglead, "serve", *where, "--duration", duration, *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
        self.port = None
        self.lines = []
        deadline = time.time() + 10
        while time.time() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            self.lines.append(line.rstrip())
            if "Modbus TCP on" in line:
                self.port = int(line.split("Modbus TCP on ")[1].split(",")[0].rsplit(":", 1)[1])
                break
            if "Modbus RTU on" in line:
                break
        if self.proc.poll() is not None:
            raise RuntimeError("maglead serve exited: " + "\n".join(self.lines + [self.proc.stdout.read()]))

    def alive(self):
        return self.proc.poll() is None

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        rest = self.proc.stdout.read()
        return rest


def raw_request(port, pdu, unit=1, tid=0x4242, timeout=2.0):
    """One MBAP request on a fresh connection; returns the response PDU (or None on close)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu)
        return read_response(s, tid)


def read_response(s, tid=0x4242):
    head = recv_exact(s, 7)
    if head is None:
        return None
    rtid, proto, length, _unit = struct.unpack(">HHHB", head)
    assert rtid == tid and proto == 0, (rtid, proto)
    return recv_exact(s, length - 1)


def recv_exact(s, n):
    buf = b""
    while len(buf) < n:
        chunk = s.recv(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return buf


def f32_words(value):
    hi, lo = struct.unpack(">HH", struct.pack(">f", value))
    return [hi, lo]


def words_f32(words):
    return struct.unpack(">f", struct.pack(">HH", *words))[0]


def words_i32(words):
    return struct.unpack(">i", struct.pack(">HH", *words))[0]


@contextlib.contextmanager
def rtu_server(maglead, config, unit, prefix):
    """`maglead serve` (RTU only) on one end of a socat pseudo-terminal pair; yields the server and
    the other end's path. Stops both afterwards; the server must say it stopped cleanly."""
    tmp = tempfile.mkdtemp(prefix=prefix)
    dev_a, dev_b = os.path.join(tmp, "ttyA"), os.path.join(tmp, "ttyB")
    socat = subprocess.Popen(["socat", f"pty,raw,echo=0,link={dev_a}", f"pty,raw,echo=0,link={dev_b}"],
                             stderr=subprocess.DEVNULL)
    try:
        end = time.time() + 5
        while not (os.path.exists(dev_a) and os.path.exists(dev_b)) and time.time() < end:
            time.sleep(0.05)
        check(os.path.exists(dev_b), "socat made a pty pair")
        srv = Server(maglead, config, "--no-tcp", "--rtu-device", dev_a, "--rtu-unit", str(unit))
        try:
            yield srv, dev_b
        finally:
            tail = srv.stop()
        check("stopped after" in tail, "serve stops cleanly")
    finally:
        socat.terminate()
        socat.wait(5)
