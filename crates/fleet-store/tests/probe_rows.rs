//! A probe event's NDATA, as a service sends it, becomes a `fleet_probes` row: its values by
//! the log's column names (null where the log had none), its state, its data time, historical
//! as sent — named through the birth's aliases, without a database.

use std::collections::HashMap;

use truepos_fleet::publisher::{birth_payload_with_probes, unit_payload};
use truepos_fleet::sparkplug::Payload;
use truepos_fleet::store::{Probe, Unit};
use truepos_fleet_store::ingest::{rows, Row};

#[test]
fn a_probe_ndata_becomes_a_probe_row() {
    let columns = vec!["t1".to_string(), "X_offset_um".to_string()];
    let probe_columns: Vec<String> = ["probe_z_mm", "probe_dz_um", "predicted_dz_um", "Z_mm"]
        .map(String::from)
        .to_vec();
    let birth = birth_payload_with_probes(1, "m", "a.toml", &columns, &probe_columns, 0);
    // Through the wire, as the ingester gets it.
    let birth = Payload::decode(&birth.encode()).unwrap();
    let names: HashMap<u64, String> = birth
        .metrics
        .iter()
        .map(|m| (m.alias.unwrap(), m.name.clone()))
        .collect();
    let unit = Unit::Probe(Probe {
        row: 4,
        time_s: 12.5,
        state: "active".into(),
        values: vec![Some(-50.0), Some(-3.25), None, Some(-50.0)],
    });
    let t = 1_764_400_012_500;
    let data = unit_payload(&unit, columns.len(), t, 7, true, t + 3);
    let data = Payload::decode(&data.encode()).unwrap();
    let row = rows(&data, &names).unwrap();
    assert_eq!(
        row,
        Row::Probe {
            t_ms: t as i64,
            state: Some("active".into()),
            values: serde_json::json!({
                "probe_z_mm": -50.0, "probe_dz_um": -3.25, "predicted_dz_um": null, "Z_mm": -50.0
            }),
            historical: true,
        }
    );
}
