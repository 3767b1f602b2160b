"""`maglead serve` over Modbus RTU through a socat pseudo-terminal pair (8E1, 19200 baud),
driven by pymodbus, mbpoll and raw frames: reads, writes, exceptions, FC8/FC43, broadcast
writes honoured without reply, other unit ids and bad CRCs ignored.
Usage: modbus_rtu_integration.py MAGLEAD_BIN CONFIG_DIR"""
import os
import struct
import subprocess
import sys
import time

import select
from modbus_common import check, crc16, f32_words, finish, rtu_server, watchdog, words_f32
from pymodbus.client import ModbusSerialClient
from pymodbus.diag_message import ReturnQueryDataRequest
from pymodbus.mei_message import ReadDeviceInformationRequest

MAGLEAD, CONFIG = sys.argv[1], sys.argv[2]
UNIT = 3


def raw(port, frame, wait=0.3, crc=None):
    """Sends one RTU frame (CRC appended) and returns whatever comes back within `wait`.
    The pty is used as it is (socat made it raw): pyserial's termios set-up fails on it."""
    fd = os.open(port, os.O_RDWR | os.O_NOCTTY)
    try:
        while select.select([fd], [], [], 0)[0]:
            os.read(fd, 256)
        os.write(fd, frame + (crc16(frame) if crc is None else crc))
        out = b""
        end = time.time() + wait
        while time.time() < end:
            if select.select([fd], [], [], max(0.0, end - time.time()))[0]:
                out += os.read(fd, 256)
        return out
    finally:
        os.close(fd)


def main():
    watchdog(90)
    with rtu_server(MAGLEAD, CONFIG, UNIT, "maglead-rtu-") as (srv, dev_b):
        check(any("Modbus RTU on" in l and "8E1" in l for l in srv.lines), f"serve reports RTU 8E1 {srv.lines}")
        run(dev_b)
    finish()


