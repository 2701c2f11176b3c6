#!/usr/bin/env python3
"""A real Modbus TCP server (pymodbus) with known registers, for truepos's Modbus source tests.

Usage: .venv/bin/python scripts/modbus_server.py PORT
Listens on 127.0.0.1:PORT only (loopback), device (unit) id 1, until killed.

Holding registers (function 03), protocol addresses (0-based):
  0: 0x00F1  int16 x0.1  ->  24.1      1: 0xFF38  int16 x0.1  -> -20.0
  2: 0x0929  int16 x0.01 ->  23.45     3: 0xF830  int16 x0.01 -> -20.00
  4-5: 0x41BC 0x0000  float32, high word first -> 23.5
  6-7: 0x0000 0x41BC  float32, low word first  -> 23.5
  8: 0x1234  uint16 -> 4660
  9: a counter that grows by one on every read that includes it
Input registers (function 04):
  0: 0x00F2  int16 x0.1 -> 24.2        1-2: 0x41AA 0x0000 float32 high word first -> 21.25
Every other address is invalid: reading it answers exception 02 (illegal data address).
"""

import asyncio
import logging
import sys

from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

COUNTER_ADDRESS = 9


async def count_reads(function_code, start_address, address, count, current_registers, set_values):
    """Advance the counter register whenever a read of holding registers covers it."""
    if function_code == 3 and address <= COUNTER_ADDRESS < address + count:
        index = COUNTER_ADDRESS - start_address
        if 0 <= index < len(current_registers):
            current_registers[index] = (current_registers[index] + 1) & 0xFFFF
    return None


def device() -> SimDevice:
    holding = [0x00F1, 0xFF38, 0x0929, 0xF830, 0x41BC, 0x0000, 0x0000, 0x41BC, 0x1234, 0]
    inputs = [0x00F2, 0x41AA, 0x0000]
    return SimDevice(
        id=1,
        simdata=(
            [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
            [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
            [SimData(0, values=holding, datatype=DataType.REGISTERS)],
            [SimData(0, values=inputs, datatype=DataType.REGISTERS)],
        ),
        action=count_reads,
    )


async def main(port: int) -> None:
    server = ModbusTcpServer(device(), address=("127.0.0.1", port))
    await server.serve_forever()


if __name__ == "__main__":
    logging.basicConfig(level=logging.ERROR)
    if len(sys.argv) != 2:
        sys.exit("usage: modbus_server.py PORT")
    asyncio.run(main(int(sys.argv[1])))
