//! The rows [`crate::shadow`] judges: per probe event and measured axis of a service's log, the
//! measured error, the running model's prediction and another model's (a shadow, or the parent
//! of a model just activated) — table `fleet_shadow_probes`, migration `0003_shadow.sql`.
//! Keyed by machine, version, data time and axis: the same probe written twice is kept once.

use postgres::GenericClient;

use crate::shadow::Pair;

/// One residual to keep.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowProbe {
    /// The probe's data time, s since the Unix epoch.
    pub t_unix_s: f64,
    /// The axis' name.
    pub axis: String,
    /// Measured error, µm.
    pub measured_um: f64,
    /// What the running model predicted, µm.
    pub active_um: f64,
    /// What the evaluated model predicts, µm.
    pub shadow_um: f64,
    /// The log's probes row.
    pub log_row: i64,
}

/// Writes the residuals of `version` evaluated beside `active_version` in one transaction;
/// returns how many were new (a row already there is left as it is).
pub fn record(
    db: &mut impl GenericClient,
    machine: &str,
    version: i32,
    active_version: i32,
    probes: &[ShadowProbe],
) -> Result<u64, postgres::Error> {
    let mut tx = db.transaction()?;
    let st = tx.prepare(
        "INSERT INTO fleet_shadow_probes
             (machine, version, active_version, t, axis, measured_um, active_um, shadow_um, log_row)
         VALUES ($1, $2, $3, to_timestamp($4), $5, $6, $7, $8, $9)
         ON CONFLICT DO NOTHING",
    )?;
    let mut new = 0;
    for p in probes {
        new += tx.execute(
            &st,
            &[
                &machine,
                &version,
                &active_version,
                &p.t_unix_s,
                &p.axis,
                &p.measured_um,
                &p.active_um,
                &p.shadow_um,
                &p.log_row,
            ],
        )?;
    }
    tx.commit()?;
    Ok(new)
}

/// The residuals of `version` evaluated while `active_version` ran, oldest first, as the
/// rule's pairs (`other` = `version`'s prediction).
pub fn pairs(
    db: &mut impl GenericClient,
    machine: &str,
    version: i32,
    active_version: i32,
) -> Result<Vec<Pair>, postgres::Error> {
    Ok(db
        .query(
            "SELECT measured_um, active_um, shadow_um FROM fleet_shadow_probes
             WHERE machine = $1 AND version = $2 AND active_version = $3 ORDER BY t, axis",
            &[&machine, &version, &active_version],
        )?
        .iter()
        .map(|r| Pair {
            measured_um: r.get(0),
            active_um: r.get(1),
            other_um: r.get(2),
        })
        .collect())
}
