"""`maglead serve` over Modbus TCP, driven by independent clients (pymodbus, mbpoll, raw
sockets): drive enable, force and position round trips, every exception case, ownership,
FC8/FC23/FC43, and that malformed frames, stalled and vanishing clients leave others served.
Usage: modbus_tcp_integration.py MAGLEAD_BIN CONFIG_DIR"""
import socket
import struct
import subprocess
import sys
import threading
import time

from modbus_common import (Server, check, f32_words, finish, raw_request, read_response,
                           watchdog, words_f32, words_i32)
from pymodbus.client import ModbusTcpClient
from pymodbus.diag_message import ReturnQueryDataRequest
from pymodbus.mei_message import ReadDeviceInformationRequest

MAGLEAD, CONFIG = sys.argv[1], sys.argv[2]
UNIT = 1
CW, MODE, HEARTBEAT, WATCHDOG = 1000, 1001, 1002, 1003
FORCE_F32, POS_F32 = 1012, 1014
ENABLE, STOP, RESET, RESYNC, EXECUTE = 1, 2, 4, 8, 16
ST_ENABLED, ST_IN_POSITION, ST_FORCE_REACHED, ST_OWNED = 1 << 1, 1 << 4, 1 << 5, 1 << 12


def exc_code(pdu):
    return pdu[1] if pdu and len(pdu) == 2 and pdu[0] & 0x80 else None


def wait_status(client, mask, timeout=4.0):
    end = time.time() + timeout
    while time.time() < end:
        rr = client.read_input_registers(10, 1, slave=UNIT)
        if not rr.isError() and rr.registers[0] & mask:
            return True
        time.sleep(0.02)
    return False


def main():
    watchdog(90)
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--sim-spring", "3000", "--frame-timeout", "0.5")
    check(srv.port is not None, f"serve printed its port ({srv.lines})")
    port = srv.port
    try:
        run(port)
        read_only_server()
        allow_list_and_cap()
    finally:
        tail = srv.stop()
    check("stopped after" in tail, "serve stops cleanly on SIGINT: " + tail.strip().splitlines()[-1] if tail.strip() else "no output")
    finish()


