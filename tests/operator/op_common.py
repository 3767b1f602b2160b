"""Helpers for the operator-tool tests. The server child, check/finish/watchdog and raw MBAP
requests come from the controller tests' modbus_common; added here: running `maglead` with a
time limit and the raw reads that check what the tools print."""
import os
import struct
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "controller"))
from modbus_common import FAILURES, Server, check, finish, raw_request, rtu_server, watchdog, words_i32  # noqa: E402,F401


def run(maglead, *args, timeout=60):
    """Runs `maglead ARGS`; returns (exit code, stdout, stderr)."""
    p = subprocess.run([maglead, *args], capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def read_regs(port, fc, start, count):
    """Raw FC3/FC4 read, words as a list of ints."""
    rsp = raw_request(port, struct.pack(">BHH", fc, start, count))
    assert rsp[0] == fc, rsp
    return list(struct.unpack(f">{count}H", rsp[2:2 + 2 * count]))


def i32(words):
    return words_i32(words)


def bus_message_count(port):
    """FC8 sub-function 0x0B: messages the server has handled (this request included)."""
    rsp = raw_request(port, struct.pack(">BHH", 8, 0x0B, 0))
    return struct.unpack(">H", rsp[3:5])[0]


def one_line(stderr):
    """The error is one line (progress lines of a non-tty Progress bar aside)."""
    lines = [l for l in stderr.splitlines() if l.strip() and not l.rstrip().endswith("%")]
    return len(lines) == 1
