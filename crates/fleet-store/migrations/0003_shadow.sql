-- Models in shadow (docs/fleet.md, "The service follows the store"): `truepos fleet follow`
-- evaluates a machine's shadow model — and, after an activation, the parent of the new active
-- model — at the inputs of every accepted probe event of the service's log, and keeps, per probe
-- and measured axis, the measured error and both predictions. The shadow rule and the rollback
-- rule (truepos_fleet_store::shadow) judge these rows.

CREATE TABLE fleet_shadow_probes (
    machine        text NOT NULL,
    -- The model evaluated beside the running one: the shadow, or the parent being watched.
    version        integer NOT NULL,
    -- The store's active version when the probe was read (the model the service ran).
    active_version integer NOT NULL,
    -- The probe's data time: the service's start (the log's meta) plus its service time.
    t              timestamptz NOT NULL,
    axis           text NOT NULL CHECK (axis <> '' AND length(axis) <= 50),
    -- Measured error (actual − nominal), what the running model predicted (the log's
    -- predicted_d<axis>_um) and what `version` predicts at the same inputs, µm.
    measured_um    float8 NOT NULL,
    active_um      float8 NOT NULL,
    shadow_um      float8 NOT NULL,
    -- The service log's probes row it came from (for a reader; not part of the key).
    log_row        bigint NOT NULL,
    written_at     timestamptz NOT NULL DEFAULT now(),
    -- Re-reading the same probes (a follower restarted, its cursor lost) writes them once.
    PRIMARY KEY (machine, version, t, axis),
    FOREIGN KEY (machine, version) REFERENCES fleet_models (machine, version),
    FOREIGN KEY (machine, active_version) REFERENCES fleet_models (machine, version)
);
