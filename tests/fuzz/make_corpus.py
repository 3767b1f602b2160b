#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz targets (tests/fuzz/corpus/NAME/), each in its target's
input format: core (fuzz_modbus_core: valid requests of every implemented function as records
[flags][len][PDU]), tcp and rtu (the framers: request streams), recording (the reader: small
recordings) and config (the TOML readers: [reader byte] + the files of config/). Run it after
changing the seeds; the files are checked in so that tools/fuzz.sh needs no generation step."""
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "controller"))
from modbus_common import crc16  # noqa: E402  (the one Modbus RTU CRC of the tests)
CONFIG = os.path.join(HERE, "..", "..", "config")


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



def mbap(pdu, tid=1, unit=1):
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def rtu(pdu, unit=1):
    return bytes([unit]) + pdu + crc16(bytes([unit]) + pdu)


# Requests as PDUs (function code first), for the framers.
PDUS = [bytes([3]) + u16(0, 8), bytes([16]) + u16(1012, 2) + bytes([4]) + f32(5.0),
        bytes([23]) + u16(0, 8) + u16(1002, 1) + bytes([2]) + u16(3), bytes([43, 0x0E, 1, 0]),
        bytes([8]) + u16(0, 0x1234), bytes([15]) + u16(0, 2) + bytes([1, 0x01]), bytes([6]) + u16(1002, 9)]

# fuzz_tcp_framer: [chunk][stream]; fuzz_rtu_framer: [chunk][silences][stream].
TCP = {
    "one_read_whole": bytes([15]) + mbap(PDUS[0]),
    "pipelined_bytewise": bytes([0]) + b"".join(mbap(p, tid=i) for i, p in enumerate(PDUS)),
    "pipelined_in_fives": bytes([4]) + b"".join(mbap(p, tid=i, unit=255) for i, p in enumerate(PDUS)),
    "bad_protocol_after_one": bytes([7]) + mbap(PDUS[0]) + struct.pack(">HHHB", 2, 1, 6, 1) + PDUS[0],
}
RTU = {
    "every_function_silent_after_each": bytes([15, 0xFF]) + b"".join(rtu(p) for p in PDUS),
    "back_to_back_bytewise": bytes([0, 0x00]) + b"".join(rtu(p) for p in PDUS),
    "unknown_function_then_read": bytes([6, 0x01]) + rtu(bytes([0x41, 1, 2])) + rtu(PDUS[0]),
    "broadcast_write_and_bad_crc": bytes([7, 0x55]) + rtu(PDUS[6], unit=0) + rtu(PDUS[0])[:-1] + b"\0",
}

HEADER = "t_s,motor_angle_rad,nut_pos_m,force_cmd_n,load_force_n"
RECORDING = {
    "actuator": "# format: mls-recording/1\n# source: maglead record\n# sample_rate_hz: 1000\n"
    + HEADER + "\n0,0,0.02,0,0.1\n0.001,0.0012,0.0200001,1.5,-0.2\n0.002,0.0025,,3,\n",
    "crlf_comment_and_spaces": "# format: mls-recording/1\r\n" + HEADER + "\r\n0, 0 ,0.02,+1,2\r\n"
    "# a comment\r\n\r\n0.001,1e-3,2E-2,-0,0\r\n",
    "no_time_column": "a,b\n1,2\n3,\n",
    "equal_times_no_newline": "t_s,x\n0,1\n0,2\n0.5,3",
}


def without_comments(text):
    """The file without its comment lines and inline comments (the format line stays): mutations
    then land on keys and values instead of prose."""
    lines = []
    for line in text.splitlines():
        if line.startswith("# format:") or not line.lstrip().startswith("#"):
            line = line.split(" #")[0].rstrip()
            if line:
                lines.append(line)
    return "\n".join(lines) + "\n"


def config_seeds():
    """[reader] + file: 0 actuator, 1 calibration, 2 network, 3 model (model.toml, emps_baseline),
    each as in config/ and without its comments."""
    seeds = {}
    for reader, name in enumerate(["actuator", "calibration", "network", "model", "emps_baseline"]):
        with open(os.path.join(CONFIG, name + ".toml"), "rb") as f:
            text = f.read()
        seeds[name] = bytes([min(reader, 3)]) + text
        seeds[name + "_bare"] = bytes([min(reader, 3)]) + without_comments(text.decode()).encode()
    seeds["model_with_terms"] = bytes([3]) + (
        b'# format: maglead-model/1\n[model]\nsource = "fuzz seed"\nnut_mass_kg = 0.1\n'
        b'fit = ["coulomb_n"]\n[[term]]\nid = "offset"\nnote = "a note"\noffset_n = -3.5\n'
        b'[[term]]\nid = "offset"\nenabled = false\noffset_n = 1\n')
    seeds["network_allow"] = bytes([2]) + b'[tcp]\nport = 0\nallow = ["10.0.0.0/8", "127.0.0.1"]\n'
    # Found by the fuzzer: finite coefficients whose curve overflows at the stable branch's edge.
    seeds["calibration_peak_overflow"] = bytes([1]) + (
        b'[calibration]\n'
        b'source = "paper eq. 7"\n'
        b'polynomial_coeffs_ascending = [-4.28, -47.6,1e308, 8.51, -8.209, -0.306]\n'
        b'periodic_mean_n = -0.2889549456\n'
        b'periodic_cos_n = [-3.227697857, -1.028128596, 0.2828951553]\n'
        b'periodic_sin_n = [-44.04634468, -2.912053278, 0.9283163344]\n')
    return seeds


def config_dict():
    """libFuzzer dictionary of the TOML readers: every key and section name of config/, and TOML's
    own tokens."""
    words = {"[[term]]", "=", "true", "false", "inf", "-inf", "nan", "[", "]", "\"\"", "1e308", "-0.0"}
    for name in os.listdir(CONFIG):
        with open(os.path.join(CONFIG, name)) as f:
            for line in f:
                line = line.split(" #")[0].strip()
                if line.startswith("[") and not line.startswith("[["):
                    words.add(line)
                elif "=" in line and not line.startswith("#"):
                    words.add(line.split("=")[0].strip())
    return sorted(w for w in words if w)


def write_dict(corpus, words):
    with open(os.path.join(HERE, "corpus", corpus + ".dict"), "w") as f:
        f.write("".join('"' + w.replace("\\", "\\\\").replace('"', '\\"') + '"\n' for w in words))


def write(corpus, seeds):
    directory = os.path.join(HERE, "corpus", corpus)
    os.makedirs(directory, exist_ok=True)
    for name, data in seeds.items():
        with open(os.path.join(directory, name), "wb") as f:
            f.write(data if isinstance(data, bytes) else data.encode())


if __name__ == "__main__":
    write("core", SEEDS)
    write("tcp", TCP)
    write("rtu", RTU)
    write("recording", RECORDING)
    write("config", config_seeds())
    write_dict("config", config_dict())
