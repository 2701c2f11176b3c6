#!/usr/bin/env python3
"""A simulated control behind a real OPC UA server (asyncua), for truepos's OPC UA tests.

Usage: .venv/bin/python scripts/opcua_control.py --port PORT --pki DIR --record OUT.csv [options]

Listens on 127.0.0.1:PORT only (loopback) until killed or --duration-s passes. Its address
space imitates a SINUMERIK's (every node a string id in ns=2), per axis u = 1, 2, 3 (X, Y, Z):
  /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_ABS_VALUE[u<u>]    K0, mm (Double, writable)
  /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_SLOPE[u<u>]        tanβ (Double, writable)
  /NC/_N_AX_SEA_ACX/$SA_TEMP_COMP_REF_POSITION[u<u>] P0, mm (Double, writable)
  /Channel/MachineAxis/actToolBasePos[u1,<u>]        the axis position, mm (Double)
  /NC/_N_AX_SEA_ACX/$SA_INT_NODE[u1]                 an Int32 node (a write of a Double is
                                                     refused with BadTypeMismatch)
and per --temp NAME=VALUE a temperature /Plc/Temp/NAME (Double, °C).

The control: X moves back and forth over --travel-x at --speed mm/s (Y and Z stand at
--pos-y and --pos-z); every --tick-ms it applies, per axis, the temperature compensation
dK = K0 + tanβ·(P − P0) from the values the client wrote, as SINUMERIK does (function manual
K3), and appends t, the positions, K0, tanβ, P0 and dK of every axis to --record (CSV, flushed
every line).

Security: endpoints None, Basic256Sha256 Sign and SignAndEncrypt; the server's certificate
(DIR/server_cert.der, made on first use) carries the application URI urn:truepos:sim-control,
as the server announces it (conforming clients refuse a mismatch), and the host name 127.0.0.1
the clients connect to. Users: --user NAME:PASSWORD
(may write), --reader NAME:PASSWORD (may open a session and read; writes are refused with
BadUserAccessDenied, like a SINUMERIK user without the SeaWrite realm); anonymous sessions only
with --anonymous. --slow-ms delays every Write by that much (a slow server). --bad-temp
NAME@SECONDS gives temperature NAME the status BadSensorFailure from that time on (its value
stays as it was, as a server keeps a failed sensor's last value).
"""

import argparse
import asyncio
import logging
import sys
import time
from pathlib import Path

from asyncua import Server, ua
from asyncua.crypto.cert_gen import setup_self_signed_certificate
from asyncua.server.user_managers import UserManager
from asyncua.crypto.permission_rules import User, UserRole
from cryptography.x509.oid import ExtendedKeyUsageOID

APP_URI = "urn:truepos:sim-control"
AXES = ("X", "Y", "Z")
SEA = "/NC/_N_AX_SEA_ACX/"


class Users(UserManager):
    """Writers and readers by name and password; anonymous only when allowed."""

    def __init__(self, writers, readers, anonymous):
        self.writers = writers
        self.readers = readers
        self.anonymous = anonymous

    def get_user(self, iserver, username=None, password=None, certificate=None):
        if username is None and certificate is None:
            return User(role=UserRole.User, name="anonymous") if self.anonymous else None
        if self.writers.get(username) == password:
            return User(role=UserRole.User, name=username)
        if self.readers.get(username) == password:
            return User(role=UserRole.User, name=username)
        return None


def pairs(items):
    out = {}
    for s in items:
        name, _, value = s.partition(":")
        out[name] = value
    return out