def run(port):
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
    check(c.connect(), "pymodbus connects")

    # Identity and word order.
    rr = c.read_input_registers(0, 8, slave=UNIT)
    check(not rr.isError() and rr.registers[0] == 0x4D4C, "device type reads 0x4D4C")
    check(rr.registers[4:6] == [0x1234, 0x5678], "word-order probe u32 is high word first")
    check(abs(words_f32(rr.registers[6:8]) - 1234.5678) < 1e-3, "word-order probe f32 reads 1234.5678")
    rr = c.read_holding_registers(0, 8, slave=UNIT)
    check(not rr.isError() and rr.registers[0] == 0x4D4C, "FC3 reads the input registers too")

    # FC43/14 and FC8.
    rsp = c.execute(ReadDeviceInformationRequest(read_code=1, object_id=0, unit=UNIT))
    info = getattr(rsp, "information", {}) if not rsp.isError() else {}
    check(info.get(0) == b"maglead project" and 1 in info and 2 in info, f"FC43/14 basic identification {info}")
    rsp = c.execute(ReturnQueryDataRequest(0xBEEF, unit=UNIT))
    check(not rsp.isError() and tuple(getattr(rsp, "message", ())) == (0xBEEF,), "FC8 echoes query data")
    check(raw_request(port, bytes([8, 0, 0x0B, 0, 0]))[:3] == bytes([8, 0, 0x0B]), "FC8 bus message counter")

    # Exceptions, via raw frames so that no client-side check interferes.
    def exc(pdu):
        return exc_code(raw_request(port, pdu))
    check(exc(struct.pack(">BHH", 3, 200, 1)) == 2, "read of an unmapped address: exception 02")
    check(exc(struct.pack(">BHH", 3, 150, 10)) == 2, "read partly outside the map: exception 02")
    # Finding 8: block reads across reserved addresses (IR 8-9, 95-99) answer, reserved as 0; IR
    # 68-69 (the drive fault's cause and code) read 0 without a fault.
    rr = c.read_input_registers(0, 16, slave=UNIT)
    check(not rr.isError() and rr.registers[8:10] == [0, 0] and rr.registers[0] == 0x4D4C,
          "FC4 0..15 reads, reserved 8-9 as 0")
    rr = c.read_holding_registers(40, 72, slave=UNIT)
    check(not rr.isError() and len(rr.registers) == 72 and rr.registers[28:30] == [0] * 2
          and rr.registers[55:60] == [0] * 5, "FC3 40..111 reads, 68-69 (no fault) and reserved 95-99 as 0")
    check(exc(struct.pack(">BHH", 4, 21, 2)) == 2, "read splitting a 32-bit value: exception 02")
    check(exc(struct.pack(">BHH", 4, 1000, 1)) == 2, "FC4 on a holding register: exception 02")
    check(exc(struct.pack(">BHH", 3, 10, 0)) == 3, "quantity 0: exception 03")
    check(exc(struct.pack(">BHH", 3, 10, 126)) == 3, "quantity 126: exception 03")
    check(exc(struct.pack(">BHH", 6, 10, 1)) == 2, "write to a read-only register: exception 02")
    check(exc(struct.pack(">BHH", 6, 1004, 1)) == 2, "FC6 to half of a 32-bit setpoint: exception 02")
    check(exc(bytes([0x41, 0, 0])) == 1, "unknown function: exception 01")
    check(exc(struct.pack(">BHHB", 16, FORCE_F32, 2, 4) + struct.pack(">HH", *f32_words(500.0))) == 3,
          "force setpoint beyond the safe limit: exception 03")
    check(exc(struct.pack(">BHH", 6, CW, EXECUTE | STOP)) == 3, "execute with stop: exception 03")
    check(exc(struct.pack(">BHH", 6, CW, 0x40)) == 3, "reserved control bit: exception 03")
    check(exc_code(raw_request(port, struct.pack(">BHH", 3, 10, 1), unit=7)) == 0x0B,
          "wrong unit id: exception 0B at once")
    rr = c.read_holding_registers(FORCE_F32, 2, slave=UNIT)
    check(not rr.isError() and words_f32(rr.registers) == 0.0, "refused writes changed nothing")
    rr = c.write_register(HEARTBEAT, 1, slave=UNIT)
    check(not rr.isError(), "heartbeat write accepted")

    # Enable: this client owns control; another one is refused with 06 but may read.
    check(not c.write_register(CW, ENABLE, slave=UNIT).isError(), "enable written")
    check(wait_status(c, ST_ENABLED), "drive reports enabled")
    other = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
    other.connect()
    rsp = other.write_register(MODE, 1, slave=UNIT)
    check(rsp.isError() and getattr(rsp, "exception_code", None) == 4,
          "non-owner write: exception 04 (not 06: retrying cannot help)")
    rr = other.read_input_registers(55, 1, slave=UNIT)
    check(not rr.isError() and rr.registers[0] == 1, "write_refusal_reason says not_owner")
    rr = other.read_input_registers(10, 10, slave=UNIT)
    check(not rr.isError() and rr.registers[7] != 0 and rr.registers[0] & ST_OWNED,
          "non-owner reads; control_owner and the owned bit say someone owns")

    # Force mode round trip.
    c.write_registers(FORCE_F32, f32_words(10.0), slave=UNIT)
    c.write_register(MODE, 2, slave=UNIT)
    c.write_register(CW, ENABLE | EXECUTE, slave=UNIT)
    c.write_register(CW, ENABLE, slave=UNIT)
    check(wait_status(c, ST_FORCE_REACHED), "force mode reports force reached")
    rr = c.read_input_registers(128, 2, slave=UNIT)
    force = words_f32(rr.registers)
    check(abs(force - 10.0) <= 1.5, f"load observer's output force {force:.2f} N within 1.5 N of 10 N")
    rr = c.read_input_registers(110, 2, slave=UNIT)
    load = words_f32(rr.registers)
    check(abs(load - 10.0) <= 1.5, f"and the load cell reads {load:.2f} N: the force is at the load")
    rr = c.read_input_registers(15, 1, slave=UNIT)
    check(rr.registers[0] & 0b11 == 0b10, "execute: ack cleared with the bit, done set")

    # Position mode round trip, in one FC23 per step as a PLC would.
    c.write_registers(POS_F32, f32_words(0.025), slave=UNIT)
    c.write_register(MODE, 1, slave=UNIT)
    rsp = c.readwrite_registers(read_address=10, read_count=8, write_address=CW,
                                write_registers=[ENABLE | EXECUTE], unit=UNIT)
    check(not rsp.isError() and len(rsp.registers) == 8, "FC23 writes the control word and reads status")
    c.write_register(CW, ENABLE, slave=UNIT)
    check(wait_status(c, ST_IN_POSITION, 5.0), "position mode reports in position")
    pos = words_f32(c.read_input_registers(100, 2, slave=UNIT).registers)
    check(abs(pos - 0.025) <= 60e-6, f"nut position {pos * 1e3:.4f} mm within 60 um of 25 mm")

    # mbpoll, an independent client, reads the word-order probes and a value.
    out = mbpoll(port, "-t", "3:hex", "-r", "4", "-c", "2")
    check("0x1234" in out and "0x5678" in out, "mbpoll reads the u32 probe high word first")
    out = mbpoll(port, "-t", "3:float", "-B", "-r", "6", "-c", "1")
    check("1234.57" in out, "mbpoll -B (high word first) reads the f32 probe as 1234.57")
    out = mbpoll(port, "-t", "3:int", "-B", "-r", "4", "-c", "1")
    check("305419896" in out, "mbpoll -B reads the u32 probe as 0x12345678")
    out = mbpoll(port, "-t", "3", "-r", "200", "-c", "1")
    check("Illegal data address" in out, "mbpoll sees exception 02 for an unmapped address")
    out = mbpoll(port, "-t", "4", "-r", str(MODE), write=1)
    check("Illegal" in out or "busy" in out.lower() or "fail" in out.lower(), f"mbpoll as non-owner is refused")

    # Robustness: malformed frames, stalled and vanishing clients.
    bad = socket.create_connection(("127.0.0.1", port), timeout=2)
    bad.sendall(struct.pack(">HHHB", 1, 5, 6, 1) + struct.pack(">BHH", 3, 10, 1))  # protocol id 5
    check(bad.recv(16) == b"", "a frame with a wrong protocol id closes that connection")
    bad.close()
    bad = socket.create_connection(("127.0.0.1", port), timeout=2)
    bad.sendall(struct.pack(">HHHB", 1, 0, 400, 1) + b"\x03")  # impossible length
    check(bad.recv(16) == b"", "a frame with an impossible length closes that connection")
    bad.close()
    stalled = socket.create_connection(("127.0.0.1", port), timeout=2)
    stalled.sendall(struct.pack(">HHHB", 9, 0, 6, 1) + b"\x03\x00")  # half a request, then silence
    vanished = socket.create_connection(("127.0.0.1", port), timeout=2)
    vanished.sendall(struct.pack(">HHHB", 9, 0, 6, 1) + b"\x03")
    vanished.close()  # gone mid-request
    t0 = time.perf_counter()
    rr = other.read_input_registers(10, 16, slave=UNIT)
    dt = time.perf_counter() - t0
    check(not rr.isError() and dt < 0.25, f"others are served beside a stalled client, well inside its 0.5 s frame timeout ({dt * 1e3:.1f} ms)")
    time.sleep(0.8)
    stalled.settimeout(1.0)
    try:
        closed = stalled.recv(16) == b""
    except (socket.timeout, ConnectionResetError):
        closed = False
    check(closed, "the stalled connection is closed after the frame timeout")
    stalled.close()
    # Pipelined requests on one connection are all answered, in order.
    with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
        s.sendall(b"".join(struct.pack(">HHHB", t, 0, 6, 1) + struct.pack(">BHH", 4, 0, 1) for t in (1, 2, 3)))
        answers = [read_response(s, t) for t in (1, 2, 3)]
        check(all(a == bytes([4, 2, 0x4D, 0x4C]) for a in answers), "three pipelined requests, three answers")

    # 16 clients at once.
    results = []

    def hammer():
        cl = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
        ok = cl.connect()
        for _ in range(50):
            r = cl.read_input_registers(10, 16, slave=UNIT)
            ok = ok and not r.isError()
        cl.close()
        results.append(ok)
    threads = [threading.Thread(target=hammer) for _ in range(16)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(20)
    check(len(results) == 16 and all(results), "16 concurrent clients, 50 reads each, all answered")

    # The owner leaves (position mode): owner loss is a fault, the drive holds position.
    c.close()
    check(wait_alarm(other, 7), "owner gone: drive faulted with alarm owner_lost")
    rr = other.read_input_registers(10, 46, slave=UNIT)
    check(rr.registers[3] == 3 and rr.registers[44] == 2, f"reaction in position mode: holding ({rr.registers[44]})")
    rsp = other.write_register(MODE, 0, slave=UNIT)
    check(not rsp.isError(), "after the owner disconnects another client may write")
    # Writing first does not take over: enable + execute at once leaves the drive in fault.
    other.write_register(CW, ENABLE | EXECUTE, slave=UNIT)
    time.sleep(0.05)
    check(other.read_input_registers(13, 1, slave=UNIT).registers[0] == 3, "a write does not re-enable the drive")
    other.write_register(CW, 0, slave=UNIT)
    other.close()
    owner_loss_releases_force(port)
    half_close(port)
    idle_flood(port)
    non_reader(port)


def wait_alarm(client, alarm, timeout=2.0):
    end = time.time() + timeout
    while time.time() < end:
        rr = client.read_input_registers(11, 1, slave=UNIT)
        if not rr.isError() and rr.registers[0] == alarm:
            return True
        time.sleep(0.01)
    return False


def owner_loss_releases_force(port):
    """Findings 1 and 2 end to end: a PLC holding 20 N against the 3000 N/m spring goes away;
    the drive releases the force (load cell), and a new client must reset and claim."""
    plc = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
    check(plc.connect(), "PLC connects")
    plc.write_register(CW, RESET, slave=UNIT)  # clear the previous owner_lost fault
    plc.write_register(CW, 0, slave=UNIT)
    plc.write_registers(FORCE_F32, f32_words(20.0), slave=UNIT)
    plc.write_register(MODE, 2, slave=UNIT)
    check(not plc.write_register(CW, ENABLE, slave=UNIT).isError(), "PLC claims with an enable edge")
    plc.write_register(CW, ENABLE | EXECUTE, slave=UNIT)
    plc.write_register(CW, ENABLE, slave=UNIT)
    check(wait_status(plc, ST_FORCE_REACHED), "PLC: 20 N reached")
    time.sleep(0.5)
    before = words_i32(plc.read_input_registers(30, 2, slave=UNIT).registers) * 1e-3
    check(before > 12.0, f"load cell carries the force before: {before:.2f} N")
    plc.close()  # cable pulled / PLC stopped: the connection closes
    obs = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
    obs.connect()
    check(wait_alarm(obs, 7), "drive faulted with alarm owner_lost")
    end = time.time() + 3
    while time.time() < end and obs.read_input_registers(54, 1, slave=UNIT).registers[0] != 3:
        time.sleep(0.02)
    check(obs.read_input_registers(54, 1, slave=UNIT).registers[0] == 3, "reaction: force released")
    time.sleep(0.5)
    after = words_i32(obs.read_input_registers(30, 2, slave=UNIT).registers) * 1e-3
    check(abs(after) < 8.5, f"load cell after the reaction {after:.2f} N (Coulomb friction 7.5 N holds the rest)")
    obs.close()


def mbpoll(port, *args, write=None):
    cmd = ["mbpoll", "-1", "-0", "-a", str(UNIT), "-p", str(port), "-o", "1", *args, "127.0.0.1"]
    if write is not None:
        cmd.append(str(write))
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=10)
    return p.stdout + p.stderr


