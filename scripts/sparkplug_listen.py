"""A Sparkplug B host for the fleet tests: subscribes to spBv1.0/# at QoS 1 with a persistent
session (so a broker restarted from its persistence file still queues for it) and writes every
message decoded by PyPI's pysparkplug (Eclipse's sparkplug_b.proto, compiled by its authors,
nothing written here) as one JSON line. A payload it cannot decode is written as
{"type": "undecodable"} and the listener goes on. Prints "subscribed" once it listens.

usage: sparkplug_listen.py PORT OUT.jsonl CLIENT_ID
"""

import json
import sys

import paho.mqtt.client as mqtt
from pysparkplug import NBirth, NData, NDeath

port, out_path, client_id = int(sys.argv[1]), sys.argv[2], sys.argv[3]
out = open(out_path, "a", encoding="utf-8")
KINDS = {"NBIRTH": NBirth, "NDATA": NData, "NDEATH": NDeath}
# The last NBIRTH of each node: NDATA names its metrics by the aliases the birth declared.
births = {}


def on_connect(client, userdata, flags, rc):
    client.subscribe("spBv1.0/#", qos=1)


def on_subscribe(client, userdata, mid, granted):
    print("subscribed", flush=True)


def on_message(client, userdata, msg):
    parts = msg.topic.split("/")
    rec = {"topic": msg.topic, "size": len(msg.payload), "dup": bool(msg.dup)}
    try:
        kind = parts[2]
        node = "/".join(parts[:2] + parts[3:])
        if kind == "NDATA":
            if node not in births:
                raise ValueError("NDATA before any NBIRTH of its node")
            payload = NData.decode(msg.payload, birth=births[node])
        else:
            payload = KINDS[kind].decode(msg.payload)
        if kind == "NBIRTH":
            births[node] = payload
        rec["type"] = kind
        if kind == "NDEATH":
            rec["bdSeq"] = payload.bd_seq_metric.value
        else:
            rec["seq"] = payload.seq
            rec["timestamp"] = payload.timestamp
            rec["metrics"] = [
                [m.name, m.value, m.timestamp, m.is_historical, m.is_null, int(m.datatype)]
                for m in payload.metrics
            ]
    except Exception as e:  # a foreign or malformed message: recorded, never fatal
        rec = {"topic": msg.topic, "type": "undecodable", "why": repr(e)}
    out.write(json.dumps(rec) + "\n")
    out.flush()


client = mqtt.Client(client_id=client_id, clean_session=False)
client.on_connect = on_connect
client.on_subscribe = on_subscribe
client.on_message = on_message
# Back within a second of the broker's restart.
client.reconnect_delay_set(min_delay=1, max_delay=1)
client.connect("127.0.0.1", port)
client.loop_forever(retry_first_connection=True)
