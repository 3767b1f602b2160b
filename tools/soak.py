#!/usr/bin/env python3
"""Long soak of `maglead serve` (issue 25, item 6; not run in CI).

Starts `maglead serve` on a free loopback port, then for --duration (default one hour) runs
  - --pollers (default 16) clients, each on its own connection, reading status and identity
    registers in turn, one request in flight, every --poll-interval seconds;
  - one writer that claims control (enable rising edge) and releases it (enable low) once per
    --claim-period seconds, and checks control_owner (input register 17) follows;
  - one `maglead record` at --record-rate polls per second for the whole duration;
and samples the server's resident memory (VmRSS), open file descriptors and threads every
--sample-every seconds. Every request has a reply deadline (--timeout); every loop ends at the
deadline. Prints one line per sample and a summary, and exits 1 if
  - a request was not answered (no reply within the timeout, a reply for another transaction,
    or an exception reply), a claim or release did not take, or `maglead record` failed;
  - after the warm-up (the first --warmup seconds), the largest RSS of the last fifth of the
    samples exceeds the largest of the first fifth by more than --rss-slack-kib (default 2048:
    a leak of a few bytes per request over ten minutes at the default rates is more than that),
    or the descriptors or threads of the last fifth exceed those of the first fifth at all.
Usage: python3 tools/soak.py [--duration 3600] [--maglead build/bin/maglead]
"""
import argparse
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Requests the pollers cycle through: status and measurements (FC4), identity (FC3), bits (FC2).
POLLS = [bytes([4]) + struct.pack(">HH", 10, 50), bytes([3]) + struct.pack(">HH", 0, 8),
         bytes([2]) + struct.pack(">HH", 0, 8), bytes([4]) + struct.pack(">HH", 100, 28)]


class Client:
    """One persistent Modbus TCP connection; counts every request sent and answered."""

    def __init__(self, port, timeout):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.tid = 0
        self.sent = self.answered = 0
        self.problems = []

    def request(self, pdu):
        """Sends one request; returns the reply PDU, or None (counted as lost) on any failure."""
        self.tid = (self.tid + 1) & 0xFFFF
        self.sent += 1
        try:
            self.sock.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, 1) + pdu)
            head = self._recv(7)
            tid, proto, length, _ = struct.unpack(">HHHB", head)
            body = self._recv(length - 1)
        except (OSError, ValueError) as e:
            self._problem(f"request {pdu[0]}: {e}")
            return None
        if tid != self.tid or proto != 0 or body[0] != pdu[0]:
            self._problem(f"request {pdu[0]}: reply tid {tid} function {body[0]:#x}")
            return None
        self.answered += 1
        return body

    def _recv(self, n):
        buf = b""
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ValueError("connection closed")
            buf += chunk
        return buf

    def _problem(self, what):
        if len(self.problems) < 5:  # the first few say what went wrong; the counts say how often
            self.problems.append(what)


def poller(client, deadline, interval):
    i = 0
    while time.monotonic() < deadline:
        client.request(POLLS[i % len(POLLS)])
        i += 1
        time.sleep(interval)


def writer(client, deadline, period, stats):
    """Claims and releases control; control_owner must be non-zero while it holds it, zero after."""
    write_enable = lambda on: client.request(bytes([5]) + struct.pack(">HH", 0, 0xFF00 if on else 0))
    read_owner = lambda: client.request(bytes([4]) + struct.pack(">HH", 17, 1))
    while time.monotonic() < deadline:
        for on in (True, False):
            if write_enable(on) is not None:
                owner = read_owner()
                if owner is not None and (struct.unpack(">H", owner[2:4])[0] != 0) == on:
                    stats["ok"] += 1
                elif owner is not None:
                    stats["failed"] += 1
            time.sleep(period / 2)


def proc_sample(pid):
    with open(f"/proc/{pid}/status") as f:
        fields = dict(line.split(":", 1) for line in f if ":" in line)
    rss_kib = int(fields["VmRSS"].split()[0])
    threads = int(fields["Threads"])
    fds = len(os.listdir(f"/proc/{pid}/fd"))
    return rss_kib, fds, threads


def start_server(args, log):
    proc = subprocess.Popen([args.maglead, "serve", "--config", args.config, "--port", "0",
                             "--duration", f"{int(args.duration + 120)}s"],
                            stdout=log, stderr=subprocess.STDOUT, text=True)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and proc.poll() is None:
        with open(log.name) as f:
            for line in f:
                if "Modbus TCP on" in line:
                    return proc, int(line.split("Modbus TCP on ")[1].split(",")[0].rsplit(":", 1)[1])
        time.sleep(0.1)
    proc.kill()
    sys.exit("soak: maglead serve did not start; its output is in " + log.name)