def allow_list_and_cap():
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--allow", "10.0.0.0/8")
    try:
        try:
            closed = raw_request(srv.port, struct.pack(">BHH", 4, 0, 1)) is None
        except (ConnectionResetError, BrokenPipeError):
            closed = True
        check(closed, "a client not on the allow-list is disconnected unanswered")
    finally:
        srv.stop()
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--max-connections", "2")
    try:
        # At the cap the connection idle longest makes room (finding 5): idle connections
        # cannot lock a PLC out.
        held = [socket.create_connection(("127.0.0.1", srv.port), timeout=2) for _ in range(2)]
        time.sleep(0.1)
        check(raw_request(srv.port, struct.pack(">BHH", 4, 0, 1)) == bytes([4, 2, 0x4D, 0x4C]),
              "a connection at the cap is served: the idle one makes room")
        try:
            evicted = held[0].recv(16) == b""
        except (ConnectionResetError, socket.timeout):
            evicted = False
        check(evicted, "the connection idle longest was closed for it")
        # Accepted in one wake-up of the server, both carry the same clock reading: the order
        # they came in still decides, so the younger one stays open and is served.
        held[1].sendall(struct.pack(">HHHB", 7, 0, 6, 1) + struct.pack(">BHH", 4, 0, 1))
        try:
            kept = read_response(held[1], 7) == bytes([4, 2, 0x4D, 0x4C])
        except (ConnectionResetError, socket.timeout, AssertionError):
            kept = False
        check(kept, "the other idle connection stays open and is served")
        # The owner and a connection with a request under way are never evicted.
        owner = socket.create_connection(("127.0.0.1", srv.port), timeout=2)
        owner.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 6, CW, ENABLE))
        read_response(owner, 1)
        busy = socket.create_connection(("127.0.0.1", srv.port), timeout=2)
        busy.sendall(struct.pack(">HHHB", 9, 0, 6, 1) + b"\x04")  # half a request
        time.sleep(0.1)
        try:
            refused = raw_request(srv.port, struct.pack(">BHH", 4, 0, 1)) is None
        except (ConnectionResetError, BrokenPipeError):
            refused = True
        check(refused, "at the cap with nobody idle (owner, a request under way): refused")
        for h in held + [owner, busy]:
            h.close()
    finally:
        srv.stop()


