#!/usr/bin/env python3
"""Writes the seed corpus of fuzz_modbus_core (tests/fuzz/corpus/core/): valid requests of every
implemented function, in the target's record format [flags][len][PDU]. Run it after changing
the seeds; the files are checked in so that tools/fuzz.sh needs no generation step."""
import os
import struct

CORPUS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "core")


def rec(pdu, flags=0):
    """flags & 3: client (0 TCP 1, 1 TCP 2, 2 RTU, 3 RTU broadcast); flags & 4: close it first."""
    return bytes([flags, len(pdu)]) + pdu


def u16(*values):
    return b"".join(struct.pack(">H", v) for v in values)


def f32(x):
    return struct.pack(">f", x)


SEEDS = {
    "fc03_read_identity": rec(bytes([3]) + u16(0, 8)),
    "fc04_read_inputs": rec(bytes([4]) + u16(0, 8)),
    "fc03_read_image": rec(bytes([3]) + u16(1000, 20)),
    "fc06_heartbeat": rec(bytes([6]) + u16(1002, 7)),
    "fc06_watchdog": rec(bytes([6]) + u16(1003, 500)),
    "fc16_force_f32": rec(bytes([16]) + u16(1012, 2) + bytes([4]) + f32(5.0)),
    "fc16_position_um": rec(bytes([16]) + u16(1006, 2) + bytes([4]) + struct.pack(">i", 25000)),
    "fc23_write_heartbeat_read_status": rec(bytes([23]) + u16(0, 8) + u16(1002, 1) + bytes([2]) + u16(3)),
    "fc01_read_coils": rec(bytes([1]) + u16(0, 5)),
    "fc02_read_discrete_inputs": rec(bytes([2]) + u16(0, 14)),
    "fc05_enable": rec(bytes([5]) + u16(0, 0xFF00)),
    "fc15_enable_stop": rec(bytes([15]) + u16(0, 2) + bytes([1, 0x01])),
    "fc08_echo": rec(bytes([8]) + u16(0, 0x1234)),
    "fc08_bus_messages": rec(bytes([8]) + u16(0x0B, 0)),
    "fc43_basic_identity": rec(bytes([43, 0x0E, 1, 0])),
    "fc43_individual_model": rec(bytes([43, 0x0E, 4, 5])),
    # Client 1 claims control, stages a position move and executes it; client 2 is refused;
    # client 1's connection closes (owner loss).
    "session_move_and_owner_loss": rec(bytes([6]) + u16(1001, 1))
    + rec(bytes([6]) + u16(1000, 1))
    + rec(bytes([16]) + u16(1014, 2) + bytes([4]) + f32(0.03))
    + rec(bytes([6]) + u16(1000, 0x11))
    + rec(bytes([6]) + u16(1002, 1), 1)
    + rec(bytes([3]) + u16(0, 8), 4),
    "rtu_broadcast_setpoint": rec(bytes([6]) + u16(1002, 9), 3) + rec(bytes([6]) + u16(1000, 1), 3),
}

if __name__ == "__main__":
    os.makedirs(CORPUS, exist_ok=True)
    for name, data in SEEDS.items():
        with open(os.path.join(CORPUS, name), "wb") as f:
            f.write(data)
