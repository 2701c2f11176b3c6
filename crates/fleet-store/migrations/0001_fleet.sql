-- The fleet store's first schema (docs/fleet.md). Every table is keyed so that a message the
-- broker or the publisher sends again is written once: machine (group, node) + the data's time.

-- One row per Sparkplug edge node (a machine): what its last birth said, when it last died.
CREATE TABLE fleet_nodes (
    group_id  text NOT NULL,
    node_id   text NOT NULL,
    machine   text,
    models    text,
    bd_seq    bigint,
    -- The birth's metric names by alias ({"4": "Cycles", …}): an ingester that restarts
    -- mid-session reads NDATA with them.
    aliases   jsonb,
    born_at   timestamptz,
    died_at   timestamptz,
    PRIMARY KEY (group_id, node_id)
);

-- One row per machine and second: its cycle counts and, per input and axis offset,
-- [min, mean, max] ("Inputs/t1": [20.1, 20.15, 20.2]; null where the second had no value).
-- Partitioned by day (the ingester creates each day's partition when its first row comes).
CREATE TABLE fleet_seconds (
    group_id      text NOT NULL,
    node_id       text NOT NULL,
    t             timestamptz NOT NULL,
    cycles        integer,
    active_cycles integer,
    stats         jsonb NOT NULL,
    historical    boolean NOT NULL,
    received_at   timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (group_id, node_id, t)
) PARTITION BY RANGE (t);

-- One row per event of the service's log.
CREATE TABLE fleet_events (
    group_id    text NOT NULL,
    node_id     text NOT NULL,
    t           timestamptz NOT NULL,
    kind        text NOT NULL,
    subject     text NOT NULL,
    detail      text NOT NULL,
    historical  boolean NOT NULL,
    received_at timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (group_id, node_id, t, kind, subject, detail)
) PARTITION BY RANGE (t);