def run(dev):
    # strict=False: a pty refuses the inter-byte timeout strict mode would set (EINVAL).
    c = ModbusSerialClient(port=dev, baudrate=19200, parity="E", stopbits=1, bytesize=8, timeout=1, strict=False)
    check(c.connect(), "pymodbus opens the serial line")
    rr = c.read_input_registers(0, 8, slave=UNIT)
    check(not rr.isError() and rr.registers[0] == 0x4D4C and rr.registers[4:6] == [0x1234, 0x5678],
          "identity and word-order probe over RTU")
    t0 = time.perf_counter()
    rr = c.read_input_registers(200, 1, slave=UNIT)
    dt = time.perf_counter() - t0
    check(rr.isError() and getattr(rr, "exception_code", None) == 2 and dt < 0.3,
          f"exception 02 over RTU, answered at once ({dt * 1e3:.0f} ms)")
    rsp = c.execute(ReturnQueryDataRequest(0x1234, unit=UNIT))
    check(not rsp.isError() and tuple(rsp.message) == (0x1234,), "FC8 echo over RTU")
    rsp = c.execute(ReadDeviceInformationRequest(read_code=1, object_id=0, unit=UNIT))
    check(not rsp.isError() and rsp.information.get(0) == b"maglead project", "FC43/14 over RTU")

    # Writes: enable, a force setpoint in float32, read back.
    check(not c.write_registers(1012, f32_words(7.5), slave=UNIT).isError(), "FC16 over RTU")
    rr = c.read_holding_registers(1012, 2, slave=UNIT)
    check(words_f32(rr.registers) == 7.5, "setpoint reads back")
    check(not c.write_register(1000, 1, slave=UNIT).isError(), "enable over RTU")
    time.sleep(0.05)
    rr = c.read_input_registers(13, 1, slave=UNIT)
    check(rr.registers[0] == 2, "drive enabled")
    c.close()

    # Raw frames: broadcast write acts without a reply; other units and bad CRCs get nothing.
    reply = raw(dev, struct.pack(">BBHHBHH", 0, 16, 1012, 2, 4, *f32_words(2.5)))
    check(reply == b"", "broadcast setpoint write: no reply")
    reply = raw(dev, struct.pack(">BBHH", UNIT, 3, 1012, 2))
    check(reply[:7] == bytes([UNIT, 3, 4, 0x40, 0x20, 0, 0]), "broadcast setpoint write was honoured")
    # Finding 7: the enable coil by broadcast does not enable the drive (nor does mode change).
    reply = raw(dev, struct.pack(">BBHH", UNIT, 6, 1000, 0))
    check(reply[:6] == struct.pack(">BBHH", UNIT, 6, 1000, 0), "disabled by a write addressed to the unit")
    check(raw(dev, struct.pack(">BBHH", 0, 5, 0, 0xFF00)) == b"", "broadcast enable coil: no reply")
    check(raw(dev, struct.pack(">BBHH", 0, 6, 1001, 2)) == b"", "broadcast mode write: no reply")
    reply = raw(dev, struct.pack(">BBHH", UNIT, 4, 13, 1))
    check(reply[:5] == bytes([UNIT, 4, 2, 0, 1]), f"broadcast enable refused: drive still ready ({reply[:5].hex()})")
    reply = raw(dev, struct.pack(">BBHH", UNIT, 3, 1000, 2))
    check(reply[3:7] == bytes([0, 0, 0, 0]), "control word and mode unchanged by broadcast")
    reply = raw(dev, struct.pack(">BBHH", UNIT, 4, 55, 1))
    check(reply[:5] == bytes([UNIT, 4, 2, 0, 2]), "write_refusal_reason: broadcast_state_change")
    check(raw(dev, struct.pack(">BBHH", 0, 4, 0, 1)) == b"", "broadcast read: ignored")
    check(raw(dev, struct.pack(">BBHH", UNIT + 1, 4, 0, 1)) == b"", "other unit id: ignored")
    check(raw(dev, struct.pack(">BBHH", UNIT, 4, 0, 1), crc=b"\x00\x00") == b"", "bad CRC: ignored")
    reply = raw(dev, struct.pack(">BBHH", UNIT, 8, 0x0C, 0))
    check(len(reply) >= 7 and reply[:3] == bytes([UNIT, 8, 0]) and struct.unpack(">H", reply[4:6])[0] >= 1,
          "FC8 bus communication error counter counted the bad CRC")
    reply = raw(dev, struct.pack(">BBHH", UNIT, 4, 0, 1))
    check(reply[:5] == bytes([UNIT, 4, 2, 0x4D, 0x4C]) and reply[5:7] == crc16(reply[:5]),
          "served normally after the bad frame, reply CRC correct")

    # Finding 4: a frame cut short is discarded after t3.5 of silence (2.0 ms at 19200 8E1); the
    # next request, 30 ms later, is answered (before: swallowed for ~200 ms).
    fd = os.open(dev, os.O_RDWR | os.O_NOCTTY)
    try:
        answered = 0
        for _ in range(10):
            good = struct.pack(">BBHH", UNIT, 4, 0, 1)
            os.write(fd, (good + crc16(good))[:5])  # truncated: 5 of 8 bytes
            time.sleep(0.03)
            os.write(fd, good + crc16(good))
            out = b""
            end = time.time() + 0.5
            while len(out) < 7 and time.time() < end:
                if select.select([fd], [], [], 0.05)[0]:
                    out += os.read(fd, 256)
            answered += out[:5] == bytes([UNIT, 4, 2, 0x4D, 0x4C])
            time.sleep(0.01)
    finally:
        os.close(fd)
    check(answered == 10, f"after a truncated frame and silence, the next request is answered ({answered} of 10)")

    out = subprocess.run(["mbpoll", "-1", "-0", "-m", "rtu", "-b", "19200", "-P", "even", "-a", str(UNIT),
                          "-t", "3:hex", "-r", "4", "-c", "2", "-o", "1", dev],
                         capture_output=True, text=True, timeout=10)
    check("0x1234" in out.stdout and "0x5678" in out.stdout, "mbpoll over RTU reads the probe")


if __name__ == "__main__":
    main()