def growth(samples, warmup_s, rss_slack_kib):
    """Compares the first and the last fifth of the samples after the warm-up; [] if flat."""
    after = [s for s in samples if s[0] >= warmup_s]
    if len(after) < 10:
        return [f"only {len(after)} samples after the warm-up: too short to judge growth"]
    k = len(after) // 5
    first, last = after[:k], after[-k:]
    problems = []
    for col, name, slack in ((1, "RSS [KiB]", rss_slack_kib), (2, "open fds", 0), (3, "threads", 0)):
        a, b = max(s[col] for s in first), max(s[col] for s in last)
        if b > a + slack:
            problems.append(f"{name} grew: {a} in the first fifth, {b} in the last (slack {slack})")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="seconds (default 3600)")
    ap.add_argument("--maglead", default=os.path.join(ROOT, "build", "bin", "maglead"))
    ap.add_argument("--config", default=os.path.join(ROOT, "build", "config"))
    ap.add_argument("--pollers", type=int, default=16)
    ap.add_argument("--poll-interval", type=float, default=0.02, help="seconds between a poller's requests")
    ap.add_argument("--claim-period", type=float, default=1.0, help="seconds per claim and release")
    ap.add_argument("--record-rate", type=float, default=100.0, help="maglead record polls per second")
    ap.add_argument("--sample-every", type=float, default=10.0, help="seconds between samples")
    ap.add_argument("--warmup", type=float, default=60.0, help="seconds before growth is judged")
    ap.add_argument("--timeout", type=float, default=2.0, help="reply deadline per request [s]")
    ap.add_argument("--rss-slack-kib", type=int, default=2048)
    args = ap.parse_args()

    work = tempfile.mkdtemp(prefix="maglead-soak-")
    log = open(os.path.join(work, "serve.log"), "w")
    server, port = start_server(args, log)
    pid = server.pid
    t0 = time.monotonic()
    deadline = t0 + args.duration
    clients = [Client(port, args.timeout) for _ in range(args.pollers + 1)]
    claims = {"ok": 0, "failed": 0}
    threads = [threading.Thread(target=poller, args=(c, deadline, args.poll_interval), daemon=True)
               for c in clients[:-1]]
    threads.append(threading.Thread(target=writer, args=(clients[-1], deadline, args.claim_period, claims),
                                    daemon=True))
    rec_path = os.path.join(work, "soak.csv")
    recorder = subprocess.Popen([args.maglead, "record", "--port", str(port), "--rate", str(args.record_rate),
                                 "--duration", f"{int(args.duration)}s", "--out", rec_path,
                                 "--timeout", str(args.timeout)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for t in threads:
        t.start()
    samples = []  # (t_s, rss_kib, fds, threads)
    print(f"soak: maglead serve pid {pid} on port {port}, {args.pollers} pollers, 1 writer, "
          f"1 recorder for {args.duration:.0f} s; work dir {work}", flush=True)
    print("t_s,rss_kib,open_fds,threads,requests_sent,requests_answered", flush=True)
    while time.monotonic() < deadline:
        time.sleep(min(args.sample_every, max(0.0, deadline - time.monotonic())))
        if server.poll() is not None:
            break
        s = (round(time.monotonic() - t0, 1), *proc_sample(pid))
        samples.append(s)
        sent, answered = sum(c.sent for c in clients), sum(c.answered for c in clients)
        print(",".join(str(x) for x in (*s, sent, answered)), flush=True)
    for t in threads:
        t.join(args.timeout + args.claim_period + 1)
    rec_out, _ = recorder.communicate(timeout=60)
    server_alive = server.poll() is None
    if server_alive:
        server.send_signal(signal.SIGINT)
        server.wait(10)
    return report(args, clients, claims, samples, recorder.returncode, rec_out, rec_path, server_alive)


def report(args, clients, claims, samples, rec_rc, rec_out, rec_path, server_alive):
    sent, answered = sum(c.sent for c in clients), sum(c.answered for c in clients)
    rows = 0
    if os.path.exists(rec_path):
        with open(rec_path) as f:
            rows = sum(1 for line in f if line[:1].isdigit())
    problems = [] if server_alive else ["maglead serve exited during the soak"]
    if sent != answered:
        problems.append(f"{sent - answered} of {sent} requests not answered: "
                        + "; ".join(p for c in clients for p in c.problems[:2]))
    if claims["failed"] or claims["ok"] == 0:
        problems.append(f"claim/release: {claims['ok']} took, {claims['failed']} did not")
    if rec_rc != 0:
        problems.append(f"maglead record exited {rec_rc}: {rec_out.strip()[-300:]}")
    # The recorder's own count: a poll without reply is a request lost; one missed while it was
    # behind (the machine busy) was never sent.
    m = re.search(r"dropped polls: \d+ of (\d+) \((\d+) without reply, (\d+) missed", rec_out)
    rec_polls, rec_lost, rec_missed = (int(x) for x in m.groups()) if m else (0, 0, 0)
    if not m:
        problems.append("maglead record did not report its polls: " + rec_out.strip()[-300:])
    elif rec_lost:
        problems.append(f"maglead record: {rec_lost} of {rec_polls} polls without reply")
    problems += growth(samples, args.warmup, args.rss_slack_kib)
    first, last = samples[0] if samples else None, samples[-1] if samples else None
    print(f"soak: {sent} requests sent, {answered} answered ({sent / max(args.duration, 1):.0f}/s); "
          f"{claims['ok']} claims and releases confirmed; maglead record: {rec_polls} polls, "
          f"{rec_lost} without reply, {rec_missed} missed while behind, {rows} rows written")
    if first and last:
        print(f"soak: server RSS {first[1]} -> {last[1]} KiB (max {max(s[1] for s in samples)}), "
              f"fds {first[2]} -> {last[2]}, threads {first[3]} -> {last[3]} over {last[0]:.0f} s")
    for p in problems:
        print("soak: FAIL " + p)
    print("soak: " + ("FAILED" if problems else "passed"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