def half_close(port):
    """Finding 3: a client that sends a request and shuts down its sending side gets its reply."""
    ok = 0
    for t in range(50):
        with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
            s.sendall(b"".join(struct.pack(">HHHB", t * 2 + k, 0, 6, 1) + struct.pack(">BHH", 4, 0, 1) for k in (0, 1)))
            s.shutdown(socket.SHUT_WR)
            if all(read_response(s, t * 2 + k) == bytes([4, 2, 0x4D, 0x4C]) for k in (0, 1)) and s.recv(16) == b"":
                ok += 1
    check(ok == 50, f"half-close after two requests: both answered, then closed, in {ok} of 50 trials")


def idle_flood(port):
    """Finding 5 with the defaults: 65 idle connections, then the PLC still gets in."""
    idle = []
    for _ in range(65):
        try:
            idle.append(socket.create_connection(("127.0.0.1", port), timeout=2))
        except OSError:
            break
    time.sleep(0.2)
    plc = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
    rr = plc.read_input_registers(0, 1, slave=UNIT) if plc.connect() else None
    check(rr is not None and not rr.isError() and rr.registers[0] == 0x4D4C,
          "after 65 idle connections (cap 32) a PLC connects and is served")
    plc.close()
    for s in idle:
        s.close()


def non_reader(port):
    """Finding 6: a client that never reads its replies is dropped after a bounded backlog; the
    server does not keep answering it while others wait."""
    def counter():
        rsp = raw_request(port, struct.pack(">BHH", 8, 0x0B, 0))
        return struct.unpack(">H", rsp[3:5])[0]
    before = counter()
    hog = socket.socket()
    hog.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    hog.connect(("127.0.0.1", port))
    hog.setblocking(False)
    req = struct.pack(">HHHBBHH", 1, 0, 6, 1, 4, 0, 124)  # reply: 257 bytes
    sent, dropped = 0, False
    end = time.time() + 10
    while sent < 20000 and time.time() < end:  # replies for up to 5 MB
        try:
            sent += hog.send(req * 16) // len(req)
        except BlockingIOError:
            time.sleep(0.01)
        except (ConnectionResetError, BrokenPipeError):
            dropped = True
            break
    if not dropped:
        try:
            hog.setblocking(True)
            hog.settimeout(2)
            hog.sendall(req)
            time.sleep(0.3)
            hog.sendall(req)
        except (ConnectionResetError, BrokenPipeError):
            dropped = True
    hog.close()
    answered = counter() - before - 1
    check(dropped, f"a client that never reads is dropped (it sent {sent} requests)")
    check(answered <= 1000, f"the server answered it at most 1000 times before dropping it ({answered})")


def read_only_server():
    srv = Server(MAGLEAD, CONFIG, "--port", "0", "--read-only")
    try:
        check(exc_code(raw_request(srv.port, struct.pack(">BHH", 6, MODE, 1))) == 1,
              "read-only server: writes get exception 01")
        check(raw_request(srv.port, struct.pack(">BHH", 4, 0, 1)) == bytes([4, 2, 0x4D, 0x4C]),
              "read-only server still reads")
    finally:
        srv.stop()


if __name__ == "__main__":
    main()
