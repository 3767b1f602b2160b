#!/usr/bin/env python3
"""Issue 22 live: the force a PLC asks for arrives at the load. `maglead serve` (simulated plant,
default 2000 N/m spring) with pymodbus as the PLC: force mode, the setpoints 5, 10, 15, 20, -5,
-10, -15, 12, 8, 3, 0, 18, 6 N through the float32 setpoint and an execute edge, 2 s to settle,
then 0.5 s of load-cell reads at ~100 Hz. The load cell is read here only to check; nothing in
the controller reads it. Passes when the load receives the setpoint within 1.0 N on average and
2.0 N at worst, and force_reached is never set while the load is more than 1.5 N off.

Usage: force_at_load_live.py MAGLEAD_BIN CONFIG_DIR"""
import sys
import time

from modbus_common import Server, check, f32_words, finish, watchdog, words_f32
from pymodbus.client import ModbusTcpClient

MAGLEAD, CONFIG = sys.argv[1], sys.argv[2]
UNIT = 1
CW, MODE, FORCE_F32 = 1000, 1001, 1012
ENABLE, EXECUTE = 1, 16
STATUS, LOAD_CELL_F32, OBSERVER_F32 = 10, 110, 128
FORCE_REACHED = 1 << 5
SETPOINTS = [5, 10, 15, 20, -5, -10, -15, 12, 8, 3, 0, 18, 6]


def f32(client, addr):
    return words_f32(client.read_input_registers(addr, 2, slave=UNIT).registers)


def main():
    watchdog(90)
    srv = Server(MAGLEAD, CONFIG, "--port", "0")
    plc = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=2)
    check(plc.connect(), f"PLC connected to port {srv.port}")
    plc.write_register(MODE, 2, slave=UNIT)
    plc.write_registers(FORCE_F32, f32_words(0.0), slave=UNIT)
    plc.write_register(CW, ENABLE, slave=UNIT)
    errors, reached_off = [], 0
    for sp in SETPOINTS:
        plc.write_registers(FORCE_F32, f32_words(float(sp)), slave=UNIT)
        plc.write_register(CW, ENABLE | EXECUTE, slave=UNIT)
        plc.write_register(CW, ENABLE, slave=UNIT)
        time.sleep(2.0)
        loads, estimates = [], []
        end = time.time() + 0.5
        while time.time() < end:
            loads.append(f32(plc, LOAD_CELL_F32))
            status = plc.read_input_registers(STATUS, 1, slave=UNIT).registers[0]
            if status & FORCE_REACHED and abs(loads[-1] - sp) > 1.5:
                reached_off += 1
            estimates.append(f32(plc, OBSERVER_F32))
            time.sleep(0.01)
        load = sum(loads) / len(loads)
        errors.append(abs(load - sp))
        print(f"set {sp:6.1f} N  load {load:7.2f} N  error {errors[-1]:5.2f} N  "
              f"observer {sum(estimates) / len(estimates):7.2f} N", flush=True)
    plc.close()
    srv.stop()
    mean, worst = sum(errors) / len(errors), max(errors)
    check(mean <= 1.0, f"load force within 1.0 N of the setpoint on average ({mean:.2f} N)")
    check(worst <= 2.0, f"and within 2.0 N at worst ({worst:.2f} N)")
    check(reached_off == 0, f"force_reached never set while the load was > 1.5 N off ({reached_off} polls)")
    finish()


if __name__ == "__main__":
    main()
