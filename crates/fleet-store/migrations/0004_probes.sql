-- Probe events in the fleet store (docs/fleet.md): every accepted probe event of a service's
-- log, as its publisher sends it (one NDATA of `Probe/<column>` metrics). `truepos fleet refit`
-- fits a machine's model from these and its seconds.

-- One row per accepted probe event: its cycle's compensation state and, by the log's column
-- names, the probed position (`probe_<axis>_mm`), the measured error (`probe_d<axis>_um`,
-- actual − nominal; null where the axis was not measured), what the running model predicted
-- there (`predicted_d<axis>_um`) and the cycle's positions, temperatures and operating state.
-- Partitioned by day like fleet_seconds; keyed on machine + data time, so a replay is written
-- once.
CREATE TABLE fleet_probes (
    group_id    text NOT NULL,
    node_id     text NOT NULL,
    t           timestamptz NOT NULL,
    state       text,
    "values"    jsonb NOT NULL,
    historical  boolean NOT NULL,
    received_at timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (group_id, node_id, t)
) PARTITION BY RANGE (t);
