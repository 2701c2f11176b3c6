-- Models as fleet objects (docs/fleet.md, "Models in the fleet store"): every generation of a
-- machine's model, signed, with its bytes, and the one it runs. `truepos fleet models register`
-- adds a candidate; `fleet activate` and `fleet rollback` move the states; every move is a row
-- of fleet_model_changes.

-- One row per model generation of a machine (the Sparkplug node id, fleet_nodes.node_id).
CREATE TABLE fleet_models (
    machine          text NOT NULL CHECK (machine <> '' AND length(machine) <= 200),
    -- The generation, 1, 2, … per machine, in the order registered.
    version          integer NOT NULL CHECK (version >= 1),
    -- What a rollback returns to: the machine's active version when this one was registered,
    -- and the one it replaced once activated. NULL: none.
    parent_version   integer CHECK (parent_version <> version),
    -- The registered file's name (its extension tells TOML from JSON to the loader).
    file_name        text NOT NULL CHECK (file_name <> '' AND length(file_name) <= 255
                                          AND strpos(file_name, '/') = 0),
    -- SHA-256 of `model` in hex, and the file's bytes (at most the loader's 16 MiB).
    sha256           text NOT NULL CHECK (sha256 ~ '^[0-9a-f]{64}$'),
    model            bytea NOT NULL CHECK (octet_length(model) BETWEEN 1 AND 16777216),
    -- The MODEL.sig line (`ed25519 <public key> <signature>`) and its public key in hex.
    signature        text NOT NULL CHECK (length(signature) <= 1000),
    public_key       text NOT NULL CHECK (public_key ~ '^[0-9a-f]{64}$'),
    -- The file's `provenance` and `validation` tables as JSON ({} when it has none).
    provenance       jsonb NOT NULL DEFAULT '{}',
    validation       jsonb NOT NULL DEFAULT '{}',
    state            text NOT NULL DEFAULT 'candidate'
                     CHECK (state IN ('candidate', 'shadow', 'active', 'retired')),
    created_at       timestamptz NOT NULL DEFAULT now(),
    state_changed_at timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (machine, version),
    FOREIGN KEY (machine, parent_version) REFERENCES fleet_models (machine, version)
);

-- At most one active model per machine.
CREATE UNIQUE INDEX fleet_models_one_active ON fleet_models (machine) WHERE state = 'active';

-- Every state a model entered: who, when, from, to, why (from_state NULL: registered).
CREATE TABLE fleet_model_changes (
    id          bigserial PRIMARY KEY,
    machine     text NOT NULL,
    version     integer NOT NULL,
    from_state  text,
    to_state    text NOT NULL,
    reason      text NOT NULL,
    changed_by  text NOT NULL,
    changed_at  timestamptz NOT NULL DEFAULT now(),
    FOREIGN KEY (machine, version) REFERENCES fleet_models (machine, version)
);
CREATE INDEX fleet_model_changes_by_machine ON fleet_model_changes (machine, changed_at);