async def main(args) -> None:
    pki = Path(args.pki)
    pki.mkdir(parents=True, exist_ok=True)
    cert, key = pki / "server_cert.der", pki / "server_key.pem"
    await setup_self_signed_certificate(
        key, cert, APP_URI, "127.0.0.1", [ExtendedKeyUsageOID.SERVER_AUTH], {"commonName": "truepos sim control"}
    )
    readers = set(pairs(args.reader))
    server = Server(user_manager=Users(pairs(args.user), pairs(args.reader), args.anonymous))
    await server.init()
    server.set_endpoint(f"opc.tcp://127.0.0.1:{args.port}/truepos-sim")
    server.set_server_name("truepos simulated control")
    await server.set_application_uri(APP_URI)
    server.set_security_policy(
        [
            ua.SecurityPolicyType.NoSecurity,
            ua.SecurityPolicyType.Basic256Sha256_Sign,
            ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt,
        ]
    )
    server.set_security_IDs(["Anonymous", "Username"] if args.anonymous else ["Username"])
    await server.load_certificate(str(cert))
    await server.load_private_key(str(key))
    ns = await server.register_namespace("urn:truepos:sim-control:nodes")
    objects = server.nodes.objects
    nc = await objects.add_object(ua.NodeId("NC", ns), "NC")

    async def var(name, value, vtype=ua.VariantType.Double, writable=False):
        node = await nc.add_variable(ua.NodeId(name, ns), name, ua.Variant(value, vtype))
        if writable:
            await node.set_writable()
        return node

    comp = {}
    pos = {}
    for u, axis in enumerate(AXES, start=1):
        comp[axis] = [
            await var(f"{SEA}$SA_TEMP_COMP_ABS_VALUE[u{u}]", 0.0, writable=True),
            await var(f"{SEA}$SA_TEMP_COMP_SLOPE[u{u}]", 0.0, writable=True),
            await var(f"{SEA}$SA_TEMP_COMP_REF_POSITION[u{u}]", 0.0, writable=True),
        ]
        pos[axis] = await var(f"/Channel/MachineAxis/actToolBasePos[u1,{u}]", 0.0)
    await var(f"{SEA}$SA_INT_NODE[u1]", 0, ua.VariantType.Int32, writable=True)
    temps = {}
    for t in args.temp:
        name, _, value = t.partition("=")
        temps[name] = (await var(f"/Plc/Temp/{name}", float(value)), float(value))
    bad = {}
    for b in args.bad_temp:
        name, _, at = b.partition("@")
        bad[name] = float(at)

    # Writes: a reader's are refused (no write realm); a slow server answers late.
    service = server.iserver.attribute_service
    plain_write = service.write

    async def write(params, user=User(role=UserRole.Admin)):
        if args.slow_ms > 0:
            await asyncio.sleep(args.slow_ms / 1000.0)
        if getattr(user, "name", None) in readers:
            return [ua.StatusCode(ua.StatusCodes.BadUserAccessDenied) for _ in params.NodesToWrite]
        return await plain_write(params, user)

    service.write = write

    lo, hi = (float(v) for v in args.travel_x.split(","))
    fixed = {"Y": args.pos_y, "Z": args.pos_z}
    record = open(args.record, "w", buffering=1)
    cols = ["t_s"] + [f"{a}_{k}" for a in AXES for k in ("mm", "k0_mm", "tan_beta", "p0_mm", "dk_mm")]
    record.write(",".join(cols) + "\n")
    async with server:
        print(f"opcua_control: listening on 127.0.0.1:{args.port}", flush=True)
        start = time.monotonic()
        while args.duration_s <= 0 or time.monotonic() - start < args.duration_s:
            t = time.monotonic() - start
            span = hi - lo
            phase = (t * args.speed) % (2 * span) if span > 0 else 0.0
            p = {"X": lo + (phase if phase <= span else 2 * span - phase), **fixed}
            for name, at in list(bad.items()):
                if t >= at:
                    node, value = temps[name]
                    status = ua.StatusCode(ua.StatusCodes.BadSensorFailure)
                    await node.write_value(ua.DataValue(ua.Variant(value, ua.VariantType.Double), StatusCode=status))
                    del bad[name]
            row = [f"{t:.4f}"]
            for axis in AXES:
                await pos[axis].write_value(ua.Variant(p[axis], ua.VariantType.Double))
                k0, tan_beta, p0 = [await n.read_value() for n in comp[axis]]
                dk = k0 + tan_beta * (p[axis] - p0)
                row += [repr(p[axis]), repr(k0), repr(tan_beta), repr(p0), repr(dk)]
            record.write(",".join(row) + "\n")
            await asyncio.sleep(args.tick_ms / 1000.0)


if __name__ == "__main__":
    logging.basicConfig(level=logging.ERROR)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--pki", required=True)
    parser.add_argument("--record", required=True)
    parser.add_argument("--user", action="append", default=[])
    parser.add_argument("--reader", action="append", default=[])
    parser.add_argument("--anonymous", action="store_true")
    parser.add_argument("--temp", action="append", default=[])
    parser.add_argument("--travel-x", default="0,800")
    parser.add_argument("--speed", type=float, default=200.0)
    parser.add_argument("--pos-y", type=float, default=250.0)
    parser.add_argument("--pos-z", type=float, default=300.0)
    parser.add_argument("--tick-ms", type=float, default=20.0)
    parser.add_argument("--slow-ms", type=float, default=0.0)
    parser.add_argument("--bad-temp", action="append", default=[])
    parser.add_argument("--duration-s", type=float, default=0.0)
    sys.exit(asyncio.run(main(parser.parse_args())))
