#!/usr/bin/python3
"""Stand-in for a Modbus TCP temperature module in scripts/linuxcnc_sensors_hal.sh: answers
function 3 (read holding registers) and 4 (read input registers) of any unit id with the
registers given on the command line (0.1 °C each), every other function with exception 1.

    modbus_temperatures.py PORT 215,221,198,…"""
import socketserver
import struct
import sys

REGISTERS = [int(v) for v in sys.argv[2].split(",")]


class Handler(socketserver.BaseRequestHandler):
    def handle(self):
        while True:
            head = self.request.recv(7)
            if len(head) < 7:
                return
            tid, _, length, unit = struct.unpack(">HHHB", head)
            pdu = self.request.recv(length - 1)
            if pdu and pdu[0] in (3, 4):
                start, count = struct.unpack(">HH", pdu[1:5])
                data = b"".join(
                    struct.pack(">H", REGISTERS[i] if i < len(REGISTERS) else 0)
                    for i in range(start, start + count)
                )
                body = bytes([pdu[0], len(data)]) + data
            else:
                body = bytes([(pdu[0] if pdu else 0) | 0x80, 1])
            self.request.sendall(struct.pack(">HHHB", tid, 0, len(body) + 1, unit) + body)


socketserver.ThreadingTCPServer.allow_reuse_address = True
socketserver.ThreadingTCPServer.daemon_threads = True
socketserver.ThreadingTCPServer(("127.0.0.1", int(sys.argv[1])), Handler).serve_forever()
